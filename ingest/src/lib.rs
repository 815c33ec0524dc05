//! Turns a scan directory into one in-memory scene: a triangle mesh with per-face object ids, cameras
//! (intrinsics + camera-to-world poses, one documented convention) and linear-radiance images with validity
//! masks. No optimisation, no tracing.

pub mod camera;
