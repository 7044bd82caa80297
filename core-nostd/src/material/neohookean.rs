//! A stable Neo-Hookean law: `Ψ = μ/2 (‖F‖² − 3) − μ (J − 1) + λ'/2 (J − 1)²`, `J = det F`,
//! `λ' = λ + μ` (Smith, de Goes and Kim, "Stable Neo-Hookean Flesh Simulation", 2018, without
//! its logarithmic term, and shifted so that `Ψ(I) = 0`).
//!
//! Why a second law: under a large stretch Saint Venant–Kirchhoff contracts sideways far more
//! than rubber or tissue does (pulled by 65 % with `ν = 0.45`, its lateral stretch is 0.47
//! against 0.79 for a Neo-Hookean solid), and it softens to nothing under strong compression.
//! This law linearizes to the same Lamé pair (`μ`, `λ`) at rest, so it agrees with SVK for
//! small strains, and it is a polynomial in `F` like SVK: finite for inverted (`J < 0`) and
//! collapsed elements, nothing divides by a quantity of the current configuration, and its
//! `(J − 1)²` term pushes an inverted element back out.
//!
//! Written in the displacement gradient `H = F − I`, so that no quantity near 1 is subtracted
//! from 1 (what `f32` needs near rest): `‖F‖² − 3 = 2 tr H + ‖H‖²`, `J − 1 = tr H + i₂(H) +
//! det H` with `i₂(H) = ½((tr H)² − tr H²)`, and the `μ tr H` terms of the first two parts
//! cancel exactly, leaving `Ψ = μ/2 ‖H‖² − μ (i₂(H) + det H) + λ'/2 (J − 1)²`.
//!
//! Stress: `P = μ F + s cof F` with `s = λ' (J − 1) − μ`, computed as
//! `μ (H + Hᵀ − tr(H) I − cof H) + λ' (J − 1) cof F` (`cof(I + H) = I + tr(H) I − Hᵀ + cof H`).
//!
//! Tangent: `d²Ψ[δF, δF] = μ ‖δF‖² + λ' (cof F : δF)² + s d²J[δF, δF]`, and for
//! `δF = u g_aᵀ`, `δF' = w g_bᵀ` the last is `(u × w) · F (g_a × g_b)`: the element block
//! `K_ab = V [μ (g_a · g_b) I + λ' (cof F g_a)(cof F g_b)ᵀ − s [F (g_a × g_b)]ₓ]`. The first
//! two parts are positive semidefinite; `s d²J` is not. Its projection uses the law's analytic
//! eigensystem (Smith, de Goes and Kim, "Analytic Eigensystems for Isotropic Distortion
//! Energies", 2019): in the frame of the signed singular value decomposition `F = U Σ Vᵀ` the
//! Hessian splits into a 3 × 3 block on the three scalings, `μ I + λ' c cᵀ + s A` with
//! `c = (σ₁σ₂, σ₀σ₂, σ₀σ₁)` and `A` the matrix with `σ₂, σ₁, σ₀` off its diagonal, and three
//! 2 × 2 blocks, one per pair `(i, j)` of axes, on the twist and the flip about the third axis
//! `k`, with eigenvalues `μ + s σ_k` and `μ − s σ_k`. Each eigenvalue is clamped at zero (the
//! nearest positive semidefinite matrix), exactly the Hessian where none is negative.

use nalgebra::{Matrix3, Vector3};

use super::eigen3::symmetric_eigen3;
use super::law::Lame;
use super::{PAIRS, TangentProjection, UpperEval};
use crate::real::Real;

/// `λ' = λ + μ`, the weight of `(J − 1)²` that gives the law the Lamé pair `(μ, λ)` at rest.
fn volume_weight<T: Real>(lame: &Lame<T>) -> T {
    lame.lambda + lame.mu
}

/// The cofactor matrix `cof A = det(A) A⁻ᵀ` without a division: its columns are the cross
/// products of `A`'s columns (`cof A = [a₁ × a₂, a₂ × a₀, a₀ × a₁]`).
pub(crate) fn cofactor<T: Real>(a: &Matrix3<T>) -> Matrix3<T> {
    let (c0, c1, c2) = (a.column(0), a.column(1), a.column(2));
    Matrix3::from_columns(&[c1.cross(&c2), c2.cross(&c0), c0.cross(&c1)])
}

/// `J − 1` for `F = I + H`, as `tr H + i₂(H) + det H`.
fn volume_change<T: Real>(h: &Matrix3<T>) -> T {
    let tr = h.trace();
    let i2 = T::of(0.5) * (tr * tr - (h * h).trace());
    tr + i2 + h.determinant()
}

/// Energy density `Ψ` (J/m³) at the displacement gradient `h` (`F = I + H`).
pub(crate) fn energy_density_of_h<T: Real>(lame: &Lame<T>, h: &Matrix3<T>) -> T {
    let tr = h.trace();
    let i2 = T::of(0.5) * (tr * tr - (h * h).trace());
    let dj = tr + i2 + h.determinant();
    T::of(0.5) * lame.mu * h.norm_squared() - lame.mu * (i2 + h.determinant())
        + T::of(0.5) * volume_weight(lame) * dj * dj
}

/// First Piola–Kirchhoff stress `P = ∂Ψ/∂F` (Pa) at the displacement gradient `h`.
pub(crate) fn first_piola_of_h<T: Real>(lame: &Lame<T>, h: &Matrix3<T>) -> Matrix3<T> {
    let f = Matrix3::identity() + h;
    let shear = h + h.transpose() - Matrix3::from_diagonal_element(h.trace()) - cofactor(h);
    shear * lame.mu + cofactor(&f) * (volume_weight(lame) * volume_change(h))
}

/// Stable Neo-Hookean energy density `Ψ` (J/m³) at deformation gradient `f`.
pub fn neo_hookean_energy_density<T: Real>(lame: &Lame<T>, f: &Matrix3<T>) -> T {
    energy_density_of_h(lame, &(f - Matrix3::identity()))
}

/// Stable Neo-Hookean first Piola–Kirchhoff stress `P = μ F + (λ' (J − 1) − μ) cof F` (Pa) at
/// deformation gradient `f`.
pub fn neo_hookean_first_piola_kirchhoff<T: Real>(lame: &Lame<T>, f: &Matrix3<T>) -> Matrix3<T> {
    first_piola_of_h(lame, &(f - Matrix3::identity()))
}

/// Energy, gradient and upper tangent blocks of one element (rest volume `v`, shape gradients
/// `g`, displacement gradient `h`): the Neo-Hookean counterpart of
/// [`super::element_eval_upper_of_h`].
pub(crate) fn element_eval_upper_of_h<T: Real>(
    lame: &Lame<T>,
    v: T,
    g: &[Vector3<T>; 4],
    h: &Matrix3<T>,
    projection: TangentProjection,
) -> UpperEval<T> {
    let energy = v * energy_density_of_h(lame, h);
    let p = first_piola_of_h(lame, h);
    let gradient = super::gradient_from_stress(v, &p, g);
    let blocks = match projection {
        TangentProjection::Exact => exact_blocks(lame, v, g, h),
        TangentProjection::PositiveDefinite => projected_blocks(lame, v, g, h),
    };
    UpperEval {
        energy,
        gradient,
        blocks,
    }
}

/// What both tangents weigh their terms with: `F`, `λ'` and `s = λ' (J − 1) − μ`.
fn tangent_factors<T: Real>(lame: &Lame<T>, h: &Matrix3<T>) -> (Matrix3<T>, T, T) {
    let weight = volume_weight(lame);
    (
        Matrix3::identity() + h,
        weight,
        weight * volume_change(h) - lame.mu,
    )
}

/// The exact tangent blocks `K_ab = V [μ (g_a · g_b) I + λ' (cof F g_a)(cof F g_b)ᵀ −
/// s [F (g_a × g_b)]ₓ]`.
fn exact_blocks<T: Real>(
    lame: &Lame<T>,
    v: T,
    g: &[Vector3<T>; 4],
    h: &Matrix3<T>,
) -> [Matrix3<T>; 10] {
    let (f, weight, s) = tangent_factors(lame, h);
    let cg = g.map(|ga| cofactor(&f) * ga);
    let mut blocks = [Matrix3::zeros(); 10];
    for (&(a, b), block) in PAIRS.iter().zip(blocks.iter_mut()) {
        // `a`, `b` < 4 (the pairs of a tetrahedron's nodes).
        let (Some(ga), Some(gb), Some(ca), Some(cb)) = (g.get(a), g.get(b), cg.get(a), cg.get(b))
        else {
            continue;
        };
        let c = f * ga.cross(gb);
        let mut k = ca * cb.transpose() * weight - c.cross_matrix() * s;
        let shear = lame.mu * ga.dot(gb);
        k.m11 += shear;
        k.m22 += shear;
        k.m33 += shear;
        *block = k * v;
    }
    blocks
}

/// The signed singular value decomposition `F = U diag(σ) Vᵀ`: `U` and `V` rotations,
/// `σ₀ ≥ σ₁ ≥ |σ₂|`, and `σ₂ < 0` exactly when `det F < 0` (an inverted element). From the
/// fixed-cost eigen-solve of `FᵀF` (for `V`), then `U` by Gram–Schmidt on `F v₀`, `F v₁` and
/// their cross product, so a collapsed or flat element still gets orthonormal frames: any
/// orthonormal `U`, `V` keep the projection positive semidefinite, only a less accurate one.
pub(crate) fn signed_svd<T: Real>(f: &Matrix3<T>) -> (Matrix3<T>, Vector3<T>, Matrix3<T>) {
    let (lam, q) = symmetric_eigen3(&(f.transpose() * f));
    // Descending order of the eigenvalues (a three-element sorting network).
    let mut order = [0usize, 1, 2];
    let at = |k: usize| lam.get(k).copied().unwrap_or_else(T::zero);
    for (i, j) in [(0, 1), (1, 2), (0, 1)] {
        let (Some(&oi), Some(&oj)) = (order.get(i), order.get(j)) else {
            continue;
        };
        if at(oi) < at(oj) {
            order.swap(i, j);
        }
    }
    let [o0, o1, o2] = order;
    let mut v = Matrix3::from_columns(&[q.column(o0), q.column(o1), q.column(o2)]);
    if v.determinant() < T::zero() {
        v.set_column(2, &(-v.column(2)));
    }
    let (v0, v1) = (v.column(0).into_owned(), v.column(1).into_owned());
    let tiny = T::EPS * (T::one() + f.norm());
    let unit_or = |x: Vector3<T>, fallback: Vector3<T>| {
        let n = x.norm();
        if n > tiny { x / n } else { fallback }
    };
    let u0 = unit_or(f * v0, v0);
    // A unit vector across `u0`, should `F v₁` vanish after taking out its `u0` part.
    let across = {
        let e = if u0.x.abs() < T::of(0.5) {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let w = e - u0 * u0.dot(&e);
        w / w.norm()
    };
    let fv1 = f * v1;
    let u1 = unit_or(fv1 - u0 * u0.dot(&fv1), across);
    let u2 = u0.cross(&u1);
    let u = Matrix3::from_columns(&[u0, u1, u2]);
    let sigma = Vector3::new(u0.dot(&(f * v0)), u1.dot(&fv1), u2.dot(&(f * v.column(2))));
    (u, sigma, v)
}

/// The tangent blocks of the nearest positive semidefinite Hessian (module docs): in the
/// frame of `F = U Σ Vᵀ`, with `ĝ = Vᵀ g`, `K̂_ab` collects the scaling block's projection
/// `A⁺` as `A⁺_ij ĝ_a[i] ĝ_b[j]` and each axis pair's twist `λ_t` and flip `λ_f` as
/// `((λ_f + λ_t)/2) ĝ_a[j] ĝ_b[j]` on `(i, i)`, `((λ_f − λ_t)/2) ĝ_a[j] ĝ_b[i]` on `(i, j)`
/// (and the same with `i` and `j` swapped); then `K_ab = V U K̂_ab Uᵀ`.
fn projected_blocks<T: Real>(
    lame: &Lame<T>,
    v: T,
    g: &[Vector3<T>; 4],
    h: &Matrix3<T>,
) -> [Matrix3<T>; 10] {
    let (f, weight, s) = tangent_factors(lame, h);
    let (u, sigma, vr) = signed_svd(&f);
    let (s0, s1, s2) = (sigma.x, sigma.y, sigma.z);
    // The scaling block and its projection.
    let c = Vector3::new(s1 * s2, s0 * s2, s0 * s1);
    let a_off = Matrix3::new(T::zero(), s2, s1, s2, T::zero(), s0, s1, s0, T::zero());
    let scaling = Matrix3::from_diagonal_element(lame.mu) + c * c.transpose() * weight + a_off * s;
    let (lam, w) = symmetric_eigen3(&scaling);
    let mut a_plus = Matrix3::zeros();
    for (wm, &l) in w.column_iter().zip(lam.iter()) {
        a_plus += wm * wm.transpose() * l.max(T::zero());
    }
    // Twist and flip of each axis pair `(i, j)` about the third axis `k`:
    // `(λ_f + λ_t) / 2` and `(λ_f − λ_t) / 2`.
    let half = T::of(0.5);
    let pairs = [(1usize, 2usize, s0), (0, 2, s1), (0, 1, s2)];
    let modes = pairs.map(|(i, j, sk)| {
        let twist = (lame.mu + s * sk).max(T::zero());
        let flip = (lame.mu - s * sk).max(T::zero());
        (i, j, (flip + twist) * half, (flip - twist) * half)
    });
    let gh = g.map(|ga| vr.transpose() * ga);
    let mut blocks = [Matrix3::zeros(); 10];
    for (&(a, b), block) in PAIRS.iter().zip(blocks.iter_mut()) {
        // `a`, `b` < 4 (the pairs of a tetrahedron's nodes).
        let (Some(ga), Some(gb)) = (gh.get(a), gh.get(b)) else {
            continue;
        };
        let mut k = a_plus.component_mul(&(ga * gb.transpose()));
        for &(i, j, diagonal, cross) in &modes {
            // `i`, `j` < 3 (the axis pairs above).
            let (Some(&gai), Some(&gaj), Some(&gbi), Some(&gbj)) =
                (ga.get(i), ga.get(j), gb.get(i), gb.get(j))
            else {
                continue;
            };
            for ((r, c), add) in [
                ((i, i), diagonal * gaj * gbj),
                ((j, j), diagonal * gai * gbi),
                ((i, j), cross * gaj * gbi),
                ((j, i), cross * gai * gbj),
            ] {
                if let Some(x) = k.get_mut((r, c)) {
                    *x += add;
                }
            }
        }
        *block = u * k * u.transpose() * v;
    }
    blocks
}
