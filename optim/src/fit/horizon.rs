//! Emitters split at the horizon: the last decision of model selection. An emitter that faces sideways — a
//! window pane above all — may send one radiance down and level (the sky's half: light that came from above
//! the horizon outside) and another up (the ground's half), as [`tracer::params::Horizon`] renders it.
//!
//! A uniform pane sends the sky's light everywhere: the ceiling gets the light that in truth falls on the
//! floor, so the fit darkens the ceiling and brightens the floor to match the photos. Under Daylight Room's
//! sky, rendered by Mitsuba with its panes replaced by uniform emitters of the right flux, the ceiling
//! receives 1.36–1.93× its true light and the floor 0.80–0.95×; with the two halves each of the right flux,
//! every surface is within 0.95–1.09× (docs/realistic/README.md, "Window panes: one radiance or two").
//!
//! The step, after the emission test:
//! 1. **Up** is the cameras' mean up axis ([`world_up`]): photos are taken upright, tilted up and down
//!    about as often, so the mean points up whatever the scan's own axes.
//! 2. **Candidates** are the kept emitters with at least [`MIN_SIDE`] of their cosine-weighted emission on
//!    each side of the horizon (`tracer::HorizonGeometry::upward`; a ceiling panel sends all of it down and has
//!    nothing to split) that the photos see from both sides of it: each half is fitted where it is seen.
//! 3. **Fit** (by model selection, `super::select`): every candidate split, its sky half graded from the
//!    horizon to the zenith (`tracer::params::Horizon`; the photos see a window's sky within about 20° of the
//!    horizon, brighter and whiter there than the sky that lights the floor), its ground half and its zenith
//!    starting at its emission (at the halves its emission test fitted where that test kept the emission only
//!    split), emission and base colour are re-fitted together, as after a dropped emission (the albedos
//!    were fitted under the uniform emitters' light; with them fixed, a sideways lamp's upward half took the
//!    light the ceiling's too-dark albedo missed, 1.7× its truth on `data-fixtures/scenes/window.toml`).
//! 4. **Test**, per candidate: the solved model with every candidate split against the same model with this
//!    candidate joined again (one radiance of the same flux), rendered with the same random numbers on the
//!    test pixels its light reaches (at most `object.holdout_pixels`): it keeps its split when the paired t of
//!    its pixels' L1 gain exceeds the lobe test's threshold and the gain its minimum share of their mean
//!    radiance. A lamp whose light is the same up and down gains nothing and keeps one radiance. A kept
//!    split's gradient is tested the same way on the same pixels, against its sky made flat (one sky
//!    radiance of the same flux), and kept on the same terms.
//! 5. A candidate not kept is **joined** again, into the one radiance of the same flux as its halves, and a
//!    kept split whose gradient is not kept has its sky made **flat**; the re-fit's albedos stay (the light the
//!    photos show did not change by a significant amount).

use super::jacobian::Ctx;
use super::layout::{self, EMISSION, EMISSION_GROUND, EMISSION_ZENITH, Split};
use super::linear::paired_t;
use super::paired::{MIN_GAIN, T_KEEP, l1, paired_renders, target};
use super::pixels::{PixelSets, Sample};
use super::{FitError, ObjectFitSettings};
use crate::progress::check_stop;
use crate::streams::{self, draw, key};
use glam::Vec3;
use tracer::PixelRef;

/// Share of an emitter's cosine-weighted emission that must leave on each side of the horizon for it to be
/// split: below 5 % one half lights almost nothing the photos see (its column is mostly noise). A ceiling panel
/// (share 0) is never a candidate, nor one tilted by less than 26° from horizontal (share (1 − cos 26°)/2 ≈
/// 0.05 on its far side); a vertical pane has 0.5 on each side.
pub const MIN_SIDE: f64 = 0.05;

/// The cameras' mean up axis (camera +y in world), normalised; None when the cameras give none (their up
/// axes cancel).
#[must_use]
pub fn world_up(cameras: &[tracer::Camera]) -> Option<Vec3> {
    let sum =
        cameras.iter().fold(glam::DVec3::ZERO, |acc, c| acc + Vec3::from(c.cam_to_world.matrix3.y_axis).as_dvec3());
    // 1e-6 of the camera count: far below any real set of upright photos (whose sum is of the order of their
    // count), where a sum that small is round-off of axes that cancel.
    (sum.length() > 1e-6 * cameras.len() as f64).then(|| sum.normalize().as_vec3())
}

/// The up axis a split uses: the cameras' ([`world_up`]), under the uniform emission profile only (the
/// halves' shares of an emitter's flux are those of a uniform emitter; the cosine profile weighs directions
/// otherwise).
fn split_up(ctx: &Ctx<'_>) -> Option<Vec3> {
    let uniform = ctx.settings.emission_profile == tracer::EmissionProfile::Uniform;
    world_up(ctx.cameras).filter(|_| uniform)
}

/// Per object: whether it would be a candidate if it emitted (its emission reaches both sides of the horizon,
/// [`MIN_SIDE`]); all false without an up axis ([`split_up`]). Model selection keeps the test rows of these
/// objects' light only.
#[must_use]
pub(super) fn sided(ctx: &Ctx<'_>) -> Vec<bool> {
    let Some(up) = split_up(ctx) else {
        return vec![false; ctx.scene.emitter_slots()];
    };
    let share = ctx.scene.horizon_geometry(up).upward;
    (0..share.len()).map(|k| is_candidate(&share, k)).collect()
}

/// Whether object k sends at least [`MIN_SIDE`] of its emission to each side of the horizon.
fn is_candidate(share: &[f64], k: usize) -> bool {
    share.get(k).is_some_and(|u| (MIN_SIDE..=1.0 - MIN_SIDE).contains(u))
}

/// Step 2 of the module docs: every kept emitter (`emits`) that may be split (`splittable`, from
/// [`splittable`] over every emitter the emission test started from: it sends enough of its emission to each
/// side of the horizon and the training photos see it from each side) and whose light reaches at least two test
/// rows (`lit[k]`), split, with its ground half set in `x` to its emission (the split model starts where the
/// uniform one is). None when the cameras give no up axis or no emitter qualifies.
pub(super) fn candidates(splittable: &Split, lit: &[Vec<usize>], x: &mut [f64], emits: &[bool]) -> Split {
    let split: Vec<bool> =
        (0..emits.len()).map(|k| emits[k] && splittable.of(k) && lit.get(k).is_some_and(|l| l.len() >= 2)).collect();
    for k in (0..emits.len()).filter(|&k| split[k]) {
        let own = layout::rgb(x, k, EMISSION);
        layout::set_rgb(x, k, EMISSION_GROUND, own);
        layout::set_rgb(x, k, EMISSION_ZENITH, own);
    }
    Split { up: splittable.up, gradient: split.clone(), split }
}

/// Per object with `wanted[k]`: whether it may be split — it sends at least [`MIN_SIDE`] of its emission to
/// each side of the horizon and the training pixels see it from each side ([`seen_from_each_side`]) — with the
/// up axis; none (and up zero) when the cameras give no up axis. The emission test asks this of every emitter
/// before it tests them; the candidates ([`candidates`]) are the kept ones among them.
pub(super) fn splittable(ctx: &Ctx<'_>, sets: &PixelSets, wanted: &[bool]) -> Split {
    let k_count = wanted.len();
    let Some(up) = split_up(ctx) else {
        return Split::flat(Vec3::ZERO, vec![false; k_count]);
    };
    let share = ctx.scene.horizon_geometry(up).upward;
    let wanted: Vec<bool> = (0..k_count).map(|k| wanted[k] && is_candidate(&share, k)).collect();
    let seen = seen_from_each_side(ctx, sets, up, &wanted);
    Split::flat(up, (0..k_count).map(|k| wanted[k] && seen[k]).collect())
}

/// Per object with `wanted[k]`: whether the training pixels see it from above its horizon (the ground half's
/// directions, ω·up > 0 from the surface to the camera) and from below it, in at least
/// [`super::solve::MIN_PIXELS`] pixels each — the threshold under which an object's material counts as
/// unconstrained. A half no photo sees is left to the light it sends alone, and in the re-fit such a half ran
/// away: on Modern Hall a lamp seen in 3 pixels took a sky half of 1393 / 32 / 1.4 for a truth of 1.5.
fn seen_from_each_side(ctx: &Ctx<'_>, sets: &PixelSets, up: Vec3, wanted: &[bool]) -> Vec<bool> {
    let mut sides = vec![[0usize; 2]; wanted.len()];
    for t in &sets.train {
        let Some(k) = t.object.map(|o| o as usize).filter(|&k| wanted.get(k).copied().unwrap_or(false)) else {
            continue;
        };
        let camera = &ctx.cameras[t.pixel.view as usize];
        let (_, dir) = camera.ray(glam::Vec2::new(t.pixel.x as f32, t.pixel.y as f32));
        // The direction from the surface to the camera is −dir.
        sides[k][usize::from(-dir.dot(up) > 0.0)] += 1;
    }
    sides.iter().map(|s| s.iter().all(|&n| n >= super::solve::MIN_PIXELS)).collect()
}

/// Step 4 of the module docs on `x`, fitted with every candidate of `all` split, its sky graded (`ctx` carries
/// that split), testing on `test` (the held-out pixels, or capped training pixels when there are none:
/// `test_name` says which) of which `lit[k]` are the rows that candidate k's light reaches. Returns the kept
/// splits and, among them, the kept gradients; every candidate not kept is joined again in `x` (one radiance of
/// the same flux), every kept split without its gradient has its sky made flat (one sky radiance of the same
/// flux), and each candidate's reasons are added to `why`.
pub(super) fn test(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    (test, test_name): (&[Sample], &str),
    lit: &[Vec<usize>],
    x: &mut [f64],
    why: &mut [Vec<String>],
    progress: &dyn crate::Progress,
) -> Result<Split, FitError> {
    let all = ctx.split;
    let (up, k_count) = (all.up, all.split.len());
    let tracer::HorizonGeometry { upward: share, sky } = ctx.scene.horizon_geometry(up);
    let candidates: Vec<usize> = (0..k_count).filter(|&k| all.of(k)).collect();
    let x_all = x.to_vec();

    // Each candidate's test rows: at most `holdout_pixels` of those its light reaches, in a seeded order. On
    // them the model with every candidate split is rendered against the same model with this candidate alone
    // joined again (one radiance of the same flux as its two halves): the difference is its own split's, given
    // the others'. (With no split in the other arm, a sideways lamp would be credited with the windows' gain on
    // the rows it shares with them; with only its own split in one arm, a window's gain would be masked by the
    // others' light fitted without theirs.) A kept split's gradient is tested the same way, on the same rows,
    // against its sky made flat.
    let budget = s.holdout_pixels as usize;
    let rank = |j: usize| streams::uniform(ctx.seed, draw::HORIZON_TEST_ORDER, streams::pixel_key(test[j].pixel), 0);
    let split_all = ctx.params(&x_all);
    let mut kept = Split { up, split: vec![false; k_count], gradient: vec![false; k_count] };
    let others =
        |v: &[bool], k: usize| -> Vec<bool> { (0..k_count).map(|o| o != k && v.get(o) == Some(&true)).collect() };
    for (n, &k) in candidates.iter().enumerate() {
        check_stop(progress)?;
        let mut rows = lit[k].clone();
        rows.sort_by(|&a, &b| rank(a).total_cmp(&rank(b)).then(a.cmp(&b)));
        rows.truncate(budget);
        let pix: Vec<PixelRef> = rows.iter().map(|&j| test[j].pixel).collect();
        // The relative L1 gain and paired t of the model with every kept split graded over `other`, the renders
        // shown in the progress as the `which` test of this emitter.
        let gain_over = |other: &tracer::Params, key: u64, which: &str| -> Result<(f64, f64), FitError> {
            let label = format!(
                "model selection: {which}, emitter {}/{} ({} pixels), block",
                n + 1,
                candidates.len(),
                pix.len()
            );
            let (a, b) = paired_renders(ctx, (other, &split_all), &pix, s.holdout_spp, key, progress, &label)?;
            let d: Vec<f64> = rows
                .iter()
                .enumerate()
                .map(|(i, &j)| {
                    let t = target(&test[j]);
                    l1(t, a[i].as_dvec3().to_array()) - l1(t, b[i].as_dvec3().to_array())
                })
                .collect();
            let (gain, t) = paired_t(&d);
            let mean = rows.iter().map(|&j| l1(target(&test[j]), [0.0; 3])).sum::<f64>() / rows.len() as f64;
            Ok((gain / mean.max(f64::MIN_POSITIVE), t))
        };
        let mut x_k = x_all.clone();
        join(&mut x_k, k, share[k], all.graded(k).then_some(sky[k]));
        let but_k = Split { up, split: others(&all.split, k), gradient: others(&all.gradient, k) };
        let (rel, t) = gain_over(&but_k.params(&x_k), key::SELECT_HORIZON_TEST, "horizon test")?;
        let half = |at: usize| layout::rgb(&x_all, k, at);
        let fitted = format!(
            "split at the horizon ({:.0} % of its emission upward), the sky half {:.4?} at the horizon and {:.4?} at \
             the zenith, the ground half {:.4?}",
            100.0 * share[k],
            half(EMISSION),
            half(EMISSION_ZENITH),
            half(EMISSION_GROUND)
        );
        if !(t > T_KEEP && rel > MIN_GAIN) {
            why[k].push(format!(
                "one emission in every direction: {fitted} changes the {test_name} L1 of {} pixels its light \
                 reaches by {:+.3} % (t = {t:.1}; needs t > {T_KEEP} and > {:.1} %)",
                rows.len(),
                -100.0 * rel,
                100.0 * MIN_GAIN
            ));
            continue;
        }
        kept.split[k] = true;
        why[k].push(format!(
            "emission {fitted}: the split lowers the {test_name} L1 of {} pixels its light reaches by {:.2} % of \
             their mean radiance (t = {t:.1})",
            rows.len(),
            100.0 * rel
        ));
        if !all.graded(k) {
            continue;
        }
        let mut x_f = x_all.clone();
        flatten(&mut x_f, k, sky[k]);
        let flat_k = Split { gradient: others(&all.gradient, k), ..all.clone() };
        let (rel, t) = gain_over(&flat_k.params(&x_f), key::SELECT_SKY_TEST, "sky gradient test")?;
        if t > T_KEEP && rel > MIN_GAIN {
            kept.gradient[k] = true;
            why[k].push(format!(
                "its sky varies with elevation: against one sky radiance of the same flux the gradient lowers the \
                 {test_name} L1 of the same pixels by {:.2} % of their mean radiance (t = {t:.1})",
                100.0 * rel
            ));
        } else {
            why[k].push(format!(
                "one sky radiance: the sky's gradient changes the {test_name} L1 of the same pixels by {:+.3} % \
                 (t = {t:.1}; needs t > {T_KEEP} and > {:.1} %)",
                -100.0 * rel,
                100.0 * MIN_GAIN
            ));
        }
    }
    for &k in &candidates {
        if !kept.of(k) {
            join(x, k, share[k], all.graded(k).then_some(sky[k]));
        } else if all.graded(k) && !kept.graded(k) {
            flatten(x, k, sky[k]);
        }
    }
    Ok(kept)
}

/// Object k's sky half made flat: its horizon and zenith radiances (`EMISSION`, `EMISSION_ZENITH`) replaced by
/// the one sky radiance of the same flux ([`tracer::params::flat_sky`], m the mean elevation sine of its sky,
/// `tracer::HorizonGeometry::sky`), its zenith entries cleared.
fn flatten(x: &mut [f64], k: usize, m: f64) {
    let v = |at: usize| glam::DVec3::from(layout::rgb(x, k, at));
    let flat = tracer::params::flat_sky(v(EMISSION), v(EMISSION_ZENITH), m);
    layout::set_rgb(x, k, EMISSION, flat.to_array());
    layout::set_rgb(x, k, EMISSION_ZENITH, [0.0; 3]);
}

/// Object k's emission joined from its two halves into the one radiance of the same flux
/// ([`tracer::params::joined_halves`], u its upward share; its sky made flat first when `graded`,
/// [`flatten`] with m), its ground and zenith entries cleared.
fn join(x: &mut [f64], k: usize, u: f64, graded: Option<f64>) {
    if let Some(m) = graded {
        flatten(x, k, m);
    }
    let half = |at: usize| glam::DVec3::from(layout::rgb(x, k, at));
    let joined = tracer::params::joined_halves(half(EMISSION), half(EMISSION_GROUND), u);
    layout::set_rgb(x, k, EMISSION, joined.to_array());
    layout::set_rgb(x, k, EMISSION_GROUND, [0.0; 3]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::layout::idx;

    #[test]
    fn the_cameras_mean_up_is_world_up_and_cancelling_axes_give_none() {
        let cam = |up: Vec3| {
            let fwd = if up.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
            let right = fwd.cross(up).normalize();
            let m = glam::Mat3::from_cols(right, up, -fwd);
            tracer::Camera::from_fov_y(4, 4, 1.0, glam::Affine3A::from_mat3(m))
        };
        // Tilted up and down by 30° about the horizontal: the mean is +z.
        let (a, b) = (30f32.to_radians().sin(), 30f32.to_radians().cos());
        let up = world_up(&[cam(Vec3::new(0.0, a, b)), cam(Vec3::new(0.0, -a, b))]).expect("an up axis");
        assert!((up - Vec3::Z).length() < 1e-6, "{up}");
        assert_eq!(world_up(&[cam(Vec3::Z), cam(-Vec3::Z)]), None);
        assert_eq!(world_up(&[]), None);
    }

    #[test]
    fn a_split_appends_one_ground_entry_per_split_object() {
        let mut x = super::super::layout::initial(3);
        for c in 0..3 {
            x[idx(1, EMISSION_GROUND + c)] = 1.0 + c as f64;
        }
        let split = Split::flat(Vec3::Z, vec![false, true, false]);
        let p = split.params(&x);
        assert_eq!(p.emission.len(), 4);
        assert_eq!(p.emission[3], Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(p.horizon.ground, vec![None, Some(3), None]);
        assert_eq!(Split::default().params(&x), super::super::layout::to_params(&x));
        let share = [0.5, 0.0, 0.04, 0.96, 0.05];
        let candidates: Vec<bool> = (0..share.len()).map(|k| is_candidate(&share, k)).collect();
        assert_eq!(candidates, [true, false, false, false, true]);
    }

    #[test]
    fn a_graded_split_appends_its_zenith_after_the_ground_halves_and_flattens_to_the_same_flux() {
        let mut x = super::super::layout::initial(3);
        let (h, g, z) = ([2.0, 2.2, 2.6], [0.5, 0.5, 0.4], [0.9, 1.3, 2.6]);
        for k in 1..3 {
            for c in 0..3 {
                (x[idx(k, EMISSION + c)], x[idx(k, EMISSION_GROUND + c)]) = (h[c], g[c]);
                x[idx(k, EMISSION_ZENITH + c)] = z[c];
            }
        }
        let split = Split { up: Vec3::Z, split: vec![false, true, true], gradient: vec![true, false, true] };
        let p = split.params(&x);
        // Objects 1 and 2 split (grounds 3, 4); only object 2 graded (object 0's flag is not read unsplit).
        assert_eq!(p.horizon.ground, vec![None, Some(3), Some(4)]);
        assert_eq!(p.horizon.zenith, vec![None, None, Some(5)]);
        assert_eq!(p.emission[5], Vec3::new(0.9, 1.3, 2.6));
        // Joined, the graded and the flat object keep the flux of their halves: through a vertical pane the sky
        // half carries a sky of mean elevation sine 4/(3π).
        let m = 4.0 / (3.0 * std::f64::consts::PI);
        let (mut flat, mut graded) = (x.clone(), x.clone());
        join(&mut flat, 1, 0.5, None);
        join(&mut graded, 2, 0.5, Some(m));
        for c in 0..3 {
            let sky = (1.0 - m) * h[c] + m * z[c];
            assert!((graded[idx(2, EMISSION + c)] - (0.5 * sky + 0.5 * g[c])).abs() < 1e-12);
            assert!((flat[idx(1, EMISSION + c)] - (0.5 * h[c] + 0.5 * g[c])).abs() < 1e-12);
            assert_eq!((graded[idx(2, EMISSION_GROUND + c)], graded[idx(2, EMISSION_ZENITH + c)]), (0.0, 0.0));
        }
        // Made flat only, it keeps its ground half and its sky's flux.
        flatten(&mut x, 2, m);
        for c in 0..3 {
            assert!((x[idx(2, EMISSION + c)] - ((1.0 - m) * h[c] + m * z[c])).abs() < 1e-12);
            assert_eq!((x[idx(2, EMISSION_GROUND + c)], x[idx(2, EMISSION_ZENITH + c)]), (g[c], 0.0));
        }
    }
}
