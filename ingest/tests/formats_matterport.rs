//! Matterport3D layout (undistorted `.conf` and raw variants) on scans the tests write, with one test per
//! bad-input case.

mod formats_common;

use std::path::{Path, PathBuf};

use formats_common::{assert_mentions, row_major_text, write_exr, write_image};
use glam::{DMat4, DVec3, DVec4, Vec3};
use ingest::camera::Camera;
use ingest::ply::{FaceProperty, FaceValues, PlyMesh, write_ply};
use ingest::{GroupBy, IngestError, ScanFormat, load_scan, objects_seen_by_no_camera};

/// Camera-to-world for a camera at `c` looking along world +y with world +z up (OpenGL camera frame:
/// x_cam = +x, y_cam = +z, z_cam = -y).
fn looking_along_y(c: DVec3) -> DMat4 {
    DMat4::from_cols(DVec4::X, DVec4::Z, -DVec4::Y, c.extend(1.0))
}

/// Appends an axis-aligned box (12 triangles, outward winding irrelevant here).
fn push_box(m: &mut PlyMesh, lo: Vec3, hi: Vec3) {
    let base = m.positions.len() as u32;
    for i in 0..8 {
        m.positions.push(Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        ));
    }
    for [a, b, c, d] in [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]] {
        m.triangles.push([base + a, base + b, base + c]);
        m.triangles.push([base + a, base + c, base + d]);
    }
}

struct House {
    root: PathBuf,
    conf_lines: Vec<String>,
    poses: Vec<DMat4>,
}

const CAM_XS: [f64; 3] = [-1.0, 0.0, 1.0];

/// Writes a house: a "chair" box (segment 10) with two degenerate triangles, a "table" box (segment 20), and a
/// "window" box (segment 30) behind every camera; three cameras in two intrinsics blocks.
fn make_house(root: &Path) -> House {
    let seg_dir = root.join("house_segmentations");
    std::fs::create_dir_all(&seg_dir).unwrap();
    let mut m = PlyMesh::default();
    let (mut seg, mut cat, mut mat) = (Vec::new(), Vec::new(), Vec::new());
    let mut tag = |m: &PlyMesh, s: i32, c: i32, mats: [i32; 2]| {
        while seg.len() < m.triangles.len() {
            let k = seg.len();
            seg.push(s);
            cat.push(c);
            mat.push(mats[k % 2]);
        }
    };
    push_box(&mut m, Vec3::new(-0.5, -0.5, 0.0), Vec3::new(0.5, 0.5, 1.0));
    // Degenerate: a repeated vertex, and three collinear vertices.
    let b = m.positions.len() as u32;
    m.positions.extend([Vec3::new(0.0, -0.6, 0.2), Vec3::new(0.1, -0.6, 0.3), Vec3::new(0.2, -0.6, 0.4)]);
    m.triangles.push([b, b, b + 1]);
    m.triangles.push([b, b + 1, b + 2]);
    tag(&m, 10, 5, [100, 101]);
    push_box(&mut m, Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 0.8));
    tag(&m, 20, 7, [200, 200]);
    push_box(&mut m, Vec3::new(-0.5, -21.0, 0.0), Vec3::new(0.5, -20.0, 1.0));
    tag(&m, 30, 9, [300, 300]);
    m.face_props = vec![
        FaceProperty { name: "material_id".into(), values: FaceValues::I32(mat.clone()) },
        FaceProperty { name: "segment_id".into(), values: FaceValues::I32(seg) },
        FaceProperty { name: "category_id".into(), values: FaceValues::I32(cat) },
    ];
    write_ply(&seg_dir.join("h1.ply"), &m).unwrap();
    std::fs::write(seg_dir.join("h1.fsegs.json"), format!("{{\"segIndices\": {mat:?}}}")).unwrap();
    std::fs::write(
        seg_dir.join("h1.semseg.json"),
        r#"{"segGroups": [
            {"id": 0, "objectId": 10, "label": "chair", "segments": [100, 101], "obb": {}},
            {"id": 1, "objectId": 20, "label": "table", "segments": [200]},
            {"id": 2, "objectId": 30, "label": "window", "segments": [300]}]}"#,
    )
    .unwrap();

    let img_dir = root.join("undistorted_color_images");
    let poses: Vec<DMat4> = CAM_XS.iter().map(|&x| looking_along_y(DVec3::new(x, -5.0, 0.5))).collect();
    let mut conf_lines = vec![
        "dataset matterport".to_string(),
        "n_images 3".into(),
        "depth_directory undistorted_depth_images".into(),
        "color_directory undistorted_color_images".into(),
        "intrinsics_matrix 50 0 32  0 50 24  0 0 1".into(),
    ];
    for (i, pose) in poses.iter().enumerate() {
        if i == 2 {
            conf_lines.push("intrinsics_matrix 60 0 40  0 60 30  0 0 1".into());
        }
        let (w, h) = if i == 2 { (80, 60) } else { (64, 48) };
        write_image(&img_dir.join(format!("pano_i1_{i}.jpg")), w, h);
        conf_lines.push(format!("scan pano_d1_{i}.png pano_i1_{i}.jpg {}", row_major_text(pose)));
    }
    // A linear sibling for the second image: it must be preferred.
    write_exr(&img_dir.join("pano_i1_1.exr"), 64, 48);
    std::fs::create_dir_all(root.join("undistorted_camera_parameters")).unwrap();
    let house = House { root: root.to_path_buf(), conf_lines, poses };
    write_conf(&house, &house.conf_lines);
    house
}

fn conf_path(h: &House) -> PathBuf {
    h.root.join("undistorted_camera_parameters").join("h1.conf")
}

fn write_conf(h: &House, lines: &[String]) {
    std::fs::write(conf_path(h), lines.join("\n") + "\n").unwrap();
}

/// Replaces conf line `line_no` (1-based) and returns the load error.
fn load_with_conf_line(h: &House, line_no: usize, text: String) -> IngestError {
    let mut lines = h.conf_lines.clone();
    lines[line_no - 1] = text;
    write_conf(h, &lines);
    load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap_err()
}

#[test]
fn loads_mesh_objects_labels_and_views() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    assert_eq!(ingest::scan::detect_format(&h.root).unwrap(), ScanFormat::Matterport);
    let scan = load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap();
    // 38 triangles written, the two degenerate ones dropped.
    assert_eq!(scan.mesh.triangles.len(), 36);
    let ids: Vec<i64> = scan.objects.iter().map(|o| o.id).collect();
    assert_eq!(ids, vec![10, 20, 30]);
    let labels: Vec<&str> = scan.objects.iter().map(|o| o.label.as_deref().unwrap()).collect();
    assert_eq!(labels, vec!["chair", "table", "window"]);
    assert!(scan.objects.iter().all(|o| o.triangles == 12));
    for (t, &o) in scan.face_object.iter().enumerate() {
        assert_eq!(scan.objects[o as usize].id, i64::from(scan.mesh.face_segment[t]));
    }
    assert_eq!(scan.views.len(), 3);
    let names: Vec<&str> = scan.views.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, vec!["pano_i1_0", "pano_i1_1", "pano_i1_2"]);
    assert_eq!(scan.views[0].image_path.extension().unwrap(), "jpg");
    assert_eq!(scan.views[1].image_path.extension().unwrap(), "exr", "linear sibling preferred");
    let sizes: Vec<(u32, u32)> = scan.views.iter().map(|v| (v.camera.width, v.camera.height)).collect();
    assert_eq!(sizes, vec![(64, 48), (64, 48), (80, 60)]);
    // The stateful intrinsics: the third scan line follows the second intrinsics_matrix.
    assert_eq!(scan.views[1].camera.intrinsics.fx, 50.0);
    assert_eq!(scan.views[2].camera.intrinsics.fx, 60.0);
    assert_eq!(scan.views[2].camera.intrinsics.cy, 30.0);
    for (v, pose) in scan.views.iter().zip(&h.poses) {
        assert!(v.camera.cam_to_world.abs_diff_eq(*pose, 1e-12));
        assert!(v.camera.distortion.is_identity());
    }
}

#[test]
fn grouping_by_category_and_material() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    let by_cat = load_scan(&h.root, ScanFormat::Matterport, GroupBy::Category).unwrap();
    assert_eq!(by_cat.objects.iter().map(|o| o.id).collect::<Vec<_>>(), vec![5, 7, 9]);
    let by_mat = load_scan(&h.root, ScanFormat::Matterport, GroupBy::Material).unwrap();
    assert_eq!(by_mat.objects.iter().map(|o| o.id).collect::<Vec<_>>(), vec![100, 101, 200, 300]);
    // Over-segments take the label of the semseg group listing them.
    assert_eq!(by_mat.objects[1].label.as_deref(), Some("chair"));
    assert_eq!(by_mat.objects.iter().map(|o| o.triangles).sum::<usize>(), 36);
}

#[test]
fn conf_camera_projects_like_hand_computation() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    let scan = load_scan(&h.root, ScanFormat::Matterport, GroupBy::Segment).unwrap();
    for (v, &cx_world) in scan.views.iter().zip(&CAM_XS) {
        let cam: &Camera = &v.camera;
        let p = DVec3::new(0.3, 0.0, 1.2);
        // Camera at (x, -5, 0.5) looking along +y, z up: depth = 5, right = p.x - x, up = p.z - 0.5.
        let (depth, right, up) = (5.0, p.x - cx_world, p.z - 0.5);
        let k = cam.intrinsics;
        let expect = (k.cx + k.fx * right / depth, k.cy - k.fy * up / depth);
        let got = cam.project_world(p).unwrap();
        assert!((got.x - expect.0).abs() < 1e-9 && (got.y - expect.1).abs() < 1e-9, "{got:?} vs {expect:?}");
        // A point behind the camera does not project.
        assert!(cam.project_world(DVec3::new(0.0, -6.0, 0.5)).is_none());
    }
}

#[test]
fn reports_objects_seen_by_no_camera() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    let scan = load_scan(&h.root, ScanFormat::Matterport, GroupBy::Segment).unwrap();
    let unseen = objects_seen_by_no_camera(&scan);
    assert_eq!(unseen.len(), 1);
    assert_eq!(scan.objects[unseen[0]].label.as_deref(), Some("window"));
}

#[test]
fn zero_area_triangles_are_dropped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    let ply = h.root.join("house_segmentations/h1.ply");
    let mut labeled = ingest::matterport::mesh_from_ply(&ply, None).unwrap();
    assert_eq!(labeled.mesh.triangles.len(), 38);
    assert_eq!(labeled.mesh.drop_zero_area(&ply), 2);
    assert_eq!(labeled.mesh.triangles.len(), 36);
    assert_eq!(labeled.mesh.face_segment.len(), 36);
    assert_eq!(labeled.mesh.face_material.len(), 36);
    assert!((0..36).all(|t| !labeled.mesh.is_zero_area(t)));
    // Nothing left to drop.
    assert_eq!(labeled.mesh.drop_zero_area(&ply), 0);
}

#[test]
fn conf_scan_line_with_wrong_token_count() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    let line = h.conf_lines[5].rsplit_once(' ').unwrap().0.to_string();
    let err = load_with_conf_line(&h, 6, line);
    assert_mentions(&err, &["h1.conf:6", "17 values, expected 18"]);
    let err = load_with_conf_line(&h, 5, "intrinsics_matrix 50 0 32 0 50 24 0 0".into());
    assert_mentions(&err, &["h1.conf:5", "8 values, expected 9"]);
}

#[test]
fn conf_non_invertible_pose() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    let singular = DMat4::from_cols(DVec4::X, DVec4::X, DVec4::Z, DVec4::W);
    let err = load_with_conf_line(&h, 7, format!("scan d.png pano_i1_1.jpg {}", row_major_text(&singular)));
    assert_mentions(&err, &["h1.conf:7", "not invertible"]);
}

#[test]
fn conf_non_rigid_pose() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    let scaled = h.poses[0] * DMat4::from_scale(DVec3::splat(1.5));
    let err = load_with_conf_line(&h, 6, format!("scan d.png pano_i1_0.jpg {}", row_major_text(&scaled)));
    assert_mentions(&err, &["h1.conf:6", "not rigid"]);
    let mirrored = h.poses[0] * DMat4::from_scale(DVec3::new(1.0, 1.0, -1.0));
    let err = load_with_conf_line(&h, 6, format!("scan d.png pano_i1_0.jpg {}", row_major_text(&mirrored)));
    assert_mentions(&err, &["h1.conf:6", "reflection"]);
    let projective = "scan d.png pano_i1_0.jpg 1 0 0 0  0 1 0 0  0 0 1 0  0 0 0.5 1".to_string();
    assert_mentions(&load_with_conf_line(&h, 6, projective), &["h1.conf:6", "last row"]);
}

#[test]
fn conf_nan_pose() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    let line = "scan d.png pano_i1_0.jpg 1 0 0 nan  0 1 0 0  0 0 1 0  0 0 0 1".to_string();
    assert_mentions(&load_with_conf_line(&h, 6, line), &["h1.conf:6", "NaN"]);
    let line = "scan d.png pano_i1_0.jpg 1 0 0 zero  0 1 0 0  0 0 1 0  0 0 0 1".to_string();
    assert_mentions(&load_with_conf_line(&h, 6, line), &["h1.conf:6", "\"zero\" is not a number"]);
}

#[test]
fn conf_image_listed_but_missing() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    std::fs::remove_file(h.root.join("undistorted_color_images/pano_i1_2.jpg")).unwrap();
    let err = load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert!(matches!(err, IngestError::MissingImage { .. }));
    assert_mentions(&err, &["h1.conf", "pano_i1_2.jpg", "does not exist"]);
}

#[test]
fn conf_image_of_the_wrong_size() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    // Same intrinsics block as pano_i1_0 (64x48), but 65x48.
    write_image(&h.root.join("undistorted_color_images/pano_i1_1.jpg"), 65, 48);
    write_exr(&h.root.join("undistorted_color_images/pano_i1_1.exr"), 65, 48);
    let err = load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert!(matches!(err, IngestError::ImageSize { width: 65, height: 48, .. }));
    assert_mentions(&err, &["pano_i1_1.exr", "65x48", "pano_i1_0.jpg (64x48)"]);
    // An image too small for its principal point.
    let dir2 = tempfile::tempdir().unwrap();
    let h2 = make_house(dir2.path());
    write_image(&h2.root.join("undistorted_color_images/pano_i1_2.jpg"), 30, 20);
    let err = load_scan(&h2.root, ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["pano_i1_2.jpg", "30x20", "principal point (40, 30)", "h1.conf:9"]);
}

#[test]
fn fsegs_with_wrong_face_count() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    std::fs::write(h.root.join("house_segmentations/h1.fsegs.json"), "{\"segIndices\": [1, 2, 3]}").unwrap();
    let err = load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["h1.fsegs.json", "3 entries", "38 faces"]);
}

/// Turns the house into the raw layout: distorted intrinsics, per-image pose files, `matterport_color_images`.
fn make_raw(h: &House) {
    std::fs::remove_dir_all(h.root.join("undistorted_camera_parameters")).unwrap();
    let intr = h.root.join("matterport_camera_intrinsics");
    let poses = h.root.join("matterport_camera_poses");
    std::fs::create_dir_all(&intr).unwrap();
    std::fs::create_dir_all(&poses).unwrap();
    std::fs::write(intr.join("pano_intrinsics_1.txt"), "64 48 50.5 49.5 31.7 23.9 -0.1 0.02 0.001 -0.002 0.003\n")
        .unwrap();
    for (yaw, pose) in h.poses.iter().enumerate() {
        let m = pose.transpose().to_cols_array();
        let text: String = m.chunks(4).map(|r| format!("{} {} {} {}\n", r[0], r[1], r[2], r[3])).collect();
        std::fs::write(poses.join(format!("pano_pose_1_{yaw}.txt")), text).unwrap();
        write_image(&h.root.join(format!("matterport_color_images/pano_i1_{yaw}.jpg")), 64, 48);
    }
}

#[test]
fn raw_variant_loads_distorted_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    make_raw(&h);
    assert_eq!(ingest::scan::detect_format(&h.root).unwrap(), ScanFormat::MatterportRaw);
    let scan = load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap();
    assert_eq!(scan.views.len(), 3);
    let c = &scan.views[0].camera;
    assert_eq!((c.width, c.height), (64, 48));
    assert_eq!((c.intrinsics.fx, c.intrinsics.fy, c.intrinsics.cx, c.intrinsics.cy), (50.5, 49.5, 31.7, 23.9));
    assert_eq!(c.distortion.coefficients(), [-0.1, 0.02, 0.001, -0.002, 0.003, 0.0, 0.0, 0.0]);
    assert_eq!(scan.views[2].name, "pano_i1_2");
    for (v, pose) in scan.views.iter().zip(&h.poses) {
        assert!(v.camera.cam_to_world.abs_diff_eq(*pose, 1e-12));
    }
}

#[test]
fn raw_image_of_the_wrong_size() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    make_raw(&h);
    write_image(&h.root.join("matterport_color_images/pano_i1_1.jpg"), 48, 64);
    let err = load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["pano_i1_1.jpg", "48x64", "pano_intrinsics_1.txt says 64x48"]);
}

#[test]
fn raw_bad_intrinsics_and_poses() {
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    make_raw(&h);
    let intr = h.root.join("matterport_camera_intrinsics/pano_intrinsics_1.txt");
    std::fs::write(&intr, "64 48 50 50 32 24 0 0 0 0\n").unwrap();
    let err = load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["pano_intrinsics_1.txt:1", "10 values, expected 11"]);
    std::fs::write(&intr, "64 48 50 50 32 24 0 0 0 0 0\n").unwrap();
    let pose = h.root.join("matterport_camera_poses/pano_pose_1_2.txt");
    std::fs::write(&pose, "2 0 0 0\n0 2 0 0\n0 0 2 0\n0 0 0 1\n").unwrap();
    let err = load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["pano_pose_1_2.txt", "not rigid"]);
    std::fs::remove_file(h.root.join("matterport_color_images/pano_i1_0.jpg")).unwrap();
    let err = load_scan(&h.root, ScanFormat::Auto, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["pano_pose_1_0.txt", "pano_i1_0.jpg", "does not exist"]);
}

#[test]
fn ascii_house_ply_loads_the_same() {
    // The same mesh written as ASCII (with an extra vertex property and no normals) loads to the same scan.
    let dir = tempfile::tempdir().unwrap();
    let h = make_house(dir.path());
    let ply = h.root.join("house_segmentations/h1.ply");
    let bin = load_scan(&h.root, ScanFormat::Matterport, GroupBy::Segment).unwrap();
    let r = ingest::ply::read_ply(&ply).unwrap();
    let cols: Vec<Vec<i32>> =
        ["material_id", "segment_id", "category_id"].iter().map(|n| r.mesh.face_ids(n).unwrap()).collect();
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nelement face {}\nproperty list uchar int vertex_indices\nproperty int material_id\n\
         property int segment_id\nproperty int category_id\nend_header\n",
        r.mesh.positions.len(),
        r.mesh.triangles.len()
    );
    for p in &r.mesh.positions {
        text += &format!("{} {} {} 7\n", p.x, p.y, p.z);
    }
    for (t, tri) in r.mesh.triangles.iter().enumerate() {
        text += &format!("3 {} {} {} {} {} {}\n", tri[0], tri[1], tri[2], cols[0][t], cols[1][t], cols[2][t]);
    }
    std::fs::write(&ply, text).unwrap();
    let ascii = load_scan(&h.root, ScanFormat::Matterport, GroupBy::Segment).unwrap();
    assert_eq!(ascii.mesh.triangles, bin.mesh.triangles);
    assert_eq!(ascii.mesh.positions, bin.mesh.positions);
    assert_eq!(ascii.objects, bin.objects);
    assert_eq!(ascii.face_object, bin.face_object);
}

#[test]
fn physical_camera_from_colour_file_stem() {
    use ingest::matterport::physical_camera;
    assert_eq!(physical_camera("17DRP5sb8fy_i0_3"), Some(0));
    assert_eq!(physical_camera("house_a_i2_17"), Some(2));
    // The index must be digits right after the last `_i`, followed by a numeric yaw.
    assert_eq!(physical_camera("house_i1_x"), None);
    assert_eq!(physical_camera("house_ix_1"), None);
    assert_eq!(physical_camera("photo_0001"), None);
    assert_eq!(physical_camera("demo"), None);
}
