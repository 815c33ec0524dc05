//! The per-triangle rounds resume exactly: stopping after a round's checkpoint and continuing from the
//! checkpointed state ends with the same mesh and parameters as an uninterrupted run (all random numbers are
//! keyed by seed, round and step). In-memory checker scene with 128-path photos.

use std::path::Path;

use pipeline::config::TriangleConfig;
use pipeline::triangle::{RoundInputs, TriangleError, TriangleState, run_rounds};

#[test]
fn a_run_resumed_from_a_round_checkpoint_ends_where_the_uninterrupted_run_ends() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/checker.toml");
    let mut desc = pipeline::synth::load_desc(&path).unwrap();
    desc.spp = 128;
    let built = pipeline::synth::build(desc, &path).unwrap();
    let images = pipeline::synth::photos(&built).unwrap();
    let k = built.desc.objects.len();
    let start = pipeline::synth::true_triangle_start(&built).unwrap();
    let config = TriangleConfig { rounds: 2, fit_steps: 2, spp: 8, ..TriangleConfig::default() };
    let object = pipeline::fit::ObjectFitSettings::default();
    let specular = vec![false; k];
    let inputs = RoundInputs {
        cameras: &built.cameras,
        images: &images,
        config: &config,
        object: &object,
        tracer: &built.settings,
        specular: &specular,
    };
    let bar = indicatif::ProgressBar::hidden();
    let mut checkpoints: Vec<TriangleState> = Vec::new();
    let mut keep = |s: &TriangleState| -> Result<(), TriangleError> {
        checkpoints.push(s.clone());
        Ok(())
    };
    let full = run_rounds(&inputs, start, &mut keep, &bar).unwrap();
    assert!(!checkpoints.is_empty(), "no round ended with a split: {:?}", full.log);
    assert!(full.triangles.len() > built.mesh.triangles.len());
    let resumed_from = checkpoints[0].clone();
    let resumed = run_rounds(&inputs, resumed_from, &mut |_| Ok(()), &bar).unwrap();
    assert_eq!(resumed.positions, full.positions);
    assert_eq!(resumed.triangles, full.triangles);
    assert_eq!(resumed.face_object, full.face_object);
    assert_eq!(resumed.materials, full.materials);
    assert_eq!(resumed.rounds_done, full.rounds_done);
}
