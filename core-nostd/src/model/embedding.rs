//! Placing what the model carries: the virtual features at frame 0 (on the surface, through the
//! camera rays) and the internal targets (in the rest mesh).

use super::*;

impl<T: Real, F: Real> Model<'_, T, F> {
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

    /// Embeds the features of frame 0 (see [`Features::embed`]) at the current positions,
    /// replacing any held before, sets up the cut detection on them (`cut` feature: neighbour
    /// pairs, a fresh cut line, frame count back to 0) and prepares the frozen factor when
    /// that strategy is configured. It also sets the springs' robust threshold from these
    /// features' spacing ([`Model::spring_threshold_px`]) and, with
    /// [`crate::Coupling::Relative`], their stiffness ([`Model::spring_stiffness`]).
    ///
    /// All or nothing: the features and their embedding are copied aside first (once, `9 ·`
    /// [`Capacities::features`] entries at most), and so are the quasi-Newton strategy's
    /// secant pairs, which preparing the frozen factor clears; the detector counts its pairs
    /// before it stores any, and the factor keeps its previous values until the call succeeds
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
        let factored = self.factored;
        // The frozen factor's assembly keeps the elements' share for the quasi-Newton strategy.
        let n = self.n_unknowns();
        self.kept.checkpoint(n);
        // Preparing the frozen factor clears the quasi-Newton strategy's secant memory, and the
        // detector's pairs, counted after it, can still be refused.
        self.secant.checkpoint(n);
        let springs = (
            self.spring_stiffness,
            self.spring_threshold_px,
            self.depth_scale,
        );
        self.factor.checkpoint();
        match self.embed_features_uncommitted(frame0) {
            Ok(report) => {
                self.factor.commit();
                Ok(report)
            }
            Err(e) => {
                self.features.copy_from(&self.saved.features);
                self.live.features.copy_from(&self.saved.embedding);
                self.factored = factored;
                self.kept.rollback(n);
                self.secant.rollback(n);
                (
                    self.spring_stiffness,
                    self.spring_threshold_px,
                    self.depth_scale,
                ) = springs;
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
            self.live.x.get(..n).unwrap_or_default(),
            &self.config.camera,
            frame0,
            margin,
        )?;
        if report.embedded == 0 {
            return Err(Error::NoFeatures);
        }
        (
            self.spring_stiffness,
            self.spring_threshold_px,
            self.depth_scale,
        ) = self.coupled_springs()?;
        #[cfg(feature = "detect")]
        {
            // Scratch: the projections and residuals at frame 0.
            for slot in 0..self.features.len() {
                let uv = self.projected_feature(slot)?;
                let t = self.features.targets().get(slot).copied();
                let t = t.unwrap_or([T::zero(); 2]);
                if let (Some(p), Some(r)) = (
                    self.cut.pixels.get_mut(slot),
                    self.cut.residuals.get_mut(slot),
                ) {
                    *p = uv;
                    *r = [t[0] - uv[0], t[1] - uv[1]];
                }
            }
        }
        // The frozen factor is part of setting up, not of the first frame, so that every frame
        // costs the same.
        self.factored = FactoredMatrix::Nothing;
        if self.config.solver.strategy.freezes() {
            self.prepare_frozen(&mut WorkCount::default())?;
        }
        #[cfg(feature = "detect")]
        {
            let n = self.features.len();
            let (live, camera) = (&self.live, &self.config.camera);
            let focal = camera.intrinsics().fx;
            let at = |slot: usize| {
                live.features
                    .position(slot, &live.mesh, live.positions())
                    .map(|p| camera.to_camera(&Vector3::from(p)))
            };
            // Pairs across a fold or a grazing slope are left out (the ratio's doc says why).
            let ratio = self.config.detection.max_surface_ratio;
            // The last step that can fail: it leaves the detector as it was on error.
            self.cut.detector.init_on_surface(
                self.cut.pixels.get(..n).unwrap_or_default(),
                self.cut.residuals.get(..n).unwrap_or_default(),
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

    /// The springs' stiffness `k` ([`crate::Coupling`]), robust threshold (pixels, shrunk by
    /// the depth prior's scale so that `k δ` stays the default coupling's) and the depth
    /// prior's scale ([`Model::depth_scale`](crate::Model)) for the embedded features: the
    /// feature spacing from the bounding box of their frame-0 pixels, the image scale from the
    /// projection's Jacobian at their virtual points.
    ///
    /// Cost: one projection with its Jacobian per embedded feature, once.
    fn coupled_springs(&self) -> Result<(T, T, T), Error> {
        let n = self.features.len();
        let (lo, hi) = image_bounds(self.features.targets()).ok_or(Error::NoFeatures)?;
        // The detector's spacing (`Detector::spacing`), so both speak of the same length.
        let spacing = spacing_px(hi[0] - lo[0], hi[1] - lo[1], n);
        let threshold = self.config.solver.spring_threshold * spacing;
        let default = T::of(crate::solve::DEFAULT_COUPLING);
        // `k` and `k / k₀` (at least 1, exactly 1 at the default coupling).
        let (k, scale) = match self.config.solver.coupling {
            Coupling::Relative(beta) => {
                let k = Coupling::Relative(beta).stiffness(
                    self.config.material.young,
                    spacing,
                    self.image_scale()?,
                )?;
                (k, (beta / default).max(T::one()))
            }
            Coupling::Stiffness(k) => {
                let k = Coupling::Stiffness(k).stiffness(k, T::one(), T::one())?;
                // A given `k` against the default coupling's for this scene; a scene whose
                // features cannot all be projected keeps the prior as it is.
                let scale = self
                    .image_scale()
                    .and_then(|scale| {
                        Coupling::Relative(default).stiffness(
                            self.config.material.young,
                            spacing,
                            scale,
                        )
                    })
                    .map_or(T::one(), |k0| {
                        if k0 > T::zero() {
                            (k / k0).max(T::one())
                        } else {
                            T::one()
                        }
                    });
                (k, scale)
            }
        };
        // Above the default coupling the threshold shrinks by `k / k₀`, so a spring pulls no
        // harder than the default's `k₀ δ` (`DEFAULT_SPRING_THRESHOLD`), and the depth prior
        // grows with the springs.
        Ok((k, threshold / scale, scale))
    }

    /// The image scale at the features, pixels per metre: the mean over the virtual features of
    /// the smaller singular value of `∂P/∂x`.
    fn image_scale(&self) -> Result<T, Error> {
        let n = self.features.len();
        let x = self.live.positions();
        let mut scale_sum = T::zero();
        for slot in 0..n {
            let p = self
                .live
                .features
                .position(slot, &self.live.mesh, x)
                .ok_or(Error::NoFeatures)?;
            let (_, j) = self
                .config
                .camera
                .project_with_jacobian(&Vector3::from(p), slot)
                .map_err(|_| self.features.behind_camera(slot))?;
            // The smaller singular value of the 2 × 3 Jacobian: the magnification of motion
            // across the ray (`f / z` for a perspective camera; the larger one adds the
            // obliquity of an off-axis ray).
            let jjt = j * j.transpose();
            let (tr, det) = (jjt.trace(), jjt.determinant());
            let disc = (tr * tr - T::of(4.0) * det).max(T::zero()).sqrt();
            scale_sum += (T::of(0.5) * (tr - disc)).max(T::zero()).sqrt();
        }
        Ok(scale_sum / T::of(n as f64))
    }
}
