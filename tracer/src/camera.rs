//! Pinhole camera in the Matterport/OpenGL convention: the camera looks down its −z axis, +x right, +y up;
//! image rows grow downwards. Pixel centres are at integer coordinates: pixel (i, j) spans
//! [i − ½, i + ½] × [j − ½, j + ½] and the ray through image point (u, v) has camera-space direction
//! ((u − cx)/fx, −(v − cy)/fy, −1).

use glam::{Affine3A, Vec2, Vec3};

/// Intrinsics (pixels) and pose (camera → world, rigid) of one view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub cam_to_world: Affine3A,
}

impl Camera {
    /// Camera with a vertical field of view `fov_y` (radians) and the principal point at the image centre
    /// in the integer-centre convention (cx = (width − 1)/2).
    #[must_use]
    pub fn from_fov_y(width: u32, height: u32, fov_y: f32, cam_to_world: Affine3A) -> Self {
        let f = 0.5 * height as f32 / (0.5 * fov_y).tan();
        Camera {
            width,
            height,
            fx: f,
            fy: f,
            cx: 0.5 * (width as f32 - 1.0),
            cy: 0.5 * (height as f32 - 1.0),
            cam_to_world,
        }
    }

    /// World-space origin and unit direction of the ray through image point `uv` (pixel units).
    #[must_use]
    pub fn ray(&self, uv: Vec2) -> (Vec3, Vec3) {
        let d_cam = Vec3::new((uv.x - self.cx) / self.fx, -(uv.y - self.cy) / self.fy, -1.0);
        let d = self.cam_to_world.transform_vector3(d_cam).normalize();
        (self.cam_to_world.translation.into(), d)
    }

    /// The jittered image point in pixel (x, y) for two uniform numbers in [0, 1).
    #[inline]
    #[must_use]
    pub fn jitter(x: u32, y: u32, u: Vec2) -> Vec2 {
        Vec2::new(x as f32 + u.x - 0.5, y as f32 + u.y - 0.5)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn principal_point_looks_down_minus_z_and_axes_follow_the_convention() {
        let c = Camera::from_fov_y(5, 3, 1.0, Affine3A::from_translation(Vec3::new(1.0, 2.0, 3.0)));
        let (o, d) = c.ray(Vec2::new(2.0, 1.0));
        assert_eq!(o, Vec3::new(1.0, 2.0, 3.0));
        assert!((d - Vec3::NEG_Z).length() < 1e-6);
        let (_, right) = c.ray(Vec2::new(4.0, 1.0));
        let (_, up) = c.ray(Vec2::new(2.0, 0.0));
        assert!(right.x > 0.0 && up.y > 0.0);
        // Top edge of the image (v = -0.5) is at half the vertical fov.
        let (_, top) = c.ray(Vec2::new(2.0, -0.5));
        assert!((top.y.atan2(-top.z) - 0.5).abs() < 1e-5);
    }
}
