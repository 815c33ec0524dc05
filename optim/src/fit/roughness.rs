//! Roughness (and, where a dielectric cannot reflect enough, metallic) of one object by 1-D searches on its
//! profile loss.
//!
//! For a fixed roughness r and metallic m, an object's own pixels are (to first order, the light it sends
//! back to itself through other surfaces aside) nearly linear in its base colour and its specular strength:
//! the diffuse lobe is (1 − m)·ρ/π weighted by (1 − F)², the specular lobe is linear in
//! F0 = (1 − m)·0.08·s + m·ρ (tracer/src/bsdf/mod.rs), and the solve below linearises about the current
//! values. So the profile loss
//! `P(r) = min over (ρ, s) of the L1 residual on the object's pixels` is cheap: one value render at r, one
//! Jacobian pass for (ρ_rgb, s), and a 4-variable box-constrained IRLS solve. `P` is searched on a coarse grid
//! and refined by Brent's method (parabolas through the best points, golden sections where a parabola does not
//! help), every evaluation with the same random numbers (common random
//! numbers: the Monte Carlo noise of P(r) is then a smooth function of r instead of independent jitter, so the
//! search does not chase it).
//!
//! Why not Gauss–Newton on roughness with the other unknowns (what the fit did first): measured on the glossy
//! fixture, 4 coupled steps from r = 0.5 with a ±0.1 trust region ended at 0.20 for a true 0.4 and 0.33 for a
//! true 0.25 — the GGX lobe is far from linear in r, and the per-pixel roughness gradient of a 128-path
//! Jacobian is noisy enough that the steps wander inside the trust region.

use super::jacobian::{self, Ctx};
use super::layout::{BASE_COLOR, METALLIC, ROUGHNESS, SPECULAR, idx};
use super::linear::{self, DataLoss, Problem};
use super::paired::half_paths;
use super::pixels::{PixelSets, Sample};
use crate::streams::{self, draw, key};
use tracer::{PixelRef, TracerError};

/// Coarse grid of the search: spans the domain with finer steps at low roughness, where the lobe changes
/// fastest (its width is α = r²).
pub const GRID: [f64; 7] = [0.04, 0.12, 0.22, 0.33, 0.45, 0.62, 0.85];
/// The grid points evaluated first (indices into [`GRID`]: 0.04, 0.22, 0.45, 0.85). When the profile is
/// flat over them ([`FLAT_PROFILE`]) the other three are not evaluated: the lobe's effect on the photos changes
/// smoothly with its width α = r², so a profile that varies by less than 0.5 % between r = 0.04 and 0.22 and
/// on to 0.85 does not dip by more in between. A diffuse wall's search then costs 4 evaluations instead of 7.
pub const COARSE: [usize; 4] = [0, 2, 4, 6];
/// Golden-section steps of the search on metallic ([`search_lobe`]): the bracket [0, 1] shrinks by 0.618 per
/// step, to < 0.06 after 6 steps.
pub const GOLDEN_STEPS: usize = 6;
/// Most evaluations of the roughness refinement inside the bracket around the best grid point ([`brent`]).
/// Its first step is the vertex of the parabola through the best grid point and its two neighbours, all
/// already evaluated, where a golden section spends two evaluations before it narrows anything; near a smooth
/// minimum each further parabola gains more than a golden section's factor 0.618, and a golden section is
/// taken wherever a parabola would not shrink the bracket. Golden sections alone took 8 evaluations for a
/// bracket of < 0.023 (0.4 · 0.618⁷), half of the lobe search's evaluations on the corpus house (137 of its
/// 196 objects refined). On smooth profiles with their minimum anywhere in [0.01, 0.99] (the test below) this
/// ends within 0.012 of it after 3.8 evaluations on average, 5 at most (a minimum within 0.04 of the
/// domain's top, where no parabola brackets it). The profile's own noise (a glossy floor's roughness
/// 0.68–0.78 for a true 0.8 between runs) is far above the last steps' gains.
pub const REFINE_EVALS: usize = 5;
/// The refinement stops once the minimum is bracketed within ±2 · this (a roughness tolerance of 0.05 is
/// what the fit is asked for): smaller steps would chase the profile's noise.
const REFINE_TOL: f64 = 0.01;
/// The refinement is skipped when the profile loss varies over the grid by less than this
/// fraction of the mean |target| of the object's pixels: roughness then does not matter to the photos (a
/// diffuse wall's best lobe is weak, its grid spread measured at 0.1–0.3 %; the glossy fixture's floor and
/// box spread 5–20 %), and the lobe, if any, is judged at the best grid point. Halves the search's cost. The same
/// holds where the lobe lowers a dielectric's profile below its best Lambert surface's by less than this at every
/// coarse point ([`lobe_gain`]): the L1 of one render grows with the noise of a sharper lobe, so a diffuse
/// surface's profile spreads over the grid by more than this while no lobe buys it anything.
pub const FLAT_PROFILE: f64 = 0.005;
/// A dielectric's specular strength at or above this is at its bound (the solve's box is [0, 1]; its IRLS
/// iterate ends on the bound, or within rounding of it, when the photos ask for more): the metal family is
/// then searched too ([`search_lobe`]).
pub const SPECULAR_BOUND: f64 = 0.99;
/// IRLS rounds of the 4-variable solve (converges in a handful).
const IRLS_ITERS: usize = 12;

/// Linearisation point of the roughness search's (base colour, specular) solve: a mid-range lobe, so that
/// the tracer samples the specular lobe and its Jacobian column is not zero.
pub(super) const TRIAL_SPECULAR: f64 = 0.5;
pub(super) const TRIAL_ROUGHNESS: f64 = 0.5;
/// Pixels of an object in its roughness search (each evaluation: a value render and 3 gradient passes at
/// `solve_spp / 2` paths). 256 pixels × 3 channels keep the profile's noise well under the 5–20 % spread of
/// a glossy object's profile over the roughness grid, at half the cost of 512 (measured below in
/// tests/fit_glossy.rs).
pub(super) const PROFILE_PIXELS: usize = 256;
/// Paths per pixel of a roughness profile's renders: half the solves' `solve_spp` (at least 1), the
/// path count behind [`PROFILE_PIXELS`]'s measurement.
pub(super) fn profile_spp(solve_spp: u32) -> u32 {
    (solve_spp / 2).max(1)
}
/// Whether a training pixel belongs to the half that chooses lobes (the other half tests them).
pub(super) fn in_profile(seed: u64, t: &Sample) -> bool {
    streams::uniform(seed, draw::PROFILE, streams::pixel_key(t.pixel), 0) < 0.5
}

/// Object k's pixels for a roughness search: its training pixels of the lobe-choosing half, at most
/// [`PROFILE_PIXELS`] of them.
pub(super) fn profile_samples(ctx: &Ctx<'_>, sets: &PixelSets, k: usize) -> Vec<Sample> {
    let own: Vec<Sample> = sets.train_of(Some(k as u32)).into_iter().filter(|t| in_profile(ctx.seed, t)).collect();
    if own.len() <= PROFILE_PIXELS {
        own
    } else {
        super::pixels::draw(&own, PROFILE_PIXELS, ctx.seed, draw::SOLVE_PIXELS, key::SELECT + k as u64)
    }
}

/// The pixels of the lobe tests: all test pixels, and, with held-out pixels, each object's training pixels of
/// the half that does not choose lobes ([`in_profile`]) up to the held-out budget `budget` per object.
pub(super) fn lobe_test_samples(ctx: &Ctx<'_>, sets: &PixelSets, test: &[Sample], budget: usize) -> Vec<Sample> {
    test.iter()
        .copied()
        .chain(if sets.holdout.is_empty() {
            Vec::new()
        } else {
            let mut held: std::collections::HashMap<Option<u32>, usize> = std::collections::HashMap::new();
            for t in test {
                *held.entry(t.object).or_default() += 1;
            }
            let room = |o: Option<u32>| budget.saturating_sub(held.get(&o).copied().unwrap_or(0));
            let rank = |t: &Sample| streams::uniform(ctx.seed, draw::PROFILE, streams::pixel_key(t.pixel), 1);
            let half: Vec<Sample> = sets.train.iter().filter(|t| !in_profile(ctx.seed, t)).copied().collect();
            super::pixels::cap_per_object_each(half, room, rank).0
        })
        .collect()
}

/// The result of one profile evaluation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfilePoint {
    pub roughness: f64,
    /// The metallic parameter the point was evaluated at (held, not fitted, by [`profile`]).
    pub metallic: f64,
    /// Mean per-channel L1 residual on the object's pixels after the best (ρ, s) for this roughness.
    pub loss: f64,
    pub base_color: [f64; 3],
    pub specular: f64,
    /// Where `specular` is at its bound ([`SPECULAR_BOUND`]): the profile loss with the specular strength at
    /// most [`HALF_SPECULAR`] instead, from the same render and Jacobian (what the last doubling of a
    /// dielectric's reflection buys); `None` below the bound.
    pub loss_half_specular: Option<f64>,
    /// For a dielectric (metallic 0): the profile loss of the object's best Lambert surface (specular
    /// strength 0), from the same render and Jacobian, so that `loss_lambert − loss` is what the lobe buys at
    /// this roughness ([`lobe_pays`]); `None` for a metal, whose reflection does not depend on the specular
    /// strength, and for a profile capped at 0 already.
    pub loss_lambert: Option<f64>,
    /// The root of the unbiased mean squared residual per channel after the same solve, from two independent
    /// value renders at half the paths each ([`profile_unbiased`]); `None` from one render ([`profile`]).
    pub rms: Option<f64>,
}

impl ProfilePoint {
    /// The unbiased RMS error where the point has one ([`profile_unbiased`]), else the L1 loss of its one render.
    #[must_use]
    pub fn rms_or_loss(&self) -> f64 {
        self.rms.unwrap_or(self.loss)
    }
}

/// The cap on the specular strength of the comparison solve behind [`ProfilePoint::loss_half_specular`]: half
/// the dielectric's range (F0 ≤ 0.04 instead of 0.08).
pub const HALF_SPECULAR: f64 = 0.5;

/// Evaluates the profile loss of object `k` at roughness `r`, linearising around the base colour and
/// specular of `x` (other objects as in `x`). `samples` are pixels whose centre sees object k.
pub fn profile(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    r: f64,
    samples: &[Sample],
    spp: u32,
    key: u64,
) -> Result<ProfilePoint, TracerError> {
    profile_capped(ctx, x, k, r, (samples, spp, key), 1.0)
}

/// [`profile`] with the value rendered twice at half of `spp` each (the second at `key` XOR
/// [`key::SECOND_ESTIMATE`]): the solve sees their mean, and [`ProfilePoint::rms`] is the root of the mean
/// product of the two residuals, the squared residual of a converged render (the L1 `loss` of one render is
/// inflated by its Monte Carlo noise, the more so the brighter and sharper the lobe; noise of the shared
/// Jacobian still enters it as the solve moves from `x`). The same paths as [`profile`].
pub fn profile_unbiased(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    r: f64,
    (samples, spp, key): (&[Sample], u32, u64),
) -> Result<ProfilePoint, TracerError> {
    profile_at(ctx, x, k, r, (samples, spp, key), 1.0, true)
}

/// [`profile`] with the specular strength at most `specular_max`: at 0 (and metallic 0 in `x`) the object's
/// best Lambert surface under the light of `x`.
pub fn profile_capped(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    r: f64,
    (samples, spp, key): (&[Sample], u32, u64),
    specular_max: f64,
) -> Result<ProfilePoint, TracerError> {
    profile_at(ctx, x, k, r, (samples, spp, key), specular_max, false)
}

/// [`profile_capped`], with the value rendered as two halves where `halves` ([`profile_unbiased`]).
fn profile_at(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    r: f64,
    (samples, spp, key): (&[Sample], u32, u64),
    specular_max: f64,
    halves: bool,
) -> Result<ProfilePoint, TracerError> {
    let mut xr = x.to_vec();
    xr[idx(k, ROUGHNESS)] = r;
    let params = ctx.params(&xr);
    let pixels: Vec<PixelRef> = samples.iter().map(|s| s.pixel).collect();
    let second = if halves {
        let [(spp_a, key_a), (spp_b, key_b)] = half_paths(spp, key);
        Some((ctx.render(&params, &pixels, spp_a, key_a)?, ctx.render(&params, &pixels, spp_b, key_b)?))
    } else {
        None
    };
    let values = match &second {
        Some((a, b)) => a.iter().zip(b).map(|(a, b)| 0.5 * (*a + *b)).collect(),
        None => ctx.render(&params, &pixels, spp, key)?,
    };
    // Independent random numbers for the Jacobian (the value and its slope must not share noise).
    let rows = jacobian::channel_rows(ctx, &params, &pixels, spp, key ^ key::PROFILE_JACOBIAN)?;
    let m = samples.len();
    // Unknowns: ρ_r, ρ_g, ρ_b, s. Rows (pixel j, channel c) at 3j + c.
    let v0 = [
        x[idx(k, BASE_COLOR)],
        x[idx(k, BASE_COLOR + 1)],
        x[idx(k, BASE_COLOR + 2)],
        x[idx(k, SPECULAR)].min(specular_max),
    ];
    let mut cols = vec![vec![0.0; 3 * m]; 4];
    let mut target = vec![0.0; 3 * m];
    for j in 0..m {
        for c in 0..3 {
            let row = rows[j][c][k];
            cols[c][3 * j + c] = row[0];
            cols[3][3 * j + c] = row[2];
            // I(v) ≈ I(v0) + J (v − v0)  ⇒  fit J v to t − I(v0) + J v0.
            target[3 * j + c] =
                f64::from(samples[j].target[c]) - f64::from(values[j][c]) + row[0] * v0[c] + row[2] * v0[3];
        }
    }
    let zeros = [0.0; 4];
    let mut v = v0.to_vec();
    let problem = Problem {
        cols: &cols,
        target: &target,
        second: None,
        weights: None,
        groups: None,
        penalty: &zeros,
        prox: &zeros,
        anchor: &zeros,
        lo: &zeros,
        hi: &[1.0, 1.0, 1.0, specular_max],
    };
    linear::solve(&problem, DataLoss::L1, &mut v, IRLS_ITERS);
    let loss_of = |v: &[f64]| {
        (0..3 * m).map(|i| (target[i] - (0..4).map(|u| cols[u][i] * v[u]).sum::<f64>()).abs()).sum::<f64>()
            / (3 * m.max(1)) as f64
    };
    let loss_half_specular = (v[3] >= SPECULAR_BOUND).then(|| {
        let mut half = v0.to_vec();
        half[3] = half[3].min(HALF_SPECULAR);
        linear::solve(&Problem { hi: &[1.0, 1.0, 1.0, HALF_SPECULAR], ..problem }, DataLoss::L1, &mut half, IRLS_ITERS);
        loss_of(&half)
    });
    let loss_lambert = (x[idx(k, METALLIC)] == 0.0 && specular_max > 0.0).then(|| {
        let mut lambert = v0.to_vec();
        lambert[3] = 0.0;
        linear::solve(&Problem { hi: &[1.0, 1.0, 1.0, 0.0], ..problem }, DataLoss::L1, &mut lambert, IRLS_ITERS);
        loss_of(&lambert)
    });
    Ok(ProfilePoint {
        roughness: r,
        metallic: x[idx(k, METALLIC)],
        loss: loss_of(&v),
        base_color: [v[0], v[1], v[2]],
        specular: v[3],
        loss_half_specular,
        loss_lambert,
        // Each half's residual is the mean's plus half their difference, with opposite signs.
        rms: second.map(|(a, b)| {
            let sum: f64 = (0..3 * m)
                .map(|i| {
                    let (j, c) = (i / 3, i % 3);
                    let fitted = target[i] - (0..4).map(|u| cols[u][i] * v[u]).sum::<f64>();
                    let half_gap = 0.5 * f64::from(a[j][c] - b[j][c]);
                    (fitted - half_gap) * (fitted + half_gap)
                })
                .sum();
            linear::root_mean_square(sum / (3 * m.max(1)) as f64)
        }),
    })
}

/// Where the metal family's profile solves start: the base colour each channel of which scales the pixels'
/// summed render at roughness `r` to their summed photo radiance, by [`RATIO_STEPS`] ratio steps from
/// [`RATIO_FROM`] (`x` holds the object at metallic 1; other objects as in `x`).
///
/// The profile's solve is one linearised step, and on a metal's pixels it moves only part of the way from its
/// linearisation point: on the corpus house, metal probes started at a dielectric's diffuse colour (0.17–0.54)
/// ended 0.1–0.4 below true metals' base colours of 0.6–0.9, at 64 paths as at 256, and started at 0.9 they
/// ended within 0.1 of the truth, while diffuse objects probed as metals ended near either start
/// (docs/optim/design-measurements.md, "Where the metal probes start"; why the step falls short is not settled,
/// and four times the paths do not shorten the gap). A ratio of sums does not depend on where it starts: a
/// metal's pixels are nearly proportional to its F0 = ρ, so one step lands near the base colour whose summed
/// render matches the photos', and the second corrects the part that does not scale (Schlick's grazing term).
pub fn ratio_start(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    r: f64,
    (samples, spp, key): (&[Sample], u32, u64),
) -> Result<[f64; 3], TracerError> {
    let mut xr = x.to_vec();
    xr[idx(k, ROUGHNESS)] = r;
    for c in 0..3 {
        xr[idx(k, BASE_COLOR + c)] = RATIO_FROM;
    }
    let pixels: Vec<PixelRef> = samples.iter().map(|s| s.pixel).collect();
    let photos: [f64; 3] = std::array::from_fn(|c| samples.iter().map(|t| f64::from(t.target[c])).sum());
    // Every step with the same random numbers: the steps iterate towards the fixed point of one estimate.
    for _ in 0..RATIO_STEPS {
        let values = ctx.render(&ctx.params(&xr), &pixels, spp, key ^ key::RATIO_START)?;
        for (c, &photo) in photos.iter().enumerate() {
            let render: f64 = values.iter().map(|v| f64::from(v[c])).sum();
            let rho = &mut xr[idx(k, BASE_COLOR + c)];
            // A channel the render leaves dark carries no information on its base colour: it stays.
            if render > 0.0 && photo.is_finite() {
                *rho = (*rho * photo / render).clamp(0.0, 1.0);
            }
        }
    }
    Ok([xr[idx(k, BASE_COLOR)], xr[idx(k, BASE_COLOR + 1)], xr[idx(k, BASE_COLOR + 2)]])
}

/// Ratio steps of [`ratio_start`]: the first scales the render to the photos, the second corrects the part of
/// the render that does not scale with the base colour (Schlick's grazing term, light from other surfaces).
pub const RATIO_STEPS: usize = 2;
/// Where [`ratio_start`] begins: the middle of the base colour's domain, so that no channel starts dark (a
/// ratio step cannot leave 0) and the first step's render is neither dim nor saturated.
pub const RATIO_FROM: f64 = 0.5;

/// Minimises the profile loss of object `k` over roughness: the coarse [`GRID`], then Brent's method ([`brent`])
/// between the neighbours of its best point. Returns the best point and every evaluation (for the record).
pub fn search(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    samples: &[Sample],
    spp: u32,
    key: u64,
) -> Result<(ProfilePoint, Vec<ProfilePoint>), TracerError> {
    search_up_to(ctx, x, k, samples, spp, key, 1.0)
}

/// [`search`] over the roughness range [0, `top`]: the grid points up to `top`, and a refinement bracket that
/// ends at `top` when the best grid point is the last of them.
pub fn search_up_to(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    samples: &[Sample],
    spp: u32,
    key: u64,
    top: f64,
) -> Result<(ProfilePoint, Vec<ProfilePoint>), TracerError> {
    search_profile(top, mean_target(samples), Rank::L1, |r| profile(ctx, x, k, r, samples, spp, key))
}

/// What a roughness search minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Rank {
    /// The profile's L1 ([`ProfilePoint::loss`]), from one render.
    L1,
    /// The profile's unbiased RMS error ([`ProfilePoint::rms`]), from two renders at half the paths each.
    Rms,
}

impl Rank {
    fn of(self, p: &ProfilePoint) -> f64 {
        match self {
            Rank::L1 => p.loss,
            Rank::Rms => p.rms_or_loss(),
        }
    }
}

/// [`search`] with every point evaluated by [`profile_unbiased`] and ranked by its unbiased RMS error
/// ([`ProfilePoint::rms`]) instead of the L1 of one render. The L1 is inflated by the render's Monte Carlo
/// noise, the more so the sharper and brighter the lobe, so where the pixels' noise hides the lobe's shape it
/// leans to the roughest one (docs/optim/design-measurements.md, "An emission's lobe alternative searched by
/// its unbiased error"). The same paths as [`search`].
pub fn search_unbiased(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    (samples, spp, key): (&[Sample], u32, u64),
) -> Result<(ProfilePoint, Vec<ProfilePoint>), TracerError> {
    search_profile(1.0, mean_target(samples), Rank::Rms, |r| profile_unbiased(ctx, x, k, r, (samples, spp, key)))
}

/// The search of [`search_up_to`] over the profile `profile_at(r)`, ranked by `rank`, whose values are relative
/// to `mean_target`.
fn search_profile(
    top: f64,
    mean_target: f64,
    rank: Rank,
    mut profile_at: impl FnMut(f64) -> Result<ProfilePoint, TracerError>,
) -> Result<(ProfilePoint, Vec<ProfilePoint>), TracerError> {
    let n_grid = GRID.iter().take_while(|&&r| r <= top).count().max(1);
    let mut evals = Vec::new();
    let mut eval = |r: f64, evals: &mut Vec<ProfilePoint>| -> Result<ProfilePoint, TracerError> {
        let p = profile_at(r)?;
        evals.push(p);
        Ok(p)
    };
    // The coarse points first; the others only where the profile is not flat over them.
    let mut grid: Vec<Option<ProfilePoint>> = vec![None; n_grid];
    for &i in COARSE.iter().filter(|&&i| i < n_grid) {
        grid[i] = Some(eval(GRID[i], &mut evals)?);
    }
    // A lobe that buys nothing over the Lambert surface at any coarse point is not refined either: the L1 of
    // one render spreads over the grid with the lobe's noise (the sharper the noisier), so a diffuse surface's
    // profile is rarely flat by that alone, but what the lobe buys changes as smoothly with its width as the
    // profile does.
    let flat = flat(&grid, mean_target, rank)
        || (rank == Rank::L1 && lobe_gain(grid.iter().flatten()).is_some_and(|g| g < FLAT_PROFILE * mean_target));
    if !flat {
        for i in 0..n_grid {
            if grid[i].is_none() {
                grid[i] = Some(eval(GRID[i], &mut evals)?);
            }
        }
    }
    let done: Vec<(usize, ProfilePoint)> = grid.iter().enumerate().filter_map(|(i, p)| p.map(|p| (i, p))).collect();
    let (best, best_point) = done
        .iter()
        .copied()
        .min_by(|a, b| rank.of(&a.1).total_cmp(&rank.of(&b.1)))
        .expect("the coarse grid is not empty");
    // More points only widen the profile's spread: a profile not flat over the coarse points is not flat over all.
    if flat {
        return Ok((best_point, evals));
    }
    let lo = if best == 0 { 0.0 } else { GRID[best - 1] };
    let hi = if best + 1 < n_grid { GRID[best + 1] } else { top.min(1.0) };
    // Brent's first parabola goes through the best grid point and its neighbours in the bracket. At an end of
    // the grid the bracket's other end is the domain's, not evaluated, and the first step is a golden section
    // (a parabola through the next grid points, all on one side of the minimum, lands far from it).
    let at = |p: &ProfilePoint| (p.roughness, rank.of(p));
    let mut near: Vec<(f64, f64)> =
        done.iter().filter(|(i, p)| *i != best && (lo..=hi).contains(&p.roughness)).map(|(_, p)| at(p)).collect();
    near.sort_by(|a, b| (a.0 - best_point.roughness).abs().total_cmp(&(b.0 - best_point.roughness).abs()));
    let x = at(&best_point);
    let w = near.first().copied().unwrap_or(x);
    let v = near.get(1).copied().unwrap_or(w);
    let open = (best == 0, best + 1 == n_grid);
    brent((lo, hi), open, (x, w, v), |r| eval(r, &mut evals).map(|p| rank.of(&p)))?;
    Ok((lowest(&evals, rank).unwrap_or(best_point), evals))
}

/// Brent's minimisation of `eval` over the bracket `[a, b]` (the minimiser of Brent, *Algorithms for
/// Minimization without Derivatives*, 1973, ch. 5, as in Numerical Recipes' `brent`), from evaluated points
/// given as (position, value): `x` the lowest, in the bracket or on its edge, and `w`, `v` the next lowest
/// (equal to `x` when there are none). An end of the bracket is `open` when it is an end of the domain that was
/// not evaluated: the minimum may lie on it, so steps may come as close to it as they like (a known end is
/// higher than `x`, and steps keep 2 · [`REFINE_TOL`] from it). At most [`REFINE_EVALS`] evaluations, fewer
/// once the minimum is bracketed within ±2 · [`REFINE_TOL`]; the caller keeps every evaluation and takes the
/// best.
fn brent(
    (mut a, mut b): (f64, f64),
    (mut open_a, mut open_b): (bool, bool),
    (mut x, mut w, mut v): ((f64, f64), (f64, f64), (f64, f64)),
    mut eval: impl FnMut(f64) -> Result<f64, TracerError>,
) -> Result<(), TracerError> {
    const CGOLD: f64 = 0.381_966_011_250_105_1;
    let tol2 = 2.0 * REFINE_TOL;
    // The step before last: a parabola is taken only if it moves less than half of it, which is what makes
    // the method converge where parabolas do not. Starting at the bracket's width lets the first parabola,
    // through points already evaluated, be taken.
    let mut e = b - a;
    let mut d = 0.0f64;
    for _ in 0..REFINE_EVALS {
        let xm = 0.5 * (a + b);
        if (x.0 - xm).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        // The vertex of the parabola through x, w and v, as the step p / q from x.
        let parabola = (e.abs() > REFINE_TOL)
            .then(|| {
                let r = (x.0 - w.0) * (x.1 - v.1);
                let q = (x.0 - v.0) * (x.1 - w.1);
                let p = (x.0 - v.0) * q - (x.0 - w.0) * r;
                let q = 2.0 * (q - r);
                let (p, q) = if q > 0.0 { (-p, q) } else { (p, -q) };
                // Taken when it moves less than half the step before last and lands inside the bracket (a
                // degenerate parabola, q = 0, never is).
                (p.abs() < (0.5 * q * e).abs() && p > q * (a - x.0) && p < q * (b - x.0)).then(|| p / q)
            })
            .flatten();
        d = match parabola {
            Some(step) => {
                e = d;
                let u = x.0 + step;
                // Not within the tolerance of a known end of the bracket, which is higher.
                if (u - a < tol2 && !open_a) || (b - u < tol2 && !open_b) {
                    REFINE_TOL.copysign(xm - x.0)
                } else {
                    step
                }
            }
            None => {
                // A golden section of the larger side.
                e = if x.0 >= xm { a - x.0 } else { b - x.0 };
                CGOLD * e
            }
        };
        let u = if d.abs() >= REFINE_TOL { x.0 + d } else { x.0 + REFINE_TOL.copysign(d) };
        let fu = eval(u)?;
        if fu <= x.1 {
            if u >= x.0 {
                (a, open_a) = (x.0, false);
            } else {
                (b, open_b) = (x.0, false);
            }
            v = w;
            w = x;
            x = (u, fu);
        } else {
            if u < x.0 {
                (a, open_a) = (u, false);
            } else {
                (b, open_b) = (u, false);
            }
            if fu <= w.1 || w.0 == x.0 {
                v = w;
                w = (u, fu);
            } else if fu <= v.1 || v.0 == x.0 || v.0 == w.0 {
                v = (u, fu);
            }
        }
    }
    Ok(())
}

/// Mean per-channel |target| of the object's pixels, which the profile's thresholds are relative to.
pub fn mean_target(samples: &[Sample]) -> f64 {
    samples.iter().map(|t| f64::from(t.target.abs().element_sum()) / 3.0).sum::<f64>() / samples.len().max(1) as f64
}

/// Whether the profile, ranked by `rank`, varies over the evaluated grid points by less than [`FLAT_PROFILE`]
/// of `mean_target`.
fn flat(grid: &[Option<ProfilePoint>], mean_target: f64, rank: Rank) -> bool {
    let losses = || grid.iter().flatten().map(|p| rank.of(p));
    let best = losses().fold(f64::INFINITY, f64::min);
    let worst = losses().fold(0.0, f64::max);
    worst - best < FLAT_PROFILE * mean_target
}

/// The most that a specular lobe lowers the profile loss below the object's best Lambert surface's at any of the
/// evaluations `evals` ([`ProfilePoint::loss_lambert`]); `None` when one of them has no Lambert loss (a metal's,
/// or a profile capped at 0), for which the question does not arise.
pub fn lobe_gain<'a>(evals: impl IntoIterator<Item = &'a ProfilePoint>) -> Option<f64> {
    evals.into_iter().try_fold(0.0f64, |most, p| p.loss_lambert.map(|l| most.max(l - p.loss)))
}

/// Whether a specular lobe buys the object at least `needs` (in the profile loss's units, per channel): at some
/// evaluation of its search (`evals`) it lowers the profile loss below the best Lambert surface's by that much, or
/// the search has points without a Lambert loss (a metal family was searched).
#[must_use]
pub fn lobe_pays(evals: &[ProfilePoint], needs: f64) -> bool {
    lobe_gain(evals).is_none_or(|g| g >= needs)
}

/// The evaluation that `rank` puts lowest.
fn lowest<'a>(evals: impl IntoIterator<Item = &'a ProfilePoint>, rank: Rank) -> Option<ProfilePoint> {
    evals.into_iter().copied().min_by(|p, q| rank.of(p).total_cmp(&rank.of(q)))
}

/// Golden-section minimisation of `eval` inside `[lo, hi]` for [`GOLDEN_STEPS`] steps; the caller keeps every
/// evaluation and takes the best.
fn golden(
    mut lo: f64,
    mut hi: f64,
    mut eval: impl FnMut(f64) -> Result<ProfilePoint, TracerError>,
) -> Result<(), TracerError> {
    const INV_PHI: f64 = 0.618_033_988_749_894_9;
    let mut a = hi - INV_PHI * (hi - lo);
    let mut b = lo + INV_PHI * (hi - lo);
    let mut pa = eval(a)?;
    let mut pb = eval(b)?;
    for _ in 0..GOLDEN_STEPS {
        if pa.loss <= pb.loss {
            hi = b;
            b = a;
            pb = pa;
            a = hi - INV_PHI * (hi - lo);
            pa = eval(a)?;
        } else {
            lo = a;
            a = b;
            pa = pb;
            b = lo + INV_PHI * (hi - lo);
            pb = eval(b)?;
        }
    }
    Ok(())
}

/// The best lobe of object k over roughness and metallic: the dielectric lobe ([`search`] at metallic 0), and
/// only when its specular strength is at its bound and the bound binds — the photos ask for a stronger
/// reflection than a dielectric's F0 ≤ 0.08 gives, and halving it ([`ProfilePoint::loss_half_specular`])
/// raises the profile loss by at least [`FLAT_PROFILE`] of the pixels' mean — the metal family too:
/// [`search`] at metallic 1, then a golden-section search on metallic in [0, 1] at the better family's
/// roughness, and, when the best metallic lies strictly between the two, [`search`] once more at it. A
/// principled BSDF between the two families (Modern Hall's tiled floor at metallic 0.75) is fitted by neither
/// end: its dielectric fit put the tiles' colour 0.1 too dark (docs/optim/design-measurements.md, "Metals
/// between dielectric and conductor"). A blend is chosen only where it pays ([`pure_unless_blend_pays`]). All
/// evaluations share `key` (common random numbers), so the families are compared on the same paths.
pub fn search_lobe(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    samples: &[Sample],
    spp: u32,
    key: u64,
) -> Result<(ProfilePoint, Vec<ProfilePoint>), TracerError> {
    let at = |m: f64| {
        let mut xm = x.to_vec();
        xm[idx(k, METALLIC)] = m;
        xm
    };
    let (dielectric, mut evals) = search(ctx, &at(0.0), k, samples, spp, key)?;
    // The dielectric falls short only if its bound binds: halving its reflection must cost the profile what
    // roughness needs to matter ([`FLAT_PROFILE`]). Where a rough lobe and the base colour explain the pixels
    // alike, the L1 solve can end on the bound of that flat valley (a diffuse wall of the corpus house), and
    // the bound says nothing about the photos.
    let binds =
        dielectric.loss_half_specular.is_some_and(|half| half - dielectric.loss >= FLAT_PROFILE * mean_target(samples));
    if !binds {
        return Ok((dielectric, evals));
    }
    let (metal, metal_evals) = search(ctx, &at(1.0), k, samples, spp, key)?;
    evals.extend(metal_evals);
    let r = if metal.loss < dielectric.loss { metal.roughness } else { dielectric.roughness };
    golden(0.0, 1.0, |m| {
        let p = profile(ctx, &at(m), k, r, samples, spp, key)?;
        evals.push(p);
        Ok(p)
    })?;
    let blend = lowest(&evals, Rank::L1).unwrap_or(dielectric);
    if blend.metallic > 0.0 && blend.metallic < 1.0 {
        // A blend of the two families: its roughness searched again at its metallic (one round of coordinate
        // descent on the profile loss over (roughness, metallic)).
        let (_, blend_evals) = search(ctx, &at(blend.metallic), k, samples, spp, key)?;
        evals.extend(blend_evals);
    }
    Ok((pure_unless_blend_pays(&evals, mean_target(samples)).unwrap_or(dielectric), evals))
}

/// The chosen lobe of a search over both families: the lowest evaluation of a pure family (metallic 0 or 1),
/// unless a blend of the two lowers the profile loss below it by at least [`FLAT_PROFILE`] of the pixels'
/// mean `mean_target`. A blend is a parameter more, kept only where the photos call for it (Modern Hall's
/// tiled floor). Where a metal's profile is flat towards metallic 1 the golden section ends at an interior
/// point (0.76–0.98 on the corpus house's metals) by the noise of the profile alone; there F0 = m·ρ, so the
/// base colour comes out 1/m too bright (docs/optim/design-measurements.md, "Blends only where they pay").
fn pure_unless_blend_pays(evals: &[ProfilePoint], mean_target: f64) -> Option<ProfilePoint> {
    let is_pure = |p: &&ProfilePoint| p.metallic == 0.0 || p.metallic == 1.0;
    let pure = lowest(evals.iter().filter(is_pure), Rank::L1);
    let blend = lowest(evals.iter().filter(|p| !is_pure(p)), Rank::L1);
    match (pure, blend) {
        (Some(p), Some(b)) if b.loss <= p.loss - FLAT_PROFILE * mean_target => Some(b),
        (Some(p), _) => Some(p),
        (None, b) => b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(metallic: f64, loss: f64) -> ProfilePoint {
        ProfilePoint {
            roughness: 0.3,
            metallic,
            loss,
            base_color: [0.5; 3],
            specular: 0.5,
            loss_half_specular: None,
            loss_lambert: None,
            rms: None,
        }
    }

    /// The search on smooth profiles with their minimum anywhere in the range, over [0, 1] and up to the metal
    /// search's top: a bowl (quadratic), one in log roughness, a cusp (|r − r*|^1.5) and a GGX-like lobe width
    /// profile (a bell in α = r², wider for rough minima). It ends within 2 · [`REFINE_TOL`] of the minimum (the
    /// golden sections it replaces ended within 0.004 after 8 evaluations; the fit's roughness tolerance is
    /// 0.05), with at most the grid and [`REFINE_EVALS`] evaluations, fewer than 4.5 after the grid on average
    /// (parabolas, not golden sections, do most of the work), and with 4 on a flat profile.
    #[test]
    fn the_search_finds_a_smooth_profiles_minimum_within_its_tolerance() {
        type Shape = fn(f64, f64) -> f64;
        let shapes: [(&str, Shape); 4] = [
            ("bowl", |r, m| (r - m).powi(2)),
            ("log", |r, m| (r.max(1e-3) / m).ln().powi(2)),
            ("cusp", |r, m| (r - m).abs().powf(1.5)),
            ("lobe width", |r, m| 1.0 - (-((r * r - m * m) / (0.1 + m * m)).powi(2)).exp()),
        ];
        let point_at = |r: f64, loss: f64| ProfilePoint { roughness: r, loss, ..point(0.0, loss) };
        let (mut refined, mut searches) = (0, 0);
        for (name, shape) in shapes {
            for top in [1.0, crate::fit::family::METAL_ROUGHEST] {
                for i in 1..100 {
                    let m = f64::from(i) / 100.0;
                    if m > top {
                        continue;
                    }
                    // Losses of 0.1 and more over a mean target of 1: never flat.
                    let (best, evals) = search_profile(top, 1.0, Rank::L1, |r| Ok(point_at(r, 0.1 + shape(r, m))))
                        .expect("no render fails");
                    assert!(
                        (best.roughness - m).abs() <= 2.0 * REFINE_TOL,
                        "{name}, top {top}: {} for {m}",
                        best.roughness
                    );
                    let grid = GRID.iter().filter(|&&r| r <= top).count();
                    assert!(evals.len() <= grid + REFINE_EVALS, "{name}: {} evaluations", evals.len());
                    refined += evals.len() - grid;
                    searches += 1;
                    assert!(evals.iter().all(|p| (0.0..=top).contains(&p.roughness)), "{name}: outside [0, {top}]");
                }
            }
        }
        let mean = refined as f64 / f64::from(searches);
        assert!(mean < 4.5, "{mean} refinement evaluations per search");
        let (_, evals) =
            search_profile(1.0, 1.0, Rank::L1, |r| Ok(point_at(r, 0.1 + 1e-4 * r))).expect("no render fails");
        assert_eq!(evals.len(), COARSE.len(), "a flat profile is evaluated at the coarse points only");
    }

    /// A dielectric's profile that spreads over the grid by far more than [`FLAT_PROFILE`] (the L1 of one render
    /// rises as the lobe sharpens) while its lobe buys less than that over the Lambert surface at every point: it
    /// is evaluated at the coarse points only, and [`lobe_pays`] says no at that margin. Where the lobe buys the
    /// margin at one point, or a point has no Lambert loss (a metal's), the search refines and the lobe pays.
    #[test]
    fn a_lobe_that_buys_nothing_over_the_lambert_surface_is_not_refined() {
        let margin = FLAT_PROFILE * 1.0;
        let noisy = |r: f64, gain: f64| {
            let loss = 0.1 + 0.05 * (1.0 - r);
            ProfilePoint { roughness: r, loss, loss_lambert: Some(loss + gain), ..point(0.0, loss) }
        };
        let (_, evals) = search_profile(1.0, 1.0, Rank::L1, |r| Ok(noisy(r, 0.5 * margin))).expect("no render fails");
        assert_eq!(evals.len(), COARSE.len(), "{} evaluations", evals.len());
        let gain = lobe_gain(&evals).expect("dielectric points");
        assert!((gain - 0.5 * margin).abs() < 1e-12, "gain {gain}");
        assert!(!lobe_pays(&evals, margin));
        assert!(lobe_pays(&evals, 0.4 * margin), "the gain is judged against the margin it is given");
        // The lobe buys the margin at r = 0.45 alone: refined, and it pays.
        let gain_at = |r: f64| if (r - GRID[4]).abs() < 1e-9 { 2.0 * margin } else { 0.0 };
        let (_, evals) = search_profile(1.0, 1.0, Rank::L1, |r| Ok(noisy(r, gain_at(r)))).expect("no render fails");
        assert!(evals.len() > COARSE.len());
        assert!(lobe_pays(&evals, margin));
        // A metal's points carry no Lambert loss: the question does not arise.
        let metal = |r: f64| ProfilePoint { loss_lambert: None, metallic: 1.0, ..noisy(r, 0.0) };
        let (_, evals) = search_profile(1.0, 1.0, Rank::L1, |r| Ok(metal(r))).expect("no render fails");
        assert!(evals.len() > COARSE.len());
        assert_eq!(lobe_gain(&evals), None);
        assert!(lobe_pays(&evals, margin));
    }

    /// A profile whose L1 carries the render's noise, which grows as the lobe sharpens (here by 0.6 · (1 − r)
    /// over a bowl at 0.2), while its unbiased RMS error is the bowl alone: ranked by the L1 the search ends
    /// rough, ranked by the RMS error at the bowl's minimum.
    #[test]
    fn a_search_ranked_by_the_unbiased_error_does_not_lean_to_rough_lobes() {
        let bowl = |r: f64| 0.1 + (r - 0.2).powi(2);
        let noisy = |r: f64| ProfilePoint { roughness: r, rms: Some(bowl(r)), ..point(1.0, bowl(r) + 0.6 * (1.0 - r)) };
        let (by_l1, _) = search_profile(1.0, 1.0, Rank::L1, |r| Ok(noisy(r))).expect("no render fails");
        let (by_rms, _) = search_profile(1.0, 1.0, Rank::Rms, |r| Ok(noisy(r))).expect("no render fails");
        assert!(by_l1.roughness > 0.4, "the L1 ends at {}", by_l1.roughness);
        assert!((by_rms.roughness - 0.2).abs() <= 2.0 * REFINE_TOL, "the RMS error ends at {}", by_rms.roughness);
        // The point keeps its L1 loss; only the ranking differs.
        assert_eq!(by_rms.loss, bowl(by_rms.roughness) + 0.6 * (1.0 - by_rms.roughness));
    }

    #[test]
    fn a_blend_is_chosen_only_where_it_lowers_the_profile_by_the_flat_margin() {
        let mean = 0.2;
        let margin = FLAT_PROFILE * mean;
        let pure = [point(0.0, 0.050), point(1.0, 0.040), point(1.0, 0.042)];
        // A blend lower by less than the margin: the metal stays.
        let evals: Vec<_> = pure.iter().copied().chain([point(0.889, 0.040 - 0.5 * margin)]).collect();
        assert_eq!(pure_unless_blend_pays(&evals, mean), Some(point(1.0, 0.040)));
        // Lower by the margin or more: the blend is kept.
        let evals: Vec<_> = pure.iter().copied().chain([point(0.618, 0.040 - 1.5 * margin)]).collect();
        assert_eq!(pure_unless_blend_pays(&evals, mean), Some(point(0.618, 0.040 - 1.5 * margin)));
        // A blend worse than a pure family is never chosen; nothing to choose from gives nothing.
        let evals: Vec<_> = pure.iter().copied().chain([point(0.5, 0.045)]).collect();
        assert_eq!(pure_unless_blend_pays(&evals, mean), Some(point(1.0, 0.040)));
        assert_eq!(pure_unless_blend_pays(&[], mean), None);
        assert_eq!(pure_unless_blend_pays(&[point(0.3, 0.1)], mean), Some(point(0.3, 0.1)));
    }
}
