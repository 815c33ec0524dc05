//! Cameras: pinhole intrinsics, an optional OpenCV-style lens distortion, and a camera-to-world pose.
//!
//! **Conventions (one for the whole workspace).**
//! - Pose: `cam_to_world` maps camera coordinates to world coordinates, camera frame OpenGL-style as in
//!   Matterport's `.conf`: the camera looks along −z, +y is up, +x is right. World: right-handed, metres.
//! - Pixels: (u, v) from the top-left corner, v down, **pixel centres at integer coordinates** (OpenCV and
//!   Matterport). COLMAP puts centres at +0.5; its readers subtract 0.5 from cx, cy.
//! - The ray through pixel (u, v) of an undistorted camera is, in camera coordinates,
//!   `((u - cx)/fx, -(v - cy)/fy, -1)`.
//! - Distortion acts on normalised OpenCV coordinates (x right, y down, z forward) = `(X/Z, Y/Z)` with
//!   `(X, Y, Z) = (x_gl, -y_gl, -z_gl)`.

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec2, DVec3};
use serde::{Deserialize, Serialize};

use crate::error::IngestError;

/// Pinhole intrinsics in pixels (pixel centres at integer coordinates).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// OpenCV lens distortion coefficients in OpenCV order. Unused coefficients are zero; `k4..k6` form the
/// denominator of the rational model (COLMAP FULL_OPENCV). SIMPLE_RADIAL/RADIAL/OPENCV/Matterport raw
/// intrinsics are special cases.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
    pub k4: f64,
    pub k5: f64,
    pub k6: f64,
}

impl Distortion {
    /// True when every coefficient is zero (a pinhole camera).
    #[must_use]
    pub fn is_identity(&self) -> bool {
        self.coefficients().iter().all(|&c| c == 0.0)
    }

    /// The coefficients in OpenCV's `distCoeffs` order (k1, k2, p1, p2, k3, k4, k5, k6).
    #[must_use]
    pub fn coefficients(&self) -> [f64; 8] {
        [self.k1, self.k2, self.p1, self.p2, self.k3, self.k4, self.k5, self.k6]
    }

    /// Applies the distortion to normalised OpenCV coordinates (OpenCV's `projectPoints` model).
    #[must_use]
    pub fn distort(&self, p: DVec2) -> DVec2 {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let r4 = r2 * r2;
        let r6 = r4 * r2;
        let radial =
            (1.0 + self.k1 * r2 + self.k2 * r4 + self.k3 * r6) / (1.0 + self.k4 * r2 + self.k5 * r4 + self.k6 * r6);
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        DVec2::new(xd, yd)
    }
}

/// One calibrated camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    pub distortion: Distortion,
    /// Camera-to-world, OpenGL camera frame (see module docs). Rigid: orthonormal rotation, last row 0 0 0 1.
    pub cam_to_world: DMat4,
}

impl Camera {
    /// Projects a point given in OpenCV camera coordinates (z forward) to pixel coordinates, with distortion.
    /// `None` for points at or behind the camera plane.
    #[must_use]
    pub fn project_opencv(&self, p: DVec3) -> Option<DVec2> {
        if p.z <= 0.0 {
            return None;
        }
        let d = self.distortion.distort(DVec2::new(p.x / p.z, p.y / p.z));
        let k = &self.intrinsics;
        Some(DVec2::new(k.fx * d.x + k.cx, k.fy * d.y + k.cy))
    }

    /// Projects a world point to pixel coordinates (with distortion), `None` behind the camera.
    #[must_use]
    pub fn project_world(&self, p: DVec3) -> Option<DVec2> {
        let c = self.cam_to_world.inverse().transform_point3(p);
        self.project_opencv(DVec3::new(c.x, -c.y, -c.z))
    }
}

/// One photo and the camera that took it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct View {
    /// Stable name (the image file stem).
    pub name: String,
    /// The image to use: a linear `.exr`/`.hdr` sibling when one exists, else the listed file.
    pub image_path: PathBuf,
    pub camera: Camera,
}

/// Refuses two views with the same name: a view's name (its image's file stem) keys its cached photo and its
/// results, so a duplicate would silently overwrite the other view's data. `listed_in` is the camera file.
pub(crate) fn check_unique_names(views: &[View], listed_in: &Path) -> Result<(), IngestError> {
    let mut seen: std::collections::HashMap<&str, &Path> = std::collections::HashMap::with_capacity(views.len());
    for v in views {
        if let Some(first) = seen.insert(&v.name, &v.image_path) {
            return Err(IngestError::format(
                listed_in,
                format!(
                    "images {} and {} share the view name {:?} (their file stem), which must be unique",
                    first.display(),
                    v.image_path.display(),
                    v.name
                ),
            ));
        }
    }
    Ok(())
}
