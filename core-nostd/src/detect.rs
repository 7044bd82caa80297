//! Detecting a cut from motion discontinuities (paper §2.2 and §2.3).
//!
//! While the model follows the real object, the residual `d_i = f_i − P(f_iᵛ)` of each feature
//! varies smoothly over the image. Where the real object is cut and the model is not, features
//! on the two lips pull the model in different directions and neighbouring residuals stop
//! agreeing. The detector measures `μ_ij = ‖d_i − d_j‖` over the neighbour pairs fixed at frame
//! 0 (features close in the image and on the model alike), flags the pairs whose `μ_ij` exceeds
//! what the frame's own statistics explain (the paper's `ε·μ̄`, made robust: see
//! [`DetectionConfig::outlier_sigmas`]), and, once a pair has been flagged for a few frames in
//! a row, records it as split: the midpoints of split pairs are the separation points the cut
//! line is fitted to ([`crate::cutline`]).
//!
//! A temporal filter keeps tracker failures out: a feature whose residual jumps from one frame
//! to the next far more than the others' (the paper's `E_i > ε_t·Ē`, made robust the same way)
//! is taken out of detection for good, with all its pairs.
//!
//! Cost per frame: bounded by [`DetectionWork::bound`] in the capacities.

#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

use crate::error::Error;
use crate::error::Parameter;
use crate::real::Real;

/// Parameters of the detection and of the cut line.
///
/// Nothing here is in pixels except the optional overrides: thresholds are in robust standard
/// deviations of what the detector measures in the frame itself, and lengths in feature spacings
/// (the side of the square each feature covers at frame 0, `√(area / features)`), so that one set
/// of defaults serves a close band and a wide liver, 300 features or 1000, 0.3 px of noise or 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetectionConfig<T> {
    /// Whether detection runs at all (a scene can switch it off at run time; the `cut` feature
    /// removes it from the build).
    pub enabled: bool,
    /// Neighbour radius `r` in pixels; 0 derives it from the features' density at frame 0
    /// ([`DetectionConfig::radius_spacings`] feature spacings).
    pub radius_px: T,
    /// Neighbour radius in feature spacings when `radius_px` is 0: 2.5 gives each feature about
    /// twenty neighbours (π·2.5²), enough for its robust statistics.
    pub radius_spacings: T,
    /// Two features close in the image are not paired when, on the model at frame 0, they lie
    /// farther apart than this multiple of their image distance taken back to their depth
    /// (`‖X_i − X_j‖ > ratio · ℓ_ij · z / f`): the pair then spans a fold, or a slope seen at
    /// a grazing angle, where the residuals of a coarse model jump without any cut (what made
    /// most of the false cuts on the liver family). 3 keeps every pair on a surface tilted up
    /// to 70° from the image plane (1 / cos 70.5° = 3); 0 pairs by image distance alone.
    pub max_surface_ratio: T,
    /// A pair is an outlier when its residual difference `μ_ij` exceeds what the frame explains
    /// by this many robust standard deviations (see [`crate::detect`]).
    pub outlier_sigmas: T,
    /// A feature is a tracking failure when its residual changes from one frame to the next by
    /// more than the median change plus this many robust standard deviations of the changes.
    /// Infinite turns the temporal filter off (what a build without the `temporal-filter`
    /// feature always does).
    pub temporal_sigmas: T,
    /// Differences below this many pixels are never outliers: the floor for scenes without
    /// noise, where the robust deviation is near zero (a tracker localises to a few tenths of a
    /// pixel at best).
    pub min_difference_px: T,
    /// Frames in a row a pair must be an outlier before it counts as split.
    pub persistence: u32,
    /// Separation points needed to start the cut line.
    pub init_points: u32,
    /// Angular restriction `α` of a front's advance, degrees.
    pub alpha_degrees: T,
    /// Shortest advance of a front, feature spacings.
    pub min_step: T,
    /// Longest advance of a front, feature spacings.
    pub max_step: T,
    /// Separation points ahead of a front needed to advance it.
    pub min_support: u32,
    /// Separation points within this distance of a candidate line count for it when the line
    /// is started (a robust fit), feature spacings.
    pub line_tolerance: T,
    /// The separation points must lie along a line to start the cut line: the spread across
    /// the fitted line over the spread along it, `√(λ_min / λ_max)`, may not exceed this.
    pub max_line_spread: T,
    /// Count only pairs whose residuals diverge across the line joining them (the lips of an
    /// opening cut), not those that converge or shear.
    pub opening_only: bool,
    /// A feature whose measured pairs are outliers in more than this fraction is taken as a
    /// tracking failure in that frame, not as evidence of a cut (a cut separates a feature
    /// from the neighbours on the far side only).
    pub max_outlier_fraction: T,
    /// Direction the cut line is extruded along into the model (world); `None` uses the
    /// camera's viewing direction.
    pub depth: Option<[T; 3]>,
}

impl<T: Real> DetectionConfig<T> {
    /// The defaults, calibrated by the data of each frame (why each value is what it is:
    /// the README's "Cut detection" section and the field docs).
    pub fn paper() -> Self {
        DetectionConfig {
            enabled: true,
            radius_px: T::zero(),
            radius_spacings: T::of(2.5),
            max_surface_ratio: T::of(3.0),
            outlier_sigmas: T::of(OUTLIER_SIGMAS),
            temporal_sigmas: T::of(TEMPORAL_SIGMAS),
            min_difference_px: T::of(0.5),
            persistence: 2,
            init_points: 6,
            alpha_degrees: T::of(35.0),
            min_step: T::of(0.1),
            max_step: T::of(1.0),
            min_support: 3,
            line_tolerance: T::of(0.3),
            max_line_spread: T::of(0.25),
            max_outlier_fraction: T::of(0.85),
            opening_only: true,
            depth: None,
        }
    }

    /// Checks the ranges, field by field in declaration order (`max_step` before `min_step`,
    /// which must not exceed it).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first field out of its range
    /// ([`Parameter::RadiusPx`] … [`Parameter::Depth`]).
    pub fn validate(&self) -> Result<(), Error> {
        let pos = |x: T| x.finite() && x > T::zero();
        let checks = [
            (
                Parameter::RadiusPx,
                self.radius_px.finite() && self.radius_px >= T::zero(),
            ),
            (Parameter::RadiusSpacings, pos(self.radius_spacings)),
            (
                Parameter::MaxSurfaceRatio,
                self.max_surface_ratio.finite()
                    && (self.max_surface_ratio == T::zero() || self.max_surface_ratio >= T::one()),
            ),
            (Parameter::OutlierSigmas, pos(self.outlier_sigmas)),
            (
                Parameter::TemporalSigmas,
                self.temporal_sigmas > T::zero(), // +∞ included: the filter off
            ),
            (
                Parameter::MinDifferencePx,
                self.min_difference_px.finite() && self.min_difference_px >= T::zero(),
            ),
            (
                Parameter::Persistence,
                self.persistence >= 1 && self.persistence < 255,
            ),
            (Parameter::InitPoints, self.init_points >= 2),
            (
                Parameter::AlphaDegrees,
                self.alpha_degrees.finite()
                    && self.alpha_degrees > T::zero()
                    && self.alpha_degrees <= T::of(90.0),
            ),
            (Parameter::MaxStep, pos(self.max_step)),
            (
                Parameter::MinStep,
                self.min_step.finite()
                    && self.min_step >= T::zero()
                    && self.min_step <= self.max_step,
            ),
            (Parameter::MinSupport, self.min_support >= 1),
            (Parameter::LineTolerance, pos(self.line_tolerance)),
            (Parameter::MaxLineSpread, pos(self.max_line_spread)),
            (
                Parameter::MaxOutlierFraction,
                pos(self.max_outlier_fraction),
            ),
            (
                Parameter::Depth,
                self.depth.is_none_or(|d| {
                    d.iter().all(|c| c.finite()) && d.iter().any(|c| *c != T::zero())
                }),
            ),
        ];
        match checks.iter().find(|(_, ok)| !ok) {
            Some(&(parameter, _)) => Err(Error::InvalidParameter { parameter }),
            None => Ok(()),
        }
    }
}

/// Default [`DetectionConfig::outlier_sigmas`].
pub const OUTLIER_SIGMAS: f64 = 6.0;
/// Default [`DetectionConfig::temporal_sigmas`].
pub const TEMPORAL_SIGMAS: f64 = 10.0;

/// What the detector saw in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DetectionReport<T> {
    /// Neighbour pairs built at frame 0.
    pub pairs: usize,
    /// Pairs measured this frame (both features observed and neither filtered out).
    pub pairs_active: usize,
    /// Pairs dropped so far because a feature was filtered out.
    pub pairs_lost: usize,
    /// Pairs whose `μ_ij` exceeded its threshold this frame.
    pub outliers: usize,
    /// Pairs counted as split this frame (outliers for `persistence` frames in a row).
    pub split: usize,
    /// Features taken out by the temporal filter so far.
    pub features_filtered: usize,
    /// Median `μ` over the active pairs, pixels.
    pub median_difference_px: T,
    /// Robust standard deviation of `μ` over the active pairs (1.4826 × MAD), pixels.
    pub deviation_px: T,
    /// Separation points this frame.
    pub separation_points: usize,
    /// Work done this frame.
    pub work: DetectionWork,
}

/// Work of the detector in one frame, counted in data-independent units; bounded by
/// [`DetectionWork::bound`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DetectionWork {
    /// Feature visits (temporal filter, per-feature statistics).
    pub feature_visits: u64,
    /// Pair visits (differences, thresholds, persistence).
    pub pair_visits: u64,
    /// Comparisons of the robust statistics' sorts.
    pub comparisons: u64,
}

impl DetectionWork {
    /// The most work of one frame with `features` feature slots, `pairs` pairs and `degree`
    /// pairs at most per feature (at most `pairs`):
    /// - feature visits `4 n`: the temporal filter's three passes and the per-feature levels;
    /// - pair visits `5 P`: differences, per-feature lists, levels, outliers, persistence;
    /// - comparisons: the median and MAD of the changes (`2 S(n)`) and of the differences
    ///   (`2 S(P)`), and each feature's lower tertile (`Σ S(dᵢ) ≤ S(2P)` as `Σ dᵢ = 2P`),
    ///   with `S(m) = 2 m ⌈log₂ m⌉ + 2 m` heapsort's bound.
    pub const fn bound(features: u64, pairs: u64) -> DetectionWork {
        use crate::robust::sort_bound;
        DetectionWork {
            feature_visits: 4 * features,
            pair_visits: 5 * pairs,
            comparisons: 2 * sort_bound(features) + 2 * sort_bound(pairs) + sort_bound(2 * pairs),
        }
    }

    /// Whether every count is at most `other`'s.
    pub fn within(&self, other: &DetectionWork) -> bool {
        self.feature_visits <= other.feature_visits
            && self.pair_visits <= other.pair_visits
            && self.comparisons <= other.comparisons
    }
}

#[cfg(feature = "detect")]
pub use detector::{Detector, GRID_CELLS};

#[cfg(feature = "detect")]
mod detector {
    use super::{DetectionConfig, DetectionReport, DetectionWork};
    use crate::error::{Error, Resource};
    use crate::real::Real;
    use crate::robust::{MAD_TO_SIGMA, median_mad, quantile_sorted, sort};
    use crate::storage::{Slab, sum, times};

    const STREAK: u32 = 0xff;
    const SPLIT: u32 = 1 << 8;
    const DROPPED: u32 = 1 << 9;
    /// Set by the outlier step of this frame, read by the persistence step.
    const OUTLIER: u32 = 1 << 10;

    const HAS_PREVIOUS: u32 = 1;
    const FILTERED: u32 = 2;
    const OBSERVED: u32 = 4;

    /// Cells of the spatial grid that finds neighbours at frame 0.
    pub const GRID_CELLS: usize = 4096;

    /// Marks a pair not measured this frame in the difference buffer.
    const UNMEASURED: f64 = -1.0;

    /// The detector's state, in fixed storage.
    #[derive(Debug)]
    pub struct Detector<'a, T> {
        pairs: &'a mut [[u32; 2]],
        pair_state: &'a mut [u32],
        n_pairs: usize,
        previous: &'a mut [[T; 2]],
        current: &'a mut [[T; 2]],
        feature_state: &'a mut [u32],
        /// Per feature, this frame: measured pairs and outlier pairs.
        pair_counts: &'a mut [[u32; 2]],
        /// Per feature, the pairs it belongs to (`incident[incident_start[i]..incident_start[i + 1]]`).
        incident_start: &'a mut [u32],
        incident: &'a mut [u32],
        /// Per pair, this frame: `μ_ij`, or [`UNMEASURED`].
        difference: &'a mut [T],
        /// Per feature, this frame: the smooth part of the residual field around it, as a
        /// difference per pixel of pair length (the lower tertile of `μ / ℓ` over its pairs).
        slope: &'a mut [T],
        /// Per pair, this frame: its length `ℓ_ij` in the image (where measured).
        length: &'a mut [T],
        /// Sort space for the robust statistics.
        scratch: &'a mut [T],
        points: &'a mut [[T; 2]],
        /// Per point: the frame its pair (last) became split.
        point_since: &'a mut [u32],
        /// Per pair: the frame it (last) became split.
        split_since: &'a mut [u32],
        n_points: usize,
        grid: &'a mut [u32],
        radius: T,
        spacing: T,
        pairs_lost: usize,
        features_filtered: usize,
    }

    /// Whether feature `f` is observed and not filtered out (`state` holds one word per slot).
    fn usable(state: &[u32], f: u32) -> bool {
        state
            .get(f as usize)
            .is_some_and(|&s| s & (OBSERVED | FILTERED) == OBSERVED)
    }

    /// Turns the per-cell counts `start[0..=cells]` (with `start[0] == 0`) into the end of
    /// each cell: `start[c]` becomes the sum of the counts up to `c`.
    fn accumulate(start: &mut [u32]) {
        let mut total = 0;
        for s in start.iter_mut() {
            *s += total;
            total = *s;
        }
    }

    /// Shifts the ends `start[0..cells]` written by a counting sort back to starts: `start[c]`
    /// becomes the old `start[c - 1]`, `start[0]` 0.
    fn ends_to_starts(start: &mut [u32]) {
        start.rotate_right(1);
        if let Some(first) = start.first_mut() {
            *first = 0;
        }
    }

    fn norm<T: Real>(a: [T; 2], b: [T; 2]) -> T {
        ((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1])).sqrt()
    }

    impl<'a, T: Real> Detector<'a, T> {
        /// Scalars of storage for `features` features and `pairs` pairs.
        pub const fn real_len(features: usize, pairs: usize) -> usize {
            let larger = if pairs > features { pairs } else { features };
            sum(&[times(5, features), times(4, pairs), larger])
        }

        /// Indices of storage.
        pub const fn index_len(features: usize, pairs: usize) -> usize {
            sum(&[
                times(5, pairs),
                times(3, features),
                GRID_CELLS + 1,
                features,
                features,
                1,
                times(2, pairs),
            ])
        }

        /// Empty detector storage.
        ///
        /// # Errors
        /// [`Error::Capacity`] if a slab is too short.
        pub fn new(
            features: usize,
            pairs: usize,
            reals: &mut Slab<'a, T>,
            indices: &mut Slab<'a, u32>,
        ) -> Result<Self, Error> {
            Ok(Detector {
                pairs: indices.take(times(2, pairs))?.as_chunks_mut::<2>().0,
                pair_state: indices.take(pairs)?,
                n_pairs: 0,
                feature_state: indices.take(features)?,
                pair_counts: indices.take(times(2, features))?.as_chunks_mut::<2>().0,
                grid: indices.take(sum(&[GRID_CELLS + 1, features]))?,
                incident_start: indices.take(sum(&[features, 1]))?,
                incident: indices.take(times(2, pairs))?,
                previous: reals.take(times(2, features))?.as_chunks_mut::<2>().0,
                current: reals.take(times(2, features))?.as_chunks_mut::<2>().0,
                difference: reals.take(pairs)?,
                slope: reals.take(features)?,
                length: reals.take(pairs)?,
                scratch: reals.take(pairs.max(features))?,
                points: reals.take(times(2, pairs))?.as_chunks_mut::<2>().0,
                point_since: indices.take(pairs)?,
                split_since: indices.take(pairs)?,
                n_points: 0,
                radius: T::zero(),
                spacing: T::zero(),
                pairs_lost: 0,
                features_filtered: 0,
            })
        }

        /// Hashes every buffer of the detector's state.
        pub(crate) fn fingerprint_into(&self, h: &mut crate::storage::Fingerprint) {
            h.words(self.pairs.iter().take(self.n_pairs).flatten());
            h.words(self.pair_state.iter().take(self.n_pairs));
            h.words(self.split_since.iter().take(self.n_pairs));
            h.reals(self.previous.iter().flatten());
            h.reals(self.current.iter().flatten());
            h.words(self.feature_state.iter());
            h.words(self.pair_counts.iter().flatten());
            h.words(self.incident_start.iter());
            h.words(self.incident.iter());
            h.reals(self.difference.iter());
            h.reals(self.length.iter());
            h.reals(self.slope.iter());
            h.reals(self.points.iter().take(self.n_points).flatten());
            h.words(self.point_since.iter().take(self.n_points));
            h.reals([self.radius, self.spacing].iter());
            h.words(
                [
                    self.n_pairs as u32,
                    self.n_points as u32,
                    self.pairs_lost as u32,
                    self.features_filtered as u32,
                ]
                .iter(),
            );
        }

        /// The neighbour pairs (feature slots).
        pub fn pairs(&self) -> &[[u32; 2]] {
            self.pairs.get(..self.n_pairs).unwrap_or_default()
        }

        /// The most neighbour pairs the storage holds.
        pub fn pair_capacity(&self) -> usize {
            self.pairs.len()
        }

        /// Whether pair `k` has been counted as split.
        pub fn is_split(&self, k: usize) -> bool {
            self.pair_state.get(k).is_some_and(|s| s & SPLIT != 0)
        }

        /// The neighbour radius in use, pixels.
        pub fn radius(&self) -> T {
            self.radius
        }

        /// The features' spacing at frame 0, `√(area / features)` over their bounding box,
        /// pixels: the unit of the cut line's lengths.
        pub fn spacing(&self) -> T {
            self.spacing
        }

        /// The separation points of the last frame, pixels.
        pub fn points(&self) -> &[[T; 2]] {
            self.points.get(..self.n_points).unwrap_or_default()
        }

        /// For each separation point, the frame at which its pair became split (the paper's
        /// separation points "inserted" since then).
        pub fn point_since(&self) -> &[u32] {
            self.point_since.get(..self.n_points).unwrap_or_default()
        }

        /// Builds the neighbour pairs from the frame-0 projections `uv` of the virtual features
        /// (one per slot) and their residuals `d` there; forgets any earlier state.
        ///
        /// # Errors
        /// [`Error::Capacity`] naming [`Resource::Pairs`] if more pairs lie within the radius than
        /// the capacity holds (a smaller radius or a larger capacity is needed), or
        /// [`Resource::Features`] for more slots than the storage holds. On error the detector
        /// is as it was before the call (the pairs are counted before any is stored).
        pub fn init(
            &mut self,
            uv: &[[T; 2]],
            d: &[[T; 2]],
            config: &DetectionConfig<T>,
        ) -> Result<(), Error> {
            self.init_on_surface(uv, d, config, |_, _, _| false)
        }

        /// As [`Detector::init`], leaving out the pairs for which `apart(i, j, ℓ)` says that
        /// features `i` and `j`, `ℓ` pixels apart in the image, are far apart on the object
        /// (see [`DetectionConfig::max_surface_ratio`]).
        pub fn init_on_surface(
            &mut self,
            uv: &[[T; 2]],
            d: &[[T; 2]],
            config: &DetectionConfig<T>,
            apart: impl Fn(usize, usize, T) -> bool,
        ) -> Result<(), Error> {
            let n = uv.len();
            // Every per-feature buffer was carved for the same number of slots; checking them
            // all here keeps the lookups below in range and the detector unchanged on error.
            let slots = self
                .feature_state
                .len()
                .min(self.previous.len())
                .min(self.incident_start.len().saturating_sub(1));
            if n > slots || d.len() != n {
                return Err(Error::Capacity {
                    resource: Resource::Features,
                    needed: n,
                    available: slots,
                });
            }
            let Some(&first) = uv.first() else {
                self.n_pairs = 0;
                self.n_points = 0;
                self.pairs_lost = 0;
                self.features_filtered = 0;
                return Ok(());
            };
            let (mut lo, mut hi) = (first, first);
            for p in uv {
                for ((l, h), &c) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
                    *l = l.min(c);
                    *h = h.max(c);
                }
            }
            let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
            let area = (w * h).max(T::one());
            let spacing = (area / T::of(n as f64)).sqrt();
            let r = if config.radius_px > T::zero() {
                config.radius_px
            } else {
                config.radius_spacings * spacing
            };
            // Cells at least `r` wide, no more than the grid holds.
            let side = T::of(libm::floor(libm::sqrt(GRID_CELLS as f64)));
            let cell = r.max(w / side).max(h / side).max(T::EPS);
            let nx = (libm::floor((w / cell).to_f64()) as usize + 1).min(64);
            let ny = (libm::floor((h / cell).to_f64()) as usize + 1).min(64);
            let cell_of = |p: &[T; 2]| -> (usize, usize) {
                let cx = (libm::floor(((p[0] - lo[0]) / cell).to_f64()) as usize).min(nx - 1);
                let cy = (libm::floor(((p[1] - lo[1]) / cell).to_f64()) as usize).min(ny - 1);
                (cx, cy)
            };
            // Counting sort of the features into cells. The grid was carved with
            // `GRID_CELLS + 1` starts and a slot per feature; `nx · ny ≤ GRID_CELLS`, so no
            // lookup below fails and nothing is skipped.
            let grid_len = self.grid.len();
            let (start, items) =
                self.grid
                    .split_at_mut_checked(GRID_CELLS + 1)
                    .ok_or(Error::Capacity {
                        resource: Resource::Workspace,
                        needed: GRID_CELLS + 1,
                        available: grid_len,
                    })?;
            start.fill(0);
            for p in uv {
                let (cx, cy) = cell_of(p);
                if let Some(c) = start.get_mut(cy * nx + cx + 1) {
                    *c += 1;
                }
            }
            let start = start.get_mut(..=nx * ny).unwrap_or_default();
            accumulate(start);
            for (i, p) in uv.iter().enumerate() {
                let (cx, cy) = cell_of(p);
                if let Some(slot) = start.get_mut(cy * nx + cx) {
                    if let Some(item) = items.get_mut(*slot as usize) {
                        *item = i as u32;
                    }
                    *slot += 1;
                }
            }
            // `start[c]` now ends cell c; shift back to starts.
            ends_to_starts(start);
            let (start, items) = (&*start, &*items);
            let r2 = r * r;
            // Every pair within the radius, in a fixed order: counted first, so that a capacity
            // error leaves the detector as it was, then stored.
            let visit_pairs = |visit: &mut dyn FnMut(u32, u32)| {
                for (i, p) in uv.iter().enumerate() {
                    let (cx, cy) = cell_of(p);
                    for gy in cy.saturating_sub(1)..(cy + 2).min(ny) {
                        for gx in cx.saturating_sub(1)..(cx + 2).min(nx) {
                            let c = gy * nx + gx;
                            let cell = match (start.get(c), start.get(c + 1)) {
                                (Some(&s), Some(&e)) => {
                                    items.get(s as usize..e as usize).unwrap_or_default()
                                }
                                _ => &[],
                            };
                            for &j in cell {
                                if (j as usize) <= i {
                                    continue;
                                }
                                let Some(q) = uv.get(j as usize) else {
                                    continue;
                                };
                                let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
                                if dx * dx + dy * dy < r2
                                    && !apart(i, j as usize, (dx * dx + dy * dy).sqrt())
                                {
                                    visit(i as u32, j);
                                }
                            }
                        }
                    }
                }
            };
            let mut count = 0usize;
            visit_pairs(&mut |_, _| count += 1);
            if count > self.pairs.len() {
                return Err(Error::Capacity {
                    resource: Resource::Pairs,
                    needed: count,
                    available: self.pairs.len(),
                });
            }
            self.n_pairs = 0;
            self.n_points = 0;
            self.pairs_lost = 0;
            self.features_filtered = 0;
            self.spacing = spacing;
            self.radius = r;
            let (pairs, pair_state, n_pairs) =
                (&mut *self.pairs, &mut *self.pair_state, &mut self.n_pairs);
            visit_pairs(&mut |i, j| {
                if let (Some(pair), Some(state)) =
                    (pairs.get_mut(*n_pairs), pair_state.get_mut(*n_pairs))
                {
                    *pair = [i, j];
                    *state = 0;
                    *n_pairs += 1;
                }
            });
            // Each feature's pairs, by counting sort (`n` was checked against the buffers above,
            // the pairs' slots are below `n`, and `incident` holds two per pair).
            let start = self.incident_start.get_mut(..=n).unwrap_or_default();
            start.fill(0);
            let pairs = self.pairs.get(..self.n_pairs).unwrap_or_default();
            for &[i, j] in pairs {
                for f in [i, j] {
                    if let Some(c) = start.get_mut(f as usize + 1) {
                        *c += 1;
                    }
                }
            }
            accumulate(start);
            for (k, &[i, j]) in pairs.iter().enumerate() {
                for f in [i, j] {
                    if let Some(slot) = start.get_mut(f as usize) {
                        if let Some(entry) = self.incident.get_mut(*slot as usize) {
                            *entry = k as u32;
                        }
                        *slot += 1;
                    }
                }
            }
            ends_to_starts(start);
            for ((previous, state), &di) in self
                .previous
                .iter_mut()
                .zip(self.feature_state.iter_mut())
                .zip(d)
            {
                *previous = di;
                *state = HAS_PREVIOUS;
            }
            Ok(())
        }

        /// One frame (number `frame`): `d` are the residuals of the slots (meaningful where
        /// `observed[i] != 0`), `targets` the tracked positions (for the separation points).
        pub fn update(
            &mut self,
            frame: u32,
            d: &[[T; 2]],
            observed: &[u32],
            targets: &[[T; 2]],
            config: &DetectionConfig<T>,
        ) -> DetectionReport<T> {
            let n = d
                .len()
                .min(observed.len())
                .min(targets.len())
                .min(self.feature_state.len())
                .min(self.incident_start.len().saturating_sub(1));
            let mut work = DetectionWork::default();
            let newly_filtered = self.temporal_filter(d, observed, n, config, &mut work);
            let (active, median, deviation) =
                self.measure_pairs(newly_filtered, targets, n, &mut work);
            let outliers = self.classify_pairs(median, deviation, targets, n, config, &mut work);
            let split = self.separation_points(frame, targets, config, &mut work);
            DetectionReport {
                pairs: self.n_pairs,
                pairs_active: active,
                pairs_lost: self.pairs_lost,
                outliers,
                split,
                features_filtered: self.features_filtered,
                median_difference_px: median,
                deviation_px: deviation,
                separation_points: self.n_points,
                work,
            }
        }

        /// Step 1, the temporal filter: a feature whose residual changes from the last frame
        /// far more than the others' (beyond the median change plus `temporal_sigmas` robust
        /// deviations) is a tracking failure and is taken out of detection for good. Returns
        /// whether a feature was taken out this frame.
        fn temporal_filter(
            &mut self,
            d: &[[T; 2]],
            observed: &[u32],
            n: usize,
            config: &DetectionConfig<T>,
            work: &mut DetectionWork,
        ) -> bool {
            // The first `n` slots of every buffer (`n` is at most each one's length, and the
            // per-feature buffers all hold the same number of slots; `scratch` at least as
            // many): the zips below stop at `n`.
            let eligible = OBSERVED | HAS_PREVIOUS;
            let mut count = 0usize;
            let slots = self
                .feature_state
                .iter_mut()
                .zip(observed)
                .zip(d.iter().zip(self.current.iter_mut()))
                .zip(self.previous.iter());
            for (((s, &o), (&di, current)), &previous) in slots.take(n) {
                *s = (*s & !OBSERVED) | if o != 0 { OBSERVED } else { 0 };
                *current = di;
                if *s & (eligible | FILTERED) == eligible
                    && let Some(slot) = self.scratch.get_mut(count)
                {
                    *slot = norm(di, previous);
                    count += 1;
                }
            }
            // A constant in a build without the feature, which then leaves the filter out.
            let filtering = cfg!(feature = "temporal-filter") && config.temporal_sigmas.finite();
            let mut newly_filtered = false;
            if filtering {
                let (median, mad, comparisons) =
                    median_mad(self.scratch.get_mut(..count).unwrap_or_default());
                work.comparisons += comparisons;
                let limit = (median + config.temporal_sigmas * T::of(MAD_TO_SIGMA) * mad)
                    .max(config.min_difference_px);
                let slots = self
                    .feature_state
                    .iter_mut()
                    .zip(d)
                    .zip(self.previous.iter());
                for ((s, &di), &previous) in slots.take(n) {
                    if *s & (eligible | FILTERED) == eligible && norm(di, previous) > limit {
                        *s |= FILTERED;
                        self.features_filtered += 1;
                        newly_filtered = true;
                    }
                }
            }
            let slots = self
                .feature_state
                .iter_mut()
                .zip(d)
                .zip(self.previous.iter_mut());
            for ((s, &di), previous) in slots.take(n) {
                if *s & OBSERVED != 0 {
                    *previous = di;
                    *s |= HAS_PREVIOUS;
                }
            }
            work.feature_visits += 3 * n as u64;
            newly_filtered
        }

        /// Step 2, the differences: `μ_ij` of every pair whose features are both usable, their
        /// median and robust deviation over the frame, and each feature's local slope (the
        /// lower tertile of `μ / ℓ` over its measured pairs: the smooth part of the residual
        /// field around it, which a cut through a third of its neighbourhood does not move).
        /// Returns `(active pairs, median, deviation)`.
        fn measure_pairs(
            &mut self,
            newly_filtered: bool,
            targets: &[[T; 2]],
            n: usize,
            work: &mut DetectionWork,
        ) -> (usize, T, T) {
            // The pair buffers hold `n_pairs` entries, `scratch` at least as many; a measured
            // pair's slots are below `n`, within `current` and `targets`. No lookup below
            // fails.
            let mut active = 0usize;
            let feature_state = &*self.feature_state;
            let pairs = self
                .pairs
                .iter()
                .zip(self.pair_state.iter_mut())
                .zip(self.difference.iter_mut().zip(self.length.iter_mut()));
            for ((&[i, j], state), (difference, length)) in pairs.take(self.n_pairs) {
                if newly_filtered
                    && *state & DROPPED == 0
                    && [i, j].iter().any(|&f| {
                        feature_state
                            .get(f as usize)
                            .is_some_and(|s| s & FILTERED != 0)
                    })
                {
                    *state |= DROPPED;
                    self.pairs_lost += 1;
                }
                let measured = if *state & DROPPED == 0
                    && usable(feature_state, i)
                    && usable(feature_state, j)
                    && (i as usize) < n
                    && (j as usize) < n
                {
                    let (i, j) = (i as usize, j as usize);
                    match (
                        self.current.get(i),
                        self.current.get(j),
                        targets.get(i),
                        targets.get(j),
                    ) {
                        (Some(&ci), Some(&cj), Some(&ti), Some(&tj)) => Some((ci, cj, ti, tj)),
                        _ => None,
                    }
                } else {
                    None
                };
                *difference = match measured {
                    Some((ci, cj, ti, tj)) => {
                        let mu = norm(ci, cj);
                        *length = norm(ti, tj);
                        if let Some(slot) = self.scratch.get_mut(active) {
                            *slot = mu;
                            active += 1;
                        }
                        mu
                    }
                    None => T::of(UNMEASURED),
                };
            }
            let (median, mad, comparisons) =
                median_mad(self.scratch.get_mut(..active).unwrap_or_default());
            work.comparisons += comparisons;
            // `incident_start` holds `n + 1` ascending starts into `incident`, whose entries
            // are pair indices below `n_pairs`.
            let starts = self
                .incident_start
                .iter()
                .zip(self.incident_start.iter().skip(1));
            for (slope, (&lo, &hi)) in self.slope.iter_mut().zip(starts).take(n) {
                let mut m = 0;
                let incident = self
                    .incident
                    .get(lo as usize..hi as usize)
                    .unwrap_or_default();
                for &k in incident {
                    let (Some(&mu), Some(&length)) =
                        (self.difference.get(k as usize), self.length.get(k as usize))
                    else {
                        continue;
                    };
                    if mu >= T::zero()
                        && let Some(slot) = self.scratch.get_mut(m)
                    {
                        *slot = mu / length.max(T::EPS);
                        m += 1;
                    }
                }
                work.pair_visits += incident.len() as u64;
                let sorted = self.scratch.get_mut(..m).unwrap_or_default();
                work.comparisons += sort(sorted);
                *slope = if m >= 3 {
                    quantile_sorted(sorted, T::of(1.0 / 3.0))
                } else {
                    T::zero()
                };
            }
            work.pair_visits += self.n_pairs as u64;
            work.feature_visits += n as u64;
            (active, median, T::of(MAD_TO_SIGMA) * mad)
        }

        /// Step 3, the outliers: a pair is one when `μ_ij` exceeds what the frame explains —
        /// the larger of the frame's median and the smooth field over the pair's length
        /// (`min(sᵢ, sⱼ) ℓ_ij`) — by `outlier_sigmas` robust deviations; with `opening_only`,
        /// only when the residuals diverge along the pair. Counts each feature's measured and
        /// outlier pairs; returns the outliers.
        fn classify_pairs(
            &mut self,
            median: T,
            deviation: T,
            targets: &[[T; 2]],
            n: usize,
            config: &DetectionConfig<T>,
            work: &mut DetectionWork,
        ) -> usize {
            for c in self.pair_counts.iter_mut().take(n) {
                *c = [0, 0];
            }
            let margin = (config.outlier_sigmas * deviation).max(config.min_difference_px);
            let mut outliers = 0;
            // A measured pair (`μ ≥ 0`) has both slots below `n` ([`Detector::measure_pairs`]),
            // so the lookups below do not fail.
            let pairs = self
                .pairs
                .iter()
                .zip(self.pair_state.iter_mut())
                .zip(self.difference.iter().zip(self.length.iter()));
            for ((&[i, j], state), (&mu, &len)) in pairs.take(self.n_pairs) {
                if mu < T::zero() {
                    continue;
                }
                *state &= !OUTLIER;
                let (i, j) = (i as usize, j as usize);
                let (Some(&a), Some(&b), Some(&si), Some(&sj), Some(&di), Some(&dj)) = (
                    targets.get(i),
                    targets.get(j),
                    self.slope.get(i),
                    self.slope.get(j),
                    self.current.get(i),
                    self.current.get(j),
                ) else {
                    continue;
                };
                let smooth = si.min(sj) * len;
                let mut out = mu > median.max(smooth) + margin;
                if out && config.opening_only {
                    // An opening cut leaves the model behind on both lips: across it, the
                    // residuals diverge along the line joining the two features.
                    let (ux, uy) = (b[0] - a[0], b[1] - a[1]);
                    let opening = ((dj[0] - di[0]) * ux + (dj[1] - di[1]) * uy) / len.max(T::EPS);
                    out = opening >= T::of(0.5) * mu;
                }
                if out {
                    *state |= OUTLIER;
                }
                for f in [i, j] {
                    if let Some(c) = self.pair_counts.get_mut(f) {
                        c[0] += 1;
                        c[1] += u32::from(out);
                    }
                }
                outliers += usize::from(out);
            }
            work.pair_visits += self.n_pairs as u64;
            outliers
        }

        /// Step 4, persistence and separation points: an outlier pair between two features that
        /// agree with most of their other neighbours extends its streak; after `persistence`
        /// frames in a row it is split, and its midpoint between the tracked features is a
        /// separation point. Returns the split pairs.
        fn separation_points(
            &mut self,
            frame: u32,
            targets: &[[T; 2]],
            config: &DetectionConfig<T>,
            work: &mut DetectionWork,
        ) -> usize {
            let trusted = |c: &[[u32; 2]], f: u32| {
                c.get(f as usize).is_some_and(|&[all, bad]| {
                    T::of(f64::from(bad)) <= config.max_outlier_fraction * T::of(f64::from(all))
                })
            };
            let mut split = 0;
            self.n_points = 0;
            let pair_counts = &*self.pair_counts;
            let pairs = self
                .pairs
                .iter()
                .zip(self.pair_state.iter_mut())
                .zip(self.difference.iter().zip(self.split_since.iter_mut()));
            for ((&[i, j], pair_state), (&difference, split_since)) in pairs.take(self.n_pairs) {
                // Unmeasured pairs keep their streak (a dropped frame does not reset it).
                if !(difference >= T::zero()) {
                    continue;
                }
                let out = *pair_state & OUTLIER != 0;
                let state = *pair_state;
                // An outlier pair only counts between two features that agree with most of
                // their other neighbours.
                let counts = out && trusted(pair_counts, i) && trusted(pair_counts, j);
                let streak = if counts {
                    ((state & STREAK) + 1).min(STREAK)
                } else {
                    0
                };
                let mut next = (state & !STREAK) | streak;
                if streak >= config.persistence {
                    next |= SPLIT;
                    split += 1;
                    if streak == config.persistence {
                        *split_since = frame;
                    }
                    // The separation point: between the two tracked features, where the cut
                    // runs (a measured pair's slots are within `targets`), while there is room.
                    if let (Some(point), Some(since), Some(&a), Some(&b)) = (
                        self.points.get_mut(self.n_points),
                        self.point_since.get_mut(self.n_points),
                        targets.get(i as usize),
                        targets.get(j as usize),
                    ) {
                        *point = [(a[0] + b[0]) * T::of(0.5), (a[1] + b[1]) * T::of(0.5)];
                        *since = *split_since;
                        self.n_points += 1;
                    }
                }
                *pair_state = next;
            }
            work.pair_visits += self.n_pairs as u64;
            split
        }
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        /// Features on a grid, `n × n`, `spacing` pixels apart.
        fn grid(n: usize, spacing: f64) -> [[f64; 2]; 400] {
            let mut uv = [[0.0; 2]; 400];
            for k in 0..n * n {
                uv[k] = [spacing * (k % n) as f64, spacing * (k / n) as f64];
            }
            uv
        }

        struct Store {
            reals: [f64; 16384],
            indices: [u32; 24576],
        }

        fn store() -> Store {
            Store {
                reals: [0.0; 16384],
                indices: [0; 24576],
            }
        }

        fn detector(s: &mut Store, features: usize, pairs: usize) -> Detector<'_, f64> {
            let mut rs = Slab::new(&mut s.reals, Resource::RealStorage);
            let mut is = Slab::new(&mut s.indices, Resource::IndexStorage);
            Detector::new(features, pairs, &mut rs, &mut is).unwrap()
        }

        fn config() -> DetectionConfig<f64> {
            DetectionConfig {
                radius_px: 15.0,
                ..DetectionConfig::paper()
            }
        }

        #[test]
        fn grid_pairs_are_the_close_ones() {
            let mut s = store();
            let mut det = detector(&mut s, 400, 2000);
            let uv = grid(20, 10.0);
            det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
            // Within 15 px of a grid point 10 px apart: 4 axis and 4 diagonal neighbours (14.1 px):
            // 2·19·20 axis pairs and 2·19·19 diagonal ones.
            assert_eq!(det.pairs().len(), 2 * 19 * 20 + 2 * 19 * 19);
            assert!(det.pairs().iter().all(|&[i, j]| i < j));
        }

        #[test]
        fn features_apart_on_the_object_are_not_paired() {
            let mut s = store();
            let mut det = detector(&mut s, 400, 2000);
            let uv = grid(20, 10.0);
            // A fold along the middle: the two halves of the grid touch in the image only.
            let half = |k: usize| uv[k][0] < 95.0;
            det.init_on_surface(&uv, &[[0.0; 2]; 400], &config(), |i, j, l| {
                assert!(l > 0.0 && l < 15.0);
                half(i) != half(j)
            })
            .unwrap();
            // Each half (10 columns × 20 rows) pairs as a grid of its own.
            let per_half = (9 * 20 + 10 * 19) + 2 * 9 * 19;
            assert_eq!(det.pairs().len(), 2 * per_half);
            assert!(
                det.pairs()
                    .iter()
                    .all(|&[i, j]| half(i as usize) == half(j as usize))
            );
        }

        #[test]
        fn a_surface_ratio_below_one_is_refused() {
            for (ratio, ok) in [
                (0.0, true),
                (1.0, true),
                (3.0, true),
                (0.5, false),
                (f64::NAN, false),
            ] {
                let c = DetectionConfig {
                    max_surface_ratio: ratio,
                    ..config()
                };
                assert_eq!(c.validate().is_ok(), ok, "ratio {ratio}");
            }
        }

        #[test]
        fn rigid_motion_gives_no_outlier() {
            let mut s = store();
            let mut det = detector(&mut s, 400, 2000);
            let uv = grid(20, 10.0);
            det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
            // Every residual the same (the model lags a rigid shift by the same amount everywhere).
            let d = [[3.0, -2.0]; 400];
            for _ in 0..5 {
                let r = det.update(0, &d, &[1; 400], &uv, &config());
                assert_eq!(r.outliers, 0);
                assert_eq!(r.split, 0);
            }
        }

        #[test]
        fn a_clean_jump_across_a_line_gives_separation_points_on_it() {
            let mut s = store();
            let mut det = detector(&mut s, 400, 2000);
            let uv = grid(20, 10.0);
            det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
            // Residuals jump across the vertical line x = 95 (between columns 9 and 10), with a
            // small smooth variation elsewhere.
            let mut d = [[0.0; 2]; 400];
            for k in 0..400 {
                let x = uv[k][0];
                d[k] = if x > 95.0 { [6.0, 0.0] } else { [-6.0, 0.0] };
                d[k][1] = 0.01 * uv[k][1];
            }
            let mut last = DetectionReport::default();
            for frame in 0..3 {
                // Reach the final residuals in one step then hold: the temporal filter sees the
                // same change everywhere, so nothing is filtered.
                let dd = if frame == 0 { [[0.0; 2]; 400] } else { d };
                last = det.update(0, &dd, &[1; 400], &uv, &config());
            }
            assert_eq!(last.features_filtered, 0);
            assert!(last.split > 0);
            for p in det.points() {
                assert!((p[0] - 95.0).abs() <= 5.0 + 1e-12, "{p:?}");
            }
        }

        #[test]
        #[cfg(feature = "temporal-filter")]
        fn a_single_jumping_feature_is_filtered_and_cuts_nothing() {
            let mut s = store();
            let mut det = detector(&mut s, 400, 2000);
            let uv = grid(20, 10.0);
            det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
            let mut d = [[0.0; 2]; 400];
            // Noise-like residuals, then feature 210 jumps by 20 px for three frames.
            for frame in 0..8 {
                for k in 0..400 {
                    // Uniform noise in ±0.5 px from a multiplicative hash.
                    let h = |salt: u64| {
                        let x = ((k as u64 * 40_503 + frame as u64 * 9_973 + salt) * 2_654_435_761)
                            % 1_000_003;
                        x as f64 / 1_000_003.0 - 0.5
                    };
                    d[k] = [h(1), h(7)];
                }
                if (2..5).contains(&frame) {
                    d[210][0] += 20.0;
                }
                let r = det.update(0, &d, &[1; 400], &uv, &config());
                assert_eq!(r.split, 0, "frame {frame}");
            }
            let r = det.update(0, &d, &[1; 400], &uv, &config());
            assert_eq!(r.features_filtered, 1);
            // Feature 210 had 8 neighbours within 15 px.
            assert_eq!(r.pairs_lost, 8);
        }

        #[test]
        fn too_many_pairs_is_a_capacity_error() {
            let mut s = store();
            let mut det = detector(&mut s, 400, 100);
            let uv = grid(20, 10.0);
            let err = det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap_err();
            assert!(matches!(
                err,
                Error::Capacity {
                    resource: Resource::Pairs,
                    available: 100,
                    ..
                }
            ));
            assert!(det.pairs().is_empty());
        }
    }
}
