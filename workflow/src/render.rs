//! `pipeline render RUN_DIR --cameras CAMERAS.conf --output DIR [--spp N] [--materials FILE]`: renders the
//! ingested scene of a run with the materials of `RUN_DIR/materials.json` (or FILE, same schema) from every
//! `scan` line of a Matterport-style `.conf`, writing `DIR/<color file stem>.exr` (linear radiance, RGB).
//! Works as soon as `ingest` has run (with `--materials` before the fit has).
//!
//! The `.conf` is read by ingest's Matterport reader (`ingest::matterport::read_conf`: `intrinsics_matrix`
//! applies to the following `scan` lines; camera-to-world, OpenGL camera). The listed
//! colour images need not exist (novel views): the image size comes from `--width/--height`, else from the
//! listed image when it exists (under `color_directory`, relative to the directory above the `.conf`'s, as in
//! the Matterport layout, or beside the `.conf`), else it is an error naming the line.

use std::path::{Path, PathBuf};

use glam::Affine3A;

use crate::artefacts::ingest::Ingested;
use crate::atomic_file::write_atomic;
use crate::materials::MaterialsFile;

/// Errors of `pipeline render`.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("{path}: {source}", path = .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}:{line}: {message}", path = .path.display())]
    Conf { path: PathBuf, line: usize, message: String },
    #[error(transparent)]
    Scan(ingest::IngestError),
    #[error("{0}")]
    Stage(#[from] crate::stage_contract::StageError),
    #[error(transparent)]
    Materials(#[from] crate::materials::MaterialsError),
    #[error("tracer: {0}")]
    Tracer(#[from] tracer::TracerError),
    #[error("{path}: cannot write EXR: {message}", path = .path.display())]
    Exr { path: PathBuf, message: String },
    #[error(transparent)]
    Write(#[from] crate::atomic_file::AtomicWriteError),
}

/// What `pipeline render` renders, and where to.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderRequest {
    /// A run directory whose `ingest` stage finished.
    pub run_dir: PathBuf,
    /// A Matterport-style cameras file.
    pub cameras: PathBuf,
    /// Output directory: one `<color file stem>.exr` per camera.
    pub output: PathBuf,
    /// Paths per pixel.
    pub spp: u32,
    /// Materials in the `ipt-materials/1` schema (default: `run_dir/materials.json`).
    pub materials: Option<PathBuf>,
    /// Largest number of scattering events of a path.
    pub max_depth: u32,
    /// Image width and height for every camera (default: the size of each listed colour image).
    pub size: Option<(u32, u32)>,
    /// Seed of the renderer's random numbers.
    pub seed: u64,
}

/// One camera of a `.conf`.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfCamera {
    /// Output name: the colour file's stem.
    pub name: String,
    pub camera: tracer::Camera,
}

fn image_size(path: &Path) -> Option<(u32, u32)> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        let meta = exr::meta::MetaData::read_from_file(path, false).ok()?;
        let size = meta.headers.first()?.layer_size;
        return Some((u32::try_from(size.0).ok()?, u32::try_from(size.1).ok()?));
    }
    image::image_dimensions(path).ok()
}

/// Reads a Matterport-style `.conf` with ingest's reader ([`ingest::matterport::read_conf`]) and gives each
/// `scan` line an image size: `size` when given, else the listed colour image's. Errors name the line.
pub fn parse_conf(path: &Path, size: Option<(u32, u32)>) -> Result<Vec<ConfCamera>, RenderError> {
    let conf = ingest::matterport::read_conf(path).map_err(|e| match e {
        ingest::IngestError::Line { path, line, message } => RenderError::Conf { path, line, message },
        other => RenderError::Scan(other),
    })?;
    let conf_dir = path.parent().unwrap_or(Path::new("."));
    let scan_dir = conf_dir.parent().unwrap_or(conf_dir);
    let mut out = Vec::with_capacity(conf.scans.len());
    for s in &conf.scans {
        let err = |message: String| RenderError::Conf { path: path.to_path_buf(), line: s.line, message };
        let color_dir = PathBuf::from(s.color_directory.as_deref().unwrap_or("undistorted_color_images"));
        let listed = Path::new(&s.color_file);
        let name = listed.file_stem().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let (width, height) = match size {
            Some(sz) => sz,
            None => [scan_dir.join(&color_dir).join(listed), conf_dir.join(listed)]
                .iter()
                .find_map(|p| image_size(p))
                .ok_or_else(|| {
                    err(format!("image {} not found: give the size with --width and --height", listed.display()))
                })?,
        };
        let k = s.intrinsics;
        let camera = tracer::Camera {
            width,
            height,
            fx: k.fx as f32,
            fy: k.fy as f32,
            cx: k.cx as f32,
            cy: k.cy as f32,
            cam_to_world: Affine3A::from_mat4(s.cam_to_world.as_mat4()),
        };
        out.push(ConfCamera { name, camera });
    }
    Ok(out)
}

/// Linear RGB EXR bytes (32-bit float R, G, B; lossless).
pub fn encode_rgb_exr(path: &Path, width: u32, height: u32, rgb: &[glam::Vec3]) -> Result<Vec<u8>, RenderError> {
    let w = width as usize;
    ingest::photo::exr::encode_rgb(width, height, ingest::photo::exr::Compression::Fast, |x, y| {
        rgb[y * w + x].to_array()
    })
    .map_err(|e| RenderError::Exr { path: path.to_path_buf(), message: e.to_string() })
}

/// Renders every camera of `args.cameras`; returns how many views it wrote.
pub fn render(args: &RenderRequest, progress: &dyn optim::Progress) -> Result<usize, RenderError> {
    let scene_data = Ingested::read(&args.run_dir)?;
    let materials_path = args.materials.clone().unwrap_or_else(|| args.run_dir.join("materials.json"));
    let materials = MaterialsFile::read(&materials_path)?;
    let ids: Vec<i64> = scene_data.objects.iter().map(|o| o.id).collect();
    let params = materials.params_for(&ids, &materials_path)?;
    let cameras = parse_conf(&args.cameras, args.size)?;
    let scene = tracer::Scene::new(scene_data.scene_input())?;
    let settings = tracer::TracerSettings {
        max_depth: args.max_depth,
        emission_profile: materials.emission_profile,
        ..tracer::TracerSettings::default()
    };
    std::fs::create_dir_all(&args.output).map_err(|source| RenderError::Io { path: args.output.clone(), source })?;
    progress.set_length(cameras.len() as u64);
    for c in &cameras {
        let img = tracer::render_image(&scene, &params, &c.camera, args.spp, &settings, args.seed, 0)?;
        let path = args.output.join(format!("{}.exr", c.name));
        write_atomic(&path, &encode_rgb_exr(&path, c.camera.width, c.camera.height, &img)?)?;
        progress.inc(1);
    }
    Ok(cameras.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conf_intrinsics_are_stateful_and_poses_row_major() {
        let dir = tempfile::tempdir().unwrap();
        let conf = dir.path().join("c.conf");
        std::fs::write(
            &conf,
            "dataset matterport\nn_images 2\nintrinsics_matrix 100 0 31.5 0 110 23.5 0 0 1\n\
             scan d0.png a_i0_0.jpg 1 0 0 5  0 1 0 6  0 0 1 7  0 0 0 1\n\
             intrinsics_matrix 50 0 15.5 0 50 11.5 0 0 1\n\
             scan d1.png b_i1_2.jpg 0 -1 0 0  1 0 0 0  0 0 1 0  0 0 0 1\n",
        )
        .unwrap();
        let cams = parse_conf(&conf, Some((64, 48))).unwrap();
        assert_eq!(cams.len(), 2);
        assert_eq!(cams[0].name, "a_i0_0");
        assert_eq!((cams[0].camera.fx, cams[0].camera.fy, cams[0].camera.cx), (100.0, 110.0, 31.5));
        assert_eq!(cams[0].camera.cam_to_world.translation, glam::Vec3A::new(5.0, 6.0, 7.0));
        assert_eq!(cams[1].camera.fx, 50.0);
        // Row-major: the camera's x axis (first column) is world +y.
        let x_axis = cams[1].camera.cam_to_world.transform_vector3(glam::Vec3::X);
        assert!((x_axis - glam::Vec3::Y).length() < 1e-6, "{x_axis}");
    }

    #[test]
    fn conf_errors_name_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let conf = dir.path().join("c.conf");
        std::fs::write(&conf, "scan d.png a.jpg 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n").unwrap();
        let e = parse_conf(&conf, Some((4, 4))).unwrap_err();
        assert!(matches!(e, RenderError::Conf { line: 1, .. }), "{e}");
        std::fs::write(
            &conf,
            "intrinsics_matrix 1 0 1 0 1 1 0 0 1\nscan d.png missing.jpg 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n",
        )
        .unwrap();
        let e = parse_conf(&conf, None).unwrap_err();
        assert!(e.to_string().contains(":2:") && e.to_string().contains("--width"), "{e}");
    }

    #[test]
    fn exr_round_trips_linear_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.exr");
        let rgb = vec![glam::Vec3::new(0.0, 1.5, 100.0), glam::Vec3::new(1e-4, 2.0, 3.0)];
        std::fs::write(&path, encode_rgb_exr(&path, 2, 1, &rgb).unwrap()).unwrap();
        let img = exr::prelude::read_first_rgba_layer_from_file(
            &path,
            |res, _| vec![[0f32; 3]; res.width() * res.height()],
            |px: &mut Vec<[f32; 3]>, pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * 2 + pos.x()] = [r, g, b],
        )
        .unwrap();
        assert_eq!(img.layer_data.channel_data.pixels, vec![[0.0, 1.5, 100.0], [1e-4, 2.0, 3.0]]);
    }
}
