//! Integer area downscaling: radiance conservation, block validity, and intrinsics consistent with the
//! integer-pixel-centre convention.

use glam::{DMat4, DVec3};
use ingest::camera::{Camera, Distortion, Intrinsics};
use ingest::photo::LinearImage;
use ingest::photo::downscale::{downscale, scale_intrinsics};

/// SplitMix64: a tiny seeded generator so the tests are reproducible without extra dependencies.
struct Rng(u64);
impl Rng {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn camera(width: u32, height: u32) -> Camera {
    Camera {
        width,
        height,
        intrinsics: Intrinsics { fx: 210.0, fy: 190.0, cx: 47.3, cy: 31.8 },
        distortion: Distortion::default(),
        cam_to_world: DMat4::IDENTITY,
    }
}

fn random_image(w: u32, h: u32, seed: u64) -> LinearImage {
    let mut rng = Rng(seed);
    // Log-uniform radiance over 4 decades, like real HDR photos.
    let rgb = (0..3 * w * h).map(|_| 10f64.powf(4.0 * rng.next_f64() - 2.0) as f32).collect();
    LinearImage::new(w, h, rgb, vec![1; (w * h) as usize]).unwrap()
}

fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64
}

#[test]
fn downscale_preserves_mean_radiance() {
    for s in [2u32, 3, 4] {
        let (w, h) = (96, 60);
        let img = random_image(w, h, 7 + u64::from(s));
        let (cam, out) = downscale(&img, &camera(w, h), s).unwrap();
        assert_eq!((out.width, out.height), (w / s, h / s));
        assert_eq!((cam.width, cam.height), (w / s, h / s));
        let (a, b) = (mean(&img.rgb), mean(&out.rgb));
        assert!((a - b).abs() < 1e-5 * a, "factor {s}: mean {a} vs {b}");
        assert_eq!(out.valid_count(), out.pixel_count());
    }
}

#[test]
fn a_block_is_valid_only_if_all_its_pixels_are() {
    let (w, h, s) = (12u32, 9u32, 3u32);
    let mut img = random_image(w, h, 1);
    img.mask[(4 * w + 7) as usize] = 0; // source (7, 4) → block (2, 1)
    let (_, out) = downscale(&img, &camera(w, h), s).unwrap();
    for by in 0..out.height {
        for bx in 0..out.width {
            assert_eq!(out.is_valid(bx, by), (bx, by) != (2, 1), "block ({bx}, {by})");
        }
    }
}

#[test]
fn partial_edge_blocks_are_dropped() {
    let img = random_image(10, 7, 3);
    let (cam, out) = downscale(&img, &camera(10, 7), 3).unwrap();
    assert_eq!((out.width, out.height, cam.width, cam.height), (3, 2, 3, 2));
    // Block (2, 1) averages source columns 6..9 and rows 3..6.
    let mut sum = [0.0f64; 3];
    for y in 3..6 {
        for x in 6..9 {
            let p = img.pixel(x, y);
            (0..3).for_each(|c| sum[c] += f64::from(p[c]));
        }
    }
    let got = out.pixel(2, 1);
    (0..3).for_each(|c| assert!((f64::from(got[c]) - sum[c] / 9.0).abs() < 1e-5 * sum[c]));
}

/// The area average of a radiance field that is affine in the image plane equals the field at the block
/// centre, so the downscaled camera must see the same field at its own pixel centres: a direct check of
/// c' = (c + 0.5)/s - 0.5 and f' = f/s.
#[test]
fn downscaled_intrinsics_see_the_same_affine_field() {
    let (w, h) = (96u32, 64u32);
    let cam = camera(w, h);
    let field = |x: f64, y: f64| 2.0 + 0.7 * x - 1.3 * y; // over normalised coordinates (x, y)
    let k = cam.intrinsics;
    let rgb: Vec<f32> = (0..h)
        .flat_map(|v| (0..w).map(move |u| (u, v)))
        .flat_map(|(u, v)| {
            let f = field((f64::from(u) - k.cx) / k.fx, (f64::from(v) - k.cy) / k.fy) as f32;
            [f, f, f]
        })
        .collect();
    let img = LinearImage::new(w, h, rgb, vec![1; (w * h) as usize]).unwrap();
    for s in [2u32, 4] {
        let (small, out) = downscale(&img, &cam, s).unwrap();
        assert_eq!(small.intrinsics, scale_intrinsics(&k, s));
        let k2 = small.intrinsics;
        for v in 0..out.height {
            for u in 0..out.width {
                let expected = field((f64::from(u) - k2.cx) / k2.fx, (f64::from(v) - k2.cy) / k2.fy);
                assert!((f64::from(out.pixel(u, v)[0]) - expected).abs() < 1e-5, "factor {s} at ({u}, {v})");
            }
        }
        // The same point projects consistently: u' = (u + 0.5)/s - 0.5.
        let p = DVec3::new(0.3, -0.2, 2.0);
        let (a, b) = (cam.project_opencv(p).unwrap(), small.project_opencv(p).unwrap());
        let sf = f64::from(s);
        assert!(((a.x + 0.5) / sf - 0.5 - b.x).abs() < 1e-12 && ((a.y + 0.5) / sf - 0.5 - b.y).abs() < 1e-12);
    }
}

#[test]
fn bad_factors_are_errors() {
    let img = random_image(8, 8, 5);
    assert!(downscale(&img, &camera(8, 8), 0).is_err());
    let err = downscale(&img, &camera(8, 8), 9).unwrap_err().to_string();
    assert!(err.contains('9') && err.contains("8x8"), "{err}");
}
