//! The lobe family look on the per-triangle scene: after the final round's light re-solve, every non-emitting
//! object is tried in the other lobe family (a dielectric as a metal, a metal as a Lambert surface) and switched
//! where held-out pixels prefer it.
//!
//! The object stage decides each object's family with one colour per object for every object of the room: a
//! metal mirrors its neighbours, and where their constants are off (a textured floor fitted by one colour, a
//! lamp fitted a few percent dim) the metal fits its pixels worse than a dielectric that absorbs the misfit, and
//! stays dielectric. The per-triangle stage resolves the neighbours by place, so the question is asked again
//! here (measured on the corpus house: with the true metallic put in between the stages the per-triangle summary
//! goes 0.0272 → 0.0221; docs/optim/design-measurements.md, "What the lobe families leave").
//!
//! - **Pixels**: the object's pixels among the round's (those whose centre ray hits it), in a random order keyed
//!   by the pixel and the round, at most `triangle.family_pixels` of them (the budget that bounds the look's
//!   cost by the objects, not by the photos); the first half of them, at most [`FIT_PIXELS`], fit, the rest
//!   test. An object with fewer than [`MIN_HALF`] pixels in either part is not looked at.
//! - **Fits**: the object's own family (its area-mean material) and the other family — for an area-mean
//!   metallic below ½ a metal (metallic 1) at each roughness of [`METAL_PROBES`], for a metal a Lambert surface
//!   (metallic 0, specular 0), for a blend ([`is_blend`]: metallic strictly between 0 and 1) the pure family it
//!   nearly is ([`blend_family_is_metal`]): the metals at the probes, or its dielectric part (metallic 0, its
//!   specular and roughness kept) — each fitted the same way, with **one colour for the object**: its triangles
//!   start at the object's area-mean base colour and take [`FAMILY_STEPS`] ratio steps of one factor per
//!   channel ([`super::ratio::ratio_steps`] with [`Update::OneFactor`]) on the fit pixels, every other
//!   triangle held. Of the alternatives, the one of lowest loss at its last step is tested.
//! - **Test**: on the test pixels the two fits are rendered twice each at half of
//!   [`METAL_TEST_PATHS`](crate::fit::paired::METAL_TEST_PATHS) × `object.holdout_spp` paths with common
//!   random numbers, and the other family is kept where it fits better on the L1 of the two renders' mean or on
//!   their unbiased squared error, with t > [`T_KEEP`](crate::fit::paired::T_KEEP) and a gain above
//!   [`MIN_GAIN`](crate::fit::paired::MIN_GAIN) of the pixels' mean radiance: the object stage's metal test
//!   ([`crate::fit::paired`]), in its sequential looks (256, 512, … of the test pixels, stopped once the test
//!   cannot pass or clearly passes). An alternative to a pure family whose colour its steps took to white in
//!   every channel, the top of the domain, is not kept ([`clamped_white`]).
//! - **A dielectric becomes a metal only where both statistics say so**: besides the pass, the squared error
//!   must show the metal's gain at t > [`T_CONFIRM`](crate::fit::paired::T_CONFIRM) (one-sided 5 %). A rough
//!   metal fits the bulk of a diffuse object's pixels better where the room's light is off and the rest worse,
//!   which the L1 rewards and the squared error does not: over 31 runs of the corpus house, 17 of the look's 20
//!   switches of diffuse objects to metals passed on the L1 with the squared error at t = −2.8 to +0.3 (room 9's
//!   `box-9-2`, `box-9-6` and `cabinet-9-0`, each at the roughest probe), and its 25 switches of true metals had
//!   t = 2.6 to 7.0 there (docs/optim/design-measurements.md, "A metal confirmed by the squared error").
//!   The other switches (a metal to a Lambert surface, a blend to the family it nearly is) are as above: a
//!   metal's way back to the dielectric most surfaces are needs no more than a pass.
//! - **Blends carry the burden**: a blend is the richer model (one more parameter than either family), which the
//!   object stage keeps only where it pays; here it stays only where it passes the same test against the pure
//!   family it nearly is (the roles swapped), and otherwise that family replaces it. On the corpus house 5 of 6 blends
//!   were true metals or a plastic, each fitted with part of the other lobe absorbing its neighbours' misfit;
//!   with the burden on the blend all 5 took their true family (the house's summary 0.0220 → 0.0204) and the
//!   sixth, which fits better as a blend (t = 4.9), stayed (docs/optim/design-measurements.md, "Blends looked
//!   at on the per-triangle scene").
//! - **Why both fitted alike, with one colour**: a metal is told from a diffuse surface by how its radiance
//!   varies over the object (a reflection of the room), and a panorama's views see a point from one place, so
//!   a colour per triangle reproduces a metal's reflection as a texture. Against the per-triangle model as the
//!   stage fitted it (which has also seen the test pixels), the metal-lamp fixture's metal box, put in as a
//!   Lambert surface, passed at t = 3.3 on its squared error and 0.7 on its L1; against its own family refitted
//!   per triangle on the fit pixels at t = 9.7 and 7.2, and on the corpus house the true metals did not pass
//!   at all (`box-0-3` t = 1.2 and 0.6, `box-4-3` 0.8 and 0.0); with one colour for both, the box passes at
//!   t = 20 and 25 (`pipeline/tests/triangle_family.rs`; docs/optim/design-measurements.md, "The lobe family
//!   look on the per-triangle scene"). The neighbours keep their per-triangle values, which is what the look
//!   adds to the object stage's decision.
//! - **After**: every object decided against the same per-triangle model, the alternatives kept replace their
//!   objects' triangles together, and `light_fit_steps` ratio steps of the switched objects' triangles on
//!   their pixels (every other triangle held) let their colours follow per triangle, a texture where their
//!   pixels show one. The rest of the scene was fitted with them in it and moves only by the light they send
//!   it: on the corpus house a pass over all the round's pixels instead took the per-triangle summary to
//!   0.0230 rather than 0.0240, at a cost of 9 of the 1280×1024 house's 49 minutes, and that gain (the
//!   walls' 0.255 → 0.216) was the stage's ratio steps taken further, not the switches (`light_fit_steps`
//!   sets those; docs/optim/design-measurements.md, "The lobe family look on the per-triangle scene").

use glam::Vec3;

use super::pixels::TriSample;
use super::ratio::{self, StepPlan, Update};
use super::{RoundInputs, TriangleError, TriangleState};
use crate::fit::paired::{self, Statistic, Verdict};
use crate::fit::{layout, roughness};
use crate::progress::{Muted, check_stop};
use crate::streams::{self, draw, key};

/// Roughness of the metal alternatives (0.22, 0.33 and 0.45), the middle points of the object stage's grid
/// ([`roughness::GRID`]), where its metal probes look: a polished or brushed metal's reflection of the room is
/// sharp enough there to tell it from a diffuse surface, and rougher metals light their pixels nearly as a
/// diffuse surface of the same colour does (the object stage's walls preferred a metal at 0.62 and above,
/// absorbing what the light got wrong).
pub const METAL_PROBES: [f32; 3] = [roughness::GRID[2] as f32, roughness::GRID[3] as f32, roughness::GRID[4] as f32];

/// Ratio steps of each family's fit on its pixels: the object's one colour settles in one or two (its render is
/// nearly linear in its base colour), the third takes up what its light on itself moved.
pub const FAMILY_STEPS: u32 = 3;

/// Fewest pixels in each part (fit, test) of an object for it to be looked at: the paired test's t rests on
/// the scatter of its differences, which fewer pixels estimate too poorly for the t > 3 threshold to hold its
/// level.
pub const MIN_HALF: usize = 32;

/// Most pixels an object's fits use: one colour per family (3 parameters) is known to well under a percent
/// from a few hundred pixels, and the rest of the budget goes to the test, whose power the switches need.
pub const FIT_PIXELS: usize = 512;

/// How many of an object's `n` rows (in the look's order) fit; the rest test. Half of them up to
/// [`FIT_PIXELS`].
#[must_use]
pub fn fit_rows(n: usize) -> usize {
    (n / 2).min(FIT_PIXELS)
}

/// Whether an object's area-mean metallic is a blend of the two lobe families rather than one of them. An
/// object's triangles share its metallic (the look and the object stage set it per object), so a pure family's
/// mean is 0 or 1 up to the f32 rounding of the area-weighted mean, far below this margin.
#[must_use]
pub fn is_blend(metallic: f32) -> bool {
    metallic > 1e-3 && metallic < 1.0 - 1e-3
}

/// The pure family a blend is held against: the metal for a metallic of ½ and above, its dielectric part below.
/// The object stage chose the blend's metallic on all its pixels, after its metal test under the settled light
/// had compared the two families; the look asks only whether the blend's extra parameter pays against the
/// family it nearly is. Choosing between the two families by their fit loss on the look's few fit pixels (as
/// the look once did) is a comparison no test guards, and a blend that then fails its burden took that family
/// on no evidence at all. On the corpus house (five runs, 29 blends) the nearer family was the true one for every
/// blend; the fit loss chose the farther for 3, and the 2 of those that failed their burden took the wrong
/// family (a metal sphere of 91 pixels at metallic 0.89 became a dark dielectric, L1 0.19 → 0.58; a dielectric
/// at 0.47 became a metal); docs/optim/design-measurements.md, "A blend held against the family it nearly is".
#[must_use]
pub fn blend_family_is_metal(metallic: f32) -> bool {
    layout::is_metal(f64::from(metallic))
}

/// The random-number stream of a blend's dielectric part among an object's fits: 0 is its own family's, 1–3 the
/// metal probes' (or a metal's Lambert surface, 1), so the dielectric part keeps the stream it had when a blend
/// was fitted in both families.
const DIELECTRIC_PART_STREAM: u32 = 1 + METAL_PROBES.len() as u32;

/// Whether an alternative's one colour sits at the top of the base colour's domain in every channel: its ratio
/// steps asked for more light than any surface reflects, so what it fits better is light missing from its pixels
/// (a neighbour's wrong model, a lamp fitted dim), not its family, and it replaces no pure family. (A blend is
/// still replaced by the pure family it nearly is unless it beats it: the burden of proof stays on the richer
/// model.)
/// Tested at four times the held-out paths, the metal-lamp fixture's white ceiling, beside a floor put in as a
/// metal, passed as a metal of colour (1, 1, 1) at t = 3.4 (docs/optim/design-measurements.md, "The metal tests
/// at four times the held-out paths").
fn clamped_white(base_color: Vec3) -> bool {
    base_color.min_element() >= 1.0
}

/// One object's look.
#[derive(Debug, Clone, PartialEq)]
pub struct Look {
    pub object: usize,
    /// The alternative tested: a metal at this roughness, or (`None`) a dielectric (a Lambert surface, or a
    /// blend's dielectric part).
    pub metal_roughness: Option<f32>,
    /// Its base colour after the steps on the fit pixels.
    pub base_color: Vec3,
    pub fit_pixels: usize,
    /// The test pixels looked at before the test ended (all of them, unless it stopped early).
    pub test_pixels: usize,
    /// The alternative's gain on the L1 of the renders' mean and on the RMS error, as fractions of the test
    /// pixels' mean radiance, with their paired t-statistics (for a blend, minus the blend's gain over it).
    pub l1: (f64, f64),
    pub rms: Option<(f64, f64)>,
    /// The alternative replaced the object's model.
    pub kept: bool,
}

/// Per object: the rows of `samples` whose centre ray hits it, in the look's random order, at most `budget`.
#[must_use]
pub fn object_rows(
    samples: &[TriSample],
    face_object: &[u32],
    objects: usize,
    budget: usize,
    seed: u64,
    round: u32,
) -> Vec<Vec<usize>> {
    let mut rows: Vec<Vec<usize>> = vec![Vec::new(); objects];
    for (j, s) in samples.iter().enumerate() {
        if let Some(r) = face_object.get(s.tri as usize).and_then(|&o| rows.get_mut(o as usize)) {
            r.push(j);
        }
    }
    for r in &mut rows {
        let mut ranked: Vec<(f64, usize)> = r
            .iter()
            .map(|&j| {
                (
                    streams::uniform(
                        seed,
                        draw::TRIANGLE_FAMILY,
                        streams::pixel_key(samples[j].pixel),
                        u64::from(round),
                    ),
                    j,
                )
            })
            .collect();
        ranked.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        ranked.truncate(budget);
        *r = ranked.into_iter().map(|(_, j)| j).collect();
    }
    rows
}

/// The look at every non-emitting object of `state` on the round's `samples` (see the module docs); the
/// alternatives kept replace their objects' triangles, whose ratio steps on their pixels follow. Returns each
/// object's look and the loss of those steps on those pixels (empty when nothing was kept).
pub fn family_look(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    state: &mut TriangleState,
    round: u32,
    progress: &dyn crate::Progress,
) -> Result<(Vec<Look>, Vec<f64>), TriangleError> {
    let cfg = inputs.settings;
    let objects = state.emission.len();
    let means = state.object_means(objects);
    let rows = object_rows(samples, &state.face_object, objects, cfg.family_pixels as usize, cfg.seed, round);
    let mut tris_of: Vec<Vec<usize>> = vec![Vec::new(); objects];
    for (t, &o) in state.face_object.iter().enumerate() {
        if let Some(v) = tris_of.get_mut(o as usize) {
            v.push(t);
        }
    }
    let candidates: Vec<usize> = (0..objects)
        .filter(|&o| state.emission[o].max_element() <= 0.0 && means[o].is_some() && rows[o].len() / 2 >= MIN_HALF)
        .collect();
    let mut free = vec![false; state.triangles.len()];
    let mut looks = Vec::new();
    let mut kept: Vec<(usize, Vec<tracer::Material>)> = Vec::new();
    let current = state.params();
    progress.phase("lobe family look: object", candidates.len() as u64, 0);
    let muted = Muted(progress);
    for (done, &o) in candidates.iter().enumerate() {
        check_stop(progress)?;
        progress.set_position(done as u64);
        let Some(mean) = means[o] else { continue };
        let (fit, test) = rows[o].split_at(fit_rows(rows[o].len()));
        let fit: Vec<TriSample> = fit.iter().map(|&j| samples[j]).collect();
        let test: Vec<TriSample> = test.iter().map(|&j| samples[j]).collect();
        // The object's own family first (its mean material), then the alternatives: for a pure family the
        // other one, for a blend the pure family it nearly is ([`blend_family_is_metal`]).
        // Each fit draws the random numbers of its alternative (its stream: 0 for the own family, then
        // [`DIELECTRIC_PART_STREAM`] or the probes' and the Lambert surface's), wherever it sits in the list.
        let blend = is_blend(mean.metallic);
        // The family its metallic puts it in (a blend's: the pure family it nearly is).
        let metal = blend_family_is_metal(mean.metallic);
        let probes = || METAL_PROBES.iter().map(|&r| tracer::Material { roughness: r, metallic: 1.0, ..mean });
        let mut families = vec![(0, mean)];
        if blend && !metal {
            families.push((DIELECTRIC_PART_STREAM, tracer::Material { metallic: 0.0, ..mean }));
        } else if blend || !metal {
            families.extend((1..).zip(probes()));
        } else {
            let lambert = tracer::Material {
                base_color: mean.base_color,
                roughness: layout::START_ROUGHNESS as f32,
                metallic: 0.0,
                specular: 0.0,
            };
            families.push((1, lambert));
        }
        let tris = &tris_of[o];
        for &t in tris {
            free[t] = true;
        }
        let saved: Vec<tracer::Material> = tris.iter().map(|&t| state.materials[t]).collect();
        let mut fitted: Vec<(f64, Vec<tracer::Material>)> = Vec::with_capacity(families.len());
        for &(a, family) in &families {
            for &t in tris {
                state.materials[t] = family;
            }
            let keys: Vec<u64> = (0..FAMILY_STEPS).map(|k| key::triangle_family(o as u32, a, k)).collect();
            let plan = StepPlan { free: &free, keys: &keys, update: Update::OneFactor, phase: &|_| String::new() };
            let stepped = ratio::ratio_steps(inputs, scene, &fit, state, &plan, &muted)?;
            ratio::bound_discards(round, stepped.work.discarded, stepped.work.paths)?;
            let loss = stepped.loss.last().copied().unwrap_or(f64::INFINITY);
            fitted.push((loss, tris.iter().map(|&t| state.materials[t]).collect()));
        }
        for (&t, m) in tris.iter().zip(&saved) {
            state.materials[t] = *m;
            free[t] = false;
        }
        let mut fitted = fitted.into_iter();
        let Some((_, own)) = fitted.next() else { continue };
        let Some((_, alt)) = fitted.min_by(|a, b| a.0.total_cmp(&b.0)) else { continue };
        let with = |materials: &[tracer::Material]| {
            let mut p = current.clone();
            for (&t, m) in tris.iter().zip(materials) {
                p.materials[t] = *m;
            }
            p
        };
        // A pure family replaces its object's model where it fits better; a blend must fit better than the best
        // pure family to stay (the object stage keeps a blend only where it pays).
        let (own_p, alt_p) = (with(&own), with(&alt));
        let (before, after) = if blend { (&alt_p, &own_p) } else { (&own_p, &alt_p) };
        let verdict = test_alternative(inputs, scene, &test, (before, after), (o, round), &muted)?;
        let mean_target = mean_target(&test);
        // One colour for the object (a uniform start moved by one factor per channel).
        let base_color = alt.first().map_or(mean.base_color, |m| m.base_color);
        // A dielectric's switch to a metal carries the burden on both statistics: the metal must also lower
        // the squared error ([`Verdict::confirmed_by_squared_error`]).
        let to_metal = !blend && !metal;
        let confirmed = !to_metal || verdict.confirmed_by_squared_error(mean_target);
        let passes = verdict.passes(mean_target) != blend && (blend || !clamped_white(base_color)) && confirmed;
        let sign = if blend { -1.0 } else { 1.0 };
        let signed = |(g, t): (f64, f64)| (sign * g, sign * t);
        let look = Look {
            object: o,
            metal_roughness: alt.first().filter(|m| layout::is_metal(f64::from(m.metallic))).map(|m| m.roughness),
            base_color,
            fit_pixels: fit.len(),
            test_pixels: verdict.d.len(),
            l1: signed(verdict.gain(mean_target)),
            rms: verdict.squared.as_ref().map(|q| signed(q.gain(mean_target))),
            kept: passes,
        };
        tracing::debug!(object = o, ?look, figures = %verdict.figures(mean_target), "lobe family look");
        if passes {
            kept.push((o, alt));
        }
        looks.push(look);
    }
    progress.set_position(candidates.len() as u64);
    if kept.is_empty() {
        return Ok((looks, Vec::new()));
    }
    for (o, alt) in &kept {
        for (&t, m) in tris_of[*o].iter().zip(alt) {
            state.materials[t] = *m;
            free[t] = true;
        }
    }
    // The switched objects' triangles follow their new family per triangle, on their own pixels: the rest of
    // the scene's colours were fitted under them and move only by the switched objects' light on them.
    let rows: Vec<TriSample> = samples.iter().filter(|s| free[s.tri as usize]).copied().collect();
    let nbrs = ratio::neighbours(state);
    let keys: Vec<u64> = (0..cfg.light_fit_steps)
        .map(|k| key::triangle_family(key::TRIANGLE_FAMILY_ALL, key::TRIANGLE_FAMILY_PASS, k))
        .collect();
    let (steps, pixels) = (keys.len(), rows.len());
    let phase =
        |i: usize| format!("round {round}: ratio step {i}/{steps} of the switched objects ({pixels} pixels), block");
    let plan = StepPlan { free: &free, keys: &keys, update: Update::PerTriangle { nbrs: &nbrs }, phase: &phase };
    let stepped = ratio::ratio_steps(inputs, scene, &rows, state, &plan, progress)?;
    ratio::bound_discards(round, stepped.work.discarded, stepped.work.paths)?;
    Ok((looks, stepped.loss))
}

/// The paired test of `after` against `before` on an object's test pixels: each rendered twice at half of
/// `object.holdout_spp` paths, the two models with common random numbers, in looks at
/// [`FIRST_LOOK`](paired::FIRST_LOOK), twice as many, … of the pixels until all are looked at or the test stops
/// because it cannot pass or clearly passes ([`paired::early_stop`], the object stage's sequential looks). Random
/// numbers are keyed by the pixel, so the looks give exactly the values of one render of the pixels looked at.
fn test_alternative(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    test: &[TriSample],
    (before, after): (&tracer::Params, &tracer::Params),
    (object, round): (usize, u32),
    progress: &dyn crate::Progress,
) -> Result<Verdict, TriangleError> {
    let spp = (inputs.object.holdout_spp.saturating_mul(paired::METAL_TEST_PATHS) / 2).max(1);
    let seed = inputs.settings.seed;
    let (r_before, r_after) =
        (tracer::Renderer::new(scene, before, inputs.tracer)?, tracer::Renderer::new(scene, after, inputs.tracer)?);
    let mean_target = mean_target(test);
    let target = |j: usize| test[j].target.as_dvec3().to_array();
    let (mut i_d, mut i_t) = (Vec::with_capacity(test.len()), Vec::with_capacity(test.len()));
    let mut n_look = paired::FIRST_LOOK;
    loop {
        let new = &test[i_d.len()..test.len().min(n_look)];
        let pix: Vec<tracer::PixelRef> = new.iter().map(|s| s.pixel).collect();
        let mut halves = Vec::with_capacity(2);
        for h in 0..2 {
            let key = key::triangle_family(object as u32, key::TRIANGLE_FAMILY_TEST, h);
            let (a, sa) = crate::blocks::render_blocks(&r_before, inputs.cameras, &pix, spp, seed, key, progress, "")?;
            let (b, sb) = crate::blocks::render_blocks(&r_after, inputs.cameras, &pix, spp, seed, key, progress, "")?;
            ratio::bound_discards(round, sa.discarded + sb.discarded, sa.paths + sb.paths)?;
            halves.push((a, b));
        }
        for j in 0..pix.len() {
            i_d.push([halves[0].0[j], halves[1].0[j]]);
            i_t.push([halves[0].1[j], halves[1].1[j]]);
        }
        let rows: Vec<usize> = (0..i_d.len()).collect();
        let (d, squared) = paired::differences(Statistic::L1OrSquaredError, target, &rows, &i_d, &i_t);
        let stopped = if rows.len() == test.len() {
            None
        } else {
            paired::early_stop(&d, squared.as_ref(), test.len(), mean_target)
        };
        if rows.len() == test.len() || stopped.is_some() {
            return Ok(Verdict { d, squared, n_full: test.len(), stopped });
        }
        n_look *= 2;
    }
}

/// The pixels' mean radiance summed over the channels, which the test's gains are fractions of.
fn mean_target(test: &[TriSample]) -> f64 {
    test.iter().map(|s| f64::from(s.target.abs().element_sum())).sum::<f64>() / test.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;
    use tracer::PixelRef;

    fn sample(i: u32, tri: u32, on_object: bool) -> TriSample {
        TriSample {
            pixel: PixelRef { view: 0, x: i, y: 0 },
            target: Vec3::splat(0.5),
            tri,
            child: 0,
            interior: on_object,
            on_object,
            bary: Vec2::ZERO,
        }
    }

    #[test]
    fn only_an_alternative_white_to_the_bound_in_every_channel_counts_as_clamped() {
        assert!(clamped_white(Vec3::ONE));
        // A silver's colour, near but under the bound, and a colour clamped in one channel only, are fitted.
        assert!(!clamped_white(Vec3::new(0.97, 0.96, 0.91)));
        assert!(!clamped_white(Vec3::new(1.0, 1.0, 0.9)));
    }

    #[test]
    fn an_objects_rows_hit_it_fit_the_budget_and_keep_one_order() {
        // Object 0 has triangles 0 and 1, object 1 triangle 2; every third pixel of object 0 straddles an edge
        // (its centre hits the object all the same).
        let samples: Vec<TriSample> =
            (0..300).map(|i| sample(i, i % 2, i % 3 != 0)).chain((300..340).map(|i| sample(i, 2, true))).collect();
        let face_object = [0, 0, 1];
        let rows = object_rows(&samples, &face_object, 2, 128, 7, 0);
        assert_eq!(rows[0].len(), 128);
        assert_eq!(rows[1].len(), 40);
        for (o, r) in rows.iter().enumerate() {
            assert!(r.iter().all(|&j| face_object[samples[j].tri as usize] as usize == o));
            let mut u = r.clone();
            u.sort_unstable();
            u.dedup();
            assert_eq!(u.len(), r.len(), "a row twice");
        }
        // Another seed draws another sample of object 0's 300 pixels; the same seed the same one.
        assert_eq!(rows, object_rows(&samples, &face_object, 2, 128, 7, 0));
        assert_ne!(rows[0], object_rows(&samples, &face_object, 2, 128, 8, 0)[0]);
        // The budget takes a prefix of one order: a larger budget keeps the smaller one's rows first.
        assert_eq!(rows[0][..], object_rows(&samples, &face_object, 2, 1000, 7, 0)[0][..128]);
    }
}
