//! The simulator's energy, gradient and Hessian assembly, and the sparse LDLᵀ that solves with
//! the Hessian (the core's factorization).

use incise_core::Error as CoreError;
use incise_core::sparse::{LdlFactor, NONE, Symbolic};
use nalgebra::Vector3;

use crate::generate::neohookean::{Projection, element_energy, element_eval};

use super::{Energy, Failure, REGULARISATION, Simulator, SolveStats};

impl Simulator {
    /// Assembles and factorizes the Hessian at the current state (and `coupling` as in
    /// [`Simulator::assemble`]): the exact Hessian when it factorizes, i.e. is positive
    /// definite, which it is near a stable equilibrium even where single elements are not, so
    /// Newton converges quadratically; else the eigenvalue-clamped one, always positive
    /// semidefinite (with clamped element Hessians alone, convergence in compressed regions is
    /// only linear). Returns which one is in service.
    pub(super) fn factor_hessian(
        &self,
        lin: &mut Linear<'_>,
        grad: &mut [f64],
        values: &mut [f64],
        mut coupling: Option<(&[[f64; 3]], &mut [f64])>,
        stats: &mut SolveStats,
    ) -> Result<Projection, Failure> {
        self.assemble(
            &self.u,
            grad,
            values,
            Projection::Exact,
            coupling.as_mut().map(|(d, r)| (*d, &mut **r)),
        );
        if lin.factorize(values, &self.diag, 0).is_ok() {
            return Ok(Projection::Exact);
        }
        self.assemble(
            &self.u,
            grad,
            values,
            Projection::ClampEigenvalues,
            coupling,
        );
        lin.factorize(values, &self.diag, 3)?;
        stats.projected += 1;
        Ok(Projection::ClampEigenvalues)
    }

    /// Total energy with its rounding estimate from the element energies alone: each element
    /// energy is uncertain by a few ulps of the terms it is summed from.
    pub(super) fn energy_of(&self, u: &[[f64; 3]]) -> Energy {
        let mut e = Energy {
            value: 0.0,
            rounding: 0.0,
        };
        for (t, el) in self.tets.iter().zip(&self.elements) {
            let w = element_energy(&self.lame, &el.rest, &el.g, &t.map(|v| u[v as usize]));
            if !w.energy.is_finite() {
                return Energy {
                    value: f64::INFINITY,
                    rounding: f64::INFINITY,
                };
            }
            e.value += w.energy;
            e.rounding += w.magnitude;
        }
        e.rounding *= 8.0 * f64::EPSILON;
        e
    }

    /// Energy and gradient over the free unknowns (`grad`, overwritten). The rounding estimate
    /// adds to [`Simulator::energy_of`]'s the effect of the displacements being known only to
    /// `ε|u|`: each element's energy moves by its nodal forces times that.
    pub(super) fn energy_gradient(&self, u: &[[f64; 3]], grad: &mut [f64]) -> Energy {
        grad.fill(0.0);
        let mut e = self.energy_of(u);
        if !e.value.is_finite() {
            grad.fill(f64::NAN);
            return e;
        }
        let mut force_sum = 0.0;
        for (t, el) in self.tets.iter().zip(&self.elements) {
            let ue = t.map(|v| u[v as usize]);
            let ev = element_eval(&self.lame, &el.rest, &el.g, &ue, Projection::Exact);
            force_sum += ev.gradient.iter().map(|f| f.abs().sum()).sum::<f64>();
            self.scatter_gradient(t, &ev.gradient, grad);
        }
        let u_max = u.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        e.rounding += 8.0 * f64::EPSILON * u_max * force_sum;
        e
    }

    pub(super) fn scatter_gradient(&self, t: &[u32; 4], ge: &[Vector3<f64>; 4], grad: &mut [f64]) {
        for (a, &v) in t.iter().enumerate() {
            let f = self.free[v as usize];
            if f != NONE {
                for c in 0..3 {
                    grad[3 * f as usize + c] += ge[a][c];
                }
            }
        }
    }

    /// Gradient (`grad`) and positive semidefinite Hessian (`values`, upper pattern) over the
    /// free unknowns, both overwritten; with `coupling = Some((d, r))`, also `r = K_fp d` for
    /// the prescribed-node displacements `d` (indexed by node, zero on free nodes), overwritten.
    /// The state must be feasible (no inverted element).
    pub(super) fn assemble(
        &self,
        u: &[[f64; 3]],
        grad: &mut [f64],
        values: &mut [f64],
        projection: Projection,
        mut coupling: Option<(&[[f64; 3]], &mut [f64])>,
    ) {
        grad.fill(0.0);
        values.fill(0.0);
        if let Some((_, r)) = coupling.as_mut() {
            r.fill(0.0);
        }
        for ((t, el), map) in self.tets.iter().zip(&self.elements).zip(&self.scatter) {
            let ue = t.map(|v| u[v as usize]);
            let ev = element_eval(&self.lame, &el.rest, &el.g, &ue, projection);
            self.scatter_gradient(t, &ev.gradient, grad);
            for (e, &s) in map.iter().enumerate() {
                if s != NONE {
                    values[s as usize] += ev.hessian[(e / 12, e % 12)];
                }
            }
            if let Some((d, r)) = coupling.as_mut() {
                let de: [f64; 12] = std::array::from_fn(|j| d[t[j / 3] as usize][j % 3]);
                if de.iter().all(|&v| v == 0.0) {
                    continue;
                }
                for i in 0..12 {
                    let f = self.free[t[i / 3] as usize];
                    if f != NONE {
                        let ki: f64 = (0..12).map(|j| ev.hessian[(i, j)] * de[j]).sum();
                        r[3 * f as usize + i % 3] += ki;
                    }
                }
            }
        }
    }
}

/// The numeric side of the sparse solve, living for one [`Simulator::solve`].
pub(super) struct Linear<'s> {
    pub(super) sym: Symbolic<'s>,
    pub(super) ldl: LdlFactor<'s, f64>,
    pub(super) y: Vec<f64>,
    pub(super) cursor: Vec<u32>,
}

impl Linear<'_> {
    /// Adds `δ I` (`δ = 10⁻⁸ ×` mean diagonal) and factorizes; on a non-positive pivot raises
    /// `δ` a hundredfold, up to `retries` times.
    pub(super) fn factorize(
        &mut self,
        values: &mut [f64],
        diag: &[u32],
        retries: u32,
    ) -> Result<(), Failure> {
        let mean = diag.iter().map(|&s| values[s as usize]).sum::<f64>() / diag.len() as f64;
        // A free node in no tetrahedron has a zero diagonal; keep δ positive regardless.
        let mut delta = REGULARISATION * if mean > 0.0 { mean } else { 1.0 };
        let mut added = 0.0;
        for _ in 0..=retries {
            for &s in diag {
                values[s as usize] += delta - added;
            }
            added = delta;
            match self
                .ldl
                .factorize(&self.sym, values, &mut self.y, &mut self.cursor)
            {
                Ok(()) => return Ok(()),
                Err(CoreError::NotPositiveDefinite { .. }) => delta *= 100.0,
                Err(_) => return Err(Failure::Factorization),
            }
        }
        Err(Failure::Factorization)
    }

    /// `dir = −K⁻¹ grad` with the factor in service; returns the slope `dir · grad`.
    pub(super) fn newton_direction(&mut self, grad: &[f64], dir: &mut [f64]) -> f64 {
        for (d, g) in dir.iter_mut().zip(grad) {
            *d = -g;
        }
        self.solve(dir);
        dir.iter().zip(grad).map(|(d, g)| d * g).sum()
    }

    /// `b ← K⁻¹ b` with the factor in service.
    pub(super) fn solve(&mut self, b: &mut [f64]) {
        self.ldl
            .solve_in_place(&self.sym, b, &mut self.y)
            .expect("sizes match the symbolic factor built for this pattern");
    }
}
