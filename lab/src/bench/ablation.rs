//! `lab bench ablation`: the paper's path-count ablations reproduced on our fit's Adam phase.
//!
//! - Fig. 9: convergence with 1 value path against 2^7 … 2^10 (one gradient path each).
//! - Fig. 10: a fixed budget of paths per pixel and iteration split between value and gradient paths.
//!
//! Each run is the per-object fit with the Gauss–Newton refinement and the specular trial switched off, so
//! the curves are Adam's alone (after the initial closed-form emission solve it shares with every run; the
//! emission then stays fixed). Per iteration: the
//! batch loss and the albedo L1 of the iterate against the truth. Outputs `ablation_value_paths.csv`,
//! `ablation_budget_split.csv` and `ablation.svg`.

use std::fmt::Write as _;
use std::path::PathBuf;

use super::{BenchError, FitSetup, tradeoff};
use workflow::svg::{self, Panel, Series};

/// What to run.
#[derive(Debug, Clone)]
pub struct AblationOptions {
    pub workspace: PathBuf,
    pub scene: String,
    pub out: PathBuf,
    pub quick: bool,
}

/// One curve: the (n_value, n_grad) of a run and its trajectory.
#[derive(Debug, Clone)]
pub struct Curve {
    pub experiment: &'static str,
    pub n_value: u32,
    pub n_grad: u32,
    pub seconds: f64,
    pub rays: u64,
    /// (iteration, batch loss, albedo L1).
    pub points: Vec<(u32, f64, f64)>,
}

/// Adam iterations of each run (the paper plots a few hundred).
const ITERATIONS: u32 = 150;
/// Paths per pixel per iteration of the budget-split experiment (value + gradient).
const BUDGET: u32 = 128;

/// Runs both ablations and writes their outputs.
pub fn run(opts: &AblationOptions) -> Result<Vec<Curve>, BenchError> {
    let scene = tradeoff::load_scene(&opts.workspace, &opts.scene, opts.quick)?;
    let (train, _) = tradeoff::holdout_views(&scene);
    let mut base = tradeoff::base_setup(&scene);
    let o = &mut base.object;
    o.iterations = if opts.quick { 3 } else { ITERATIONS };
    // Emission stays at the initial closed-form solve: the curves are Adam's alone (a re-solve every 25
    // iterations would cost more than the Adam steps themselves).
    (o.refine_steps, o.try_specular, o.emission_solve_every) = (0, false, 0);
    if opts.quick {
        (o.solve_pixels, o.solve_spp, o.holdout_spp) = (64, 4, 8);
        base.max_depth = 3;
    }
    let value_paths: Vec<u32> = if opts.quick { vec![1, 8] } else { vec![1, 128, 256, 512, 1024] };
    let budget = if opts.quick { 8 } else { BUDGET };
    let splits: Vec<u32> = if opts.quick { vec![1, 4] } else { vec![1, 8, 32, 64, 96, 120] };
    let mut runs: Vec<(&'static str, u32, u32)> = value_paths.iter().map(|&v| ("value_paths", v, 1)).collect();
    runs.extend(splits.iter().map(|&g| ("budget_split", budget - g, g)));
    let truth = &scene.built.params;
    let light: Vec<bool> = truth.emission.iter().map(|e| e.max_element() > 0.0).collect();
    let mut curves = Vec::new();
    for (experiment, n_value, n_grad) in runs {
        let setup = FitSetup {
            object: optim::fit::ObjectFitSettings { n_value, n_grad, ..base.object.clone() },
            ..base.clone()
        };
        let fit = super::timed_fit(&scene, &train, &setup)?;
        let points: Vec<(u32, f64, f64)> = fit
            .outcome
            .history
            .iter()
            .filter(|h| h.phase == "adam")
            .map(|h| {
                let errs: Vec<f64> = (0..truth.materials.len())
                    .filter(|&k| !light[k])
                    .map(|k| {
                        let t = truth.materials[k].base_color;
                        (0..3).map(|c| (h.base_color[k][c] - f64::from(t[c])).abs()).sum::<f64>() / 3.0
                    })
                    .collect();
                (h.iteration, h.loss, super::metrics::mean(&errs))
            })
            .collect();
        eprintln!(
            "bench ablation: {experiment} n_value {n_value} n_grad {n_grad}: {:.1} s, final albedo L1 {:.4}",
            fit.seconds,
            points.last().map_or(f64::NAN, |p| p.2)
        );
        curves.push(Curve { experiment, n_value, n_grad, seconds: fit.seconds, rays: fit.rays, points });
    }
    for (experiment, file) in
        [("value_paths", "ablation_value_paths.csv"), ("budget_split", "ablation_budget_split.csv")]
    {
        let mut s = String::from("experiment,n_value,n_grad,run_wall_time_s,run_rays,iteration,loss,albedo_l1\n");
        for c in curves.iter().filter(|c| c.experiment == experiment) {
            for (it, loss, a) in &c.points {
                let _ = writeln!(
                    s,
                    "{},{},{},{:.3},{},{},{:.6},{:.6}",
                    c.experiment, c.n_value, c.n_grad, c.seconds, c.rays, it, loss, a
                );
            }
        }
        super::write_file(&opts.out.join(file), s.as_bytes())?;
    }
    super::write_file(&opts.out.join("ablation.svg"), plot(&curves, &opts.scene, budget).as_bytes())?;
    Ok(curves)
}

fn plot(curves: &[Curve], scene: &str, budget: u32) -> String {
    let mut panels = Vec::new();
    for (experiment, title) in [
        ("value_paths", "value paths (1 gradient path)".to_owned()),
        ("budget_split", format!("{budget} paths split value/gradient")),
    ] {
        for (metric, idx) in [("batch loss (mean L1)", 1usize), ("albedo L1", 2)] {
            let series: Vec<Series> = curves
                .iter()
                .filter(|c| c.experiment == experiment)
                .enumerate()
                .map(|(i, c)| Series {
                    name: format!("{} value / {} grad", c.n_value, c.n_grad),
                    color: svg::PALETTE[i % svg::PALETTE.len()].into(),
                    points: c.points.iter().map(|p| (f64::from(p.0), if idx == 1 { p.1 } else { p.2 })).collect(),
                    line: true,
                    markers: false,
                })
                .collect();
            panels.push(Panel {
                title: format!("{scene}: {title}"),
                x_label: "Adam iteration".into(),
                y_label: metric.into(),
                log_x: false,
                log_y: true,
                series,
            });
        }
    }
    svg::render("Adam-phase ablations (paper Fig. 9 and 10)", &panels, 2)
}
