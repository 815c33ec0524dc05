//! Export of the fitted mesh in formats a user can open anywhere: `mesh.ply` (every per-triangle parameter
//! as a face column), `textured.obj` + `textured.mtl` + the albedo atlas `albedo.png` / `albedo.exr`, and
//! `scene.glb` (glTF 2.0, PBR metallic-roughness).
//!
//! Code map: [`ply`] (face columns), [`atlas`] (layout rule, UVs, images), [`obj_atlas`] (OBJ/MTL text),
//! [`gltf`] (GLB); display encoding with `ingest::srgb`. [`write_all`] validates the input once, then writes every
//! file atomically (ingest's [`ingest::write_atomic`]: a reader never sees a torn file).
//!
//! Values: albedo and emission are linear (emission is radiance, unbounded); 8-bit encodings (PNG, PLY
//! `red green blue`) clamp to [0, 1] and albedo is sRGB-encoded there. Float columns (PLY, EXR) are exact.

pub mod atlas;
pub mod gltf;
pub mod obj_atlas;
pub mod ply;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::Vec3;
use tracer::Material;

pub use atlas::AtlasLayout;
pub use gltf::GlbSummary;

/// File names inside the export directory.
pub const PLY_FILE: &str = "mesh.ply";
pub const OBJ_FILE: &str = "textured.obj";
pub const MTL_FILE: &str = "textured.mtl";
pub const ALBEDO_PNG_FILE: &str = "albedo.png";
pub const ALBEDO_EXR_FILE: &str = "albedo.exr";
pub const GLB_FILE: &str = "scene.glb";

/// The mesh and its per-triangle parameters.
#[derive(Debug, Clone, Copy)]
pub struct ExportInput<'a> {
    pub positions: &'a [Vec3],
    pub triangles: &'a [[u32; 3]],
    /// Per triangle.
    pub materials: &'a [Material],
    /// Per triangle: emitted radiance (linear RGB, ≥ 0).
    pub emission: &'a [Vec3],
    /// Per triangle: object (segment) id.
    pub segment_id: &'a [i32],
    /// Per triangle: its sub-triangle albedo grid, if any (`optim::triangle::detail`); the atlas then holds
    /// the texels ([`atlas`], "Layout with sub-triangle detail"), the PLY and per-segment values the base colour.
    pub detail: Option<&'a [Option<optim::triangle::detail::TexelGrid>]>,
}

/// Export settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExportOptions {
    /// Atlas cell side in texels (power of two ≥ 4); see [`atlas`] for the layout rule.
    pub cell_texels: u32,
    /// Largest atlas width/height; the cell shrinks to 4 before this is exceeded (then the export fails).
    pub max_atlas_size: u32,
    /// The scene is Z-up: the GLB gets a root node turning it to glTF's Y-up.
    pub z_up: bool,
}

impl Default for ExportOptions {
    fn default() -> Self {
        // 8-texel cells keep a 2-texel margin (clean at mip levels 0 and 1); 4096 px is a texture size every
        // desktop and mobile renderer accepts.
        Self { cell_texels: 8, max_atlas_size: 4096, z_up: false }
    }
}

/// What [`write_all`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExportReport {
    /// Absolute paths of the written files, in writing order.
    pub files: Vec<PathBuf>,
    pub atlas: AtlasLayout,
    pub segments: usize,
    pub glb: GlbSummary,
}

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("export: {message}")]
    Input { message: String },
    #[error("export: triangle {triangle}: {message}")]
    Triangle { triangle: usize, message: String },
    #[error(
        "export: {triangles} triangles do not fit an atlas of at most {max_size}x{max_size} texels with 4-texel cells; raise max_atlas_size"
    )]
    AtlasTooLarge { triangles: usize, max_size: u32 },
    #[error("{path}: cannot encode: {message}", path = .path.display())]
    Encode { path: PathBuf, message: String },
    #[error("{path}: cannot create directory: {source}", path = .path.display())]
    CreateDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Write(#[from] ingest::IngestError),
}

/// Per-segment means, used where a format has one material per segment (MTL).
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentSummary {
    pub id: i32,
    pub triangles: usize,
    pub mean_roughness: f32,
    pub mean_metallic: f32,
    pub mean_emission: Vec3,
}

/// Segments in ascending id order with their mean roughness, metallic and emission (accumulated in f64).
#[must_use]
pub fn segment_summaries(input: &ExportInput<'_>) -> Vec<SegmentSummary> {
    let mut acc: BTreeMap<i32, (usize, f64, f64, glam::DVec3)> = BTreeMap::new();
    for (t, &id) in input.segment_id.iter().enumerate() {
        let m = &input.materials[t];
        let a = acc.entry(id).or_insert((0, 0.0, 0.0, glam::DVec3::ZERO));
        a.0 += 1;
        a.1 += f64::from(m.roughness);
        a.2 += f64::from(m.metallic);
        a.3 += input.emission[t].as_dvec3();
    }
    acc.into_iter()
        .map(|(id, (n, r, m, e))| {
            let k = n as f64;
            SegmentSummary {
                id,
                triangles: n,
                mean_roughness: (r / k) as f32,
                mean_metallic: (m / k) as f32,
                mean_emission: (e / k).as_vec3(),
            }
        })
        .collect()
}

/// Per-triangle columns for [`ExportInput`], owned.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PerTriangle {
    pub materials: Vec<Material>,
    pub emission: Vec<Vec3>,
    pub segment_id: Vec<i32>,
}

/// Expands per-object values to per-triangle columns (the export of a per-object fit, before the per-triangle
/// stage): triangle t gets object `face_object[t]`'s material, emission and id.
pub fn expand_per_object(
    face_object: &[u32],
    object_ids: &[i64],
    materials: &[Material],
    emission: &[Vec3],
) -> Result<PerTriangle, ExportError> {
    let n = object_ids.len();
    if materials.len() != n || emission.len() != n {
        return Err(ExportError::Input {
            message: format!("{n} objects but {} materials and {} emissions", materials.len(), emission.len()),
        });
    }
    let ids = object_ids
        .iter()
        .map(|&id| {
            i32::try_from(id).map_err(|_| ExportError::Input {
                message: format!("object id {id} does not fit the PLY `int segment_id` column"),
            })
        })
        .collect::<Result<Vec<i32>, _>>()?;
    let mut out = PerTriangle::default();
    for (t, &o) in face_object.iter().enumerate() {
        let o = o as usize;
        if o >= n {
            return Err(ExportError::Triangle { triangle: t, message: format!("object index {o} of {n}") });
        }
        out.materials.push(materials[o]);
        out.emission.push(emission[o]);
        out.segment_id.push(ids[o]);
    }
    Ok(out)
}

/// Checks lengths, indices and values; every writer relies on this.
pub fn validate(input: &ExportInput<'_>) -> Result<(), ExportError> {
    let n = input.triangles.len();
    if n == 0 {
        return Err(ExportError::Input { message: "the mesh has no triangles".into() });
    }
    for (what, len) in [
        ("materials", input.materials.len()),
        ("emission", input.emission.len()),
        ("segment_id", input.segment_id.len()),
    ] {
        if len != n {
            return Err(ExportError::Input { message: format!("{what} has {len} entries for {n} triangles") });
        }
    }
    if let Some(d) = input.detail {
        if d.len() != n {
            return Err(ExportError::Input { message: format!("detail has {} entries for {n} triangles", d.len()) });
        }
        for (t, g) in d.iter().enumerate() {
            if let Some(g) = g
                && (g.n == 0
                    || g.texels.len() != g.n as usize * g.n as usize
                    || g.texels.iter().any(|v| !v.is_finite()))
            {
                return Err(ExportError::Triangle {
                    triangle: t,
                    message: format!(
                        "texel grid of side {} must hold {} finite texels, holds {} (or a non-finite one)",
                        g.n,
                        g.n as usize * g.n as usize,
                        g.texels.len()
                    ),
                });
            }
        }
    }
    // OBJ and PLY indices are written as signed 32-bit integers (PLY `int`, OBJ readers parse i32/i64).
    if input.positions.len() > i32::MAX as usize {
        return Err(ExportError::Input { message: format!("{} vertices exceed i32 indices", input.positions.len()) });
    }
    if let Some(v) = input.positions.iter().position(|p| !p.is_finite()) {
        return Err(ExportError::Input { message: format!("vertex {v} has a non-finite position") });
    }
    for t in 0..n {
        let err = |message: String| Err(ExportError::Triangle { triangle: t, message });
        if let Some(&v) = input.triangles[t].iter().find(|&&v| v as usize >= input.positions.len()) {
            return err(format!("vertex index {v} out of range ({} vertices)", input.positions.len()));
        }
        let m = &input.materials[t];
        let scalars = [m.roughness, m.metallic, m.specular];
        if !m.base_color.is_finite() || scalars.iter().any(|x| !x.is_finite()) {
            return err(format!("material has a non-finite value: {m:?}"));
        }
        let e = input.emission[t];
        // glTF emissive factors are in [0, 1] after normalising by the largest component, which needs e ≥ 0.
        if !e.is_finite() || e.min_element() < 0.0 {
            return err(format!("emission must be finite and >= 0, got {e}"));
        }
    }
    Ok(())
}

fn write(dir: &Path, name: &str, bytes: &[u8], files: &mut Vec<PathBuf>) -> Result<(), ExportError> {
    let path = dir.join(name);
    ingest::write_atomic(&path, bytes)?;
    files.push(path);
    Ok(())
}

/// Writes `mesh.ply`, `albedo.png`, `albedo.exr`, `textured.mtl`, `textured.obj` and `scene.glb` into `dir`
/// (created if missing), each atomically. Fails before writing anything if the input is invalid.
pub fn write_all(dir: &Path, input: &ExportInput<'_>, opts: &ExportOptions) -> Result<ExportReport, ExportError> {
    validate(input)?;
    let layout = match input.detail {
        Some(d) => AtlasLayout::with_detail(d, opts.cell_texels, opts.max_atlas_size)?,
        None => AtlasLayout::new(input.triangles.len(), opts.cell_texels, opts.max_atlas_size)?,
    };
    std::fs::create_dir_all(dir).map_err(|source| ExportError::CreateDir { path: dir.to_path_buf(), source })?;
    let mut files = Vec::new();

    let ply_path = dir.join(PLY_FILE);
    ingest::ply::write_ply(&ply_path, &ply::mesh(input))?;
    files.push(ply_path);

    let albedo: Vec<Vec3> = input.materials.iter().map(|m| m.base_color).collect();
    let texels = atlas::albedo_texels(&layout, &albedo, input.detail);
    let png = atlas::albedo_png(&dir.join(ALBEDO_PNG_FILE), &layout, &texels)?;
    write(dir, ALBEDO_PNG_FILE, &png, &mut files)?;
    let exr = atlas::albedo_exr(&dir.join(ALBEDO_EXR_FILE), &layout, &texels)?;
    drop(texels);
    write(dir, ALBEDO_EXR_FILE, &exr, &mut files)?;

    let segments = segment_summaries(input);
    write(dir, MTL_FILE, obj_atlas::mtl(&segments, ALBEDO_PNG_FILE).as_bytes(), &mut files)?;
    write(dir, OBJ_FILE, obj_atlas::obj(input, &layout, MTL_FILE).as_bytes(), &mut files)?;

    let glb_path = dir.join(GLB_FILE);
    let roughness: Vec<f32> = input.materials.iter().map(|m| m.roughness).collect();
    let metallic: Vec<f32> = input.materials.iter().map(|m| m.metallic).collect();
    let mr = atlas::metallic_roughness_png(&glb_path, &layout, &roughness, &metallic)?;
    let (glb, summary) = gltf::glb(&glb_path, input, &layout, &png, &mr, opts.z_up)?;
    write(dir, GLB_FILE, &glb, &mut files)?;

    Ok(ExportReport { files, atlas: layout, segments: segments.len(), glb: summary })
}
