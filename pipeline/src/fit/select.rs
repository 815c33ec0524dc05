//! Model selection per object (issue 7): every object starts diffuse without emission and keeps an emission
//! term or gains a specular lobe only when that lowers the residual on held-out pixels significantly (a
//! paired t-test over the held-out pixels, plus a minimum relative improvement).

use super::emission_solve::{Unknowns, coupled_step, solve_step};
use super::jacobian::{self, Ctx};
use super::layout::{self, BASE_COLOR, EMISSION, METALLIC, PER_OBJECT, ROUGHNESS, SPECULAR, idx};
use super::object::{keys, solve_options};
use super::pixels::{PixelSets, Sample};
use super::{FitError, ObjectFitSettings, ObjectModel};
use tracer::PixelRef;

/// A term is kept when the paired t-statistic of its held-out improvement exceeds 3 (one-sided p ≈ 0.1 %:
/// with tens of objects, a spurious acceptance is unlikely)…
const T_KEEP: f64 = 3.0;
/// …and the improvement is at least 0.5 % of the mean held-out |target| (a statistically clear but practically
/// invisible gain does not justify extra parameters; the glossy fixture's floor, specular 0.8 and roughness
/// 0.4, gains 0.75 %, while on the default scene every diffuse wall's trial made the residual worse).
const MIN_GAIN: f64 = 0.005;
/// Starting point of the specular trial: a mid-range lobe, from which Adam can move either way.
const TRIAL_SPECULAR: f64 = 0.5;
const TRIAL_ROUGHNESS: f64 = 0.5;

/// Mean and t-statistic of paired differences.
#[must_use]
pub fn paired_t(d: &[f64]) -> (f64, f64) {
    let n = d.len() as f64;
    if d.len() < 2 {
        return (d.first().copied().unwrap_or(0.0), 0.0);
    }
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let se = (var / n).sqrt();
    let t = if se > 0.0 {
        mean / se
    } else if mean > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    (mean, t)
}

fn l1(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|c| (a[c] - b[c]).abs()).sum()
}

fn target(s: &Sample) -> [f64; 3] {
    [f64::from(s.target.x), f64::from(s.target.y), f64::from(s.target.z)]
}

/// Decides every object's model; returns the final parameters and the decisions.
pub fn choose_models(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    sets: &PixelSets,
    x_fit: &[f64],
    free: &[bool],
) -> Result<(Vec<f64>, Vec<ObjectModel>), FitError> {
    let k_count = x_fit.len() / PER_OBJECT;
    let mut x = x_fit.to_vec();
    // Without held-out pixels (holdout_fraction = 0) the tests run on training pixels and say so.
    let (test, test_name): (&[Sample], &str) =
        if sets.holdout.is_empty() { (&sets.train, "training") } else { (&sets.holdout, "held-out") };
    let pix: Vec<PixelRef> = test.iter().map(|t| t.pixel).collect();
    let mean_target = test.iter().map(|t| l1(target(t), [0.0; 3])).sum::<f64>() / test.len().max(1) as f64;
    let mut why: Vec<Vec<String>> = vec![Vec::new(); k_count];

    // Specular lobe trial.
    let mut glossy = vec![false; k_count];
    if s.try_specular && free.iter().any(|&f| f) {
        let mut xt = x.clone();
        for k in (0..k_count).filter(|&k| free[k]) {
            xt[idx(k, SPECULAR)] = TRIAL_SPECULAR;
            xt[idx(k, ROUGHNESS)] = TRIAL_ROUGHNESS;
        }
        // Gauss–Newton on every unknown of the trial model. Measured on the glossy fixture: 100 Adam iterations
        // from this start left roughness and specular near where they began; 4 coupled steps bring the box
        // (roughness 0.25, specular 1) to roughness 0.23–0.33, specular 0.9–1.0, though the floor's roughness
        // (0.4) is not identified (drifts to 0) and its held-out gain is not yet significant.
        let lobe: Vec<bool> = free.to_vec();
        for step in 1..=s.specular_trial_steps {
            let key = keys::SELECT + u64::from(step);
            let samples = super::pixels::draw(
                &sets.train,
                s.solve_pixels as usize,
                ctx.seed,
                super::pixels::stream::SOLVE_PIXELS,
                key,
            );
            coupled_step(
                ctx,
                &mut xt,
                &samples,
                s.solve_spp,
                key,
                free,
                &lobe,
                &solve_options(s, Unknowns::EmissionAndBaseColor),
            )?;
        }
        // Common random numbers for both renders: the paired differences then carry little path noise.
        let key = keys::SELECT + (1 << 20);
        let render = |v: &[f64]| {
            tracer::render_pixels(
                ctx.scene,
                &layout::to_params(v),
                ctx.cameras,
                &pix,
                s.holdout_spp,
                ctx.settings,
                ctx.seed,
                key,
            )
        };
        let (i_d, i_t) = (render(&x)?, render(&xt)?);
        for k in (0..k_count).filter(|&k| free[k]) {
            let d: Vec<f64> = test
                .iter()
                .enumerate()
                .filter(|(_, t)| t.object == Some(k as u32))
                .map(|(j, t)| {
                    let a = i_d[j].as_dvec3().to_array();
                    let b = i_t[j].as_dvec3().to_array();
                    l1(target(t), a) - l1(target(t), b)
                })
                .collect();
            let (gain, t) = paired_t(&d);
            let rel = gain / mean_target.max(f64::MIN_POSITIVE);
            if t > T_KEEP && rel > MIN_GAIN {
                glossy[k] = true;
                for p in [BASE_COLOR, BASE_COLOR + 1, BASE_COLOR + 2, ROUGHNESS, METALLIC, SPECULAR] {
                    x[idx(k, p)] = xt[idx(k, p)];
                }
                why[k].push(format!(
                    "specular lobe kept: it lowers the {test_name} L1 by {:.1} % of the mean radiance on {} pixels (t = {t:.1})",
                    100.0 * rel,
                    d.len()
                ));
            } else {
                why[k].push(format!(
                    "diffuse: a specular lobe changed the {test_name} L1 by {:+.2} % on {} pixels (t = {t:.1}; needs t > {T_KEEP} and > {:.0} %)",
                    -100.0 * rel,
                    d.len(),
                    100.0 * MIN_GAIN
                ));
            }
        }
        if glossy.iter().any(|&g| g) {
            let key = keys::SELECT + (2 << 20);
            let samples = super::pixels::draw(
                &sets.train,
                s.solve_pixels as usize,
                ctx.seed,
                super::pixels::stream::SOLVE_PIXELS,
                key,
            );
            solve_step(ctx, &mut x, &samples, s.solve_spp, key, free, &solve_options(s, Unknowns::Emission))?;
        }
    }

    // Emission test: radiance is linear in emission, so the render without object k's emission is the render
    // with it minus J_k e_k — one set of basis renders answers every object.
    let params = layout::to_params(&x);
    let je = jacobian::emission_columns(ctx, &params.materials, &pix, s.solve_spp, keys::SELECT + (3 << 20))?;
    let pred: Vec<[f64; 3]> = (0..test.len())
        .map(|j| {
            let mut p = [0.0; 3];
            for k in 0..k_count {
                for c in 0..3 {
                    p[c] += je[k][j][c] * x[idx(k, EMISSION + c)];
                }
            }
            p
        })
        .collect();
    let mut emits = vec![false; k_count];
    for k in 0..k_count {
        let e = [x[idx(k, EMISSION)], x[idx(k, EMISSION + 1)], x[idx(k, EMISSION + 2)]];
        if e.iter().all(|&v| v == 0.0) {
            why[k].push("no emission: the L1-penalised emission solve set it to 0".into());
            continue;
        }
        let d: Vec<f64> = test
            .iter()
            .enumerate()
            .map(|(j, t)| {
                let without: [f64; 3] = std::array::from_fn(|c| pred[j][c] - je[k][j][c] * e[c]);
                l1(target(t), without) - l1(target(t), pred[j])
            })
            .collect();
        let (gain, t) = paired_t(&d);
        let rel = gain / mean_target.max(f64::MIN_POSITIVE);
        if t > T_KEEP && rel > MIN_GAIN * 1e-2 {
            emits[k] = true;
            why[k].push(format!(
                "emission kept: without it the {test_name} L1 rises by {:.3} % of the mean radiance (t = {t:.1})",
                100.0 * rel
            ));
        } else {
            why[k].push(format!(
                "emission {e:.4?} dropped: it changes the {test_name} L1 by {:+.4} % (t = {t:.1}; needs t > {T_KEEP})",
                -100.0 * rel
            ));
        }
    }
    for k in (0..k_count).filter(|&k| !emits[k]) {
        for c in 0..3 {
            x[idx(k, EMISSION + c)] = 0.0;
        }
    }
    let models = (0..k_count)
        .map(|k| {
            let mut reasons = why[k].clone();
            if !free[k] {
                reasons.insert(0, format!(
                    "material unconstrained: seen in fewer than {} training pixels; base colour left at the start value",
                    super::object::MIN_PIXELS
                ));
            }
            let model = match (glossy[k], emits[k]) {
                (false, false) => "diffuse",
                (true, false) => "specular",
                (false, true) => "diffuse+emission",
                (true, true) => "specular+emission",
            };
            ObjectModel { model: model.into(), why: reasons.join("; "), constrained: free[k] }
        })
        .collect();
    Ok((x, models))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paired_t_matches_the_textbook_formula() {
        // d = 1, 2, 3, 4: mean 2.5, sample sd √(5/3), se = sd/2 → t = 2.5 / 0.6455 = 3.873.
        let (mean, t) = paired_t(&[1.0, 2.0, 3.0, 4.0]);
        assert!((mean - 2.5).abs() < 1e-12);
        assert!((t - 2.5 / ((5.0f64 / 3.0).sqrt() / 2.0)).abs() < 1e-12);
        // Symmetric differences: no evidence either way.
        assert_eq!(paired_t(&[-1.0, 1.0, -2.0, 2.0]).1, 0.0);
        // Too few samples: no t.
        assert_eq!(paired_t(&[5.0]).1, 0.0);
    }
}
