//! The pixels a fit uses: every valid pixel of every image with its target radiance and the object its centre
//! sees, split once into a training set and a held-out set (for model decisions), and seeded batch draws.
//!
//! The training pixels are held as a pool, not in full: of each object's training pixels (and of those that
//! see no object) at most `train_pool` are kept, a uniform sample, with the count of all of them. Every draw
//! over the training pixels is a draw over all of them — a kept pixel stands for its object's count over its
//! kept count — so the fit is the same in distribution, while memory stops growing with the photos: a house
//! of 180 photos of 1280×1024 has 2.4·10⁸ valid pixels (7.5 GB as samples), of which a fit draws a few 10⁴.
//! Below the budget nothing is left out and every draw is the one it always was.
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
    /// The training pool: every training pixel of a stratum below the pool budget, a uniform sample of the
    /// budget's size of the others; in scan order (view, row, column), held-out candidates beyond their budget
    /// after the rest.
    pub train: Vec<Sample>,
    pub holdout: Vec<Sample>,
    /// Training pixels in the photos (not only in the pool) whose centre sees each object.
    pub train_per_object: Vec<usize>,
    /// The strata of the training pixels (objects in increasing order, then "no object"): how many the
    /// photos hold and which pool entries are theirs.
    pub strata: Vec<Stratum>,
}

/// One stratum of the training pixels: an object's, or those that see no object.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stratum {
    pub object: Option<u32>,
    /// Training pixels of the stratum in the photos.
    pub population: usize,
    /// Indices of its pool entries into the pixels it groups ([`PixelSets::train`] in the object stage), in
    /// pool order.
    pub members: Vec<usize>,
}

impl PixelSets {
    /// The pool's training pixels that see `object`, in pool order: its stratum's members, the pixels a pass over
    /// the whole pool would pick out, at the cost of the object's own pixels rather than of every object's (a
    /// house's model selection looks up each of its 200 objects this way, twice, and a pass costs the whole
    /// pool: 17 M pixels at 320×256). Without strata (a set built by hand), that pass.
    #[must_use]
    pub fn train_of(&self, object: Option<u32>) -> Vec<Sample> {
        if self.strata.is_empty() {
            return self.train.iter().filter(|t| t.object == object).copied().collect();
        }
        self.strata
            .iter()
            .find(|st| st.object == object)
            .map_or_else(Vec::new, |st| st.members.iter().map(|&i| self.train[i]).collect())
    }

    /// Training pixels in the photos (the pool holds all of them or a sample).
    #[must_use]
    pub fn train_total(&self) -> usize {
        self.strata.iter().map(|s| s.population).sum()
    }

    /// `n` training pixels drawn uniformly with replacement from all training pixels of the photos, keyed by
    /// (seed, stream, draw); with a complete pool exactly [`draw()`] over `train`.
    #[must_use]
    pub fn draw_train(&self, n: usize, seed: u64, stream: u64, draw_key: u64) -> Vec<Sample> {
        let total = self.train_total();
        if total == self.train.len() || self.strata.is_empty() {
            return draw(&self.train, n, seed, stream, draw_key);
        }
        // Pixel number v of the photos' training pixels (strata in order) is the stratum's kept entry at the
        // same relative position: the kept entries are a uniform sample, so this is a uniform draw.
        let mut starts = Vec::with_capacity(self.strata.len());
        let mut acc = 0usize;
        for s in &self.strata {
            starts.push(acc);
            acc += s.population;
        }
        (0..n as u64)
            .map(|i| {
                let u = uniform(seed, stream, draw_key, i);
                let v = ((u * total as f64) as usize).min(total - 1);
                let k = starts.partition_point(|&st| st <= v) - 1;
                let st = &self.strata[k];
                let j = ((v - starts[k]) * st.members.len() / st.population).min(st.members.len() - 1);
                self.train[st.members[j]]
            })
            .collect()
    }

    /// [`draw_stratified`] over all training pixels of the photos: the strata's shares and weights follow their
    /// counts in the photos, the pixels come from the pool.
    #[must_use]
    pub fn draw_train_stratified(&self, n: usize, floor: usize, seed: u64, stream: u64, draw_key: u64) -> WeightedDraw {
        draw_strata(&self.train, &self.strata, n, floor, seed, stream, draw_key)
    }

    /// Pixel sets whose training pool is all of `train` (each stratum's population its pixels in it), without
    /// held-out pixels: for tests of the draws.
    #[cfg(test)]
    pub(crate) fn of_train(train: Vec<Sample>) -> PixelSets {
        let strata = strata_of(&train, |_| 0);
        PixelSets { train, strata, ..Default::default() }
    }
}

/// A pixel offered to a [`Pool`]: ordered by its seeded rank, then by its position in the scan.
#[derive(Debug, Clone, Copy)]
struct Ranked {
    rank: f64,
    seq: u64,
    sample: Sample,
}

impl PartialEq for Ranked {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == std::cmp::Ordering::Equal
    }
}
impl Eq for Ranked {}
impl PartialOrd for Ranked {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Ranked {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.rank.total_cmp(&other.rank).then(self.seq.cmp(&other.seq))
    }
}

/// Per stratum, the `cap` offered pixels of smallest rank (a uniform sample when the ranks are seeded
/// uniforms), kept in one pass: memory `cap` per stratum whatever is offered.
struct Pool {
    cap: usize,
    heaps: std::collections::BTreeMap<Option<u32>, std::collections::BinaryHeap<Ranked>>,
}

impl Pool {
    fn new(cap: usize) -> Self {
        Pool { cap, heaps: std::collections::BTreeMap::new() }
    }

    /// Offers `r`; returns the pixel that does not fit (`r` itself or the one it displaces), if any.
    fn offer(&mut self, r: Ranked) -> Option<Ranked> {
        let heap = self.heaps.entry(r.sample.object).or_default();
        if heap.len() < self.cap {
            heap.push(r);
            return None;
        }
        match heap.peek() {
            Some(top) if r < *top => {
                let out = heap.pop();
                heap.push(r);
                out
            }
            _ => Some(r),
        }
    }

    /// Everything kept, in scan order (`seq`).
    fn into_sorted(self) -> Vec<Ranked> {
        let mut all: Vec<Ranked> = self.heaps.into_values().flat_map(std::collections::BinaryHeap::into_vec).collect();
        all.sort_by_key(|r| r.seq);
        all
    }
}

/// Collects the valid pixels (mask ≠ 0 and finite RGB) of all images: each is a held-out candidate with
/// probability `holdout_fraction`, of which at most `holdout_pixels` per object are held out (the rest train),
/// and of the training pixels at most `train_pool` per object are kept (see the module docs). One pass, with
/// memory bounded by the budgets.
#[must_use]
#[allow(clippy::too_many_arguments)]
pub fn collect(
    scene: &tracer::Scene,
    cameras: &[tracer::Camera],
    images: &[ingest::photo::LinearImage],
    objects: usize,
    holdout_fraction: f64,
    holdout_pixels: usize,
    train_pool: usize,
    seed: u64,
) -> PixelSets {
    // Held-out candidates beyond their object's budget train after every other pixel (the order the sets
    // always had): their scan position is offset by this.
    const REJECTED: u64 = 1 << 62;
    let mut holdout = Pool::new(holdout_pixels);
    let mut train = Pool::new(train_pool.max(1));
    let mut population: std::collections::BTreeMap<Option<u32>, usize> = std::collections::BTreeMap::new();
    let mut to_train = |r: Ranked, population: &mut std::collections::BTreeMap<Option<u32>, usize>| {
        *population.entry(r.sample.object).or_default() += 1;
        let rank = uniform(seed, draw::TRAIN_POOL, pixel_key(r.sample.pixel), 0);
        let _ = train.offer(Ranked { rank, ..r });
    };
    let mut seq = 0u64;
    for (view, (cam, img)) in cameras.iter().zip(images).enumerate() {
        for (x, y, t) in valid_pixels(cam, img) {
            let (o, d) = cam.ray(Vec2::new(x as f32, y as f32));
            let object = scene.intersect(o, d, f32::INFINITY).map(|(hit, _)| scene.material_of(hit.tri));
            let pixel = PixelRef { view: view as u32, x, y };
            let sample = Sample { pixel, target: t, object };
            let key = pixel_key(pixel);
            seq += 1;
            if uniform(seed, draw::HOLDOUT, key, 0) < holdout_fraction {
                let rank = uniform(seed, draw::HOLDOUT, key, 1);
                if let Some(out) = holdout.offer(Ranked { rank, seq, sample }) {
                    to_train(Ranked { seq: REJECTED + out.seq, ..out }, &mut population);
                }
            } else {
                to_train(Ranked { rank: 0.0, seq, sample }, &mut population);
            }
        }
    }
    let mut sets = PixelSets { train_per_object: vec![0; objects], ..Default::default() };
    sets.holdout = holdout.into_sorted().into_iter().map(|r| r.sample).collect();
    sets.train = train.into_sorted().into_iter().map(|r| r.sample).collect();
    for (&object, &n) in &population {
        if let Some(k) = object
            && (k as usize) < objects
        {
            sets.train_per_object[k as usize] = n;
        }
    }
    sets.strata = strata_of(&sets.train, |object| population.get(&object).copied().unwrap_or(0));
    sets
}

/// The strata of `from` in a fixed order (by object, "no object" last), with the population of each.
fn strata_of(from: &[Sample], population: impl Fn(Option<u32>) -> usize) -> Vec<Stratum> {
    let mut groups: HashMap<Option<u32>, Vec<usize>> = HashMap::new();
    for (i, s) in from.iter().enumerate() {
        groups.entry(s.object).or_default().push(i);
    }
    let mut strata: Vec<Stratum> = groups
        .into_iter()
        .map(|(object, members)| Stratum { object, population: population(object).max(members.len()), members })
        .collect();
    strata.sort_by_key(|s| s.object.map_or(u64::MAX, u64::from));
    strata
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
    cap_per_object_each(samples, |_| per_object, rank)
}

/// [`cap_per_object`] with a cap of its own for each object, `cap(object)`.
#[must_use]
pub fn cap_per_object_each(
    samples: Vec<Sample>,
    cap: impl Fn(Option<u32>) -> usize,
    rank: impl Fn(&Sample) -> f64,
) -> (Vec<Sample>, Vec<Sample>) {
    let mut groups: HashMap<Option<u32>, Vec<usize>> = HashMap::new();
    for (i, s) in samples.iter().enumerate() {
        groups.entry(s.object).or_default().push(i);
    }
    let mut keep = vec![true; samples.len()];
    for (object, idx) in &groups {
        let per_object = cap(*object);
        if idx.len() <= per_object {
            continue;
        }
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
    let strata = strata_of(from, |_| 0);
    draw_strata(from, &strata, n, floor, seed, stream, draw)
}

/// [`draw_stratified`] on given strata of `from`: shares and weights follow each stratum's `population`, the
/// pixels come from its `members`.
fn draw_strata(
    from: &[Sample],
    strata: &[Stratum],
    n: usize,
    floor: usize,
    seed: u64,
    stream: u64,
    draw: u64,
) -> WeightedDraw {
    if from.is_empty() {
        return WeightedDraw::default();
    }
    let (rows, weights) = draw_strata_rows(strata, n, floor, seed, stream, draw);
    WeightedDraw { samples: rows.iter().map(|&j| from[j]).collect(), weights }
}

/// The draw of [`draw_stratified`] on given strata, as the drawn members (indices into the array the strata's
/// `members` index) and their weights (mean 1): the one allocation and weighting of stratified solve pixels,
/// shared by the object stage's solves and the per-triangle stage's light re-solve.
#[must_use]
pub fn draw_strata_rows(
    strata: &[Stratum],
    n: usize,
    floor: usize,
    seed: u64,
    stream: u64,
    draw: u64,
) -> (Vec<usize>, Vec<f64>) {
    if strata.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let total = strata.iter().map(|s| s.population).sum::<usize>() as f64;
    let rest = n.saturating_sub(floor * strata.len());
    let exact: Vec<f64> = strata.iter().map(|s| rest as f64 * s.population as f64 / total).collect();
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
    let (mut rows, mut weights) = (Vec::new(), Vec::new());
    for (stratum, &s) in strata.iter().zip(&share) {
        let idx = &stratum.members;
        let want = (floor + s).max(1);
        let stratum_weight = stratum.population as f64 / total;
        // Keyed by the stratum and the index within it: one stratum's draw does not depend on the others'.
        let stratum_key = mix64(stratum.object.map_or(0, |o| u64::from(o) + 1));
        if want >= idx.len() {
            // The whole stratum (or its whole pool), each pixel once.
            for &j in idx {
                rows.push(j);
                weights.push(stratum_weight / idx.len() as f64);
            }
        } else {
            for i in 0..want as u64 {
                let u = uniform(seed, stream, draw, stratum_key ^ i);
                rows.push(idx[((u * idx.len() as f64) as usize).min(idx.len() - 1)]);
                weights.push(stratum_weight / want as f64);
            }
        }
    }
    let m = rows.len() as f64;
    weights.iter_mut().for_each(|w| *w *= m);
    (rows, weights)
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

    /// A pool of 500 pixels per stratum for strata of 20 000, 2 000 and 20 pixels and 300 that see no object.
    fn pooled() -> (Vec<Sample>, PixelSets) {
        let all = strata();
        let mut pool = Pool::new(500);
        let mut population: HashMap<Option<u32>, usize> = HashMap::new();
        for (seq, s) in all.iter().enumerate() {
            *population.entry(s.object).or_default() += 1;
            let rank = uniform(4, draw::TRAIN_POOL, pixel_key(s.pixel), 0);
            let _ = pool.offer(Ranked { rank, seq: seq as u64, sample: *s });
        }
        let train: Vec<Sample> = pool.into_sorted().into_iter().map(|r| r.sample).collect();
        let strata = strata_of(&train, |o| population[&o]);
        (all, PixelSets { train, strata, ..Default::default() })
    }

    /// The pool keeps the budget of each stratum (all of a smaller one), in scan order, and knows the counts.
    #[test]
    fn the_pool_keeps_its_budget_per_stratum_in_scan_order() {
        let (all, sets) = pooled();
        assert_eq!(sets.train.len(), 500 + 500 + 20 + 300);
        assert_eq!(sets.train_total(), all.len());
        let pos = |s: &Sample| all.iter().position(|a| a == s).unwrap();
        assert!(sets.train.windows(2).all(|w| pos(&w[0]) < pos(&w[1])));
        let pops: Vec<(Option<u32>, usize, usize)> =
            sets.strata.iter().map(|s| (s.object, s.population, s.members.len())).collect();
        assert_eq!(pops, vec![(Some(0), 20_000, 500), (Some(1), 2_000, 500), (Some(2), 20, 20), (None, 300, 300)]);
    }

    /// An object's pixels looked up by its stratum are those a pass over the pool picks out, in the same order,
    /// for every stratum, an object with none, and a set without strata.
    #[test]
    fn an_objects_pixels_by_its_stratum_are_those_of_a_pass_over_the_pool() {
        let (_, sets) = pooled();
        let hand_built = PixelSets { train: sets.train.clone(), ..Default::default() };
        for object in [Some(0), Some(1), Some(2), Some(7), None] {
            let pass: Vec<Sample> = sets.train.iter().filter(|t| t.object == object).copied().collect();
            assert_eq!(sets.train_of(object), pass, "{object:?}");
            assert_eq!(hand_built.train_of(object), pass, "{object:?}");
        }
        assert!(sets.train_of(Some(7)).is_empty());
    }

    /// Drawn from the pool, the training pixels of each stratum come in proportion to its count in the photos
    /// (not in the pool): 200 000 draws, each stratum's frequency within 5 binomial σ of its share.
    #[test]
    fn draws_from_a_pool_are_uniform_over_all_training_pixels() {
        let (all, sets) = pooled();
        let n = 200_000;
        let d = sets.draw_train(n, 9, draw::BATCH, 3);
        for st in &sets.strata {
            let p = st.population as f64 / all.len() as f64;
            let got = d.iter().filter(|s| s.object == st.object).count() as f64;
            let sigma = (n as f64 * p * (1.0 - p)).sqrt();
            assert!((got - n as f64 * p).abs() < 5.0 * sigma.max(1.0), "{:?}: {got} for {}", st.object, n as f64 * p);
        }
        // The stratified draw weighs each stratum by its share of the photos' pixels.
        let w = sets.draw_train_stratified(256, 32, 5, draw::SOLVE_PIXELS, 0);
        let m = w.samples.len() as f64;
        for st in &sets.strata {
            let share: f64 =
                w.samples.iter().zip(&w.weights).filter(|(s, _)| s.object == st.object).map(|(_, x)| x).sum();
            let p = st.population as f64 / all.len() as f64;
            assert!((share / m - p).abs() < 1e-12, "{:?}: {} for {p}", st.object, share / m);
        }
    }

    /// With every pixel kept, the draws are exactly those over the plain list.
    #[test]
    fn a_complete_pool_draws_as_the_plain_list() {
        let all = strata();
        let sets = PixelSets { train: all.clone(), strata: strata_of(&all, |_| 0), ..Default::default() };
        assert_eq!(sets.draw_train(300, 2, draw::BATCH, 7), draw(&all, 300, 2, draw::BATCH, 7));
        assert_eq!(
            sets.draw_train_stratified(256, 32, 5, draw::SOLVE_PIXELS, 1),
            draw_stratified(&all, 256, 32, 5, draw::SOLVE_PIXELS, 1)
        );
    }
}
