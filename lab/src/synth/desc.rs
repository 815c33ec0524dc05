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
//! emission_ground = [0, 0, 0] # optional: split at the horizon (up = +z), the radiance towards directions
//!                             # that point up; `emission` is then the one towards those pointing down or level
//! hidden = false              # true: generation fails if any camera pixel sees this object
//! checker = { squares = 4, colors = [[0.8, 0.8, 0.8], [0.1, 0.1, 0.1]] }   # optional, quads only
//!
//! [[cameras]]
//! eye = [1, 1, 1.5]
//! target = [3, 2, 1]
//! up = [0, 0, 1]
//!
//! [camera_pipeline]          # optional: photos written as consumer-camera JPEGs (see camera_pipeline.rs)
//! exposure = [0.5, 2.0]       # per-photo exposure gain, log-uniform in this range
//! white_balance = 0.12        # per-photo, per-channel factor uniform in [1 − x, 1 + x]
//! vignetting_corner = [0.6, 0.62, 0.58]   # one per physical camera: photo k is taken by camera k % n
//! tone_curve = "filmic"       # display curve applied after gain and vignetting
//! jpeg_quality = 90
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
    /// When present, every photo goes through a consumer camera pipeline and is written as JPEG only.
    #[serde(default)]
    pub camera_pipeline: Option<CameraPipelineSpec>,
}

/// `[camera_pipeline]`: how each rendered linear photo becomes an 8-bit JPEG, as a consumer camera makes it.
/// The random draws are keyed by the description's `seed` and the photo index.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPipelineSpec {
    /// `[lo, hi]`, 0 < lo ≤ hi: the range of the per-photo exposure gain, drawn log-uniformly (auto exposure).
    pub exposure: [f64; 2],
    /// x ∈ [0, 1): each photo's per-channel white-balance factor is drawn uniformly in [1 − x, 1 + x].
    pub white_balance: f64,
    /// One entry per physical camera, each in (0, 1): the vignetting factor at the image corner (1 at the
    /// principal point). Photo k is taken by camera `k % vignetting_corner.len()`.
    pub vignetting_corner: Vec<f64>,
    /// The display curve applied to the gained, vignetted linear value (`"filmic"`).
    pub tone_curve: ToneCurveName,
    /// Quality of the `image` crate's JPEG encoder, 1–100.
    pub jpeg_quality: u8,
}

/// The tone curves [`CameraPipelineSpec::tone_curve`] names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ToneCurveName {
    /// Hable's filmic curve (Uncharted 2) followed by a display gamma of 1/2.2; not sRGB.
    Filmic,
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
    /// The emission split at the horizon (world up +z, `tracer::params::Horizon`): the radiance towards the
    /// directions that point up, as a window's from the ground outside; `emission` is then the one towards
    /// those that point down or level (the sky's). None: one radiance in every direction.
    #[serde(default)]
    pub emission_ground: Option<[f32; 3]>,
    #[serde(default)]
    pub hidden: bool,
    /// A checkerboard albedo (quads only): the photos are rendered from a finely tessellated copy of the quad
    /// whose triangles carry the square colours, while the scan mesh keeps only the `subdivisions` grid;
    /// `base_color` is then unused for rendering (the ground truth lists the mean of the two colours).
    #[serde(default)]
    pub checker: Option<Checker>,
}

/// `checker = { squares = N, colors = [[r, g, b], [r, g, b]] }`: N × N squares over the quad's (s, t) ∈ [0, 1]²,
/// square (i, j) (i along `u`, j along `v`) has colour `colors[(i + j) % 2]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Checker {
    pub squares: u32,
    pub colors: [[f32; 3]; 2],
}

impl Checker {
    /// The true albedo at quad parameters (s, t) ∈ [0, 1]².
    #[must_use]
    pub fn albedo_at(&self, s: f32, t: f32) -> [f32; 3] {
        let n = self.squares.max(1);
        let cell = |x: f32| ((x * n as f32).floor().max(0.0) as u32).min(n - 1);
        self.colors[((cell(s) + cell(t)) % 2) as usize]
    }
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
