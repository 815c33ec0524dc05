//! The path samples a fit traced and the ones the tracer discarded: a sample whose estimate is
//! not finite contributes nothing and is counted (`tracer::TraceStats::discarded`, see `tracer::batch`);
//! the fit sums both counts over every tracer call, reports them and fails when too many were discarded.

use std::sync::atomic::{AtomicU64, Ordering};

/// Largest accepted fraction of a fit's path samples that were discarded. Discards come from f32 overflow at
/// extreme inputs; each one replaces a sample by zero and so darkens its pixel's estimate. At ≤ 1e-4, a pixel
/// estimated with up to 1024 paths loses a sample with probability ≤ 0.1 when discards are spread over the
/// fit, so the fitted values are those of the unbiased estimator for at least 9 pixels in 10; a larger
/// fraction means something systematic (a whole object or view overflowing), and the result would be
/// silently biased, so the fit fails instead.
pub const MAX_DISCARDED_FRACTION: f64 = 1e-4;

/// Path samples traced and discarded by the tracer calls of one fit. Atomic because the Jacobians call the
/// tracer from rayon tasks; the totals are integer sums, so they do not depend on the order of the calls.
#[derive(Debug, Default)]
pub struct SampleCounter {
    paths: AtomicU64,
    discarded: AtomicU64,
}

impl SampleCounter {
    /// A counter that starts from earlier totals (a resumed fit continues its checkpoint's counts).
    #[must_use]
    pub fn starting_at(paths: u64, discarded: u64) -> Self {
        SampleCounter { paths: AtomicU64::new(paths), discarded: AtomicU64::new(discarded) }
    }

    /// Adds one tracer call's work.
    pub fn add(&self, stats: &tracer::TraceStats) {
        self.paths.fetch_add(stats.paths, Ordering::Relaxed);
        self.discarded.fetch_add(stats.discarded, Ordering::Relaxed);
    }

    /// Path samples traced so far, discarded ones included.
    #[must_use]
    pub fn paths(&self) -> u64 {
        self.paths.load(Ordering::Relaxed)
    }

    /// Path samples discarded so far.
    #[must_use]
    pub fn discarded(&self) -> u64 {
        self.discarded.load(Ordering::Relaxed)
    }
}

/// Whether `discarded` of `paths` samples is within [`MAX_DISCARDED_FRACTION`].
#[must_use]
pub fn within_bound(discarded: u64, paths: u64) -> bool {
    // Compared in f64: exact for counts below 2^53, far beyond any fit.
    discarded as f64 <= MAX_DISCARDED_FRACTION * paths as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bound_is_one_in_ten_thousand_inclusive() {
        assert!(within_bound(0, 0));
        assert!(within_bound(0, 1));
        assert!(!within_bound(1, 9_999));
        assert!(within_bound(1, 10_000));
        assert!(within_bound(100, 1_000_000));
        assert!(!within_bound(101, 1_000_000));
    }

    #[test]
    fn the_error_names_both_counts_and_the_bound() {
        let e = crate::fit::FitError::TooManyDiscarded { discarded: 12, paths: 34_567 };
        let text = e.to_string();
        assert!(text.contains("discarded 12 of 34567 path samples") && text.contains("1e-4"), "{text}");
    }

    #[test]
    fn the_counter_sums_calls_from_any_thread_and_resumes_from_a_checkpoint() {
        use rayon::prelude::*;
        let c = SampleCounter::starting_at(10, 1);
        (0..1000u64).into_par_iter().for_each(|i| {
            c.add(&tracer::TraceStats { paths: i, discarded: i % 2, ..Default::default() });
        });
        assert_eq!(c.paths(), 10 + 999 * 1000 / 2);
        assert_eq!(c.discarded(), 1 + 500);
    }
}
