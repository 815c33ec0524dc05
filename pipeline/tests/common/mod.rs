//! Helpers shared by the integration tests: running the `pipeline` binary, copying scans, loading a bundled
//! synthetic scene with its photos, walking the workspace's sources. Each test crate uses a subset, so unused items are allowed here.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
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

/// The workspace root (the directory above this crate).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every `.rs` file under `dir`, recursively, in sorted order.
pub fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().flatten().map(|e| e.path()).collect();
    entries.sort();
    let mut out = Vec::new();
    for p in entries {
        if p.is_dir() {
            out.extend(rust_files(&p));
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
    out
}

/// Copies directory `from` (recursively) to `to`.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// The bundled scene `data-fixtures/scenes/<name>.toml` with its photos rendered in memory at `spp` paths per
/// pixel (instead of the description's own count).
pub fn synth_scene(name: &str, spp: u32) -> (lab::synth::BuiltScene, Vec<ingest::photo::LinearImage>) {
    let path = workspace_root().join(format!("data-fixtures/scenes/{name}.toml"));
    let mut desc = lab::synth::load_desc(&path).unwrap();
    desc.spp = spp;
    let built = lab::synth::build(desc, &path).unwrap();
    let images = lab::synth::photos(&built).unwrap();
    (built, images)
}

/// A per-triangle round's settings for a test, owned: `config` as given, the object fit's defaults, no
/// specular object and every object constrained; [`RoundSetup::inputs`] lends them with a built scene as a
/// round's inputs.
pub struct RoundSetup {
    pub config: workflow::config::TriangleConfig,
    settings: optim::triangle::TriangleSettings,
    object: optim::fit::ObjectFitSettings,
    specular: Vec<bool>,
    constrained: Vec<bool>,
}

impl RoundSetup {
    /// `config` for a scene of `objects` objects.
    pub fn new(config: workflow::config::TriangleConfig, objects: usize) -> Self {
        let settings = optim::triangle::TriangleSettings::from(&config);
        Self {
            config,
            settings,
            object: optim::fit::ObjectFitSettings::default(),
            specular: vec![false; objects],
            constrained: vec![true; objects],
        }
    }

    /// Marks object `o` as one the object stage left unconstrained (`materials.json`'s `constrained`: false).
    pub fn unconstrained(mut self, o: usize) -> Self {
        self.constrained[o] = false;
        self
    }

    /// A round's inputs on `built` and its photos `images`.
    pub fn inputs<'a>(
        &'a self,
        built: &'a lab::synth::BuiltScene,
        images: &'a [ingest::photo::LinearImage],
    ) -> optim::triangle::RoundInputs<'a> {
        optim::triangle::RoundInputs {
            cameras: &built.cameras,
            images,
            settings: &self.settings,
            object: &self.object,
            tracer: &built.settings,
            specular: &self.specular,
            constrained: &self.constrained,
        }
    }
}

/// A progress that asks to stop once it is armed (by [`StopAfter::arm`], or by the start of a phase whose name
/// begins with `arm_on_phase`) and two more positions have been reported; it counts the positions reported
/// after it first said so, which a prompt stop keeps at 0.
#[derive(Default)]
pub struct StopAfter {
    arm_on_phase: Option<&'static str>,
    armed: std::sync::atomic::AtomicBool,
    positions: std::sync::atomic::AtomicU64,
    answered: std::sync::atomic::AtomicBool,
    after_stop: std::sync::atomic::AtomicU64,
}

impl StopAfter {
    /// One that arms itself when a phase whose name begins with `prefix` starts.
    pub fn on_phase(prefix: &'static str) -> Self {
        Self { arm_on_phase: Some(prefix), ..Self::default() }
    }
    pub fn arm(&self) {
        self.armed.store(true, std::sync::atomic::Ordering::SeqCst);
    }
    /// Whether it has asked to stop.
    pub fn asked(&self) -> bool {
        self.answered.load(std::sync::atomic::Ordering::SeqCst)
    }
    /// Positions reported after it first asked to stop.
    pub fn positions_after_stop(&self) -> u64 {
        self.after_stop.load(std::sync::atomic::Ordering::SeqCst)
    }
}

impl optim::Progress for StopAfter {
    fn phase(&self, name: &str, _total: u64, done: u64) {
        if self.arm_on_phase.is_some_and(|p| name.starts_with(p)) {
            self.arm();
        }
        self.set_position(done);
    }
    fn set_position(&self, _: u64) {
        use std::sync::atomic::Ordering::SeqCst;
        if self.answered.load(SeqCst) {
            self.after_stop.fetch_add(1, SeqCst);
        } else if self.armed.load(SeqCst) {
            self.positions.fetch_add(1, SeqCst);
        }
    }
    fn stop_requested(&self) -> bool {
        use std::sync::atomic::Ordering::SeqCst;
        let stop = self.armed.load(SeqCst) && self.positions.load(SeqCst) >= 2;
        if stop {
            self.answered.store(true, SeqCst);
        }
        stop
    }
}
