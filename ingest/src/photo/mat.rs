//! Copies between our interleaved buffers and OpenCV `Mat`s (owned, continuous).

use opencv::core::{CV_8UC3, CV_32FC1, CV_32FC3, Mat, MatTraitConst, MatTraitConstManual, MatTraitManual, Scalar};

use super::OpError;

fn dims(width: u32, height: u32) -> Result<(i32, i32), OpError> {
    let w = i32::try_from(width).map_err(|_| OpError::Invalid(format!("width {width} too large for OpenCV")))?;
    let h = i32::try_from(height).map_err(|_| OpError::Invalid(format!("height {height} too large for OpenCV")))?;
    Ok((w, h))
}

fn zeros(width: u32, height: u32, typ: i32) -> Result<Mat, OpError> {
    let (w, h) = dims(width, height)?;
    Mat::new_rows_cols_with_default(h, w, typ, Scalar::all(0.0)).map_err(OpError::cv("Mat allocation"))
}

/// Copies f32 values into a freshly allocated (continuous) float Mat of matching size. Goes through bytes
/// because `data_typed_mut::<f32>` refuses multi-channel Mats.
fn copy_f32(m: &mut Mat, values: &[f32]) -> Result<(), OpError> {
    let bytes = m.data_bytes_mut().map_err(OpError::cv("Mat access"))?;
    if bytes.len() != 4 * values.len() {
        return Err(OpError::Invalid(format!("Mat holds {} floats, got {}", bytes.len() / 4, values.len())));
    }
    for (dst, v) in bytes.chunks_exact_mut(4).zip(values) {
        dst.copy_from_slice(&v.to_ne_bytes());
    }
    Ok(())
}

/// Interleaved f32 RGB → CV_32FC3.
pub(crate) fn rgb_f32_to_mat(width: u32, height: u32, rgb: &[f32]) -> Result<Mat, OpError> {
    let mut m = zeros(width, height, CV_32FC3)?;
    copy_f32(&mut m, rgb)?;
    Ok(m)
}

/// One f32 channel → CV_32FC1.
pub(crate) fn f32_to_mat(width: u32, height: u32, values: &[f32]) -> Result<Mat, OpError> {
    let mut m = zeros(width, height, CV_32FC1)?;
    copy_f32(&mut m, values)?;
    Ok(m)
}

/// Interleaved u8 RGB → CV_8UC3.
pub(crate) fn rgb_u8_to_mat(width: u32, height: u32, rgb: &[u8]) -> Result<Mat, OpError> {
    let mut m = zeros(width, height, CV_8UC3)?;
    m.data_bytes_mut().map_err(OpError::cv("Mat access"))?.copy_from_slice(rgb);
    Ok(m)
}

/// Any continuous f32 Mat → its values (channels interleaved).
pub(crate) fn mat_to_f32(m: &Mat, expected_len: usize) -> Result<Vec<f32>, OpError> {
    let owned;
    let m = if m.is_continuous() {
        m
    } else {
        owned = m.try_clone().map_err(OpError::cv("Mat clone"))?;
        &owned
    };
    // `data_typed::<f32>` checks the depth only for single-channel element types, so check it here.
    if m.depth() != opencv::core::CV_32F {
        return Err(OpError::Invalid(format!("expected a float Mat, got depth {}", m.depth())));
    }
    let bytes = m.data_bytes().map_err(OpError::cv("Mat access"))?;
    if bytes.len() != 4 * expected_len {
        return Err(OpError::Invalid(format!("Mat holds {} floats, expected {expected_len}", bytes.len() / 4)));
    }
    Ok(bytes.chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect())
}
