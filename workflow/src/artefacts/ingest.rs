//! The `ingest` stage's artefacts (`crate::stages::ingest` writes them) and their reader, [`Ingested`].
//!
//! In `output.path/ingest/`:
//! - `mesh.ply` — binary PLY (ingest's writer): vertex positions (+ normals when the scan has them),
//!   triangles, and per-face `int` columns `object` (index into `scene.json`'s `objects`), `segment_id`,
//!   `category_id`, `material_id` (the scan's ids, `-1` where absent).
//! - `scene.json` — `{"format": "ipt-ingest/1", "objects": [{"id", "label", "triangles"}],
//!   "views": [{"name", "image_path", "camera"}]}`; cameras in the convention of `ingest::camera`.

use std::path::Path;

use glam::{Affine3A, Vec3};
use ingest::View;
use ingest::scan::ObjectInfo;
use serde::{Deserialize, Serialize};

use crate::stage_contract::StageError;

/// Mesh file name inside the stage directory.
pub const MESH_FILE: &str = "mesh.ply";
/// Object and view index file name inside the stage directory.
pub const SCENE_FILE: &str = "scene.json";
/// Format tag of `scene.json`.
pub const SCENE_FORMAT: &str = "ipt-ingest/1";

/// `scene.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneIndex {
    pub format: String,
    pub objects: Vec<ObjectInfo>,
    pub views: Vec<View>,
}

/// The ingested scene as later stages read it.
#[derive(Debug, Clone, PartialEq)]
pub struct Ingested {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub triangles: Vec<[u32; 3]>,
    /// Index into `objects` per triangle.
    pub face_object: Vec<u32>,
    pub objects: Vec<ObjectInfo>,
    pub views: Vec<View>,
}

impl Ingested {
    /// Reads `run_dir/ingest/`.
    pub fn read(run_dir: &Path) -> Result<Self, StageError> {
        let dir = run_dir.join("ingest");
        let scene_path = dir.join(SCENE_FILE);
        let text = std::fs::read_to_string(&scene_path)
            .map_err(|source| StageError::Io { path: scene_path.clone(), source })?;
        let index: SceneIndex = serde_json::from_str(&text)
            .map_err(|e| StageError::Artefact { path: scene_path.clone(), message: e.to_string() })?;
        if index.format != SCENE_FORMAT {
            return Err(StageError::OldFormat {
                path: scene_path,
                found: index.format,
                expected: SCENE_FORMAT,
                stage: "ingest",
            });
        }
        let mesh_path = dir.join(MESH_FILE);
        let ply = ingest::ply::read_ply(&mesh_path)?.mesh;
        let face_object = super::face_objects(&ply, index.objects.len(), &mesh_path, SCENE_FILE)?;
        Ok(Self {
            positions: ply.positions,
            normals: ply.normals,
            triangles: ply.triangles,
            face_object,
            objects: index.objects,
            views: index.views,
        })
    }

    /// The tracer's scene input: one material slot and one emitter slot per object.
    #[must_use]
    pub fn scene_input(&self) -> tracer::SceneInput {
        tracer::SceneInput {
            positions: self.positions.clone(),
            triangles: self.triangles.clone(),
            normals: self.normals.clone(),
            material_of_tri: self.face_object.clone(),
            emitter_of_tri: self.face_object.clone(),
        }
    }

    /// Triangle indices of each object.
    #[must_use]
    pub fn object_triangles(&self) -> Vec<Vec<u32>> {
        let mut out = vec![Vec::new(); self.objects.len()];
        for (t, &o) in self.face_object.iter().enumerate() {
            out[o as usize].push(t as u32);
        }
        out
    }

    /// Object labels (`"unlabelled"` where the scan has none).
    #[must_use]
    pub fn label(&self, object: usize) -> String {
        self.objects[object].label.clone().unwrap_or_else(|| "unlabelled".to_owned())
    }
}

/// A pinhole `ingest` camera (zero distortion, as prepared views are) as the tracer's camera.
#[must_use]
pub fn tracer_camera(c: &ingest::camera::Camera) -> tracer::Camera {
    tracer::Camera {
        width: c.width,
        height: c.height,
        fx: c.intrinsics.fx as f32,
        fy: c.intrinsics.fy as f32,
        cx: c.intrinsics.cx as f32,
        cy: c.intrinsics.cy as f32,
        cam_to_world: Affine3A::from_mat4(c.cam_to_world.as_mat4()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ingest::ply::{FaceProperty, FaceValues, PlyMesh};

    fn write_run(dir: &Path, face_object: Vec<i32>, objects: usize) {
        let ingest_dir = dir.join("ingest");
        std::fs::create_dir_all(&ingest_dir).unwrap();
        let ply = PlyMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            normals: None,
            triangles: vec![[0, 1, 2], [0, 1, 3]],
            face_props: vec![FaceProperty { name: "object".into(), values: FaceValues::I32(face_object) }],
        };
        let path = ingest_dir.join(MESH_FILE);
        std::fs::write(&path, ingest::ply::encode_ply(&path, &ply).unwrap()).unwrap();
        let index = SceneIndex {
            format: SCENE_FORMAT.into(),
            objects: (0..objects).map(|i| ObjectInfo { id: 10 + i as i64, label: None, triangles: 1 }).collect(),
            views: Vec::new(),
        };
        std::fs::write(ingest_dir.join(SCENE_FILE), serde_json::to_string(&index).unwrap()).unwrap();
    }

    #[test]
    fn read_back_groups_triangles_by_object() {
        let dir = tempfile::tempdir().unwrap();
        write_run(dir.path(), vec![1, 0], 2);
        let s = Ingested::read(dir.path()).unwrap();
        assert_eq!(s.object_triangles(), [vec![1], vec![0]]);
        assert_eq!(s.label(0), "unlabelled");
        let input = s.scene_input();
        assert_eq!(input.material_of_tri, [1, 0]);
        assert_eq!(input.emitter_of_tri, [1, 0]);
    }

    #[test]
    fn an_object_index_outside_the_table_names_the_face() {
        let dir = tempfile::tempdir().unwrap();
        write_run(dir.path(), vec![0, 2], 2);
        let e = Ingested::read(dir.path()).unwrap_err();
        assert!(e.to_string().contains("face 1: object 2"), "{e}");
    }

    #[test]
    fn pinhole_camera_converts_with_the_same_rays() {
        let c = ingest::camera::Camera {
            width: 8,
            height: 6,
            intrinsics: ingest::camera::Intrinsics { fx: 10.0, fy: 12.0, cx: 3.5, cy: 2.5 },
            distortion: ingest::camera::Distortion::default(),
            cam_to_world: glam::DMat4::from_translation(glam::DVec3::new(1.0, 2.0, 3.0)),
        };
        let t = tracer_camera(&c);
        // The principal point looks down −z from the camera centre (both crates' documented convention).
        let (o, d) = t.ray(glam::Vec2::new(3.5, 2.5));
        assert_eq!(o, Vec3::new(1.0, 2.0, 3.0));
        assert!((d - Vec3::NEG_Z).length() < 1e-6);
        // One focal length right of it: 45° towards +x.
        let (_, d) = t.ray(glam::Vec2::new(13.5, 2.5));
        assert!((d - Vec3::new(1.0, 0.0, -1.0).normalize()).length() < 1e-6, "{d}");
    }
}
