//! The optimisation that fits materials and emission to photos (paper §3–4): a differentiable path tracer
//! (`tracer`) inside closed-form solves and Adam.
//!
//! - [`fit`] — the per-object fit: one material and one emission per object, model selection on held-out
//!   pixels.
//! - [`triangle`] — the per-triangle fit with adaptive subdivision, started from the per-object result.
//! - [`photometric`] — the photos' tone-curve exponent measured against a fit's renders (linear light
//!   transport fixes what the photos alone leave open).
//! - [`subdivide`] — conforming adaptive subdivision of a triangle mesh (used by [`triangle`]).
//! - [`streams`] — every random-number stream and key space the optimiser draws from.
//! - [`progress`] — how progress and decisions leave the optimiser: the crate prints nothing; callers render
//!   [`Progress`] calls and `tracing` events as they like.

pub mod blocks;
pub mod fit;
pub mod photometric;
pub mod progress;
pub mod streams;
pub mod subdivide;
pub mod triangle;

pub use progress::{NoProgress, Progress};
