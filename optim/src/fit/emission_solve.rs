//! Linearised solves around the current parameters, per colour channel:
//!
//! - [`Unknowns::Emission`]: the closed-form emission solve. Radiance is linear in emission, so for fixed
//!   materials `I_j = Σ_k J_jk e_k` exactly, with J from basis renders ([`super::jacobian`]); e ≥ 0 minimises
//!   the data term (the object stage's per-object Huber, [`DataLoss::GroupHuber`], by IRLS) plus the relative
//!   emission penalty `λ Σ_k s_k e_k`, where s_k = mean_j |J_jk| is how strongly object k's emission moves the
//!   loss. A single λ then treats a visible wall (s ≈ its share of the pixels) and a hidden light (s ≈ 1e-4 of
//!   that) alike.
//! - [`Unknowns::EmissionAndBaseColor`]: one Gauss–Newton step on emission and base colour jointly, with a
//!   Levenberg–Marquardt proximal term on base colour. Moving both together is what crosses the
//!   albedo/emission scale valley that alternating or joint first-order steps creep along. The step keeps the
//!   emitters it starts from, or those its caller gives ([`Support`]): no emission penalty, objects that do
//!   not emit pinned at 0. Which objects emit is
//!   chosen where it is identifiable — by the emission-only solves (materials fixed) and model selection — and
//!   not here: the linearisation has a spurious near-degeneracy between a light and every albedo it shines on
//!   (I = J_e·e exactly, and J_ρ·ρ₀ ≈ I as well), along which the penalty dragged a hidden light's channel to
//!   0 with every albedo of that channel doubled, one step in four on a textured-floor room
//!   (docs/optim/design-measurements.md, "Solve pixels per object and the checker light").

use super::jacobian::{self, Ctx};
use super::layout::{self, BASE_COLOR, EMISSION, EMISSION_GROUND, EMISSION_MAX, EMISSION_ZENITH, idx};
use super::linear::{self, DataLoss, Problem};
use super::pixels::WeightedDraw;
use rayon::prelude::*;
use tracer::{PixelRef, TracerError};

use crate::streams::key::SECOND_ESTIMATE;

/// Which unknowns a linearised solve updates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unknowns {
    Emission,
    EmissionAndBaseColor,
}

/// Which objects a joint step ([`Unknowns::EmissionAndBaseColor`]) treats as emitters, besides those the
/// caller holds at 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Support {
    /// Those that emit when the step starts: an object whose emission is 0 in every channel stays at 0 (the step
    /// keeps the emitters it starts from; the refinement, whose emitters the emission-only solves chose).
    Current,
    /// Those, and every emitter no photo sees (its base colour not free) that the caller does not hold at 0: a
    /// hidden light whose emission one step takes to 0 is still an unknown of the next. A hidden light is
    /// reached only through the albedos it lights, along the linearisation's near-degeneracy (module docs);
    /// under `Current` a single step to 0 is final, and on the corpus house (natively rendered photos, seed 0)
    /// the re-fit after a dropped emission took an unseen ceiling lamp that its emission test had kept at
    /// t = 16.2 to 0 for good, and its room's floor and ceiling to an albedo of 1. A seen emitter's own pixels
    /// constrain it directly: one that a step takes to 0 stays there, as under `Current` (freed as well, a
    /// wall of Daylight Room kept a spurious emission). Measured: docs/scale/README.md, "Accuracy on natively
    /// rendered photos".
    KeepHidden,
}

/// Whether each object's emission is held at 0 in a solve: the caller's `no_emission` verdicts, and in a joint
/// step every object that does not emit now (`dark[k]`: 0 in every channel), except under
/// [`Support::KeepHidden`] those no photo sees (`seen[k]` false).
fn pinned_objects(no_emission: &[bool], dark: &[bool], seen: &[bool], joint: bool, support: Support) -> Vec<bool> {
    dark.iter()
        .enumerate()
        .map(|(k, &d)| {
            let hidden = !seen.get(k).copied().unwrap_or(true);
            no_emission.get(k).copied().unwrap_or(false) || (joint && d && !(support == Support::KeepHidden && hidden))
        })
        .collect()
}

/// Options of one solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveOptions {
    pub unknowns: Unknowns,
    /// The emitters of a joint step (ignored by an emission-only solve, which chooses them).
    pub support: Support,
    pub loss: DataLoss,
    /// λ of the relative emission penalty.
    pub emission_l1: f64,
    /// Marquardt damping of base colour: prox_k = damping · mean_j (∂I_j/∂ρ_k)².
    pub damping: f64,
    pub irls_iters: usize,
    /// Rows at which each basis render of an emission-only solve takes the solve's `spp` paths per row. A draw
    /// with more rows (its floor of pixels per object passes `solve_pixels` beyond `solve_pixels / 32`
    /// objects) takes proportionally fewer per row, at least 1: a basis render's paths — what an emission's
    /// precision rests on — stay as they are, and the K basis renders of a solve over ~32·K rows cost K·const
    /// paths instead of growing as K².
    pub basis_rows: usize,
}

/// Paths per row of a basis render over `rows` rows: `spp` up to `basis_rows` rows, then the same total.
#[must_use]
pub fn basis_spp(spp: u32, basis_rows: usize, rows: usize) -> u32 {
    if rows <= basis_rows || rows == 0 {
        return spp;
    }
    let total = u64::from(spp) * basis_rows as u64;
    (total.div_ceil(rows as u64)).clamp(1, u64::from(spp)) as u32
}

/// Updates emission (and base colour) of `x` in place from a solve on `draw` (with its row weights, see
/// [`linear::Problem::weights`]) with `spp` paths per Jacobian entry, random numbers keyed by `iteration_key`.
/// `free_base_color[k]` = object k's base colour is constrained by the photos (seen in enough pixels); other base
/// colours are left as they are. The emission of every object with `no_emission[k]` is held at 0 (model
/// selection's verdict that it does not emit, or an object outside a comparison fit's lights). Returns the mean
/// per-channel L1 residual of the parameters before the update.
#[allow(clippy::too_many_arguments)]
pub fn solve_step_pinned(
    ctx: &Ctx<'_>,
    x: &mut [f64],
    draw: &WeightedDraw,
    spp: u32,
    iteration_key: u64,
    free_base_color: &[bool],
    no_emission: &[bool],
    opts: &SolveOptions,
) -> Result<f64, TracerError> {
    let k_count = x.len() / layout::PER_OBJECT;
    let samples = &draw.samples;
    let pixels: Vec<PixelRef> = samples.iter().map(|s| s.pixel).collect();
    let params = ctx.params(x);
    // Two independent estimates of every Jacobian entry (instrumental variables, see `linear::Problem`).
    let key2 = iteration_key ^ SECOND_ESTIMATE;
    let joint = opts.unknowns == Unknowns::EmissionAndBaseColor;
    // The emission unknowns (object, its layout entry, the tracer's emission entry): every object's own (its
    // sky half when split), then the ground half of every object the context splits, then the zenith of every
    // split object whose sky has a gradient, in object order (`layout::Split::params`). An emission-only
    // solve leaves out the objects held at 0: their columns would be rendered for nothing (the solver drops a
    // variable held at 0 from its sums, so the others' values are the same bit for bit).
    let held = |k: usize| !joint && no_emission.get(k).copied().unwrap_or(false);
    let unknowns: Vec<(usize, usize, u32)> = (0..k_count)
        .filter(|&k| !held(k))
        .map(|k| (k, EMISSION, k as u32))
        .chain(
            (0..k_count)
                .filter(|&k| !held(k))
                .filter_map(|k| params.horizon.ground_of(k as u32).map(|g| (k, EMISSION_GROUND, g))),
        )
        .chain(
            (0..k_count)
                .filter(|&k| !held(k))
                .filter_map(|k| params.horizon.zenith_of(k as u32).map(|z| (k, EMISSION_ZENITH, z))),
        )
        .collect();
    for k in (0..k_count).filter(|&k| held(k)) {
        for c in 0..3 {
            x[idx(k, EMISSION + c)] = 0.0;
            x[idx(k, EMISSION_GROUND + c)] = 0.0;
            x[idx(k, EMISSION_ZENITH + c)] = 0.0;
        }
    }
    // Emission-only solves use basis renders (every object's column by next-event estimation, also for objects
    // that do not emit yet); the joint step takes both blocks from the same gradient paths, one pass instead
    // of K basis renders.
    let (je, je2, jr, jr2) = if joint {
        let r1 = jacobian::pixel_rows(ctx, &params, &pixels, spp, iteration_key)?;
        let r2 = jacobian::pixel_rows(ctx, &params, &pixels, spp, key2)?;
        let cols = |r: &[jacobian::PixelRow]| -> Vec<Vec<[f64; 3]>> {
            unknowns.iter().map(|&(_, _, e)| r.iter().map(|row| row.emission[e as usize]).collect()).collect()
        };
        let rho =
            |r: &[jacobian::PixelRow]| -> Vec<Vec<[f64; 3]>> { r.iter().map(|row| row.base_color.clone()).collect() };
        (cols(&r1), cols(&r2), rho(&r1), rho(&r2))
    } else {
        let spp = basis_spp(spp, opts.basis_rows, pixels.len());
        let entries: Vec<u32> = unknowns.iter().map(|&(_, _, e)| e).collect();
        (
            jacobian::entry_columns(ctx, &params, &pixels, spp, iteration_key, &entries)?,
            jacobian::entry_columns(ctx, &params, &pixels, spp, key2, &entries)?,
            Vec::new(),
            Vec::new(),
        )
    };
    // Variables: e_0..e_{K-1}, then the free base colours, with their columns ∂I_j/∂ρ_k from the pixel rows.
    let free: Vec<usize> = if joint { (0..k_count).filter(|&k| free_base_color[k]).collect() } else { Vec::new() };
    let base_color_cols = |rows: &[Vec<[f64; 3]>]| -> Vec<Vec<[f64; 3]>> {
        free.iter().map(|&k| rows.iter().map(|row| row[k]).collect()).collect()
    };
    let (jm, jm2) = (base_color_cols(&jr), base_color_cols(&jr2));
    let targets: Vec<glam::Vec3> = samples.iter().map(|s| s.target).collect();
    let groups: Vec<u32> = samples.iter().map(|s| s.object.unwrap_or(u32::MAX)).collect();
    // The joint step keeps the emitters it is given (see the module docs): no emission penalty, and an object
    // that does not emit does not start to.
    let dark: Vec<bool> = (0..k_count).map(|k| layout::rgb(x, k, EMISSION).iter().all(|&v| v == 0.0)).collect();
    let pinned_object = pinned_objects(no_emission, &dark, free_base_color, joint, opts.support);
    let pinned: Vec<bool> = unknowns.iter().map(|&(k, _, _)| pinned_object[k]).collect();
    let opts = &if joint { SolveOptions { emission_l1: 0.0, ..*opts } } else { *opts };
    let mut emission: Vec<[f64; 3]> = unknowns.iter().map(|&(k, at, _)| layout::rgb(x, k, at)).collect();
    let mut base_color: Vec<[f64; 3]> = free.iter().map(|&k| layout::base_color(x, k)).collect();
    let loss = solve_on_columns(
        Columns { a: &je, b: &je2 },
        Columns { a: &jm, b: &jm2 },
        &targets,
        &draw.weights,
        &groups,
        &mut emission,
        &pinned,
        &mut base_color,
        &[],
        &vec![[1.0; 3]; free.len()],
        opts,
    );
    for (&(k, at, _), &e) in unknowns.iter().zip(&emission) {
        layout::set_rgb(x, k, at, e);
    }
    for (&k, &rho) in free.iter().zip(&base_color) {
        layout::set_rgb(x, k, BASE_COLOR, rho);
    }
    Ok(loss)
}

/// Two independent Monte Carlo estimates of a block of Jacobian columns, per channel: `a[i][j]`, `b[i][j]` =
/// ∂I_j/∂θ_i (RGB) over the solve's pixels (instrumental variables, see [`linear::Problem::second`]).
#[derive(Debug, Clone, Copy)]
pub struct Columns<'a> {
    pub a: &'a [Vec<[f64; 3]>],
    pub b: &'a [Vec<[f64; 3]>],
}

/// [`solve_step_pinned`]'s per-channel solve on Jacobian columns the caller estimated, for scenes whose material
/// table is not per object (the per-triangle stage): unknowns are the listed emissions `emission[i]` (columns
/// `emission_cols`, exact since radiance is linear in emission) and material unknowns `material[i]` (columns
/// `material_cols`, a linearisation about their current values; empty for an emission-only solve), over the pixels
/// whose photo values are `targets`, with row weights `weights` (empty: all 1; see [`linear::Problem::weights`])
/// and row groups `groups` (the object each pixel sees, for [`DataLoss::GroupHuber`]; empty: one group). Same
/// estimator: the two column estimates as instrumental variables, IRLS-L1 (or L2), the relative emission lasso
/// relaxed on its support, e ∈ [0, EMISSION_MAX], Marquardt damping `opts.damping · mean_j J_ij²` of each material
/// unknown towards its current value and the box [`material_lo[i]`, `material_hi[i]`] (`material_lo` empty: 0).
/// Emissions with `emission_pinned[i]` are held at 0 (a model-selection verdict; the slice may be shorter than
/// `emission`: missing entries are free); emitters not listed at all must be held at 0 by the caller. Returns the
/// mean per-channel L1 residual before the update. The one assembly of these problems: the object stage's
/// [`solve_step_pinned`] and the per-triangle stage's light re-solve both call it.
#[allow(clippy::too_many_arguments)]
pub fn solve_on_columns(
    emission_cols: Columns<'_>,
    material_cols: Columns<'_>,
    targets: &[glam::Vec3],
    weights: &[f64],
    groups: &[u32],
    emission: &mut [[f64; 3]],
    emission_pinned: &[bool],
    material: &mut [[f64; 3]],
    material_lo: &[[f64; 3]],
    material_hi: &[[f64; 3]],
    opts: &SolveOptions,
) -> f64 {
    let ne = emission_cols.a.len().min(emission_cols.b.len()).min(emission.len());
    let nm = material_cols.a.len().min(material_cols.b.len()).min(material.len()).min(material_hi.len());
    let m = targets.len();
    let weights: Vec<f64> = if weights.len() == m { weights.to_vec() } else { vec![1.0; m] };
    // Weighted mean over the rows: with the draw's weights, an unbiased estimate of the mean over all pixels.
    let wmean = |v: &mut dyn Iterator<Item = f64>| v.zip(&weights).map(|(a, w)| a * w).sum::<f64>() / m.max(1) as f64;
    // The three channels are independent problems, solved side by side; each returns its rows' terms of the
    // loss, which are summed afterwards in the order of a sequential pass (channel by channel, row by row).
    let solved: Vec<(Vec<f64>, Vec<f64>)> = (0..3usize)
        .into_par_iter()
        .map(|c| {
            let chan = |cols: &[Vec<[f64; 3]>], n: usize| -> Vec<Vec<f64>> {
                (0..n).map(|k| cols[k].iter().map(|v| v[c]).collect()).collect()
            };
            let mut cols = chan(emission_cols.a, ne);
            let mut cols2 = chan(emission_cols.b, ne);
            let mut target: Vec<f64> = targets.iter().map(|t| f64::from(t[c])).collect();
            let mut target2 = target.clone();
            let n = ne + nm;
            let mut penalty = vec![0.0; n];
            let mut prox = vec![0.0; n];
            let mut anchor = vec![0.0; n];
            let mut lo = vec![0.0; n];
            let mut hi = vec![EMISSION_MAX; n];
            let mut var = vec![0.0; n];
            for k in 0..ne {
                let s = wmean(&mut cols[k].iter().zip(&cols2[k]).map(|(a, b)| 0.5 * (a + b).abs()));
                penalty[k] = opts.emission_l1 * s;
                var[k] = emission[k][c];
            }
            // Mean |residual| of the current parameters (I_j = Σ_k J_jk e_k exactly), before the update.
            let loss_terms: Vec<f64> = target
                .iter()
                .enumerate()
                .map(|(j, t)| {
                    let pred: f64 = (0..ne).map(|k| 0.5 * (cols[k][j] + cols2[k][j]) * var[k]).sum();
                    weights[j] * (t - pred).abs() / (3 * m.max(1)) as f64
                })
                .collect();
            for k in (0..ne).filter(|&k| emission_pinned.get(k).copied().unwrap_or(false)) {
                hi[k] = 0.0;
                var[k] = 0.0;
            }
            for (i, (ca, cb)) in chan(material_cols.a, nm).into_iter().zip(chan(material_cols.b, nm)).enumerate() {
                let v = ne + i;
                let x0 = material[i][c];
                // Linearisation about x0: I ≈ J_e·e + J_x·(x − x0)  ⇒  target t + J_x·x0 for the variables (e, x).
                for j in 0..m {
                    target[j] += ca[j] * x0;
                    target2[j] += cb[j] * x0;
                }
                let diag = wmean(&mut ca.iter().zip(&cb).map(|(a, b)| (a * b).abs()));
                prox[v] = opts.damping * diag;
                anchor[v] = x0;
                lo[v] = material_lo.get(i).map_or(0.0, |l| l[c]);
                hi[v] = material_hi[i][c];
                var[v] = x0;
                cols.push(ca);
                cols2.push(cb);
            }
            let problem = Problem {
                cols: &cols,
                target: &target,
                second: Some((&cols2, &target2)),
                weights: Some(&weights),
                groups: (groups.len() == m).then_some(groups),
                penalty: &penalty,
                prox: &prox,
                anchor: &anchor,
                lo: &lo,
                hi: &hi,
            };
            solve_relaxed_lasso(problem, ne, opts, &mut var);
            (loss_terms, var)
        })
        .collect();
    let mut loss = 0.0;
    for (c, (loss_terms, var)) in solved.into_iter().enumerate() {
        loss_terms.iter().for_each(|t| loss += t);
        for (e, v) in emission.iter_mut().zip(&var[..ne]) {
            e[c] = *v;
        }
        for (x, v) in material.iter_mut().zip(&var[ne..]) {
            x[c] = *v;
        }
    }
    loss
}

/// Relaxed lasso over the first `n_emission` unknowns (the emissions): `problem` is solved with its penalty,
/// which only selects which objects emit; on that support the emission is solved again without it. A penalty
/// left on a true light shrinks it, and in the joint Gauss–Newton step that pull is a force along the
/// albedo/emission valley (dimmer light, brighter walls) that nothing else in the data opposes strongly.
fn solve_relaxed_lasso(problem: Problem<'_>, n_emission: usize, opts: &SolveOptions, var: &mut [f64]) {
    linear::solve(&problem, opts.loss, var, opts.irls_iters);
    let hi: Vec<f64> =
        problem.hi.iter().enumerate().map(|(i, &h)| if i < n_emission && var[i] == 0.0 { 0.0 } else { h }).collect();
    let penalty: Vec<f64> =
        problem.penalty.iter().enumerate().map(|(i, &p)| if i < n_emission { 0.0 } else { p }).collect();
    linear::solve(&Problem { penalty: &penalty, hi: &hi, ..problem }, opts.loss, var, opts.irls_iters);
}

#[cfg(test)]
mod tests {
    use super::{Support, basis_spp, pinned_objects};

    #[test]
    fn a_hidden_emitter_at_zero_stays_an_unknown_of_the_joint_step() {
        // Objects: 0 held at 0 by the caller, 1 emitting, 2 a seen emitter a step took to 0, 3 a hidden one.
        let (no_emission, dark, seen) =
            ([true, false, false, false], [true, false, true, true], [true, true, true, false]);
        // Under the current support both dark emitters are pinned; keeping the hidden, only the seen one is.
        assert_eq!(pinned_objects(&no_emission, &dark, &seen, true, Support::Current), vec![true, false, true, true]);
        assert_eq!(
            pinned_objects(&no_emission, &dark, &seen, true, Support::KeepHidden),
            vec![true, false, true, false]
        );
        // A hidden object the caller holds at 0 stays there.
        assert_eq!(pinned_objects(&[true; 4], &dark, &seen, true, Support::KeepHidden), vec![true; 4]);
        // An emission-only solve chooses its emitters: only the caller's verdicts pin, whatever the support.
        assert_eq!(
            pinned_objects(&no_emission, &dark, &seen, false, Support::Current),
            vec![true, false, false, false]
        );
    }

    #[test]
    fn a_material_unknown_stays_in_its_box_from_below() {
        // One light (column 1 on every row) and one material unknown linearised about 1 whose column is 1 on the
        // even rows: I_j = e + (x − 1)·[j even]. Photos of 1 on the odd rows and 0 on the even ones call for
        // e = 1 and x = 0; held at x ≥ 1/2, the least-squares light is the mean of 1 and 1/2.
        let rows = 8;
        let light: Vec<[f64; 3]> = vec![[1.0; 3]; rows];
        let material: Vec<[f64; 3]> = (0..rows).map(|j| [if j % 2 == 0 { 1.0 } else { 0.0 }; 3]).collect();
        let targets: Vec<glam::Vec3> = (0..rows).map(|j| glam::Vec3::splat((j % 2) as f32)).collect();
        let opts = super::SolveOptions {
            unknowns: super::Unknowns::EmissionAndBaseColor,
            support: Support::Current,
            loss: super::DataLoss::L2,
            emission_l1: 0.0,
            damping: 0.0,
            irls_iters: 1,
            basis_rows: usize::MAX,
        };
        let solve = |lo: &[[f64; 3]]| {
            let (mut e, mut x) = (vec![[1.0; 3]], vec![[1.0; 3]]);
            let (le, lm) = (vec![light.clone()], vec![material.clone()]);
            super::solve_on_columns(
                super::Columns { a: &le, b: &le },
                super::Columns { a: &lm, b: &lm },
                &targets,
                &[],
                &[],
                &mut e,
                &[],
                &mut x,
                lo,
                &[[2.0; 3]],
                &opts,
            );
            (e[0][0], x[0][0])
        };
        let (e, x) = solve(&[]);
        assert!((e - 1.0).abs() < 1e-6 && x.abs() < 1e-6, "unbounded below: e {e}, x {x}");
        let (e, x) = solve(&[[0.5; 3]]);
        assert!((x - 0.5).abs() < 1e-12 && (e - 0.75).abs() < 1e-6, "bounded at 1/2: e {e}, x {x}");
    }

    #[test]
    fn basis_renders_keep_their_paths_when_a_draw_has_more_rows() {
        assert_eq!(basis_spp(128, 1024, 1024), 128);
        assert_eq!(basis_spp(128, 1024, 500), 128);
        // 57 objects × 32 rows: the same 131 072 paths per basis render, rounded up.
        assert_eq!(basis_spp(128, 1024, 1856), 71);
        // Never below one path per row.
        assert_eq!(basis_spp(4, 1024, 1_000_000), 1);
    }
}
