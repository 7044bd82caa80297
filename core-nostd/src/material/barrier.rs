//! A volumetric barrier against element inversion, added to the SVK energy.
//!
//! SVK has no resistance to inversion: a tetrahedron reflected through a face is stress-free,
//! and under uniaxial compression to stretch `s` the SVK stress `(λ + 2μ) s (s² − 1) / 2`
//! peaks at `s = 1/√3` and falls to zero at `s = 0`. Strong feature springs can therefore pull
//! the model through itself, and elements stay inside out after the pull is gone. The barrier
//! takes over where SVK softens: with `J = det F` and floor `J₀`, it adds the energy density
//!
//! `ψ(J) = κ (J₀ − J)³ / (3 J₀²)` for `J < J₀`, zero above,
//!
//! so that `ψ`, `ψ'` and `ψ''` are continuous at the floor (the Newton tangent has no jump),
//! and the pressure it exerts, `ψ'(J) = −κ (J₀ − J)² / J₀²`, reaches `−κ` at a flat element and
//! keeps growing (quadratically in `J`) through inversion, which pushes an inverted element
//! back out. It never becomes infinite: a barrier that did would turn a frame that starts
//! inverted (after a cut, or from a user's positions) into an error.
//!
//! [`InversionBarrier::for_material`] sets `J₀ = 1/√3`, the compression at which SVK's
//! resistance peaks, and `κ = λ + 2μ` (the P-wave modulus, about five times that peak), so
//! elements compressed less than that see exactly the SVK model.
//!
//! With `C = cof F` (so `∂J/∂F = C`, and `∂J/∂x_a = C g_a`), an element of rest volume `V`
//! adds `V ψ` to the energy, `V ψ' C g_a` to the gradient at node `a`, and to the tangent block
//! `K_ab` the positive semidefinite `V ψ'' (C g_a)(C g_b)ᵀ` and, in the exact tangent only, the
//! indefinite `V ψ' [F (g_a × g_b)]ₓᵀ` (the second derivative of `det`). The projected tangent
//! leaves the latter out (a Gauss–Newton step on `J`), so it stays positive semidefinite.

use nalgebra::{Matrix3, Vector3};

use super::{ElementEval, Lame, PAIRS, TangentProjection, UpperEval, full_tangent};
use crate::real::Real;

/// The barrier's floor `J₀` and stiffness `κ` (Pa); see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InversionBarrier<T> {
    /// The volume ratio `J₀` below which the barrier acts, in `(0, 1]`.
    pub floor: T,
    /// `κ`, the pressure (Pa) the barrier exerts on a flat element.
    pub stiffness: T,
}

impl<T: Real> InversionBarrier<T> {
    /// `J₀ = 1/√3` (where SVK's uniaxial resistance peaks) and `κ = λ + 2μ`.
    pub fn for_material(lame: &Lame<T>) -> Self {
        InversionBarrier {
            floor: T::of(3.0).sqrt().recip(),
            stiffness: lame.lambda + T::of(2.0) * lame.mu,
        }
    }

    /// `(ψ(J), ψ'(J), ψ''(J))` at `J = j`: all three zero at or above the floor (and for a NaN
    /// `j`, whose NaN the SVK part carries on).
    pub fn density(&self, j: T) -> (T, T, T) {
        let gap = if j < self.floor {
            self.floor - j
        } else {
            T::zero()
        };
        let scale = self.stiffness / (self.floor * self.floor);
        (
            scale * gap * gap * gap / T::of(3.0),
            -scale * gap * gap,
            T::of(2.0) * scale * gap,
        )
    }

    /// What the gradient and the tangent share: `F = I + h`, the density and its derivatives
    /// at `det F`, and the cofactor of `F` (the derivative of `det F`).
    #[inline(always)]
    fn strained(&self, h: &Matrix3<T>) -> Strained<T> {
        let f = Matrix3::identity() + h;
        let (psi, dpsi, d2psi) = self.density(f.determinant());
        Strained {
            f,
            psi,
            dpsi,
            d2psi,
            c: cofactor(&f),
        }
    }

    // The element functions below do the same work whatever `J` is (above the floor they add
    // exact zeros), so that a frame's cost does not depend on how its elements are strained:
    // every frame of one topology costs the same, as the rest of the assembly does.

    /// The element's barrier energy `V ψ(J)` (J), zero at or above the floor, from its rest
    /// `volume` and its displacement gradient `h` ([`super::displacement_gradient`], which the
    /// SVK part computes anyway: `F = I + h`).
    pub fn element_energy(&self, volume: T, h: &Matrix3<T>) -> T {
        let f = Matrix3::identity() + h;
        let (psi, _, _) = self.density(f.determinant());
        volume * psi
    }

    /// Adds the element's barrier energy and gradient to `energy` and `gradient` (zeros at or
    /// above the floor); `g` are the element's shape gradients, `h` as in
    /// [`InversionBarrier::element_energy`].
    pub fn add_element_gradient(
        &self,
        volume: T,
        g: &[Vector3<T>; 4],
        h: &Matrix3<T>,
        energy: &mut T,
        gradient: &mut [Vector3<T>; 4],
    ) {
        let Strained { psi, dpsi, c, .. } = self.strained(h);
        *energy += volume * psi;
        // The same operations in the same order as `add_element_tangent`: both give the same
        // gradient, bit for bit.
        for (ga, out) in g.iter().zip(gradient.iter_mut()) {
            *out += c * ga * (volume * dpsi);
        }
    }

    /// Adds the element's barrier energy to `energy` and its stress `ψ'(J) cof F` to `p` (zeros
    /// at or above the floor), `h` as in [`InversionBarrier::element_energy`]: for a gradient
    /// formed once from the element's whole stress. Inlined always, as the other kernels of a
    /// gradient-only assembly are.
    #[inline(always)]
    pub(crate) fn add_element_stress(
        &self,
        volume: T,
        h: &Matrix3<T>,
        energy: &mut T,
        p: &mut Matrix3<T>,
    ) {
        let Strained { psi, dpsi, c, .. } = self.strained(h);
        *energy += volume * psi;
        *p += c * dpsi;
    }

    /// Adds the element's barrier energy, gradient and tangent (see the module documentation
    /// for what `projection` leaves out) to `eval` (zeros at or above the floor).
    pub fn add_element_tangent(
        &self,
        volume: T,
        g: &[Vector3<T>; 4],
        h: &Matrix3<T>,
        projection: TangentProjection,
        eval: &mut ElementEval<T>,
    ) {
        let mut upper = UpperEval {
            energy: eval.energy,
            gradient: eval.gradient,
            blocks: [Matrix3::zeros(); 10],
        };
        self.add_upper_tangent(volume, g, h, projection, &mut upper);
        eval.energy = upper.energy;
        eval.gradient = upper.gradient;
        for (row, added) in eval.tangent.iter_mut().zip(full_tangent(&upper.blocks)) {
            for (k, block) in row.iter_mut().zip(added) {
                *k += block;
            }
        }
    }

    /// [`InversionBarrier::add_element_tangent`] on the upper blocks the assembly reads.
    pub(crate) fn add_upper_tangent(
        &self,
        volume: T,
        g: &[Vector3<T>; 4],
        h: &Matrix3<T>,
        projection: TangentProjection,
        eval: &mut UpperEval<T>,
    ) {
        let Strained {
            f,
            psi,
            dpsi,
            d2psi,
            c,
        } = self.strained(h);
        eval.energy += volume * psi;
        let cg = g.map(|ga| c * ga);
        for (cga, out) in cg.iter().zip(eval.gradient.iter_mut()) {
            *out += cga * (volume * dpsi);
        }
        let exact = projection == TangentProjection::Exact;
        // `V ψ'' C g_a`, so that each block is one outer product.
        let scaled = cg.map(|v| v * (volume * d2psi));
        for (&(a, b), k_ab) in PAIRS.iter().zip(eval.blocks.iter_mut()) {
            // `a`, `b` < 4 (the pairs of a tetrahedron's nodes).
            let (Some(sa), Some(cgb), Some(ga), Some(gb)) =
                (scaled.get(a), cg.get(b), g.get(a), g.get(b))
            else {
                continue;
            };
            *k_ab += sa * cgb.transpose();
            if exact {
                *k_ab += (f * ga.cross(gb)).cross_matrix().transpose() * (volume * dpsi);
            }
        }
    }
}

/// An element's deformation as the barrier reads it ([`InversionBarrier::strained`]).
struct Strained<T: Real> {
    f: Matrix3<T>,
    psi: T,
    dpsi: T,
    d2psi: T,
    /// The cofactor of `f`.
    c: Matrix3<T>,
}

/// The cofactor matrix of `f`, `det(f) f⁻ᵀ` without the division: its columns are the cross
/// products of `f`'s other two columns.
fn cofactor<T: Real>(f: &Matrix3<T>) -> Matrix3<T> {
    let (c0, c1, c2) = (f.column(0), f.column(1), f.column(2));
    Matrix3::from_columns(&[c1.cross(&c2), c2.cross(&c0), c0.cross(&c1)])
}
