//! Compressible Neo-Hookean elasticity on linear tetrahedra: the law of the simulated *real*
//! object, deliberately different from the model's Saint Venant–Kirchhoff law so that the model
//! is never fitted to data made with its own equations.
//!
//! Energy density, with `F = I + H`, `J = det F`, `C = FᵀF`:
//!
//! `Ψ = μ/2 (tr C − 3) − μ ln J + λ/2 (ln J)²`,
//! `P = ∂Ψ/∂F = μ (F − F⁻ᵀ) + λ ln J F⁻ᵀ`.
//!
//! The rest geometry (`Dm⁻¹`, volume, shape gradients `g_a`) and the displacement gradient
//! `H = Σ_a u_a g_aᵀ` are the core's ([`ElementRest`], [`displacement_gradient`]), so both laws
//! see exactly the same kinematics. As in the core, everything is evaluated from displacements
//! `u` (metres) rather than positions, and the energy is rearranged so that no term subtracts
//! numbers near 1 (see [`energy_density`]): energy differences stay resolvable down to small
//! strains, which the line search of [`super::sim`] relies on.
//!
//! Ψ is infinite for `J ≤ 0` (`ln J` diverges as `J → 0⁺`). An element with `J ≤ 0`, or whose
//! quantities overflow, is reported as [`ElementEval::inverted`] with infinite energy and zero
//! gradient and Hessian: never NaN, so a line search simply rejects the step.
//!
//! Units: positions and displacements in metres, Lamé parameters and stresses in pascals, energy
//! density in J/m³, element energy in joules, gradient (force) in newtons, Hessian in N/m.

use incise_core::material::{ElementRest, Lame, displacement_gradient};
use nalgebra::{Matrix3, SMatrix, SymmetricEigen, Vector3};

/// A 12 × 12 element matrix; row and column `3a + i` belong to component `i` of local node `a`.
pub type Matrix12 = SMatrix<f64, 12, 12>;

/// Which element Hessian [`element_eval`] returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Projection {
    /// The exact Hessian `∂²W/∂x∂x`; indefinite under strong compression.
    Exact,
    /// The exact Hessian with its negative eigenvalues removed: `K⁺ = K − Σ_{λ_i < 0} λ_i q_i q_iᵀ`
    /// from the eigen-decomposition of the full 12 × 12 matrix, i.e. the nearest positive
    /// semidefinite matrix in the Frobenius norm. Subtracting only the negative part (rather
    /// than rebuilding `Q max(Λ, 0) Qᵀ`) leaves an element that is already positive
    /// semidefinite untouched up to the rounding-level eigenvalues of its six rigid modes.
    ClampEigenvalues,
}

/// Energy, gradient and Hessian of one element, from [`element_eval`].
#[derive(Clone, Debug, PartialEq)]
pub struct ElementEval {
    /// `W = V Ψ(F)` (J); `f64::INFINITY` when [`ElementEval::inverted`].
    pub energy: f64,
    /// `∂W/∂x_a = V P g_a` (N) for local nodes `a = 0..3`; they sum to zero exactly. Zero when
    /// inverted.
    pub gradient: [Vector3<f64>; 4],
    /// `∂²W/∂x∂x` (N/m), symmetric, per the requested [`Projection`]. Zero when inverted.
    pub hessian: Matrix12,
    /// `J ≤ 0`, or a quantity overflowed: the energy is infinite and nothing else is
    /// meaningful.
    pub inverted: bool,
}

/// Element energy from [`element_energy`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementEnergy {
    /// `W = V Ψ(F)` (J), `f64::INFINITY` for an inverted element.
    pub energy: f64,
    /// `V` times the sum of the absolute values of the terms `Ψ` is summed from (J): the scale
    /// of the energy's rounding error, which can exceed `|W|` when the terms cancel (an element
    /// that is mostly rotated). Infinite for an inverted element.
    pub magnitude: f64,
}

/// Kinematic quantities of one `H`, computed once and shared by energy, stress and Hessian.
struct Kinematics {
    /// `J − 1`, computed from the invariants of `H` without forming `det(I + H)`.
    j_minus_1: f64,
    /// `ln J`.
    log_j: f64,
    /// `F⁻ᵀ`.
    f_inv_t: Matrix3<f64>,
}

/// `None` when `J ≤ 0` or anything is not finite (NaN input included).
fn kinematics(h: &Matrix3<f64>) -> Option<Kinematics> {
    if !h.iter().all(|v| v.is_finite()) {
        return None;
    }
    // det(I + H) = 1 + I1 + I2 + I3 (the characteristic polynomial of H at −1), so J − 1 keeps
    // its relative accuracy for small H.
    let j_minus_1 = h.trace() + second_invariant(h) + h.determinant();
    if !(j_minus_1 > -1.0 && j_minus_1.is_finite()) {
        return None;
    }
    let f = Matrix3::identity() + h;
    let f_inv_t = f.try_inverse()?.transpose();
    if !f_inv_t.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some(Kinematics {
        j_minus_1,
        log_j: j_minus_1.ln_1p(),
        f_inv_t,
    })
}

/// `I2 = ½ ((tr H)² − tr(H²))`.
fn second_invariant(h: &Matrix3<f64>) -> f64 {
    let tr = h.trace();
    0.5 * (tr * tr - (h * h).trace())
}

/// `φ(x) = x − ln(1 + x)`, accurate also for small `|x|` where the two terms nearly cancel.
fn x_minus_ln_1p(x: f64) -> f64 {
    if x.abs() < 0.1 {
        // φ(x) = Σ_{k ≥ 2} (−1)^k x^k / k; with |x| < 0.1 the terms beyond k = 20 are below
        // 1e-20 of the first, so 19 terms reach full precision.
        // Horner in y = −x on x² Σ_{m=0}^{18} y^m / (m + 2).
        let mut s = 0.0;
        for k in (2..=20).rev() {
            s = 1.0 / f64::from(k) - x * s;
        }
        s * x * x
    } else {
        x - x.ln_1p()
    }
}

/// `(Ψ, Σ|terms|)` from the kinematics.
fn density_terms(lame: &Lame<f64>, h: &Matrix3<f64>, k: &Kinematics) -> (f64, f64) {
    // μ/2 (tr C − 3) − μ ln J with tr C − 3 = 2 tr H + |H|² and ln J = (J − 1) − φ(J − 1),
    // J − 1 = tr H + I2 + det H: the first-order terms μ tr H cancel analytically, leaving
    // only second-order terms, none of which subtracts numbers near 1.
    let terms = [
        0.5 * lame.mu * h.norm_squared(),
        -lame.mu * (second_invariant(h) + h.determinant()),
        lame.mu * x_minus_ln_1p(k.j_minus_1),
        0.5 * lame.lambda * k.log_j * k.log_j,
    ];
    (terms.iter().sum(), terms.iter().map(|t| t.abs()).sum())
}

/// Neo-Hookean energy density `Ψ` (J/m³) at displacement gradient `h` (`F = I + h`), or
/// `f64::INFINITY` when `det F ≤ 0` or `h` is not finite. Zero for `h = 0`, and for every
/// rotation up to rounding.
pub fn energy_density(lame: &Lame<f64>, h: &Matrix3<f64>) -> f64 {
    match kinematics(h) {
        Some(k) => density_terms(lame, h, &k).0,
        None => f64::INFINITY,
    }
}

/// First Piola–Kirchhoff stress `P = ∂Ψ/∂F` (Pa) at displacement gradient `h`, or `None` when
/// `det F ≤ 0` or something is not finite.
///
/// Written as `P = μ (H + F⁻ᵀ Hᵀ) + λ ln J F⁻ᵀ`, using `F − F⁻ᵀ = H + F⁻ᵀ(Fᵀ − I)`, so that
/// small stresses are not the difference of two matrices near `I`.
pub fn first_piola_kirchhoff(lame: &Lame<f64>, h: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let k = kinematics(h)?;
    let p = piola(lame, h, &k);
    p.iter().all(|v| v.is_finite()).then_some(p)
}

fn piola(lame: &Lame<f64>, h: &Matrix3<f64>, k: &Kinematics) -> Matrix3<f64> {
    (h + k.f_inv_t * h.transpose()) * lame.mu + k.f_inv_t * (lame.lambda * k.log_j)
}

/// Element energy `W = V Ψ(F)` (J) with its rounding scale: the cheap evaluation a line search
/// needs. `g` comes from `rest.shape_gradients()`, `u` holds the node displacements from rest
/// (metres).
pub fn element_energy(
    lame: &Lame<f64>,
    rest: &ElementRest<f64>,
    g: &[Vector3<f64>; 4],
    u: &[[f64; 3]; 4],
) -> ElementEnergy {
    let h = displacement_gradient(u, g);
    let inverted = ElementEnergy {
        energy: f64::INFINITY,
        magnitude: f64::INFINITY,
    };
    let Some(k) = kinematics(&h) else {
        return inverted;
    };
    let (psi, magnitude) = density_terms(lame, &h, &k);
    if !(psi.is_finite() && magnitude.is_finite()) {
        return inverted;
    }
    ElementEnergy {
        energy: rest.volume * psi,
        magnitude: rest.volume * magnitude,
    }
}

/// Energy, gradient and 12 × 12 Hessian of one element (node displacements `u` from rest,
/// metres; `g` from `rest.shape_gradients()`).
///
/// With `q_a = F⁻ᵀ g_a` the exact Hessian blocks are
/// `K_ab = V [μ (g_a · g_b) I + (μ − λ ln J) q_b q_aᵀ + λ q_a q_bᵀ]`,
/// from `dP = μ dF + (μ − λ ln J) F⁻ᵀ dFᵀ F⁻ᵀ + λ tr(F⁻¹ dF) F⁻ᵀ` with `dF = e_c g_bᵀ`; they
/// satisfy `K_ba = K_abᵀ` exactly as built. `projection` selects the exact matrix or its
/// positive semidefinite part.
///
/// An inverted element (`J ≤ 0`) or one whose values overflow comes back with
/// [`ElementEval::inverted`] set, infinite energy, and zero gradient and Hessian.
pub fn element_eval(
    lame: &Lame<f64>,
    rest: &ElementRest<f64>,
    g: &[Vector3<f64>; 4],
    u: &[[f64; 3]; 4],
    projection: Projection,
) -> ElementEval {
    let inverted = ElementEval {
        energy: f64::INFINITY,
        gradient: [Vector3::zeros(); 4],
        hessian: Matrix12::zeros(),
        inverted: true,
    };
    let h = displacement_gradient(u, g);
    let Some(k) = kinematics(&h) else {
        return inverted;
    };
    let v = rest.volume;
    let energy = v * density_terms(lame, &h, &k).0;
    let vp = piola(lame, &h, &k) * v;
    let (f1, f2, f3) = (vp * g[1], vp * g[2], vp * g[3]);
    // Node 0 as minus the others, so the element forces balance exactly.
    let gradient = [-(f1 + f2 + f3), f1, f2, f3];

    let q = g.map(|ga| k.f_inv_t * ga);
    let c_swap = lame.mu - lame.lambda * k.log_j;
    let mut hessian = Matrix12::zeros();
    for a in 0..4 {
        for b in a..4 {
            let block = Matrix3::from_diagonal_element(lame.mu * g[a].dot(&g[b]))
                + q[b] * q[a].transpose() * c_swap
                + q[a] * q[b].transpose() * lame.lambda;
            let block = block * v;
            hessian
                .fixed_view_mut::<3, 3>(3 * a, 3 * b)
                .copy_from(&block);
            hessian
                .fixed_view_mut::<3, 3>(3 * b, 3 * a)
                .copy_from(&block.transpose());
        }
    }
    if projection == Projection::ClampEigenvalues {
        hessian = clamp_negative_eigenvalues(&hessian);
    }
    let finite = energy.is_finite()
        && gradient.iter().all(|f| f.iter().all(|c| c.is_finite()))
        && hessian.iter().all(|c| c.is_finite());
    if !finite {
        return inverted;
    }
    ElementEval {
        energy,
        gradient,
        hessian,
        inverted: false,
    }
}

/// `K − Σ_{λ_i < 0} λ_i q_i q_iᵀ`, symmetrised. `k` must be symmetric and finite.
fn clamp_negative_eigenvalues(k: &Matrix12) -> Matrix12 {
    let eig = SymmetricEigen::new(*k);
    let mut out = *k;
    for (i, &lam) in eig.eigenvalues.iter().enumerate() {
        if lam < 0.0 {
            let qi = eig.eigenvectors.column(i);
            out -= qi * qi.transpose() * lam;
        }
    }
    // The rank-one updates are symmetric only up to rounding; the assembly stores the upper
    // triangle, so make both halves agree.
    (out + out.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use nalgebra::{Rotation3, Unit};

    fn lame(nu: f64) -> Lame<f64> {
        Lame::from_young_poisson(3.0e3, nu).unwrap()
    }

    fn unit_vec(rng: &mut Rng) -> Vector3<f64> {
        loop {
            let v = Vector3::from_fn(|_, _| rng.range(-1.0, 1.0));
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }

    fn rotation(rng: &mut Rng) -> Matrix3<f64> {
        let angle = rng.range(-3.0, 3.0);
        Rotation3::from_axis_angle(&Unit::new_normalize(unit_vec(rng)), angle).into_inner()
    }

    /// A well-shaped, positively oriented tetrahedron of size about `h` (metres), off the
    /// origin: a perturbed regular tetrahedron, randomly rotated.
    fn rest_tet(rng: &mut Rng, h: f64) -> [Vector3<f64>; 4] {
        let reg = [
            Vector3::new(1.0, 1.0, 1.0),
            Vector3::new(1.0, -1.0, -1.0),
            Vector3::new(-1.0, 1.0, -1.0),
            Vector3::new(-1.0, -1.0, 1.0),
        ];
        let r = rotation(rng);
        let c = Vector3::from_fn(|_, _| rng.range(-0.05, 0.05));
        let mut p = reg.map(|v| {
            let jitter = Vector3::from_fn(|_, _| rng.range(-0.15, 0.15));
            c + r * (v + jitter) * (0.5 * h)
        });
        let det = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]).determinant();
        if det < 0.0 {
            p.swap(1, 2);
        }
        p
    }

    #[derive(Clone, Copy, Debug)]
    enum Kind {
        /// `F` near the identity (±30 %) with a rotation.
        General,
        /// 40 % compression along a random axis, rotated.
        Compressed,
        /// Stretch by 1.0–1.5 along random principal axes, rotated.
        Stretched,
    }

    fn deformed(rng: &mut Rng, kind: Kind, xr: &[Vector3<f64>; 4]) -> [Vector3<f64>; 4] {
        let a = match kind {
            Kind::General => Matrix3::identity() + Matrix3::from_fn(|_, _| rng.range(-0.3, 0.3)),
            Kind::Compressed => {
                let n = unit_vec(rng);
                Matrix3::identity() - n * n.transpose() * 0.4
            }
            Kind::Stretched => {
                let q = rotation(rng);
                let d = Vector3::from_fn(|_, _| rng.range(1.0, 1.5));
                q * Matrix3::from_diagonal(&d) * q.transpose()
            }
        };
        let a = rotation(rng) * a;
        let t = Vector3::from_fn(|_, _| rng.range(-0.01, 0.01));
        xr.map(|v| a * v + t)
    }

    struct Case {
        lame: Lame<f64>,
        rest: ElementRest<f64>,
        g: [Vector3<f64>; 4],
        u: [[f64; 3]; 4],
    }

    /// 3 kinds × 3 Poisson ratios × 20 random tetrahedra of 1 cm.
    fn cases() -> Vec<(Kind, Case)> {
        let mut rng = Rng::new(17);
        let mut out = Vec::new();
        for kind in [Kind::General, Kind::Compressed, Kind::Stretched] {
            for nu in [0.0, 0.3, 0.45] {
                for _ in 0..20 {
                    let xr = rest_tet(&mut rng, 0.01);
                    let x = deformed(&mut rng, kind, &xr);
                    let rest = ElementRest::new(&xr.map(|p| [p.x, p.y, p.z]), 0).unwrap();
                    let u = std::array::from_fn(|a| {
                        let d = x[a] - xr[a];
                        [d.x, d.y, d.z]
                    });
                    let g = rest.shape_gradients();
                    out.push((
                        kind,
                        Case {
                            lame: lame(nu),
                            rest,
                            g,
                            u,
                        },
                    ));
                }
            }
        }
        out
    }

    fn perturbed(u: &[[f64; 3]; 4], dof: usize, d: f64) -> [[f64; 3]; 4] {
        let mut p = *u;
        p[dof / 3][dof % 3] += d;
        p
    }

    fn flat(g: &[Vector3<f64>; 4]) -> [f64; 12] {
        std::array::from_fn(|i| g[i / 3][i % 3])
    }

    fn max_abs(v: impl IntoIterator<Item = f64>) -> f64 {
        v.into_iter().fold(0.0, |m, x| m.max(x.abs()))
    }

    #[test]
    fn gradient_matches_central_differences_of_energy() {
        let mut worst: f64 = 0.0;
        for (kind, c) in cases() {
            let e = element_eval(&c.lame, &c.rest, &c.g, &c.u, Projection::Exact);
            assert!(!e.inverted, "{kind:?}");
            // Step relative to the element size (1 cm): truncation error ~ step², rounding
            // ~ EPS·W/step, both far below 1e-6 of the gradient here.
            let step = 1e-7;
            let fd: [f64; 12] = std::array::from_fn(|i| {
                let ep = element_energy(&c.lame, &c.rest, &c.g, &perturbed(&c.u, i, step)).energy;
                let em = element_energy(&c.lame, &c.rest, &c.g, &perturbed(&c.u, i, -step)).energy;
                (ep - em) / (2.0 * step)
            });
            let an = flat(&e.gradient);
            let err = max_abs((0..12).map(|i| fd[i] - an[i])) / max_abs(an);
            worst = worst.max(err);
            assert!(err <= 1e-6, "{kind:?}: relative error {err:e}");
            // The energy-only path agrees with the full evaluation.
            let w = element_energy(&c.lame, &c.rest, &c.g, &c.u);
            assert_eq!(w.energy, e.energy);
            assert!(w.magnitude >= w.energy.abs());
        }
        println!("NH gradient vs central differences: worst relative error {worst:e}");
    }

    #[test]
    fn exact_hessian_matches_central_differences_of_gradient() {
        let mut worst: f64 = 0.0;
        for (kind, c) in cases() {
            let k = element_eval(&c.lame, &c.rest, &c.g, &c.u, Projection::Exact).hessian;
            let step = 1e-7;
            let mut fd = Matrix12::zeros();
            for j in 0..12 {
                let gp = element_eval(
                    &c.lame,
                    &c.rest,
                    &c.g,
                    &perturbed(&c.u, j, step),
                    Projection::Exact,
                );
                let gm = element_eval(
                    &c.lame,
                    &c.rest,
                    &c.g,
                    &perturbed(&c.u, j, -step),
                    Projection::Exact,
                );
                let (gp, gm) = (flat(&gp.gradient), flat(&gm.gradient));
                for i in 0..12 {
                    fd[(i, j)] = (gp[i] - gm[i]) / (2.0 * step);
                }
            }
            let err = (fd - k).amax() / k.amax();
            worst = worst.max(err);
            assert!(err <= 1e-6, "{kind:?}: relative error {err:e}");
            assert_eq!(k, k.transpose(), "{kind:?}: not exactly symmetric");
        }
        println!("NH Hessian vs central differences: worst relative error {worst:e}");
    }

    #[test]
    fn rest_state_has_zero_energy_and_gradient() {
        let mut rng = Rng::new(5);
        for nu in [0.0, 0.3, 0.49] {
            let xr = rest_tet(&mut rng, 0.01);
            let rest = ElementRest::new(&xr.map(|p| [p.x, p.y, p.z]), 0).unwrap();
            let g = rest.shape_gradients();
            let e = element_eval(&lame(nu), &rest, &g, &[[0.0; 3]; 4], Projection::Exact);
            assert_eq!(e.energy, 0.0);
            assert!(e.gradient.iter().all(|f| *f == Vector3::zeros()));
            // At rest the Hessian is the linear-elastic stiffness: PSD with exactly the six
            // rigid modes in its null space.
            let eig = SymmetricEigen::new(e.hessian).eigenvalues;
            let mut sorted: Vec<f64> = eig.iter().copied().collect();
            sorted.sort_by(f64::total_cmp);
            let top = sorted[11];
            assert!(
                sorted[..6].iter().all(|l| l.abs() <= 1e-12 * top),
                "{sorted:?}"
            );
            assert!(sorted[6] > 1e-4 * top, "{sorted:?}");
        }
    }

    #[test]
    fn rotations_change_nothing_but_the_frame() {
        let mut rng = Rng::new(8);
        let l = lame(0.3);
        for (kind, c) in cases().into_iter().step_by(3) {
            let e0 = element_eval(&l, &c.rest, &c.g, &c.u, Projection::Exact);
            // Current positions relative to the rest positions; rotate the deformed shape.
            let h = displacement_gradient(&c.u, &c.g);
            let r = rotation(&mut rng);
            // x' = R x  ⇔  F' = R F  ⇔  H' = R (I + H) − I; build u' with that H' and the
            // same node-0 displacement (energy depends on H only).
            let h_rot = r * (Matrix3::identity() + h) - Matrix3::identity();
            let dm_inv = c.rest.dm_inv;
            let dm = dm_inv.try_inverse().unwrap();
            let du = h_rot * dm; // columns: u_k − u_0 for k = 1..3
            let u_rot = [
                [0.0; 3],
                [du[(0, 0)], du[(1, 0)], du[(2, 0)]],
                [du[(0, 1)], du[(1, 1)], du[(2, 1)]],
                [du[(0, 2)], du[(1, 2)], du[(2, 2)]],
            ];
            let e1 = element_eval(&l, &c.rest, &c.g, &u_rot, Projection::Exact);
            assert!(
                (e1.energy - e0.energy).abs() <= 1e-10 * e0.energy.abs().max(1e-30),
                "{kind:?}: {} vs {}",
                e1.energy,
                e0.energy
            );
            // Forces rotate with the body, the Hessian as R K Rᵀ blockwise.
            let scale = max_abs(flat(&e0.gradient));
            for a in 0..4 {
                let d = (e1.gradient[a] - r * e0.gradient[a]).amax();
                assert!(
                    d <= 1e-9 * scale,
                    "{kind:?}: force of node {a} off by {d:e}"
                );
            }
            let mut rb = Matrix12::zeros();
            for a in 0..4 {
                rb.fixed_view_mut::<3, 3>(3 * a, 3 * a).copy_from(&r);
            }
            let d = (e1.hessian - rb * e0.hessian * rb.transpose()).amax();
            assert!(
                d <= 1e-9 * e0.hessian.amax(),
                "{kind:?}: Hessian off by {d:e}"
            );
        }
        // Pure rotations of the rest shape store no energy.
        let c = &cases()[0].1;
        for _ in 0..20 {
            let r = rotation(&mut rng);
            let dm = c.rest.dm_inv.try_inverse().unwrap();
            let du = (r - Matrix3::identity()) * dm;
            let u = [
                [0.0; 3],
                [du[(0, 0)], du[(1, 0)], du[(2, 0)]],
                [du[(0, 1)], du[(1, 1)], du[(2, 1)]],
                [du[(0, 2)], du[(1, 2)], du[(2, 2)]],
            ];
            let e = element_eval(&l, &c.rest, &c.g, &u, Projection::Exact);
            let unit = l.mu * c.rest.volume;
            assert!(e.energy.abs() <= 1e-13 * unit, "{}", e.energy);
            let force = unit * max_abs(c.g.iter().flat_map(|v| v.iter().copied()));
            assert!(max_abs(flat(&e.gradient)) <= 1e-13 * force);
        }
    }

    #[test]
    fn projected_hessian_is_psd_and_exact_when_already_psd() {
        let mut indefinite = 0;
        let mut worst: f64 = 0.0;
        for (kind, c) in cases() {
            let exact = element_eval(&c.lame, &c.rest, &c.g, &c.u, Projection::Exact).hessian;
            let proj =
                element_eval(&c.lame, &c.rest, &c.g, &c.u, Projection::ClampEigenvalues).hessian;
            let ratio = |k: &Matrix12| {
                let e = SymmetricEigen::new(*k).eigenvalues;
                e.min() / e.amax()
            };
            let r = ratio(&proj);
            worst = worst.min(r);
            assert!(r >= -1e-12, "{kind:?}: smallest/largest eigenvalue {r:e}");
            assert_eq!(proj, proj.transpose());
            if ratio(&exact) < -1e-8 {
                indefinite += 1;
                // Only the negative part is removed, so K⁺ − K = −Σ_{λ_i<0} λ_i q_i q_iᵀ ⪰ 0.
                let diff = SymmetricEigen::new(proj - exact).eigenvalues;
                assert!(diff.min() >= -1e-12 * exact.amax());
            } else {
                assert!((proj - exact).amax() <= 1e-10 * exact.amax(), "{kind:?}");
            }
        }
        assert!(indefinite >= 10, "only {indefinite} indefinite Hessians");
        println!(
            "NH projected Hessian: worst smallest/largest eigenvalue {worst:e}, {indefinite} exact Hessians indefinite"
        );
    }

    #[test]
    fn inverted_and_degenerate_elements_give_infinity_without_nan() {
        let mut rng = Rng::new(21);
        let l = lame(0.3);
        let xr = rest_tet(&mut rng, 0.01);
        let rest = ElementRest::new(&xr.map(|p| [p.x, p.y, p.z]), 0).unwrap();
        let g = rest.shape_gradients();
        let disp = |x: [Vector3<f64>; 4]| -> [[f64; 3]; 4] {
            std::array::from_fn(|a| {
                let d = x[a] - xr[a];
                [d.x, d.y, d.z]
            })
        };
        // Node 3 reflected through the opposite face; the mirror image; all nodes collapsed
        // to a point and to a plane; NaN and infinite input.
        let mut through = xr;
        let n = (xr[1] - xr[0]).cross(&(xr[2] - xr[0])).normalize();
        through[3] -= n * (2.5 * (xr[3] - xr[0]).dot(&n));
        let mirrored = xr.map(|p| Vector3::new(-p.x, p.y, p.z));
        let point = [xr[0]; 4];
        let plane = xr.map(|p| Vector3::new(p.x, p.y, 0.0));
        let mut cases = vec![disp(through), disp(mirrored)];
        cases.push([[f64::NAN; 3]; 4]);
        let mut inf = [[0.0; 3]; 4];
        inf[2][1] = f64::INFINITY;
        cases.push(inf);
        for u in cases {
            for projection in [Projection::Exact, Projection::ClampEigenvalues] {
                let e = element_eval(&l, &rest, &g, &u, projection);
                assert!(e.inverted);
                assert_eq!(e.energy, f64::INFINITY);
                assert!(e.gradient.iter().all(|f| f.iter().all(|c| *c == 0.0)));
                assert!(e.hessian.iter().all(|c| *c == 0.0));
            }
            let w = element_energy(&l, &rest, &g, &u);
            assert_eq!(w.energy, f64::INFINITY);
            assert_eq!(
                energy_density(&l, &displacement_gradient(&u, &g)),
                f64::INFINITY
            );
            assert!(first_piola_kirchhoff(&l, &displacement_gradient(&u, &g)).is_none());
        }
        // Collapsed to a point or a plane: J = 0 in exact arithmetic, ±rounding in floating
        // point. Either verdict is acceptable, NaN is not: inverted, or finite with a huge
        // energy.
        for u in [disp(point), disp(plane)] {
            for projection in [Projection::Exact, Projection::ClampEigenvalues] {
                let e = element_eval(&l, &rest, &g, &u, projection);
                let finite = e.gradient.iter().all(|f| f.iter().all(|c| c.is_finite()))
                    && e.hessian.iter().all(|c| c.is_finite());
                assert!(finite);
                assert!(
                    e.inverted || e.energy > 100.0 * l.mu * rest.volume,
                    "{}",
                    e.energy
                );
                assert!(!e.energy.is_nan());
            }
        }
        // Nearly flat but positive: finite and large, pushing back.
        let mut flat_ish = xr;
        let d = (xr[3] - xr[0]).dot(&n);
        flat_ish[3] -= n * (d * (1.0 - 1e-6));
        let e = element_eval(&l, &rest, &g, &disp(flat_ish), Projection::ClampEigenvalues);
        assert!(!e.inverted && e.energy.is_finite() && e.energy > 0.0);
    }

    #[test]
    fn small_strain_matches_linear_elasticity_and_large_strain_the_closed_form() {
        let l = lame(0.3);
        for eps in [1e-3, 1e-4, 1e-6] {
            let h = Matrix3::from_diagonal(&Vector3::new(eps, 0.0, 0.0));
            let p = first_piola_kirchhoff(&l, &h).unwrap();
            let sxx = (l.lambda + 2.0 * l.mu) * eps;
            assert!(((p[(0, 0)] - sxx) / sxx).abs() <= 2.0 * eps);
            assert!(((p[(1, 1)] - l.lambda * eps) / (l.lambda * eps)).abs() <= 2.0 * eps);
            // The energy keeps its relative accuracy at tiny strain (no cancellation).
            let psi = energy_density(&l, &h);
            let lin = 0.5 * (l.lambda + 2.0 * l.mu) * eps * eps;
            assert!(
                ((psi - lin) / lin).abs() <= 2.0 * eps,
                "eps={eps}: {psi} vs {lin}"
            );
        }
        // Uniaxial F = diag(s, 1, 1): P_xx = μ (s − 1/s) + λ ln s / s.
        let s: f64 = 1.4;
        let p = first_piola_kirchhoff(
            &l,
            &Matrix3::from_diagonal(&Vector3::new(s - 1.0, 0.0, 0.0)),
        )
        .unwrap();
        let want = l.mu * (s - 1.0 / s) + l.lambda * s.ln() / s;
        assert!(((p[(0, 0)] - want) / want).abs() <= 1e-14);
        let psi = energy_density(
            &l,
            &Matrix3::from_diagonal(&Vector3::new(s - 1.0, 0.0, 0.0)),
        );
        let want = 0.5 * l.mu * (s * s - 1.0) - l.mu * s.ln() + 0.5 * l.lambda * s.ln().powi(2);
        assert!(((psi - want) / want).abs() <= 1e-14);
        // φ on both sides of the series switch.
        for x in [
            -0.5, -0.1000001, -0.0999999, -1e-3, 1e-8, 0.05, 0.0999999, 0.1, 2.0,
        ] {
            let want = x - f64::ln_1p(x);
            let got = x_minus_ln_1p(x);
            let tol = if x.abs() > 0.01 { 1e-13 } else { 1e-6 };
            assert!(((got - want) / want).abs() <= tol, "x={x}: {got} vs {want}");
        }
        let x = 1e-8;
        let series = x * x / 2.0 - x * x * x / 3.0;
        assert!((x_minus_ln_1p(x) - series).abs() <= 1e-15 * series);
    }
}
