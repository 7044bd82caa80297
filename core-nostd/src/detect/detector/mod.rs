//! The detector: its storage, set-up at frame 0 and the frame update, whose steps live in
//! `steps.rs`.

use super::{DetectionConfig, DetectionReport, DetectionWork, PairMeasure};
use crate::error::{Error, Resource};
use crate::features::{image_bounds, spacing_px};
use crate::real::Real;
use crate::robust::{
    KEY_WORDS, MAD_TO_SIGMA, from_single_value, median_mad_of, quantile_index, radix_order,
    single_value,
};
#[cfg(all(test, feature = "f64"))]
use crate::robust::{RANK_MAX, quantile_of};
use crate::storage::{Slab, sum, times};

const STREAK: u32 = 0xff;
const SPLIT: u32 = 1 << 8;
const DROPPED: u32 = 1 << 9;
/// Set by the outlier step of this frame, read by the persistence step.
const OUTLIER: u32 = 1 << 10;

const HAS_PREVIOUS: u32 = 1;
const FILTERED: u32 = 2;
/// Observed in the current frame: the features' own flag, copied by the temporal filter's
/// step so that a pair's two ends are one lookup each.
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
    /// Per feature, this frame: measured pairs and outlier pairs (set by the outlier step;
    /// before it, the tertiles' walk holds each feature's rank to find and its pairs seen).
    pair_counts: &'a mut [[u32; 2]],
    /// The pairs in ascending order of their slopes this frame (`order[..n_pairs]`), and the
    /// radix sort's second buffer (`order[n_pairs..2 n_pairs]`).
    order: &'a mut [u32],
    /// Per pair, this frame: `μ_ij`, or [`UNMEASURED`].
    difference: &'a mut [T],
    /// Per feature, this frame: the smooth part of the residual field around it, as a
    /// difference per pixel of pair length (the lower tertile of `μ / ℓ` over its pairs).
    slope: &'a mut [T],
    /// Per pair, this frame: its length `ℓ_ij` in the image (where measured).
    length: &'a mut [T],
    /// Sort space for the robust statistics.
    scratch: &'a mut [T],
    /// Key space of their radix selections ([`crate::robust::select_rounded`]): as many
    /// values as `scratch`, [`KEY_WORDS`] words each. Once the selections of a frame are done
    /// it holds the pairs' slopes as keys for the tertiles' sort, and then the split pairs'
    /// indices, ascending (`keys[..n_split]`, written by
    /// the last step): the cut line looks for the split pairs near a vertex several times a
    /// frame, and scans those alone instead of every pair ([`SplitPairs`]).
    keys: &'a mut [u32],
    /// How many split pairs `keys` lists.
    n_split: usize,
    points: &'a mut [[T; 2]],
    /// Per point: the frame its pair (last) became split.
    point_since: &'a mut [u32],
    /// Per point: its pair (an index into `pairs`).
    point_pair: &'a mut [u32],
    /// Per pair: the frame it (last) became split.
    split_since: &'a mut [u32],
    n_points: usize,
    grid: &'a mut [u32],
    radius: T,
    spacing: T,
    pairs_lost: usize,
    features_filtered: usize,
}

/// The pairs a detector has counted as split ([`Detector::split_pairs`]), read in place: the
/// two features of each lie on opposite lips of a cut. A split pair stays split, so the lips
/// stay known where the mesh has been cut and the model follows them again.
#[derive(Clone, Copy, Debug, Default)]
pub struct SplitPairs<'d> {
    pairs: &'d [[u32; 2]],
    /// The split pairs' indices into `pairs`, ascending.
    split: &'d [u32],
}

impl<'d> SplitPairs<'d> {
    /// The split pairs (feature slots), in the order of the detector's pairs.
    pub fn iter(&self) -> impl Iterator<Item = [u32; 2]> + 'd {
        let pairs = self.pairs;
        self.split
            .iter()
            .filter_map(move |&k| pairs.get(k as usize).copied())
    }

    /// `pairs`, every one split, for the cut line's unit tests (which need `f64`; at most 64
    /// pairs).
    #[cfg(all(test, feature = "f64"))]
    pub(crate) fn for_test(pairs: &'d [[u32; 2]]) -> Self {
        const ALL: [u32; 64] = {
            let mut all = [0; 64];
            let mut k = 0;
            while k < 64 {
                all[k] = k as u32;
                k += 1;
            }
            all
        };
        SplitPairs {
            pairs,
            split: ALL.get(..pairs.len()).unwrap_or(&ALL),
        }
    }

    /// The two feature slots of pair `k` (an index from [`Detector::point_pair`]).
    pub fn slots(&self, k: u32) -> Option<[u32; 2]> {
        self.pairs.get(k as usize).copied()
    }

    /// The pairs a pass over [`SplitPairs::iter`] visits: the split ones (at most the
    /// detector's pair capacity, which the work bounds count).
    pub fn scanned(&self) -> usize {
        self.split.len()
    }
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

/// The larger of two sizes (`const`, for the storage sizes).
const fn larger(a: usize, b: usize) -> usize {
    if a > b { a } else { b }
}

fn norm<T: Real>(a: [T; 2], b: [T; 2]) -> T {
    ((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1])).sqrt()
}

impl<'a, T: Real> Detector<'a, T> {
    /// Scalars of storage for `features` features and `pairs` pairs.
    pub const fn real_len(features: usize, pairs: usize) -> usize {
        sum(&[times(5, features), times(4, pairs), larger(features, pairs)])
    }

    /// Indices of storage.
    pub const fn index_len(features: usize, pairs: usize) -> usize {
        sum(&[
            times(5, pairs),
            times(3, features),
            GRID_CELLS + 1,
            features,
            times(3, pairs),
            times(KEY_WORDS, larger(features, pairs)),
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
            order: indices.take(times(2, pairs))?,
            previous: reals.take(times(2, features))?.as_chunks_mut::<2>().0,
            current: reals.take(times(2, features))?.as_chunks_mut::<2>().0,
            difference: reals.take(pairs)?,
            slope: reals.take(features)?,
            length: reals.take(pairs)?,
            scratch: reals.take(pairs.max(features))?,
            keys: indices.take(times(KEY_WORDS, pairs.max(features)))?,
            n_split: 0,
            points: reals.take(times(2, pairs))?.as_chunks_mut::<2>().0,
            point_since: indices.take(pairs)?,
            point_pair: indices.take(pairs)?,
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
        h.reals(self.difference.iter());
        h.reals(self.length.iter());
        h.reals(self.slope.iter());
        h.reals(self.points.iter().take(self.n_points).flatten());
        h.words(self.point_since.iter().take(self.n_points));
        h.words(self.point_pair.iter().take(self.n_points));
        h.words(self.keys.iter().take(self.n_split));
        h.reals([self.radius, self.spacing].iter());
        h.words(
            [
                self.n_pairs as u32,
                self.n_points as u32,
                self.n_split as u32,
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

    /// Whether pair `k` has been counted as split: with [`Detector::pairs`], for a caller that
    /// draws the split pairs.
    pub fn is_split(&self, k: usize) -> bool {
        self.pair_state.get(k).is_some_and(|s| s & SPLIT != 0)
    }

    /// Whether pair `k` was an outlier in the last frame (its difference beyond what the frame
    /// explains), split or not: with [`Detector::pairs`], for a caller that draws the
    /// detector's evidence.
    pub fn is_outlier(&self, k: usize) -> bool {
        self.pair_state.get(k).is_some_and(|s| s & OUTLIER != 0)
    }

    /// What the outlier test read of pair `k` in the last frame, `None` when it was not
    /// measured then: with [`Detector::pairs`] and the frame's [`DetectionReport`] (its median
    /// and robust deviation), for a caller that studies the evidence. The test itself
    /// ([`crate::detect`]): an outlier when `difference > max(median, smooth) + margin`,
    /// with the margin `max(κ σ̂, min_difference_px)`, and with `opening_only` when the
    /// residuals also diverge along the pair.
    pub fn pair_measure(&self, k: usize) -> Option<PairMeasure<T>> {
        let &[i, j] = self.pairs().get(k)?;
        let difference = *self.difference.get(k)?;
        if !(difference >= T::zero()) {
            return None;
        }
        let length = *self.length.get(k)?;
        let (si, sj) = (*self.slope.get(i as usize)?, *self.slope.get(j as usize)?);
        Some(PairMeasure {
            difference,
            length,
            smooth: si.min(sj) * length,
        })
    }

    /// The pairs counted as split so far, for the cut line to tell the lips apart.
    pub fn split_pairs(&self) -> SplitPairs<'_> {
        SplitPairs {
            pairs: self.pairs(),
            split: self.keys.get(..self.n_split).unwrap_or_default(),
        }
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

    /// Whether the temporal filter has taken the feature in `slot` out of detection (for
    /// good: a tracking failure); `false` for a slot the detector does not hold.
    pub fn is_filtered(&self, slot: usize) -> bool {
        self.feature_state
            .get(slot)
            .is_some_and(|&s| s & FILTERED != 0)
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

    /// For each separation point, its pair: an index for [`SplitPairs::slots`].
    pub fn point_pair(&self) -> &[u32] {
        self.point_pair.get(..self.n_points).unwrap_or_default()
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
    ///
    /// # Errors
    /// As [`Detector::init`]; the pairs left out are not counted against the capacity.
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
            .min(self.pair_counts.len());
        if n > slots || d.len() != n {
            return Err(Error::Capacity {
                resource: Resource::Features,
                needed: n,
                available: slots,
            });
        }
        let Some((lo, hi)) = image_bounds(uv) else {
            self.n_pairs = 0;
            self.n_points = 0;
            self.n_split = 0;
            self.pairs_lost = 0;
            self.features_filtered = 0;
            return Ok(());
        };
        let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
        let spacing = spacing_px(w, h, n);
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
        self.n_split = 0;
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
            .min(self.pair_counts.len());
        let mut work = DetectionWork::default();
        let newly_filtered = self.temporal_filter(d, observed, n, config, &mut work);
        let (active, median, deviation) = self.measure_pairs(newly_filtered, targets, n, &mut work);
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
}

mod steps;

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests;
