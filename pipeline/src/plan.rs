//! The resolved, validated plan of a run: the [`Config`] with paths made absolute (relative to the config
//! file) and values checked, plus the stage list and each stage's config section (what its manifest hashes).

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::Serialize;

use crate::config::{
    Config, ConfigError, ExportConfig, GroupBy, ImagesConfig, ScanFormat, TracerConfig, TriangleConfig,
};
use optim::fit::ObjectFitSettings;

/// The pipeline's stages, in execution order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum StageId {
    /// Reads the scan: mesh, objects, cameras, view list.
    Ingest,
    /// Prepares the photos: linear radiance, downscaled, cached as EXR.
    Preprocess,
    /// Per-object material and emission fit.
    Object,
    /// Per-triangle fit with adaptive subdivision (its own issue; a placeholder for now).
    Triangle,
    /// materials.json, trajectories, report.html.
    Export,
}

impl StageId {
    /// Every stage in execution order.
    pub const ALL: [StageId; 5] = [Self::Ingest, Self::Preprocess, Self::Object, Self::Triangle, Self::Export];

    /// The stage's name (also its directory under `output.path`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Ingest => "ingest",
            Self::Preprocess => "preprocess",
            Self::Object => "object",
            Self::Triangle => "triangle",
            Self::Export => "export",
        }
    }

    /// The stages whose outputs this stage reads (their manifests' output digests are its inputs).
    #[must_use]
    pub fn upstream(self) -> &'static [StageId] {
        match self {
            Self::Ingest => &[],
            Self::Preprocess => &[Self::Ingest],
            Self::Object => &[Self::Ingest, Self::Preprocess],
            Self::Triangle => &[Self::Ingest, Self::Preprocess, Self::Object],
            Self::Export => &[Self::Ingest, Self::Preprocess, Self::Object, Self::Triangle],
        }
    }
}

impl fmt::Display for StageId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for StageId {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL.into_iter().find(|st| st.name() == s).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|st| st.name()).collect();
            format!("unknown stage `{s}`, expected one of {}", names.join(", "))
        })
    }
}

/// `[scan]` resolved.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScanPlan {
    /// Absolute scan directory (exists).
    pub path: PathBuf,
    pub format: ScanFormat,
    pub group_by: GroupBy,
}

/// The validated plan.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The config file the plan came from (absolute).
    pub config_path: PathBuf,
    pub scan: ScanPlan,
    /// Absolute run directory.
    pub output: PathBuf,
    pub images: ImagesConfig,
    pub tracer: TracerConfig,
    pub object: ObjectFitSettings,
    pub triangle: TriangleConfig,
    pub export: ExportConfig,
}

impl Plan {
    /// Validates `config` (read from `config_path`) and resolves its paths relative to the config file's
    /// directory.
    pub fn resolve(config: Config, config_path: &Path) -> Result<Self, ConfigError> {
        let config_path = absolute(config_path, &std::env::current_dir().unwrap_or_default());
        let base = config_path.parent().map(Path::to_path_buf).unwrap_or_default();
        let key_err =
            |key: &str, message: String| ConfigError::Key { path: config_path.clone(), key: key.to_owned(), message };

        let scan_path = absolute(&config.scan.path, &base);
        if !scan_path.is_dir() {
            return Err(key_err("scan.path", format!("scan directory {} does not exist", scan_path.display())));
        }
        let output = absolute(&config.output.path, &base);
        if output == scan_path || scan_path.starts_with(&output) {
            return Err(key_err("output.path", format!("{} would contain the scan directory", output.display())));
        }
        if config.images.downscale == 0 {
            return Err(key_err("images.downscale", "must be at least 1".to_owned()));
        }
        if config.images.every == 0 {
            return Err(key_err("images.every", "must be at least 1".to_owned()));
        }
        // Bounds the tracer's per-vertex random-number dimensions (it refuses more).
        const MAX_DEPTH_LIMIT: u32 = 1024;
        if config.tracer.max_depth > MAX_DEPTH_LIMIT {
            return Err(key_err("tracer.max_depth", format!("must be at most {MAX_DEPTH_LIMIT}")));
        }
        if config.export.report_spp == 0 {
            return Err(key_err("export.report_spp", "must be at least 1".to_owned()));
        }
        Ok(Self {
            config_path,
            scan: ScanPlan { path: scan_path, format: config.scan.format, group_by: config.scan.group_by },
            output,
            images: config.images,
            tracer: config.tracer,
            object: config.object,
            triangle: config.triangle,
            export: config.export,
        })
    }

    /// Loads, overrides and resolves in one go (what `pipeline run` does).
    pub fn load(config_path: &Path, overrides: &[String]) -> Result<Self, ConfigError> {
        let config = crate::config::load(config_path, overrides)?;
        Self::resolve(config, config_path)
    }

    /// The directory of `stage`'s artefacts.
    #[must_use]
    pub fn stage_dir(&self, stage: StageId) -> PathBuf {
        self.output.join(stage.name())
    }

    /// The config section a stage depends on, as JSON; its SHA-256 goes into the stage's manifest, so a
    /// change of any of these values reruns the stage. Each section carries a format version of the
    /// stage's artefacts so that a change of what the code writes also invalidates old runs.
    #[must_use]
    pub fn stage_config(&self, stage: StageId) -> serde_json::Value {
        use serde_json::json;
        match stage {
            StageId::Ingest => json!({"artefacts": 1, "scan": self.scan}),
            StageId::Preprocess => json!({"artefacts": 1, "images": self.images}),
            StageId::Object => json!({"artefacts": 1, "object": self.object, "tracer": self.tracer}),
            StageId::Triangle => json!({"artefacts": 1, "triangle": self.triangle, "tracer": self.tracer}),
            StageId::Export => json!({"artefacts": 1, "export": self.export, "tracer": self.tracer}),
        }
    }
}

/// `p` made absolute against `base` and lexically normalised (`.` and `..` removed), without touching the
/// file system (the output directory need not exist yet).
#[must_use]
pub fn absolute(p: &Path, base: &Path) -> PathBuf {
    let joined = if p.is_absolute() { p.to_path_buf() } else { base.join(p) };
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_names_round_trip_and_order_is_the_documented_one() {
        let names: Vec<&str> = StageId::ALL.iter().map(|s| s.name()).collect();
        assert_eq!(names, ["ingest", "preprocess", "object", "triangle", "export"]);
        for s in StageId::ALL {
            assert_eq!(s.name().parse::<StageId>().unwrap(), s);
            assert!(s.upstream().iter().all(|u| *u < s), "{s} depends on a later stage");
        }
        assert!("fit".parse::<StageId>().unwrap_err().contains("ingest, preprocess"));
    }

    #[test]
    fn paths_resolve_relative_to_the_config_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("cfg/scans/a")).unwrap();
        let cfg = dir.path().join("cfg/run.toml");
        std::fs::write(&cfg, "[scan]\npath = \"scans/./a\"\n[output]\npath = \"../out\"\n").unwrap();
        let plan = Plan::load(&cfg, &[]).unwrap();
        assert_eq!(plan.scan.path, dir.path().join("cfg/scans/a"));
        assert_eq!(plan.output, dir.path().join("out"));
        assert_eq!(plan.stage_dir(StageId::Object), dir.path().join("out/object"));
    }

    #[test]
    fn missing_scan_directory_names_scan_path() {
        let dir = tempfile::tempdir().unwrap();
        let cfg = dir.path().join("run.toml");
        std::fs::write(&cfg, "[scan]\npath = \"nowhere\"\n").unwrap();
        let e = Plan::load(&cfg, &[]).unwrap_err();
        assert!(e.to_string().contains("`scan.path`"), "{e}");
    }

    #[test]
    fn invalid_values_name_their_key() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("s")).unwrap();
        let cfg = dir.path().join("run.toml");
        std::fs::write(&cfg, "[scan]\npath = \"s\"\n").unwrap();
        for (set, key) in [("images.downscale=0", "images.downscale"), ("output.path=.", "output.path")] {
            let e = Plan::load(&cfg, &[set.to_owned()]).unwrap_err();
            assert!(e.to_string().contains(&format!("`{key}`")), "{e}");
        }
    }

    #[test]
    fn stage_config_sections_are_independent() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("s")).unwrap();
        let cfg = dir.path().join("run.toml");
        std::fs::write(&cfg, "[scan]\npath = \"s\"\n").unwrap();
        let a = Plan::load(&cfg, &[]).unwrap();
        let b = Plan::load(&cfg, &["tracer.max_depth=9".to_owned()]).unwrap();
        assert_eq!(a.stage_config(StageId::Ingest), b.stage_config(StageId::Ingest));
        assert_eq!(a.stage_config(StageId::Preprocess), b.stage_config(StageId::Preprocess));
        assert_ne!(a.stage_config(StageId::Object), b.stage_config(StageId::Object));
        assert_ne!(a.stage_config(StageId::Export), b.stage_config(StageId::Export));
    }
}
