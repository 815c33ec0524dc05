//! Accuracy of fitted parameters against the ground truth of a synthetic scene.

use glam::Vec3;
use serde::Serialize;

use crate::synth::BuiltScene;

/// Errors of one fit against the truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Accuracy {
    /// Mean over the non-emitting objects of the mean |base colour − truth| over RGB (the issue's "albedo
    /// mean L1"; the Mitsuba baseline's `albedo_l1` is the same formula).
    pub albedo_l1: f64,
    /// Max over the true emitters and RGB of |emission − truth| / truth.
    pub emission_rel_err: f64,
    /// Largest emission channel of any object that does not emit in the truth, relative to the brightest
    /// true emitter's largest channel (spurious emitters).
    pub spurious_emission: f64,
    /// Mean |roughness − truth| over the objects that have a specular lobe in the truth; on a scene with no
    /// such object, over every object (whose roughness then barely affects the images: a weak check).
    pub roughness_err: f64,
}

/// Compares fitted `params` with the truth of `built`.
#[must_use]
pub fn accuracy(built: &BuiltScene, params: &tracer::Params) -> Accuracy {
    let truth = &built.params;
    let emits = |e: Vec3| e.max_element() > 0.0;
    let mut albedo = Vec::new();
    let mut emission_rel_err: f64 = 0.0;
    let brightest = truth.emission.iter().map(|e| e.max_element()).fold(0.0f32, f32::max);
    let mut spurious: f64 = 0.0;
    for (k, (t, f)) in truth.materials.iter().zip(&params.materials).enumerate() {
        if emits(truth.emission[k]) {
            let rel =
                (params.emission[k] - truth.emission[k]).abs() / truth.emission[k].max(Vec3::splat(f32::MIN_POSITIVE));
            emission_rel_err = emission_rel_err.max(f64::from(rel.max_element()));
        } else {
            albedo.push(f64::from((f.base_color - t.base_color).abs().element_sum()) / 3.0);
            if brightest > 0.0 {
                spurious = spurious.max(f64::from(params.emission[k].max_element() / brightest));
            }
        }
    }
    let glossy: Vec<usize> = (0..truth.materials.len())
        .filter(|&k| truth.materials[k].specular > 0.0 || truth.materials[k].metallic > 0.0)
        .collect();
    let rough_set: Vec<usize> = if glossy.is_empty() { (0..truth.materials.len()).collect() } else { glossy };
    let roughness_err = mean(
        &rough_set
            .iter()
            .map(|&k| f64::from((params.materials[k].roughness - truth.materials[k].roughness).abs()))
            .collect::<Vec<_>>(),
    );
    Accuracy { albedo_l1: mean(&albedo), emission_rel_err, spurious_emission: spurious, roughness_err }
}

/// Mean of `v` (0 for an empty slice: no object of that kind, nothing wrong).
#[must_use]
pub fn mean(v: &[f64]) -> f64 {
    if v.is_empty() { 0.0 } else { v.iter().sum::<f64>() / v.len() as f64 }
}

/// Relative L1 of a re-render against a photo: Σ|I − photo| / Σ|photo| over pixels and channels.
#[must_use]
pub fn relative_l1(render: &[Vec3], photo: &[f32]) -> f64 {
    let mut num = 0.0;
    let mut den = 0.0;
    for (r, p) in render.iter().zip(photo.chunks_exact(3)) {
        for c in 0..3 {
            num += f64::from((r[c] - p[c]).abs());
            den += f64::from(p[c].abs());
        }
    }
    if den > 0.0 { num / den } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_l1_is_zero_for_equal_images_and_scales() {
        let photo = [1.0, 2.0, 3.0, 0.5, 0.5, 0.5];
        let same = [Vec3::new(1.0, 2.0, 3.0), Vec3::splat(0.5)];
        assert_eq!(relative_l1(&same, &photo), 0.0);
        let double: Vec<Vec3> = same.iter().map(|v| *v * 2.0).collect();
        assert!((relative_l1(&double, &photo) - 1.0).abs() < 1e-12);
    }
}
