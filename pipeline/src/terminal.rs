//! The binary's [`Reporter`]: stage messages and progress on the terminal and in the run log.
//!
//! - Messages (`[stage] line`) go to stderr and, with a timestamp, to `<output>/run.log`.
//! - Progress is an `indicatif` bar with an ETA when stderr is a terminal. Every [`LOG_EVERY`] a line with
//!   the position and the ETA (`[object] fit: 37/212, 1m12s left`) also goes to the run log, and to stderr
//!   when stderr is not a terminal (a redirected run still shows where it is and when it will end); a step
//!   that enters a new phase (a message with a new first word) writes that line at once.

use std::fs::File;
use std::io::{IsTerminal, Write};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use indicatif::{ProgressBar, ProgressStyle};
use workflow::plan::StageId;
use workflow::stage_contract::Reporter;

/// How often a long step writes its position and ETA into the log: often enough to follow a run of tens of
/// minutes, rare enough that a log stays readable (one line per step per ten seconds).
const LOG_EVERY: Duration = Duration::from_secs(10);

/// SIGINT and SIGTERM as flags. The first one asks the run to stop at its next step boundary (with a
/// checkpoint); a second one of the same kind ends the process at once (the signal's default action).
#[derive(Debug, Clone, Default)]
pub struct Signals {
    int: Arc<AtomicBool>,
    term: Arc<AtomicBool>,
}

impl Signals {
    /// Installs the handlers; without them (an error registering) a signal keeps its default action.
    pub fn install() -> Self {
        let s = Self::default();
        for (sig, flag) in [(signal_hook::consts::SIGINT, &s.int), (signal_hook::consts::SIGTERM, &s.term)] {
            let _ = signal_hook::flag::register_conditional_default(sig, Arc::clone(flag));
            let _ = signal_hook::flag::register(sig, Arc::clone(flag));
        }
        s
    }

    /// The signal received, if any, with the exit code it gives (128 + its number, as shells report it).
    pub fn received(&self) -> Option<(&'static str, u8)> {
        if self.int.load(Ordering::Relaxed) {
            Some(("SIGINT", 130))
        } else if self.term.load(Ordering::Relaxed) {
            Some(("SIGTERM", 143))
        } else {
            None
        }
    }
}

/// Stage messages and progress for a terminal and `run.log`.
#[derive(Debug)]
pub struct Terminal {
    log: Option<Mutex<File>>,
    tty: bool,
    signals: Signals,
}

impl Terminal {
    /// Appends to `<output>/run.log` (created with the directory); without a writable output directory the
    /// messages still reach stderr.
    pub fn new(output: &Path, signals: Signals) -> Self {
        let log = std::fs::create_dir_all(output)
            .and_then(|()| std::fs::OpenOptions::new().create(true).append(true).open(output.join("run.log")))
            .ok()
            .map(Mutex::new);
        Self { log, tty: std::io::stderr().is_terminal(), signals }
    }

    /// Messages to stderr only (commands without an output directory).
    pub fn stderr_only() -> Self {
        Self { log: None, tty: std::io::stderr().is_terminal(), signals: Signals::default() }
    }

    fn log_line(&self, line: &str) {
        if let Some(log) = &self.log
            && let Ok(mut f) = log.lock()
        {
            let t = SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
            let _ = writeln!(f, "{t} {line}");
        }
    }
}

impl Reporter for Terminal {
    fn note(&self, stage: StageId, line: &str) {
        let line = format!("[{stage}] {line}");
        eprintln!("{line}");
        self.log_line(&line);
    }

    fn progress(&self, stage: StageId, what: &str, total: u64) -> Box<dyn optim::Progress + '_> {
        let bar = if self.tty { ProgressBar::new(total) } else { ProgressBar::hidden() };
        bar.set_length(total);
        let template = format!("[{stage}] {what} {{bar:40}} {{pos}}/{{len}} {{msg}} ({{elapsed}}, eta {{eta}})");
        bar.set_style(ProgressStyle::with_template(&template).unwrap_or_else(|_| ProgressStyle::default_bar()));
        Box::new(Step {
            owner: self,
            label: format!("[{stage}] {what}"),
            bar,
            started: Instant::now(),
            last_logged: Mutex::new(Instant::now()),
        })
    }

    fn stop_requested(&self) -> bool {
        self.signals.received().is_some()
    }
}

/// One long step: its bar and its periodic log lines.
struct Step<'a> {
    owner: &'a Terminal,
    label: String,
    bar: ProgressBar,
    started: Instant,
    last_logged: Mutex<Instant>,
}

impl Step<'_> {
    fn maybe_log(&self) {
        self.log_unless_recent(false);
    }

    /// Writes the position line when [`LOG_EVERY`] has passed since the last one, or at once with `now`.
    fn log_unless_recent(&self, now: bool) {
        let Ok(mut last) = self.last_logged.lock() else { return };
        if !now && last.elapsed() < LOG_EVERY {
            return;
        }
        *last = Instant::now();
        let mut line = format!(
            "{}: {}",
            self.label,
            position_line(self.bar.position(), self.bar.length(), self.started.elapsed())
        );
        let message = self.bar.message();
        if !message.is_empty() {
            line.push_str(&format!(" ({message})"));
        }
        if !self.owner.tty {
            eprintln!("{line}");
        }
        self.owner.log_line(&line);
    }
}

/// `pos/len, <eta> left` (or `pos/len` before the first step, when no rate is known).
fn position_line(pos: u64, len: Option<u64>, elapsed: Duration) -> String {
    let Some(len) = len else { return format!("{pos}") };
    if pos == 0 || pos >= len {
        return format!("{pos}/{len}");
    }
    let left = elapsed.as_secs_f64() / pos as f64 * (len - pos) as f64;
    format!("{pos}/{len}, {} left", human(left))
}

fn human(seconds: f64) -> String {
    let s = seconds.round() as u64;
    match s {
        0..60 => format!("{s}s"),
        60..3600 => format!("{}m{:02}s", s / 60, s % 60),
        _ => format!("{}h{:02}m", s / 3600, (s % 3600) / 60),
    }
}

impl optim::Progress for Step<'_> {
    fn set_length(&self, total: u64) {
        self.bar.set_length(total);
    }

    fn set_position(&self, position: u64) {
        self.bar.set_position(position);
        self.maybe_log();
    }

    fn inc(&self, delta: u64) {
        self.bar.inc(delta);
        self.maybe_log();
    }

    fn set_message(&self, message: &str) {
        // A new phase (its message's first word changes: "loss 0.0123" → "lobe test: …") is logged as it
        // starts, since it may run for minutes without a step (model selection's last renders); a message
        // that only updates a figure waits for the next periodic line.
        let phase = |m: &str| m.split_whitespace().next().unwrap_or("").to_owned();
        let new_phase = phase(&self.bar.message()) != phase(message);
        self.bar.set_message(message.to_owned());
        self.log_unless_recent(new_phase);
    }

    fn note(&self, line: &str) {
        self.bar.suspend(|| eprintln!("{line}"));
        self.owner.log_line(line);
    }

    fn stop_requested(&self) -> bool {
        self.owner.stop_requested()
    }
}

impl Drop for Step<'_> {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eta_is_the_remaining_steps_at_the_mean_rate() {
        assert_eq!(position_line(0, Some(10), Duration::from_secs(5)), "0/10");
        assert_eq!(position_line(2, Some(10), Duration::from_secs(10)), "2/10, 40s left");
        assert_eq!(position_line(37, Some(212), Duration::from_secs(37)), "37/212, 2m55s left");
        assert_eq!(position_line(1, Some(1000), Duration::from_secs(10)), "1/1000, 2h46m left");
        assert_eq!(position_line(10, Some(10), Duration::from_secs(10)), "10/10");
    }
}
