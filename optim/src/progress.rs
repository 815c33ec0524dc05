//! Progress and decisions reported by the optimiser. The crate prints nothing: a long run reports its
//! position through [`Progress`], whose implementation (a terminal progress bar, a log, nothing) is the
//! caller's choice, and the decisions a user reads (a light kept or changed, a round's summary) through
//! [`Progress::note`] as one line each. The same facts also go out as structured `tracing` events.

/// Receives a run's progress: its length and position (rounds or iterations), a short status message, and
/// one-line notes of decisions. Every method defaults to doing nothing.
pub trait Progress: Sync {
    /// The run has `total` steps.
    fn set_length(&self, total: u64) {
        let _ = total;
    }
    /// `position` steps are done.
    fn set_position(&self, position: u64) {
        let _ = position;
    }
    /// `delta` more steps are done (for steps that finish in parallel, out of order).
    fn inc(&self, delta: u64) {
        let _ = delta;
    }
    /// A new phase of the run begins: `name` says what it does and what it counts (e.g. "emission test:
    /// emitter"), it has `total` steps of which `done` are already done (a resumed run). Positions from here
    /// on count within the phase, and an ETA is the phase's own: the phases of a fit cost very different
    /// times per step (an Adam iteration, a model-selection render of every held-out pixel), so a rate
    /// measured on one says nothing about the next. By default the phase's name becomes the message.
    fn phase(&self, name: &str, total: u64, done: u64) {
        self.set_message(name);
        self.set_length(total);
        self.set_position(done);
    }
    /// A short status of the current step (e.g. its loss).
    fn set_message(&self, message: &str) {
        let _ = message;
    }
    /// A decision or summary the user reads, one line.
    fn note(&self, line: &str) {
        let _ = line;
    }
    /// True once the caller wants the run to stop (e.g. on SIGINT). A fit asks at every step boundary, hands
    /// out a checkpoint of the last finished step and returns its `Interrupted` error.
    fn stop_requested(&self) -> bool {
        false
    }
}

/// A long phase that stopped between two of its steps because [`Progress::stop_requested`] said so: its
/// unfinished work is dropped, and the stage's last checkpoint is where a rerun resumes. Checked at every step
/// of a phase that may run for minutes (a block of a render, an object of a search, an emitter of a test), so
/// that a signal stops a house-sized run within seconds instead of at the end of a round.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("stopped on request")]
pub struct Stopped;

/// `Err(Stopped)` once the caller wants the run to stop.
pub fn check_stop(progress: &dyn Progress) -> Result<(), Stopped> {
    if progress.stop_requested() { Err(Stopped) } else { Ok(()) }
}

/// Reports nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;

impl Progress for NoProgress {}

/// Passes on only the stop requests of the progress it wraps: for the many short renders within one step of a
/// phase (an object's fits in the lobe family look), whose own phases would replace the caller's and its ETA.
#[derive(Clone, Copy)]
pub(crate) struct Muted<'a>(pub &'a dyn Progress);

impl Progress for Muted<'_> {
    fn stop_requested(&self) -> bool {
        self.0.stop_requested()
    }
}
