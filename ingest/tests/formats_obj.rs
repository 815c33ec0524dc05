//! OBJ scans (objects by `o`/`g` or by material, cameras from transforms.json), the Mitsuba Cornell box meshes
//! from ../shared/data, and layout detection errors.

mod formats_common;

use std::path::{Path, PathBuf};

use formats_common::{assert_mentions, write_image};
use ingest::{GroupBy, ScanFormat, load_scan, objects_seen_by_no_camera};

const OBJ: &str = "mtllib room.mtl
o floor
v -2 -2 0
v 2 -2 0
v 2 2 0
v -2 2 0
usemtl white
f 1 2 3 4
o box
v 0 0 0
v 0.5 0 0
v 0.5 0.5 0
v 0 0.5 1
usemtl red
f 5 6 7
f 5 7 8
usemtl white
f 5 6 8
o hidden
v 0 0 50
v 1 0 50
v 0 1 50
usemtl red
f 9 10 11
f 9 9 10
";

fn write_obj_scan(dir: &Path) {
    std::fs::write(dir.join("room.obj"), OBJ).unwrap();
    std::fs::write(dir.join("room.mtl"), "newmtl white\nKd 0.8 0.8 0.8\nnewmtl red\nKd 0.8 0.1 0.1\n").unwrap();
    write_image(&dir.join("cam.png"), 32, 24);
    // A camera 5 m above the floor looking straight down (OpenGL: -z_cam = -z_world): identity rotation.
    std::fs::write(
        dir.join("transforms.json"),
        r#"{"fl_x": 20, "fl_y": 20, "cx": 16, "cy": 12, "w": 32, "h": 24,
            "frames": [{"file_path": "cam.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,5],[0,0,0,1]]}]}"#,
    )
    .unwrap();
}

#[test]
fn obj_objects_by_group_and_by_material() {
    let dir = tempfile::tempdir().unwrap();
    write_obj_scan(dir.path());
    assert_eq!(ingest::scan::detect_format(dir.path()).unwrap(), ScanFormat::Obj);
    let scan = load_scan(dir.path(), ScanFormat::Auto, GroupBy::OBJ_GROUP).unwrap();
    // Quad → 2 triangles; the degenerate `f 9 9 10` is dropped.
    assert_eq!(scan.mesh.triangles.len(), 2 + 3 + 1);
    let by_label: Vec<(Option<&str>, usize)> = scan.objects.iter().map(|o| (o.label.as_deref(), o.triangles)).collect();
    assert_eq!(by_label, vec![(Some("floor"), 2), (Some("box"), 3), (Some("hidden"), 1)]);
    assert_eq!(scan.views.len(), 1);
    let unseen = objects_seen_by_no_camera(&scan);
    assert_eq!(unseen.iter().map(|&o| scan.objects[o].label.as_deref()).collect::<Vec<_>>(), vec![Some("hidden")]);

    let by_mat = load_scan(dir.path(), ScanFormat::Obj, GroupBy::OBJ_MATERIAL).unwrap();
    let mats: Vec<(Option<&str>, usize)> = by_mat.objects.iter().map(|o| (o.label.as_deref(), o.triangles)).collect();
    assert_eq!(mats, vec![(Some("white"), 3), (Some("red"), 3)]);
}

#[test]
fn obj_nan_vertex_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.obj"), "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n").unwrap();
    let err = load_scan(dir.path(), ScanFormat::Obj, GroupBy::OBJ_GROUP).unwrap_err();
    assert_mentions(&err, &["bad.obj", "vertex 2", "not finite"]);
}

#[test]
fn obj_face_index_out_of_range_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap();
    let err = load_scan(dir.path(), ScanFormat::Obj, GroupBy::OBJ_GROUP).unwrap_err();
    assert_mentions(&err, &["bad.obj"]);
}

#[test]
fn unknown_layout_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "nothing here").unwrap();
    let err = load_scan(dir.path(), ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["unknown scan layout"]);
    std::fs::create_dir(dir.path().join("house_segmentations")).unwrap();
    let err = load_scan(dir.path(), ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["house_segmentations/", "neither"]);
}

fn shared_data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
}

/// Triangles a fan triangulation makes from an OBJ's `f` lines: Σ (arity − 2).
fn fan_triangles(text: &str) -> usize {
    text.lines().filter_map(|l| l.strip_prefix("f ")).map(|f| f.split_ascii_whitespace().count() - 2).sum()
}

#[test]
fn mitsuba_cornell_box_meshes_load_as_objects() {
    let meshes = shared_data().join("mitsuba-cbox/meshes");
    if !meshes.is_dir() {
        eprintln!("skipping: {} is absent", meshes.display());
        return;
    }
    let files: Vec<PathBuf> = {
        let mut f: Vec<PathBuf> = std::fs::read_dir(&meshes)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "obj"))
            .collect();
        f.sort();
        f
    };
    let scan = load_scan(&meshes, ScanFormat::Obj, GroupBy::OBJ_GROUP).unwrap();
    // One object per file (these files have no o/g lines), named after the file.
    assert_eq!(scan.objects.len(), files.len());
    let expected: usize = files.iter().map(|f| fan_triangles(&std::fs::read_to_string(f).unwrap())).sum();
    assert_eq!(scan.mesh.triangles.len(), expected);
    for (o, f) in scan.objects.iter().zip(&files) {
        let stem = f.file_stem().unwrap().to_string_lossy();
        // Faces before any `o`/`g` line form a group named after the file.
        assert_eq!(o.label.as_deref(), Some(&*stem));
        assert_eq!(o.triangles, fan_triangles(&std::fs::read_to_string(f).unwrap()));
    }
    // The box is about 556 x 549 x 559 units (Cornell box measurements, in mm).
    let (lo, hi) =
        scan.mesh.positions.iter().fold((glam::Vec3::MAX, glam::Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let extent = hi - lo;
    assert!(extent.min_element() > 540.0 && extent.max_element() < 560.0, "extent {extent}");
    assert!(scan.views.is_empty());
}

#[test]
fn bitterli_staircase_meshes_load_with_every_face() {
    let models = shared_data().join("bitterli-staircase2/models");
    if !models.is_dir() {
        eprintln!("skipping: {} is absent", models.display());
        return;
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(&models)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .collect();
    files.sort();
    // Before zero-area removal, every `f` line becomes arity - 2 triangles, one group per file.
    let (labeled, _) = ingest::obj::load_obj_dir(&models).unwrap();
    let expected: usize = files.iter().map(|f| fan_triangles(&std::fs::read_to_string(f).unwrap())).sum();
    assert_eq!(labeled.mesh.triangles.len(), expected);
    assert_eq!(labeled.segment_labels.len(), files.len());
    for (k, f) in files.iter().enumerate() {
        let stem = f.file_stem().unwrap().to_string_lossy();
        let n = labeled.mesh.face_segment.iter().filter(|&&s| s == k as i32).count();
        assert_eq!(n, fan_triangles(&std::fs::read_to_string(f).unwrap()), "{stem}");
        assert_eq!(labeled.segment_labels[&(k as i32)], stem);
    }
    let scan = load_scan(&models, ScanFormat::Obj, GroupBy::OBJ_GROUP).unwrap();
    assert!(scan.mesh.triangles.len() <= expected);
    assert!(scan.mesh.positions.iter().all(|p| p.is_finite()));
}
