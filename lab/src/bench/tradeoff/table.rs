//! `tradeoff.csv`: the measured rows, their columns, and the CSV written and read back (`--replot`).

use std::fmt::Write as _;

use optim::fit::ObjectFitSettings;

use super::SweepPoint;
use crate::bench::FitSetup;
use crate::bench::metrics::Accuracy;

/// One measured row of `tradeoff.csv`.
#[derive(Debug, Clone)]
pub struct Row {
    pub scene: String,
    pub point: SweepPoint,
    /// Wall time of the point: the per-object fit plus, on textured scenes, the per-triangle stage.
    pub seconds: f64,
    /// This process's user + system CPU time over the same span.
    pub cpu_seconds: f64,
    /// The machine's 1-minute load average when the point started.
    pub load_avg_1m: f64,
    pub paths: u64,
    pub rays: u64,
    pub accuracy: Accuracy,
    /// Relative L1 of the held-back views re-rendered with the fitted materials.
    pub rerender_l1: f64,
    /// The same for the true materials (the noise floor of `rerender_l1`).
    pub rerender_l1_truth: f64,
    /// The per-triangle stage, on scenes with textured objects.
    pub triangle: Option<TriangleColumns>,
    /// On the (seconds, [`pareto_error`]) Pareto front of its scene.
    pub pareto: bool,
}

/// What the per-triangle stage of a point did and how well its texture matches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleColumns {
    /// Wall time of the stage (included in [`Row::seconds`]).
    pub seconds: f64,
    /// Faces of the final mesh (all objects).
    pub faces: usize,
    /// Mean |albedo − true checker| over RGB at random points of the textured objects.
    pub texture_l1: f64,
    /// PSNR of the same (peak 1).
    pub texture_psnr_db: f64,
    /// Largest relative error of a true emitter's emission after the stage (the stage may re-solve the
    /// light; `Accuracy::emission_rel_err` is the per-object stage's).
    pub emission_rel_err: f64,
}

/// The error a scene's Pareto front is drawn on: the texture L1 on scenes whose rows ran the per-triangle
/// stage, else the per-object albedo L1.
#[must_use]
pub fn pareto_error(r: &Row) -> f64 {
    r.triangle.map_or(r.accuracy.albedo_l1, |t| t.texture_l1)
}

/// A row's point for its scene's Pareto front: wall time and [`pareto_error`] as [`csv`] writes them (3 and 6
/// decimals). A sweep and a `--replot` of its CSV then mark the same front: on the exact values two points
/// that tie in the CSV (0.1812 s and 0.1808 s, both written 0.181) can dominate each other, and on the
/// parsed ones not.
#[must_use]
pub fn pareto_point(r: &Row) -> (f64, f64) {
    let written = |v: f64, decimals: usize| format!("{v:.decimals$}").parse().unwrap_or(v);
    (written(r.seconds, 3), written(pareto_error(r), 6))
}

/// The CSV columns, in order.
pub const CSV_COLUMNS: [&str; 31] = [
    "scene",
    "group",
    "label",
    "iterations",
    "batch_pixels",
    "n_value",
    "n_grad",
    "solve_pixels",
    "solve_spp",
    "refine_steps",
    "try_specular",
    "max_depth",
    "downscale",
    "wall_time_s",
    "cpu_time_s",
    "load_avg_1m",
    "paths",
    "rays",
    "albedo_l1",
    "emission_rel_err",
    "spurious_emission",
    "roughness_err",
    "rerender_l1",
    "rerender_l1_truth",
    "triangle_time_s",
    "faces",
    "texture_l1",
    "texture_psnr_db",
    "triangle_emission_rel_err",
    "pareto",
    "models",
];

pub(super) fn csv(rows: &[Row], models: &[String]) -> String {
    let mut s = CSV_COLUMNS.join(",");
    s.push('\n');
    for (r, m) in rows.iter().zip(models) {
        let o = &r.point.setup.object;
        let a = &r.accuracy;
        let tri = r.triangle.map_or_else(
            || ",,,,".to_owned(),
            |t| {
                format!(
                    "{:.3},{},{:.6},{:.3},{:.6}",
                    t.seconds, t.faces, t.texture_l1, t.texture_psnr_db, t.emission_rel_err
                )
            },
        );
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3},{:.3},{:.2},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{},{},{}",
            r.scene,
            r.point.group,
            r.point.label,
            o.iterations,
            o.batch_pixels,
            o.n_value,
            o.n_grad,
            o.solve_pixels,
            o.solve_spp,
            o.refine_steps,
            o.try_specular,
            r.point.setup.max_depth,
            r.point.setup.downscale,
            r.seconds,
            r.cpu_seconds,
            r.load_avg_1m,
            r.paths,
            r.rays,
            a.albedo_l1,
            a.emission_rel_err,
            a.spurious_emission,
            a.roughness_err,
            r.rerender_l1,
            r.rerender_l1_truth,
            tri,
            r.pareto,
            m
        );
    }
    s
}

/// Rows and model columns of a `tradeoff.csv` written by [`csv`]; the error names the line and column.
pub fn parse(text: &str) -> Result<(Vec<Row>, Vec<String>), String> {
    let bad = |m: String| m;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    if header != CSV_COLUMNS {
        return Err(bad("header differs from this version's columns".into()));
    }
    let mut rows = Vec::new();
    let mut models = Vec::new();
    for (n, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let c: Vec<&str> = line.split(',').collect();
        if c.len() != CSV_COLUMNS.len() {
            return Err(bad(format!("line {}: {} cells", n + 2, c.len())));
        }
        let at = |name: &str| CSV_COLUMNS.iter().position(|c| *c == name).unwrap_or(0);
        let cell = |name: &str| c[at(name)];
        let int = |name: &str| cell(name).parse::<u64>().map_err(|e| bad(format!("line {}: {name}: {e}", n + 2)));
        let num = |name: &str| cell(name).parse::<f64>().map_err(|e| bad(format!("line {}: {name}: {e}", n + 2)));
        let u32_at = |name: &str| int(name).map(|v| v as u32);
        let object = ObjectFitSettings {
            iterations: u32_at("iterations")?,
            batch_pixels: u32_at("batch_pixels")?,
            n_value: u32_at("n_value")?,
            n_grad: u32_at("n_grad")?,
            solve_pixels: u32_at("solve_pixels")?,
            solve_spp: u32_at("solve_spp")?,
            refine_steps: u32_at("refine_steps")?,
            try_specular: cell("try_specular") == "true",
            ..ObjectFitSettings::default()
        };
        // The per-triangle columns are empty on rows that did not run the stage.
        let triangle = if cell("faces").is_empty() {
            None
        } else {
            Some(TriangleColumns {
                seconds: num("triangle_time_s")?,
                faces: int("faces")? as usize,
                texture_l1: num("texture_l1")?,
                texture_psnr_db: num("texture_psnr_db")?,
                emission_rel_err: num("triangle_emission_rel_err")?,
            })
        };
        rows.push(Row {
            scene: cell("scene").to_owned(),
            point: SweepPoint {
                group: cell("group").to_owned(),
                label: cell("label").to_owned(),
                setup: FitSetup { object, max_depth: u32_at("max_depth")?, downscale: u32_at("downscale")? },
            },
            seconds: num("wall_time_s")?,
            cpu_seconds: num("cpu_time_s")?,
            load_avg_1m: num("load_avg_1m")?,
            paths: int("paths")?,
            rays: int("rays")?,
            accuracy: Accuracy {
                albedo_l1: num("albedo_l1")?,
                emission_rel_err: num("emission_rel_err")?,
                spurious_emission: num("spurious_emission")?,
                roughness_err: num("roughness_err")?,
            },
            rerender_l1: num("rerender_l1")?,
            rerender_l1_truth: num("rerender_l1_truth")?,
            triangle,
            pareto: false,
        });
        models.push(cell("models").to_owned());
    }
    Ok((rows, models))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_points_are_the_values_the_csv_holds() {
        let header = CSV_COLUMNS.join(",");
        let line = "demo,corner,quick,2,16,4,1,64,4,2,false,3,1,0.181,0.170,1.85,60448,462172,0.090227,0.246056,\
                    0.000000,0.000000,0.088929,0.118621,,,,,,false,diffuse";
        let (mut rows, _) = parse(&format!("{header}\n{line}\n{line}\n")).unwrap();
        // Two sweep points 0.4 ms apart, written with the same 3 decimals: neither dominates the other on the
        // written values, as in a `--replot` of the CSV.
        rows[0].seconds = 0.1812;
        rows[1].seconds = 0.1808;
        rows[0].accuracy.albedo_l1 = 0.090_227_4;
        assert_eq!(pareto_point(&rows[0]), (0.181, 0.090227));
        assert_eq!(pareto_point(&rows[0]), pareto_point(&rows[1]));
    }
}
