//! Growing the cut line: its robust start, following the separation points, advancing a front,
//! and anchoring each vertex to the tracked features around it.

use super::*;
use crate::detect::SplitPairs;

impl<'a, T: Real> CutLine<'a, T> {
    /// Fits the line (robustly, then by total least squares) and places its two ends.
    /// `pairs[k]` is point `k`'s pair in `tracked.split`.
    pub(super) fn start(
        &mut self,
        frame: u32,
        points: &[[T; 2]],
        pairs: &[u32],
        tracked: &Tracked<'_, T>,
        rules: &Rules<T>,
        work: &mut LineWork,
    ) -> usize {
        let pts = points.get(..FIT_POINTS).unwrap_or(points);
        // Each point's pair (its two feature slots) and how it opens: the second feature's
        // residual less the first's.
        let mut slots = [[NO_SLOT; 2]; FIT_POINTS];
        let mut opening = [[T::zero(); 2]; FIT_POINTS];
        for ((s, o), &k) in slots.iter_mut().zip(opening.iter_mut()).zip(pairs) {
            if let Some([a, b]) = tracked.split.slots(k)
                && let (Some(ra), Some(rb)) = (
                    tracked.residuals.get(a as usize),
                    tracked.residuals.get(b as usize),
                )
            {
                *s = [a, b];
                *o = sub(*rb, *ra);
            }
        }
        let tol = rules.tolerance;
        let f = pts.len() as u64;
        // Of the lines through two separation points, the one that most points support:
        // spurious clusters (a tracking failure, a region where the model is poor) then do not
        // tilt the line. A point supports a line within the tolerance of it whose pair opens
        // across it ([`crosses`]): where the lips part beside a cut's tip, the pairs between
        // a lip and the material beyond the tip open along the line their midpoints make
        // there, and would otherwise start the line across the cut instead of along it. And
        // no feature may be in all the supporting pairs but one ([`carried_by_one`]).
        let supports = |p: &[T; 2], o: &[T; 2], p_i: [T; 2], d: [T; 2], len: T| {
            (cross(d, sub(*p, p_i)) / len).abs() <= tol && crosses(*o, d)
        };
        // The support and the two points of the best line.
        let mut best = (0usize, [T::zero(); 2], [T::zero(); 2]);
        for (i, &p_i) in pts.iter().enumerate() {
            for &p_j in pts.iter().skip(i + 1) {
                let d = sub(p_j, p_i);
                let len = length(d);
                if !(len > T::EPS) {
                    continue;
                }
                // One pass: the supporting points' pairs, gathered for the check below.
                let mut supporting = [[NO_SLOT; 2]; FIT_POINTS];
                let mut count = 0;
                work.fit_tests += f;
                for ((p, o), s) in pts.iter().zip(&opening).zip(&slots) {
                    if supports(p, o, p_i, d, len)
                        && let Some(slot) = supporting.get_mut(count)
                    {
                        *slot = *s;
                        count += 1;
                    }
                }
                if count <= best.0 {
                    continue;
                }
                work.fit_tests += CARRIED_BY_ONE_VISITS * f;
                if !carried_by_one(supporting.get(..count).unwrap_or_default()) {
                    best = (count, p_i, p_j);
                }
            }
        }
        if best.0 < rules.init_points {
            return 0;
        }
        let (pi, d) = (best.1, sub(best.2, best.1));
        let dl = length(d);
        let inlier = |(p, o): &(&[T; 2], &[T; 2])| supports(p, o, pi, d, dl);
        // Then total least squares on the inliers: the principal direction of their scatter.
        work.fit_tests += 3 * f;
        let n = T::of(best.0 as f64);
        let mut c = [T::zero(); 2];
        for (p, _) in pts.iter().zip(&opening).filter(inlier) {
            c[0] += p[0] / n;
            c[1] += p[1] / n;
        }
        let (mut sxx, mut sxy, mut syy) = (T::zero(), T::zero(), T::zero());
        for (p, _) in pts.iter().zip(&opening).filter(inlier) {
            let d = sub(*p, c);
            sxx += d[0] * d[0];
            sxy += d[0] * d[1];
            syy += d[1] * d[1];
        }
        // No test of how line-like the inliers are: they lie within the tolerance of a line
        // through two of them, and the rules above refuse what made clouds and rings (one
        // feature's fan, pairs that open along the line). A bound on the spread across the
        // fitted line over the spread along it (at most 0.25 once) then refused only the
        // first few points of real cuts, a spacing or two long, and delayed their start.
        // Points that coincide have no direction: the ends below are then equal, and refused.
        let angle = T::of(0.5) * (T::of(2.0) * sxy).libm_atan2(sxx - syy);
        let (sin, cos) = angle.libm_sin_cos();
        let e = [cos, sin];
        let (mut lo, mut hi) = (T::zero(), T::zero());
        for (p, _) in pts.iter().zip(&opening).filter(inlier) {
            let t = sub(*p, c)[0] * e[0] + sub(*p, c)[1] * e[1];
            lo = lo.min(t);
            hi = hi.max(t);
        }
        let a = [c[0] + e[0] * lo, c[1] + e[1] * lo];
        let b = [c[0] + e[0] * hi, c[1] + e[1] * hi];
        work.anchor_visits += 2 * tracked.anchor_cost();
        match (
            anchor_across(a, e, tracked, rules.lip_reach),
            anchor_across(b, e, tracked, rules.lip_reach),
        ) {
            (Some((aa, wa)), Some((ab, wb))) if hi > lo => {
                // [`CutLine::update`] starts the line only with room for two vertices.
                let ([a0, a1, ..], [w0, w1, ..]) = (&mut *self.anchors, &mut *self.weights) else {
                    return 0;
                };
                *a0 = aa;
                *w0 = wa;
                *a1 = ab;
                *w1 = wb;
                self.n = 2;
                self.direction = [[-e[0], -e[1]], e];
                self.moved = [frame; 2];
                self.detected_frame = Some(frame);
                2
            }
            _ => 0,
        }
    }

    /// Keeps the line on its evidence. A vertex anchored while the cut was narrow stays at the
    /// same fraction of the way between the lips as they part, which need not be the middle;
    /// the separation points (midpoints of pairs across the cut) are. Each vertex with enough
    /// of them within a maximum step moves across the line (not along it) to their mean and is
    /// anchored again there. Where the model is cut there are no separation points left and
    /// the vertex stays where its anchors on both lips hold it. `projected` are the vertices'
    /// current pixels.
    ///
    /// Every vertex follows, those already applied to the mesh too. Holding those where they
    /// are was tried: the liver's line ended nearer its cut (73 → 69 px, Dice 0.936 → 0.948)
    /// but its front still hooked down the lobe, its targets ended further out (1.07 →
    /// 1.60 mm), and the side cut lost (Dice 0.990 → 0.987).
    pub(super) fn follow_points(
        &mut self,
        points: &[[T; 2]],
        tracked: &Tracked<'_, T>,
        rules: &Rules<T>,
        projected: &[[T; 2]],
        work: &mut LineWork,
    ) {
        let m = projected.len();
        if m < 2 {
            return;
        }
        for (k, &v) in projected.iter().enumerate() {
            let (Some(&a), Some(&b)) = (
                projected.get(k.saturating_sub(1)),
                projected.get((k + 1).min(m - 1)),
            ) else {
                continue;
            };
            let t = sub(b, a);
            let len = length(t);
            if !(len > T::EPS) {
                continue;
            }
            let normal = [-t[1] / len, t[0] / len];
            let across = |p: &[T; 2], reach: T| -> Option<T> {
                let w = sub(*p, v);
                (length(w) <= reach).then(|| w[0] * normal[0] + w[1] * normal[1])
            };
            let (mut offset, mut count) = (T::zero(), 0u32);
            work.point_visits += points.len() as u64;
            for d in points.iter().filter_map(|p| across(p, rules.max_step)) {
                offset += d;
                count += 1;
            }
            if count < rules.min_support {
                continue;
            }
            let shift = offset / T::of(f64::from(count));
            let target = [v[0] + normal[0] * shift, v[1] + normal[1] * shift];
            work.anchor_visits += tracked.anchor_cost();
            // `projected` holds one pixel per vertex (`k < n`).
            if let Some((anchor, w)) = anchor_across(target, t, tracked, rules.lip_reach)
                && let (Some(sa), Some(sw)) = (self.anchors.get_mut(k), self.weights.get_mut(k))
            {
                *sa = anchor;
                *sw = w;
            }
        }
    }

    /// Where a front at `v` heading `u` moves, if enough `fresh` points ahead, inside the
    /// angle `α` and within [`REACH_STEPS`] maximum steps, support it: toward their mean, by at most the
    /// maximum step.
    ///
    /// `α` decides which points count, not only how far the front may turn. Counting every
    /// fresh point ahead (within 90°) and clamping the turn to `α` let the fronts chase
    /// points off the cut: the live cut's and the liver's lines closed more of their deficit
    /// (16 → 34 %, 21 → 36 %), but the liver's looped round its lobe (its distance to the
    /// true cut 73 → 145 px, its targets 1.07 → 1.35 mm) and the middle cut's zig-zagged
    /// (11 → 41 px). The price of this rule is a front that cannot turn: the live cut's top
    /// front, heading 17° off its slit, never sees the slit's tip inside its angle again.
    /// Turning a front, before each advance, to the principal axis of the separation points
    /// around it (old and fresh, within the same reach) does not free it: the live cut's line
    /// then bent along the opening at the band's edge and zig-zagged (its deficit closed
    /// 16 → 17 %), and no other scene moved.
    pub(super) fn advance(
        v: [T; 2],
        u: [T; 2],
        points: &[[T; 2]],
        fresh: impl Fn(usize) -> bool,
        rules: &Rules<T>,
    ) -> Option<([T; 2], [T; 2])> {
        let cos_alpha = rules.cos_alpha;
        let (mut sum, mut count) = ([T::zero(); 2], 0u32);
        for (k, p) in points.iter().enumerate() {
            if !fresh(k) {
                continue;
            }
            let w = sub(*p, v);
            let d = length(w);
            if d > T::EPS
                && d <= T::of(REACH_STEPS) * rules.max_step
                && (w[0] * u[0] + w[1] * u[1]) >= cos_alpha * d
            {
                sum[0] += w[0];
                sum[1] += w[1];
                count += 1;
            }
        }
        if count < rules.min_support {
            return None;
        }
        let mean = [
            sum[0] / T::of(f64::from(count)),
            sum[1] / T::of(f64::from(count)),
        ];
        let len = length(mean);
        if len < rules.min_step || !(len > T::zero()) {
            return None;
        }
        let dir = [mean[0] / len, mean[1] / len];
        let step = len.min(rules.max_step).max(rules.min_step);
        Some(([v[0] + dir[0] * step, v[1] + dir[1] * step], dir))
    }

    /// Adds a vertex at the start (`end == 0`) or the end of the line. The caller checks that
    /// there is room (`n` below the capacity); without room nothing changes.
    pub(super) fn insert(&mut self, end: usize, anchor: [u32; ANCHORS], w: [T; ANCHORS]) {
        let n = self.n;
        let (Some(anchors), Some(weights)) =
            (self.anchors.get_mut(..=n), self.weights.get_mut(..=n))
        else {
            return;
        };
        let slots = if end == 0 {
            // Vertices `0..n` move to `1..=n`.
            anchors.rotate_right(1);
            weights.rotate_right(1);
            (anchors.first_mut(), weights.first_mut())
        } else {
            (anchors.last_mut(), weights.last_mut())
        };
        if let (Some(sa), Some(sw)) = slots {
            *sa = anchor;
            *sw = w;
        }
        self.n += 1;
    }
}

/// Anchors image point `p` on a line running along `tangent` to the features on both lips:
/// half of it follows three features on one lip (their affine combination, which may
/// extrapolate a little), half three on the other. As the cut opens, each half moves with its
/// lip and the vertex stays between them; anchored to one triangle across the cut, it would
/// slide toward whichever lip holds more of the triangle's weight.
///
/// Which lip a feature is on is read from the detector where it can be: with at least
/// [`MIN_LIP_PAIRS`] split pairs near `p` (`split`, the [`LIP_PAIRS`] nearest within `reach`
/// pixels, by their midpoints), each half is anchored to the features of those pairs on one
/// side, each pair oriented across the line. A split pair spans the cut wherever the line lies,
/// so a vertex placed a little off the cut (a line fitted while few points existed, or a tilted
/// one) is still held by both lips. Split by the side of the line instead, the features
/// between the line and the cut count for the wrong lip, and the vertex drifts with one lip
/// as the cut opens. Reading the lips, `band-middle-cut`'s cut closes 69 % of the deficit
/// instead of 53 % (though its line ends 33 px from the true cut instead of 22), the liver's
/// line 73 px instead of 100, and the median line distance of the scene families falls from
/// 12.2 to 9.0 % of the diagonal (band), 8.7 to 7.5 (dome), 8.6 to 8.1 (liver). A vertex placed
/// before the pairs around it split (the liver's lower end, at frame 7) still holds one lip
/// only; anchoring it anew once they split keeps the liver's line on its cut (12 % → 4 %) but
/// folds other lines back on themselves, so it is not done. With fewer pairs,
/// or without a usable triangle on each lip, the features of the pairs keep their lip and each
/// other feature is given one by [`Lips::side_of`]: by how it moves where that is clear, else
/// by its side of the cut as the pairs place it. Where one side has no usable feature near (the
/// line's end at the object's edge), the three features around `p` hold it. `None` when
/// nothing works.
pub(super) fn anchor_across<T: Real>(
    p: [T; 2],
    tangent: [T; 2],
    tracked: &Tracked<'_, T>,
    reach: T,
) -> Option<([u32; ANCHORS], [T; ANCHORS])> {
    let Tracked {
        features,
        residuals,
        usable,
        split,
    } = tracked;
    let normal = [-tangent[1], tangent[0]];
    let across = |f: &[T; 2]| {
        let d = sub(*f, p);
        d[0] * normal[0] + d[1] * normal[1]
    };
    let lips = Lips::near(p, features, residuals, split, reach, &across);
    anchor_halves(p, tracked, &lips, &across, true)
        .or_else(|| anchor_halves(p, tracked, &lips, &across, false))
        .or_else(|| {
            anchor_at(p, features, usable).map(|(a, w)| {
                (
                    [a[0], a[1], a[2], a[0], a[1], a[2]],
                    [w[0], w[1], w[2], T::zero(), T::zero(), T::zero()],
                )
            })
        })
}

/// Half of `p` on three features of each lip ([`anchor_across`]), `lips` the split pairs near
/// it and `across` a feature's offset across the line: with `lips_only`, the lips are the
/// features of those pairs alone (`None` with fewer than
/// [`MIN_LIP_PAIRS`] of them); without, those features keep their pair's side and the others
/// are given one by [`Lips::side_of`].
fn anchor_halves<T: Real>(
    p: [T; 2],
    tracked: &Tracked<'_, T>,
    lips: &Lips<T>,
    across: &impl Fn(&[T; 2]) -> T,
    lips_only: bool,
) -> Option<([u32; ANCHORS], [T; ANCHORS])> {
    if lips_only && lips.n < 2 * MIN_LIP_PAIRS {
        return None;
    }
    let (features, usable) = (tracked.features, tracked.usable);
    let side = |positive: bool| {
        move |i: usize, f: &[T; 2]| match lips.side(i) {
            Some(s) => s == positive,
            None => !lips_only && lips.side_of(*f, tracked.residuals.get(i), across) == positive,
        }
    };
    // With `lips_only`, the candidates of a side are the lips' features on it: scanned
    // alone (in slot order, as the whole scan meets them) instead of every feature. Without,
    // every feature is on one side or the other: one scan fills both sides' nearest.
    let ((a, wa), (b, wb)) = if lips_only {
        let half = |positive: bool| {
            let (on, m) = lips.slots_on(positive);
            let on = on.get(..m).unwrap_or_default();
            anchor_among(
                p,
                features,
                usable,
                on.iter().map(|&s| s as usize),
                side(positive),
            )
        };
        half(true).zip(half(false))?
    } else {
        let [positive, negative] = nearest_on_sides(p, features, usable, side(true));
        best_triangle(p, features, &positive).zip(best_triangle(p, features, &negative))?
    };
    let half = T::of(0.5);
    Some((
        [a[0], a[1], a[2], b[0], b[1], b[2]],
        [
            wa[0] * half,
            wa[1] * half,
            wa[2] * half,
            wb[0] * half,
            wb[1] * half,
            wb[2] * half,
        ],
    ))
}

/// Split pairs whose sides [`anchor_across`] reads near one point.
const LIP_PAIRS: usize = 8;

/// Split pairs near a point from which [`anchor_across`] anchors it to their features alone.
const MIN_LIP_PAIRS: usize = 3;

/// The features of the split pairs nearest a point, each with its lip (`true` for the side the
/// line's normal points to), and the cut as those pairs see it.
struct Lips<T> {
    slots: [(u32, bool); 2 * LIP_PAIRS],
    n: usize,
    /// Bit `slot % 64` set for each of `slots`: a feature whose bit is clear is in none of
    /// the pairs, told without the scan ([`Lips::side`] is asked of every feature a nearest
    /// list would take).
    mask: u64,
    /// Where the pairs place the cut, if any pair is near: see [`PairsCut`].
    cut: Option<PairsCut<T>>,
}

/// The cut near a point as its split pairs see it: each pair spans it, so their midpoints
/// lie on it (to within half a pair's length) and their directions cross it; and the
/// features of each lip move alike, apart from the other lip's.
#[derive(Clone, Copy)]
struct PairsCut<T> {
    /// The pairs' mean midpoint.
    centre: [T; 2],
    /// The mean of the pairs' unit vectors from the negative lip's feature to the positive
    /// one's: the cut's normal, pointing to the positive lip.
    normal: [T; 2],
    /// The mean residual of the positive lip's features and of the negative lip's.
    motion: [[T; 2]; 2],
}

impl<T: Real> Lips<T> {
    /// The [`LIP_PAIRS`] split pairs whose midpoints lie nearest `p` within `reach`, each
    /// oriented by which of its features lies further along the line's normal (`across`).
    fn near(
        p: [T; 2],
        features: &[[T; 2]],
        residuals: &[[T; 2]],
        split: &SplitPairs<'_>,
        reach: T,
        across: &impl Fn(&[T; 2]) -> T,
    ) -> Lips<T> {
        let mut near: [(T, [u32; 2]); LIP_PAIRS] = [(reach, [u32::MAX; 2]); LIP_PAIRS];
        let mut found = 0;
        for [i, j] in split.iter() {
            let (Some(a), Some(b)) = (features.get(i as usize), features.get(j as usize)) else {
                continue;
            };
            let mid = [(a[0] + b[0]) * T::of(0.5), (a[1] + b[1]) * T::of(0.5)];
            let d = length(sub(mid, p));
            // The list starts full of `reach`: a pair at or beyond it never enters.
            if d < near[LIP_PAIRS - 1].0 {
                found = keep_nearest(&mut near, found, d, [i, j]);
            }
        }
        let mut lips = Lips {
            slots: [(u32::MAX, false); 2 * LIP_PAIRS],
            n: 0,
            mask: 0,
            cut: None,
        };
        // Sums over the pairs: midpoints, unit directions, the positive and the negative lip's
        // residuals.
        let (mut centre, mut normal) = ([T::zero(); 2], [T::zero(); 2]);
        let mut motion = [[T::zero(); 2]; 2];
        let mut counted = 0u32;
        for &(_, [i, j]) in near.iter().take(found) {
            let (Some(a), Some(b), Some(ra), Some(rb)) = (
                features.get(i as usize),
                features.get(j as usize),
                residuals.get(i as usize),
                residuals.get(j as usize),
            ) else {
                continue;
            };
            let i_positive = across(a) > across(b);
            let ((fp, rp), (fn_, rn)) = if i_positive {
                ((a, ra), (b, rb))
            } else {
                ((b, rb), (a, ra))
            };
            let u = sub(*fp, *fn_);
            let l = length(u);
            if !(l > T::EPS) {
                continue;
            }
            let half = T::of(0.5);
            centre = [
                centre[0] + (fp[0] + fn_[0]) * half,
                centre[1] + (fp[1] + fn_[1]) * half,
            ];
            normal = [normal[0] + u[0] / l, normal[1] + u[1] / l];
            let [plus, minus] = motion;
            motion = [
                [plus[0] + rp[0], plus[1] + rp[1]],
                [minus[0] + rn[0], minus[1] + rn[1]],
            ];
            counted += 1;
            for (slot, positive) in [(i, i_positive), (j, !i_positive)] {
                if let Some(s) = lips.slots.get_mut(lips.n) {
                    *s = (slot, positive);
                    lips.n += 1;
                    lips.mask |= 1 << (slot % 64);
                }
            }
        }
        let norm = length(normal);
        if counted > 0 && norm > T::EPS {
            let k = T::of(f64::from(counted));
            lips.cut = Some(PairsCut {
                centre: centre.map(|x| x / k),
                normal: normal.map(|x| x / norm),
                motion: motion.map(|m| m.map(|x| x / k)),
            });
        }
        lips
    }

    /// The lip of a feature at `f` with residual `residual` that is in none of the pairs
    /// (`true` for the positive one). By how it moves, where that is clear: its residual is
    /// nearer one lip's mean residual than the other's by more than half the distance between
    /// the two means (on the segment between them, within a quarter of the way from one end;
    /// a lip is what moves together, the detector's own evidence). Otherwise by its side of the cut as
    /// the pairs place it ([`PairsCut`]), not of the line: a line's end can lie a spacing off
    /// the cut, or tilted across it, and the features between the two would count for the
    /// wrong lip. Without pairs, by the side of the line (`across`).
    ///
    /// Before, every such feature went by the side of the line: the liver's lower end, placed
    /// at frame 7 with a tilted line and one lip's pairs from two features only, held the
    /// right lip with both halves and moved 85 px with it, its line ending 70 px from the cut
    /// (now 25 px; `band-live-cut` 27 → 20 px).
    fn side_of(
        &self,
        f: [T; 2],
        residual: Option<&[T; 2]>,
        across: &impl Fn(&[T; 2]) -> T,
    ) -> bool {
        let Some(cut) = self.cut else {
            return across(&f) > T::zero();
        };
        if let Some(r) = residual {
            let [plus, minus] = cut.motion;
            let (to_plus, to_minus) = (length(sub(*r, plus)), length(sub(*r, minus)));
            // `|d₊ − d₋| > D / 2`, `D` the distance between the means.
            if (to_plus - to_minus).abs() > T::of(0.5) * length(sub(plus, minus)) {
                return to_plus < to_minus;
            }
        }
        let d = sub(f, cut.centre);
        d[0] * cut.normal[0] + d[1] * cut.normal[1] > T::zero()
    }

    /// The lip of feature `slot`, if it belongs to one of the pairs.
    fn side(&self, slot: usize) -> Option<bool> {
        if self.mask & (1 << (slot % 64)) == 0 {
            return None;
        }
        self.slots
            .iter()
            .take(self.n)
            .find(|(s, _)| *s as usize == slot)
            .map(|(_, positive)| *positive)
    }

    /// The features whose [`Lips::side`] is `positive`, ascending, each once, and how many.
    fn slots_on(&self, positive: bool) -> ([u32; 2 * LIP_PAIRS], usize) {
        let mut on = [0u32; 2 * LIP_PAIRS];
        let mut m = 0;
        let slots = self.slots.get(..self.n).unwrap_or_default();
        for (k, &(slot, side)) in slots.iter().enumerate() {
            // A feature's side is its first entry's, as `side` finds it.
            let first = slots.iter().take(k).all(|&(s, _)| s != slot);
            if first
                && side == positive
                && let Some(o) = on.get_mut(m)
            {
                *o = slot;
                m += 1;
            }
        }
        if let Some(on) = on.get_mut(..m) {
            on.sort_unstable();
        }
        (on, m)
    }
}

/// Anchors image point `p` to three usable features around it, as their affine combination
/// (weights sum to one): of the triangles of its six nearest usable features, the one that
/// contains `p` most centrally (largest smallest weight). A point on a cut is then held by
/// features on both lips and stays between them as the cut opens. If no triangle contains
/// `p`, the best-shaped one of the nearest is used. `None` with fewer than three usable
/// features or only collinear ones.
pub(super) fn anchor_at<T: Real>(
    p: [T; 2],
    features: &[[T; 2]],
    usable: &[u32],
) -> Option<([u32; 3], [T; 3])> {
    anchor_where(p, features, usable, |_, _| true)
}

/// [`anchor_at`] among the features that `keep` accepts.
pub(super) fn anchor_where<T: Real>(
    p: [T; 2],
    features: &[[T; 2]],
    usable: &[u32],
    keep: impl Fn(usize, &[T; 2]) -> bool,
) -> Option<([u32; 3], [T; 3])> {
    anchor_among(p, features, usable, 0..features.len(), keep)
}

/// [`anchor_where`] among the feature slots `slots` (ascending, each once): with every slot
/// that `keep` accepts among them, the same result as the scan of all.
fn anchor_among<T: Real>(
    p: [T; 2],
    features: &[[T; 2]],
    usable: &[u32],
    slots: impl Iterator<Item = usize>,
    keep: impl Fn(usize, &[T; 2]) -> bool,
) -> Option<([u32; 3], [T; 3])> {
    // The six nearest usable features, by insertion into a small sorted list.
    let mut near = Nearest::new();
    for i in slots {
        let Some(f) = features.get(i) else {
            continue;
        };
        if usable.get(i).is_none_or(|&u| u == 0) {
            continue;
        }
        let d = length(sub(*f, p));
        // `keep` (a lookup among the lips) only for a feature that would enter the list.
        if near.would_keep(d) && keep(i, f) {
            near.keep(d, i as u32);
        }
    }
    best_triangle(p, features, &near)
}

/// The [`Nearest`] usable features to `p` on each side, `[positive, negative]`, as
/// [`anchor_among`] finds each over every slot with `keep` and its negation, in one scan:
/// `positive(i, f)` is asked once of a feature that would enter either list.
fn nearest_on_sides<T: Real>(
    p: [T; 2],
    features: &[[T; 2]],
    usable: &[u32],
    positive: impl Fn(usize, &[T; 2]) -> bool,
) -> [Nearest<T>; 2] {
    let (mut plus, mut minus) = (Nearest::new(), Nearest::new());
    for (i, f) in features.iter().enumerate() {
        if usable.get(i).is_none_or(|&u| u == 0) {
            continue;
        }
        let d = length(sub(*f, p));
        let (to_plus, to_minus) = (plus.would_keep(d), minus.would_keep(d));
        if to_plus || to_minus {
            let on_plus = positive(i, f);
            if on_plus && to_plus {
                plus.keep(d, i as u32);
            } else if !on_plus && to_minus {
                minus.keep(d, i as u32);
            }
        }
    }
    [plus, minus]
}

/// Features a point is anchored among: its six nearest (of which 20 triangles).
const NEAREST: usize = 6;

/// Features nearest a point: the [`NEAREST`] nearest so far, by insertion into a small sorted
/// list.
struct Nearest<T> {
    near: [(T, u32); NEAREST],
    found: usize,
}

impl<T: Real> Nearest<T> {
    fn new() -> Self {
        Nearest {
            near: [(T::max_value().unwrap_or(T::one()), u32::MAX); NEAREST],
            found: 0,
        }
    }

    /// Whether a feature at distance `d` would enter the list.
    fn would_keep(&self, d: T) -> bool {
        self.found < NEAREST || d < self.near[NEAREST - 1].0
    }

    /// Enters a feature at distance `d` (the caller checked [`Nearest::would_keep`]).
    fn keep(&mut self, d: T, slot: u32) {
        self.found = keep_nearest(&mut self.near, self.found, d, slot);
    }

    /// The features kept, nearest first.
    fn kept(&self) -> &[(T, u32)] {
        self.near.get(..self.found).unwrap_or_default()
    }
}

/// Of the triangles of the features `near` (at most [`NEAREST`]), the one that contains `p`
/// most centrally (largest smallest weight), as [`anchor_at`] describes; `None` when all are
/// slivers or fewer than three.
fn best_triangle<T: Real>(
    p: [T; 2],
    features: &[[T; 2]],
    near: &Nearest<T>,
) -> Option<([u32; 3], [T; 3])> {
    let near = near.kept();
    let mut best: Option<(T, [u32; 3], [T; 3])> = None;
    for (i, &(_, si)) in near.iter().enumerate() {
        for (j, &(_, sj)) in near.iter().enumerate().skip(i + 1) {
            for &(_, sk) in near.iter().skip(j + 1) {
                let idx = [si, sj, sk];
                // The slots come from enumerating `features`.
                let (Some(&fa), Some(&fb), Some(&fc)) = (
                    features.get(si as usize),
                    features.get(sj as usize),
                    features.get(sk as usize),
                ) else {
                    continue;
                };
                let (ab, ac) = (sub(fb, fa), sub(fc, fa));
                let det = cross(ab, ac);
                let scale = (length(ab) + length(ac)) * (length(ab) + length(ac));
                // Skip slivers: their weights blow up with the noise of the features.
                if !(det.abs() > T::of(0.05) * scale) {
                    continue;
                }
                let wb = cross(sub(p, fa), ac) / det;
                let wc = cross(ab, sub(p, fa)) / det;
                let w = [T::one() - wb - wc, wb, wc];
                // Containment first (largest smallest weight), then closeness to containment.
                let score = w[0].min(w[1]).min(w[2]);
                if best.is_none_or(|(s, _, _)| score > s) {
                    best = Some((score, idx, w));
                }
            }
        }
    }
    best.map(|(_, idx, w)| (idx, w))
}

/// Puts `item` at distance `d` into `near`, a list sorted by distance whose first `found`
/// places are in use, in the last place in use (or the first free one) and then down to its
/// rank; returns the places now in use. The caller checks that `d` beats the last place when
/// the list is full.
fn keep_nearest<T: Real, I: Copy>(near: &mut [(T, I)], found: usize, d: T, item: I) -> usize {
    let Some(last) = near.len().checked_sub(1) else {
        return 0;
    };
    let mut k = found.min(last);
    if let Some(slot) = near.get_mut(k) {
        *slot = (d, item);
    }
    while k > 0 {
        match (near.get(k - 1), near.get(k)) {
            (Some(lower), Some(this)) if this.0 < lower.0 => {
                near.swap(k, k - 1);
                k -= 1;
            }
            _ => break,
        }
    }
    (found + 1).min(near.len())
}

/// A pair slot that no feature has: a point whose pair is unknown (never so for the detector's
/// points).
const NO_SLOT: u32 = u32::MAX;

/// Whether a pair opening by `o` crosses a line heading `d`: the opening lies within 60° of the
/// line's normal (`|o × d| ≥ |o| |d| / 2`), the same half that `opening_only` asks of the
/// opening along the pair itself. A cut opens across itself.
pub(super) fn crosses<T: Real>(o: [T; 2], d: [T; 2]) -> bool {
    let scale = length(o) * length(d);
    scale > T::EPS && cross(o, d).abs() >= T::of(0.5) * scale
}

/// Visits per point of the check that no single feature carries a line (`carried_by_one`):
/// one pass to find the candidates, one to count each of the three.
pub const CARRIED_BY_ONE_VISITS: u64 = 4;

/// Whether one feature is in all of the `n` `pairs` but at most one. Then a single feature
/// carries the line: it jumped and the temporal filter missed it (its pairs with every
/// neighbour open alike and their midpoints ring it), or it is the only evidence of a cut yet.
/// Either way the line would stand on one feature's track; at least two pairs without it
/// (two points fix a line) are asked for. The feature, if there is one, is in more than a
/// quarter of the `2 n` slots when `n ≥ 3`, so Misra and Gries' frequent-items count with three
/// counters keeps it; each candidate kept is then counted.
pub(super) fn carried_by_one(pairs: &[[u32; 2]]) -> bool {
    let n = pairs.len();
    if n <= 2 {
        // Any feature of a pair leaves at most one pair without it.
        return true;
    }
    let mut kept = [(NO_SLOT, 0usize); 3];
    for &f in pairs.iter().flatten().filter(|&&f| f != NO_SLOT) {
        if let Some(k) = kept.iter_mut().find(|k| k.1 > 0 && k.0 == f) {
            k.1 += 1;
        } else if let Some(k) = kept.iter_mut().find(|k| k.1 == 0) {
            *k = (f, 1);
        } else {
            for k in kept.iter_mut() {
                k.1 -= 1;
            }
        }
    }
    kept.iter()
        .filter(|k| k.1 > 0)
        .any(|&(f, _)| pairs.iter().filter(|p| p.contains(&f)).count() + 1 >= n)
}
