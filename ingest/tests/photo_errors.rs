//! Bad photo input: every error names the file and says what is wrong; nothing panics.

use glam::DMat4;
use ingest::camera::{Camera, Distortion, Intrinsics};
use ingest::photo::{PhotoError, PhotoOptions, prepare_view};

fn camera(width: u32, height: u32) -> Camera {
    Camera {
        width,
        height,
        intrinsics: Intrinsics { fx: 50.0, fy: 50.0, cx: 3.5, cy: 2.5 },
        distortion: Distortion { k1: -0.1, ..Default::default() },
        cam_to_world: DMat4::IDENTITY,
    }
}

fn write_png(path: &std::path::Path, w: u32, h: u32) {
    image::RgbImage::from_pixel(w, h, image::Rgb([100, 120, 140])).save(path).unwrap();
}

#[test]
fn missing_image_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nope.jpg");
    let err = prepare_view(&path, &camera(8, 6), &PhotoOptions::default()).unwrap_err();
    assert!(matches!(err, PhotoError::Read { .. }), "{err:?}");
    assert!(err.to_string().contains("nope.jpg"), "{err}");
}

#[test]
fn image_of_wrong_size_names_the_file_and_both_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small.png");
    write_png(&path, 7, 6);
    let err = prepare_view(&path, &camera(8, 6), &PhotoOptions::default()).unwrap_err();
    assert!(matches!(err, PhotoError::WrongSize { expected: (8, 6), found: (7, 6), .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("small.png") && msg.contains("7x6") && msg.contains("8x6"), "{msg}");
}

#[test]
fn undecodable_file_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("garbage.png");
    std::fs::write(&path, b"\x89PNG\r\n\x1a\n truncated").unwrap();
    let err = prepare_view(&path, &camera(8, 6), &PhotoOptions::default()).unwrap_err();
    assert!(matches!(err, PhotoError::Decode { .. }), "{err:?}");
    assert!(err.to_string().contains("garbage.png"), "{err}");
    let exr = dir.path().join("cut.exr");
    std::fs::write(&exr, [0x76, 0x2f, 0x31, 0x01, 2, 0, 0]).unwrap();
    let err = prepare_view(&exr, &camera(8, 6), &PhotoOptions::default()).unwrap_err();
    assert!(err.to_string().contains("cut.exr"), "{err}");
}

#[test]
fn bad_options_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ok.png");
    write_png(&path, 8, 6);
    for opts in [
        PhotoOptions { exposure_time: Some(0.0), ..Default::default() },
        PhotoOptions { exposure_time: Some(f64::NAN), ..Default::default() },
        PhotoOptions { downscale: 0, ..Default::default() },
        PhotoOptions { downscale: 7, ..Default::default() },
    ] {
        let err = prepare_view(&path, &camera(8, 6), &opts).unwrap_err().to_string();
        assert!(err.contains("ok.png"), "{err}");
    }
    // The good case works and undistorts.
    let (cam, img) = prepare_view(&path, &camera(8, 6), &PhotoOptions::default()).unwrap();
    assert!(cam.distortion.is_identity());
    assert_eq!((img.width, img.height), (8, 6));
}
