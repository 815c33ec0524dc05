//! `lab bench tradeoff --quick` and `lab bench ablation --quick` write well-formed outputs: the CSV
//! has the documented header and a full row per sweep point with finite accuracy columns (on the textured
//! `checker` scene also the per-triangle stage's time, face count and texture error), CPU time and load
//! average; the SVG is one well-formed document with a marker per point, the markdown names every scene. No
//! timing assertions beyond what must hold on any machine (CPU time ≤ cores × wall time).

use std::path::Path;
use std::process::Command;

use lab::bench::tradeoff::CSV_COLUMNS;

/// Checks that `svg` is a single well-formed XML element tree (tags balanced and properly nested, attribute
/// quotes closed) — enough for a file we write ourselves, without an XML dependency.
fn assert_well_formed_xml(svg: &str) {
    let mut stack: Vec<String> = Vec::new();
    let mut rest = svg.trim();
    let mut roots = 0;
    while let Some(start) = rest.find('<') {
        let text = &rest[..start];
        assert!(!text.contains('>'), "stray '>' in text: {text:?}");
        let end = rest[start..].find('>').expect("unclosed tag") + start;
        let tag = &rest[start + 1..end];
        assert_eq!(tag.matches('"').count() % 2, 0, "unbalanced quotes in <{tag}>");
        if let Some(name) = tag.strip_prefix('/') {
            assert_eq!(stack.pop().as_deref(), Some(name.trim()), "mismatched </{name}>");
        } else if !tag.ends_with('/') {
            if stack.is_empty() {
                roots += 1;
            }
            stack.push(tag.split_whitespace().next().unwrap_or_default().to_owned());
        } else if stack.is_empty() {
            roots += 1;
        }
        rest = &rest[end + 1..];
    }
    assert!(stack.is_empty(), "unclosed elements {stack:?}");
    assert_eq!(roots, 1, "exactly one root element");
}

fn read(dir: &Path, name: &str) -> String {
    std::fs::read_to_string(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn quick_tradeoff_writes_well_formed_csv_svg_and_markdown() {
    let out = tempfile::tempdir().unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_lab"))
        .args(["bench", "tradeoff", "--quick", "--scenes", "demo,glossy,checker", "--out"])
        .arg(out.path())
        .status()
        .unwrap();
    assert!(status.success());

    let csv = read(out.path(), "tradeoff.csv");
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap().split(',').collect::<Vec<_>>(), CSV_COLUMNS);
    let col = |name: &str| CSV_COLUMNS.iter().position(|c| *c == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.len() >= 6, "two quick points per scene, got {} rows", rows.len());
    for scene in ["demo", "glossy", "checker"] {
        let sr: Vec<&Vec<&str>> = rows.iter().filter(|r| r[0] == scene).collect();
        assert!(!sr.is_empty(), "no rows for {scene}");
        assert!(sr.iter().any(|r| r[col("pareto")] == "true"), "{scene}: no point on the Pareto front");
    }
    for r in &rows {
        assert_eq!(r.len(), CSV_COLUMNS.len(), "{r:?}");
        for name in [
            "wall_time_s",
            "albedo_l1",
            "emission_rel_err",
            "spurious_emission",
            "roughness_err",
            "rerender_l1",
            "rerender_l1_truth",
            "cpu_time_s",
            "load_avg_1m",
        ] {
            let v: f64 = r[col(name)].parse().unwrap_or_else(|e| panic!("{name} = {}: {e}", r[col(name)]));
            assert!(v.is_finite() && v >= 0.0, "{name} = {v}");
        }
        let num = |name: &str| r[col(name)].parse::<f64>().unwrap_or_else(|e| panic!("{name}: {e}"));
        // A process cannot use more CPU than its cores over the wall time (+ 2 ticks of /proc's 10 ms clock).
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
        assert!(num("cpu_time_s") <= cores * num("wall_time_s") + 0.02, "{r:?}");
        let triangle_cols = ["triangle_time_s", "faces", "texture_l1", "texture_psnr_db", "triangle_emission_rel_err"];
        if r[0] == "checker" {
            // The textured scene ran the per-triangle stage: its time is part of the point's, the mesh only grows
            // from the scan's 14 triangles, the texture error is an albedo difference in [0, 1].
            for name in triangle_cols {
                assert!(num(name).is_finite(), "{name} = {}", r[col(name)]);
            }
            assert!(num("triangle_time_s") >= 0.0 && num("triangle_time_s") <= num("wall_time_s"), "{r:?}");
            assert!(r[col("faces")].parse::<usize>().unwrap() >= 14, "{r:?}");
            assert!((0.0..=1.0).contains(&num("texture_l1")), "{r:?}");
        } else {
            for name in triangle_cols {
                assert!(r[col(name)].is_empty(), "{name} on an untextured scene: {r:?}");
            }
        }
        let (paths, rays): (u64, u64) = (r[col("paths")].parse().unwrap(), r[col("rays")].parse().unwrap());
        // Every path casts at least its camera ray.
        assert!(paths > 0 && rays >= paths, "paths {paths}, rays {rays}");
        // One model per object of the scene.
        assert!(r[col("models")].split(';').all(|m| m.starts_with("diffuse") || m.starts_with("specular")));
    }

    let svg = read(out.path(), "tradeoff.svg");
    assert!(svg.starts_with("<svg"));
    assert_well_formed_xml(&svg);
    // Four panels per scene, each with one grey marker per sweep point.
    assert_eq!(svg.matches("fill=\"#999999\" fill-opacity").count(), 4 * rows.len());

    let md = read(out.path(), "tradeoff.md");
    assert!(md.starts_with("# "));
    for scene in ["demo", "glossy", "checker"] {
        assert!(md.contains(&format!("## {scene}: Pareto front")), "{md}");
    }
    assert!(md.contains("load average") && md.contains("CPU time"), "{md}");
    assert!(md.contains("texture L1"), "{md}");
    let front_rows = rows.iter().filter(|r| r[col("pareto")] == "true").count();
    assert_eq!(md.matches("(front)").count(), front_rows);

    // `--replot` parses the CSV back (every column, the empty per-triangle cells of untextured scenes included)
    // and rewrites it unchanged, the Pareto flags recomputed from the parsed times and errors.
    let status = Command::new(env!("CARGO_BIN_EXE_lab"))
        .args(["bench", "tradeoff", "--replot", "--out"])
        .arg(out.path())
        .status()
        .unwrap();
    assert!(status.success());
    assert_eq!(read(out.path(), "tradeoff.csv"), csv);
    assert_eq!(read(out.path(), "tradeoff.md").matches("(front)").count(), front_rows);
}

#[test]
fn quick_ablation_writes_one_curve_per_run() {
    let out = tempfile::tempdir().unwrap();
    let opts = lab::bench::ablation::AblationOptions {
        workspace: lab::bench::default_workspace(),
        scene: "demo".into(),
        out: out.path().to_path_buf(),
        quick: true,
    };
    let curves = lab::bench::ablation::run(&opts).unwrap();
    assert_eq!(curves.len(), 4);
    for (file, experiment) in
        [("ablation_value_paths.csv", "value_paths"), ("ablation_budget_split.csv", "budget_split")]
    {
        let csv = read(out.path(), file);
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(
            header,
            ["experiment", "n_value", "n_grad", "run_wall_time_s", "run_rays", "iteration", "loss", "albedo_l1"]
        );
        let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
        // Two runs of three Adam iterations each.
        assert_eq!(rows.len(), 6, "{file}");
        for r in rows {
            assert_eq!(r[0], experiment);
            for v in &r[5..] {
                assert!(v.parse::<f64>().unwrap().is_finite());
            }
        }
    }
    for c in curves.iter().filter(|c| c.experiment == "budget_split") {
        assert_eq!(c.n_value + c.n_grad, 8, "the quick budget is 8 paths");
    }
    assert_well_formed_xml(&read(out.path(), "ablation.svg"));
}
