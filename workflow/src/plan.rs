//! The resolved, validated plan of a run: the [`Config`] with paths made absolute (relative to the config
//! file) and values checked, plus the stage list and each stage's config section (what its manifest hashes).

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::Serialize;

use ingest::{GroupBy, ScanFormat};

use crate::config::{Config, ConfigError, ExportConfig, ImagesConfig, TracerConfig, TriangleConfig};
use optim::fit::{AdamLoss, ObjectFitSettings};

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
        validate(&config).map_err(|e| key_err(e.key, e.message))?;
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
            StageId::Export => json!({"artefacts": 2, "export": self.export, "tracer": self.tracer}),
        }
    }
}

/// A value that breaks its key's rule: the dotted key and a message that states the rule and the value
/// (`must be > 0, got -1`).
#[derive(Debug, Clone, PartialEq)]
struct Invalid {
    key: &'static str,
    message: String,
}

/// `Ok` when `ok`, else the rule `rule` broken by `value` at `key`.
fn rule(ok: bool, key: &'static str, rule: &str, value: impl fmt::Display) -> Result<(), Invalid> {
    if ok { Ok(()) } else { Err(Invalid { key, message: format!("must be {rule}, got {value}") }) }
}

fn at_least_one(key: &'static str, v: u32) -> Result<(), Invalid> {
    rule(v >= 1, key, ">= 1", v)
}

fn positive(key: &'static str, v: f64) -> Result<(), Invalid> {
    rule(v.is_finite() && v > 0.0, key, "finite and > 0", v)
}

fn non_negative(key: &'static str, v: f64) -> Result<(), Invalid> {
    rule(v.is_finite() && v >= 0.0, key, "finite and >= 0", v)
}

/// Largest `tracer.max_depth` the tracer accepts (`tracer::Renderer::new` refuses more); checked here so
/// that it is reported before any stage runs.
const TRACER_MAX_DEPTH: u32 = tracer::MAX_DEPTH_LIMIT;

/// Every value rule of the config, table by table, in the order of `configs/README.md`. Enumerations
/// (`scan.format`, `scan.group_by`, `tracer.emission_profile`, `object.loss`, `quality`) and types are checked
/// by deserialisation; paths by [`Plan::resolve`]. Keys without a rule here take every value of their type.
fn validate(c: &Config) -> Result<(), Invalid> {
    let i = &c.images;
    at_least_one("images.downscale", i.downscale)?;
    rule(i.max_pixels >= 1, "images.max_pixels", ">= 1", i.max_pixels)?;
    at_least_one("images.every", i.every)?;
    at_least_one("images.calibration_points", i.calibration_points)?;
    for name in &i.cameras {
        rule(!name.trim().is_empty(), "images.cameras", "a list of view names (non-empty)", format!("{name:?}"))?;
    }

    let t = &c.tracer;
    rule(t.max_depth <= TRACER_MAX_DEPTH, "tracer.max_depth", &format!("<= {TRACER_MAX_DEPTH}"), t.max_depth)?;

    let o = &c.object;
    at_least_one("object.batch_pixels", o.batch_pixels)?;
    positive("object.lr", o.lr)?;
    rule(
        o.lr_final_fraction > 0.0 && o.lr_final_fraction <= 1.0,
        "object.lr_final_fraction",
        "in (0, 1]",
        o.lr_final_fraction,
    )?;
    at_least_one("object.n_value", o.n_value)?;
    at_least_one("object.n_grad", o.n_grad)?;
    if o.loss == AdamLoss::Huber {
        positive("object.huber_delta", o.huber_delta)?;
    } else {
        non_negative("object.huber_delta", o.huber_delta)?;
    }
    non_negative("object.emission_l1", o.emission_l1)?;
    at_least_one("object.solve_pixels", o.solve_pixels)?;
    at_least_one("object.solve_spp", o.solve_spp)?;
    at_least_one("object.interim_solve_spp", o.interim_solve_spp)?;
    at_least_one("object.check_spp", o.check_spp)?;
    rule((0.0..0.5).contains(&o.holdout_fraction), "object.holdout_fraction", "in [0, 0.5)", o.holdout_fraction)?;
    at_least_one("object.holdout_spp", o.holdout_spp)?;
    at_least_one("object.holdout_pixels", o.holdout_pixels)?;

    let g = &c.triangle;
    at_least_one("triangle.spp", g.spp)?;
    // The split test compares a triangle's four would-be children.
    rule(g.pixels_per_triangle >= 4, "triangle.pixels_per_triangle", "≥ 4", g.pixels_per_triangle)?;
    positive("triangle.adam_lr", g.adam_lr)?;
    non_negative("triangle.smoothness", g.smoothness)?;
    rule(
        g.split_significance > 0.0 && g.split_significance < 1.0,
        "triangle.split_significance",
        "in (0, 1)",
        g.split_significance,
    )?;
    non_negative("triangle.split_contrast", g.split_contrast)?;
    at_least_one("triangle.max_triangles", g.max_triangles)?;
    // The light-change test needs 2 averaged steps after the burn-in; each step's key must stay inside the
    // 2^17 the key layout leaves the light solves of a round's two cycles.
    let fewest = optim::triangle::light::LIGHT_BURN_IN + 2;
    rule(
        g.light_steps == 0 || (fewest..=10_000).contains(&g.light_steps),
        "triangle.light_steps",
        &format!("0 or in [{fewest}, 10000]"),
        g.light_steps,
    )?;
    non_negative("triangle.light_precision", g.light_precision)?;
    // The ratio steps of a round's passes (`fit_steps`, then `light_fit_steps` after each of the two light
    // cycles and after the lobe family look) are numbered on in one key field below the 2^16 of the Adam
    // iterations.
    rule(g.fit_steps <= 10_000, "triangle.fit_steps", "at most 10000", g.fit_steps)?;
    rule((1..=10_000).contains(&g.light_fit_steps), "triangle.light_fit_steps", "in [1, 10000]", g.light_fit_steps)?;
    // Fewer pixels than two halves of the look's minimum look at no object at all: 0 says so plainly.
    let fewest = 2 * optim::triangle::family::MIN_HALF as u32;
    rule(
        g.family_pixels == 0 || g.family_pixels >= fewest,
        "triangle.family_pixels",
        &format!("0 or at least {fewest}"),
        g.family_pixels,
    )?;

    let e = &c.export;
    at_least_one("export.report_spp", e.report_spp)?;
    at_least_one("export.report_views", e.report_views)?;
    positive("export.detail_density", e.detail_density)?;
    at_least_one("export.detail_spp", e.detail_spp)?;
    Ok(())
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
        for (set, key) in [
            ("images.downscale=0", "images.downscale"),
            ("output.path=.", "output.path"),
            // Too few light steps for the light-change test's two averaged steps after the burn-in.
            ("triangle.light_steps=3", "triangle.light_steps"),
            ("triangle.light_precision=-0.01", "triangle.light_precision"),
            ("triangle.light_fit_steps=0", "triangle.light_fit_steps"),
            ("triangle.fit_steps=10001", "triangle.fit_steps"),
            // Two halves of fewer than the look's minimum each.
            ("triangle.family_pixels=63", "triangle.family_pixels"),
        ] {
            let e = Plan::load(&cfg, &[set.to_owned()]).unwrap_err();
            assert!(e.to_string().contains(&format!("`{key}`")), "{e}");
        }
        // No light re-solve, or the fewest steps that allow its test: valid.
        for set in [
            "triangle.light_steps=0",
            "triangle.light_steps=4",
            "triangle.light_precision=0",
            "triangle.light_fit_steps=1",
            "triangle.family_pixels=0",
            "triangle.family_pixels=64",
            "triangle.fit_steps=0",
        ] {
            Plan::load(&cfg, &[set.to_owned()]).unwrap_or_else(|e| panic!("{set}: {e}"));
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
