//! The benchmark scenes: a synthetic scene description with its photos (read from a committed scan when one
//! exists, else rendered in memory exactly as `lab synth` would write them) and its ground truth.

use std::path::{Path, PathBuf};

use ingest::photo::LinearImage;

use super::BenchError;
use crate::synth::BuiltScene;

/// One benchmark scene.
#[derive(Debug)]
pub struct BenchScene {
    /// Short name (`demo`, `glossy`, ...): the description file's stem.
    pub name: String,
    pub built: BuiltScene,
    /// One photo per camera of `built`, full resolution, all pixels valid.
    pub photos: Vec<LinearImage>,
    /// For a scene with textured (checker) objects, whose photos come from a finer mesh than the scan's: the
    /// scan mesh with one material and emitter slot per object, what the fits see (`None`: `built.scene` is
    /// already that).
    pub scan_scene: Option<tracer::Scene>,
}

impl BenchScene {
    /// A bench scene from a built description and its photos.
    pub fn new(name: &str, built: BuiltScene, photos: Vec<LinearImage>) -> Result<Self, BenchError> {
        let scan_scene = if built.desc.objects.iter().any(|o| o.checker.is_some()) {
            let m = &built.mesh;
            Some(tracer::Scene::new(tracer::SceneInput {
                positions: m.positions.clone(),
                triangles: m.triangles.clone(),
                normals: Some(m.normals.clone()),
                material_of_tri: m.object_of_tri.clone(),
                emitter_of_tri: m.object_of_tri.clone(),
            })?)
        } else {
            None
        };
        Ok(Self { name: name.to_owned(), built, photos, scan_scene })
    }

    /// The scene the fits run on: the scan mesh, one slot per object.
    #[must_use]
    pub fn fit_scene(&self) -> &tracer::Scene {
        self.scan_scene.as_ref().unwrap_or(&self.built.scene)
    }

    /// Description indices of the objects with a checker albedo.
    #[must_use]
    pub fn textured_objects(&self) -> Vec<usize> {
        (0..self.built.desc.objects.len()).filter(|&k| self.built.desc.objects[k].checker.is_some()).collect()
    }
}

/// Where the scene descriptions and the committed scans live: `<workspace>/data-fixtures`.
#[must_use]
pub fn fixtures_dir(workspace: &Path) -> PathBuf {
    workspace.join("data-fixtures")
}

/// Loads scene `name` from `data-fixtures/scenes/<name>.toml`; the photos come from `data-fixtures/<name>/`
/// when that scan exists (the committed default scene), else they are rendered from the description.
pub fn load(workspace: &Path, name: &str) -> Result<BenchScene, BenchError> {
    let fixtures = fixtures_dir(workspace);
    let desc_path = fixtures.join("scenes").join(format!("{name}.toml"));
    let built = crate::synth::build(crate::synth::load_desc(&desc_path)?, &desc_path)?;
    let scan = fixtures.join(name).join("undistorted_color_images");
    let photos = if scan.is_dir() {
        (0..built.cameras.len())
            .map(|k| {
                let file = crate::synth::matterport::image_names(&built.desc, k).0;
                read_exr(&scan.join(file))
            })
            .collect::<Result<Vec<_>, _>>()?
    } else {
        crate::synth::photos(&built)?
    };
    for (k, (p, c)) in photos.iter().zip(&built.cameras).enumerate() {
        if p.width != c.width || p.height != c.height {
            return Err(BenchError::Scene {
                scene: name.to_owned(),
                message: format!("photo {k} is {}x{}, its camera {}x{}", p.width, p.height, c.width, c.height),
            });
        }
    }
    BenchScene::new(name, built, photos)
}

/// Reads a linear EXR (the synthetic scans' photos) through ingest's photo reader.
pub fn read_exr(path: &Path) -> Result<LinearImage, BenchError> {
    match ingest::photo::read_image(path) {
        Ok(ingest::photo::DecodedImage::Linear(img)) => Ok(img),
        Ok(ingest::photo::DecodedImage::Display(_)) => {
            Err(BenchError::Io { path: path.to_path_buf(), message: "not a linear (EXR/HDR) image".into() })
        }
        Err(e) => Err(BenchError::Io { path: path.to_path_buf(), message: e.to_string() }),
    }
}

/// The camera of the same view at `1/factor` resolution, matching [`downscale_image`] of its image (the
/// intrinsics rule is ingest's [`ingest::photo::downscale::scale_intrinsics`]).
#[must_use]
pub fn downscale_camera(c: &tracer::Camera, factor: u32) -> tracer::Camera {
    let k = ingest::photo::downscale::scale_intrinsics(
        &ingest::camera::Intrinsics {
            fx: f64::from(c.fx),
            fy: f64::from(c.fy),
            cx: f64::from(c.cx),
            cy: f64::from(c.cy),
        },
        factor,
    );
    tracer::Camera {
        width: c.width / factor,
        height: c.height / factor,
        fx: k.fx as f32,
        fy: k.fy as f32,
        cx: k.cx as f32,
        cy: k.cy as f32,
        cam_to_world: c.cam_to_world,
    }
}

/// Box-filter downscale of an image by an integer factor (ingest's area average; the bench only uses factors
/// that divide the size, see [`divisible`]).
pub fn downscale_image(img: &LinearImage, factor: u32) -> Result<LinearImage, BenchError> {
    ingest::photo::downscale::downscale_image(img, factor)
        .map_err(|e| BenchError::Other(format!("downscale by {factor}: {e}")))
}

/// Whether every camera's size is divisible by `factor`.
#[must_use]
pub fn divisible(scene: &BenchScene, factor: u32) -> bool {
    factor >= 1 && scene.built.cameras.iter().all(|c| c.width % factor == 0 && c.height % factor == 0)
}
