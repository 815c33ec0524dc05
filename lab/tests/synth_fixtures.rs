//! The synthetic scan generator: layout, determinism, the hidden-light check, and (on request) regeneration
//! of the committed fixture `data-fixtures/demo/`.

use std::path::{Path, PathBuf};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures")
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn small_scene_is_written_in_the_matterport_layout_and_deterministically() {
    let desc = fixtures().join("scenes/small.toml");
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    lab::synth::generate(&desc, a.path()).unwrap();
    lab::synth::generate(&desc, b.path()).unwrap();
    let files = [
        "house_segmentations/small.ply",
        "house_segmentations/small.semseg.json",
        "house_segmentations/small.fsegs.json",
        "undistorted_camera_parameters/small.conf",
        "undistorted_color_images/small_i0_0.exr",
        "undistorted_color_images/small_i0_3.exr",
        "ground_truth_materials.json",
    ];
    for f in files {
        assert_eq!(read(&a.path().join(f)), read(&b.path().join(f)), "{f} differs between two runs");
    }
    let conf = String::from_utf8(read(&a.path().join("undistorted_camera_parameters/small.conf"))).unwrap();
    assert_eq!(conf.lines().filter(|l| l.starts_with("scan ")).count(), 4);
    assert_eq!(conf.lines().filter(|l| l.starts_with("intrinsics_matrix ")).count(), 1);
    for line in conf.lines().filter(|l| l.starts_with("scan ")) {
        // depth name, colour name, 16 matrix entries; last row of a rigid transform is 0 0 0 1.
        let f: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(f.len(), 19, "{line}");
        let m: Vec<f64> = f[3..].iter().map(|x| x.parse().unwrap()).collect();
        assert_eq!(&m[12..], &[0.0, 0.0, 0.0, 1.0]);
    }
    let ply = read(&a.path().join("house_segmentations/small.ply"));
    let header_end = ply.windows(11).position(|w| w == b"end_header\n").unwrap();
    let header = String::from_utf8_lossy(&ply[..header_end]);
    for p in ["property int material_id", "property int segment_id", "property int category_id"] {
        assert!(header.contains(p), "missing {p}");
    }
    let gt: serde_json::Value = serde_json::from_slice(&read(&a.path().join("ground_truth_materials.json"))).unwrap();
    assert_eq!(gt["format"], "ipt-materials/1");
    let emitters: Vec<_> = gt["objects"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|o| o["model"].as_str().unwrap().contains("emission"))
        .collect();
    assert_eq!(emitters.len(), 1);
}

#[test]
fn a_camera_that_sees_a_hidden_object_is_rejected() {
    let text = std::fs::read_to_string(fixtures().join("scenes/small.toml")).unwrap();
    // Look straight up at the light from below it.
    let text = text + "\n[[cameras]]\neye = [1.5, 1.25, 1.0]\ntarget = [1.5, 1.25, 2.2]\nup = [0, 1, 0]\n";
    let dir = tempfile::tempdir().unwrap();
    let desc = dir.path().join("seen.toml");
    std::fs::write(&desc, text).unwrap();
    let err = lab::synth::generate(&desc, &dir.path().join("out")).unwrap_err();
    assert!(matches!(err, lab::synth::SynthError::HiddenSeen { camera: 4, object: 17, .. }), "{err}");
}

/// Regenerates `data-fixtures/demo/` from `data-fixtures/scenes/demo.toml` when IPT_REGENERATE_FIXTURES is set.
#[test]
fn regenerate_demo_fixture_on_request() {
    if std::env::var_os("IPT_REGENERATE_FIXTURES").is_none() {
        eprintln!("skipping: set IPT_REGENERATE_FIXTURES=1 to regenerate data-fixtures/demo");
        return;
    }
    let out = fixtures().join("demo");
    lab::synth::generate(&fixtures().join("scenes/demo.toml"), &out).unwrap();
}
