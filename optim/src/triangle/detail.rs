//! Sub-triangle albedo detail: a grid of texels per triangle, valued by dividing the photos by the final
//! model's shading once the per-triangle fit has settled the light and every triangle's mean albedo.
//!
//! # Why
//! A triangle carries one base colour, and the split test ([`super::split`]) refines a triangle only where its
//! four would-be children differ. A texture whose features are smaller than those children (stripes, tiles,
//! wood grain, wallpaper: centimetres, on triangles of decimetres to metres) has the same mean in every
//! child, so it is never split and stays averaged. Measured on the corpus's textured room
//! (`docs/realistic/README.md`, "Sub-triangle detail"): the per-triangle stage left the striped and
//! checkered walls at their per-object mean (held-out albedo PSNR 14.9 dB, the same as the per-object truth's
//! 15.0 dB), while one texel per best-view pixel recovers them.
//!
//! # Method
//! A Lambertian surface sends ρ(x)·S(x) towards every camera, where the shading S (irradiance over π)
//! varies smoothly across a triangle — it integrates the light over a hemisphere — and ρ carries the texture.
//! The per-triangle fit has found the light and each triangle's mean ρ_t, so S is known up to Monte Carlo
//! noise and ρ(x) = photo(x) / S(x).
//! 1. **Resolution**: triangle t gets n_t × n_t cells over its barycentric square (u, v) ∈ [0, 1)², of which
//!    the n_t(n_t + 1)/2 with i + j ≤ n_t − 1 meet the triangle; n_t = ⌈√(2·density·P_t)⌉ with P_t its pixel
//!    centres in its best view, so that at density 1 a texel is about one pixel of the best view. When the
//!    texels exceed `max_texels` the density shrinks (×0.8 per try) until they fit. n_t < 2: no detail.
//! 2. **Pixels**: the valid pixels whose centre hits a detailed triangle, at most [`SAMPLES_PER_TEXEL`] per
//!    texel (a uniform sample, [`super::pixels::collect_budgets`]).
//! 3. **Shading**: the final model rendered at those pixels (`spp` paths, key [`key::TRIANGLE_DETAIL`]),
//!    divided by ρ_t, and smoothed per triangle and channel by a least-squares quadratic in (u, v) (linear,
//!    then constant, when the pixels do not span the quadratic): the fit removes the render's Monte Carlo
//!    noise, which would otherwise become texture.
//! 4. **Texels**: each pixel gives an albedo sample a_s = T_s / Ŝ(u_s, v_s) from its photo value T_s,
//!    capped at an albedo of 1 plus [`CLIP_SIGMAS`] standard deviations of the samples' noise (a robust
//!    scale from pairs of samples in the same texel): Monte Carlo renders, the corpus's photos, carry
//!    fireflies, single pixels many times too bright, which a texel of one to three pixels cannot average
//!    away, while no albedo exceeds 1. The texels are then shrunk towards the triangle:
//!    ρ_k = ρ_t + m_k / (m_k + κ) · (ā_k − ā), with ā_k the mean of texel k's m_k samples and ā the
//!    triangle's, and κ = σ² / τ² the ratio of the samples' within-texel variance σ² to the variance τ² of the
//!    texels' true albedos, both estimated from the samples grouped by texel (the one-way random-effects
//!    ANOVA, [`super::split::Anova::between_variance`]). This is the empirical-Bayes
//!    estimate, which minimises the expected squared error for normally spread texel albedos: a texel keeps
//!    its own mean where the texture's spread dwarfs a texel's noise, and leans towards ρ_t where it does
//!    not. A texel no pixel sees, and every texel of a channel whose texels vary no more than their noise
//!    predicts (τ² = 0) or that has no texel of two pixels (no σ²), takes ρ_t. Clamped to [0, 1]. A fixed
//!    weight of one pseudo-pixel at ρ_t instead painted the noise of the 160×128 house's photos into its
//!    plain walls (`docs/realistic/README.md`, "Texels shrunk by their noise").
//!
//! 5. **Only where the photos call for it**: per triangle, a one-way ANOVA of the pixels' residuals
//!    photo − render (T_s − R_s, the render unsmoothed) grouped by texel (per channel, ×3 Bonferroni), Holm
//!    over every triangle tested at [`DETAIL_SIGNIFICANCE`]; a triangle whose texels differ only by noise
//!    keeps its one colour (as the split test, [`super::split`], which groups the same residuals by would-be
//!    child). The raw render cancels every shading structure the model explains, sharp or not: a shadow edge,
//!    which the quadratic Ŝ of step 3 cannot follow, made a test of T_s − ρ_t Ŝ read shading as texture (on
//!    the uniform demo room 121 triangles got 16 347 texels; 1 triangle 105 with this test). Measured in
//!    `docs/realistic/README.md`, "Sub-triangle detail".
//!
//! Only triangles of objects whose model is diffuse and emits nothing get detail: a specular highlight
//! depends on the view and would be baked into the albedo, and an emitter's radiance is not ρ·S. The caller
//! also leaves out the objects the photos do not constrain (the export's `detail_eligible`), which keep
//! their value through the per-triangle stage ([`super::fitted_triangles`]).

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use tracer::PixelRef;

use super::pixels::{self, TriSample};
use super::significance::holm;
use super::split::anova;
use super::{TriangleError, TriangleState};
use crate::fit::linear::{median, solve_spd};
use crate::streams::key;

/// Pixels kept per texel: a texel's ratio estimate averages the photos' noise over up to this many pixels;
/// more costs renders without sharpening the texel (its footprint is one best-view pixel).
pub const SAMPLES_PER_TEXEL: usize = 64;

/// Largest cells per triangle edge: 254 leaves a 1-texel border inside a 256-texel atlas cell.
pub const MAX_CELLS: u32 = 254;

/// Below this base colour a channel's shading (render / ρ) is not measurable (a channel ρ = 0 renders 0 in
/// every pixel); the channel keeps the triangle's value.
const MIN_BASE: f32 = 1e-3;

/// Pixels a triangle needs for the quadratic shading fit (6 coefficients: 4 pixels per coefficient keep the
/// fit's own noise well below the render's) and for the linear one (3 coefficients).
const MIN_QUADRATIC: usize = 24;
const MIN_LINEAR: usize = 12;

/// The fitted shading is kept at or above this fraction of the triangle's mean shading: a quadratic
/// extrapolated into a corner no pixel saw can reach 0 or below, and a division by it would blow the texel
/// up; real shading on one triangle (the light integrated over a hemisphere) does not fall that far.
const MIN_SHADING_FRACTION: f64 = 0.05;

/// σ of a normal distribution per median absolute deviation: 1 / Φ⁻¹(3/4).
const MAD_TO_SIGMA: f64 = 1.482_602_218_505_602;

/// A pixel's albedo sample is capped at 1 (no surface reflects more than it receives) plus this many standard
/// deviations of the samples' noise (step 4): noise lifts a sample of a white surface past the cap in 0.13 %
/// of pixels, so the cap barely biases a texel, while a firefly (tens of σ) is cut to it. Any texture, however
/// bright, sparse or noise-free, lies below it, where a cap relative to the triangle's median (median + 3
/// robust σ) cut a noise-free stripe covering a quarter of a triangle down to the median.
const CLIP_SIGMAS: f64 = 3.0;

/// Family-wise level of the per-triangle test that keeps a grid: the probability that any triangle whose
/// texels differ only by noise gets one is at most this (the split test's level, `triangle.split_significance`
/// default).
pub const DETAIL_SIGNIFICANCE: f64 = 0.01;

/// The settings of [`estimate`] (the `[export]` table's `detail_*` keys).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetailSettings {
    /// Budget: texels over all triangles.
    pub max_texels: u64,
    /// Texels per best-view pixel (before the budget).
    pub density: f64,
    /// Paths per pixel of the shading render.
    pub spp: u32,
    pub seed: u64,
}

/// One triangle's texels: `n × n` cells over barycentric (u, v), cell (i, j) = [i/n, (i+1)/n) × [j/n,
/// (j+1)/n) at index `i·n + j` (cells with i + j > n − 1 lie outside the triangle and hold their nearest
/// inside neighbour's value, so that any filter reads sensible values).
#[derive(Debug, Clone, PartialEq)]
pub struct TexelGrid {
    pub n: u32,
    pub texels: Vec<Vec3>,
}

impl TexelGrid {
    /// The cell holding barycentrics `bary` = (u, v), clamped into the grid.
    #[must_use]
    pub fn cell(&self, bary: Vec2) -> (usize, usize) {
        let n = self.n as usize;
        // `as usize` saturates (NaN and negatives to 0); the min keeps u = 1 in the last cell.
        let i = ((bary.x * self.n as f32) as usize).min(n - 1);
        let j = ((bary.y * self.n as f32) as usize).min(n - 1);
        (i, j)
    }

    /// The texel value at barycentrics `bary`.
    #[must_use]
    pub fn at(&self, bary: Vec2) -> Vec3 {
        let (i, j) = self.cell(bary);
        self.texels[i * self.n as usize + j]
    }
}

/// Barycentrics `b` = (u, v) clamped to [0, 1] each, then pulled back across the diagonal (u + v ≤ 1) by
/// moving both by half the excess: the point of the triangle nearest to `b` along the diagonal's normal.
#[must_use]
pub fn into_triangle(b: Vec2) -> Vec2 {
    let (u, v) = (b.x.clamp(0.0, 1.0), b.y.clamp(0.0, 1.0));
    // u, v ≤ 1 make the excess at most min(u, v): both stay ≥ 0.
    let excess = (u + v - 1.0).max(0.0);
    Vec2::new(u - excess / 2.0, v - excess / 2.0)
}

/// What [`estimate`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetailReport {
    /// Triangles given a grid.
    pub triangles: usize,
    /// Cells meeting those triangles (n(n+1)/2 each).
    pub texels: u64,
    /// Pixels rendered and divided.
    pub pixels: usize,
    /// The density used (the setting, or less to fit the budget).
    pub density: f64,
}

/// Per triangle of `state`, its texel grid (`None`: no detail), for the objects with `eligible[object]`
/// (diffuse, no emission; the caller knows the models). See the module docs.
#[allow(clippy::too_many_arguments)]
pub fn estimate(
    scene: &tracer::Scene,
    state: &TriangleState,
    cameras: &[tracer::Camera],
    images: &[ingest::photo::LinearImage],
    tracer_settings: &tracer::TracerSettings,
    eligible: &[bool],
    settings: &DetailSettings,
    progress: &dyn crate::Progress,
) -> Result<(Vec<Option<TexelGrid>>, DetailReport), TriangleError> {
    if settings.spp == 0 {
        return Err(TriangleError::Setting { key: "detail_spp", message: "must be ≥ 1".into() });
    }
    if !(settings.density.is_finite() && settings.density > 0.0) {
        return Err(TriangleError::Setting { key: "detail_density", message: "must be finite and > 0".into() });
    }
    let nt = state.triangles.len();
    let free: Vec<bool> = (0..nt)
        .map(|t| {
            let o = state.face_object[t] as usize;
            eligible.get(o).copied().unwrap_or(false) && state.emission.get(o).is_none_or(|e| e.max_element() <= 0.0)
        })
        .collect();
    progress.set_message("counting each triangle's pixels");
    let counts = pixels::collect_budgets(scene, cameras, images, &vec![0; nt], settings.seed);
    let cells_at = |density: f64| -> Vec<u32> {
        (0..nt)
            .map(|t| {
                let n = (2.0 * density * f64::from(counts.best_view[t])).sqrt().ceil();
                if free[t] && n >= 2.0 { (n as u32).min(MAX_CELLS) } else { 0 }
            })
            .collect()
    };
    let texels_of = |n: &[u32]| n.iter().map(|&k| u64::from(k) * u64::from(k + 1) / 2).sum::<u64>();
    let mut density = settings.density;
    let mut n = cells_at(density);
    while texels_of(&n) > settings.max_texels && n.iter().any(|&k| k > 0) {
        density *= 0.8;
        n = cells_at(density);
    }
    let budgets: Vec<usize> = n.iter().map(|&k| SAMPLES_PER_TEXEL * (k as usize * (k as usize + 1) / 2)).collect();
    progress.set_message("collecting the pixels of the detailed triangles");
    let pix = pixels::collect_budgets(scene, cameras, images, &budgets, settings.seed);
    let refs: Vec<PixelRef> = pix.samples.iter().map(|s| s.pixel).collect();
    let renders = if refs.is_empty() {
        Vec::new()
    } else {
        crate::blocks::render_blocks(
            &tracer::Renderer::new(scene, &state.params(), tracer_settings)?,
            cameras,
            &refs,
            settings.spp,
            settings.seed,
            key::TRIANGLE_DETAIL,
            progress,
            &format!("rendering the shading at {} pixels, block", refs.len()),
        )?
        .0
    };
    // Samples grouped by triangle (counting sort; each group keeps the samples' order).
    let mut start = vec![0usize; nt + 1];
    for s in &pix.samples {
        start[s.tri as usize + 1] += 1;
    }
    for t in 0..nt {
        start[t + 1] += start[t];
    }
    let mut order = vec![0usize; pix.samples.len()];
    let mut fill = start.clone();
    for (k, s) in pix.samples.iter().enumerate() {
        order[fill[s.tri as usize]] = k;
        fill[s.tri as usize] += 1;
    }
    progress.phase("dividing the photos by the shading", 1, 0);
    let tested: Vec<Option<(TexelGrid, f64)>> = (0..nt)
        .into_par_iter()
        .map(|t| {
            let idx = &order[start[t]..start[t + 1]];
            (n[t] >= 2 && !idx.is_empty()).then(|| {
                let samples: Vec<(&TriSample, Vec3)> = idx.iter().map(|&k| (&pix.samples[k], renders[k])).collect();
                triangle_grid(n[t], state.materials[t].base_color, &samples)
            })
        })
        .collect();
    // Holm over every triangle tested: only texel structure beyond noise becomes detail.
    let p: Vec<f64> = tested.iter().flatten().map(|(_, p)| *p).collect();
    let mut significant = holm(&p, DETAIL_SIGNIFICANCE).into_iter();
    let grids: Vec<Option<TexelGrid>> =
        tested.into_iter().map(|g| g.and_then(|(g, _)| significant.next().unwrap_or(false).then_some(g))).collect();
    let report = DetailReport {
        triangles: grids.iter().flatten().count(),
        texels: grids.iter().flatten().map(|g| u64::from(g.n) * u64::from(g.n + 1) / 2).sum(),
        pixels: refs.len(),
        density,
    };
    tracing::info!(triangles = report.triangles, texels = report.texels, pixels = report.pixels, density, "detail");
    Ok((grids, report))
}

/// The quadratic basis in barycentrics.
fn basis(b: Vec2) -> [f64; 6] {
    let (u, v) = (f64::from(b.x), f64::from(b.y));
    [1.0, u, v, u * u, u * v, v * v]
}

/// Least-squares coefficients of `values` over `points` in the first `k` basis functions (6, 3 or 1);
/// `None` when the normal equations are singular.
fn fit_shading(points: &[Vec2], values: &[f64], k: usize) -> Option<Vec<f64>> {
    let mut a = vec![0.0; k * k];
    let mut b = vec![0.0; k];
    for (p, &y) in points.iter().zip(values) {
        let f = basis(*p);
        for i in 0..k {
            b[i] += f[i] * y;
            for j in 0..k {
                a[i * k + j] += f[i] * f[j];
            }
        }
    }
    solve_spd(&a, &b)
}

/// One triangle's grid from its pixels (sample, render at the final model): steps 3 and 4 of the module docs.
fn triangle_grid(n: u32, base: Vec3, samples: &[(&TriSample, Vec3)]) -> (TexelGrid, f64) {
    let nn = n as usize;
    let points: Vec<Vec2> = samples.iter().map(|(s, _)| s.bary).collect();
    let mut grid = TexelGrid { n, texels: vec![base; nn * nn] };
    let mut p_min = 1.0f64;
    let mut varies = false;
    for c in 0..3 {
        if base[c] < MIN_BASE {
            continue;
        }
        let shading: Vec<f64> = samples.iter().map(|(_, r)| f64::from(r[c]) / f64::from(base[c])).collect();
        let mean = shading.iter().sum::<f64>() / shading.len() as f64;
        if !(mean.is_finite() && mean > 0.0) {
            continue;
        }
        let coef = [(6, MIN_QUADRATIC), (3, MIN_LINEAR)]
            .iter()
            .filter(|&&(_, need)| samples.len() >= need)
            .find_map(|&(k, _)| fit_shading(&points, &shading, k))
            .unwrap_or_else(|| vec![mean]);
        let floor = MIN_SHADING_FRACTION * mean;
        let eval = |b: Vec2| {
            let f = basis(b);
            coef.iter().zip(f).map(|(a, x)| a * x).sum::<f64>().max(floor)
        };
        // Per texel, the pixels' albedo samples T_s / Ŝ(u_s, v_s) (step 4), and step 5's residuals photo −
        // render, the render unsmoothed: it carries every structure the model explains (shadow edges, light
        // pools, the shading's falloff), so that structure cancels whatever its shape, where the smoothed Ŝ
        // would leave its sharp parts; what remains differs between texels only through albedo structure
        // within the triangle, or noise (the photo's and the render's, both in the within-texel variance).
        let mut albedo: Vec<Vec<f64>> = vec![Vec::new(); nn * nn];
        let mut residuals: Vec<Vec<f64>> = vec![Vec::new(); nn * nn];
        for (s, r) in samples {
            let (i, j) = grid.cell(s.bary);
            albedo[i * nn + j].push(f64::from(s.target[c]) / eval(s.bary));
            residuals[i * nn + j].push(f64::from(s.target[c]) - f64::from(r[c]));
        }
        if let Some(a) = anova(&residuals) {
            p_min = p_min.min(a.p_value());
        }
        // Step 4's cap on fireflies: an albedo of 1 plus CLIP_SIGMAS of the samples' noise, whose scale comes
        // from pairs of samples in the same texel (their difference is noise alone, with variance 2σ²).
        let mut pairs: Vec<f64> = albedo.iter().flat_map(|v| v.chunks_exact(2).map(|p| (p[0] - p[1]).abs())).collect();
        if pairs.is_empty() {
            continue;
        }
        let sigma = MAD_TO_SIGMA * median(&mut pairs) / std::f64::consts::SQRT_2;
        let cap = 1.0 + CLIP_SIGMAS * sigma;
        albedo.iter_mut().flatten().for_each(|v| *v = v.min(cap));
        // Without a within-texel variance (fewer pixels than texels plus one) noise cannot be told from texture:
        // the channel keeps the triangle's value.
        let Some(spread) = anova(&albedo) else { continue };
        let tau2 = spread.between_variance();
        if !(tau2 > 0.0 && spread.ms_within.is_finite()) {
            continue;
        }
        varies = true;
        let kappa = spread.ms_within / tau2;
        let n_all: usize = albedo.iter().map(Vec::len).sum();
        let level = albedo.iter().flatten().sum::<f64>() / n_all as f64;
        for (k, values) in albedo.iter().enumerate().filter(|(_, v)| !v.is_empty()) {
            let m = values.len() as f64;
            let texel = values.iter().sum::<f64>() / m;
            let value = f64::from(base[c]) + m / (m + kappa) * (texel - level);
            grid.texels[k][c] = if value.is_finite() { value.clamp(0.0, 1.0) as f32 } else { base[c] };
        }
    }
    if !varies {
        // Every channel kept the triangle's value: a grid would only repeat it.
        p_min = 1.0;
    }
    // Cells beyond the diagonal (no pixel centre lies there) take the value of the inside cell nearest to them.
    for i in 0..nn {
        for j in 0..nn {
            if i + j > nn - 1 {
                // i, j ≤ n − 1 and i + j = n − 1 + over give i, j ≥ over: both steps stay inside the grid,
                // and the cell reached lies on the diagonal.
                let over = i + j - (nn - 1);
                let (ii, jj) = (i - over.div_ceil(2), j - over / 2);
                grid.texels[i * nn + j] = grid.texels[ii * nn + jj];
            }
        }
    }
    // Bonferroni over the 3 channels, as the split test.
    (grid, (3.0 * p_min).min(1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(u: f32, v: f32, target: Vec3) -> TriSample {
        TriSample {
            pixel: PixelRef { view: 0, x: 0, y: 0 },
            target,
            tri: 0,
            child: pixels::child_of(u, v),
            interior: true,
            on_object: true,
            bary: Vec2::new(u, v),
        }
    }

    #[test]
    fn a_striped_albedo_under_smooth_shading_is_recovered_per_texel() {
        // Shading S(u, v) = 2 + u − 0.5 v (smooth), albedo 0.2 for u < ½ and 0.8 beyond (a stripe edge
        // through the triangle), base colour the triangle's mean; renders at the base colour (noise-free).
        let n = 8u32;
        let albedo = |u: f32| if u < 0.5 { 0.2 } else { 0.8 };
        let shade = |u: f32, v: f32| 2.0 + u - 0.5 * v;
        let mut pts = Vec::new();
        for a in 0..40 {
            for b in 0..40 - a {
                pts.push(((a as f32 + 0.3) / 40.0, (b as f32 + 0.3) / 40.0));
            }
        }
        let base = pts.iter().map(|&(u, _)| albedo(u)).sum::<f32>() / pts.len() as f32;
        let data: Vec<(TriSample, Vec3)> = pts
            .iter()
            .map(|&(u, v)| (sample(u, v, Vec3::splat(albedo(u) * shade(u, v))), Vec3::splat(base * shade(u, v))))
            .collect();
        let refs: Vec<(&TriSample, Vec3)> = data.iter().map(|(s, r)| (s, *r)).collect();
        let (g, p) = triangle_grid(n, Vec3::splat(base), &refs);
        assert!(p < 1e-6, "a stripe is structure: p = {p}");
        // Texels well inside each stripe: within 2 % of the truth (the pseudo-pixel at the mean pulls a texel
        // of ~25 pixels by ≤ 1/26 of the difference).
        for &(u, v) in &[(0.1f32, 0.1f32), (0.3, 0.5), (0.7, 0.1), (0.9, 0.05)] {
            let got = g.at(Vec2::new(u, v)).x;
            assert!((got - albedo(u)).abs() < 0.03, "({u}, {v}): {got} for {}", albedo(u));
        }
        // A uniform albedo under the same shading stays uniform (the division removes the shading).
        let flat: Vec<(TriSample, Vec3)> = pts
            .iter()
            .map(|&(u, v)| (sample(u, v, Vec3::splat(0.5 * shade(u, v))), Vec3::splat(0.5 * shade(u, v))))
            .collect();
        let refs: Vec<(&TriSample, Vec3)> = flat.iter().map(|(s, r)| (s, *r)).collect();
        let (g, p) = triangle_grid(n, Vec3::splat(0.5), &refs);
        assert!(p > 0.5, "no structure: p = {p}");
        for t in &g.texels {
            assert!((t.x - 0.5).abs() < 1e-4, "{t}");
        }
    }

    /// A deterministic stand-in for Monte Carlo noise: uniform in [−1, 1), keyed by `k` (the optimiser's
    /// counter-based generator; seed and stream 0, a test's own).
    fn noise(k: u64) -> f32 {
        (2.0 * crate::streams::uniform(0, 0, k, 0) - 1.0) as f32
    }

    #[test]
    fn a_shadow_edge_the_model_renders_is_not_texture() {
        // A uniform albedo 0.5 under a shadow edge (shading 2 for u < 0.4, 0.5 beyond), photo and render each
        // with 10 % noise: no texel structure, though the quadratic shading cannot follow the edge. The same
        // shading over stripes of albedo 0.2 / 0.8 one texel wide is structure.
        let shade = |u: f32| if u < 0.4 { 2.0 } else { 0.5 };
        let mut pts = Vec::new();
        for a in 0..40 {
            for b in 0..40 - a {
                pts.push(((a as f32 + 0.3) / 40.0, (b as f32 + 0.3) / 40.0));
            }
        }
        let run = |albedo: &dyn Fn(f32) -> f32| {
            let data: Vec<(TriSample, Vec3)> = pts
                .iter()
                .enumerate()
                .map(|(k, &(u, v))| {
                    let k = k as u64;
                    let photo = albedo(u) * shade(u) * (1.0 + 0.1 * noise(2 * k));
                    let render = 0.5 * shade(u) * (1.0 + 0.1 * noise(2 * k + 1));
                    (sample(u, v, Vec3::splat(photo)), Vec3::splat(render))
                })
                .collect();
            let refs: Vec<(&TriSample, Vec3)> = data.iter().map(|(s, r)| (s, *r)).collect();
            triangle_grid(8, Vec3::splat(0.5), &refs).1
        };
        let p = run(&|_| 0.5);
        assert!(p > 0.05, "a shadow edge is not texture: p = {p}");
        let p = run(&|u| if (u * 8.0) as u32 % 2 == 0 { 0.2 } else { 0.8 });
        assert!(p < 1e-6, "stripes one texel wide are texture: p = {p}");
    }

    #[test]
    fn cells_clamp_and_empty_texels_keep_the_triangle_value() {
        let g = TexelGrid { n: 4, texels: (0..16).map(|k| Vec3::splat(k as f32)).collect() };
        assert_eq!(g.cell(Vec2::new(1.0, 0.0)), (3, 0));
        assert_eq!(g.cell(Vec2::new(-0.5, f32::NAN)), (0, 0));
        // One pixel in one corner, another in a second texel: no texel holds two pixels, so nothing tells
        // texture from noise, and every texel keeps the base colour.
        let a = sample(0.05, 0.05, Vec3::splat(0.3));
        let b = sample(0.6, 0.2, Vec3::splat(0.9));
        let (g, p) = triangle_grid(4, Vec3::splat(0.6), &[(&a, Vec3::splat(0.6)), (&b, Vec3::splat(0.6))]);
        assert!(g.texels.iter().all(|&t| t == Vec3::splat(0.6)), "{:?}", g.texels);
        assert_eq!(p, 1.0);
        // Two texels of two pixels each, 0.3 and 0.9 with a spread of ±0.01 within each: clear texture, and
        // the texels keep their means almost fully (shrunk by m / (m + σ²/τ²), σ²/τ² ≈ 1e-3).
        let pts = [(0.05, 0.05, 0.29), (0.06, 0.04, 0.31), (0.6, 0.2, 0.89), (0.61, 0.21, 0.91)];
        let s: Vec<TriSample> = pts.iter().map(|&(u, v, t)| sample(u, v, Vec3::splat(t))).collect();
        let refs: Vec<(&TriSample, Vec3)> = s.iter().map(|s| (s, Vec3::splat(0.6))).collect();
        let (g, _) = triangle_grid(4, Vec3::splat(0.6), &refs);
        assert!((g.at(Vec2::new(0.05, 0.05)).x - 0.3).abs() < 1e-3, "{}", g.at(Vec2::new(0.05, 0.05)));
        assert!((g.at(Vec2::new(0.6, 0.2)).x - 0.9).abs() < 1e-3, "{}", g.at(Vec2::new(0.6, 0.2)));
        // A texel no pixel sees keeps the triangle's value.
        assert_eq!(g.at(Vec2::new(0.3, 0.6)), Vec3::splat(0.6));
    }

    /// Pixels on a lattice of `res` points per edge over the triangle, with photo = albedo(u) · shading ·
    /// (1 + `noise_level` · noise) and render = ρ_t · shading, ρ_t the true mean albedo (noise-free: the
    /// render's noise is not what this tests); returns per cell with pixels of a grid of `n` cells per edge
    /// (channel 0): the texel, the cell's true mean albedo and the plain mean of its pixels' albedos; and
    /// the triangle's p-value.
    fn noisy_grid(n: u32, res: usize, albedo: &dyn Fn(f32) -> f32, noise_level: f32) -> (Vec<(f32, f32, f32)>, f64) {
        noisy_grid_with(n, res, albedo, &|k| 1.0 + noise_level * noise(k))
    }

    /// [`noisy_grid`] with the photo's noise factor per pixel index given by `factor`.
    fn noisy_grid_with(
        n: u32,
        res: usize,
        albedo: &dyn Fn(f32) -> f32,
        factor: &dyn Fn(u64) -> f32,
    ) -> (Vec<(f32, f32, f32)>, f64) {
        let shade = |u: f32, v: f32| 1.5 + 0.5 * u - 0.3 * v;
        let mut pts = Vec::new();
        for a in 0..res {
            for b in 0..res - a {
                pts.push(((a as f32 + 0.5) / res as f32, (b as f32 + 0.5) / res as f32));
            }
        }
        let base = pts.iter().map(|&(u, _)| albedo(u)).sum::<f32>() / pts.len() as f32;
        let mut data = Vec::new();
        for &(u, v) in &pts {
            let k = data.len() as u64;
            let photo = albedo(u) * shade(u, v) * factor(k);
            data.push((sample(u, v, Vec3::splat(photo)), Vec3::splat(base * shade(u, v))));
        }
        let refs: Vec<(&TriSample, Vec3)> = data.iter().map(|(s, r)| (s, *r)).collect();
        let (g, p) = triangle_grid(n, Vec3::splat(base), &refs);
        let mut cells: std::collections::BTreeMap<(usize, usize), (f32, f32, usize)> = Default::default();
        for (s, _) in &data {
            let e = cells.entry(g.cell(s.bary)).or_insert((0.0, 0.0, 0));
            e.0 += s.target.x / shade(s.bary.x, s.bary.y);
            e.1 += albedo(s.bary.x);
            e.2 += 1;
        }
        let out = cells
            .iter()
            .map(|(&(i, j), &(raw, truth, m))| (g.texels[i * n as usize + j].x, truth / m as f32, raw / m as f32))
            .collect();
        (out, p)
    }

    fn rms(v: impl Iterator<Item = f32>) -> f32 {
        let (s, n) = v.fold((0.0, 0), |(s, n), x| (s + x * x, n + 1));
        (s / n as f32).sqrt()
    }

    #[test]
    fn photo_noise_on_a_uniform_albedo_is_not_painted_into_the_texels() {
        // Albedo 0.5 everywhere, photos with ±30 % uniform noise (17 % standard deviation), ~4 pixels per texel:
        // the texels' plain means scatter by ~0.04, which a fixed one-pixel prior would leave in the albedo. The
        // between-texel variance estimated on the triangle is ~0, so the texels stay at the base colour.
        let (cells, _) = noisy_grid(32, 64, &|_| 0.5, 0.3);
        let raw = rms(cells.iter().map(|&(_, t, r)| r - t));
        let got = rms(cells.iter().map(|&(g, t, _)| g - t));
        assert!(raw > 0.03, "the test's noise is real: {raw}");
        assert!(got < raw / 4.0, "texel error {got} against the plain means' {raw}");
    }

    #[test]
    fn fireflies_are_capped_before_they_reach_a_texel() {
        // A uniform albedo 0.5 under ±5 % noise, one pixel in 40 a firefly 30× too bright (a Monte Carlo
        // photo's): with ~4 pixels per texel a firefly lifts its texel's plain mean by ~3.6, which no shrinkage
        // weight estimated from such samples undoes; capped at 1 + 3σ, the texels stay near 0.5.
        let factor = |k: u64| if k % 40 == 17 { 30.0 } else { 1.0 + 0.05 * noise(k) };
        let (cells, _) = noisy_grid_with(32, 64, &|_| 0.5, &factor);
        let raw = rms(cells.iter().map(|&(_, t, r)| r - t));
        let got = rms(cells.iter().map(|&(g, t, _)| g - t));
        assert!(raw > 0.5, "the fireflies are in the plain means: {raw}");
        assert!(got < 0.02, "texel error {got}");
    }

    #[test]
    fn a_noisy_stripe_pattern_keeps_its_contrast() {
        // Stripes of 0.2 and 0.8, 4 cells wide, under the same ±30 % noise: the between-texel variance (0.09)
        // dwarfs a texel mean's noise, so the texels keep their stripes: shrunk by m / (m + σ²/τ²) ≈ 0.98 towards
        // the triangle's mean, they are as close to the truth as the plain means (the shrinkage is optimal for
        // normally spread texel albedos; for two stripe values it trades a little bias for the noise it removes).
        let albedo = |u: f32| if (u * 8.0) as u32 % 2 == 0 { 0.2 } else { 0.8 };
        let (cells, p) = noisy_grid(32, 64, &albedo, 0.3);
        assert!(p < 1e-6, "stripes are structure: p = {p}");
        let raw = rms(cells.iter().map(|&(_, t, r)| r - t));
        let got = rms(cells.iter().map(|&(g, t, _)| g - t));
        assert!(got < 1.05 * raw, "texel error {got} against the plain means' {raw}");
        let contrast = |hi: bool| {
            let v: Vec<f32> = cells.iter().filter(|c| (c.1 > 0.5) == hi).map(|c| c.0).collect();
            v.iter().sum::<f32>() / v.len() as f32
        };
        assert!(contrast(true) - contrast(false) > 0.5, "{} vs {}", contrast(true), contrast(false));
    }
}
