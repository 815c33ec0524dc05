//! Subdivision geometry: the refined mesh stays conforming (closed meshes stay closed, no T-junctions, also
//! across objects and across duplicated boundary vertices), area is preserved per parent, parents are right,
//! orientation is kept, the size limits hold, and objects away from the marks are untouched.

use std::collections::HashMap;

use glam::{DVec3, Vec3};
use optim::subdivide::{SplitKind, SplitLimits, SubdivideError, SubdivideMesh, Subdivided, subdivide};

/// SplitMix64: seeded, reproducible marks without a rand dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// A closed cube [0, 2]³, each face a `k × k` grid of quads (2 triangles each), vertices shared across faces,
/// outward winding; object id = face index (6 objects). Coordinates are multiples of 2/k, dyadic for k a power
/// of two, so midpoints of a few rounds are exact in f32.
fn cube(k: u32) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<i32>) {
    let mut index: HashMap<[i64; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut tris = Vec::new();
    let mut ids = Vec::new();
    let mut vid = |p: [i64; 3], positions: &mut Vec<Vec3>| {
        *index.entry(p).or_insert_with(|| {
            positions.push(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) * (2.0 / k as f32));
            (positions.len() - 1) as u32
        })
    };
    let k = i64::from(k);
    // (axis, side): the face normal is ±axis; u, v axes chosen so (u × v) points outward.
    let faces = [(0, 1), (0, 0), (1, 1), (1, 0), (2, 1), (2, 0)];
    for (f, &(axis, side)) in faces.iter().enumerate() {
        let (u_ax, v_ax) = ((axis + 1) % 3, (axis + 2) % 3);
        for i in 0..k {
            for j in 0..k {
                let corner = |di: i64, dj: i64| {
                    let mut p = [0; 3];
                    p[axis] = side * k;
                    p[u_ax] = i + di;
                    p[v_ax] = j + dj;
                    p
                };
                let q = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)].map(|c| vid(c, &mut positions));
                let (a, b) = if side == 1 {
                    ([q[0], q[1], q[2]], [q[0], q[2], q[3]])
                } else {
                    ([q[0], q[2], q[1]], [q[0], q[3], q[2]])
                };
                tris.push(a);
                tris.push(b);
                ids.extend([f as i32, f as i32]);
            }
        }
    }
    (positions, tris, ids)
}

fn dv(p: Vec3) -> DVec3 {
    p.as_dvec3()
}

fn area(p: &[Vec3], t: [u32; 3]) -> f64 {
    0.5 * (dv(p[t[1] as usize]) - dv(p[t[0] as usize])).cross(dv(p[t[2] as usize]) - dv(p[t[0] as usize])).length()
}

fn normal(p: &[Vec3], t: [u32; 3]) -> DVec3 {
    (dv(p[t[1] as usize]) - dv(p[t[0] as usize])).cross(dv(p[t[2] as usize]) - dv(p[t[0] as usize]))
}

/// Every undirected edge (by vertex index) is used by exactly two triangles, in opposite directions.
fn assert_closed_manifold(tris: &[[u32; 3]]) {
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for t in tris {
        for i in 0..3 {
            *directed.entry((t[i], t[(i + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "directed edge {a}->{b} used {n} times");
        assert_eq!(directed.get(&(b, a)), Some(&1), "edge {a}-{b} has no opposite half: a crack");
    }
}

/// No vertex lies strictly inside any edge (a T-junction), checked exactly in f64 on the f32 positions.
fn assert_no_t_junctions(p: &[Vec3], tris: &[[u32; 3]]) {
    let mut used: Vec<u32> = tris.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    let mut edges: Vec<(u32, u32)> =
        tris.iter().flat_map(|t| (0..3).map(move |i| (t[i].min(t[(i + 1) % 3]), t[i].max(t[(i + 1) % 3])))).collect();
    edges.sort_unstable();
    edges.dedup();
    for &(a, b) in &edges {
        let (pa, pb) = (dv(p[a as usize]), dv(p[b as usize]));
        let d = pb - pa;
        for &v in &used {
            if v == a || v == b {
                continue;
            }
            let w = dv(p[v as usize]) - pa;
            let s = w.dot(d) / d.length_squared();
            // Collinear (cross product zero up to f64 rounding of f32 inputs) and strictly between the ends.
            let on_line = w.cross(d).length() <= 1e-9 * d.length_squared();
            assert!(!(on_line && s > 1e-9 && s < 1.0 - 1e-9), "vertex {v} lies inside edge {a}-{b}: T-junction");
        }
    }
}

/// Per-parent checks: area preserved, children inside the parent, orientation kept, counts match the kind.
fn assert_parents(positions: &[Vec3], tris: &[[u32; 3]], ids: &[i32], out: &Subdivided) {
    let mut child_area = vec![0.0f64; tris.len()];
    let mut child_count = vec![0usize; tris.len()];
    let mut last = 0u32;
    for (c, &t) in out.triangles.iter().zip(&out.parent_of_new_triangle) {
        assert!(t >= last, "parents are non-decreasing");
        last = t;
        let parent = tris[t as usize];
        child_area[t as usize] += area(&out.positions, *c);
        child_count[t as usize] += 1;
        assert!(normal(&out.positions, *c).dot(normal(positions, parent)) > 0.0, "child of {t} flipped");
        // The child's centroid lies inside the parent (barycentric coordinates ≥ 0 up to rounding).
        let g = c.iter().map(|&v| dv(out.positions[v as usize])).sum::<DVec3>() / 3.0;
        let [a, b, cc] = parent.map(|v| dv(positions[v as usize]));
        let n = (b - a).cross(cc - a);
        for (p, q) in [(a, b), (b, cc), (cc, a)] {
            assert!((q - p).cross(g - p).dot(n) >= -1e-12, "child centroid outside parent {t}");
        }
    }
    for (t, tri) in tris.iter().enumerate() {
        let a = area(positions, *tri);
        assert!((child_area[t] - a).abs() <= 1e-12 * a.max(1.0), "area of {t}: {} vs {a}", child_area[t]);
        assert_eq!(child_count[t], out.kind[t].child_count());
    }
    for (c, &t) in out.object_id.iter().zip(&out.parent_of_new_triangle) {
        assert_eq!(*c, ids[t as usize]);
    }
    assert_eq!(out.inherit(ids).unwrap(), out.object_id);
    assert!(matches!(out.inherit(&ids[1..]), Err(SubdivideError::LengthMismatch { .. })));
    assert_eq!(&out.positions[..positions.len()], positions, "input vertices keep their indices");
}

#[test]
fn random_marks_on_closed_cube_stay_closed_over_rounds() {
    let (mut positions, mut tris, mut ids) = cube(4);
    let limits = SplitLimits { min_edge_length: 0.05, min_area: 0.0 };
    let mut rng = Rng(7);
    for round in 0..3 {
        let marked: Vec<u32> = (0..tris.len() / 6).map(|_| rng.below(tris.len()) as u32).collect();
        let mesh = SubdivideMesh { positions: &positions, triangles: &tris, object_id: &ids };
        let out = subdivide(&mesh, &marked, &limits).unwrap();
        assert!(!out.refined.is_empty(), "round {round} refined nothing");
        assert_closed_manifold(&out.triangles);
        assert_no_t_junctions(&out.positions, &out.triangles);
        assert_parents(&positions, &tris, &ids, &out);
        // Euler characteristic of a sphere: V − E + F = 2.
        let v = out.positions.len() as i64;
        let f = out.triangles.len() as i64;
        assert_eq!(v - 3 * f / 2 + f, 2, "round {round}");
        for &t in &out.refined {
            assert_eq!(out.kind[t as usize], SplitKind::Red);
        }
        (positions, tris, ids) = (out.positions, out.triangles, out.object_id);
    }
}

#[test]
fn closure_crosses_objects_and_distant_objects_are_untouched() {
    let (positions, tris, ids) = cube(2);
    // Mark the first triangle of the +x face (object 0): it sits in a corner of that face, so one of its edges
    // lies on the cube edge shared with another face (another object).
    let interior: Vec<u32> = (0..tris.len() as u32)
        .filter(|&t| ids[t as usize] == 0)
        .filter(|&t| tris[t as usize].iter().all(|&v| positions[v as usize].x == 2.0))
        .collect();
    let mesh = SubdivideMesh { positions: &positions, triangles: &tris, object_id: &ids };
    let limits = SplitLimits { min_edge_length: 1e-3, min_area: 0.0 };
    let out = subdivide(&mesh, &interior[..1], &limits).unwrap();
    assert_closed_manifold(&out.triangles);
    assert_no_t_junctions(&out.positions, &out.triangles);
    // Objects whose triangles share no split edge are byte-identical (same vertex indices, same order).
    let split_objects: std::collections::BTreeSet<i32> =
        (0..tris.len()).filter(|&t| out.kind[t] != SplitKind::Unchanged).map(|t| ids[t]).collect();
    assert!(split_objects.contains(&0));
    for obj in 0..6 {
        if split_objects.contains(&obj) {
            continue;
        }
        let before: Vec<[u32; 3]> = (0..tris.len()).filter(|&t| ids[t] == obj).map(|t| tris[t]).collect();
        let after: Vec<[u32; 3]> =
            (0..out.triangles.len()).filter(|&t| out.object_id[t] == obj).map(|t| out.triangles[t]).collect();
        assert_eq!(before, after, "object {obj} changed");
    }
    // The marked triangle's corner at the cube edge is shared with other faces: closure cut those objects'
    // triangles (green/blue), never refined them.
    let other_cut: Vec<u32> = out.closure_cut.iter().copied().filter(|&t| ids[t as usize] != 0).collect();
    assert!(!other_cut.is_empty(), "the edge on the cube edge must be closed in the neighbouring object too");
    assert!(6 - split_objects.len() >= 3, "a corner triangle touches at most three faces");
    for &t in &other_cut {
        assert!(matches!(out.kind[t as usize], SplitKind::Green | SplitKind::Blue));
    }
    assert_eq!(out.refined, &interior[..1]);
}

#[test]
fn duplicated_boundary_vertices_share_the_midpoint() {
    // Two objects meeting along the edge x = 1, each with its own copies of the shared vertices.
    let positions = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        // object 1's copies of (1,0,0) and (1,1,0)
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(2.0, 1.0, 0.0),
    ];
    let tris = vec![[0, 1, 2], [0, 2, 3], [4, 6, 7], [4, 7, 5]];
    let ids = vec![0, 0, 1, 1];
    let mesh = SubdivideMesh { positions: &positions, triangles: &tris, object_id: &ids };
    let out = subdivide(&mesh, &[0], &SplitLimits { min_edge_length: 0.1, min_area: 0.0 }).unwrap();
    // Edge (1,0,0)-(1,1,0) is split; object 1's triangle [4,7,5] must use the same midpoint vertex.
    let mid = out.positions.iter().position(|&p| p == Vec3::new(1.0, 0.5, 0.0)).unwrap() as u32;
    assert_eq!(out.positions.iter().filter(|&&p| p == Vec3::new(1.0, 0.5, 0.0)).count(), 1);
    assert_eq!(out.kind[3], SplitKind::Green);
    let uses_mid = out.parent_of_new_triangle.iter().zip(&out.triangles).filter(|(p, t)| **p == 3 && t.contains(&mid));
    assert_eq!(uses_mid.count(), 2);
    assert_eq!(out.kind[2], SplitKind::Unchanged);
    assert_no_t_junctions(&out.positions, &out.triangles);
    assert_parents(&positions, &tris, &ids, &out);
}

#[test]
fn limits_refuse_splits_that_would_be_too_small() {
    let (positions, tris, ids) = cube(4); // edges 0.5 and diagonals 0.707
    let mesh = SubdivideMesh { positions: &positions, triangles: &tris, object_id: &ids };
    let all: Vec<u32> = (0..tris.len() as u32).collect();
    // Red children have edges 0.25: a 0.3 minimum refuses every mark; nothing changes.
    let out = subdivide(&mesh, &all, &SplitLimits { min_edge_length: 0.3, min_area: 0.0 }).unwrap();
    assert!(out.refined.is_empty());
    assert_eq!(out.refused, all);
    assert_eq!(out.triangles, tris);
    assert_eq!(out.positions, positions);
    // Area limit: children of a 0.125-area triangle have 0.03125.
    let out = subdivide(&mesh, &[0], &SplitLimits { min_edge_length: 1e-3, min_area: 0.04 }).unwrap();
    assert_eq!((out.refined.len(), out.refused.as_slice()), (0, &[0u32][..]));
    // A limit that the marked triangle passes: every created triangle respects it.
    let limits = SplitLimits { min_edge_length: 0.25, min_area: 0.01 };
    let mut rng = Rng(11);
    let marked: Vec<u32> = (0..40).map(|_| rng.below(tris.len()) as u32).collect();
    let out = subdivide(&mesh, &marked, &limits).unwrap();
    assert!(!out.refined.is_empty());
    for (c, &p) in out.triangles.iter().zip(&out.parent_of_new_triangle) {
        if out.kind[p as usize] == SplitKind::Unchanged {
            continue;
        }
        let q = c.map(|v| dv(out.positions[v as usize]));
        for i in 0..3 {
            assert!(q[i].distance(q[(i + 1) % 3]) >= 0.25 - 1e-12);
        }
        assert!(area(&out.positions, *c) >= 0.01);
    }
    assert_closed_manifold(&out.triangles);
}

#[test]
fn closure_that_would_be_too_small_drops_the_mark() {
    // A large triangle next to a sliver: refining the large one would green-cut the sliver into children
    // with edges far below the limit, so the mark is refused and the mesh is unchanged.
    let positions =
        vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(2.0, 3.0, 0.0), Vec3::new(2.0, -0.01, 0.0)];
    let tris = vec![[0, 1, 2], [1, 0, 3]];
    let ids = vec![0, 1];
    let mesh = SubdivideMesh { positions: &positions, triangles: &tris, object_id: &ids };
    let out = subdivide(&mesh, &[0], &SplitLimits { min_edge_length: 0.5, min_area: 0.0 }).unwrap();
    assert_eq!(out.refused, [0]);
    assert_eq!(out.triangles, tris);
    // With a limit the sliver's children pass (its green children have a 0.01 median), the split happens.
    let out = subdivide(&mesh, &[0], &SplitLimits { min_edge_length: 0.005, min_area: 0.0 }).unwrap();
    assert_eq!(out.refined, [0]);
    assert_eq!(out.kind[1], SplitKind::Green);
    assert_no_t_junctions(&out.positions, &out.triangles);
}

#[test]
fn bad_input_is_a_typed_error() {
    let (positions, tris, ids) = cube(1);
    let mesh = SubdivideMesh { positions: &positions, triangles: &tris, object_id: &ids };
    let ok = SplitLimits { min_edge_length: 0.1, min_area: 0.0 };
    assert!(matches!(subdivide(&mesh, &[99], &ok), Err(SubdivideError::MarkOutOfRange { triangle: 99, .. })));
    for bad in [
        SplitLimits { min_edge_length: 0.0, min_area: 0.0 },
        SplitLimits { min_edge_length: f32::NAN, min_area: 0.0 },
        SplitLimits { min_edge_length: 0.1, min_area: -1.0 },
    ] {
        assert!(matches!(subdivide(&mesh, &[0], &bad), Err(SubdivideError::BadLimits { .. })));
    }
    let short_ids = &ids[1..];
    let m = SubdivideMesh { object_id: short_ids, ..mesh };
    assert!(matches!(subdivide(&m, &[], &ok), Err(SubdivideError::LengthMismatch { .. })));
    let bad_tris = vec![[0, 1, 100]];
    let m = SubdivideMesh { triangles: &bad_tris, object_id: &ids[..1], ..mesh };
    assert!(matches!(subdivide(&m, &[], &ok), Err(SubdivideError::VertexOutOfRange { triangle: 0, vertex: 100, .. })));
    let mut nan = positions.clone();
    nan[2].y = f32::NAN;
    let m = SubdivideMesh { positions: &nan, ..mesh };
    assert!(matches!(subdivide(&m, &[], &ok), Err(SubdivideError::NonFinitePosition { vertex: 2 })));
}
