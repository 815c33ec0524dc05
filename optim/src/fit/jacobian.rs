//! Per-pixel Jacobians of pixel radiance with respect to the per-object unknowns.
//!
//! - Emission: radiance is linear in emission and emission channel c only affects image channel c, so
//!   rendering the scene with object k's emission set to (1, 1, 1) and every other emission to 0 gives, per
//!   pixel and channel, exactly ∂I_c/∂e_{k,c} (a "basis render"). Light selection then samples object k
//!   itself, so these columns have next-event-estimation noise even for a light no photo sees — far lower
//!   than the gradient path's estimate at e_k = 0, which finds a non-emitting object only by BSDF sampling.
//! - Base colour: `gradient_pixels` over one pixel with weight (1, 1, 1) returns that pixel's row
//!   ∂I_c/∂ρ_{k,c} (base colour acts per channel).

use super::samples::SampleCounter;
use rayon::prelude::*;
use tracer::{PixelRef, TracerError};

/// `cols[k][j]` = ∂I_j/∂e_k per channel (as f64 RGB) for the objects with `wanted[k]`, no emitter split; the
/// others' columns are left empty. Every
/// column is, bit for bit, the basis render of its object alone (`tracer::Renderer::render_emission_columns`:
/// the columns share each path's continuation rays and differ in their next-event connections), so a column
/// does not depend on which others are asked for.
pub fn emission_columns_of(
    ctx: &Ctx<'_>,
    materials: &[tracer::Material],
    pixels: &[PixelRef],
    spp: u32,
    iteration_key: u64,
    wanted: &[bool],
) -> Result<Vec<Vec<[f64; 3]>>, TracerError> {
    let k_count = materials.len();
    let slots: Vec<u32> = (0..k_count).filter(|&k| wanted.get(k).copied().unwrap_or(false)).map(|k| k as u32).collect();
    let mut out = vec![Vec::new(); k_count];
    if slots.is_empty() {
        return Ok(out);
    }
    let params = tracer::Params {
        materials: materials.to_vec(),
        emission: vec![glam::Vec3::ZERO; k_count],
        horizon: Default::default(),
    };
    for (&k, col) in slots.iter().zip(entry_columns(ctx, &params, pixels, spp, iteration_key, &slots)?) {
        out[k as usize] = col;
    }
    Ok(out)
}

/// The basis images of the emission entries `entries` of `params` over `pixels` — an object's slot, or the
/// ground half that `params.horizon` splits off a slot (`tracer::params::Horizon`); `params.emission` itself
/// is not used: `cols[i][j]` = ∂I_j/∂e per channel for entry `entries[i]`, bit for bit its basis render alone.
pub fn entry_columns(
    ctx: &Ctx<'_>,
    params: &tracer::Params,
    pixels: &[PixelRef],
    spp: u32,
    iteration_key: u64,
    entries: &[u32],
) -> Result<Vec<Vec<[f64; 3]>>, TracerError> {
    if entries.is_empty() {
        return Ok(Vec::new());
    }
    let r = tracer::Renderer::new(ctx.scene, params, ctx.settings)?;
    let (cols, stats) = r.render_emission_columns(ctx.cameras, pixels, entries, spp, ctx.seed, iteration_key)?;
    ctx.samples.add(&stats);
    Ok(cols.iter().map(|col| col.iter().map(|c| [f64::from(c.x), f64::from(c.y), f64::from(c.z)]).collect()).collect())
}

/// One pixel's Jacobian row: `base_color[k]` = ∂I/∂ρ_k and `emission[k]` = ∂I/∂e_k, per channel.
#[derive(Debug, Clone, PartialEq)]
pub struct PixelRow {
    pub base_color: Vec<[f64; 3]>,
    pub emission: Vec<[f64; 3]>,
}

/// The Jacobian row of every pixel from its gradient paths. The emission entries of objects that currently
/// emit are found by next-event estimation (low noise); those of non-emitting objects only by BSDF sampling,
/// which is still unbiased and, for the large visible surfaces that such columns matter for, not noisy.
pub fn pixel_rows(
    ctx: &Ctx<'_>,
    params: &tracer::Params,
    pixels: &[PixelRef],
    spp: u32,
    iteration_key: u64,
) -> Result<Vec<PixelRow>, TracerError> {
    pixels
        .par_iter()
        .map(|p| {
            let g = ctx.gradient(params, std::slice::from_ref(p), &[glam::Vec3::ONE], spp, iteration_key)?;
            Ok(PixelRow {
                base_color: g.materials.iter().map(|m| m.base_color.to_array()).collect(),
                emission: g.emission.iter().map(|e| e.to_array()).collect(),
            })
        })
        .collect()
}

/// One object's sparse Jacobian column: (pixel index, ∂I/∂θ per channel) for its non-zero entries.
pub type SparseColumn = Vec<(u32, [f64; 3])>;

/// ∂I_j/∂ρ_k per channel over `pixels` for the objects with `wanted[k]`, from the same gradient paths as
/// [`pixel_rows`], kept as each object's list of (pixel index, value) for its non-zero entries (the others'
/// lists are empty). A pixel's paths touch a few objects, so the lists hold pixels × path vertices entries
/// at most, where dense rows hold pixels × objects (a 213-object house's 171 k test pixels: 1.7 GB).
pub fn base_color_columns_of(
    ctx: &Ctx<'_>,
    params: &tracer::Params,
    pixels: &[PixelRef],
    spp: u32,
    iteration_key: u64,
    wanted: &[bool],
) -> Result<Vec<SparseColumn>, TracerError> {
    let rows: Vec<SparseColumn> = ctx.gradient_rows(params, pixels, spp, iteration_key, |g| {
        g.materials
            .iter()
            .filter(|(k, m)| wanted.get(*k as usize).copied().unwrap_or(false) && m.base_color != glam::DVec3::ZERO)
            .map(|&(k, ref m)| (k, m.base_color.to_array()))
            .collect()
    })?;
    let mut cols = vec![Vec::new(); params.materials.len()];
    for (j, row) in rows.into_iter().enumerate() {
        for (k, v) in row {
            cols[k as usize].push((j as u32, v));
        }
    }
    Ok(cols)
}

/// What every tracer call of the fit shares.
#[derive(Debug, Clone, Copy)]
pub struct Ctx<'a> {
    pub scene: &'a tracer::Scene,
    pub cameras: &'a [tracer::Camera],
    pub settings: &'a tracer::TracerSettings,
    pub seed: u64,
    /// Where every call through [`Ctx::render`] and [`Ctx::gradient`] adds its path counts.
    pub samples: &'a SampleCounter,
    /// The emitters split at the horizon ([`super::layout::NO_SPLIT`] until model selection splits any).
    pub split: &'a super::layout::Split,
}

impl Ctx<'_> {
    /// The tracer's tables of the layout vector `x` under this context's split.
    #[must_use]
    pub fn params(&self, x: &[f64]) -> tracer::Params {
        self.split.params(x)
    }

    /// `tracer::Renderer::render_pixels` with this context's scene, cameras, settings and seed; the work is
    /// counted in `samples`.
    pub fn render(
        &self,
        params: &tracer::Params,
        pixels: &[PixelRef],
        spp: u32,
        key: u64,
    ) -> Result<Vec<glam::Vec3>, TracerError> {
        let r = tracer::Renderer::new(self.scene, params, self.settings)?;
        let (values, stats) = r.render_pixels(self.cameras, pixels, spp, self.seed, key)?;
        self.samples.add(&stats);
        Ok(values)
    }

    /// `tracer::Renderer::gradient_pixels` with this context's scene, cameras, settings and seed; the work is
    /// counted in `samples`.
    pub fn gradient(
        &self,
        params: &tracer::Params,
        pixels: &[PixelRef],
        weights: &[glam::Vec3],
        spp: u32,
        key: u64,
    ) -> Result<tracer::Grads, TracerError> {
        let r = tracer::Renderer::new(self.scene, params, self.settings)?;
        let (grads, stats) = r.gradient_pixels(self.cameras, pixels, weights, spp, self.seed, key)?;
        self.samples.add(&stats);
        Ok(grads)
    }

    /// `tracer::Renderer::gradient_rows`: per pixel, the sparse gradient of that pixel alone at unit weight,
    /// reduced by `reduce`, with this context's scene, cameras, settings and seed; the work is counted in
    /// `samples`.
    pub fn gradient_rows<T: Send>(
        &self,
        params: &tracer::Params,
        pixels: &[PixelRef],
        spp: u32,
        key: u64,
        reduce: impl Fn(tracer::SparseGrads) -> T + Sync,
    ) -> Result<Vec<T>, TracerError> {
        let r = tracer::Renderer::new(self.scene, params, self.settings)?;
        let ones = vec![glam::Vec3::ONE; pixels.len()];
        let (rows, stats) = r.gradient_rows(self.cameras, pixels, &ones, spp, self.seed, key, reduce)?;
        self.samples.add(&stats);
        Ok(rows)
    }

    /// `tracer::Renderer::gradient_pixels_weighted`: one gradient per weighting, all from the same paths
    /// (traced once), with this context's scene, cameras, settings and seed; the work is counted in `samples`.
    pub fn gradient_weighted(
        &self,
        params: &tracer::Params,
        pixels: &[PixelRef],
        weight_sets: &[&[glam::Vec3]],
        spp: u32,
        key: u64,
    ) -> Result<Vec<tracer::Grads>, TracerError> {
        let r = tracer::Renderer::new(self.scene, params, self.settings)?;
        let (grads, stats) = r.gradient_pixels_weighted(self.cameras, pixels, weight_sets, spp, self.seed, key)?;
        self.samples.add(&stats);
        Ok(grads)
    }
}

/// Full Jacobian rows per pixel and channel: `rows[j][c]` holds, for every object k, ∂I_{j,c}/∂θ_k for
/// θ = (base colour channel c, roughness, specular, emission channel c). Roughness and specular act on all
/// channels, so each channel has its own backward pass (weight = unit vector of c), all three on the same
/// paths, traced once.
pub fn channel_rows(
    ctx: &Ctx<'_>,
    params: &tracer::Params,
    pixels: &[PixelRef],
    spp: u32,
    iteration_key: u64,
) -> Result<Vec<[Vec<[f64; 4]>; 3]>, TracerError> {
    const UNIT: [[glam::Vec3; 1]; 3] = [[glam::Vec3::X], [glam::Vec3::Y], [glam::Vec3::Z]];
    pixels
        .par_iter()
        .map(|p| {
            let g = ctx.gradient_weighted(
                params,
                std::slice::from_ref(p),
                &[&UNIT[0], &UNIT[1], &UNIT[2]],
                spp,
                iteration_key,
            )?;
            let row = |c: usize| -> Vec<[f64; 4]> {
                g[c].materials
                    .iter()
                    .zip(&g[c].emission)
                    .map(|(m, e)| [m.base_color[c], m.roughness, m.specular, e[c]])
                    .collect()
            };
            Ok([row(0), row(1), row(2)])
        })
        .collect()
}
