//! The benchmark scenes: a synthetic scene description with its photos (read from a committed scan when one
//! exists, else rendered in memory exactly as `pipeline synth` would write them) and its ground truth.

use std::path::{Path, PathBuf};

use ingest::photo::LinearImage;

use super::BenchError;
use crate::synth::BuiltScene;

/// One benchmark scene.
#[derive(Debug)]
pub struct BenchScene {
    /// Short name (`demo`, `glossy`, ...): the description file's stem.
    pub name: String,
    pub built: BuiltScene,
    /// One photo per camera of `built`, full resolution, all pixels valid.
    pub photos: Vec<LinearImage>,
}

/// Where the scene descriptions and the committed scans live: `<workspace>/data-fixtures`.
#[must_use]
pub fn fixtures_dir(workspace: &Path) -> PathBuf {
    workspace.join("data-fixtures")
}

/// Loads scene `name` from `data-fixtures/scenes/<name>.toml`; the photos come from `data-fixtures/<name>/`
/// when that scan exists (the committed default scene), else they are rendered from the description.
pub fn load(workspace: &Path, name: &str) -> Result<BenchScene, BenchError> {
    let fixtures = fixtures_dir(workspace);
    let desc_path = fixtures.join("scenes").join(format!("{name}.toml"));
    let built = crate::synth::build(crate::synth::load_desc(&desc_path)?, &desc_path)?;
    let scan = fixtures.join(name).join("undistorted_color_images");
    let photos = if scan.is_dir() {
        (0..built.cameras.len())
            .map(|k| {
                let file = crate::synth::matterport::image_names(&built.desc, k).0;
                read_exr(&scan.join(file))
            })
            .collect::<Result<Vec<_>, _>>()?
    } else {
        crate::synth::photos(&built)?
    };
    for (k, (p, c)) in photos.iter().zip(&built.cameras).enumerate() {
        if p.width != c.width || p.height != c.height {
            return Err(BenchError::Scene {
                scene: name.to_owned(),
                message: format!("photo {k} is {}x{}, its camera {}x{}", p.width, p.height, c.width, c.height),
            });
        }
    }
    Ok(BenchScene { name: name.to_owned(), built, photos })
}

/// Reads a linear RGB(A) EXR (the synthetic scans' photos) with every pixel valid.
pub fn read_exr(path: &Path) -> Result<LinearImage, BenchError> {
    use exr::prelude::*;
    let img = read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), res.height(), vec![0f32; 3 * res.width() * res.height()]),
        |(w, _, buf), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let i = 3 * (pos.y() * *w + pos.x());
            buf[i] = r;
            buf[i + 1] = g;
            buf[i + 2] = b;
        },
    )
    .map_err(|e| BenchError::Io { path: path.to_path_buf(), message: e.to_string() })?;
    let (w, h, rgb) = img.layer_data.channel_data.pixels;
    Ok(LinearImage { width: w as u32, height: h as u32, rgb, mask: vec![1; w * h] })
}

/// The camera of the same view at `1/factor` resolution, matching a `factor`×`factor` box filter of its image
/// (pixel centres at integer coordinates: new pixel X covers old pixels factor·X … factor·X + factor − 1,
/// centred at old coordinate factor·X + (factor − 1)/2).
#[must_use]
pub fn downscale_camera(c: &tracer::Camera, factor: u32) -> tracer::Camera {
    let f = factor as f32;
    let shift = 0.5 * (f - 1.0);
    tracer::Camera {
        width: c.width / factor,
        height: c.height / factor,
        fx: c.fx / f,
        fy: c.fy / f,
        cx: (c.cx - shift) / f,
        cy: (c.cy - shift) / f,
        cam_to_world: c.cam_to_world,
    }
}

/// Box-filter downscale of an all-valid image by an integer factor (the size must be divisible by it).
#[must_use]
pub fn downscale_image(img: &LinearImage, factor: u32) -> LinearImage {
    let (w, h) = (img.width / factor, img.height / factor);
    let mut rgb = vec![0f32; 3 * (w * h) as usize];
    let norm = 1.0 / (factor * factor) as f32;
    for y in 0..h {
        for x in 0..w {
            let o = 3 * (y * w + x) as usize;
            for dy in 0..factor {
                for dx in 0..factor {
                    let i = 3 * ((y * factor + dy) * img.width + x * factor + dx) as usize;
                    for c in 0..3 {
                        rgb[o + c] += img.rgb[i + c] * norm;
                    }
                }
            }
        }
    }
    LinearImage { width: w, height: h, rgb, mask: vec![1; (w * h) as usize] }
}

/// Whether every camera's size is divisible by `factor`.
#[must_use]
pub fn divisible(scene: &BenchScene, factor: u32) -> bool {
    factor >= 1 && scene.built.cameras.iter().all(|c| c.width % factor == 0 && c.height % factor == 0)
}
