//! The scene description a synthetic scan is generated from (TOML, `deny_unknown_fields`).
//!
//! ```toml
//! house_id = "demo"           # file stem of the Matterport files
//! width = 96                  # image size in pixels
//! height = 72
//! fov_y_deg = 60.0            # vertical field of view of every camera
//! spp = 1024                  # paths per pixel of the rendered photos
//! seed = 1
//! max_depth = 8               # tracer settings used to render the photos
//! rr_depth = 4
//! emission_profile = "uniform"
//!
//! [[objects]]                 # one object = one segment (segment_id = id)
//! id = 1
//! label = "floor"
//! category_id = 2             # mpcat40 row (28 = lighting)
//! shape = { quad = { corner = [0, 0, 0], u = [4, 0, 0], v = [0, 3, 0] } }   # front face = u × v
//! # or  shape = { box = { min = [..], max = [..] } }                        # outward-facing faces
//! subdivisions = 4            # each quad face is an n×n grid of quads (2 triangles each)
//! base_color = [0.6, 0.6, 0.6]
//! roughness = 0.5
//! metallic = 0.0
//! specular = 0.0
//! emission = [0, 0, 0]
//! hidden = false              # true: generation fails if any camera pixel sees this object
//!
//! [[cameras]]
//! eye = [1, 1, 1.5]
//! target = [3, 2, 1]
//! up = [0, 0, 1]
//! ```

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// A whole synthetic scan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    pub house_id: String,
    pub width: u32,
    pub height: u32,
    pub fov_y_deg: f32,
    pub spp: u32,
    pub seed: u64,
    pub max_depth: u32,
    pub rr_depth: u32,
    #[serde(default)]
    pub emission_profile: tracer::EmissionProfile,
    pub objects: Vec<ObjectSpec>,
    pub cameras: Vec<CameraSpec>,
}

/// Geometry of one object.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub enum Shape {
    /// Parallelogram `corner + s·u + t·v`, s, t ∈ [0, 1]; its front face (the emitting side) is `u × v`.
    Quad { corner: [f32; 3], u: [f32; 3], v: [f32; 3] },
    /// Axis-aligned box, six outward-facing faces.
    Box { min: [f32; 3], max: [f32; 3] },
}

/// One object (one segment) with its true material and emission.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    pub id: i32,
    pub label: String,
    #[serde(default)]
    pub category_id: i32,
    pub shape: Shape,
    #[serde(default = "one")]
    pub subdivisions: u32,
    pub base_color: [f32; 3],
    #[serde(default = "half")]
    pub roughness: f32,
    #[serde(default)]
    pub metallic: f32,
    #[serde(default)]
    pub specular: f32,
    #[serde(default)]
    pub emission: [f32; 3],
    #[serde(default)]
    pub hidden: bool,
}

fn one() -> u32 {
    1
}

fn half() -> f32 {
    0.5
}

/// A look-at camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    pub eye: [f32; 3],
    pub target: [f32; 3],
    #[serde(default = "z_up")]
    pub up: [f32; 3],
}

fn z_up() -> [f32; 3] {
    [0.0, 0.0, 1.0]
}

impl ObjectSpec {
    /// The true material of the object.
    #[must_use]
    pub fn material(&self) -> tracer::bsdf::Material {
        tracer::bsdf::Material {
            base_color: Vec3::from(self.base_color),
            roughness: self.roughness,
            metallic: self.metallic,
            specular: self.specular,
        }
    }
}
