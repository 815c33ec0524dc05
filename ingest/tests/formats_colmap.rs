//! COLMAP text models and nerfstudio `transforms.json`: conventions checked against hand-computed projections,
//! and one test per bad-input case.

mod formats_common;

use std::path::Path;

use formats_common::{Rng, assert_mentions, write_image};
use glam::{DMat3, DMat4, DQuat, DVec2, DVec3, Vec3};
use ingest::colmap::{load_views, read_cameras};
use ingest::ply::{PlyMesh, write_ply};
use ingest::{GroupBy, IngestError, ScanFormat, load_scan};

/// COLMAP's projection written out from its documentation (pixel centres at +0.5): world-to-camera quaternion
/// `q = (w, x, y, z)` and translation, OPENCV model `fx fy cx cy k1 k2 p1 p2`.
fn colmap_opencv_pixel(q: [f64; 4], t: [f64; 3], params: [f64; 8], p: [f64; 3]) -> Option<[f64; 2]> {
    let [w, x, y, z] = q;
    let r = [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ];
    let c: Vec<f64> = (0..3).map(|i| r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2] + t[i]).collect();
    if c[2] <= 0.0 {
        return None;
    }
    let (u, v) = (c[0] / c[2], c[1] / c[2]);
    let [fx, fy, cx, cy, k1, k2, p1, p2] = params;
    let (u2, uv, v2) = (u * u, u * v, v * v);
    let r2 = u2 + v2;
    let radial = k1 * r2 + k2 * r2 * r2;
    let du = u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2);
    let dv = v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2);
    Some([fx * (u + du) + cx, fy * (v + dv) + cy])
}

fn random_unit_quaternion(rng: &mut Rng) -> [f64; 4] {
    let q: Vec<f64> = (0..4).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
}

struct Model {
    q: [f64; 4],
    t: [f64; 3],
    params: [f64; 8],
}

const W: u32 = 40;
const H: u32 = 30;

/// Writes a COLMAP text model with one OPENCV camera and `models.len()` images, plus the image files and a mesh.
fn write_colmap(root: &Path, models: &[Model]) {
    let p = models[0].params;
    std::fs::create_dir_all(root.join("sparse/0")).unwrap();
    let p_text: Vec<String> = p.iter().map(|v| format!("{v:.17}")).collect();
    std::fs::write(
        root.join("sparse/0/cameras.txt"),
        format!("# Camera list\n# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n1 OPENCV {W} {H} {}\n", p_text.join(" ")),
    )
    .unwrap();
    let mut images = String::from(
        "# Image list with two lines of data per image:\n#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n",
    );
    for (i, m) in models.iter().enumerate() {
        let v: Vec<String> = m.q.iter().chain(&m.t).map(|v| format!("{v:.17}")).collect();
        images += &format!("{} {} 1 view {i}.jpg\n", i + 1, v.join(" "));
        // Alternate empty and non-empty POINTS2D lines.
        images += if i % 2 == 0 { "\n" } else { "12.5 3.5 -1 20.0 7.25 4\n" };
        write_image(&root.join(format!("images/view {i}.jpg")), W, H);
    }
    std::fs::write(root.join("sparse/0/images.txt"), images).unwrap();
    let mesh =
        PlyMesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y], triangles: vec![[0, 1, 2]], ..PlyMesh::default() };
    write_ply(&root.join("mesh.ply"), &mesh).unwrap();
}

fn sample_models(rng: &mut Rng, n: usize) -> Vec<Model> {
    let params = [41.5, 39.25, 20.3, 14.9, -0.21, 0.05, 0.002, -0.003];
    (0..n)
        .map(|_| Model {
            q: random_unit_quaternion(rng),
            t: [rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(2.0, 4.0)],
            params,
        })
        .collect()
}

#[test]
fn cameras_txt_models_map_to_our_convention() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cameras.txt");
    std::fs::write(
        &path,
        "# comment\n1 SIMPLE_PINHOLE 100 80 90 50 40\n2 PINHOLE 100 80 90 91 50.5 40.5\n\
         3 SIMPLE_RADIAL 100 80 90 50 40 -0.1\n4 RADIAL 100 80 90 50 40 -0.1 0.02\n\
         5 OPENCV 100 80 90 91 50 40 -0.1 0.02 0.001 0.002\n\
         6 FULL_OPENCV 100 80 90 91 50 40 -0.1 0.02 0.001 0.002 0.003 0.1 0.01 0.001\n",
    )
    .unwrap();
    let cams = read_cameras(&path).unwrap();
    assert_eq!(cams.len(), 6);
    // Pixel centres: COLMAP +0.5, ours at integers.
    assert_eq!((cams[&1].intrinsics.cx, cams[&1].intrinsics.cy), (49.5, 39.5));
    assert_eq!((cams[&2].intrinsics.fx, cams[&2].intrinsics.fy, cams[&2].intrinsics.cx), (90.0, 91.0, 50.0));
    assert_eq!(cams[&3].intrinsics.fy, 90.0);
    assert_eq!(cams[&3].distortion.coefficients(), [-0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert_eq!(cams[&4].distortion.coefficients(), [-0.1, 0.02, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert_eq!(cams[&5].distortion.coefficients(), [-0.1, 0.02, 0.001, 0.002, 0.0, 0.0, 0.0, 0.0]);
    assert_eq!(cams[&6].distortion.coefficients(), [-0.1, 0.02, 0.001, 0.002, 0.003, 0.1, 0.01, 0.001]);
    assert_eq!((cams[&6].width, cams[&6].height), (100, 80));
}

#[test]
fn colmap_poses_project_like_colmap_hand_computation() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(7);
    let models = sample_models(&mut rng, 4);
    write_colmap(dir.path(), &models);
    assert_eq!(ingest::scan::detect_format(dir.path()).unwrap(), ScanFormat::Colmap);
    let scan = load_scan(dir.path(), ScanFormat::Auto, GroupBy::Segment).unwrap();
    assert_eq!(scan.views.len(), 4);
    assert_eq!(scan.views[1].name, "view 1");
    let mut checked = 0;
    for (view, m) in scan.views.iter().zip(&models) {
        assert!(ingest::pose::check_rigid(&view.camera.cam_to_world).is_ok());
        for _ in 0..200 {
            let p = [rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0)];
            let expect = colmap_opencv_pixel(m.q, m.t, m.params, p);
            let got = view.camera.project_world(DVec3::from_array(p));
            match (expect, got) {
                (Some(e), Some(g)) => {
                    checked += 1;
                    // Our pixel centres are at integers, COLMAP's at +0.5.
                    assert!((g.x + 0.5 - e[0]).abs() < 1e-8 && (g.y + 0.5 - e[1]).abs() < 1e-8, "{g:?} vs {e:?}");
                }
                (None, None) => {}
                _ => panic!("visibility disagrees for {p:?}"),
            }
        }
    }
    assert!(checked > 100, "too few points in front of the cameras: {checked}");
}

#[test]
fn colmap_and_transforms_describe_the_same_camera_identically() {
    // One camera (pose + OPENCV intrinsics) written both as COLMAP and as transforms.json must map every world
    // point to the same pixel.
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(11);
    let models = sample_models(&mut rng, 1);
    write_colmap(dir.path(), &models);
    let colmap_view = &load_views(&dir.path().join("sparse/0"), &dir.path().join("images")).unwrap()[0];
    // COLMAP world-to-camera (OpenCV) → camera-to-world (OpenGL), computed here independently.
    let m = &models[0];
    let r_wc = DMat3::from_quat(DQuat::from_xyzw(m.q[1], m.q[2], m.q[3], m.q[0]));
    let centre = -(r_wc.transpose() * DVec3::from_array(m.t));
    let r_gl = r_wc.transpose() * DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    let c2w = DMat4::from_mat3_translation(r_gl, centre);
    let rows: Vec<String> = (0..4)
        .map(|r| {
            let row = c2w.row(r);
            format!("[{:.17}, {:.17}, {:.17}, {:.17}]", row.x, row.y, row.z, row.w)
        })
        .collect();
    let [fx, fy, cx, cy, k1, k2, p1, p2] = m.params;
    let tdir = dir.path().join("tf");
    write_image(&tdir.join("images/frame_00001.jpg"), W, H);
    std::fs::write(
        tdir.join("transforms.json"),
        format!(
            r#"{{"camera_model": "OPENCV", "fl_x": {fx}, "fl_y": {fy}, "cx": {cx}, "cy": {cy}, "w": {W}, "h": {H},
              "k1": {k1}, "k2": {k2}, "p1": {p1}, "p2": {p2},
              "frames": [{{"file_path": "images/frame_00001.jpg", "transform_matrix": [{}]}}]}}"#,
            rows.join(", ")
        ),
    )
    .unwrap();
    let tf_view = &ingest::transforms::load_views(&tdir.join("transforms.json")).unwrap()[0];
    assert_eq!(tf_view.camera.intrinsics, colmap_view.camera.intrinsics);
    assert_eq!(tf_view.camera.distortion, colmap_view.camera.distortion);
    for _ in 0..500 {
        let p = DVec3::new(rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0));
        match (colmap_view.camera.project_world(p), tf_view.camera.project_world(p)) {
            // Relative: points far outside the image project to huge (distorted) coordinates.
            (Some(a), Some(b)) => assert!((a - b).length() < 1e-10 * (1.0 + a.length()), "{a:?} vs {b:?}"),
            (None, None) => {}
            _ => panic!("visibility disagrees for {p:?}"),
        }
    }
}

#[test]
fn transforms_pose_projects_like_nerfstudio_hand_computation() {
    // nerfstudio: the ray through pixel index (i, j) has camera direction ((i + 0.5 - cx)/fx, -(j + 0.5 - cy)/fy,
    // -1) in the OpenGL camera frame, rotated by the c2w matrix. So a point p_cam projects to
    // i = cx - 0.5 + fx * x / -z, j = cy - 0.5 - fy * y / -z.
    let dir = tempfile::tempdir().unwrap();
    let (fx, fy, cx, cy) = (35.0, 36.0, 20.0, 15.0);
    // Camera at (1, 2, 3), yawed 30° about world z.
    let yaw = 30f64.to_radians();
    let c2w = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0)) * DMat4::from_rotation_z(yaw);
    let rows: Vec<String> = (0..4).map(|r| format!("{:?}", c2w.row(r).to_array())).collect();
    write_image(&dir.path().join("r_0.png"), W, H);
    std::fs::write(
        dir.path().join("transforms.json"),
        format!(
            r#"{{"fl_x": {fx}, "fl_y": {fy}, "cx": {cx}, "cy": {cy}, "w": {W}, "h": {H},
              "frames": [{{"file_path": "./r_0", "transform_matrix": [{}]}}]}}"#,
            rows.join(", ")
        ),
    )
    .unwrap();
    let views = ingest::transforms::load_views(&dir.path().join("transforms.json")).unwrap();
    let cam = views[0].camera;
    assert_eq!(views[0].image_path.file_name().unwrap(), "r_0.png", "extension-less file_path resolved");
    let mut rng = Rng(3);
    for _ in 0..100 {
        // Points in front of the camera, expressed in camera coordinates and moved to the world by hand.
        let pc = DVec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), -rng.uniform(1.0, 5.0));
        let (s, c) = yaw.sin_cos();
        let pw = DVec3::new(c * pc.x - s * pc.y + 1.0, s * pc.x + c * pc.y + 2.0, pc.z + 3.0);
        let expect = DVec2::new(cx - 0.5 + fx * pc.x / -pc.z, cy - 0.5 - fy * pc.y / -pc.z);
        let got = cam.project_world(pw).unwrap();
        assert!((got - expect).length() < 1e-9, "{got:?} vs {expect:?}");
    }
}

#[test]
fn transforms_camera_angle_and_defaults() {
    let dir = tempfile::tempdir().unwrap();
    write_image(&dir.path().join("a.png"), W, H);
    let angle = 2.0 * (0.5 * f64::from(W) / 50.0).atan();
    std::fs::write(
        dir.path().join("transforms.json"),
        format!(
            r#"{{"camera_angle_x": {angle}, "frames": [{{"file_path": "a.png",
               "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}}]}}"#
        ),
    )
    .unwrap();
    let v = &ingest::transforms::load_views(&dir.path().join("transforms.json")).unwrap()[0];
    let k = v.camera.intrinsics;
    assert!((k.fx - 50.0).abs() < 1e-9 && (k.fy - 50.0).abs() < 1e-9);
    // Default principal point = image centre: (W - 1)/2 with integer pixel centres.
    assert_eq!((k.cx, k.cy), ((f64::from(W) - 1.0) / 2.0, (f64::from(H) - 1.0) / 2.0));
}

// ---- bad input ----

#[test]
fn colmap_unknown_model_and_wrong_parameter_count() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cameras.txt");
    std::fs::write(&path, "# c\n\n1 PINHOLE 10 10 5 5 5 5\n2 THIN_PRISM_FISHEYE 10 10 1 2 3 4 5 6 7 8 9 10 11 12\n")
        .unwrap();
    assert_mentions(
        &read_cameras(&path).unwrap_err(),
        &["cameras.txt:4", "unsupported camera model \"THIN_PRISM_FISHEYE\""],
    );
    std::fs::write(&path, "1 OPENCV 10 10 5 5 5 5 0.1\n").unwrap();
    assert_mentions(&read_cameras(&path).unwrap_err(), &["cameras.txt:1", "OPENCV needs 8 parameters, found 5"]);
    std::fs::write(&path, "1 PINHOLE 10 10 5 5 5 nan\n").unwrap();
    assert_mentions(&read_cameras(&path).unwrap_err(), &["cameras.txt:1", "\"nan\" is not a finite number"]);
}

#[test]
fn colmap_non_rigid_pose() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(5);
    let mut models = sample_models(&mut rng, 2);
    models[1].q = models[1].q.map(|v| 2.0 * v);
    write_colmap(dir.path(), &models);
    let err = load_scan(dir.path(), ScanFormat::Colmap, GroupBy::Segment).unwrap_err();
    // Two comment lines, then image 1 on line 3 and its points on line 4: image 2 is on line 5.
    assert_mentions(&err, &["images.txt:5", "norm 2.000000", "not a rotation"]);
    models[1].q = [0.0; 4];
    write_colmap(dir.path(), &models);
    let err = load_scan(dir.path(), ScanFormat::Colmap, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["images.txt:5", "norm 0.000000"]);
}

#[test]
fn colmap_image_missing_or_wrong_size() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(9);
    write_colmap(dir.path(), &sample_models(&mut rng, 2));
    write_image(&dir.path().join("images/view 1.jpg"), W + 1, H);
    let err = load_scan(dir.path(), ScanFormat::Colmap, GroupBy::Segment).unwrap_err();
    assert!(matches!(err, IngestError::ImageSize { .. }));
    assert_mentions(&err, &["view 1.jpg", "41x30", "images.txt:5 (camera 1) says 40x30"]);
    std::fs::remove_file(dir.path().join("images/view 0.jpg")).unwrap();
    let err = load_scan(dir.path(), ScanFormat::Colmap, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["images.txt", "view 0.jpg", "does not exist"]);
}

#[test]
fn colmap_image_line_with_wrong_token_count_or_unknown_camera() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(13);
    write_colmap(dir.path(), &sample_models(&mut rng, 1));
    let images = dir.path().join("sparse/0/images.txt");
    std::fs::write(&images, "1 1 0 0 0 0 0 1 1\n\n").unwrap();
    let err = load_scan(dir.path(), ScanFormat::Colmap, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["images.txt:1", "9 values"]);
    std::fs::write(&images, "1 1 0 0 0 0 0 1 7 view 0.jpg\n\n").unwrap();
    let err = load_scan(dir.path(), ScanFormat::Colmap, GroupBy::Segment).unwrap_err();
    assert_mentions(&err, &["images.txt:1", "camera 7 is not in cameras.txt"]);
}

fn write_transforms(dir: &Path, frames: &str) {
    write_image(&dir.join("a.png"), W, H);
    std::fs::write(
        dir.join("transforms.json"),
        format!(r#"{{"fl_x": 30, "fl_y": 30, "w": {W}, "h": {H}, "frames": [{frames}]}}"#),
    )
    .unwrap();
}

#[test]
fn transforms_bad_pose_missing_image_wrong_size() {
    let dir = tempfile::tempdir().unwrap();
    let id = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
    let p = dir.path().join("transforms.json");
    write_transforms(
        dir.path(),
        &format!(
            r#"{{"file_path": "a.png", "transform_matrix": {id}}},
        {{"file_path": "a.png", "transform_matrix": [[2,0,0,0],[0,2,0,0],[0,0,2,0],[0,0,0,1]]}}"#
        ),
    );
    assert_mentions(&ingest::transforms::load_views(&p).unwrap_err(), &["transforms.json", "frame 1", "not rigid"]);
    write_transforms(dir.path(), r#"{"file_path": "a.png", "transform_matrix": [[1,0,0],[0,1,0],[0,0,1]]}"#);
    assert_mentions(&ingest::transforms::load_views(&p).unwrap_err(), &["frame 0", "4x4"]);
    write_transforms(dir.path(), &format!(r#"{{"file_path": "missing.png", "transform_matrix": {id}}}"#));
    assert_mentions(
        &ingest::transforms::load_views(&p).unwrap_err(),
        &["transforms.json", "missing.png", "does not exist"],
    );
    write_transforms(dir.path(), &format!(r#"{{"file_path": "a.png", "w": 64, "transform_matrix": {id}}}"#));
    assert_mentions(&ingest::transforms::load_views(&p).unwrap_err(), &["a.png", "40x30", "frame 0 says 64x30"]);
    std::fs::write(&p, "{\"frames\": [1, 2,]}").unwrap();
    assert_mentions(&ingest::transforms::load_views(&p).unwrap_err(), &["transforms.json:1", "bad JSON"]);
}
