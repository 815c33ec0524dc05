//! Quality presets: the top-level config key `quality = "preview" | "balanced" | "final"` stands for a set of
//! `[object]` and `[images]` values, chosen from the measured speed/accuracy front of `lab bench tradeoff`
//! (docs/tradeoff/). A preset only fills keys the user did not write: any key given in the file or by `--set`
//! wins over the preset's value. No preset sets the path depth: a fit whose paths stop before the photos' light
//! does is biased whatever its budgets, so every preset keeps `tracer.max_depth` at its default
//! ([`crate::config::DEFAULT_MAX_DEPTH`]).
//!
//! The preset is applied to the TOML table before it is deserialised ([`apply`], called by
//! [`crate::config::parse`]), so the resolved plan — and every stage manifest — holds the effective values.

use serde::{Deserialize, Serialize};

/// A named point of the measured speed/accuracy front.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quality {
    /// A usable answer in seconds.
    Preview,
    /// Close to the best accuracy at a fraction of its time.
    Balanced,
    /// The most accurate point measured.
    Final,
}

/// The value of one preset key.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PresetValue {
    Int(i64),
    Bool(bool),
}

impl PresetValue {
    fn to_toml(self) -> toml::Value {
        match self {
            PresetValue::Int(i) => toml::Value::Integer(i),
            PresetValue::Bool(b) => toml::Value::Boolean(b),
        }
    }
}

impl Quality {
    /// Every preset, fastest first.
    pub const ALL: [Quality; 3] = [Quality::Preview, Quality::Balanced, Quality::Final];

    /// The name written in the config.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Quality::Preview => "preview",
            Quality::Balanced => "balanced",
            Quality::Final => "final",
        }
    }

    /// The dotted config keys the preset sets, with their values. Every value is a point of the front
    /// measured by `lab bench tradeoff` (docs/tradeoff/summary.md names the sweep row of each).
    #[must_use]
    pub fn values(self) -> &'static [(&'static str, PresetValue)] {
        use PresetValue::{Bool, Int};
        match self {
            // Sweep point `corner:fast-depth8` (its measured time and accuracy: configs/README.md, presets).
            Quality::Preview => &[
                ("object.iterations", Int(25)),
                ("object.n_value", Int(32)),
                ("object.solve_pixels", Int(256)),
                ("object.solve_spp", Int(64)),
                ("object.refine_steps", Int(4)),
                ("object.holdout_spp", Int(64)),
                ("object.try_specular", Bool(false)),
                ("images.downscale", Int(2)),
            ],
            // Sweep point `corner:mid` (measured: configs/README.md, presets).
            Quality::Balanced => &[
                ("object.iterations", Int(50)),
                ("object.n_value", Int(128)),
                ("object.solve_pixels", Int(512)),
                ("object.solve_spp", Int(128)),
                ("object.refine_steps", Int(8)),
                ("object.holdout_spp", Int(256)),
                ("object.try_specular", Bool(true)),
                ("images.downscale", Int(1)),
            ],
            // Sweep point `default`: the fit's defaults, written out (measured: configs/README.md, presets).
            Quality::Final => &[
                ("object.iterations", Int(100)),
                ("object.n_value", Int(128)),
                ("object.solve_pixels", Int(1024)),
                ("object.solve_spp", Int(128)),
                ("object.refine_steps", Int(8)),
                ("object.holdout_spp", Int(128)),
                ("object.try_specular", Bool(true)),
                ("images.downscale", Int(1)),
            ],
        }
    }
}

impl std::str::FromStr for Quality {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Quality::ALL.into_iter().find(|q| q.name() == s).ok_or_else(|| {
            let names: Vec<&str> = Quality::ALL.iter().map(|q| q.name()).collect();
            format!("unknown quality `{s}`, expected one of {}", names.join(", "))
        })
    }
}

/// Reads the top-level `quality` key of a config table (after `--set` overrides) and inserts the preset's
/// values for every key the table does not already hold. Returns the preset, if any; the error message is
/// about the key `quality` (wrong type or unknown name), or names a section that is not a table.
pub fn apply(table: &mut toml::Table) -> Result<Option<Quality>, (String, String)> {
    let Some(value) = table.get("quality") else {
        return Ok(None);
    };
    let name = value
        .as_str()
        .ok_or_else(|| ("quality".to_owned(), format!("expected a string, found {}", value.type_str())))?;
    let quality: Quality = name.parse().map_err(|m| ("quality".to_owned(), m))?;
    for (key, v) in quality.values() {
        let (section, field) = key.split_once('.').unwrap_or(("", key));
        let entry = table.entry(section.to_owned()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let Some(sub) = entry.as_table_mut() else {
            return Err((section.to_owned(), "expected a table".to_owned()));
        };
        sub.entry(field.to_owned()).or_insert_with(|| v.to_toml());
    }
    Ok(Some(quality))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for q in Quality::ALL {
            assert_eq!(q.name().parse::<Quality>().unwrap(), q);
        }
        assert!("fast".parse::<Quality>().unwrap_err().contains("preview, balanced, final"));
    }

    #[test]
    fn preset_fills_only_missing_keys() {
        let mut t: toml::Table = "quality = \"preview\"\n[object]\nn_value = 7\n".parse().unwrap();
        assert_eq!(apply(&mut t).unwrap(), Some(Quality::Preview));
        assert_eq!(t["object"]["n_value"].as_integer(), Some(7));
        assert_eq!(t["object"]["iterations"].as_integer(), Some(25));
        assert_eq!(t["images"]["downscale"].as_integer(), Some(2));
    }

    #[test]
    fn wrong_type_and_unknown_name_are_errors_about_quality() {
        let mut t: toml::Table = "quality = 3\n".parse().unwrap();
        assert_eq!(apply(&mut t).unwrap_err().0, "quality");
        let mut t: toml::Table = "quality = \"ultra\"\n".parse().unwrap();
        let (key, msg) = apply(&mut t).unwrap_err();
        assert_eq!(key, "quality");
        assert!(msg.contains("ultra"), "{msg}");
    }

    #[test]
    fn presets_are_ordered_by_work() {
        // Each preset traces at least as many solve paths as the one before it.
        let work = |q: Quality| {
            let get = |k: &str| match q.values().iter().find(|(n, _)| *n == k).map(|(_, v)| *v) {
                Some(PresetValue::Int(i)) => i,
                _ => panic!("{k} missing in {}", q.name()),
            };
            get("object.solve_pixels") * get("object.solve_spp") * get("object.refine_steps")
                / (get("images.downscale") * get("images.downscale"))
        };
        assert!(work(Quality::Preview) < work(Quality::Balanced));
        assert!(work(Quality::Balanced) < work(Quality::Final));
    }
}
