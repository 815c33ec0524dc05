//! ARCHITECTURE.md's code map matches the tree: every module of every crate is listed, and every path the map
//! lists exists.
//!
//! The map has one `### \`<crate>/\`` section per crate. Each bullet starts with the paths it describes, in
//! backticks, relative to `<crate>/src/` (`scan.rs`, `photo/`; `tests/…`, `benches/…` and `examples/…` relative
//! to the crate), before the first " — ". A directory bullet
//! covers its `mod.rs`; every other file is named somewhere in the section (`pose.rs`, `embree/ffi.rs`, or
//! inside a directory by its module name `ffi`).

mod common;
use common::{rust_files, workspace_root};
use std::collections::BTreeSet;

/// Crate sections: (crate directory, section text).
fn sections(map: &str) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    for line in map.lines() {
        if let Some(rest) = line.strip_prefix("### `") {
            let name = rest.split('`').next().unwrap_or_default().trim_end_matches('/').to_owned();
            out.push((name, String::new()));
        } else if line.starts_with("## ") || line.starts_with("### ") {
            out.push((String::new(), String::new()));
        } else if let Some((_, text)) = out.last_mut() {
            text.push_str(line);
            text.push('\n');
        }
    }
    out.retain(|(name, _)| !name.is_empty() && workspace_root().join(name).join("Cargo.toml").is_file());
    out
}

/// The backticked paths at the head of each bullet (before its first " — ").
fn heads(section: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in section.lines().filter(|l| l.starts_with("- `")) {
        let head = line.split(" — ").next().unwrap_or_default();
        out.extend(head.split('`').skip(1).step_by(2).map(str::to_owned));
    }
    out
}

/// Backticked words anywhere in the section.
fn mentioned(section: &str) -> BTreeSet<String> {
    section.split('`').skip(1).step_by(2).map(str::to_owned).collect()
}

#[test]
fn code_map_lists_every_module_and_only_existing_paths() {
    let map = std::fs::read_to_string(workspace_root().join("ARCHITECTURE.md")).unwrap();
    let sections = sections(&map);
    let mut problems = Vec::new();
    let members: Vec<String> = {
        let cargo = std::fs::read_to_string(workspace_root().join("Cargo.toml")).unwrap();
        let line = cargo.lines().find(|l| l.starts_with("members")).unwrap().to_owned();
        line.split('"').skip(1).step_by(2).map(str::to_owned).collect()
    };
    for m in &members {
        if !sections.iter().any(|(name, _)| name == m) {
            problems.push(format!("crate {m}/ has no ### section"));
        }
    }
    for (krate, text) in &sections {
        let src = workspace_root().join(krate).join("src");
        let heads = heads(text);
        for h in &heads {
            // Test, bench and example files are relative to the crate; modules to its src/.
            let base = if ["tests/", "benches/", "examples/"].iter().any(|d| h.starts_with(d)) {
                workspace_root().join(krate)
            } else {
                src.clone()
            };
            let p = base.join(h.trim_end_matches('/'));
            let ok = if h.ends_with('/') { p.is_dir() } else { p.is_file() };
            if !ok {
                problems.push(format!("{krate}: listed `{h}` does not exist at {}", p.display()));
            }
        }
        let words = mentioned(text);
        for f in rust_files(&src) {
            let rel = f.strip_prefix(&src).unwrap().to_string_lossy().replace('\\', "/");
            let name = f.file_name().unwrap().to_string_lossy().into_owned();
            let stem = name.trim_end_matches(".rs").to_owned();
            let listed = match rel.rsplit_once('/') {
                // lib.rs is the crate itself; any other top-level file is named in the section.
                None => rel == "lib.rs" || words.contains(&rel),
                // A directory's mod.rs: the directory is named (`photo/` or `bsdf/tests/`, or its last part).
                Some((dir, "mod.rs")) => {
                    let last = dir.rsplit('/').next().unwrap_or(dir);
                    words.contains(&format!("{dir}/")) || words.contains(&format!("{last}/"))
                }
                // Any other file of a module directory: named by path, file name or module name.
                Some(_) => [&rel, &name, &stem].iter().any(|w| words.contains(*w)),
            };
            if !listed {
                problems.push(format!("{krate}: src/{rel} is not in the code map"));
            }
        }
    }
    assert!(problems.is_empty(), "ARCHITECTURE.md code map:\n{}", problems.join("\n"));
}
