//! Hyperelasticity on linear tetrahedra: Saint Venant–Kirchhoff (the paper's law) and a stable
//! Neo-Hookean law ([`Law`]).
//!
//! Kept in layers, as fenris keeps element, material and assembly apart, so that each can be
//! read and tested on its own:
//!
//! 1. **Material** (`law`: [`Lame`], [`green_strain`], [`energy_density`],
//!    [`second_piola_kirchhoff`], [`first_piola_kirchhoff`]): the law as a function of the
//!    deformation gradient `F` only, `E = ½(FᵀF − I)`, `S = λ tr(E) I + 2μ E`, `P = F S`,
//!    `Ψ = μ tr(E²) + ½ λ (tr E)²`.
//! 2. **Element geometry** (`element`: [`ElementRest`], [`deformation_gradient`]): the rest
//!    shape of one tetrahedron, `Dm = [X1 − X0, X2 − X0, X3 − X0]`, its inverse, its volume and
//!    the constant shape gradients `g_a` with `F = Σ_a x_a g_aᵀ`.
//! 3. **Element quantities** (here: [`element_energy`], [`element_gradient`],
//!    [`element_energy_gradient_tangent`]): `W = V Ψ(F)`, its gradient `∂W/∂x_a = V P g_a` and
//!    its 12 × 12 tangent, the latter optionally made positive semidefinite
//!    ([`TangentProjection`]) so that the assembled stiffness can be handed to a Cholesky /
//!    LDLᵀ factorization; the projection's small dense kernel, a fixed-cost closed-form 3 × 3
//!    eigen-solve, is `eigen3`.
//! 4. **Inversion barrier** (`barrier`: [`InversionBarrier`]): an energy on `det F`, zero
//!    unless an element is compressed below a floor, that SVK lacks; the assembly adds it to
//!    the element quantities above when the model's material asks for it.
//! 5. **Another law** (`neohookean`, chosen by [`Law`]): a stable Neo-Hookean law with the same
//!    three element quantities, its tangent projected through the law's analytic eigensystem;
//!    [`Law`]'s methods are what the assembly calls, so it reads the same for either law.
//!
//! Units: positions in metres, Lamé parameters and stresses in pascals, energy density in J/m³,
//! element energy in joules, gradient (force) in newtons, tangent in N/m.
//!
//! SVK is a polynomial in `F`, so every quantity here is finite for finite, moderately sized
//! inputs, including inverted (`det F < 0`) and collapsed (`F = 0`) elements: nothing divides by
//! a quantity of the current configuration. The one place that divides, the eigen-solve of
//! the positive semidefinite projection, scales the stress by its largest entry first and
//! guards each of its divisors.

mod barrier;
mod eigen3;
mod element;
mod law;
#[cfg(feature = "neo-hookean")]
mod neohookean;
#[cfg(feature = "paired-elements")]
mod paired;

use nalgebra::{Matrix3, Vector3};

use crate::real::Real;
use eigen3::positive_part_closed_form;
use law::{energy_density_of_strain, green_strain_of_displacement, stress_from_strain};

pub use barrier::InversionBarrier;
pub use element::{ElementRest, deformation_gradient, displacement_gradient};
pub use law::{Lame, energy_density, first_piola_kirchhoff, green_strain, second_piola_kirchhoff};
#[cfg(feature = "neo-hookean")]
pub use neohookean::{neo_hookean_energy_density, neo_hookean_first_piola_kirchhoff};
#[cfg(feature = "paired-elements")]
pub(crate) use paired::{ElementShare, svk_shares_of_two};

/// The strain energy law of the model's material. Both laws take the same Lamé pair and agree
/// for small strains; they differ as the strain grows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Law {
    /// Saint Venant–Kirchhoff, the paper's: `Ψ = μ tr(E²) + ½ λ (tr E)²`. Cheap, and exact
    /// for large rotations, but under a large stretch it contracts sideways far more than
    /// rubber or tissue, and it softens to nothing under strong compression (hence the
    /// [`InversionBarrier`]).
    #[default]
    SaintVenantKirchhoff,
    /// A stable Neo-Hookean law, `Ψ = μ/2 (‖F‖² − 3) − μ (J − 1) + (λ + μ)/2 (J − 1)²`
    /// (Smith, de Goes and Kim 2018, without its logarithmic term): the lateral contraction
    /// of rubber under stretch, a restoring volume term under compression and inversion, and
    /// a tangent projected onto its nearest positive semidefinite matrix through the law's
    /// analytic eigensystem (the module `neohookean`). Built with the `neo-hookean` feature.
    StableNeoHookean,
}

impl Law {
    /// Whether this core was built with the law (SVK always; the stable Neo-Hookean law with
    /// the `neo-hookean` feature). `Model::new` refuses a law that is not, naming
    /// [`crate::Parameter::Law`]; the element functions below take it for SVK.
    pub const fn is_built(self) -> bool {
        match self {
            Law::SaintVenantKirchhoff => true,
            Law::StableNeoHookean => cfg!(feature = "neo-hookean"),
        }
    }

    /// Element energy `W = V Ψ` (J) from the displacement gradient `h`.
    pub(crate) fn element_energy_of_h<T: Real>(
        self,
        lame: &Lame<T>,
        volume: T,
        h: &Matrix3<T>,
    ) -> T {
        match self {
            #[cfg(feature = "neo-hookean")]
            Law::StableNeoHookean => volume * neohookean::energy_density_of_h(lame, h),
            _ => element_energy_of_h(lame, volume, h),
        }
    }

    /// Element gradient `∂W/∂x_a` (N) from the displacement gradient `h`.
    // The assembly forms the gradient from the summed stress; the tests check it against this,
    // so it is built with them only (the unit tests compute in `f64`).
    #[cfg(all(test, feature = "f64"))]
    pub(crate) fn element_gradient_of_h<T: Real>(
        self,
        lame: &Lame<T>,
        volume: T,
        g: &[Vector3<T>; 4],
        h: &Matrix3<T>,
    ) -> [Vector3<T>; 4] {
        match self {
            #[cfg(feature = "neo-hookean")]
            Law::StableNeoHookean => {
                gradient_from_stress(volume, &neohookean::first_piola_of_h(lame, h), g)
            }
            _ => element_gradient_of_h(lame, volume, g, h),
        }
    }

    /// Element energy `W = V Ψ` (J) and first Piola–Kirchhoff stress `P` (Pa) from the
    /// displacement gradient `h`: what a gradient without tangent needs, the energy bit for bit
    /// [`Law::element_energy_of_h`]'s. SVK forms the strain once for both; a caller adds what
    /// else stresses the element (the [`InversionBarrier`]) to `P` and forms the nodes'
    /// gradient once from the sum ([`element_gradient_of_stress`]).
    #[inline(always)]
    pub(crate) fn element_energy_stress_of_h<T: Real>(
        self,
        lame: &Lame<T>,
        volume: T,
        h: &Matrix3<T>,
    ) -> (T, Matrix3<T>) {
        match self {
            #[cfg(feature = "neo-hookean")]
            Law::StableNeoHookean => (
                self.element_energy_of_h(lame, volume, h),
                neohookean::first_piola_of_h(lame, h),
            ),
            _ => {
                let e = green_strain_of_displacement(h);
                (
                    volume * energy_density_of_strain(lame, &e),
                    (Matrix3::identity() + h) * stress_from_strain(lame, &e),
                )
            }
        }
    }

    /// Energy, gradient and upper tangent blocks of one element from its displacement
    /// gradient `h`: the assembly's element kernel.
    pub(crate) fn element_eval_upper_of_h<T: Real>(
        self,
        lame: &Lame<T>,
        volume: T,
        g: &[Vector3<T>; 4],
        h: &Matrix3<T>,
        projection: TangentProjection,
    ) -> UpperEval<T> {
        match self {
            #[cfg(feature = "neo-hookean")]
            Law::StableNeoHookean => {
                neohookean::element_eval_upper_of_h(lame, volume, g, h, projection)
            }
            _ => element_eval_upper_of_h(lame, volume, g, h, projection),
        }
    }

    /// Energy, gradient and 12 × 12 tangent of one element under this law (node displacements
    /// `u` from rest, metres), as [`element_energy_gradient_tangent`] computes them for SVK;
    /// a law this core was not built with ([`Law::is_built`]) is taken for SVK.
    pub fn element_energy_gradient_tangent<T: Real>(
        self,
        lame: &Lame<T>,
        rest: &ElementRest<T>,
        g: &[Vector3<T>; 4],
        u: &[[T; 3]; 4],
        projection: TangentProjection,
    ) -> ElementEval<T> {
        let upper = self.element_eval_upper_of_h(
            lame,
            rest.volume,
            g,
            &displacement_gradient(u, g),
            projection,
        );
        ElementEval {
            energy: upper.energy,
            gradient: upper.gradient,
            tangent: full_tangent(&upper.blocks),
        }
    }
}

/// Which tangent [`element_energy_gradient_tangent`] returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TangentProjection {
    /// The exact Hessian of the element energy; indefinite under strong compression or
    /// inversion.
    Exact,
    /// A positive semidefinite modification, cheap and PSD by construction:
    ///
    /// - The geometric term `(g_aᵀ S g_b) I` uses `S⁺ = Q max(Λ, 0) Qᵀ` in place of `S`, from a
    ///   fixed-cost closed-form eigen-decomposition `S = Q Λ Qᵀ`. As a quadratic form it is
    ///   `Σ_i v_iᵀ S⁺ v_i` over the rows `v_i` of `δF`, hence PSD. When no eigenvalue of `S` is
    ///   negative, `S` itself is used, so the tangent is then the exact one. The eigen-solve
    ///   runs for every element, so a frame's cost does not follow the strain; the
    ///   `psd-shortcut` feature skips it for a positive definite `S` (Sylvester's criterion,
    ///   three leading minors).
    /// - The material term is `V (λ (tr δE)² + 2μ |δE|²)`, `δE = sym(Fᵀ δF)`, which splits into
    ///   `V (2μ |dev δE|² + (λ + 2μ/3)(tr δE)²)`: PSD whenever `μ ≥ 0` and `3λ + 2μ ≥ 0`, which
    ///   every [`Lame::from_young_poisson`] pair satisfies, including `λ < 0` for `ν < 0`. So
    ///   `λ` is kept as is; only for hand-made pairs outside that range the term uses
    ///   `μ⁺ = max(μ, 0)` and `λ⁺ = max(λ, −2μ⁺/3)`.
    PositiveDefinite,
}

/// Energy, gradient and tangent of one element, from [`element_energy_gradient_tangent`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementEval<T> {
    /// Element energy `W = V Ψ(F)` (J).
    pub energy: T,
    /// `∂W/∂x_a = V P g_a` (N) for local nodes `a = 0..3`; they sum to zero exactly.
    pub gradient: [Vector3<T>; 4],
    /// `tangent[a][b] = ∂²W/∂x_a∂x_b` (N/m), a `3 × 3` block; rows index the components of
    /// `x_a`. `tangent[b][a]` is exactly `tangent[a][b]ᵀ`.
    pub tangent: [[Matrix3<T>; 4]; 4],
}

/// Element energy `W = V Ψ(F)` (J) alone: the cheap evaluation a line search needs.
///
/// `g` comes from `rest.shape_gradients()`, `u` holds the node displacements from rest
/// (metres).
pub fn element_energy<T: Real>(
    lame: &Lame<T>,
    rest: &ElementRest<T>,
    g: &[Vector3<T>; 4],
    u: &[[T; 3]; 4],
) -> T {
    element_energy_of_h(lame, rest.volume, &displacement_gradient(u, g))
}

/// [`element_energy`] from the displacement gradient `h` (the assembly computes it once per
/// element and hands it to the inversion barrier too).
pub(crate) fn element_energy_of_h<T: Real>(lame: &Lame<T>, volume: T, h: &Matrix3<T>) -> T {
    volume * energy_density_of_strain(lame, &green_strain_of_displacement(h))
}

/// Element gradient `∂W/∂x_a = V P g_a` (N), `a = 0..3`, without the tangent.
///
/// The node-0 entry is formed as `−(f_1 + f_2 + f_3)` (equal because `Σ_a g_a = 0`) so that
/// the element forces balance exactly.
pub fn element_gradient<T: Real>(
    lame: &Lame<T>,
    rest: &ElementRest<T>,
    g: &[Vector3<T>; 4],
    u: &[[T; 3]; 4],
) -> [Vector3<T>; 4] {
    element_gradient_of_h(lame, rest.volume, g, &displacement_gradient(u, g))
}

/// [`element_gradient`] from the displacement gradient `h`, as [`element_energy_of_h`].
pub(crate) fn element_gradient_of_h<T: Real>(
    lame: &Lame<T>,
    volume: T,
    g: &[Vector3<T>; 4],
    h: &Matrix3<T>,
) -> [Vector3<T>; 4] {
    let s = stress_from_strain(lame, &green_strain_of_displacement(h));
    gradient_from_stress(volume, &((Matrix3::identity() + h) * s), g)
}

/// Element gradient `∂W/∂x_a = V P g_a` (N) of the stress `p`, the node-0 entry
/// `−(f_1 + f_2 + f_3)` as in [`element_gradient`]. Inlined always, as the kernels of a
/// gradient-only assembly are (see [`Law::element_energy_stress_of_h`]).
#[inline(always)]
pub(crate) fn element_gradient_of_stress<T: Real>(
    volume: T,
    p: &Matrix3<T>,
    g: &[Vector3<T>; 4],
) -> [Vector3<T>; 4] {
    gradient_from_stress(volume, p, g)
}

#[inline(always)]
fn gradient_from_stress<T: Real>(
    volume: T,
    p: &Matrix3<T>,
    g: &[Vector3<T>; 4],
) -> [Vector3<T>; 4] {
    let vp = p * volume;
    let (f1, f2, f3) = (vp * g[1], vp * g[2], vp * g[3]);
    [-(f1 + f2 + f3), f1, f2, f3]
}

/// Energy, gradient and 12 × 12 tangent of one element (node displacements `u` from rest,
/// metres) from a single `F`: the per-frame assembly calls this once per element.
///
/// With `f_a = F g_a`, the tangent blocks are
/// `K_ab = V [(g_aᵀ S g_b) I + λ f_a f_bᵀ + μ f_b f_aᵀ + μ (g_a · g_b) F Fᵀ]`
/// (the first term geometric, the rest material), modified per `projection`. The cost is
/// bounded independently of the data: the projection runs the same closed-form eigen-solve, and
/// is skipped (cheaper, never dearer) when the stress is positive definite.
pub fn element_energy_gradient_tangent<T: Real>(
    lame: &Lame<T>,
    rest: &ElementRest<T>,
    g: &[Vector3<T>; 4],
    u: &[[T; 3]; 4],
    projection: TangentProjection,
) -> ElementEval<T> {
    Law::SaintVenantKirchhoff.element_energy_gradient_tangent(lame, rest, g, u, projection)
}

/// The ten node pairs `(a, b)`, `a ≤ b`, of a tetrahedron whose `3 × 3` tangent blocks are
/// stored: the diagonal blocks first, then the pairs in row order. The stiffness pattern is
/// symmetric and stored upper, so the assembly needs no other block.
pub(crate) const PAIRS: [(usize, usize); 10] = [
    (0, 0),
    (1, 1),
    (2, 2),
    (3, 3),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 2),
    (1, 3),
    (2, 3),
];

/// An element's energy, gradient and the tangent blocks `K_ab` of the node pairs [`PAIRS`]
/// (`a ≤ b`, `K_ba = K_abᵀ`): what the assembly reads, without the six transposed blocks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct UpperEval<T> {
    pub energy: T,
    pub gradient: [Vector3<T>; 4],
    /// `blocks[k] = K_ab` for `(a, b) = PAIRS[k]`.
    pub blocks: [Matrix3<T>; 10],
}

/// The full `4 × 4` array of blocks from the upper ones. A diagonal block is read from its
/// upper triangle, as the assembly reads it (the upper pattern stores no other entry), and
/// mirrored: the scaled outer products round each of its two triangles differently.
pub(crate) fn full_tangent<T: Real>(blocks: &[Matrix3<T>; 10]) -> [[Matrix3<T>; 4]; 4] {
    let mut tangent = [[Matrix3::zeros(); 4]; 4];
    for (&(a, b), block) in PAIRS.iter().zip(blocks) {
        let block = if a == b {
            block.upper_triangle() + block.upper_triangle().transpose()
                - Matrix3::from_diagonal(&block.diagonal())
        } else {
            *block
        };
        // `a`, `b` < 4 (the pairs of a tetrahedron's nodes).
        if let Some(k_ab) = tangent.get_mut(a).and_then(|row| row.get_mut(b)) {
            *k_ab = block;
        }
        if let Some(k_ba) = tangent.get_mut(b).and_then(|row| row.get_mut(a)) {
            *k_ba = block.transpose();
        }
    }
    tangent
}

/// Energy, gradient and the upper tangent blocks ([`UpperEval`]) of one element from its
/// displacement gradient `h`: the per-frame assembly's element kernel.
///
/// The factors that every block shares are scaled once, so that a block costs three outer
/// products and no further scaling:
/// `K_ab = (g_a · V S g_b) I + (λV f_a) f_bᵀ + (μV f_b) f_aᵀ + (μV g_a · g_b) F Fᵀ`.
pub(crate) fn element_eval_upper_of_h<T: Real>(
    lame: &Lame<T>,
    v: T,
    g: &[Vector3<T>; 4],
    h: &Matrix3<T>,
    projection: TangentProjection,
) -> UpperEval<T> {
    let f = Matrix3::identity() + h;
    let e = green_strain_of_displacement(h);
    let energy = v * energy_density_of_strain(lame, &e);
    let s = stress_from_strain(lame, &e);
    let gradient = gradient_from_stress(v, &(f * s), g);

    let (s_geo, mu, lambda) = match projection {
        TangentProjection::Exact => (s, lame.mu, lame.lambda),
        TangentProjection::PositiveDefinite => {
            let mu = lame.mu.max(T::zero());
            let lambda = lame.lambda.max(-T::of(2.0 / 3.0) * mu);
            (positive_part(&s), mu, lambda)
        }
    };

    let fg = g.map(|ga| f * ga);
    let (lv, mv) = (lambda * v, mu * v);
    let lfg = fg.map(|x| x * lv);
    let mfg = fg.map(|x| x * mv);
    let s_geo = s_geo * v;
    let sg = g.map(|gb| s_geo * gb);
    let ff = f * f.transpose();
    let mut blocks = [Matrix3::zeros(); 10];
    for (&(a, b), block) in PAIRS.iter().zip(blocks.iter_mut()) {
        // `a`, `b` < 4 (the pairs of a tetrahedron's nodes).
        let (Some(ga), Some(gb), Some(sgb), Some(fa), Some(fb), Some(lfa), Some(mfb)) = (
            g.get(a),
            g.get(b),
            sg.get(b),
            fg.get(a),
            fg.get(b),
            lfg.get(a),
            mfg.get(b),
        ) else {
            continue;
        };
        let mut k = lfa * fb.transpose() + mfb * fa.transpose() + ff * (mv * ga.dot(gb));
        let geometric = ga.dot(sgb);
        k.m11 += geometric;
        k.m22 += geometric;
        k.m33 += geometric;
        *block = k;
    }
    UpperEval {
        energy,
        gradient,
        blocks,
    }
}

/// `S⁺ = Q max(Λ, 0) Qᵀ`, or `s` itself when no eigenvalue is negative (so the projected
/// tangent equals the exact one for a positive semidefinite stress).
///
/// Every element runs the eigen-solve, so that a frame's cost does not depend on how its
/// elements are strained: every frame of one topology costs the same (issue 14). The
/// `psd-shortcut` feature skips it where [`positive_definite`] says the result is `s` anyway:
/// 6–8 % fewer instructions in a typical frame of the committed scenes, the same worst case,
/// but a frame's cost then follows the strain.
fn positive_part<T: Real>(s: &Matrix3<T>) -> Matrix3<T> {
    if cfg!(feature = "psd-shortcut") && positive_definite(s) {
        return *s;
    }
    positive_part_closed_form(s)
}

/// Whether symmetric `s` is positive definite, by Sylvester's criterion (its leading principal
/// minors positive): the eigen-solve would then keep `s` as it is. A tensile stress, the common
/// case of a pulled organ, is.
fn positive_definite<T: Real>(s: &Matrix3<T>) -> bool {
    let minor2 = s[(0, 0)] * s[(1, 1)] - s[(0, 1)] * s[(1, 0)];
    s[(0, 0)] > T::zero() && minor2 > T::zero() && s.determinant() > T::zero()
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests;
