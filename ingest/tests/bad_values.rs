//! Bad values inside otherwise valid files. Each is either refused with a one-line error naming the file, or
//! masked with a count returned to the caller — never a silent wrong result:
//! - NaN/Inf/negative EXR pixels: masked and counted (`PixelReport`); one hot pixel must not stop a run, and the
//!   mask keeps it out of every loss.
//! - Non-rigid or NaN poses, fx ≤ 0 or non-finite intrinsics, duplicated view names, photos whose size differs
//!   from their calibration: refused (no correct result can be made from them).
//! - Objects whose triangles all have zero area: dropped and listed in `Scan::removed`.

mod formats_common;

use formats_common::{assert_mentions, write_image};
use glam::DMat4;
use ingest::camera::{Camera, Distortion, Intrinsics};
use ingest::mesh::{LabeledMesh, Mesh};
use ingest::photo::{PhotoError, PhotoOptions, prepare_view_counted};
use ingest::{GroupBy, ScanFormat, load_scan};

fn one_line(e: &impl std::fmt::Display) {
    assert!(!e.to_string().contains('\n'), "{e}");
}

fn pinhole(width: u32, height: u32) -> Camera {
    Camera {
        width,
        height,
        intrinsics: Intrinsics { fx: 10.0, fy: 10.0, cx: 3.0, cy: 2.0 },
        distortion: Distortion::default(),
        cam_to_world: DMat4::IDENTITY,
    }
}

#[test]
fn exr_nan_inf_negative_pixels_are_masked_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hot.exr");
    let bytes = ingest::photo::exr::encode_rgb(6, 4, ingest::photo::exr::Compression::Fast, |x, y| match (x, y) {
        (0, 0) => [f32::NAN, 1.0, 1.0],
        (1, 0) => [f32::INFINITY, 1.0, 1.0],
        (2, 0) => [1.0, -0.5, 1.0],
        (3, 0) => [-1.0, f32::NEG_INFINITY, 1.0],
        _ => [0.25, 0.5, 0.75],
    })
    .unwrap();
    std::fs::write(&path, bytes).unwrap();
    let (_, img, report) = prepare_view_counted(&path, &pinhole(6, 4), &PhotoOptions::default()).unwrap();
    assert_eq!((report.non_finite, report.negative, report.masked()), (3, 1, 4));
    assert_eq!(img.valid_count(), 24 - 4);
    for x in 0..4 {
        assert!(!img.is_valid(x, 0));
        assert!(img.pixel(x, 0).iter().all(|v| v.is_finite() && *v >= 0.0), "{:?}", img.pixel(x, 0));
    }
}

#[test]
fn photo_whose_size_differs_from_its_camera_is_refused_before_decoding() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small.png");
    write_image(&path, 5, 4);
    let err = prepare_view_counted(&path, &pinhole(6, 4), &PhotoOptions::default()).unwrap_err();
    assert!(matches!(err, PhotoError::WrongSize { expected: (6, 4), found: (5, 4), .. }), "{err:?}");
    assert_mentions(&err, &["small.png", "5x4", "6x4"]);
    one_line(&err);
}

fn conf_with(intrinsics: &str, pose: &str) -> Vec<u8> {
    format!("intrinsics_matrix {intrinsics}\nscan d.png c.jpg {pose}\n").into_bytes()
}

const IDENTITY: &str = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";
const GOOD_K: &str = "500 0 320 0 500 240 0 0 1";

#[test]
fn non_rigid_or_nan_poses_are_refused_in_every_format() {
    let conf = std::path::Path::new("/scan/house.conf");
    for (pose, why) in [
        ("2 0 0 0 0 2 0 0 0 0 2 0 0 0 0 1", "not rigid"),
        ("1 0.3 0 0 0 1 0 0 0 0 1 0 0 0 0 1", "not rigid"),
        ("-1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1", "reflection"),
        ("1 0 0 nan 0 1 0 0 0 0 1 0 0 0 0 1", "NaN"),
        ("1 0 0 inf 0 1 0 0 0 0 1 0 0 0 0 1", "NaN or infinite"),
        ("1 0 0 0 0 1 0 0 0 0 1 0 0 0 1 1", "not affine"),
        ("0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 1", "not invertible"),
    ] {
        let err = ingest::matterport::parse_conf(conf, &conf_with(GOOD_K, pose)).unwrap_err();
        assert_mentions(&err, &["house.conf:2", why]);
        one_line(&err);
        let raw = std::path::Path::new("/scan/u_pose_0_0.txt");
        let err = ingest::matterport::parse_raw_pose(raw, pose.as_bytes()).unwrap_err();
        assert_mentions(&err, &["u_pose_0_0.txt", why]);
    }
    // COLMAP: a quaternion that is not unit, a NaN translation.
    let images = std::path::Path::new("/scan/images.txt");
    for (line, why) in [("1 2 0 0 0 0 0 0 1 a.jpg\n\n", "norm"), ("1 1 0 0 0 nan 0 0 1 a.jpg\n\n", "finite")] {
        let err = ingest::colmap::parse_images(images, line.as_bytes()).unwrap_err();
        assert_mentions(&err, &["images.txt:1", why]);
    }
}

#[test]
fn bad_focal_lengths_are_refused_in_every_format() {
    let conf = std::path::Path::new("/scan/house.conf");
    for k in
        ["0 0 320 0 500 240 0 0 1", "-500 0 320 0 500 240 0 0 1", "500 0 nan 0 500 240 0 0 1", "inf 0 1 0 1 1 0 0 1"]
    {
        let err = ingest::matterport::parse_conf(conf, &conf_with(k, IDENTITY)).unwrap_err();
        assert_mentions(&err, &["house.conf:1", "positive fx"]);
    }
    let raw = std::path::Path::new("/scan/u_intrinsics_0.txt");
    for text in [
        "640 480 0 500 320 240 0 0 0 0 0",
        "640 480 500 -1 320 240 0 0 0 0 0",
        "640 480 nan 500 320 240 0 0 0 0 0",
        "640 480 500 500 320 240 inf 0 0 0 0",
        "1e20 480 500 500 320 240 0 0 0 0 0",
        "640.5 480 500 500 320 240 0 0 0 0 0",
    ] {
        let err = ingest::matterport::parse_raw_intrinsics(raw, text.as_bytes()).unwrap_err();
        assert_mentions(&err, &["u_intrinsics_0.txt:1"]);
        one_line(&err);
    }
    let cams = std::path::Path::new("/scan/cameras.txt");
    for line in [
        "1 PINHOLE 100 80 0 90 50 40",
        "1 SIMPLE_PINHOLE 100 80 -3 50 40",
        "1 PINHOLE 100 80 nan 1 1 1",
        "1 PINHOLE 0 80 1 1 1 1",
    ] {
        let err = ingest::colmap::parse_cameras(cams, line.as_bytes()).unwrap_err();
        assert_mentions(&err, &["cameras.txt:1"]);
    }
}

/// A transforms.json beside a 13×7 image `a.png`.
fn transforms_dir(json: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    write_image(&dir.path().join("a.png"), 13, 7);
    write_image(&dir.path().join("b.jpg"), 13, 7);
    write_image(&dir.path().join("sub/a.jpg"), 13, 7);
    std::fs::write(dir.path().join("transforms.json"), json).unwrap();
    dir
}

const M: &str = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";

#[test]
fn transforms_focal_from_a_zero_or_full_angle_is_refused() {
    for angle in ["0", "3.141592653589793", "-0.5", "1e-320"] {
        let dir = transforms_dir(&format!(
            r#"{{"camera_angle_x": {angle}, "frames": [{{"file_path": "a.png", "transform_matrix": {M}}}]}}"#
        ));
        let err = ingest::transforms::load_views(&dir.path().join("transforms.json")).unwrap_err();
        assert_mentions(&err, &["transforms.json", "frame 0", "focal"]);
        one_line(&err);
    }
}

#[test]
fn duplicated_view_names_are_refused() {
    // transforms.json: the same image twice, and two images with the same stem in different directories.
    for files in [("a.png", "a.png"), ("a.png", "sub/a.jpg")] {
        let dir = transforms_dir(&format!(
            r#"{{"fl_x": 10, "frames": [{{"file_path": "{}", "transform_matrix": {M}}},
                {{"file_path": "{}", "transform_matrix": {M}}}]}}"#,
            files.0, files.1
        ));
        let err = ingest::transforms::load_views(&dir.path().join("transforms.json")).unwrap_err();
        assert_mentions(&err, &["transforms.json", "share the view name \"a\""]);
        one_line(&err);
    }
    // COLMAP.
    let dir = tempfile::tempdir().unwrap();
    write_image(&dir.path().join("images/a.png"), 13, 7);
    std::fs::write(dir.path().join("cameras.txt"), "1 PINHOLE 13 7 10 10 6.5 3.5\n").unwrap();
    std::fs::write(dir.path().join("images.txt"), "1 1 0 0 0 0 0 0 1 a.png\n\n2 1 0 0 0 1 0 0 1 a.png\n\n").unwrap();
    let err = ingest::colmap::load_views(dir.path(), &dir.path().join("images")).unwrap_err();
    assert_mentions(&err, &["images.txt", "share the view name \"a\""]);
}

#[test]
fn colmap_photo_whose_size_differs_from_its_camera_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    write_image(&dir.path().join("images/a.png"), 13, 7);
    std::fs::write(dir.path().join("cameras.txt"), "1 PINHOLE 26 14 10 10 6.5 3.5\n").unwrap();
    std::fs::write(dir.path().join("images.txt"), "1 1 0 0 0 0 0 0 1 a.png\n\n").unwrap();
    let err = ingest::colmap::load_views(dir.path(), &dir.path().join("images")).unwrap_err();
    assert_mentions(&err, &["a.png", "13x7", "26x14", "images.txt:1"]);
    one_line(&err);
}

#[test]
fn object_whose_triangles_all_have_zero_area_is_dropped_and_reported() {
    let positions = vec![
        glam::Vec3::ZERO,
        glam::Vec3::X,
        glam::Vec3::Y,
        glam::Vec3::new(2.0, 0.0, 0.0),
        glam::Vec3::new(3.0, 0.0, 0.0),
    ];
    // Object 1: a real triangle; object 2: two collinear/point triangles; object 3: one of each.
    let triangles = vec![[0, 1, 2], [1, 3, 4], [3, 3, 3], [0, 1, 2], [0, 3, 4]];
    let mut mesh = Mesh::without_ids(positions, None, triangles);
    mesh.face_segment = vec![1, 2, 2, 3, 3];
    let mut labeled = LabeledMesh { mesh, ..LabeledMesh::default() };
    labeled.segment_labels.insert(2, "rod".into());
    let scan = ingest::scan::assemble(labeled, std::path::Path::new("m.ply"), Vec::new(), GroupBy::Segment);
    assert_eq!(scan.removed.zero_area_triangles, 3);
    assert_eq!(scan.objects.iter().map(|o| (o.id, o.triangles)).collect::<Vec<_>>(), vec![(1, 1), (3, 1)]);
    let lost: Vec<(i64, Option<&str>, usize)> =
        scan.removed.objects_without_area.iter().map(|o| (o.id, o.label.as_deref(), o.triangles)).collect();
    assert_eq!(lost, vec![(2, Some("rod"), 2)]);
}

#[test]
fn ply_values_outside_their_type_or_not_finite_are_refused() {
    let path = std::path::Path::new("/scan/m.ply");
    let header = |body: &str, extra: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n{extra}\
             element face 1\nproperty list uchar int vertex_indices\nproperty uchar category_id\nend_header\n{body}"
        )
    };
    // A uchar column holding 300 (or 1e38) used to be clamped to 255.
    for v in ["300", "1e38", "-1"] {
        let text = header(&format!("0 0 0\n1 0 0\n0 1 0\n3 0 1 2 {v}\n"), "");
        let err = ingest::ply::read_ply_bytes(path, text.as_bytes()).unwrap_err();
        assert_mentions(&err, &["m.ply", "face 0", "category_id", "outside the range"]);
    }
    // NaN normals.
    let text = header(
        "0 0 0 0 0 1\n1 0 0 0 nan 1\n0 1 0 0 0 1\n3 0 1 2 4\n",
        "property float nx\nproperty float ny\nproperty float nz\n",
    );
    let err = ingest::ply::read_ply_bytes(path, text.as_bytes()).unwrap_err();
    assert_mentions(&err, &["m.ply", "vertex 1", "normal"]);
    // Two vertex elements: faces would be checked against one and index the other.
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                element face 1\nproperty list uchar int vertex_indices\nelement vertex 1\nproperty float x\n\
                property float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n5 5 5\n";
    let err = ingest::ply::read_ply_bytes(path, text.as_bytes()).unwrap_err();
    assert_mentions(&err, &["m.ply", "more than one `vertex`"]);
    // An element without properties and an enormous count is skipped at once.
    let text = "ply\nformat binary_little_endian 1.0\nelement nothing 18446744073709551615\nelement vertex 0\n\
                property float x\nproperty float y\nproperty float z\nelement face 0\n\
                property list uchar int vertex_indices\nend_header\n";
    let start = std::time::Instant::now();
    let read = ingest::ply::read_ply_bytes(path, text.as_bytes()).unwrap();
    assert_eq!(read.face_count, 0);
    // Generous: the read takes microseconds; the loop it replaced took hours.
    assert!(start.elapsed() < std::time::Duration::from_secs(1));
}

#[test]
fn obj_indices_that_overflow_are_refused_with_the_line() {
    let dir = tempfile::tempdir().unwrap();
    for (face, what) in [
        ("f 1/1/-2147483648 2/1/1 3/1/1", "normal index"),
        ("f 1 2 0", "vertex index \"0\""),
        ("f 1 2 9223372036854775807", "vertex index"),
        ("f 1 2 -4", "vertex index \"-4\""),
        ("f 1/1/1/1 2 3", "more than 3"),
    ] {
        std::fs::write(dir.path().join("bad.obj"), format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n{face}\n"))
            .unwrap();
        let err = load_scan(dir.path(), ScanFormat::Obj, GroupBy::OBJ_GROUP).unwrap_err();
        assert_mentions(&err, &["bad.obj:6", what]);
    }
    // A malformed MTL value line (tobj panicked on `Kd` with one number) costs nothing: only names are read.
    std::fs::write(dir.path().join("bad.obj"), "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n")
        .unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 0.8\n").unwrap();
    let (labeled, _) = ingest::obj::load_obj_dir(dir.path()).unwrap();
    assert_eq!(labeled.material_labels.values().collect::<Vec<_>>(), vec!["red"]);
}
