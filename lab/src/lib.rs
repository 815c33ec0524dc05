//! Development tools over the product crates, never shipped in the `pipeline` binary: the synthetic-scan
//! generator ([`synth`]: scene descriptions → Matterport-layout scans with ground truth, rendered by our
//! tracer) and the benchmarks ([`bench`]: the speed/accuracy trade-off, path ablations, the Mitsuba
//! baseline), with the accuracy metrics ([`bench::metrics`]) that the end-to-end tests share.

pub mod bench;
pub mod synth;
