//! Symmetric 3 × 3 eigen-solves at a cost that does not depend on the data: the tangent's
//! positive semidefinite projection of the stress in closed form
//! ([`positive_part_closed_form`]), and cyclic Jacobi with a fixed number of sweeps
//! ([`symmetric_eigen3`]) where all three eigenvectors are needed (the Neo-Hookean law's
//! analytic eigensystem).

use nalgebra::{Matrix3, Vector3};

use crate::real::Real;

/// Cyclic Jacobi sweeps of [`symmetric_eigen3`]. Cyclic Jacobi converges quadratically once
/// the off-diagonal part is small relative to the eigenvalue gaps, and also for repeated
/// eigenvalues; on 3 × 3 matrices the off-diagonal norm falls below `4 EPS ‖S‖` in at most
/// four sweeps in the tests (random, clustered and repeated spectra), so five leaves a sweep of
/// margin. Fewer sweeps never break positive semidefiniteness of the projection (that holds
/// for any orthogonal `Q`), they only make `S⁺` a slightly less accurate projection.
#[cfg(any(feature = "neo-hookean", all(test, feature = "f64")))]
pub(crate) const JACOBI_SWEEPS: usize = 5;

/// Eigen-decomposition `A ≈ Q diag(λ) Qᵀ` of `a` by cyclic Jacobi with a fixed
/// number of sweeps ([`JACOBI_SWEEPS`]); `a` must be symmetric.
/// Returns the eigenvalues (unsorted) and `Q` (orthogonal up to rounding, eigenvectors as
/// columns). Finite input gives finite output: the one division is skipped for a zero
/// off-diagonal entry, and an overflowing ratio leads to the identity rotation, not NaN.
#[cfg(any(feature = "neo-hookean", all(test, feature = "f64")))]
pub(crate) fn symmetric_eigen3<T: Real>(a: &Matrix3<T>) -> (Vector3<T>, Matrix3<T>) {
    jacobi(a, JACOBI_SWEEPS)
}

/// [`symmetric_eigen3`] with `sweeps` cyclic sweeps.
#[cfg(any(feature = "neo-hookean", all(test, feature = "f64")))]
pub(crate) fn jacobi<T: Real>(a: &Matrix3<T>, sweeps: usize) -> (Vector3<T>, Matrix3<T>) {
    // The symmetric matrix by its six entries: the diagonal and `M_01`, `M_02`, `M_12` (read
    // from the upper triangle). A rotation changes only the entries of its rows and columns,
    // and by symmetry each of them once.
    let mut sym = Symmetric {
        diag: [a.m11, a.m22, a.m33],
        off: [a.m12, a.m13, a.m23],
    };
    // Column-major, as nalgebra stores them: `q[k][i]` is `Q_ik`.
    let mut q: [[T; 3]; 3] = Matrix3::<T>::identity().into();
    for _ in 0..sweeps {
        for pair in [Pair::P01, Pair::P02, Pair::P12] {
            rotate_pair(&mut sym, &mut q, pair);
        }
    }
    let [d0, d1, d2] = sym.diag;
    (Vector3::new(d0, d1, d2), Matrix3::from(q))
}

/// A symmetric 3 × 3 matrix: its diagonal and its entries `(0, 1)`, `(0, 2)`, `(1, 2)`.
#[cfg(any(feature = "neo-hookean", all(test, feature = "f64")))]
struct Symmetric<T> {
    diag: [T; 3],
    off: [T; 3],
}

/// An index pair `(p, r)`, `p < r`, of a cyclic sweep.
#[cfg(any(feature = "neo-hookean", all(test, feature = "f64")))]
#[derive(Clone, Copy)]
enum Pair {
    P01,
    P02,
    P12,
}

#[cfg(any(feature = "neo-hookean", all(test, feature = "f64")))]
impl Pair {
    /// Entries `p` and `r` of `v`, mutable.
    #[inline(always)]
    fn of_mut<X>(self, v: &mut [X; 3]) -> (&mut X, &mut X) {
        let [v0, v1, v2] = v;
        match self {
            Pair::P01 => (v0, v1),
            Pair::P02 => (v0, v2),
            Pair::P12 => (v1, v2),
        }
    }

    /// The off-diagonal entries `M_pr`, `M_po` and `M_ro` of `off` (`o` the third index).
    #[inline(always)]
    fn off_mut<X>(self, off: &mut [X; 3]) -> (&mut X, &mut X, &mut X) {
        let [m01, m02, m12] = off;
        match self {
            Pair::P01 => (m01, m02, m12),
            Pair::P02 => (m02, m01, m12),
            Pair::P12 => (m12, m01, m02),
        }
    }
}

/// One Jacobi rotation on `(p, r)`: `M ← Jᵀ M J` with `M_pr = M_rp = 0`, `Q ← Q J`; `q` by
/// columns.
#[cfg(any(feature = "neo-hookean", all(test, feature = "f64")))]
#[inline(always)]
fn rotate_pair<T: Real>(m: &mut Symmetric<T>, q: &mut [[T; 3]; 3], pair: Pair) {
    let one = T::one();
    let (mpr, mpo, mro) = pair.off_mut(&mut m.off);
    let apr = *mpr;
    if apr == T::zero() {
        return;
    }
    let (mpp, mrr) = pair.of_mut(&mut m.diag);
    // Golub & Van Loan, Algorithm 8.5.1 (sym.schur2): the rotation J with
    // J_pp = J_rr = c, J_pr = s, J_rp = −s zeroes (JᵀMJ)_pr. The smaller root `t`
    // keeps the rotation angle within ±π/4. τ may overflow to ±∞, giving t = 0.
    let tau = (*mrr - *mpp) / (T::of(2.0) * apr);
    let root = (one + tau * tau).sqrt();
    let t = if tau >= T::zero() {
        one / (tau + root)
    } else {
        -one / (root - tau)
    };
    let c = one / (one + t * t).sqrt();
    let s = t * c;
    // The two-sided update in closed form (`M_pp − t M_pr`, `M_rr + t M_pr`: the rotation
    // zeroes `M_pr` exactly there), and the third row and column rotated once, not twice.
    *mpp -= t * apr;
    *mrr += t * apr;
    *mpr = T::zero();
    rotate(mpo, mro, c, s);
    // Q ← Q J (columns p, r).
    let (col_p, col_r) = pair.of_mut(q);
    for (xp, xr) in col_p.iter_mut().zip(col_r.iter_mut()) {
        rotate(xp, xr, c, s);
    }
}

/// `(x_p, x_r) ← (c x_p − s x_r, s x_p + c x_r)`.
#[cfg(any(feature = "neo-hookean", all(test, feature = "f64")))]
#[inline(always)]
fn rotate<T: Real>(xp: &mut T, xr: &mut T, c: T, s: T) {
    let (p, r) = (*xp, *xr);
    *xp = c * p - s * r;
    *xr = s * p + c * r;
}

/// `S⁺ = Q max(Λ, 0) Qᵀ`, the nearest positive semidefinite matrix to symmetric `s` (its
/// negative eigenvalues cleared), or `s` itself, bit for bit, when no eigenvalue is negative;
/// at a cost that does not depend on `s`.
///
/// The eigensystem in closed form, as Eberly's robust 3 × 3 solver does it (D. Eberly, "A
/// Robust Eigensolver for 3 × 3 Symmetric Matrices", Geometric Tools, 2014):
/// 1. `s = q I + p B` with `q = tr s / 3` and `p = ‖s − q I‖_F / √6`; the eigenvalues are
///    `q + 2p cos(φ + 2πk/3)`, `3φ` the angle whose cosine is `r = det B / 2` (Smith, CACM
///    1961). Near a double eigenvalue the pair that meets is sensitive to rounding in `r`
///    (errors of order `√ε ‖s‖`), the third is not: the largest when `r ≥ 0`, the smallest when
///    `r < 0`, at least `√3 p` from both others. Only that one is kept.
/// 2. Its eigenvector, well defined by that gap: the largest cross product of two rows of
///    `s − λ I`, normalised.
/// 3. The other two eigenpairs from the symmetric 2 × 2 that `s` is on the plane orthogonal to
///    it, by the stable closed form of the 2 × 2 (half sum ± the hypotenuse of half the
///    difference and the off-diagonal), exact to rounding even when the two coincide.
///
/// `S⁺` is then a sum of rank-one terms with nonnegative weights: semidefinite to rounding
/// whatever the spectrum. About 500 instructions a call, where the five Jacobi sweeps it
/// replaced here (fifteen rotations, each with a square root and a division or two) took 800.
///
/// Computed on `s` scaled by its largest entry, so that no square overflows; finite input
/// gives finite output. Transcendental functions by `libm`, as everywhere in the core
/// ([`Real::libm_atan2`]).
pub(crate) fn positive_part_closed_form<T: Real>(s: &Matrix3<T>) -> Matrix3<T> {
    let scale = s.amax();
    if !(scale > T::zero()) || !scale.finite() {
        // Zero (already semidefinite), or not finite (left for the caller to find).
        return *s;
    }
    let a = s / scale;
    let [(l0, v0), (l1, v1), (l2, v2)] = eigensystem(&a);
    if l0 >= T::zero() && l1 >= T::zero() && l2 >= T::zero() {
        return *s;
    }
    let term = |l: T, v: Vector3<T>| v * v.transpose() * (l.max(T::zero()) * scale);
    term(l0, v0) + term(l1, v1) + term(l2, v2)
}

/// The eigenpairs of symmetric `a` (entries of order one) in closed form (see
/// [`positive_part_closed_form`]): the isolated one first, then the two of the orthogonal
/// plane, larger first. Unit eigenvectors, orthogonal to rounding.
pub(crate) fn eigensystem<T: Real>(a: &Matrix3<T>) -> [(T, Vector3<T>); 3] {
    let (one, two, three) = (T::one(), T::of(2.0), T::of(3.0));
    let off = a.m12 * a.m12 + a.m13 * a.m13 + a.m23 * a.m23;
    let q = (a.m11 + a.m22 + a.m33) / three;
    let (d1, d2, d3) = (a.m11 - q, a.m22 - q, a.m33 - q);
    let p = ((d1 * d1 + d2 * d2 + d3 * d3 + two * off) / T::of(6.0)).sqrt();
    // `a = q I` when `p = 0`: `r = 0` below then picks any axis, and the plane's 2 × 2 is `q I`.
    let p_safe = if p > T::zero() { p } else { one };
    // det((a − q I) / p) / 2, in [−1, 1] up to rounding.
    let det = d1 * (d2 * d3 - a.m23 * a.m23) - a.m12 * (a.m12 * d3 - a.m23 * a.m13)
        + a.m13 * (a.m12 * a.m23 - d2 * a.m13);
    let r = (det / (two * p_safe * p_safe * p_safe)).max(-one).min(one);
    // φ ∈ [0, π/3]: atan2 rather than acos, accurate near r = ±1 too.
    let phi = ((one - r * r).max(T::zero()).sqrt()).libm_atan2(r) / three;
    let (sin, cos) = phi.libm_sin_cos();
    let isolated = if r >= T::zero() {
        q + two * p * cos
    } else {
        // cos(φ + 2π/3) = −(cos φ + √3 sin φ) / 2.
        q - p * (cos + T::of(SQRT_3) * sin)
    };
    let v = eigenvector(a, isolated);
    // An orthonormal pair spanning the plane orthogonal to `v`.
    let u = if v.x.abs() > v.y.abs() {
        Vector3::new(-v.z, T::zero(), v.x) / (v.x * v.x + v.z * v.z).sqrt()
    } else {
        Vector3::new(T::zero(), v.z, -v.y) / (v.y * v.y + v.z * v.z).sqrt()
    };
    let w = v.cross(&u);
    let (au, aw) = (a * u, a * w);
    let (m00, m01, m11) = (u.dot(&au), u.dot(&aw), w.dot(&aw));
    let half_sum = (m00 + m11) / two;
    let half_diff = (m00 - m11) / two;
    let h = (half_diff * half_diff + m01 * m01).sqrt();
    // The larger eigenvalue's eigenvector of the 2 × 2, `(c, s)`, from whichever of its two
    // equivalent forms does not cancel.
    let (c, s) = if half_diff >= T::zero() {
        (half_diff + h, m01)
    } else {
        (m01, h - half_diff)
    };
    let n = (c * c + s * s).sqrt();
    let (c, s) = if n > T::zero() {
        (c / n, s / n)
    } else {
        (one, T::zero())
    };
    let larger = u * c + w * s;
    let smaller = w * c - u * s;
    [
        (isolated, v),
        (half_sum + h, larger),
        (half_sum - h, smaller),
    ]
}

/// √3.
const SQRT_3: f64 = 1.732_050_807_568_877_2;

/// A unit eigenvector of symmetric `a` for an eigenvalue `lambda` at least a few rounding
/// errors from the other two: the largest cross product of two rows of `a − λ I` (each
/// orthogonal to the eigenvector), normalised. A unit axis when all three vanish (`a = λ I`).
fn eigenvector<T: Real>(a: &Matrix3<T>, lambda: T) -> Vector3<T> {
    let m = a - Matrix3::identity() * lambda;
    let (r0, r1, r2) = (
        Vector3::new(m.m11, m.m12, m.m13),
        Vector3::new(m.m21, m.m22, m.m23),
        Vector3::new(m.m31, m.m32, m.m33),
    );
    let mut best = r0.cross(&r1);
    let mut best_norm = best.norm_squared();
    for c in [r0.cross(&r2), r1.cross(&r2)] {
        let n = c.norm_squared();
        if n > best_norm {
            best = c;
            best_norm = n;
        }
    }
    if best_norm > T::zero() {
        best / best_norm.sqrt()
    } else {
        Vector3::x()
    }
}
