//! In-process mutation fuzzing of every reader of the crate (stable Rust, no external fuzzer).
//!
//! Each case is a seeded mutation of a valid input ([`mutate`]) fed to one reader ([`readers`]) under
//! `catch_unwind`, with the thread's largest single allocation counted ([`alloc`]) and the case timed. A case
//! fails when the reader panics, when its error is not one line naming the file, when its largest allocation
//! exceeds [`alloc_bound`], or when it takes longer than the reader's time bound (see [`run_reader`]). Failing
//! cases are saved as `tests/fuzz/regressions/<reader>/<seed>-<case>.bin` and replayed by every later run.
//!
//! Knobs: `IPT_FUZZ_CASES` (cases per reader, default [`CI_CASES`]), `IPT_FUZZ_SEED` (base seed, default
//! [`DEFAULT_SEED`]). Each reader prints one summary line starting with `fuzz-summary` (read by `scripts/fuzz`).

#![allow(dead_code)]

pub mod alloc;
pub mod mutate;
pub mod readers;

use std::cell::RefCell;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Once};
use std::time::{Duration, Instant};

use readers::Reader;

/// Cases per reader in the CI test (debug profile): 10⁴ per reader is the figure CI asks for; the whole binary
/// then takes about 2 s on 2 cores, far inside its 60 s budget (measured; see docs/reliability.md).
pub const CI_CASES: u64 = 10_000;

/// Base seed when `IPT_FUZZ_SEED` is not set.
pub const DEFAULT_SEED: u64 = 1;

/// Allocation bound, bytes per input byte. The largest legitimate ratio is a text format's token table: a
/// `Vec<&str>` (16 bytes per token) of at-least-2-byte tokens, or a `serde_json::Value` array (32 bytes per
/// element of at least 2 bytes), i.e. 8–16× the input, doubled by `Vec`'s amortised growth: 32×. Anything
/// proportional to a header's claim rather than to the data fails this.
pub const ALLOC_PER_INPUT_BYTE: usize = 32;

/// Allocation floor, bytes: buffers whose size does not depend on the input length. The largest are the EXR
/// reader's block reservations, which ingest bounds by the image's geometry (at most 64 KiB for the 13×7 photo
/// seeds: a 64 × 64 tile at 16 bytes per pixel, see `photo::image_io`), and the PNG decoder's 32 KiB inflate
/// window; the largest measured over 10⁶ cases of every reader is 64 KiB (`scripts/fuzz` prints it as
/// `largest_alloc`). 128 KiB is twice that, and still fails a header claim of ten thousand elements or pixels
/// on these small inputs.
pub const ALLOC_FLOOR: usize = 128 << 10;

/// The largest single allocation a case of `len` input bytes may make.
#[must_use]
pub fn alloc_bound(len: usize) -> usize {
    (ALLOC_PER_INPUT_BYTE * len).max(ALLOC_FLOOR)
}

/// Time bound factor over the reader's median case time. Every reader is linear in its input, and mutated
/// cases stay within a few times the seeds' sizes, so a case 50× slower than the median does work out of
/// proportion to its input (a loop over a header's count, quadratic rescans).
pub const TIME_FACTOR_OVER_MEDIAN: u32 = 50;

/// Floor of the time bound: medians are 1–10 µs of CPU time, so 50× the median would be below the cost of a
/// few page faults or a cold cache; no case of a correct reader comes near 2 ms (the measured worst is given in
/// docs/reliability.md), while a pathological one (a loop over a header's count, quadratic rescans) on these
/// inputs takes far longer.
pub const TIME_FLOOR: Duration = Duration::from_millis(2);

/// A case over its time bound is re-run this many times and judged on its fastest run, so that a one-off cost
/// (a page fault storm, a cold cache, an interrupt accounted to the thread) is not mistaken for a slow reader.
pub const TIME_RETRIES: usize = 3;

/// How many of the slowest cases are re-run ([`TIME_RETRIES`] times) before the worst time is reported: one-off
/// costs hit a handful of cases per run, so the true worst is among the 16 slowest first runs.
pub const SLOWEST_RERUN: usize = 16;

/// A case running longer than this is hung: the watchdog saves it and aborts the process (no time bound can
/// be checked after a case that never returns).
pub const HANG_LIMIT: Duration = Duration::from_secs(60);

/// CPU-time bound when replaying saved regressions one by one (no median to compare against): every saved case
/// runs in well under a millisecond once fixed; one second means a pathology.
pub const REPLAY_TIME_LIMIT: Duration = Duration::from_secs(1);

/// Cases per reader: `IPT_FUZZ_CASES` or [`CI_CASES`].
#[must_use]
pub fn cases_from_env() -> u64 {
    std::env::var("IPT_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(CI_CASES)
}

/// Base seed: `IPT_FUZZ_SEED` or [`DEFAULT_SEED`].
#[must_use]
pub fn seed_from_env() -> u64 {
    std::env::var("IPT_FUZZ_SEED").ok().and_then(|v| v.parse().ok()).unwrap_or(DEFAULT_SEED)
}

/// The directory of saved failing cases of `reader`.
#[must_use]
pub fn regression_dir(reader: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/regressions").join(reader)
}

/// What one run of a reader did.
#[derive(Debug)]
pub enum Outcome {
    Ok,
    Err(String),
    Panic(String),
}

/// One case's outcome, CPU time and largest single allocation.
#[derive(Debug)]
pub struct CaseRun {
    pub outcome: Outcome,
    pub time: Duration,
    pub largest_alloc: usize,
}

thread_local! {
    static IN_CASE: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Installs (once) a panic hook that records a fuzz case's panic message instead of printing it; panics
/// outside a case go to the previous hook.
fn install_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let captured = IN_CASE.with(|c| {
                let mut c = c.borrow_mut();
                match c.as_mut() {
                    Some(slot) => {
                        *slot = format!("{info}");
                        true
                    }
                    None => false,
                }
            });
            if !captured {
                previous(info);
            }
        }));
    });
}

/// Runs `reader` once on `bytes`, counting allocations and time.
pub fn run_case(reader: &Reader, path: &Path, bytes: &[u8]) -> CaseRun {
    install_panic_hook();
    static TRACE: Once = Once::new();
    TRACE.call_once(|| {
        if let Some(n) = std::env::var("IPT_FUZZ_TRACE_ALLOC").ok().and_then(|v| v.parse().ok()) {
            alloc::TRACE_ABOVE.store(n, Ordering::Relaxed);
        }
    });
    IN_CASE.with(|c| *c.borrow_mut() = Some(String::new()));
    alloc::arm();
    let start = thread_cpu_time();
    let result = catch_unwind(AssertUnwindSafe(|| (reader.run)(path, bytes)));
    let time = thread_cpu_time().saturating_sub(start);
    let largest_alloc = alloc::disarm();
    let panic_message = IN_CASE.with(|c| c.borrow_mut().take()).unwrap_or_default();
    let outcome = match result {
        Ok(Ok(())) => Outcome::Ok,
        Ok(Err(m)) => Outcome::Err(m),
        Err(_) => Outcome::Panic(panic_message),
    };
    CaseRun { outcome, time, largest_alloc }
}

/// CPU time consumed by the calling thread. Cases are timed in CPU time, not wall time: on a loaded machine a
/// case of a few µs is often preempted for a scheduler tick (4 ms) or more, which says nothing about the reader.
#[must_use]
pub fn thread_cpu_time() -> Duration {
    let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `t` is a valid, writable timespec; CLOCK_THREAD_CPUTIME_ID exists on every Linux.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed");
    Duration::new(t.tv_sec as u64, t.tv_nsec as u32)
}

/// Why a case failed, excluding time (judged over the whole run); `None` when it passed.
#[must_use]
pub fn violation(path: &Path, len: usize, run: &CaseRun) -> Option<String> {
    let file = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    match &run.outcome {
        Outcome::Panic(m) => return Some(format!("panic: {m}")),
        Outcome::Err(m) if m.contains('\n') || m.contains('\r') => {
            return Some(format!("error message is not one line: {m:?}"));
        }
        Outcome::Err(m) if !m.contains(&file) => return Some(format!("error message does not name {file}: {m:?}")),
        _ => {}
    }
    if run.largest_alloc > alloc_bound(len) {
        return Some(format!(
            "allocated {} bytes at once for {len} input bytes (bound {})",
            run.largest_alloc,
            alloc_bound(len)
        ));
    }
    None
}

/// What makes two failures the same bug, for saving one file per bug and run: a panic's first line (its message
/// and location), or the start of any other violation up to the first quote or colon, numbers removed (the
/// quoted message or the sizes differ from case to case).
fn failure_kind(why: &str) -> String {
    if why.starts_with("panic") {
        return why.lines().next().unwrap_or_default().to_string();
    }
    why.split(['"', ':']).next().unwrap_or_default().chars().filter(|c| !c.is_ascii_digit()).collect()
}

/// Summary of one reader's run.
#[derive(Debug, Default)]
pub struct Stats {
    pub cases: u64,
    pub ok: u64,
    pub errors: u64,
    pub panics: u64,
    pub failures: Vec<(u64, String)>,
    pub median: Duration,
    pub worst: Duration,
    pub worst_case: u64,
    pub time_bound: Duration,
    pub largest_alloc: usize,
    /// Largest (allocation / input bytes) over cases whose allocation exceeds the floor (0 when none does).
    pub worst_ratio_above_floor: f64,
    /// Largest (allocation / bound): must stay at most 1.
    pub worst_bound_use: f64,
}

/// Saves a failing case and returns its path.
pub fn save_case(reader: &str, seed: u64, case: u64, bytes: &[u8]) -> PathBuf {
    let dir = regression_dir(reader);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{seed}-{case}.bin"));
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The bytes of case `case` of `reader` under `seed`.
#[must_use]
pub fn case_bytes(reader: &Reader, corpus: &[Vec<u8>], seed: u64, case: u64) -> Vec<u8> {
    mutate::mutate(&mut mutate::case_rng(seed, reader.name, case), corpus)
}

/// Fuzzes `reader` with `cases` cases under `seed`; saves failing cases; prints the summary line.
///
/// Time bound (thread CPU time per case): max([`TIME_FACTOR_OVER_MEDIAN`] × the median case time, [`TIME_FLOOR`]), each offending case
/// judged on its fastest of [`TIME_RETRIES`] re-runs.
pub fn run_reader(reader: &Reader, cases: u64, seed: u64) -> Stats {
    let corpus = Arc::new(readers::corpus(reader));
    let path = (reader.path)();
    let mut stats = Stats { cases, ..Stats::default() };
    // The seeds themselves must be accepted: a fuzzer mutating invalid inputs explores little.
    for (i, s) in corpus.iter().enumerate() {
        if let Err(e) = (reader.run)(&path, s) {
            panic!("{}: seed {i} is not valid: {e}", reader.name);
        }
    }
    let watchdog = Watchdog::start(*reader, Arc::clone(&corpus), seed);
    let mut times = Vec::with_capacity(cases as usize);
    let mut kinds = std::collections::HashSet::new();
    // `IPT_FUZZ_VERBOSE=1` prints the most frequent error messages: a corpus whose mutations all fail at the
    // same first check explores little of the reader.
    let verbose = std::env::var_os("IPT_FUZZ_VERBOSE").is_some();
    let mut error_kinds = std::collections::HashMap::new();
    for case in 0..cases {
        let bytes = case_bytes(reader, &corpus, seed, case);
        alloc::set_current_case(&bytes, reader.name, seed, case);
        watchdog.begin(case);
        let run = run_case(reader, &path, &bytes);
        watchdog.end();
        alloc::clear_current_case();
        times.push(run.time);
        match &run.outcome {
            Outcome::Ok => stats.ok += 1,
            Outcome::Err(m) => {
                stats.errors += 1;
                if verbose {
                    let kind: String = m.chars().filter(|c| !c.is_ascii_digit()).take(100).collect();
                    *error_kinds.entry(kind).or_insert(0u64) += 1;
                }
            }
            Outcome::Panic(_) => stats.panics += 1,
        }
        stats.largest_alloc = stats.largest_alloc.max(run.largest_alloc);
        let len = bytes.len().max(1);
        stats.worst_bound_use = stats.worst_bound_use.max(run.largest_alloc as f64 / alloc_bound(len) as f64);
        if run.largest_alloc > ALLOC_FLOOR {
            stats.worst_ratio_above_floor = stats.worst_ratio_above_floor.max(run.largest_alloc as f64 / len as f64);
        }
        if let Some(why) = violation(&path, bytes.len(), &run) {
            // One saved file per kind of failure and run (see `failure_kind`).
            let kind = failure_kind(&why);
            let note = if kinds.insert(kind) {
                format!(" (saved {})", save_case(reader.name, seed, case, &bytes).display())
            } else {
                String::new()
            };
            stats.failures.push((case, format!("{why}{note}")));
        }
    }
    watchdog.stop();
    let mut sorted = times.clone();
    sorted.sort_unstable();
    stats.median = sorted.get(sorted.len() / 2).copied().unwrap_or_default();
    stats.time_bound = (stats.median * TIME_FACTOR_OVER_MEDIAN).max(TIME_FLOOR);
    // The slowest cases are re-run as well, so that the reported worst time is a reader's, not a preemption's.
    let slowest_kept = sorted.get(sorted.len().saturating_sub(SLOWEST_RERUN)).copied().unwrap_or_default();
    for (case, &t) in times.iter().enumerate() {
        let case = case as u64;
        let mut best = t;
        if t > stats.time_bound || t >= slowest_kept {
            let bytes = case_bytes(reader, &corpus, seed, case);
            for _ in 0..TIME_RETRIES {
                best = best.min(run_case(reader, &path, &bytes).time);
            }
            if best > stats.time_bound {
                let saved = save_case(reader.name, seed, case, &bytes);
                stats
                    .failures
                    .push((case, format!("took {best:?} (bound {:?}) (saved {})", stats.time_bound, saved.display())));
            }
        }
        if best > stats.worst {
            stats.worst = best;
            stats.worst_case = case;
        }
    }
    if verbose {
        let mut kinds: Vec<(u64, String)> = error_kinds.into_iter().map(|(k, n)| (n, k)).collect();
        kinds.sort_unstable_by(|a, b| b.cmp(a));
        for (n, k) in kinds.iter().take(12) {
            println!("fuzz-errors reader={} count={n} {k}", reader.name);
        }
    }
    println!(
        "fuzz-summary reader={} seed={seed} cases={} ok={} errors={} panics={} failures={} median_us={:.1} \
         worst_us={:.1} worst_case={} time_bound_us={:.0} largest_alloc={} worst_ratio_above_floor={:.2} \
         worst_bound_use={:.3}",
        reader.name,
        stats.cases,
        stats.ok,
        stats.errors,
        stats.panics,
        stats.failures.len(),
        stats.median.as_secs_f64() * 1e6,
        stats.worst.as_secs_f64() * 1e6,
        stats.worst_case,
        stats.time_bound.as_secs_f64() * 1e6,
        stats.largest_alloc,
        stats.worst_ratio_above_floor,
        stats.worst_bound_use,
    );
    stats
}

/// Fuzzes the reader called `name` with the knobs from the environment and asserts that no case failed.
pub fn fuzz(name: &str) {
    let reader = readers::reader(name);
    let stats = run_reader(&reader, cases_from_env(), seed_from_env());
    let shown: Vec<String> = stats.failures.iter().take(20).map(|(c, why)| format!("case {c}: {why}")).collect();
    assert!(stats.failures.is_empty(), "{name}: {} failing cases:\n{}", stats.failures.len(), shown.join("\n"));
}

/// Replays every saved regression of every reader; returns the failures.
#[must_use]
pub fn replay_regressions() -> (usize, Vec<String>) {
    let mut failures = Vec::new();
    let mut replayed = 0;
    for reader in readers::READERS {
        let path = (reader.path)();
        let Ok(entries) = std::fs::read_dir(regression_dir(reader.name)) else { continue };
        let mut files: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
        files.sort();
        // A saved case that hangs again aborts the run with its name instead of stalling it.
        let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
        let watchdog = Watchdog::start_with(move |k, running| {
            eprintln!("fuzz: saved case {} hung for {running:?}; aborting", names[k as usize]);
        });
        for (k, f) in files.into_iter().enumerate() {
            let bytes = std::fs::read(&f).unwrap();
            watchdog.begin(k as u64);
            let run = run_case(reader, &path, &bytes);
            watchdog.end();
            replayed += 1;
            if let Some(why) = violation(&path, bytes.len(), &run) {
                failures.push(format!("{}: {why}", f.display()));
            } else if run.time > REPLAY_TIME_LIMIT {
                failures.push(format!("{}: took {:?}", f.display(), run.time));
            }
        }
        watchdog.stop();
    }
    (replayed, failures)
}

/// Aborts the process, after saving the running case, when a case hangs.
struct Watchdog {
    /// Start of the running case in µs since `origin`, plus 1 (0 = no case running).
    started: Arc<AtomicU64>,
    case: Arc<AtomicU64>,
    done: Arc<AtomicBool>,
    origin: Instant,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Watchdog {
    /// Starts watching the fuzz cases of `reader` under `seed`: a hung case is regenerated and saved.
    fn start(reader: Reader, corpus: Arc<Vec<Vec<u8>>>, seed: u64) -> Self {
        Self::start_with(move |k, running| {
            let bytes = case_bytes(&reader, &corpus, seed, k);
            let saved = save_case(reader.name, seed, k, &bytes);
            eprintln!(
                "fuzz: reader {} seed {seed} case {k} hung for {running:?}; saved to {}; aborting",
                reader.name,
                saved.display()
            );
        })
    }

    /// Starts watching; `on_hang(case, running)` reports a case running longer than [`HANG_LIMIT`], after which
    /// the process aborts.
    fn start_with(on_hang: impl Fn(u64, Duration) + Send + 'static) -> Self {
        let started = Arc::new(AtomicU64::new(0));
        let case = Arc::new(AtomicU64::new(0));
        let done = Arc::new(AtomicBool::new(false));
        let origin = Instant::now();
        let (s, c, d) = (Arc::clone(&started), Arc::clone(&case), Arc::clone(&done));
        let thread = std::thread::spawn(move || {
            while !d.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(200));
                let t = s.load(Ordering::Relaxed);
                if t == 0 {
                    continue;
                }
                let running = origin.elapsed().saturating_sub(Duration::from_micros(t - 1));
                if running > HANG_LIMIT {
                    on_hang(c.load(Ordering::Relaxed), running);
                    std::process::abort();
                }
            }
        });
        Self { started, case, done, origin, thread: Some(thread) }
    }

    fn begin(&self, case: u64) {
        self.case.store(case, Ordering::Relaxed);
        self.started.store(self.origin.elapsed().as_micros() as u64 + 1, Ordering::Relaxed);
    }

    fn end(&self) {
        self.started.store(0, Ordering::Relaxed);
    }

    fn stop(mut self) {
        self.done.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.join().unwrap();
        }
    }
}
