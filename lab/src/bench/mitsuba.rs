//! `lab bench mitsuba`: the Mitsuba 3 baseline (`prb` + Adam, tests/validation/mitsuba_baseline) and our
//! fit on the same scene, same photos (all views), in one process one after the other on the same machine;
//! reports the time each needs to reach the same albedo error and their ratio.
//!
//! The common error is the larger of the two best errors reached (Mitsuba within its budget, ours over a
//! ladder of settings), i.e. the smallest error both reach; each side's time is the first time it is at or
//! below it (Mitsuba: the first CSV row; ours: the fastest setting of the ladder). Both times include loading
//! the scan and building the scene.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use super::{BenchError, FitSetup, tradeoff};
use workflow::svg::{self, Panel, Series};

/// What to run.
#[derive(Debug, Clone)]
pub struct MitsubaOptions {
    pub workspace: PathBuf,
    pub scene: String,
    pub out: PathBuf,
    /// Wall-time budget of the Mitsuba solve.
    pub budget_seconds: f64,
    /// The Python with Mitsuba 3 (default `<workspace>/deps/venv/bin/python`).
    pub python: PathBuf,
    pub quick: bool,
}

/// One (time, error) measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    pub label: String,
    pub seconds: f64,
    pub albedo_l1: f64,
    pub light_rel_err: f64,
}

/// The comparison.
#[derive(Debug, Clone)]
pub struct Comparison {
    pub mitsuba: Vec<Sample>,
    pub ours: Vec<Sample>,
    /// The albedo error both reach.
    pub common_error: f64,
    pub mitsuba_seconds: f64,
    pub ours_seconds: f64,
    /// Label of our fastest setting at or below the common error.
    pub ours_label: String,
}

impl Comparison {
    /// Mitsuba's time over ours at the common error.
    #[must_use]
    pub fn ratio(&self) -> f64 {
        self.mitsuba_seconds / self.ours_seconds
    }
}

/// Reads the baseline's CSV (columns `wall_time_s`, `albedo_l1`, `light_rel_err`, by header name).
pub fn read_mitsuba_csv(path: &Path) -> Result<Vec<Sample>, BenchError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| BenchError::Io { path: path.to_path_buf(), message: e.to_string() })?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').map(str::trim).collect();
    let col = |name: &str| {
        header.iter().position(|h| *h == name).ok_or_else(|| BenchError::Io {
            path: path.to_path_buf(),
            message: format!("no column `{name}` in the header"),
        })
    };
    let (t, a, l, it) = (col("wall_time_s")?, col("albedo_l1")?, col("light_rel_err")?, col("iteration")?);
    let mut out = Vec::new();
    for (n, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let num = |i: usize| -> Result<f64, BenchError> {
            cells.get(i).and_then(|c| c.parse::<f64>().ok()).ok_or_else(|| BenchError::Io {
                path: path.to_path_buf(),
                message: format!("line {}: column {} is not a number", n + 2, header[i]),
            })
        };
        out.push(Sample {
            label: format!("iteration {}", cells.get(it).unwrap_or(&"?")),
            seconds: num(t)?,
            albedo_l1: num(a)?,
            light_rel_err: num(l)?,
        });
    }
    Ok(out)
}

/// The time each side needs to reach the smallest albedo error both reach.
#[must_use]
pub fn compare(mitsuba: Vec<Sample>, ours: Vec<Sample>) -> Option<Comparison> {
    let best = |v: &[Sample]| v.iter().map(|s| s.albedo_l1).filter(|a| a.is_finite()).fold(f64::INFINITY, f64::min);
    let common = best(&mitsuba).max(best(&ours));
    if !common.is_finite() {
        return None;
    }
    let m = mitsuba.iter().filter(|s| s.albedo_l1 <= common).map(|s| s.seconds).fold(f64::INFINITY, f64::min);
    let o = ours.iter().filter(|s| s.albedo_l1 <= common).min_by(|a, b| a.seconds.total_cmp(&b.seconds))?;
    Some(Comparison {
        common_error: common,
        mitsuba_seconds: m,
        ours_seconds: o.seconds,
        ours_label: o.label.clone(),
        mitsuba,
        ours,
    })
}

/// Runs both solvers and writes `mitsuba_comparison.csv`, `mitsuba_comparison.svg` and `mitsuba_comparison.md`.
pub fn run(opts: &MitsubaOptions) -> Result<Comparison, BenchError> {
    std::fs::create_dir_all(&opts.out)
        .map_err(|e| BenchError::Io { path: opts.out.clone(), message: e.to_string() })?;
    // The solve runs in tests/validation: hand it absolute paths.
    let absolute = |p: &Path| {
        std::fs::canonicalize(p).map_err(|e| BenchError::Io { path: p.to_path_buf(), message: e.to_string() })
    };
    let scan = absolute(&super::scenes::fixtures_dir(&opts.workspace).join(&opts.scene))?;
    let mitsuba_csv = absolute(&opts.out)?.join("mitsuba_baseline.csv");
    let validation = opts.workspace.join("tests/validation");
    eprintln!("bench mitsuba: Mitsuba 3 prb + Adam on {} for {} s", scan.display(), opts.budget_seconds);
    let status = Command::new(&opts.python)
        .current_dir(&validation)
        .args(["-m", "mitsuba_baseline.solve", "--scene"])
        .arg(&scan)
        .arg("--budget-seconds")
        .arg(opts.budget_seconds.to_string())
        .arg("--out")
        .arg(&mitsuba_csv)
        .status()
        .map_err(|e| BenchError::Io { path: opts.python.clone(), message: format!("cannot run: {e}") })?;
    if !status.success() {
        return Err(BenchError::Other(format!("the Mitsuba baseline failed ({status})")));
    }
    let mitsuba = read_mitsuba_csv(&mitsuba_csv)?;

    let mut ours = Vec::new();
    let n_views;
    {
        let t = Instant::now();
        let scene = tradeoff::load_scene(&opts.workspace, &opts.scene, opts.quick)?;
        let load = t.elapsed().as_secs_f64();
        let base = tradeoff::base_setup(&scene);
        let mut ladder: Vec<(String, FitSetup)> =
            tradeoff::corners(&base).into_iter().map(|p| (p.label, p.setup)).collect();
        // The default settings are `corner:mid` at 2–3× the time (docs/tradeoff/tradeoff.md): left out to
        // keep the comparison inside a few minutes.
        if opts.quick {
            ladder = tradeoff::sweep_points(&base, true).into_iter().map(|p| (p.label, p.setup)).collect();
        }
        let all: Vec<usize> = (0..scene.built.cameras.len()).collect();
        n_views = all.len();
        for (label, setup) in &ladder {
            if !super::scenes::divisible(&scene, setup.downscale) {
                continue;
            }
            let fit = super::timed_fit(&scene, &all, setup)?;
            let a = super::metrics::accuracy(&scene.built, &fit.outcome.params);
            eprintln!(
                "bench mitsuba: ours {label}: {:.2} s (+{load:.2} s load), albedo L1 {:.4}",
                fit.seconds, a.albedo_l1
            );
            ours.push(Sample {
                label: label.clone(),
                seconds: load + fit.seconds,
                albedo_l1: a.albedo_l1,
                light_rel_err: a.emission_rel_err,
            });
        }
    }
    let cmp = compare(mitsuba.clone(), ours.clone())
        .ok_or_else(|| BenchError::Other("no finite albedo error on one side".into()))?;

    let mut s = String::from("solver,label,wall_time_s,albedo_l1,light_rel_err\n");
    for (solver, v) in [("mitsuba", &cmp.mitsuba), ("ours", &cmp.ours)] {
        for x in v {
            let _ = writeln!(s, "{solver},{},{:.3},{:.6},{:.6}", x.label, x.seconds, x.albedo_l1, x.light_rel_err);
        }
    }
    super::write_file(&opts.out.join("mitsuba_comparison.csv"), s.as_bytes())?;
    let pts = |v: &[Sample]| v.iter().map(|x| (x.seconds, x.albedo_l1)).collect::<Vec<_>>();
    let front: Vec<(f64, f64)> = {
        let p = pts(&cmp.ours);
        svg::pareto_front(&p).into_iter().map(|i| p[i]).collect()
    };
    let panel = Panel {
        title: format!("{}: albedo L1 against wall time (load + solve)", opts.scene),
        x_label: "wall time [s]".into(),
        y_label: "albedo mean L1".into(),
        log_x: true,
        log_y: true,
        series: vec![
            Series {
                name: "Mitsuba 3 prb + Adam".into(),
                color: svg::PALETTE[1].into(),
                points: pts(&cmp.mitsuba),
                line: true,
                markers: false,
            },
            Series {
                name: "ours (settings ladder)".into(),
                color: svg::PALETTE[0].into(),
                points: pts(&cmp.ours),
                line: false,
                markers: true,
            },
            Series {
                name: "ours, Pareto front".into(),
                color: svg::PALETTE[2].into(),
                points: front,
                line: true,
                markers: false,
            },
        ],
    };
    super::write_file(
        &opts.out.join("mitsuba_comparison.svg"),
        svg::render("Ours against Mitsuba 3", &[panel], 1).as_bytes(),
    )?;
    let mut md = String::new();
    let _ = writeln!(md, "# Ours against Mitsuba 3 (`lab bench mitsuba`)\n");
    let _ = writeln!(
        md,
        "Scene `{}`, all {} views, same photos; Mitsuba 3 `prb` + Adam (tests/validation/mitsuba_baseline, its default \
         settings) for a {} s budget, then our fit at {} settings of the sweep's corners, one after the other in the same process on the \
         same machine. Times include loading the scan.\n",
        opts.scene,
        n_views,
        opts.budget_seconds,
        cmp.ours.len()
    );
    let m_best = cmp.mitsuba.iter().map(|x| x.albedo_l1).fold(f64::INFINITY, f64::min);
    let _ = writeln!(
        md,
        "- Common albedo error (smallest both reach): **{:.4}**\n- Mitsuba reaches it after **{:.1} s** (its best within the budget: {:.4}; final light error {:.3})\n- Ours reaches it after **{:.2} s** (`{}`)\n- **Ratio: {:.1}×**\n",
        cmp.common_error,
        cmp.mitsuba_seconds,
        m_best,
        cmp.mitsuba.last().map_or(f64::NAN, |x| x.light_rel_err),
        cmp.ours_seconds,
        cmp.ours_label,
        cmp.ratio()
    );
    let _ = writeln!(md, "| ours: setting | wall time [s] | albedo L1 | light rel. err |\n|---|---|---|---|");
    for x in &cmp.ours {
        let _ = writeln!(md, "| `{}` | {:.2} | {:.4} | {:.4} |", x.label, x.seconds, x.albedo_l1, x.light_rel_err);
    }
    super::write_file(&opts.out.join("mitsuba_comparison.md"), md.as_bytes())?;
    eprintln!(
        "bench mitsuba: common albedo error {:.4}: Mitsuba {:.1} s, ours {:.2} s ({}), ratio {:.1}x",
        cmp.common_error,
        cmp.mitsuba_seconds,
        cmp.ours_seconds,
        cmp.ours_label,
        cmp.ratio()
    );
    Ok(cmp)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(t: f64, a: f64) -> Sample {
        Sample { label: format!("{t}"), seconds: t, albedo_l1: a, light_rel_err: 0.0 }
    }

    #[test]
    fn common_error_is_the_worse_best_and_times_are_first_reach() {
        let m = vec![s(10.0, 0.3), s(20.0, 0.1), s(30.0, 0.05), s(40.0, 0.06)];
        let o = vec![s(1.0, 0.2), s(2.0, 0.04), s(5.0, 0.01)];
        let c = compare(m, o).unwrap();
        assert_eq!(c.common_error, 0.05);
        assert_eq!(c.mitsuba_seconds, 30.0);
        assert_eq!(c.ours_seconds, 2.0);
        assert_eq!(c.ratio(), 15.0);
    }
}
