//! The scalar type of the core: `f32` (feature `f32`) or `f64` (feature `f64`).
//!
//! The core is generic over it, and a build holds only the types it instantiates; the features
//! make the choice a guarantee: a build with `f32` alone cannot compute in `f64` by mistake.

/// A real scalar the core computes in. Implemented for `f32` and `f64` (features `f32`, `f64`).
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
    /// Four-quadrant arctangent of `self / x`, computed by the `libm` crate in every build.
    ///
    /// Not nalgebra's `atan2`: a host that links `std` switches nalgebra (by feature
    /// unification) to the platform's C library, whose transcendental functions may differ
    /// from `libm`'s in the last bit, and a firmware build would no longer compute the same
    /// bits as the host ([`crate::Model::from_precomputed`], `tests/firmware.rs`). Square
    /// roots need no such care: they are correctly rounded everywhere.
    fn libm_atan2(self, x: Self) -> Self;
    /// Sine and cosine, by the `libm` crate in every build (see [`Real::libm_atan2`]).
    fn libm_sin_cos(self) -> (Self, Self);
}

#[cfg(feature = "f64")]
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
    #[inline]
    fn libm_atan2(self, x: Self) -> Self {
        libm::atan2(self, x)
    }
    #[inline]
    fn libm_sin_cos(self) -> (Self, Self) {
        libm::sincos(self)
    }
}

#[cfg(feature = "f32")]
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
    #[inline]
    fn libm_atan2(self, x: Self) -> Self {
        libm::atan2f(self, x)
    }
    #[inline]
    fn libm_sin_cos(self) -> (Self, Self) {
        libm::sincosf(self)
    }
}
