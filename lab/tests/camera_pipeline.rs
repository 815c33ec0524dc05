//! The synthetic consumer camera pipeline (`lab::synth::camera_pipeline`, `[camera_pipeline]` of a scene
//! description): the tone curve and its recorded inverse, a generated scan that ingest reads and whose recorded
//! truth inverts the JPEGs back to the linear render, and the refusal of bad values.

use lab::synth::camera_pipeline::{inverse_table, tone_curve, tone_curve_inverse, vignetting};
use std::path::{Path, PathBuf};

fn camera_desc() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/camera.toml")
}

/// The fixture's text with each `(from, to)` replaced (each `from` must occur exactly once).
fn edited(replacements: &[(&str, &str)]) -> String {
    let mut text = std::fs::read_to_string(camera_desc()).unwrap();
    for (from, to) in replacements {
        assert_eq!(text.matches(from).count(), 1, "{from:?} must occur once in camera.toml");
        text = text.replace(from, to);
    }
    text
}

fn median(mut v: Vec<f64>) -> f64 {
    assert!(!v.is_empty());
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn tone_curve_is_monotone_clips_at_one_and_its_table_inverts_it_within_quantisation() {
    assert_eq!(tone_curve(0.0), 0.0);
    // Dense grid up to well past the clip point (W / bias = 5.6).
    let xs: Vec<f64> = (0..=20_000).map(|i| i as f64 * 1e-3).collect();
    for w in xs.windows(2) {
        assert!(tone_curve(w[1]) >= tone_curve(w[0]), "not monotone at {}", w[0]);
    }
    let clip = tone_curve_inverse(1.0);
    assert!((tone_curve(clip) - 1.0).abs() < 1e-12, "f(f⁻¹(1)) = {}", tone_curve(clip));
    assert_eq!(tone_curve(2.0 * clip), 1.0);
    assert!(tone_curve(0.9 * clip) < 1.0);
    // Not sRGB: the two curves differ by far more than a code somewhere in [0, 1].
    let gap =
        (0..=100).map(|i| (tone_curve(i as f64 / 100.0) - f64::from(ingest::srgb::encode(i as f32 / 100.0))).abs());
    assert!(gap.fold(0.0, f64::max) > 0.05);

    let table = inverse_table();
    assert_eq!(table.len(), 256);
    assert_eq!(table[0], 0.0);
    for (code, &x) in table.iter().enumerate() {
        // The table holds f⁻¹(code/255): encoding it again gives the code.
        assert_eq!(ingest::srgb::to_u8(tone_curve(x) as f32) as usize, code, "code {code}");
    }
    // Forward, quantise, invert through the table, forward again: within half a code (8-bit quantisation).
    for &x in &xs {
        let y = tone_curve(x);
        let code = ingest::srgb::to_u8(y as f32) as usize;
        assert!((tone_curve(table[code]) - y).abs() <= 0.5 / 255.0 + 1e-9, "x = {x}");
    }
}

#[test]
fn vignetting_is_one_at_the_centre_and_the_corner_value_at_the_corner() {
    for corner in [0.3, 0.6, 0.95] {
        assert!((vignetting(corner, 0.0) - 1.0).abs() < 1e-12);
        assert!((vignetting(corner, 1.0) - corner).abs() < 1e-12);
        assert!(vignetting(corner, 0.5) < 1.0 && vignetting(corner, 0.5) > corner);
    }
}

/// The recorded vignetting of one camera at r², linearly interpolated between its 17 samples.
fn recorded_vignetting(camera: &serde_json::Value, r2: f64) -> f64 {
    let v: Vec<f64> = camera["v"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    let t = r2.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let i = (t.floor() as usize).min(v.len() - 2);
    v[i] + (t - i as f64) * (v[i + 1] - v[i])
}

#[test]
fn generated_jpegs_are_read_by_ingest_and_the_recorded_truth_inverts_them_to_the_linear_render() {
    // A quarter-size variant of the fixture (same rig, same pipeline, same spp) for the debug build.
    check_generated(&[("width = 128", "width = 64"), ("height = 96", "height = 48")]);
}

/// The same checks on the fixture itself (128×96, about a minute in a debug build), when
/// IPT_CAMERA_FIXTURE_FULL is set.
#[test]
fn full_fixture_on_request() {
    if std::env::var_os("IPT_CAMERA_FIXTURE_FULL").is_none() {
        eprintln!("skipping: set IPT_CAMERA_FIXTURE_FULL=1 to check data-fixtures/scenes/camera.toml at full size");
        return;
    }
    check_generated(&[]);
}

/// Generates the fixture edited by `replacements` into a temporary directory and checks that ingest reads it
/// and that the recorded truth inverts its JPEGs to the linear render.
fn check_generated(replacements: &[(&str, &str)]) {
    let dir = tempfile::tempdir().unwrap();
    let desc_path = dir.path().join("camera.toml");
    std::fs::write(&desc_path, edited(replacements)).unwrap();
    let out = dir.path().join("scan");
    lab::synth::generate(&desc_path, &out).unwrap();

    let images: Vec<String> = std::fs::read_dir(out.join("undistorted_color_images"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(images.len(), 18, "{images:?}");
    assert!(images.iter().all(|n| n.ends_with(".jpg")), "JPEG only, no EXR sibling: {images:?}");

    let scan = ingest::load_scan(&out, ingest::ScanFormat::Matterport, ingest::GroupBy::default()).unwrap();
    assert_eq!(scan.views.len(), 18);
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("ground_truth_camera.json")).unwrap()).unwrap();
    assert_eq!(truth["format"], "ipt-camera-truth/1");
    let inverse: Vec<f64> =
        truth["tone_curve"]["inverse"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert_eq!(inverse.len(), 256);
    let cameras = truth["vignetting"]["cameras"].as_array().unwrap();
    assert_eq!(cameras.len(), 3);

    // The same description without [camera_pipeline] renders the same linear photos.
    let desc = lab::synth::load_desc(&desc_path).unwrap();
    let spec = desc.camera_pipeline.clone().unwrap();
    let built = lab::synth::build(lab::synth::desc::SceneDesc { camera_pipeline: None, ..desc }, &desc_path).unwrap();
    let linear = lab::synth::photos(&built).unwrap();

    // Relative errors of the inverted JPEG codes, of the inverted codes before JPEG encoding (quantisation
    // only), and of a naive sRGB decoding; JPEG code changes.
    let (mut errors, mut quantised_errors, mut naive_errors) = (Vec::new(), Vec::new(), Vec::new());
    let (mut code_changes, mut exposures) = (Vec::new(), Vec::new());
    for (k, view) in scan.views.iter().enumerate() {
        let c = k % 3;
        assert_eq!(view.name, format!("camera_i{c}_{k}"));
        assert_eq!(view.image_path.extension().unwrap(), "jpg");
        let ingest::photo::DecodedImage::Display(img) = ingest::photo::read_image(&view.image_path).unwrap() else {
            panic!("{}: a JPEG decodes to display codes", view.image_path.display());
        };
        assert_eq!((img.width, img.height, img.max_code), (built.desc.width, built.desc.height, 255));
        let photo = &truth["photos"][&view.name];
        assert_eq!(photo["camera"], c);
        exposures.push(photo["exposure"].as_f64().unwrap());
        let draw = lab::synth::camera_pipeline::draw(&spec, built.desc.seed, k);
        let before_jpeg = lab::synth::camera_pipeline::to_codes(&spec, &draw, &built.cameras[k], &linear[k].rgb);
        let gain: Vec<f64> = photo["gain"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        let k_in = view.camera.intrinsics;
        let far = |c: f64, size: u32| (c + 0.5).max(f64::from(size) - 0.5 - c);
        let corner2 = far(k_in.cx, img.width).powi(2) + far(k_in.cy, img.height).powi(2);
        for y in 0..img.height {
            for x in 0..img.width {
                let r2 = ((f64::from(x) - k_in.cx).powi(2) + (f64::from(y) - k_in.cy).powi(2)) / corner2;
                let v = recorded_vignetting(&cameras[c], r2);
                let i = 3 * (y * img.width + x) as usize;
                for ch in 0..3 {
                    let code = img.codes[i + ch];
                    // Codes near 0 and 255 are dominated by quantisation and clipping.
                    if !(10..=245).contains(&code) {
                        continue;
                    }
                    let truth_linear = f64::from(linear[k].rgb[i + ch]);
                    let recovered = inverse[code as usize] / (gain[ch] * v);
                    errors.push((recovered - truth_linear).abs() / truth_linear);
                    let quantised = inverse[usize::from(before_jpeg[i + ch])] / (gain[ch] * v);
                    quantised_errors.push((quantised - truth_linear).abs() / truth_linear);
                    code_changes.push((i32::from(code) - i32::from(before_jpeg[i + ch])).unsigned_abs());
                    let naive = f64::from(ingest::srgb::decode(f32::from(code) / 255.0));
                    naive_errors.push((naive - truth_linear).abs() / truth_linear);
                }
            }
        }
    }
    let n = errors.len();
    let (med, quantised, naive) = (median(errors), median(quantised_errors), median(naive_errors));
    let mean_change = f64::from(code_changes.iter().sum::<u32>()) / n as f64;
    eprintln!(
        "{n} channel values with codes in [10, 245]: median relative error {med:.4} after JPEG, {quantised:.4} \
         before (8-bit only), {naive:.4} for a naive sRGB decoding; JPEG changes a code by {mean_change:.2} on average"
    );
    // Most pixels of the room are within [10, 245] (few dark corners, no lamp in view).
    let total = 18 * 3 * (built.desc.width * built.desc.height) as usize;
    assert!(n > total / 2, "only {n} of {total} channel values in [10, 245]");
    // 8-bit quantisation alone: ±0.5 code at 2–4 % per code for the typical codes 60–160 (0.7 % measured).
    assert!(quantised < 0.01, "median relative error before JPEG {quantised}");
    // JPEG at quality 90 on these 128-spp photos (Monte Carlo noise is detail to it) moves a code by about 1
    // (1.10 measured at 64×48); with quantisation the median relative error is 2.5 % measured.
    assert!(mean_change < 1.5, "JPEG changes a code by {mean_change} on average");
    assert!(med < 0.03, "median relative error {med}");
    // The camera pipeline matters: decoding as if the photos were plain sRGB is far off.
    assert!(naive > 0.1, "naive sRGB decoding is already within {naive}");
    // Auto exposure varies per photo, within the description's range.
    assert!(exposures.iter().all(|&e| (0.5..=2.0).contains(&e)));
    let spread =
        exposures.iter().copied().fold(0.0, f64::max) / exposures.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(spread > 1.5, "18 log-uniform draws in [0.5, 2] span more than 1.5×: {exposures:?}");
}

#[test]
fn bad_camera_pipeline_values_are_refused_in_one_line_naming_the_file() {
    let cases = [
        ("exposure = [0.5, 2.0]", "exposure = [2.0, 0.5]", "exposure"),
        ("exposure = [0.5, 2.0]", "exposure = [0.0, 2.0]", "exposure"),
        ("white_balance = 0.12", "white_balance = 1.2", "white_balance"),
        ("vignetting_corner = [0.6, 0.62, 0.58]", "vignetting_corner = [0.6, 1.0, 0.58]", "vignetting_corner"),
        ("vignetting_corner = [0.6, 0.62, 0.58]", "vignetting_corner = []", "vignetting_corner"),
        ("jpeg_quality = 90", "jpeg_quality = 0", "jpeg_quality"),
        ("tone_curve = \"filmic\"", "tone_curve = \"srgb\"", "srgb"),
        ("jpeg_quality = 90", "jpeg_quality = 90\ngamma = 2.2", "gamma"),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (i, (from, to, word)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad{i}.toml"));
        let text = edited(&[(from, to)]);
        std::fs::write(&path, &text).unwrap();
        let msg = lab::synth::load_desc(&path).unwrap_err().to_string();
        if *word == "gamma" {
            // An unknown key is refused by the parser, which names its line.
            let line = text.lines().position(|l| l.starts_with("gamma")).unwrap() + 1;
            assert!(msg.contains(&format!("line {line}:")), "{to}: does not name line {line}: {msg}");
        }
        assert!(!msg.contains('\n'), "{to}: not one line: {msg}");
        assert!(msg.contains(&*path.to_string_lossy()), "{to}: does not name the file: {msg}");
        assert!(msg.contains(word), "{to}: does not name {word}: {msg}");
    }
    // The unedited fixture is accepted (so the refusals above come from the edits).
    lab::synth::load_desc(&camera_desc()).unwrap();
}
