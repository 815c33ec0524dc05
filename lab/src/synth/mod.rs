//! Synthetic scans: a TOML scene description of quads and boxes with known materials, emission and look-at
//! cameras becomes a triangle mesh with per-face segment ids, photos rendered by our own tracer at high spp
//! (linear EXR), and the Matterport3D directory layout the `ingest` stage reads — plus the ground truth
//! (`ground_truth_materials.json`, schema `ipt-materials/1`) that tests compare a fit against.
//!
//! Output layout under `out_dir`:
//! ```text
//! house_segmentations/<id>.ply            mesh, face props material_id / segment_id / category_id
//! house_segmentations/<id>.semseg.json    segment groups with labels
//! house_segmentations/<id>.fsegs.json     over-segment id per face
//! undistorted_camera_parameters/<id>.conf intrinsics_matrix + scan lines
//! undistorted_color_images/<id>_i0_<k>.exr            (or <id>_i<c>_<k>.jpg with [camera_pipeline])
//! ground_truth_materials.json
//! ground_truth_camera.json                           (with [camera_pipeline] only)
//! ```
//! Deterministic: the same description gives byte-identical files (the tracer's random numbers are keyed
//! by seed, view, pixel and sample, EXR is written from the same floats, and the camera pipeline's draws are
//! keyed by seed and photo, see [`camera_pipeline`]).

pub mod camera_pipeline;
pub mod desc;
pub mod matterport;
pub mod mesh;

use desc::SceneDesc;
use glam::Vec3;
use mesh::SynthMesh;
use std::path::{Path, PathBuf};

/// Why a synthetic scan could not be generated.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{source}")]
    Write { path: PathBuf, source: ingest::IngestError },
    #[error("{path}: cannot encode JPEG: {message}")]
    Jpeg { path: PathBuf, message: String },
    #[error("{path}: bad scene description: {message}")]
    Desc { path: PathBuf, message: String },
    #[error("{path}: {message}")]
    Exr { path: PathBuf, message: String },
    #[error("rendering the synthetic photos: {0}")]
    Tracer(#[from] tracer::TracerError),
    #[error("{path}: camera {camera} sees object {object} (\"{label}\") which is marked hidden, in pixel ({x}, {y})")]
    HiddenSeen { path: PathBuf, camera: usize, object: i32, label: String, x: u32, y: u32 },
}

/// A description turned into tracer inputs: the mesh, the true parameters (one material and one emitter
/// slot per object, in description order) and the cameras.
#[derive(Debug)]
pub struct BuiltScene {
    pub desc: SceneDesc,
    /// The scan mesh (what the Matterport PLY holds).
    pub mesh: SynthMesh,
    /// Object index of every triangle of `scene` (equals `mesh.object_of_tri` unless an object has a
    /// `checker`, whose photos are rendered from a finer tessellation than the scan mesh).
    pub render_object_of_tri: Vec<u32>,
    pub scene: tracer::Scene,
    pub params: tracer::Params,
    pub cameras: Vec<tracer::Camera>,
    pub settings: tracer::TracerSettings,
}

impl BuiltScene {
    /// The per-object fit's context on this scene with `seed`, counting its paths into `counter` (no emitter
    /// split at the horizon).
    #[must_use]
    pub fn fit_context<'a>(
        &'a self,
        seed: u64,
        counter: &'a optim::fit::samples::SampleCounter,
    ) -> optim::fit::jacobian::Ctx<'a> {
        optim::fit::jacobian::Ctx {
            scene: &self.scene,
            cameras: &self.cameras,
            settings: &self.settings,
            seed,
            samples: counter,
            split: &optim::fit::layout::NO_SPLIT,
        }
    }
}

/// Reads and validates a description file.
pub fn load_desc(path: &Path) -> Result<SceneDesc, SynthError> {
    let text = std::fs::read_to_string(path).map_err(|e| SynthError::Io { path: path.to_path_buf(), source: e })?;
    let bad = |message: String| SynthError::Desc { path: path.to_path_buf(), message };
    let desc: SceneDesc = toml::from_str(&text).map_err(|e| {
        // toml's own Display quotes the source over several lines; the error stays one line: line + message.
        let line = e.span().and_then(|s| text.get(..s.start)).map(|before| before.matches('\n').count() + 1);
        let message = e.message().split_whitespace().collect::<Vec<_>>().join(" ");
        bad(line.map_or(message.clone(), |l| format!("line {l}: {message}")))
    })?;
    if desc.objects.is_empty() || desc.cameras.is_empty() {
        return Err(bad("needs at least one object and one camera".into()));
    }
    if desc.width == 0 || desc.height == 0 || desc.spp == 0 {
        return Err(bad("width, height and spp must be ≥ 1".into()));
    }
    if !(desc.fov_y_deg > 0.0 && desc.fov_y_deg < 180.0) {
        return Err(bad(format!("fov_y_deg = {} is outside (0, 180)", desc.fov_y_deg)));
    }
    let mut ids: Vec<i32> = desc.objects.iter().map(|o| o.id).collect();
    ids.sort_unstable();
    if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
        return Err(bad(format!("object id {} is used twice", w[0])));
    }
    for o in &desc.objects {
        let in_unit = |x: f32| (0.0..=1.0).contains(&x);
        if !(o.base_color.iter().all(|&c| in_unit(c))
            && in_unit(o.roughness)
            && in_unit(o.metallic)
            && in_unit(o.specular))
        {
            return Err(bad(format!("object {}: material parameters must lie in [0, 1]", o.id)));
        }
        if let Some(c) = &o.checker
            && (c.squares == 0 || !c.colors.iter().flatten().all(|&x| in_unit(x)))
        {
            return Err(bad(format!("object {}: checker needs squares ≥ 1 and colours in [0, 1]", o.id)));
        }
        if !o.emission.iter().chain(o.emission_ground.iter().flatten()).all(|&e| e >= 0.0 && e.is_finite()) {
            return Err(bad(format!("object {}: emission must be finite and ≥ 0", o.id)));
        }
    }
    if let Some(p) = &desc.camera_pipeline {
        camera_pipeline::validate(p).map_err(bad)?;
    }
    Ok(desc)
}

/// Builds the tracer scene, true parameters and cameras of a description (`path` only names errors).
pub fn build(desc: SceneDesc, path: &Path) -> Result<BuiltScene, SynthError> {
    let mut mesh = SynthMesh::default();
    for (i, o) in desc.objects.iter().enumerate() {
        mesh.push_object(o, i as u32);
    }
    let mut materials: Vec<tracer::Material> = desc.objects.iter().map(desc::ObjectSpec::material).collect();
    let (render, material_of_tri) = if desc.objects.iter().any(|o| o.checker.is_some()) {
        // Checker objects: one n×n grid cell per square (2 triangles), each cell's colour its own slot.
        let mut render = SynthMesh::default();
        let mut material_of_tri = Vec::new();
        for (i, o) in desc.objects.iter().enumerate() {
            let before = render.triangles.len();
            match (o.checker, o.shape) {
                (Some(ch), desc::Shape::Quad { corner, u, v }) => {
                    let n = ch.squares.max(1);
                    render.push_quad(corner.into(), u.into(), v.into(), n, i as u32);
                    let slot0 = materials.len() as u32;
                    for c in ch.colors {
                        materials.push(tracer::Material { base_color: Vec3::from(c), ..o.material() });
                    }
                    // push_quad emits cells row by row (j along v, i along u), two triangles per cell.
                    for j in 0..n {
                        for i in 0..n {
                            let slot = slot0 + (i + j) % 2;
                            material_of_tri.extend([slot, slot]);
                        }
                    }
                }
                (Some(_), desc::Shape::Box { .. }) => {
                    return Err(SynthError::Desc {
                        path: path.to_path_buf(),
                        message: format!("object {}: `checker` needs a quad shape", o.id),
                    });
                }
                (None, _) => {
                    render.push_object(o, i as u32);
                    material_of_tri.extend(std::iter::repeat_n(i as u32, render.triangles.len() - before));
                }
            }
        }
        (render, material_of_tri)
    } else {
        (mesh.clone(), mesh.object_of_tri.clone())
    };
    let scene = tracer::Scene::new(tracer::SceneInput {
        positions: render.positions.clone(),
        triangles: render.triangles.clone(),
        normals: Some(render.normals.clone()),
        material_of_tri,
        emitter_of_tri: render.object_of_tri.clone(),
    })?;
    let mut params = tracer::Params {
        materials,
        emission: desc.objects.iter().map(|o| Vec3::from(o.emission)).collect(),
        horizon: Default::default(),
    };
    // Emissions split at the horizon (world up +z): each ground half is an entry after the objects' own.
    let halves =
        desc.objects.iter().enumerate().filter_map(|(k, o)| o.emission_ground.map(|g| (k as u32, Vec3::from(g))));
    params.split_at_horizon(Vec3::Z, halves);
    let mut cameras = Vec::with_capacity(desc.cameras.len());
    for (k, c) in desc.cameras.iter().enumerate() {
        let pose = matterport::look_at(c.eye.into(), c.target.into(), c.up.into()).ok_or_else(|| SynthError::Desc {
            path: path.to_path_buf(),
            message: format!("camera {k}: eye equals target or up is parallel to the view direction"),
        })?;
        cameras.push(tracer::Camera::from_fov_y(desc.width, desc.height, desc.fov_y_deg.to_radians(), pose));
    }
    let settings = tracer::TracerSettings {
        max_depth: desc.max_depth,
        rr_depth: desc.rr_depth,
        emission_profile: desc.emission_profile,
    };
    Ok(BuiltScene { desc, mesh, render_object_of_tri: render.object_of_tri, scene, params, cameras, settings })
}

/// Fails when a pixel centre of any camera sees an object marked `hidden`.
fn check_hidden(built: &BuiltScene, path: &Path) -> Result<(), SynthError> {
    for (k, cam) in built.cameras.iter().enumerate() {
        for y in 0..cam.height {
            for x in 0..cam.width {
                // The pixel corners as well as the centre: a hidden object must not leak into any pixel.
                for (dx, dy) in [(0.0, 0.0), (-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)] {
                    let (o, d) = cam.ray(glam::Vec2::new(x as f32 + dx, y as f32 + dy));
                    if let Some((hit, _)) = built.scene.intersect(o, d, f32::INFINITY) {
                        let obj = &built.desc.objects[built.render_object_of_tri[hit.tri as usize] as usize];
                        if obj.hidden {
                            return Err(SynthError::HiddenSeen {
                                path: path.to_path_buf(),
                                camera: k,
                                object: obj.id,
                                label: obj.label.clone(),
                                x,
                                y,
                            });
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

/// The ground truth in the `ipt-materials/1` schema of `materials.json` (an emission split at the horizon
/// as `materials.json` writes it: both halves, and the uniform emission of the same flux).
#[must_use]
pub fn ground_truth_json(built: &BuiltScene) -> serde_json::Value {
    let uniform = built.params.uniform_emission(&built.scene.horizon_geometry(Vec3::Z));
    let mut tris = vec![0usize; built.desc.objects.len()];
    for &o in &built.mesh.object_of_tri {
        tris[o as usize] += 1;
    }
    let objects: Vec<_> = built
        .desc
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| {
            let emits = o.emission.iter().chain(o.emission_ground.iter().flatten()).any(|&e| e > 0.0);
            let glossy = o.specular > 0.0 || o.metallic > 0.0;
            let model = match (glossy, emits) {
                (false, false) => "diffuse",
                (true, false) => "specular",
                (false, true) => "diffuse+emission",
                (true, true) => "specular+emission",
            };
            let mut v = serde_json::json!({
                "id": o.id, "label": o.label, "triangles": tris[i],
                "base_color": o.checker.map_or(o.base_color, |c| std::array::from_fn(|k| 0.5 * (c.colors[0][k] + c.colors[1][k]))),
                "roughness": o.roughness, "metallic": o.metallic, "specular": o.specular,
                "emission": uniform[i].to_array(), "model": model,
            });
            if let Some(g) = o.emission_ground {
                v["horizon"] = serde_json::json!({"up": [0.0, 0.0, 1.0], "sky": o.emission, "ground": g});
            }
            v
        })
        .collect();
    let profile = match built.desc.emission_profile {
        tracer::EmissionProfile::Uniform => "uniform",
        tracer::EmissionProfile::Cosine => "cosine",
    };
    serde_json::json!({"format": "ipt-materials/1", "emission_profile": profile, "objects": objects})
}

fn create_dir(path: &Path) -> Result<(), SynthError> {
    std::fs::create_dir_all(path).map_err(|e| SynthError::Io { path: path.to_path_buf(), source: e })
}

/// Generates the synthetic scan described by `desc_path` into `out_dir` (created if missing).
pub fn generate(desc_path: &Path, out_dir: &Path) -> Result<(), SynthError> {
    let desc = load_desc(desc_path)?;
    let built = build(desc, desc_path)?;
    check_hidden(&built, desc_path)?;
    write_scan(&built, out_dir)
}

/// The text of a `pipeline run` config for the scan of `desc` at `scan`, output `out` beside the config: the fit
/// traces paths as deep as the renderer that made the photos (`desc.max_depth`, `desc.rr_depth`), as the
/// in-memory fits of the scenes do, since a fit deeper or shallower than its photos is biased
/// (docs/optim/design-measurements.md, "Path depth against photos of unbounded depth").
#[must_use]
pub fn run_config(scan: &Path, desc: &SceneDesc) -> String {
    format!(
        "[scan]\npath = {:?}\n[output]\npath = \"out\"\n[tracer]\nmax_depth = {}\nrr_depth = {}\n",
        scan.to_string_lossy(),
        desc.max_depth,
        desc.rr_depth
    )
}

/// Writes the Matterport layout of a built scene (mesh, cameras, rendered photos, ground truth) into
/// `out_dir`.
pub fn write_scan(built: &BuiltScene, out_dir: &Path) -> Result<(), SynthError> {
    let id = built.desc.house_id.clone();
    let seg_dir = out_dir.join("house_segmentations");
    let cam_dir = out_dir.join("undistorted_camera_parameters");
    let img_dir = out_dir.join("undistorted_color_images");
    for d in [&seg_dir, &cam_dir, &img_dir] {
        create_dir(d)?;
    }
    let json = |v: &serde_json::Value| serde_json::to_vec_pretty(v).unwrap_or_default();
    matterport::write_file(&seg_dir.join(format!("{id}.ply")), &matterport::ply_bytes(&built.desc, &built.mesh))?;
    matterport::write_file(&seg_dir.join(format!("{id}.semseg.json")), &json(&matterport::semseg_json(&built.desc)))?;
    matterport::write_file(
        &seg_dir.join(format!("{id}.fsegs.json")),
        &json(&matterport::fsegs_json(&built.desc, &built.mesh)),
    )?;
    matterport::write_file(
        &cam_dir.join(format!("{id}.conf")),
        matterport::conf_text(&built.desc, &built.cameras).as_bytes(),
    )?;
    let mut draws = Vec::new();
    for (k, img) in photos(built)?.iter().enumerate() {
        let path = img_dir.join(matterport::image_names(&built.desc, k).0);
        let bytes = match &built.desc.camera_pipeline {
            None => matterport::exr_bytes(&path, img.width, img.height, &img.rgb)?,
            Some(spec) => {
                let d = camera_pipeline::draw(spec, built.desc.seed, k);
                let codes = camera_pipeline::to_codes(spec, &d, &built.cameras[k], &img.rgb);
                let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
                draws.push((stem, d));
                camera_pipeline::jpeg_bytes(&codes, img.width, img.height, spec.jpeg_quality)
                    .map_err(|e| SynthError::Jpeg { path: path.clone(), message: e.to_string() })?
            }
        };
        matterport::write_file(&path, &bytes)?;
    }
    matterport::write_file(&out_dir.join("ground_truth_materials.json"), &json(&ground_truth_json(built)))?;
    if let Some(spec) = &built.desc.camera_pipeline {
        let truth = camera_pipeline::truth_json(spec, &draws);
        matterport::write_file(&out_dir.join("ground_truth_camera.json"), &json(&truth))?;
    }
    tracing::info!(out = %out_dir.display(), views = built.cameras.len(), "synthetic scan written");
    Ok(())
}

/// Renders the photos of a built scene in memory (what [`generate`] writes as EXR), all pixels valid.
pub fn photos(built: &BuiltScene) -> Result<Vec<ingest::photo::LinearImage>, SynthError> {
    built
        .cameras
        .iter()
        .enumerate()
        .map(|(k, cam)| {
            // One iteration index per view keeps the views' noise independent.
            let rgb = tracer::render_image(
                &built.scene,
                &built.params,
                cam,
                built.desc.spp,
                &built.settings,
                built.desc.seed,
                k as u64,
            )?;
            Ok(ingest::photo::LinearImage {
                width: cam.width,
                height: cam.height,
                rgb: rgb.iter().flat_map(|c| c.to_array()).collect(),
                mask: vec![1; rgb.len()],
            })
        })
        .collect()
}

/// The objects of a built scene in the fit's form (object i = description object i).
#[must_use]
pub fn fit_objects(built: &BuiltScene) -> Vec<optim::fit::ObjectDesc> {
    built
        .desc
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| optim::fit::ObjectDesc {
            id: i64::from(o.id),
            label: o.label.clone(),
            triangles: (0..built.mesh.object_of_tri.len() as u32)
                .filter(|&t| built.mesh.object_of_tri[t as usize] == i as u32)
                .collect(),
        })
        .collect()
}

/// The per-object fit of a synthetic scene from `images` (one per camera), from scratch, without checkpoints or
/// a visible progress bar: the common form of the fits that tests run on synthetic scenes.
pub fn fit(
    built: &BuiltScene,
    images: &[ingest::photo::LinearImage],
    settings: &optim::fit::ObjectFitSettings,
) -> Result<optim::fit::FitOutcome, optim::fit::FitError> {
    fit_resumable(built, images, settings, None, &mut |_| Ok(()))
}

/// [`fit`] continued from `resume` (when given), calling `on_checkpoint` at every checkpoint (as the object stage
/// does), without a visible progress bar.
pub fn fit_resumable(
    built: &BuiltScene,
    images: &[ingest::photo::LinearImage],
    settings: &optim::fit::ObjectFitSettings,
    resume: Option<optim::fit::FitState>,
    on_checkpoint: &mut dyn FnMut(&optim::fit::FitState) -> Result<(), optim::fit::FitError>,
) -> Result<optim::fit::FitOutcome, optim::fit::FitError> {
    fit_in_mode(built, images, settings, optim::fit::FitMode::Full, resume, on_checkpoint, &optim::NoProgress)
}

/// [`fit_resumable`] in a given [`optim::fit::FitMode`] (a comparison fit with a fixed set of lights, or the whole
/// fit), reporting to `progress`, whose [`optim::Progress::stop_requested`] the fit obeys (what a signal does to
/// the object stage).
pub fn fit_in_mode(
    built: &BuiltScene,
    images: &[ingest::photo::LinearImage],
    settings: &optim::fit::ObjectFitSettings,
    mode: optim::fit::FitMode<'_>,
    resume: Option<optim::fit::FitState>,
    on_checkpoint: &mut dyn FnMut(&optim::fit::FitState) -> Result<(), optim::fit::FitError>,
    progress: &dyn optim::Progress,
) -> Result<optim::fit::FitOutcome, optim::fit::FitError> {
    let objects = fit_objects(built);
    let inputs = optim::fit::FitInputs {
        scene: &built.scene,
        cameras: &built.cameras,
        images,
        objects: &objects,
        settings,
        tracer: &built.settings,
        mode,
    };
    optim::fit::fit_objects(&inputs, resume, on_checkpoint, progress)
}

/// The per-triangle stage's start on a synthetic scene with its true per-object values (what the object stage
/// recovers; checker objects at their mean colour): the common start of the tests of the per-triangle stage.
pub fn true_triangle_start(
    built: &BuiltScene,
) -> Result<optim::triangle::TriangleState, optim::triangle::TriangleError> {
    let k = built.desc.objects.len();
    let params = tracer::Params {
        materials: built.params.materials[..k].to_vec(),
        emission: built.params.emission.clone(),
        horizon: built.params.horizon.clone(),
    };
    optim::triangle::TriangleState::from_objects(
        built.mesh.positions.clone(),
        Some(built.mesh.normals.clone()),
        built.mesh.triangles.clone(),
        built.mesh.object_of_tri.clone(),
        &params,
    )
}
