//! The Saint Venant–Kirchhoff law as a function of the deformation gradient `F` only:
//! `E = ½(FᵀF − I)`, `S = λ tr(E) I + 2μ E`, `P = F S`, `Ψ = μ tr(E²) + ½ λ (tr E)²`.

use nalgebra::Matrix3;

use crate::error::{Error, Parameter};
use crate::real::Real;

/// Lamé parameters of an isotropic material, in pascals.
///
/// Built by [`Lame::from_young_poisson`], they satisfy `μ > 0` and `3λ + 2μ > 0` (the bulk
/// modulus `K = λ + 2μ/3` is positive), which makes the material part of the SVK tangent
/// positive semidefinite even when `λ < 0` (Poisson ratio below zero). The fields are public
/// for callers that know their Lamé pair directly; values outside that range are accepted by
/// the element functions, and [`TangentProjection::PositiveDefinite`](super::TangentProjection::PositiveDefinite) clamps them (see there).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lame<T> {
    /// Shear modulus `μ` (Pa).
    pub mu: T,
    /// First Lamé parameter `λ` (Pa); negative for a negative Poisson ratio.
    pub lambda: T,
}

impl<T: Real> Lame<T> {
    /// Converts Young's modulus `young` (Pa) and the Poisson ratio `poisson` (dimensionless)
    /// into `μ = E / (2(1 + ν))` and `λ = E ν / ((1 + ν)(1 − 2ν))`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming [`Parameter::YoungModulus`] unless `young` is positive
    /// and finite (or `μ` overflows), naming [`Parameter::PoissonRatio`] unless
    /// `-1 < poisson < 0.5` (or `λ` overflows because `ν` is too close to `0.5`).
    pub fn from_young_poisson(young: T, poisson: T) -> Result<Self, Error> {
        let young_bad = Error::InvalidParameter {
            parameter: Parameter::YoungModulus,
        };
        let poisson_bad = Error::InvalidParameter {
            parameter: Parameter::PoissonRatio,
        };
        // Written so that NaN fails every test.
        if !(young.finite() && young > T::zero()) {
            return Err(young_bad);
        }
        if !(poisson.finite() && poisson > -T::one() && poisson < T::of(0.5)) {
            return Err(poisson_bad);
        }
        let one = T::one();
        let mu = young / (T::of(2.0) * (one + poisson));
        if !(mu.finite() && mu > T::zero()) {
            return Err(young_bad);
        }
        let lambda = young * poisson / ((one + poisson) * (one - T::of(2.0) * poisson));
        if !lambda.finite() {
            return Err(poisson_bad);
        }
        Ok(Lame { mu, lambda })
    }
}

/// Green–Lagrange strain `E = ½(FᵀF − I)` (dimensionless, symmetric).
pub fn green_strain<T: Real>(f: &Matrix3<T>) -> Matrix3<T> {
    (f.transpose() * f - Matrix3::identity()) * T::of(0.5)
}

/// SVK strain energy density `Ψ = μ tr(E²) + ½ λ (tr E)²` (J/m³) at deformation gradient `f`.
///
/// `tr(E²) = E : E` because `E` is symmetric. Zero for every rotation.
pub fn energy_density<T: Real>(lame: &Lame<T>, f: &Matrix3<T>) -> T {
    let e = green_strain(f);
    let tr = e.trace();
    lame.mu * e.norm_squared() + T::of(0.5) * lame.lambda * tr * tr
}

/// Second Piola–Kirchhoff stress `S = λ tr(E) I + 2μ E` (Pa, symmetric) at `f`.
pub fn second_piola_kirchhoff<T: Real>(lame: &Lame<T>, f: &Matrix3<T>) -> Matrix3<T> {
    stress_from_strain(lame, &green_strain(f))
}

/// First Piola–Kirchhoff stress `P = F S = ∂Ψ/∂F` (Pa) at `f`.
pub fn first_piola_kirchhoff<T: Real>(lame: &Lame<T>, f: &Matrix3<T>) -> Matrix3<T> {
    f * second_piola_kirchhoff(lame, f)
}

pub(crate) fn stress_from_strain<T: Real>(lame: &Lame<T>, e: &Matrix3<T>) -> Matrix3<T> {
    Matrix3::from_diagonal_element(lame.lambda * e.trace()) + e * (T::of(2.0) * lame.mu)
}

/// Green strain from the displacement gradient, `E = ½(H + Hᵀ + HᵀH)`: the same as
/// [`green_strain`] of `I + H`, without subtracting `I` from a number near it.
pub(crate) fn green_strain_of_displacement<T: Real>(h: &Matrix3<T>) -> Matrix3<T> {
    (h + h.transpose() + h.transpose() * h) * T::of(0.5)
}

pub(crate) fn energy_density_of_strain<T: Real>(lame: &Lame<T>, e: &Matrix3<T>) -> T {
    let tr = e.trace();
    lame.mu * e.norm_squared() + T::of(0.5) * lame.lambda * tr * tr
}
