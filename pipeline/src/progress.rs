//! The terminal rendering of the optimiser's progress: an `indicatif` bar implementing [`optim::Progress`],
//! whose notes (the optimiser's decisions, one line each) are printed to stderr above the bar.

use indicatif::ProgressBar;

/// An `indicatif` progress bar as the optimiser's [`optim::Progress`].
#[derive(Debug, Clone)]
pub struct Bar(pub ProgressBar);

impl Bar {
    /// No bar drawn; notes are still printed.
    #[must_use]
    pub fn hidden() -> Self {
        Self(ProgressBar::hidden())
    }
}

impl optim::Progress for Bar {
    fn set_length(&self, total: u64) {
        self.0.set_length(total);
    }

    fn set_position(&self, position: u64) {
        self.0.set_position(position);
    }

    fn set_message(&self, message: &str) {
        self.0.set_message(message.to_owned());
    }

    fn note(&self, line: &str) {
        self.0.suspend(|| eprintln!("{line}"));
    }
}
