//! The binary's [`Reporter`]: stage messages and progress on the terminal and in the run log.
//!
//! - Messages (`[stage] line`) go to stderr and, with a timestamp, to `<output>/run.log`.
//! - Progress is an `indicatif` bar with an ETA when stderr is a terminal. Every [`LOG_EVERY`] a line with
//!   the phase, the position and the ETA (`[object] fit: emission test: emitter 37/212, 1m12s left`) also
//!   goes to the run log, and to stderr when stderr is not a terminal (a redirected run still shows where it
//!   is and when it will end); a new phase, or a message with a new first word, writes that line at once.
//! - The ETA is the phase's own: its remaining steps at the rate of the steps it has done since it began
//!   (steps a resumed run had already done are not counted as fast ones), less the time the current step has
//!   already run (but never less than the steps after it): a line written in the middle of a long step (a
//!   per-triangle round of a minute) counts down instead of growing.

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
        let template =
            format!("[{stage}] {what}{{prefix}} {{bar:40}} {{pos}}/{{len}} {{msg}} ({{elapsed}}, eta {{eta}})");
        bar.set_style(ProgressStyle::with_template(&template).unwrap_or_else(|_| ProgressStyle::default_bar()));
        Box::new(Step {
            owner: self,
            label: format!("[{stage}] {what}"),
            bar,
            phase: Mutex::new(Phase::new(String::new(), 0)),
            last_logged: Mutex::new(Instant::now()),
        })
    }

    fn stop_requested(&self) -> bool {
        self.signals.received().is_some()
    }
}

/// One long step: its bar, its current phase and its periodic log lines.
struct Step<'a> {
    owner: &'a Terminal,
    label: String,
    bar: ProgressBar,
    phase: Mutex<Phase>,
    last_logged: Mutex<Instant>,
}

/// The phase the positions count in: its name (empty before the first), when it began, how many of its
/// steps were already done then, and when its position last moved forward (and to where).
struct Phase {
    name: String,
    started: Instant,
    done_at_start: u64,
    last_step: Instant,
    last_position: u64,
}

impl Phase {
    fn new(name: String, done: u64) -> Self {
        let now = Instant::now();
        Self { name, started: now, done_at_start: done, last_step: now, last_position: done }
    }

    /// Notes the position reached; a step forward restarts the clock of the current step.
    fn reached(&mut self, position: u64) {
        if position > self.last_position {
            self.last_position = position;
            self.last_step = Instant::now();
        }
    }
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
        let Ok(phase) = self.phase.lock() else { return };
        let position = position_line(
            phase.last_position,
            self.bar.length(),
            phase.done_at_start,
            phase.last_step.duration_since(phase.started),
            phase.last_step.elapsed(),
        );
        let mut line = if phase.name.is_empty() {
            format!("{}: {position}", self.label)
        } else {
            format!("{}: {} {position}", self.label, phase.name)
        };
        drop(phase);
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

/// `pos/len, <eta> left`: the `len - pos` remaining steps at the rate of the `pos - done_at_start` steps
/// done in `elapsed`, less the `since_step` the current step has run, but at least the steps after it (just
/// `pos/len` before the phase's first step, when no rate is known).
fn position_line(pos: u64, len: Option<u64>, done_at_start: u64, elapsed: Duration, since_step: Duration) -> String {
    let Some(len) = len else { return format!("{pos}") };
    if pos <= done_at_start || pos >= len {
        return format!("{pos}/{len}");
    }
    let per_step = elapsed.as_secs_f64() / (pos - done_at_start) as f64;
    let left = (per_step * (len - pos) as f64 - since_step.as_secs_f64()).max(per_step * (len - pos - 1) as f64);
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
    fn phase(&self, name: &str, total: u64, done: u64) {
        if let Ok(mut phase) = self.phase.lock() {
            *phase = Phase::new(name.to_owned(), done);
        }
        self.bar.set_prefix(format!(": {name}"));
        self.bar.set_message(String::new());
        self.bar.set_length(total);
        self.bar.set_position(done);
        self.bar.reset_eta();
        self.log_unless_recent(true);
    }

    fn set_length(&self, total: u64) {
        self.bar.set_length(total);
    }

    fn set_position(&self, position: u64) {
        self.bar.set_position(position);
        if let Ok(mut phase) = self.phase.lock() {
            phase.reached(position);
        }
        self.maybe_log();
    }

    fn inc(&self, delta: u64) {
        self.bar.inc(delta);
        if let Ok(mut phase) = self.phase.lock() {
            phase.reached(self.bar.position());
        }
        self.maybe_log();
    }

    fn set_message(&self, message: &str) {
        // A message that changes what the step is doing (its first word changes: "loss 0.0999" → "round 3:
        // light step …") is logged as it starts, since it may run for minutes without a step; a message that
        // only updates a figure ("round 3: ratio step 2/3" → "… 3/3"), or the first message of a phase (whose
        // start was just logged), waits for the next periodic line.
        let first_word = |m: &str| m.split_whitespace().next().unwrap_or("").to_owned();
        let previous = self.bar.message();
        let new_phase = !previous.is_empty() && first_word(&previous) != first_word(message);
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
        assert_eq!(position_line(0, Some(10), 0, Duration::from_secs(5), Duration::ZERO), "0/10");
        assert_eq!(position_line(2, Some(10), 0, Duration::from_secs(10), Duration::ZERO), "2/10, 40s left");
        assert_eq!(position_line(37, Some(212), 0, Duration::from_secs(37), Duration::ZERO), "37/212, 2m55s left");
        assert_eq!(position_line(1, Some(1000), 0, Duration::from_secs(10), Duration::ZERO), "1/1000, 2h46m left");
        assert_eq!(position_line(10, Some(10), 0, Duration::from_secs(10), Duration::ZERO), "10/10");
    }

    #[test]
    fn eta_counts_only_the_steps_done_since_the_phase_began() {
        // A run resumed at step 40 of 100: the 40 were done before, so no rate is known yet, and after 5 more
        // steps in 50 s the 55 left take 550 s (a rate over all 45 would say 61 s).
        assert_eq!(position_line(40, Some(100), 40, Duration::from_secs(3), Duration::ZERO), "40/100");
        assert_eq!(position_line(45, Some(100), 40, Duration::from_secs(50), Duration::ZERO), "45/100, 9m10s left");
    }

    #[test]
    fn eta_counts_down_within_a_long_step_but_not_below_the_steps_after_it() {
        // Round 1 of 4 took 53 s: 159 s are left when it ends, 99 s a minute into round 2, and never less
        // than the 106 s of rounds 3 and 4.
        let eta = |since| position_line(1, Some(4), 0, Duration::from_secs(53), Duration::from_secs(since));
        assert_eq!(eta(0), "1/4, 2m39s left");
        assert_eq!(eta(20), "1/4, 2m19s left");
        assert_eq!(eta(60), "1/4, 1m46s left");
        assert_eq!(eta(600), "1/4, 1m46s left");
    }

    #[test]
    fn a_phase_restarts_the_position_and_the_rate_and_names_itself_in_the_log() {
        let dir = std::env::temp_dir().join(format!("ipt-terminal-phase-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let terminal = Terminal::new(&dir, Signals::default());
        {
            let step = terminal.progress(StageId::Object, "fit", 10);
            step.set_position(7);
            step.phase("emission test: emitter", 26, 0);
            step.set_position(1);
        }
        let log = std::fs::read_to_string(dir.join("run.log")).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        // The phase's first line is written at once, at its own position 0 of its own length.
        assert!(log.contains("[object] fit: emission test: emitter 0/26"), "{log}");
        assert!(!log.contains("/10"), "{log}");
    }
}
