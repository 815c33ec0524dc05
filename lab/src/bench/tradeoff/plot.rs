//! `tradeoff.svg`: four panels per scene (the Pareto error, emission, re-render error, CPU time) against the
//! wall time, with each scene's Pareto front.

use workflow::svg::{self, Panel, Series};

use super::{Row, pareto_error, scene_names};

pub(super) fn plot(rows: &[Row]) -> String {
    let mut panels = Vec::new();
    type Metric = (&'static str, fn(&Row) -> f64);
    for scene in scene_names(rows) {
        let sr: Vec<&Row> = rows.iter().filter(|r| r.scene == scene).collect();
        let textured = sr.iter().any(|r| r.triangle.is_some());
        // Four panels per scene: the Pareto front's own error first (the texture error on textured scenes),
        // then emission, re-render and the CPU time (against the same wall time: contention shows as points
        // far below the line CPU = cores × wall).
        let metrics: [Metric; 4] = [
            if textured {
                ("texture L1 after the per-triangle stage", pareto_error)
            } else {
                ("albedo mean L1", pareto_error)
            },
            ("emission max relative error", |r| r.accuracy.emission_rel_err),
            ("held-back view re-render relative L1", |r| r.rerender_l1),
            ("process CPU time [s]", |r| r.cpu_seconds),
        ];
        for (name, f) in metrics {
            let pts: Vec<(f64, f64)> = sr.iter().map(|r| (r.seconds, f(r))).collect();
            let front: Vec<(f64, f64)> = svg::pareto_front(&pts).into_iter().map(|i| pts[i]).collect();
            let mut series = vec![Series {
                name: "sweep points".into(),
                color: "#999999".into(),
                points: pts,
                line: false,
                markers: true,
            }];
            series.push(Series {
                name: "Pareto front".into(),
                color: svg::PALETTE[1].into(),
                points: front,
                line: true,
                markers: true,
            });
            if let Some(d) = sr.iter().find(|r| r.point.group == "default") {
                series.push(Series {
                    name: "default settings".into(),
                    color: svg::PALETTE[0].into(),
                    points: vec![(d.seconds, f(d))],
                    line: false,
                    markers: true,
                });
            }
            if name.starts_with("held-back") {
                let floor = sr.first().map_or(0.0, |r| r.rerender_l1_truth);
                let (lo, hi) =
                    sr.iter().fold((f64::INFINITY, 0.0f64), |(a, b), r| (a.min(r.seconds), b.max(r.seconds)));
                series.push(Series {
                    name: "true materials (noise floor)".into(),
                    color: svg::PALETTE[2].into(),
                    points: vec![(lo, floor), (hi, floor)],
                    line: true,
                    markers: false,
                });
            }
            panels.push(Panel {
                title: format!("{scene}: {name}"),
                x_label: "fit wall time [s]".into(),
                y_label: name.into(),
                log_x: true,
                log_y: true,
                series,
            });
        }
    }
    svg::render("Per-object fit (+ per-triangle stage on textured scenes): error against time", &panels, 4)
}
