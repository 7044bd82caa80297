//! The model: mesh, material, camera, virtual features, internal targets and the fixed-budget
//! solver, built once in caller storage and stepped frame by frame.
//!
//! ```text
//! let size = ModelSize::new(&capacities)?;                every length a const fn of them
//! Model::new(mesh, config, &size, ModelBuffers::new(&size, reals, indices)?)
//! model.embed_features(frame_0)                          virtual features on the surface
//! model.embed_targets(points)                            internal targets (optional)
//! loop { model.step(frame) }                             observe → solve → detect → grow → cut
//! ```
//!
//! The storage that a cut changes lives twice ([`discretization`]): the half in service and a
//! spare the cut is built into, swapped in only when the whole rebuild succeeded.

#[cfg(feature = "cut")]
mod cutting;
#[cfg(feature = "detect")]
mod detecting;
pub(crate) mod discretization;
mod size;

pub use size::{
    Capacities, MAX_STORAGE_LEN, MeshAnalysis, ModelBuffers, ModelSize, StoragePart, analyse_mesh,
    analyse_mesh_work_len,
};

use nalgebra::Vector3;

use crate::camera::Camera;
#[cfg(feature = "cut")]
use crate::cut::{self, CutEvent, CutReport, CutWork};
#[cfg(feature = "detect")]
use crate::cutline::{CutLine, CutLineReport, LineWork};
use crate::detect::DetectionConfig;
#[cfg(feature = "detect")]
use crate::detect::{DetectionReport, DetectionWork, Detector};
use crate::embed::{Embedding, interpolate, locate_at_rest};
use crate::error::{Error, Resource};
use crate::features::{EmbedReport, Features, Observation};
use crate::material::Lame;
use crate::mesh::{Mesh, MeshInput};
use crate::real::Real;
use crate::solve::{Energies, SolverConfig, Strategy, WorkCount, problem_of};
#[cfg(feature = "cut")]
use crate::solve::{assemble_on, factorize_on};
use crate::sparse::{LdlFactor, NONE, PrecomputedAnalysis, Symbolic, UpperCsc};
use crate::storage::{Fingerprint, Slab, ensure_exact_len, ensure_len};

use discretization::Discretization;

/// Material parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material<T> {
    /// Young's modulus, pascals.
    pub young: T,
    /// Poisson ratio, dimensionless, in `(-1, 0.5)`.
    pub poisson: T,
}

/// Everything a model needs besides its mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelConfig<T: Real> {
    /// Material of the organ.
    pub material: Material<T>,
    /// The calibrated camera.
    pub camera: Camera<T>,
    /// The per-frame solve.
    pub solver: SolverConfig<T>,
    /// Cut detection (used only when the crate is built with the `cut` feature).
    pub detection: DetectionConfig<T>,
}

/// Which matrix the factor in service holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FactorHolds {
    Nothing,
    /// The frozen matrix of [`Strategy::Frozen`].
    Frozen,
    /// The Hessian of the last Newton step.
    Step,
}

/// What one [`Model::step`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport<T> {
    /// Frame number (0 for the first step).
    pub frame: u32,
    /// Features observed in this frame.
    pub observed: usize,
    /// Energies at the start of the step (new observations, previous positions).
    pub energy_before: Energies<T>,
    /// Energies at the end of the step.
    pub energy_after: Energies<T>,
    /// Norm of the gradient over the free unknowns at the start of the step.
    pub gradient_norm_before: T,
    /// Norm of the gradient at the end of the step.
    pub gradient_norm_after: T,
    /// The smallest step length the line search accepted over the Newton steps (0 if one
    /// Newton step could not decrease the energy).
    pub min_step_length: T,
    /// Work of the steady part of the frame (the solve), per stage.
    pub work: WorkCount,
    /// What the cut detection saw (zeros when it is switched off).
    #[cfg(feature = "detect")]
    pub detection: DetectionReport<T>,
    /// The cut line.
    #[cfg(feature = "detect")]
    pub cut_line: CutLineReport,
    /// The cut of the mesh in this frame, with its own work (apart from the steady frame).
    #[cfg(feature = "cut")]
    pub cut: CutReport,
}

/// The linear system of a Newton step, from [`Model::linearize`].
#[derive(Debug)]
pub struct Linearization<'m, T> {
    /// Energies at the current positions.
    pub energies: Energies<T>,
    /// Gradient over the free unknowns.
    pub gradient: &'m [T],
    /// Positive definite Hessian values on `pattern`.
    pub hessian: &'m [T],
    /// The stiffness pattern (upper triangle, unknowns in free-node order).
    pub pattern: UpperCsc<'m>,
}

/// Vectors of the Newton step and its linear solve, over the unknowns (no meaning between
/// calls; a cut uses them as scratch too).
pub(crate) struct SolveVectors<'a, T> {
    pub(crate) gradient: &'a mut [T],
    pub(crate) step: &'a mut [T],
    /// PCG residual, preconditioned residual, direction and `H·direction`.
    pub(crate) residual: &'a mut [T],
    pub(crate) preconditioned: &'a mut [T],
    pub(crate) direction: &'a mut [T],
    pub(crate) product: &'a mut [T],
    /// Work of the triangular solves and the factorization.
    pub(crate) solve_work: &'a mut [T],
    /// Positions tried by the line search.
    pub(crate) trial: &'a mut [[T; 3]],
    /// Packed blocks of the supernodal factorization ([`LdlFactor::SUPERNODAL_WORK_LEN`]).
    pub(crate) factor_work: &'a mut [T],
    /// Index workspace of the supernodal factorization
    /// ([`LdlFactor::supernodal_index_work_len`] of the unknowns).
    pub(crate) factor_indices: &'a mut [u32],
}

/// The organ model.
pub struct Model<'a, T: Real> {
    pub(crate) config: ModelConfig<T>,
    pub(crate) lame: Lame<T>,
    /// The mesh and everything built on it, in service.
    pub(crate) live: Discretization<'a, T>,
    /// Room to build the next topology in (no meaning between cuts).
    #[cfg(feature = "cut")]
    pub(crate) spare: Discretization<'a, T>,
    pub(crate) hessian: &'a mut [T],
    pub(crate) factor: LdlFactor<'a, T>,
    pub(crate) holds: FactorHolds,
    pub(crate) vectors: SolveVectors<'a, T>,
    /// Workspace of rebuilds and cuts (no meaning between calls).
    #[cfg(feature = "cut")]
    pub(crate) work: &'a mut [u32],
    pub(crate) features: Features<'a, T>,
    /// What a failing call gives back (no meaning between calls).
    pub(crate) saved: Saved<'a, T>,
    #[cfg(feature = "detect")]
    cut: CutState<'a, T>,
    pub(crate) frame: u32,
}

/// Copies of the state that [`Model::step`] and [`Model::embed_features`] overwrite before they
/// know whether they succeed, so that a failure can put it back bit for bit.
pub(crate) struct Saved<'a, T> {
    /// The features' ids, targets and observed flags.
    pub(crate) features: Features<'a, T>,
    /// The virtual features' embedding.
    pub(crate) embedding: Embedding<'a, T>,
    /// The damping reference (positions before the last frame).
    pub(crate) previous: &'a mut [[T; 3]],
}

/// The detector, the cut line and their scratch.
#[cfg(feature = "detect")]
struct CutState<'a, T> {
    detector: Detector<'a, T>,
    line: CutLine<'a, T>,
    /// Residual `d_i` per feature slot.
    residuals: &'a mut [[T; 2]],
    /// Scratch: projections of the virtual features at frame 0, then the cut line's vertices
    /// each frame.
    pixels: &'a mut [[T; 2]],
    /// Scratch of the mesh cut ([`cut::real_len`]).
    #[cfg(feature = "cut")]
    scratch: &'a mut [T],
}

impl<'a, T: Real> Model<'a, T> {
    /// Builds the model in caller storage (sizes from `size`); the model starts at rest with
    /// no features and no targets.
    ///
    /// # Errors
    /// As [`Mesh::load`]; [`Error::InvalidParameter`] for a bad material, solver or detection
    /// setting; [`Error::Capacity`] when a buffer or a capacity of `size` is too small (the
    /// mesh larger than its capacities, or its factor larger than
    /// [`Capacities::factor_entries`]).
    pub fn new(
        input: &MeshInput<'_, T>,
        config: &ModelConfig<T>,
        size: &ModelSize,
        buffers: ModelBuffers<'a, T>,
    ) -> Result<Self, Error> {
        Self::build(config, size, buffers, |live, lame, solver, work| {
            live.load(input, lame, solver, work)
        })
    }

    /// As [`Model::new`], with the ordering and symbolic analysis of the uncut mesh taken from
    /// `analysis` (generated ahead of time by `incise codegen`, or
    /// [`Symbolic::precomputed`] of a model built from the same mesh) instead of computed: a
    /// firmware build that never cuts then links neither the minimum-degree ordering nor the
    /// analysis. The analysis is checked against the mesh's stiffness pattern in time linear in
    /// the factor's entries ([`crate::sparse::precomputed`]); the model is the same, bit for
    /// bit, as [`Model::new`] builds. A cut (feature `cut`) still orders and analyses the cut
    /// mesh itself.
    ///
    /// # Errors
    /// As [`Model::new`]; [`Error::Precomputed`] when `analysis` is not that of this mesh's
    /// pattern or is damaged.
    pub fn from_precomputed(
        input: &MeshInput<'_, T>,
        config: &ModelConfig<T>,
        size: &ModelSize,
        buffers: ModelBuffers<'a, T>,
        analysis: &PrecomputedAnalysis<'_>,
    ) -> Result<Self, Error> {
        Self::build(config, size, buffers, |live, lame, solver, work| {
            live.load_precomputed(input, lame, solver, work, analysis)
        })
    }

    /// Carves the model out of `buffers`, then loads the mesh with `load`: generic, so that
    /// each constructor links only its own way of analysing the system.
    fn build(
        config: &ModelConfig<T>,
        size: &ModelSize,
        buffers: ModelBuffers<'a, T>,
        load: impl FnOnce(
            &mut Discretization<'a, T>,
            &Lame<T>,
            &SolverConfig<T>,
            &mut [u32],
        ) -> Result<(), Error>,
    ) -> Result<Self, Error> {
        config.solver.validate()?;
        config.detection.validate()?;
        let lame = Lame::from_young_poisson(config.material.young, config.material.poisson)?;
        let ModelBuffers { reals, indices } = buffers;
        ensure_len(reals, size.real_len(), Resource::RealStorage)?;
        ensure_len(indices, size.index_len(), Resource::IndexStorage)?;
        let caps = size.capacities();
        let mut rs = Slab::new(reals, Resource::RealStorage);
        let mut is = Slab::new(indices, Resource::IndexStorage);
        let mut live = Discretization::with_capacity(size, &mut rs, &mut is)?;
        #[cfg(feature = "cut")]
        let spare = Discretization::with_capacity(size, &mut rs, &mut is)?;
        let dofs = size.unknowns();
        let hessian = rs.take(size.nnz_a())?;
        let factor = LdlFactor::new(
            &size.symbolic_capacity(),
            rs.take(LdlFactor::<T>::storage_len(&size.symbolic_capacity()))?,
        )?;
        let vectors = SolveVectors {
            gradient: rs.take(dofs)?,
            step: rs.take(dofs)?,
            residual: rs.take(dofs)?,
            preconditioned: rs.take(dofs)?,
            direction: rs.take(dofs)?,
            product: rs.take(dofs)?,
            solve_work: rs.take(dofs)?,
            trial: rs.take(3 * caps.mesh.nodes)?.as_chunks_mut::<3>().0,
            factor_work: rs.take(LdlFactor::<T>::SUPERNODAL_WORK_LEN)?,
            factor_indices: is.take(LdlFactor::<T>::supernodal_index_work_len(dofs))?,
        };
        let features = Features::new(caps.features, &mut rs, &mut is)?;
        let saved = Saved {
            features: Features::new(caps.features, &mut rs, &mut is)?,
            embedding: Embedding::with_capacity(caps.features, &mut rs, &mut is)?,
            previous: rs.take(3 * caps.mesh.nodes)?.as_chunks_mut::<3>().0,
        };
        #[cfg(feature = "detect")]
        let cut = CutState {
            detector: Detector::new(caps.features, caps.pairs, &mut rs, &mut is)?,
            line: CutLine::new(caps.cut_vertices, &mut rs, &mut is)?,
            residuals: rs.take(2 * caps.features)?.as_chunks_mut::<2>().0,
            pixels: rs
                .take(2 * caps.features.max(caps.cut_vertices))?
                .as_chunks_mut::<2>()
                .0,
            #[cfg(feature = "cut")]
            scratch: rs.take(cut::real_len(caps.mesh.nodes, caps.cut_vertices))?,
        };
        let work = is.take(size.work_len())?;
        load(&mut live, &lame, &config.solver, work)?;
        Ok(Model {
            config: *config,
            lame,
            live,
            #[cfg(feature = "cut")]
            spare,
            hessian,
            factor,
            holds: FactorHolds::Nothing,
            vectors,
            #[cfg(feature = "cut")]
            work,
            features,
            saved,
            #[cfg(feature = "detect")]
            cut,
            frame: 0,
        })
    }

    /// The mesh in service.
    pub fn mesh(&self) -> &Mesh<'a, T> {
        &self.live.mesh
    }

    /// Current node positions, metres.
    pub fn positions(&self) -> &[[T; 3]] {
        &self.live.x[..self.live.mesh.n_nodes()]
    }

    /// The features' observations (ids, latest pixels, observed this frame).
    pub fn features(&self) -> &Features<'a, T> {
        &self.features
    }

    /// Where each virtual feature sits in the mesh (tetrahedron and weights, by slot).
    pub fn feature_embedding(&self) -> &crate::embed::Embedding<'a, T> {
        &self.live.features
    }

    /// Where each internal target sits in the mesh.
    pub fn target_embedding(&self) -> &crate::embed::Embedding<'a, T> {
        &self.live.targets
    }

    /// The configuration.
    pub fn config(&self) -> &ModelConfig<T> {
        &self.config
    }

    /// The symbolic factorization of the stiffness pattern in service (sizes, flop counts).
    pub fn symbolic(&self) -> &Symbolic<'a> {
        &self.live.symbolic
    }

    /// The numeric factor (values of the last factorization in service, if any).
    pub fn factor(&self) -> &LdlFactor<'a, T> {
        &self.factor
    }

    /// Number of unknowns (three per free node).
    pub fn n_unknowns(&self) -> usize {
        self.live.n_unknowns()
    }

    /// World position of the virtual feature in `slot`, metres.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] naming [`Resource::FeatureSlots`] for a slot not in use
    /// (slots are `0..` the number embedded; [`Features::slot_of`] gives a feature id's).
    pub fn feature_position(&self, slot: usize) -> Result<[T; 3], Error> {
        self.live
            .features
            .position(slot, &self.live.mesh, self.positions())
            .ok_or(Error::IndexOutOfRange {
                resource: Resource::FeatureSlots,
                position: slot,
                index: slot,
                bound: self.live.features.len(),
            })
    }

    /// Current pixel of the virtual feature in `slot`.
    ///
    /// # Errors
    /// As [`Model::feature_position`]; [`Error::FeatureBehindCamera`].
    pub fn projected_feature(&self, slot: usize) -> Result<[T; 2], Error> {
        let p = self.feature_position(slot)?;
        let uv = self
            .config
            .camera
            .project(&Vector3::from(p), slot)
            .map_err(|_| self.features.behind_camera(slot))?;
        Ok([uv.x, uv.y])
    }

    /// Number of internal targets carried.
    pub fn n_targets(&self) -> usize {
        self.live.targets.len()
    }

    /// Current position of internal target `k`, metres (`None` out of range).
    pub fn target_position(&self, k: usize) -> Option<[T; 3]> {
        self.live
            .targets
            .position(k, &self.live.mesh, self.positions())
    }

    /// Embeds internal targets given by their rest positions (metres): each in the rest
    /// tetrahedron that contains it, or, for a point just outside the mesh, the one it lies
    /// least outside of (weights clamped to it). Replaces the targets held before. The model
    /// carries them from then on, through cuts (each is re-embedded in the piece of its own
    /// side).
    ///
    /// Cost: targets × tetrahedra barycentric solves, once.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming [`Resource::Targets`] for more points than
    /// [`Capacities::targets`]; [`Error::NonFiniteInput`] for a non-finite coordinate. On error
    /// the targets held before stay.
    pub fn embed_targets(&mut self, rest_points: &[[T; 3]]) -> Result<usize, Error> {
        let capacity = self.live.targets.capacity();
        if rest_points.len() > capacity {
            return Err(Error::Capacity {
                resource: Resource::Targets,
                needed: rest_points.len(),
                available: capacity,
            });
        }
        if let Some(position) = rest_points
            .iter()
            .position(|p| !p.iter().all(|c| c.finite()))
        {
            return Err(Error::NonFiniteInput {
                resource: Resource::Targets,
                position,
            });
        }
        let targets = &mut self.live.targets;
        targets.clear();
        for &p in rest_points {
            // A mesh has at least one proper tetrahedron, so a point always lands somewhere.
            let (t, w) = locate_at_rest(&self.live.mesh, p).unwrap_or((0, [T::of(0.25); 4]));
            targets.push(t, w, Resource::Targets)?;
        }
        Ok(targets.len())
    }

    /// Switches the linear strategy; a later step refactors what the new strategy needs.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for an iteration count out of range.
    pub fn set_strategy(&mut self, strategy: Strategy) -> Result<(), Error> {
        let solver = SolverConfig {
            strategy,
            ..self.config.solver
        };
        solver.validate()?;
        self.config.solver = solver;
        Ok(())
    }

    /// Embeds the features of frame 0 (see [`Features::embed`]) at the current positions,
    /// replacing any held before, sets up the cut detection on them (`cut` feature: neighbour
    /// pairs, a fresh cut line, frame count back to 0) and prepares the frozen factor when
    /// that strategy is configured.
    ///
    /// All or nothing: the features and their embedding are copied aside first (once, `9 ·`
    /// [`Capacities::features`] entries at most), the detector counts its pairs before it
    /// stores any, and the factor keeps its previous values until the call succeeds
    /// ([`LdlFactor::checkpoint`]).
    ///
    /// # Errors
    /// As [`Features::embed`]; [`Error::NoFeatures`] if no ray hits the model;
    /// [`Error::FeatureBehindCamera`] for a virtual feature that cannot be projected;
    /// [`Error::Capacity`] naming [`Resource::Pairs`] for more neighbour pairs than
    /// [`Capacities::pairs`]; the factorization's errors for the frozen factor. On any error
    /// the model is exactly as before the call ([`Model::fingerprint`] unchanged).
    pub fn embed_features(&mut self, frame0: &[Observation<T>]) -> Result<EmbedReport, Error> {
        self.saved.features.copy_from(&self.features);
        self.saved.embedding.copy_from(&self.live.features);
        let holds = self.holds;
        self.factor.checkpoint();
        match self.embed_features_uncommitted(frame0) {
            Ok(report) => {
                self.factor.commit();
                Ok(report)
            }
            Err(e) => {
                self.features.copy_from(&self.saved.features);
                self.live.features.copy_from(&self.saved.embedding);
                self.holds = holds;
                self.factor.rollback();
                Err(e)
            }
        }
    }

    /// [`Model::embed_features`] without the roll-back: what fails comes before what cannot.
    fn embed_features_uncommitted(
        &mut self,
        frame0: &[Observation<T>],
    ) -> Result<EmbedReport, Error> {
        let margin = self.config.solver.image_margin;
        let n = self.live.mesh.n_nodes();
        let report = self.features.embed(
            &mut self.live.features,
            &self.live.mesh,
            &self.live.x[..n],
            &self.config.camera,
            frame0,
            margin,
        )?;
        if report.embedded == 0 {
            return Err(Error::NoFeatures);
        }
        #[cfg(feature = "detect")]
        {
            // Scratch: the projections and residuals at frame 0.
            for slot in 0..self.features.len() {
                let uv = self.projected_feature(slot)?;
                let t = self.features.targets()[slot];
                self.cut.pixels[slot] = uv;
                self.cut.residuals[slot] = [t[0] - uv[0], t[1] - uv[1]];
            }
        }
        // The frozen factor is part of setting up, not of the first frame, so that every frame
        // costs the same.
        self.holds = FactorHolds::Nothing;
        if cfg!(feature = "frozen")
            && let Strategy::Frozen { .. } = self.config.solver.strategy
        {
            self.prepare_frozen(&mut WorkCount::default())?;
        }
        #[cfg(feature = "detect")]
        {
            let n = self.features.len();
            let (live, camera) = (&self.live, &self.config.camera);
            let focal = camera.intrinsics().fx;
            let at = |slot: usize| {
                live.features
                    .position(slot, &live.mesh, &live.x[..live.mesh.n_nodes()])
                    .map(|p| camera.to_camera(&Vector3::from(p)))
            };
            // Pairs across a fold or a grazing slope are left out (the ratio's doc says why).
            let ratio = self.config.detection.max_surface_ratio;
            // The last step that can fail: it leaves the detector as it was on error.
            self.cut.detector.init_on_surface(
                &self.cut.pixels[..n],
                &self.cut.residuals[..n],
                &self.config.detection,
                |i, j, l| match (at(i), at(j)) {
                    (Some(a), Some(b)) if ratio > T::zero() => {
                        let z = T::of(0.5) * (a.z + b.z);
                        (a - b).norm() > ratio * l * z / focal
                    }
                    _ => false,
                },
            )?;
            self.frame = 0;
            self.cut.line.reset();
        }
        Ok(report)
    }

    /// One registration step, its stages in order:
    /// 1. **observe**: take the frame's observations;
    /// 2. **solve**: a fixed number of Newton steps lowering `W_I + W_S + W_D`;
    /// 3. **detect** (`cut` feature): residuals, the discontinuity detector;
    /// 4. **grow**: the cut line follows its evidence and its fronts advance;
    /// 5. **cut**: the mesh is cut along the line's separation surface ([`Model::apply_cut`]).
    ///
    /// The steady work (stages 1–4) is fixed by the configuration and the scene's sizes:
    /// `newton_iterations + 1` assemblies, one factorization per Newton step (`Refactor`) or
    /// `pcg_iterations` matrix–vector products and solves (`Frozen`), and
    /// `line_search_steps` energy evaluations per Newton step. A cut event is reported apart
    /// ([`StepReport::cut`]); a cut that cannot be made (a capacity, a factorization) is
    /// reported there and leaves the mesh as it was, without failing the frame.
    ///
    /// All or nothing: before the frame is taken, the features' observations (`5 ·` features
    /// entries) and the damping reference (`3 ·` nodes) are copied aside, and the factor keeps
    /// its previous values ([`LdlFactor::checkpoint`], no copy); a frame that fails puts them
    /// back. These copies are counted in [`WorkCount::state_copies`].
    ///
    /// # Errors
    /// As [`Features::set_frame`] for a bad frame; [`Error::NoFeatures`] before
    /// [`Model::embed_features`]; [`Error::NotPositiveDefinite`] / [`Error::NotFinite`] /
    /// [`Error::Diverged`] / [`Error::FeatureBehindCamera`] if the solve breaks down. On any error the
    /// model is exactly as before the call ([`Model::fingerprint`] unchanged): positions,
    /// damping reference, observations, factor, frame count.
    pub fn step(&mut self, frame: &[Observation<T>]) -> Result<StepReport<T>, Error> {
        if self.features.is_empty() {
            return Err(Error::NoFeatures);
        }
        let n_nodes = self.live.mesh.n_nodes();
        self.saved.features.copy_from(&self.features);
        // Checked completely before anything is written: on error nothing has changed.
        let observed = self.observe(frame)?;
        let live = &mut self.live;
        self.saved.previous[..n_nodes].copy_from_slice(&live.previous[..n_nodes]);
        live.previous[..n_nodes].copy_from_slice(&live.x[..n_nodes]);
        let holds = self.holds;
        self.factor.checkpoint();
        let mut report = match self.solve_frame() {
            Ok(report) => {
                self.factor.commit();
                report
            }
            Err(e) => {
                let live = &mut self.live;
                live.x[..n_nodes].copy_from_slice(&live.previous[..n_nodes]);
                live.previous[..n_nodes].copy_from_slice(&self.saved.previous[..n_nodes]);
                self.features.copy_from(&self.saved.features);
                self.holds = holds;
                self.factor.rollback();
                return Err(e);
            }
        };
        report.work.state_copies += (5 * self.features.len() + 3 * n_nodes) as u64;
        report.frame = self.frame;
        report.observed = observed;
        #[cfg(feature = "detect")]
        if self.config.detection.enabled {
            report.detection = self.detect();
            report.cut_line = self.grow_cut_line();
            #[cfg(feature = "cut")]
            {
                report.cut = match self.apply_cut() {
                    Ok(cut) => cut,
                    Err(e) => CutReport::refused(e),
                };
            }
        }
        self.frame = self.frame.wrapping_add(1);
        Ok(report)
    }

    /// Takes a frame's observations without solving (what [`Model::step`] does first); for
    /// validation with an outside solver through [`Model::linearize`]. Returns the number
    /// observed.
    ///
    /// # Errors
    /// As [`Features::set_frame`]; [`Error::NoFeatures`] before [`Model::embed_features`].
    pub fn observe(&mut self, frame: &[Observation<T>]) -> Result<usize, Error> {
        if self.features.is_empty() {
            return Err(Error::NoFeatures);
        }
        let margin = self.config.solver.image_margin;
        self.features.set_frame(&self.config.camera, frame, margin)
    }

    /// The worst-case work of one [`Model::step`]'s steady part with every feature observed:
    /// a formula of the scene's sizes and the configuration.
    pub fn worst_case_work(&self) -> WorkCount {
        let s = &self.config.solver;
        let newton = s.newton_iterations;
        let tets = self.live.mesh.n_tets() as u64;
        let feats = self.features.len() as u64;
        let nnz = self.live.nnz_a as u64;
        let sym = &self.live.symbolic;
        let mut w = WorkCount {
            assemblies: newton + 1,
            element_tangents: u64::from(newton) * tets,
            element_evaluations: tets * (1 + u64::from(newton * s.line_search_steps)),
            feature_evaluations: feats
                * (1 + u64::from(newton) * (1 + u64::from(s.line_search_steps))),
            energy_evaluations: newton * s.line_search_steps,
            state_copies: 5 * feats + 3 * self.live.mesh.n_nodes() as u64,
            ..WorkCount::default()
        };
        match s.strategy {
            Strategy::Refactor => {
                w.factorizations = newton;
                w.factor_flops = u64::from(newton) * sym.factor_flops();
                w.solves = newton;
                w.solve_flops = u64::from(newton) * sym.solve_flops();
            }
            Strategy::Frozen { pcg_iterations } => {
                w.solves = newton * (pcg_iterations + 1);
                w.solve_flops = u64::from(w.solves) * sym.solve_flops();
                w.matvecs = newton * pcg_iterations;
                w.matvec_flops = u64::from(w.matvecs) * 2 * nnz;
            }
            Strategy::FactorOnce { pcg_iterations } => {
                let later = newton.saturating_sub(1);
                w.factorizations = 1;
                w.factor_flops = sym.factor_flops();
                w.solves = 1 + later * (pcg_iterations + 1);
                w.solve_flops = u64::from(w.solves) * sym.solve_flops();
                w.matvecs = later * pcg_iterations;
                w.matvec_flops = u64::from(w.matvecs) * 2 * nnz;
            }
        }
        w
    }

    /// The energies at the current positions (observations of the last frame, damping toward
    /// the previous frame's positions).
    ///
    /// # Errors
    /// [`Error::FeatureBehindCamera`] if a virtual feature cannot be projected.
    pub fn energy(&self) -> Result<Energies<T>, Error> {
        problem_of(&self.live, &self.features, &self.lame, &self.config)
            .energy(self.positions(), &mut WorkCount::default())
    }

    /// Assembles the system a Newton step solves at the current positions, for validation
    /// against other solvers: the gradient over the free unknowns (`3 · n_free`, node by free
    /// index) and the positive definite Hessian on the stiffness pattern.
    ///
    /// # Errors
    /// As [`Model::energy`].
    pub fn linearize(&mut self) -> Result<Linearization<'_, T>, Error> {
        let energies = self.assemble(true, &mut WorkCount::default())?;
        let n = self.n_unknowns();
        let nnz = self.live.nnz_a;
        Ok(Linearization {
            energies,
            gradient: &self.vectors.gradient[..n],
            hessian: &self.hessian[..nnz],
            pattern: self.live.pattern()?,
        })
    }

    /// Moves the free nodes to `x` (one position per node; the entries of fixed nodes are
    /// ignored, they stay at rest). The damping reference moves with them.
    ///
    /// # Errors
    /// [`Error::Length`] if `x` does not have one entry per node, [`Error::NonFiniteInput`]
    /// for a non-finite coordinate; nothing changes then.
    pub fn set_positions(&mut self, x: &[[T; 3]]) -> Result<(), Error> {
        let n = self.live.mesh.n_nodes();
        ensure_exact_len(x, n, Resource::Nodes)?;
        if let Some(position) = x.iter().position(|p| !p.iter().all(|c| c.finite())) {
            return Err(Error::NonFiniteInput {
                resource: Resource::Nodes,
                position,
            });
        }
        let live = &mut self.live;
        let free = live.mesh.free_index();
        for v in 0..n {
            if free[v] != NONE {
                live.x[v] = x[v];
            }
        }
        live.previous[..n].copy_from_slice(&live.x[..n]);
        Ok(())
    }

    /// A 64-bit fingerprint (FNV-1a) of every buffer that holds the model's state: the mesh
    /// (rest positions, element data, tetrahedra, free map, boundary surface), positions,
    /// previous positions, damping weights, stiffness pattern, symbolic analysis, scatter map,
    /// feature and target embeddings, the cut's lips, the factor in service, the features'
    /// observations, the frame count, the strategy and what the factor holds, the detector and
    /// the cut line. Scratch (the spare half, workspaces, the
    /// Hessian and solve vectors) has no meaning between calls and is left out. Two models in
    /// the same state have the same fingerprint; a call that fails must leave it unchanged.
    pub fn fingerprint(&self) -> u64 {
        let mut h = Fingerprint::new();
        let d = &self.live;
        let m = &d.mesh;
        h.reals(m.rest().iter().flatten());
        for t in 0..m.n_tets() {
            if let Some(e) = m.element_rest(t) {
                h.reals(e.dm_inv.iter());
                h.reals(core::iter::once(&e.volume));
            }
        }
        h.words(m.tets().iter().flatten());
        h.words(m.free_index());
        h.words(m.surface().iter().flatten());
        h.words(m.surface_tet());
        let n = m.n_nodes();
        h.reals(d.x[..n].iter().flatten());
        h.reals(d.previous[..n].iter().flatten());
        h.reals(d.damping[..n].iter());
        h.words(&d.col_ptr[..d.n_unknowns() + 1]);
        h.words(&d.row_idx[..d.nnz_a]);
        let sym = &d.symbolic;
        for part in [
            sym.perm(),
            sym.iperm(),
            sym.etree(),
            sym.c_ptr(),
            sym.c_row(),
            sym.c_src(),
            sym.l_ptr(),
            sym.l_row(),
            sym.lt_ptr(),
            sym.lt_col(),
        ] {
            h.words(part);
        }
        h.words(d.scatter[..m.n_tets()].iter().flatten());
        for e in [&d.features, &d.targets] {
            h.words(e.tets());
            h.reals(e.weights().iter().flatten());
        }
        #[cfg(feature = "cut")]
        h.words(d.lips.pairs().iter().flatten());
        if let (Some(l), Some(dv)) = (self.factor.l_values(), self.factor.d_values()) {
            h.reals(l.iter());
            h.reals(dv.iter());
        }
        h.words(self.features.ids().iter().flatten());
        h.reals(self.features.targets().iter().flatten());
        h.words(self.features.active());
        h.words(core::iter::once(&self.frame));
        let strategy = match self.config.solver.strategy {
            Strategy::Refactor => [0, 0],
            Strategy::Frozen { pcg_iterations } => [1, pcg_iterations],
            Strategy::FactorOnce { pcg_iterations } => [2, pcg_iterations],
        };
        h.words(strategy.iter());
        h.words(core::iter::once(&(self.holds as u32)));
        #[cfg(feature = "detect")]
        {
            self.cut.detector.fingerprint_into(&mut h);
            self.cut.line.fingerprint_into(&mut h);
        }
        h.finish()
    }

    /// Position of internal target `k` interpolated at positions `x` (for callers that move the
    /// nodes themselves); `None` out of range.
    pub fn target_at(&self, k: usize, x: &[[T; 3]]) -> Option<[T; 3]> {
        let t = *self.live.targets.tets().get(k)?;
        let tet = self.live.mesh.tets().get(t as usize)?;
        interpolate(x, tet, &self.live.targets.weights()[k])
    }
}
