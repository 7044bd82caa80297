//! Unit tests of the laws and the element quantities: finite differences, closed forms,
//! eigen-solves and extreme deformations.

use super::eigen3::{
    JACOBI_SWEEPS, eigensystem, jacobi, positive_part_closed_form, symmetric_eigen3,
};
use super::element::nodes;
use super::*;
use crate::error::{Error, Parameter, Resource};
use nalgebra::{SMatrix, SymmetricEigen, UnitQuaternion};

type K12 = SMatrix<f64, 12, 12>;

/// splitmix64, for reproducible random geometry without external crates.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    fn vec3(&mut self, r: f64) -> Vector3<f64> {
        Vector3::new(self.range(-r, r), self.range(-r, r), self.range(-r, r))
    }
    fn unit_vec3(&mut self) -> Vector3<f64> {
        loop {
            let v = self.vec3(1.0);
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }
    fn rotation(&mut self) -> Matrix3<f64> {
        let axis = nalgebra::Unit::new_normalize(self.unit_vec3());
        UnitQuaternion::from_axis_angle(&axis, self.range(-3.0, 3.0))
            .to_rotation_matrix()
            .into_inner()
    }
}

fn arr(p: &[Vector3<f64>; 4]) -> [[f64; 3]; 4] {
    p.map(|v| [v.x, v.y, v.z])
}

fn vecs(x: &[[f64; 3]; 4]) -> [Vector3<f64>; 4] {
    nodes(x)
}

/// A well-shaped, positively oriented rest tetrahedron of size about `h`, placed off the
/// origin: a regular tetrahedron, randomly rotated and perturbed by 15 %.
fn rest_tet(rng: &mut Rng, h: f64) -> [[f64; 3]; 4] {
    let reg = [
        Vector3::new(1.0, 1.0, 1.0),
        Vector3::new(1.0, -1.0, -1.0),
        Vector3::new(-1.0, 1.0, -1.0),
        Vector3::new(-1.0, -1.0, 1.0),
    ];
    let r = rng.rotation();
    let c = rng.vec3(10.0);
    let mut p = reg.map(|v| c + r * (v + rng.vec3(0.15)) * (0.5 * h));
    let det = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]).determinant();
    if det < 0.0 {
        p.swap(1, 2);
    }
    arr(&p)
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// Random `F` near the identity (up to ±30 %), plus a rotation and translation.
    General,
    /// 50 % compression along a random axis (and a random rotation).
    Compressed,
    /// 50 % compression along z only: `x = diag(1, 1, 0.5) X`.
    CompressedZ,
    /// Node 3 pushed through its opposite face.
    Inverted,
    /// Pure stretch `diag(≥ 1)` along random principal axes: `E` and `S` PSD for `λ ≥ 0`.
    Stretch,
}

const KINDS: [Kind; 5] = [
    Kind::General,
    Kind::Compressed,
    Kind::CompressedZ,
    Kind::Inverted,
    Kind::Stretch,
];

fn deform(rng: &mut Rng, kind: Kind, rest: &[[f64; 3]; 4]) -> [[f64; 3]; 4] {
    let xr = vecs(rest);
    let map = |a: Matrix3<f64>, t: Vector3<f64>| xr.map(|v| a * v + t);
    let t = rng.vec3(1.0);
    let p = match kind {
        Kind::General => {
            let a = Matrix3::identity() + Matrix3::from_fn(|_, _| rng.range(-0.3, 0.3));
            map(rng.rotation() * a, t)
        }
        Kind::Compressed => {
            let n = rng.unit_vec3();
            map(
                rng.rotation() * (Matrix3::identity() - n * n.transpose() * 0.5),
                t,
            )
        }
        Kind::CompressedZ => map(Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.5)), t),
        Kind::Inverted => {
            let mut p = map(rng.rotation(), t);
            let n = (p[1] - p[0]).cross(&(p[2] - p[0])).normalize();
            let d = (p[3] - p[0]).dot(&n);
            // Reflect node 3 through the plane of face 0-1-2 and beyond by 20-100 %.
            p[3] -= n * (d * (2.0 + rng.range(0.2, 1.0)));
            p
        }
        Kind::Stretch => {
            let r = rng.rotation();
            let d = Vector3::new(
                rng.range(1.0, 1.3),
                rng.range(1.0, 1.3),
                rng.range(1.0, 1.3),
            );
            map(r * Matrix3::from_diagonal(&d) * r.transpose(), t)
        }
    };
    arr(&p)
}

fn lame(nu: f64) -> Lame<f64> {
    Lame::from_young_poisson(3000.0, nu).unwrap()
}

fn assemble(t: &[[Matrix3<f64>; 4]; 4]) -> K12 {
    K12::from_fn(|i, j| t[i / 3][j / 3][(i % 3, j % 3)])
}

fn flat(g: &[Vector3<f64>; 4]) -> [f64; 12] {
    core::array::from_fn(|i| g[i / 3][i % 3])
}

/// Node displacements `x − xr`: what the element functions take.
fn disp(x: &[[f64; 3]; 4], xr: &[[f64; 3]; 4]) -> [[f64; 3]; 4] {
    core::array::from_fn(|a| core::array::from_fn(|c| x[a][c] - xr[a][c]))
}

fn perturbed(x: &[[f64; 3]; 4], i: usize, d: f64) -> [[f64; 3]; 4] {
    let mut y = *x;
    y[i / 3][i % 3] += d;
    y
}

fn max_abs(v: impl IntoIterator<Item = f64>) -> f64 {
    v.into_iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// All cases: for several Poisson ratios (including a negative one), every kind of
/// deformation, several random tetrahedra.
fn for_cases(
    mut f: impl FnMut(Kind, f64, &Lame<f64>, &ElementRest<f64>, &[Vector3<f64>; 4], &[[f64; 3]; 4], f64),
) {
    let mut rng = Rng(0x5EED_1234);
    for nu in [0.3, 0.45, 0.0, -0.5] {
        let l = lame(nu);
        for kind in KINDS {
            for _ in 0..8 {
                let h = rng.range(0.01, 2.0);
                let xr = rest_tet(&mut rng, h);
                let rest = ElementRest::new(&xr, 0).unwrap();
                let g = rest.shape_gradients();
                let x = deform(&mut rng, kind, &xr);
                f(kind, nu, &l, &rest, &g, &disp(&x, &xr), h);
            }
        }
    }
}

#[test]
fn gradient_matches_energy_finite_differences() {
    let mut worst: f64 = 0.0;
    for_cases(|kind, nu, l, rest, g, x, h| {
        let grad = flat(&element_gradient(l, rest, g, x));
        let step = 1e-6 * h;
        let fd: [f64; 12] = core::array::from_fn(|i| {
            let ep = element_energy(l, rest, g, &perturbed(x, i, step));
            let em = element_energy(l, rest, g, &perturbed(x, i, -step));
            (ep - em) / (2.0 * step)
        });
        let scale = max_abs(grad);
        let err = max_abs((0..12).map(|i| grad[i] - fd[i])) / scale;
        worst = worst.max(err);
        assert!(err <= 1e-6, "{kind:?} nu={nu}: relative error {err:e}");
    });
}

#[test]
fn exact_tangent_matches_gradient_finite_differences() {
    let mut worst: f64 = 0.0;
    for_cases(|kind, nu, l, rest, g, x, h| {
        let eval = element_energy_gradient_tangent(l, rest, g, x, TangentProjection::Exact);
        let k = assemble(&eval.tangent);
        let step = 1e-6 * h;
        let mut fd = K12::zeros();
        for j in 0..12 {
            let gp = flat(&element_gradient(l, rest, g, &perturbed(x, j, step)));
            let gm = flat(&element_gradient(l, rest, g, &perturbed(x, j, -step)));
            for i in 0..12 {
                fd[(i, j)] = (gp[i] - gm[i]) / (2.0 * step);
            }
        }
        let err = (k - fd).amax() / k.amax();
        worst = worst.max(err);
        assert!(err <= 1e-6, "{kind:?} nu={nu}: relative error {err:e}");
        // The combined call agrees with the cheap ones.
        assert_eq!(eval.energy, element_energy(l, rest, g, x));
        assert_eq!(eval.gradient, element_gradient(l, rest, g, x));
        assert_eq!(k, k.transpose());
    });
}

/// SVK with the barrier: energy, gradient and tangent as the assembly forms them.
fn with_barrier(
    b: &InversionBarrier<f64>,
    l: &Lame<f64>,
    rest: &ElementRest<f64>,
    g: &[Vector3<f64>; 4],
    x: &[[f64; 3]; 4],
    projection: TangentProjection,
) -> ElementEval<f64> {
    let mut eval = element_energy_gradient_tangent(l, rest, g, x, projection);
    let h = displacement_gradient(x, g);
    b.add_element_tangent(rest.volume, g, &h, projection, &mut eval);
    eval
}

fn barrier_energy(
    b: &InversionBarrier<f64>,
    l: &Lame<f64>,
    rest: &ElementRest<f64>,
    g: &[Vector3<f64>; 4],
    x: &[[f64; 3]; 4],
) -> f64 {
    element_energy(l, rest, g, x) + b.element_energy(rest.volume, &displacement_gradient(x, g))
}

fn barrier_gradient(
    b: &InversionBarrier<f64>,
    l: &Lame<f64>,
    rest: &ElementRest<f64>,
    g: &[Vector3<f64>; 4],
    x: &[[f64; 3]; 4],
) -> [f64; 12] {
    let mut e = 0.0;
    let mut grad = element_gradient(l, rest, g, x);
    let h = displacement_gradient(x, g);
    b.add_element_gradient(rest.volume, g, &h, &mut e, &mut grad);
    flat(&grad)
}

#[test]
fn barrier_density_is_c2_at_the_floor_and_zero_above() {
    let b = InversionBarrier::for_material(&lame(0.3));
    assert!((b.floor - 1.0 / 3f64.sqrt()).abs() < 1e-15);
    assert_eq!(b.density(b.floor), (0.0, -0.0, 0.0));
    assert_eq!(b.density(1.0), (0.0, -0.0, 0.0));
    let (psi, dpsi, d2psi) = b.density(b.floor - 1e-9);
    assert!(psi.abs() < 1e-20 && dpsi.abs() < 1e-10 && d2psi.abs() < 1e-4 * b.stiffness);
    // A flat element is pushed with the barrier's stiffness.
    let (_, dpsi, _) = b.density(0.0);
    assert!((dpsi + b.stiffness).abs() <= 1e-12 * b.stiffness);
    // Derivatives against finite differences, through inversion.
    for j in [0.5, 0.2, 0.0, -0.3, -1.0] {
        let h = 1e-6;
        let (psi, dpsi, d2psi) = b.density(j);
        let (pp, dp, _) = b.density(j + h);
        let (pm, dm, _) = b.density(j - h);
        assert!(psi > 0.0);
        assert!(((pp - pm) / (2.0 * h) - dpsi).abs() <= 1e-6 * dpsi.abs());
        assert!(((dp - dm) / (2.0 * h) - d2psi).abs() <= 1e-6 * d2psi.abs());
    }
}

/// The assembly's gradient without tangent sums the law's and the barrier's stresses and forms
/// the nodes' gradient once ([`Law::element_energy_stress_of_h`],
/// [`InversionBarrier::add_element_stress`], [`element_gradient_of_stress`]): the same energy,
/// bit for bit, and the same gradient to rounding as the law's gradient plus the barrier's,
/// under both laws, through inversion.
#[test]
fn the_summed_stress_gives_the_law_and_barrier_gradients() {
    let mut laws = [Law::SaintVenantKirchhoff; 2];
    if Law::StableNeoHookean.is_built() {
        laws[1] = Law::StableNeoHookean;
    }
    let mut active = 0;
    for law in laws {
        for_cases(|kind, nu, l, rest, g, x, _| {
            let b = InversionBarrier {
                floor: 0.9,
                stiffness: 10.0 * (l.lambda + 2.0 * l.mu),
            };
            let h = displacement_gradient(x, g);
            if (Matrix3::identity() + h).determinant() < b.floor {
                active += 1;
            }
            let mut e_two = law.element_energy_of_h(l, rest.volume, &h);
            let mut two = law.element_gradient_of_h(l, rest.volume, g, &h);
            b.add_element_gradient(rest.volume, g, &h, &mut e_two, &mut two);
            let (mut e_one, mut p) = law.element_energy_stress_of_h(l, rest.volume, &h);
            b.add_element_stress(rest.volume, &h, &mut e_one, &mut p);
            let one = element_gradient_of_stress(rest.volume, &p, g);
            assert_eq!(e_one, e_two, "{law:?} {kind:?} nu={nu}");
            let err = max_abs((0..12).map(|i| flat(&one)[i] - flat(&two)[i])) / max_abs(flat(&two));
            assert!(err <= 1e-13, "{law:?} {kind:?} nu={nu}: {err:e}");
        });
    }
    assert!(active > 0, "no case reached the barrier");
}

#[test]
fn barrier_gradient_and_exact_tangent_match_finite_differences() {
    let mut active = 0;
    for_cases(|kind, nu, l, rest, g, x, h| {
        // Stiffer than the default so that the barrier dominates where it acts.
        let b = InversionBarrier {
            floor: 0.9,
            stiffness: 10.0 * (l.lambda + 2.0 * l.mu),
        };
        let f = Matrix3::identity() + displacement_gradient(x, g);
        if f.determinant() < b.floor {
            active += 1;
        }
        let step = 1e-6 * h;
        let grad = barrier_gradient(&b, l, rest, g, x);
        let fd: [f64; 12] = core::array::from_fn(|i| {
            let ep = barrier_energy(&b, l, rest, g, &perturbed(x, i, step));
            let em = barrier_energy(&b, l, rest, g, &perturbed(x, i, -step));
            (ep - em) / (2.0 * step)
        });
        let err = max_abs((0..12).map(|i| grad[i] - fd[i])) / max_abs(grad);
        assert!(err <= 1e-6, "{kind:?} nu={nu}: gradient error {err:e}");

        let eval = with_barrier(&b, l, rest, g, x, TangentProjection::Exact);
        assert_eq!(eval.energy, barrier_energy(&b, l, rest, g, x));
        assert_eq!(flat(&eval.gradient), grad);
        let k = assemble(&eval.tangent);
        let mut fd = K12::zeros();
        for j in 0..12 {
            let gp = barrier_gradient(&b, l, rest, g, &perturbed(x, j, step));
            let gm = barrier_gradient(&b, l, rest, g, &perturbed(x, j, -step));
            for i in 0..12 {
                fd[(i, j)] = (gp[i] - gm[i]) / (2.0 * step);
            }
        }
        let err = (k - fd).amax() / k.amax();
        assert!(err <= 1e-6, "{kind:?} nu={nu}: tangent error {err:e}");
        assert!((k - k.transpose()).amax() <= 1e-12 * k.amax());

        // The projected tangent stays positive semidefinite with the barrier's term.
        let p = with_barrier(&b, l, rest, g, x, TangentProjection::PositiveDefinite);
        let kp = assemble(&p.tangent);
        assert!(
            min_eig_ratio(&kp) >= -1e-10,
            "{kind:?} nu={nu}: projected tangent not PSD"
        );
    });
    // The compressed and inverted cases put the barrier to work.
    assert!(active >= 48, "the barrier acted in {active} cases only");
}

#[test]
fn barrier_pushes_an_inverted_element_back_out() {
    let l = lame(0.3);
    let b = InversionBarrier::for_material(&l);
    let xr = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let rest = ElementRest::new(&xr, 0).unwrap();
    let g = rest.shape_gradients();
    // Node 3 pushed through the opposite face to z = −0.5: SVK's force on it points
    // further down (towards the mirror image, which SVK finds stress-free); the barrier's
    // points up, and wins.
    let mut x = [[0.0; 3]; 4];
    x[3][2] = -1.5;
    let svk = element_gradient(&l, &rest, &g, &x);
    let mut e = 0.0;
    let mut total = svk;
    b.add_element_gradient(
        rest.volume,
        &g,
        &displacement_gradient(&x, &g),
        &mut e,
        &mut total,
    );
    // The force is minus the gradient.
    assert!(-svk[3].z < 0.0, "SVK pulls node 3 further through");
    assert!(-total[3].z > 0.0, "with the barrier node 3 is pushed back");
    assert!(e > 0.0);
    // At rest and under mild compression, nothing changes.
    let mut mild = [[0.0; 3]; 4];
    mild[3][2] = -0.3;
    let mut none = element_gradient(&l, &rest, &g, &mild);
    let before = none;
    let mut e0 = 0.0;
    let h = displacement_gradient(&mild, &g);
    b.add_element_gradient(rest.volume, &g, &h, &mut e0, &mut none);
    assert_eq!((e0, none), (0.0, before));
}

fn min_eig_ratio(k: &K12) -> f64 {
    let eig = SymmetricEigen::new(*k).eigenvalues;
    eig.min() / max_abs(eig.iter().copied())
}

#[test]
fn the_shortcut_skips_only_what_the_eigen_solve_keeps() {
    // Positive definite (tensile, sheared), semidefinite and indefinite stresses.
    let pd = Matrix3::new(4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 2.0);
    let psd = Matrix3::new(1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 2.0);
    let indefinite = Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, -0.5);
    assert!(positive_definite(&pd));
    assert!(!positive_definite(&psd) && !positive_definite(&indefinite));
    // What the shortcut returns (`s`) is what the eigen-solve returns, bit for bit.
    let (lam, _) = eigen3::symmetric_eigen3(&pd);
    assert!(lam.iter().all(|&l| l > 0.0));
    assert_eq!(positive_part(&pd), pd);
    let projected = positive_part(&indefinite);
    assert_ne!(projected, indefinite);
    let eig = SymmetricEigen::new(projected).eigenvalues;
    assert!(eig.iter().all(|&l| l >= -1e-12), "{eig}");
}

#[test]
fn projected_tangent_is_psd_and_exact_for_psd_stress() {
    let mut indefinite_seen = 0;
    let mut worst_psd: f64 = 0.0;
    for_cases(|kind, nu, l, rest, g, x, _| {
        let exact = assemble(
            &element_energy_gradient_tangent(l, rest, g, x, TangentProjection::Exact).tangent,
        );
        let proj = assemble(
            &element_energy_gradient_tangent(l, rest, g, x, TangentProjection::PositiveDefinite)
                .tangent,
        );
        let r = min_eig_ratio(&proj);
        worst_psd = worst_psd.min(r);
        assert!(
            r >= -1e-10,
            "{kind:?} nu={nu}: smallest/largest eigenvalue {r:e}"
        );
        if min_eig_ratio(&exact) < -1e-8 {
            indefinite_seen += 1;
        }
        if matches!(kind, Kind::Stretch) && nu >= 0.0 {
            // Pure stretch: E ⪰ 0 and λ ≥ 0 make S ⪰ 0, so nothing is projected.
            assert_eq!(proj, exact, "{kind:?} nu={nu}");
        }
    });
    // The projection has something to do on the compressed and inverted cases.
    assert!(
        indefinite_seen > 20,
        "only {indefinite_seen} indefinite exact tangents"
    );
}

#[test]
fn hand_made_lame_outside_range_is_clamped_to_psd() {
    let mut rng = Rng(7);
    let l = Lame {
        mu: 100.0,
        lambda: -300.0,
    }; // 3λ + 2μ < 0
    for kind in KINDS {
        let xr = rest_tet(&mut rng, 1.0);
        let rest = ElementRest::new(&xr, 0).unwrap();
        let g = rest.shape_gradients();
        let x = disp(&deform(&mut rng, kind, &xr), &xr);
        let k = assemble(
            &element_energy_gradient_tangent(
                &l,
                &rest,
                &g,
                &x,
                TangentProjection::PositiveDefinite,
            )
            .tangent,
        );
        assert!(min_eig_ratio(&k) >= -1e-10, "{kind:?}");
    }
}

#[test]
fn collapsed_and_inverted_elements_stay_finite() {
    let mut rng = Rng(99);
    let xr = rest_tet(&mut rng, 1.0);
    let rest = ElementRest::new(&xr, 0).unwrap();
    let g = rest.shape_gradients();
    let c = vecs(&xr)[0];
    let all_same = [[c.x, c.y, c.z]; 4];
    let mut flat_z = xr;
    for p in &mut flat_z {
        p[2] = 0.0;
    }
    let mut line = xr;
    for p in &mut line {
        p[1] = 0.0;
        p[2] = 0.0;
    }
    let inverted = deform(&mut rng, Kind::Inverted, &xr);
    let mirrored = [xr[0], xr[2], xr[1], xr[3]];
    for nu in [0.3, -0.9, 0.499] {
        let l = lame(nu);
        for x in [all_same, flat_z, line, inverted, mirrored] {
            let x = disp(&x, &xr);
            let det = deformation_gradient(&x, &g).determinant();
            assert!(det <= 1e-12, "det F = {det}");
            for projection in [
                TangentProjection::Exact,
                TangentProjection::PositiveDefinite,
            ] {
                let e = element_energy_gradient_tangent(&l, &rest, &g, &x, projection);
                assert!(e.energy.is_finite());
                assert!(e.gradient.iter().all(|v| v.iter().all(|c| c.is_finite())));
                assert!(
                    e.tangent
                        .iter()
                        .flatten()
                        .all(|m| m.iter().all(|c| c.is_finite()))
                );
            }
        }
    }
}

#[test]
fn rigid_motion_has_zero_energy_and_force() {
    let mut rng = Rng(3);
    let l = lame(0.3);
    for _ in 0..50 {
        let xr = rest_tet(&mut rng, 1.0);
        let rest = ElementRest::new(&xr, 0).unwrap();
        let g = rest.shape_gradients();
        let r = rng.rotation();
        let t = rng.vec3(5.0);
        let x = disp(&arr(&vecs(&xr).map(|v| r * v + t)), &xr);
        let e = element_energy_gradient_tangent(&l, &rest, &g, &x, TangentProjection::Exact);
        // A unit strain would give energy ~ μ V and forces ~ μ V |g|.
        let force_scale = l.mu * rest.volume * max_abs(g.iter().flat_map(|v| v.iter().copied()));
        assert!(e.energy.abs() <= 1e-24 * l.mu * rest.volume, "{}", e.energy);
        assert!(max_abs(flat(&e.gradient)) <= 1e-12 * force_scale);
    }
}

#[test]
fn lame_closed_form_and_rejections() {
    let l = Lame::<f64>::from_young_poisson(1000.0, 0.3).unwrap();
    assert!((l.mu - 384.615_384_615_384_6).abs() < 1e-10);
    assert!((l.lambda - 576.923_076_923_077).abs() < 1e-10);
    let l = Lame::from_young_poisson(1000.0, -0.5).unwrap();
    assert!(l.lambda < 0.0 && 3.0 * l.lambda + 2.0 * l.mu > 0.0);
    let young = Err(Error::InvalidParameter {
        parameter: Parameter::YoungModulus,
    });
    let poisson = Err(Error::InvalidParameter {
        parameter: Parameter::PoissonRatio,
    });
    assert_eq!(Lame::from_young_poisson(1000.0, 0.5), poisson);
    assert_eq!(Lame::from_young_poisson(1000.0, 0.7), poisson);
    assert_eq!(Lame::from_young_poisson(1000.0, -1.0), poisson);
    assert_eq!(Lame::from_young_poisson(1000.0, f64::NAN), poisson);
    assert_eq!(Lame::from_young_poisson(0.0, 0.3), young);
    assert_eq!(Lame::from_young_poisson(-5.0, 0.3), young);
    assert_eq!(Lame::from_young_poisson(f64::INFINITY, 0.3), young);
    assert_eq!(Lame::from_young_poisson(f64::NAN, 0.3), young);
    assert_eq!(Lame::from_young_poisson(1e308, 0.5 - 1e-17), poisson);
}

#[test]
fn rest_geometry_errors() {
    let good = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let rest = ElementRest::<f64>::new(&good, 0).unwrap();
    assert!((rest.volume - 1.0 / 6.0).abs() < 1e-15);
    assert_eq!(rest.dm_inv, Matrix3::identity());
    // F of the rest positions is the identity, and the shape gradients sum to zero.
    let g = rest.shape_gradients();
    assert_eq!(
        deformation_gradient(&[[0.0; 3]; 4], &g),
        Matrix3::identity()
    );
    assert_eq!(g[0] + g[1] + g[2] + g[3], Vector3::zeros());

    let inverted = [good[0], good[2], good[1], good[3]];
    assert_eq!(
        ElementRest::new(&inverted, 7),
        Err(Error::InvertedElement { tet: 7 })
    );
    let coplanar = [good[0], good[1], good[2], [0.3, 0.3, 0.0]];
    assert_eq!(
        ElementRest::new(&coplanar, 3),
        Err(Error::DegenerateElement { tet: 3 })
    );
    let sliver = [good[0], good[1], good[2], [0.3, 0.3, 1e-14]];
    assert_eq!(
        ElementRest::new(&sliver, 3),
        Err(Error::DegenerateElement { tet: 3 })
    );
    let thin_but_fine = [good[0], good[1], good[2], [0.3, 0.3, 1e-9]];
    assert!(ElementRest::new(&thin_but_fine, 3).is_ok());
    let coincident = [[2.0, 2.0, 2.0]; 4];
    assert_eq!(
        ElementRest::new(&coincident, 1),
        Err(Error::DegenerateElement { tet: 1 })
    );
    // Degeneracy is relative to size: a tiny well-shaped tetrahedron is accepted.
    let tiny = good.map(|p| p.map(|c| c * 1e-30));
    assert!(ElementRest::new(&tiny, 0).is_ok());
    let mut nan = good;
    nan[2][1] = f64::NAN;
    assert_eq!(
        ElementRest::new(&nan, 5),
        Err(Error::NonFiniteInput {
            resource: Resource::Nodes,
            position: 22
        })
    );
    let mut inf = good;
    inf[0][0] = f64::INFINITY;
    assert_eq!(
        ElementRest::new(&inf, usize::MAX),
        Err(Error::NonFiniteInput {
            resource: Resource::Nodes,
            position: usize::MAX
        })
    );
    let huge = good.map(|p| p.map(|c| c * 1e200));
    assert!(matches!(
        ElementRest::new(&huge, 0),
        Err(Error::NonFiniteInput { .. })
    ));
}

#[test]
fn small_strain_matches_linear_elasticity() {
    let l = lame(0.3);
    let mut prev_err = f64::NAN;
    for eps in [1e-2, 1e-3, 1e-4] {
        let f = Matrix3::from_diagonal(&Vector3::new(1.0 + eps, 1.0, 1.0));
        let p = first_piola_kirchhoff(&l, &f);
        let sigma = Matrix3::from_diagonal(&Vector3::new(
            (l.lambda + 2.0 * l.mu) * eps,
            l.lambda * eps,
            l.lambda * eps,
        ));
        let err = (p - sigma).amax() / sigma.amax();
        // SVK: P_xx = (1 + ε)(λ + 2μ)(ε + ε²/2), so the relative error is 3ε/2 + O(ε²).
        assert!(err <= 2.0 * eps, "eps={eps}: relative error {err:e}");
        assert!(err >= eps, "eps={eps}: relative error {err:e}");
        if prev_err.is_finite() {
            let ratio = prev_err / err;
            assert!((9.0..11.0).contains(&ratio), "error ratio {ratio}");
        }
        prev_err = err;
        // Energy density against ½ σ : ε.
        let psi = energy_density(&l, &f);
        let lin = 0.5 * (l.lambda + 2.0 * l.mu) * eps * eps;
        assert!(((psi - lin) / lin).abs() <= 2.0 * eps);
    }
}

/// A random spectrum of one of four kinds (`kind` below 4): uniform, a repeated eigenvalue,
/// clustered eigenvalues, one eigenvalue dominating.
fn spectrum(rng: &mut Rng, kind: u64) -> Vector3<f64> {
    match kind {
        0 => rng.vec3(1.0),
        1 => {
            let a = rng.range(-1.0, 1.0);
            Vector3::new(a, a, rng.range(-1.0, 1.0))
        }
        2 => {
            let a = rng.range(-1.0, 1.0);
            Vector3::new(a, a + 1e-9, a - 1e-7)
        }
        _ => Vector3::new(1.0, rng.range(-1e-8, 1e-8), rng.range(-1e-3, 1e-3)),
    }
}

/// `Q diag(d) Qᵀ`, symmetrised to the last bit.
fn symmetric_with(q: &Matrix3<f64>, d: &Vector3<f64>) -> Matrix3<f64> {
    let a = q * Matrix3::from_diagonal(d) * q.transpose();
    (a + a.transpose()) * 0.5
}

#[test]
fn jacobi_is_accurate_after_fixed_sweeps() {
    let mut rng = Rng(11);
    let mut cases = [Matrix3::<f64>::zeros(); 2003];
    cases[1] = Matrix3::from_diagonal(&Vector3::new(3.0, -1.0, 2.0));
    cases[2] = Matrix3::identity() * 5.0;
    for case in cases.iter_mut().skip(3) {
        let q = rng.rotation();
        let scale = 10f64.powf(rng.range(-6.0, 6.0));
        let kind = rng.next_u64() % 4;
        *case = symmetric_with(&q, &(spectrum(&mut rng, kind) * scale));
    }
    let mut worst_rec: f64 = 0.0;
    let mut worst_orth: f64 = 0.0;
    for a in &cases {
        let (lam, q) = symmetric_eigen3(a);
        let norm = a.norm().max(f64::MIN_POSITIVE);
        let rec = (q * Matrix3::from_diagonal(&lam) * q.transpose() - a).norm() / norm;
        let orth = (q.transpose() * q - Matrix3::identity()).norm();
        worst_rec = worst_rec.max(rec);
        worst_orth = worst_orth.max(orth);
        assert!(rec <= 1e-14, "reconstruction error {rec:e} for {a}");
        assert!(orth <= 1e-14);
        let mut ours: [f64; 3] = lam.into();
        ours.sort_by(f64::total_cmp);
        let mut reference: [f64; 3] = SymmetricEigen::new(*a).eigenvalues.into();
        reference.sort_by(f64::total_cmp);
        for i in 0..3 {
            assert!((ours[i] - reference[i]).abs() <= 1e-13 * norm);
        }
    }
    // Already diagonal: no rotation, exact, no division.
    let d = Matrix3::from_diagonal(&Vector3::new(3.0, -1.0, 0.0));
    assert_eq!(
        symmetric_eigen3(&d),
        (Vector3::new(3.0, -1.0, 0.0), Matrix3::identity())
    );
}

/// `S⁺` through the Jacobi eigen-decomposition: `Q max(Λ, 0) Qᵀ`, the projection the closed
/// form replaced.
fn positive_part_by_jacobi(s: &Matrix3<f64>) -> Matrix3<f64> {
    let (lam, q) = symmetric_eigen3(s);
    let mut out = Matrix3::zeros();
    for (qi, &l) in q.column_iter().zip(lam.iter()) {
        out += qi * qi.transpose() * l.max(0.0);
    }
    out
}

#[test]
fn the_closed_form_projection_matches_jacobi_and_stays_semidefinite() {
    let mut rng = Rng(13);
    let mut cases = [Matrix3::<f64>::zeros(); 20006];
    cases[1] = Matrix3::identity() * -2.0;
    cases[2] = Matrix3::from_diagonal(&Vector3::new(3.0, -1.0, 2.0));
    cases[3] = Matrix3::from_diagonal(&Vector3::new(-3.0, -1.0, 2.0));
    cases[4] = Matrix3::from_diagonal(&Vector3::new(0.0, -1.0, 0.0));
    cases[5] = Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, -0.5);
    for case in cases.iter_mut().skip(6) {
        let q = rng.rotation();
        let scale = 10f64.powf(rng.range(-8.0, 8.0));
        let d = match rng.next_u64() % 6 {
            // Clustered about zero: the sign decisions and the eigenvector are hardest.
            4 => Vector3::new(
                rng.range(-1e-9, 1e-9),
                rng.range(-1e-9, 1e-9),
                rng.range(-1.0, 1.0),
            ),
            // Tension with one slightly compressed direction, the common indefinite stress.
            5 => Vector3::new(1.0, rng.range(0.0, 1.0), -rng.range(0.0, 1e-2)),
            kind => spectrum(&mut rng, kind),
        };
        *case = symmetric_with(&q, &(d * scale));
    }
    let mut worst: f64 = 0.0;
    for s in &cases {
        let norm = s.norm().max(f64::MIN_POSITIVE);
        let ours = positive_part_closed_form(s);
        let jacobi = positive_part_by_jacobi(s);
        let error = (ours - jacobi).norm() / norm;
        worst = worst.max(error);
        assert!(
            error <= 1e-14,
            "{error:e} off the Jacobi projection for {s}"
        );
        assert_eq!(ours, ours.transpose(), "not symmetric for {s}");
        let eig = SymmetricEigen::new(ours).eigenvalues;
        assert!(
            eig.min() >= -1e-14 * norm,
            "not semidefinite ({eig}) for {s}"
        );
        // The eigensystem in closed form against nalgebra's eigenvalues, and as eigenpairs.
        let a = s / s.amax().max(f64::MIN_POSITIVE);
        let pairs = eigensystem(&a);
        let mut closed = pairs.map(|(l, _)| l);
        closed.sort_by(f64::total_cmp);
        let mut reference: [f64; 3] = SymmetricEigen::new(a).eigenvalues.into();
        reference.sort_by(f64::total_cmp);
        for (c, r) in closed.iter().zip(reference) {
            assert!(
                (c - r).abs() <= 1e-14,
                "eigenvalues {closed:?} against {reference:?}"
            );
        }
        for (l, v) in pairs {
            assert!(
                (a * v - v * l).norm() <= 1e-14,
                "({l}, {v}) not an eigenpair of {a}"
            );
            assert!((v.norm() - 1.0).abs() <= 1e-14);
        }
    }
    // A semidefinite stress comes back bit for bit, as the projected tangent's exactness needs.
    let pd = Matrix3::new(4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 2.0);
    assert_eq!(positive_part_closed_form(&pd), pd);
    // Not finite: handed back for the caller's checks, never a panic.
    let inf = Matrix3::from_diagonal(&Vector3::new(f64::INFINITY, -1.0, 2.0));
    assert_eq!(positive_part_closed_form(&inf), inf);
    assert!(
        worst > 0.0,
        "the two projections never differed: the comparison ran on nothing"
    );
}

/// Sweeps needed until the off-diagonal norm of `QᵀAQ` is below `EPS · ‖A‖`, over random,
/// repeated and clustered spectra: the basis of [`JACOBI_SWEEPS`].
#[test]
fn jacobi_sweeps_needed() {
    let mut rng = Rng(12);
    let mut histogram = [0usize; JACOBI_SWEEPS + 1];
    for _ in 0..20000 {
        let q = rng.rotation();
        let d = match rng.next_u64() % 4 {
            0 => rng.vec3(1.0),
            1 => {
                let a = rng.range(-1.0, 1.0);
                Vector3::new(a, a + 1e-12, rng.range(-1.0, 1.0))
            }
            2 => {
                let a = rng.range(-1.0, 1.0);
                Vector3::new(a, a + 1e-8, a - 1e-6)
            }
            _ => Vector3::new(1.0, rng.range(-1e-8, 1e-8), rng.range(-1e-3, 1e-3)),
        };
        let a = q * Matrix3::from_diagonal(&d) * q.transpose();
        let a = (a + a.transpose()) * 0.5;
        let off = |sweeps: usize| {
            let (_, qq) = jacobi(&a, sweeps);
            let m = qq.transpose() * a * qq;
            (m - Matrix3::from_diagonal(&m.diagonal())).norm()
        };
        let needed = (0..=JACOBI_SWEEPS)
            .find(|&k| off(k) <= 4.0 * f64::EPSILON * a.norm())
            .unwrap_or_else(|| panic!("not converged in {JACOBI_SWEEPS} sweeps: {a}"));
        histogram[needed] += 1;
    }
    assert_eq!(histogram[JACOBI_SWEEPS], 0, "no margin left");
}

#[test]
#[cfg(feature = "f32")]
fn works_in_f32() {
    let l = Lame::<f32>::from_young_poisson(3000.0, 0.3).unwrap();
    let xr = [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let rest = ElementRest::new(&xr, 0).unwrap();
    let g = rest.shape_gradients();
    // Node 3 pushed through the opposite face: displacements from rest.
    let u = [
        [0.0f32, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.1, 0.1, -1.5],
    ];
    let e = element_energy_gradient_tangent(&l, &rest, &g, &u, TangentProjection::PositiveDefinite);
    assert!(e.energy.is_finite() && e.energy > 0.0);
    assert!(
        e.tangent
            .iter()
            .flatten()
            .all(|m| m.iter().all(|c| c.is_finite()))
    );
}

/// Which laws this core accepts: SVK always, the stable Neo-Hookean law with its feature (CI
/// runs the core's tests without it too).
#[test]
fn a_law_is_accepted_exactly_when_built() {
    assert!(Law::SaintVenantKirchhoff.is_built());
    assert_eq!(
        Law::StableNeoHookean.is_built(),
        cfg!(feature = "neo-hookean")
    );
}

// The stable Neo-Hookean law.
#[cfg(feature = "neo-hookean")]
mod neo_hookean {
    use super::*;

    const SNH: Law = Law::StableNeoHookean;

    fn snh_energy(
        l: &Lame<f64>,
        rest: &ElementRest<f64>,
        g: &[Vector3<f64>; 4],
        x: &[[f64; 3]; 4],
    ) -> f64 {
        SNH.element_energy_of_h(l, rest.volume, &displacement_gradient(x, g))
    }

    fn snh_gradient(
        l: &Lame<f64>,
        rest: &ElementRest<f64>,
        g: &[Vector3<f64>; 4],
        x: &[[f64; 3]; 4],
    ) -> [f64; 12] {
        flat(&SNH.element_gradient_of_h(l, rest.volume, g, &displacement_gradient(x, g)))
    }

    /// The map from node displacements (12) to `vec(F)` (9, row-major `F_ij` at `3 i + j`):
    /// `δF = Σ_a δx_a g_aᵀ`.
    fn f_map(g: &[Vector3<f64>; 4]) -> SMatrix<f64, 9, 12> {
        SMatrix::<f64, 9, 12>::from_fn(|r, c| {
            let (i, j) = (r / 3, r % 3);
            let (a, k) = (c / 3, c % 3);
            if i == k { g[a][j] } else { 0.0 }
        })
    }

    /// The Neo-Hookean Hessian in `vec(F)` (row-major), by central differences of the stress.
    fn snh_hessian_f(l: &Lame<f64>, f: &Matrix3<f64>) -> SMatrix<f64, 9, 9> {
        let step = 1e-6 * (1.0 + f.norm());
        let mut hess = SMatrix::<f64, 9, 9>::zeros();
        for c in 0..9 {
            let mut fp = *f;
            let mut fm = *f;
            fp[(c / 3, c % 3)] += step;
            fm[(c / 3, c % 3)] -= step;
            let dp = (neo_hookean_first_piola_kirchhoff(l, &fp)
                - neo_hookean_first_piola_kirchhoff(l, &fm))
                / (2.0 * step);
            for r in 0..9 {
                hess[(r, c)] = dp[(r / 3, r % 3)];
            }
        }
        (hess + hess.transpose()) * 0.5
    }

    #[test]
    fn neo_hookean_is_stress_free_at_rest_and_linearizes_to_the_same_lame_pair_as_svk() {
        for_cases(|kind, nu, l, rest, g, _x, _h| {
            let at_rest = [[0.0; 3]; 4];
            let snh =
                SNH.element_energy_gradient_tangent(l, rest, g, &at_rest, TangentProjection::Exact);
            let svk =
                element_energy_gradient_tangent(l, rest, g, &at_rest, TangentProjection::Exact);
            assert_eq!(snh.energy, 0.0);
            assert!(max_abs(flat(&snh.gradient)) == 0.0, "{kind:?} nu={nu}");
            let (ks, kv) = (assemble(&snh.tangent), assemble(&svk.tangent));
            assert!((ks - kv).amax() <= 1e-12 * kv.amax(), "{kind:?} nu={nu}");
            // Rigid motions are free: a rotation costs nothing and stresses nothing.
            let q = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
            assert!(neo_hookean_energy_density(l, &q).abs() < 1e-12 * l.mu);
            assert!(neo_hookean_first_piola_kirchhoff(l, &q).amax() < 1e-12 * l.mu);
        });
    }

    #[test]
    fn neo_hookean_gradient_and_exact_tangent_match_finite_differences() {
        for_cases(|kind, nu, l, rest, g, x, h| {
            let step = 1e-6 * h;
            let grad = snh_gradient(l, rest, g, x);
            let fd: [f64; 12] = core::array::from_fn(|i| {
                (snh_energy(l, rest, g, &perturbed(x, i, step))
                    - snh_energy(l, rest, g, &perturbed(x, i, -step)))
                    / (2.0 * step)
            });
            let err = max_abs((0..12).map(|i| grad[i] - fd[i])) / max_abs(grad);
            assert!(
                err <= 1e-6,
                "{kind:?} nu={nu}: gradient, relative error {err:e}"
            );
            let eval = SNH.element_energy_gradient_tangent(l, rest, g, x, TangentProjection::Exact);
            let k = assemble(&eval.tangent);
            let mut fdk = K12::zeros();
            for j in 0..12 {
                let gp = snh_gradient(l, rest, g, &perturbed(x, j, step));
                let gm = snh_gradient(l, rest, g, &perturbed(x, j, -step));
                for i in 0..12 {
                    fdk[(i, j)] = (gp[i] - gm[i]) / (2.0 * step);
                }
            }
            let err = (k - fdk).amax() / k.amax();
            assert!(
                err <= 1e-6,
                "{kind:?} nu={nu}: tangent, relative error {err:e}"
            );
            assert_eq!(flat(&eval.gradient), grad);
            assert_eq!(eval.energy, snh_energy(l, rest, g, x));
        });
    }

    #[test]
    fn signed_svd_reconstructs_f_with_rotations_and_the_sign_of_det_on_the_last_value() {
        let mut rng = Rng(0xD15C_0517);
        let fixed = [
            Matrix3::identity(),
            Matrix3::zeros(),
            Matrix3::from_diagonal(&Vector3::new(2.0, 1.0, 0.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 0.0, 0.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)),
            Matrix3::from_diagonal(&Vector3::new(3.0, 3.0, 3.0)),
        ];
        let random = (0..400).map(|k| {
            if k % 2 == 0 {
                Matrix3::from_fn(|_, _| rng.range(-2.0, 2.0))
            } else {
                rng.rotation()
                    * Matrix3::from_diagonal(&Vector3::new(1.5, 1.5, 0.2))
                    * rng.rotation()
            }
        });
        let cases = fixed.into_iter().chain(random);
        for f in cases {
            let (u, sigma, v) = neohookean::signed_svd(&f);
            let scale = 1.0 + f.norm();
            assert!(
                (u.transpose() * u - Matrix3::identity()).amax() < 1e-12,
                "{f}"
            );
            assert!(
                (v.transpose() * v - Matrix3::identity()).amax() < 1e-12,
                "{f}"
            );
            assert!((u.determinant() - 1.0).abs() < 1e-12 && (v.determinant() - 1.0).abs() < 1e-12);
            let back = u * Matrix3::from_diagonal(&sigma) * v.transpose();
            assert!((back - f).amax() <= 1e-10 * scale, "{f}: {back}");
            assert!(
                sigma.x >= sigma.y - 1e-12 * scale && sigma.y >= sigma.z.abs() - 1e-10 * scale,
                "{sigma}"
            );
            assert!(sigma.y >= 0.0 && sigma.x >= 0.0);
            if f.determinant() < -1e-9 {
                assert!(sigma.z < 0.0, "{f}: {sigma}");
            }
        }
    }

    /// The projection is the nearest positive semidefinite Hessian: against the Hessian in
    /// `vec(F)` (finite differences of the stress), eigen-solved by nalgebra, its negative
    /// eigenvalues set to zero and taken to the element's nodes.
    #[test]
    fn neo_hookean_projection_is_the_nearest_psd_hessian() {
        let mut clamped = 0;
        for_cases(|kind, nu, l, rest, g, x, _h| {
            let f = Matrix3::identity() + displacement_gradient(x, g);
            let hess = snh_hessian_f(l, &f);
            let eig = SymmetricEigen::new(hess);
            if eig
                .eigenvalues
                .iter()
                .any(|&e| e < -1e-6 * eig.eigenvalues.amax())
            {
                clamped += 1;
            }
            let plus = eig.eigenvectors
                * SMatrix::<f64, 9, 9>::from_diagonal(&eig.eigenvalues.map(|e| e.max(0.0)))
                * eig.eigenvectors.transpose();
            let m = f_map(g);
            let want = m.transpose() * plus * m * rest.volume;
            let got = assemble(
                &SNH.element_energy_gradient_tangent(
                    l,
                    rest,
                    g,
                    x,
                    TangentProjection::PositiveDefinite,
                )
                .tangent,
            );
            let err = (got - want).amax() / want.amax().max(1e-300);
            assert!(err <= 1e-5, "{kind:?} nu={nu}: relative error {err:e}");
            let min = SymmetricEigen::new(got).eigenvalues.min();
            assert!(
                min >= -1e-9 * got.amax(),
                "{kind:?} nu={nu}: eigenvalue {min:e}"
            );
        });
        // The cases include indefinite Hessians (compression, inversion), so the clamp is
        // exercised, not only the exact branch.
        assert!(clamped > 20, "{clamped} cases clamped");
    }

    /// Uniaxial stretch `λ` with the sides free: the lateral stretch `t` makes the lateral
    /// stress vanish, `μ t + s λ t = 0`, so `s = −μ/λ` and `λ t² = J = 1 + μ (λ − 1)/(λ (λ + μ))`
    /// in the law's own Lamé pair (`λ' = λ_L + μ`): a closed form to hold the stress against,
    /// and the reason for the law (SVK contracts far more).
    #[test]
    fn neo_hookean_lateral_contraction_under_uniaxial_stretch_has_its_closed_form() {
        let l = lame(0.45);
        let weight = l.lambda + l.mu;
        for stretch in [1.1, 1.3, 1.65, 2.0] {
            let j = 1.0 + l.mu * (stretch - 1.0) / (stretch * weight);
            let t = (j / stretch).sqrt();
            let f = Matrix3::from_diagonal(&Vector3::new(stretch, t, t));
            let p = neo_hookean_first_piola_kirchhoff(&l, &f);
            assert!(
                p[(1, 1)].abs() <= 1e-12 * l.mu && p[(2, 2)].abs() <= 1e-12 * l.mu,
                "{p}"
            );
            assert!(p[(0, 0)] > 0.0);
            if stretch == 1.65 {
                // About 0.79: rubber keeps most of its width; SVK's 0.47 does not.
                assert!((t - 0.794).abs() < 2e-3, "{t}");
                let s = second_piola_kirchhoff(
                    &l,
                    &Matrix3::from_diagonal(&Vector3::new(stretch, 0.47, 0.47)),
                );
                assert!(
                    s[(1, 1)].abs() < 0.05 * l.mu,
                    "SVK's lateral stretch near 0.47: {s}"
                );
            }
        }
    }
}

/// Two elements at once ([`paired::svk_shares_of_two`], what a gradient-only assembly of SVK
/// elements runs) give each element the energy, barrier energy and gradient of the
/// one-element path bit for bit (a zero's sign aside, which no sum can tell), on every kind of
/// deformation — below the barrier's floor and inverted included — with and without the
/// barrier, and for each element of a pair whatever the other is.
#[cfg(feature = "paired-elements")]
#[test]
fn paired_gradient_is_the_single_elements_bit_for_bit() {
    let same = |a: f64, b: f64| a == b || (a.is_nan() && b.is_nan());
    let mut rng = Rng(0xB17_F0B17);
    let mut below_floor = 0;
    for nu in [0.3, 0.45, 0.0, -0.5] {
        let l = lame(nu);
        let floor_barrier = InversionBarrier::for_material(&l);
        for round in 0..200 {
            let kinds = [
                KINDS[round % KINDS.len()],
                KINDS[(round / 5 + 2) % KINDS.len()],
            ];
            let sizes = [rng.range(0.002, 2.0), rng.range(0.002, 2.0)];
            let rests = [0, 1].map(|k| rest_tet(&mut rng, sizes[k]));
            let elements = [0, 1].map(|k| ElementRest::new(&rests[k], k).unwrap());
            let u = [0, 1].map(|k| disp(&deform(&mut rng, kinds[k], &rests[k]), &rests[k]));
            for barrier in [Some(&floor_barrier), None] {
                let shares = paired::svk_shares_of_two(
                    &l,
                    barrier,
                    [&elements[0], &elements[1]],
                    [&u[0], &u[1]],
                );
                for ((rest, u), share) in elements.iter().zip(&u).zip(&shares) {
                    let g = rest.shape_gradients();
                    let du = displacement_gradient(u, &g);
                    let (energy, mut stress) =
                        Law::SaintVenantKirchhoff.element_energy_stress_of_h(&l, rest.volume, &du);
                    let barrier_energy = barrier.map(|b| {
                        let mut e = 0.0;
                        b.add_element_stress(rest.volume, &du, &mut e, &mut stress);
                        if (Matrix3::identity() + du).determinant() < b.floor {
                            below_floor += 1;
                        }
                        e
                    });
                    let gradient = element_gradient_of_stress(rest.volume, &stress, &g);
                    assert!(
                        same(share.energy, energy),
                        "{kinds:?}: {} {energy}",
                        share.energy
                    );
                    match (share.barrier_energy, barrier_energy) {
                        (Some(a), Some(b)) => assert!(same(a, b), "{kinds:?}: barrier {a} {b}"),
                        (None, None) => {}
                        other => panic!("barrier energies {other:?}"),
                    }
                    for (a, b) in share
                        .gradient
                        .iter()
                        .flatten()
                        .zip(gradient.iter().flatten())
                    {
                        assert!(same(*a, *b), "{kinds:?}: gradient {a} {b}");
                    }
                }
            }
        }
    }
    // The barrier acted in some of them.
    assert!(below_floor > 100, "{below_floor} elements below the floor");
}
