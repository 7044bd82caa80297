//! The model: mesh, material, camera, virtual features and the fixed-budget solver, built once
//! in caller storage and stepped frame by frame.
//!
//! ```text
//! ModelSize::analyse(mesh, capacities, work)   sizes (pattern, factor) for this mesh
//! Model::new(mesh, config, size, reals, indices, work)
//! model.embed_features(frame_0)                 virtual features on the surface
//! loop { model.step(frame) }                    one registration step per frame
//! ```

use nalgebra::Vector3;

use crate::camera::Camera;
#[cfg(feature = "cut")]
use crate::cutline::{CutLine, CutLineReport};
use crate::detect::DetectionConfig;
#[cfg(feature = "cut")]
use crate::detect::{DetectionReport, Detector};
use crate::error::{Error, Resource};
use crate::features::{EmbedReport, Features, Observation};
use crate::material::{Lame, TangentProjection, element_energy_gradient_tangent};
use crate::mesh::{Mesh, MeshCapacity, MeshInput};
use crate::real::Real;
use crate::solve::{Energies, Problem, SolverConfig, Strategy, WorkCount, build_scatter, dot};
use crate::sparse::{
    Graph, LdlFactor, NONE, Symbolic, SymbolicSize, UpperCsc, analyse_work_len, block_upper_len,
    block_upper_pattern, expand_block_permutation, minimum_degree, minimum_degree_work_len,
    sym_matvec, tet_graph_work_len,
};
use crate::storage::{Slab, ensure_len};

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

/// Capacities fixed at construction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Capacities {
    /// Mesh capacities.
    pub mesh: MeshCapacity,
    /// Tracked features.
    pub features: usize,
    /// Extra room, in percent, for the matrix and factor entries beyond what the initial mesh
    /// needs (a cut adds nodes and fill).
    pub factor_headroom_percent: usize,
    /// Neighbour pairs of the cut detection (`cut` feature; the paper's liver had 18 503).
    pub pairs: usize,
    /// Vertices of the cut line (`cut` feature).
    pub cut_vertices: usize,
}

/// The storage sizes of a model, from [`ModelSize::analyse`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ModelSize {
    /// The capacities.
    pub capacities: Capacities,
    /// Capacity of stored entries of the stiffness matrix (upper triangle).
    pub nnz_a: usize,
    /// Capacity of entries of the factor `L` (strictly lower).
    pub nnz_l: usize,
    /// Entries the initial mesh needs: matrix.
    pub nnz_a_initial: usize,
    /// Entries the initial mesh needs: factor.
    pub nnz_l_initial: usize,
}

impl ModelSize {
    /// Length of the `u32` workspace that [`ModelSize::analyse`] and [`Model::new`] need.
    pub const fn work_len(capacity: &MeshCapacity, features: usize) -> usize {
        let (n, t) = (capacity.nodes, capacity.tets);
        // A tetrahedron joins 6 node pairs, so the node graph has at most 12 t entries and
        // the block pattern at most 6 n + 54 t.
        let graph = 12 * t;
        let nnz_a = 6 * n + 54 * t;
        let topo = (n + 1) + graph + n + 3 * n + (3 * n + 1) + nnz_a;
        let a = tet_graph_work_len(n, t);
        let b = minimum_degree_work_len(n, graph);
        let c = analyse_work_len(3 * n, nnz_a);
        let d = capacity.work_len();
        let mut m = if a > b { a } else { b };
        if c > m {
            m = c;
        }
        if d > m {
            m = d;
        }
        if features > m {
            m = features;
        }
        topo + m
    }

    /// Analyses `mesh` (node graph of the free nodes, minimum-degree ordering, symbolic
    /// factorization) to size the storage of a model with `capacities`.
    ///
    /// # Errors
    /// As [`Mesh::new`] for a bad mesh, [`Error::Capacity`] for a short `work`.
    pub fn analyse<T: Real>(
        mesh: &MeshInput<'_, T>,
        capacities: &Capacities,
        work: &mut [u32],
    ) -> Result<Self, Error> {
        let cap = &capacities.mesh;
        ensure_len(
            work,
            Self::work_len(cap, capacities.features),
            Resource::Workspace,
        )?;
        if mesh.rest.len() > cap.nodes || mesh.tets.len() > cap.tets {
            return Err(Error::Capacity {
                resource: Resource::Nodes,
                needed: mesh.rest.len(),
                available: cap.nodes,
            });
        }
        let mut slab = Slab::new(work, Resource::Workspace);
        let free = slab.take(mesh.rest.len())?;
        free.fill(0);
        for (position, &f) in mesh.fixed.iter().enumerate() {
            let slot = free.get_mut(f as usize).ok_or(Error::IndexOutOfRange {
                resource: Resource::Nodes,
                position,
                index: f as usize,
                bound: mesh.rest.len(),
            })?;
            *slot = NONE;
        }
        let mut next = 0u32;
        for f in free.iter_mut() {
            if *f != NONE {
                *f = next;
                next += 1;
            }
        }
        let topo = Topology::build(mesh.tets, free, next as usize, &mut slab)?;
        let (nnz_a, nnz_l) = (topo.nnz_a, topo.size.nnz_l);
        let grow = |x: usize| x + x * capacities.factor_headroom_percent / 100;
        Ok(ModelSize {
            capacities: *capacities,
            nnz_a: grow(nnz_a),
            nnz_l: grow(nnz_l),
            nnz_a_initial: nnz_a,
            nnz_l_initial: nnz_l,
        })
    }

    fn dofs(&self) -> usize {
        3 * self.capacities.mesh.nodes
    }

    fn symbolic_size(&self) -> SymbolicSize {
        SymbolicSize {
            n: self.dofs(),
            nnz_a: self.nnz_a,
            nnz_l: self.nnz_l,
        }
    }

    /// Scalars of storage [`Model::new`] needs (independent of the scalar type).
    pub fn real_len(&self) -> usize {
        let n = self.capacities.mesh.nodes;
        let dofs = self.dofs();
        self.capacities.mesh.real_len()
            + 9 * n // positions, previous positions, trial positions
            + n // damping weights
            + self.nnz_a // Hessian values
            + LdlFactor::<f64>::storage_len(&self.symbolic_size())
            + 7 * dofs // gradient, step and the PCG vectors, solve work
            + Features::<f64>::real_len(self.capacities.features)
            + self.detection_real_len()
    }

    #[cfg(feature = "cut")]
    fn detection_real_len(&self) -> usize {
        let c = &self.capacities;
        Detector::<f64>::real_len(c.features, c.pairs)
            + CutLine::<f64>::real_len(c.cut_vertices)
            + 2 * c.features // residuals
            + 2 * c.features.max(c.cut_vertices) // projections
    }

    #[cfg(not(feature = "cut"))]
    fn detection_real_len(&self) -> usize {
        0
    }

    #[cfg(feature = "cut")]
    fn detection_index_len(&self) -> usize {
        let c = &self.capacities;
        Detector::<f64>::index_len(c.features, c.pairs) + CutLine::<f64>::index_len(c.cut_vertices)
    }

    #[cfg(not(feature = "cut"))]
    fn detection_index_len(&self) -> usize {
        0
    }

    /// Indices of storage [`Model::new`] needs.
    pub fn index_len(&self) -> usize {
        let dofs = self.dofs();
        self.capacities.mesh.index_len()
            + 30 * self.capacities.mesh.tets // scatter map
            + (dofs + 1)
            + self.nnz_a // stiffness pattern
            + self.symbolic_size().index_len()
            + dofs // factorization cursor
            + Features::<f64>::index_len(self.capacities.features)
            + self.detection_index_len()
    }
}

/// The node graph, ordering and block pattern of a mesh, built in a workspace slab.
struct Topology<'w> {
    col_ptr: &'w mut [u32],
    row_idx: &'w mut [u32],
    perm: &'w mut [u32],
    /// What is left of the workspace, for the symbolic factorization.
    scratch: &'w mut [u32],
    nnz_a: usize,
    size: SymbolicSize,
}

impl<'w> Topology<'w> {
    fn build(
        tets: &[[u32; 4]],
        free: &[u32],
        n_free: usize,
        slab: &mut Slab<'w, u32>,
    ) -> Result<Self, Error> {
        let g_ptr = slab.take(n_free + 1)?;
        let g_adj = slab.take(12 * tets.len())?;
        let node_perm = slab.take(n_free)?;
        let perm = slab.take(3 * n_free)?;
        let col_ptr = slab.take(3 * n_free + 1)?;
        let row_idx = slab.take(6 * n_free + 54 * tets.len())?;
        // The rest of the slab is scratch for each phase in turn.
        let tail = slab.take(slab.remaining())?;
        let graph = Graph::from_tets(tets, free, g_ptr, g_adj, tail)?;
        minimum_degree(&graph, node_perm, tail)?;
        expand_block_permutation(node_perm, 3, perm)?;
        let nnz_a = block_upper_len(&graph, 3);
        let a = block_upper_pattern(&graph, 3, col_ptr, row_idx)?;
        let size = Symbolic::size(&a, perm, tail)?;
        Ok(Topology {
            col_ptr,
            row_idx,
            perm,
            scratch: tail,
            nnz_a,
            size,
        })
    }
}

/// Which matrix the factor in service holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FactorHolds {
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
    /// Work done, per stage.
    pub work: WorkCount,
    /// What the cut detection saw (zeros when it is switched off).
    #[cfg(feature = "cut")]
    pub detection: DetectionReport<T>,
    /// The cut line.
    #[cfg(feature = "cut")]
    pub cut_line: CutLineReport,
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

/// The organ model.
pub struct Model<'a, T: Real> {
    config: ModelConfig<T>,
    lame: Lame<T>,
    mesh: Mesh<'a, T>,
    x: &'a mut [[T; 3]],
    anchor: &'a mut [[T; 3]],
    trial: &'a mut [[T; 3]],
    damping: &'a mut [T],
    scatter: &'a mut [[u32; 30]],
    col_ptr: &'a [u32],
    row_idx: &'a [u32],
    symbolic: Symbolic<'a>,
    hessian: &'a mut [T],
    factor: LdlFactor<'a, T>,
    holds: FactorHolds,
    grad: &'a mut [T],
    step: &'a mut [T],
    r: &'a mut [T],
    z: &'a mut [T],
    p: &'a mut [T],
    q: &'a mut [T],
    y: &'a mut [T],
    cursor: &'a mut [u32],
    features: Features<'a, T>,
    #[cfg(feature = "cut")]
    cut: CutState<'a, T>,
    frame: u32,
}

/// The detector, the cut line and their scratch.
#[cfg(feature = "cut")]
struct CutState<'a, T> {
    detector: Detector<'a, T>,
    line: CutLine<'a, T>,
    /// Residual `d_i` per feature slot.
    residuals: &'a mut [[T; 2]],
    /// Projections of the virtual features, or of the cut line's vertices.
    projections: &'a mut [[T; 2]],
}

impl<'a, T: Real> Model<'a, T> {
    /// Builds the model in caller storage: `reals` ([`ModelSize::real_len`] scalars) and
    /// `indices` ([`ModelSize::index_len`]); `work` ([`ModelSize::work_len`]) is scratch with
    /// no meaning on return. The model starts at rest with no features.
    ///
    /// # Errors
    /// As [`Mesh::new`]; [`Error::InvalidParameter`] for a bad material or solver setting;
    /// [`Error::Capacity`] when storage or a capacity of `size` is too small.
    pub fn new(
        input: &MeshInput<'_, T>,
        config: &ModelConfig<T>,
        size: &ModelSize,
        reals: &'a mut [T],
        indices: &'a mut [u32],
        work: &mut [u32],
    ) -> Result<Self, Error> {
        config.solver.validate()?;
        config.detection.validate()?;
        let lame = Lame::from_young_poisson(config.material.young, config.material.poisson)?;
        let caps = &size.capacities;
        ensure_len(reals, size.real_len(), Resource::RealStorage)?;
        ensure_len(indices, size.index_len(), Resource::IndexStorage)?;
        ensure_len(
            work,
            ModelSize::work_len(&caps.mesh, caps.features),
            Resource::Workspace,
        )?;
        let mut rs = Slab::new(reals, Resource::RealStorage);
        let mut is = Slab::new(indices, Resource::IndexStorage);
        let mesh = Mesh::new(input, &caps.mesh, &mut rs, &mut is, work)?;

        let n_nodes = caps.mesh.nodes;
        let dofs = 3 * n_nodes;
        let x = rs.take(3 * n_nodes)?.as_chunks_mut::<3>().0;
        let anchor = rs.take(3 * n_nodes)?.as_chunks_mut::<3>().0;
        let trial = rs.take(3 * n_nodes)?.as_chunks_mut::<3>().0;
        let damping = rs.take(n_nodes)?;
        let hessian = rs.take(size.nnz_a)?;
        let factor_store = rs.take(LdlFactor::<T>::storage_len(&size.symbolic_size()))?;
        let grad = rs.take(dofs)?;
        let step = rs.take(dofs)?;
        let r = rs.take(dofs)?;
        let z = rs.take(dofs)?;
        let p = rs.take(dofs)?;
        let q = rs.take(dofs)?;
        let y = rs.take(dofs)?;
        let scatter = is.take(30 * caps.mesh.tets)?.as_chunks_mut::<30>().0;
        let col_ptr = is.take(dofs + 1)?;
        let row_idx = is.take(size.nnz_a)?;
        let sym_store = is.take(size.symbolic_size().index_len())?;
        let cursor = is.take(dofs)?;
        let features = Features::new(caps.features, &mut rs, &mut is)?;
        #[cfg(feature = "cut")]
        let cut = CutState {
            detector: Detector::new(caps.features, caps.pairs, &mut rs, &mut is)?,
            line: CutLine::new(caps.cut_vertices, &mut rs, &mut is)?,
            residuals: rs.take(2 * caps.features)?.as_chunks_mut::<2>().0,
            projections: rs
                .take(2 * caps.features.max(caps.cut_vertices))?
                .as_chunks_mut::<2>()
                .0,
        };

        // Pattern, ordering and symbolic factorization of the free nodes.
        let n_free = mesh.n_free();
        let mut ws = Slab::new(work, Resource::Workspace);
        let topo = Topology::build(mesh.tets(), mesh.free_index(), n_free, &mut ws)?;
        if topo.nnz_a > size.nnz_a || topo.size.nnz_l > size.nnz_l {
            return Err(Error::Capacity {
                resource: Resource::FactorEntries,
                needed: topo.size.nnz_l,
                available: size.nnz_l,
            });
        }
        let n = 3 * n_free;
        col_ptr[..n + 1].copy_from_slice(&topo.col_ptr[..n + 1]);
        row_idx[..topo.nnz_a].copy_from_slice(&topo.row_idx[..topo.nnz_a]);
        let col_ptr: &'a [u32] = &col_ptr[..n + 1];
        let row_idx: &'a [u32] = &row_idx[..topo.nnz_a];
        let a = UpperCsc::new(n, col_ptr, row_idx)?;
        let symbolic = Symbolic::new(&a, topo.perm, sym_store, topo.scratch)?;
        let factor = LdlFactor::new(&symbolic.size_info(), factor_store)?;
        build_scatter(&mesh, &a, scatter)?;

        // Start at rest; damping weights from the rest stiffness.
        x[..mesh.n_nodes()].copy_from_slice(mesh.rest());
        anchor[..mesh.n_nodes()].copy_from_slice(mesh.rest());
        damping.fill(T::zero());
        for (t, tet) in mesh.tets().iter().enumerate() {
            let rest = mesh.element_rest(t).ok_or(Error::SymbolicMismatch)?;
            let g = rest.shape_gradients();
            let at_rest = [[T::zero(); 3]; 4];
            let eval = element_energy_gradient_tangent(
                &lame,
                &rest,
                &g,
                &at_rest,
                TangentProjection::Exact,
            );
            for (l, &v) in tet.iter().enumerate() {
                damping[v as usize] += eval.tangent[l][l].trace() / T::of(3.0);
            }
        }
        for c in damping.iter_mut() {
            *c *= config.solver.damping;
        }

        Ok(Model {
            config: *config,
            lame,
            mesh,
            x,
            anchor,
            trial,
            damping,
            scatter,
            col_ptr,
            row_idx,
            symbolic,
            hessian,
            factor,
            holds: FactorHolds::Nothing,
            grad,
            step,
            r,
            z,
            p,
            q,
            y,
            cursor,
            features,
            #[cfg(feature = "cut")]
            cut,
            frame: 0,
        })
    }

    /// The mesh.
    pub fn mesh(&self) -> &Mesh<'a, T> {
        &self.mesh
    }

    /// Current node positions, metres.
    pub fn positions(&self) -> &[[T; 3]] {
        &self.x[..self.mesh.n_nodes()]
    }

    /// The virtual features.
    pub fn features(&self) -> &Features<'a, T> {
        &self.features
    }

    /// The configuration.
    pub fn config(&self) -> &ModelConfig<T> {
        &self.config
    }

    /// The symbolic factorization of the stiffness pattern (sizes, flop counts).
    pub fn symbolic(&self) -> &Symbolic<'a> {
        &self.symbolic
    }

    /// Number of unknowns (three per free node).
    pub fn n_unknowns(&self) -> usize {
        3 * self.mesh.n_free()
    }

    /// Current pixel of the virtual feature in `slot`.
    ///
    /// # Errors
    /// [`Error::UnknownFeature`] for a bad slot; [`Error::BehindCamera`].
    pub fn projected_feature(&self, slot: usize) -> Result<[T; 2], Error> {
        let p = self
            .features
            .position(slot, &self.mesh, self.positions())
            .ok_or(Error::UnknownFeature { id: slot as u32 })?;
        let uv = self.config.camera.project(&p, slot)?;
        Ok([uv.x, uv.y])
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
    /// replacing any held before, and prepares the frozen factor when that strategy is
    /// configured.
    ///
    /// # Errors
    /// As [`Features::embed`]; [`Error::NoFeatures`] if no ray hits the model. On error the
    /// model is as before.
    pub fn embed_features(&mut self, frame0: &[Observation<T>]) -> Result<EmbedReport, Error> {
        let margin = self.config.solver.image_margin;
        let n = self.mesh.n_nodes();
        let report = self.features.embed(
            &self.mesh,
            &self.x[..n],
            &self.config.camera,
            frame0,
            margin,
        )?;
        if report.embedded == 0 {
            return Err(Error::NoFeatures);
        }
        self.holds = FactorHolds::Nothing;
        #[cfg(feature = "cut")]
        {
            self.frame = 0;
            self.cut.line.reset();
            let n = self.features.len();
            for slot in 0..n {
                let uv = self.projected_feature(slot)?;
                let t = self.features.targets()[slot];
                self.cut.projections[slot] = uv;
                self.cut.residuals[slot] = [t[0] - uv[0], t[1] - uv[1]];
            }
            let init = self.cut.detector.init(
                &self.cut.projections[..n],
                &self.cut.residuals[..n],
                &self.config.detection,
            );
            if let Err(e) = init {
                // The features are placed but cannot be watched for a cut: refuse them all, so
                // the caller sees a model as it was before any embedding.
                self.features.clear();
                return Err(e);
            }
        }
        // The frozen factor is part of setting up, not of the first frame, so that every frame
        // costs the same.
        if let Strategy::Frozen { .. } = self.config.solver.strategy {
            self.prepare_frozen(&mut WorkCount::default())?;
        }
        Ok(report)
    }

    fn problem(&self) -> Problem<'_, 'a, T> {
        Problem {
            mesh: &self.mesh,
            lame: self.lame,
            camera: &self.config.camera,
            features: &self.features,
            spring_stiffness: self.config.solver.spring_stiffness,
            damping: &self.damping[..self.mesh.n_nodes()],
            anchor: &self.anchor[..self.mesh.n_nodes()],
            scatter: &self.scatter[..self.mesh.n_tets()],
            col_ptr: self.col_ptr,
        }
    }

    /// One registration step: takes the observations of a frame and moves the free nodes to
    /// lower `W_I + W_S + W_D` with a fixed number of Newton steps.
    ///
    /// The work is fixed by the configuration and the scene's sizes: `newton_iterations + 1`
    /// assemblies, one factorization per Newton step (`Refactor`) or `pcg_iterations`
    /// matrix–vector products and solves (`Frozen`), and `line_search_steps` energy
    /// evaluations per Newton step.
    ///
    /// # Errors
    /// As [`Features::set_frame`] for a bad frame; [`Error::NoFeatures`] before
    /// [`Model::embed_features`]; [`Error::NotPositiveDefinite`] / [`Error::Diverged`] /
    /// [`Error::BehindCamera`] if the solve breaks down. On any error the positions and
    /// targets are those from before the call.
    pub fn step(&mut self, frame: &[Observation<T>]) -> Result<StepReport<T>, Error> {
        if self.features.is_empty() {
            return Err(Error::NoFeatures);
        }
        let margin = self.config.solver.image_margin;
        let observed = self
            .features
            .set_frame(&self.config.camera, frame, margin)?;
        let n_nodes = self.mesh.n_nodes();
        self.anchor[..n_nodes].copy_from_slice(&self.x[..n_nodes]);
        match self.solve_frame() {
            Ok(mut report) => {
                report.frame = self.frame;
                report.observed = observed;
                #[cfg(feature = "cut")]
                if self.config.detection.enabled {
                    let (detection, line) = self.detect();
                    report.detection = detection;
                    report.cut_line = line;
                }
                self.frame = self.frame.wrapping_add(1);
                Ok(report)
            }
            Err(e) => {
                self.x[..n_nodes].copy_from_slice(&self.anchor[..n_nodes]);
                Err(e)
            }
        }
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

    fn solve_frame(&mut self) -> Result<StepReport<T>, Error> {
        let n = self.n_unknowns();
        let n_nodes = self.mesh.n_nodes();
        let mut work = WorkCount::default();
        let newton = self.config.solver.newton_iterations;
        let trials = self.config.solver.line_search_steps;

        if let Strategy::Frozen { .. } = self.config.solver.strategy
            && self.holds != FactorHolds::Frozen
        {
            // Only after a switch of strategy: a one-off cost, counted in this frame's work.
            self.prepare_frozen(&mut work)?;
        }

        let mut energy_before = Energies::default();
        let mut gradient_norm_before = T::zero();
        let mut min_step = T::one();
        for it in 0..newton {
            let e = self.assemble(true, &mut work)?;
            if it == 0 {
                energy_before = e;
                gradient_norm_before = dot(&self.grad[..n], &self.grad[..n]).sqrt();
            }
            match self.config.solver.strategy {
                Strategy::Refactor => {
                    self.factorize(&mut work)?;
                    self.holds = FactorHolds::Step;
                    for (s, &g) in self.step[..n].iter_mut().zip(&self.grad[..n]) {
                        *s = -g;
                    }
                    self.factor.solve_in_place(
                        &self.symbolic,
                        &mut self.step[..n],
                        &mut self.y[..n],
                    )?;
                    work.solves += 1;
                    work.solve_flops += self.symbolic.solve_flops();
                }
                Strategy::Frozen { pcg_iterations } => {
                    self.pcg(pcg_iterations, &mut work)?;
                }
            }
            let slope = dot(&self.grad[..n], &self.step[..n]);
            let alpha = self.line_search(&e, slope, trials, &mut work)?;
            min_step = min_step.min(alpha);
            if alpha > T::zero() {
                self.move_along(alpha, n_nodes);
            }
        }
        let energy_after = self.assemble(false, &mut work)?;
        let gradient_norm_after = dot(&self.grad[..n], &self.grad[..n]).sqrt();
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
            #[cfg(feature = "cut")]
            detection: DetectionReport::default(),
            #[cfg(feature = "cut")]
            cut_line: CutLineReport::default(),
        })
    }

    /// Assembles the gradient (and, if asked, the Hessian) at the current positions.
    fn assemble(&mut self, with_hessian: bool, work: &mut WorkCount) -> Result<Energies<T>, Error> {
        let n = self.n_unknowns();
        let n_nodes = self.mesh.n_nodes();
        let nnz = self.row_idx.len();
        let Model {
            mesh,
            lame,
            config,
            features,
            damping,
            anchor,
            scatter,
            col_ptr,
            x,
            grad,
            hessian,
            ..
        } = self;
        let problem = Problem {
            mesh,
            lame: *lame,
            camera: &config.camera,
            features,
            spring_stiffness: config.solver.spring_stiffness,
            damping: &damping[..n_nodes],
            anchor: &anchor[..n_nodes],
            scatter: &scatter[..mesh.n_tets()],
            col_ptr,
        };
        let h = if with_hessian {
            Some(&mut hessian[..nnz])
        } else {
            None
        };
        problem.assemble(&x[..n_nodes], &mut grad[..n], h, work)
    }

    /// Factors the frozen matrix: the positive definite Hessian at the current state.
    fn prepare_frozen(&mut self, work: &mut WorkCount) -> Result<(), Error> {
        self.assemble(true, work)?;
        self.factorize(work)?;
        self.holds = FactorHolds::Frozen;
        Ok(())
    }

    fn factorize(&mut self, work: &mut WorkCount) -> Result<(), Error> {
        let n = self.n_unknowns();
        let nnz = self.row_idx.len();
        self.factor.factorize(
            &self.symbolic,
            &self.hessian[..nnz],
            &mut self.y[..n],
            &mut self.cursor[..n],
        )?;
        work.factorizations += 1;
        work.factor_flops += self.symbolic.factor_flops();
        Ok(())
    }

    /// Preconditioned conjugate gradients on `H step = −grad` with the frozen factor, a fixed
    /// number of iterations (fewer only if the residual vanishes exactly).
    fn pcg(&mut self, iterations: u32, work: &mut WorkCount) -> Result<(), Error> {
        let n = self.n_unknowns();
        let nnz = self.row_idx.len();
        let a = UpperCsc::new(n, self.col_ptr, self.row_idx)?;
        let (step, r, z, p, q) = (
            &mut self.step[..n],
            &mut self.r[..n],
            &mut self.z[..n],
            &mut self.p[..n],
            &mut self.q[..n],
        );
        step.fill(T::zero());
        for (ri, &g) in r.iter_mut().zip(&self.grad[..n]) {
            *ri = -g;
        }
        z.copy_from_slice(r);
        self.factor
            .solve_in_place(&self.symbolic, z, &mut self.y[..n])?;
        work.solves += 1;
        work.solve_flops += self.symbolic.solve_flops();
        p.copy_from_slice(z);
        let mut rz = dot(r, z);
        for _ in 0..iterations {
            sym_matvec(&a, &self.hessian[..nnz], p, q)?;
            work.matvecs += 1;
            work.matvec_flops += 2 * nnz as u64;
            let pq = dot(p, q);
            if !(pq > T::zero() && rz > T::zero()) {
                break;
            }
            let alpha = rz / pq;
            for i in 0..n {
                step[i] += alpha * p[i];
                r[i] -= alpha * q[i];
            }
            z.copy_from_slice(r);
            self.factor
                .solve_in_place(&self.symbolic, z, &mut self.y[..n])?;
            work.solves += 1;
            work.solve_flops += self.symbolic.solve_flops();
            let rz_new = dot(r, z);
            let beta = rz_new / rz;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
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
    fn line_search(
        &mut self,
        at: &Energies<T>,
        slope: T,
        trials: u32,
        work: &mut WorkCount,
    ) -> Result<T, Error> {
        let n_nodes = self.mesh.n_nodes();
        let energy = at.total();
        let slack = T::of(2.0) * at.rounding;
        let mut alpha = T::one();
        let mut chosen: Option<T> = None;
        let mut best = (energy, T::zero());
        for _ in 0..trials {
            self.fill_trial(alpha, n_nodes);
            let e = match self.problem().energy(&self.trial[..n_nodes], work) {
                Ok(e) => e.total(),
                Err(Error::BehindCamera { .. }) => T::zero() / T::zero(),
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
        Ok(chosen.unwrap_or(best.1))
    }

    fn fill_trial(&mut self, alpha: T, n_nodes: usize) {
        let free = self.mesh.free_index();
        for v in 0..n_nodes {
            let f = free[v];
            self.trial[v] = self.x[v];
            if f != NONE {
                let b = 3 * f as usize;
                for c in 0..3 {
                    self.trial[v][c] += alpha * self.step[b + c];
                }
            }
        }
    }

    fn move_along(&mut self, alpha: T, n_nodes: usize) {
        self.fill_trial(alpha, n_nodes);
        self.x[..n_nodes].copy_from_slice(&self.trial[..n_nodes]);
    }

    /// The worst-case work of one [`Model::step`] with every feature observed: a formula of
    /// the scene's sizes and the configuration.
    pub fn worst_case_work(&self) -> WorkCount {
        let s = &self.config.solver;
        let newton = s.newton_iterations;
        let tets = self.mesh.n_tets() as u64;
        let feats = self.features.len() as u64;
        let nnz = self.row_idx.len() as u64;
        let mut w = WorkCount {
            assemblies: newton + 1,
            element_tangents: u64::from(newton) * tets,
            element_evaluations: tets * (1 + u64::from(newton * s.line_search_steps)),
            feature_evaluations: feats
                * (1 + u64::from(newton) * (1 + u64::from(s.line_search_steps))),
            energy_evaluations: newton * s.line_search_steps,
            ..WorkCount::default()
        };
        match s.strategy {
            Strategy::Refactor => {
                w.factorizations = newton;
                w.factor_flops = u64::from(newton) * self.symbolic.factor_flops();
                w.solves = newton;
                w.solve_flops = u64::from(newton) * self.symbolic.solve_flops();
            }
            Strategy::Frozen { pcg_iterations } => {
                w.solves = newton * (pcg_iterations + 1);
                w.solve_flops = u64::from(w.solves) * self.symbolic.solve_flops();
                w.matvecs = newton * pcg_iterations;
                w.matvec_flops = u64::from(w.matvecs) * 2 * nnz;
            }
        }
        w
    }

    /// The energies at the current positions (observations of the last frame, damping toward
    /// the previous frame's positions).
    ///
    /// # Errors
    /// [`Error::BehindCamera`] if a virtual feature cannot be projected.
    pub fn energy(&self) -> Result<Energies<T>, Error> {
        let n = self.mesh.n_nodes();
        self.problem()
            .energy(&self.x[..n], &mut WorkCount::default())
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
        let nnz = self.row_idx.len();
        Ok(Linearization {
            energies,
            gradient: &self.grad[..n],
            hessian: &self.hessian[..nnz],
            pattern: UpperCsc::new(n, self.col_ptr, self.row_idx)?,
        })
    }

    /// Moves the free nodes to `x` (one position per node; the entries of fixed nodes are
    /// ignored, they stay at rest). The damping anchor moves with them.
    ///
    /// # Errors
    /// [`Error::Length`] if `x` does not have one entry per node, [`Error::NonFiniteInput`]
    /// for a non-finite coordinate; nothing changes then.
    pub fn set_positions(&mut self, x: &[[T; 3]]) -> Result<(), Error> {
        let n = self.mesh.n_nodes();
        crate::storage::ensure_exact_len(x, n, Resource::Nodes)?;
        if let Some(position) = x.iter().position(|p| !p.iter().all(|c| c.finite())) {
            return Err(Error::NonFiniteInput {
                resource: Resource::Nodes,
                position,
            });
        }
        let free = self.mesh.free_index();
        for v in 0..n {
            if free[v] != NONE {
                self.x[v] = x[v];
            }
        }
        self.anchor[..n].copy_from_slice(&self.x[..n]);
        Ok(())
    }

    /// Residuals of the frame, the detector, then the cut line (after the frame's solve).
    #[cfg(feature = "cut")]
    fn detect(&mut self) -> (DetectionReport<T>, CutLineReport) {
        let n = self.features.len();
        for slot in 0..n {
            let t = self.features.targets()[slot];
            // A feature whose virtual point cannot be projected is treated as unobserved.
            self.cut.residuals[slot] = match self.projected_feature(slot) {
                Ok(uv) => [t[0] - uv[0], t[1] - uv[1]],
                Err(_) => [T::zero(); 2],
            };
        }
        let detection = self.cut.detector.update(
            &self.cut.residuals[..n],
            self.features.active(),
            self.features.targets(),
            &self.config.detection,
        );
        let line = self.cut.line.update(
            self.frame,
            self.cut.detector.points(),
            self.features.targets(),
            self.features.active(),
            &self.config.detection,
            self.cut.projections,
        );
        (detection, line)
    }

    /// The detected cut line in the image, as its anchoring features are seen now: writes up
    /// to `out.len()` vertices (pixels), returns how many (0 before a cut is detected).
    #[cfg(feature = "cut")]
    pub fn cut_polyline(&self, out: &mut [[T; 2]]) -> usize {
        self.cut.line.project(self.features.targets(), out)
    }

    /// The separation surface of the detected cut: one quadrilateral (metres) per segment of
    /// the cut line, extruded along the depth direction by the size of the model. Writes up to
    /// `out.len()`, returns how many.
    #[cfg(feature = "cut")]
    pub fn separation_surface(&self, out: &mut [[[T; 3]; 4]]) -> usize {
        let n = self.mesh.n_nodes();
        let x = &self.x[..n];
        // Long enough to pass through the whole model: its bounding-box diagonal.
        let (mut lo, mut hi) = ([T::zero(); 3], [T::zero(); 3]);
        for (k, p) in x.iter().enumerate() {
            for c in 0..3 {
                lo[c] = if k == 0 { p[c] } else { lo[c].min(p[c]) };
                hi[c] = if k == 0 { p[c] } else { hi[c].max(p[c]) };
            }
        }
        let diagonal = ((hi[0] - lo[0]) * (hi[0] - lo[0])
            + (hi[1] - lo[1]) * (hi[1] - lo[1])
            + (hi[2] - lo[2]) * (hi[2] - lo[2]))
            .sqrt();
        self.cut.line.separation_surface(
            self.features.targets(),
            &self.mesh,
            x,
            &self.config.camera,
            &self.config.detection,
            diagonal,
            out,
        )
    }

    /// The cut detector (pairs, separation points).
    #[cfg(feature = "cut")]
    pub fn detector(&self) -> &Detector<'a, T> {
        &self.cut.detector
    }

    /// Positions of node `v` as a vector (`None` out of range).
    pub fn node(&self, v: usize) -> Option<Vector3<T>> {
        let p = self.positions().get(v)?;
        Some(Vector3::new(p[0], p[1], p[2]))
    }
}
