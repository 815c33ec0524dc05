//! Optional Adam iterations after a round's ratio steps, on every fitted triangle's base colour (and the
//! roughness and metallic of objects whose model has a specular lobe), with the object stage's loss and the
//! smoothness term. See the module docs of [`crate::triangle`].

use glam::Vec3;
use tracer::PixelRef;

use super::pixels::TriSample;
use super::{RoundInputs, TriangleError, TriangleState};
use crate::fit::adam::{AdamConfig, AdamState};
use crate::streams::{draw, key, uniform};

/// Layout of Adam's flat parameter vector: [`PER_TRIANGLE`] entries per triangle, triangle t's parameter p at
/// [`idx`]`(t, p)`.
mod layout {
    /// Parameters per triangle: base colour RGB, roughness, metallic.
    pub const PER_TRIANGLE: usize = 5;
    /// Offset of the base colour's red channel (green and blue follow).
    pub const BASE_COLOR: usize = 0;
    pub const ROUGHNESS: usize = 3;
    pub const METALLIC: usize = 4;
    /// Parameters of a triangle whose object has no specular lobe: the base colour only.
    pub const DIFFUSE: usize = 3;

    /// Index of triangle `t`'s parameter `p`.
    #[must_use]
    pub const fn idx(t: usize, p: usize) -> usize {
        PER_TRIANGLE * t + p
    }
}

use layout::{BASE_COLOR, DIFFUSE, METALLIC, PER_TRIANGLE, ROUGHNESS, idx};

/// Adam on the per-triangle base colours (and roughness/metallic of specular objects): batches of
/// `object.batch_pixels` pixels drawn uniformly, `object.n_value` value and `object.n_grad` gradient paths,
/// the object stage's loss weight, plus the smoothness term `λ/N Σ_(t,u) |ρ_t − ρ_u|²` (N = fitted pixels,
/// the scale at which λ counts pixels of evidence), clamped to [0, 1]. The tracer's work is added to `work`.
pub(super) fn adam(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    state: &mut TriangleState,
    free: &[bool],
    nbrs: &[Vec<u32>],
    round: u32,
    work: &mut tracer::TraceStats,
) -> Result<(), TriangleError> {
    let cfg = inputs.settings;
    let s = inputs.object;
    let n = state.triangles.len();
    let mut x: Vec<f64> = state
        .materials
        .iter()
        .flat_map(|m| [m.base_color.x, m.base_color.y, m.base_color.z, m.roughness, m.metallic].map(f64::from))
        .collect();
    let mut lr = vec![0.0; PER_TRIANGLE * n];
    for t in (0..n).filter(|&t| free[t]) {
        let spec = inputs.specular.get(state.face_object[t] as usize).copied().unwrap_or(false);
        for p in 0..if spec { PER_TRIANGLE } else { DIFFUSE } {
            lr[idx(t, p)] = cfg.adam_lr;
        }
    }
    let (lo, hi) = (vec![0.0; PER_TRIANGLE * n], vec![1.0; PER_TRIANGLE * n]);
    let mut st = AdamState::new(PER_TRIANGLE * n, AdamConfig::default());
    let pool: Vec<&TriSample> = samples.iter().filter(|p| free[p.tri as usize]).collect();
    if pool.is_empty() {
        return Ok(());
    }
    let b = s.batch_pixels.max(1) as usize;
    let lambda = cfg.smoothness / pool.len() as f64;
    for it in 0..cfg.adam_iterations {
        let key = key::triangle(round, key::TRIANGLE_ADAM | it);
        let batch: Vec<&TriSample> = (0..b as u64)
            .map(|i| {
                let u = uniform(cfg.seed, draw::TRIANGLE_BATCH, key, i);
                pool[((u * pool.len() as f64) as usize).min(pool.len() - 1)]
            })
            .collect();
        let pix: Vec<PixelRef> = batch.iter().map(|p| p.pixel).collect();
        let params = state.params();
        let renderer = tracer::Renderer::new(scene, &params, inputs.tracer)?;
        let (values, stats) = renderer.render_pixels(inputs.cameras, &pix, s.n_value, cfg.seed, key)?;
        work.add(&stats);
        let weights: Vec<Vec3> = values
            .iter()
            .zip(&batch)
            .map(|(v, p)| crate::fit::object::loss_weight(s, *v - p.target, p.target) / b as f32)
            .collect();
        let (g, stats) = renderer.gradient_pixels(inputs.cameras, &pix, &weights, s.n_grad, cfg.seed, key)?;
        work.add(&stats);
        let mut grad = vec![0.0; PER_TRIANGLE * n];
        for t in 0..n {
            let m = &g.materials[t];
            grad[idx(t, 0)..idx(t, PER_TRIANGLE)].copy_from_slice(&[
                m.base_color.x,
                m.base_color.y,
                m.base_color.z,
                m.roughness,
                m.metallic,
            ]);
            for &u in &nbrs[t] {
                for c in 0..3 {
                    let (i, j) = (idx(t, BASE_COLOR + c), idx(u as usize, BASE_COLOR + c));
                    grad[i] += 2.0 * lambda * (x[i] - x[j]);
                }
            }
        }
        // The tracer discards non-finite samples, so this is a bug check (e.g. a non-finite weight).
        if !grad.iter().all(|v| v.is_finite()) {
            return Err(TriangleError::Input(format!("non-finite gradient in round {round}, Adam iteration {it}")));
        }
        st.step(&mut x, &grad, &lr, &lo, &hi);
        for (t, m) in state.materials.iter_mut().enumerate() {
            let base = idx(t, BASE_COLOR);
            m.base_color = Vec3::new(x[base] as f32, x[base + 1] as f32, x[base + 2] as f32);
            m.roughness = x[idx(t, ROUGHNESS)] as f32;
            m.metallic = x[idx(t, METALLIC)] as f32;
        }
    }
    Ok(())
}
