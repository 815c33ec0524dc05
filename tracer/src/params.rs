//! The unknowns (material and emission tables), render settings, and the gradient table shaped like them.

use crate::bsdf::{Material, MaterialGrad};
use crate::error::TracerError;
use crate::scene::Scene;
use glam::{DVec3, Vec3};

/// Parameter tables, indexed by `SceneInput::material_of_tri` and `SceneInput::emitter_of_tri`.
/// `emission[i]` is the RGB radiance scale `e` of emitter slot i (see [`EmissionProfile`]); 0 = not a light.
/// Entries past the scene's emitter slots are the ground halves of the slots that [`Horizon`] splits, then the
/// zenith radiances of the split slots whose sky half has a gradient.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Params {
    pub materials: Vec<Material>,
    pub emission: Vec<Vec3>,
    pub horizon: Horizon,
}

/// Emitters whose radiance depends on the side of the horizon it leaves towards: a window pane, through which
/// the room receives the sky from above the horizon (light travelling down) and the ground outside from
/// below it (light travelling up), two radiances that differ by several times in brightness and in colour.
/// A split slot emits `emission[slot]` in the directions ω that point down or level (ω·up ≤ 0, the sky's
/// half) and `emission[ground[slot]]` in those that point up; each half is one emission entry, so radiance
/// stays linear in the emission table and every derivative and basis image is one entry's.
///
/// A split slot may also have a **zenith** entry: its sky half then varies with the elevation of the sky it
/// carries, linearly in the sine of that elevation, s = −ω·up ∈ [0, 1]: L = (1 − s)·`emission[slot]` (the sky
/// at the horizon) + s·`emission[zenith[slot]]` (the sky at the zenith). The CIE standard overcast sky has
/// exactly this form (Moon and Spencer 1942: L ∝ 1 + 2 sin e), and a clear sky's brighter, whiter horizon is
/// its first-order term: the photos see a window's sky within 20° of the horizon, while most of the light it
/// sends onto the floor comes from higher up. A path takes the zenith entry with probability s and the
/// horizon entry otherwise ([`Params::emission_entry`]), so each path still reads one entry, its expected
/// radiance is the blend, and every derivative and basis image stays one entry's (unbiased, and linear in
/// the table for fixed random numbers).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Horizon {
    /// World up, unit length (only read for split slots).
    pub up: Vec3,
    /// `ground[slot]`: the emission entry of the slot's upward half; None, or a slot past the vector's end,
    /// emits one radiance in every direction.
    pub ground: Vec<Option<u32>>,
    /// `zenith[slot]`: the emission entry of a split slot's sky at the zenith; None, or a slot past the
    /// vector's end, has one radiance over its sky half. Absent in tables written before sky gradients.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub zenith: Vec<Option<u32>>,
}

impl Horizon {
    /// The ground entry of `slot`, if the slot is split.
    #[inline]
    #[must_use]
    pub fn ground_of(&self, slot: u32) -> Option<u32> {
        self.ground.get(slot as usize).copied().flatten()
    }

    /// The zenith entry of `slot`, if its sky half has a gradient.
    #[inline]
    #[must_use]
    pub fn zenith_of(&self, slot: u32) -> Option<u32> {
        self.zenith.get(slot as usize).copied().flatten()
    }

    /// How many emission entries the split slots add after the scene's slots (ground halves and zeniths).
    #[must_use]
    pub fn extra_entries(&self) -> usize {
        self.ground.iter().flatten().count() + self.zenith.iter().flatten().count()
    }
}

impl Params {
    /// Checks that the tables cover every index the scene uses.
    pub fn check(&self, scene: &Scene) -> Result<(), TracerError> {
        if self.materials.len() < scene.material_slots() {
            return Err(TracerError::LengthMismatch {
                what: "Params::materials",
                expected: scene.material_slots(),
                got: self.materials.len(),
            });
        }
        if self.emission.len() < scene.emitter_slots() {
            return Err(TracerError::LengthMismatch {
                what: "Params::emission",
                expected: scene.emitter_slots(),
                got: self.emission.len(),
            });
        }
        let slots = scene.emitter_slots();
        let split: Vec<(usize, u32)> =
            self.horizon.ground.iter().enumerate().filter_map(|(s, g)| g.map(|g| (s, g))).collect();
        // 1e-3: a normalised f32 vector is unit to ~1e-7; anything further off was not normalised (NaN is not).
        let unit = (self.horizon.up.length() - 1.0).abs() < 1e-3;
        if !split.is_empty() && !unit {
            return Err(TracerError::BadSetting {
                what: "Params::horizon.up",
                requirement: "a unit vector",
                value: format!("{:?}", self.horizon.up),
            });
        }
        let zenith: Vec<(usize, u32)> =
            self.horizon.zenith.iter().enumerate().filter_map(|(s, z)| z.map(|z| (s, z))).collect();
        let mut used = vec![false; self.emission.len()];
        for &(slot, z) in &zenith {
            // A zenith entry belongs to a split slot's sky half, and is its own parameter like a ground entry.
            let ok = self.horizon.ground_of(slot as u32).is_some() && (z as usize) < self.emission.len();
            if !ok || (z as usize) < slots || std::mem::replace(&mut used[z as usize], true) {
                return Err(TracerError::BadSetting {
                    what: "Params::horizon.zenith",
                    requirement: "for a split slot, an emission entry past the slots owned by no other slot",
                    value: format!("slot {slot} → entry {z} (slots {slots}, entries {})", self.emission.len()),
                });
            }
        }
        for (slot, g) in split {
            // A ground entry is its own parameter: past the slots, within the table, owned by one slot.
            let ok = slot < slots && (g as usize) >= slots && (g as usize) < self.emission.len();
            if !ok || std::mem::replace(&mut used[g as usize], true) {
                return Err(TracerError::BadSetting {
                    what: "Params::horizon.ground",
                    requirement: "for an emitter slot, an emission entry past the slots owned by no other slot",
                    value: format!("slot {slot} → entry {g} (slots {slots}, entries {})", self.emission.len()),
                });
            }
        }
        Ok(())
    }

    /// The emission entry that emitter slot `slot` uses for radiance leaving it in direction `wo` (unit, away
    /// from the surface), with `u` drawing a number uniform in [0, 1) (called only for a graded sky, so paths
    /// that meet none hash nothing): its ground entry when the slot is split and `wo` points up; its zenith
    /// entry with probability s = −wo·up when its sky half has a gradient and `wo` points down ([`Horizon`]);
    /// else the slot's own.
    #[inline]
    #[must_use]
    pub fn emission_entry(&self, slot: u32, wo: Vec3, u: impl FnOnce() -> f32) -> u32 {
        let Some(g) = self.horizon.ground_of(slot) else { return slot };
        let up = wo.dot(self.horizon.up);
        if up > 0.0 {
            return g;
        }
        match self.horizon.zenith_of(slot) {
            Some(z) if u() < -up => z,
            _ => slot,
        }
    }

    /// Gives the sky halves of split slots a gradient: each `(slot, zenith)` of `zeniths` appends `zenith` as
    /// a new emission entry, the slot's sky at the zenith (its own entry becomes its sky at the horizon).
    /// Expects the slots split ([`Params::split_at_horizon`]) and no zenith yet.
    pub fn add_zeniths(&mut self, zeniths: impl IntoIterator<Item = (u32, Vec3)>) {
        let mut zenith = vec![None; self.horizon.ground.len()];
        for (slot, z) in zeniths {
            if let Some(e) = zenith.get_mut(slot as usize) {
                *e = Some(self.emission.len() as u32);
                self.emission.push(z);
            }
        }
        if zenith.iter().any(Option::is_some) {
            self.horizon.zenith = zenith;
        }
    }

    /// Splits emitter slots at the horizon `up`: each `(slot, ground)` of `halves` appends `ground` as a new
    /// emission entry, the slot's upward half (its own entry becomes its sky half). Expects a table with no
    /// split yet, one emission entry per slot; with no halves it stays as it is.
    pub fn split_at_horizon(&mut self, up: Vec3, halves: impl IntoIterator<Item = (u32, Vec3)>) {
        let mut ground = vec![None; self.emission.len()];
        for (slot, half) in halves {
            ground[slot as usize] = Some(self.emission.len() as u32);
            self.emission.push(half);
        }
        if ground.iter().any(Option::is_some) {
            self.horizon = Horizon { up, ground, zenith: Vec::new() };
        }
    }

    /// Per emitter slot (one per entry of `g`, the slots' [`crate::scene::HorizonGeometry`]): the radiance of a
    /// uniform emitter that sends the same flux — [`joined_halves`] of its [`Params::flat_sky`] and ground half
    /// for a split slot, its emission for the others (exact for the uniform profile).
    #[must_use]
    pub fn uniform_emission(&self, g: &crate::scene::HorizonGeometry) -> Vec<Vec3> {
        let sky = &g.sky;
        g.upward
            .iter()
            .enumerate()
            .map(|(slot, &u)| {
                let own = self.emission.get(slot).copied().unwrap_or(Vec3::ZERO);
                match self.horizon.ground_of(slot as u32).and_then(|g| self.emission.get(g as usize)) {
                    Some(&ground) => {
                        let flat = self.flat_sky(slot as u32, sky.get(slot).copied().unwrap_or(0.0));
                        joined_halves(flat, ground.as_dvec3(), u).as_vec3()
                    }
                    None => own,
                }
            })
            .collect()
    }

    /// The one sky radiance of the same flux as emitter slot `slot`'s sky half, whose directions carry a sky of
    /// mean elevation sine `m` ([`crate::scene::HorizonGeometry::sky`]): [`flat_sky`] of its horizon and zenith
    /// entries when its sky has a gradient, else its own entry.
    #[must_use]
    pub fn flat_sky(&self, slot: u32, m: f64) -> DVec3 {
        let own = self.emission.get(slot as usize).copied().unwrap_or(Vec3::ZERO).as_dvec3();
        match self.horizon.zenith_of(slot).and_then(|z| self.emission.get(z as usize)) {
            Some(&zenith) => flat_sky(own, zenith.as_dvec3(), m),
            None => own,
        }
    }

    /// The emitter slot whose radiance emission entry `entry` is: the entry itself, or the split slot whose
    /// ground half or zenith it is (None for an entry past the slots that no slot uses).
    #[must_use]
    pub fn slot_of_entry(&self, entry: u32, slots: usize) -> Option<u32> {
        if (entry as usize) < slots {
            return Some(entry);
        }
        let find = |v: &[Option<u32>]| v.iter().position(|&g| g == Some(entry)).map(|s| s as u32);
        find(&self.horizon.ground).or_else(|| find(&self.horizon.zenith))
    }
}

/// The one radiance of the same flux as the halves `sky` and `ground` of an emitter split at the horizon that
/// sends the share `upward` of its cosine-weighted emission upward: (1 − u)·sky + u·ground.
#[inline]
#[must_use]
pub fn joined_halves(sky: DVec3, ground: DVec3, upward: f64) -> DVec3 {
    (1.0 - upward) * sky + upward * ground
}

/// The one radiance of the same flux as a sky half with a gradient from `horizon` to `zenith` ([`Horizon`])
/// whose directions carry a sky of mean elevation sine `m` (cosine-weighted; 4/(3π) ≈ 0.42 through a vertical
/// pane): (1 − m)·horizon + m·zenith.
#[inline]
#[must_use]
pub fn flat_sky(horizon: DVec3, zenith: DVec3, m: f64) -> DVec3 {
    (1.0 - m) * horizon + m * zenith
}

/// Directional profile of emitted radiance at a front-facing direction with cosine `cos` to the geometric
/// normal; both are zero on the back face (one-sided emitters).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EmissionProfile {
    /// L_e = e: Lambertian emitter, what Mitsuba, Tungsten and pbrt call an area light.
    #[default]
    Uniform,
    /// L_e = e·(i·n)₊, the paper's profile (§4.3).
    Cosine,
}

impl EmissionProfile {
    /// ∂L_e/∂e (the same for every colour channel): L_e = e · factor(cos).
    #[inline]
    #[must_use]
    pub fn factor(self, cos: f32) -> f32 {
        if cos <= 0.0 {
            return 0.0;
        }
        match self {
            EmissionProfile::Uniform => 1.0,
            EmissionProfile::Cosine => cos,
        }
    }
}

/// Path-tracing settings.
///
/// Depth convention (pbrt's): `max_depth` is the largest number of scattering events on a path;
/// 0 = emitters seen directly only, 1 = plus direct illumination, … (Mitsuba's `max_depth` is ours + 1).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TracerSettings {
    pub max_depth: u32,
    /// Russian roulette is applied to the scattering at vertices with depth ≥ `rr_depth`.
    pub rr_depth: u32,
    pub emission_profile: EmissionProfile,
}

/// Depth 8 (that of the default scene's photos, data-fixtures/scenes/demo.toml) with roulette from 3, for the
/// library's own callers and tests. The pipeline's config default is deeper (`tracer.max_depth`,
/// configs/README.md).
impl Default for TracerSettings {
    fn default() -> Self {
        TracerSettings { max_depth: 8, rr_depth: 3, emission_profile: EmissionProfile::Uniform }
    }
}

/// Accumulated derivative of Σ_pixels w·I with respect to one material's parameters.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MaterialGradSum {
    pub base_color: DVec3,
    pub roughness: f64,
    pub metallic: f64,
    pub specular: f64,
}

impl MaterialGradSum {
    /// Adds `c ⊙ ∂f` for a per-channel chain factor `c` (weight ⊙ throughput ⊙ incoming radiance …):
    /// base colour is per channel (diagonal Jacobian), scalar parameters sum over channels.
    #[inline]
    pub fn add_chain(&mut self, d: &MaterialGrad, c: Vec3) {
        self.base_color += (d.d_base_color * c).as_dvec3();
        self.roughness += f64::from((d.d_roughness * c).element_sum());
        self.metallic += f64::from((d.d_metallic * c).element_sum());
        self.specular += f64::from((d.d_specular * c).element_sum());
    }

    pub fn add(&mut self, o: &MaterialGradSum) {
        self.base_color += o.base_color;
        self.roughness += o.roughness;
        self.metallic += o.metallic;
        self.specular += o.specular;
    }
}

/// Gradient table indexed like [`Params`]: `∂(Σ_j w_j · I_j)/∂θ` for the weights the caller passed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Grads {
    pub materials: Vec<MaterialGradSum>,
    pub emission: Vec<DVec3>,
}

impl Grads {
    #[must_use]
    pub fn zeros_like(params: &Params) -> Self {
        Grads {
            materials: vec![MaterialGradSum::default(); params.materials.len()],
            emission: vec![DVec3::ZERO; params.emission.len()],
        }
    }
}
