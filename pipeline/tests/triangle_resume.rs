//! The per-triangle rounds resume exactly: stopping after a round's checkpoint and continuing from the
//! checkpointed state ends with the same mesh and parameters — per-triangle materials and the per-object
//! emission that the final round re-solves — as an uninterrupted run (all random numbers are keyed by seed,
//! round, pass and step), also when the checkpoint went through its JSON form. In-memory checker scene with
//! 128-path photos, started from the true per-object values but a light 8 % low (as the object stage leaves it
//! at `iterations = 0`), so that the final round's light-change test finds the light wrong and re-solves it.

mod common;

use optim::triangle::{TriangleError, TriangleState, run_rounds};
use workflow::config::TriangleConfig;

#[test]
fn a_run_resumed_from_a_round_checkpoint_ends_where_the_uninterrupted_run_ends() {
    let (built, images) = common::synth_scene("checker", 128);
    let k = built.desc.objects.len();
    let mut start = lab::synth::true_triangle_start(&built).unwrap();
    // 8 %: ~10 standard errors of the light-change test's averaged steps (scatter ±1.5 % per step), so the
    // re-solve (the part of the stage whose resumption this checks last) runs.
    for e in &mut start.emission {
        *e *= 0.92;
    }
    let setup =
        common::RoundSetup::new(TriangleConfig { rounds: 2, fit_steps: 2, spp: 8, ..TriangleConfig::default() }, k);
    let inputs = setup.inputs(&built, &images);
    let bar = optim::NoProgress;
    let mut checkpoints: Vec<TriangleState> = Vec::new();
    let mut keep = |s: &TriangleState| -> Result<(), TriangleError> {
        checkpoints.push(s.clone());
        Ok(())
    };
    let start_emission = start.emission.clone();
    let full = run_rounds(&inputs, start, &mut keep, &bar).unwrap();
    assert!(!checkpoints.is_empty(), "no round ended with a split: {:?}", full.log);
    assert!(full.triangles.len() > built.mesh.triangles.len());
    // The checkpoint as the stage writes and reads it (serde_json), so the resumed state is bit-identical.
    let json = serde_json::to_string(&checkpoints[0]).unwrap();
    let resumed_from: TriangleState = serde_json::from_str(&json).unwrap();
    assert_eq!(resumed_from, checkpoints[0]);
    let resumed = run_rounds(&inputs, resumed_from, &mut |_| Ok(()), &bar).unwrap();
    assert_eq!(resumed.positions, full.positions);
    assert_eq!(resumed.triangles, full.triangles);
    assert_eq!(resumed.face_object, full.face_object);
    assert_eq!(resumed.materials, full.materials);
    assert_eq!(resumed.emission, full.emission);
    // The final round re-solved the light (started 8 % low, the change is significant); no object that did not
    // emit emits now.
    assert_ne!(full.emission, start_emission);
    assert!(full.log.last().is_some_and(|r| r.emission == full.emission));
    for (got, was) in full.emission.iter().zip(&start_emission) {
        assert_eq!(got.max_element() > 0.0, was.max_element() > 0.0, "{got} from {was}");
    }
    assert_eq!(resumed.rounds_done, full.rounds_done);

    // A stop requested within a round (two blocks or steps after the first round's checkpoint) ends the stage
    // at the next block or step, before any more work, with the first round's checkpoint as the last one
    // written: the one a rerun resumes from, shown above to end where the uninterrupted run ends.
    let stopping = common::StopAfter::default();
    let mut written: Vec<TriangleState> = Vec::new();
    let mut keep = |s: &TriangleState| -> Result<(), TriangleError> {
        written.push(s.clone());
        stopping.arm();
        Ok(())
    };
    let start = {
        let mut s = lab::synth::true_triangle_start(&built).unwrap();
        s.emission.clone_from(&start_emission);
        s
    };
    let err = run_rounds(&inputs, start, &mut keep, &stopping).unwrap_err();
    assert!(matches!(err, TriangleError::Stopped(_)), "{err}");
    assert_eq!(written.len(), 1, "a round finished after the stop");
    // The same first round (its log's wall-clock time aside).
    let (a, b) = (&written[0], &checkpoints[0]);
    assert_eq!(
        (&a.positions, &a.triangles, &a.materials, &a.emission),
        (&b.positions, &b.triangles, &b.materials, &b.emission)
    );
    assert_eq!(a.rounds_done, b.rounds_done);
    assert!(stopping.asked(), "the stop was never asked for");
    assert_eq!(stopping.positions_after_stop(), 0, "work went on after the stop was requested");
}
