//! The sRGB transfer function (IEC 61966-2-1) and 8-bit quantisation: the one home of the curve in the
//! workspace. `ingest` decodes display-referred photos with it ([`crate::photo::linearise`]); `pipeline`
//! encodes its viewer-facing outputs with it (PLY `red green blue`, `albedo.png`, the glTF base-colour texture,
//! the images of report.html). Linear values are the physics; the encoded ones are for display only.

/// Linear [0, 1] → sRGB-encoded [0, 1]; input is clamped to [0, 1] first (8-bit encodings cannot hold more).
#[must_use]
pub fn encode(linear: f32) -> f32 {
    let c = linear.clamp(0.0, 1.0);
    // 0.0031308 and 12.92 are the breakpoint and slope of the standard's linear segment.
    if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

/// sRGB-encoded [0, 1] → linear (the inverse of [`encode`] on [0, 1]).
#[must_use]
pub fn decode(encoded: f32) -> f32 {
    let s = encoded.clamp(0.0, 1.0);
    // 0.04045 = 12.92 · 0.0031308, the breakpoint on the encoded side.
    if s <= 0.040_45 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) }
}

/// A [0, 1] value (clamped) to the nearest 8-bit code.
#[must_use]
pub fn to_u8(unit: f32) -> u8 {
    // Clamped to [0, 1], so the rounded product is in [0, 255] and the cast is exact.
    (unit.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Linear → 8-bit sRGB code.
#[must_use]
pub fn linear_to_srgb8(linear: f32) -> u8 {
    to_u8(encode(linear))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_known_points() {
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            assert!((decode(encode(x)) - x).abs() < 1e-5, "{x}");
        }
        // Mid grey: linear 0.214 is sRGB ≈ 0.5 (the familiar "18% grey looks half").
        assert!((encode(0.214_041_14) - 0.5).abs() < 1e-4);
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(2.0), 255);
        assert_eq!(linear_to_srgb8(-1.0), 0);
        // The two segments meet continuously.
        assert!((encode(0.003_130_8) - (1.055 * 0.003_130_8_f32.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6);
    }

    #[test]
    fn srgb_curve_is_continuous_at_the_breakpoint() {
        let srgb_to_linear = decode;
        let below = srgb_to_linear(0.04045);
        let above = srgb_to_linear(0.040_450_1);
        assert!((below - above).abs() < 1e-6, "{below} vs {above}");
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
    }
}
