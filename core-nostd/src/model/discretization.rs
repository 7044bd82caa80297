//! Everything a cut changes: the mesh, the node positions and what hangs on the nodes, and the
//! structure of the linear system built on the mesh (stiffness pattern, ordering, symbolic
//! factorization, scatter map).
//!
//! A model holds two of these in its storage: the one in service and a spare. A cut copies the
//! one in service into the spare, cuts the spare, rebuilds its system and factors it; only when
//! all of that succeeds are the two swapped, so a refused cut leaves the model as it was.

use crate::embed::Embedding;
use crate::error::{Error, Resource};
use crate::material::{Lame, TangentProjection, element_energy_gradient_tangent};
use crate::mesh::{Mesh, MeshInput};
use crate::real::Real;
use crate::solve::{SolverConfig, build_scatter};
use crate::sparse::{PrecomputedAnalysis, Symbolic, UpperCsc};
use crate::storage::{Slab, prefix, sum, times};

use super::size::{ModelSize, free_node_pattern, order_free_nodes};

/// One half of a model's topology-dependent storage.
#[derive(Debug)]
pub(crate) struct Discretization<'a, T> {
    pub mesh: Mesh<'a, T>,
    /// Node positions, metres.
    pub x: &'a mut [[T; 3]],
    /// Positions at the end of the previous frame: what the damping pulls toward.
    pub previous: &'a mut [[T; 3]],
    /// Damping weight per node.
    pub damping: &'a mut [T],
    /// Depth-prior weight per node.
    pub depth_weight: &'a mut [T],
    /// Stiffness pattern (upper triangle, unknowns in free-node order): column pointers…
    pub col_ptr: &'a mut [u32],
    /// … and row indices; `nnz_a` of them in use.
    pub row_idx: &'a mut [u32],
    pub nnz_a: usize,
    pub symbolic: Symbolic<'a>,
    /// Per tetrahedron, where its blocks go in the pattern's values.
    pub scatter: &'a mut [[u32; 30]],
    /// Where each virtual feature sits (slot by slot).
    pub features: Embedding<'a, T>,
    /// Where each internal target sits.
    pub targets: Embedding<'a, T>,
    /// Nodes the cuts separated, with their copies.
    #[cfg(feature = "cut")]
    pub lips: crate::cut::Lips<'a>,
}

impl<'a, T: Real> Discretization<'a, T> {
    /// An empty half, in storage taken from the slabs.
    pub fn with_capacity(
        size: &ModelSize,
        reals: &mut Slab<'a, T>,
        indices: &mut Slab<'a, u32>,
    ) -> Result<Self, Error> {
        let c = size.capacities();
        let n = c.mesh.nodes;
        let mesh = Mesh::with_capacity(&c.mesh, reals, indices)?;
        Ok(Discretization {
            mesh,
            x: reals.take(times(3, n))?.as_chunks_mut::<3>().0,
            previous: reals.take(times(3, n))?.as_chunks_mut::<3>().0,
            damping: reals.take(n)?,
            depth_weight: reals.take(n)?,
            features: Embedding::with_capacity(c.features, reals, indices)?,
            targets: Embedding::with_capacity(c.targets, reals, indices)?,
            col_ptr: indices.take(sum(&[size.unknowns(), 1]))?,
            row_idx: indices.take(size.nnz_a())?,
            nnz_a: 0,
            symbolic: Symbolic::with_capacity(
                size.symbolic_capacity(),
                indices.take(size.symbolic_capacity().index_len())?,
            )?,
            scatter: indices
                .take(times(30, c.mesh.tets))?
                .as_chunks_mut::<30>()
                .0,
            #[cfg(feature = "cut")]
            lips: crate::cut::Lips::with_capacity(n, indices)?,
        })
    }

    /// Loads `input` at rest (positions and previous positions at the rest positions, no
    /// feature, no target), computes the nodes' damping and depth-prior weights and builds the
    /// system.
    pub fn load(
        &mut self,
        input: &MeshInput<'_, T>,
        lame: &Lame<T>,
        solver: &SolverConfig<T>,
        work: &mut [u32],
    ) -> Result<(), Error> {
        self.load_state(input, lame, solver, work)?;
        self.rebuild_system(work)
    }

    /// As [`Discretization::load`], with the system's ordering and symbolic analysis taken
    /// from `pre` (checked against the mesh's stiffness pattern) instead of computed.
    pub fn load_precomputed(
        &mut self,
        input: &MeshInput<'_, T>,
        lame: &Lame<T>,
        solver: &SolverConfig<T>,
        work: &mut [u32],
        pre: &PrecomputedAnalysis<'_>,
    ) -> Result<(), Error> {
        self.load_state(input, lame, solver, work)?;
        self.build_system(
            work,
            |tets, free, n_free, col_ptr, row_idx, slab| {
                free_node_pattern(tets, free, n_free, col_ptr, row_idx, slab)
                    .map(|(_, entries, scratch)| (entries, scratch))
            },
            |symbolic, a, scratch| symbolic.load(a, pre, scratch),
        )
    }

    /// The part of loading that does not depend on how the system is analysed: the mesh, the
    /// positions at rest, no feature or target, the node weights.
    fn load_state(
        &mut self,
        input: &MeshInput<'_, T>,
        lame: &Lame<T>,
        solver: &SolverConfig<T>,
        work: &mut [u32],
    ) -> Result<(), Error> {
        self.mesh.load(input, work)?;
        // `rest()` holds the `n_nodes()` loaded nodes, at most the capacity `x` and `previous`
        // were carved for.
        for ((x, previous), rest) in self
            .x
            .iter_mut()
            .zip(self.previous.iter_mut())
            .zip(self.mesh.rest())
        {
            *x = *rest;
            *previous = *rest;
        }
        self.features.clear();
        self.targets.clear();
        #[cfg(feature = "cut")]
        self.lips.clear();
        self.compute_node_weights(lame, solver);
        Ok(())
    }

    /// Makes this half a copy of `other`'s mesh and state (not of its system, which a cut
    /// rebuilds anyway).
    #[cfg_attr(not(feature = "cut"), allow(dead_code))]
    pub fn copy_state_from(&mut self, other: &Discretization<'_, T>) {
        self.mesh.copy_from(&other.mesh);
        let n = other.mesh.n_nodes();
        copy_prefix(self.x, other.x, n);
        copy_prefix(self.previous, other.previous, n);
        copy_prefix(self.damping, other.damping, n);
        copy_prefix(self.depth_weight, other.depth_weight, n);
        self.features.copy_from(&other.features);
        self.targets.copy_from(&other.targets);
        #[cfg(feature = "cut")]
        self.lips.copy_from(&other.lips);
    }

    /// Damping and depth-prior weights from the rest stiffness: the solver's fractions
    /// ([`SolverConfig::damping`], [`SolverConfig::depth_prior`]) of a third of the trace of each
    /// node's diagonal block of the rest tangent.
    pub fn compute_node_weights(&mut self, lame: &Lame<T>, solver: &SolverConfig<T>) {
        let n = self.mesh.n_nodes();
        // `damping` was carved for the node capacity, which `n_nodes()` never exceeds; the
        // fallback (no node) is not reached.
        let damping = self.damping.get_mut(..n).unwrap_or_default();
        damping.fill(T::zero());
        for (t, tet) in self.mesh.tets().iter().enumerate() {
            let Some(rest) = self.mesh.element_rest(t) else {
                continue;
            };
            let g = rest.shape_gradients();
            let at_rest = [[T::zero(); 3]; 4];
            let eval = element_energy_gradient_tangent(
                lame,
                &rest,
                &g,
                &at_rest,
                TangentProjection::Exact,
            );
            // The mesh checked its tetrahedra's nodes against `n_nodes()` when it was loaded or
            // edited, so `v` is in range and nothing is skipped.
            for (l, (&v, row)) in tet.iter().zip(eval.tangent.iter()).enumerate() {
                if let (Some(d), Some(block)) = (damping.get_mut(v as usize), row.get(l)) {
                    *d += block.trace() / T::of(3.0);
                }
            }
        }
        for (r, c) in self.depth_weight.iter_mut().zip(damping.iter_mut()) {
            *r = *c * solver.depth_prior;
            *c *= solver.damping;
        }
    }

    /// Rebuilds the stiffness pattern, its ordering, the symbolic factorization and the
    /// scatter map for the current mesh, using `work` ([`ModelSize::work_len`]).
    pub fn rebuild_system(&mut self, work: &mut [u32]) -> Result<(), Error> {
        self.build_system(
            work,
            |tets, free, n_free, col_ptr, row_idx, slab| {
                order_free_nodes(tets, free, n_free, col_ptr, row_idx, slab)
                    .map(|ordered| (ordered.nnz_a, (ordered.perm, ordered.scratch)))
            },
            |symbolic, a, (perm, scratch)| symbolic.analyse(a, perm, scratch),
        )
    }

    /// What [`Discretization::rebuild_system`] and [`Discretization::load_precomputed`] share:
    /// builds the stiffness pattern of the current mesh with `pattern` (which also orders it,
    /// or not) in `work`, then the symbolic factorization with `analyse` (computed from the
    /// ordering, or a precomputed one loaded and checked), then the scatter map. `pattern`
    /// returns the pattern's stored entries and what `analyse` takes from the workspace.
    ///
    /// The two steps are closures, not a choice made inside, so that a firmware build that only
    /// loads precomputed analyses links neither the ordering nor the analysis
    /// (tests/firmware.rs).
    fn build_system<'w, P>(
        &mut self,
        work: &'w mut [u32],
        pattern: impl FnOnce(
            &[[u32; 4]],
            &[u32],
            usize,
            &mut [u32],
            &mut [u32],
            &mut Slab<'w, u32>,
        ) -> Result<(usize, P), Error>,
        analyse: impl FnOnce(&mut Symbolic<'a>, &UpperCsc<'_>, P) -> Result<(), Error>,
    ) -> Result<(), Error> {
        let Discretization {
            mesh,
            col_ptr,
            row_idx,
            nnz_a,
            symbolic,
            scatter,
            ..
        } = self;
        let n_free = mesh.n_free();
        let n = 3 * n_free;
        // `row_idx` holds the bound `6 n + 54 t` of the capacities, so the pattern always fits.
        let mut slab = Slab::new(work, Resource::Workspace);
        let (entries, rest) = pattern(
            mesh.tets(),
            mesh.free_index(),
            n_free,
            col_ptr,
            row_idx,
            &mut slab,
        )?;
        let a = UpperCsc::new(
            n,
            prefix(col_ptr, n + 1, Resource::ColumnPointers)?,
            prefix(row_idx, entries, Resource::MatrixEntries)?,
        )?;
        analyse(symbolic, &a, rest)?;
        build_scatter(mesh, &a, scatter)?;
        *nnz_a = entries;
        Ok(())
    }

    /// The positions of the mesh's nodes, metres.
    pub fn positions(&self) -> &[[T; 3]] {
        self.x.get(..self.mesh.n_nodes()).unwrap_or_default()
    }

    /// The stiffness pattern in use.
    pub fn pattern(&self) -> Result<UpperCsc<'_>, Error> {
        let n = 3 * self.mesh.n_free();
        UpperCsc::new(
            n,
            prefix(self.col_ptr, n + 1, Resource::ColumnPointers)?,
            prefix(self.row_idx, self.nnz_a, Resource::MatrixEntries)?,
        )
    }

    /// Unknowns in use: three per free node.
    pub fn n_unknowns(&self) -> usize {
        3 * self.mesh.n_free()
    }
}

/// Copies the first `n` entries of `src` into `dst`. Both halves of a model are carved from
/// the same [`ModelSize`], so their buffers have the same lengths, at least the `n` nodes in
/// use; were either shorter, nothing would be copied.
#[cfg_attr(not(feature = "cut"), allow(dead_code))]
fn copy_prefix<X: Copy>(dst: &mut [X], src: &[X], n: usize) {
    if let (Some(d), Some(s)) = (dst.get_mut(..n), src.get(..n)) {
        d.copy_from_slice(s);
    }
}
