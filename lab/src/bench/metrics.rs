//! Accuracy of fitted parameters against the ground truth of a synthetic scene: per-object errors
//! ([`accuracy`]) and, for objects with a checker albedo, the texture error of a per-triangle result at seeded
//! random points of the object ([`checker_albedo_error`], shared with tests/triangle_checker.rs).

use glam::Vec3;
use serde::Serialize;

use crate::synth::BuiltScene;
use crate::synth::desc::{Checker, ObjectSpec, Shape};

/// Errors of one fit against the truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Accuracy {
    /// Mean over the non-emitting untextured objects of the mean |base colour − truth| over RGB (the issue's
    /// "albedo mean L1"; the Mitsuba baseline's `albedo_l1` is the same formula). Objects with a checker albedo
    /// are left out: one base colour cannot match a texture (see [`checker_albedo_error`]).
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
        let textured = built.desc.objects.get(k).is_some_and(|o| o.checker.is_some());
        if emits(truth.emission[k]) {
            let rel =
                (params.emission[k] - truth.emission[k]).abs() / truth.emission[k].max(Vec3::splat(f32::MIN_POSITIVE));
            emission_rel_err = emission_rel_err.max(f64::from(rel.max_element()));
        } else if !textured {
            albedo.push(f64::from((f.base_color - t.base_color).abs().element_sum()) / 3.0);
        }
        if !emits(truth.emission[k]) && brightest > 0.0 {
            spurious = spurious.max(f64::from(params.emission[k].max_element() / brightest));
        }
    }
    // One slot per object in both (a checker scene's truth has extra slots for its square colours after them).
    let objects = truth.materials.len().min(params.materials.len());
    let glossy: Vec<usize> =
        (0..objects).filter(|&k| truth.materials[k].specular > 0.0 || truth.materials[k].metallic > 0.0).collect();
    let rough_set: Vec<usize> = if glossy.is_empty() { (0..objects).collect() } else { glossy };
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

/// A quad object with a checker albedo: where it lies (`corner + s·u + t·v`, s, t ∈ [0, 1]) and its squares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckerQuad {
    pub corner: Vec3,
    pub u: Vec3,
    pub v: Vec3,
    pub checker: Checker,
}

impl CheckerQuad {
    /// The checker quad of a description object (`None` for untextured objects and boxes).
    #[must_use]
    pub fn of(spec: &ObjectSpec) -> Option<Self> {
        match (spec.checker, spec.shape) {
            (Some(checker), Shape::Quad { corner, u, v }) => {
                Some(Self { corner: corner.into(), u: u.into(), v: v.into(), checker })
            }
            _ => None,
        }
    }

    /// Quad parameters (s, t) of `p` (least squares in the quad's plane: exact for points on it).
    #[must_use]
    pub fn params_of(&self, p: Vec3) -> (f64, f64) {
        let d = (p - self.corner).as_dvec3();
        let (u, v) = (self.u.as_dvec3(), self.v.as_dvec3());
        let (uu, uv, vv) = (u.dot(u), u.dot(v), v.dot(v));
        let (du, dv) = (d.dot(u), d.dot(v));
        let det = uu * vv - uv * uv;
        if det == 0.0 {
            return (f64::NAN, f64::NAN);
        }
        ((vv * du - uv * dv) / det, (uu * dv - uv * du) / det)
    }
}

/// Texture error of a per-triangle albedo against a checker: mean absolute error and PSNR (peak 1, the
/// albedo range) over RGB at `points` seeded random points of the quad.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TextureAccuracy {
    pub l1: f64,
    pub psnr_db: f64,
    pub points: usize,
}

/// Why [`checker_albedo_error`] could not measure.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    #[error("checker albedo: no face of the object contains sample point {index} at (s, t) = ({s:.4}, {t:.4})")]
    Uncovered { index: usize, s: f32, t: f32 },
    #[error("checker albedo: face {face} is out of range ({faces} faces, {albedos} albedos)")]
    BadFace { face: usize, faces: usize, albedos: usize },
    #[error("checker albedo: no sample points")]
    NoPoints,
}

/// Samples `points` random points of `quad` (keyed by `seed` via [`optim::streams::uniform`], stream 1,
/// so the same seed gives the same points everywhere), finds the face among `faces` (indices into
/// `triangles`, vertices in `positions`) that contains each, and compares that face's `albedo` (indexed by
/// face) with the true checker colour there.
pub fn checker_albedo_error(
    quad: &CheckerQuad,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    albedo: &[Vec3],
    faces: &[usize],
    points: usize,
    seed: u64,
) -> Result<TextureAccuracy, TextureError> {
    if points == 0 {
        return Err(TextureError::NoPoints);
    }
    // The faces in the quad's (s, t) coordinates, once.
    let mut st_faces = Vec::with_capacity(faces.len());
    for &f in faces {
        let bad = || TextureError::BadFace { face: f, faces: triangles.len(), albedos: albedo.len() };
        let tri = triangles.get(f).ok_or_else(bad)?;
        if f >= albedo.len() {
            return Err(bad());
        }
        let mut st = [(0.0, 0.0); 3];
        for (c, &k) in st.iter_mut().zip(tri) {
            *c = quad.params_of(*positions.get(k as usize).ok_or_else(bad)?);
        }
        st_faces.push((f, st));
    }
    let (mut abs, mut sq) = (0.0f64, 0.0f64);
    for i in 0..points {
        let s = optim::streams::uniform(seed, 1, i as u64, 0);
        let t = optim::streams::uniform(seed, 1, i as u64, 1);
        let face = st_faces
            .iter()
            .find(|(_, st)| contains(*st, s, t))
            .map(|(f, _)| *f)
            .ok_or(TextureError::Uncovered { index: i, s: s as f32, t: t as f32 })?;
        let truth = quad.checker.albedo_at(s as f32, t as f32);
        for c in 0..3 {
            let e = f64::from(albedo[face][c] - truth[c]);
            abs += e.abs();
            sq += e * e;
        }
    }
    let n = 3.0 * points as f64;
    let mse = sq / n;
    // Peak signal 1: albedos lie in [0, 1]. A perfect fit gives +inf, which the CSV writes as `inf`.
    Ok(TextureAccuracy { l1: abs / n, psnr_db: 10.0 * (1.0 / mse).log10(), points })
}

/// Seed of the random points of [`triangle_texture_error`] (tests/triangle_checker.rs uses the same).
pub const TEXTURE_POINTS_SEED: u64 = 6;
/// Points of [`triangle_texture_error`]: the L1's sampling error is ≈ 1 % of its value at this count.
pub const TEXTURE_POINTS: usize = 2000;

/// Texture error of a per-triangle result over the objects of `built` that have a checker albedo (their
/// triangles: `face_object` = description index): L1 averaged over those objects, PSNR of their mean squared
/// error. `None` when the scene has no checker object.
pub fn triangle_texture_error(
    built: &BuiltScene,
    state: &optim::triangle::TriangleState,
) -> Result<Option<TextureAccuracy>, TextureError> {
    let albedo: Vec<Vec3> = state.materials.iter().map(|m| m.base_color).collect();
    let mut per_object = Vec::new();
    for (k, spec) in built.desc.objects.iter().enumerate() {
        let Some(quad) = CheckerQuad::of(spec) else { continue };
        let faces: Vec<usize> = (0..state.face_object.len()).filter(|&f| state.face_object[f] as usize == k).collect();
        per_object.push(checker_albedo_error(
            &quad,
            &state.positions,
            &state.triangles,
            &albedo,
            &faces,
            TEXTURE_POINTS,
            TEXTURE_POINTS_SEED,
        )?);
    }
    if per_object.is_empty() {
        return Ok(None);
    }
    let l1 = mean(&per_object.iter().map(|a| a.l1).collect::<Vec<_>>());
    let mse = mean(&per_object.iter().map(|a| 10f64.powf(-a.psnr_db / 10.0)).collect::<Vec<_>>());
    Ok(Some(TextureAccuracy { l1, psnr_db: 10.0 * (1.0 / mse).log10(), points: per_object.len() * TEXTURE_POINTS }))
}

/// Whether (s, t) lies in the triangle with corners `p` (barycentric, with a tolerance for points on an
/// edge: relative to the quad's unit parameter range, far below a pixel and far above f64 rounding).
fn contains(p: [(f64, f64); 3], s: f64, t: f64) -> bool {
    let [(ax, ay), (bx, by), (cx, cy)] = p;
    let d = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy);
    if d == 0.0 || !d.is_finite() {
        return false;
    }
    let l1 = ((by - cy) * (s - cx) + (cx - bx) * (t - cy)) / d;
    let l2 = ((cy - ay) * (s - cx) + (ax - cx) * (t - cy)) / d;
    let eps = 1e-9;
    l1 >= -eps && l2 >= -eps && 1.0 - l1 - l2 >= -eps
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2 m × 1 m quad in a tilted plane, split into its two triangles, and a 2 × 2 checker.
    fn quad() -> (CheckerQuad, Vec<Vec3>, Vec<[u32; 3]>) {
        let q = CheckerQuad {
            corner: Vec3::new(0.5, -1.0, 0.25),
            u: Vec3::new(2.0, 0.0, 0.0),
            v: Vec3::new(0.0, 0.6, 0.8),
            checker: Checker { squares: 2, colors: [[0.8, 0.7, 0.5], [0.1, 0.2, 0.3]] },
        };
        let pos = vec![q.corner, q.corner + q.u, q.corner + q.u + q.v, q.corner + q.v];
        (q, pos, vec![[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn params_of_inverts_the_quad_parametrisation() {
        let (q, ..) = quad();
        let (s, t) = q.params_of(q.corner + 0.3 * q.u + 0.9 * q.v);
        assert!((s - 0.3).abs() < 1e-6 && (t - 0.9).abs() < 1e-6, "{s} {t}");
    }

    #[test]
    fn checker_error_of_a_uniform_albedo_is_half_the_colour_difference() {
        let (q, pos, tris) = quad();
        let [a, b] = q.checker.colors.map(Vec3::from);
        // Colour `a` everywhere: wrong on half the area (the two colours' squares have equal area), by |a − b|.
        let r = checker_albedo_error(&q, &pos, &tris, &[a, a], &[0, 1], 4000, 3).unwrap();
        let half_l1 = f64::from((a - b).abs().element_sum()) / 3.0 / 2.0;
        let half_mse = f64::from((a - b).length_squared()) / 3.0 / 2.0;
        // 4000 Bernoulli(1/2) samples: the fraction's standard deviation is 0.008, 5σ = 4 %.
        assert!((r.l1 / half_l1 - 1.0).abs() < 0.04, "{} vs {half_l1}", r.l1);
        assert!((r.psnr_db - 10.0 * (1.0 / half_mse).log10()).abs() < 0.2, "{}", r.psnr_db);
    }

    #[test]
    fn checker_error_is_zero_on_exact_squares_and_fails_on_uncovered_points() {
        let (q, ..) = quad();
        // The 2 × 2 squares as 8 triangles, each with its true colour.
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        let mut alb = Vec::new();
        for j in 0..2 {
            for i in 0..2 {
                let p = |a: f32, b: f32| q.corner + a * 0.5 * q.u + b * 0.5 * q.v;
                let (i0, j0) = (i as f32, j as f32);
                let k = pos.len() as u32;
                pos.extend([p(i0, j0), p(i0 + 1.0, j0), p(i0 + 1.0, j0 + 1.0), p(i0, j0 + 1.0)]);
                tris.extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
                let c = Vec3::from(q.checker.colors[(i + j) % 2]);
                alb.extend([c, c]);
            }
        }
        let faces: Vec<usize> = (0..tris.len()).collect();
        let r = checker_albedo_error(&q, &pos, &tris, &alb, &faces, 500, 9).unwrap();
        assert_eq!(r.l1, 0.0);
        assert!(r.psnr_db.is_infinite());
        // Without the last square's faces some points fall nowhere.
        assert!(matches!(
            checker_albedo_error(&q, &pos, &tris, &alb, &faces[..6], 500, 9),
            Err(TextureError::Uncovered { .. })
        ));
    }

    #[test]
    fn relative_l1_is_zero_for_equal_images_and_scales() {
        let photo = [1.0, 2.0, 3.0, 0.5, 0.5, 0.5];
        let same = [Vec3::new(1.0, 2.0, 3.0), Vec3::splat(0.5)];
        assert_eq!(relative_l1(&same, &photo), 0.0);
        let double: Vec<Vec3> = same.iter().map(|v| *v * 2.0).collect();
        assert!((relative_l1(&double, &photo) - 1.0).abs() < 1e-12);
    }
}
