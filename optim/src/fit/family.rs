//! A second look at each object's lobe family once the room's light is settled (the emission test and the horizon split
//! have run). The first look (`super::select`) searches the metal family only where a dielectric's specular strength
//! binds, and under lights still uniform at the horizon: a polished metal whose dielectric fit stays below its bound
//! comes out a dark, tinted diffuse surface. Here every constrained non-emitting object that ended dielectric is probed
//! with a metal lobe, and a metal is kept only where the held-out pixels prefer it both to the object's model and to
//! the best dielectric lobe under the same light (measured: docs/optim/design-measurements.md, "A second look at the
//! lobe family"). The metal's solves start where its render's summed radiance matches the photos' ("Where the metal
//! probes start"): started at the dielectric's diffuse colour they stay near it. The probes are weighed by the unbiased
//! RMS error of their profile solves, and the metal tests keep a metal where it passes on the L1 of two half-path
//! renders' mean or on their unbiased squared error ("An unbiased test for metals"): the L1 of one render, which the
//! renders' noise inflates the more the brighter and sharper the lobe, refused metals near the truth. These tests
//! render at [`METAL_TEST_PATHS`] times the held-out paths ("The metal tests at four times the held-out paths").
//! The objects the first look made metal face the same comparison the other way: a metal lobe stays only where the
//! held-out pixels prefer it to the best dielectric lobe under the settled light, else that dielectric lobe replaces
//! it ("Metals that the first look chose, looked at again"). Last, every dielectric lobe faces the object's best
//! Lambert surface under the same light, which replaces it unless the held-out pixels prefer the lobe ("Lobes under
//! the settled light").

use super::jacobian::Ctx;
use super::layout::{self, BASE_COLOR, METALLIC, ROUGHNESS, SPECULAR, idx};
use super::paired::{METAL_TEST_PATHS, MIN_GAIN, Statistic, T_KEEP, Verdict, sequential_lobe_test};
use super::pixels::{PixelSets, Sample};
use super::roughness::{self, TRIAL_ROUGHNESS, TRIAL_SPECULAR, profile_samples};
use super::{FitError, ObjectFitSettings};
use crate::progress::check_stop;
use crate::streams::key;

/// Roughness of the metal probes (0.22 and 0.45): the middle points of the search's coarse grid ([`roughness::GRID`]),
/// where a polished or brushed metal's reflection of the room is sharp enough to tell it from a diffuse surface.
const METAL_PROBES: [f64; 2] = [roughness::GRID[2], roughness::GRID[4]];
/// The roughest metal the second look searches (0.62, the grid's next-to-last point). Above it a metal's lobe spreads
/// over the hemisphere and lights its pixels nearly as a diffuse surface of the same colour does; probed there, diffuse
/// walls and boxes of the corpus house preferred a metal by 5–85× [`roughness::FLAT_PROFILE`], absorbing what the
/// room's light got wrong, and the lobe test kept 8 of them (docs/optim/design-measurements.md, "A metal probe for
/// dielectrics below their bound").
pub(super) const METAL_ROUGHEST: f64 = roughness::GRID[5];
/// What the metal tests compare per pixel: the metal, the noisier of the two models, passes on the L1 of two
/// half-path renders' mean or on their unbiased squared error ([`Statistic::L1OrSquaredError`]). With the L1
/// alone, which the renders' noise inflates the more the brighter and sharper the lobe, the metals started
/// near the truth were refused; with the squared error alone, which has little power where a few pixels
/// reflect a lamp, first-look metals were lost (two at gains of 49 % and 69 % of the RMS error, t = 2.4 and
/// 2.9). Either way the corpus house lost true metals (object stage 0.0648 → 0.0735 and 0.0744 at seed 1); with
/// both it ends with 13 of its 17 seen true metals metal at seeds 1 and 2 (14 and 12 before), at 0.0641 and
/// 0.0566 (0.0648 and 0.0615 before; docs/optim/design-measurements.md, "An unbiased test for metals").
const METAL_STATISTIC: Statistic = Statistic::L1OrSquaredError;
/// Roughness at which the metal probes' start is found ([`roughness::ratio_start`]): the grid point between the
/// two probes.
const METAL_START_ROUGHNESS: f64 = roughness::GRID[3];

/// Where a metal lobe's profile solves start for object k of `x` (whose metallic is 1): the base colour whose
/// render at [`METAL_START_ROUGHNESS`] matches the pixels' summed radiance ([`roughness::ratio_start`]).
pub(super) fn metal_start(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    at: (&[Sample], u32, u64),
) -> Result<[f64; 3], tracer::TracerError> {
    roughness::ratio_start(ctx, x, k, METAL_START_ROUGHNESS, at)
}

/// The second look for every free object without emission whose metallic is below one half (`x`, `free`, `emits` as
/// model selection ends with them). The metal family is probed at [`METAL_PROBES`], its profile solves started at the
/// base colour whose render matches the pixels' summed radiance ([`roughness::ratio_start`] at
/// [`METAL_START_ROUGHNESS`]), against the object's model refitted at its own roughness (the profile solves of
/// [`roughness::profile_unbiased`], on the object's lobe-choosing pixels); where a probe's unbiased RMS error is below
/// the model's by [`roughness::FLAT_PROFILE`] of the pixels' mean, the metal's roughness is searched up to
/// [`METAL_ROUGHEST`] and the dielectric family's best lobe is searched again. Both paired tests run on `lobe_test`
/// (the first look's test pixels) with [`METAL_STATISTIC`]: the metal against the model, then, where it passes, against
/// the dielectric lobe; it is kept where both pass (t > [`T_KEEP`] and a gain above [`MIN_GAIN`] of `mean_target`). The
/// light and the other objects stay as fitted: a switched object's base colour is its profile solve's, under the
/// settled light. Then the objects that were metal (metallic ≥ ½) when it began face their dielectric lobe
/// ([`recheck_metals`]), and last every dielectric lobe faces the object's best Lambert surface ([`recheck_lobes`]).
/// Each decision is added to `why`.
#[allow(clippy::too_many_arguments)]
pub(super) fn second_look(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    sets: &PixelSets,
    lobe_test: &[Sample],
    mean_target: f64,
    x: &mut [f64],
    (free, emits): (&[bool], &[bool]),
    glossy: &mut [bool],
    why: &mut [Vec<String>],
    progress: &dyn crate::Progress,
) -> Result<(), FitError> {
    let k_count = free.len();
    let first_metals: Vec<bool> =
        (0..k_count).map(|k| free[k] && !emits[k] && layout::is_metal(x[idx(k, METALLIC)])).collect();
    let candidates: Vec<usize> =
        (0..k_count).filter(|&k| free[k] && !emits[k] && !layout::is_metal(x[idx(k, METALLIC)])).collect();
    progress.phase("model selection: metal probe, object", candidates.len() as u64, 0);
    let spp = roughness::profile_spp(s.solve_spp);
    let (mut xt, mut xd) = (x.to_vec(), x.to_vec());
    let mut tested = vec![false; k_count];
    let mut probed: Vec<Option<(f64, f64)>> = vec![None; k_count];
    for (done, &k) in candidates.iter().enumerate() {
        check_stop(progress)?;
        progress.set_position(done as u64);
        let samples = profile_samples(ctx, sets, k);
        if samples.is_empty() {
            continue;
        }
        let key = key::SELECT_METAL + k as u64;
        let unbiased = |x: &[f64], r: f64| -> Result<f64, FitError> {
            let p = roughness::profile_unbiased(ctx, x, k, r, (&samples, spp, key))?;
            Ok(p.rms_or_loss())
        };
        let current = unbiased(x, x[idx(k, ROUGHNESS)])?;
        let mut at_metal = x.to_vec();
        at_metal[idx(k, METALLIC)] = 1.0;
        let start = metal_start(ctx, &at_metal, k, (&samples, spp, key))?;
        for c in 0..3 {
            at_metal[idx(k, BASE_COLOR + c)] = start[c];
        }
        let mut probe = f64::INFINITY;
        for r in METAL_PROBES {
            probe = probe.min(unbiased(&at_metal, r)?);
        }
        probed[k] = Some((current, probe));
        let margin = roughness::FLAT_PROFILE * roughness::mean_target(&samples);
        if probe > current - margin {
            why[k].push(format!(
                "under the settled light, a metal lobe not searched: at the probes (roughness {:?}, base colour from \
                 {start:.3?}) its profile RMS error is {probe:.4} against {current:.4} for the model on {} pixels \
                 (needs to be lower by {margin:.4}, {:.1} % of their mean radiance)",
                METAL_PROBES,
                samples.len(),
                100.0 * roughness::FLAT_PROFILE
            ));
            continue;
        }
        let (best, evals) = roughness::search_up_to(ctx, &at_metal, k, &samples, spp, key, METAL_ROUGHEST)?;
        tracing::debug!(object = k, ?best, evals = evals.len(), current, "metal search");
        for c in 0..3 {
            xt[idx(k, BASE_COLOR + c)] = best.base_color[c];
        }
        xt[idx(k, ROUGHNESS)] = best.roughness;
        xt[idx(k, METALLIC)] = best.metallic;
        // The dielectric family's best lobe under the same light, at the object's own metallic (below ½).
        dielectric_lobe(ctx, x, k, x[idx(k, METALLIC)], (&samples, spp, key), &mut xd)?;
        tested[k] = true;
    }
    progress.set_position(candidates.len() as u64);
    if tested.iter().any(|&t| t) {
        switch_to_metals(ctx, s, lobe_test, mean_target, x, &tested, &probed, (&xt, &xd), glossy, why, progress)?;
    }
    recheck_metals(ctx, s, sets, lobe_test, mean_target, x, &first_metals, why, progress)?;
    let lobes: Vec<bool> =
        (0..k_count).map(|k| free[k] && !emits[k] && glossy[k] && !layout::is_metal(x[idx(k, METALLIC)])).collect();
    recheck_lobes(ctx, s, sets, lobe_test, mean_target, x, &lobes, glossy, why, progress)
}

/// The dielectric lobes (`lobes`: metallic below ½ when the metal steps end) against the object's best Lambert
/// surface under the settled light (its profile solve at specular 0, metallic 0, on the object's lobe-choosing
/// pixels), on `lobe_test` as the other tests of the second look: the lobe stays where it beats that surface
/// ([`Verdict::passes`]), else the object becomes diffuse with that base colour, at
/// [`layout::START_ROUGHNESS`]. The first look tests every lobe under a light not yet settled: before the
/// emission test has found the lamps no photo sees and before the horizon split, so a lobe can stand in for a
/// room's missing light. On the corpus house the floor, the ceiling, walls and furniture of one room took lobes
/// there, with base colours up to 42 % bright (the diffuse lobe's Fresnel coupling darkens a surface with a
/// lobe), while our renderer with the true, Lambert materials matches the photos of its walls, floor and
/// ceiling within 2 % (docs/optim/design-measurements.md, "Lobes under the settled light"). The lobe is judged
/// by the L1 of one render ([`Statistic::L1`]): let it pass on the squared error as well, as a metal does, the
/// house kept a lobe on a diffuse box (its base colour 0.009 → 0.038 off) and the object stage moved 0.0641 →
/// 0.0643 and 0.0566 → 0.0568 at seeds 1 and 2 ("An unbiased test for metals").
#[allow(clippy::too_many_arguments)]
fn recheck_lobes(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    sets: &PixelSets,
    lobe_test: &[Sample],
    mean_target: f64,
    x: &mut [f64],
    lobes: &[bool],
    glossy: &mut [bool],
    why: &mut [Vec<String>],
    progress: &dyn crate::Progress,
) -> Result<(), FitError> {
    let names = ("model selection: lobe recheck, object", "lobe recheck against Lambert surfaces");
    let keys = (key::SELECT_LAMBERT, key::SELECT_LAMBERT_TEST);
    let (xl, verdicts) = against_alternatives(
        ctx,
        s,
        sets,
        (lobe_test, mean_target),
        x,
        lobes,
        names,
        keys,
        Statistic::L1,
        progress,
        |k, samples, xl| {
            let mut lambert = x.to_vec();
            lambert[idx(k, SPECULAR)] = 0.0;
            lambert[idx(k, METALLIC)] = 0.0;
            let p = roughness::profile_capped(ctx, &lambert, k, layout::START_ROUGHNESS, samples, 0.0)?;
            for c in 0..3 {
                xl[idx(k, BASE_COLOR + c)] = p.base_color[c];
            }
            xl[idx(k, ROUGHNESS)] = layout::START_ROUGHNESS;
            xl[idx(k, SPECULAR)] = 0.0;
            xl[idx(k, METALLIC)] = 0.0;
            Ok(())
        },
    )?;
    let replaced = settle(&verdicts, (x, &xl), mean_target, ("a diffuse surface", "a lobe"), why, |k, x, xl| {
        (
            format!("the dielectric lobe (roughness {:.3}, specular {:.3})", x[idx(k, ROUGHNESS)], x[idx(k, SPECULAR)]),
            format!("the best Lambert surface under the settled light (base colour {:.3?})", layout::base_color(xl, k)),
        )
    });
    for k in replaced {
        glossy[k] = false;
    }
    Ok(())
}

/// The second look's tests of the metal lobes `xt` of the `tested` objects against their models `x` and then
/// against their dielectric lobes `xd`, and the switch of those that pass both.
#[allow(clippy::too_many_arguments)]
fn switch_to_metals(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    lobe_test: &[Sample],
    mean_target: f64,
    x: &mut [f64],
    tested: &[bool],
    probed: &[Option<(f64, f64)>],
    (xt, xd): (&[f64], &[f64]),
    glossy: &mut [bool],
    why: &mut [Vec<String>],
    progress: &dyn crate::Progress,
) -> Result<(), FitError> {
    let s = &metal_test_settings(s);
    let verdicts = sequential_lobe_test(
        ctx,
        s,
        METAL_STATISTIC,
        lobe_test,
        tested,
        (x, xt),
        mean_target,
        key::SELECT_METAL_TEST,
        progress,
        "metal test",
    )?;
    // The metals that beat the current model face the dielectric family's best lobe: the evidence must be for
    // a metal, not for any lobe.
    let beats_current: Vec<bool> = verdicts.iter().map(|v| v.as_ref().is_some_and(|v| v.passes(mean_target))).collect();
    let against_dielectric = if beats_current.iter().any(|&b| b) {
        sequential_lobe_test(
            ctx,
            s,
            METAL_STATISTIC,
            lobe_test,
            &beats_current,
            (xd, xt),
            mean_target,
            key::SELECT_METAL_TEST,
            progress,
            "metal test against the dielectric lobes",
        )?
    } else {
        Vec::new()
    };
    for (k, v) in verdicts.iter().enumerate().filter_map(|(k, v)| v.as_ref().map(|v| (k, v))) {
        let (current, probe) = probed[k].unwrap_or((f64::NAN, f64::NAN));
        let lobe = format!(
            "a metal lobe (roughness {:.3}, base colour {:.3?}; profile RMS error {probe:.4} against {current:.4} at the probes)",
            xt[idx(k, ROUGHNESS)],
            layout::base_color(xt, k),
        );
        if let Some(vd) = against_dielectric.get(k).and_then(Option::as_ref) {
            let against = format!(
                "it lowers the lobe test's {} of the mean radiance on {}, and its {} on {} against the best \
                 dielectric lobe there (roughness {:.3}, specular {:.3})",
                v.figures(mean_target),
                v.on(),
                vd.figures(mean_target),
                vd.on(),
                xd[idx(k, ROUGHNESS)],
                xd[idx(k, SPECULAR)]
            );
            if keeps_metal(v, Some(vd), mean_target) {
                glossy[k] = true;
                layout::copy_material(x, xt, k);
                why[k].push(format!("under the settled light, {lobe} kept: {against}"));
            } else {
                why[k].push(format!(
                    "under the settled light, {lobe} not kept: {against} (needs t > {T_KEEP} and > {:.1} % on either \
                     statistic against both)",
                    100.0 * MIN_GAIN
                ));
            }
        } else {
            why[k].push(format!(
                "under the settled light, {lobe} not kept: it lowers the lobe test's {} on {} (needs t > {T_KEEP} and > \
                 {:.1} % on either statistic)",
                v.figures(mean_target),
                v.on(),
                100.0 * MIN_GAIN
            ));
        }
    }
    Ok(())
}

/// The objects the first look made metal (`first_metals`: metallic ≥ ½ when the second look began) against the
/// dielectric family's best lobe under the settled light (the roughness search of [`roughness::search`] at metallic 0
/// from the first look's mid-range start, on the object's lobe-choosing pixels), on `lobe_test` as the second look
/// tests: the metal stays where it beats that lobe ([`Verdict::passes`] with [`METAL_STATISTIC`]), else the dielectric
/// lobe (its profile solve's base colour, roughness and specular, metallic 0) replaces it (a replacing lobe whose
/// specular strength is 0 is exactly Lambert, and model selection's last step makes such an object diffuse). The burden
/// of proof is the second look's: a metal is a departure from the dielectric that most surfaces are, and the evidence
/// must be for a metal, not for any lobe. The first look decides between the families on its training pixels, under a
/// light not yet settled, and a rough metal lobe (roughness ≥ 0.6) lights its pixels nearly as a diffuse or dielectric
/// surface does with another base colour: on the house such lobes took diffuse and glossy objects
/// (docs/scale/README.md, "Where the error is"). Each decision is added to `why`.
#[allow(clippy::too_many_arguments)]
fn recheck_metals(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    sets: &PixelSets,
    lobe_test: &[Sample],
    mean_target: f64,
    x: &mut [f64],
    first_metals: &[bool],
    why: &mut [Vec<String>],
    progress: &dyn crate::Progress,
) -> Result<(), FitError> {
    let names = ("model selection: metal recheck, object", "metal recheck against the dielectric lobes");
    // The stream of the second look's probes of object k, which a metal object does not use.
    let keys = (key::SELECT_METAL, key::SELECT_METAL_TEST);
    let (xd, verdicts) = against_alternatives(
        ctx,
        &metal_test_settings(s),
        sets,
        (lobe_test, mean_target),
        x,
        first_metals,
        names,
        keys,
        METAL_STATISTIC,
        progress,
        |k, samples, xd| dielectric_lobe(ctx, x, k, 0.0, samples, xd),
    )?;
    settle(&verdicts, (x, &xd), mean_target, ("the dielectric lobe", "a metal"), why, |k, x, xd| {
        (
            format!(
                "the first look's metal lobe (metallic {:.3}, roughness {:.3})",
                x[idx(k, METALLIC)],
                x[idx(k, ROUGHNESS)]
            ),
            format!(
                "the best dielectric lobe under the settled light (roughness {:.3}, specular {:.3}, base colour {:.3?})",
                xd[idx(k, ROUGHNESS)],
                xd[idx(k, SPECULAR)],
                layout::base_color(xd, k)
            ),
        )
    });
    Ok(())
}

/// The rechecks' common part: for every object of `candidates` with lobe-choosing pixels, `alternative(k, (samples,
/// spp, key), xa)` writes object k's alternative material into `xa` (a copy of `x`; its random numbers at `keys.0 +
/// k`), and one sequential paired test on `lobe_test` weighs `x` against those alternatives (renders at `keys.1`,
/// common random numbers, compared by `statistic`). Returns `xa` and the verdicts (positive: `x` better), `None` where
/// an object was not tested. `names`: the progress phase and the test's name.
#[allow(clippy::too_many_arguments)]
fn against_alternatives(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    sets: &PixelSets,
    (lobe_test, mean_target): (&[Sample], f64),
    x: &[f64],
    candidates: &[bool],
    (phase, test_name): (&str, &str),
    (alternative_key, test_key): (u64, u64),
    statistic: Statistic,
    progress: &dyn crate::Progress,
    mut alternative: impl FnMut(usize, (&[Sample], u32, u64), &mut [f64]) -> Result<(), FitError>,
) -> Result<(Vec<f64>, Vec<Option<Verdict>>), FitError> {
    let objects: Vec<usize> = (0..candidates.len()).filter(|&k| candidates[k]).collect();
    progress.phase(phase, objects.len() as u64, 0);
    let spp = roughness::profile_spp(s.solve_spp);
    let mut xa = x.to_vec();
    let mut tested = vec![false; candidates.len()];
    for (done, &k) in objects.iter().enumerate() {
        check_stop(progress)?;
        progress.set_position(done as u64);
        let samples = profile_samples(ctx, sets, k);
        if samples.is_empty() {
            continue;
        }
        alternative(k, (&samples, spp, alternative_key + k as u64), &mut xa)?;
        tested[k] = true;
    }
    progress.set_position(objects.len() as u64);
    if !tested.iter().any(|&t| t) {
        return Ok((xa, (0..candidates.len()).map(|_| None).collect()));
    }
    let verdicts = sequential_lobe_test(
        ctx,
        s,
        statistic,
        lobe_test,
        &tested,
        (&xa, x),
        mean_target,
        test_key,
        progress,
        test_name,
    )?;
    Ok((xa, verdicts))
}

/// The rechecks' verdicts (from [`against_alternatives`]) applied: where the model `x` beats its alternative
/// `xa` ([`Verdict::passes`]) it stays, else `xa`'s material replaces it. `describe(k, x, xa)` names object k's
/// model and its alternative; each decision, with the test's figures, is added to `why` (a replaced model as
/// "replaced by `replaced_by`", and "`needs` needs" the thresholds). Returns the replaced objects.
fn settle(
    verdicts: &[Option<Verdict>],
    (x, xa): (&mut [f64], &[f64]),
    mean_target: f64,
    (replaced_by, needs): (&str, &str),
    why: &mut [Vec<String>],
    describe: impl Fn(usize, &[f64], &[f64]) -> (String, String),
) -> Vec<usize> {
    let mut replaced = Vec::new();
    for (k, v) in verdicts.iter().enumerate().filter_map(|(k, v)| v.as_ref().map(|v| (k, v))) {
        let (model, alternative) = describe(k, x, xa);
        let against = format!(
            "against {alternative} it lowers the lobe test's {} of the mean radiance on {}",
            v.figures(mean_target),
            v.on(),
        );
        if v.passes(mean_target) {
            why[k].push(format!("{model} kept: {against}"));
        } else {
            layout::copy_material(x, xa, k);
            replaced.push(k);
            why[k].push(format!(
                "{model} replaced by {replaced_by}: {against} ({needs} needs t > {T_KEEP} and > {:.1} %)",
                100.0 * MIN_GAIN
            ));
        }
    }
    replaced
}

/// The dielectric family's best lobe of object `k` under the light of `x`: the roughness search of
/// [`roughness::search`] at `metallic`, from the first look's mid-range start (roughness [`TRIAL_ROUGHNESS`],
/// specular [`TRIAL_SPECULAR`]), on the object's lobe-choosing `samples`; its base colour, roughness, specular
/// and `metallic` are written into `xd`.
fn dielectric_lobe(
    ctx: &Ctx<'_>,
    x: &[f64],
    k: usize,
    metallic: f64,
    (samples, spp, key): (&[Sample], u32, u64),
    xd: &mut [f64],
) -> Result<(), FitError> {
    let mut at_dielectric = x.to_vec();
    at_dielectric[idx(k, METALLIC)] = metallic;
    at_dielectric[idx(k, SPECULAR)] = TRIAL_SPECULAR;
    at_dielectric[idx(k, ROUGHNESS)] = TRIAL_ROUGHNESS;
    let (d, _) = roughness::search(ctx, &at_dielectric, k, samples, spp, key)?;
    for c in 0..3 {
        xd[idx(k, BASE_COLOR + c)] = d.base_color[c];
    }
    xd[idx(k, ROUGHNESS)] = d.roughness;
    xd[idx(k, SPECULAR)] = d.specular;
    xd[idx(k, METALLIC)] = metallic;
    Ok(())
}

/// `s` with the metal tests' held-out paths ([`METAL_TEST_PATHS`] × `holdout_spp`).
fn metal_test_settings(s: &ObjectFitSettings) -> ObjectFitSettings {
    ObjectFitSettings { holdout_spp: s.holdout_spp.saturating_mul(METAL_TEST_PATHS), ..s.clone() }
}

/// Whether the second look keeps a metal lobe: it beats the object's model, and then (tested only where it
/// does) the dielectric family's best lobe, each by [`Verdict::passes`].
fn keeps_metal(against_model: &Verdict, against_dielectric: Option<&Verdict>, mean_target: f64) -> bool {
    against_model.passes(mean_target) && against_dielectric.is_some_and(|v| v.passes(mean_target))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::paired::Stop;

    /// Paired differences of mean `gain` with an alternating spread of ±0.01 (t ≈ gain / 0.01 · √n).
    fn verdict(gain: f64, n: usize, stopped: Option<Stop>) -> Verdict {
        let d = (0..n).map(|i| gain + if i % 2 == 0 { 0.01 } else { -0.01 }).collect();
        Verdict { d, squared: None, n_full: 2048, stopped }
    }

    #[test]
    fn a_metal_is_kept_only_where_it_beats_both_the_model_and_the_dielectric_lobe() {
        let mean = 1.0;
        let clear = verdict(0.05, 2048, None);
        // Better than the model, and than the dielectric lobe: kept.
        assert!(keeps_metal(&clear, Some(&verdict(0.02, 2048, None)), mean));
        // Better than the model, but the dielectric lobe explains the pixels as well (a floor that asks for a
        // lobe, not for a metal): refused.
        assert!(!keeps_metal(&clear, Some(&verdict(0.0, 2048, None)), mean));
        assert!(!keeps_metal(&clear, Some(&verdict(-0.03, 256, Some(Stop::CannotPass))), mean));
        // A gain over the dielectric that is significant but under MIN_GAIN of the pixels' mean: refused.
        assert!(!keeps_metal(&clear, Some(&verdict(0.004, 2048, None)), mean));
        // Not better than the model: refused, whatever the dielectric comparison says (it is then not run).
        assert!(!keeps_metal(&verdict(0.0, 2048, None), Some(&clear), mean));
        assert!(!keeps_metal(&verdict(0.05, 256, Some(Stop::CannotPass)), None, mean));
        // A metal that beat its model but was never compared with the dielectric lobe is not kept.
        assert!(!keeps_metal(&clear, None, mean));
    }
}
