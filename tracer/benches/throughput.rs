//! Throughput benchmark on a ~100k-triangle room, written as CSV to `target/bench/throughput.csv` (and
//! stdout): raw Embree incoherent closest-hit and shadow rays/s (the ceiling), the path tracer's rays/s and
//! paths/s, and gradient paths/s, each with 1 and 2 rayon threads (plus path tracing with every material
//! Lambertian, to separate BSDF cost from integrator overhead). The four measurements are interleaved over
//! `ROUNDS` rounds and the fastest of each is kept, so that background load affects them alike; the
//! `rays_vs_embree` column is the tracer's ray rate over the raw Embree rate for the same mix of closest-hit and
//! shadow rays, with the raw rates of random rays (origins uniform in the room, uniform directions);
//! `rays_vs_embree_pathlike` uses instead the raw rates of path-like rays (cosine-distributed bounce rays from
//! random points of the heightfield, and shadow rays from there to the light), closer to what the tracer casts. Run with `cargo bench -p tracer --bench throughput`.

use glam::{Affine3A, Mat4, Vec3};
use rayon::prelude::*;
use std::time::Instant;
use tracer::numerics::{Frame, offset_ray_origin};
use tracer::rng::{PathSampler, PixelKey, Stream};
use tracer::{Camera, Material, Params, PixelRef, Renderer, Scene, SceneInput, TraceStats, TracerSettings};

const ROUNDS: usize = 5;

/// Heightfield of `n × n` quads inside a closed box with a ceiling light: 2n² + 14 triangles.
fn scene(n: u32) -> (Scene, Params) {
    let mut s = SceneInput::default();
    let h = |x: f32, z: f32| 0.1 * (7.0 * x).sin() * (5.0 * z).cos() + 0.03 * (31.0 * x + 17.0 * z).sin();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (-1.0 + 2.0 * i as f32 / n as f32, -1.0 + 2.0 * j as f32 / n as f32);
            s.positions.push(Vec3::new(x, h(x, z), z));
        }
    }
    let idx = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            // Counter-clockwise seen from +y.
            s.triangles.push([idx(i, j), idx(i, j + 1), idx(i + 1, j + 1)]);
            s.triangles.push([idx(i, j), idx(i + 1, j + 1), idx(i + 1, j)]);
        }
    }
    s.material_of_tri = vec![0; s.triangles.len()];
    s.emitter_of_tri = vec![0; s.triangles.len()];
    let (lo, hi) = (Vec3::new(-1.0, -0.3, -1.0), Vec3::new(1.0, 1.5, 1.0));
    let c = |x: bool, y: bool, z: bool| {
        Vec3::new(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
    };
    // Walls facing inwards.
    let faces = [
        [c(true, false, false), c(true, false, true), c(true, true, true), c(true, true, false)],
        [c(false, false, false), c(false, true, false), c(false, true, true), c(false, false, true)],
        [c(false, true, false), c(true, true, false), c(true, true, true), c(false, true, true)],
        [c(false, false, false), c(false, false, true), c(true, false, true), c(true, false, false)],
        [c(false, false, true), c(false, true, true), c(true, true, true), c(true, false, true)],
        [c(false, false, false), c(true, false, false), c(true, true, false), c(false, true, false)],
    ];
    let l = 0.3;
    let light = [Vec3::new(-l, 1.49, -l), Vec3::new(l, 1.49, -l), Vec3::new(l, 1.49, l), Vec3::new(-l, 1.49, l)];
    for (k, f) in faces.iter().chain(std::iter::once(&light)).enumerate() {
        let b = s.positions.len() as u32;
        s.positions.extend_from_slice(f);
        s.triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
        s.material_of_tri.extend([1, 1]);
        let e = u32::from(k == 6);
        s.emitter_of_tri.extend([e, e]);
    }
    let params = Params {
        materials: vec![
            Material { base_color: Vec3::new(0.7, 0.5, 0.3), roughness: 0.5, metallic: 0.2, specular: 0.5 },
            Material { base_color: Vec3::splat(0.7), roughness: 1.0, metallic: 0.0, specular: 0.0 },
        ],
        emission: vec![Vec3::ZERO, Vec3::splat(10.0)],
    };
    (Scene::new(s).expect("scene"), params)
}

fn timed<T>(best: &mut f64, f: impl FnOnce() -> T) -> T {
    let t = Instant::now();
    let r = f();
    *best = best.min(t.elapsed().as_secs_f64());
    r
}

fn main() {
    // `cargo bench` passes `--bench`; other arguments are ignored.
    let (scene, params) = scene(223);
    let tris = scene.triangle_count();
    // Incoherent rays: uniform origins in the room, uniform directions, random shadow-ray lengths; fixed seed.
    let n_rays = 1_000_000u32;
    let rays: Vec<(Vec3, Vec3, f32)> = (0..n_rays)
        .map(|i| {
            let r = PathSampler::new(1, Stream::Value, 0, PixelKey { view: 0, x: i, y: 0 }, 0);
            let o = Vec3::new(-0.95 + 1.9 * r.get(0), 0.15 + 1.3 * r.get(1), -0.95 + 1.9 * r.get(2));
            let z = 1.0 - 2.0 * r.get(3);
            let phi = std::f32::consts::TAU * r.get(4);
            let s = (1.0 - z * z).max(0.0).sqrt();
            (o, Vec3::new(s * phi.cos(), s * phi.sin(), z), 0.1 + 1.4 * r.get(5))
        })
        .collect();
    // Path-like rays: bounce rays leaving random points of the heightfield with cosine-distributed directions,
    // and shadow rays from those points to random points of the light (what the path tracer casts).
    let field_tris = tris as u32 - 14;
    let light_tris = [tris as u32 - 2, tris as u32 - 1];
    let path_rays: Vec<(Vec3, Vec3, Vec3)> = (0..n_rays)
        .map(|i| {
            let r = PathSampler::new(2, Stream::Value, 0, PixelKey { view: 0, x: i, y: 0 }, 0);
            let tri = ((r.get(0) * field_tris as f32) as u32).min(field_tris - 1);
            let sq = r.get(1).sqrt();
            let p = scene.position(tri, 1.0 - sq, r.get(2) * sq);
            let n = scene.geometric_normal(tri);
            let (rad, phi) = (r.get(3).sqrt(), std::f32::consts::TAU * r.get(4));
            let local = Vec3::new(rad * phi.cos(), rad * phi.sin(), (1.0 - r.get(3)).max(0.0).sqrt());
            let d = Frame::from_normal(n).to_world(local);
            let o = offset_ray_origin(p, n, d);
            let lt = light_tris[usize::from(r.get(5) >= 0.5)];
            let lsq = r.get(6).sqrt();
            let target = scene.position(lt, 1.0 - lsq, r.get(7) * lsq);
            (o, d, target - o)
        })
        .collect();
    let eye = Vec3::new(0.0, 1.0, 0.95);
    let cam_to_world = Affine3A::from_mat4(Mat4::look_at_rh(eye, Vec3::new(0.0, 0.0, -0.3), Vec3::Y).inverse());
    let size = 96;
    let cam = Camera::from_fov_y(size, size, 70f32.to_radians(), cam_to_world);
    let pixels: Vec<PixelRef> = (0..size).flat_map(|y| (0..size).map(move |x| PixelRef { view: 0, x, y })).collect();
    let weights = vec![Vec3::ONE; pixels.len()];
    let settings = TracerSettings { max_depth: 8, rr_depth: 3, ..Default::default() };
    let spp = 8;
    // The same scene with the heightfield made Lambertian: separates the integrator's overhead from the cost
    // of the full Disney/GGX evaluation.
    let mut lambert = params.clone();
    lambert.materials[0].metallic = 0.0;
    lambert.materials[0].specular = 0.0;

    let mut rows = vec![
        "measurement,threads,triangles,rays_per_s,paths_per_s,seconds,rays_vs_embree,rays_vs_embree_pathlike"
            .to_string(),
    ];
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        let mut t = [f64::INFINITY; 7];
        let mut stats = [TraceStats::default(); 3];
        pool.install(|| {
            for _ in 0..ROUNDS {
                let hits = timed(&mut t[0], || {
                    rays.par_chunks(4096)
                        .map(|c| {
                            c.iter()
                                .filter(|(o, d, _)| scene.embree().intersect(*o, *d, 0.0, f32::INFINITY).is_some())
                                .count()
                        })
                        .sum::<usize>()
                });
                assert!(hits > 0);
                timed(&mut t[1], || {
                    rays.par_chunks(4096)
                        .map(|c| c.iter().filter(|(o, d, tf)| scene.embree().occluded(*o, *d, 0.0, *tf)).count())
                        .sum::<usize>()
                });
                timed(&mut t[5], || {
                    path_rays
                        .par_chunks(4096)
                        .map(|c| {
                            c.iter()
                                .filter(|(o, d, _)| scene.embree().intersect(*o, *d, 0.0, f32::INFINITY).is_some())
                                .count()
                        })
                        .sum::<usize>()
                });
                // Shadow rays stop short of the light like the tracer's (1 − 1e-4 of the segment).
                timed(&mut t[6], || {
                    path_rays
                        .par_chunks(4096)
                        .map(|c| c.iter().filter(|(o, _, s)| scene.embree().occluded(*o, *s, 0.0, 1.0 - 1e-4)).count())
                        .sum::<usize>()
                });
                stats[0] = timed(&mut t[2], || {
                    let r = Renderer::new(&scene, &params, &settings).expect("renderer");
                    r.render_pixels(&[cam], &pixels, spp, 1, 0).expect("render")
                })
                .1;
                stats[2] = timed(&mut t[4], || {
                    let r = Renderer::new(&scene, &lambert, &settings).expect("renderer");
                    r.render_pixels(&[cam], &pixels, spp, 1, 0).expect("render")
                })
                .1;
                stats[1] = timed(&mut t[3], || {
                    let r = Renderer::new(&scene, &params, &settings).expect("renderer");
                    r.gradient_pixels(&[cam], &pixels, &weights, spp, 1, 0).expect("gradient")
                })
                .1;
            }
        });
        let (ri, ro) = (f64::from(n_rays) / t[0], f64::from(n_rays) / t[1]);
        rows.push(format!("embree_intersect1,{threads},{tris},{ri:.0},,{:.4},,", t[0]));
        rows.push(format!("embree_occluded1,{threads},{tris},{ro:.0},,{:.4},,", t[1]));
        let (pi, po) = (f64::from(n_rays) / t[5], f64::from(n_rays) / t[6]);
        rows.push(format!("embree_intersect1_pathlike,{threads},{tris},{pi:.0},,{:.4},,", t[5]));
        rows.push(format!("embree_occluded1_pathlike,{threads},{tris},{po:.0},,{:.4},,", t[6]));
        for (name, st, secs) in [
            ("path_tracing", stats[0], t[2]),
            ("gradient_paths", stats[1], t[3]),
            ("path_tracing_all_lambert", stats[2], t[4]),
        ] {
            let closest = (st.rays - st.shadow_rays) as f64;
            let shadow = st.shadow_rays as f64;
            // Time raw Embree would need for the same numbers of closest-hit and shadow rays.
            let raw_secs = closest / ri + shadow / ro;
            let raw_pathlike_secs = closest / pi + shadow / po;
            rows.push(format!(
                "{name},{threads},{tris},{:.0},{:.0},{secs:.4},{:.3},{:.3}",
                st.rays as f64 / secs,
                st.paths as f64 / secs,
                raw_secs / secs,
                raw_pathlike_secs / secs
            ));
        }
    }
    let csv = rows.join("\n") + "\n";
    print!("{csv}");
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/bench");
    std::fs::create_dir_all(&dir).expect("create target/bench");
    std::fs::write(dir.join("throughput.csv"), csv).expect("write throughput.csv");
}
