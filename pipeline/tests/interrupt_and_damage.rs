//! Interruptions, damaged files and failed writes, through the built binary on the bundled demo scan with a
//! tiny fit:
//! - SIGINT and SIGTERM during `object` stop the run with a message, a checkpoint and exit code 130 / 143;
//!   the rerun resumes and ends with exactly the uninterrupted result;
//! - a checkpoint that is damaged or from another version is refused with a message (the stage starts afresh,
//!   and still ends with the uninterrupted result);
//! - a damaged artefact (one flipped byte, or truncated) makes its stage rerun with a message naming it;
//! - a write that fails as on a full disk ends the run with one line naming the file, leaves no temporary
//!   file, and every finished stage is kept and skipped by the next run.

mod common;
use common::{decisions, pipeline};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

const ITERATIONS: u32 = 150;

fn fixture() -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data-fixtures/demo")).to_path_buf()
}

/// A tiny fit (as in resume.rs): quarter-resolution photos, half the views, few paths, a checkpoint every
/// iteration, enough iterations that the fit is still running well after its first checkpoints.
fn write_config(dir: &Path) -> PathBuf {
    let cfg = dir.join("run.toml");
    let text = format!(
        "[scan]\npath = {scan:?}\n[output]\npath = \"out\"\n[images]\ndownscale = 4\nevery = 2\n[tracer]\nmax_depth = 3\n\
         [object]\niterations = {ITERATIONS}\nbatch_pixels = 32\nn_value = 8\ncheckpoint_every = 1\n\
         emission_solve_every = 0\nsolve_pixels = 128\nsolve_spp = 4\nrefine_steps = 2\ntry_specular = false\nseed = 7\n\
         [triangle]\nenabled = false\n[export]\nreport_spp = 4\nreport_views = 2\n",
        scan = fixture().to_str().unwrap()
    );
    std::fs::write(&cfg, text).unwrap();
    cfg
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

fn checkpoint_iteration(path: &Path) -> Option<u64> {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| v["state"]["iteration"].as_u64())
}

/// Starts a run, waits for a checkpoint at iteration ≥ 3, sends `signal` (`INT`, `TERM`) and returns the exit
/// code and stderr.
fn run_and_signal(cfg: &Path, out: &Path, signal: &str) -> (i32, String) {
    let checkpoint = out.join("object/checkpoint.json");
    let child = Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(["run", cfg.to_str().unwrap()])
        .env_remove("RUST_LOG")
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    loop {
        if checkpoint_iteration(&checkpoint).is_some_and(|i| i >= 3) {
            let ok = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status().unwrap();
            assert!(ok.success());
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let done = child.wait_with_output().unwrap();
    (done.status.code().unwrap_or(-1), String::from_utf8_lossy(&done.stderr).into_owned())
}

fn no_temporaries(dir: &Path) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        assert!(!name.contains(".tmp."), "temporary file left behind: {}", e.path().display());
        if e.file_type().unwrap().is_dir() {
            no_temporaries(&e.path());
        }
    }
}

fn edit_checkpoint(path: &Path, f: impl FnOnce(&mut serde_json::Value)) {
    let mut v = json(path);
    f(&mut v);
    std::fs::write(path, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
}

#[test]
fn signals_stop_with_a_checkpoint_and_bad_checkpoints_are_refused() {
    let reference = tempfile::tempdir().unwrap();
    let cfg = write_config(reference.path());
    let (code, err) = pipeline(&["run", cfg.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let want = json(&reference.path().join("out/materials.json"));

    for (signal, code_want) in [("INT", 130), ("TERM", 143)] {
        let dir = tempfile::tempdir().unwrap();
        let cfg = write_config(dir.path());
        let out = dir.path().join("out");
        let (code, err) = run_and_signal(&cfg, &out, signal);
        assert_eq!(code, code_want, "SIG{signal}: {err}");
        let last = err.lines().last().unwrap_or_default();
        assert!(last.starts_with(&format!("interrupted by SIG{signal}")), "SIG{signal}: {err}");
        assert!(out.join("object/checkpoint.json").is_file(), "SIG{signal}: no checkpoint");
        assert!(!out.join("object/manifest.json").exists(), "an interrupted stage must not look finished");
        assert!(out.join("preprocess/manifest.json").is_file());
        no_temporaries(&out);

        let (code, err) = pipeline(&["run", cfg.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        assert_eq!(decisions(&err, "skipped")[..2], ["ingest", "preprocess"], "{err}");
        assert!(err.contains("[object] resuming from the checkpoint at iteration "), "{err}");
        assert_eq!(json(&out.join("materials.json")), want, "SIG{signal}: resumed result differs");
    }

    // A damaged checkpoint (one value changed, digest kept) and one from another version are refused; the
    // fit starts afresh and still ends with the uninterrupted result.
    for (what, edit) in [
        (
            "it is damaged",
            Box::new(|v: &mut serde_json::Value| v["state"]["params"][0] = 0.123.into()) as Box<dyn Fn(&mut _)>,
        ),
        (
            "it was written by version",
            Box::new(|v: &mut serde_json::Value| v["program_version"] = "0.0.0-other".into()),
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let cfg = write_config(dir.path());
        let out = dir.path().join("out");
        let (code, err) = run_and_signal(&cfg, &out, "INT");
        assert_eq!(code, 130, "{err}");
        edit_checkpoint(&out.join("object/checkpoint.json"), edit);
        let (code, err) = pipeline(&["run", cfg.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        assert!(err.contains(&format!("[object] checkpoint not resumed: {what}")), "{err}");
        assert!(!err.contains("resuming from the checkpoint"), "{err}");
        assert_eq!(json(&out.join("materials.json")), want, "{what}: result differs");
    }
}

#[test]
fn damaged_artefacts_rerun_their_stage_and_a_failed_write_keeps_finished_stages() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_config(dir.path());
    let cfg = cfg.to_str().unwrap();
    let out = dir.path().join("out");

    // A full disk when the object stage writes its result: one line naming the file, exit 1, no temporary
    // file, the earlier stages kept.
    let run = Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(["run", cfg])
        .env_remove("RUST_LOG")
        .env("IPT_FAULT_WRITE", "object/materials.json")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{err}");
    let last = err.lines().last().unwrap_or_default();
    assert!(last.starts_with("error: ") && last.contains("object/materials.json"), "{err}");
    assert!(last.contains("No space left on device"), "{err}");
    assert!(out.join("ingest/manifest.json").is_file() && out.join("preprocess/manifest.json").is_file());
    assert!(!out.join("object/manifest.json").exists());
    no_temporaries(&out);

    let (code, err) = pipeline(&["run", cfg]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(decisions(&err, "skipped"), ["ingest", "preprocess"], "{err}");
    let want = json(&out.join("materials.json"));

    // One flipped byte in a cached photo (same size): preprocess reruns, saying which file and why.
    let cached = std::fs::read_dir(out.join("preprocess"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|e| e == "exr"))
        .unwrap();
    let mut bytes = std::fs::read(&cached).unwrap();
    let at = bytes.len() / 2;
    bytes[at] ^= 0x10;
    std::fs::write(&cached, &bytes).unwrap();
    let (code, err) = pipeline(&["run", cfg]);
    assert_eq!(code, 0, "{err}");
    let name = cached.file_name().unwrap().to_string_lossy().into_owned();
    assert!(err.contains(&format!("[preprocess] running: output preprocess/{name} is damaged")), "{err}");
    assert_eq!(decisions(&err, "skipped"), ["ingest"], "{err}");
    assert_eq!(json(&out.join("materials.json")), want);

    // A truncated mesh: ingest reruns, and so does everything after it.
    let mesh = out.join("ingest/mesh.ply");
    let len = std::fs::metadata(&mesh).unwrap().len();
    std::fs::OpenOptions::new().write(true).open(&mesh).unwrap().set_len(len / 2).unwrap();
    let (code, err) = pipeline(&["run", cfg]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("[ingest] running: output ingest/mesh.ply is damaged"), "{err}");
    assert!(decisions(&err, "skipped").is_empty(), "{err}");
    assert_eq!(json(&out.join("materials.json")), want);
}
