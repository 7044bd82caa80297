//! The scalar type of the core: `f32` or `f64`.

#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

/// A real scalar the core computes in. Implemented for `f32` and `f64`.
///
/// It is nalgebra's [`RealField`](nalgebra::RealField) (so small fixed-size matrices work) plus
/// the few conversions and checks the core needs without `std`.
pub trait Real: nalgebra::RealField + Copy + Default {
    /// Converts an `f64` constant (rounding for `f32`).
    fn of(x: f64) -> Self;
    /// Widens to `f64` (for reports).
    fn to_f64(self) -> f64;
    /// `true` unless NaN or infinite.
    fn finite(self) -> bool;
    /// Machine epsilon.
    const EPS: Self;
}

impl Real for f64 {
    #[inline]
    fn of(x: f64) -> Self {
        x
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    const EPS: Self = f64::EPSILON;
}

impl Real for f32 {
    #[inline]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    const EPS: Self = f32::EPSILON;
}
