//! The tracer's error type: bad input from the caller, with enough context to find it.

use crate::embree::EmbreeError;

#[derive(Debug, thiserror::Error)]
pub enum TracerError {
    #[error(transparent)]
    Embree(#[from] EmbreeError),
    #[error("{what} has {got} entries but the mesh needs {expected}")]
    LengthMismatch { what: &'static str, expected: usize, got: usize },
    #[error("vertex {vertex} has a non-finite {what}: {value}")]
    NonFinite { what: &'static str, vertex: usize, value: glam::Vec3 },
    #[error("triangle {tri} uses {what} {index} but the parameter table has {len} entries")]
    ParamIndex { what: &'static str, tri: usize, index: u32, len: usize },
    #[error("pixel {index} (view {view}, x {x}, y {y}) is outside its view or the view does not exist")]
    BadPixel { index: usize, view: u32, x: u32, y: u32 },
    #[error("{what} must be {requirement}, got {value}")]
    BadSetting { what: &'static str, requirement: &'static str, value: String },
}
