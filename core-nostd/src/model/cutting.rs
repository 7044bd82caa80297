//! The last stage of [`Model::step`] (`cut` feature): cutting the mesh along the separation
//! surface of the cut line, and what a caller reads of the cuts. One module behind one `cfg`,
//! so that a build without the `cut` feature leaves all of it out.

use super::*;

impl<'a, T: Real, F: Real> Model<'a, T, F> {
    /// The worst-case work of one cut event ([`Model::apply_cut`]): a formula of the
    /// capacities. The geometry of the line applied, whole ([`CutWork::bound`]), and the
    /// rebuild: one assembly with every tetrahedron's tangent and
    /// every feature's spring, and one factorization whose multiply-adds are bounded by the
    /// factor entries `L` and the unknowns `n` as `Σ c (c − 1) / 2 + 2 c ≤ L (n + 3) / 2` over
    /// the column counts `c` (`Σ c = L`, `c < n`). The ordering and the symbolic analysis, run
    /// once per event, are bounded by the same sizes and are not counted separately.
    pub fn worst_case_cut_work(&self) -> (CutWork, WorkCount) {
        let cap = self.live.mesh.capacity();
        let features = self.features.capacity() as u64;
        let segments = self.cut.line.capacity().saturating_sub(1) as u64;
        let part = CutWork::bound(
            cap.nodes as u64,
            cap.tets as u64,
            cap.surface_triangles as u64,
            segments,
            features,
            self.live.targets.capacity() as u64,
        );
        let geometry = part;
        let sym = self.live.symbolic.capacity();
        let rebuild = WorkCount {
            assemblies: 1,
            element_tangents: cap.tets as u64,
            feature_evaluations: features,
            factorizations: 1,
            factor_flops: sym.nnz_l as u64 * (sym.n as u64 + 3) / 2,
            ..WorkCount::default()
        };
        (geometry, rebuild)
    }

    /// Holds the cuts (`true`) or lets [`Model::step`] apply them (`false`, as built): held,
    /// a step still detects the cut and grows its line, but leaves the mesh whole, for a cut
    /// to be watched and not followed (an alarm), or to read the detector on the model that
    /// never cuts. A line grown while held is applied, whole, at the first step after release.
    pub fn hold_cuts(&mut self, held: bool) {
        self.cut.held = held;
    }

    /// Stage 5: cuts the mesh along the separation surface of the cut line as it is seen now
    /// (the line extruded along the camera rays, or the configured depth direction), where the
    /// mesh is not cut yet. A cut event happens when the line has grown since the last one
    /// (or has just started); nothing happens before that or when the surface crosses nothing
    /// new.
    ///
    /// The event cuts along the whole line, not only the segments added since the last one.
    /// The vertices already applied keep following their evidence and their lips
    /// (`CutLine::update`), so the line there is no longer where the mesh was cut: a line
    /// started on its first few separation points can lie tilted across its cut (the liver's
    /// by 34° at frame 7) and is straightened over the next frames. Cut again along where the
    /// line is now, the material between the first cut and the cut itself comes apart; where
    /// the surface runs along the faces already separated, it crosses nothing new. Cutting only
    /// the new segments, `liver-lobe` closed 32 % of its Dice deficit (targets 1.67 mm from
    /// the truth); along the whole line, 42 % (1.36 mm), the bands' cut scenes within 0.001 of
    /// their Dice (the README, "Scenes").
    ///
    /// The cut is built into the spare half of the storage — mesh, positions, embeddings,
    /// stiffness pattern, ordering, symbolic analysis — then the Hessian at the current state
    /// is factored with it, and only then is it put in service. Its work is reported in
    /// [`CutReport::work`], apart from the steady frame.
    ///
    /// # Errors
    /// [`Error::Capacity`] when the cut needs more nodes, tetrahedra, boundary triangles or
    /// factor entries than the capacities hold; [`Error::NonManifold`] for a cut that would
    /// leave a non-manifold surface; the factorization's errors. On any error the model is
    /// exactly as before the call.
    // Out of line, so that profilers (and `benches/cut_event.rs`, which takes the cut events
    // out of a steady frame by this function's name) can tell a cut event from the frame.
    #[inline(never)]
    pub fn apply_cut(&mut self) -> Result<CutReport, Error> {
        let m = self
            .cut
            .line
            .project(self.features.targets(), self.cut.pixels);
        if m < 2 || !self.cut.line.grown() {
            return Ok(CutReport::default());
        }
        let spacing = self.cut.detector.spacing();
        let report = self.cut_pixels(m, spacing)?;
        // Applied, or crossing nothing new: that part of the line is done with.
        self.cut.line.mark_applied();
        Ok(report)
    }

    /// Cuts the mesh along a polyline given in the image (pixels, at least two vertices, at
    /// most [`Capacities::cut_vertices`], what the cut's scratch holds a plane for),
    /// extruded along the camera rays (or the configured depth direction), as
    /// [`Model::apply_cut`] does with the detected line: for a cut known from elsewhere (a
    /// tracked instrument, a plan). Each end is extended by `extension_px` where that reaches
    /// the model's silhouette, else by half of it; by at least one pixel, so that the cut
    /// reaches past the last vertex.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming [`Resource::CutVertices`] for a polyline longer than the
    /// storage; [`Error::NonFiniteInput`] for a non-finite vertex;
    /// [`Error::InvalidParameter`] naming [`Parameter::CutExtension`] for an extension that is
    /// negative or not finite; otherwise as [`Model::apply_cut`], and the model is then
    /// exactly as before the call.
    pub fn cut_along(&mut self, polyline: &[[T; 2]], extension_px: T) -> Result<CutReport, Error> {
        let m = polyline.len();
        let room = self.cut.line.capacity().min(self.cut.pixels.len());
        if m > room {
            return Err(Error::Capacity {
                resource: Resource::CutVertices,
                needed: m,
                available: room,
            });
        }
        if let Some(position) = polyline
            .iter()
            .position(|p| !(p[0].finite() && p[1].finite()))
        {
            return Err(Error::NonFiniteInput {
                resource: Resource::CutVertices,
                position,
            });
        }
        if !(extension_px.finite() && extension_px >= T::zero()) {
            return Err(Error::InvalidParameter {
                parameter: Parameter::CutExtension,
            });
        }
        if m < 2 {
            return Ok(CutReport::default());
        }
        crate::storage::copy_front(self.cut.pixels, polyline, m);
        self.cut_pixels(m, extension_px)
    }

    /// Cuts along the polyline held in `cut.pixels[..m]`, each end extended by `extension_px`
    /// ([`cut::Surface`]); the model changes only if everything succeeds.
    fn cut_pixels(&mut self, m: usize, extension_px: T) -> Result<CutReport, Error> {
        self.spare.copy_state_from(&self.live);
        let coefficients = self.coefficients();
        let keeps = self.keeps_elements();
        let spare = &mut self.spare;
        let event = cut::apply(
            &cut::Surface {
                polyline: self.cut.pixels.get(..m).unwrap_or_default(),
                camera: &self.config.camera,
                depth: self.config.detection.depth,
                extension_px,
                extend: [true, true],
            },
            self.features.targets(),
            cut::Pieces {
                mesh: &mut spare.mesh,
                x: &mut spare.x[..],
                previous: &mut spare.previous[..],
                features: &mut spare.features,
                targets: &mut spare.targets,
                lips: &mut spare.lips,
            },
            self.cut.scratch,
            self.work,
        )?;
        let mut report = CutReport {
            applied: false,
            refused: None,
            event,
            work: WorkCount::default(),
        };
        if !event.changes_mesh() {
            return Ok(report);
        }
        spare.compute_node_weights(&self.lame, &self.config.solver);
        spare.rebuild_system(self.work)?;
        let mut work = WorkCount::default();
        // The quasi-Newton strategy starts the next frame from the elements' share of this
        // assembly (taken only if the cut goes into service).
        let n_new = spare.n_unknowns();
        let keep = if keeps {
            Some(self.kept.trial_mut(n_new)?)
        } else {
            None
        };
        assemble_on(
            spare,
            &self.features,
            coefficients,
            &self.config,
            AssemblyOutput {
                gradient: &mut self.vectors.gradient[..],
                hessian: Some(&mut self.hessian[..]),
                keep,
                spring_nodes: &mut self.vectors.spring_nodes[..],
            },
            &mut work,
        )?;
        factorize_on(
            spare,
            self.hessian,
            &mut self.factor,
            &mut self.vectors,
            &mut work,
        )?;
        // Everything succeeded: the new topology goes into service with its factor.
        core::mem::swap(&mut self.live, &mut self.spare);
        self.factored = if self.config.solver.strategy.freezes() {
            // The quasi-Newton strategy's secant pairs belong to the old topology's unknowns.
            self.secant.clear();
            FactoredMatrix::Frozen
        } else {
            FactoredMatrix::Step
        };
        if keeps {
            work.state_copies += self.kept.accept(n_new);
        } else {
            self.kept.forget();
        }
        report.applied = true;
        report.work = work;
        Ok(report)
    }

    /// The node pairs the cuts have separated (a node on the cut and its copy on the other
    /// lip): for a caller that inspects or draws the two sides of a cut.
    pub fn lips(&self) -> &[[u32; 2]] {
        self.live.lips.pairs()
    }
}
