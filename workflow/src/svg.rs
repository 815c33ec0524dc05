//! The workspace's SVG plotter (hand-written, no dependencies): [`render`] draws titled panels of scatter/line
//! series on linear or log axes with decade ticks (the benchmark's figures); [`line_chart`] draws one compact
//! line chart with the axis extremes as ticks (report.html's loss curves). Both escape text with [`escape`].

use std::fmt::Write as _;

/// One series of a panel.
#[derive(Debug, Clone)]
pub struct Series {
    pub name: String,
    /// CSS colour.
    pub color: String,
    pub points: Vec<(f64, f64)>,
    /// Join the points with a polyline (in the given order).
    pub line: bool,
    /// Draw markers.
    pub markers: bool,
}

/// One plot.
#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
    pub series: Vec<Series>,
}

const PANEL_W: f64 = 460.0;
const PANEL_H: f64 = 320.0;
const MARGIN_L: f64 = 62.0;
const MARGIN_R: f64 = 14.0;
const MARGIN_T: f64 = 28.0;
const MARGIN_B: f64 = 44.0;

/// A qualitative palette (colour-blind safe, Okabe–Ito).
pub const PALETTE: [&str; 8] = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#F0E442"];

/// Escapes text for SVG/HTML element content and attribute values.
#[must_use]
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

struct Axis {
    lo: f64,
    hi: f64,
    log: bool,
}

impl Axis {
    fn new(values: impl Iterator<Item = f64>, log: bool) -> Axis {
        let v: Vec<f64> = values.filter(|v| v.is_finite() && (!log || *v > 0.0)).collect();
        let (mut lo, mut hi) = v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
        if !lo.is_finite() {
            (lo, hi) = (1.0, 10.0);
        }
        if log {
            let (l, h) = (lo.log10().floor(), hi.log10().ceil());
            // At least one decade so that a single point still gets a readable axis.
            Axis { lo: l, hi: if h > l { h } else { l + 1.0 }, log }
        } else {
            let pad = if hi > lo { 0.05 * (hi - lo) } else { 0.5f64.max(lo.abs() * 0.1) };
            Axis { lo: (lo - pad).min(if lo >= 0.0 { 0.0 } else { lo - pad }), hi: hi + pad, log }
        }
    }

    fn t(&self, v: f64) -> Option<f64> {
        let x = if self.log { if v > 0.0 { v.log10() } else { return None } } else { v };
        x.is_finite().then(|| (x - self.lo) / (self.hi - self.lo))
    }

    fn ticks(&self) -> Vec<(f64, String)> {
        if self.log {
            (self.lo as i32..=self.hi as i32).map(|e| (10f64.powi(e), format!("1e{e}"))).collect()
        } else {
            (0..=4)
                .map(|i| {
                    let v = self.lo + (self.hi - self.lo) * f64::from(i) / 4.0;
                    (v, format!("{v:.3}"))
                })
                .collect()
        }
    }
}

/// Renders `panels` in a grid of `columns` columns as a standalone SVG document.
#[must_use]
pub fn render(title: &str, panels: &[Panel], columns: usize) -> String {
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let (w, h) = (PANEL_W * columns as f64, PANEL_H * rows as f64 + 30.0);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="11">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(s, r#"<text x="{}" y="20" text-anchor="middle" font-size="14">{}</text>"#, w / 2.0, escape(title));
    for (i, p) in panels.iter().enumerate() {
        let ox = PANEL_W * (i % columns) as f64;
        let oy = 30.0 + PANEL_H * (i / columns) as f64;
        panel(&mut s, p, ox, oy);
    }
    s.push_str("</svg>\n");
    s
}

fn panel(s: &mut String, p: &Panel, ox: f64, oy: f64) {
    let all = || p.series.iter().flat_map(|se| se.points.iter());
    let ax = Axis::new(all().map(|q| q.0), p.log_x);
    let ay = Axis::new(all().map(|q| q.1), p.log_y);
    let (x0, y0) = (ox + MARGIN_L, oy + MARGIN_T);
    let (pw, ph) = (PANEL_W - MARGIN_L - MARGIN_R, PANEL_H - MARGIN_T - MARGIN_B);
    let px = |v: f64| ax.t(v).map(|t| x0 + t * pw);
    let py = |v: f64| ay.t(v).map(|t| y0 + (1.0 - t) * ph);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle" font-size="12">{}</text>"#,
        x0 + pw / 2.0,
        oy + 16.0,
        escape(&p.title)
    );
    let _ = writeln!(s, r##"<rect x="{x0}" y="{y0}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>"##);
    for (v, label) in ax.ticks() {
        if let Some(x) = px(v) {
            let _ = writeln!(s, r##"<line x1="{x}" y1="{y0}" x2="{x}" y2="{}" stroke="#ddd"/>"##, y0 + ph);
            let _ = writeln!(s, r#"<text x="{x}" y="{}" text-anchor="middle">{label}</text>"#, y0 + ph + 14.0);
        }
    }
    for (v, label) in ay.ticks() {
        if let Some(y) = py(v) {
            let _ = writeln!(s, r##"<line x1="{x0}" y1="{y}" x2="{}" y2="{y}" stroke="#ddd"/>"##, x0 + pw);
            let _ = writeln!(s, r#"<text x="{}" y="{}" text-anchor="end">{label}</text>"#, x0 - 4.0, y + 4.0);
        }
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
        x0 + pw / 2.0,
        y0 + ph + 32.0,
        escape(&p.x_label)
    );
    let _ = writeln!(
        s,
        r#"<text transform="translate({},{}) rotate(-90)" text-anchor="middle">{}</text>"#,
        ox + 14.0,
        y0 + ph / 2.0,
        escape(&p.y_label)
    );
    let mut drawn: Vec<(f64, f64)> = Vec::new();
    for se in &p.series {
        let pts: Vec<(f64, f64)> = se.points.iter().filter_map(|&(x, y)| Some((px(x)?, py(y)?))).collect();
        if se.line && pts.len() > 1 {
            let d: Vec<String> = pts.iter().map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
            let _ = writeln!(
                s,
                r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="1.6"/>"#,
                d.join(" "),
                se.color
            );
            // The line's course, for the legend's placement below.
            for w in pts.windows(2) {
                drawn.extend((0..=LEGEND_LINE_SAMPLES).map(|i| {
                    let t = f64::from(i) / f64::from(LEGEND_LINE_SAMPLES);
                    (w[0].0 + t * (w[1].0 - w[0].0), w[0].1 + t * (w[1].1 - w[0].1))
                }));
            }
        }
        if se.markers {
            for (x, y) in &pts {
                let _ = writeln!(
                    s,
                    r#"<circle cx="{x:.1}" cy="{y:.1}" r="{MARKER_R}" fill="{}" fill-opacity="0.8"/>"#,
                    se.color
                );
            }
        }
        drawn.extend(pts);
    }
    // Legend: in the inner corner that covers the fewest drawn points and line samples (top right on a tie),
    // on a translucent white box, so that it hides as little of the data as the panel allows.
    let widest = p.series.iter().map(|se| se.name.chars().count()).max().unwrap_or(0) as f64;
    let (lw, lh) = (LEGEND_CHAR_W * widest + 22.0, 13.0 * p.series.len() as f64 + 6.0);
    let corners = [
        (x0 + pw - lw - 4.0, y0 + 4.0),
        (x0 + 4.0, y0 + 4.0),
        (x0 + pw - lw - 4.0, y0 + ph - lh - 4.0),
        (x0 + 4.0, y0 + ph - lh - 4.0),
    ];
    // A point counts where its marker reaches the box, not only where its centre lies in it.
    let covered = |&(bx, by): &(f64, f64)| {
        let m = MARKER_R + 1.0;
        drawn.iter().filter(|&&(x, y)| x >= bx - m && x <= bx + lw + m && y >= by - m && y <= by + lh + m).count()
    };
    let (bx, by) = corners.iter().copied().min_by_key(|c| covered(c)).unwrap_or(corners[0]);
    if !p.series.is_empty() {
        let _ = writeln!(
            s,
            r#"<rect x="{bx:.1}" y="{by:.1}" width="{lw:.1}" height="{lh:.1}" fill="white" fill-opacity="0.7"/>"#
        );
    }
    for (k, se) in p.series.iter().enumerate() {
        let ly = by + 14.0 + 13.0 * k as f64;
        let lx = bx + 4.0;
        let _ = writeln!(s, r#"<rect x="{lx:.1}" y="{:.1}" width="10" height="3" fill="{}"/>"#, ly - 4.0, se.color);
        let _ = writeln!(s, r#"<text x="{:.1}" y="{ly:.1}">{}</text>"#, lx + 14.0, escape(&se.name));
    }
}

/// Radius of a point's marker, px.
const MARKER_R: f64 = 3.0;

/// Points sampled along each segment of a series' line when choosing the legend's corner: a line that crosses
/// a corner without a marker in it still counts.
const LEGEND_LINE_SAMPLES: u32 = 20;

/// Width of a legend character at the panels' 11 px sans-serif, an upper estimate of the average advance
/// (most glyphs are 5–7 px): the box is sized to hold the longest name.
const LEGEND_CHAR_W: f64 = 6.2;

/// Indices of the points on the lower-left Pareto front of (cost, error): no other point is at most as costly
/// and at most as wrong with one of the two strictly smaller. Sorted by cost.
#[must_use]
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut idx: Vec<usize> =
        (0..points.len()).filter(|&i| points[i].0.is_finite() && points[i].1.is_finite()).collect();
    idx.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0).then(points[a].1.total_cmp(&points[b].1)));
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for i in idx {
        if points[i].1 < best {
            best = points[i].1;
            front.push(i);
        }
    }
    front
}

/// An axis tick's label: integers as such (iterations, sizes), other values to four decimals without
/// trailing zeros between 10⁻³ and 10⁴ (a code 1/255 is `0.0039`, not its 17 digits), else in exponent form.
fn tick_label(v: f64) -> String {
    let a = v.abs();
    if v == v.round() && a < 1e9 {
        format!("{v:.0}")
    } else if (1e-3..1e4).contains(&a) {
        format!("{v:.4}").trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        format!("{v:.3e}")
    }
}

/// One named curve of a [`line_chart`].
#[derive(Debug, Clone, Copy)]
pub struct Curve<'a> {
    pub name: &'a str,
    pub points: &'a [(f64, f64)],
}

/// A single SVG line chart of `series` (log10 y axis when every y is positive), as report.html shows loss
/// curves: a compact layout with the axis extremes as the only ticks.
#[must_use]
pub fn line_chart(series: &[Curve<'_>], width: u32, height: u32, x_label: &str, y_label: &str) -> String {
    const COLOURS: [&str; 6] = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf"];
    let pts: Vec<(f64, f64)> =
        series.iter().flat_map(|s| s.points.iter().copied()).filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
    let mut svg = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="11">"#
    );
    if pts.is_empty() {
        let _ = write!(svg, r#"<text x="10" y="20">no data</text></svg>"#);
        return svg;
    }
    let log = pts.iter().all(|p| p.1 > 0.0);
    let fy = |y: f64| if log { y.log10() } else { y };
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in &pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(fy(y));
        y1 = y1.max(fy(y));
    }
    // Degenerate ranges (one point, constant curve) get a unit span so the mapping stays finite.
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    if y1 <= y0 {
        y1 = y0 + 1.0;
    }
    let (left, right, top, bottom) = (60.0, 10.0, 10.0, 35.0);
    let (w, h) = (f64::from(width) - left - right, f64::from(height) - top - bottom);
    let sx = |x: f64| left + (x - x0) / (x1 - x0) * w;
    let sy = |y: f64| top + (1.0 - (fy(y) - y0) / (y1 - y0)) * h;
    let _ = write!(
        svg,
        r##"<rect x="{left}" y="{top}" width="{w}" height="{h}" fill="none" stroke="#888"/><text x="{}" y="{}" text-anchor="middle">{}</text><text x="12" y="{}" transform="rotate(-90 12 {})" text-anchor="middle">{}{}</text>"##,
        left + w / 2.0,
        f64::from(height) - 5.0,
        escape(x_label),
        top + h / 2.0,
        top + h / 2.0,
        escape(y_label),
        if log { " (log)" } else { "" }
    );
    for (tick, v) in [(y0, y0), (y1, y1)] {
        let shown = if log { 10f64.powf(v) } else { v };
        let y = top + (1.0 - (tick - y0) / (y1 - y0)) * h;
        let _ = write!(svg, r#"<text x="{}" y="{}" text-anchor="end">{shown:.3e}</text>"#, left - 4.0, y + 4.0);
    }
    for (tick, anchor) in [(x0, "start"), (x1, "end")] {
        let label = tick_label(tick);
        let _ = write!(svg, r#"<text x="{}" y="{}" text-anchor="{anchor}">{label}</text>"#, sx(tick), top + h + 14.0);
    }
    for (i, s) in series.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let path: Vec<String> = s
            .points
            .iter()
            .filter(|p| p.0.is_finite() && p.1.is_finite() && (!log || p.1 > 0.0))
            .map(|&(x, y)| format!("{:.1},{:.1}", sx(x), sy(y)))
            .collect();
        let _ = write!(
            svg,
            r#"<polyline fill="none" stroke="{colour}" stroke-width="1.5" points="{}"/><text x="{}" y="{}" fill="{colour}">{}</text>"#,
            path.join(" "),
            left + 8.0,
            top + 14.0 + 13.0 * i as f64,
            escape(s.name)
        );
    }
    svg.push_str("</svg>");
    svg
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(100.0), "100");
        assert_eq!(tick_label(1.0 / 255.0), "0.0039");
        assert_eq!(tick_label(0.25), "0.25");
        assert_eq!(tick_label(2.5e-5), "2.500e-5");
    }

    #[test]
    fn pareto_front_keeps_only_undominated_points() {
        let pts = [(1.0, 5.0), (2.0, 3.0), (3.0, 4.0), (4.0, 1.0), (0.5, 9.0), (4.0, 2.0)];
        assert_eq!(pareto_front(&pts), vec![4, 0, 1, 3]);
    }

    #[test]
    fn svg_is_one_document_with_a_marker_per_point() {
        let p = Panel {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            log_x: true,
            log_y: true,
            series: vec![Series {
                name: "a<b".into(),
                color: PALETTE[0].into(),
                points: vec![(1.0, 0.1), (10.0, 0.01), (0.0, 1.0)],
                line: true,
                markers: true,
            }],
        };
        let s = render("title", &[p], 1);
        assert!(s.starts_with("<svg") && s.trim_end().ends_with("</svg>"));
        // The point at x = 0 has no place on a log axis and is left out.
        assert_eq!(s.matches("<circle").count(), 2);
        assert!(s.contains("a&lt;b"));
    }

    /// A one-panel document of `series` on linear axes (the panel spans x 62–446, y 58–306), and its legend's
    /// box: the translucent white rectangle.
    fn with_legend(series: Vec<Series>) -> (String, String) {
        let p =
            Panel { title: "t".into(), x_label: "x".into(), y_label: "y".into(), log_x: false, log_y: false, series };
        let s = render("title", &[p], 1);
        let line = s.lines().find(|l| l.contains(r#"fill="white" fill-opacity"#)).expect("a legend box").to_owned();
        (s, line)
    }

    fn series(name: &str, colour: usize, points: Vec<(f64, f64)>, line: bool, markers: bool) -> Series {
        Series { name: name.into(), color: PALETTE[colour].into(), points, line, markers }
    }

    #[test]
    fn the_legend_goes_to_the_corner_with_the_least_data() {
        // A line from the bottom left to the top right, and a cloud of points in the top left: of the four
        // inner corners only the bottom right is free.
        let cloud: Vec<(f64, f64)> = (0..10).map(|i| (1.0 + 0.1 * f64::from(i), 9.0 + 0.1 * f64::from(i))).collect();
        let (_, line) = with_legend(vec![
            series("diagonal", 0, vec![(0.0, 0.0), (10.0, 10.0)], true, false),
            series("cloud", 1, cloud, false, true),
        ]);
        // The box's corner is right of and well below the panel's centre (x 254, y 182).
        let attr = |name: &str| -> f64 {
            let start = line.find(&format!(r#" {name}=""#)).unwrap() + name.len() + 3;
            line[start..].split('"').next().unwrap().parse().unwrap()
        };
        assert!(attr("x") > 254.0 && attr("y") > 196.0, "{line}");
    }

    #[test]
    fn the_legend_leaves_a_marker_beside_its_corner_uncovered() {
        // Each linear axis is padded by 5 % of its range. The top point's centre lands at (369.0, 69.3), where
        // its line ends, 1.4 px left of the top-right corner's box (from x 370.4 for an 8-character name), which
        // its marker of radius 3 overlaps; the two bottom corners hold the other points. Counting centres only,
        // the top right would tie with the free top left and win.
        let (s, line) = with_legend(vec![
            series("peak RSS", 0, vec![(0.0, 0.0), (0.8294, 1.0)], true, true),
            series("b", 1, vec![(1.0, 0.0)], false, true),
        ]);
        assert!(s.contains(r#"<circle cx="369.0" cy="69.3""#), "{s}");
        assert!(line.contains(r#"x="66.0" y="62.0""#), "{line}");
    }
}
