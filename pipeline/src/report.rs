//! `report.html`: one self-contained page (no external files or scripts): input photos beside re-renders and
//! error maps (inline base64 PNG), loss curves (inline SVG), and the per-object table with colour swatches.
//! The functions here are pure (data in, text out); the export stage gathers the data.

use std::fmt::Write;

use crate::materials::ObjectMaterial;

/// A linear RGB image to show (interleaved, row-major, top row first).
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<f32>,
}

/// One view's row of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewPanel {
    pub name: String,
    pub photo: RgbImage,
    pub render: RgbImage,
    /// Per-pixel validity of the photo (1 = valid); masked pixels are shown black in the error map.
    pub mask: Vec<u8>,
}

/// One curve of a chart: (x, y) points.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// Everything the page shows.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportData {
    pub title: String,
    pub emission_profile: String,
    pub views: Vec<ViewPanel>,
    /// Loss curves (one chart, log y when every value is positive).
    pub loss: Vec<Series>,
    pub objects: Vec<ObjectMaterial>,
    /// Per object (same order): why the fit chose its model; may be shorter than `objects`.
    pub why: Vec<String>,
    /// Free text lines shown under the title (settings, timings).
    pub notes: Vec<String>,
    /// The per-triangle stage's summary, when it ran.
    pub triangle: Option<TriangleSection>,
    /// The object fit's path-sample counts, when its result recorded them.
    pub samples: Option<SampleCounts>,
}

/// Path samples a fit traced and, of them, the ones the tracer discarded as non-finite (issue 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleCounts {
    pub traced_paths: u64,
    pub discarded: u64,
}

/// The sentence the report shows for `c`.
#[must_use]
pub fn samples_sentence(c: &SampleCounts) -> String {
    let share = if c.discarded > 0 && c.traced_paths > 0 {
        format!(" ({:.2e} of them)", c.discarded as f64 / c.traced_paths as f64)
    } else {
        String::new()
    };
    format!(
        "Path samples of the object fit: {} traced, {} discarded as non-finite{share}. A discarded sample \
         contributes nothing and darkens its pixel; the fit accepts at most 1e-4 of its samples discarded, and \
         an ordinary scene discards none.",
        c.traced_paths, c.discarded
    )
}

/// The "Per-triangle stage" section: triangle counts per object and the exported albedo atlas.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleSection {
    /// Per object: (id, label, triangles in the scan's mesh, triangles after the stage).
    pub counts: Vec<(i64, String, usize, usize)>,
    /// `export/albedo.png` (sRGB 8-bit PNG bytes), when export wrote one; shown inline.
    pub atlas_png: Option<Vec<u8>>,
}

/// Standard base64 (RFC 4648 §4, with padding).
#[must_use]
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[((n >> (18 - 6 * i)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value clamped to [0, 1].
#[must_use]
pub fn linear_to_srgb(l: f32) -> f32 {
    let l = l.clamp(0.0, 1.0);
    if l <= 0.003_130_8 { 12.92 * l } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 }
}

/// An 8-bit sRGB code of a linear value.
#[must_use]
pub fn srgb8(l: f32) -> u8 {
    (linear_to_srgb(l) * 255.0).round() as u8
}

/// The exposure scale that maps the 99th percentile of an image's channel values to 1 (so a few bright
/// pixels, e.g. a visible lamp, do not darken the whole picture); 1 for an all-black image.
#[must_use]
pub fn exposure_for(img: &RgbImage) -> f32 {
    let mut v: Vec<f32> = img.rgb.iter().copied().filter(|x| x.is_finite() && *x > 0.0).collect();
    if v.is_empty() {
        return 1.0;
    }
    let k = ((v.len() - 1) as f64 * 0.99) as usize;
    let (_, p, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    1.0 / *p
}

/// PNG bytes of a linear image times `scale`, sRGB-encoded.
#[must_use]
pub fn png_srgb(img: &RgbImage, scale: f32) -> Vec<u8> {
    let buf: Vec<u8> = img.rgb.iter().map(|&x| srgb8(x * scale)).collect();
    encode_png(img.width, img.height, buf)
}

/// PNG of the per-pixel error |render − photo| (mean over channels) times `scale`, as a black → red →
/// yellow → white heat map; masked pixels black.
#[must_use]
pub fn png_error_map(photo: &RgbImage, render: &RgbImage, mask: &[u8], scale: f32) -> Vec<u8> {
    let n = photo.width as usize * photo.height as usize;
    let mut buf = Vec::with_capacity(3 * n);
    for i in 0..n {
        let valid = mask.get(i).is_none_or(|&m| m != 0);
        let e = if valid {
            (0..3).map(|c| (render.rgb[3 * i + c] - photo.rgb[3 * i + c]).abs()).sum::<f32>() / 3.0 * scale
        } else {
            0.0
        };
        let t = e.clamp(0.0, 1.0) * 3.0;
        let rgb = [t.min(1.0), (t - 1.0).clamp(0.0, 1.0), (t - 2.0).clamp(0.0, 1.0)];
        buf.extend(rgb.map(|x| (x * 255.0).round() as u8));
    }
    encode_png(photo.width, photo.height, buf)
}

fn encode_png(width: u32, height: u32, buf: Vec<u8>) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    let img = image::RgbImage::from_raw(width, height, buf).expect("buffer is 3·width·height by construction");
    img.write_to(&mut out, image::ImageFormat::Png).expect("PNG encoding into memory does not fail");
    out.into_inner()
}

/// Mean |render − photo| over the valid pixels and channels, relative to the photo's mean there; `None`
/// without valid pixels or with a black photo.
#[must_use]
pub fn relative_error(photo: &RgbImage, render: &RgbImage, mask: &[u8]) -> Option<f64> {
    let (mut err, mut sum) = (0.0f64, 0.0f64);
    for i in 0..photo.width as usize * photo.height as usize {
        if mask.get(i).is_some_and(|&m| m == 0) {
            continue;
        }
        for c in 0..3 {
            err += f64::from((render.rgb[3 * i + c] - photo.rgb[3 * i + c]).abs());
            sum += f64::from(photo.rgb[3 * i + c]);
        }
    }
    (sum > 0.0).then(|| err / sum)
}

/// Escapes text for HTML element content and attribute values.
#[must_use]
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// An SVG line chart of `series` (log10 y axis when every y is positive).
#[must_use]
pub fn svg_chart(series: &[Series], width: u32, height: u32, x_label: &str, y_label: &str) -> String {
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
        let _ = write!(svg, r#"<text x="{}" y="{}" text-anchor="{anchor}">{tick}</text>"#, sx(tick), top + h + 14.0);
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
            escape(&s.name)
        );
    }
    svg.push_str("</svg>");
    svg
}

fn swatch(rgb: [f32; 3], scale: f32) -> String {
    let c = rgb.map(|x| srgb8(x * scale));
    format!(
        r#"<span class="sw" style="background:#{:02x}{:02x}{:02x}" title="{:.4} {:.4} {:.4}"></span>"#,
        c[0], c[1], c[2], rgb[0], rgb[1], rgb[2]
    )
}

/// The whole page.
#[must_use]
pub fn html(data: &ReportData) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>\
         body{{font-family:sans-serif;margin:1.5em;color:#222}} table{{border-collapse:collapse}} \
         td,th{{border:1px solid #ccc;padding:3px 6px;text-align:right}} th{{background:#f4f4f4}} \
         td.l{{text-align:left}} .sw{{display:inline-block;width:2.2em;height:1.1em;border:1px solid #555;vertical-align:middle}} \
         .views img{{max-width:32%;margin-right:.5%}} figure{{margin:0 0 1em 0}}</style></head><body>\n",
        escape(&data.title)
    );
    let _ = writeln!(s, "<h1>{}</h1>", escape(&data.title));
    for n in &data.notes {
        let _ = writeln!(s, "<p>{}</p>", escape(n));
    }
    let _ = writeln!(s, "<h2>Loss</h2>\n{}", svg_chart(&data.loss, 720, 280, "iteration", "loss"));
    if let Some(c) = &data.samples {
        // Discarded samples bias their pixels darker: shown in red when there were any.
        let style = if c.discarded > 0 { " style=\"color:#b00\"" } else { "" };
        let _ = writeln!(s, "<p class=\"samples\"{style}>{}</p>", escape(&samples_sentence(c)));
    }

    let _ = writeln!(
        s,
        "<h2>Objects</h2>\n<p>Emission profile: {}. Values are linear; swatches show base colour in sRGB and \
         emission scaled so the brightest emitter is white.</p>",
        escape(&data.emission_profile)
    );
    let max_e = data.objects.iter().flat_map(|o| o.emission).fold(0.0f32, f32::max);
    let e_scale = if max_e > 0.0 { 1.0 / max_e } else { 1.0 };
    s.push_str(
        "<table><tr><th>id</th><th>label</th><th>triangles</th><th>model</th><th>base colour</th><th>r g b</th>\
         <th>roughness</th><th>metallic</th><th>specular</th><th>emission</th><th>r g b</th><th>why this model</th></tr>\n",
    );
    for (i, o) in data.objects.iter().enumerate() {
        let [r, g, b] = o.base_color;
        let [er, eg, eb] = o.emission;
        let _ = writeln!(
            s,
            "<tr><td>{}</td><td class=\"l\">{}</td><td>{}</td><td class=\"l\">{}</td><td>{}</td><td>{r:.3} {g:.3} {b:.3}</td>\
             <td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{}</td><td>{er:.4} {eg:.4} {eb:.4}</td><td class=\"l\">{}</td></tr>",
            o.id,
            escape(&o.label),
            o.triangles,
            // Issue 7: values no photo constrains are flagged, not presented as estimates.
            if o.constrained == Some(false) {
                format!("{} (unconstrained)", escape(&o.model))
            } else {
                escape(&o.model)
            },
            swatch(o.base_color, 1.0),
            o.roughness,
            o.metallic,
            o.specular,
            swatch(o.emission, e_scale),
            escape(data.why.get(i).map_or("", String::as_str))
        );
    }
    s.push_str("</table>\n");

    if let Some(t) = &data.triangle {
        s.push_str(
            "<h2>Per-triangle stage</h2>\n<p>Triangles per object before (scan mesh) and after adaptive \
             subdivision; a uniform object keeps its count and its value.</p>\n\
             <table><tr><th>id</th><th>label</th><th>before</th><th>after</th></tr>\n",
        );
        for (id, label, before, after) in &t.counts {
            let _ = writeln!(
                s,
                "<tr><td>{id}</td><td class=\"l\">{}</td><td>{before}</td><td>{after}</td></tr>",
                escape(label)
            );
        }
        s.push_str("</table>\n");
        if let Some(png) = &t.atlas_png {
            let _ = writeln!(
                s,
                "<figure><figcaption>Albedo atlas (export/albedo.png, one padded patch per triangle)</figcaption>\
                 <img alt=\"albedo atlas\" style=\"image-rendering:pixelated;max-width:100%\" \
                 src=\"data:image/png;base64,{}\"></figure>",
                base64(png)
            );
        }
    }

    s.push_str(
        "<h2>Views</h2>\n<p>Each row: input photo, re-render with the fitted materials (same exposure), \
                and |re-render − photo| (heat map, white = 25 % of the photo's 99th-percentile value or more).</p>\n",
    );
    for v in &data.views {
        let scale = exposure_for(&v.photo);
        let photo = base64(&png_srgb(&v.photo, scale));
        let render = base64(&png_srgb(&v.render, scale));
        // White at a quarter of the display range: errors that large are gross, smaller ones stay visible.
        let err = base64(&png_error_map(&v.photo, &v.render, &v.mask, 4.0 * scale));
        let _ = writeln!(
            s,
            "<figure class=\"views\"><figcaption>{}{}</figcaption><img alt=\"photo\" src=\"data:image/png;base64,{photo}\">\
             <img alt=\"re-render\" src=\"data:image/png;base64,{render}\"><img alt=\"error\" src=\"data:image/png;base64,{err}\"></figure>",
            escape(&v.name),
            relative_error(&v.photo, &v.render, &v.mask).map_or(String::new(), |e| format!(
                " — mean |re-render − photo| = {:.1} % of the mean radiance",
                100.0 * e
            ))
        );
    }
    s.push_str("</body></html>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        // RFC 4648 §10.
        for (input, want) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(input.as_bytes()), want);
        }
    }

    #[test]
    fn srgb_curve_hits_its_defining_points() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        // 18 % grey is sRGB code 118 (0.4613 · 255 = 117.6).
        assert_eq!(srgb8(0.18), 118);
        assert_eq!(srgb8(2.0), 255);
    }

    #[test]
    fn png_decodes_back_to_the_encoded_codes() {
        let img = RgbImage { width: 2, height: 1, rgb: vec![0.0, 0.18, 1.0, 0.5, 0.5, 0.5] };
        let png = png_srgb(&img, 1.0);
        let back = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(back.dimensions(), (2, 1));
        assert_eq!(back.as_raw(), &vec![0, 118, 255, srgb8(0.5), srgb8(0.5), srgb8(0.5)]);
    }

    #[test]
    fn exposure_maps_the_99th_percentile_to_one() {
        let mut rgb: Vec<f32> = (1..=300).map(|i| i as f32).collect();
        rgb[299] = 1e6; // one very bright lamp pixel must not set the exposure
        let img = RgbImage { width: 10, height: 10, rgb };
        let s = exposure_for(&img);
        assert!((1.0 / s - 297.0).abs() <= 1.0, "{}", 1.0 / s);
    }

    #[test]
    fn relative_error_ignores_masked_pixels() {
        let photo = RgbImage { width: 2, height: 1, rgb: vec![1.0, 1.0, 1.0, 5.0, 5.0, 5.0] };
        let render = RgbImage { width: 2, height: 1, rgb: vec![1.5, 1.0, 0.5, 0.0, 0.0, 0.0] };
        assert_eq!(relative_error(&photo, &render, &[1, 0]), Some(1.0 / 3.0));
        assert_eq!(relative_error(&photo, &render, &[0, 0]), None);
    }

    #[test]
    fn html_is_self_contained_and_escapes_labels() {
        let img = RgbImage { width: 1, height: 1, rgb: vec![0.5, 0.5, 0.5] };
        let data = ReportData {
            title: "run".into(),
            emission_profile: "uniform".into(),
            views: vec![ViewPanel { name: "v0".into(), photo: img.clone(), render: img, mask: vec![1] }],
            loss: vec![Series { name: "loss".into(), points: vec![(0.0, 1.0), (1.0, 0.5)] }],
            objects: vec![ObjectMaterial {
                id: 1,
                label: "<script>".into(),
                triangles: 2,
                base_color: [1.0, 0.0, 0.0],
                roughness: 0.5,
                metallic: 0.0,
                specular: 0.0,
                emission: [0.0; 3],
                model: "diffuse".into(),
                why: None,
                constrained: Some(false),
            }],
            why: vec!["because".into()],
            notes: vec![],
            triangle: Some(TriangleSection {
                counts: vec![(1, "floor & co".into(), 2, 32)],
                atlas_png: Some(png_srgb(&RgbImage { width: 2, height: 1, rgb: vec![0.5; 6] }, 1.0)),
            }),
            samples: Some(SampleCounts { traced_paths: 2_000_000, discarded: 3 }),
        };
        let page = html(&data);
        assert!(!page.contains("<script>"));
        assert!(page.contains("&lt;script&gt;"));
        assert!(page.contains("diffuse (unconstrained)"));
        // 3 view images and the atlas.
        assert_eq!(page.matches("data:image/png;base64,").count(), 4);
        assert!(page.contains("<h2>Per-triangle stage</h2>"));
        assert!(page.contains("<td class=\"l\">floor &amp; co</td><td>2</td><td>32</td>"));
        assert!(page.contains("<svg") && page.contains("<polyline"));
        assert!(page.contains("background:#ff0000"));
        assert!(page.contains("<td class=\"l\">because</td>"));
        assert!(!page.contains("src=\"http") && !page.contains("href="));
        assert!(page.contains("2000000 traced, 3 discarded as non-finite (1.50e-6 of them)."), "samples line");
        let none = samples_sentence(&SampleCounts { traced_paths: 10, discarded: 0 });
        assert!(none.contains("10 traced, 0 discarded as non-finite. "), "{none}");
        assert!(page.contains("<p class=\"samples\" style=\"color:#b00\">"));
    }
}
