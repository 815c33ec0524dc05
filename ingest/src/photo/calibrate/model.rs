//! From observations to the least-squares problem and back: usable channels, which photos are linked well
//! enough to solve, the unknowns' layout, gauges, and the result.

use std::collections::HashMap;

use super::response::{self, KNOTS};
use super::result::{Layout, RowInfo, finish};
use super::solve::{self, Constraint, Penalty, Problem, Row};
use super::{CalibrateError, Calibration, CalibrationOptions, Observation, ResponseChannels, ResponseMode};
use crate::photo::mask::SATURATION_FRACTION;
use crate::srgb;

/// Codes at or below 2/255 are black: sensor black level, noise and the 8-bit floor make `ln` of them
/// meaningless (one code step is ≥ 40 % of the value there).
const BLACK_CODE: f64 = 2.0 / 255.0;
/// A photo needs this many usable observations of points that other solved photos also see. It has up to 3
/// gain unknowns, and the robust weights may discard a good part of its rows (highlights, occlusions): 10
/// links keep it over-determined even when half are rejected.
const MIN_LINKS: usize = 10;
/// Vignetting of a group is estimated only when its observations' r² spread within points (rms around the
/// point's mean) exceeds this: with a spread of 0.02 in r² a 1 % radiance noise still pins ln v(1) to a few
/// percent with a hundred points; below it the coefficients are confounded with the radiances.
const MIN_R2_SPREAD: f64 = 0.02;
/// Noise floor of a known-response observation in `ln` units (1 %), added to the quantisation variance so
/// that bright codes do not get unbounded weight.
const NOISE_FLOOR: f64 = 0.01;
/// Smoothness weight of the response's second differences, relative to the mean data weight per knot. A
/// scan's channels each fill a narrow band of codes (the consumer-camera fixture's blue: 96 % of its pixels in
/// codes 32..128), so most knots hold few rows: at 0.1 the curve bent at the ends of each band, and after the
/// best power per channel it still linearised the photos' codes with an rms error of 4–17 % (three renders of
/// the fixture); at 10 the error is 0.1–1.4 %, while the exposure-bracket cases, whose codes span the whole
/// range, do not change (Memorial against OpenCV: 0.024 → 0.022; the synthetic curves: within 0.002)
/// (docs/photo/self-calibration.md, "Smoothness of the estimated response").
const SMOOTHNESS: f64 = 10.0;
/// Floor of the hat factor of the smoothness weight, so that knots beyond the last observation are still tied
/// to their neighbours (linear extrapolation) instead of being left free.
const MIN_SMOOTHING_HAT: f64 = 0.05;
/// Codes of the rows an estimated response is fitted to: the middle 32..=224 of 255, away from the toe and
/// shoulder where a response may be flat (a film's fog floor, clipping) and contradict the exposure ratios.
/// The curve outside is the smoothness penalty's extrapolation.
const START_CODES: (f64, f64) = (32.0 / 255.0, 224.0 / 255.0);
/// Reference code of the response normalisation and offset gauge (`curve(128) = 1`).
const REF_CODE: f64 = 128.0 / 255.0;
/// Codes of the provisional scale gauge of an estimated response: a quarter and three quarters of the range,
/// where every curve is well observed.
const GAUGE_CODES: (f64, f64) = (64.0 / 255.0, 192.0 / 255.0);

/// Whether channel value `v` is usable, and its `ln` radiance (known response) and base weight.
pub(super) fn usable(v: f32, mode: ResponseMode) -> Option<(f64, f64)> {
    let v = f64::from(v);
    if !v.is_finite() {
        return None;
    }
    match mode {
        ResponseMode::Linear => (v > 0.0).then(|| (v.ln(), 1.0)),
        _ if v <= BLACK_CODE || v >= SATURATION_FRACTION => None,
        ResponseMode::Srgb => {
            let lin = f64::from(srgb::decode(v as f32));
            // Quantisation: one 8-bit code step in ln units is (dh/dz)/255, uniform → variance step²/12.
            let dz = 0.5 / 255.0;
            let slope = (f64::from(srgb::decode((v + dz) as f32)) / f64::from(srgb::decode((v - dz) as f32))).ln();
            Some((lin.ln(), 1.0 / (slope * slope / 12.0 + NOISE_FLOOR * NOISE_FLOOR)))
        }
        // Debevec & Malik's hat weight (squared, as they weight the residual): quantisation dominates at
        // the dark end, clipping at the bright end.
        ResponseMode::Estimate => Some((0.0, (v.min(1.0 - v) * 2.0).powi(2))),
    }
}

/// Which photos are solved: iteratively drop photos with fewer than [`MIN_LINKS`] links, then split the rest
/// into linked sets (photos joined by shared points). With `all_sets` every set is kept, each with its own
/// gain gauge (a known response: rooms that no photo links are calibrated each on its own, which is never
/// worse than one fixed exposure for all); otherwise only the largest (an estimated response: its exponent
/// and exposure lattice need one set of comparable exposures). Returns each photo's set (`None` = not
/// solved) and the reasons of the photos left out.
fn linked_photos(
    n_photos: usize,
    obs: &[(usize, u32)],
    observations: &[Observation],
    all_sets: bool,
) -> (Vec<Option<usize>>, Vec<(u32, String)>) {
    let mut active = vec![true; n_photos];
    let mut reasons = Vec::new();
    let mut by_point: HashMap<u32, Vec<u32>> = HashMap::new();
    for &(i, _) in obs {
        by_point.entry(observations[i].point).or_default().push(observations[i].photo);
    }
    loop {
        let mut links = vec![0usize; n_photos];
        for photos in by_point.values() {
            let seen: Vec<u32> = photos.iter().copied().filter(|&p| active[p as usize]).collect();
            for &p in &seen {
                if seen.iter().any(|&q| q != p) {
                    links[p as usize] += 1;
                }
            }
        }
        let drop: Vec<usize> = (0..n_photos).filter(|&p| active[p] && links[p] < MIN_LINKS).collect();
        if drop.is_empty() {
            break;
        }
        for p in drop {
            active[p] = false;
            reasons.push((
                p as u32,
                format!("{} usable observations shared with other photos, need {MIN_LINKS}", links[p]),
            ));
        }
    }
    // Union-find over photos joined by a shared point.
    let mut parent: Vec<usize> = (0..n_photos).collect();
    fn root(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    for photos in by_point.values() {
        let seen: Vec<usize> = photos.iter().map(|&p| p as usize).filter(|&p| active[p]).collect();
        for w in seen.windows(2) {
            let (a, b) = (root(&mut parent, w[0]), root(&mut parent, w[1]));
            parent[a] = b;
        }
    }
    let mut size = vec![0usize; n_photos];
    for p in (0..n_photos).filter(|&p| active[p]) {
        size[root(&mut parent, p)] += 1;
    }
    let main = (0..n_photos).max_by_key(|&r| (size[r], std::cmp::Reverse(r))).unwrap_or(0);
    let mut set_of_root: HashMap<usize, usize> = HashMap::new();
    let mut set = vec![None; n_photos];
    for p in 0..n_photos {
        if !active[p] {
            continue;
        }
        let r = root(&mut parent, p);
        if all_sets || r == main {
            let next = set_of_root.len();
            set[p] = Some(*set_of_root.entry(r).or_insert(next));
        } else {
            reasons.push((p as u32, "not linked by shared points to the largest set of photos".into()));
        }
    }
    reasons.sort_by_key(|r| r.0);
    (set, reasons)
}

pub(super) fn run(
    photo_groups: &[u32],
    observations: &[Observation],
    opts: &CalibrationOptions,
) -> Result<Calibration, CalibrateError> {
    let mode = opts.response;
    let n_photos = photo_groups.len();
    let n_groups = photo_groups.iter().max().map_or(0, |&g| g as usize + 1);
    // (observation, channel) → (y, weight) for usable channels.
    let mut clipped_channels = 0;
    let mut cells: Vec<(usize, u32, f64, f64)> = Vec::new();
    for (i, o) in observations.iter().enumerate() {
        for c in 0..3u32 {
            match usable(o.value[c as usize], mode) {
                Some((y, w)) => cells.push((i, c, y, w)),
                None => clipped_channels += 1,
            }
        }
    }
    let pairs: Vec<(usize, u32)> = cells.iter().map(|&(i, c, ..)| (i, c)).collect();
    let (set, unconstrained) = linked_photos(n_photos, &pairs, observations, mode != ResponseMode::Estimate);
    let active: Vec<bool> = set.iter().map(Option::is_some).collect();
    let linked = active.iter().filter(|&&a| a).count();
    if linked < 2 {
        return Err(CalibrateError::TooFewLinked { linked, photos: n_photos });
    }
    cells.retain(|&(i, ..)| active[observations[i].photo as usize]);
    // Group rows by (point, channel); single-row groups carry no information.
    cells.sort_by_key(|&(i, c, ..)| (observations[i].point, c, i));
    let mut groups: Vec<std::ops::Range<usize>> = Vec::new();
    let mut start = 0;
    for j in 1..=cells.len() {
        let key = |k: usize| (observations[cells[k].0].point, cells[k].1);
        if j == cells.len() || key(j) != key(start) {
            if j - start >= 2 {
                groups.push(start..j);
            }
            start = j;
        }
    }
    // Vignetting identifiability per group: r² spread within points.
    let (mut spread, mut count) = (vec![0.0; n_groups], vec![0usize; n_groups]);
    for g in &groups {
        let mean = g.clone().map(|j| f64::from(observations[cells[j].0].r2)).sum::<f64>() / g.len() as f64;
        for j in g.clone() {
            let o = &observations[cells[j].0];
            let k = photo_groups[o.photo as usize] as usize;
            spread[k] += (f64::from(o.r2) - mean).powi(2);
            count[k] += 1;
        }
    }
    let estimated: Vec<bool> = (0..n_groups)
        .map(|k| opts.vignetting && count[k] > 0 && (spread[k] / count[k] as f64).sqrt() > MIN_R2_SPREAD)
        .collect();
    // Layout: response knots, gains, vignetting.
    let curves = match (mode, opts.response_channels) {
        (ResponseMode::Estimate, ResponseChannels::Shared) => 1,
        (ResponseMode::Estimate, ResponseChannels::PerChannel) => 3,
        _ => 0,
    };
    let h_len = curves * KNOTS;
    let per_photo = if opts.white_balance { 3 } else { usize::from(opts.exposure) };
    let mut n = h_len;
    let gain = (0..n_photos)
        .map(|p| {
            (active[p] && per_photo > 0).then(|| {
                n += per_photo;
                n - per_photo
            })
        })
        .collect();
    let beta = estimated
        .iter()
        .map(|&e| {
            e.then(|| {
                n += 3;
                n - 3
            })
        })
        .collect();
    let layout = Layout { curves, gain, set, per_photo, beta, n };
    // A known response is trusted over its whole range: every row, Huber's weights, then Tukey's. An
    // estimated one uses mid codes only (see START_CODES) and Huber's weights throughout: the exponent gauge
    // is not a symmetry of Tukey's bounded loss, and the biweight finds it cheaper to reject every row of one
    // channel or photo and let that block absorb the gauge while the rest flattens (measured on the Memorial
    // bracket: every exposure ratio collapses to 1). Huber's loss is convex, so the gauged problem has one
    // minimum, and its influence is still bounded.
    let huber_iterations = if mode == ResponseMode::Estimate { usize::MAX } else { solve::HUBER_ITERATIONS };
    let mut problem = Problem { n_params: layout.n, huber_iterations, ..Problem::default() };
    let mut row_cell = Vec::with_capacity(cells.len());
    for g in &groups {
        let s = problem.rows.len();
        for j in g.clone() {
            let (i, c, y, w) = cells[j];
            let o = &observations[i];
            let mut row = Row::new(y, w);
            if mode == ResponseMode::Estimate {
                let (k, t) = response::knot_weights(f64::from(o.value[c as usize]));
                let h = layout.curve(c as usize);
                row.push(h + k, 1.0 - t);
                row.push(h + k + 1, t);
            }
            if let Some(first) = layout.gain[o.photo as usize] {
                row.push(first + if layout.per_photo == 3 { c as usize } else { 0 }, -1.0);
            }
            if let Some(b) = layout.beta[photo_groups[o.photo as usize] as usize] {
                let r2 = f64::from(o.r2);
                row.push(b, -r2);
                row.push(b + 1, -r2 * r2);
                row.push(b + 2, -r2 * r2 * r2);
            }
            problem.rows.push(row);
            row_cell.push(j);
            if mode == ResponseMode::Estimate {
                let z = f64::from(o.value[c as usize]);
                problem.start.push(f64::from(u8::from((START_CODES.0..=START_CODES.1).contains(&z))));
            }
        }
        problem.groups.push(s..problem.rows.len());
    }
    // The smoothness is relative to the weight of the rows that take part.
    let total_w: f64 = if problem.start.is_empty() {
        problem.rows.iter().map(|r| r.w).sum()
    } else {
        problem.rows.iter().zip(&problem.start).map(|(r, s)| r.w * s).sum()
    };
    let n_scale = add_gauges(&mut problem, &layout, opts, total_w);
    gauge_on_shape(&mut problem, &layout, n_scale)?;
    let mut sol = solve::solve(&problem).ok_or(CalibrateError::Singular)?;
    let mut chosen = None;
    if mode == ResponseMode::Estimate && layout.per_photo == 1 {
        if let Some((choice, snapped)) = snap_exposures(&sol.theta, &layout) {
            refit_with_exposures(&mut problem, &layout, &snapped);
            sol = solve::solve(&problem).ok_or(CalibrateError::Singular)?;
            chosen = Some(choice);
        }
    }
    let rows = RowInfo {
        observation: row_cell.iter().map(|&j| cells[j].0).collect(),
        channel: row_cell.iter().map(|&j| cells[j].1 as usize).collect(),
    };
    Ok(finish(n_groups, opts, &layout, &problem, &sol, &rows, unconstrained, clipped_channels, estimated, chosen))
}

/// Adds the gauge constraints and the response's smoothness; returns how many of the constraints (the last
/// ones) are the response's provisional scale gauge.
fn add_gauges(problem: &mut Problem, layout: &Layout, opts: &CalibrationOptions, total_w: f64) -> usize {
    let solved: Vec<usize> = layout.gain.iter().flatten().copied().collect();
    // One gauge per linked set: nothing relates the gains of photos that share no point.
    let sets: Vec<Vec<usize>> = (0..layout.n_sets())
        .map(|s| {
            layout.gain.iter().zip(&layout.set).filter(|(_, set)| **set == Some(s)).filter_map(|(g, _)| *g).collect()
        })
        .collect();
    match layout.per_photo {
        1 => {
            for set in &sets {
                problem.constraints.push(Constraint { entries: set.iter().map(|&g| (g, 1.0)).collect(), target: 0.0 });
            }
        }
        3 => {
            // Without a common exposure every photo's channels multiply to 1; the per-channel means then
            // need only two constraints (the third is implied).
            let channels = if opts.exposure { 3 } else { 2 };
            for set in &sets {
                for c in 0..channels {
                    problem
                        .constraints
                        .push(Constraint { entries: set.iter().map(|&g| (g + c, 1.0)).collect(), target: 0.0 });
                }
            }
            if !opts.exposure {
                for &g in &solved {
                    problem
                        .constraints
                        .push(Constraint { entries: (0..3).map(|c| (g + c, 1.0)).collect(), target: 0.0 });
                }
            }
        }
        _ => {}
    }
    if opts.response != ResponseMode::Estimate {
        return 0;
    }
    let mut scale_gauges = Vec::new();
    // Per channel and knot, so that a shared curve (which holds all three channels' rows) is smoothed as
    // strongly as each of three per-channel curves.
    let lambda = SMOOTHNESS * total_w / (3 * KNOTS) as f64;
    let point = |h: usize, z: f64| {
        let (k, t) = response::knot_weights(z);
        vec![(h + k, 1.0 - t), (h + k + 1, t)]
    };
    for curve in 0..layout.curves {
        let h = curve * KNOTS;
        for k in 1..KNOTS - 1 {
            let entries = vec![(h + k - 1, 1.0), (h + k, -2.0), (h + k + 1, 1.0)];
            // Debevec & Malik weight the smoothness like the data (hat weight at the knot's code), so the curve
            // may bend sharply at the ends, where a film toe or shoulder compresses many stops into few codes.
            let z = (k as f64 / (KNOTS - 1) as f64).powi(2);
            let hat = (z.min(1.0 - z) * 2.0).max(MIN_SMOOTHING_HAT);
            problem.penalties.push(Penalty { entries, target: 0.0, weight: lambda * hat * hat });
        }
        problem.constraints.push(Constraint { entries: point(h, REF_CODE), target: 0.0 });
        // Provisional exponent: shared gains tie the channels' exponents, so one channel's gauge fixes all.
        if layout.per_photo == 3 || layout.curves == 1 || curve == 1 {
            let mut entries = point(h, GAUGE_CODES.1);
            entries.extend(point(h, GAUGE_CODES.0).into_iter().map(|(i, w)| (i, -w)));
            scale_gauges.push(Constraint { entries, target: response::gauge_span(GAUGE_CODES.0, GAUGE_CODES.1) });
        }
    }
    let n = scale_gauges.len();
    problem.constraints.extend(scale_gauges);
    n
}

/// Replaces the response's provisional scale gauge (a span of the curve between two codes) by the curve's
/// projection on the shape of a first solve from the start rows. A two-code span leaves the IRLS free to
/// flatten the curve everywhere else and shrink every exposure ratio towards 1 — the direction in which a
/// film's fog floor (codes that do not move with exposure) pulls; the projection involves every knot the start
/// rows reach, so flattening the curve violates it. It does not involve the gains either: a photo whose rows
/// all end up rejected cannot absorb the scale.
fn gauge_on_shape(problem: &mut Problem, layout: &Layout, n_scale: usize) -> Result<(), CalibrateError> {
    if n_scale == 0 {
        return Ok(());
    }
    let first = solve::solve_weighted(problem, &problem.start).ok_or(CalibrateError::Singular)?;
    let mut support = vec![0usize; problem.n_params];
    for (row, &w) in problem.rows.iter().zip(&problem.start) {
        if w > 0.0 {
            for k in 0..usize::from(row.len) {
                support[row.idx[k] as usize] += 1;
            }
        }
    }
    // A shared curve or shared gains tie the channels' exponents: one gauge over all knots; per-channel
    // curves with per-channel gains one per curve.
    let curve_sets: Vec<Vec<usize>> = match layout.curves {
        3 if layout.per_photo == 3 => vec![vec![0], vec![1], vec![2]],
        3 => vec![vec![0, 1, 2]],
        _ => vec![vec![0]],
    };
    let mut gauges = Vec::new();
    for set in curve_sets {
        let knots: Vec<usize> =
            set.iter().flat_map(|&c| c * KNOTS..(c + 1) * KNOTS).filter(|&k| support[k] >= MIN_LINKS).collect();
        // Centred per curve: the offsets are gauged separately (curve(128) = 1).
        let mut entries = Vec::new();
        for &c in &set {
            let own: Vec<usize> = knots.iter().copied().filter(|k| k / KNOTS == c).collect();
            let mean = own.iter().map(|&k| first[k]).sum::<f64>() / own.len().max(1) as f64;
            entries.extend(own.iter().map(|&k| (k, first[k] - mean)));
        }
        let target: f64 = entries.iter().map(|e| e.1 * e.1).sum();
        if target <= 0.0 || !target.is_finite() {
            return Ok(());
        }
        gauges.push(Constraint { entries, target });
    }
    problem.constraints.truncate(problem.constraints.len() - n_scale);
    problem.constraints.extend(gauges);
    Ok(())
}

/// Exposures of the provisional solution snapped to a lattice (exposure-only gains): the ⅓-EV lattice when
/// exactly one exponent near the shape prior fits it, else the bracket's own step. Returns the exponent choice
/// and the snapped log exposures per solved photo (provisional units), or `None` when neither lattice fits.
fn snap_exposures(theta: &[f64], layout: &Layout) -> Option<(response::ScaleChoice, Vec<f64>)> {
    let h: Vec<&[f64]> = (0..3).map(|c| layout.knots(theta, c)).collect();
    let prior = response::shape_prior_scale(&h);
    let x: Vec<f64> = layout.gain.iter().flatten().map(|&g| theta[g]).collect();
    let choice = response::choose_scale(prior, &x);
    if choice.source == response::GammaSource::ExposureLattice {
        return Some((choice, response::snap_to_lattice(choice.kappa, &x)));
    }
    let fit = response::fit_bracket_steps(prior, &x)?;
    let choice = response::ScaleChoice {
        kappa: fit.kappa,
        source: response::GammaSource::BracketSteps,
        misfit: fit.misfit,
        reliable: fit.thirds == 1,
    };
    Some((choice, fit.snapped))
}

/// Turns `problem` into a fit of the response alone with the gains fixed to `snapped` (centred): the
/// exponential ambiguity is gone, so the exponent gauge and the gains' mean gauge are dropped.
fn refit_with_exposures(problem: &mut Problem, layout: &Layout, snapped: &[f64]) {
    let mean = snapped.iter().sum::<f64>() / snapped.len().max(1) as f64;
    let gains: Vec<usize> = layout.gain.iter().flatten().copied().collect();
    let curve_end = layout.curves * KNOTS;
    problem.constraints.retain(|c| c.entries.iter().all(|e| e.0 < curve_end) && c.entries.len() <= 2);
    for (&g, &x) in gains.iter().zip(snapped) {
        problem.constraints.push(Constraint { entries: vec![(g, 1.0)], target: x - mean });
    }
}
