//! Stage resume through the built binary on the bundled demo scan with a tiny, fast fit config:
//! rerun → every stage skipped; an `object` key changed → object and export rerun, earlier stages skipped;
//! a pixel budget below the photos' pixels → a larger downscale, noted in the log and the report;
//! SIGKILL during `object` → the rerun resumes from the checkpoint and ends with exactly the result of an
//! uninterrupted run with the same seed.

mod common;
use common::{decisions, pipeline};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn fixture() -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data-fixtures/demo")).to_path_buf()
}

/// A tiny fit: quarter-resolution photos, half the views, few paths, no specular trial. Fast, not accurate.
fn write_config(dir: &Path, iterations: u32) -> PathBuf {
    let cfg = dir.join("run.toml");
    let text = format!(
        "[scan]\npath = {scan:?}\n[output]\npath = \"out\"\n[images]\ndownscale = 4\nevery = 2\n[tracer]\nmax_depth = 3\n\
         [object]\niterations = {iterations}\nbatch_pixels = 32\nn_value = 8\ncheckpoint_every = 1\n\
         emission_solve_every = 0\nsolve_pixels = 128\nsolve_spp = 4\nrefine_steps = 2\ntry_specular = false\nseed = 7\n\
         [export]\nreport_spp = 4\nreport_views = 2\n",
        scan = fixture().to_str().unwrap()
    );
    std::fs::write(&cfg, text).unwrap();
    cfg
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

#[test]
fn rerun_skips_every_stage_and_an_object_key_reruns_object_and_later() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_config(dir.path(), 6);
    let cfg = cfg.to_str().unwrap();

    let (code, err) = pipeline(&["run", cfg]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(decisions(&err, "running"), ["ingest", "preprocess", "object", "triangle", "export"], "{err}");
    let out = dir.path().join("out");
    let materials = workflow::materials::MaterialsFile::read(&out.join("materials.json")).unwrap();
    assert_eq!(materials.objects.len(), 9);
    assert!(!out.join("object/checkpoint.json").exists(), "checkpoint left behind after a finished fit");
    for f in ["export/report.html", "export/trajectories.csv", "object/history.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let report = std::fs::read_to_string(out.join("export/report.html")).unwrap();
    assert!(report.contains("photos prepared at 24×18 from 96×72 (downscale 4)"), "{report}");

    let (code, err) = pipeline(&["run", cfg]);
    assert_eq!(code, 0, "{err}");
    assert!(decisions(&err, "running").is_empty(), "{err}");
    assert_eq!(decisions(&err, "skipped"), ["ingest", "preprocess", "object", "triangle", "export"], "{err}");

    let (code, err) = pipeline(&["run", cfg, "--set", "object.lr=0.05"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(decisions(&err, "running"), ["object", "triangle", "export"], "{err}");
    assert_eq!(decisions(&err, "skipped"), ["ingest", "preprocess"], "{err}");
    assert!(err.contains("[object] running: its config section changed"), "{err}");
    assert!(err.contains("[triangle] running: upstream stage `object` reran"), "{err}");
    assert!(err.contains("[export] running: upstream stage `object` reran"), "{err}");

    // Back to the first config: object reruns again (its manifest now records lr = 0.05) and is
    // deterministic, so materials.json is what the first run wrote.
    let (code, err) = pipeline(&["run", cfg]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(decisions(&err, "running"), ["object", "triangle", "export"], "{err}");
    let again = workflow::materials::MaterialsFile::read(&out.join("materials.json")).unwrap();
    assert_eq!(again, materials);

    // A pixel budget below the 4 views' 1728 pixels raises the downscale to the smallest factor that fits:
    // 5 leaves 4 × 19 × 14 = 1064 pixels, 6 leaves 4 × 16 × 12 = 768.
    let (code, err) = pipeline(&["run", cfg, "--set", "images.max_pixels=1000"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("[preprocess] downscale 6 instead of 4"), "{err}");
    let report = std::fs::read_to_string(out.join("export/report.html")).unwrap();
    assert!(
        report.contains("photos prepared at 16×12 from 96×72 (downscale 6, raised from images.downscale = 4"),
        "{report}"
    );
}

#[test]
fn sigkill_during_object_resumes_from_the_checkpoint_with_the_uninterrupted_result() {
    // Enough iterations that the fit is still running well after its first checkpoints.
    const ITERATIONS: u32 = 150;
    let reference = tempfile::tempdir().unwrap();
    let cfg = write_config(reference.path(), ITERATIONS);
    let (code, err) = pipeline(&["run", cfg.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");

    let dir = tempfile::tempdir().unwrap();
    let cfg = write_config(dir.path(), ITERATIONS);
    let out = dir.path().join("out");
    let checkpoint = out.join("object/checkpoint.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(["run", cfg.to_str().unwrap()])
        .env_remove("RUST_LOG")
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Wait for a checkpoint a few iterations in (the file is replaced atomically, so any read is whole).
    let killed_at = loop {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before a checkpoint at iteration ≥ 3 was seen");
        }
        let it = std::fs::read_to_string(&checkpoint)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| v["state"]["iteration"].as_u64());
        if let Some(it) = it.filter(|&i| i >= 3) {
            child.kill().unwrap(); // SIGKILL on Unix
            child.wait().unwrap();
            break it;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    assert!(!out.join("object/manifest.json").exists(), "killed stage must not look finished");
    assert!(checkpoint.is_file());

    let (code, err) = pipeline(&["run", cfg.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(decisions(&err, "skipped")[..2], ["ingest", "preprocess"], "{err}");
    let resumed_at: u64 = err
        .lines()
        .find_map(|l| l.strip_prefix("[object] resuming from the checkpoint at iteration "))
        .unwrap_or_else(|| panic!("no resume line in: {err}"))
        .trim()
        .parse()
        .unwrap();
    assert!(resumed_at >= killed_at, "resumed at {resumed_at}, killed after checkpoint {killed_at}");
    assert!(resumed_at < u64::from(ITERATIONS), "the kill came after the last Adam checkpoint: {resumed_at}");

    let r = reference.path().join("out");
    assert_eq!(json(&out.join("object/materials.json")), json(&r.join("object/materials.json")));
    assert_eq!(json(&out.join("object/history.json")), json(&r.join("object/history.json")));
    assert_eq!(json(&out.join("materials.json")), json(&r.join("materials.json")));
}
