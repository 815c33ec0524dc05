//! Front end for an aligned exposure bracket: every photo shows the same static view on the same pixels, so
//! a pixel position is a scene point seen once per photo. Pixel positions are sampled (seeded) and turned into
//! [`Observation`]s; the photos form one camera group and vignetting is not estimated (every photo sees a point
//! at the same radius, so vignetting is indistinguishable from radiance).

use super::{CalibrateError, Calibration, CalibrationOptions, Observation, SplitMix64, calibrate};
use crate::photo::image_io::DisplayImage;

/// Pixel positions sampled uniformly: 2000 points × N photos × 3 channels is ample for ~150 unknowns
/// (response knots and gains) while keeping the solve well under a second.
const SAMPLES: usize = 2000;
/// Further positions per photo among its well-exposed pixels: in a wide bracket the darkest photos are
/// well exposed only on a few bright objects (a window), which uniform sampling hits a few dozen times —
/// too few to tie those photos' exposures to the rest within a few percent.
const SAMPLES_PER_PHOTO: usize = 400;
/// Well exposed: every channel within these codes (fractions of the code range), the middle of the range
/// where the response is fitted (see `model::START_CODES`).
const WELL_EXPOSED: (f64, f64) = (40.0 / 255.0, 216.0 / 255.0);

/// Of each photo's well-exposed pixels, the smoothest tenth (by [`roughness`]) are sampled. The photos of a
/// bracket may be registered by hand (or by a homography fitted to features) to within a pixel or so; at an
/// edge that turns into errors of many codes that do not average out (the same edge is mis-registered the same
/// way in every pair) and bias the exposure ratios of the photos that are well exposed only on a few bright,
/// edged objects. A fraction rather than a code threshold adapts to the scene's texture; a tenth still leaves
/// thousands of candidates per photo at 0.4 megapixels (on the Memorial bracket, the quarter and the half
/// gave worse ratios: docs/photo/self-calibration.md).
const SMOOTH_FRACTION: f64 = 0.1;

/// Largest code difference, over channels, between pixel `i` and its 3×3 neighbours.
fn roughness(img: &DisplayImage, i: usize) -> u16 {
    let w = img.width as usize;
    let h = img.height as usize;
    let (x, y) = (i % w, i / w);
    let mut m = 0u16;
    for yy in y.saturating_sub(1)..(y + 2).min(h) {
        for xx in x.saturating_sub(1)..(x + 2).min(w) {
            let j = yy * w + xx;
            for c in 0..3 {
                m = m.max(img.codes[3 * j + c].abs_diff(img.codes[3 * i + c]));
            }
        }
    }
    m
}

/// Calibrates an aligned bracket (≥ 2 images of equal size): samples pixel positions with `opts.seed` ([`SAMPLES`]
/// uniformly, [`SAMPLES_PER_PHOTO`] among the smoothest [`SMOOTH_FRACTION`] of each photo's well-exposed pixels) and calls [`calibrate`] with one camera
/// group and `vignetting` off. Pixels invalid (alpha 0) in an image are left out of that image.
pub fn calibrate_bracket(images: &[DisplayImage], opts: &CalibrationOptions) -> Result<Calibration, CalibrateError> {
    let Some(first) = images.first() else {
        return Err(CalibrateError::Bracket("no images".into()));
    };
    if images.len() < 2 {
        return Err(CalibrateError::Bracket(format!("needs at least 2 images, got {}", images.len())));
    }
    if let Some((i, img)) =
        images.iter().enumerate().find(|(_, img)| (img.width, img.height) != (first.width, first.height))
    {
        return Err(CalibrateError::Bracket(format!(
            "image {i} is {}x{}, image 0 is {}x{}",
            img.width, img.height, first.width, first.height
        )));
    }
    let pixels = first.width as usize * first.height as usize;
    if pixels == 0 {
        return Err(CalibrateError::Bracket("images are empty".into()));
    }
    let mut rng = SplitMix64(opts.seed);
    let mut positions: Vec<usize> =
        (0..SAMPLES.min(pixels)).map(|_| (rng.next_u64() % pixels as u64) as usize).collect();
    for img in images {
        let max = f64::from(img.max_code.max(1));
        let mut well: Vec<(u16, usize)> = (0..pixels)
            .filter(|&i| {
                img.mask[i] != 0
                    && img.codes[3 * i..3 * i + 3]
                        .iter()
                        .all(|&z| (WELL_EXPOSED.0..=WELL_EXPOSED.1).contains(&(f64::from(z) / max)))
            })
            .map(|i| (roughness(img, i), i))
            .collect();
        well.sort_unstable();
        let keep = ((well.len() as f64 * SMOOTH_FRACTION).ceil() as usize).min(well.len());
        let well: Vec<usize> = well[..keep].iter().map(|w| w.1).collect();
        if !well.is_empty() {
            positions.extend((0..SAMPLES_PER_PHOTO).map(|_| well[(rng.next_u64() % well.len() as u64) as usize]));
        }
    }
    positions.sort_unstable();
    positions.dedup();
    let mut observations = Vec::with_capacity(positions.len() * images.len());
    for (point, &i) in positions.iter().enumerate() {
        for (photo, img) in images.iter().enumerate() {
            if img.mask[i] == 0 || img.max_code == 0 {
                continue;
            }
            let max = f32::from(img.max_code);
            let value = std::array::from_fn(|c| f32::from(img.codes[3 * i + c]) / max);
            observations.push(Observation { point: point as u32, photo: photo as u32, r2: 0.0, value });
        }
    }
    let opts = CalibrationOptions { vignetting: false, ..opts.clone() };
    calibrate(&vec![0; images.len()], &observations, &opts)
}
