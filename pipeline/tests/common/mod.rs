//! Helpers shared by the integration tests that drive the `pipeline` binary. Each test crate uses a subset, so
//! unused items are allowed here.
#![allow(dead_code)]

use std::process::Command;

/// Runs the built `pipeline` binary (without RUST_LOG, so stderr holds only its own lines): exit code and stderr.
pub fn pipeline(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_pipeline")).args(args).env_remove("RUST_LOG").output().unwrap();
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// The stages a run reports as running / skipped, from its `[stage] running:` / `[stage] skipped:` lines.
pub fn decisions(stderr: &str, what: &str) -> Vec<String> {
    stderr
        .lines()
        .filter_map(|l| {
            let (stage, rest) = l.strip_prefix('[')?.split_once("] ")?;
            rest.starts_with(what).then(|| stage.to_owned())
        })
        .collect()
}
