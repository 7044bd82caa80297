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
struct Symmetric<T> {
    diag: [T; 3],
    off: [T; 3],
}

/// An index pair `(p, r)`, `p < r`, of a cyclic sweep.
#[derive(Clone, Copy)]
enum Pair {
    P01,
    P02,
    P12,
}

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
#[inline(always)]
fn rotate<T: Real>(xp: &mut T, xr: &mut T, c: T, s: T) {
    let (p, r) = (*xp, *xr);
    *xp = c * p - s * r;
    *xr = s * p + c * r;
}
