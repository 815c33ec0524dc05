//! The base colour of an object that the photos do not see (fewer than `solve::MIN_PIXELS` training
//! pixels): estimated from the light it reflects onto the surfaces they do see, and drawn towards a stated
//! prior as far as that estimate is uncertain.
//!
//! Such an object is still in the light transport: a ceiling no photo sees reflects a lamp's light onto the
//! walls. Held at a start value (grey 0.5 for a 0.85 ceiling), its missing bounce was made up by every wall's
//! albedo (2–4 % too bright) and by the lamp (3–7 % too bright). So the fit treats every object's base colour
//! as an unknown — Adam's gradient paths and the Gauss–Newton columns reach an unseen surface through the
//! light it reflects — and, once the fit is done, weighs each unseen object's estimate against a prior:
//!
//! - **the estimate's standard error** per channel, from the fit's data at the final parameters
//!   ([`standard_errors`]): the sandwich variance of a weighted least-squares estimate over a fresh solve draw
//!   of pixels, from the Jacobian with respect to every base colour and every light's emission (so that a
//!   ceiling's albedo is judged net of what the lamp and the walls can trade for it), the residuals' robust
//!   scale per object, and the number of Gauss–Newton steps the estimate averages. The few pixels that see
//!   an unconstrained object itself are left out: a fitting seen in 5 pixel centres beside a lamp fits
//!   anything there, and only what it reflects elsewhere counts;
//! - **the prior**: the area-weighted mean and spread of the base colours of the observed objects that do not
//!   emit, of the same category when the scan has any ([`UnseenPrior`]), else of all of them — the scan's
//!   own distribution of surfaces — and of those, of the object's own lobe family (metal or dielectric) when
//!   any is: a metal's base colour is its reflectance at normal incidence, a dielectric's its diffuse albedo,
//!   two quantities that one mean does not describe. On the corpus house the spheres seen in too few pixels
//!   (fitted as Lambert surfaces) took a prior of 0.51 / 0.54 / 0.44 from all 21 observed spheres, a third
//!   of them metals of base colour 0.6–0.9, and 0.42 / 0.45 / 0.34 from the dielectric ones alone
//!   (docs/optim/design-measurements.md, "A prior of the object's own lobe family");
//! - **the result** is the precision-weighted mean of the two ([`combine`]), the posterior mean under Gaussian
//!   errors: a ceiling that lights the walls takes its estimate, a lamp panel (whose reflection no pixel can
//!   tell from its emission) or a cabinet's hidden back takes the prior. `materials.json` says which, with the
//!   data's weight and standard error.
//!
//! Measured on rooms whose ceiling and lamp no photo sees (`docs/optim/design-measurements.md`, "Objects no
//! photo sees"). The category of an object is the leading word of its label, lower-cased ("wall south" and
//! "Wall_0002" are both `wall`): Matterport's segment labels are category names, and ours follow that rule.

use super::ObjectDesc;
use super::jacobian::{self, Ctx};
use super::layout::{self, BASE_COLOR, EMISSION, METALLIC, PER_OBJECT, idx};
use super::linear::sandwich_diagonal;
use super::pixels::WeightedDraw;
use crate::streams::key::{PROFILE_JACOBIAN, SECOND_ESTIMATE};
use tracer::{PixelRef, TracerError};

/// The prior's standard deviation never falls below this: a scan whose observed objects share one colour
/// (or has one observed object) says little about a surface no photo sees, and an albedo known to ±0.1 is
/// the most a scan's other surfaces can claim about it (indoor albedos span about 0.05–0.9).
pub const MIN_PRIOR_SD: f64 = 0.1;

/// Where an unseen object's prior comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum PriorSource {
    /// The observed, non-emitting objects of the same category.
    SameCategory { category: String, objects: usize },
    /// All observed, non-emitting objects (none of its category).
    AllObserved { objects: usize },
    /// No observed object that does not emit: the start value, with an uninformative spread.
    StartValue,
}

/// A lobe family: what a base colour means (a metal's reflectance at normal incidence, a dielectric's diffuse
/// albedo).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    Dielectric,
    Metal,
}

impl Family {
    /// The family of metallic `m`, as model selection counts it ([`layout::is_metal`]).
    #[must_use]
    pub fn of(metallic: f64) -> Self {
        if layout::is_metal(metallic) { Self::Metal } else { Self::Dielectric }
    }

    fn name(self) -> &'static str {
        match self {
            Self::Dielectric => "dielectric",
            Self::Metal => "metal",
        }
    }
}

/// A prior per channel: mean and standard deviation, and where it comes from.
#[derive(Debug, Clone, PartialEq)]
pub struct Prior {
    pub mean: [f64; 3],
    pub sd: [f64; 3],
    pub source: PriorSource,
    /// The lobe family the donors were restricted to (the object's own) and how many of the pool are of it, or
    /// `None` where none of the pool is of its family and the whole pool was taken.
    pub family: Option<(Family, usize)>,
}

impl Prior {
    fn describe_source(&self) -> String {
        let of = match self.family {
            Some((f, n)) => format!("the {n} {} ones among ", f.name()),
            None => String::new(),
        };
        match &self.source {
            PriorSource::SameCategory { category, objects } => {
                format!(
                    "the area-weighted mean of {of}the {objects} observed non-emitting objects of category '{category}'"
                )
            }
            PriorSource::AllObserved { objects } => format!(
                "the area-weighted mean of {of}all {objects} observed non-emitting objects (none of its category is observed)"
            ),
            PriorSource::StartValue => "the start value (no observed object without emission)".to_owned(),
        }
    }
}

/// The category key of a label: its leading run of letters, lower-cased; `None` when it has none.
#[must_use]
pub fn category(label: &str) -> Option<String> {
    let word: String = label.chars().take_while(|c| c.is_alphabetic()).flat_map(char::to_lowercase).collect();
    (!word.is_empty()).then_some(word)
}

/// What the prior needs to know of the objects: their surface areas and categories, and which are observed.
#[derive(Debug, Clone)]
pub struct UnseenPrior {
    area: Vec<f64>,
    category: Vec<Option<String>>,
    observed: Vec<bool>,
}

impl UnseenPrior {
    /// `observed[k]`: object k's material is constrained by the photos. Areas from the scene's triangles.
    #[must_use]
    pub fn new(scene: &tracer::Scene, objects: &[ObjectDesc], observed: &[bool]) -> Self {
        let area = objects.iter().map(|o| o.triangles.iter().map(|&t| f64::from(scene.area(t))).sum()).collect();
        Self::from_parts(area, objects.iter().map(|o| category(&o.label)).collect(), observed.to_vec())
    }

    /// The same from areas and categories directly (tests).
    #[must_use]
    pub fn from_parts(area: Vec<f64>, category: Vec<Option<String>>, observed: Vec<bool>) -> Self {
        Self { area, category, observed }
    }

    /// The objects the photos do not constrain.
    #[must_use]
    pub fn unseen(&self) -> Vec<usize> {
        (0..self.observed.len()).filter(|&k| !self.observed[k]).collect()
    }

    /// The prior of object `k` given the parameters `x`: area-weighted mean and standard deviation of the base
    /// colours of the observed objects none of whose emission channels is positive, of k's category when any
    /// is observed, else of all; of those, the ones of k's lobe family ([`Family::of`] its metallic in `x`)
    /// when any is.
    #[must_use]
    pub fn prior(&self, x: &[f64], k: usize) -> Prior {
        let n = (x.len() / PER_OBJECT).min(self.observed.len());
        let donors: Vec<usize> = (0..n)
            .filter(|&d| self.observed[d] && self.area[d] > 0.0 && (0..3).all(|c| x[idx(d, EMISSION + c)] <= 0.0))
            .collect();
        let same: Vec<usize> = match &self.category[k] {
            Some(cat) => donors.iter().copied().filter(|&d| self.category[d].as_ref() == Some(cat)).collect(),
            None => Vec::new(),
        };
        let (set, source) = if !same.is_empty() {
            let objects = same.len();
            (same, PriorSource::SameCategory { category: self.category[k].clone().unwrap_or_default(), objects })
        } else if !donors.is_empty() {
            let objects = donors.len();
            (donors, PriorSource::AllObserved { objects })
        } else {
            let start = layout::base_color(x, k);
            return Prior { mean: start, sd: [0.5; 3], source: PriorSource::StartValue, family: None };
        };
        let own = Family::of(x[idx(k, METALLIC)]);
        let of_family: Vec<usize> = set.iter().copied().filter(|&d| Family::of(x[idx(d, METALLIC)]) == own).collect();
        let family = (!of_family.is_empty()).then_some((own, of_family.len()));
        let set = if of_family.is_empty() { set } else { of_family };
        let w: f64 = set.iter().map(|&d| self.area[d]).sum();
        let mut mean = [0.0; 3];
        let mut sd = [0.0; 3];
        for c in 0..3 {
            mean[c] = set.iter().map(|&d| self.area[d] * x[idx(d, BASE_COLOR + c)]).sum::<f64>() / w;
            let var =
                set.iter().map(|&d| self.area[d] * (x[idx(d, BASE_COLOR + c)] - mean[c]).powi(2)).sum::<f64>() / w;
            sd[c] = var.sqrt().max(MIN_PRIOR_SD);
        }
        Prior { mean, sd, source, family }
    }
}

/// The estimate combined with the prior, per channel: the precision-weighted mean (the posterior mean for
/// Gaussian errors) and the data's weight in it, in [0, 1]. A non-finite standard error (no information)
/// gives the prior.
#[must_use]
pub fn combine(estimate: [f64; 3], se: [f64; 3], prior: &Prior) -> ([f64; 3], [f64; 3]) {
    let mut out = [0.0; 3];
    let mut weight = [0.0; 3];
    for c in 0..3 {
        let data_precision = if se[c].is_finite() && se[c] > 0.0 { se[c].powi(-2) } else { 0.0 };
        let prior_precision = prior.sd[c].powi(-2);
        weight[c] = data_precision / (data_precision + prior_precision);
        // Both terms lie in [0, 1]; the clamp only guards the box against rounding.
        out[c] = (weight[c] * estimate[c] + (1.0 - weight[c]) * prior.mean[c]).clamp(0.0, 1.0);
    }
    (out, weight)
}

/// One sentence for an unseen object's `why` in `materials.json`.
#[must_use]
pub fn describe(result: [f64; 3], estimate: [f64; 3], se: [f64; 3], weight: [f64; 3], prior: &Prior) -> String {
    let v3 = |v: [f64; 3]| format!("({:.3}, {:.3}, {:.3})", v[0], v[1], v[2]);
    let w = weight.iter().sum::<f64>() / 3.0;
    let how = if w >= 0.5 {
        "estimated from the light it reflects onto the observed surfaces"
    } else {
        "mostly a prior: the light it reflects onto the observed surfaces leaves it uncertain"
    };
    format!(
        "base colour {} {how}: estimate {} ± {} (standard error), prior {} ± {} = {}; the data's weight {}",
        v3(result),
        v3(estimate),
        v3(se),
        v3(prior.mean),
        v3(prior.sd),
        prior.describe_source(),
        v3(weight)
    )
}

/// Standard errors of the base colours of `objects` in the fit at `x`, per channel: the sandwich A⁻¹BA⁻¹ of the
/// weighted least-squares fit over the pixels of `draw`, with A = JᵀWJ (J = ∂I/∂θ for every base colour that
/// reaches them and the emission of every light, from the cross products of two independent gradient-path
/// estimates) and B = JᵀW Σ W J (Σ the rows' residual variances, robust scale per object, `row_sigmas`: both
/// the photos' and the render's noise and what the model cannot represent), divided by the `averaged`
/// independent draws of this size behind the estimate (the Gauss–Newton steps it averages). The weights are
/// the draw's sampling weights, not the rows' precisions, so σ²A⁻¹ alone is wrong wherever they differ from 1:
/// an object seen in a few pixels has all of them in every draw at weight ≈ M/N (a few hundredths), and A⁻¹
/// overstated its variance by N/M; the sandwich gives the variance of the estimate the solves compute
/// (docs/optim/design-measurements.md, "Objects seen in a few pixels"). Infinite where the information matrix is singular or the object reaches no pixel.
pub fn standard_errors(
    ctx: &Ctx<'_>,
    x: &[f64],
    draw: &WeightedDraw,
    spp: u32,
    key: u64,
    objects: &[usize],
    averaged: usize,
) -> Result<Vec<[f64; 3]>, TracerError> {
    let k_count = x.len() / PER_OBJECT;
    let params = ctx.params(x);
    let pixels: Vec<PixelRef> = draw.samples.iter().map(|s| s.pixel).collect();
    let m = pixels.len();
    let mut out = vec![[f64::INFINITY; 3]; objects.len()];
    if m == 0 {
        return Ok(out);
    }
    let values = ctx.render(&params, &pixels, spp, key)?;
    let rows_a = jacobian::pixel_rows(ctx, &params, &pixels, spp, key ^ PROFILE_JACOBIAN)?;
    let rows_b = jacobian::pixel_rows(ctx, &params, &pixels, spp, key ^ PROFILE_JACOBIAN ^ SECOND_ESTIMATE)?;
    let weights: Vec<f64> = if draw.weights.len() == m { draw.weights.clone() } else { vec![1.0; m] };
    for c in 0..3 {
        // Unknowns: every base colour with a non-zero column, then every light's emission.
        let entry = |rows: &[jacobian::PixelRow], j: usize, v: usize| -> f64 {
            if v < k_count { rows[j].base_color[v][c] } else { rows[j].emission[v - k_count][c] }
        };
        let vars: Vec<usize> = (0..k_count)
            .filter(|&k| (0..m).any(|j| entry(&rows_a, j, k) != 0.0 || entry(&rows_b, j, k) != 0.0))
            .chain((0..k_count).filter(|&k| x[idx(k, EMISSION + c)] > 0.0).map(|k| k_count + k))
            .collect();
        // The information matrix (the sandwich's bread) from the two independent estimates' cross products,
        // ½(AᵀWB + BᵀWA): its expectation is that of the noise-free Jacobian, where AᵀWA would add each entry's
        // Monte Carlo variance to the diagonal and claim information that a faintly reached surface (a lamp
        // panel's own reflection) does not give.
        let n_all = vars.len();
        let mut gram = vec![0.0; n_all * n_all];
        let mut meat = vec![0.0; n_all * n_all];
        let (mut ra, mut rb) = (vec![0.0; n_all], vec![0.0; n_all]);
        let row_sigma = row_sigmas(draw, &values, c);
        for j in 0..m {
            // The pixels that see an unconstrained object itself (a few, often at its silhouette or beside a
            // lamp) are not information about its base colour: it is judged by what it reflects elsewhere.
            if draw.samples[j].object.is_some_and(|o| objects.contains(&(o as usize))) {
                continue;
            }
            for (i, &v) in vars.iter().enumerate() {
                ra[i] = entry(&rows_a, j, v);
                rb[i] = entry(&rows_b, j, v);
            }
            let nz: Vec<usize> = (0..n_all).filter(|&i| ra[i] != 0.0 || rb[i] != 0.0).collect();
            // The meat Σ w²σ² J Jᵀ from the same cross products: each estimate's own products would add the
            // Jacobian's Monte Carlo variance, which for a surface reached only through interreflection (a few
            // gradient paths per pixel) exceeds its mean square and made a well-determined ceiling's standard
            // error 0.8–27 instead of 0.02.
            let wn = weights[j] * weights[j] * row_sigma[j] * row_sigma[j];
            for &p in &nz {
                for &q in &nz {
                    gram[p * n_all + q] += weights[j] * 0.5 * (ra[p] * rb[q] + rb[p] * ra[q]) / m as f64;
                    meat[p * n_all + q] += wn * 0.5 * (ra[p] * rb[q] + rb[p] * ra[q]) / m as f64;
                }
            }
        }
        // A variable whose cross-product diagonal is not positive carries no information beyond its noise.
        let keep: Vec<usize> = (0..n_all).filter(|&i| gram[i * n_all + i] > 0.0).collect();
        let n = keep.len();
        let sub = |mat: &[f64]| -> Vec<f64> {
            keep.iter().flat_map(|&p| keep.iter().map(move |&q| (p, q))).map(|(p, q)| mat[p * n_all + q]).collect()
        };
        let (g, meat) = (sub(&gram), sub(&meat));
        let wanted: Vec<(usize, usize)> = objects
            .iter()
            .enumerate()
            .filter_map(|(o, &k)| keep.iter().position(|&i| vars[i] == k).map(|i| (o, i)))
            .collect();
        let idxs: Vec<usize> = wanted.iter().map(|&(_, i)| i).collect();
        let (variances, ridge) = ridged_sandwich(&g, &meat, n, &idxs);
        for (&(o, i), v) in wanted.iter().zip(variances) {
            out[o][c] = v.map_or(f64::INFINITY, |d| (d / (m * averaged.max(1)) as f64).sqrt());
            tracing::debug!(
                object = objects[o],
                channel = c,
                information = g[i * n + i],
                ridge,
                se = out[o][c],
                "unseen object's standard error"
            );
        }
    }
    Ok(out)
}

/// A variable keeps a variance from a ridged bread only where its own information is at least this many times
/// the ridge: the ridge then removes at most 1 − (10/11)² ≈ 17 % of its variance. Below it the ridge is most of
/// the variable's "information" and the sandwich's (g + r)⁻² · meat shrinks its variance towards 0 as its
/// column does: an object seen in 7 pixel centres, reached by almost no reflected path, came out at its start
/// value ± 0.000 and kept that value over its prior (docs/optim/design-measurements.md, "A ridge that
/// claimed information").
const RIDGE_DOMINANCE: f64 = 10.0;

/// The sandwich variances of the variables `idxs` of the bread `g` and meat `meat` (row-major n×n), `None`
/// for a variable the data do not determine. The cross-product bread need not be positive definite (noise); a
/// ridge of 10⁻⁶ of its largest diagonal entry, raised tenfold up to 10⁻², makes it so while shrinking no
/// well-determined variance measurably. A variable whose own diagonal is below [`RIDGE_DOMINANCE`] times the
/// ridge that was needed, or whose variance is not positive (the cross-product meat is unbiased but not
/// positive definite: such a variance is noise), gets `None`, as does every variable when no ridge makes the
/// bread factorisable. Returns the variances and the ridge.
fn ridged_sandwich(g: &[f64], meat: &[f64], n: usize, idxs: &[usize]) -> (Vec<Option<f64>>, f64) {
    let own = |i: usize| g[i * n + i];
    let scale = (0..n).map(own).fold(0.0f64, f64::max);
    let mut ridged = g.to_vec();
    let mut ridge = 0.0;
    let mut diag = None;
    for step in 0..6 {
        diag = sandwich_diagonal(&ridged, meat, n, idxs);
        if diag.is_some() {
            break;
        }
        let next = scale * 10f64.powi(step - 6);
        for i in 0..n {
            ridged[i * n + i] += next - ridge;
        }
        ridge = next;
    }
    let variances = match diag {
        Some(diag) => {
            idxs.iter().zip(diag).map(|(&i, d)| (d > 0.0 && own(i) >= RIDGE_DOMINANCE * ridge).then_some(d)).collect()
        }
        None => vec![None; idxs.len()],
    };
    (variances, ridge)
}

/// Per row of the draw, the standard deviation of its residual in channel `c`: the robust scale (1.4826 ·
/// median |photo − render|, the standard deviation of Gaussian residuals, robust to outliers) of the rows of the
/// same object, as the data term's Huber corner is per object; never below the scale of all rows, so that a
/// handful of rows that happen to agree claims no more precision than the scan's typical pixel; the scale of all
/// rows where the object has fewer than [`MIN_GROUP_ROWS`].
fn row_sigmas(draw: &WeightedDraw, values: &[glam::Vec3], c: usize) -> Vec<f64> {
    let m = draw.samples.len();
    let abs_res = |j: usize| (f64::from(draw.samples[j].target[c]) - f64::from(values[j][c])).abs();
    let robust = |mut r: Vec<f64>| {
        r.sort_by(f64::total_cmp);
        1.4826 * r[r.len() / 2]
    };
    let all = robust((0..m).map(abs_res).collect());
    let mut groups: std::collections::HashMap<Option<u32>, Vec<usize>> = std::collections::HashMap::new();
    for j in 0..m {
        groups.entry(draw.samples[j].object).or_default().push(j);
    }
    let mut out = vec![all; m];
    for rows in groups.values().filter(|r| r.len() >= MIN_GROUP_ROWS) {
        let own = robust(rows.iter().map(|&j| abs_res(j)).collect()).max(all);
        for &j in rows {
            out[j] = own;
        }
    }
    out
}

/// Rows an object needs in a draw for its own residual scale: a median of fewer says little about the spread.
const MIN_GROUP_ROWS: usize = 3;

#[cfg(test)]
mod tests {
    use super::*;

    fn scene_x(colors: &[[f64; 3]], emission: &[[f64; 3]]) -> Vec<f64> {
        let mut x = crate::fit::layout::initial(colors.len());
        for (k, (c, e)) in colors.iter().zip(emission).enumerate() {
            for i in 0..3 {
                x[idx(k, BASE_COLOR + i)] = c[i];
                x[idx(k, EMISSION + i)] = e[i];
            }
        }
        x
    }

    #[test]
    fn categories_are_the_leading_word() {
        assert_eq!(category("wall south").as_deref(), Some("wall"));
        assert_eq!(category("Wall_0002").as_deref(), Some("wall"));
        assert_eq!(category("light rectangle 31").as_deref(), Some("light"));
        assert_eq!(category("17"), None);
        assert_eq!(category(""), None);
    }

    #[test]
    fn the_prior_is_the_area_weighted_distribution_of_the_observed_category() {
        // Two observed walls (areas 1 and 3), an observed floor, an unseen wall and an unseen ceiling, and an
        // observed lamp whose emission keeps it out of every prior.
        let colors = [[0.2, 0.4, 0.6], [0.6, 0.4, 0.2], [0.1, 0.1, 0.1], [0.5; 3], [0.5; 3], [0.9; 3]];
        let emission = [[0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3], [5.0, 0.0, 0.0]];
        let x = scene_x(&colors, &emission);
        let cats = ["wall", "wall", "floor", "wall", "ceiling", "wall"].map(|s| Some(s.to_owned())).to_vec();
        let prior = UnseenPrior::from_parts(
            vec![1.0, 3.0, 4.0, 2.0, 2.0, 1.0],
            cats,
            vec![true, true, true, false, false, true],
        );
        assert_eq!(prior.unseen(), vec![3, 4]);
        // Unseen wall: mean (1·0.2 + 3·0.6)/4 = 0.5 with sd √((0.09 + 3·0.01)/4) = 0.173; 0.4 with no spread
        // (the floor of the sd); 0.3.
        let p = prior.prior(&x, 3);
        assert_eq!(p.source, PriorSource::SameCategory { category: "wall".into(), objects: 2 });
        for (got, want) in p.mean.iter().zip([0.5, 0.4, 0.3]) {
            assert!((got - want).abs() < 1e-12, "{p:?}");
        }
        assert!((p.sd[0] - 0.03f64.sqrt()).abs() < 1e-12 && p.sd[1] == MIN_PRIOR_SD, "{p:?}");
        // Unseen ceiling: no observed ceiling, so all three non-emitting observed objects (areas 1, 3, 4).
        let p = prior.prior(&x, 4);
        assert_eq!(p.source, PriorSource::AllObserved { objects: 3 });
        assert!((p.mean[0] - (0.2 + 1.8 + 0.4) / 8.0).abs() < 1e-12, "{p:?}");
    }

    #[test]
    fn the_prior_pools_the_objects_own_lobe_family_when_the_category_has_any() {
        // Observed spheres: a dielectric of 0.2 (area 1), a dielectric of 0.4 (area 1) and a metal of 0.9 (area
        // 2); an unseen dielectric sphere and an unseen metal one. Observed rods: a metal alone.
        let colors = [[0.2; 3], [0.4; 3], [0.9; 3], [0.5; 3], [0.5; 3], [0.7; 3], [0.5; 3]];
        let mut x = scene_x(&colors, &[[0.0; 3]; 7]);
        for k in [2, 4, 5] {
            x[idx(k, METALLIC)] = 1.0;
        }
        let cats =
            ["sphere", "sphere", "sphere", "sphere", "sphere", "rod", "rod"].map(|s| Some(s.to_owned())).to_vec();
        let observed = vec![true, true, true, false, false, true, false];
        let prior = UnseenPrior::from_parts(vec![1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 1.0], cats, observed);
        // The dielectric takes the two dielectric spheres' mean, 0.3, not the whole category's 0.6.
        let p = prior.prior(&x, 3);
        assert_eq!(p.source, PriorSource::SameCategory { category: "sphere".into(), objects: 3 });
        assert_eq!(p.family, Some((Family::Dielectric, 2)));
        assert!(p.mean.iter().all(|m| (m - 0.3).abs() < 1e-12), "{p:?}");
        assert!(p.describe_source().contains("the 2 dielectric ones among the 3 observed"), "{}", p.describe_source());
        // The metal takes the metal sphere.
        let p = prior.prior(&x, 4);
        assert_eq!(p.family, Some((Family::Metal, 1)));
        assert!(p.mean.iter().all(|m| (m - 0.9).abs() < 1e-12), "{p:?}");
        // The unseen dielectric rod: no observed rod of its family, so the whole category (the metal rod).
        let p = prior.prior(&x, 6);
        assert_eq!(p.family, None);
        assert!(p.mean.iter().all(|m| (m - 0.7).abs() < 1e-12), "{p:?}");
    }

    #[test]
    fn without_an_observed_non_emitter_the_start_value_is_an_uninformative_prior() {
        let x = scene_x(&[[0.9; 3], [0.3; 3]], &[[1.0; 3], [0.0; 3]]);
        let prior = UnseenPrior::from_parts(vec![1.0, 1.0], vec![None, None], vec![true, false]);
        let p = prior.prior(&x, 1);
        assert_eq!(p.source, PriorSource::StartValue);
        assert_eq!(p.mean, [0.3; 3]);
    }

    #[test]
    fn a_ridge_gives_no_variance_to_a_variable_it_determines() {
        // Well conditioned: no ridge, and the sandwich with meat = bread is the inverse's diagonal.
        let g = vec![2.0, 0.5, 0.5, 1.0];
        let (v, ridge) = ridged_sandwich(&g, &[2.0, 0.5, 0.5, 1.0], 2, &[0, 1]);
        assert_eq!(ridge, 0.0);
        assert!((v[0].unwrap() - 1.0 / 1.75).abs() < 1e-12 && (v[1].unwrap() - 2.0 / 1.75).abs() < 1e-12, "{v:?}");
        // A variable with 10⁻¹⁴ of the largest information forces a ridge of 10⁻⁶; its sandwich through the
        // ridge would be 10⁻¹⁴σ²/10⁻¹² = 0.01σ², a hundred times more precise than the data can make it
        // (σ²/10⁻¹⁴). It is left undetermined; the well-determined variable keeps its variance.
        let (info, sigma2) = (1e-14, 4.0);
        let g = vec![1.0, 0.0, 0.0, info];
        let meat = [sigma2, 0.0, 0.0, info * sigma2];
        let (v, ridge) = ridged_sandwich(&g, &meat, 2, &[0, 1]);
        assert_eq!(ridge, 1e-6);
        assert!((v[0].unwrap() - sigma2).abs() < 1e-4 * sigma2, "{v:?}");
        assert_eq!(v[1], None);
        // A bread made indefinite by noise (a near-collinear pair) needs a ridge of 10⁻³: the pair keeps
        // variances, a third variable with information 10⁻⁴ (below 10 ridges) does not.
        let g = vec![1.0, 1.0, 0.0, 1.0, 1.0 - 1e-3, 0.0, 0.0, 0.0, 1e-4];
        let meat = [1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1e-4];
        let (v, ridge) = ridged_sandwich(&g, &meat, 3, &[0, 1, 2]);
        assert_eq!(ridge, 1e-3);
        assert!(v[0].is_some_and(|d| d > 0.0) && v[1].is_some_and(|d| d > 0.0) && v[2].is_none(), "{v:?}");
    }

    #[test]
    fn the_combination_weighs_estimate_and_prior_by_their_precision() {
        let prior =
            Prior { mean: [0.5; 3], sd: [0.2; 3], source: PriorSource::AllObserved { objects: 4 }, family: None };
        // A precise estimate wins, one with the prior's precision meets it halfway, none at all gives the prior.
        let (v, w) = combine([0.9; 3], [0.002, 0.2, f64::INFINITY], &prior);
        assert!((v[0] - 0.9).abs() < 1e-3 && w[0] > 0.999, "{v:?} {w:?}");
        assert!((v[1] - 0.7).abs() < 1e-12 && (w[1] - 0.5).abs() < 1e-12, "{v:?} {w:?}");
        assert_eq!((v[2], w[2]), (0.5, 0.0));
        // Weights (1, 0.8, 0): the data decide on average.
        let (v, w) = combine([0.9; 3], [0.002, 0.1, f64::INFINITY], &prior);
        let text = describe(v, [0.9; 3], [0.002, 0.1, f64::INFINITY], w, &prior);
        assert!(text.contains("estimated from the light it reflects"), "{text}");
        let (v, w) = combine([0.9; 3], [1.0; 3], &prior);
        assert!(describe(v, [0.9; 3], [1.0; 3], w, &prior).contains("mostly a prior"));
    }
}
