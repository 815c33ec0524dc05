//! The `preprocess` stage's artefacts (`crate::stages::preprocess` writes them) and their reader, [`Prepared`].
//!
//! In `output.path/preprocess/`: `<view>.exr` + `<view>.json` per view (ingest's photo cache: R, G, B, mask
//! and the prepared pinhole camera) and `views.json` = `{"format": "ipt-views/1", "views": [names in order]}`,
//! the order every later stage uses for view indices.

use std::path::Path;

use ingest::photo::LinearImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::stage_contract::StageError;

/// The view list's file name.
pub const VIEWS_FILE: &str = "views.json";
/// Format tag of `views.json`.
pub const VIEWS_FORMAT: &str = "ipt-views/1";

/// `views.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewList {
    pub format: String,
    pub views: Vec<String>,
}

/// The prepared views as later stages read them.
#[derive(Debug, Clone, PartialEq)]
pub struct Prepared {
    pub names: Vec<String>,
    pub cameras: Vec<ingest::camera::Camera>,
    pub images: Vec<LinearImage>,
}

impl Prepared {
    /// Reads `run_dir/preprocess/`.
    pub fn read(run_dir: &Path) -> Result<Self, StageError> {
        let dir = run_dir.join("preprocess");
        let list_path = dir.join(VIEWS_FILE);
        let text =
            std::fs::read_to_string(&list_path).map_err(|source| StageError::Io { path: list_path.clone(), source })?;
        let list: ViewList = serde_json::from_str(&text)
            .map_err(|e| StageError::Artefact { path: list_path.clone(), message: e.to_string() })?;
        if list.format != VIEWS_FORMAT {
            return Err(StageError::Artefact { path: list_path, message: format!("format is not `{VIEWS_FORMAT}`") });
        }
        let loaded: Vec<(ingest::camera::Camera, LinearImage)> = list
            .views
            .par_iter()
            .map(|name| ingest::photo::read_cached(&dir, name).map_err(StageError::from))
            .collect::<Result<_, _>>()?;
        let (cameras, images) = loaded.into_iter().unzip();
        Ok(Self { names: list.views, cameras, images })
    }

    /// The prepared cameras as the tracer's.
    #[must_use]
    pub fn tracer_cameras(&self) -> Vec<tracer::Camera> {
        self.cameras.iter().map(super::ingest::tracer_camera).collect()
    }
}
