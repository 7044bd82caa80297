//! Quasi-static simulation of the *real* object: a tetrahedral mesh of compressible
//! Neo-Hookean material ([`super::neohookean`]) whose prescribed nodes (held or grasped) are
//! moved frame by frame, the other nodes following to the energy minimum.
//!
//! Each [`Simulator::solve`] moves the prescribed nodes to their targets and minimises the elastic
//! energy over the free nodes:
//!
//! 1. **Sub-steps.** The prescribed displacement is applied in fractions of the frame's increment
//!    (dyadic, so they add up exactly): the whole increment first; a sub-step that fails is
//!    undone and retried at half its size, a sub-step that succeeds lets the next one double
//!    again. At most [`MAX_HALVINGS`] halvings per frame.
//! 2. **Predictor.** A sub-step moves the prescribed nodes by `d_p` and the free nodes by the
//!    linearised response `−K_ff⁻¹ K_fp d_p` from the current state, so that the elements next to
//!    a grasped node are carried along instead of being crushed by it. On the grasp test it
//!    saves a third of the Newton iterations of ordinary frames, and on its 14 mm push it cuts
//!    12 halvings and 67 iterations down to 1 and 14. If that start is inverted, the free nodes
//!    are left where they were; if that is inverted too, the sub-step fails.
//! 3. **Newton.** Newton's method on the free nodes. The assembled *exact* Hessian is tried
//!    first: near a stable equilibrium it is positive definite even where single elements are
//!    compressed into indefiniteness, and it gives quadratic convergence. If its LDLᵀ meets a
//!    non-positive pivot (or its step is not a descent direction), the positive semidefinite
//!    Hessian assembled from eigenvalue-clamped element Hessians is used instead. Clamped
//!    Hessians alone were tried first and converge only linearly (rate ≈ ½) once compressed
//!    elements are present: 25 iterations did not suffice on the grasp test. Both get a
//!    Tikhonov term `δ I`, `δ = 10⁻⁸ × mean diagonal`: the clamped Hessian is only
//!    semidefinite, singular for a free part of the mesh not connected to any prescribed node
//!    (its rigid motions). `δ` only shortens the step in near-null directions; it does not move
//!    the minimum, since convergence is judged on the true gradient. Should the clamped
//!    Hessian still meet a non-positive pivot (rounding), `δ` is raised a hundredfold, up to
//!    three times.
//! 4. **Line search.** Backtracking from the full step by halving, at most [`MAX_BACKTRACKS`]
//!    times, on the Armijo condition `W(u + α s) ≤ W(u) + 10⁻⁴ α ∇W·s + slack`: an inverted
//!    element makes `W = +∞`, so steps that invert are rejected. `slack` is twice an estimate of
//!    the energy's rounding error, so that near the minimum, where the decrease falls below what
//!    the energy resolves, the Newton step is still taken (as the core's line search does).
//! 5. **Convergence** when `‖∇W‖∞ ≤ tol · E h²` over the free nodes, `E h²` being the nodal
//!    force a unit strain produces on an element of mean size (`h³` the mean element volume).
//!    A sub-step fails on an iteration limit, a stalled line search or an infeasible start.
//!
//! The sparse LDLᵀ is the core's: node graph of the free nodes, minimum-degree ordering and
//! 3 × 3-block upper pattern are built once in [`Simulator::new`] (the prescribed set is fixed),
//! with a map from each element-matrix entry to its slot in the pattern. The core's
//! [`Symbolic`] borrows its index storage, which a struct cannot hold next to that storage
//! without `unsafe`, so the symbolic factor is rebuilt from the stored pattern and ordering at
//! the start of every `solve` (one linear-time pass, cheaper than one numeric factorization, and
//! shared by all Newton iterations of the frame).
//!
//! Everything runs sequentially in a fixed order, so results are bit-for-bit reproducible.
//!
//! Here: the simulator, its sub-steps, predictor, Newton and line search; `assembly`: the
//! energy, gradient and Hessian assembly and the sparse solve; `error`: why a step fails.

use incise_core::Error as CoreError;
use incise_core::material::{ElementRest, Lame};
use incise_core::sparse::{
    Graph, LdlFactor, NONE, Symbolic, SymbolicSize, UpperCsc, analyse_work_len, block_upper_len,
    block_upper_pattern, expand_block_permutation, minimum_degree, minimum_degree_work_len,
    tet_graph_work_len,
};
use nalgebra::Vector3;

use crate::generate::neohookean::{Projection, element_eval};

mod assembly;
mod error;

use assembly::Linear;
pub use error::{Failure, SimError};

/// Convergence tolerance of [`Simulator::solve`], relative to the force scale `E h²`
/// (see [`Simulator::force_scale`]): strain errors of about `10⁻¹⁰`. Rounding leaves residual
/// forces of `10⁻¹⁹`–`10⁻¹⁷ E h²` on the test bars (30 % stretch), so there is ample margin
/// for finer or more distorted meshes.
pub const TOLERANCE: f64 = 1e-10;

/// Most halvings of the sub-step size in one [`Simulator::solve`]: the smallest sub-step is
/// `2⁻¹²` of the frame's prescribed increment.
pub const MAX_HALVINGS: u32 = 12;

/// Most backtracking halvings of one line search (smallest step length `2⁻²⁴`).
pub const MAX_BACKTRACKS: u32 = 24;

/// Most sub-steps in one [`Simulator::solve`] (a bound that failing and regrowing sub-steps
/// cannot cycle past).
pub const MAX_SUBSTEPS: usize = 1024;

/// Armijo sufficient-decrease constant.
const ARMIJO: f64 = 1e-4;

/// Tikhonov term relative to the mean diagonal of the free-node Hessian.
const REGULARISATION: f64 = 1e-8;

/// What one [`Simulator::solve`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveStats {
    /// Newton iterations over all sub-steps (each is one Hessian assembly and factorization;
    /// the predictors add one more factorization per sub-step).
    pub iterations: usize,
    /// Sub-steps that succeeded (1 when the frame went in one piece).
    pub substeps: usize,
    /// Failed sub-steps that were halved.
    pub halvings: u32,
    /// Factorizations (Newton iterations and predictors) that used the eigenvalue-clamped
    /// Hessian because the exact one was not positive definite.
    pub projected: usize,
    /// Final `‖∇W‖∞` over the free nodes (N).
    pub gradient_norm: f64,
    /// Final elastic energy (J).
    pub energy: f64,
}

/// Rest geometry of one tetrahedron, checked once.
#[derive(Clone, Copy, Debug)]
struct Element {
    rest: ElementRest<f64>,
    g: [Vector3<f64>; 4],
}

/// Why a sub-step stopped: a recoverable [`Failure`] (the caller halves the sub-step) or a
/// non-finite gradient at a feasible state (a bug: the caller gives up).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum StepError {
    Failed(Failure),
    NotFinite,
}

impl From<Failure> for StepError {
    fn from(f: Failure) -> Self {
        StepError::Failed(f)
    }
}

/// Energy of a state with the scale of its rounding error.
#[derive(Clone, Copy, Debug)]
struct Energy {
    /// Total elastic energy (J), `+∞` if any element is inverted.
    value: f64,
    /// Estimated rounding error of `value` (J).
    rounding: f64,
}

/// A quasi-static Neo-Hookean simulation of a tetrahedral mesh driven by prescribed nodes.
///
/// Invariants after [`Simulator::new`]: every tetrahedron is positively oriented and not
/// degenerate at rest, indices are in range, the prescribed nodes are distinct and at least one
/// node is free; the current state has no inverted element.
#[derive(Clone, Debug)]
pub struct Simulator {
    lame: Lame<f64>,
    rest: Vec<[f64; 3]>,
    tets: Vec<[u32; 4]>,
    elements: Vec<Element>,
    prescribed: Vec<u32>,
    /// Compact index of each free node, [`NONE`] for a prescribed one.
    free: Vec<u32>,
    /// Displacements from rest (m): the state. Strain is computed from these, not from
    /// positions, to avoid cancellation (see `incise_core::material::displacement_gradient`).
    u: Vec<[f64; 3]>,
    /// `rest + u` (m), kept in step with `u` for [`Simulator::positions`].
    x: Vec<[f64; 3]>,
    /// Upper pattern of the free-node Hessian (3 unknowns per free node).
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
    /// Minimum-degree ordering of the unknowns.
    perm: Vec<u32>,
    size: SymbolicSize,
    /// Per tetrahedron, the slot in the pattern's values of element-matrix entry `(i, j)`
    /// (`12 i + j`, local unknowns `3a + c`), or [`NONE`] if either unknown is prescribed or
    /// the entry is below the diagonal (its mirror carries it).
    scatter: Vec<[u32; 144]>,
    /// Slot of each diagonal entry, for the regularisation.
    diag: Vec<u32>,
    force_scale: f64,
}

impl Simulator {
    /// Builds a simulator at rest.
    ///
    /// `rest`: node positions (m); `tets`: node indices, each tetrahedron positively oriented
    /// at rest; `prescribed`: distinct node indices whose positions [`Simulator::solve`] is
    /// given each frame (held or grasped), in the order of its `targets`; `young` (Pa) and
    /// `poisson` the material. Nodes in no tetrahedron are allowed (they stay where they are).
    ///
    /// # Errors
    /// [`SimError::NodeOutOfRange`], [`SimError::DuplicatePrescribed`],
    /// [`SimError::NoFreeNodes`]; [`SimError::Core`] with the core's error for bad material
    /// parameters or a non-finite, degenerate or inverted rest tetrahedron (it names the
    /// tetrahedron), or if the pattern overflows the core's `u32` indices.
    pub fn new(
        rest: &[[f64; 3]],
        tets: &[[u32; 4]],
        prescribed: &[u32],
        young: f64,
        poisson: f64,
    ) -> Result<Self, SimError> {
        let lame = Lame::from_young_poisson(young, poisson)?;
        let n_nodes = rest.len();
        let check = |node: u32| {
            if (node as usize) < n_nodes {
                Ok(())
            } else {
                Err(SimError::NodeOutOfRange {
                    node,
                    nodes: n_nodes,
                })
            }
        };
        for t in tets {
            t.iter().try_for_each(|&v| check(v))?;
        }
        let mut free = vec![0u32; n_nodes];
        for &p in prescribed {
            check(p)?;
            if free[p as usize] == NONE {
                return Err(SimError::DuplicatePrescribed { node: p });
            }
            free[p as usize] = NONE;
        }
        let mut n_free = 0u32;
        for f in free.iter_mut().filter(|f| **f != NONE) {
            *f = n_free;
            n_free += 1;
        }
        if n_free == 0 {
            return Err(SimError::NoFreeNodes);
        }
        let elements = tets
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let rest = ElementRest::new(&t.map(|v| rest[v as usize]), i)?;
                Ok(Element {
                    g: rest.shape_gradients(),
                    rest,
                })
            })
            .collect::<Result<Vec<_>, CoreError>>()?;

        // Pattern and ordering, once: the prescribed set never changes.
        let n_free = n_free as usize;
        let mut work = vec![0u32; tet_graph_work_len(n_free, tets.len())];
        let nnz_g = Graph::tets_nnz(tets, &free, &mut work)?;
        let (mut g_ptr, mut g_adj) = (vec![0u32; n_free + 1], vec![0u32; nnz_g]);
        let graph = Graph::from_tets(tets, &free, &mut g_ptr, &mut g_adj, &mut work)?;
        let mut node_perm = vec![0u32; n_free];
        let mut md_work = vec![0u32; minimum_degree_work_len(n_free, nnz_g)];
        minimum_degree(&graph, &mut node_perm, &mut md_work)?;
        let mut perm = vec![0u32; 3 * n_free];
        expand_block_permutation(&node_perm, 3, &mut perm)?;
        let nnz = block_upper_len(&graph, 3);
        let (mut col_ptr, mut row_idx) = (vec![0u32; 3 * n_free + 1], vec![0u32; nnz]);
        let a = block_upper_pattern(&graph, 3, &mut col_ptr, &mut row_idx)?;
        let mut a_work = vec![0u32; analyse_work_len(a.n(), a.nnz())];
        let size = Symbolic::size(&a, &perm, &mut a_work)?;

        let dof = |v: u32, c: usize| {
            let f = free[v as usize];
            (f != NONE).then(|| 3 * f as usize + c)
        };
        let slot = |i: usize, j: usize| a.find(i, j).map_or(NONE, |s| s as u32);
        let scatter = tets
            .iter()
            .map(|t| {
                std::array::from_fn(|e| {
                    let (i, j) = (e / 12, e % 12);
                    match (dof(t[i / 3], i % 3), dof(t[j / 3], j % 3)) {
                        (Some(r), Some(c)) if r <= c => slot(r, c),
                        _ => NONE,
                    }
                })
            })
            .collect();
        let diag = (0..a.n()).map(|j| slot(j, j)).collect();

        let mean_volume = elements.iter().map(|e| e.rest.volume).sum::<f64>() / tets.len() as f64;
        // No tetrahedra at all leaves only free floating nodes; any positive scale will do.
        let force_scale = if tets.is_empty() {
            young
        } else {
            young * mean_volume.powf(2.0 / 3.0)
        };
        Ok(Simulator {
            lame,
            rest: rest.to_vec(),
            tets: tets.to_vec(),
            elements,
            prescribed: prescribed.to_vec(),
            free,
            u: vec![[0.0; 3]; n_nodes],
            x: rest.to_vec(),
            col_ptr,
            row_idx,
            perm,
            size,
            scatter,
            diag,
            force_scale,
        })
    }

    /// Current node positions (m), in the order of `rest`.
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.x
    }

    /// Current node displacements from rest (m).
    pub fn displacements(&self) -> &[[f64; 3]] {
        &self.u
    }

    /// Sets the state: the displacement from rest (m) of every node, in the order of `rest`.
    /// The next [`Simulator::solve`] starts from it, its prescribed nodes moving from there to
    /// their targets. Used to carry a simulation over to a simulator with other tetrahedra on
    /// the same nodes (a live cut's release).
    ///
    /// # Errors
    /// [`SimError::StateLength`] for a state of the wrong length, [`SimError::InfeasibleState`]
    /// for one that is not finite or inverts an element; the state is then left unchanged.
    pub fn set_displacements(&mut self, u: &[[f64; 3]]) -> Result<(), SimError> {
        if u.len() != self.rest.len() {
            return Err(SimError::StateLength {
                expected: self.rest.len(),
                got: u.len(),
            });
        }
        if !u.iter().flatten().all(|c| c.is_finite()) || !self.energy_of(u).value.is_finite() {
            return Err(SimError::InfeasibleState);
        }
        self.u.copy_from_slice(u);
        self.sync_positions();
        Ok(())
    }

    /// The prescribed nodes, in the order `targets` follows.
    pub fn prescribed(&self) -> &[u32] {
        &self.prescribed
    }

    /// The force scale `E h²` (N) the tolerance is relative to: Young's modulus times the mean
    /// element volume to the power ⅔, the nodal force a unit strain produces on a typical
    /// element.
    pub fn force_scale(&self) -> f64 {
        self.force_scale
    }

    /// Elastic energy of the current state (J).
    pub fn energy(&self) -> f64 {
        self.energy_of(&self.u).value
    }

    /// The forces (N) the holders exert on the prescribed nodes in the current state, in the
    /// order of [`Simulator::prescribed`]: `∂W/∂x` at those nodes, which balances the elastic
    /// forces there. After a converged solve they sum to zero up to the residual forces left on
    /// the free nodes (element forces balance exactly, so the totals are opposite).
    pub fn holding_forces(&self) -> Vec<[f64; 3]> {
        let mut nodal = vec![[0.0f64; 3]; self.rest.len()];
        for (t, el) in self.tets.iter().zip(&self.elements) {
            let ue = t.map(|v| self.u[v as usize]);
            let e = element_eval(&self.lame, &el.rest, &el.g, &ue, Projection::Exact);
            for (&v, f) in t.iter().zip(&e.gradient) {
                for (n, fc) in nodal[v as usize].iter_mut().zip(f.iter()) {
                    *n += fc;
                }
            }
        }
        self.prescribed.iter().map(|&p| nodal[p as usize]).collect()
    }

    /// Moves the prescribed nodes to `targets` (positions in m, one per prescribed node in the
    /// order given to [`Simulator::new`]) and minimises the elastic energy over the free nodes,
    /// starting from the current state (see the module documentation for the strategy).
    /// `max_iter` bounds the Newton iterations of each sub-step; a frame that goes in one piece
    /// typically needs 3–6.
    ///
    /// On success the state is the equilibrium with `‖∇W‖∞ ≤ tol · E h²` over the free nodes
    /// and the prescribed nodes exactly at their targets.
    ///
    /// # Errors
    /// [`SimError::TargetCount`] and [`SimError::NonFiniteTarget`] before anything moves;
    /// [`SimError::NotConverged`] or [`SimError::NotFinite`], after which the state is the one
    /// before the call.
    pub fn solve(&mut self, targets: &[[f64; 3]], max_iter: usize) -> Result<SolveStats, SimError> {
        if targets.len() != self.prescribed.len() {
            return Err(SimError::TargetCount {
                expected: self.prescribed.len(),
                got: targets.len(),
            });
        }
        if let Some(index) = targets
            .iter()
            .position(|t| !t.iter().all(|c| c.is_finite()))
        {
            return Err(SimError::NonFiniteTarget { index });
        }
        // Prescribed displacements at the start and at the end of the frame.
        let from: Vec<[f64; 3]> = self
            .prescribed
            .iter()
            .map(|&p| self.u[p as usize])
            .collect();
        let to: Vec<[f64; 3]> = self
            .prescribed
            .iter()
            .zip(targets)
            .map(|(&p, t)| std::array::from_fn(|c| t[c] - self.rest[p as usize][c]))
            .collect();

        // The symbolic factor borrows `sym_storage`, so it lives in this call (module docs).
        let a = UpperCsc::new(self.size.n, &self.col_ptr, &self.row_idx)?;
        let mut sym_storage = vec![0u32; self.size.index_len()];
        let mut a_work = vec![0u32; analyse_work_len(a.n(), a.nnz())];
        let sym = Symbolic::new(&a, &self.perm, &mut sym_storage, &mut a_work)?;
        let mut f_storage = vec![0.0f64; LdlFactor::<f64>::storage_len(&self.size)];
        let ldl = LdlFactor::new(&self.size, &mut f_storage)?;
        let mut lin = Linear {
            sym,
            ldl,
            y: vec![0.0; self.size.n],
            cursor: vec![0; self.size.n],
        };

        let start = self.u.clone();
        let mut stats = SolveStats {
            iterations: 0,
            substeps: 0,
            halvings: 0,
            projected: 0,
            gradient_norm: f64::NAN,
            energy: f64::NAN,
        };
        // Fractions of the increment are dyadic (1, ½, ¼, … and their sums), so `done` reaches
        // exactly 1 and the last sub-step lands exactly on the targets.
        let mut done = 0.0f64;
        let mut step = 1.0f64;
        while done < 1.0 {
            let h = step.min(1.0 - done);
            let next = done + h;
            let goal: Vec<[f64; 3]> = if next == 1.0 {
                to.clone()
            } else {
                from.iter()
                    .zip(&to)
                    .map(|(f, t)| std::array::from_fn(|c| f[c] + next * (t[c] - f[c])))
                    .collect()
            };
            let saved = self.u.clone();
            let outcome = if stats.substeps + stats.halvings as usize >= MAX_SUBSTEPS {
                Err(StepError::Failed(Failure::IterationLimit))
            } else {
                self.substep(&mut lin, &goal, max_iter, &mut stats)
            };
            match outcome {
                Ok(()) => {
                    done = next;
                    stats.substeps += 1;
                    step = (2.0 * h).min(1.0);
                }
                Err(StepError::NotFinite) => {
                    self.u = start;
                    self.sync_positions();
                    return Err(SimError::NotFinite);
                }
                Err(StepError::Failed(cause)) => {
                    self.u = saved;
                    stats.halvings += 1;
                    if stats.halvings > MAX_HALVINGS
                        || stats.substeps + stats.halvings as usize > MAX_SUBSTEPS
                    {
                        self.u = start;
                        self.sync_positions();
                        return Err(SimError::NotConverged {
                            reached: done,
                            iterations: stats.iterations,
                            gradient_norm: stats.gradient_norm,
                            cause,
                        });
                    }
                    step = 0.5 * h;
                }
            }
        }
        self.sync_positions();
        stats.energy = self.energy();
        Ok(stats)
    }

    fn sync_positions(&mut self) {
        for ((x, r), u) in self.x.iter_mut().zip(&self.rest).zip(&self.u) {
            *x = std::array::from_fn(|c| r[c] + u[c]);
        }
    }

    /// One sub-step: prescribed displacements to `goal`, predictor, Newton. On `Err` the state
    /// is garbage and the caller restores it. `stats` receives the iterations done and the last
    /// `‖∇W‖∞` seen.
    fn substep(
        &mut self,
        lin: &mut Linear<'_>,
        goal: &[[f64; 3]],
        max_iter: usize,
        stats: &mut SolveStats,
    ) -> Result<(), StepError> {
        let n = self.size.n;
        // Predictor: K_ff p = −K_fp d_p, with the Hessian at the current (feasible) state.
        let mut d = vec![[0.0f64; 3]; self.rest.len()];
        for (&p, g) in self.prescribed.iter().zip(goal) {
            d[p as usize] = std::array::from_fn(|c| g[c] - self.u[p as usize][c]);
        }
        let mut grad = vec![0.0; n];
        let mut values = vec![0.0; self.row_idx.len()];
        let mut predictor = vec![0.0; n];
        self.factor_hessian(
            lin,
            &mut grad,
            &mut values,
            Some((&d, &mut predictor)),
            stats,
        )?;
        predictor.iter_mut().for_each(|v| *v = -*v);
        lin.solve(&mut predictor);

        for (&p, g) in self.prescribed.iter().zip(goal) {
            self.u[p as usize] = *g;
        }
        let without = self.u.clone();
        self.add_free(&predictor, 1.0);
        if !self.energy_of(&self.u).value.is_finite() {
            self.u = without;
            if !self.energy_of(&self.u).value.is_finite() {
                return Err(Failure::InvertedStart.into());
            }
        }
        self.newton(lin, max_iter, stats)
    }

    /// Newton iterations with line search on the free nodes from the current (feasible) state.
    fn newton(
        &mut self,
        lin: &mut Linear<'_>,
        max_iter: usize,
        stats: &mut SolveStats,
    ) -> Result<(), StepError> {
        let n = self.size.n;
        let (mut grad, mut values, mut dir) =
            (vec![0.0; n], vec![0.0; self.row_idx.len()], vec![0.0; n]);
        let limit = TOLERANCE * self.force_scale;
        let mut at = self.energy_gradient(&self.u, &mut grad);
        for it in 0..=max_iter {
            if !grad.iter().all(|g| g.is_finite()) {
                return Err(StepError::NotFinite);
            }
            let norm = grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
            stats.gradient_norm = norm;
            if norm <= limit {
                return Ok(());
            }
            if it == max_iter {
                return Err(Failure::IterationLimit.into());
            }
            let projection = self.factor_hessian(lin, &mut grad, &mut values, None, stats)?;
            // Written so that a NaN slope is not a descent either.
            let descends = |slope: f64| slope < 0.0;
            let mut slope = lin.newton_direction(&grad, &mut dir);
            if !descends(slope) && projection == Projection::Exact {
                // Positive pivots up to rounding, yet not a descent direction: the exact
                // Hessian was too close to singular. Fall back to the clamped one.
                self.assemble(
                    &self.u,
                    &mut grad,
                    &mut values,
                    Projection::ClampEigenvalues,
                    None,
                );
                lin.factorize(&mut values, &self.diag, 3)?;
                stats.projected += 1;
                slope = lin.newton_direction(&grad, &mut dir);
            }
            if !descends(slope) {
                return Err(Failure::LineSearchStalled.into());
            }
            let base = self.u.clone();
            let slack = 2.0 * at.rounding;
            let mut alpha = 1.0;
            let mut accepted = false;
            for _ in 0..=MAX_BACKTRACKS {
                self.u.copy_from_slice(&base);
                self.add_free(&dir, alpha);
                let e = self.energy_of(&self.u).value;
                if e.is_finite() && e <= at.value + ARMIJO * alpha * slope + slack {
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            if !accepted {
                return Err(Failure::LineSearchStalled.into());
            }
            stats.iterations += 1;
            at = self.energy_gradient(&self.u, &mut grad);
        }
        unreachable!("the loop returns at it == max_iter")
    }

    /// `u_f += alpha · v` over the free nodes (`v` indexed by unknown).
    fn add_free(&mut self, v: &[f64], alpha: f64) {
        for (u, &f) in self.u.iter_mut().zip(&self.free) {
            if f != NONE {
                for c in 0..3 {
                    u[c] += alpha * v[3 * f as usize + c];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    /// The box `[0, l]` cut into `n` cells of six tetrahedra (the generator's own band).
    fn box_mesh(n: [usize; 3], l: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 4]>) {
        let m = crate::generate::object::TetMesh::band(l, n);
        (m.nodes, m.tets)
    }

    /// `det [x1 − x0, x2 − x0, x3 − x0]` of tetrahedron `t`.
    fn det(x: &[[f64; 3]], t: [u32; 4]) -> f64 {
        let p = t.map(|v| Vector3::from(x[v as usize]));
        nalgebra::Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]).determinant()
    }

    /// Smallest `det F` over the mesh.
    fn min_jacobian(sim: &Simulator) -> f64 {
        sim.tets
            .iter()
            .map(|&t| det(sim.positions(), t) / det(&sim.rest, t))
            .fold(f64::INFINITY, f64::min)
    }

    const YOUNG: f64 = 5.0e3; // soft tissue / silicone, Pa
    const NU: f64 = 0.3;

    /// Lateral stretch `t` of homogeneous uniaxial stress at axial stretch `s` for NH:
    /// `P22 = μ (t − 1/t) + λ ln(s t²) / t = 0`, by bisection (`P22` increases with `t`).
    fn lateral_stretch(l: &Lame<f64>, s: f64) -> f64 {
        let p22 = |t: f64| l.mu * (t - 1.0 / t) + l.lambda * (s * t * t).ln() / t;
        let (mut lo, mut hi) = (0.1, 2.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if p22(mid) > 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// A bar `[0, len] × [0, w]²` with both end faces prescribed; returns the simulator and
    /// the indices (into `prescribed`) of the `x = len` face.
    fn bar(n: [usize; 3], len: f64, w: f64) -> (Simulator, Vec<usize>) {
        let (x, tets) = box_mesh(n, [len, w, w]);
        let prescribed: Vec<u32> = (0..x.len() as u32)
            .filter(|&v| x[v as usize][0] == 0.0 || x[v as usize][0] == len)
            .collect();
        let far = prescribed
            .iter()
            .enumerate()
            .filter(|(_, v)| x[**v as usize][0] == len)
            .map(|(i, _)| i)
            .collect();
        (
            Simulator::new(&x, &tets, &prescribed, YOUNG, NU).unwrap(),
            far,
        )
    }

    /// Targets for the end faces: axial stretch `s` and, when `contract`, the lateral stretch
    /// `t` about the bar's axis (the exact homogeneous uniaxial-stress state); otherwise the
    /// ends are clamped laterally.
    fn end_targets(sim: &Simulator, s: f64, t: f64, w: f64) -> Vec<[f64; 3]> {
        let c = 0.5 * w;
        sim.prescribed()
            .iter()
            .map(|&v| {
                let p = sim.rest[v as usize];
                [s * p[0], c + t * (p[1] - c), c + t * (p[2] - c)]
            })
            .collect()
    }

    fn axial_force(sim: &Simulator, far: &[usize]) -> f64 {
        let f = sim.holding_forces();
        far.iter().map(|&i| f[i][0]).sum()
    }

    #[test]
    fn uniaxial_stretch_matches_linear_elasticity_and_the_nh_closed_form() {
        let clock = Instant::now();
        let (len, w) = (0.05, 0.01);
        let lame = Lame::from_young_poisson(YOUNG, NU).unwrap();
        let area = w * w;
        for (strain, frames) in [(1e-3, 1), (0.3, 1)] {
            let (mut sim, far) = bar([10, 2, 2], len, w);
            let s = 1.0 + strain;
            let t = lateral_stretch(&lame, s);
            let mut stats = Vec::new();
            for f in 1..=frames {
                let sf = 1.0 + strain * f as f64 / frames as f64;
                let tf = lateral_stretch(&lame, sf);
                stats.push(sim.solve(&end_targets(&sim, sf, tf, w), 30).unwrap());
            }
            // Linear tetrahedra reproduce the homogeneous state exactly: every node sits on
            // x = diag(s, t, t) X about the axis.
            let c = 0.5 * w;
            let mut worst: f64 = 0.0;
            for (p, r) in sim.positions().iter().zip(&sim.rest) {
                let want = [s * r[0], c + t * (r[1] - c), c + t * (r[2] - c)];
                for k in 0..3 {
                    worst = worst.max((p[k] - want[k]).abs());
                }
            }
            assert!(
                worst <= 1e-9 * len,
                "strain {strain}: off the homogeneous state by {worst:e} m"
            );
            let force = axial_force(&sim, &far);
            let nh = (lame.mu * (s - 1.0 / s) + lame.lambda * (s * t * t).ln() / s) * area;
            let rel_nh = (force - nh) / nh;
            assert!(
                rel_nh.abs() <= 1e-6,
                "strain {strain}: {force} N vs NH {nh} N"
            );
            if strain < 0.01 {
                let linear = YOUNG * strain * area;
                let rel = (force - linear) / linear;
                // NH deviates from Hooke by O(strain).
                assert!(rel.abs() <= 2.0 * strain, "{force} N vs E ε A = {linear} N");
                println!(
                    "uniaxial 0.1 %: force {force:.6e} N, E ε A {linear:.6e} N, rel {rel:.2e}"
                );
            }
            println!("uniaxial {strain}: {stats:?}, NH closed form rel {rel_nh:.1e}");
        }
        println!("uniaxial tests: {:?}", clock.elapsed());
    }

    #[test]
    fn clamped_bar_reaction_is_close_to_e_eps_a() {
        // A slender bar with laterally clamped ends: the end constraint stiffens it a little,
        // so this is the few-% comparison, the homogeneous test above the exact one.
        let (len, w) = (0.1, 0.01);
        let (mut sim, far) = bar([20, 2, 2], len, w);
        let strain = 1e-3;
        let stats = sim
            .solve(&end_targets(&sim, 1.0 + strain, 1.0, w), 30)
            .unwrap();
        let force = axial_force(&sim, &far);
        let linear = YOUNG * strain * w * w;
        let rel = (force - linear) / linear;
        println!(
            "clamped bar 0.1 %: force {force:.6e} N, E ε A {linear:.6e} N, rel {rel:+.3}, {stats:?}"
        );
        assert!((0.0..0.05).contains(&rel), "relative difference {rel}");
        // Equilibrium: the two ends pull equally (free nodes carry no load).
        let total: f64 = sim.holding_forces().iter().map(|f| f[0]).sum();
        assert!(total.abs() <= 1e-8 * force, "net axial force {total:e}");
    }

    #[test]
    fn thirty_percent_stretch_of_clamped_bar_in_three_frames() {
        let clock = Instant::now();
        let (len, w) = (0.05, 0.01);
        let (mut sim, far) = bar([10, 2, 2], len, w);
        let lame = Lame::from_young_poisson(YOUNG, NU).unwrap();
        let mut log = Vec::new();
        for f in 1..=3 {
            let s = 1.0 + 0.1 * f as f64; // 5 mm per frame
            let stats = sim.solve(&end_targets(&sim, s, 1.0, w), 30).unwrap();
            assert!(stats.gradient_norm <= TOLERANCE * sim.force_scale());
            assert!(stats.iterations <= 30, "{stats:?}");
            let jmin = min_jacobian(&sim);
            assert!(jmin > 0.3, "frame {f}: min det F {jmin}");
            log.push((stats, jmin));
        }
        // Against homogeneous uniaxial stress: the clamped ends only stiffen it, by little on
        // a 5:1 bar.
        let s = 1.3;
        let t = lateral_stretch(&lame, s);
        let nh = (lame.mu * (s - 1.0 / s) + lame.lambda * (s * t * t).ln() / s) * w * w;
        let force = axial_force(&sim, &far);
        let ratio = force / nh;
        println!(
            "30 % clamped stretch: {log:?}; force / uniaxial NH = {ratio:.4}; {:?}",
            clock.elapsed()
        );
        assert!((1.0..1.15).contains(&ratio), "{ratio}");
    }

    /// A 5 cm × 5 cm × 2 cm slab (6.25 × 6.25 × 5 mm cells) held on its bottom face, a 2 × 2
    /// patch of top nodes grasped and pulled up 3 mm and sideways 1.5 mm per frame for five
    /// frames; then moved down by 12 mm in one frame, then by 17 mm down and 7.5 mm sideways in
    /// one frame (14 mm into the 20 mm slab), which needs a sub-step.
    fn grasp_run() -> (Vec<[f64; 3]>, Vec<SolveStats>) {
        let (x, tets) = box_mesh([8, 8, 4], [0.05, 0.05, 0.02]);
        let held: Vec<u32> = (0..x.len() as u32)
            .filter(|&v| x[v as usize][2] == 0.0)
            .collect();
        let grasped: Vec<u32> = (0..x.len() as u32)
            .filter(|&v| {
                let p = x[v as usize];
                p[2] == 0.02 && (0.0249..0.0314).contains(&p[0]) && (0.0249..0.0314).contains(&p[1])
            })
            .collect();
        assert_eq!(grasped.len(), 4);
        let prescribed: Vec<u32> = held.iter().chain(&grasped).copied().collect();
        let mut sim = Simulator::new(&x, &tets, &prescribed, YOUNG, 0.45).unwrap();
        let mut stats = Vec::new();
        let frame = |sim: &Simulator, d: [f64; 3]| -> Vec<[f64; 3]> {
            sim.prescribed()
                .iter()
                .map(|&v| {
                    let r = x[v as usize];
                    if r[2] == 0.0 {
                        r
                    } else {
                        [r[0] + d[0], r[1] + d[1], r[2] + d[2]]
                    }
                })
                .collect()
        };
        for f in 1..=5 {
            let k = f as f64 * 0.003;
            stats.push(sim.solve(&frame(&sim, [0.5 * k, 0.0, k]), 25).unwrap());
            assert!(min_jacobian(&sim) > 0.0);
        }
        stats.push(
            sim.solve(&frame(&sim, [0.0075, 0.0, -0.012 + 0.015]), 25)
                .unwrap(),
        );
        assert!(min_jacobian(&sim) > 0.0);
        stats.push(sim.solve(&frame(&sim, [0.0, 0.0, -0.014]), 25).unwrap());
        assert!(min_jacobian(&sim) > 0.0);
        (sim.positions().to_vec(), stats)
    }

    #[test]
    fn grasp_and_push_converge_and_are_deterministic() {
        let clock = Instant::now();
        let (a, stats) = grasp_run();
        let t1 = clock.elapsed();
        for s in &stats {
            println!("grasp frame: {s:?}");
        }
        // Ordinary frames go in one piece, in a few Newton iterations.
        for s in &stats[..6] {
            assert_eq!((s.substeps, s.halvings), (1, 0), "{s:?}");
            assert!(s.iterations <= 6, "{s:?}");
        }
        // The 14 mm push in one frame is where sub-stepping earns its keep.
        let push = stats[6];
        assert!(push.halvings >= 1 && push.substeps >= 2, "{push:?}");
        let (b, _) = grasp_run();
        assert!(
            a.iter()
                .flatten()
                .zip(b.iter().flatten())
                .all(|(p, q)| p.to_bits() == q.to_bits()),
            "two runs differ"
        );
        println!("grasp run: {t1:?} per run");
    }

    #[test]
    fn disconnected_free_part_is_regularised() {
        // Two cubes; the second has no prescribed node and floats. δI keeps the Hessian
        // definite; the floating cube carries no force, so it stays at rest.
        let (x1, t1) = box_mesh([2, 2, 2], [0.01, 0.01, 0.01]);
        let off = x1.len() as u32;
        let mut x = x1.clone();
        x.extend(x1.iter().map(|p| [p[0] + 0.02, p[1], p[2]]));
        let mut tets = t1.clone();
        tets.extend(t1.iter().map(|t| t.map(|v| v + off)));
        let held: Vec<u32> = (0..off).filter(|&v| x[v as usize][0] == 0.0).collect();
        let pulled: Vec<u32> = (0..off).filter(|&v| x[v as usize][0] == 0.01).collect();
        let prescribed: Vec<u32> = held.iter().chain(&pulled).copied().collect();
        let mut sim = Simulator::new(&x, &tets, &prescribed, YOUNG, NU).unwrap();
        let targets: Vec<[f64; 3]> = prescribed
            .iter()
            .map(|&v| {
                let p = x[v as usize];
                [if p[0] > 0.0 { 0.0105 } else { 0.0 }, p[1], p[2]]
            })
            .collect();
        let stats = sim.solve(&targets, 30).unwrap();
        let floating_move = sim.displacements()[off as usize..]
            .iter()
            .flatten()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(floating_move <= 1e-12, "{floating_move:e}");
        assert!(stats.gradient_norm <= TOLERANCE * sim.force_scale());
    }

    #[test]
    fn bad_input_is_rejected() {
        let (x, tets) = box_mesh([1, 1, 1], [0.01, 0.01, 0.01]);
        let err = |r: Result<Simulator, SimError>| r.err().unwrap();
        assert_eq!(
            err(Simulator::new(&x, &tets, &[0, 99], YOUNG, NU)),
            SimError::NodeOutOfRange { node: 99, nodes: 8 }
        );
        assert_eq!(
            err(Simulator::new(&x, &tets, &[3, 1, 3], YOUNG, NU)),
            SimError::DuplicatePrescribed { node: 3 }
        );
        let all: Vec<u32> = (0..8).collect();
        assert_eq!(
            err(Simulator::new(&x, &tets, &all, YOUNG, NU)),
            SimError::NoFreeNodes
        );
        assert!(matches!(
            err(Simulator::new(&x, &tets, &[0], YOUNG, 0.5)),
            SimError::Core(CoreError::InvalidParameter { .. })
        ));
        let mut flipped = tets.clone();
        flipped[4].swap(0, 1);
        assert_eq!(
            err(Simulator::new(&x, &flipped, &[0], YOUNG, NU)),
            SimError::Core(CoreError::InvertedElement { tet: 4 })
        );
        let mut sim = Simulator::new(&x, &tets, &[0, 7], YOUNG, NU).unwrap();
        assert_eq!(
            sim.solve(&[[0.0; 3]], 10),
            Err(SimError::TargetCount {
                expected: 2,
                got: 1
            })
        );
        assert_eq!(
            sim.solve(&[[0.0; 3], [f64::NAN, 0.0, 0.0]], 10),
            Err(SimError::NonFiniteTarget { index: 1 })
        );
        // Node 7 driven through node 0 cannot be reached without inversion: the error leaves
        // the state as it was.
        let before = sim.positions().to_vec();
        let r = sim.solve(&[[0.0; 3], [-0.01, -0.01, -0.01]], 10);
        assert!(matches!(r, Err(SimError::NotConverged { .. })), "{r:?}");
        assert_eq!(sim.positions(), &before[..]);
    }
}
