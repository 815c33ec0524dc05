//! OpenCV undistortion of synthetic images whose distortion we know exactly: the distorted image is built by
//! forward-mapping an analytic pattern through our own distortion model (camera.rs, inverted by Newton), so
//! the undistorted result can be compared with the pattern at every output pixel.

use glam::{DMat4, DVec2};
use ingest::camera::{Camera, Distortion, Intrinsics};
use ingest::photo::LinearImage;
use ingest::photo::undistort::{optimal_new_intrinsics, undistort};

fn distorted_camera() -> Camera {
    Camera {
        width: 320,
        height: 240,
        intrinsics: Intrinsics { fx: 280.0, fy: 276.0, cx: 161.3, cy: 118.2 },
        // Strong barrel distortion (like the OpenCV chessboard camera) plus tangential terms.
        distortion: Distortion { k1: -0.28, k2: 0.08, p1: 0.0012, p2: -0.0008, k3: 0.0, ..Default::default() },
        cam_to_world: DMat4::IDENTITY,
    }
}

/// Inverts `Distortion::distort` by Newton's method with a central-difference Jacobian.
fn undistort_point(d: &Distortion, target: DVec2) -> DVec2 {
    let mut p = target;
    for _ in 0..50 {
        let r = d.distort(p) - target;
        if r.length() < 1e-14 {
            break;
        }
        let h = 1e-7;
        let jx = (d.distort(p + DVec2::new(h, 0.0)) - d.distort(p - DVec2::new(h, 0.0))) / (2.0 * h);
        let jy = (d.distort(p + DVec2::new(0.0, h)) - d.distort(p - DVec2::new(0.0, h))) / (2.0 * h);
        let det = jx.x * jy.y - jy.x * jx.y;
        let step = DVec2::new((jy.y * r.x - jy.x * r.y) / det, (-jx.y * r.x + jx.x * r.y) / det);
        p -= step;
    }
    assert!((d.distort(p) - target).length() < 1e-10, "Newton did not converge at {target:?}");
    p
}

/// Smooth test pattern over undistorted normalised coordinates, period 0.08 (≈ 22 px at fx 280).
fn pattern(p: DVec2) -> [f32; 3] {
    let tau = std::f64::consts::TAU;
    let a = (tau * p.x / 0.08).sin() * (tau * p.y / 0.08).cos();
    let b = (tau * (p.x + p.y) / 0.11).sin();
    [(0.5 + 0.2 * a) as f32, (0.5 + 0.2 * b) as f32, (0.3 + 0.1 * a * b) as f32]
}

/// Pixel → normalised OpenCV coordinates of a camera's intrinsics.
fn normalised(k: &Intrinsics, u: f64, v: f64) -> DVec2 {
    DVec2::new((u - k.cx) / k.fx, (v - k.cy) / k.fy)
}

fn render_distorted(cam: &Camera) -> LinearImage {
    let (w, h) = (cam.width, cam.height);
    let mut rgb = Vec::with_capacity(3 * (w * h) as usize);
    for v in 0..h {
        for u in 0..w {
            let xd = normalised(&cam.intrinsics, f64::from(u), f64::from(v));
            rgb.extend(pattern(undistort_point(&cam.distortion, xd)));
        }
    }
    LinearImage::new(w, h, rgb, vec![1; (w * h) as usize]).unwrap()
}

#[test]
fn undistorted_pixels_match_the_analytic_pattern() {
    let cam = distorted_camera();
    let img = render_distorted(&cam);
    let (new_cam, out) = undistort(&img, &cam).unwrap();
    assert!(new_cam.distortion.is_identity());
    assert_eq!((new_cam.width, new_cam.height), (cam.width, cam.height));
    assert_eq!(new_cam.cam_to_world, cam.cam_to_world);
    assert_eq!(new_cam.intrinsics, optimal_new_intrinsics(&cam).unwrap());

    let k = new_cam.intrinsics;
    let (mut err_sum, mut err_max, mut baseline_sum, mut n) = (0.0f64, 0.0f64, 0.0f64, 0usize);
    for v in 0..out.height {
        for u in 0..out.width {
            if !out.is_valid(u, v) {
                continue;
            }
            let expected = pattern(normalised(&k, f64::from(u), f64::from(v)));
            let got = out.pixel(u, v);
            let raw = img.pixel(u, v);
            for c in 0..3 {
                let e = f64::from((got[c] - expected[c]).abs());
                err_sum += e;
                err_max = err_max.max(e);
                baseline_sum += f64::from((raw[c] - expected[c]).abs());
            }
            n += 3;
        }
    }
    let (mean, baseline) = (err_sum / n as f64, baseline_sum / n as f64);
    let valid_fraction = out.valid_count() as f64 / out.pixel_count() as f64;
    eprintln!(
        "undistort vs analytic: mean {mean:.5}, max {err_max:.5}, no-undistort baseline {baseline:.4}, valid {valid_fraction:.4}"
    );
    // Bilinear interpolation of a sinusoid with a ≥ 15 px period (amplitude 0.2) errs by at most
    // 0.2·(π·0.5/15)²/2 ≈ 1e-3 per axis, plus OpenCV's 1/32-px position quantisation (slope ≤ 0.085/px → 1.3e-3).
    assert!(mean < 2e-3, "mean error {mean}");
    assert!(err_max < 1e-2, "max error {err_max}");
    // Without undistortion the pattern is displaced by pixels near the border: a large error.
    assert!(baseline > 20.0 * mean, "baseline {baseline} vs {mean}");
    // alpha = 0: (almost) every output pixel has a source; OpenCV's coarse border sampling may lose a few rows.
    assert!(valid_fraction > 0.97, "valid fraction {valid_fraction}");
}

#[test]
fn invalid_and_out_of_view_pixels_never_leak_into_valid_output() {
    let cam = distorted_camera();
    let (w, h) = (cam.width, cam.height);
    let mut img = LinearImage::new(w, h, vec![1.0; 3 * (w * h) as usize], vec![1; (w * h) as usize]).unwrap();
    // A 3×3 block of invalid pixels with a huge value: any leak shows up as a valid pixel ≠ 1.
    let block = 60..63u32;
    for y in block.clone() {
        for x in block.clone() {
            let i = (y * w + x) as usize;
            img.mask[i] = 0;
            img.rgb[3 * i..3 * i + 3].fill(1000.0);
        }
    }
    let (new_cam, out) = undistort(&img, &cam).unwrap();
    let mut invalid_near_block = 0;
    for v in 0..h {
        for u in 0..w {
            // Where this output pixel samples the distorted source (our model, independent of OpenCV).
            let xu = normalised(&new_cam.intrinsics, f64::from(u), f64::from(v));
            let xd = cam.distortion.distort(xu);
            let k = cam.intrinsics;
            let (su, sv) = (k.fx * xd.x + k.cx, k.fy * xd.y + k.cy);
            let valid = out.is_valid(u, v);
            if valid {
                let p = out.pixel(u, v);
                assert!(p.iter().all(|&c| (c - 1.0).abs() < 1e-5), "leak at ({u}, {v}): {p:?}");
            }
            // 0.1 px margins stay clear of OpenCV's 1/32-px quantisation of the sampling position.
            let outside = su < -0.1 || sv < -0.1 || su > f64::from(w - 1) + 0.1 || sv > f64::from(h - 1) + 0.1;
            let in_block = (59.0 + 0.1..63.0 - 0.1).contains(&su) && (59.0 + 0.1..63.0 - 0.1).contains(&sv);
            if outside || in_block {
                assert!(!valid, "({u}, {v}) samples ({su:.2}, {sv:.2}) but is valid");
            }
            invalid_near_block += usize::from(in_block);
            let interior = su > 0.1 && sv > 0.1 && su < f64::from(w - 1) - 0.1 && sv < f64::from(h - 1) - 0.1;
            let far_from_block = !((58.0..64.0).contains(&su) && (58.0..64.0).contains(&sv));
            if interior && far_from_block {
                assert!(valid, "({u}, {v}) samples ({su:.2}, {sv:.2}) inside the image but is invalid");
            }
        }
    }
    assert!(invalid_near_block > 0, "the invalid block must map to some output pixels");
}

#[test]
fn pinhole_camera_passes_through_unchanged() {
    let cam = Camera { distortion: Distortion::default(), ..distorted_camera() };
    let img = render_distorted(&cam);
    let (new_cam, out) = undistort(&img, &cam).unwrap();
    assert_eq!(new_cam, cam);
    assert_eq!(out, img);
}

#[test]
fn image_of_wrong_size_is_an_error() {
    let cam = distorted_camera();
    let img = LinearImage::new(10, 10, vec![0.0; 300], vec![1; 100]).unwrap();
    let err = undistort(&img, &cam).unwrap_err().to_string();
    assert!(err.contains("10x10") && err.contains("320x240"), "{err}");
}
