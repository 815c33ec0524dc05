//! `tradeoff.md`: the sweep's summary — per scene the table of points, the Pareto front and how to read the
//! times (load average, CPU/wall).

use std::fmt::Write as _;

use super::{HOLDOUT_RENDER_SPP, QUICK_HOLDOUT_RENDER_SPP, Row, TradeoffOptions, scene_names, triangle_config};
use crate::bench::metrics;

pub(super) fn summary(rows: &[Row], opts: &TradeoffOptions) -> String {
    let mut s = String::new();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let _ = writeln!(s, "# Speed/accuracy trade-off of the per-object fit\n");
    let _ = writeln!(
        s,
        "Measured by `lab bench tradeoff{}` on {} ({cores} logical cores). One view per scene is held back \
         from the fit (the last; on textured scenes the last whose centre sees the textured object, see \
         `holdout_views`) and re-rendered with the fitted materials ({} paths/pixel; `rerender_l1_truth` is the same for \
         the true materials, i.e. the noise floor). Errors against the scene's ground truth. Full data: \
         `tradeoff.csv`; plot: `tradeoff.svg`.\n",
        if opts.quick { " --quick" } else { "" },
        std::env::consts::ARCH,
        if opts.quick { QUICK_HOLDOUT_RENDER_SPP } else { HOLDOUT_RENDER_SPP },
    );
    let _ = writeln!(s, "{}\n", timing_note(rows, cores));
    if rows.iter().any(|r| r.triangle.is_some()) {
        let t = triangle_config(opts.quick);
        let _ = writeln!(
            s,
            "Scenes with a textured (checker) object also run the per-triangle stage (adaptive subdivision + \
             per-triangle fit, `rounds = {}`, `spp = {}`, `fit_steps = {}`) after the per-object fit at every point: \
             its time is part of the point's wall time and also listed alone; `texture L1`/`PSNR` compare the \
             final per-triangle albedo with the true checker at {} seeded random points of the textured object; \
             their Pareto front is on the texture L1, and `albedo L1` covers the untextured objects only. The \
             re-render uses the per-triangle result.\n",
            t.rounds,
            t.spp,
            t.fit_steps,
            metrics::TEXTURE_POINTS,
        );
    }
    for scene in scene_names(rows) {
        let sr: Vec<&Row> = rows.iter().filter(|r| r.scene == scene).collect();
        let textured = sr.iter().any(|r| r.triangle.is_some());
        let error_name = if textured { "texture L1" } else { "albedo L1" };
        let _ = writeln!(s, "## {scene}: Pareto front (wall time vs {error_name})\n");
        let _ = writeln!(
            s,
            "| point | wall [s] | CPU [s] | load 1 min | rays | albedo L1 | emission rel. err | roughness err | \
             re-render L1 |{}\n|---|---|---|---|---|---|---|---|---|{}",
            if textured {
                " triangle stage [s] | faces | texture L1 | PSNR [dB] | emission rel. err after it |"
            } else {
                ""
            },
            if textured { "---|---|---|---|---|" } else { "" }
        );
        let mut front: Vec<&&Row> = sr.iter().filter(|r| r.pareto).collect();
        front.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
        for r in front {
            let _ = writeln!(
                s,
                "| `{}` | {:.2} | {:.2} | {:.2} | {:.3e} | {:.4} | {:.4} | {:.3} | {:.4} |{}",
                r.point.label,
                r.seconds,
                r.cpu_seconds,
                r.load_avg_1m,
                r.rays as f64,
                r.accuracy.albedo_l1,
                r.accuracy.emission_rel_err,
                r.accuracy.roughness_err,
                r.rerender_l1,
                triangle_cells(r)
            );
        }
        if let Some(d) = sr.iter().find(|r| r.point.group == "default") {
            let _ = writeln!(
                s,
                "\nDefault settings: {:.2} s wall ({:.2} s CPU, load {:.2}), albedo L1 {:.4}, emission error {:.4}, \
                 re-render L1 {:.4} (floor {:.4}){}.\n",
                d.seconds,
                d.cpu_seconds,
                d.load_avg_1m,
                d.accuracy.albedo_l1,
                d.accuracy.emission_rel_err,
                d.rerender_l1,
                d.rerender_l1_truth,
                d.triangle.map_or(String::new(), |t| format!(
                    ", per-triangle stage {:.2} s, {} faces, texture L1 {:.4} ({:.2} dB), emission error after it {:.4}",
                    t.seconds, t.faces, t.texture_l1, t.texture_psnr_db, t.emission_rel_err
                ))
            );
        }
        let _ = writeln!(
            s,
            "\nEvery point:\n\n| point | wall [s] | CPU [s] | load 1 min | albedo L1 | emission rel. err | re-render L1 |{}\n\
             |---|---|---|---|---|---|---|{}",
            if textured {
                " triangle stage [s] | faces | texture L1 | PSNR [dB] | emission rel. err after it |"
            } else {
                ""
            },
            if textured { "---|---|---|---|---|" } else { "" }
        );
        for r in &sr {
            let _ = writeln!(
                s,
                "| `{}`{} | {:.2} | {:.2} | {:.2} | {:.4} | {:.4} | {:.4} |{}",
                r.point.label,
                if r.pareto { " (front)" } else { "" },
                r.seconds,
                r.cpu_seconds,
                r.load_avg_1m,
                r.accuracy.albedo_l1,
                r.accuracy.emission_rel_err,
                r.rerender_l1,
                triangle_cells(r)
            );
        }
        s.push('\n');
    }
    s
}

/// The per-triangle cells of a markdown row (empty for rows without the stage).
fn triangle_cells(r: &Row) -> String {
    r.triangle.map_or(String::new(), |t| {
        format!(
            " {:.2} | {} | {:.4} | {:.2} | {:.4} |",
            t.seconds, t.faces, t.texture_l1, t.texture_psnr_db, t.emission_rel_err
        )
    })
}

/// How to read the times: the range of load averages and of CPU/wall ratios over the rows.
fn timing_note(rows: &[Row], cores: usize) -> String {
    let finite = |v: Vec<f64>| -> Option<(f64, f64)> {
        let v: Vec<f64> = v.into_iter().filter(|x| x.is_finite()).collect();
        (!v.is_empty()).then(|| v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x))))
    };
    let load = finite(rows.iter().map(|r| r.load_avg_1m).collect());
    // Points shorter than 0.1 s are left out of the ratio: the CPU clock ticks in 10 ms steps.
    let ratio = finite(rows.iter().filter(|r| r.seconds >= 0.1).map(|r| r.cpu_seconds / r.seconds).collect());
    let mut s = format!(
        "Timing: `wall_time_s` is the elapsed time of the point (the Pareto fronts use it); `cpu_time_s` is this \
         process's user + system CPU time over the same span (all threads, `/proc/self/stat`), and `load_avg_1m` \
         the machine's 1-minute load average when the point started (`/proc/loadavg`). On an idle machine the \
         load stays below the {cores} cores and CPU ≈ {cores} × wall for the parallel parts; a load above the core \
         count with CPU/wall well below {cores} means other jobs took the cores and the wall time is inflated."
    );
    if let Some((lo, hi)) = load {
        let _ = write!(s, " This run: load average {lo:.2}–{hi:.2}");
        if let Some((a, b)) = ratio {
            let _ = write!(s, ", CPU/wall {a:.2}–{b:.2}");
        }
        s.push('.');
    }
    s
}
