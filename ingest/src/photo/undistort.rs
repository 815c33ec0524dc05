//! Undistortion of linear images with OpenCV: `getOptimalNewCameraMatrix` → `initUndistortRectifyMap` →
//! `remap` (bilinear, on linear values), to a pinhole camera whose intrinsics replace the original ones.
//!
//! **alpha = 0.** `getOptimalNewCameraMatrix` chooses the new intrinsics so that (up to its sampling of the
//! border) every output pixel has a source pixel: no black corners, at the cost of cropping the outermost
//! distorted field of view. alpha = 1 would keep every source pixel but leave large invalid regions that cost
//! memory and tracing time while contributing nothing to the loss. The few output pixels that still fall
//! outside the source (OpenCV samples the border on a coarse grid) are caught by remapping the mask.
//!
//! **Mask.** The 0/1 validity mask is remapped with the same bilinear weights and a zero border; an output
//! pixel stays valid only if the result is 1, i.e. every source pixel with nonzero weight was valid and inside
//! the image (see [`super::mask::REMAPPED_VALID_MIN`]). Invalid (e.g. saturated) pixels therefore never leak
//! into valid output pixels.

use opencv::calib3d;
use opencv::core::{BORDER_CONSTANT, CV_32FC1, CV_64F, Mat, MatTraitConst, Scalar, Size};
use opencv::imgproc;

use super::mask::REMAPPED_VALID_MIN;
use super::{LinearImage, OpError, mat};
use crate::camera::{Camera, Distortion, Intrinsics};

/// `getOptimalNewCameraMatrix` free-scaling parameter: 0 = only valid pixels in the output (see module docs).
pub const ALPHA: f64 = 0.0;

fn camera_matrix(k: &Intrinsics) -> Result<Mat, OpError> {
    Mat::from_slice_2d(&[[k.fx, 0.0, k.cx], [0.0, k.fy, k.cy], [0.0, 0.0, 1.0]]).map_err(OpError::cv("Mat from K"))
}

fn dist_coeffs(d: &Distortion) -> Result<Mat, OpError> {
    let c = d.coefficients();
    // 5 coefficients select OpenCV's plain Brown-Conrady model; 8 add the rational denominator k4..k6.
    let used = if c[5..].iter().all(|&x| x == 0.0) { &c[..5] } else { &c[..] };
    Mat::from_slice(used).and_then(|m| m.try_clone()).map_err(OpError::cv("Mat from distortion"))
}

fn image_size(camera: &Camera) -> Result<Size, OpError> {
    let w = i32::try_from(camera.width).map_err(|_| OpError::Invalid("camera width too large".into()))?;
    let h = i32::try_from(camera.height).map_err(|_| OpError::Invalid("camera height too large".into()))?;
    Ok(Size::new(w, h))
}

fn optimal_new_matrix(camera: &Camera) -> Result<Mat, OpError> {
    let k = camera_matrix(&camera.intrinsics)?;
    let d = dist_coeffs(&camera.distortion)?;
    let size = image_size(camera)?;
    calib3d::get_optimal_new_camera_matrix(&k, &d, size, ALPHA, size, None, false)
        .map_err(OpError::cv("getOptimalNewCameraMatrix"))
}

fn intrinsics_of(m: &Mat) -> Result<Intrinsics, OpError> {
    if m.typ() != CV_64F || m.rows() != 3 || m.cols() != 3 {
        return Err(OpError::Invalid("getOptimalNewCameraMatrix did not return a 3x3 double matrix".into()));
    }
    let at = |r, c| m.at_2d::<f64>(r, c).copied().map_err(OpError::cv("Mat access"));
    let k = Intrinsics { fx: at(0, 0)?, fy: at(1, 1)?, cx: at(0, 2)?, cy: at(1, 2)? };
    if [k.fx, k.fy, k.cx, k.cy].iter().any(|v| !v.is_finite()) || k.fx <= 0.0 || k.fy <= 0.0 {
        return Err(OpError::Invalid(format!("OpenCV returned unusable new intrinsics {k:?}")));
    }
    Ok(k)
}

/// The pinhole intrinsics (same image size) that [`undistort`] produces for `camera`.
pub fn optimal_new_intrinsics(camera: &Camera) -> Result<Intrinsics, OpError> {
    intrinsics_of(&optimal_new_matrix(camera)?)
}

/// Undistorts a linear image taken by `camera`. Returns the pinhole camera of the result (same size and pose,
/// new intrinsics, zero distortion) and the image with its remapped mask. A camera without distortion is
/// returned unchanged with a copy of the image.
pub fn undistort(image: &LinearImage, camera: &Camera) -> Result<(Camera, LinearImage), OpError> {
    if (image.width, image.height) != (camera.width, camera.height) {
        return Err(OpError::Invalid(format!(
            "image is {}x{} but camera is {}x{}",
            image.width, image.height, camera.width, camera.height
        )));
    }
    if camera.distortion.is_identity() {
        return Ok((*camera, image.clone()));
    }
    let k = camera_matrix(&camera.intrinsics)?;
    let d = dist_coeffs(&camera.distortion)?;
    let size = image_size(camera)?;
    let new_k = optimal_new_matrix(camera)?;
    let intrinsics = intrinsics_of(&new_k)?;

    let mut map_x = Mat::default();
    let mut map_y = Mat::default();
    calib3d::init_undistort_rectify_map(
        &k,
        &d,
        &opencv::core::no_array(),
        &new_k,
        size,
        CV_32FC1,
        &mut map_x,
        &mut map_y,
    )
    .map_err(OpError::cv("initUndistortRectifyMap"))?;

    let (w, h) = (image.width, image.height);
    let src = mat::rgb_f32_to_mat(w, h, &image.rgb)?;
    let mut dst = Mat::default();
    imgproc::remap(&src, &mut dst, &map_x, &map_y, imgproc::INTER_LINEAR, BORDER_CONSTANT, Scalar::all(0.0))
        .map_err(OpError::cv("remap (image)"))?;
    let rgb = mat::mat_to_f32(&dst, image.rgb.len())?;

    let mask_f: Vec<f32> = image.mask.iter().map(|&m| if m != 0 { 1.0 } else { 0.0 }).collect();
    let mask_src = mat::f32_to_mat(w, h, &mask_f)?;
    let mut mask_dst = Mat::default();
    imgproc::remap(&mask_src, &mut mask_dst, &map_x, &map_y, imgproc::INTER_LINEAR, BORDER_CONSTANT, Scalar::all(0.0))
        .map_err(OpError::cv("remap (mask)"))?;
    let mask: Vec<u8> =
        mat::mat_to_f32(&mask_dst, image.mask.len())?.iter().map(|&v| u8::from(v >= REMAPPED_VALID_MIN)).collect();

    let camera = Camera { intrinsics, distortion: Distortion::default(), ..*camera };
    Ok((camera, LinearImage::new(w, h, rgb, mask)?))
}
