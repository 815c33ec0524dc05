//! Self-calibration of Debevec's Memorial bracket from the photos alone, checked against the listed shutter
//! times and against OpenCV's `CalibrateDebevec` given those times. Skips (with a message) when the data set
//! is not at `<repo>/../shared/data/debevec-memorial`.

use std::path::PathBuf;

use ingest::photo::calibrate::{CalibrationOptions, GammaSource, ResponseChannels, ResponseMode, calibrate_bracket};
use ingest::photo::response::bracket;
use ingest::photo::{DecodedImage, ResponseCurve, read_image, recover_response, recover_response_sampled};

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/debevec-memorial")
}

/// Exposure times in seconds from `memorial.hdr_image_list.txt` (its second column is 1/shutter time).
fn exposure_times(dir: &std::path::Path) -> Vec<(String, f64)> {
    let text = std::fs::read_to_string(dir.join("memorial.hdr_image_list.txt")).unwrap();
    text.lines()
        .filter(|l| l.starts_with("memorial"))
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f[0].replace(".ppm", ".png"), 1.0 / f[1].parse::<f64>().unwrap())
        })
        .collect()
}

/// Grid samples of the OpenCV reference curve: its SVD takes about 25 s at 500 (16 photos).
const REFERENCE_SAMPLES: i32 = 500;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Median and largest |ln(a / b)| over channels and codes `lo..=hi`, both curves normalised at code 128.
fn curve_distance(a: &ResponseCurve, b: &ResponseCurve, lo: usize, hi: usize) -> (f64, f64) {
    let mut errors = Vec::new();
    for c in 0..3 {
        for z in lo..=hi {
            let x = f64::from(a.values()[z][c]) / f64::from(a.values()[128][c]);
            let y = f64::from(b.values()[z][c]) / f64::from(b.values()[128][c]);
            errors.push((x / y).ln().abs());
        }
    }
    (median(errors.clone()), errors.iter().copied().fold(0.0, f64::max))
}

#[test]
fn memorial_exposures_and_response_from_the_photos_alone() {
    let dir = data_dir();
    if !dir.join("memorial0061.png").exists() {
        println!("skipped: Memorial bracket not found at {}", dir.display());
        return;
    }
    let listed = exposure_times(&dir);
    assert_eq!(listed.len(), 16);
    let paths: Vec<PathBuf> = listed.iter().map(|(name, _)| dir.join(name)).collect();
    let times: Vec<f64> = listed.iter().map(|(_, t)| *t).collect();
    let images: Vec<_> = paths
        .iter()
        .map(|p| match read_image(p).unwrap() {
            DecodedImage::Display(d) => d,
            DecodedImage::Linear(_) => panic!("{} is not display-referred", p.display()),
        })
        .collect();
    let opts = CalibrationOptions {
        response: ResponseMode::Estimate,
        // Colour film: each dye layer has its own characteristic curve.
        response_channels: ResponseChannels::PerChannel,
        exposure: true,
        white_balance: false,
        vignetting: false,
        seed: 7,
    };
    let cal = calibrate_bracket(&images, &opts).unwrap();
    println!(
        "memorial: {:?} (misfit {:.4}), rms {:.4}, used {}, clipped {}, rejected {}, unconstrained {:?}",
        cal.gamma_source,
        cal.lattice_misfit,
        cal.residual_rms,
        cal.used_observations,
        cal.clipped_channels,
        cal.rejected_channels,
        cal.unconstrained
    );
    let gains: Vec<f64> = cal.gains.iter().map(|g| g.expect("every photo is constrained")[1]).collect();
    let mut worst_ratio = 0.0f64;
    for p in 0..15 {
        let ratio = (gains[p + 1] / gains[p]) / (times[p + 1] / times[p]);
        println!("  photos {p:2}->{:2}: recovered/listed exposure ratio {ratio:.4}", p + 1);
        worst_ratio = worst_ratio.max((ratio - 1.0).abs());
    }

    // OpenCV's curve from its default 70 grid samples moves by about 0.05 in this metric when only its samples
    // change; from 500 grid samples its own sampling noise is about half that (docs/photo/self-calibration.md),
    // so the 500-sample curve is the reference the target is judged against, the 70-sample one is printed.
    let default_ref = recover_response(&bracket(&paths, &times)).unwrap();
    let reference = recover_response_sampled(&bracket(&paths, &times), REFERENCE_SAMPLES).unwrap();
    let ours = cal.response.as_ref().unwrap();
    let compare = |other: &ResponseCurve, lo: usize, hi: usize| curve_distance(ours, other, lo, hi);
    for (lo, hi) in [(3, 15), (16, 31), (32, 63), (64, 127), (128, 191), (192, 249)] {
        println!(
            "  response vs OpenCV ({REFERENCE_SAMPLES} samples), codes {lo}..={hi}: median |ln| {:.4}",
            compare(&reference, lo, hi).0
        );
    }
    let (med, max) = compare(&reference, 3, 249);
    let (med_mid, max_mid) = compare(&reference, 16, 240);
    let (med_default, _) = compare(&default_ref, 3, 249);
    let (ref_vs_default, _) = curve_distance(&reference, &default_ref, 3, 249);
    println!("  worst exposure-ratio error {worst_ratio:.4}");
    println!(
        "  response vs OpenCV ({REFERENCE_SAMPLES} samples): median |ln| {med:.4} (max {max:.3}) over codes 3..=249"
    );
    println!(
        "  response vs OpenCV ({REFERENCE_SAMPLES} samples): median |ln| {med_mid:.4} (max {max_mid:.3}) over codes 16..=240"
    );
    println!("  response vs OpenCV (70 samples, its default): median |ln| {med_default:.4} over codes 3..=249");
    println!("  OpenCV {REFERENCE_SAMPLES} samples vs OpenCV 70 samples: median |ln| {ref_vs_default:.4}");
    // Measured (docs/photo/self-calibration.md): the recovered exposures lie within 0.15 of a step of a
    // one-stop lattice, so the ratios snap to the listed ×2; the exponent rests on the shape prior's choice
    // among multiples of ⅓ EV, so it is not called reliable. Targets: consecutive ratios within 5 %, and the
    // response within a median |ln| of 0.05 of OpenCV's given the listed times.
    assert_eq!(cal.gamma_source, GammaSource::BracketSteps);
    assert!(!cal.gamma_reliable);
    assert!(worst_ratio < 0.05, "{worst_ratio}");
    assert!(med <= 0.05, "{med}");
}
