//! `pipeline run` through the built binary on the bundled demo scan (data-fixtures/demo): stage skipping and
//! rerun decisions for ingest and preprocess, the artefacts they leave, and `pipeline render` reproducing the
//! scan's photos from its ground-truth materials.

mod common;
use common::{copy_dir, decisions, pipeline};
use std::path::{Path, PathBuf};

fn fixture() -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data-fixtures/demo")).to_path_buf()
}

#[test]
fn ingest_and_preprocess_rerun_exactly_when_their_config_or_inputs_change() {
    let dir = tempfile::tempdir().unwrap();
    copy_dir(&fixture(), &dir.path().join("scan"));
    let cfg = dir.path().join("run.toml");
    std::fs::write(&cfg, "[scan]\npath = \"scan\"\n[output]\npath = \"out\"\n").unwrap();
    let cfg = cfg.to_str().unwrap();
    let until = ["--until", "preprocess"];

    let (code, err) = pipeline(&[&["run", cfg][..], &until].concat());
    assert_eq!(code, 0, "{err}");
    assert_eq!(decisions(&err, "running"), ["ingest", "preprocess"], "{err}");
    let out = dir.path().join("out");
    for f in ["ingest/manifest.json", "ingest/mesh.ply", "ingest/scene.json", "preprocess/views.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let views: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("preprocess/views.json")).unwrap()).unwrap();
    assert_eq!(views["views"].as_array().unwrap().len(), 8);
    let scene = workflow::artefacts::ingest::Ingested::read(&out).unwrap();
    let gt: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture().join("ground_truth_materials.json")).unwrap()).unwrap();
    let gt_tris: usize =
        gt["objects"].as_array().unwrap().iter().map(|o| o["triangles"].as_u64().unwrap() as usize).sum();
    assert_eq!(scene.triangles.len(), gt_tris);
    assert_eq!(scene.objects.len(), gt["objects"].as_array().unwrap().len());

    let (code, err) = pipeline(&[&["run", cfg][..], &until].concat());
    assert_eq!(code, 0, "{err}");
    assert_eq!(decisions(&err, "skipped"), ["ingest", "preprocess"], "{err}");
    assert!(decisions(&err, "running").is_empty(), "{err}");

    let (code, err) = pipeline(&[&["run", cfg, "--set", "images.every=2"][..], &until].concat());
    assert_eq!(code, 0, "{err}");
    assert_eq!(decisions(&err, "skipped"), ["ingest"], "{err}");
    assert_eq!(decisions(&err, "running"), ["preprocess"], "{err}");
    assert!(err.contains("[preprocess] running: its config section changed"), "{err}");
    let views: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("preprocess/views.json")).unwrap()).unwrap();
    assert_eq!(views["views"].as_array().unwrap().len(), 4);

    // A changed scan file reruns ingest and everything after it.
    let conf = dir.path().join("scan/undistorted_camera_parameters/demo.conf");
    let text = std::fs::read_to_string(&conf).unwrap();
    std::fs::write(&conf, text.replace("dataset matterport", "dataset  matterport")).unwrap();
    let (code, err) = pipeline(&[&["run", cfg, "--set", "images.every=2"][..], &until].concat());
    assert_eq!(code, 0, "{err}");
    assert_eq!(decisions(&err, "running"), ["ingest", "preprocess"], "{err}");
    assert!(err.contains("file:undistorted_camera_parameters/demo.conf"), "{err}");
}

fn read_rgb(path: &Path) -> Vec<[f32; 3]> {
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![[0f32; 3]; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b]
        },
    )
    .unwrap();
    img.layer_data.channel_data.pixels.1
}

#[test]
fn render_with_the_true_materials_reproduces_the_photos() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("run.toml");
    let scan = fixture();
    std::fs::write(&cfg, format!("[scan]\npath = {:?}\n[output]\npath = \"out\"\n", scan.to_str().unwrap())).unwrap();
    let (code, err) = pipeline(&["run", cfg.to_str().unwrap(), "--until", "ingest"]);
    assert_eq!(code, 0, "{err}");
    // Two of the scan's cameras; the photos are our tracer's renders at 1024 paths per pixel.
    let conf_text = std::fs::read_to_string(scan.join("undistorted_camera_parameters/demo.conf")).unwrap();
    let keep: Vec<&str> = conf_text
        .lines()
        .filter(|l| l.starts_with("intrinsics_matrix") || l.contains("demo_i0_0.") || l.contains("demo_i0_5."))
        .collect();
    let conf = dir.path().join("two.conf");
    std::fs::write(&conf, keep.join("\n")).unwrap();
    let renders = dir.path().join("renders");
    let (code, err) = pipeline(&[
        "render",
        dir.path().join("out").to_str().unwrap(),
        "--cameras",
        conf.to_str().unwrap(),
        "--output",
        renders.to_str().unwrap(),
        "--spp",
        "16",
        "--width",
        "96",
        "--height",
        "72",
        "--materials",
        scan.join("ground_truth_materials.json").to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    for name in ["demo_i0_0", "demo_i0_5"] {
        let ours = read_rgb(&renders.join(format!("{name}.exr")));
        let photo = read_rgb(&scan.join(format!("undistorted_color_images/{name}.exr")));
        assert_eq!(ours.len(), photo.len());
        // Mean radiance over ~7000 pixels: Monte Carlo noise of 16 spp averages down to well under 1 %, so a
        // 2 % difference would mean a wrong camera, material mapping or emission unit.
        for c in 0..3 {
            let m_ours: f64 = ours.iter().map(|p| f64::from(p[c])).sum::<f64>() / ours.len() as f64;
            let m_photo: f64 = photo.iter().map(|p| f64::from(p[c])).sum::<f64>() / photo.len() as f64;
            assert!((m_ours / m_photo - 1.0).abs() < 0.02, "{name} channel {c}: {m_ours} vs {m_photo}");
        }
        // Per pixel: a wrong pose would move edges; the mean absolute difference stays at the noise level.
        let mad: f64 = ours
            .iter()
            .zip(&photo)
            .map(|(a, b)| (0..3).map(|c| f64::from((a[c] - b[c]).abs())).sum::<f64>())
            .sum::<f64>()
            / (3 * ours.len()) as f64;
        let mean: f64 = photo.iter().map(|p| f64::from(p[0] + p[1] + p[2])).sum::<f64>() / (3 * photo.len()) as f64;
        assert!(mad / mean < 0.15, "{name}: mean |render − photo| is {:.1} % of the mean", 100.0 * mad / mean);
    }
}
