//! What this process costs, read from `/proc` (Linux; elsewhere every reading is `None`): its CPU time
//! (user and system, all threads, `/proc/self/stat`) next to the wall time, its peak resident set size
//! (`VmHWM` of `/proc/self/status`, what `getrusage` reports as `ru_maxrss`, read without `unsafe`), and the
//! machine's 1-minute load average (`/proc/loadavg`), which says how far a wall time is inflated by other
//! work. The runner reports them after every stage; the benchmarks record them per point.

use std::path::Path;

/// Clock ticks per second of `/proc/<pid>/stat`'s `utime`/`stime`: the kernel's `USER_HZ`, fixed at 100 by the
/// Linux ABI on every architecture this project builds for (`sysconf(_SC_CLK_TCK)` would need `unsafe`).
/// Resolution 10 ms: fine for sweep points of ≥ 0.1 s.
pub const USER_HZ: f64 = 100.0;

/// User + system CPU seconds of this process so far (all threads, including finished ones).
#[must_use]
pub fn cpu_time_s() -> Option<f64> {
    let (user, system) = parse_stat_cpu_ticks(&read("/proc/self/stat")?)?;
    Some((user + system) as f64 / USER_HZ)
}

/// The machine's 1-minute load average now.
#[must_use]
pub fn load_average_1m() -> Option<f64> {
    parse_loadavg_1m(&read("/proc/loadavg")?)
}

/// The largest resident set size this process has had so far, in bytes.
#[must_use]
pub fn peak_rss_bytes() -> Option<u64> {
    parse_vm_hwm_bytes(&read("/proc/self/status")?)
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(Path::new(path)).ok()
}

/// `VmHWM:   123456 kB` of a `/proc/<pid>/status`, in bytes.
#[must_use]
pub fn parse_vm_hwm_bytes(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let mut f = line["VmHWM:".len()..].split_whitespace();
    let kb: u64 = f.next()?.parse().ok()?;
    (f.next()? == "kB").then_some(kb * 1024)
}

/// `utime` and `stime` (fields 14 and 15, in clock ticks) of a `/proc/<pid>/stat` line. The command name
/// (field 2) is in parentheses and may itself contain spaces and parentheses, so fields are counted after the
/// last `)`.
#[must_use]
pub fn parse_stat_cpu_ticks(stat: &str) -> Option<(u64, u64)> {
    let after = &stat[stat.rfind(')')? + 1..];
    // After the name: field 3 (state) is the first; utime is field 14, i.e. the 12th after the name.
    let mut f = after.split_whitespace().skip(11);
    let user = f.next()?.parse().ok()?;
    let system = f.next()?.parse().ok()?;
    Some((user, system))
}

/// The first field of `/proc/loadavg` (`0.52 0.58 0.59 2/345 12345`).
#[must_use]
pub fn parse_loadavg_1m(text: &str) -> Option<f64> {
    text.split_whitespace().next()?.parse().ok().filter(|v: &f64| v.is_finite() && *v >= 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peak_rss_is_read_from_vm_hwm_in_kilobytes() {
        let status = "Name:\tpipeline\nVmPeak:\t  900000 kB\nVmHWM:\t   31832 kB\nVmRSS:\t   30000 kB\n";
        assert_eq!(parse_vm_hwm_bytes(status), Some(31832 * 1024));
        assert_eq!(parse_vm_hwm_bytes("VmRSS:\t1 kB\n"), None);
        // This process has touched memory: its own reading exists and is at least a page.
        assert!(peak_rss_bytes().is_some_and(|b| b >= 4096));
    }

    #[test]
    fn stat_fields_are_counted_after_the_command_name() {
        // A real line's layout (proc(5)); the name contains a space and a parenthesis.
        let line = "4242 (a (b) c) R 1 4242 4242 0 -1 4194304 1234 0 0 0 731 29 0 0 20 0 3 0 12345 1000 200";
        assert_eq!(parse_stat_cpu_ticks(line), Some((731, 29)));
        assert_eq!(parse_stat_cpu_ticks("12 (x) R 1 2"), None);
    }

    #[test]
    fn loadavg_first_field() {
        assert_eq!(parse_loadavg_1m("1.25 0.80 0.50 3/456 7890\n"), Some(1.25));
        assert_eq!(parse_loadavg_1m(""), None);
    }

    #[test]
    fn cpu_time_grows_with_work_on_linux() {
        if !Path::new("/proc/self/stat").exists() {
            eprintln!("skipping: no /proc/self/stat");
            return;
        }
        let before = cpu_time_s().unwrap();
        // Busy work until the counter (10 ms ticks) has moved, bounded so the test cannot hang.
        let mut x = 0u64;
        let mut after = before;
        for i in 0..2_000_000_000u64 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(i);
            if i % 1_000_000 == 0 {
                after = cpu_time_s().unwrap();
                if after > before {
                    break;
                }
            }
        }
        std::hint::black_box(x);
        assert!(after > before, "{before} → {after}");
        assert!(load_average_1m().unwrap() >= 0.0);
    }
}
