//! Renders a triangle scene with per-object (or per-triangle) Disney-style materials and emission, and
//! differentiates pixel estimates with respect to those parameters (Azinović et al. 2019, §3.3).
//!
//! The tracer does no file I/O: meshes, parameter tables and cameras come from the caller.

#[allow(unsafe_code)]
pub mod embree;
pub mod bsdf;
pub mod numerics;

/// The floating-point type of radiance, geometry and parameters inside the tracer.
pub type Float = f32;
