//! `report.html`: one self-contained page (no external files or scripts): input photos beside re-renders and
//! error maps (inline base64 PNG), loss curves (inline SVG), and the per-object table with colour swatches.
//! The functions here are pure (data in, text out); the export stage gathers the data. Image encoding (PNG,
//! base64) is [`crate::display`]'s, the sRGB curve `ingest::srgb`'s, the chart [`crate::svg`]'s; the
//! photometric calibration's section is [`calibration`]'s.

pub mod calibration;

use std::fmt::Write;

use ingest::srgb::linear_to_srgb8;

pub use crate::display::RgbImage;
use crate::display::{base64, exposure_for, png_error_map, png_srgb};
use crate::materials::ObjectMaterial;
pub use crate::svg::escape;
use crate::svg::{Curve, line_chart};

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
    /// The preprocess stage's photometric calibration, when it ran.
    pub calibration: Option<crate::artefacts::preprocess::CalibrationFile>,
    /// The object stage's tone-curve exponent search, when it ran.
    pub photometric: Option<crate::artefacts::object::PhotometricFile>,
}

/// Path samples a fit traced and, of them, the ones the tracer discarded as non-finite.
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
    /// Triangles the split test found significant but the triangle budget left unsplit, over all rounds
    /// (`optim::triangle::RoundRecord::over_budget`).
    pub over_budget: usize,
    /// What the sub-triangle detail did (`None`: it did not run).
    pub detail: Option<optim::triangle::detail::DetailReport>,
    /// `export/albedo.png` (sRGB 8-bit PNG bytes), when export wrote one; shown inline.
    pub atlas_png: Option<Vec<u8>>,
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

fn loss_chart(loss: &[Series]) -> String {
    let curves: Vec<Curve<'_>> = loss.iter().map(|s| Curve { name: &s.name, points: &s.points }).collect();
    line_chart(&curves, 720, 280, "iteration", "loss")
}

fn swatch(rgb: [f32; 3], scale: f32) -> String {
    let c = rgb.map(|x| linear_to_srgb8(x * scale));
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
         .views img{{max-width:32%;margin-right:.5%}} figure{{margin:0 0 1em 0}} \
         .wide{{overflow-x:auto}} .wide table{{width:100%}} td.why{{color:#444;font-size:90%;border-top:none}} \
         tr.data td{{border-bottom:none}}</style></head><body>\n",
        escape(&data.title)
    );
    let _ = writeln!(s, "<h1>{}</h1>", escape(&data.title));
    for n in &data.notes {
        let _ = writeln!(s, "<p>{}</p>", escape(n));
    }
    let _ = writeln!(s, "<h2>Loss</h2>\n{}", loss_chart(&data.loss));
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
        // The reasons are sentences, up to a paragraph each: each object's is a row of its own under its
        // values, as wide as the table, so that neither the reasons nor the values are squeezed or cut off.
        "<div class=\"wide\"><table><tr><th>id</th><th>label</th><th>triangles</th><th>model</th><th>base colour</th><th>r g b</th>\
         <th>roughness</th><th>metallic</th><th>specular</th><th>emission</th><th>r g b</th></tr>\n",
    );
    for (i, o) in data.objects.iter().enumerate() {
        let [r, g, b] = o.base_color;
        let [er, eg, eb] = o.emission;
        let _ = writeln!(
            s,
            "<tr class=\"data\"><td>{}</td><td class=\"l\">{}</td><td>{}</td><td class=\"l\">{}</td><td>{}</td><td>{r:.3} {g:.3} {b:.3}</td>\
             <td>{}</td><td>{:.3}</td><td>{:.3}</td><td>{}</td><td>{er:.4} {eg:.4} {eb:.4}</td></tr>\n\
             <tr><td></td><td class=\"l why\" colspan=\"10\">{}</td></tr>",
            o.id,
            escape(&o.label),
            o.triangles,
            // Values no photo constrains are flagged, not presented as estimates.
            if !o.is_constrained() { format!("{} (unconstrained)", escape(&o.model)) } else { escape(&o.model) },
            swatch(o.base_color, 1.0),
            roughness_cell(o),
            o.metallic,
            o.specular,
            swatch(o.emission, e_scale),
            escape(data.why.get(i).map_or("", String::as_str))
        );
    }
    s.push_str("</table></div>\n");

    if let Some(c) = &data.calibration {
        s.push_str(&calibration::section(c, data.photometric.as_ref()));
    }
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
        if t.over_budget > 0 {
            // The counts above would otherwise read as "nothing needed splitting".
            let _ = writeln!(
                s,
                "<p>The split test found {} triangles whose photos show more detail than one colour, which the \
                 triangle budget (triangle.max_triangles, a bound on the mesh's size) left unsplit.</p>",
                t.over_budget
            );
        }
        if let Some(d) = &t.detail {
            let _ = writeln!(
                s,
                "<p>Sub-triangle detail: {} texels on {} triangles ({:.3} texels per pixel of a triangle's best \
                 view), from {} photo pixels divided by the fitted shading. A triangle keeps one colour unless its \
                 residuals photo − render differ between its texels beyond noise (optim::triangle::detail).</p>",
                d.texels, d.triangles, d.density, d.pixels
            );
        }
        if let Some(png) = &t.atlas_png {
            let _ = writeln!(
                s,
                "<figure><figcaption>Albedo atlas (export/albedo.png: one padded cell per triangle, holding its \
                 texels where it has detail)</figcaption>\
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

/// The roughness column's cell: the value, or a dash for a Lambert surface (metallic and specular 0), which has
/// no specular lobe for a roughness to shape. `materials.json` still holds the fit's value (the tracer's default);
/// the report does not present it as an estimate.
fn roughness_cell(o: &ObjectMaterial) -> String {
    if o.material().is_lambert() {
        "<span title=\"no specular lobe: roughness has no effect\">–</span>".to_owned()
    } else {
        format!("{:.3}", o.roughness)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_error_ignores_masked_pixels() {
        let photo = RgbImage { width: 2, height: 1, rgb: vec![1.0, 1.0, 1.0, 5.0, 5.0, 5.0] };
        let render = RgbImage { width: 2, height: 1, rgb: vec![1.5, 1.0, 0.5, 0.0, 0.0, 0.0] };
        assert_eq!(relative_error(&photo, &render, &[1, 0]), Some(1.0 / 3.0));
        assert_eq!(relative_error(&photo, &render, &[0, 0]), None);
    }

    #[test]
    fn a_lambert_surface_shows_no_roughness_and_a_lobed_one_its_value() {
        let mut o = crate::materials::test_object(1, "diffuse", None);
        o.roughness = 0.5;
        assert!(roughness_cell(&o).contains('–') && !roughness_cell(&o).contains("0.500"));
        o.specular = 0.5;
        o.roughness = 0.3;
        assert_eq!(roughness_cell(&o), "0.300");
        o.specular = 0.0;
        o.metallic = 1.0;
        assert_eq!(roughness_cell(&o), "0.300");
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
                label: "<script>".into(),
                base_color: [1.0, 0.0, 0.0],
                ..crate::materials::test_object(1, "diffuse", Some(false))
            }],
            why: vec!["because".into()],
            notes: vec![],
            triangle: Some(TriangleSection {
                counts: vec![(1, "floor & co".into(), 2, 32)],
                over_budget: 18,
                detail: Some(optim::triangle::detail::DetailReport {
                    triangles: 7,
                    texels: 1234,
                    pixels: 5678,
                    density: 0.8,
                }),
                atlas_png: Some(png_srgb(&RgbImage { width: 2, height: 1, rgb: vec![0.5; 6] }, 1.0)),
            }),
            samples: Some(SampleCounts { traced_paths: 2_000_000, discarded: 3 }),
            calibration: None,
            photometric: None,
        };
        let page = html(&data);
        assert!(!page.contains("<script>"));
        assert!(page.contains("&lt;script&gt;"));
        assert!(page.contains("diffuse (unconstrained)"));
        assert!(
            page.contains("<td><span title=\"no specular lobe: roughness has no effect\">–</span></td><td>0.000</td>")
        );
        // 3 view images and the atlas.
        assert_eq!(page.matches("data:image/png;base64,").count(), 4);
        assert!(page.contains("<h2>Per-triangle stage</h2>"));
        assert!(page.contains("found 18 triangles"), "the triangles the budget left unsplit are reported");
        assert!(page.contains("<td class=\"l\">floor &amp; co</td><td>2</td><td>32</td>"));
        assert!(
            page.contains("Sub-triangle detail: 1234 texels on 7 triangles (0.800 texels per pixel"),
            "detail line"
        );
        assert!(page.contains("<svg") && page.contains("<polyline"));
        assert!(page.contains("background:#ff0000"));
        assert!(page.contains("<tr><td></td><td class=\"l why\" colspan=\"10\">because</td></tr>\n</table></div>"));
        assert!(!page.contains("src=\"http") && !page.contains("href="));
        assert!(page.contains("2000000 traced, 3 discarded as non-finite (1.50e-6 of them)."), "samples line");
        let none = samples_sentence(&SampleCounts { traced_paths: 10, discarded: 0 });
        assert!(none.contains("10 traced, 0 discarded as non-finite. "), "{none}");
        assert!(page.contains("<p class=\"samples\" style=\"color:#b00\">"));
    }
}
