//! `lab bench scale --quick` (two points of the photo axis, each run in its own process) writes a CSV with
//! every column and one row per stage and point, and the held-out budget bounds the held-out pixels whatever
//! the photo count: with a budget of 8 pixels per object, both points hold at most 8 per object (and per
//! "no object") although their held-out candidates (10 % of all valid pixels) outnumber that at the larger
//! point. The SVG is drawn from the CSV, and `--replot` redraws the same document from it alone.

use std::process::Command;

use lab::bench::scale::CSV_COLUMNS;

const BUDGET: usize = 8;

#[test]
fn quick_scale_sweep_writes_every_column_and_the_budget_bounds_the_held_out_pixels() {
    let out = tempfile::tempdir().unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_lab"))
        .args(["bench", "scale", "--quick", "--out"])
        .arg(out.path())
        .args(["--set", "quality=preview", "--set", &format!("object.holdout_pixels={BUDGET}")])
        .env_remove("RUST_LOG")
        .status()
        .unwrap();
    assert!(status.success());
    let text = std::fs::read_to_string(out.path().join("scale.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header, CSV_COLUMNS);
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let col = |name: &str| CSV_COLUMNS.iter().position(|c| *c == name).unwrap();
    // Two points × (five stages + the total).
    assert_eq!(rows.len(), 12, "{text}");
    assert!(rows.iter().all(|r| r.len() == CSV_COLUMNS.len()), "{text}");
    let totals: Vec<&Vec<&str>> = rows.iter().filter(|r| r[col("stage")] == "total").collect();
    assert_eq!(totals.len(), 2);
    let num = |r: &Vec<&str>, name: &str| r[col(name)].parse::<f64>().unwrap();
    for r in &rows {
        for c in ["wall_s", "cpu_s", "peak_rss_mb"] {
            assert!(num(r, c).is_finite() && num(r, c) >= 0.0, "{c} in {r:?}");
        }
    }
    let (small, large) = (totals[0], totals[1]);
    assert!(num(large, "photos") > num(small, "photos"));
    for t in [small, large] {
        let groups = num(t, "objects") as usize + 1;
        let held = num(t, "holdout_pixels") as usize;
        assert!(held > 0 && held <= groups * BUDGET, "{held} held-out pixels for {groups} groups: {t:?}");
        assert!(num(t, "peak_rss_mb") > 0.0 && num(t, "albedo_l1").is_finite());
    }
    // The budget is what bounds the larger point: its candidates (10 % of its pixels) exceed it.
    let candidates = 0.1 * (num(large, "train_pixels") + num(large, "holdout_pixels"));
    assert!(candidates > ((num(large, "objects") as usize + 1) * BUDGET) as f64, "{large:?}");
    for f in ["scale.svg", "scale.md"] {
        assert!(out.path().join(f).is_file(), "{f} missing");
    }
    // The plot is drawn from the CSV: redrawn from it alone, it is the same document.
    let svg = std::fs::read_to_string(out.path().join("scale.svg")).unwrap();
    assert_eq!(svg.matches("<circle").count(), 4, "two points, each in a time and a memory panel");
    std::fs::remove_file(out.path().join("scale.svg")).unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_lab"))
        .args(["bench", "scale", "--replot", "--out"])
        .arg(out.path())
        .status()
        .unwrap();
    assert!(status.success());
    assert_eq!(std::fs::read_to_string(out.path().join("scale.svg")).unwrap(), svg);
}
