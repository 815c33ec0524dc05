//! The preprocess stage's photometric calibration through the built binary: on a scan whose photos were taken
//! at different exposures (the bundled demo's linear EXR photos, each scaled by its own factor) the per-photo
//! gains must come out as those factors, every view kept, and the estimates recorded in
//! `preprocess/calibration.json`; on the demo as it is (one exposure) the calibration is declined.

mod common;
use common::{copy_dir, pipeline};
use ingest::photo::exr::{Compression, encode_rgb_interleaved};
use ingest::photo::{DecodedImage, read_image};
use std::path::Path;

/// Photo i of the demo's eight is scaled by `EXPOSURES[i]` (±1 EV and between).
const EXPOSURES: [f32; 8] = [1.0, 2.0, 0.5, 1.5, 0.75, 1.25, 0.6, 1.8];

/// Scales the demo scan's photo i by `EXPOSURES[i]`.
fn vary_exposures(scan: &Path) {
    let photos = scan.join("undistorted_color_images");
    for (i, k) in EXPOSURES.iter().enumerate() {
        let path = photos.join(format!("demo_i0_{i}.exr"));
        let DecodedImage::Linear(img) = read_image(&path).unwrap() else { panic!("{}: not linear", path.display()) };
        let rgb: Vec<f32> = img.rgb.iter().map(|v| v * k).collect();
        std::fs::write(&path, encode_rgb_interleaved(img.width, img.height, Compression::Fast, &rgb).unwrap()).unwrap();
    }
}

#[test]
fn different_exposures_calibrate_to_their_ratios_and_one_exposure_is_declined() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scan");
    copy_dir(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data-fixtures/demo")), &scan);
    let cfg = dir.path().join("run.toml");
    std::fs::write(
        &cfg,
        "[scan]\npath = \"scan\"\n[output]\npath = \"out\"\n[images]\nexposure = \"per_photo\"\n\
         white_balance = \"per_photo\"\nvignetting = \"estimate\"\n",
    )
    .unwrap();
    // One exposure: gains and vignetting do not predict held-out observations better than none.
    let (code, err) = pipeline(&["run", cfg.to_str().unwrap(), "--until", "preprocess"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("photometric calibration skipped") && err.contains("no better than one exposure"), "{err}");
    let out = dir.path().join("out");
    assert!(workflow::artefacts::preprocess::CalibrationFile::read(&out).unwrap().is_none());

    vary_exposures(&scan);
    let (code, err) = pipeline(&["run", cfg.to_str().unwrap(), "--until", "preprocess"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("calibrated 8 of 8 views"), "{err}");
    let cal = workflow::artefacts::preprocess::CalibrationFile::read(&out).unwrap().expect("calibration.json");
    assert_eq!(cal.response_mode, "linear");
    assert_eq!(cal.views.len(), 8);
    // Gains have a geometric mean of 1: compare with the exposures over theirs.
    let mean = (EXPOSURES.iter().map(|k| f64::from(*k).ln()).sum::<f64>() / 8.0).exp();
    for v in &cal.views {
        let g = v.gain.unwrap_or_else(|| panic!("{} left out: {:?}", v.name, v.left_out));
        let i: usize = v.name.rsplit('_').next().unwrap().parse().unwrap();
        let want = f64::from(EXPOSURES[i]) / mean;
        // The estimate may differ from the truth only by its noise (0.5 %).
        assert!(g.iter().all(|x| (x / want - 1.0).abs() <= 0.005), "{}: gain {g:?}, want {want}", v.name);
    }
    for c in &cal.cameras {
        assert!((c.corner - 1.0).abs() <= 0.01, "camera {}: corner falloff {}", c.camera, c.corner);
    }
    let views: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("preprocess/views.json")).unwrap()).unwrap();
    assert_eq!(views["views"].as_array().unwrap().len(), 8);
}

/// A scan photographed through a consumer camera (per-photo auto exposure and white balance, vignetting, a
/// filmic tone curve, JPEG; `data-fixtures/scenes/camera.toml` at a quarter of its pixels): the preprocess
/// stage recovers every photo's gain and every camera's vignetting up to the one power the photos alone
/// cannot fix, and says that this power is open.
#[test]
fn consumer_camera_scan_calibrates_up_to_one_common_power() {
    let dir = tempfile::tempdir().unwrap();
    let desc = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data-fixtures/scenes/camera.toml"));
    let text = std::fs::read_to_string(desc)
        .unwrap()
        .replace("width = 128", "width = 64")
        .replace("height = 96", "height = 48");
    let small = dir.path().join("camera.toml");
    std::fs::write(&small, text).unwrap();
    lab::synth::generate(&small, &dir.path().join("scan")).unwrap();
    let cfg = dir.path().join("run.toml");
    std::fs::write(
        &cfg,
        "[scan]\npath = \"scan\"\n[output]\npath = \"out\"\n[images]\nresponse = \"estimate\"\nexposure = \"per_photo\"\n\
         white_balance = \"per_photo\"\nvignetting = \"estimate\"\n",
    )
    .unwrap();
    let (code, err) = pipeline(&["run", cfg.to_str().unwrap(), "--until", "preprocess"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("not fixed by the photos alone"), "{err}");
    let cal = workflow::artefacts::preprocess::CalibrationFile::read(&dir.path().join("out")).unwrap().unwrap();
    assert!(!cal.exponent_reliable);
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("scan/ground_truth_camera.json")).unwrap())
            .unwrap();
    // Log gains, each side centred per channel: estimate = s · truth for one s.
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    for c in 0..3 {
        let mut est: Vec<f64> = Vec::new();
        let mut tru: Vec<f64> = Vec::new();
        for v in &cal.views {
            let g = v.gain.unwrap_or_else(|| panic!("{} left out: {:?}", v.name, v.left_out));
            est.push(g[c].ln());
            tru.push(truth["photos"][&v.name]["gain"][c].as_f64().unwrap().ln());
        }
        let (me, mt) = (est.iter().sum::<f64>() / est.len() as f64, tru.iter().sum::<f64>() / tru.len() as f64);
        pairs.extend(est.iter().zip(&tru).map(|(e, t)| (e - me, t - mt)));
    }
    let s = pairs.iter().map(|(e, t)| e * t).sum::<f64>() / pairs.iter().map(|(_, t)| t * t).sum::<f64>();
    assert!(s > 0.2 && s < 5.0, "common power {s}");
    let worst = pairs.iter().map(|(e, t)| (e - s * t).abs()).fold(0.0, f64::max);
    // After the common power, each gain within 3 % (the estimator's own synthetic bound is 2 % on 10⁴ points;
    // this scan has a quarter of the fixture's pixels and JPEG noise).
    assert!(worst < 0.03, "worst log-gain residual {worst} after the power {s}");
    for cam in &cal.cameras {
        let t = truth["vignetting"]["cameras"][cam.camera as usize]["corner"].as_f64().unwrap();
        let expected = t.powf(s);
        assert!(
            (cam.corner / expected - 1.0).abs() < 0.03,
            "camera {}: corner {} vs {expected}",
            cam.camera,
            cam.corner
        );
    }
}

/// The default config estimates per-photo exposure and white balance (here of photos at different exposures).
/// A single photo cannot be compared with
/// another: the stage says so and prepares it with one exposure instead of failing. A later run that does not
/// calibrate removes the calibration an earlier run left, so that no later stage reads stale estimates.
#[test]
fn one_photo_falls_back_to_one_exposure_and_a_stale_calibration_is_removed() {
    let dir = tempfile::tempdir().unwrap();
    copy_dir(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data-fixtures/demo")), &dir.path().join("scan"));
    vary_exposures(&dir.path().join("scan"));
    let out = dir.path().join("out");
    let run = |images: &str| {
        let cfg = dir.path().join("run.toml");
        std::fs::write(&cfg, format!("[scan]\npath = \"scan\"\n[output]\npath = \"out\"\n[images]\n{images}\n"))
            .unwrap();
        pipeline(&["run", cfg.to_str().unwrap(), "--until", "preprocess"])
    };
    // The defaults, all eight photos at their own exposures: calibrated.
    let (code, err) = run("");
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("calibrated 8 of 8 views"), "{err}");
    assert!(workflow::artefacts::preprocess::CalibrationFile::read(&out).unwrap().is_some());
    // Fixed exposure and white balance: nothing to calibrate, and the earlier estimates are gone.
    let (code, err) = run("exposure = \"fixed\"\nwhite_balance = \"fixed\"");
    assert_eq!(code, 0, "{err}");
    assert!(workflow::artefacts::preprocess::CalibrationFile::read(&out).unwrap().is_none(), "{err}");
    // The defaults, one photo: the fallback.
    let (code, err) = run("every = 8");
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("photometric calibration skipped"), "{err}");
    assert!(workflow::artefacts::preprocess::CalibrationFile::read(&out).unwrap().is_none());
    let views: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("preprocess/views.json")).unwrap()).unwrap();
    assert_eq!(views["views"].as_array().unwrap().len(), 1);
}
