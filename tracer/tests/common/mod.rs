//! Small analytic scenes shared by the integration tests.
#![allow(dead_code)]

use glam::{Affine3A, Vec3};
use tracer::{Camera, SceneInput};

/// Appends the quad p0 p1 p2 p3 (counter-clockwise seen from its front) as two triangles.
pub fn add_quad(input: &mut SceneInput, p: [Vec3; 4], material: u32, emitter: u32) {
    let base = input.positions.len() as u32;
    input.positions.extend_from_slice(&p);
    input.triangles.push([base, base + 1, base + 2]);
    input.triangles.push([base, base + 2, base + 3]);
    input.material_of_tri.extend([material, material]);
    input.emitter_of_tri.extend([emitter, emitter]);
}

/// Axis-aligned box `[lo, hi]`; faces front-facing towards the inside when `inward`, else outside.
pub fn add_box(input: &mut SceneInput, lo: Vec3, hi: Vec3, inward: bool, material: u32, emitter: u32) {
    let c = |x: bool, y: bool, z: bool| {
        Vec3::new(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
    };
    // Each face listed counter-clockwise seen from outside.
    let faces = [
        [c(true, false, false), c(true, true, false), c(true, true, true), c(true, false, true)], // +x
        [c(false, false, false), c(false, false, true), c(false, true, true), c(false, true, false)], // -x
        [c(false, true, false), c(false, true, true), c(true, true, true), c(true, true, false)], // +y
        [c(false, false, false), c(true, false, false), c(true, false, true), c(false, false, true)], // -y
        [c(false, false, true), c(true, false, true), c(true, true, true), c(false, true, true)], // +z
        [c(false, false, false), c(false, true, false), c(true, true, false), c(true, false, false)], // -z
    ];
    for mut f in faces {
        if inward {
            f.reverse();
        }
        add_quad(input, f, material, emitter);
    }
}

/// A square camera at `eye` looking at `target` with +y up.
pub fn look_at_camera(size: u32, fov_y_deg: f32, eye: Vec3, target: Vec3) -> Camera {
    let view = glam::Mat4::look_at_rh(eye, target, Vec3::Y);
    let cam_to_world = Affine3A::from_mat4(view.inverse());
    Camera::from_fov_y(size, size, fov_y_deg.to_radians(), cam_to_world)
}

/// Mean and standard error of the mean.
pub fn mean_se(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// A small closed room: floor (material 0), ceiling (1), walls (2), a light quad under the ceiling
/// (material 1, emitter 1), an inner box (material 3, outward), and every other surface on emitter 2
/// (floor) or 0 (the rest). Materials: 4 slots, emitters: 3 slots.
pub fn small_room() -> SceneInput {
    let mut s = SceneInput::default();
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    // Floor y = -1, facing +y (counter-clockwise seen from above).
    add_quad(&mut s, [v(-1.0, -1.0, -1.0), v(-1.0, -1.0, 1.0), v(1.0, -1.0, 1.0), v(1.0, -1.0, -1.0)], 0, 2);
    // Ceiling y = 1, facing −y.
    add_quad(&mut s, [v(-1.0, 1.0, -1.0), v(1.0, 1.0, -1.0), v(1.0, 1.0, 1.0), v(-1.0, 1.0, 1.0)], 1, 0);
    // Walls x = ±1, z = ±1, facing inwards.
    add_quad(&mut s, [v(-1.0, -1.0, -1.0), v(-1.0, 1.0, -1.0), v(-1.0, 1.0, 1.0), v(-1.0, -1.0, 1.0)], 2, 0);
    add_quad(&mut s, [v(1.0, -1.0, -1.0), v(1.0, -1.0, 1.0), v(1.0, 1.0, 1.0), v(1.0, 1.0, -1.0)], 2, 0);
    add_quad(&mut s, [v(-1.0, -1.0, -1.0), v(1.0, -1.0, -1.0), v(1.0, 1.0, -1.0), v(-1.0, 1.0, -1.0)], 2, 0);
    add_quad(&mut s, [v(-1.0, -1.0, 1.0), v(-1.0, 1.0, 1.0), v(1.0, 1.0, 1.0), v(1.0, -1.0, 1.0)], 2, 0);
    // Light: 0.8 × 0.8 quad at y = 0.98 facing down.
    let l = 0.4;
    add_quad(&mut s, [v(-l, 0.98, -l), v(l, 0.98, -l), v(l, 0.98, l), v(-l, 0.98, l)], 1, 1);
    add_box(&mut s, v(-0.5, -1.0, -0.6), v(0.1, -0.3, 0.0), false, 3, 0);
    s
}

pub mod mitsuba_xml;

/// `<workspace>/../shared/data`, where third-party reference data lives (may be absent).
pub fn shared_data() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
}

/// Box-downsamples a row-major RGB image by an integer factor.
pub fn downsample(img: &[Vec3], width: usize, height: usize, factor: usize) -> Vec<Vec3> {
    let (w, h) = (width / factor, height / factor);
    let mut out = vec![Vec3::ZERO; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = glam::DVec3::ZERO;
            for dy in 0..factor {
                for dx in 0..factor {
                    s += img[(y * factor + dy) * width + x * factor + dx].as_dvec3();
                }
            }
            out[y * w + x] = (s / (factor * factor) as f64).as_vec3();
        }
    }
    out
}

/// Per-channel means of an image.
pub fn channel_means(img: &[Vec3]) -> glam::DVec3 {
    img.iter().map(|c| c.as_dvec3()).sum::<glam::DVec3>() / img.len() as f64
}

/// Mean absolute difference over all pixels and channels.
pub fn mean_abs_diff(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| f64::from((*x - *y).abs().element_sum())).sum::<f64>() / (3 * a.len()) as f64
}
