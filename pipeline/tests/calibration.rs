//! The preprocess stage's photometric calibration through the built binary: on a scan photographed with one
//! exposure and no vignetting (the bundled demo, linear EXR photos) the per-photo estimates must come out as
//! the identity, every view kept, and the estimates recorded in `preprocess/calibration.json`.

mod common;
use common::{copy_dir, pipeline};
use std::path::Path;

#[test]
fn single_exposure_scan_calibrates_to_unit_gains_and_no_vignetting() {
    let dir = tempfile::tempdir().unwrap();
    copy_dir(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data-fixtures/demo")), &dir.path().join("scan"));
    let cfg = dir.path().join("run.toml");
    std::fs::write(
        &cfg,
        "[scan]\npath = \"scan\"\n[output]\npath = \"out\"\n[images]\nexposure = \"per_photo\"\n\
         white_balance = \"per_photo\"\nvignetting = \"estimate\"\n",
    )
    .unwrap();
    let (code, err) = pipeline(&["run", cfg.to_str().unwrap(), "--until", "preprocess"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("calibrated 8 of 8 views"), "{err}");
    let out = dir.path().join("out");
    let cal = workflow::artefacts::preprocess::CalibrationFile::read(&out).unwrap().expect("calibration.json");
    assert_eq!(cal.response_mode, "linear");
    assert_eq!(cal.views.len(), 8);
    for v in &cal.views {
        let g = v.gain.unwrap_or_else(|| panic!("{} left out: {:?}", v.name, v.left_out));
        // One exposure: the estimate may differ from 1 only by its noise (the bound: 0.5 %).
        assert!(g.iter().all(|x| (x - 1.0).abs() <= 0.005), "{}: gain {g:?}", v.name);
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

/// The default config estimates per-photo exposure and white balance. A single photo cannot be compared with
/// another: the stage says so and prepares it with one exposure instead of failing. A later run that does not
/// calibrate removes the calibration an earlier run left, so that no later stage reads stale estimates.
#[test]
fn one_photo_falls_back_to_one_exposure_and_a_stale_calibration_is_removed() {
    let dir = tempfile::tempdir().unwrap();
    copy_dir(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data-fixtures/demo")), &dir.path().join("scan"));
    let out = dir.path().join("out");
    let run = |images: &str| {
        let cfg = dir.path().join("run.toml");
        std::fs::write(&cfg, format!("[scan]\npath = \"scan\"\n[output]\npath = \"out\"\n[images]\n{images}\n"))
            .unwrap();
        pipeline(&["run", cfg.to_str().unwrap(), "--until", "preprocess"])
    };
    // The defaults, all eight photos: calibrated.
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
