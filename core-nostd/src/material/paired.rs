//! The SVK element gradient of two tetrahedra at once, for the gradient-only assembly
//! (feature `paired-elements`: the host builds it; a firmware build at opt-level "s", where the
//! compiler does not pack the two lanes and the kernel only adds code, leaves it out).
//!
//! Every quantity of the two elements is held as a [`Pair`] of scalars, one lane each, so
//! that each operation of the one-element path ([`super::Law::element_energy_stress_of_h`],
//! [`InversionBarrier::add_element_stress`], [`super::element_gradient_of_stress`]) is one
//! operation on both: on x86-64 a single packed instruction for `f64`, where the one-element
//! path, written on nalgebra's 3 × 3 matrices, leaves the compiler a mix of packed and single
//! operations and the shuffles between them (the liver's quasi-Newton frame: about 680
//! instructions an element before, 590 now, the scatter into the gradient included).
//!
//! **The same bits.** Each lane computes every scalar by the same operations in the same
//! order as the one-element path does through nalgebra (its products sum their terms left to
//! right, `Σ_k a_ik b_kj` from `k = 0`; its squared norm column by column; its 3 × 3
//! determinant and cross product by the formulas written out below), so that the two paths
//! give the same energy and gradient bit for bit: the committed scenes' results do not move,
//! and `paired_gradient_is_the_single_elements_bit_for_bit` (in `material/tests.rs`) holds
//! the two paths to each other on random elements, stretched, compressed below the barrier's
//! floor and inverted. The kernel has no array `map` and no closure per entry: the compiler
//! left those out of line, and the pairs went through memory.

use core::ops::{Add, Div, Mul, Neg, Sub};

use nalgebra::Vector3;

use super::{ElementRest, InversionBarrier, Lame};
use crate::real::Real;

/// Two scalars, one per element, combined lane by lane.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pair<T>([T; 2]);

impl<T: Real> Pair<T> {
    #[inline(always)]
    fn splat(x: T) -> Self {
        Pair([x, x])
    }
    #[inline(always)]
    fn of(a: T, b: T) -> Self {
        Pair([a, b])
    }
    /// `a` in the lanes where `self < bound`, `b` elsewhere (NaN included), as the barrier's
    /// `if j < floor` chooses per element.
    #[inline(always)]
    fn below(self, bound: T, a: Self, b: Self) -> Self {
        let [x, y] = self.0;
        Pair([
            if x < bound { a.0[0] } else { b.0[0] },
            if y < bound { a.0[1] } else { b.0[1] },
        ])
    }
}

macro_rules! lane_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<T: Real> $tr for Pair<T> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                Pair([self.0[0] $op o.0[0], self.0[1] $op o.0[1]])
            }
        }
    };
}
lane_op!(Add, add, +);
lane_op!(Sub, sub, -);
lane_op!(Mul, mul, *);
lane_op!(Div, div, /);

impl<T: Real> Neg for Pair<T> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Pair([-self.0[0], -self.0[1]])
    }
}

/// A 3 × 3 matrix of pairs, `m[row][column]`.
type Mat<T> = [[Pair<T>; 3]; 3];

/// `(x_0 y_0 + x_1 y_1) + x_2 y_2`: an entry of nalgebra's products, whose terms are summed
/// left to right.
#[inline(always)]
fn dot<T: Real>(x: [Pair<T>; 3], y: [Pair<T>; 3]) -> Pair<T> {
    (x[0] * y[0] + x[1] * y[1]) + x[2] * y[2]
}

/// `c_ij = a_i · b_j` (rows of both): `a bᵀ`, each entry as nalgebra sums a product's.
#[inline(always)]
fn row_products<T: Real>(a: &Mat<T>, b: &Mat<T>) -> Mat<T> {
    [
        [dot(a[0], b[0]), dot(a[0], b[1]), dot(a[0], b[2])],
        [dot(a[1], b[0]), dot(a[1], b[1]), dot(a[1], b[2])],
        [dot(a[2], b[0]), dot(a[2], b[1]), dot(a[2], b[2])],
    ]
}

/// `mᵀ` (its columns as rows).
#[inline(always)]
fn transpose<T: Real>(m: &Mat<T>) -> Mat<T> {
    [
        [m[0][0], m[1][0], m[2][0]],
        [m[0][1], m[1][1], m[2][1]],
        [m[0][2], m[1][2], m[2][2]],
    ]
}

/// `a × b` as nalgebra's cross product forms it.
#[inline(always)]
fn cross<T: Real>(a: [Pair<T>; 3], b: [Pair<T>; 3]) -> [Pair<T>; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The symmetric matrix whose upper triangle `$entry!(i, j)` (`i ≤ j`) gives, the indices
/// written out (constants, so that no index can fall outside).
macro_rules! symmetric {
    ($entry:ident) => {{
        let (e01, e02, e12) = ($entry!(0, 1), $entry!(0, 2), $entry!(1, 2));
        [
            [$entry!(0, 0), e01, e02],
            [e01, $entry!(1, 1), e12],
            [e02, e12, $entry!(2, 2)],
        ]
    }};
}

/// The pairs of two elements' vectors `a` and `b`.
#[inline(always)]
fn pair3<T: Real>(a: [T; 3], b: [T; 3]) -> [Pair<T>; 3] {
    let ([a0, a1, a2], [b0, b1, b2]) = (a, b);
    [Pair::of(a0, b0), Pair::of(a1, b1), Pair::of(a2, b2)]
}

/// `a − b`, lane by lane.
#[inline(always)]
fn sub3<T: Real>(a: [Pair<T>; 3], b: [Pair<T>; 3]) -> [Pair<T>; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The two elements' vectors held in `x`.
#[inline(always)]
fn lanes<T: Real>(x: [Pair<T>; 3]) -> [Vector3<T>; 2] {
    let [Pair([x0, y0]), Pair([x1, y1]), Pair([x2, y2])] = x;
    [Vector3::new(x0, x1, x2), Vector3::new(y0, y1, y2)]
}

/// One element's share of a gradient-only assembly, as the one-element path adds it: the
/// law's energy, then the barrier's (when the material has one), and the nodes' gradient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ElementShare<T: Real> {
    /// `V Ψ(F)` (J).
    pub energy: T,
    /// `V ψ(J)` (J), added after `energy`; `None` without a barrier.
    pub barrier_energy: Option<T>,
    /// `∂W/∂x_a` (N) of the four nodes.
    pub gradient: [Vector3<T>; 4],
}

/// The SVK energy, barrier energy and nodes' gradient of two elements with rest geometry
/// `rest` and node displacements `u` (metres, from rest), each bit for bit what the
/// one-element path gives (see the module documentation).
///
/// Where nalgebra adds a zero (its trace starts from zero; `I + H` and `λ tr(E) I` add zeros
/// off the diagonal), this leaves the addition out: it changes nothing but the sign of a zero
/// result (and for the trace not even that: a diagonal entry of `E` is never `−0`), which no
/// sum the assembly forms can tell (they start from `+0`). Where two NaNs meet, the NaN kept
/// may be the other one (some products take their operands the other way round): a NaN
/// either way.
#[inline(always)]
pub(crate) fn svk_shares_of_two<T: Real>(
    lame: &Lame<T>,
    barrier: Option<&InversionBarrier<T>>,
    rest: [&ElementRest<T>; 2],
    u: [&[[T; 3]; 4]; 2],
) -> [ElementShare<T>; 2] {
    let [ra, rb] = rest;
    let [ua, ub] = u;
    // `g_k = (row k − 1 of Dm⁻¹)ᵀ` for k = 1, 2, 3, here `g[k − 1]` (`g_0` is not needed: the
    // gradient of node 0 is minus the others'); nalgebra's arrays are its columns.
    let rows = |r: &ElementRest<T>| -> [[T; 3]; 3] { r.dm_inv.transpose().into() };
    let (ga, gb) = (rows(ra), rows(rb));
    let g: Mat<T> = [
        pair3(ga[0], gb[0]),
        pair3(ga[1], gb[1]),
        pair3(ga[2], gb[2]),
    ];
    let volume = Pair::of(ra.volume, rb.volume);
    // `u_k − u_0`, k = 1, 2, 3.
    let ([ua0, ua1, ua2, ua3], [ub0, ub1, ub2, ub3]) = (*ua, *ub);
    let u0 = pair3(ua0, ub0);
    let d: Mat<T> = [
        sub3(pair3(ua1, ub1), u0),
        sub3(pair3(ua2, ub2), u0),
        sub3(pair3(ua3, ub3), u0),
    ];
    // `H = Σ_k (u_k − u_0) g_kᵀ`, the three outer products added left to right:
    // `H_rc = (d_1r g_1c + d_2r g_2c) + d_3r g_3c`.
    let (dt, gt) = (transpose(&d), transpose(&g));
    let h = row_products(&dt, &gt);
    // `E = ((H + Hᵀ) + HᵀH) / 2`, symmetric bit for bit (`h_ij + h_ji` and the terms of
    // `(HᵀH)_ij` are the same operands either way round): its upper triangle.
    let half = Pair::splat(T::of(0.5));
    let ht = transpose(&h);
    macro_rules! strain {
        ($i:tt, $j:tt) => {
            ((h[$i][$j] + ht[$i][$j]) + dot(ht[$i], ht[$j])) * half
        };
    }
    let e: Mat<T> = symmetric!(strain);
    let tr = (e[0][0] + e[1][1]) + e[2][2];
    // `‖E‖²` column by column (a column of `E` is its row), each summed left to right.
    let norm_squared = (dot(e[0], e[0]) + dot(e[1], e[1])) + dot(e[2], e[2]);
    let (mu, lambda) = (Pair::splat(lame.mu), Pair::splat(lame.lambda));
    let density = mu * norm_squared + ((half * lambda) * tr) * tr;
    let energy = volume * density;
    // `S = λ tr(E) I + 2μ E` (symmetric), then `P = F S`: `P_ij = F_i · (column j of S)`, the
    // column being row `j`.
    let two_mu = Pair::splat(T::of(2.0)) * mu;
    let lambda_tr = lambda * tr;
    macro_rules! stress {
        ($i:tt, $j:tt) => {
            if $i == $j {
                lambda_tr + e[$i][$j] * two_mu
            } else {
                e[$i][$j] * two_mu
            }
        };
    }
    let s: Mat<T> = symmetric!(stress);
    let one = Pair::splat(T::one());
    let f: Mat<T> = [
        [one + h[0][0], h[0][1], h[0][2]],
        [h[1][0], one + h[1][1], h[1][2]],
        [h[2][0], h[2][1], one + h[2][2]],
    ];
    let mut p = row_products(&f, &s);
    let zero = Pair::splat(T::zero());
    let barrier_energy = barrier.map(|barrier| {
        // `J = det F` by nalgebra's 3 × 3 formula.
        let minor_12_23 = f[1][1] * f[2][2] - f[2][1] * f[1][2];
        let minor_11_23 = f[1][0] * f[2][2] - f[2][0] * f[1][2];
        let minor_11_22 = f[1][0] * f[2][1] - f[2][0] * f[1][1];
        let j = (f[0][0] * minor_12_23 - f[0][1] * minor_11_23) + f[0][2] * minor_11_22;
        let floor = barrier.floor;
        let gap = j.below(floor, Pair::splat(floor) - j, zero);
        let scale = Pair::splat(barrier.stiffness / (floor * floor));
        let psi = ((scale * gap) * gap) * gap / Pair::splat(T::of(3.0));
        let dpsi = ((-scale) * gap) * gap;
        // `cof F`, whose column j is the cross product of F's other two columns; added to
        // `P` row by row.
        let ft = transpose(&f);
        let cof = transpose(&[
            cross(ft[1], ft[2]),
            cross(ft[2], ft[0]),
            cross(ft[0], ft[1]),
        ]);
        for (pi, ci) in p.iter_mut().zip(&cof) {
            for (x, &c) in pi.iter_mut().zip(ci) {
                *x = *x + c * dpsi;
            }
        }
        volume * psi
    });
    // `f_k = (V P) g_k`, and node 0's `−((f_1 + f_2) + f_3)`.
    let mut vp = p;
    for x in vp.iter_mut().flatten() {
        *x = *x * volume;
    }
    let fk = row_products(&g, &vp);
    let [f1, f2, f3] = fk;
    let f0 = [
        -((f1[0] + f2[0]) + f3[0]),
        -((f1[1] + f2[1]) + f3[1]),
        -((f1[2] + f2[2]) + f3[2]),
    ];
    let ([a0, b0], [a1, b1], [a2, b2], [a3, b3]) = (lanes(f0), lanes(f1), lanes(f2), lanes(f3));
    let [energy_a, energy_b] = energy.0;
    let [barrier_a, barrier_b] = barrier_energy.unwrap_or(zero).0;
    let with_barrier = barrier_energy.is_some();
    [
        ElementShare {
            energy: energy_a,
            barrier_energy: with_barrier.then_some(barrier_a),
            gradient: [a0, a1, a2, a3],
        },
        ElementShare {
            energy: energy_b,
            barrier_energy: with_barrier.then_some(barrier_b),
            gradient: [b0, b1, b2, b3],
        },
    ]
}
