//! The pixels a fit uses: every valid pixel of every image with its target radiance and the object its centre
//! sees, split once into a training set and a held-out set (for model decisions), and seeded batch draws.

use glam::{Vec2, Vec3};
use tracer::PixelRef;

use crate::streams::{draw, pixel_key, uniform};

/// One training or held-out pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub pixel: PixelRef,
    pub target: Vec3,
    /// Object seen through the pixel centre, `None` when the ray leaves the scene.
    pub object: Option<u32>,
}

/// Training and held-out pixels.
#[derive(Debug, Clone, Default)]
pub struct PixelSets {
    pub train: Vec<Sample>,
    pub holdout: Vec<Sample>,
    /// Training pixels whose centre sees each object.
    pub train_per_object: Vec<usize>,
}

/// Collects the valid pixels (mask ≠ 0 and finite RGB) of all images.
#[must_use]
pub fn collect(
    scene: &tracer::Scene,
    cameras: &[tracer::Camera],
    images: &[ingest::photo::LinearImage],
    objects: usize,
    holdout_fraction: f64,
    seed: u64,
) -> PixelSets {
    let mut sets = PixelSets { train_per_object: vec![0; objects], ..Default::default() };
    for (view, (cam, img)) in cameras.iter().zip(images).enumerate() {
        for (x, y, t) in valid_pixels(cam, img) {
            let (o, d) = cam.ray(Vec2::new(x as f32, y as f32));
            let object = scene.intersect(o, d, f32::INFINITY).map(|(hit, _)| scene.material_of(hit.tri));
            let pixel = PixelRef { view: view as u32, x, y };
            let s = Sample { pixel, target: t, object };
            let key = pixel_key(pixel);
            if uniform(seed, draw::HOLDOUT, key, 0) < holdout_fraction {
                sets.holdout.push(s);
            } else {
                if let Some(k) = object
                    && (k as usize) < objects
                {
                    sets.train_per_object[k as usize] += 1;
                }
                sets.train.push(s);
            }
        }
    }
    sets
}

/// The valid pixels of one image seen by `cam` — mask ≠ 0 and finite RGB, within both sizes — as (column,
/// row, target radiance) in row-major order: the one definition of a usable photo pixel for both fits.
pub fn valid_pixels<'a>(
    cam: &tracer::Camera,
    img: &'a ingest::photo::LinearImage,
) -> impl Iterator<Item = (u32, u32, Vec3)> + 'a {
    let (w, h) = (img.width.min(cam.width), img.height.min(cam.height));
    (0..h).flat_map(move |y| (0..w).map(move |x| (x, y))).filter_map(move |(x, y)| {
        let i = (y * img.width + x) as usize;
        let t = Vec3::new(img.rgb[3 * i], img.rgb[3 * i + 1], img.rgb[3 * i + 2]);
        (img.mask[i] != 0 && t.is_finite()).then_some((x, y, t))
    })
}

/// `n` samples drawn uniformly with replacement from `from`, keyed by (seed, stream, draw).
#[must_use]
pub fn draw(from: &[Sample], n: usize, seed: u64, stream: u64, draw: u64) -> Vec<Sample> {
    if from.is_empty() {
        return Vec::new();
    }
    (0..n as u64)
        .map(|i| {
            let u = uniform(seed, stream, draw, i);
            from[((u * from.len() as f64) as usize).min(from.len() - 1)]
        })
        .collect()
}
