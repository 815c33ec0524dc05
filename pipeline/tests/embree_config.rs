//! `IPT_EMBREE_CONFIG` through the built binary: a bad value is a config error (exit 2, one line naming the
//! variable) found before any stage runs; a good one is reported with the kernels it selects.

mod common;
use std::path::Path;
use std::process::Command;

fn run_with(config: &str, dir: &Path) -> (Option<i32>, String) {
    let cfg = dir.join("run.toml");
    let scan = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/demo");
    std::fs::write(&cfg, format!("[scan]\npath = {:?}\n[output]\npath = \"out\"\n", scan.to_str().unwrap())).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(["run", cfg.to_str().unwrap(), "--until", "ingest"])
        .env("IPT_EMBREE_CONFIG", config)
        .env_remove("RUST_LOG")
        .output()
        .unwrap();
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn bad_embree_config_exits_2_before_any_stage() {
    for bad in ["max_isa=avx3", "maxisa=sse4.2", "verbose"] {
        let dir = tempfile::tempdir().unwrap();
        let (code, err) = run_with(bad, dir.path());
        assert_eq!(code, Some(2), "{bad}: {err}");
        let lines: Vec<&str> = err.lines().collect();
        assert_eq!(lines.len(), 1, "{bad}: expected one line, got {err:?}");
        assert!(lines[0].contains("IPT_EMBREE_CONFIG"), "{bad}: {err}");
        assert!(!dir.path().join("out/ingest").exists(), "{bad}: ingest ran");
    }
}

#[test]
fn embree_kernels_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let (code, err) = run_with("max_isa=sse4.2", dir.path());
    assert_eq!(code, Some(0), "{err}");
    assert!(err.lines().any(|l| l.starts_with("embree: ") && l.contains("max_isa=sse4.2, 4-wide kernels")), "{err}");
    assert_eq!(common::decisions(&err, "running"), ["ingest"], "{err}");
}
