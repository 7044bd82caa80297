//! The four steps of `Detector::update`: the temporal filter, the pair differences, the
//! outlier classification and the separation points.

use super::*;

impl<'a, T: Real> Detector<'a, T> {
    /// Step 1, the temporal filter: a feature whose residual changes from the last frame
    /// far more than the others' (beyond the median change plus `temporal_sigmas` robust
    /// deviations) is a tracking failure and is taken out of detection for good. Keeps each
    /// feature's `observed` flag in its state ([`OBSERVED`]) for the steps after it. Returns
    /// whether a feature was taken out this frame.
    pub(super) fn temporal_filter(
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
        // Observed this frame, seen in an earlier one and not filtered out.
        let eligible = |s: u32, o: u32| o != 0 && s & (HAS_PREVIOUS | FILTERED) == HAS_PREVIOUS;
        let mut count = 0usize;
        let slots = self
            .feature_state
            .iter()
            .zip(observed)
            .zip(d.iter().zip(self.current.iter_mut()))
            .zip(self.previous.iter());
        for (((&s, &o), (&di, current)), &previous) in slots.take(n) {
            *current = di;
            if eligible(s, o)
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
            // Every feature takes part, an ineligible one as `+∞` (as the pairs below): the
            // sort costs as much in every frame, the median and MAD are the eligible ones'.
            let (median, mad, steps) = median_mad_of(
                self.scratch.get_mut(..n).unwrap_or_default(),
                count,
                self.keys,
            );
            work.selection_steps += steps;
            let limit = (median + config.temporal_sigmas * T::of(MAD_TO_SIGMA) * mad)
                .max(config.min_difference_px);
            // A feature jumps alone, a tracking failure, when no neighbour's residual changed
            // with it. Where a cut opens under the camera (a scissor advancing), the features
            // of each lip jump together, each with neighbours on its own lip that moved alike:
            // they are the cut's evidence, and are kept. Decided for every feature from the
            // states the frame starts with, every pair visited once whatever the data, so that
            // the work does not depend on it. `scratch` holds each feature's verdict: `0` did
            // not jump (or is not eligible), `1` jumped alone so far, `-1` jumped with a
            // neighbour that jumped alike (a jumper either way, for its other neighbours).
            // An eligible feature's slot of `previous` holds its change from here on (the last
            // pass below sets it to this frame's residual, as every eligible feature is
            // observed), so that each pair end reads it with one lookup.
            let slots = self
                .feature_state
                .iter()
                .zip(observed)
                .zip(self.current.iter().zip(self.previous.iter_mut()));
            for (((&s, &o), (&c, p)), verdict) in slots.zip(self.scratch.iter_mut()).take(n) {
                *verdict = T::zero();
                if eligible(s, o) {
                    if norm(c, *p) > limit {
                        *verdict = T::one();
                    }
                    *p = [c[0] - p[0], c[1] - p[1]];
                }
            }
            let change = |f: usize| self.previous.get(f).copied().unwrap_or([T::zero(); 2]);
            // The verdicts of the first `n` slots: a lookup in them is the test `< n`.
            let verdicts = self.scratch.get_mut(..n).unwrap_or_default();
            for &[a, b] in self.pairs.get(..self.n_pairs).unwrap_or_default() {
                let (a, b) = (a as usize, b as usize);
                let (Some(&va), Some(&vb)) = (verdicts.get(a), verdicts.get(b)) else {
                    continue;
                };
                // Two jumpers (rare) that jumped alike. `‖cₐ − c_b‖` is the same number from
                // either end (the differences only change sign), as when each feature scanned
                // its own pairs.
                if va != T::zero() && vb != T::zero() && norm(change(a), change(b)) <= limit {
                    for f in [a, b] {
                        if let Some(v) = verdicts.get_mut(f) {
                            *v = -T::one();
                        }
                    }
                }
            }
            work.pair_visits += self.n_pairs as u64;
            let slots = self.feature_state.iter_mut().zip(self.scratch.iter());
            for (s, &verdict) in slots.take(n) {
                if verdict > T::zero() {
                    *s |= FILTERED;
                    self.features_filtered += 1;
                    newly_filtered = true;
                }
            }
        }
        let slots = self
            .feature_state
            .iter_mut()
            .zip(observed)
            .zip(d.iter().zip(self.previous.iter_mut()));
        for ((s, &o), (&di, previous)) in slots.take(n) {
            if o != 0 {
                *previous = di;
                *s |= HAS_PREVIOUS | OBSERVED;
            } else {
                *s &= !OBSERVED;
            }
        }
        // The first pass and the last, and the filter's two between them.
        let passes: u64 = if filtering { 4 } else { 2 };
        work.feature_visits += passes * n as u64;
        newly_filtered
    }

    /// Step 2, the differences: `μ_ij` of every pair whose features are both usable, their
    /// median and robust deviation over the frame, and each feature's local slope (the
    /// lower tertile of `μ / ℓ` over its measured pairs: the smooth part of the residual
    /// field around it, which a cut through a third of its neighbourhood does not move).
    /// Returns `(active pairs, median, deviation)`.
    pub(super) fn measure_pairs(
        &mut self,
        newly_filtered: bool,
        targets: &[[T; 2]],
        n: usize,
        work: &mut DetectionWork,
    ) -> (usize, T, T) {
        // The pair buffers hold `n_pairs` entries, `scratch` at least as many (the zip runs
        // over slices of that length, with no bounds check in the loop); a pair is measured
        // when both its slots are below `n`, within `current` and `targets`, which the
        // lookups in the slices cut to `n` check.
        let mut active = 0usize;
        let mut lost = 0usize;
        let feature_state = &*self.feature_state;
        let usable_states = feature_state.get(..n).unwrap_or_default();
        let current = self.current.get(..n).unwrap_or_default();
        let targets = targets.get(..n).unwrap_or_default();
        let np = self.n_pairs;
        if newly_filtered {
            // A pair with a newly filtered end is dropped for good: a pass of its own, in the
            // frames that filter a feature, so that the other frames' loop below does not test
            // for it on every pair.
            let ends = self.pairs.get(..np).unwrap_or_default().iter();
            for (&[i, j], state) in ends.zip(self.pair_state.get_mut(..np).unwrap_or_default()) {
                let filtered = |f: u32| {
                    feature_state
                        .get(f as usize)
                        .is_some_and(|s| s & FILTERED != 0)
                };
                if *state & DROPPED == 0 && (filtered(i) || filtered(j)) {
                    *state |= DROPPED;
                    lost += 1;
                }
            }
        }
        let mut scratch = self.scratch.get_mut(..np).unwrap_or_default().iter_mut();
        let pairs = self
            .pairs
            .get(..np)
            .unwrap_or_default()
            .iter()
            .zip(self.pair_state.get_mut(..np).unwrap_or_default())
            .zip(self.difference.get_mut(..np).unwrap_or_default())
            .zip(self.length.get_mut(..np).unwrap_or_default());
        for (((&[i, j], state), difference), length) in pairs {
            let (i, j) = (i as usize, j as usize);
            let measured = match (
                *state & DROPPED == 0,
                usable_states.get(i),
                usable_states.get(j),
                current.get(i),
                current.get(j),
                targets.get(i),
                targets.get(j),
            ) {
                (true, Some(&si), Some(&sj), Some(&ci), Some(&cj), Some(&ti), Some(&tj))
                    // Both observed this frame, neither filtered out.
                    if (si & sj) & OBSERVED != 0 && (si | sj) & FILTERED == 0 =>
                {
                    Some((ci, cj, ti, tj))
                }
                _ => None,
            };
            *difference = match measured {
                Some((ci, cj, ti, tj)) => {
                    let mu = norm(ci, cj);
                    *length = norm(ti, tj);
                    if let Some(slot) = scratch.next() {
                        *slot = mu;
                        active += 1;
                    }
                    mu
                }
                None => T::of(UNMEASURED),
            };
        }
        self.pairs_lost += lost;
        // The differences' pass, and the drop pass in a frame that filtered a feature.
        work.pair_visits += (np * (1 + usize::from(newly_filtered))) as u64;
        // Every pair in use takes part, an unmeasured one as `+∞` behind the measured ones:
        // the selections cost as much in every frame of a topology, however many pairs are
        // measured, and the median and MAD are those of the measured pairs.
        let (median, mad, steps) = median_mad_of(
            self.scratch.get_mut(..self.n_pairs).unwrap_or_default(),
            active,
            self.keys,
        );
        work.selection_steps += steps;
        // Each feature's lower tertile of its pairs' slopes `μ / ℓ`, rounded to single
        // precision as the selections round ([`single_value`]): the pairs are walked once in
        // ascending order of slope, and a feature's tertile is the slope of its pair of rank
        // `⌊(m − 1)/3⌋` among its `m` measured ones (unmeasured pairs order last, as `+∞`).
        // Every pair takes part, so that the work is that of the topology, however many
        // pairs are measured.
        //
        // First each pair's slope as a key (the bits of a non-negative `f32` order as the
        // values do) in `keys`, which holds a word for each of the `n_pairs` pairs, and each
        // feature's measured pairs counted in its `pair_counts` (which the outlier step
        // resets for its own counts).
        let counts = self.pair_counts.get_mut(..n).unwrap_or_default();
        for c in counts.iter_mut() {
            *c = [0, 0];
        }
        let infinite = f32::INFINITY.to_bits();
        let pairs = self.pairs.get(..np).unwrap_or_default();
        let slopes = self
            .difference
            .get(..np)
            .unwrap_or_default()
            .iter()
            .zip(self.length.get(..np).unwrap_or_default());
        for ((key, &[i, j]), (&mu, &length)) in self.keys.iter_mut().zip(pairs).zip(slopes) {
            *key = if mu >= T::zero() {
                single_value(mu / length.max(T::EPS)).to_bits()
            } else {
                infinite
            };
            // A finite slope is a measured pair's (whose slots are below `n`).
            if *key < infinite {
                for f in [i, j] {
                    if let Some(c) = counts.get_mut(f as usize) {
                        c[0] += 1;
                    }
                }
            }
        }
        // Each feature's rank to find (none below three measured pairs, whose slope is zero)
        // in its first count, the pairs of it seen so far in its second.
        let slopes_out = self.slope.get_mut(..n).unwrap_or_default();
        for (c, slope) in counts.iter_mut().zip(slopes_out.iter_mut()) {
            let m = c[0] as usize;
            c[0] = if m >= 3 {
                quantile_index(m, T::of(1.0 / 3.0)) as u32
            } else {
                u32::MAX
            };
            *slope = T::zero();
        }
        // The pairs in ascending order of slope, in the first half of `order` (the second is
        // the sort's other buffer).
        let keys = self.keys.get(..np).unwrap_or_default();
        let (order, spare) = self.order.split_at_mut(np.min(self.order.len()));
        let sorted = radix_order(keys, order, spare);
        work.selection_steps += sorted;
        // No steps: `order` or its spare half too short for the pairs (never, as the storage
        // is carved), and no order to walk: the slopes stay zero.
        let order = if sorted > 0 { &*order } else { &[] };
        for &k in order {
            let (Some(&key), Some(&[i, j])) = (keys.get(k as usize), pairs.get(k as usize)) else {
                continue;
            };
            for f in [i, j] {
                if let (Some(c), Some(slope)) =
                    (counts.get_mut(f as usize), slopes_out.get_mut(f as usize))
                {
                    if c[1] == c[0] {
                        *slope = from_single_value(f32::from_bits(key));
                    }
                    c[1] += 1;
                }
            }
        }
        // The slopes and the walk.
        work.pair_visits += 2 * np as u64;
        // The counts' reset, and the ranks and slopes set.
        work.feature_visits += 2 * n as u64;
        (active, median, T::of(MAD_TO_SIGMA) * mad)
    }

    /// Step 3, the outliers: a pair is one when `μ_ij` exceeds what the frame explains —
    /// the larger of the frame's median and the smooth field over the pair's length
    /// (`min(sᵢ, sⱼ) ℓ_ij`) — by `outlier_sigmas` robust deviations; with `opening_only`,
    /// only when the residuals diverge along the pair. Counts each feature's measured and
    /// outlier pairs; returns the outliers.
    pub(super) fn classify_pairs(
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
        work.feature_visits += n as u64;
        let margin = (config.outlier_sigmas * deviation).max(config.min_difference_px);
        let mut outliers = 0;
        // A measured pair (`μ ≥ 0`) has both slots below `n` ([`Detector::measure_pairs`]),
        // so the lookups below do not fail. The per-pair buffers hold at least `n_pairs`
        // slots (the zips run over slices of that length, with no bounds check in the loop).
        let np = self.n_pairs;
        let pairs = self
            .pairs
            .get(..np)
            .unwrap_or_default()
            .iter()
            .zip(self.pair_state.get_mut(..np).unwrap_or_default())
            .zip(self.difference.get(..np).unwrap_or_default())
            .zip(self.length.get(..np).unwrap_or_default());
        for (((&[i, j], state), &mu), &len) in pairs {
            // Cleared on every pair, so that one not measured this frame is not reported as an
            // outlier of it ([`Detector::is_outlier`]).
            *state &= !OUTLIER;
            if mu < T::zero() {
                continue;
            }
            let (i, j) = (i as usize, j as usize);
            let (Some(&si), Some(&sj)) = (self.slope.get(i), self.slope.get(j)) else {
                continue;
            };
            let smooth = si.min(sj) * len;
            let mut out = mu > median.max(smooth) + margin;
            if out && config.opening_only {
                // An opening cut leaves the model behind on both lips: across it, the
                // residuals diverge along the line joining the two features.
                let (Some(&a), Some(&b), Some(&di), Some(&dj)) = (
                    targets.get(i),
                    targets.get(j),
                    self.current.get(i),
                    self.current.get(j),
                ) else {
                    continue;
                };
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
    /// separation point. Lists every split pair, measured this frame or not, in `keys` for
    /// [`Detector::split_pairs`]. Returns how many pairs are split and measured this frame.
    pub(super) fn separation_points(
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
        // Counted in locals and stored at the end, so that the loop keeps them in registers.
        let mut n_points = 0;
        // The selections are done with `keys`: it lists the split pairs from here on.
        let mut n_split = 0;
        let pair_counts = &*self.pair_counts;
        // Every per-pair buffer holds at least `n_pairs` slots: the zips below run over all
        // of them, on slices of one length, with no bounds check left in the loop.
        let np = self.n_pairs;
        let pairs = self
            .pairs
            .get(..np)
            .unwrap_or_default()
            .iter()
            .zip(self.pair_state.get_mut(..np).unwrap_or_default())
            .zip(self.difference.get(..np).unwrap_or_default())
            .zip(self.split_since.get_mut(..np).unwrap_or_default());
        for (k, (((&[i, j], pair_state), &difference), split_since)) in pairs.enumerate() {
            // Unmeasured pairs keep their streak (a dropped frame does not reset it).
            if difference >= T::zero() {
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
                    if let (Some(point), Some(since), Some(pair), Some(&a), Some(&b)) = (
                        self.points.get_mut(n_points),
                        self.point_since.get_mut(n_points),
                        self.point_pair.get_mut(n_points),
                        targets.get(i as usize),
                        targets.get(j as usize),
                    ) {
                        *point = [(a[0] + b[0]) * T::of(0.5), (a[1] + b[1]) * T::of(0.5)];
                        *since = *split_since;
                        // `k < n_pairs`, which fits the `u32` slots.
                        *pair = k as u32;
                        n_points += 1;
                    }
                }
                *pair_state = next;
            }
            // Split now or before: listed for the cut line (`keys` holds a word per pair).
            if *pair_state & SPLIT != 0
                && let Some(slot) = self.keys.get_mut(n_split)
            {
                *slot = k as u32;
                n_split += 1;
            }
        }
        self.n_points = n_points;
        self.n_split = n_split;
        work.pair_visits += self.n_pairs as u64;
        split
    }
}
