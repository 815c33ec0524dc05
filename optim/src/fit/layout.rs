//! The flat parameter vector of the per-object fit and its mapping to the tracer's tables.
//!
//! Object k owns entries `15k .. 15k + 15`: base colour RGB, roughness, metallic, specular, emission RGB, the
//! RGB ground half of its emission, read only when model selection splits the object's emission at the
//! horizon (`super::horizon`; then `emission` is its sky half), and the RGB zenith of that sky half, read only
//! when the split's sky varies with elevation (then `emission` is its sky at the horizon;
//! `tracer::params::Horizon`).
//! Values are kept in f64 (the optimiser's precision, and what checkpoints store) and converted to f32 for
//! the tracer, so an interrupted and resumed run sees exactly the same numbers as an uninterrupted one.

use glam::Vec3;

/// Entries per object.
pub const PER_OBJECT: usize = 15;
pub const BASE_COLOR: usize = 0;
pub const ROUGHNESS: usize = 3;
pub const METALLIC: usize = 4;
pub const SPECULAR: usize = 5;
pub const EMISSION: usize = 6;
pub const EMISSION_GROUND: usize = 9;
pub const EMISSION_ZENITH: usize = 12;

/// Upper bound of emission in the optimiser's box. Emission is radiance in image units and has no natural
/// upper limit; 1e6 only keeps a diverging run finite (HDR pixels of 1e5 are the largest the fit must handle).
pub const EMISSION_MAX: f64 = 1e6;

/// The metallic from which an object is a metal, its base colour a reflectance at normal incidence rather than
/// a diffuse albedo: the middle of the range, so that a blend belongs to the family it nearly is.
pub const METAL_FROM: f64 = 0.5;

/// Whether metallic `m` makes a metal ([`METAL_FROM`]).
#[inline]
#[must_use]
pub fn is_metal(m: f64) -> bool {
    m >= METAL_FROM
}

/// Index of parameter `p` of object `k`.
#[inline]
#[must_use]
pub fn idx(k: usize, p: usize) -> usize {
    PER_OBJECT * k + p
}

/// The three channels of object k's entry that starts at `at` (`BASE_COLOR`, `EMISSION`, `EMISSION_GROUND`,
/// `EMISSION_ZENITH`) in `x`.
#[must_use]
pub fn rgb(x: &[f64], k: usize, at: usize) -> [f64; 3] {
    std::array::from_fn(|c| x[idx(k, at + c)])
}

/// [`rgb`] in the tracer's precision (f32).
fn rgb_f32(x: &[f64], k: usize, at: usize) -> Vec3 {
    Vec3::from(rgb(x, k, at).map(|v| v as f32))
}

/// Sets the three channels of object k's entry that starts at `at` in `x` to `v`.
pub fn set_rgb(x: &mut [f64], k: usize, at: usize, v: [f64; 3]) {
    x[idx(k, at)..idx(k, at) + 3].copy_from_slice(&v);
}

/// Object k's base colour in `x`.
#[must_use]
pub fn base_color(x: &[f64], k: usize) -> [f64; 3] {
    rgb(x, k, BASE_COLOR)
}

/// Copies object `k`'s material — base colour, roughness, metallic and specular, the entries `BASE_COLOR` to
/// `SPECULAR`, which lie next to each other — from `src` into `dst` (its emission stays).
pub fn copy_material(dst: &mut [f64], src: &[f64], k: usize) {
    let material = idx(k, BASE_COLOR)..=idx(k, SPECULAR);
    dst[material.clone()].copy_from_slice(&src[material]);
}

/// Every object's roughness at the start, which a diffuse object keeps (metallic = specular = 0 is exactly
/// Lambert, whatever the roughness): the middle of its range.
pub const START_ROUGHNESS: f64 = 0.5;

/// The starting point: grey diffuse, roughness [`START_ROUGHNESS`], no emission.
#[must_use]
pub fn initial(objects: usize) -> Vec<f64> {
    let mut x = vec![0.0; PER_OBJECT * objects];
    for k in 0..objects {
        for c in 0..3 {
            x[idx(k, BASE_COLOR + c)] = 0.5;
        }
        x[idx(k, ROUGHNESS)] = START_ROUGHNESS;
    }
    x
}

/// Box domain of every entry: materials in [0, 1], emission in [0, EMISSION_MAX].
#[must_use]
pub fn bounds(objects: usize) -> (Vec<f64>, Vec<f64>) {
    let lo = vec![0.0; PER_OBJECT * objects];
    let mut hi = vec![1.0; PER_OBJECT * objects];
    for k in 0..objects {
        for c in 0..3 {
            hi[idx(k, EMISSION + c)] = EMISSION_MAX;
            hi[idx(k, EMISSION_GROUND + c)] = EMISSION_MAX;
            hi[idx(k, EMISSION_ZENITH + c)] = EMISSION_MAX;
        }
    }
    (lo, hi)
}

/// Which emitters are split at the horizon (model selection's decision, `super::horizon`); their halves are
/// the layout's `EMISSION` (sky) and `EMISSION_GROUND` entries, and the sky half of those with a gradient runs
/// from `EMISSION` (at the horizon) to `EMISSION_ZENITH`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Split {
    /// World up (unit; zero when no split is possible).
    pub up: Vec3,
    /// Per object: split (an object past the end is not).
    pub split: Vec<bool>,
    /// Per object: its sky half varies with elevation (only read for split objects; past the end: does not).
    pub gradient: Vec<bool>,
}

/// No object split: the fit's context until model selection splits any.
pub static NO_SPLIT: Split = Split { up: Vec3::ZERO, split: Vec::new(), gradient: Vec::new() };

impl Split {
    /// True when no object is split.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        !self.split.iter().any(|&s| s)
    }

    /// Whether object k is split.
    #[must_use]
    pub fn of(&self, k: usize) -> bool {
        self.split.get(k).copied().unwrap_or(false)
    }

    /// Whether object k is split and its sky half varies with elevation.
    #[must_use]
    pub fn graded(&self, k: usize) -> bool {
        self.of(k) && self.gradient.get(k).copied().unwrap_or(false)
    }

    /// Splits `split` at `up`, none with a gradient.
    #[must_use]
    pub fn flat(up: Vec3, split: Vec<bool>) -> Self {
        Split { up, split, gradient: Vec::new() }
    }

    /// The tracer's tables of `x`: [`to_params`] with the ground half of every split object appended after
    /// the objects' own emission entries, in object order, then the zenith of every split object with a
    /// gradient, in object order.
    #[must_use]
    pub fn params(&self, x: &[f64]) -> tracer::Params {
        let mut p = to_params(x);
        let n = p.emission.len();
        let entry = |k: usize, at: usize| (k as u32, rgb_f32(x, k, at));
        p.split_at_horizon(self.up, (0..n).filter(|&k| self.of(k)).map(|k| entry(k, EMISSION_GROUND)));
        p.add_zeniths((0..n).filter(|&k| self.graded(k)).map(|k| entry(k, EMISSION_ZENITH)));
        p
    }
}

/// The tracer's parameter tables (material slot k = emitter slot k = object k), no emitter split
/// ([`Split::params`] splits).
#[must_use]
pub fn to_params(x: &[f64]) -> tracer::Params {
    let n = x.len() / PER_OBJECT;
    tracer::Params {
        materials: (0..n)
            .map(|k| tracer::Material {
                base_color: rgb_f32(x, k, BASE_COLOR),
                roughness: x[idx(k, ROUGHNESS)] as f32,
                metallic: x[idx(k, METALLIC)] as f32,
                specular: x[idx(k, SPECULAR)] as f32,
            })
            .collect(),
        emission: (0..n).map(|k| rgb_f32(x, k, EMISSION)).collect(),
        horizon: tracer::params::Horizon::default(),
    }
}

/// The parameter vector of the tracer's tables `p` (the inverse of [`to_params`]; a split emitter's ground half
/// is not read: every other entry starts as [`initial`] has it).
#[must_use]
pub fn from_params(p: &tracer::Params) -> Vec<f64> {
    let mut x = initial(p.materials.len());
    for (k, (m, e)) in p.materials.iter().zip(&p.emission).enumerate() {
        for c in 0..3 {
            x[idx(k, BASE_COLOR + c)] = f64::from(m.base_color[c]);
            x[idx(k, EMISSION + c)] = f64::from(e[c]);
        }
        x[idx(k, ROUGHNESS)] = f64::from(m.roughness);
        x[idx(k, METALLIC)] = f64::from(m.metallic);
        x[idx(k, SPECULAR)] = f64::from(m.specular);
    }
    x
}

/// The tracer's gradient table as a flat vector in the same layout.
#[must_use]
pub fn flatten_grads(g: &tracer::Grads, objects: usize) -> Vec<f64> {
    let mut out = vec![0.0; PER_OBJECT * objects];
    for k in 0..objects {
        if let Some(m) = g.materials.get(k) {
            out[idx(k, BASE_COLOR)] = m.base_color.x;
            out[idx(k, BASE_COLOR + 1)] = m.base_color.y;
            out[idx(k, BASE_COLOR + 2)] = m.base_color.z;
            out[idx(k, ROUGHNESS)] = m.roughness;
            out[idx(k, METALLIC)] = m.metallic;
            out[idx(k, SPECULAR)] = m.specular;
        }
        if let Some(e) = g.emission.get(k) {
            out[idx(k, EMISSION)] = e.x;
            out[idx(k, EMISSION + 1)] = e.y;
            out[idx(k, EMISSION + 2)] = e.z;
        }
    }
    out
}
