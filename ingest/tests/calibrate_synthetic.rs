//! Self-calibration on synthetic observations with known gains, vignetting and response: linear input with
//! noise and outliers, a single exposure, and LDR photos through tone curves the estimator was not tuned on.
//! Each test prints the errors it reaches (docs/photo/self-calibration.md quotes them).

mod formats_common;

use formats_common::Rng;
use ingest::photo::calibrate::{
    CalibrateError, Calibration, CalibrationOptions, GammaSource, Observation, ResponseChannels, ResponseMode,
    Vignetting, calibrate,
};

fn normal(rng: &mut Rng) -> f64 {
    // Box–Muller; 1 − u keeps the logarithm finite.
    let (u, v) = (rng.uniform(0.0, 1.0), rng.uniform(0.0, 1.0));
    (-2.0 * (1.0 - u).ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// Gains normalised to geometric mean 1 per channel over `photos`.
fn normalised(gains: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mean: [f64; 3] =
        std::array::from_fn(|c| (gains.iter().map(|g| g[c].ln()).sum::<f64>() / gains.len() as f64).exp());
    gains.iter().map(|g| std::array::from_fn(|c| g[c] / mean[c])).collect()
}

fn worst_gain_error(cal: &Calibration, truth: &[[f64; 3]]) -> f64 {
    let truth = normalised(truth);
    let mut worst = 0.0f64;
    for (p, t) in truth.iter().enumerate() {
        let g = cal.gains[p].expect("every photo is constrained");
        for c in 0..3 {
            worst = worst.max((g[c] / t[c] - 1.0).abs());
        }
    }
    worst
}

struct Scene {
    groups: Vec<u32>,
    gains: Vec<[f64; 3]>,
    vignetting: Vec<Vignetting>,
    observations: Vec<Observation>,
}

/// Linear observations: `points` points, each seen by a photo with probability 0.6 at a random radius.
fn linear_scene(seed: u64, photos: usize, groups: u32, spread: bool, noise: f64, outliers: f64) -> Scene {
    let mut rng = Rng(seed);
    let group_of: Vec<u32> = (0..photos).map(|p| p as u32 % groups).collect();
    let gains: Vec<[f64; 3]> = (0..photos)
        .map(|_| {
            let e = if spread { 2f64.powf(rng.uniform(-1.0, 1.0)) } else { 1.0 };
            std::array::from_fn(|_| e * if spread { rng.uniform(0.88, 1.12) } else { 1.0 })
        })
        .collect();
    // Corner vignetting 0.6, 0.7, 0.8 with different profiles: ln v = β1 r² + β2 r⁴.
    let vignetting: Vec<Vignetting> = (0..groups)
        .map(|k| {
            let corner = if spread { 0.6 + 0.1 * f64::from(k) } else { 1.0 };
            let b2 = 0.3 * corner.ln() * f64::from(k) / 2.0;
            Vignetting { beta: [corner.ln() - b2, b2, 0.0] }
        })
        .collect();
    let mut observations = Vec::new();
    for point in 0..500u32 {
        let radiance: [f64; 3] = std::array::from_fn(|_| 2f64.powf(rng.uniform(-4.0, 2.0)));
        for p in 0..photos {
            if rng.uniform(0.0, 1.0) > 0.6 {
                continue;
            }
            let r2 = rng.uniform(0.0, 1.0);
            let v = vignetting[group_of[p] as usize].factor(r2);
            let bad = rng.uniform(0.0, 1.0) < outliers;
            let value = std::array::from_fn(|c| {
                let mut x = gains[p][c] * v * radiance[c] * (noise * normal(&mut rng)).exp();
                if bad {
                    // A highlight or an occluder: off by ×2..×5 either way.
                    x *= rng.uniform(2.0, 5.0).powf(if c == 0 || rng.uniform(0.0, 1.0) < 0.5 { 1.0 } else { -1.0 });
                }
                x as f32
            });
            observations.push(Observation { point, photo: p as u32, r2: r2 as f32, value });
        }
    }
    Scene { groups: group_of, gains, vignetting, observations }
}

/// Linear values, every gain and the vignetting estimated.
fn linear_all_estimates() -> CalibrationOptions {
    CalibrationOptions {
        response: ResponseMode::Linear,
        response_channels: ResponseChannels::Shared,
        exposure: true,
        white_balance: true,
        vignetting: true,
        seed: 0,
    }
}

#[test]
fn linear_gains_and_vignetting_with_noise_and_outliers() {
    let scene = linear_scene(11, 12, 3, true, 0.01, 0.05);
    let opts = linear_all_estimates();
    let cal = calibrate(&scene.groups, &scene.observations, &opts).unwrap();
    let gain_error = worst_gain_error(&cal, &scene.gains);
    let corner_error = (0..3)
        .map(|k| (cal.vignetting[k].factor(1.0) / scene.vignetting[k].factor(1.0) - 1.0).abs())
        .fold(0.0, f64::max);
    println!(
        "linear: worst gain error {gain_error:.5}, worst corner error {corner_error:.5}, rms {:.4}, rejected {}",
        cal.residual_rms, cal.rejected_channels
    );
    assert!(cal.unconstrained.is_empty(), "{:?}", cal.unconstrained);
    assert!(cal.vignetting_estimated.iter().all(|&e| e));
    assert!(gain_error < 0.005, "{gain_error}");
    assert!(corner_error < 0.01, "{corner_error}");
    assert_eq!(cal.gamma_source, GammaSource::Given);
}

#[test]
fn single_exposure_is_not_calibrated() {
    // Photos of one exposure and no vignetting: gains and vignetting fitted to half of the points predict the
    // other half no better than one exposure, so the calibration declines them.
    let scene = linear_scene(12, 12, 3, false, 0.01, 0.0);
    let opts = linear_all_estimates();
    match calibrate(&scene.groups, &scene.observations, &opts) {
        Err(CalibrateError::NotSupported(check)) => {
            println!("single exposure: {check:?}");
            assert!(check.groups > 100, "{check:?}");
            assert!(!check.supports());
        }
        other => panic!("expected NotSupported, got {other:?}"),
    }
}

#[test]
fn isolated_photo_is_unconstrained_and_the_rest_solved() {
    let mut scene = linear_scene(13, 6, 1, true, 0.01, 0.0);
    // Photo 6 sees only 3 points of its own.
    scene.groups.push(0);
    for point in 10_000..10_003 {
        scene.observations.push(Observation { point, photo: 6, r2: 0.5, value: [0.5; 3] });
    }
    let opts = CalibrationOptions { response: ResponseMode::Linear, ..CalibrationOptions::default() };
    let cal = calibrate(&scene.groups, &scene.observations, &opts).unwrap();
    assert_eq!(cal.gains[6], None);
    assert_eq!(cal.unconstrained.len(), 1);
    assert_eq!(cal.unconstrained[0].0, 6);
    assert!(cal.gains[..6].iter().all(Option::is_some));
}

/// A tone curve: linear exposure → display code in [0, 1].
type Curve = fn(f64) -> f64;

/// Hable's filmic operator ("Uncharted 2") with white point 11.2, then a display gamma 1/2.2: an S-curve in
/// log exposure, neither sRGB nor a power law.
fn filmic(x: f64) -> f64 {
    let hable = |x: f64| {
        let (a, b, c, d, e, f) = (0.15, 0.50, 0.10, 0.20, 0.02, 0.30);
        ((x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f)) - e / f
    };
    (hable(4.0 * x) / hable(11.2)).clamp(0.0, 1.0).powf(1.0 / 2.2)
}

/// Plain display gamma 1/2.2.
fn gamma22(x: f64) -> f64 {
    x.clamp(0.0, 1.0).powf(1.0 / 2.2)
}

/// Display gammas 1/1.8 and 1/2.6: with [`gamma22`], three channels of one film with different dye curves.
fn gamma18(x: f64) -> f64 {
    x.clamp(0.0, 1.0).powf(1.0 / 1.8)
}

fn gamma26(x: f64) -> f64 {
    x.clamp(0.0, 1.0).powf(1.0 / 2.6)
}

/// A film-like shoulder with a linear toe, normalised to 1 at x = 1.
fn film(x: f64) -> f64 {
    (1.0 - (-4.0 * x.max(0.0)).exp()) / (1.0 - (-4.0f64).exp())
}

/// Inverse of a monotone curve on [0, 1] by bisection.
fn inverse(f: fn(f64) -> f64, z: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < z { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// Median over channels and codes 8..=245 of |ln(estimated / true inverse response)|, both normalised at 128.
fn response_error(cal: &Calibration, f: fn(f64) -> f64) -> f64 {
    let curve = cal.response.as_ref().expect("estimated response");
    let truth = |z: usize| inverse(f, z as f64 / 255.0);
    let mut errors = Vec::new();
    for c in 0..3 {
        for z in 8..=245 {
            let est = f64::from(curve.values()[z][c]) / f64::from(curve.values()[128][c]);
            errors.push((est.ln() - (truth(z) / truth(128)).ln()).abs());
        }
    }
    errors.sort_by(f64::total_cmp);
    errors[errors.len() / 2]
}

/// 10 photos through tone curve `f`, 8-bit quantised; exposures either on the ⅓-EV lattice within ×0.5–2 or
/// log-uniform over the same range; 2 % multiplicative noise before the curve.
fn ldr_scene(seed: u64, f: fn(f64) -> f64, lattice: bool) -> (Vec<[f64; 3]>, Vec<Observation>) {
    let mut rng = Rng(seed);
    let exposures: Vec<f64> = (0..10)
        .map(|p| {
            if lattice {
                // Every ⅓ step from −1 to +1 EV appears at least once.
                2f64.powf((p as f64 % 7.0 - 3.0) / 3.0)
            } else {
                2f64.powf(rng.uniform(-1.0, 1.0))
            }
        })
        .collect();
    let mut observations = Vec::new();
    for point in 0..1500u32 {
        let radiance: [f64; 3] = std::array::from_fn(|_| 2f64.powf(rng.uniform(-9.0, 0.5)));
        for (p, e) in exposures.iter().enumerate() {
            let value = std::array::from_fn(|c| {
                let x = e * radiance[c] * (0.02 * normal(&mut rng)).exp();
                ((255.0 * f(x)).round() / 255.0) as f32
            });
            observations.push(Observation { point, photo: p as u32, r2: 0.0, value });
        }
    }
    (exposures.iter().map(|&e| [e; 3]).collect(), observations)
}

fn estimate(seed: u64, f: fn(f64) -> f64, lattice: bool) -> (Calibration, f64, f64) {
    let (gains, observations) = ldr_scene(seed, f, lattice);
    let opts = CalibrationOptions { response: ResponseMode::Estimate, ..CalibrationOptions::default() };
    let cal = calibrate(&[0; 10], &observations, &opts).unwrap();
    let (g, r) = (worst_gain_error(&cal, &gains), response_error(&cal, f));
    (cal, g, r)
}

#[test]
fn estimated_response_on_curves_not_tuned_on() {
    // ⅓-EV exposures: the exposure lattice fixes the exponent whatever the curve's shape.
    let curves: [(&str, Curve, u64); 3] = [("filmic", filmic, 21), ("gamma 2.2", gamma22, 21), ("film", film, 22)];
    for (name, f, seed) in curves {
        let (cal, g, r) = estimate(seed, f, true);
        println!(
            "{name:10} lattice exposures: worst gain error {g:.4}, response |ln| {r:.4}, {:?} (misfit {:.4}), rms {:.4}",
            cal.gamma_source, cal.lattice_misfit, cal.residual_rms
        );
        // The film curve is too far from sRGB for a ⅓-EV lattice fit within the prior's window, but its
        // exposures lie on a common step that the prior puts at ⅓ EV (the next candidate is twice as far).
        let source = if name == "film" { GammaSource::BracketSteps } else { GammaSource::ExposureLattice };
        assert_eq!(cal.gamma_source, source, "{name}");
        assert!(cal.gamma_reliable);
        assert!(g < 0.02, "{name}: {g}");
        assert!(r < 0.05, "{name}: {r}");
    }
}

#[test]
fn unfixable_exponent_is_flagged() {
    // Continuous exposures (no lattice, no common step) leave only the shape prior. The result must say it is
    // unreliable.
    let cases: [(&str, Curve, bool); 3] =
        [("filmic", filmic, false), ("gamma 2.2", gamma22, false), ("film", film, false)];
    for (name, f, lattice) in cases {
        let (cal, g, r) = estimate(22, f, lattice);
        println!(
            "{name:10} lattice={lattice:5}: worst gain error {g:.4}, response |ln| {r:.4}, {:?} (lowest misfit {:.4})",
            cal.gamma_source, cal.lattice_misfit
        );
        assert_eq!(cal.gamma_source, GammaSource::ShapePrior, "{name} {lattice}");
        assert!(!cal.gamma_reliable);
    }
}

#[test]
fn whole_stop_bracket_far_from_srgb_is_flagged() {
    // 16 exposures one stop apart fit the lattice at every third of the true exponent; with the film curve the
    // prior is too far off to pick one, so the estimator must refuse to call it reliable.
    let mut rng = Rng(5);
    let exposures: Vec<f64> = (0..16).map(|p| 2f64.powi(-p)).collect();
    let mut observations = Vec::new();
    for point in 0..1500u32 {
        let radiance: [f64; 3] = std::array::from_fn(|_| 2f64.powf(rng.uniform(-8.0, 8.0)));
        for (p, e) in exposures.iter().enumerate() {
            let value = std::array::from_fn(|c| {
                let x = e * radiance[c] * (0.02 * normal(&mut rng)).exp();
                ((255.0 * film(x)).round() / 255.0) as f32
            });
            observations.push(Observation { point, photo: p as u32, r2: 0.0, value });
        }
    }
    let opts = CalibrationOptions { response: ResponseMode::Estimate, ..CalibrationOptions::default() };
    let cal = calibrate(&[0; 16], &observations, &opts).unwrap();
    let step = cal.gains[0].unwrap()[1] / cal.gains[1].unwrap()[1];
    println!("film, 1-stop bracket: recovered step {step:.3} (true 2), {:?}", cal.gamma_source);
    assert!(!cal.gamma_reliable);
}

/// 12 photos of a warm room: exposures on the ⅓-EV lattice within ×0.5–2, each photo with its own white
/// balance (±12 % per channel, product 1, so the channels' mean log gain is the exposure), channel `c` through
/// `curves[c]`, 2 % noise, 8-bit. The radiances are tinted 1 : 0.6 : 0.3, so that each channel holds its own
/// band of codes (blue mostly in the toe), as the consumer-camera fixture's walls do. Each photo sees a point
/// with probability 0.7.
fn tinted_scene(seed: u64, curves: [Curve; 3]) -> (Vec<[f64; 3]>, Vec<Observation>) {
    let mut rng = Rng(seed);
    let gains: Vec<[f64; 3]> = (0..12)
        .map(|p| {
            let exposure = 2f64.powf((p as f64 % 7.0 - 3.0) / 3.0);
            let ln_wb: [f64; 3] = std::array::from_fn(|_| rng.uniform(0.88, 1.12).ln());
            let mean = ln_wb.iter().sum::<f64>() / 3.0;
            std::array::from_fn(|c| exposure * (ln_wb[c] - mean).exp())
        })
        .collect();
    let tint = [1.0, 0.6, 0.3];
    let mut observations = Vec::new();
    for point in 0..1500u32 {
        let level = 2f64.powf(rng.uniform(-6.0, 0.0));
        let radiance: [f64; 3] = std::array::from_fn(|c| level * tint[c] * rng.uniform(0.8, 1.25));
        for (p, g) in gains.iter().enumerate() {
            if rng.uniform(0.0, 1.0) > 0.7 {
                continue;
            }
            let value = std::array::from_fn(|c| {
                let x = g[c] * radiance[c] * (0.02 * normal(&mut rng)).exp();
                ((255.0 * curves[c](x)).round() / 255.0) as f32
            });
            observations.push(Observation { point, photo: p as u32, r2: 0.0, value });
        }
    }
    (gains, observations)
}

fn estimate_tinted(
    seed: u64,
    curves: [Curve; 3],
    channels: ResponseChannels,
    white_balance: bool,
) -> (Calibration, Vec<[f64; 3]>) {
    let (gains, observations) = tinted_scene(seed, curves);
    let opts = CalibrationOptions {
        response: ResponseMode::Estimate,
        response_channels: channels,
        white_balance,
        ..CalibrationOptions::default()
    };
    (calibrate(&[0; 12], &observations, &opts).unwrap(), gains)
}

/// Median over codes 8..=245 of |ln(estimated / true inverse response)| of channel `c`, both normalised at 128.
fn channel_response_error(cal: &Calibration, f: Curve, c: usize) -> f64 {
    let curve = cal.response.as_ref().expect("estimated response");
    let truth = |z: usize| inverse(f, z as f64 / 255.0);
    let mut errors: Vec<f64> = (8..=245)
        .map(|z| {
            let est = f64::from(curve.values()[z][c]) / f64::from(curve.values()[128][c]);
            (est.ln() - (truth(z) / truth(128)).ln()).abs()
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    errors[errors.len() / 2]
}

#[test]
fn shared_curve_through_per_photo_white_balance() {
    // One camera curve after white balance: the shared curve is one set of knots for the three channels, so
    // its three channels are the same function, and the gains come out on the lattice's exponent.
    let curves: [Curve; 3] = [filmic, filmic, filmic];
    let (cal, gains) = estimate_tinted(31, curves, ResponseChannels::Shared, true);
    let (g, r) = (worst_gain_error(&cal, &gains), response_error(&cal, filmic));
    let (per, _) = estimate_tinted(31, curves, ResponseChannels::PerChannel, true);
    println!(
        "tinted filmic, shared curve: worst gain error {g:.4}, response |ln| {r:.4}, {:?}; per-channel curves: \
         worst gain error {:.4}, response |ln| {:.4}, {:?}",
        cal.gamma_source,
        worst_gain_error(&per, &gains),
        response_error(&per, filmic),
        per.gamma_source
    );
    let values = cal.response.as_ref().expect("estimated response").values();
    assert!(values.iter().all(|v| v[0] == v[1] && v[1] == v[2]), "a shared curve differs between channels");
    assert!(cal.gamma_reliable, "{:?}", cal.gamma_source);
    assert!(g < 0.02, "{g}");
    assert!(r < 0.05, "{r}");
}

#[test]
fn per_channel_curves_of_film() {
    // Three dye curves (gamma 1.8, 2.2, 2.6) and exposure-only gains: per-channel curves recover each, and a
    // shared curve, which cannot represent them, lands between them: worse on the outer two.
    let curves: [Curve; 3] = [gamma18, gamma22, gamma26];
    let (per, gains) = estimate_tinted(32, curves, ResponseChannels::PerChannel, false);
    let (shared, _) = estimate_tinted(32, curves, ResponseChannels::Shared, false);
    let per_r: [f64; 3] = std::array::from_fn(|c| channel_response_error(&per, curves[c], c));
    let shared_r: [f64; 3] = std::array::from_fn(|c| channel_response_error(&shared, curves[c], c));
    // Exposure-only gains are the same for the three channels: compare with the channels' common exposure.
    let exposures: Vec<[f64; 3]> =
        gains.iter().map(|g| [(g.iter().map(|v| v.ln()).sum::<f64>() / 3.0).exp(); 3]).collect();
    let g = worst_gain_error(&per, &exposures);
    println!(
        "film dyes: per-channel curves response |ln| {per_r:.4?}, worst gain error {g:.4}, {:?}; shared curve \
         response |ln| {shared_r:.4?}",
        per.gamma_source
    );
    assert!(per.gamma_reliable, "{:?}", per.gamma_source);
    assert!(g < 0.02, "{g}");
    for c in 0..3 {
        assert!(per_r[c] < 0.05, "channel {c}: {}", per_r[c]);
    }
    for c in [0, 2] {
        assert!(shared_r[c] > 2.0 * per_r[c], "channel {c}: shared {} per-channel {}", shared_r[c], per_r[c]);
    }
}

#[test]
fn photos_of_unlinked_rooms_are_calibrated_each_on_their_own() {
    // Two rooms of 6 photos each that no photo links (disjoint points): with a known response both are
    // solved, each with gains of geometric mean 1; nothing relates the two rooms' exposures.
    let a = linear_scene(14, 6, 1, true, 0.01, 0.0);
    let b = linear_scene(15, 6, 1, true, 0.01, 0.0);
    let mut observations = a.observations.clone();
    observations.extend(b.observations.iter().map(|o| Observation {
        point: o.point + 100_000,
        photo: o.photo + 6,
        ..*o
    }));
    // One camera group per room (its vignetting estimated), so that the rooms share no unknown.
    let groups: Vec<u32> = (0..12).map(|p| u32::from(p >= 6)).collect();
    let cal = calibrate(&groups, &observations, &linear_all_estimates()).unwrap();
    assert_eq!(cal.linked_sets, 2);
    assert!(cal.unconstrained.is_empty(), "{:?}", cal.unconstrained);
    let room = |range: std::ops::Range<usize>, truth: &[[f64; 3]]| {
        let part = Calibration { gains: cal.gains[range].to_vec(), ..cal.clone() };
        worst_gain_error(&part, truth)
    };
    let (ea, eb) = (room(0..6, &a.gains), room(6..12, &b.gains));
    println!("unlinked rooms: worst gain error {ea:.5} / {eb:.5}");
    assert!(ea < 0.005 && eb < 0.005, "{ea} {eb}");
}
