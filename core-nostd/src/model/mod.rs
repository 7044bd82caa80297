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
//! The storage that a cut changes lives twice (`discretization.rs`): the half in service and a
//! spare the cut is built into, swapped in only when the whole rebuild succeeded.

#[cfg(feature = "cut")]
mod cutting;
#[cfg(feature = "detect")]
mod detecting;
pub(crate) mod discretization;
mod embedding;
mod inspect;
mod size;

pub use size::{
    Capacities, MAX_STORAGE_LEN, MeshAnalysis, ModelBuffers, ModelSize, StoragePart, analyse_mesh,
    analyse_mesh_work_len,
};

use nalgebra::Vector3;

use crate::camera::Camera;
#[cfg(feature = "cut")]
use crate::cut::{self, CutReport, CutWork};
#[cfg(feature = "detect")]
use crate::cutline::{CutLine, CutLineReport, LineWork};
use crate::detect::DetectionConfig;
#[cfg(feature = "detect")]
use crate::detect::{DetectionReport, DetectionWork, Detector};
use crate::embed::{Embedding, locate_at_rest};
use crate::error::{Error, Parameter, Resource};
use crate::features::{EmbedReport, Features, Observation, image_bounds, spacing_px};
use crate::material::{InversionBarrier, Lame, Law};
use crate::mesh::{Mesh, MeshInput};
use crate::real::Real;
#[cfg(feature = "cut")]
use crate::solve::{AssemblyOutput, assemble_on, factorize_on};
use crate::solve::{
    Coupling, Energies, KeptElements, MIXED_REFINEMENT_STEPS, SecantMemory, SolverConfig, Strategy,
    WorkCount,
};
use crate::sparse::{LdlFactor, NONE, PrecomputedAnalysis, Symbolic, UpperCsc};
use crate::storage::{Fingerprint, Slab, copy_front, ensure_exact_len, ensure_len};

use discretization::Discretization;

/// Material parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material<T> {
    /// Young's modulus, pascals.
    pub young: T,
    /// Poisson ratio, dimensionless, in `(-1, 0.5)`.
    pub poisson: T,
    /// Adds [`InversionBarrier::for_material`] to the energy: elements compressed below
    /// `det F = 1/√3` are pushed back, and inverted ones out again (SVK alone lets strong
    /// springs turn elements inside out for good). Off, the energy is the law's alone, bit for
    /// bit.
    pub inversion_barrier: bool,
    /// The strain energy law ([`Law::SaintVenantKirchhoff`], the paper's, or
    /// [`Law::StableNeoHookean`]).
    pub law: Law,
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
    /// Cut detection (used only when the crate is built with the `detect` feature).
    pub detection: DetectionConfig<T>,
}

impl<T: Real> ModelConfig<T> {
    /// The same configuration in another scalar type (each value rounded to it): how a host
    /// that reads its scenes in `f64` runs a core built for `f32`.
    ///
    /// # Errors
    /// As [`Camera::cast`].
    pub fn cast<U: Real>(&self) -> Result<ModelConfig<U>, Error> {
        Ok(ModelConfig {
            material: Material {
                young: U::of(self.material.young.to_f64()),
                poisson: U::of(self.material.poisson.to_f64()),
                inversion_barrier: self.material.inversion_barrier,
                law: self.material.law,
            },
            camera: self.camera.cast()?,
            solver: self.solver.cast(),
            detection: self.detection.cast(),
        })
    }
}

/// Which matrix the factor in service is a factorization of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FactoredMatrix {
    /// None yet (before the features are embedded, or after they were embedded again).
    Nothing,
    /// The frozen matrix of [`Strategy::Frozen`] and [`Strategy::QuasiNewton`].
    Frozen,
    /// The Hessian of the last Newton step.
    Step,
}

/// What one [`Model::step`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport<T> {
    /// Frame number (0 for the first step).
    pub frame: u32,
    /// Features observed in this frame (less those the detection found unobservable: a
    /// virtual point that cannot be projected).
    pub observed: usize,
    /// Energies at the start of the step (new observations, previous positions).
    pub energy_before: Energies<T>,
    /// Energies at the end of the step.
    pub energy_after: Energies<T>,
    /// Norm of the gradient over the free unknowns at the start of the step, J/m (newtons).
    pub gradient_norm_before: T,
    /// Norm of the gradient at the end of the step, J/m (newtons).
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
pub(crate) struct SolveVectors<'a, T, F = T> {
    pub(crate) gradient: &'a mut [T],
    pub(crate) step: &'a mut [T],
    /// PCG residual, preconditioned residual, direction and `H·direction`.
    pub(crate) residual: &'a mut [T],
    pub(crate) preconditioned: &'a mut [T],
    pub(crate) direction: &'a mut [T],
    pub(crate) product: &'a mut [T],
    /// Work of the triangular solves, in the factor's scalar type (`2 ·` unknowns: the
    /// right-hand side rounded to it and the solves' scratch).
    pub(crate) solve_work: &'a mut [F],
    /// Positions tried by the line search.
    pub(crate) trial: &'a mut [[T; 3]],
    /// The springs' room, two entries per node: the camera rays through the nodes' previous
    /// positions, which every spring of an assembly reads (rebuilt by each assembly from the
    /// positions it starts from), then what the springs see of each node in the pass under
    /// way (filled once per pass instead of once per feature and element node).
    pub(crate) spring_nodes: &'a mut [[T; 3]],
    /// Packed blocks of the supernodal factorization ([`LdlFactor::SUPERNODAL_WORK_LEN`]).
    pub(crate) factor_work: &'a mut [F],
    /// Index workspace of the supernodal factorization
    /// ([`LdlFactor::supernodal_index_work_len`] of the unknowns).
    pub(crate) factor_indices: &'a mut [u32],
}

/// The organ model, computing in `T` and factorizing its linear systems in `F`.
///
/// `F` is `T` but for **mixed precision** (`Model<'a, f64, f32>`): the factor, its
/// factorization and its triangular solves in `f32` (half the factor's memory, on a
/// co-processor's single-precision unit), the energy, the residuals and the positions in
/// `f64`. Each Newton step's solve is then refined on the `f64` residual: the PCG iterations of
/// `Frozen` and `FactorOnce` do that already, and `Refactor` runs [`MIXED_REFINEMENT_STEPS`]
/// of them after its factorization.
pub struct Model<'a, T: Real, F: Real = T> {
    pub(crate) config: ModelConfig<T>,
    pub(crate) lame: Lame<T>,
    /// The inversion barrier of the material, if it asks for one.
    pub(crate) barrier: Option<InversionBarrier<T>>,
    /// The mesh and everything built on it, in service.
    pub(crate) live: Discretization<'a, T>,
    /// Room to build the next topology in (no meaning between cuts).
    #[cfg(feature = "cut")]
    pub(crate) spare: Discretization<'a, T>,
    pub(crate) hessian: &'a mut [T],
    pub(crate) factor: LdlFactor<'a, F>,
    /// Which matrix `factor` is a factorization of.
    pub(crate) factored: FactoredMatrix,
    /// The springs' `k`, J/px²: given, or derived from the scene when the features are
    /// embedded ([`crate::Coupling`]).
    pub(crate) spring_stiffness: T,
    /// Where the springs turn linear, pixels ([`SolverConfig::spring_threshold`] feature
    /// spacings, set when the features are embedded; `∞` before).
    pub(crate) spring_threshold_px: T,
    /// What the depth prior's weights are multiplied by: the springs' stiffness over the
    /// default coupling's, at least 1 ([`crate::solve::DEFAULT_DEPTH_PRIOR`]); set when the
    /// features are embedded, 1 before.
    pub(crate) depth_scale: T,
    pub(crate) vectors: SolveVectors<'a, T, F>,
    /// Workspace of rebuilds and cuts (no meaning between calls).
    #[cfg(feature = "cut")]
    pub(crate) work: &'a mut [u32],
    pub(crate) features: Features<'a, T>,
    /// What a failing call gives back (no meaning between calls).
    pub(crate) saved: Saved<'a, T>,
    #[cfg(feature = "detect")]
    cut: CutState<'a, T>,
    pub(crate) frame: u32,
    /// The secant pairs of [`Strategy::QuasiNewton`] (no storage without the `quasi-newton`
    /// feature).
    pub(crate) secant: SecantMemory<'a, T>,
    /// The elements' gradient share that [`Strategy::QuasiNewton`] with one line-search trial
    /// starts a frame from (no storage without the `quasi-newton` feature).
    pub(crate) kept: KeptElements<'a, T>,
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
    /// Cuts held: detected and grown, never applied to the mesh ([`Model::hold_cuts`]).
    #[cfg(feature = "cut")]
    held: bool,
}

impl<'a, T: Real, F: Real> Model<'a, T, F> {
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
        buffers: ModelBuffers<'a, T, F>,
    ) -> Result<Self, Error> {
        Self::build(config, size, buffers, |live, lame, solver, work| {
            live.load(input, lame, solver, work)
        })
    }

    /// As [`Model::new`], with the ordering and symbolic analysis of the uncut mesh taken from
    /// `analysis` (generated ahead of time by `incise codegen`, or
    /// [`Symbolic::precomputed`] of a model built from the same mesh) instead of computed: a
    /// firmware build that never cuts then links neither the fill-reducing ordering nor the
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
        buffers: ModelBuffers<'a, T, F>,
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
        buffers: ModelBuffers<'a, T, F>,
        load: impl FnOnce(
            &mut Discretization<'a, T>,
            &Lame<T>,
            &SolverConfig<T>,
            &mut [u32],
        ) -> Result<(), Error>,
    ) -> Result<Self, Error> {
        config.solver.validate()?;
        config.detection.validate()?;
        if !config.material.law.is_built() {
            return Err(Error::InvalidParameter {
                parameter: Parameter::Law,
            });
        }
        let lame = Lame::from_young_poisson(config.material.young, config.material.poisson)?;
        let ModelBuffers {
            reals,
            factor_reals,
            indices,
        } = buffers;
        ensure_len(reals, size.model_real_len(), Resource::RealStorage)?;
        ensure_len(factor_reals, size.factor_real_len(), Resource::RealStorage)?;
        ensure_len(indices, size.index_len(), Resource::IndexStorage)?;
        let caps = size.capacities();
        let mut scalar_slab = Slab::new(reals, Resource::RealStorage);
        let mut factor_slab = Slab::new(factor_reals, Resource::RealStorage);
        let mut index_slab = Slab::new(indices, Resource::IndexStorage);
        let mut live = Discretization::with_capacity(size, &mut scalar_slab, &mut index_slab)?;
        #[cfg(feature = "cut")]
        let spare = Discretization::with_capacity(size, &mut scalar_slab, &mut index_slab)?;
        let dofs = size.unknowns();
        let hessian = scalar_slab.take(size.nnz_a())?;
        let factor = LdlFactor::new(
            &size.symbolic_capacity(),
            factor_slab.take(LdlFactor::<F>::storage_len(&size.symbolic_capacity()))?,
        )?;
        let vectors = SolveVectors {
            gradient: scalar_slab.take(dofs)?,
            step: scalar_slab.take(dofs)?,
            residual: scalar_slab.take(dofs)?,
            preconditioned: scalar_slab.take(dofs)?,
            direction: scalar_slab.take(dofs)?,
            product: scalar_slab.take(dofs)?,
            solve_work: factor_slab.take(2 * dofs)?,
            trial: scalar_slab
                .take(3 * caps.mesh.nodes)?
                .as_chunks_mut::<3>()
                .0,
            spring_nodes: scalar_slab
                .take(6 * caps.mesh.nodes)?
                .as_chunks_mut::<3>()
                .0,
            factor_work: factor_slab.take(LdlFactor::<F>::SUPERNODAL_WORK_LEN)?,
            factor_indices: index_slab.take(LdlFactor::<F>::supernodal_index_work_len(dofs))?,
        };
        let secant = SecantMemory::new(size.secant_unknowns(), &mut scalar_slab)?;
        let kept = KeptElements::new(size.secant_unknowns(), &mut scalar_slab)?;
        let features = Features::new(caps.features, &mut scalar_slab, &mut index_slab)?;
        let saved = Saved {
            features: Features::new(caps.features, &mut scalar_slab, &mut index_slab)?,
            embedding: Embedding::with_capacity(caps.features, &mut scalar_slab, &mut index_slab)?,
            previous: scalar_slab
                .take(3 * caps.mesh.nodes)?
                .as_chunks_mut::<3>()
                .0,
        };
        #[cfg(feature = "detect")]
        let cut = CutState {
            detector: Detector::new(caps.features, caps.pairs, &mut scalar_slab, &mut index_slab)?,
            line: CutLine::new(caps.cut_vertices, &mut scalar_slab, &mut index_slab)?,
            residuals: scalar_slab.take(2 * caps.features)?.as_chunks_mut::<2>().0,
            pixels: scalar_slab
                .take(2 * caps.features.max(caps.cut_vertices))?
                .as_chunks_mut::<2>()
                .0,
            #[cfg(feature = "cut")]
            scratch: scalar_slab.take(cut::real_len(caps.mesh.nodes, caps.cut_vertices))?,
            #[cfg(feature = "cut")]
            held: false,
        };
        let work = index_slab.take(size.work_len())?;
        load(&mut live, &lame, &config.solver, work)?;
        Ok(Model {
            config: *config,
            lame,
            barrier: config
                .material
                .inversion_barrier
                .then(|| InversionBarrier::for_material(&lame)),
            live,
            #[cfg(feature = "cut")]
            spare,
            hessian,
            factor,
            factored: FactoredMatrix::Nothing,
            spring_stiffness: match config.solver.coupling {
                Coupling::Stiffness(k) => k,
                // Set when the features are embedded; no spring acts before.
                Coupling::Relative(_) => T::zero(),
            },
            spring_threshold_px: T::of(f64::INFINITY),
            depth_scale: T::one(),
            vectors,
            #[cfg(feature = "cut")]
            work,
            features,
            saved,
            #[cfg(feature = "detect")]
            cut,
            frame: 0,
            secant,
            kept,
        })
    }

    /// The springs' stiffness `k` in service, J/px²: the given one, or the one derived from the
    /// scene when the features were embedded ([`crate::Coupling::Relative`]; zero before).
    pub fn spring_stiffness(&self) -> T {
        self.spring_stiffness
    }

    /// The residual, pixels, beyond which the springs pull with a constant force (Huber's
    /// loss): [`SolverConfig::spring_threshold`] times the feature spacing measured when the
    /// features were embedded, divided by `k / k₀` for springs stiffer than the default
    /// coupling's `k₀`, so that their largest force stays the default's (`∞` before, or for
    /// quadratic springs).
    pub fn spring_threshold_px(&self) -> T {
        self.spring_threshold_px
    }

    /// The mesh in service.
    pub fn mesh(&self) -> &Mesh<'a, T> {
        &self.live.mesh
    }

    /// Current node positions, metres.
    pub fn positions(&self) -> &[[T; 3]] {
        self.live.positions()
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
    pub fn factor(&self) -> &LdlFactor<'a, F> {
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
        if solver.strategy != self.config.solver.strategy {
            // Secant pairs belong to the factor they corrected, which a new strategy replaces;
            // the elements' share was kept for the strategy that keeps it.
            self.secant.clear();
            self.kept.forget();
        }
        self.config.solver = solver;
        Ok(())
    }

    /// One registration step, its stages in order:
    /// 1. **observe**: take the frame's observations;
    /// 2. **solve**: a fixed number of Newton steps lowering `W_I + W_S + W_D + W_R`
    ///    ([`crate::solve`]);
    /// 3. **detect** (`detect` feature): residuals, the discontinuity detector;
    /// 4. **grow** (`detect` feature): the cut line follows its evidence and its fronts advance;
    /// 5. **cut** (`cut` feature): the mesh is cut along the line's separation surface
    ///    ([`Model::apply_cut`]).
    ///
    /// The steady work (stages 1–4) is fixed by the configuration and the scene's sizes:
    /// `newton_iterations + 1` assemblies, one factorization per Newton step (`Refactor`),
    /// `pcg_iterations` matrix–vector products and solves (`Frozen`), or one solve and no
    /// tangents (`QuasiNewton`), and
    /// `line_search_steps` energy evaluations per Newton step. A cut event is reported apart
    /// ([`StepReport::cut`]); a cut that cannot be made (a capacity, a factorization) is
    /// reported there and leaves the mesh as it was, without failing the frame.
    ///
    /// All or nothing: before the frame is taken, the features' observations (`5 ·` features
    /// entries), the damping reference (`3 ·` nodes) and, for `QuasiNewton`, its secant pairs
    /// are copied aside, and the factor keeps
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
        copy_front(self.saved.previous, live.previous, n_nodes);
        copy_front(live.previous, live.x, n_nodes);
        let factored = self.factored;
        self.factor.checkpoint();
        // Only the quasi-Newton strategy writes its secant pairs.
        let secant = self.config.solver.strategy == Strategy::QuasiNewton;
        let n = self.n_unknowns();
        let mut secant_copies = if secant { self.secant.checkpoint(n) } else { 0 };
        let keeps = self.keeps_elements();
        if keeps {
            secant_copies += self.kept.checkpoint(n);
        }
        let mut report = match self.solve_frame() {
            Ok(report) => {
                self.factor.commit();
                report
            }
            Err(e) => {
                let live = &mut self.live;
                copy_front(live.x, live.previous, n_nodes);
                copy_front(live.previous, self.saved.previous, n_nodes);
                self.features.copy_from(&self.saved.features);
                self.factored = factored;
                self.factor.rollback();
                if secant {
                    self.secant.rollback(n);
                }
                if keeps {
                    self.kept.rollback(n);
                }
                return Err(e);
            }
        };
        report.work.state_copies += (5 * self.features.len() + 3 * n_nodes) as u64 + secant_copies;
        report.frame = self.frame;
        report.observed = observed;
        #[cfg(feature = "detect")]
        if self.config.detection.enabled {
            let (detection, unobservable) = self.detect();
            report.detection = detection;
            report.observed = report.observed.saturating_sub(unobservable);
            report.cut_line = self.grow_cut_line();
            #[cfg(feature = "cut")]
            if !self.cut.held {
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

    /// The worst-case work of one [`Model::step`]'s steady part (every embedded feature is
    /// evaluated in every frame, observed or not):
    /// a formula of the scene's sizes and the configuration. Per frame: an assembly with
    /// tangents per Newton step, every line-search trial, and an assembly without tangents
    /// that closes the frame, but with one trial per Newton step, whose last trial is that
    /// assembly ([`SolverConfig::line_search_steps`](crate::SolverConfig::line_search_steps)).
    /// `QuasiNewton` with one trial assembles every trial and starts each step from the last
    /// one's, the frame's first from the elements' share the last frame ended with: its
    /// elements are evaluated once per trial, no more. (Once after a switch to it from
    /// `Frozen` and after [`Model::set_positions`], no share is kept and the frame's first
    /// assembly evaluates the elements too, as a switch's first frame factors the frozen
    /// matrix: one-off costs beyond this formula.)
    pub fn worst_case_work(&self) -> WorkCount {
        let s = &self.config.solver;
        let newton = s.newton_iterations;
        let tets = self.live.mesh.n_tets() as u64;
        let feats = self.features.len() as u64;
        let nnz = self.live.nnz_a as u64;
        let sym = &self.live.symbolic;
        // The assembly that closes a frame, but where the last Newton step's single line-search
        // trial is evaluated by an assembly and gives the closing gradient with it.
        let closing = u64::from(!(s.line_search_steps == 1 && newton > 0));
        // The Newton steps' assemblies: with tangents, or, for `QuasiNewton`, without; with
        // one trial, only the first step's (each later one starts from the assembled trial of
        // the step before), and that one reuses the elements' share the last frame ended with
        // ([`KeptElements`]): its springs and priors alone.
        let (with_tangents, without) = if s.strategy.assembles_hessian() {
            (u64::from(newton), 0)
        } else if s.line_search_steps == 1 {
            (0, u64::from(newton.min(1)))
        } else {
            (0, u64::from(newton))
        };
        let element_passes = if self.keeps_elements() { 0 } else { without };
        let trials = u64::from(newton * s.line_search_steps);
        let mut w = WorkCount {
            assemblies: newton + 1,
            element_tangents: with_tangents * tets,
            element_evaluations: tets * (closing + element_passes + trials),
            feature_evaluations: feats * (closing + with_tangents + without + trials),
            energy_evaluations: newton * s.line_search_steps,
            state_copies: 5 * feats + 3 * self.live.mesh.n_nodes() as u64,
            ..WorkCount::default()
        };
        // Mixed precision refines each solve that follows a factorization.
        let refine = if Self::mixed() {
            MIXED_REFINEMENT_STEPS
        } else {
            0
        };
        match s.strategy {
            Strategy::Refactor => {
                w.factorizations = newton;
                w.factor_flops = u64::from(newton) * sym.factor_flops();
                w.solves = newton * (1 + refine);
                w.solve_flops = u64::from(w.solves) * sym.solve_flops();
                w.matvecs = newton * refine;
                w.matvec_flops = u64::from(w.matvecs) * 2 * nnz;
            }
            Strategy::Frozen { pcg_iterations } => {
                w.solves = newton * (pcg_iterations + 1);
                w.solve_flops = u64::from(w.solves) * sym.solve_flops();
                w.matvecs = newton * pcg_iterations;
                w.matvec_flops = u64::from(w.matvecs) * 2 * nnz;
            }
            Strategy::QuasiNewton => {
                let unknowns = self.n_unknowns();
                w.solves = newton;
                w.solve_flops = u64::from(w.solves) * sym.solve_flops();
                // Each step's recursion, and a pair stored after each step.
                w.secant_flops = u64::from(newton)
                    * (SecantMemory::<T>::step_flops(unknowns)
                        + SecantMemory::<T>::pair_flops(unknowns));
                w.state_copies += SecantMemory::<T>::copies(unknowns);
                if self.keeps_elements() {
                    // The kept share's checkpoint, and each step's trial share taken.
                    w.state_copies +=
                        KeptElements::<T>::copies(unknowns) + u64::from(newton) * unknowns as u64;
                }
            }
            Strategy::FactorOnce { pcg_iterations } => {
                let later = newton.saturating_sub(1);
                w.factorizations = 1;
                w.factor_flops = sym.factor_flops();
                w.solves = 1 + refine + later * (pcg_iterations + 1);
                w.solve_flops = u64::from(w.solves) * sym.solve_flops();
                w.matvecs = refine + later * pcg_iterations;
                w.matvec_flops = u64::from(w.matvecs) * 2 * nnz;
            }
        }
        w
    }
}
