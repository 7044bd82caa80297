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
    /// Bits of [`Real::order_key`] that can differ: the type's width.
    const KEY_BITS: u32;
    /// An integer key in the order of the values: `a < b` exactly when
    /// `a.order_key() < b.order_key()` for finite `a`, `b` (`-0.0` and `+0.0` share a key),
    /// and every non-finite value (`±∞`, NaN) has the largest key, after every finite one.
    /// The key fits in the low [`Real::KEY_BITS`] bits. What the radix selection of
    /// [`crate::robust::select_in`] sorts by.
    fn order_key(self) -> u64;
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
    const KEY_BITS: u32 = 64;
    #[inline]
    fn order_key(self) -> u64 {
        if !self.is_finite() {
            return u64::MAX;
        }
        // `+ 0.0` turns `-0.0` into `+0.0`. A negative value's bits, flipped, order it
        // before the positives and reverse the order of the magnitudes.
        let bits = (self + 0.0).to_bits();
        if bits >> 63 == 1 {
            !bits
        } else {
            bits | 1 << 63
        }
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
    const KEY_BITS: u32 = 32;
    #[inline]
    fn order_key(self) -> u64 {
        if !self.is_finite() {
            return u64::from(u32::MAX);
        }
        // As for `f64`, on the 32 bits of an `f32`.
        let bits = (self + 0.0).to_bits();
        u64::from(if bits >> 31 == 1 {
            !bits
        } else {
            bits | 1 << 31
        })
    }
}
