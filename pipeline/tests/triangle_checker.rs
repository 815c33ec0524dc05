//! The per-triangle fit on the checker scene (data-fixtures/scenes/checker.toml: a 4 × 4 checkerboard floor
//! that the scan mesh models as 2 triangles, untextured walls) through `pipeline run` (ingest → preprocess →
//! object → triangle → export), tracing paths as deep as the renderer that made the photos. After the
//! per-triangle stage the floor's exported albedo, sampled at 2000 random floor points through
//! `export/mesh.ply` (point → containing face → albedo), has PSNR ≥ 40 dB against the true checker (28 dB was
//! the first bound), the walls were not subdivided, and the light of the per-triangle result is within 3 % of
//! the truth. Also: a rerun resumes nothing and skips every stage, and `pipeline export RUN_DIR` rewrites the
//! same mesh.ply.
//!
//! The run directory's `export/`, `triangle/result.json` + `triangle/mesh.ply` and `ingest/scene.json` are copied to
//! `target/triangle_checker/` for tests/validation/test_triangle_export.py.

mod common;
use common::{copy_dir, pipeline};
use std::path::{Path, PathBuf};

use glam::Vec3;
use ingest::ply::FaceValues;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn f32_col(mesh: &ingest::ply::PlyMesh, name: &str) -> Vec<f32> {
    match mesh.face_prop(name) {
        Some(FaceValues::F32(v)) => v.clone(),
        other => panic!("face column {name}: {other:?}"),
    }
}

#[test]
fn checker_floor_is_recovered_per_triangle_and_walls_stay_whole() {
    let scan = workspace().join("data-fixtures/checker");
    let desc = lab::synth::load_desc(&workspace().join("data-fixtures/scenes/checker.toml")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("run.toml");
    // The fit traces paths as deep as the renderer that made the photos did, so that what is measured is the
    // texture's recovery. At depth 8 against photos of depth 6 the fit's extra bounces put the light about 2 %
    // high and the albedos as much low: over seeds 0–5 the floor's PSNR was 39.0–45.0 dB (40.00 at seed 0 with
    // Embree's AVX-512 kernels, 40.01 with its AVX2 ones), at the photos' depth 41.6–53.3 dB over seeds 0–11
    // (docs/optim/design-measurements.md, "The checker fit at the photos' path depth").
    std::fs::write(&cfg, lab::synth::run_config(&scan, &desc)).unwrap();
    let cfg = cfg.to_str().unwrap();
    let started = std::time::Instant::now();
    let (code, err) = pipeline(&["run", cfg]);
    assert_eq!(code, 0, "{err}");
    eprintln!("pipeline run took {:.1} s\n{err}", started.elapsed().as_secs_f64());
    let out = dir.path().join("out");

    let ingested = workflow::artefacts::ingest::Ingested::read(&out).unwrap();
    let ids: Vec<i64> = ingested.objects.iter().map(|o| o.id).collect();
    let exported = ingest::ply::read_ply(&out.join("export/mesh.ply")).unwrap().mesh;
    let segment = exported.face_ids("segment_id").unwrap();
    let count = |mesh_segments: &[i32], id: i32| mesh_segments.iter().filter(|&&s| s == id).count();
    let scan_segments: Vec<i32> = ingested.face_object.iter().map(|&o| ids[o as usize] as i32).collect();

    // Walls (untextured) keep their face count; the floor was refined.
    let floor = desc.objects.iter().find(|o| o.label == "floor").unwrap();
    for wall in desc.objects.iter().filter(|o| o.label.starts_with("wall")) {
        assert_eq!(count(&segment, wall.id), count(&scan_segments, wall.id), "wall {} was subdivided", wall.id);
    }
    let (floor_before, floor_after) = (count(&scan_segments, floor.id), count(&segment, floor.id));
    eprintln!("floor: {floor_before} → {floor_after} triangles; mesh {} → {}", scan_segments.len(), segment.len());
    assert!(floor_after > floor_before);

    // 2000 random floor points → containing exported face → albedo, against the true checker (the metric of
    // `lab bench tradeoff`, one source of truth).
    let quad = lab::bench::metrics::CheckerQuad::of(floor).expect("the floor is a checker quad");
    let albedo = [f32_col(&exported, "albedo_r"), f32_col(&exported, "albedo_g"), f32_col(&exported, "albedo_b")];
    let albedo: Vec<Vec3> = (0..segment.len()).map(|f| Vec3::new(albedo[0][f], albedo[1][f], albedo[2][f])).collect();
    let floor_faces: Vec<usize> = (0..segment.len()).filter(|&t| segment[t] == floor.id).collect();
    let n = lab::bench::metrics::TEXTURE_POINTS;
    let texture = lab::bench::metrics::checker_albedo_error(
        &quad,
        &exported.positions,
        &exported.triangles,
        &albedo,
        &floor_faces,
        n,
        lab::bench::metrics::TEXTURE_POINTS_SEED,
    )
    .unwrap();
    let psnr = texture.psnr_db;
    eprintln!("floor albedo PSNR {psnr:.2} dB, L1 {:.4} over {n} points", texture.l1);
    // Measured 53.3 dB here at seed 0 (54.6 with Embree's AVX2 kernels), 41.6–53.3 dB over seeds 0–11. 40 dB is
    // the level the per-triangle fit was built to reach on this floor; the light's scatter (±2 %) moves the PSNR
    // by several dB, its lowest seed's 41.6 dB with the light 3.7 % off.
    assert!(psnr >= 40.0, "PSNR {psnr:.2} dB");

    // The light of the per-triangle result (re-solved with the per-triangle materials, module docs of
    // optim::triangle): within 3 % per channel of the truth, where the per-object stage's light, fitted with
    // one colour for the whole checker floor, is 6.5 % off at the bench's default point (here: 1.6 %, 20.17,
    // 17.71, 14.96; the light-change gate finds the change significant, p = 8.7e-3). Measured: 20.04, 17.93,
    // 15.02, max 0.4 %; over seeds 0–11 at most 1.7 % but for seed 1's 3.7 %. No other object emits (the object
    // stage's model decision is kept).
    let state = workflow::artefacts::triangle::read_result(&out).unwrap().expect("triangle/result.json");
    for (o, id) in ids.iter().enumerate() {
        let truth = desc.objects.iter().find(|d| i64::from(d.id) == *id).unwrap();
        let (got, want) = (state.emission[o], Vec3::from_array(truth.emission));
        if want.max_element() > 0.0 {
            let rel = ((got - want) / want).abs().max_element();
            eprintln!("light {}: {got} (truth {want}), max relative error {rel:.4}", truth.label);
            assert!(rel < 0.03, "light {}: {got} vs {want}", truth.label);
        } else {
            assert_eq!(got, Vec3::ZERO, "{} emits {got}", truth.label);
        }
    }

    // Nothing changed: every stage skipped.
    let (code, err) = pipeline(&["run", cfg]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("[triangle] skipped"), "{err}");
    assert!(err.contains("[export] skipped"), "{err}");

    // `pipeline export RUN_DIR` writes the same mesh.ply again.
    let before = std::fs::read(out.join("export/mesh.ply")).unwrap();
    let (code, err) = pipeline(&["export", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(std::fs::read(out.join("export/mesh.ply")).unwrap(), before);

    // For tests/validation/test_triangle_export.py.
    let keep = workspace().join("target/triangle_checker");
    let _ = std::fs::remove_dir_all(&keep);
    copy_dir(&out.join("export"), &keep.join("export"));
    std::fs::create_dir_all(keep.join("triangle")).unwrap();
    for f in ["result.json", "mesh.ply"] {
        std::fs::copy(out.join("triangle").join(f), keep.join("triangle").join(f)).unwrap();
    }
    std::fs::copy(out.join("ingest/scene.json"), keep.join("scene.json")).unwrap();
}

/// Regenerates `data-fixtures/checker/` from `data-fixtures/scenes/checker.toml` when IPT_REGENERATE_FIXTURES
/// is set.
#[test]
fn regenerate_checker_fixture_on_request() {
    if std::env::var_os("IPT_REGENERATE_FIXTURES").is_none() {
        eprintln!("skipping: set IPT_REGENERATE_FIXTURES=1 to regenerate data-fixtures/checker");
        return;
    }
    let out = workspace().join("data-fixtures/checker");
    lab::synth::generate(&workspace().join("data-fixtures/scenes/checker.toml"), &out).unwrap();
}
