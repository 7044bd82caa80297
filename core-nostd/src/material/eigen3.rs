//! The symmetric 3 × 3 eigen-solve of the tangent's positive semidefinite projection: cyclic
//! Jacobi with a fixed number of sweeps, so that its cost does not depend on the data.

use nalgebra::{Matrix3, Vector3};

use crate::real::Real;

/// Cyclic Jacobi sweeps of [`symmetric_eigen3`]. Cyclic Jacobi converges quadratically once
/// the off-diagonal part is small relative to the eigenvalue gaps, and also for repeated
/// eigenvalues; on 3 × 3 matrices the off-diagonal norm falls below `4 EPS ‖S‖` in at most
/// four sweeps in the tests (random, clustered and repeated spectra), so five leaves a sweep of
/// margin. Fewer sweeps never break positive semidefiniteness of the projection (that holds
/// for any orthogonal `Q`), they only make `S⁺` a slightly less accurate projection.
pub(crate) const JACOBI_SWEEPS: usize = 5;

/// Eigen-decomposition `A ≈ Q diag(λ) Qᵀ` of `a` by cyclic Jacobi with a fixed
/// number of sweeps ([`JACOBI_SWEEPS`]); `a` must be symmetric.
/// Returns the eigenvalues (unsorted) and `Q` (orthogonal up to rounding, eigenvectors as
/// columns). Finite input gives finite output: the one division is skipped for a zero
/// off-diagonal entry, and an overflowing ratio leads to the identity rotation, not NaN.
pub(crate) fn symmetric_eigen3<T: Real>(a: &Matrix3<T>) -> (Vector3<T>, Matrix3<T>) {
    jacobi(a, JACOBI_SWEEPS)
}

/// [`symmetric_eigen3`] with `sweeps` cyclic sweeps.
pub(crate) fn jacobi<T: Real>(a: &Matrix3<T>, sweeps: usize) -> (Vector3<T>, Matrix3<T>) {
    // Column-major, as nalgebra stores them: `m[k][i]` is `M_ik`.
    let mut m: [[T; 3]; 3] = (*a).into();
    let mut q: [[T; 3]; 3] = Matrix3::<T>::identity().into();
    for _ in 0..sweeps {
        for pair in [Pair::P01, Pair::P02, Pair::P12] {
            rotate_pair(&mut m, &mut q, pair);
        }
    }
    (Vector3::new(m[0][0], m[1][1], m[2][2]), Matrix3::from(q))
}

/// An index pair `(p, r)`, `p < r`, of a cyclic sweep.
#[derive(Clone, Copy)]
enum Pair {
    P01,
    P02,
    P12,
}

impl Pair {
    /// Entries `p` and `r` of `v`.
    #[inline(always)]
    fn of<X: Copy>(self, v: &[X; 3]) -> (X, X) {
        match self {
            Pair::P01 => (v[0], v[1]),
            Pair::P02 => (v[0], v[2]),
            Pair::P12 => (v[1], v[2]),
        }
    }

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
}

/// One Jacobi rotation on `(p, r)`: `M ← Jᵀ M J` with `M_pr = M_rp = 0`, `Q ← Q J`; `m` and
/// `q` by columns.
#[inline(always)]
fn rotate_pair<T: Real>(m: &mut [[T; 3]; 3], q: &mut [[T; 3]; 3], pair: Pair) {
    let one = T::one();
    // Columns `p` and `r`; `M_pp`, and `M_pr`, `M_rr`.
    let (col_p, col_r) = pair.of(m);
    let (mpp, _) = pair.of(&col_p);
    let (apr, mrr) = pair.of(&col_r);
    if apr == T::zero() {
        return;
    }
    // Golub & Van Loan, Algorithm 8.5.1 (sym.schur2): the rotation J with
    // J_pp = J_rr = c, J_pr = s, J_rp = −s zeroes (JᵀMJ)_pr. The smaller root `t`
    // keeps the rotation angle within ±π/4. τ may overflow to ±∞, giving t = 0.
    let tau = (mrr - mpp) / (T::of(2.0) * apr);
    let root = (one + tau * tau).sqrt();
    let t = if tau >= T::zero() {
        one / (tau + root)
    } else {
        -one / (root - tau)
    };
    let c = one / (one + t * t).sqrt();
    let s = t * c;
    // M ← M J (columns p, r), Q ← Q J.
    for x in [&mut *m, &mut *q] {
        let (col_p, col_r) = pair.of_mut(x);
        for (xp, xr) in col_p.iter_mut().zip(col_r.iter_mut()) {
            rotate(xp, xr, c, s);
        }
    }
    // M ← Jᵀ M (rows p, r).
    for col in m.iter_mut() {
        let (xp, xr) = pair.of_mut(col);
        rotate(xp, xr, c, s);
    }
    // M_pr = M_rp = 0.
    let (col_p, col_r) = pair.of_mut(m);
    *pair.of_mut(col_r).0 = T::zero();
    *pair.of_mut(col_p).1 = T::zero();
}

/// `(x_p, x_r) ← (c x_p − s x_r, s x_p + c x_r)`.
#[inline(always)]
fn rotate<T: Real>(xp: &mut T, xr: &mut T, c: T, s: T) {
    let (p, r) = (*xp, *xr);
    *xp = c * p - s * r;
    *xr = s * p + c * r;
}
