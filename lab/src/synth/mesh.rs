//! Triangulates a [`SceneDesc`](super::desc::SceneDesc) into one mesh with per-face object indices.

use super::desc::{ObjectSpec, Shape};
use glam::Vec3;

/// A flat-shaded triangle mesh; `object_of_tri[t]` indexes the description's object list.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SynthMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub object_of_tri: Vec<u32>,
}

impl SynthMesh {
    /// Appends an n×n grid over the parallelogram `corner + s·u + t·v` with front face `u × v`
    /// (counter-clockwise winding seen from the front, the tracer's convention).
    pub(crate) fn push_quad(&mut self, corner: Vec3, u: Vec3, v: Vec3, n: u32, object: u32) {
        let normal = u.cross(v).normalize_or_zero();
        let base = self.positions.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                let (s, t) = (i as f32 / n as f32, j as f32 / n as f32);
                self.positions.push(corner + s * u + t * v);
                self.normals.push(normal);
            }
        }
        let row = n + 1;
        for j in 0..n {
            for i in 0..n {
                let a = base + j * row + i;
                let (b, c, d) = (a + 1, a + row + 1, a + row);
                self.triangles.push([a, b, c]);
                self.triangles.push([a, c, d]);
                self.object_of_tri.extend([object, object]);
            }
        }
    }

    /// Appends one object's faces.
    pub fn push_object(&mut self, spec: &ObjectSpec, object: u32) {
        let n = spec.subdivisions.max(1);
        match spec.shape {
            Shape::Quad { corner, u, v } => self.push_quad(corner.into(), u.into(), v.into(), n, object),
            Shape::Box { min, max } => {
                let (lo, hi) = (Vec3::from(min), Vec3::from(max));
                let d = hi - lo;
                let (x, y, z) = (Vec3::new(d.x, 0.0, 0.0), Vec3::new(0.0, d.y, 0.0), Vec3::new(0.0, 0.0, d.z));
                // Each face: corner and two edges ordered so that u × v points out of the box.
                let faces = [
                    (lo, y, x),     // bottom, −z
                    (lo + z, x, y), // top, +z
                    (lo, x, z),     // front, −y
                    (lo + y, z, x), // back, +y
                    (lo, z, y),     // left, −x
                    (lo + x, y, z), // right, +x
                ];
                for (c, u, v) in faces {
                    self.push_quad(c, u, v, n, object);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(shape: Shape) -> ObjectSpec {
        ObjectSpec {
            id: 1,
            label: "x".into(),
            category_id: 0,
            shape,
            subdivisions: 2,
            base_color: [0.5; 3],
            roughness: 0.5,
            metallic: 0.0,
            specular: 0.0,
            emission: [0.0; 3],
            emission_ground: None,
            hidden: false,
            checker: None,
        }
    }

    #[test]
    fn box_faces_point_outwards_and_cover_the_surface_area() {
        let mut m = SynthMesh::default();
        m.push_object(&spec(Shape::Box { min: [0.0; 3], max: [1.0, 2.0, 3.0] }), 0);
        assert_eq!(m.triangles.len(), 6 * 2 * 4);
        let centre = Vec3::new(0.5, 1.0, 1.5);
        let mut area = 0.0;
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let cr = (b - a).cross(c - a);
            area += 0.5 * cr.length();
            // Winding normal points away from the centre.
            assert!(cr.dot((a + b + c) / 3.0 - centre) > 0.0);
        }
        assert!((area - 2.0 * (2.0 + 3.0 + 6.0)).abs() < 1e-4);
    }

    #[test]
    fn quad_winding_matches_u_cross_v() {
        let mut m = SynthMesh::default();
        m.push_object(&spec(Shape::Quad { corner: [0.0; 3], u: [1.0, 0.0, 0.0], v: [0.0, 1.0, 0.0] }), 3);
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            assert!((b - a).cross(c - a).z > 0.0);
        }
        assert!(m.object_of_tri.iter().all(|&o| o == 3));
    }
}
