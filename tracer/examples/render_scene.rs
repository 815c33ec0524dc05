//! Renders a scene described by a JSON file to an OpenEXR image (RGB float32), for comparisons against other
//! renderers (tests/validation/test_mitsuba_ggx.py). Usage: `render_scene SCENE.json OUT.exr`.
//!
//! JSON format (all lengths in scene units; `cam_to_world` row-major 4×4 in the tracer's camera convention:
//! looking down −z, +x right, +y up):
//! ```json
//! { "camera": {"width": 64, "height": 64, "fov_y_deg": 40.0, "cam_to_world": [16 numbers]},
//!   "meshes": [{"positions": [[x,y,z], ...], "triangles": [[i,j,k], ...], "normals": null,
//!               "material": {"base_color": [r,g,b], "roughness": 0.5, "metallic": 0.0, "specular": 0.5},
//!               "emission": [r,g,b]}],
//!   "settings": {"max_depth": 8, "rr_depth": 5, "emission_profile": "uniform"},
//!   "spp": 64, "seed": 1, "iteration": 0 }
//! ```

use glam::{Affine3A, Mat4, Vec3};
use serde::Deserialize;
use tracer::{Camera, Material, Params, Scene, SceneInput, TracerSettings, render_image};

#[derive(Deserialize)]
struct CameraDesc {
    width: u32,
    height: u32,
    fov_y_deg: f32,
    cam_to_world: [f32; 16],
}

#[derive(Deserialize)]
struct MeshDesc {
    positions: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    material: Material,
    emission: [f32; 3],
}

#[derive(Deserialize)]
struct SceneDesc {
    camera: CameraDesc,
    meshes: Vec<MeshDesc>,
    settings: TracerSettings,
    spp: u32,
    seed: u64,
    #[serde(default)]
    iteration: u64,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, scene_path, out_path] = &args[..] else {
        return Err("usage: render_scene SCENE.json OUT.exr".into());
    };
    let desc: SceneDesc =
        serde_json::from_str(&std::fs::read_to_string(scene_path)?).map_err(|e| format!("{scene_path}: {e}"))?;
    let mut input = SceneInput::default();
    let mut params = Params::default();
    let smooth = desc.meshes.iter().any(|m| m.normals.is_some());
    let mut normals = Vec::new();
    for (slot, m) in desc.meshes.iter().enumerate() {
        let base = input.positions.len() as u32;
        input.positions.extend(m.positions.iter().map(|&p| Vec3::from(p)));
        match &m.normals {
            Some(n) => normals.extend(n.iter().map(|&v| Vec3::from(v))),
            // Flat meshes mixed with smooth ones: the geometric normal is used where the vertex normal is zero.
            None => normals.extend(std::iter::repeat_n(Vec3::ZERO, m.positions.len())),
        }
        input.triangles.extend(m.triangles.iter().map(|t| t.map(|i| i + base)));
        input.material_of_tri.extend(std::iter::repeat_n(slot as u32, m.triangles.len()));
        input.emitter_of_tri.extend(std::iter::repeat_n(slot as u32, m.triangles.len()));
        params.materials.push(m.material);
        params.emission.push(Vec3::from(m.emission));
    }
    if smooth {
        input.normals = Some(normals);
    }
    let scene = Scene::new(input)?;
    let c = &desc.camera;
    let m = Mat4::from_cols_array(&c.cam_to_world).transpose();
    let cam = Camera::from_fov_y(c.width, c.height, c.fov_y_deg.to_radians(), Affine3A::from_mat4(m));
    let t0 = std::time::Instant::now();
    let img = render_image(&scene, &params, &cam, desc.spp, &desc.settings, desc.seed, desc.iteration)?;
    eprintln!("rendered {}×{} at {} spp in {:.2} s", c.width, c.height, desc.spp, t0.elapsed().as_secs_f64());
    let w = c.width as usize;
    exr::prelude::write_rgb_file(out_path, w, c.height as usize, |x, y| {
        let p = img[y * w + x];
        (p.x, p.y, p.z)
    })
    .map_err(|e| format!("{out_path}: {e}"))?;
    Ok(())
}
