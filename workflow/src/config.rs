//! The user's TOML configuration as written (`config.toml`), and its parsing with `--set key=value`
//! overrides. Every table denies unknown keys; every default is documented in `configs/README.md`.
//!
//! Parsing goes TOML text → `toml::Table` → overrides applied → typed [`Config`] through
//! `serde_path_to_error`, so every error names the dotted key it is about (`object.lr`, `scan.path`).
//! [`crate::plan::Plan::resolve`] then validates values and resolves paths.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use ingest::photo::calibrate::ResponseChannels;
use ingest::{GroupBy, ScanFormat};
use tracer::EmissionProfile;

use optim::fit::ObjectFitSettings;

/// A configuration error. Its `Display` is always a single line that names the offending key where there
/// is one; the binary prints it and exits with code 2.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The config file could not be read.
    #[error("{path}: cannot read config: {source}", path = .path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML (syntax).
    #[error("{path}: {message}", path = .path.display())]
    Syntax { path: PathBuf, message: String },
    /// A key is unknown, has the wrong type, is missing, or has an invalid value.
    #[error("{path}: `{key}`: {message}", path = .path.display())]
    Key { path: PathBuf, key: String, message: String },
    /// A `--set` argument is malformed.
    #[error("--set {arg}: {message}")]
    Override { arg: String, message: String },
}

/// The whole configuration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Quality preset (`preview` | `balanced` | `final`, see [`crate::presets`]): fills the `[object]`,
    /// `[tracer]` and `[images]` keys the config does not set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<crate::presets::Quality>,
    pub scan: ScanConfig,
    #[serde(default)]
    pub output: OutputConfig,
    #[serde(default)]
    pub images: ImagesConfig,
    #[serde(default)]
    pub tracer: TracerConfig,
    #[serde(default)]
    pub object: ObjectFitSettings,
    #[serde(default)]
    pub triangle: TriangleConfig,
    #[serde(default)]
    pub export: ExportConfig,
}

/// `[scan]`: where the scan is and how its faces are grouped into objects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanConfig {
    /// Scan directory (required); relative paths are relative to the config file.
    pub path: PathBuf,
    #[serde(default)]
    pub format: ScanFormat,
    /// Which per-face id column defines objects.
    #[serde(default)]
    pub group_by: GroupBy,
}

/// `[output]`: where the run directory goes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    /// Run directory; relative paths are relative to the config file.
    #[serde(default = "default_output_path")]
    pub path: PathBuf,
}

fn default_output_path() -> PathBuf {
    PathBuf::from("run")
}

impl Default for OutputConfig {
    fn default() -> Self {
        Self { path: default_output_path() }
    }
}

/// `[images]`: photo preparation (the `preprocess` stage).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImagesConfig {
    /// Integer downscale factor applied to every photo (box filter); 1 = full resolution. The preprocess stage
    /// raises it where the prepared photos would exceed `max_pixels`.
    #[serde(default = "one")]
    pub downscale: u32,
    /// Budget: the most pixels of all prepared photos together. Memory and the per-pixel work of the later
    /// stages (the per-triangle stage's pixel collection, the export's detail shading) grow with them, so the
    /// downscale factor grows until the chosen views fit (the smallest factor that fits is used).
    #[serde(default = "default_max_pixels")]
    pub max_pixels: u64,
    /// Keep only these views (colour file stems, e.g. `abc_i1_2`); empty = all views.
    #[serde(default)]
    pub cameras: Vec<String>,
    /// Keep every n-th view (after `cameras`); 1 = all.
    #[serde(default = "one")]
    pub every: u32,
    /// How display-referred (8/16-bit) photos become linear: the sRGB curve, or a response estimated from the
    /// photos themselves (their overlap under different exposures). Linear (EXR/HDR) photos ignore it.
    #[serde(default)]
    pub response: ResponseChoice,
    /// With `response = "estimate"`: one curve for the three channels (a digital camera's single tone curve
    /// after white balance) or one per channel (colour film).
    #[serde(default)]
    pub response_channels: ResponseChannels,
    /// One exposure for every photo, or one gain per photo estimated from the photos' overlap.
    #[serde(default)]
    pub exposure: PerPhoto,
    /// One white balance for every photo, or per-photo channel gains estimated from the photos' overlap.
    #[serde(default)]
    pub white_balance: PerPhoto,
    /// No vignetting, or a radial falloff per physical camera estimated from the photos' overlap.
    #[serde(default)]
    pub vignetting: VignettingChoice,
    /// Surface points sampled (area-uniformly) to compare the photos that see them, when anything above is
    /// estimated: a statistical budget, independent of the photos' number and resolution.
    #[serde(default = "default_calibration_points")]
    pub calibration_points: u32,
}

/// `images.response`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResponseChoice {
    #[default]
    Srgb,
    Estimate,
}

/// `images.exposure` and `images.white_balance`. Per photo by default: real cameras set both per photo, and
/// on a scan with one exposure the estimate costs nothing measurable (the bundled demo: gains within 0.1 % of
/// 1, albedo L1 0.00275 against 0.00270 with `"fixed"`, the same run time; docs/photo/self-calibration.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PerPhoto {
    Fixed,
    #[default]
    PerPhoto,
}

/// `images.vignetting`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VignettingChoice {
    #[default]
    None,
    Estimate,
}

/// 20 000 points: each gain is a robust mean over the points its photo shares with others, so a photo that
/// sees a tenth of the scene averages ~2000 comparisons (docs/photo/self-calibration.md).
fn default_calibration_points() -> u32 {
    20_000
}

/// 2²³ ≈ 8.4 M pixels: 180 photos of 1280×1024 are prepared at 213×170 (downscale 6). Measured on the
/// corpus's house (docs/scale/README.md, "Photos larger than the budget"): at 3.7 M prepared pixels the whole
/// run takes 25 minutes, at 26 M (the budget 2²⁵) the object stage alone peaked at 2.8 GB and each of the
/// per-triangle stage's fit steps took 4 minutes, which puts the run well past the 45 minutes a house is
/// allowed. At 17.7 M (320×256) the whole run took 34 minutes in 2.3 GB, against 35 minutes in 1.2 GB at this
/// default, and its albedo (0.0201 against 0.0217) still misses 0.02; the object stage takes about 13 minutes at
/// either (same file, "A budget of paths per render" and "The object stage's cost at house scale"). The budget is
/// the knob between the photos' detail and the run's cost.
fn default_max_pixels() -> u64 {
    1 << 23
}

impl ImagesConfig {
    /// The downscale factor for views of `sizes` (width, height): `downscale`, raised to the smallest factor
    /// at which the prepared pixels, Σ ⌊w/f⌋·⌊h/f⌋, fit `max_pixels`. Never more than the smallest view's
    /// shorter side (a factor beyond it leaves no pixel).
    #[must_use]
    pub fn effective_downscale(&self, sizes: &[(u32, u32)]) -> u32 {
        let pixels = |f: u32| sizes.iter().map(|&(w, h)| u64::from(w / f) * u64::from(h / f)).sum::<u64>();
        let largest = sizes.iter().map(|&(w, h)| w.min(h)).min().unwrap_or(1).max(1);
        let mut f = self.downscale.max(1);
        while f < largest && pixels(f) > self.max_pixels {
            f += 1;
        }
        f
    }

    /// Whether any photometric quantity is estimated (the preprocess stage then samples the photos' overlap
    /// before preparing them).
    #[must_use]
    pub fn calibrates(&self) -> bool {
        self.response == ResponseChoice::Estimate
            || self.exposure == PerPhoto::PerPhoto
            || self.white_balance == PerPhoto::PerPhoto
            || self.vignetting == VignettingChoice::Estimate
    }
}

fn one() -> u32 {
    1
}

impl Default for ImagesConfig {
    fn default() -> Self {
        Self {
            downscale: 1,
            max_pixels: default_max_pixels(),
            cameras: Vec::new(),
            every: 1,
            response: ResponseChoice::default(),
            response_channels: ResponseChannels::default(),
            exposure: PerPhoto::default(),
            white_balance: PerPhoto::default(),
            vignetting: VignettingChoice::default(),
            calibration_points: default_calibration_points(),
        }
    }
}

/// `[tracer]`: path tracing settings shared by every stage that renders.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TracerConfig {
    /// Largest number of scattering events on a path (pbrt's convention: 0 = emitters seen directly only,
    /// 1 = plus direct illumination; Mitsuba's `max_depth` is this + 1).
    #[serde(default = "default_max_depth")]
    pub max_depth: u32,
    /// Bounce from which Russian roulette may end a path.
    #[serde(default = "default_rr_depth")]
    pub rr_depth: u32,
    /// `uniform` (default; Mitsuba/pbrt area lights) or `cosine` (the paper's `e (i·n)+`).
    #[serde(default)]
    pub emission_profile: EmissionProfile,
}

impl TracerConfig {
    /// The tracer's settings.
    #[must_use]
    pub fn settings(&self) -> tracer::TracerSettings {
        tracer::TracerSettings {
            max_depth: self.max_depth,
            rr_depth: self.rr_depth,
            emission_profile: self.emission_profile,
        }
    }
}

/// The name of an emission profile as written in `materials.json` and the config.
#[must_use]
pub fn profile_name(p: EmissionProfile) -> &'static str {
    match p {
        EmissionProfile::Uniform => "uniform",
        EmissionProfile::Cosine => "cosine",
    }
}

/// Default `tracer.max_depth`: deep enough that no photo's light is cut short. Photos (and renderers such as
/// Mitsuba at its default, or the reference scenes under `../shared/data` at 65) carry light of every path
/// length; a fit whose paths stop earlier explains the missing light with brighter albedos and a dimmer light.
/// In a white room whose photos carry 12 % of their light on paths of more than 8 bounces, a fit at depth 8
/// ended at albedo L1 0.048 (albedos 5–7 % high, the light 8 % low), at 16 at 0.0066, at 32 at 0.0039 and at
/// 64 at 0.0058, for 13 % more time than at 8; Russian roulette ends paths long before the cap, so 32 and 64
/// cost the same (docs/optim/design-measurements.md, "Path depth against photos of unbounded depth").
pub const DEFAULT_MAX_DEPTH: u32 = 64;

fn default_max_depth() -> u32 {
    DEFAULT_MAX_DEPTH
}

fn default_rr_depth() -> u32 {
    3
}

impl Default for TracerConfig {
    fn default() -> Self {
        Self {
            max_depth: default_max_depth(),
            rr_depth: default_rr_depth(),
            emission_profile: EmissionProfile::Uniform,
        }
    }
}

/// `[triangle]`: the per-triangle stage (`optim::triangle`): per-triangle base colour starting from the
/// per-object result, and adaptive subdivision rounds. Every default is documented in configs/README.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TriangleConfig {
    /// Run the per-triangle fit; `false` makes the stage a no-op and the export uses the per-object result.
    pub enabled: bool,
    /// Subdivision rounds (fit → split → fit …); 0 = per-triangle fit on the scan's mesh only.
    pub rounds: u32,
    /// Closed-form (ratio) base-colour updates per fit.
    pub fit_steps: u32,
    /// Paths per pixel of the renders of every fit step and of the split test.
    pub spp: u32,
    /// Budget: pixels per triangle per round (a uniform sample of its pixels when it has more).
    pub pixels_per_triangle: u32,
    /// Budget: paths per triangle of each ratio step's render: a triangle's pixels are rendered at fewer
    /// than `spp` paths each (at least 1) where they would take more; 0 = every pixel at `spp`.
    pub paths_per_triangle: u32,
    /// … as long as each object's pixels keep at least this many paths in all (up to `spp` each).
    pub paths_per_object: u32,
    /// Budget: paths of each render of a round's passes over all its pixels: where the round's pixels at
    /// `spp` each would take more, the passes take ⌊this / pixels⌋ per pixel (at least 1); 0 = no bound.
    pub paths_per_step: u64,
    /// Adam iterations per fit after the closed-form steps (batches of `object.batch_pixels` pixels,
    /// `object.n_value`/`object.n_grad` paths, the object stage's loss); 0 = closed form only.
    pub adam_iterations: u32,
    /// Adam learning rate of those iterations.
    pub adam_lr: f64,
    /// Weight of the smoothness regulariser between neighbouring triangles of one object, in pixels of
    /// evidence per shared edge (0 = none).
    pub smoothness: f64,
    /// A triangle is split when the residuals of its interior pixels, grouped by the four would-be children,
    /// differ between the children significantly (one-way ANOVA F test per channel; Bonferroni over the 3
    /// channels, Holm over all triangles tested in the round) at this family-wise level: the probability that
    /// a round splits any triangle whose pixels differ only by noise is at most this.
    pub split_significance: f64,
    /// … and when the split would change some child's albedo by more than this fraction (largest mean
    /// residual of a would-be child over the triangle's mean radiance): systematic misfit that is not texture
    /// (e.g. light bounced from a not yet refined neighbour) is well above the noise but small.
    pub split_contrast: f64,
    /// Smallest pixel footprint of a triangle a split may create: pixel centres in its parent's best view / 4.
    pub min_pixels: u32,
    /// Budget: the mesh never grows beyond this many triangles.
    pub max_triangles: u32,
    /// Budget: most joint light/albedo-scale steps per cycle of the last round's light re-solve (at least
    /// `optim::triangle::light::LIGHT_MIN_STEPS` are taken); 0 = no light re-solve.
    pub light_steps: u32,
    /// A light cycle stops before `light_steps` once every emitter's averaged emission has at most this
    /// relative standard error.
    pub light_precision: f64,
    /// Budget: ratio steps of the pass after each light cycle of the last round's light re-solve, and of the
    /// switched objects after the lobe family look when it switched some.
    pub light_fit_steps: u32,
    /// Budget: pixels per object of the lobe family look after the last round's light re-solve (half of them,
    /// at most 512, fit both lobe families, the rest test); 0 = no look.
    pub family_pixels: u32,
    /// Seed of the stage's renders.
    pub seed: u64,
}

impl Default for TriangleConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            rounds: 3,
            fit_steps: 3,
            spp: 32,
            // The split test's power grows with the pixels per would-be child: at 256 (64 per child) the
            // checker fixture's floor (2 triangles of ~3000 pixels, each child averaging several squares) was
            // no longer split; 4096 keeps every fixture's triangles whole and bounds the large ones of a
            // house scan (docs/optim/design-measurements.md, "Budgets of the decisions and of the
            // per-triangle stage").
            pixels_per_triangle: 4096,
            // A ratio step's value of a triangle rests on all its pixels' paths together: on the 1280×1024 timing
            // house a round's pass traced 64 % of its paths with these two, for albedo L1 0.0332 against 0.0328;
            // without the object floor 58 % and 0.0337, walls of 2 triangles up to 0.02 off
            // (docs/optim/design-measurements.md, "Paths per triangle in the ratio steps").
            paths_per_triangle: 8192,
            paths_per_object: 262_144,
            // 16 paths per pixel at the 10.5 M pixels the 320×256 house fits: albedo L1 0.0201 against 0.0196
            // at 32 (two seeds), the per-triangle stage at 0.50–0.57 times the CPU (docs/scale/README.md, "A
            // budget of paths per render"); rounds of up to 5.31 M pixels (the 160×128 house, the default scene)
            // keep `spp`.
            paths_per_step: 170_000_000,
            adam_iterations: 0,
            adam_lr: 0.01,
            smoothness: 0.1,
            // At most 1 round in 100 splits a uniform scene by noise; the checker's texture (p-values 2e-9 and
            // below, docs/optim/design-measurements.md) passes it by orders of magnitude.
            split_significance: 0.01,
            split_contrast: 0.1,
            min_pixels: 4,
            max_triangles: 200_000,
            // A lamp that no photo sees scatters by about a quarter of its value per joint step on the
            // natively rendered house: 4 averaged steps left its emission up to 46 % off, 16 within 10 % (the
            // 14 lamps' mean error 0.072 → 0.024, per-triangle albedo L1 0.0369 → 0.0311); seen lamps settle
            // to 1 % in the 6 steps of the minimum, so the default scene takes no more
            // (docs/optim/design-measurements.md, "Joint steps per light cycle").
            light_steps: 18,
            light_precision: 0.01,
            // One step after a cycle left the house's albedos short of the re-solved light, and the fit check
            // refused the re-solve at both seeds; two let the check decide as three did on three house runs,
            // with the summary within the seeds' scatter, for one render of every pixel less per cycle
            // (docs/optim/design-measurements.md, "Ratio steps after a light cycle").
            light_fit_steps: 2,
            // The fits take at most 512 and the test the rest: with 512 test pixels the corpus house's only
            // switch was a small metal sphere; with up to 7680 a metal box passed too and a diffuse box the
            // object stage made metal went back (docs/optim/design-measurements.md, "The lobe family look on
            // the per-triangle scene"). The test's sequential looks stop most objects long before.
            family_pixels: 8192,
            seed: 0,
        }
    }
}

/// `[export]`: materials.json, trajectories and report.html.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExportConfig {
    /// Samples per pixel of the re-renders shown in report.html.
    #[serde(default = "default_report_spp")]
    pub report_spp: u32,
    /// At most this many views appear in report.html (evenly spread over the prepared views).
    #[serde(default = "default_report_views")]
    pub report_views: u32,
    /// Seed of the report re-renders and of the detail's pixels and shading render.
    #[serde(default)]
    pub seed: u64,
    /// Budget of the sub-triangle albedo detail in the atlas: texels over all triangles (0 = no detail).
    #[serde(default = "default_detail_texels")]
    pub detail_texels: u64,
    /// Detail texels per pixel of a triangle's best view (before the budget).
    #[serde(default = "default_detail_density")]
    pub detail_density: f64,
    /// Paths per pixel of the detail's shading render.
    #[serde(default = "default_detail_spp")]
    pub detail_spp: u32,
}

fn default_report_spp() -> u32 {
    64
}

fn default_detail_texels() -> u64 {
    4_000_000
}

fn default_detail_density() -> f64 {
    1.0
}

/// 8 paths: the shading is smoothed per triangle, so fewer paths cost it little, and they cut the export's
/// largest render 4× (on the 1280×1024 house 7.5 M pixels, export 399 s → 126 s); measured against 32 in
/// docs/realistic/README.md, "Fewer paths for the detail's shading".
fn default_detail_spp() -> u32 {
    8
}

fn default_report_views() -> u32 {
    6
}

impl Default for ExportConfig {
    fn default() -> Self {
        Self {
            report_spp: default_report_spp(),
            report_views: default_report_views(),
            seed: 0,
            detail_texels: default_detail_texels(),
            detail_density: default_detail_density(),
            detail_spp: default_detail_spp(),
        }
    }
}

/// Reads `path`, applies `overrides` (`a.b=value`), and deserialises the result.
pub fn load(path: &Path, overrides: &[String]) -> Result<Config, ConfigError> {
    let text =
        std::fs::read_to_string(path).map_err(|source| ConfigError::Read { path: path.to_path_buf(), source })?;
    parse(&text, path, overrides)
}

/// Parses config text (`path` only labels errors), applies `overrides`, deserialises.
pub fn parse(text: &str, path: &Path, overrides: &[String]) -> Result<Config, ConfigError> {
    let mut table: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| ConfigError::Syntax { path: path.to_path_buf(), message: one_line(&e) })?;
    for arg in overrides {
        apply_override(&mut table, arg)?;
    }
    // After the overrides, so that `--set quality=...` works and `--set` keys win over the preset.
    crate::presets::apply(&mut table).map_err(|(key, message)| ConfigError::Key {
        path: path.to_path_buf(),
        key,
        message,
    })?;
    let de = toml::Value::Table(table);
    serde_path_to_error::deserialize(de).map_err(|e| {
        let parent = e.path().to_string();
        let message = one_line(&e.inner().message());
        // serde reports a missing field at its parent; name the field itself.
        let missing = message.strip_prefix("missing field `").and_then(|m| m.split('`').next());
        let key = match missing {
            Some(field) if parent == "." => field.to_owned(),
            Some(field) => format!("{parent}.{field}"),
            None => parent,
        };
        ConfigError::Key { path: path.to_path_buf(), key, message }
    })
}

/// Applies one `a.b.c=value` override. The value is parsed as a TOML value (`3`, `1e-3`, `true`,
/// `"text"`, `[1, 2]`); if that fails it is taken as a plain string (so `scan.path=/data/x` works unquoted).
pub fn apply_override(table: &mut toml::Table, arg: &str) -> Result<(), ConfigError> {
    let err = |message: &str| ConfigError::Override { arg: arg.to_owned(), message: message.to_owned() };
    let (key, raw) = arg.split_once('=').ok_or_else(|| err("expected key=value"))?;
    let parts: Vec<&str> = key.trim().split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(err("empty key segment"));
    }
    let value = parse_value(raw.trim());
    let (last, parents) = parts.split_last().ok_or_else(|| err("empty key"))?;
    let mut cur = table;
    for (i, part) in parents.iter().enumerate() {
        let entry = cur.entry((*part).to_owned()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
        cur = entry.as_table_mut().ok_or_else(|| ConfigError::Override {
            arg: arg.to_owned(),
            message: format!("`{}` is not a table", parts[..=i].join(".")),
        })?;
    }
    cur.insert((*last).to_owned(), value);
    Ok(())
}

fn parse_value(raw: &str) -> toml::Value {
    let doc = format!("v = {raw}");
    match doc.parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").unwrap_or_else(|| toml::Value::String(raw.to_owned())),
        Err(_) => toml::Value::String(raw.to_owned()),
    }
}

/// Collapses a possibly multi-line error message (toml's include a source excerpt) into one line.
fn one_line(e: &dyn std::fmt::Display) -> String {
    let text = e.to_string();
    let lines: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('|')).collect();
    // toml's syntax errors are "TOML parse error at line L, column C" + excerpt lines + the message; keep the
    // location and the message, drop the excerpt (lines like "3 | key = " and "  ^").
    let kept: Vec<&str> =
        lines.into_iter().filter(|l| !l.chars().next().is_some_and(|c| c.is_ascii_digit()) && *l != "^").collect();
    kept.join(": ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pixel_budget_raises_the_downscale_to_the_smallest_factor_that_fits() {
        let house = vec![(1280, 1024); 180];
        let images = ImagesConfig::default();
        // 236 M pixels at full resolution, 9.4 M at 5 (256×204 each), 6.5 M at 6 (213×170).
        assert_eq!(images.effective_downscale(&house), 6);
        assert_eq!(images.effective_downscale(&[(96, 72); 8]), 1);
        // A configured factor is a floor.
        assert_eq!(ImagesConfig { downscale: 8, ..images.clone() }.effective_downscale(&house), 8);
        assert_eq!(ImagesConfig { downscale: 2, ..images.clone() }.effective_downscale(&[(96, 72); 8]), 2);
        // Exactly at the budget fits; one pixel less does not.
        let exact = ImagesConfig { max_pixels: 8 * 48 * 36, ..images.clone() };
        assert_eq!(exact.effective_downscale(&[(96, 72); 8]), 2);
        assert_eq!(ImagesConfig { max_pixels: 8 * 48 * 36 - 1, ..exact }.effective_downscale(&[(96, 72); 8]), 3);
        // A budget no factor meets stops at the smallest view's shorter side.
        assert_eq!(ImagesConfig { max_pixels: 1, ..images }.effective_downscale(&[(96, 72), (40, 30)]), 30);
    }

    fn p(text: &str, sets: &[&str]) -> Result<Config, ConfigError> {
        let sets: Vec<String> = sets.iter().map(|s| (*s).to_owned()).collect();
        parse(text, Path::new("c.toml"), &sets)
    }

    #[test]
    fn minimal_config_takes_documented_defaults() {
        let c = p("[scan]\npath = \"scan\"\n", &[]).unwrap();
        assert_eq!(c.scan.path, PathBuf::from("scan"));
        assert_eq!(c.scan.format, ScanFormat::Auto);
        assert_eq!(c.output.path, PathBuf::from("run"));
        assert_eq!(c.images, ImagesConfig::default());
        assert_eq!(
            c.tracer.settings(),
            tracer::TracerSettings { max_depth: DEFAULT_MAX_DEPTH, ..tracer::TracerSettings::default() }
        );
    }

    #[test]
    fn unknown_key_error_names_the_dotted_key_on_one_line() {
        let e = p("[scan]\npath = \"s\"\n[tracer]\nmax_dept = 3\n", &[]).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("tracer.max_dept"), "{msg}");
        assert!(!msg.contains('\n'), "{msg}");
    }

    #[test]
    fn wrong_type_error_names_the_key() {
        let e = p("[scan]\npath = \"s\"\n[tracer]\nmax_depth = \"deep\"\n", &[]).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("`tracer.max_depth`"), "{msg}");
        assert!(!msg.contains('\n'), "{msg}");
    }

    #[test]
    fn missing_scan_path_names_scan() {
        let e = p("[scan]\nformat = \"obj\"\n", &[]).unwrap_err();
        assert!(e.to_string().contains("`scan.path`: missing field `path`"), "{e}");
        let e = p("[output]\npath = \"o\"\n", &[]).unwrap_err();
        assert!(e.to_string().contains("`scan`: missing field `scan`"), "{e}");
    }

    #[test]
    fn syntax_error_is_one_line_with_location() {
        let e = p("[scan\npath = 1\n", &[]).unwrap_err();
        let msg = e.to_string();
        assert!(!msg.contains('\n'), "{msg}");
        assert!(msg.contains("line 1"), "{msg}");
    }

    #[test]
    fn overrides_parse_toml_values_and_fall_back_to_strings() {
        let c = p(
            "[scan]\npath = \"a\"\n",
            &["scan.path=/data/x y", "tracer.max_depth=7", "images.cameras=[\"v1\", \"v2\"]", "output.path=\"o\""],
        )
        .unwrap();
        assert_eq!(c.scan.path, PathBuf::from("/data/x y"));
        assert_eq!(c.tracer.max_depth, 7);
        assert_eq!(c.images.cameras, vec!["v1".to_owned(), "v2".to_owned()]);
        assert_eq!(c.output.path, PathBuf::from("o"));
    }

    #[test]
    fn override_of_unknown_key_is_rejected_by_name() {
        let e = p("[scan]\npath = \"a\"\n", &["images.downscal=2"]).unwrap_err();
        assert!(e.to_string().contains("images.downscal"), "{e}");
    }

    #[test]
    fn override_through_a_non_table_is_rejected() {
        let e = p("[scan]\npath = \"a\"\n", &["scan.path.x=2"]).unwrap_err();
        assert!(e.to_string().contains("`scan.path` is not a table"), "{e}");
        let e = p("[scan]\npath = \"a\"\n", &["noequals"]).unwrap_err();
        assert!(matches!(e, ConfigError::Override { .. }));
    }
}
