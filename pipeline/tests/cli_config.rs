//! Bad configs through the built binary: exit code 2 and exactly one line on stderr that names the key.

use std::path::Path;
use std::process::Command;

struct Outcome {
    code: Option<i32>,
    stderr: String,
}

fn run(dir: &Path, config: &str, extra: &[&str]) -> Outcome {
    let cfg = dir.join("run.toml");
    std::fs::write(&cfg, config).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .arg("run")
        .arg(&cfg)
        .args(extra)
        .env_remove("RUST_LOG")
        .output()
        .unwrap();
    Outcome { code: out.status.code(), stderr: String::from_utf8_lossy(&out.stderr).into_owned() }
}

fn assert_config_error(o: &Outcome, key: &str) {
    assert_eq!(o.code, Some(2), "stderr: {}", o.stderr);
    let lines: Vec<&str> = o.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "expected one line, got: {:?}", o.stderr);
    assert!(lines[0].contains(key), "`{key}` not named in: {}", lines[0]);
}

fn scan_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("scan")).unwrap();
    dir
}

#[test]
fn unknown_key_is_named_with_its_table() {
    let d = scan_dir();
    let o = run(d.path(), "[scan]\npath = \"scan\"\n[object]\nlearning_rate = 0.1\n", &[]);
    assert_config_error(&o, "object.learning_rate");
    let o = run(d.path(), "[scan]\npath = \"scan\"\n[sacn]\npath = \"x\"\n", &[]);
    assert_config_error(&o, "sacn");
}

#[test]
fn wrong_type_is_named() {
    let d = scan_dir();
    let o = run(d.path(), "[scan]\npath = \"scan\"\n[object]\niterations = \"many\"\n", &[]);
    assert_config_error(&o, "object.iterations");
    let o = run(d.path(), "[scan]\npath = \"scan\"\n[tracer]\nemission_profile = \"spot\"\n", &[]);
    assert_config_error(&o, "tracer.emission_profile");
}

#[test]
fn missing_or_absent_scan_path_is_named() {
    let d = scan_dir();
    let o = run(d.path(), "[scan]\npath = \"no-such-scan\"\n", &[]);
    assert_config_error(&o, "scan.path");
    let o = run(d.path(), "[scan]\nformat = \"obj\"\n", &[]);
    assert_config_error(&o, "path");
    let o = run(d.path(), "[output]\npath = \"o\"\n", &[]);
    assert_config_error(&o, "scan");
}

#[test]
fn bad_override_is_named() {
    let d = scan_dir();
    let o = run(d.path(), "[scan]\npath = \"scan\"\n", &["--set", "images.downscale=big"]);
    assert_config_error(&o, "images.downscale");
    let o = run(d.path(), "[scan]\npath = \"scan\"\n", &["--set", "scan.path=elsewhere"]);
    assert_config_error(&o, "scan.path");
}

#[test]
fn toml_syntax_error_is_one_line() {
    let d = scan_dir();
    let o = run(d.path(), "[scan\npath = \"scan\"\n", &[]);
    assert_config_error(&o, "line 1");
}

#[test]
fn unknown_stage_name_is_a_usage_error() {
    let d = scan_dir();
    let o = run(d.path(), "[scan]\npath = \"scan\"\n", &["--from", "fitting"]);
    assert_eq!(o.code, Some(2), "{}", o.stderr);
    assert!(o.stderr.contains("fitting"), "{}", o.stderr);
}

/// One bad value per table, each given by `--set` on a config that is otherwise valid: exit code 2, the key
/// named, and no stage has run (the output directory holds no `ingest/`).
#[test]
fn one_bad_value_per_table_exits_2_before_ingest() {
    let cases: [(&str, &str); 13] = [
        ("quality=\"ultra\"", "quality"),
        ("scan.group_by=\"obj_group\"", "scan.group_by"),
        ("scan.format=\"ply\"", "scan.format"),
        ("output.path=\"scan\"", "output.path"),
        ("images.every=0", "images.every"),
        ("tracer.max_depth=5000", "tracer.max_depth"),
        ("object.lr=-1", "object.lr"),
        ("object.holdout_fraction=0.7", "object.holdout_fraction"),
        ("object.huber_delta=nan", "object.huber_delta"),
        ("triangle.split_significance=1.5", "triangle.split_significance"),
        ("triangle.adam_lr=0", "triangle.adam_lr"),
        ("export.report_views=0", "export.report_views"),
        ("export.report_spp=0", "export.report_spp"),
    ];
    for (set, key) in cases {
        let d = scan_dir();
        let o = run(d.path(), "[scan]\npath = \"scan\"\n[output]\npath = \"out\"\n", &["--set", set]);
        assert_config_error(&o, key);
        assert!(!d.path().join("out/ingest").exists(), "{set}: ingest ran");
        assert!(!d.path().join("scan/ingest").exists(), "{set}: ingest ran");
    }
}

#[test]
fn bad_value_message_states_the_rule_and_the_value() {
    let d = scan_dir();
    let o = run(d.path(), "[scan]\npath = \"scan\"\n", &["--set", "object.lr=-1"]);
    assert_config_error(&o, "`object.lr`: must be finite and > 0, got -1");
}
