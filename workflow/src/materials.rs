//! `materials.json`, schema `ipt-materials/1`: the per-object result a user reads and reuses (and
//! `pipeline render --materials` reads back). A compatibility boundary: a field is only ever added as an
//! optional one (files without it read as before); a change of meaning takes a new format tag.
//!
//! ```json
//! {"format": "ipt-materials/1", "emission_profile": "uniform",
//!  "objects": [{"id": 3, "label": "wall", "triangles": 12, "base_color": [0.7, 0.2, 0.2], "roughness": 0.5,
//!               "metallic": 0.0, "specular": 0.0, "emission": [0, 0, 0], "model": "diffuse"}]}
//! ```
//! Written by the fit, each object also carries `"why"` (the evidence for its model) and `"constrained"`
//! (`false`: no photo constrains its material, so its values are start values, not estimates).
//! Values are linear; `emission` is radiance in the units of the input images (the scale `e` of the
//! emission profile: `L_e = e` for `uniform`, `L_e = e (i·n)+` for `cosine`). An emitter the fit split at the
//! horizon (a window pane, `optim::fit::horizon`) also carries
//! `"horizon": {"up": [0, 0, 1], "sky": [..], "ground": [..]}`: it emits `sky` in the directions that point
//! down or level (ω·up ≤ 0) and `ground` in those that point up, and its `emission` is the uniform radiance
//! that sends the same flux (what a renderer without the split, and every mesh export, uses). A split whose
//! sky half varies with elevation also carries `"zenith": [..]`: its sky half is then `sky` at the horizon and
//! `zenith` at the zenith, blended linearly in s = −ω·up (`tracer::params::Horizon`).

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::{Deserialize, Serialize};
use tracer::{EmissionProfile, Material, Params};

/// The format tag.
pub const MATERIALS_FORMAT: &str = "ipt-materials/1";

/// The file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialsFile {
    pub format: String,
    pub emission_profile: EmissionProfile,
    pub objects: Vec<ObjectMaterial>,
}

/// One object's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectMaterial {
    /// Group id of the object in the scan (Matterport `segment_id`, OBJ group index, ...).
    pub id: i64,
    pub label: String,
    /// Number of triangles of the object.
    pub triangles: usize,
    pub base_color: [f32; 3],
    pub roughness: f32,
    pub metallic: f32,
    pub specular: f32,
    pub emission: [f32; 3],
    /// The model the fit chose for the object (e.g. `diffuse`, `specular+emission`).
    pub model: String,
    /// Why the fit chose `model`: the held-out evidence for or against each term. Optional, so
    /// files without it (written by hand, or by earlier versions) still read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub why: Option<String>,
    /// `false` when the photos cannot constrain the object's material (seen by no camera, or in too few
    /// pixels): its values are then the fit's start values, not estimates. Optional like `why`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub constrained: Option<bool>,
    /// The two radiances of an emitter split at the horizon; absent for one radiance in every direction.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub horizon: Option<HorizonEmission>,
}

/// An emitter's radiance on either side of the horizon (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HorizonEmission {
    /// World up, unit length.
    pub up: [f32; 3],
    /// Radiance in the directions with ω·up ≤ 0 (light travelling down or level, as the sky's through a window).
    pub sky: [f32; 3],
    /// Radiance in the directions with ω·up > 0.
    pub ground: [f32; 3],
    /// Radiance straight down (ω·up = −1) when the sky half varies with elevation; `sky` is then its radiance
    /// leaving level. Absent for one sky radiance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zenith: Option<[f32; 3]>,
}

/// Errors reading a materials file or matching it to a scene.
#[derive(Debug, thiserror::Error)]
pub enum MaterialsError {
    #[error("{path}: {source}", path = .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not an ipt-materials/1 file: {message}", path = .path.display())]
    Parse { path: PathBuf, message: String },
    #[error("{path}: object {index} (id {id}): {message}", path = .path.display())]
    Object { path: PathBuf, index: usize, id: i64, message: String },
}

impl HorizonEmission {
    /// The two halves of emitter slot `k` in the tracer's tables, `None` when the slot is not split:
    /// `emission[k]` is its sky half (at the horizon when it has a zenith entry) and the entry `horizon` names
    /// its ground half.
    #[must_use]
    pub fn of_slot(horizon: &tracer::params::Horizon, emission: &[Vec3], k: usize) -> Option<Self> {
        horizon.ground_of(k as u32).map(|g| HorizonEmission {
            up: horizon.up.to_array(),
            sky: emission[k].to_array(),
            ground: emission[g as usize].to_array(),
            zenith: horizon.zenith_of(k as u32).map(|z| emission[z as usize].to_array()),
        })
    }
}

impl ObjectMaterial {
    /// The tracer's material.
    #[must_use]
    pub fn material(&self) -> Material {
        Material {
            base_color: Vec3::from(self.base_color),
            roughness: self.roughness,
            metallic: self.metallic,
            specular: self.specular,
        }
    }

    /// Whether the photos constrain the object's material: `constrained`, and an object that does not say
    /// (a file written by hand, or by an earlier version) counts as constrained.
    #[must_use]
    pub fn is_constrained(&self) -> bool {
        self.constrained.unwrap_or(true)
    }
}

impl MaterialsFile {
    /// Reads and checks a file: the format tag, finite values, parameters in [0, 1], emission ≥ 0.
    pub fn read(path: &Path) -> Result<Self, MaterialsError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| MaterialsError::Io { path: path.to_path_buf(), source })?;
        let file: Self = serde_json::from_str(&text)
            .map_err(|e| MaterialsError::Parse { path: path.to_path_buf(), message: e.to_string() })?;
        if file.format != MATERIALS_FORMAT {
            return Err(MaterialsError::Parse {
                path: path.to_path_buf(),
                message: format!("format is `{}`, expected `{MATERIALS_FORMAT}`", file.format),
            });
        }
        for (index, o) in file.objects.iter().enumerate() {
            let bad = |message: &str| MaterialsError::Object {
                path: path.to_path_buf(),
                index,
                id: o.id,
                message: message.into(),
            };
            let unit = |x: f32| (0.0..=1.0).contains(&x);
            if !(o.base_color.iter().all(|&c| unit(c)) && unit(o.roughness) && unit(o.metallic) && unit(o.specular)) {
                return Err(bad("base_color, roughness, metallic and specular must lie in [0, 1]"));
            }
            if !o.emission.iter().all(|&e| e.is_finite() && e >= 0.0) {
                return Err(bad("emission must be finite and non-negative"));
            }
            if let Some(h) = &o.horizon {
                if !h.sky.iter().chain(&h.ground).chain(h.zenith.iter().flatten()).all(|&e| e.is_finite() && e >= 0.0) {
                    return Err(bad("horizon.sky, horizon.ground and horizon.zenith must be finite and non-negative"));
                }
                // 1e-3: a unit vector written with f32's 9 significant digits is unit to ~1e-7 (NaN is not).
                let unit = (Vec3::from(h.up).length() - 1.0).abs() < 1e-3;
                if !unit {
                    return Err(bad("horizon.up must be a unit vector"));
                }
            }
        }
        let ups: Vec<[f32; 3]> = file.objects.iter().filter_map(|o| o.horizon.map(|h| h.up)).collect();
        if ups.windows(2).any(|w| w[0] != w[1]) {
            return Err(MaterialsError::Parse {
                path: path.to_path_buf(),
                message: "objects split at the horizon give different `horizon.up` vectors".into(),
            });
        }
        Ok(file)
    }

    /// The parameter tables for a scene whose objects have `ids` (material slot i = emitter slot i = object
    /// i), with the emitters split at the horizon split (their ground halves appended after the objects'
    /// entries). Every object must appear in the file; extra entries are ignored.
    pub fn params_for(&self, ids: &[i64], path: &Path) -> Result<Params, MaterialsError> {
        let objects = self.objects_for(ids, path)?;
        let mut params = Params {
            materials: objects.iter().map(|o| o.material()).collect(),
            emission: objects.iter().map(|o| Vec3::from(o.horizon.map_or(o.emission, |h| h.sky))).collect(),
            horizon: Default::default(),
        };
        // Every split object gives the same `up` (`read` checks it).
        let up = objects.iter().find_map(|o| o.horizon).map_or(Vec3::ZERO, |h| Vec3::from(h.up).normalize());
        let halves: Vec<(u32, Vec3)> = objects
            .iter()
            .enumerate()
            .filter_map(|(k, o)| o.horizon.map(|h| (k as u32, Vec3::from(h.ground))))
            .collect();
        params.split_at_horizon(up, halves);
        let zeniths: Vec<(u32, Vec3)> = objects
            .iter()
            .enumerate()
            .filter_map(|(k, o)| o.horizon.and_then(|h| h.zenith).map(|z| (k as u32, Vec3::from(z))))
            .collect();
        params.add_zeniths(zeniths);
        Ok(params)
    }

    /// Per object of `ids`: its `emission`, the uniform radiance (for a split emitter, the one of the same
    /// flux): what the mesh exports carry.
    pub fn uniform_emission_for(&self, ids: &[i64], path: &Path) -> Result<Vec<Vec3>, MaterialsError> {
        Ok(self.objects_for(ids, path)?.iter().map(|o| Vec3::from(o.emission)).collect())
    }

    /// The file's entry of every object of `ids`, in that order.
    fn objects_for(&self, ids: &[i64], path: &Path) -> Result<Vec<&ObjectMaterial>, MaterialsError> {
        ids.iter()
            .enumerate()
            .map(|(index, &id)| {
                self.objects.iter().find(|o| o.id == id).ok_or_else(|| MaterialsError::Object {
                    path: path.to_path_buf(),
                    index,
                    id,
                    message: "the scene has this object but the materials file does not".into(),
                })
            })
            .collect()
    }
}

/// One object of a `materials.json` as the fit writes it, for the crate's tests: label `o{id}`, one triangle, base
/// colour 0.1, roughness 0.3, no lobe, no emission, `why` = `why {id}`.
#[cfg(test)]
pub(crate) fn test_object(id: i64, model: &str, constrained: Option<bool>) -> ObjectMaterial {
    ObjectMaterial {
        id,
        label: format!("o{id}"),
        triangles: 1,
        base_color: [0.1; 3],
        roughness: 0.3,
        metallic: 0.0,
        specular: 0.0,
        emission: [0.0; 3],
        model: model.into(),
        why: Some(format!("why {id}")),
        constrained,
        horizon: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> MaterialsFile {
        MaterialsFile {
            format: MATERIALS_FORMAT.into(),
            emission_profile: EmissionProfile::Uniform,
            objects: vec![ObjectMaterial {
                id: 7,
                label: "lamp".into(),
                triangles: 2,
                base_color: [0.5, 0.25, 0.125],
                roughness: 0.5,
                metallic: 0.0,
                specular: 0.5,
                emission: [10.0, 9.0, 8.0],
                model: "diffuse+emission".into(),
                why: None,
                constrained: None,
                horizon: None,
            }],
        }
    }

    #[test]
    fn json_has_exactly_the_documented_keys_and_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.json");
        std::fs::write(&path, serde_json::to_string(&sample()).unwrap()).unwrap();
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let mut top: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
        top.sort_unstable();
        assert_eq!(top, ["emission_profile", "format", "objects"]);
        assert_eq!(v["emission_profile"], "uniform");
        let mut keys: Vec<&str> = v["objects"][0].as_object().unwrap().keys().map(String::as_str).collect();
        keys.sort_unstable();
        assert_eq!(
            keys,
            ["base_color", "emission", "id", "label", "metallic", "model", "roughness", "specular", "triangles"]
        );
        assert_eq!(MaterialsFile::read(&path).unwrap(), sample());
    }

    #[test]
    fn out_of_domain_values_and_missing_objects_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.json");
        let mut m = sample();
        m.objects[0].roughness = 1.5;
        std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
        let e = MaterialsFile::read(&path).unwrap_err();
        assert!(e.to_string().contains("id 7"), "{e}");
        let e = sample().params_for(&[7, 8], &path).unwrap_err();
        assert!(matches!(e, MaterialsError::Object { index: 1, id: 8, .. }), "{e}");
        let p = sample().params_for(&[7], &path).unwrap();
        assert_eq!(p.emission, [Vec3::new(10.0, 9.0, 8.0)]);
        assert_eq!(p.materials[0].base_color, Vec3::new(0.5, 0.25, 0.125));
    }

    #[test]
    fn an_emitter_split_at_the_horizon_reads_back_as_two_entries() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.json");
        let mut m = sample();
        m.objects.push(ObjectMaterial { id: 9, label: "window".into(), ..m.objects[0].clone() });
        m.objects[1].emission = [2.0, 2.0, 2.0];
        m.objects[1].horizon =
            Some(HorizonEmission { up: [0.0, 0.0, 1.0], sky: [3.0, 3.0, 3.0], ground: [1.0, 1.0, 1.0], zenith: None });
        std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        assert_eq!(v["objects"][1]["horizon"]["ground"], serde_json::json!([1.0, 1.0, 1.0]));
        assert!(v["objects"][0].get("horizon").is_none());
        let read = MaterialsFile::read(&path).unwrap();
        assert_eq!(read, m);
        // The tracer's tables: the sky half in the object's own entry, the ground half appended.
        let p = read.params_for(&[9, 7], &path).unwrap();
        assert_eq!(p.emission, [Vec3::splat(3.0), Vec3::new(10.0, 9.0, 8.0), Vec3::splat(1.0)]);
        assert_eq!(p.horizon.ground, [Some(2), None]);
        assert_eq!(p.horizon.up, Vec3::Z);
        assert_eq!(read.uniform_emission_for(&[9], &path).unwrap(), [Vec3::splat(2.0)]);
        // A horizon whose up is not a unit vector is refused, naming the object.
        m.objects[1].horizon =
            Some(HorizonEmission { up: [0.0, 0.0, 2.0], sky: [3.0; 3], ground: [1.0; 3], zenith: None });
        std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
        let e = MaterialsFile::read(&path).unwrap_err();
        assert!(e.to_string().contains("id 9") && e.to_string().contains("horizon.up"), "{e}");
    }

    #[test]
    fn a_graded_sky_reads_back_with_its_zenith_after_the_ground_halves() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.json");
        let mut m = sample();
        m.objects.push(ObjectMaterial { id: 9, label: "window".into(), ..m.objects[0].clone() });
        let graded = HorizonEmission { up: [0.0, 0.0, 1.0], sky: [3.0; 3], ground: [1.0; 3], zenith: Some([0.5; 3]) };
        m.objects[1].horizon = Some(graded);
        std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
        let read = MaterialsFile::read(&path).unwrap();
        assert_eq!(read, m);
        // Objects [9, 7]: the sky at the horizon in object 9's own entry, then its ground half, then its zenith.
        let p = read.params_for(&[9, 7], &path).unwrap();
        assert_eq!(p.emission, [Vec3::splat(3.0), Vec3::new(10.0, 9.0, 8.0), Vec3::splat(1.0), Vec3::splat(0.5)]);
        assert_eq!(
            (p.horizon.ground.as_slice(), p.horizon.zenith.as_slice()),
            ([Some(2), None].as_slice(), [Some(3), None].as_slice())
        );
        // And back: the slot's halves as written.
        assert_eq!(HorizonEmission::of_slot(&p.horizon, &p.emission, 0), Some(graded));
        // A negative zenith is refused, naming the object.
        m.objects[1].horizon = Some(HorizonEmission { zenith: Some([-1.0, 0.5, 0.5]), ..graded });
        std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
        let e = MaterialsFile::read(&path).unwrap_err();
        assert!(e.to_string().contains("id 9") && e.to_string().contains("horizon.zenith"), "{e}");
    }
}
