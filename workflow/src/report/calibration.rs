//! The report's "Photometric calibration" section: each photo's estimated exposure and white balance, the
//! recovered response beside the sRGB curve, and each camera's vignetting profile, from the preprocess stage's
//! `calibration.json` ([`CalibrationFile`]).

use std::fmt::Write;

use ingest::photo::calibrate::ResponseChannels;

use crate::artefacts::object::PhotometricFile;
use crate::artefacts::preprocess::CalibrationFile;
use crate::svg::{Curve, escape, line_chart};

/// The section's HTML: the calibration as the fit used it (raised to the searched exponent, when there was a
/// search, whose trials are listed).
#[must_use]
pub fn section(preprocessed: &CalibrationFile, search: Option<&PhotometricFile>) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "<h2>Photometric calibration</h2>\n<p>{}</p>", escape(&preprocessed.summary()));
    let raised;
    let c = match search {
        Some(p) => {
            let e = p.exponent[1];
            // Labels repeat (two boxes); the id tells them apart, as in the objects table.
            let name = |e: &crate::artefacts::object::SearchEmitter| format!("{} (id {})", escape(&e.label), e.id);
            let lights: Vec<String> = p.emitters.iter().filter(|e| e.light).map(name).collect();
            let glows: Vec<String> = p.emitters.iter().filter(|e| !e.light).map(name).collect();
            let _ = writeln!(
                s,
                "<p>The photos alone left the tone curve's exponent open; diffuse fits of the photos raised to the \
                 exponents below, with emission only on the first whole fit's lights ({}{}), were compared by their \
                 held-out log misfit per channel (in the photos' original log units; the search minimises the \
                 mean over channels of each one relative to its first trial), and the final fit used \
                 <b>{e:.3}</b>. Gains, vignetting and response below are raised to it.</p>",
                if lights.is_empty() { "none: every object could emit".to_owned() } else { lights.join(", ") },
                if glows.is_empty() {
                    String::new()
                } else {
                    format!("; left out as faint emissions: {}", glows.join(", "))
                }
            );
            let _ =
                writeln!(s, "<table><tr><th>exponent</th><th>misfit R</th><th>G</th><th>B</th><th>relative</th></tr>");
            for r in &p.rounds {
                let _ = writeln!(
                    s,
                    "<tr><td>{:.3}</td><td>{:.4e}</td><td>{:.4e}</td><td>{:.4e}</td><td>{:.4}</td></tr>",
                    r.exponent, r.misfit[0], r.misfit[1], r.misfit[2], r.criterion
                );
            }
            let _ = writeln!(s, "</table>");
            raised = preprocessed.raised(e);
            &raised
        }
        None => preprocessed,
    };
    let _ = writeln!(
        s,
        "<p>Gains divide each photo's linear values (exposure × white balance; geometric mean 1 over the kept \
         photos, since a common factor cannot be told from the lights' emission). Exposure {}, white balance {}, \
         vignetting {}, response {}.</p>",
        per_photo(c.exposure),
        per_photo(c.white_balance),
        if c.vignetting { "estimated per camera" } else { "none" },
        match c.response_channels {
            Some(ResponseChannels::Shared) =>
                format!("{} (one curve for the three channels)", escape(&c.response_mode)),
            Some(ResponseChannels::PerChannel) => format!("{} (one curve per channel)", escape(&c.response_mode)),
            None => escape(&c.response_mode),
        }
    );
    let _ = writeln!(s, "<table><tr><th>view</th><th>camera</th><th>gain R</th><th>gain G</th><th>gain B</th></tr>");
    for v in &c.views {
        match (&v.gain, &v.left_out) {
            (Some(g), _) => {
                let _ = writeln!(
                    s,
                    "<tr><td class=\"l\">{}</td><td>{}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td></tr>",
                    escape(&v.name),
                    v.camera,
                    g[0],
                    g[1],
                    g[2]
                );
            }
            (None, why) => {
                let _ = writeln!(
                    s,
                    "<tr><td class=\"l\">{}</td><td>{}</td><td class=\"l\" colspan=\"3\">left out: {}</td></tr>",
                    escape(&v.name),
                    v.camera,
                    escape(why.as_deref().unwrap_or("unconstrained"))
                );
            }
        }
    }
    let _ = writeln!(s, "</table>");
    if let Some(r) = &c.response {
        let n = (r.len().max(2) - 1) as f64;
        let channel = |k: usize| -> Vec<(f64, f64)> {
            r.iter().enumerate().skip(1).map(|(z, v)| (z as f64 / n, f64::from(v[k]))).collect()
        };
        // sRGB scaled like the estimate (1 at code 128), so that the shapes compare.
        let mid = f64::from(ingest::srgb::decode(128.0 / n as f32));
        let srgb: Vec<(f64, f64)> =
            (1..r.len()).map(|z| (z as f64 / n, f64::from(ingest::srgb::decode(z as f32 / n as f32)) / mid)).collect();
        let (red, green, blue) = (channel(0), channel(1), channel(2));
        // In the order of `svg::line_chart`'s colours (blue, red, green, purple), so that each channel is
        // drawn in its own colour; a curve shared by the channels is drawn once.
        let curves = if c.response_channels == Some(ResponseChannels::Shared) {
            vec![
                Curve { name: "estimated (one curve for R, G, B)", points: &green },
                Curve { name: "sRGB", points: &srgb },
            ]
        } else {
            vec![
                Curve { name: "estimated B", points: &blue },
                Curve { name: "estimated R", points: &red },
                Curve { name: "estimated G", points: &green },
                Curve { name: "sRGB", points: &srgb },
            ]
        };
        let _ = writeln!(
            s,
            "<figure><figcaption>Inverse response: code value → relative exposure (1 at code 128), log scale\
             </figcaption>{}</figure>",
            line_chart(&curves, 560, 260, "code / max", "exposure")
        );
    }
    if c.vignetting && !c.cameras.is_empty() {
        let profiles: Vec<(String, Vec<(f64, f64)>)> = c
            .cameras
            .iter()
            .map(|cam| {
                let n = (cam.profile.len().max(2) - 1) as f64;
                (
                    format!("camera {}", cam.camera),
                    cam.profile.iter().enumerate().map(|(k, &v)| (k as f64 / n, v)).collect(),
                )
            })
            .collect();
        let curves: Vec<Curve<'_>> = profiles.iter().map(|(n, p)| Curve { name: n, points: p }).collect();
        let _ = writeln!(
            s,
            "<figure><figcaption>Vignetting: relative brightness against distance from the principal point (1 = \
             image corner), log scale</figcaption>{}</figure>",
            line_chart(&curves, 560, 220, "radius / corner radius", "falloff")
        );
    }
    s
}

fn per_photo(on: bool) -> &'static str {
    if on { "per photo" } else { "fixed" }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::artefacts::preprocess::{CALIBRATION_FORMAT, CalibratedView, CameraVignetting};

    fn file(response: bool, vignetting: bool) -> CalibrationFile {
        CalibrationFile {
            format: CALIBRATION_FORMAT.into(),
            response_mode: if response { "estimate" } else { "linear" }.into(),
            response_channels: response.then_some(ResponseChannels::Shared),
            exposure: true,
            white_balance: false,
            vignetting,
            points: 100,
            observations: 250,
            used_observations: 240,
            residual_rms: 0.01,
            linked_sets: 1,
            views: vec![
                CalibratedView { name: "a<b".into(), camera: 0, gain: Some([0.5, 0.5, 0.5]), left_out: None },
                CalibratedView { name: "c".into(), camera: 1, gain: None, left_out: Some("all clipped".into()) },
            ],
            cameras: vec![CameraVignetting {
                camera: 0,
                beta: [-0.5, 0.0, 0.0],
                corner: 0.61,
                profile: vec![1.0, 0.8, 0.61],
            }],
            response: response.then(|| (0..256).map(|z| [(z as f32 / 255.0).powf(2.0); 3]).collect()),
            exponent_source: "ShapePrior".into(),
            exponent_reliable: !response,
        }
    }

    #[test]
    fn section_lists_every_view_and_shows_only_what_was_estimated() {
        let s = section(&file(true, true), None);
        assert!(s.contains("a&lt;b") && s.contains("0.5000"), "gains table escapes names: {s}");
        assert!(s.contains("left out: all clipped"));
        assert!(s.contains("Inverse response") && s.contains("sRGB"));
        assert!(s.contains("one curve for R, G, B") && !s.contains("estimated B"), "a shared curve is drawn once");
        let mut film = file(true, true);
        film.response_channels = Some(ResponseChannels::PerChannel);
        let per = section(&film, None);
        assert!(per.contains("estimated B") && per.contains("estimated R") && per.contains("estimated G"));
        assert!(s.contains("Vignetting"));
        let plain = section(&file(false, false), None);
        assert!(!plain.contains("Inverse response") && !plain.contains("Vignetting:"));
        assert!(plain.contains("exposure per photo") || plain.contains("Exposure per photo"));
    }

    #[test]
    fn a_searched_exponent_raises_what_is_shown_and_lists_its_trials() {
        use crate::artefacts::object::{ExponentRound, PHOTOMETRIC_FORMAT, SearchEmitter};
        let search = PhotometricFile {
            format: PHOTOMETRIC_FORMAT.into(),
            exponent: [2.0; 3],
            emitters: vec![
                SearchEmitter { id: 7, label: "lamp".into(), share: Some(0.9), light: true },
                SearchEmitter { id: 3, label: "wall".into(), share: Some(0.05), light: false },
            ],
            rounds: vec![
                ExponentRound { exponent: 1.0, misfit: [4e-3; 3], criterion: 1.0, terms: 10 },
                ExponentRound { exponent: 2.0, misfit: [3e-3; 3], criterion: 0.75, terms: 10 },
            ],
        };
        let s = section(&file(true, true), Some(&search));
        assert!(s.contains("<b>2.000</b>"), "{s}");
        assert!(s.contains("0.2500"), "gain 0.5 raised to 2: {s}");
        assert!(s.contains("4.0000e-3") && s.contains("3.0000e-3"), "{s}");
        assert!(s.contains("(lamp (id 7); left out as faint emissions: wall (id 3))"), "{s}");
    }
}
