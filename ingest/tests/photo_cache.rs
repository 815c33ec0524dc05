//! The prepared-view cache: round trip of camera and mask (exact) and radiance (within half float's 2⁻¹¹ of
//! the image's maximum when half float keeps it, else exact); errors that name the file.

use glam::{DMat4, DQuat, DVec3};
use ingest::camera::{Camera, Distortion, Intrinsics};
use ingest::photo::cache::{cached_paths, read_manifest};
use ingest::photo::{LinearImage, read_cached, write_cached};

fn camera(width: u32, height: u32) -> Camera {
    Camera {
        width,
        height,
        intrinsics: Intrinsics { fx: 123.456_789, fy: 120.5, cx: 11.25, cy: 7.75 },
        distortion: Distortion::default(),
        cam_to_world: DMat4::from_rotation_translation(
            DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
            DVec3::new(1.5, -2.0, 0.25),
        ),
    }
}

/// Values spanning eight decades below `top` (tiny, fractional, large) so that any lossy step shows.
fn image_up_to(w: u32, h: u32, top: f32) -> LinearImage {
    let rgb = (0..3 * w * h).map(|i| (i as f32 * 0.37).sin().abs() * top * 10f32.powi((i % 9) as i32 - 8)).collect();
    let mask = (0..w * h).map(|i| u8::from(i % 5 != 0)).collect();
    LinearImage::new(w, h, rgb, mask).unwrap()
}

/// An image whose values half float holds exactly (multiples of 1/64 up to 4).
fn image(w: u32, h: u32) -> LinearImage {
    let rgb = (0..3 * w * h).map(|i| (i % 257) as f32 / 64.0).collect();
    let mask = (0..w * h).map(|i| u8::from(i % 5 != 0)).collect();
    LinearImage::new(w, h, rgb, mask).unwrap()
}

#[test]
fn cache_round_trip_keeps_every_value_within_its_bound() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run/views");
    let cam = camera(23, 17);
    // Half float's range (its maximum is 65504, its smallest normal 2⁻¹⁴): within 2⁻¹¹ of the maximum.
    // Outside it, above or below: exact.
    for (top, exact) in [(1.0, false), (6.0e4, false), (1.0e-3, false), (1.0e5, true), (1.0e-5, true)] {
        let img = image_up_to(23, 17, top);
        let exr = write_cached(&run, "view_0007", &cam, &img).unwrap();
        assert_eq!(exr, run.join("view_0007.exr"));
        let (cam2, img2) = read_cached(&run, "view_0007").unwrap();
        assert_eq!(cam2, cam);
        assert_eq!(img2.mask, img.mask);
        let max = img.rgb.iter().fold(0.0_f32, |m, v| m.max(*v));
        let worst = img.rgb.iter().zip(&img2.rgb).map(|(a, b)| (a - b).abs()).fold(0.0_f32, f32::max);
        if exact {
            assert_eq!(img2.rgb, img.rgb, "top {top}");
        } else {
            assert!(worst <= max / 2048.0 && worst > 0.0, "top {top}: worst {worst}, max {max}");
        }
    }
    let img = image(23, 17);
    write_cached(&run, "view_0007", &cam, &img).unwrap();
    assert_eq!(read_cached(&run, "view_0007").unwrap().1, img);
    let entry = read_manifest(&run, "view_0007").unwrap();
    assert_eq!(entry.valid_pixels, img.valid_count());
    assert_eq!(entry.image, "view_0007.exr");
    // Atomic writes leave no temporary files behind.
    let names: Vec<String> =
        std::fs::read_dir(&run).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

#[test]
fn rewriting_an_entry_replaces_it() {
    let dir = tempfile::tempdir().unwrap();
    write_cached(dir.path(), "v", &camera(4, 3), &image(4, 3)).unwrap();
    let small = image(2, 2);
    write_cached(dir.path(), "v", &camera(2, 2), &small).unwrap();
    assert_eq!(read_cached(dir.path(), "v").unwrap().1, small);
}

#[test]
fn missing_entry_names_the_manifest_file() {
    let dir = tempfile::tempdir().unwrap();
    let err = read_cached(dir.path(), "absent").unwrap_err().to_string();
    assert!(err.contains("absent.json"), "{err}");
}

#[test]
fn missing_image_names_the_image_file() {
    let dir = tempfile::tempdir().unwrap();
    write_cached(dir.path(), "v", &camera(4, 3), &image(4, 3)).unwrap();
    std::fs::remove_file(dir.path().join("v.exr")).unwrap();
    let err = read_cached(dir.path(), "v").unwrap_err().to_string();
    assert!(err.contains("v.exr"), "{err}");
}

#[test]
fn image_disagreeing_with_manifest_size_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    write_cached(dir.path(), "v", &camera(4, 3), &image(4, 3)).unwrap();
    write_cached(dir.path(), "w", &camera(5, 3), &image(5, 3)).unwrap();
    std::fs::rename(dir.path().join("w.exr"), dir.path().join("v.exr")).unwrap();
    let err = read_cached(dir.path(), "v").unwrap_err().to_string();
    assert!(err.contains("v.exr") && err.contains("5x3") && err.contains("4x3"), "{err}");
}

#[test]
fn corrupt_manifest_and_bad_names_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (_, json) = cached_paths(dir.path(), "v");
    std::fs::write(&json, b"{\"format\": \"something-else\"").unwrap();
    let err = read_cached(dir.path(), "v").unwrap_err().to_string();
    assert!(err.contains("v.json"), "{err}");
    for bad in ["", "../x", "a/b", ".hidden"] {
        assert!(write_cached(dir.path(), bad, &camera(2, 2), &image(2, 2)).is_err(), "{bad:?}");
    }
    // Camera and image sizes must agree.
    let err = write_cached(dir.path(), "v", &camera(3, 3), &image(2, 2)).unwrap_err().to_string();
    assert!(err.contains("v.exr"), "{err}");
}
