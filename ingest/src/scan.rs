//! A loaded scan (mesh, objects, views) and the entry point [`load_scan`] with format auto-detection.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec2, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::camera::{Camera, View};
use crate::error::IngestError;
use crate::listing::files_with_extension;
use crate::mesh::{LabeledMesh, Mesh};
use crate::{colmap, matterport, obj, transforms};

/// One object: all faces sharing an id in the chosen grouping column.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ObjectInfo {
    /// The id in the source file (`-1` for faces without one).
    pub id: i64,
    pub label: Option<String>,
    /// Number of triangles in the object.
    pub triangles: usize,
}

/// A scan: mesh, objects (sorted by id), the object of each triangle, and the views.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    pub mesh: Mesh,
    pub objects: Vec<ObjectInfo>,
    /// Index into `objects` for each triangle of `mesh`.
    pub face_object: Vec<u32>,
    pub views: Vec<View>,
    /// What loading removed from the file's mesh, for the caller to report.
    pub removed: Removed,
}

/// Geometry dropped while loading a scan. Nothing is dropped silently: the caller reports these counts.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Removed {
    /// Zero-area triangles (no area, no normal; see [`Mesh::is_zero_area`]).
    pub zero_area_triangles: usize,
    /// Objects all of whose triangles had zero area, as they were in the file (`triangles` = how many were
    /// dropped). They are absent from [`Scan::objects`]: no photo can constrain a surface without area.
    pub objects_without_area: Vec<ObjectInfo>,
}

/// Which per-face id column defines objects: one variant per column, so that the config (which deserialises
/// this type, `scan.group_by`) names each column once. OBJ readers store `o`/`g` groups in the segment column
/// and `usemtl` materials in the material column; [`GroupBy::OBJ_GROUP`] and [`GroupBy::OBJ_MATERIAL`] name
/// those for Rust callers without adding config values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GroupBy {
    /// Matterport `segment_id` (object instances); OBJ `o`/`g` groups. The default.
    #[default]
    Segment,
    /// Matterport `category_id`.
    Category,
    /// Matterport `material_id` (over-segments); OBJ `usemtl` materials.
    Material,
}

impl GroupBy {
    /// OBJ `o`/`g` groups (stored in the segment column).
    pub const OBJ_GROUP: GroupBy = GroupBy::Segment;
    /// OBJ `usemtl` materials (stored in the material column).
    pub const OBJ_MATERIAL: GroupBy = GroupBy::Material;
}

/// Scan directory layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScanFormat {
    /// `house_segmentations/` + `undistorted_camera_parameters/*.conf` + `undistorted_color_images/`.
    Matterport,
    /// `house_segmentations/` + `matterport_camera_poses/` + `matterport_camera_intrinsics/` +
    /// `matterport_color_images/` (distorted photos).
    MatterportRaw,
    /// `*.obj` mesh(es) with COLMAP or `transforms.json` cameras beside them.
    Obj,
    /// COLMAP text model (`cameras.txt`, `images.txt` in the directory, `sparse/0/` or `sparse/`), images in
    /// `images/`, mesh `*.obj` or a single `*.ply` in the directory.
    Colmap,
    /// nerfstudio `transforms.json`, mesh `*.obj` or a single `*.ply` in the directory.
    Transforms,
    /// Detect from the directory contents (see [`detect_format`]).
    #[default]
    Auto,
}

/// Loads the scan in `dir`.
///
/// Zero-area triangles are dropped (one counted warning). Objects seen by no camera are reported with a warning
/// (see [`objects_seen_by_no_camera`]) but kept.
pub fn load_scan(dir: &Path, format: ScanFormat, group_by: GroupBy) -> Result<Scan, IngestError> {
    let format = match format {
        ScanFormat::Auto => detect_format(dir)?,
        f => f,
    };
    tracing::info!("{}: loading scan as {format:?}", dir.display());
    let (labeled, mesh_source, views) = match format {
        ScanFormat::Matterport => {
            let (m, src) = matterport::load_mesh(dir)?;
            (m, src, matterport::load_views_conf(dir)?)
        }
        ScanFormat::MatterportRaw => {
            let (m, src) = matterport::load_mesh(dir)?;
            (m, src, matterport::load_views_raw(dir)?)
        }
        ScanFormat::Obj => {
            let (m, src) = obj::load_obj_dir(dir)?;
            (m, src, load_views_beside(dir)?)
        }
        ScanFormat::Colmap => {
            let (m, src) = load_mesh_beside(dir)?;
            let model = colmap::find_model_dir(dir).ok_or_else(|| IngestError::Layout {
                dir: dir.to_path_buf(),
                message: "no COLMAP cameras.txt".into(),
            })?;
            (m, src, colmap::load_views(&model, &dir.join("images"))?)
        }
        ScanFormat::Transforms => {
            let (m, src) = load_mesh_beside(dir)?;
            (m, src, transforms::load_views(&dir.join("transforms.json"))?)
        }
        ScanFormat::Auto => {
            return Err(IngestError::Layout {
                dir: dir.to_path_buf(),
                message: "format detection returned Auto".into(),
            });
        }
    };
    let scan = assemble(labeled, &mesh_source, views, group_by);
    let unseen = objects_seen_by_no_camera(&scan);
    if !unseen.is_empty() {
        let names: Vec<String> = unseen
            .iter()
            .take(10)
            .map(|&o| {
                let obj = &scan.objects[o];
                format!("{} ({})", obj.id, obj.label.as_deref().unwrap_or("unlabelled"))
            })
            .collect();
        tracing::warn!(
            "{}: {} of {} objects are seen by no camera (their materials cannot be recovered): {}{}",
            dir.display(),
            unseen.len(),
            scan.objects.len(),
            names.join(", "),
            if unseen.len() > 10 { ", ..." } else { "" }
        );
    }
    Ok(scan)
}

/// Detects the layout of `dir`: Matterport (`house_segmentations/` + `.conf`), Matterport raw
/// (`house_segmentations/` + `matterport_camera_poses/`), OBJ (`*.obj`), COLMAP (`cameras.txt`), transforms
/// (`transforms.json`), in that order of precedence.
pub fn detect_format(dir: &Path) -> Result<ScanFormat, IngestError> {
    if !dir.is_dir() {
        return Err(IngestError::Layout { dir: dir.to_path_buf(), message: "not a directory".into() });
    }
    if dir.join("house_segmentations").is_dir() {
        if dir.join("undistorted_camera_parameters").is_dir() {
            return Ok(ScanFormat::Matterport);
        }
        if dir.join("matterport_camera_poses").is_dir() {
            return Ok(ScanFormat::MatterportRaw);
        }
        return Err(IngestError::Layout {
            dir: dir.to_path_buf(),
            message: "has house_segmentations/ but neither undistorted_camera_parameters/ nor matterport_camera_poses/"
                .into(),
        });
    }
    if !files_with_extension(dir, "obj")?.is_empty() {
        return Ok(ScanFormat::Obj);
    }
    if colmap::find_model_dir(dir).is_some() {
        return Ok(ScanFormat::Colmap);
    }
    if dir.join("transforms.json").is_file() {
        return Ok(ScanFormat::Transforms);
    }
    Err(IngestError::Layout {
        dir: dir.to_path_buf(),
        message: "unknown scan layout: expected house_segmentations/, *.obj, COLMAP cameras.txt or transforms.json"
            .into(),
    })
}

/// The views for an OBJ directory: COLMAP if present, else `transforms.json`, else none (with a warning).
fn load_views_beside(dir: &Path) -> Result<Vec<View>, IngestError> {
    if let Some(model) = colmap::find_model_dir(dir) {
        if dir.join("transforms.json").is_file() {
            tracing::warn!("{}: both COLMAP and transforms.json cameras present; using COLMAP", dir.display());
        }
        return colmap::load_views(&model, &dir.join("images"));
    }
    if dir.join("transforms.json").is_file() {
        return transforms::load_views(&dir.join("transforms.json"));
    }
    tracing::warn!("{}: no cameras (no COLMAP model, no transforms.json)", dir.display());
    Ok(Vec::new())
}

/// The mesh for a COLMAP/transforms directory: `*.obj` if any, else the single `*.ply` (or `mesh.ply`).
fn load_mesh_beside(dir: &Path) -> Result<(LabeledMesh, PathBuf), IngestError> {
    if !files_with_extension(dir, "obj")?.is_empty() {
        return obj::load_obj_dir(dir);
    }
    let plys = files_with_extension(dir, "ply")?;
    let ply = match plys.as_slice() {
        [one] => one.clone(),
        _ if dir.join("mesh.ply").is_file() => dir.join("mesh.ply"),
        [] => return Err(IngestError::Layout { dir: dir.to_path_buf(), message: "no mesh (*.obj or *.ply)".into() }),
        _ => {
            return Err(IngestError::Layout {
                dir: dir.to_path_buf(),
                message: format!("{} *.ply files and no mesh.ply: cannot tell which is the mesh", plys.len()),
            });
        }
    };
    Ok((matterport::mesh_from_ply(&ply, None)?, ply))
}

/// Drops zero-area triangles and groups faces into objects.
#[must_use]
pub fn assemble(labeled: LabeledMesh, mesh_source: &Path, views: Vec<View>, group_by: GroupBy) -> Scan {
    let LabeledMesh { mut mesh, segment_labels, category_labels, material_labels } = labeled;
    let column = |mesh: &Mesh| match group_by {
        GroupBy::Segment => mesh.face_segment.clone(),
        GroupBy::Category => mesh.face_category.clone(),
        GroupBy::Material => mesh.face_material.clone(),
    };
    // Per id: (triangles, zero-area triangles) before the drop.
    let mut before: BTreeMap<i32, (usize, usize)> = BTreeMap::new();
    for (t, id) in column(&mesh).into_iter().enumerate() {
        let e = before.entry(id).or_default();
        e.0 += 1;
        e.1 += usize::from(mesh.is_zero_area(t));
    }
    let zero_area_triangles = mesh.drop_zero_area(mesh_source);
    let (ids, labels) = match group_by {
        GroupBy::Segment => (&mesh.face_segment, &segment_labels),
        GroupBy::Category => (&mesh.face_category, &category_labels),
        GroupBy::Material => (&mesh.face_material, &material_labels),
    };
    let mut counts: BTreeMap<i32, usize> = BTreeMap::new();
    for &id in ids {
        *counts.entry(id).or_default() += 1;
    }
    let index: BTreeMap<i32, u32> = counts.keys().enumerate().map(|(k, &id)| (id, k as u32)).collect();
    let objects = counts
        .iter()
        .map(|(&id, &n)| ObjectInfo { id: i64::from(id), label: labels.get(&id).cloned(), triangles: n })
        .collect();
    let face_object = ids.iter().map(|id| index[id]).collect();
    let objects_without_area = before
        .iter()
        .filter(|&(_, &(all, zero))| all == zero)
        .map(|(&id, &(all, _))| ObjectInfo { id: i64::from(id), label: labels.get(&id).cloned(), triangles: all })
        .collect();
    Scan { mesh, objects, face_object, views, removed: Removed { zero_area_triangles, objects_without_area } }
}

/// A camera prepared for fast visibility tests.
struct Frustum {
    world_to_cam: DMat4,
    camera: Camera,
}

impl Frustum {
    /// True when world point `p` projects inside the image (no occlusion test).
    fn sees(&self, p: DVec3) -> bool {
        let c = self.world_to_cam.transform_point3(p);
        let cv = DVec3::new(c.x, -c.y, -c.z);
        if cv.z <= 0.0 {
            return false;
        }
        let (w, h) = (f64::from(self.camera.width), f64::from(self.camera.height));
        let k = &self.camera.intrinsics;
        let pin = DVec2::new(k.fx * cv.x / cv.z + k.cx, k.fy * cv.y / cv.z + k.cy);
        // Distortion polynomials fold back far outside the calibrated field; only trust them for points whose
        // pinhole projection lies within half an image of the frame (wider than any real lens's distortion).
        if pin.x < -0.5 * w || pin.x > 1.5 * w || pin.y < -0.5 * h || pin.y > 1.5 * h {
            return false;
        }
        let Some(px) = self.camera.project_opencv(cv) else { return false };
        // Pixel centres are at integers, so the image covers [-0.5, w - 0.5] x [-0.5, h - 0.5].
        px.x >= -0.5 && px.x <= w - 0.5 && px.y >= -0.5 && px.y <= h - 0.5
    }
}

/// Indices (into `scan.objects`) of objects none of whose triangle centroids or vertices projects inside any
/// camera's image. Occlusion is ignored, so this is a lower bound on the objects no photo constrains.
#[must_use]
pub fn objects_seen_by_no_camera(scan: &Scan) -> Vec<usize> {
    let frusta: Vec<Frustum> = scan
        .views
        .iter()
        .map(|v| Frustum { world_to_cam: v.camera.cam_to_world.inverse(), camera: v.camera })
        .collect();
    let mut tris_of: Vec<Vec<u32>> = vec![Vec::new(); scan.objects.len()];
    for (t, &o) in scan.face_object.iter().enumerate() {
        tris_of[o as usize].push(t as u32);
    }
    let mesh = &scan.mesh;
    let seen = |t: u32| {
        let tri = mesh.triangles[t as usize];
        let pts = [
            mesh.centroid(t as usize),
            mesh.positions[tri[0] as usize],
            mesh.positions[tri[1] as usize],
            mesh.positions[tri[2] as usize],
        ];
        pts.iter().any(|p| frusta.iter().any(|f| f.sees(p.as_dvec3())))
    };
    tris_of.par_iter().enumerate().filter(|(_, tris)| !tris.iter().any(|&t| seen(t))).map(|(o, _)| o).collect()
}
