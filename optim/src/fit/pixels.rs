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

use crate::streams::{draw, mix64, pixel_key, uniform};

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

/// Training pixels of a solve drawn per stratum, with their weights: see [`draw_stratified`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WeightedDraw {
    pub samples: Vec<Sample>,
    /// One per sample, mean 1: `(1/M) Σ_j weights[j] · f(samples[j])` is an unbiased estimate of the mean of
    /// `f` over all pixels of `from`.
    pub weights: Vec<f64>,
}

/// Pixels drawn per object (each object is a stratum, and so are the pixels that see no object): every
/// stratum gets `floor` pixels, the rest of `n` (if any) is shared in proportion to the strata's sizes (largest
/// remainder, so the shares sum exactly). A stratum whose share reaches its size contributes each of its
/// pixels once; otherwise its share is drawn uniformly with replacement, keyed by (seed, stream, draw, index).
/// Pixel j of stratum k (N_k of the N pixels, n_k drawn) has the weight (N_k / N) · (M / n_k), M the number
/// drawn: the weighted mean over the draw is the stratified estimate of the mean over all of `from`, which is
/// unbiased whatever the allocation — the floor buys small objects rows without changing what a solve
/// minimises in expectation.
#[must_use]
pub fn draw_stratified(from: &[Sample], n: usize, floor: usize, seed: u64, stream: u64, draw: u64) -> WeightedDraw {
    if from.is_empty() {
        return WeightedDraw::default();
    }
    // Strata in a fixed order (by object, "no object" last) so that the draw is a pure function of its key.
    let mut strata: Vec<(Option<u32>, Vec<usize>)> = {
        let mut groups: HashMap<Option<u32>, Vec<usize>> = HashMap::new();
        for (i, s) in from.iter().enumerate() {
            groups.entry(s.object).or_default().push(i);
        }
        groups.into_iter().collect()
    };
    strata.sort_by_key(|(o, _)| o.map_or(u64::MAX, u64::from));
    let total = from.len() as f64;
    let rest = n.saturating_sub(floor * strata.len());
    let exact: Vec<f64> = strata.iter().map(|(_, idx)| rest as f64 * idx.len() as f64 / total).collect();
    let mut share: Vec<usize> = exact.iter().map(|e| e.floor() as usize).collect();
    // Saturating: rounding could make the floors' sum exceed `rest` by one in a degenerate split.
    let mut left = rest.saturating_sub(share.iter().sum::<usize>());
    let mut order: Vec<usize> = (0..strata.len()).collect();
    order.sort_by(|&a, &b| (exact[b] - exact[b].floor()).total_cmp(&(exact[a] - exact[a].floor())).then(a.cmp(&b)));
    for &k in &order {
        if left == 0 {
            break;
        }
        share[k] += 1;
        left -= 1;
    }
    let mut out = WeightedDraw::default();
    for ((object, idx), &s) in strata.iter().zip(&share) {
        let want = (floor + s).max(1);
        let stratum_weight = idx.len() as f64 / total;
        // Keyed by the stratum and the index within it: one stratum's draw does not depend on the others'.
        let stratum_key = mix64(object.map_or(0, |o| u64::from(o) + 1));
        if want >= idx.len() {
            // The whole stratum, each pixel once.
            for &j in idx {
                out.samples.push(from[j]);
                out.weights.push(stratum_weight / idx.len() as f64);
            }
        } else {
            for i in 0..want as u64 {
                let u = uniform(seed, stream, draw, stratum_key ^ i);
                out.samples.push(from[idx[((u * idx.len() as f64) as usize).min(idx.len() - 1)]]);
                out.weights.push(stratum_weight / want as f64);
            }
        }
    }
    let m = out.samples.len() as f64;
    out.weights.iter_mut().for_each(|w| *w *= m);
    out
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

    /// Strata of 20 000, 2 000 and 20 pixels and 300 that see no object, 256 solve pixels with a floor of 32.
    fn strata() -> Vec<Sample> {
        let mut all = Vec::new();
        for (k, n) in [(0u32, 20_000u32), (1, 2_000), (2, 20)] {
            all.extend((0..n).map(|x| sample(k, x, Some(k))));
        }
        all.extend((0..300).map(|x| sample(9, x, None)));
        all
    }

    /// Every stratum gets its floor (or all its pixels when it has fewer), the rest goes in proportion to the
    /// strata's sizes, and each stratum's weights sum to its share of the population.
    #[test]
    fn the_stratified_draw_meets_every_floor_and_weighs_each_stratum_by_its_share() {
        let all = strata();
        let (n, floor) = (256, 32);
        let d = draw_stratified(&all, n, floor, 5, draw::SOLVE_PIXELS, 0);
        let m = d.samples.len();
        assert_eq!(d.weights.len(), m);
        // The 20-pixel object is taken whole (20 instead of its floor), the others get 32 + their share of
        // 256 − 4·32 = 128: 114.70, 11.47, 0.11, 1.72 → 115, 11, 0, 2 by largest remainder.
        let want = [(Some(0), 32 + 115), (Some(1), 32 + 11), (Some(2), 20), (None, 32 + 2)];
        for (group, count) in want {
            let got = d.samples.iter().filter(|s| s.object == group).count();
            assert_eq!(got, count, "stratum {group:?}");
            let share: f64 = d.samples.iter().zip(&d.weights).filter(|(s, _)| s.object == group).map(|(_, w)| w).sum();
            let population = all.iter().filter(|s| s.object == group).count() as f64 / all.len() as f64;
            // Sums of a few hundred f64 terms: equal to rounding.
            assert!((share / m as f64 - population).abs() < 1e-12, "stratum {group:?}: {share} of {m}");
        }
        assert_eq!(m, 147 + 43 + 20 + 34);
        // A floor larger than the budget: every stratum still gets it.
        let d = draw_stratified(&all, 16, floor, 5, draw::SOLVE_PIXELS, 0);
        assert_eq!(d.samples.len(), 32 + 32 + 20 + 32);
    }

    /// The weighted mean of a pixel function over the draw is an unbiased estimate of its mean over all pixels:
    /// over 400 seeded draws the mean of the estimates lies within 4 standard errors of the population mean,
    /// while the unweighted mean (which over-represents the small strata) is far from it.
    #[test]
    fn the_weighted_mean_over_the_stratified_draw_is_unbiased() {
        let all = strata();
        // A value that differs between strata and varies within them.
        let f = |s: &Sample| f64::from(s.object.map_or(7, |o| 3 * o + 1)) + (s.pixel.x % 13) as f64 * 0.1;
        let truth = all.iter().map(f).sum::<f64>() / all.len() as f64;
        let draws = 400;
        let (mut est, mut naive) = (Vec::new(), Vec::new());
        for key in 0..draws {
            let d = draw_stratified(&all, 256, 32, 11, draw::SOLVE_PIXELS, key);
            let m = d.samples.len() as f64;
            est.push(d.samples.iter().zip(&d.weights).map(|(s, w)| w * f(s)).sum::<f64>() / m);
            naive.push(d.samples.iter().map(f).sum::<f64>() / m);
        }
        let mean = est.iter().sum::<f64>() / draws as f64;
        let sd = (est.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (draws - 1) as f64).sqrt();
        let se = sd / (draws as f64).sqrt();
        // 4 standard errors: a false failure has probability < 1e-4; a bias of the size of the naive mean's
        // (below) would be hundreds of them.
        assert!((mean - truth).abs() < 4.0 * se, "weighted {mean} vs {truth} (se {se})");
        let naive_mean = naive.iter().sum::<f64>() / draws as f64;
        assert!((naive_mean - truth).abs() > 100.0 * se, "unweighted {naive_mean} vs {truth}");
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
