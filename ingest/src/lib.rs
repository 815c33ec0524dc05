//! Turns a scan directory into one in-memory scene: a triangle mesh with per-face object ids, cameras
//! (intrinsics + camera-to-world poses, one documented convention) and linear-radiance images with validity
//! masks. No optimisation, no tracing.

pub mod atomic;
pub mod camera;
pub mod colmap;
pub mod error;
pub mod image_header;
pub mod listing;
pub mod matterport;
pub mod mesh;
pub mod obj;
pub mod photo;
pub mod ply;
pub mod pose;
pub mod scan;
pub mod srgb;
pub mod transforms;

pub use atomic::write_atomic;
pub use camera::View;
pub use error::IngestError;
pub use mesh::Mesh;
pub use scan::{GroupBy, ObjectInfo, Removed, Scan, ScanFormat, load_scan, objects_seen_by_no_camera};
