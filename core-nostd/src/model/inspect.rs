//! What validation reads and sets from outside the per-frame path: the linear system of a
//! Newton step with its energies (for an outside solver), positions set by the caller, the
//! fingerprint of the state.

use super::*;

impl<'a, T: Real, F: Real> Model<'a, T, F> {
    /// Assembles the system a Newton step solves at the current positions, for validation
    /// against other solvers: the gradient over the free unknowns (`3 · n_free`, node by free
    /// index) and the positive definite Hessian on the stiffness pattern.
    ///
    /// # Errors
    /// [`Error::FeatureBehindCamera`] if a virtual feature cannot be projected.
    pub fn linearize(&mut self) -> Result<Linearization<'_, T>, Error> {
        let energies = self.assemble(true, false, &mut WorkCount::default())?;
        let n = self.n_unknowns();
        let nnz = self.live.nnz_a;
        Ok(Linearization {
            energies,
            gradient: self.vectors.gradient.get(..n).unwrap_or_default(),
            hessian: self.hessian.get(..nnz).unwrap_or_default(),
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
        for ((xv, &f), &new) in live.x.iter_mut().zip(free).zip(x) {
            if f != NONE {
                *xv = new;
            }
        }
        copy_front(live.previous, live.x, n);
        // The nodes moved: the elements' share kept for the old positions no longer holds.
        self.kept.forget();
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
        h.reals(d.x.iter().take(n).flatten());
        h.reals(d.previous.iter().take(n).flatten());
        h.reals(d.damping.iter().take(n));
        h.words(d.col_ptr.iter().take(d.n_unknowns() + 1));
        h.words(d.row_idx.iter().take(d.nnz_a));
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
        h.words(d.scatter.iter().take(m.n_tets()).flatten());
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
        h.reals(
            [
                self.spring_stiffness,
                self.spring_threshold_px,
                self.depth_scale,
            ]
            .iter(),
        );
        let strategy = match self.config.solver.strategy {
            Strategy::Refactor => [0, 0],
            Strategy::Frozen { pcg_iterations } => [1, pcg_iterations],
            Strategy::FactorOnce { pcg_iterations } => [2, pcg_iterations],
            Strategy::QuasiNewton => [3, 0],
        };
        h.words(strategy.iter());
        h.words(core::iter::once(&(self.factored as u32)));
        self.secant.fingerprint_into(self.n_unknowns(), &mut h);
        self.kept.fingerprint_into(self.n_unknowns(), &mut h);
        #[cfg(feature = "detect")]
        {
            self.cut.detector.fingerprint_into(&mut h);
            self.cut.line.fingerprint_into(&mut h);
        }
        h.finish()
    }
}
