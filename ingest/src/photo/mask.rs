//! Validity-mask rules shared by linearisation, bracket merging and undistortion.

/// A display-referred pixel is saturated when any channel reaches this fraction of its code range. The sensor
/// (or film scan) clips near the top and the response curve is unreliable there; 0.98 of the 8-bit range is
/// code 250 (249/255 = 0.976 is kept, 250/255 = 0.980 is not).
pub const SATURATION_FRACTION: f64 = 0.98;

/// Whether any channel of `codes` (code values in `0..=max_code`) is at or near saturation.
#[must_use]
pub fn is_saturated(codes: [u16; 3], max_code: u16) -> bool {
    // Integer comparison against the smallest saturated code avoids float rounding at the boundary:
    // code >= 0.98 * max  <=>  code >= ceil(0.98 * max).
    let limit = saturation_code(max_code);
    codes.iter().any(|&c| c >= limit)
}

/// The smallest saturated code for a code range `0..=max_code` (250 for 8-bit, 64225 for 16-bit).
#[must_use]
pub fn saturation_code(max_code: u16) -> u16 {
    // 0.98 * max is below max, so the ceiling fits in u16.
    (SATURATION_FRACTION * f64::from(max_code) - 1e-9).ceil() as u16
}

/// After bilinear remapping of a 0/1 validity mask, an output pixel is valid only when every source pixel with
/// nonzero interpolation weight was valid, i.e. the remapped value is 1. OpenCV's `remap` quantises the
/// sub-pixel position to 1/32 per axis (INTER_BITS = 5), so each nonzero bilinear weight is a multiple of
/// 1/1024 and one invalid neighbour lowers the value to at most 1 - 1/1024. Half of that step separates the
/// two cases robustly against float summation error (~1e-7).
pub const REMAPPED_VALID_MIN: f32 = 1.0 - 1.0 / 2048.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saturation_boundary_8_bit_is_250() {
        assert_eq!(saturation_code(255), 250);
        assert!(!is_saturated([249, 249, 249], 255));
        assert!(is_saturated([0, 250, 0], 255));
        assert!(is_saturated([0, 0, 255], 255));
    }

    #[test]
    fn saturation_boundary_16_bit_is_98_percent() {
        let c = saturation_code(65535);
        assert!(f64::from(c) >= 0.98 * 65535.0);
        assert!(f64::from(c - 1) < 0.98 * 65535.0);
    }
}
