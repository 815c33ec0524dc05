//! The pixels a fit uses: every valid pixel of every image with its target radiance and the object its centre
//! sees, split once into a training set and a held-out set (for model decisions), and seeded batch draws.
//!
//! The held-out set is a budget, not a fraction of the photos: each pixel is a held-out candidate with
//! probability `holdout_fraction`, and of an object's candidates (and of those that see no object) at most
//! `holdout_pixels` are kept, chosen uniformly; the others train. A model decision's statistics need a
//! sample of fixed size (docs/optim/design-measurements.md), so its cost stops growing with the number and
//! resolution of the photos and grows at most linearly with the number of objects.

use std::collections::HashMap;

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
    holdout_pixels: usize,
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
    let candidates = std::mem::take(&mut sets.holdout);
    let rank = |s: &Sample| uniform(seed, draw::HOLDOUT, pixel_key(s.pixel), 1);
    let (kept, rejected) = cap_per_object(candidates, holdout_pixels, rank);
    sets.holdout = kept;
    // Candidates beyond an object's budget train, appended after the others (a deterministic order; below the
    // budget nothing moves, so small scans keep exactly the sets they always had).
    for s in rejected {
        if let Some(k) = s.object
            && (k as usize) < objects
        {
            sets.train_per_object[k as usize] += 1;
        }
        sets.train.push(s);
    }
    sets
}

/// Splits `samples` into at most `per_object` samples per object (and per "no object"), those with the
/// smallest `rank`, and the rest; both keep the input order. With a seeded uniform `rank` the kept ones are
/// a uniform sample of each object's.
#[must_use]
pub fn cap_per_object(
    samples: Vec<Sample>,
    per_object: usize,
    rank: impl Fn(&Sample) -> f64,
) -> (Vec<Sample>, Vec<Sample>) {
    let mut groups: HashMap<Option<u32>, Vec<usize>> = HashMap::new();
    for (i, s) in samples.iter().enumerate() {
        groups.entry(s.object).or_default().push(i);
    }
    let mut keep = vec![true; samples.len()];
    for idx in groups.values_mut().filter(|g| g.len() > per_object) {
        let ranks: Vec<f64> = idx.iter().map(|&i| rank(&samples[i])).collect();
        let mut order: Vec<usize> = (0..idx.len()).collect();
        order.sort_by(|&a, &b| ranks[a].total_cmp(&ranks[b]).then(a.cmp(&b)));
        for &o in &order[per_object..] {
            keep[idx[o]] = false;
        }
    }
    let (mut kept, mut rest) = (Vec::new(), Vec::new());
    for (s, k) in samples.into_iter().zip(keep) {
        if k { kept.push(s) } else { rest.push(s) }
    }
    (kept, rest)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(view: u32, x: u32, object: Option<u32>) -> Sample {
        Sample { pixel: PixelRef { view, x, y: 0 }, target: Vec3::ONE, object }
    }

    /// Held-out candidates of `views` photos of 3 objects (object k sees 100·(k + 1) pixels per photo) and
    /// some sky pixels: the budget bounds every object's held-out pixels whatever the photo count, keeps
    /// all of them below it, loses none, and keeps the input order.
    #[test]
    fn the_budget_bounds_each_objects_held_out_pixels_whatever_the_photo_count() {
        let budget = 500;
        for views in [1, 4, 16, 64] {
            let mut all = Vec::new();
            for v in 0..views {
                for k in 0..3u32 {
                    all.extend((0..100 * (k + 1)).map(|x| sample(v, x + 1000 * k, Some(k))));
                }
                all.extend((0..50).map(|x| sample(v, 5000 + x, None)));
            }
            let n = all.len();
            let rank = |s: &Sample| uniform(9, draw::HOLDOUT, pixel_key(s.pixel), 1);
            let (kept, rest) = cap_per_object(all.clone(), budget, rank);
            assert_eq!(kept.len() + rest.len(), n);
            for group in [Some(0), Some(1), Some(2), None] {
                let have = all.iter().filter(|s| s.object == group).count();
                let got = kept.iter().filter(|s| s.object == group).count();
                assert_eq!(got, have.min(budget), "{views} views, object {group:?}");
            }
            let key = |s: &Sample| (s.pixel.view, s.pixel.x);
            assert!(kept.windows(2).all(|w| key(&w[0]) < key(&w[1])), "kept samples out of order");
            assert!(rest.windows(2).all(|w| key(&w[0]) < key(&w[1])), "other samples out of order");
        }
    }

    /// The kept pixels are a uniform sample: with a budget of half an object's pixels, each photo of 64
    /// contributes about half of its pixels (binomial spread, 5σ bound).
    #[test]
    fn the_kept_pixels_are_spread_uniformly_over_the_photos() {
        let all: Vec<Sample> = (0..64).flat_map(|v| (0..200).map(move |x| sample(v, x, Some(0)))).collect();
        let rank = |s: &Sample| uniform(3, draw::HOLDOUT, pixel_key(s.pixel), 1);
        let (kept, _) = cap_per_object(all, 64 * 100, rank);
        for v in 0..64 {
            let c = kept.iter().filter(|s| s.pixel.view == v).count() as f64;
            // Hypergeometric, close to binomial(200, 1/2): σ ≈ 7.1; 5σ ≈ 35.
            assert!((c - 100.0).abs() < 35.0, "photo {v}: {c} of 200 kept");
        }
    }
}
