//! configs/README.md documents every config key with its actual default, and configs/demo.toml is valid.

use std::collections::BTreeMap;
use std::path::Path;

fn workspace() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// Dotted key → default value (as JSON) of every leaf of the default config.
fn defaults() -> BTreeMap<String, serde_json::Value> {
    let config = workflow::config::parse("[scan]\npath = \"x\"\n", Path::new("t.toml"), &[]).unwrap();
    let v = serde_json::to_value(&config).unwrap();
    let mut out = BTreeMap::new();
    for (table, fields) in v.as_object().unwrap() {
        for (k, x) in fields.as_object().unwrap() {
            out.insert(format!("{table}.{k}"), x.clone());
        }
    }
    out
}

/// Dotted key → default cell of the README's key tables.
fn documented() -> BTreeMap<String, String> {
    let text = std::fs::read_to_string(workspace().join("configs/README.md")).unwrap();
    text.lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            // "| `key` | default | meaning |" → ["", "`key`", "default", "meaning", ""]
            let key = cells.get(1)?.strip_prefix('`')?.strip_suffix('`')?;
            let default = cells.get(2)?.trim_matches('`');
            key.contains('.').then(|| (key.to_owned(), default.to_owned()))
        })
        .collect()
}

#[test]
fn every_key_is_documented_with_its_default() {
    let docs = documented();
    for (key, value) in defaults() {
        let cell = docs.get(&key).unwrap_or_else(|| panic!("configs/README.md does not document `{key}`"));
        if key == "scan.path" {
            assert_eq!(cell, "required");
            continue;
        }
        let parsed: toml::Table =
            format!("v = {cell}").parse().unwrap_or_else(|e| panic!("`{key}`: default {cell}: {e}"));
        let doc_value = serde_json::to_value(&parsed["v"]).unwrap();
        let same = match (doc_value.as_f64(), value.as_f64()) {
            (Some(a), Some(b)) => a == b,
            _ => doc_value == value,
        };
        assert!(same, "`{key}`: README says {cell}, the code's default is {value}");
    }
    let known = defaults();
    for key in docs.keys() {
        assert!(known.contains_key(key), "configs/README.md documents `{key}`, which the config does not have");
    }
}

#[test]
fn demo_config_resolves() {
    let plan = workflow::plan::Plan::load(&workspace().join("configs/demo.toml"), &[]).unwrap();
    assert!(plan.scan.path.ends_with("data-fixtures/demo"));
    assert!(plan.scan.path.join("undistorted_camera_parameters").is_dir());
}
