//! Renders a triangle scene with per-object (or per-triangle) Disney-style materials and emission, and
//! differentiates pixel estimates with respect to those parameters (Azinović et al. 2019, §3.3).
//!
//! The tracer does no file I/O: meshes, parameter tables and cameras come from the caller.
//!
//! # Use
//!
//! ```text
//! let scene = Scene::new(SceneInput { positions, triangles, normals, material_of_tri, emitter_of_tri })?;
//! let renderer = Renderer::new(&scene, &params, &settings)?;          // once per optimiser iteration
//! let (values, _) = renderer.render_pixels(&cameras, &batch, n_value, seed, it)?;
//! let weights = /* dLoss/dI per pixel, e.g. sign(values − target) / B for L1 */;
//! let (grads, _) = renderer.gradient_pixels(&cameras, &batch, &weights, n_grad, seed, it)?;
//! ```
//! `grads` is shaped like `params` and holds ∂(Σ_j w_j·I_j)/∂θ; the value and gradient estimates use
//! independent random streams, so their product in Eq. 4 is unbiased.
//!
//! # Conventions
//!
//! - Front face of triangle (v0, v1, v2): the side of (v1 − v0) × (v2 − v0). Emission is one-sided (front
//!   only); reflection is two-sided (the shading frame is flipped to the viewer's side).
//! - Shading normals interpolate the vertex normals when given; geometric normals decide visibility, the
//!   emitting side and ray offsets ([`numerics::offset_ray_origin`]).
//! - Camera: pinhole looking down −z, +y up, pixel centres at integer coordinates ([`Camera`]).
//! - Depth: `max_depth` counts scattering events (pbrt's convention; Mitsuba's `max_depth` is ours + 1).
//! - Determinism: every random number is a hash of (seed, stream, iteration, view, pixel, sample, dimension)
//!   ([`rng`]); results are bit-identical for any number of rayon threads.
//!
//! # Modules
//!
//! [`scene`] geometry and per-triangle data · [`params`] parameter tables, settings, gradient tables ·
//! [`camera`] · [`lights`] light selection ∝ emitted power · `integrator` path tracing with NEE + MIS and the
//! adjoint path derivative · [`batch`] parallel entry points · [`bsdf`] the BRDF · [`embree`] the FFI ·
//! [`numerics`] robust helpers · [`rng`] counter-based sampler.

pub mod batch;
pub mod bsdf;
pub mod camera;
#[allow(unsafe_code)]
pub mod embree;
pub mod error;
mod integrator;
pub mod lights;
pub mod numerics;
pub mod params;
pub mod rng;
pub mod scene;

pub use batch::{
    MAX_DEPTH_LIMIT, PixelRef, Renderer, SparseGrads, TraceStats, gradient_pixels, render_image, render_pixels,
    total_trace_stats,
};
pub use bsdf::{Material, MaterialAt, MaterialGrad};
pub use camera::Camera;
pub use error::TracerError;
pub use lights::LightSampler;
pub use params::{EmissionProfile, Grads, MaterialGradSum, Params, TracerSettings};
pub use scene::{HorizonGeometry, Scene, SceneInput};

/// The floating-point type of radiance, geometry and parameters inside the tracer.
pub type Float = f32;
