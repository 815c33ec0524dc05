//! The scalar type the BRDF formulas are written over. The renderer instantiates them with `f32`; the tests
//! instantiate the very same code with `f64` as a reference for finite differences and round-off checks.

use std::fmt::Debug;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A real number: `f32` in the renderer, `f64` in reference computations.
pub(crate) trait Real:
    Copy
    + Debug
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// A literal constant (rounded to the type).
    fn lit(x: f64) -> Self;
    /// `sqrt(max(0, x))`: arguments negative only by round-off give 0, not NaN.
    fn safe_sqrt(self) -> Self;
    /// The smaller of the two (NaN-ignoring like `f32::min`).
    fn min_r(self, other: Self) -> Self;
}

impl Real for f32 {
    #[inline]
    fn lit(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn safe_sqrt(self) -> Self {
        crate::numerics::safe_sqrt(self)
    }
    #[inline]
    fn min_r(self, other: Self) -> Self {
        self.min(other)
    }
}

impl Real for f64 {
    #[inline]
    fn lit(x: f64) -> Self {
        x
    }
    #[inline]
    fn safe_sqrt(self) -> Self {
        self.max(0.0).sqrt()
    }
    #[inline]
    fn min_r(self, other: Self) -> Self {
        self.min(other)
    }
}

/// x⁵, the Schlick weight's power, by two squarings.
#[inline]
#[must_use]
pub(crate) fn pow5<T: Real>(x: T) -> T {
    let x2 = x * x;
    x2 * x2 * x
}
