//! Decoding + linearisation of display-referred photos (sRGB or response curve), exposure scaling, saturation
//! and alpha masking, and linear inputs (EXR, Radiance HDR) through `prepare_view`.

use std::path::Path;

use glam::DMat4;
use ingest::camera::{Camera, Distortion, Intrinsics};
use ingest::photo::calibrate::{Vignetting, normalised_r2};
use ingest::photo::{LinearImage, PhotoOptions, ResponseCurve, prepare_view, write_exr};
use ingest::srgb::{decode as srgb_to_linear, encode as linear_to_srgb};

fn pinhole(width: u32, height: u32) -> Camera {
    Camera {
        width,
        height,
        intrinsics: Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: f64::from(width - 1) / 2.0,
            cy: f64::from(height - 1) / 2.0,
        },
        distortion: Distortion::default(),
        cam_to_world: DMat4::IDENTITY,
    }
}

/// The sRGB decoding curve written out independently in f64 (IEC 61966-2-1).
fn srgb_reference(v: f64) -> f64 {
    if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

#[test]
fn srgb_round_trip_recovers_every_8_bit_and_sampled_16_bit_code() {
    for code in 0..=255u32 {
        let v = code as f32 / 255.0;
        let back = (linear_to_srgb(srgb_to_linear(v)) * 255.0).round() as u32;
        assert_eq!(back, code);
        assert!((f64::from(srgb_to_linear(v)) - srgb_reference(f64::from(v))).abs() < 1e-6);
    }
    for code in (0..=65535u32).step_by(97) {
        let v = code as f32 / 65535.0;
        let back = (linear_to_srgb(srgb_to_linear(v)) * 65535.0).round() as u32;
        assert!(back.abs_diff(code) <= 1, "{code} -> {back}");
    }
}

/// A 16×16 image whose pixel i has code i in the red channel, 255 - i in green and a constant 128 in blue.
fn ramp_codes() -> Vec<u8> {
    (0..256u32).flat_map(|i| [i as u8, (255 - i) as u8, 128]).collect()
}

#[test]
fn png_8_bit_is_srgb_linearised_scaled_by_exposure_and_saturation_masked() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ramp.png");
    image::RgbImage::from_raw(16, 16, ramp_codes()).unwrap().save(&path).unwrap();
    let t = 0.25;
    let opts = PhotoOptions { exposure_time: Some(t), ..Default::default() };
    let (cam, img) = prepare_view(&path, &pinhole(16, 16), &opts).unwrap();
    assert_eq!(cam, pinhole(16, 16));
    for i in 0..256usize {
        let (r, g) = (i as f64 / 255.0, (255 - i) as f64 / 255.0);
        let expected = [srgb_reference(r) / t, srgb_reference(g) / t, srgb_reference(128.0 / 255.0) / t];
        for c in 0..3 {
            let got = f64::from(img.rgb[3 * i + c]);
            assert!((got - expected[c]).abs() <= 1e-6 * expected[c].max(1.0), "pixel {i} channel {c}: {got}");
        }
        // Codes ≥ 250 in any channel (0.98 of 255) are saturated: red for i ≥ 250, green for i ≤ 5.
        let saturated = i >= 250 || 255 - i >= 250;
        assert_eq!(img.mask[i] == 0, saturated, "pixel {i}");
    }
}

#[test]
fn png_16_bit_uses_the_full_code_range_and_the_same_saturation_fraction() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ramp16.png");
    let codes: Vec<u16> = [0u16, 1000, 30000, 64224, 64225, 65535].iter().flat_map(|&c| [c, c, 0]).collect();
    image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(6, 1, codes.clone()).unwrap().save(&path).unwrap();
    let (_, img) = prepare_view(&path, &pinhole(6, 1), &PhotoOptions::default()).unwrap();
    for (i, px) in codes.chunks_exact(3).enumerate() {
        let expected = srgb_reference(f64::from(px[0]) / 65535.0);
        assert!((f64::from(img.rgb[3 * i]) - expected).abs() < 1e-6, "pixel {i}");
        // 0.98 · 65535 = 64224.3: 64224 is below, 64225 at or above.
        assert_eq!(img.mask[i] == 0, px[0] >= 64225, "pixel {i}");
    }
}

#[test]
fn grey_png_with_alpha_replicates_grey_and_masks_transparent_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grey.png");
    let la: Vec<u8> = vec![10, 255, 200, 0, 100, 1];
    image::ImageBuffer::<image::LumaA<u8>, _>::from_raw(3, 1, la).unwrap().save(&path).unwrap();
    let (_, img) = prepare_view(&path, &pinhole(3, 1), &PhotoOptions::default()).unwrap();
    assert_eq!(img.mask, vec![1, 0, 1]);
    for (i, grey) in [10.0f64, 200.0, 100.0].iter().enumerate() {
        for c in 0..3 {
            assert!((f64::from(img.rgb[3 * i + c]) - srgb_reference(grey / 255.0)).abs() < 1e-6);
        }
    }
}

#[test]
fn response_curve_replaces_srgb_and_is_divided_by_exposure_time() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ramp.png");
    image::RgbImage::from_raw(16, 16, ramp_codes()).unwrap().save(&path).unwrap();
    // A distinct, strictly positive curve per channel.
    let values: Vec<[f32; 3]> =
        (0..256).map(|z| z as f32).map(|z| [(z + 1.0).powi(2), 0.5 * (z + 1.0), (z / 255.0).exp()]).collect();
    let curve = ResponseCurve::from_values(values.clone()).unwrap();
    let t = 2.0;
    let opts = PhotoOptions { response: Some(curve), exposure_time: Some(t), ..Default::default() };
    let (_, img) = prepare_view(&path, &pinhole(16, 16), &opts).unwrap();
    let codes = ramp_codes();
    for i in 0..256 {
        for c in 0..3 {
            let expected = values[usize::from(codes[3 * i + c])][c] / t as f32;
            assert!((img.rgb[3 * i + c] - expected).abs() <= 1e-6 * expected.max(1.0), "pixel {i} channel {c}");
        }
    }
}

#[test]
fn response_curve_rejects_wrong_length_and_non_positive_entries() {
    assert!(ResponseCurve::from_values(vec![[1.0; 3]; 255]).is_err());
    let mut v = vec![[1.0f32; 3]; 256];
    v[17][1] = 0.0;
    let err = ResponseCurve::from_values(v).unwrap_err().to_string();
    assert!(err.contains("17"), "{err}");
}

fn write_linear_exr(path: &Path, w: u32, h: u32) -> LinearImage {
    // Radiance over several orders of magnitude, one invalid pixel.
    let rgb: Vec<f32> = (0..3 * w * h).map(|i| 10f32.powf((i % 7) as f32 - 3.0) * (1.0 + i as f32 * 0.01)).collect();
    let mut mask = vec![1u8; (w * h) as usize];
    mask[2] = 0;
    let img = LinearImage::new(w, h, rgb, mask).unwrap();
    write_exr(path, &img).unwrap();
    img
}

#[test]
fn exr_input_is_already_linear_and_ignores_exposure_time() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lin.exr");
    let original = write_linear_exr(&path, 5, 4);
    let opts = PhotoOptions { exposure_time: Some(8.0), ..Default::default() };
    let (_, img) = prepare_view(&path, &pinhole(5, 4), &opts).unwrap();
    // The file is the photo cache's (half float: every value here is a normal half, within 2⁻¹¹ of itself);
    // an exposure time applied would scale every value by 1/8.
    assert_eq!((img.width, img.height, &img.mask), (original.width, original.height, &original.mask));
    for (got, want) in img.rgb.iter().zip(&original.rgb) {
        assert!((got - want).abs() <= want.abs() / 2048.0, "{got} vs {want}");
    }
}

#[test]
fn radiance_hdr_input_is_linear_within_rgbe_precision() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lin.hdr");
    let (w, h) = (6u32, 3u32);
    let pixels: Vec<image::Rgb<f32>> =
        (0..w * h).map(|i| image::Rgb([0.001 * (i + 1) as f32, 3.0 * i as f32, 150.0 / (i + 1) as f32])).collect();
    let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    image::codecs::hdr::HdrEncoder::new(file).encode(&pixels, w as usize, h as usize).unwrap();
    let (_, img) = prepare_view(&path, &pinhole(w, h), &PhotoOptions::default()).unwrap();
    assert_eq!(img.valid_count(), (w * h) as usize);
    for (i, p) in pixels.iter().enumerate() {
        let max = p.0.iter().copied().fold(0.0f32, f32::max);
        for c in 0..3 {
            // RGBE shares one exponent: each channel is quantised to 1/256 of the pixel's largest channel.
            assert!((img.rgb[3 * i + c] - p.0[c]).abs() <= max / 128.0, "pixel {i} channel {c}");
        }
    }
}

#[test]
fn calibrated_gain_and_vignetting_divide_the_linear_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grey.png");
    let (w, h) = (12u32, 8u32);
    image::RgbImage::from_pixel(w, h, image::Rgb([128, 100, 160])).save(&path).unwrap();
    let camera = pinhole(w, h);
    let (_, plain) = prepare_view(&path, &camera, &PhotoOptions::default()).unwrap();
    let vignetting = Vignetting { beta: [-0.5, 0.1, 0.0] };
    let gain = [2.0f32, 0.5, 1.25];
    let opts = PhotoOptions { gain: Some(gain), vignetting: Some(vignetting), ..Default::default() };
    let (_, calibrated) = prepare_view(&path, &camera, &opts).unwrap();
    let (cx, cy) = (camera.intrinsics.cx, camera.intrinsics.cy);
    for y in 0..h {
        for x in 0..w {
            let v = vignetting.factor(normalised_r2(x.into(), y.into(), cx, cy, w, h));
            for c in 0..3 {
                let i = 3 * (y * w + x) as usize + c;
                let expected = f64::from(plain.rgb[i]) / (f64::from(gain[c]) * v);
                let got = f64::from(calibrated.rgb[i]);
                assert!((got - expected).abs() <= 1e-6 * expected, "({x}, {y}) channel {c}: {got} vs {expected}");
            }
        }
    }
    // The corner pixels are darkened most: r² = 1 at the outer corner, a little less at the pixel centre.
    assert!(normalised_r2(-0.5, -0.5, cx, cy, w, h) > 0.999);
    // Options written before these fields existed still read.
    let old: PhotoOptions = serde_json::from_str(r#"{"response":null,"exposure_time":null,"downscale":1}"#).unwrap();
    assert_eq!(old, PhotoOptions::default());
}
