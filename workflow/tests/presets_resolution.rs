//! `quality = "preview" | "balanced" | "final"`: the preset fills the keys the config does not set; keys in
//! the file and `--set` overrides win; a bad preset name is a one-line error naming `quality`.

use std::path::Path;

use workflow::config::parse;
use workflow::presets::{PresetValue, Quality};

fn p(text: &str, sets: &[&str]) -> Result<workflow::config::Config, workflow::config::ConfigError> {
    let sets: Vec<String> = sets.iter().map(|s| (*s).to_owned()).collect();
    parse(text, Path::new("c.toml"), &sets)
}

/// The effective value of a dotted key in a parsed config, as JSON.
fn value(c: &workflow::config::Config, key: &str) -> serde_json::Value {
    let v = serde_json::to_value(c).unwrap();
    let (a, b) = key.split_once('.').unwrap();
    v[a][b].clone()
}

fn preset_json(v: PresetValue) -> serde_json::Value {
    match v {
        PresetValue::Int(i) => serde_json::json!(i),
        PresetValue::Bool(b) => serde_json::json!(b),
    }
}

#[test]
fn every_preset_sets_all_its_keys() {
    for q in Quality::ALL {
        let c = p(&format!("quality = \"{}\"\n[scan]\npath = \"s\"\n", q.name()), &[]).unwrap();
        assert_eq!(c.quality, Some(q));
        for (key, v) in q.values() {
            assert_eq!(value(&c, key), preset_json(*v), "{}: {key}", q.name());
        }
    }
}

#[test]
fn explicit_keys_in_the_file_win_over_the_preset() {
    let c = p("quality = \"preview\"\n[scan]\npath = \"s\"\n[object]\nn_value = 300\n[images]\ndownscale = 1\n", &[])
        .unwrap();
    assert_eq!(c.object.n_value, 300);
    assert_eq!(c.images.downscale, 1);
    // Keys the file does not set still come from the preset.
    let iterations = Quality::Preview.values().iter().find(|(k, _)| *k == "object.iterations").unwrap().1;
    assert_eq!(serde_json::json!(c.object.iterations), preset_json(iterations));
}

#[test]
fn set_overrides_win_over_the_preset_and_can_choose_it() {
    let c = p("quality = \"final\"\n[scan]\npath = \"s\"\n", &["object.refine_steps=3"]).unwrap();
    assert_eq!(c.object.refine_steps, 3);
    let c = p("[scan]\npath = \"s\"\n", &["quality=preview", "tracer.max_depth=11"]).unwrap();
    assert_eq!(c.quality, Some(Quality::Preview));
    assert_eq!(c.tracer.max_depth, 11);
    let downscale = Quality::Preview.values().iter().find(|(k, _)| *k == "images.downscale").unwrap().1;
    assert_eq!(serde_json::json!(c.images.downscale), preset_json(downscale));
}

#[test]
fn without_a_preset_the_defaults_hold() {
    let c = p("[scan]\npath = \"s\"\n", &[]).unwrap();
    assert_eq!(c.quality, None);
    assert_eq!(c.object, optim::fit::ObjectFitSettings::default());
}

#[test]
fn unknown_preset_is_a_one_line_error_naming_quality() {
    for text in ["quality = \"ultra\"\n[scan]\npath = \"s\"\n", "quality = 2\n[scan]\npath = \"s\"\n"] {
        let e = p(text, &[]).unwrap_err().to_string();
        assert!(e.contains("`quality`"), "{e}");
        assert!(!e.contains('\n'), "{e}");
    }
}

#[test]
fn the_preset_reaches_the_object_stage_hash() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("s")).unwrap();
    let cfg = dir.path().join("run.toml");
    std::fs::write(&cfg, "[scan]\npath = \"s\"\n").unwrap();
    let plain = workflow::plan::Plan::load(&cfg, &[]).unwrap();
    let preview = workflow::plan::Plan::load(&cfg, &["quality=preview".to_owned()]).unwrap();
    let stage = workflow::plan::StageId::Object;
    assert_ne!(plain.stage_config(stage), preview.stage_config(stage));
}
