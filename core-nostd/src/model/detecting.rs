//! The detection stages of [`Model::step`] (`detect` feature): detecting the cut and growing
//! its line, and what a caller reads of them. One module behind one `cfg`, so that a build
//! without the `detect` feature leaves all of it out.

use super::*;

impl<'a, T: Real, F: Real> Model<'a, T, F> {
    /// The worst-case work of the cut detection and the cut line in one [`Model::step`]: a
    /// formula of the capacities ([`DetectionWork::bound`], [`LineWork::bound`]), whether the
    /// frame starts the line (its robust fit) or grows it.
    pub fn worst_case_detection_work(&self) -> (DetectionWork, LineWork) {
        let features = self.features.capacity() as u64;
        let pairs = self.cut.detector.pair_capacity() as u64;
        (
            DetectionWork::bound(features, pairs),
            LineWork::bound(self.cut.line.capacity() as u64, pairs, features),
        )
    }

    /// Stage 3: the residuals of the frame and the detector. Also returns how many observed
    /// features it found unobservable (their virtual point cannot be projected) and marked
    /// unobserved for the frame.
    pub(super) fn detect(&mut self) -> (DetectionReport<T>, usize) {
        let n = self.features.len();
        let mut unobservable = 0;
        for slot in 0..n {
            let t = self.features.targets().get(slot).copied();
            let t = t.unwrap_or([T::zero(); 2]);
            let residual = match self.projected_feature(slot) {
                Ok(uv) => [t[0] - uv[0], t[1] - uv[1]],
                Err(_) => {
                    // A feature whose virtual point cannot be projected is unobserved in this
                    // frame: its residual has no meaning and the detector must not read it.
                    if self.features.active().get(slot).is_some_and(|&a| a != 0) {
                        unobservable += 1;
                    }
                    self.features.set_unobserved(slot);
                    [T::zero(); 2]
                }
            };
            if let Some(r) = self.cut.residuals.get_mut(slot) {
                *r = residual;
            }
        }
        let report = self.cut.detector.update(
            self.frame,
            self.cut.residuals.get(..n).unwrap_or_default(),
            self.features.active(),
            self.features.targets(),
            &self.config.detection,
        );
        (report, unobservable)
    }

    /// Stage 4: the cut line starts or advances. Where the mesh is already cut, the model
    /// follows the opening and leaves no separation points there: the line's vertices then stay
    /// anchored to the tracked features on both lips.
    pub(super) fn grow_cut_line(&mut self) -> CutLineReport {
        self.cut.line.update(
            self.frame,
            self.cut.detector.points(),
            self.cut.detector.point_since(),
            self.cut.detector.point_pair(),
            self.cut.detector.split_pairs(),
            self.features.targets(),
            self.cut
                .residuals
                .get(..self.features.len())
                .unwrap_or_default(),
            self.features.active(),
            &self.config.detection,
            self.cut.detector.spacing(),
            self.cut.pixels,
        )
    }

    /// The detected cut line in the image, as its anchoring features are seen now: writes its
    /// vertices (pixels) to the front of `out`, returns how many (0 before a cut is detected).
    /// [`Capacities::cut_vertices`] entries always suffice.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming [`Resource::CutVertices`] when `out` is shorter than the line
    /// (nothing is written then: no silent truncation).
    pub fn cut_polyline(&self, out: &mut [[T; 2]]) -> Result<usize, Error> {
        ensure_len(out, self.cut.line.len(), Resource::CutVertices)?;
        Ok(self.cut.line.project(self.features.targets(), out))
    }

    /// The separation surface of the detected cut: one quadrilateral (metres) per segment of
    /// the cut line, extruded along the depth direction by the size of the model. Writes them
    /// to the front of `out`, returns how many; [`Capacities::cut_vertices`] entries always
    /// suffice.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming [`Resource::CutSegments`] when `out` is shorter than the
    /// line has segments (nothing is written then).
    pub fn separation_surface(&self, out: &mut [[[T; 3]; 4]]) -> Result<usize, Error> {
        ensure_len(
            out,
            self.cut.line.len().saturating_sub(1),
            Resource::CutSegments,
        )?;
        let x = self.positions();
        // Long enough to pass through the whole model: its bounding-box diagonal.
        let (mut lo, mut hi) = ([T::zero(); 3], [T::zero(); 3]);
        for (k, p) in x.iter().enumerate() {
            for ((l, h), &c) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
                *l = if k == 0 { c } else { l.min(c) };
                *h = if k == 0 { c } else { h.max(c) };
            }
        }
        let diagonal = ((hi[0] - lo[0]) * (hi[0] - lo[0])
            + (hi[1] - lo[1]) * (hi[1] - lo[1])
            + (hi[2] - lo[2]) * (hi[2] - lo[2]))
            .sqrt();
        Ok(self.cut.line.separation_surface(
            self.features.targets(),
            &self.live.mesh,
            x,
            &self.config.camera,
            &self.config.detection,
            diagonal,
            out,
        ))
    }

    /// The cut detector (pairs, separation points).
    pub fn detector(&self) -> &Detector<'a, T> {
        &self.cut.detector
    }

    /// The cut line.
    pub fn cut_line(&self) -> &CutLine<'a, T> {
        &self.cut.line
    }
}
