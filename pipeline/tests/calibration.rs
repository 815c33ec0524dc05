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
