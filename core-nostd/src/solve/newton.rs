//! The per-frame minimisation of [`Model::step`]: Newton steps on the total energy, each with
//! its linear solve (by the strategy: a factorization per step, a frozen factor and PCG, one
//! factorization per frame and PCG after it, or the frozen factor's own step) and a line search
//! over fixed trial lengths; and
//! the assembly and factorization that a cut's rebuild shares with it.

// The vectors are cut to the model's unknowns and nodes with checked prefixes (`prefix`), once
// per use and before any loop over them. The model's storage is sized for those lengths
// (`ModelSize`) and every cut re-checks them, so the `Error::Capacity` a short buffer would
// give cannot occur for a model built by its constructors; it stands where a panic would.

use core::cell::Cell;

#[cfg(feature = "cut")]
use crate::cut::CutReport;
#[cfg(feature = "detect")]
use crate::cutline::CutLineReport;
#[cfg(feature = "detect")]
use crate::detect::DetectionReport;
use crate::error::{Error, Parameter, Resource};
use crate::features::Features;
use crate::material::{InversionBarrier, Lame};
use crate::model::discretization::Discretization;
use crate::model::{FactoredMatrix, Model, ModelConfig, SolveVectors, StepReport};
use crate::real::Real;
use crate::solve::assembly::camera_rays;
use crate::solve::{
    ElementSums, Energies, MIXED_REFINEMENT_STEPS, Problem, SecantMemory, Strategy, WorkCount, dot,
};
use crate::sparse::{LdlFactor, NONE, sym_matvec, ux};
use crate::storage::{ensure_exact_len, prefix, prefix_mut, times};

impl<'a, T: Real, F: Real> Model<'a, T, F> {
    pub(crate) fn solve_frame(&mut self) -> Result<StepReport<T>, Error> {
        let n = self.n_unknowns();
        let mut work = WorkCount::default();
        let newton = self.config.solver.newton_iterations;
        let trials = self.config.solver.line_search_steps;

        let strategy = self.config.solver.strategy;
        if strategy.freezes() && self.factored != FactoredMatrix::Frozen {
            // Only after a switch of strategy: a one-off cost, counted in this frame's work.
            self.prepare_frozen(&mut work)?;
        }

        let mut energy_before = Energies::default();
        let mut gradient_norm_before = T::zero();
        let mut min_step = T::one();
        // The energies at the frame's end, when the last line search already gave them (and
        // the gradient there), so that the closing assembly is not needed.
        let mut closing = None;
        // The quasi-Newton strategy keeps, from each step taken, the step in `product` and the
        // gradient before it in `direction` (PCG vectors it does not use), until the next
        // assembly gives the gradient after it: a secant pair.
        let quasi = cfg!(feature = "quasi-newton") && strategy == Strategy::QuasiNewton;
        let mut pending = false;
        // The energies (and, in the model's gradient, the gradient) where the last step
        // ended, when its line search assembled them: the next step starts from them.
        let mut carried = None;
        // With one trial, the quasi-Newton strategy also starts the frame from the elements'
        // share of the assembly that ended the last one ([`KeptElements`](crate::solve::KeptElements)).
        let keeps = self.keeps_elements();
        for it in 0..newton {
            let e = match carried.take() {
                Some(e) => e,
                None if keeps => self.assemble_frame_start(&mut work)?,
                None => self.assemble(strategy.assembles_hessian(), false, &mut work)?,
            };
            if pending {
                self.push_secant_pair(&mut work)?;
            }
            let v = &mut self.vectors;
            if it == 0 {
                energy_before = e;
                let gradient = prefix(v.gradient, n, Resource::Unknowns)?;
                gradient_norm_before = dot(gradient, gradient).sqrt();
            }
            // The guards are constants: a strategy left out of the build leaves its code out.
            let (refactor, frozen, once, quasi_newton) = (
                cfg!(feature = "refactor"),
                cfg!(feature = "frozen"),
                cfg!(feature = "factor-once"),
                cfg!(feature = "quasi-newton"),
            );
            match strategy {
                Strategy::Refactor if refactor => self.refactor_and_solve(&mut work)?,
                Strategy::FactorOnce { .. } if once && it == 0 => {
                    self.refactor_and_solve(&mut work)?;
                }
                Strategy::Frozen { pcg_iterations } if frozen => {
                    self.pcg(pcg_iterations, &mut work)?;
                }
                Strategy::FactorOnce { pcg_iterations } if once => {
                    self.pcg(pcg_iterations, &mut work)?;
                }
                Strategy::QuasiNewton if quasi_newton => self.quasi_newton_step(&mut work)?,
                // Not built: `SolverConfig::validate`, which every way of setting a strategy
                // runs, refuses it before a frame can reach here.
                _ => {
                    return Err(Error::InvalidParameter {
                        parameter: Parameter::Strategy,
                    });
                }
            }
            let v = &self.vectors;
            let slope = dot(
                prefix(v.gradient, n, Resource::Unknowns)?,
                prefix(v.step, n, Resource::Unknowns)?,
            );
            if quasi {
                // Before the line search, which may leave the trial's gradient in `gradient`.
                let v = &mut self.vectors;
                prefix_mut(v.direction, n, Resource::Unknowns)?.copy_from_slice(prefix(
                    v.gradient,
                    n,
                    Resource::Unknowns,
                )?);
            }
            let last = it + 1 == newton;
            let (alpha, at_end) = self.line_search(&e, slope, trials, last, &mut work)?;
            if quasi {
                self.secant.rescale(alpha);
            }
            if last {
                closing = at_end;
            } else {
                carried = at_end;
            }
            min_step = min_step.min(alpha);
            pending = quasi && alpha > T::zero();
            if pending {
                let v = &mut self.vectors;
                let taken = prefix_mut(v.product, n, Resource::Unknowns)?;
                for (p, &s) in taken.iter_mut().zip(prefix(v.step, n, Resource::Unknowns)?) {
                    *p = alpha * s;
                }
            }
            if alpha > T::zero() {
                self.move_along(alpha)?;
            }
        }
        let energy_after = match closing {
            Some(e) => e,
            None => self.assemble(false, false, &mut work)?,
        };
        if pending {
            self.push_secant_pair(&mut work)?;
        }
        let gradient = prefix(self.vectors.gradient, n, Resource::Unknowns)?;
        let gradient_norm_after = dot(gradient, gradient).sqrt();
        if !(gradient_norm_after.finite() && energy_after.total().finite()) {
            return Err(Error::Diverged);
        }
        Ok(StepReport {
            frame: 0,
            observed: 0,
            energy_before,
            energy_after,
            gradient_norm_before,
            gradient_norm_after,
            min_step_length: min_step,
            work,
            #[cfg(feature = "detect")]
            detection: DetectionReport::default(),
            #[cfg(feature = "detect")]
            cut_line: CutLineReport::default(),
            #[cfg(feature = "cut")]
            cut: CutReport::default(),
        })
    }

    /// Assembles the gradient (and, if asked, the Hessian) at the current positions; with
    /// `keep_share`, the elements' share of it is kept aside as a trial of
    /// [`KeptElements`](crate::solve::KeptElements), for the caller to accept once what it
    /// assembled for has succeeded.
    pub(crate) fn assemble(
        &mut self,
        with_hessian: bool,
        keep_share: bool,
        work: &mut WorkCount,
    ) -> Result<Energies<T>, Error> {
        let n = self.n_unknowns();
        let coefficients = self.coefficients();
        let Model {
            live,
            config,
            features,
            vectors,
            hessian,
            kept,
            ..
        } = self;
        let keep = if keep_share {
            Some(kept.trial_mut(n)?)
        } else {
            None
        };
        assemble_on(
            live,
            features,
            coefficients,
            config,
            AssemblyOutput {
                gradient: &mut vectors.gradient[..],
                hessian: with_hessian.then_some(&mut hessian[..]),
                keep,
                spring_nodes: &mut vectors.spring_nodes[..],
            },
            work,
        )
    }

    /// Whether frames start from the elements' share kept from the last assembly
    /// ([`KeptElements`](crate::solve::KeptElements)): the quasi-Newton strategy (no tangents) with one line-search trial
    /// (every step's trial assembled), in a build with it.
    pub(crate) fn keeps_elements(&self) -> bool {
        cfg!(feature = "quasi-newton")
            && self.config.solver.strategy == Strategy::QuasiNewton
            && self.config.solver.line_search_steps == 1
    }

    /// The gradient and energies where the frame starts, without tangents, from the elements'
    /// share kept at these positions; when none is kept (after a switch of strategy or
    /// [`Model::set_positions`]), by a whole assembly that keeps its share.
    fn assemble_frame_start(&mut self, work: &mut WorkCount) -> Result<Energies<T>, Error> {
        let n = self.n_unknowns();
        let coefficients = self.coefficients();
        let Model {
            live,
            config,
            features,
            vectors,
            kept,
            ..
        } = self;
        let SolveVectors {
            gradient,
            spring_nodes,
            ..
        } = vectors;
        let problem = problem_of(live, features, coefficients, config, spring_nodes)?;
        let x = prefix(live.x, live.mesh.n_nodes(), Resource::Nodes)?;
        let gradient = prefix_mut(gradient, n, Resource::Unknowns)?;
        if let Some((share, sums)) = kept.current(n) {
            return problem.assemble_reusing(x, gradient, share, sums, work);
        }
        let (share, sums) = kept.trial_mut(n)?;
        let e = problem.assemble_keeping(x, gradient, None, share, sums, work)?;
        work.state_copies += kept.accept(n);
        Ok(e)
    }

    /// Factors the Hessian just assembled and solves the Newton system: exactly, or, with a
    /// factor of lower precision than the model's, by [`MIXED_REFINEMENT_STEPS`] PCG
    /// iterations on the residual in the model's precision after the first solve.
    fn refactor_and_solve(&mut self, work: &mut WorkCount) -> Result<(), Error> {
        self.factorize(work)?;
        self.factored = FactoredMatrix::Step;
        if Self::mixed() {
            return self.pcg(MIXED_REFINEMENT_STEPS, work);
        }
        self.factor_step(work)
    }

    /// The step of the factor in service, `step = −F⁻¹ ∇E`, by one solve in the factor's
    /// precision (the Newton step after a refactorization).
    fn factor_step(&mut self, work: &mut WorkCount) -> Result<(), Error> {
        let n = self.n_unknowns();
        let v = &mut self.vectors;
        let step = prefix_mut(v.step, n, Resource::Unknowns)?;
        let gradient = prefix(v.gradient, n, Resource::Unknowns)?;
        let solve_work = prefix_mut(v.solve_work, times(2, n), Resource::Workspace)?;
        for (s, &g) in step.iter_mut().zip(gradient) {
            *s = -g;
        }
        self.factor
            .solve_converting(&self.live.symbolic, step, solve_work)?;
        work.solves += 1;
        work.solve_flops += self.live.symbolic.solve_flops();
        Ok(())
    }

    /// The quasi-Newton step ([`Strategy::QuasiNewton`]): `step = −c H ∇E`, `H` the frozen
    /// factor's inverse corrected by the secant pairs, `c ≤ 1` the memory's step scale, with one solve in the factor's precision
    /// (in mixed precision too: refining it would need the Hessian the strategy does not
    /// assemble, and `H` is an approximation anyway).
    fn quasi_newton_step(&mut self, work: &mut WorkCount) -> Result<(), Error> {
        let n = self.n_unknowns();
        let Model {
            vectors: v,
            factor,
            live,
            secant,
            ..
        } = self;
        let step = prefix_mut(v.step, n, Resource::Unknowns)?;
        step.copy_from_slice(prefix(v.gradient, n, Resource::Unknowns)?);
        let solve_work = prefix_mut(v.solve_work, times(2, n), Resource::Workspace)?;
        secant.apply(n, step, |q| {
            factor.solve_converting(&live.symbolic, q, solve_work)
        })?;
        // Shortened after steps the line search refused (`SecantMemory::rescale`).
        let scale = -secant.scale();
        for s in step.iter_mut() {
            *s *= scale;
        }
        work.solves += 1;
        work.solve_flops += live.symbolic.solve_flops();
        work.secant_flops += SecantMemory::<T>::step_flops(n);
        Ok(())
    }

    /// Stores the secant pair of the step just taken: the step in `product`, the gradients
    /// before (`direction`) and after it (`gradient`, just assembled).
    fn push_secant_pair(&mut self, work: &mut WorkCount) -> Result<(), Error> {
        let n = self.n_unknowns();
        let v = &self.vectors;
        self.secant.push(n, v.product, v.direction, v.gradient)?;
        work.secant_flops += SecantMemory::<T>::pair_flops(n);
        Ok(())
    }

    /// Whether the factor computes in a lower precision than the model (mixed precision).
    pub(crate) fn mixed() -> bool {
        F::EPS.to_f64() > T::EPS.to_f64()
    }

    /// Factors the frozen matrix: the positive definite Hessian at the current state.
    pub(crate) fn prepare_frozen(&mut self, work: &mut WorkCount) -> Result<(), Error> {
        // With the elements' share kept, the first frame starts from it (taken once the
        // factorization succeeds).
        let keeps = self.keeps_elements();
        self.assemble(true, keeps, work)?;
        self.factorize(work)?;
        self.factored = FactoredMatrix::Frozen;
        // The quasi-Newton strategy's pairs corrected the factor before this one.
        self.secant.clear();
        if keeps {
            work.state_copies += self.kept.accept(self.n_unknowns());
        }
        Ok(())
    }

    pub(crate) fn factorize(&mut self, work: &mut WorkCount) -> Result<(), Error> {
        factorize_on(
            &self.live,
            self.hessian,
            &mut self.factor,
            &mut self.vectors,
            work,
        )
    }

    /// Preconditioned conjugate gradients on `H step = −grad` with the factor in service (the
    /// frozen one, or this frame's first Newton step's), a fixed
    /// number of iterations (fewer only if the residual vanishes exactly).
    fn pcg(&mut self, iterations: u32, work: &mut WorkCount) -> Result<(), Error> {
        let n = self.n_unknowns();
        let nnz = self.live.nnz_a;
        let a = self.live.pattern()?;
        let sym = &self.live.symbolic;
        let v = &mut self.vectors;
        // All of length `n` (`y`, `2 n`): `copy_from_slice` between them cannot fail.
        let (step, r, z, p, q, y) = (
            prefix_mut(v.step, n, Resource::Unknowns)?,
            prefix_mut(v.residual, n, Resource::Unknowns)?,
            prefix_mut(v.preconditioned, n, Resource::Unknowns)?,
            prefix_mut(v.direction, n, Resource::Unknowns)?,
            prefix_mut(v.product, n, Resource::Unknowns)?,
            prefix_mut(v.solve_work, times(2, n), Resource::Workspace)?,
        );
        let gradient = prefix(v.gradient, n, Resource::Unknowns)?;
        let hessian = prefix(self.hessian, nnz, Resource::MatrixEntries)?;
        step.fill(T::zero());
        for (ri, &g) in r.iter_mut().zip(gradient) {
            *ri = -g;
        }
        z.copy_from_slice(r);
        self.factor.solve_converting(sym, z, y)?;
        work.solves += 1;
        work.solve_flops += sym.solve_flops();
        p.copy_from_slice(z);
        let mut rz = dot(r, z);
        for _ in 0..iterations {
            sym_matvec(&a, hessian, p, q)?;
            work.matvecs += 1;
            work.matvec_flops += 2 * nnz as u64;
            let pq = dot(p, q);
            if !(pq > T::zero() && rz > T::zero()) {
                break;
            }
            let alpha = rz / pq;
            for (((si, ri), &pi), &qi) in step.iter_mut().zip(r.iter_mut()).zip(&*p).zip(&*q) {
                *si += alpha * pi;
                *ri -= alpha * qi;
            }
            z.copy_from_slice(r);
            self.factor.solve_converting(sym, z, y)?;
            work.solves += 1;
            work.solve_flops += sym.solve_flops();
            let rz_new = dot(r, z);
            let beta = rz_new / rz;
            for (pi, &zi) in p.iter_mut().zip(&*z) {
                *pi = zi + beta * *pi;
            }
            rz = rz_new;
        }
        Ok(())
    }

    /// Evaluates all trial lengths `1, ½, …` and returns the first that satisfies the Armijo
    /// condition, else the one with the lowest energy if it improves, else 0.
    ///
    /// Armijo is tested with the energy's rounding error as slack: near the minimum the
    /// decrease a Newton step buys falls below what the energy can resolve, and the step must
    /// still be taken for the gradient to keep shrinking.
    ///
    /// In a frame's `last` Newton step with a single trial, the trial is assembled (energy and
    /// gradient, into the PCG residual, which has no meaning between solves) rather than only
    /// evaluated, and the energies where the frame ends come back with the step: the trial's,
    /// its gradient then the model's, or `at` if the step is not taken (positions and gradient
    /// stay). The frame then needs no closing assembly ([`Self::solve_frame`]): one assembly
    /// without tangents in place of an energy evaluation and an assembly, every frame alike.
    /// With more trials the step taken need not be the last one evaluated, so they do not.
    /// A strategy whose Newton steps assemble no tangents ([`Strategy::QuasiNewton`]) has
    /// every step's single trial assembled so: the next step starts from its energies and
    /// gradient instead of assembling them again.
    fn line_search(
        &mut self,
        at: &Energies<T>,
        slope: T,
        trials: u32,
        last: bool,
        work: &mut WorkCount,
    ) -> Result<(T, Option<Energies<T>>), Error> {
        let n = self.n_unknowns();
        let n_nodes = self.live.mesh.n_nodes();
        // A Newton step that needs no tangents (`QuasiNewton`) needs no more than the
        // trial's gradient either: every step's single trial is assembled.
        let closes = trials == 1 && (last || !self.config.solver.strategy.assembles_hessian());
        // The trial's elements' share, kept for the next frame or step to start from.
        let keeps = closes && self.keeps_elements();
        let energy = at.total();
        let slack = T::of(2.0) * at.rounding;
        let mut alpha = T::one();
        let mut chosen: Option<T> = None;
        let mut best = (energy, T::zero());
        let mut assembled = None;
        for _ in 0..trials {
            self.fill_trial(alpha)?;
            let coefficients = self.coefficients();
            let SolveVectors {
                trial,
                residual,
                spring_nodes,
                ..
            } = &mut self.vectors;
            let problem = problem_of(
                &self.live,
                &self.features,
                coefficients,
                &self.config,
                spring_nodes,
            )?;
            let trial = prefix(trial, n_nodes, Resource::Nodes)?;
            let evaluated = if closes {
                work.energy_evaluations += 1;
                let gradient = prefix_mut(residual, n, Resource::Unknowns)?;
                let assembly = if keeps {
                    let (share, sums) = self.kept.trial_mut(n)?;
                    problem.assemble_keeping(trial, gradient, None, share, sums, work)
                } else {
                    problem.assemble(trial, gradient, None, work)
                };
                assembly.map(|e| {
                    assembled = Some(e);
                    e
                })
            } else {
                problem.energy(trial, work)
            };
            let e = match evaluated {
                Ok(e) => e.total(),
                Err(Error::FeatureBehindCamera { .. }) => T::zero() / T::zero(),
                Err(e) => return Err(e),
            };
            if e.finite() {
                if chosen.is_none() && e <= energy + T::of(1e-4) * alpha * slope + slack {
                    chosen = Some(alpha);
                }
                if e < best.0 {
                    best = (e, alpha);
                }
            }
            alpha *= T::of(0.5);
        }
        let alpha = chosen.unwrap_or(best.1);
        if !closes {
            return Ok((alpha, None));
        }
        match assembled {
            Some(e) if alpha > T::zero() => {
                let v = &mut self.vectors;
                prefix_mut(v.gradient, n, Resource::Unknowns)?.copy_from_slice(prefix(
                    v.residual,
                    n,
                    Resource::Unknowns,
                )?);
                if keeps {
                    work.state_copies += self.kept.accept(n);
                }
                Ok((alpha, Some(e)))
            }
            _ => Ok((alpha, Some(*at))),
        }
    }

    /// The positions `x + alpha · step` into `trial`, node by node (a fixed node stays).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a free index beyond the free nodes, and
    /// [`Error::Length`] / [`Error::Capacity`] for a free-index map or a vector shorter than the
    /// mesh's nodes or unknowns: none can occur for a model built by its constructors.
    fn fill_trial(&mut self, alpha: T) -> Result<(), Error> {
        let n_nodes = self.live.mesh.n_nodes();
        let n_free = self.live.mesh.n_free();
        let free = self.live.mesh.free_index();
        ensure_exact_len(free, n_nodes, Resource::Nodes)?;
        let v = &mut self.vectors;
        let trial = prefix_mut(v.trial, n_nodes, Resource::Nodes)?;
        let x = prefix(self.live.x, n_nodes, Resource::Nodes)?;
        // The step of free node `f` is `step[3 f..3 f + 3]`.
        let (step, _) = prefix(v.step, times(3, n_free), Resource::Unknowns)?.as_chunks::<3>();
        for (node, ((t, &xn), &f)) in trial.iter_mut().zip(x).zip(free).enumerate() {
            *t = xn;
            if f != NONE {
                let Some(d) = step.get(ux(f)) else {
                    return Err(Error::IndexOutOfRange {
                        resource: Resource::Nodes,
                        position: node,
                        index: ux(f),
                        bound: n_free,
                    });
                };
                for (tc, &dc) in t.iter_mut().zip(d) {
                    *tc += alpha * dc;
                }
            }
        }
        Ok(())
    }

    /// Moves the nodes to `x + alpha · step`.
    ///
    /// # Errors
    /// As `fill_trial`; on an error the positions are unchanged.
    fn move_along(&mut self, alpha: T) -> Result<(), Error> {
        self.fill_trial(alpha)?;
        let n_nodes = self.live.mesh.n_nodes();
        let trial = prefix(self.vectors.trial, n_nodes, Resource::Nodes)?;
        // Both of length `n_nodes`.
        prefix_mut(self.live.x, n_nodes, Resource::Nodes)?.copy_from_slice(trial);
        Ok(())
    }
}

/// The constants of the energy besides the mesh and the observations: the material's and the
/// springs' stiffness.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Coefficients<T> {
    pub(crate) lame: Lame<T>,
    /// The inversion barrier, if the material has one.
    pub(crate) barrier: Option<InversionBarrier<T>>,
    /// `k`, J/px² ([`crate::Model::spring_stiffness`]).
    pub(crate) spring_stiffness: T,
    /// `δ`, pixels ([`crate::Model::spring_threshold_px`]).
    pub(crate) spring_threshold_px: T,
    /// What the depth prior's weights are multiplied by.
    pub(crate) depth_scale: T,
}

impl<T: Real, F: Real> Model<'_, T, F> {
    /// The constants of this model's energy.
    pub(crate) fn coefficients(&self) -> Coefficients<T> {
        Coefficients {
            lame: self.lame,
            barrier: self.barrier,
            spring_stiffness: self.spring_stiffness,
            spring_threshold_px: self.spring_threshold_px,
            depth_scale: self.depth_scale,
        }
    }
}

/// The energy of a discretization with the features' observations. `spring_nodes` is the
/// springs' room, two entries per node: the camera rays through the nodes' previous positions,
/// computed here, then what the springs see of the nodes, filled by each spring pass
/// ([`Problem::seen`]).
///
/// # Errors
/// [`Error::Capacity`] if a per-node, per-tetrahedron or column-pointer array of `d`, or
/// `spring_nodes`, is shorter than its mesh and unknowns: it cannot be for a model built by its
/// constructors.
fn problem_of<'p, 'a, T: Real>(
    d: &'p Discretization<'a, T>,
    features: &'p Features<'a, T>,
    coefficients: Coefficients<T>,
    config: &'p ModelConfig<T>,
    spring_nodes: &'p mut [[T; 3]],
) -> Result<Problem<'p, 'a, T>, Error> {
    let n = d.mesh.n_nodes();
    let previous = prefix(d.previous, n, Resource::Nodes)?;
    let spring_nodes = prefix_mut(spring_nodes, times(2, n), Resource::Nodes)?;
    let (rays, seen) = spring_nodes.split_at_mut(n);
    camera_rays(&config.camera, previous, rays);
    let Coefficients {
        lame,
        barrier,
        spring_stiffness,
        spring_threshold_px,
        depth_scale,
    } = coefficients;
    Ok(Problem {
        mesh: &d.mesh,
        law: config.material.law,
        lame,
        barrier,
        camera: &config.camera,
        features,
        embedding: &d.features,
        spring_stiffness,
        spring_threshold_px,
        depth_scale,
        damping: prefix(d.damping, n, Resource::Nodes)?,
        depth_weight: prefix(d.depth_weight, n, Resource::Nodes)?,
        previous,
        rays,
        seen: Cell::from_mut(seen).as_slice_of_cells(),
        scatter: prefix(d.scatter, d.mesh.n_tets(), Resource::Tetrahedra)?,
        col_ptr: prefix(d.col_ptr, d.n_unknowns() + 1, Resource::ColumnPointers)?,
    })
}

/// Where [`assemble_on`] writes.
pub(crate) struct AssemblyOutput<'o, T> {
    /// The gradient (at least the discretization's unknowns).
    pub gradient: &'o mut [T],
    /// The Hessian's values (at least the pattern's entries), when tangents are assembled.
    pub hessian: Option<&'o mut [T]>,
    /// Where the elements' share is kept ([`Problem::assemble_keeping`]), if it is.
    pub keep: Option<(&'o mut [T], &'o mut ElementSums<T>)>,
    /// The springs' room, two entries per node (at least twice the discretization's nodes:
    /// [`problem_of`]).
    pub spring_nodes: &'o mut [[T; 3]],
}

/// Gradient (and, if asked for, the Hessian values) of a discretization at its positions.
///
/// # Errors
/// As [`Problem::assemble`], and [`Error::Capacity`] if an output or an array of `d` is
/// shorter than the unknowns, entries or mesh it holds (not for a model built by its
/// constructors).
pub(crate) fn assemble_on<T: Real>(
    d: &Discretization<'_, T>,
    features: &Features<'_, T>,
    coefficients: Coefficients<T>,
    config: &ModelConfig<T>,
    out: AssemblyOutput<'_, T>,
    work: &mut WorkCount,
) -> Result<Energies<T>, Error> {
    let n = d.n_unknowns();
    let nnz = d.nnz_a;
    let problem = problem_of(d, features, coefficients, config, out.spring_nodes)?;
    let x = prefix(d.x, d.mesh.n_nodes(), Resource::Nodes)?;
    let gradient = prefix_mut(out.gradient, n, Resource::Unknowns)?;
    let hessian = out
        .hessian
        .map(|h| prefix_mut(h, nnz, Resource::MatrixEntries))
        .transpose()?;
    match out.keep {
        Some((share, sums)) => problem.assemble_keeping(x, gradient, hessian, share, sums, work),
        None => problem.assemble(x, gradient, hessian, work),
    }
}

/// Factors the Hessian values of a discretization with its symbolic analysis.
///
/// # Errors
/// As [`LdlFactor::factorize_supernodal`], and [`Error::Capacity`] if `hessian` or the index
/// workspace is shorter than the pattern's entries or than the factorization needs (not for a
/// model built by its constructors).
pub(crate) fn factorize_on<T: Real, F: Real>(
    d: &Discretization<'_, T>,
    hessian: &[T],
    factor: &mut LdlFactor<'_, F>,
    vectors: &mut SolveVectors<'_, T, F>,
    work: &mut WorkCount,
) -> Result<(), Error> {
    let n = d.n_unknowns();
    factor.factorize_supernodal(
        &d.symbolic,
        prefix(hessian, d.nnz_a, Resource::MatrixEntries)?,
        vectors.factor_work,
        prefix_mut(
            vectors.factor_indices,
            LdlFactor::<F>::supernodal_index_work_len(n),
            Resource::Workspace,
        )?,
    )?;
    work.factorizations += 1;
    work.factor_flops += d.symbolic.factor_flops();
    Ok(())
}
