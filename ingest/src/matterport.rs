//! Matterport3D layout: `house_segmentations/<id>.ply` (+ `.fsegs.json`, `.semseg.json`), undistorted cameras
//! from `undistorted_camera_parameters/<id>.conf`, and the raw distorted variant
//! (`matterport_camera_intrinsics/`, `matterport_camera_poses/`, `matterport_color_images/`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::camera::{Camera, Distortion, Intrinsics, View, check_unique_names};
use crate::error::{IngestError, utf8};
use crate::image_header::{check_image_size, image_dimensions, resolve_image};
use crate::listing::files_with_extension;
use crate::mesh::{LabeledMesh, Mesh};
use crate::ply::read_ply;
use crate::pose::{check_rigid, from_row_major};

/// Loads `house_segmentations/<id>.ply` with its `.fsegs.json` and `.semseg.json` (both optional). Returns the
/// mesh and the PLY path.
pub fn load_mesh(dir: &Path) -> Result<(LabeledMesh, PathBuf), IngestError> {
    let seg_dir = dir.join("house_segmentations");
    let plys = files_with_extension(&seg_dir, "ply")?;
    let ply = match plys.as_slice() {
        [one] => one.clone(),
        [] => return Err(IngestError::Layout { dir: seg_dir, message: "no <id>.ply mesh".into() }),
        many => {
            // Several houses: take the one named after the scan directory.
            let want = dir.file_name().map(|n| format!("{}.ply", n.to_string_lossy()));
            match many.iter().find(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()) == want) {
                Some(p) => p.clone(),
                None => {
                    return Err(IngestError::Layout {
                        dir: seg_dir,
                        message: format!("{} PLY files and none named after the scan directory", many.len()),
                    });
                }
            }
        }
    };
    let stem = ply.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let fsegs = seg_dir.join(format!("{stem}.fsegs.json"));
    let semseg = seg_dir.join(format!("{stem}.semseg.json"));
    let mut labeled = mesh_from_ply(&ply, fsegs.is_file().then_some(fsegs.as_path()))?;
    if semseg.is_file() {
        apply_semseg(&semseg, &mut labeled)?;
    }
    Ok((labeled, ply))
}

#[derive(Deserialize)]
struct Fsegs {
    #[serde(rename = "segIndices")]
    seg_indices: Vec<i64>,
}

#[derive(Deserialize)]
struct SemSeg {
    #[serde(rename = "segGroups")]
    seg_groups: Vec<SegGroup>,
}

#[derive(Deserialize)]
struct SegGroup {
    id: Option<i64>,
    #[serde(rename = "objectId")]
    object_id: Option<i64>,
    label: Option<String>,
    #[serde(default)]
    segments: Vec<i64>,
}

fn parse_json<T: for<'de> Deserialize<'de>>(path: &Path, bytes: &[u8]) -> Result<T, IngestError> {
    serde_json::from_slice(bytes).map_err(|e| IngestError::line(path, e.line(), format!("bad JSON: {e}")))
}

/// Reads a PLY mesh with optional `material_id`, `segment_id`, `category_id` face columns. `fsegs` (a
/// `.fsegs.json` with one over-segment id per file face) fills the material column when the PLY has none.
pub fn mesh_from_ply(path: &Path, fsegs: Option<&Path>) -> Result<LabeledMesh, IngestError> {
    let read = read_ply(path)?;
    let fsegs = match fsegs {
        Some(f) => Some((f, std::fs::read(f).map_err(|e| IngestError::io(f, e))?)),
        None => None,
    };
    mesh_from_ply_read(path, read, fsegs.as_ref().map(|(f, b)| (*f, b.as_slice())))
}

/// [`mesh_from_ply`] on a PLY already read (`path` names it in messages) and the `.fsegs.json` bytes already in
/// memory (with their path, for messages).
pub fn mesh_from_ply_read(
    path: &Path,
    read: crate::ply::PlyRead,
    fsegs: Option<(&Path, &[u8])>,
) -> Result<LabeledMesh, IngestError> {
    if read.polygons_triangulated > 0 {
        tracing::info!("{}: fan-triangulated {} polygon faces", path.display(), read.polygons_triangulated);
    }
    let ids = |name: &str| read.mesh.face_ids(name);
    let n = read.mesh.triangles.len();
    let face_segment = ids("segment_id").unwrap_or_else(|| vec![-1; n]);
    let face_category = ids("category_id").unwrap_or_else(|| vec![-1; n]);
    let mut face_material = ids("material_id");
    if let Some((fsegs, bytes)) = fsegs {
        let f: Fsegs = parse_json(fsegs, bytes)?;
        if f.seg_indices.len() != read.face_count {
            return Err(IngestError::format(
                fsegs,
                format!(
                    "segIndices has {} entries but {} has {} faces",
                    f.seg_indices.len(),
                    path.display(),
                    read.face_count
                ),
            ));
        }
        if face_material.is_none() {
            let mut col = Vec::with_capacity(n);
            for &face in &read.source_face {
                let v = f.seg_indices[face as usize];
                let v = i32::try_from(v).map_err(|_| {
                    IngestError::element(
                        fsegs,
                        "segIndices entry",
                        face as usize,
                        format!("{v} does not fit in an int"),
                    )
                })?;
                col.push(v);
            }
            face_material = Some(col);
        }
    }
    let mesh = Mesh {
        positions: read.mesh.positions,
        normals: read.mesh.normals,
        triangles: read.mesh.triangles,
        face_segment,
        face_category,
        face_material: face_material.unwrap_or_else(|| vec![-1; n]),
    };
    Ok(LabeledMesh { mesh, ..LabeledMesh::default() })
}

/// Names objects from `.semseg.json`: a segment (object) id takes the label of the group whose `objectId` (or
/// else `id`) equals it; an over-segment (material) id takes the label of the group listing it in `segments`.
fn apply_semseg(path: &Path, labeled: &mut LabeledMesh) -> Result<(), IngestError> {
    let bytes = std::fs::read(path).map_err(|e| IngestError::io(path, e))?;
    apply_semseg_bytes(path, &bytes, labeled)
}

/// Names the objects of `labeled` from a `.semseg.json` already in memory (see [`load_mesh`]); `path` is used
/// only in error messages.
pub fn apply_semseg_bytes(path: &Path, bytes: &[u8], labeled: &mut LabeledMesh) -> Result<(), IngestError> {
    let s: SemSeg = parse_json(path, bytes)?;
    let mut by_object = HashMap::new();
    let mut by_id = HashMap::new();
    let mut by_overseg = HashMap::new();
    for g in &s.seg_groups {
        let Some(label) = &g.label else { continue };
        if let Some(o) = g.object_id.and_then(|o| i32::try_from(o).ok()) {
            by_object.insert(o, label.clone());
        }
        if let Some(i) = g.id.and_then(|i| i32::try_from(i).ok()) {
            by_id.insert(i, label.clone());
        }
        for &seg in &g.segments {
            if let Ok(seg) = i32::try_from(seg) {
                by_overseg.insert(seg, label.clone());
            }
        }
    }
    for &id in &labeled.mesh.face_segment {
        if let Some(l) = by_object.get(&id).or_else(|| by_id.get(&id)) {
            labeled.segment_labels.entry(id).or_insert_with(|| l.clone());
        }
    }
    for &id in &labeled.mesh.face_material {
        if let Some(l) = by_overseg.get(&id) {
            labeled.material_labels.entry(id).or_insert_with(|| l.clone());
        }
    }
    Ok(())
}

/// The `.conf` in `undistorted_camera_parameters/` (exactly one, or the one named after the PLY's house).
fn find_conf(dir: &Path) -> Result<PathBuf, IngestError> {
    let conf_dir = dir.join("undistorted_camera_parameters");
    let confs = files_with_extension(&conf_dir, "conf")?;
    match confs.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(IngestError::Layout { dir: conf_dir, message: "no <id>.conf camera file".into() }),
        many => {
            let plys = files_with_extension(&dir.join("house_segmentations"), "ply")?;
            many.iter().find(|c| plys.iter().any(|p| p.file_stem() == c.file_stem())).cloned().ok_or_else(|| {
                IngestError::Layout {
                    dir: conf_dir,
                    message: format!("{} .conf files and none matches the mesh", many.len()),
                }
            })
        }
    }
}

fn parse_floats<const N: usize>(path: &Path, line: usize, tokens: &[&str]) -> Result<[f64; N], IngestError> {
    let mut out = [0.0; N];
    for (o, t) in out.iter_mut().zip(tokens) {
        *o = t.parse::<f64>().map_err(|_| IngestError::line(path, line, format!("{t:?} is not a number")))?;
    }
    Ok(out)
}

/// One `scan` line of a Matterport `.conf`, converted to the workspace convention (camera-to-world, OpenGL
/// camera frame — Matterport's own).
#[derive(Debug, Clone, PartialEq)]
pub struct ConfScan {
    /// 1-based line of the `scan` entry.
    pub line: usize,
    /// The colour image as listed (relative to `color_directory`).
    pub color_file: String,
    /// The `color_directory` in force for this line, when the file set one (relative to the scan directory).
    pub color_directory: Option<String>,
    /// The `intrinsics_matrix` in force for this line.
    pub intrinsics: Intrinsics,
    /// 1-based line of that `intrinsics_matrix`: scans with the same value share it (and, in a scan, a size).
    pub intrinsics_line: usize,
    /// Camera-to-world, checked rigid.
    pub cam_to_world: glam::DMat4,
}

/// The physical camera of a Matterport colour image from its file stem `<house>_i<camera>_<yaw>` (the rig
/// has three cameras, 0 to 2, each with its own lens). `None` when the stem does not follow that pattern.
#[must_use]
pub fn physical_camera(stem: &str) -> Option<u32> {
    let (rest, yaw) = stem.rsplit_once('_')?;
    let (_, camera) = rest.rsplit_once("_i")?;
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if !digits(yaw) || !digits(camera) {
        return None;
    }
    camera.parse().ok()
}

/// A Matterport `.conf` as read: its `scan` entries in order and the `n_images` it declares.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Conf {
    pub scans: Vec<ConfScan>,
    pub n_images: Option<usize>,
}

/// Reads a Matterport `.conf` (the undistorted cameras; also what `pipeline render` takes): every
/// `intrinsics_matrix fx 0 cx 0 fy cy 0 0 1` applies to the following `scan <depth> <color> <16 camera-to-world
/// values, row-major>` lines until the next one. Errors name the line. Images are not opened here.
pub fn read_conf(conf: &Path) -> Result<Conf, IngestError> {
    let bytes = std::fs::read(conf).map_err(|e| IngestError::io(conf, e))?;
    parse_conf(conf, &bytes)
}

/// [`read_conf`] on bytes already in memory; `conf` is used only in error messages.
pub fn parse_conf(conf: &Path, bytes: &[u8]) -> Result<Conf, IngestError> {
    let text = utf8(conf, bytes)?;
    let mut color_directory: Option<String> = None;
    let mut intrinsics: Option<(Intrinsics, usize)> = None;
    let mut out = Conf::default();
    for (k, line) in text.lines().enumerate() {
        let ln = k + 1;
        let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
        let Some(&key) = tokens.first() else { continue };
        let args = &tokens[1..];
        let want = |n: usize| {
            if args.len() == n {
                Ok(())
            } else {
                Err(IngestError::line(conf, ln, format!("`{key}` line has {} values, expected {n}", args.len())))
            }
        };
        match key {
            "dataset" | "depth_directory" => {}
            "n_images" => {
                want(1)?;
                out.n_images =
                    Some(args[0].parse::<usize>().map_err(|_| IngestError::line(conf, ln, "n_images is not a count"))?);
            }
            "color_directory" => {
                want(1)?;
                color_directory = Some(args[0].to_owned());
            }
            "intrinsics_matrix" => {
                want(9)?;
                let m: [f64; 9] = parse_floats(conf, ln, args)?;
                let k = Intrinsics { fx: m[0], fy: m[4], cx: m[2], cy: m[5] };
                if !m.iter().all(|v| v.is_finite()) || k.fx <= 0.0 || k.fy <= 0.0 {
                    return Err(IngestError::line(
                        conf,
                        ln,
                        "intrinsics_matrix needs finite values and positive fx, fy",
                    ));
                }
                intrinsics = Some((k, ln));
            }
            "scan" => {
                if args.len() != 18 {
                    return Err(IngestError::line(
                        conf,
                        ln,
                        format!(
                            "`scan` line has {} values, expected 18 (depth file, color file, 16 pose values)",
                            args.len()
                        ),
                    ));
                }
                let Some((k, k_line)) = intrinsics else {
                    return Err(IngestError::line(conf, ln, "`scan` line before any intrinsics_matrix"));
                };
                let m: [f64; 16] = parse_floats(conf, ln, &args[2..])?;
                let cam_to_world = from_row_major(&m);
                check_rigid(&cam_to_world).map_err(|why| IngestError::line(conf, ln, why))?;
                out.scans.push(ConfScan {
                    line: ln,
                    color_file: args[1].to_owned(),
                    color_directory: color_directory.clone(),
                    intrinsics: k,
                    intrinsics_line: k_line,
                    cam_to_world,
                });
            }
            other => tracing::warn!("{}:{ln}: ignoring unknown keyword {other:?}", conf.display()),
        }
    }
    Ok(out)
}

/// Reads the undistorted cameras of `undistorted_camera_parameters/<id>.conf` ([`read_conf`]). Each image's
/// size is read from its header; images that share an `intrinsics_matrix` must share a size, and the principal
/// point must lie inside the image.
pub fn load_views_conf(dir: &Path) -> Result<Vec<View>, IngestError> {
    let conf = find_conf(dir)?;
    let parsed = read_conf(&conf)?;
    // Size of the first image under the current intrinsics block, and its path.
    let mut block_size: Option<(usize, u32, u32, PathBuf)> = None;
    let mut views = Vec::new();
    for s in &parsed.scans {
        let (ln, k) = (s.line, s.intrinsics);
        let color_dir = dir.join(s.color_directory.as_deref().unwrap_or("undistorted_color_images"));
        let listed = color_dir.join(&s.color_file);
        let image_path = resolve_image(&listed, &conf)?;
        let (w, h) = image_dimensions(&image_path)?;
        match &block_size {
            Some((block, bw, bh, first)) if *block == s.intrinsics_line && (*bw, *bh) != (w, h) => {
                return Err(IngestError::ImageSize {
                    path: image_path,
                    width: w,
                    height: h,
                    expected: format!(
                        "{} ({bw}x{bh}) shares its intrinsics_matrix ({}:{ln})",
                        first.display(),
                        conf.display()
                    ),
                });
            }
            Some((block, ..)) if *block == s.intrinsics_line => {}
            _ => block_size = Some((s.intrinsics_line, w, h, image_path.clone())),
        }
        if !(0.0..=f64::from(w)).contains(&k.cx) || !(0.0..=f64::from(h)).contains(&k.cy) {
            return Err(IngestError::ImageSize {
                path: image_path,
                width: w,
                height: h,
                expected: format!(
                    "the principal point ({}, {}) of {}:{ln} lies outside it",
                    k.cx,
                    k.cy,
                    conf.display()
                ),
            });
        }
        let name = Path::new(&s.color_file).file_stem().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        views.push(View {
            name,
            image_path,
            camera: Camera {
                width: w,
                height: h,
                intrinsics: k,
                distortion: Distortion::default(),
                cam_to_world: s.cam_to_world,
            },
        });
    }
    if let Some(n) = parsed.n_images
        && n != views.len()
    {
        tracing::warn!("{}: n_images says {n} but {} scan lines were read", conf.display(), views.len());
    }
    check_unique_names(&views, &conf)?;
    Ok(views)
}

/// One raw intrinsics file as read: image size, pinhole intrinsics and OpenCV distortion.
pub type RawIntrinsics = (u32, u32, Intrinsics, Distortion);

/// Reads one raw intrinsics file: `width height fx fy cx cy k1 k2 p1 p2 k3` (OpenCV model).
fn read_raw_intrinsics(path: &Path) -> Result<RawIntrinsics, IngestError> {
    let bytes = std::fs::read(path).map_err(|e| IngestError::io(path, e))?;
    parse_raw_intrinsics(path, &bytes)
}

/// Parses a raw intrinsics file already in memory (`width height fx fy cx cy k1 k2 p1 p2 k3`); `path` is used
/// only in error messages.
pub fn parse_raw_intrinsics(path: &Path, bytes: &[u8]) -> Result<RawIntrinsics, IngestError> {
    let text = utf8(path, bytes)?;
    let tokens: Vec<&str> = text.split_ascii_whitespace().collect();
    if tokens.len() != 11 {
        return Err(IngestError::line(
            path,
            1,
            format!("{} values, expected 11 (W H fx fy cx cy k1 k2 p1 p2 k3)", tokens.len()),
        ));
    }
    let v: [f64; 11] = parse_floats(path, 1, &tokens)?;
    let size_ok = |x: f64| (1.0..=f64::from(u32::MAX)).contains(&x) && x.fract() == 0.0;
    if !v.iter().all(|x| x.is_finite()) || !size_ok(v[0]) || !size_ok(v[1]) {
        return Err(IngestError::line(
            path,
            1,
            "width and height must be integers in 1..=4294967295 and all values finite",
        ));
    }
    if v[2] <= 0.0 || v[3] <= 0.0 {
        return Err(IngestError::line(path, 1, "fx and fy must be positive"));
    }
    let k = Intrinsics { fx: v[2], fy: v[3], cx: v[4], cy: v[5] };
    let d = Distortion { k1: v[6], k2: v[7], p1: v[8], p2: v[9], k3: v[10], ..Distortion::default() };
    Ok((v[0] as u32, v[1] as u32, k, d))
}

/// Parses a raw pose file already in memory (16 values, row-major camera-to-world, OpenGL camera), checked
/// rigid; `path` is used only in error messages.
pub fn parse_raw_pose(path: &Path, bytes: &[u8]) -> Result<glam::DMat4, IngestError> {
    let text = utf8(path, bytes)?;
    let tokens: Vec<&str> = text.split_ascii_whitespace().collect();
    if tokens.len() != 16 {
        return Err(IngestError::format(path, format!("{} values, expected 16 (4x4 camera-to-world)", tokens.len())));
    }
    let m: [f64; 16] = parse_floats(path, 1, &tokens)?;
    let cam_to_world = from_row_major(&m);
    check_rigid(&cam_to_world).map_err(|why| IngestError::format(path, why))?;
    Ok(cam_to_world)
}

/// Reads the raw distorted cameras: every `matterport_camera_poses/<uuid>_pose_<cam>_<yaw>.txt` (16 values,
/// camera-to-world, OpenGL camera) with `matterport_camera_intrinsics/<uuid>_intrinsics_<cam>.txt` and the photo
/// `matterport_color_images/<uuid>_i<cam>_<yaw>.jpg`, whose size must match the intrinsics.
pub fn load_views_raw(dir: &Path) -> Result<Vec<View>, IngestError> {
    let pose_dir = dir.join("matterport_camera_poses");
    let mut intrinsics_cache: HashMap<PathBuf, RawIntrinsics> = HashMap::new();
    let mut views = Vec::new();
    for pose_path in files_with_extension(&pose_dir, "txt")? {
        let stem = pose_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let Some((uuid, rest)) = stem.rsplit_once("_pose_") else {
            tracing::warn!("{}: not named <uuid>_pose_<cam>_<yaw>.txt; ignored", pose_path.display());
            continue;
        };
        let Some((cam, yaw)) = rest.split_once('_') else {
            return Err(IngestError::format(&pose_path, "file name is not <uuid>_pose_<cam>_<yaw>.txt"));
        };
        let intr_path = dir.join("matterport_camera_intrinsics").join(format!("{uuid}_intrinsics_{cam}.txt"));
        if !intr_path.is_file() {
            return Err(IngestError::format(
                &pose_path,
                format!("its intrinsics file {} does not exist", intr_path.display()),
            ));
        }
        let (w, h, k, d) = match intrinsics_cache.get(&intr_path) {
            Some(v) => *v,
            None => {
                let v = read_raw_intrinsics(&intr_path)?;
                intrinsics_cache.insert(intr_path.clone(), v);
                v
            }
        };
        let bytes = std::fs::read(&pose_path).map_err(|e| IngestError::io(&pose_path, e))?;
        let cam_to_world = parse_raw_pose(&pose_path, &bytes)?;
        let name = format!("{uuid}_i{cam}_{yaw}");
        let listed = dir.join("matterport_color_images").join(format!("{name}.jpg"));
        let image_path = resolve_image(&listed, &pose_path)?;
        check_image_size(&image_path, w, h, &intr_path.display().to_string())?;
        views.push(View {
            name,
            image_path,
            camera: Camera { width: w, height: h, intrinsics: k, distortion: d, cam_to_world },
        });
    }
    if views.is_empty() {
        return Err(IngestError::Layout {
            dir: pose_dir,
            message: "no <uuid>_pose_<cam>_<yaw>.txt camera poses".into(),
        });
    }
    check_unique_names(&views, &pose_dir)?;
    Ok(views)
}
