//! Checks that a camera-to-world matrix read from a file is a rigid motion (rotation + translation).

use glam::{DMat3, DMat4, DVec4};

/// Largest deviation of `RᵀR` from the identity accepted as "orthonormal". Files print poses with about six
/// significant digits, which perturbs `RᵀR` by ~1e-5; 1e-3 leaves margin for that while still rejecting any
/// scale or shear above 0.1 %.
const ORTHONORMAL_TOL: f64 = 1e-3;

/// Below this |det R| the 3×3 part is treated as singular (non-invertible): a rigid rotation has det 1, and
/// anything this small means the matrix collapses a dimension.
const SINGULAR_DET: f64 = 1e-6;

/// Tolerance on the last row being exactly `0 0 0 1` (text files write these as integers; 1e-6 absorbs
/// printing round-off in files that write them as floats).
const LAST_ROW_TOL: f64 = 1e-6;

/// Returns `Err(reason)` unless `m` is finite, invertible and rigid (orthonormal rotation with det +1 and a last
/// row of `0 0 0 1`). The reason is a short phrase for an error message.
pub fn check_rigid(m: &DMat4) -> Result<(), String> {
    if !m.to_cols_array().iter().all(|v| v.is_finite()) {
        return Err("pose has NaN or infinite entries".into());
    }
    let last_row = m.row(3);
    if (last_row - DVec4::new(0.0, 0.0, 0.0, 1.0)).abs().max_element() > LAST_ROW_TOL {
        return Err(format!("pose is not affine: last row is {last_row:?}, expected 0 0 0 1"));
    }
    let r = DMat3::from_mat4(*m);
    let det = r.determinant();
    if det.abs() < SINGULAR_DET {
        return Err(format!("pose is not invertible (rotation determinant {det:e})"));
    }
    let rtr = r.transpose() * r;
    let dev = (rtr - DMat3::IDENTITY).to_cols_array().iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    if dev > ORTHONORMAL_TOL {
        return Err(format!(
            "pose is not rigid: rotation part is not orthonormal (max |RᵀR - I| = {dev:.3e}, scale or shear)"
        ));
    }
    if det < 0.0 {
        return Err("pose is not rigid: rotation part is a reflection (determinant -1)".into());
    }
    Ok(())
}

/// Builds a matrix from 16 row-major values (the layout every text pose format here uses).
#[must_use]
pub fn from_row_major(v: &[f64; 16]) -> DMat4 {
    DMat4::from_cols_array(v).transpose()
}
