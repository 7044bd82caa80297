//! The cut line (paper §2.2, Fig. 2) and the separation surface it spans.
//!
//! Once enough separation points exist, a line is fitted to them — robustly first (the line
//! through two points with the most points near it), then by total least squares on those
//! points; its two ends become fronts that advance on their own, each only toward separation
//! points inside an angle `α` of its direction, by a step between a minimum and a maximum, and
//! only when enough points ahead support it.
//!
//! A vertex is anchored to the three tracked features around it when it is placed (an affine
//! combination of their image positions), so the line moves with the real object rather than
//! with the model, which, uncut, cannot follow the opening lips. The separation surface is made
//! on demand: each vertex is carried onto the model surface along its camera ray and the line is
//! extruded along the camera direction, or a configured depth vector, through the model.

#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

use nalgebra::Vector3;

use crate::camera::Camera;
use crate::detect::DetectionConfig;
use crate::error::Error;
use crate::features::first_hit;
use crate::mesh::Mesh;
use crate::real::Real;
use crate::storage::{Slab, times};

/// What the cut line did in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CutLineReport {
    /// Frame at which the line was started (the cut detected), if it has been.
    pub detected_frame: Option<u32>,
    /// Vertices of the polyline.
    pub vertices: usize,
    /// Vertices added this frame (0, 1 or 2; 2 when the line was started).
    pub added: usize,
    /// Whether a front could not advance because the vertex capacity is full.
    pub capped: bool,
    /// Work done this frame.
    pub work: LineWork,
}

/// Work of the cut line in one frame, counted in data-independent units; bounded by
/// [`LineWork::bound`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineWork {
    /// Point-to-line distance tests of the robust fit that starts the line.
    pub fit_tests: u64,
    /// Separation points and lip midpoints visited by the fronts and by the vertices following
    /// their evidence.
    pub point_visits: u64,
    /// Features visited to anchor a vertex (each anchoring scans every slot once and tries
    /// the 20 triangles of the six nearest).
    pub anchor_visits: u64,
}

impl LineWork {
    /// The most work of one frame with `vertices` vertices of capacity, `points` separation
    /// points (the pair capacity) and `features` slots, whichever of
    /// starting or growing the line the frame does:
    /// - starting: `F (F − 1) / 2 · F + 2 F` fit tests with `F = min(points, FIT_POINTS)` (every
    ///   candidate line through two points against every point, then three passes over the
    ///   inliers),
    ///   and two anchorings;
    /// - growing: each vertex follows its evidence (`points` visits) and each front
    ///   looks ahead (`points`), with one anchoring per vertex and per front.
    ///
    /// An anchoring scans the slots at most three times (each side, then both), each scan
    /// `features + 20` visits.
    pub const fn bound(vertices: u64, points: u64, features: u64) -> LineWork {
        let f = if points < FIT_POINTS as u64 {
            points
        } else {
            FIT_POINTS as u64
        };
        let start_fit = f * f.saturating_sub(1) / 2 * f + 3 * f;
        let grow_points = (vertices + 2) * points;
        let anchor = ANCHOR_COST * (features + 20);
        let start_anchor = 2 * anchor;
        let grow_anchor = (vertices + 2) * anchor;
        LineWork {
            fit_tests: start_fit,
            point_visits: grow_points,
            anchor_visits: if start_anchor > grow_anchor {
                start_anchor
            } else {
                grow_anchor
            },
        }
    }

    /// Whether every count is at most `other`'s.
    pub fn within(&self, other: &LineWork) -> bool {
        self.fit_tests <= other.fit_tests
            && self.point_visits <= other.point_visits
            && self.anchor_visits <= other.anchor_visits
    }
}

/// The line's rules in pixels: the configuration's lengths (in feature spacings) times the
/// spacing measured at frame 0.
#[derive(Clone, Copy, Debug)]
struct Rules<T> {
    tolerance: T,
    min_step: T,
    max_step: T,
    cos_alpha: T,
    min_support: u32,
    init_points: usize,
    max_line_spread: T,
}

impl<T: Real> Rules<T> {
    fn new(config: &DetectionConfig<T>, spacing: T) -> Self {
        Rules {
            tolerance: config.line_tolerance * spacing,
            min_step: config.min_step * spacing,
            max_step: config.max_step * spacing,
            cos_alpha: (config.alpha_degrees * T::pi() / T::of(180.0))
                .libm_sin_cos()
                .1,
            min_support: config.min_support,
            init_points: config.init_points as usize,
            max_line_spread: config.max_line_spread,
        }
    }
}

/// Separation points considered when the line is started: bounds the robust fit's cost to
/// `FIT_POINTS³ / 2` distance evaluations.
pub const FIT_POINTS: usize = 64;

/// The polyline in fixed storage: each vertex anchored to three feature slots.
#[derive(Debug)]
pub struct CutLine<'a, T> {
    anchors: &'a mut [[u32; ANCHORS]],
    weights: &'a mut [[T; ANCHORS]],
    n: usize,
    /// Directions of the two fronts in the image (start, end), unit length.
    direction: [[T; 2]; 2],
    /// Frame each front last moved forward (or the line started).
    moved: [u32; 2],
    detected_frame: Option<u32>,
    capped: bool,
    /// The vertices (an index range, inclusive) whose segments have been applied to the mesh:
    /// the line grows only at its ends, so they stay contiguous.
    applied: Option<[usize; 2]>,
}

/// A part of the line not yet applied to the mesh: vertices `first..=last`, and which of its
/// two ends are open (the line's own ends) rather than continuing the part already applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PendingPart {
    /// First vertex.
    pub first: usize,
    /// Last vertex.
    pub last: usize,
    /// Whether each end is an end of the line.
    pub open: [bool; 2],
}

fn sub<T: Real>(a: [T; 2], b: [T; 2]) -> [T; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn length<T: Real>(a: [T; 2]) -> T {
    (a[0] * a[0] + a[1] * a[1]).sqrt()
}

fn cross<T: Real>(a: [T; 2], b: [T; 2]) -> T {
    a[0] * b[1] - a[1] * b[0]
}

impl<'a, T: Real> CutLine<'a, T> {
    /// Scalars of storage for `capacity` vertices.
    pub const fn real_len(capacity: usize) -> usize {
        times(ANCHORS, capacity)
    }

    /// Indices of storage for `capacity` vertices.
    pub const fn index_len(capacity: usize) -> usize {
        times(ANCHORS, capacity)
    }

    /// An empty line with room for `capacity` vertices.
    ///
    /// # Errors
    /// [`Error::Capacity`] if a slab is too short.
    pub fn new(
        capacity: usize,
        reals: &mut Slab<'a, T>,
        indices: &mut Slab<'a, u32>,
    ) -> Result<Self, Error> {
        Ok(CutLine {
            anchors: indices
                .take(times(ANCHORS, capacity))?
                .as_chunks_mut::<ANCHORS>()
                .0,
            weights: reals
                .take(times(ANCHORS, capacity))?
                .as_chunks_mut::<ANCHORS>()
                .0,
            n: 0,
            direction: [[T::zero(); 2]; 2],
            moved: [0; 2],
            detected_frame: None,
            capped: false,
            applied: None,
        })
    }

    /// Hashes every buffer of the line's state.
    pub(crate) fn fingerprint_into(&self, h: &mut crate::storage::Fingerprint) {
        h.words(self.anchors.iter().take(self.n).flatten());
        h.reals(self.weights.iter().take(self.n).flatten());
        h.reals(self.direction.iter().flatten());
        let applied = self.applied.map_or([u32::MAX; 2], |r| r.map(|v| v as u32));
        let detected = self.detected_frame.unwrap_or(u32::MAX);
        h.words([self.n as u32, detected, u32::from(self.capped)].iter());
        h.words(applied.iter().chain(self.moved.iter()));
    }

    /// Forgets the line.
    pub fn reset(&mut self) {
        self.n = 0;
        self.detected_frame = None;
        self.capped = false;
        self.applied = None;
    }

    /// The parts of the line not yet applied to the mesh (at most one per end; the whole line
    /// before anything is applied).
    pub fn pending(&self) -> [Option<PendingPart>; 2] {
        if self.n < 2 {
            return [None, None];
        }
        let last = self.n - 1;
        match self.applied {
            None => [
                Some(PendingPart {
                    first: 0,
                    last,
                    open: [true, true],
                }),
                None,
            ],
            Some([lo, hi]) => [
                (lo > 0).then_some(PendingPart {
                    first: 0,
                    last: lo,
                    open: [true, false],
                }),
                (hi < last).then_some(PendingPart {
                    first: hi,
                    last,
                    open: [false, true],
                }),
            ],
        }
    }

    /// Records that the whole line as it is now has been applied to the mesh.
    pub fn mark_applied(&mut self) {
        if self.n >= 2 {
            self.applied = Some([0, self.n - 1]);
        }
    }

    /// The most vertices the storage holds.
    pub fn capacity(&self) -> usize {
        self.anchors.len()
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the line has not started.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Frame at which the line started.
    pub fn detected_frame(&self) -> Option<u32> {
        self.detected_frame
    }

    /// Pixel of vertex `k` given the features' latest image positions `features` (one per
    /// slot).
    pub fn vertex(&self, k: usize, features: &[[T; 2]]) -> Option<[T; 2]> {
        if k >= self.n {
            return None;
        }
        let mut p = [T::zero(); 2];
        for (slot, w) in self.anchors.get(k)?.iter().zip(*self.weights.get(k)?) {
            let f = features.get(*slot as usize)?;
            p[0] += f[0] * w;
            p[1] += f[1] * w;
        }
        Some(p)
    }

    /// The polyline in the image: writes up to `out.len()` vertices, returns how many.
    pub fn project(&self, features: &[[T; 2]], out: &mut [[T; 2]]) -> usize {
        let mut m = 0;
        for k in 0..self.n {
            let Some(slot) = out.get_mut(m) else {
                break;
            };
            if let Some(p) = self.vertex(k, features) {
                *slot = p;
                m += 1;
            }
        }
        m
    }

    /// The separation surface the mesh is cut along ([`crate::cut`]): one quadrilateral per
    /// polyline segment. Extruded along the camera rays (the default), the quadrilateral of
    /// segment `[a, b]` is `[a_near, b_near, b_far, a_far]`, the points of the rays through `a`
    /// and `b` at the nearest and farthest depth of the model (`x`) along the view. Along a
    /// configured depth direction `e`, it is `[a, b, b + L·e, a + L·e]`, where `a` and `b` are
    /// the vertices carried onto the model along their rays (or, for a ray that misses it, onto
    /// the plane through its centroid across the view) and `L = length` metres. Writes up to
    /// `out.len()` quads, returns how many.
    #[allow(clippy::too_many_arguments)]
    pub fn separation_surface(
        &self,
        features: &[[T; 2]],
        mesh: &Mesh<'_, T>,
        x: &[[T; 3]],
        camera: &Camera<T>,
        config: &DetectionConfig<T>,
        length: T,
        out: &mut [[[T; 3]; 4]],
    ) -> usize {
        let view = camera.view_direction();
        let centre = *camera.centre();
        let n = mesh.n_nodes();
        let (mut near, mut far) = (T::zero(), T::zero());
        let mut centroid = Vector3::zeros();
        for (k, p) in x.iter().take(n).enumerate() {
            let q = Vector3::new(p[0], p[1], p[2]);
            centroid += q;
            let z = (q - centre).dot(&view);
            near = if k == 0 { z } else { near.min(z) };
            far = if k == 0 { z } else { far.max(z) };
        }
        centroid /= T::of(n.max(1) as f64);
        let at_depth = |uv: [T; 2], z: T| -> Vector3<T> {
            let (origin, dir) = camera.ray(uv[0], uv[1]);
            let denom = dir.dot(&view);
            origin + dir * if denom > T::EPS { z / denom } else { z }
        };
        let on_model = |uv: [T; 2]| -> Vector3<T> {
            if let Some((tet, w)) = first_hit(mesh, x, camera, uv)
                && let Some(tet) = mesh.tets().get(tet as usize)
                && let Some(p) = crate::embed::interpolate(x, tet, &w)
            {
                return Vector3::new(p[0], p[1], p[2]);
            }
            at_depth(uv, (centroid - centre).dot(&view))
        };
        let mut m = 0;
        for k in 1..self.n {
            let Some(slot) = out.get_mut(m) else {
                break;
            };
            let (Some(a), Some(b)) = (self.vertex(k - 1, features), self.vertex(k, features))
            else {
                continue;
            };
            let quad = match config.depth {
                None => [
                    at_depth(a, near),
                    at_depth(b, near),
                    at_depth(b, far),
                    at_depth(a, far),
                ],
                Some(d) => {
                    let e = Vector3::new(d[0], d[1], d[2]);
                    let e = e / e.norm() * length;
                    let (pa, pb) = (on_model(a), on_model(b));
                    [pa, pb, pb + e, pa + e]
                }
            };
            *slot = quad.map(|p| [p.x, p.y, p.z]);
            m += 1;
        }
        m
    }

    /// One frame: starts the line from the separation `points` once there are enough, or
    /// advances its fronts. `since[k]` is the frame at which point `k`'s pair became split: a
    /// front advances only on points inserted after it last moved (the paper's "new cut lines
    /// are only inserted when a sufficient number of separation points have been inserted"),
    /// so a discrepancy that stays put, such as the strain at a cut's tip that a coarse model
    /// cannot follow, cannot push a front along frame after frame. `features` are the latest image positions of the feature
    /// slots (vertices are anchored to them); `usable[i] != 0` marks slots that may anchor a
    /// new vertex; `scratch` holds the projected vertices (at least the capacity); `spacing`
    /// is the features' spacing at frame 0 (pixels), the unit of the configured lengths.
    #[allow(clippy::too_many_arguments)]
    pub fn update(
        &mut self,
        frame: u32,
        points: &[[T; 2]],
        since: &[u32],
        features: &[[T; 2]],
        usable: &[u32],
        config: &DetectionConfig<T>,
        spacing: T,
        scratch: &mut [[T; 2]],
    ) -> CutLineReport {
        let rules = Rules::new(config, spacing);
        let mut work = LineWork::default();
        let mut added = 0;
        if self.n == 0 {
            if points.len() >= rules.init_points && self.anchors.len() >= 2 {
                added = self.start(frame, points, features, usable, &rules, &mut work);
            }
        } else {
            // `project` writes at most `scratch.len()` vertices.
            let m = self.project(features, scratch);
            if m == self.n {
                let projected = scratch.get(..m).unwrap_or_default();
                self.follow_points(points, features, usable, &rules, projected, &mut work);
                let m = self.project(features, scratch);
                let projected = scratch.get(..m).unwrap_or_default();
                for end in 0..2 {
                    let tip = if end == 0 {
                        projected.first()
                    } else {
                        projected.last()
                    };
                    // `end` < 2, the length of `moved` and `direction`.
                    let (Some(&v), Some(&moved), Some(&heading)) =
                        (tip, self.moved.get(end), self.direction.get(end))
                    else {
                        continue;
                    };
                    let fresh = |k: usize| since.get(k).is_some_and(|&f| f >= moved);
                    work.point_visits += points.len() as u64;
                    if let Some((p, dir)) = Self::advance(v, heading, points, fresh, &rules) {
                        if self.n == self.anchors.len() {
                            self.capped = true;
                            continue;
                        }
                        work.anchor_visits += ANCHOR_COST * (features.len() as u64 + 20);
                        if let Some((anchor, w)) = anchor_across(p, dir, features, usable) {
                            self.insert(end, anchor, w);
                            if let (Some(d), Some(m)) =
                                (self.direction.get_mut(end), self.moved.get_mut(end))
                            {
                                *d = dir;
                                *m = frame;
                            }
                            added += 1;
                        }
                    }
                }
            }
        }
        CutLineReport {
            detected_frame: self.detected_frame,
            vertices: self.n,
            added,
            capped: self.capped,
            work,
        }
    }

    /// Fits the line (robustly, then by total least squares) and places its two ends.
    fn start(
        &mut self,
        frame: u32,
        points: &[[T; 2]],
        features: &[[T; 2]],
        usable: &[u32],
        rules: &Rules<T>,
        work: &mut LineWork,
    ) -> usize {
        // Of the lines through two separation points, the one with most points within the
        // tolerance: spurious clusters (a tracking failure, a region where the model is poor)
        // then do not tilt the line.
        let pts = points.get(..FIT_POINTS).unwrap_or(points);
        let tol = rules.tolerance;
        let f = pts.len() as u64;
        work.fit_tests += f * f.saturating_sub(1) / 2 * f + 3 * f;
        // The inlier count and the two points of the best line.
        let mut best = (0usize, [T::zero(); 2], [T::zero(); 2]);
        for (i, &p_i) in pts.iter().enumerate() {
            for &p_j in pts.iter().skip(i + 1) {
                let d = sub(p_j, p_i);
                let len = length(d);
                if !(len > T::EPS) {
                    continue;
                }
                let inliers = pts
                    .iter()
                    .filter(|p| (cross(d, sub(**p, p_i)) / len).abs() <= tol)
                    .count();
                if inliers > best.0 {
                    best = (inliers, p_i, p_j);
                }
            }
        }
        if best.0 < rules.init_points {
            return 0;
        }
        let (pi, d) = (best.1, sub(best.2, best.1));
        let dl = length(d);
        let inlier = |p: &&[T; 2]| (cross(d, sub(**p, pi)) / dl).abs() <= tol;
        // Then total least squares on the inliers: the principal direction of their scatter.
        let n = T::of(best.0 as f64);
        let mut c = [T::zero(); 2];
        for p in pts.iter().filter(inlier) {
            c[0] += p[0] / n;
            c[1] += p[1] / n;
        }
        let (mut sxx, mut sxy, mut syy) = (T::zero(), T::zero(), T::zero());
        for p in pts.iter().filter(inlier) {
            let d = sub(*p, c);
            sxx += d[0] * d[0];
            sxy += d[0] * d[1];
            syy += d[1] * d[1];
        }
        // A cut is a line: refuse a cloud (one bad feature's pairs make a ring, noise a blob).
        let half_trace = (sxx + syy) * T::of(0.5);
        let root = ((sxx - syy) * (sxx - syy) * T::of(0.25) + sxy * sxy).sqrt();
        let (major, minor) = (half_trace + root, (half_trace - root).max(T::zero()));
        if !(major > T::zero()) || (minor / major).sqrt() > rules.max_line_spread {
            return 0;
        }
        let angle = T::of(0.5) * (T::of(2.0) * sxy).libm_atan2(sxx - syy);
        let (sin, cos) = angle.libm_sin_cos();
        let e = [cos, sin];
        let (mut lo, mut hi) = (T::zero(), T::zero());
        for p in pts.iter().filter(inlier) {
            let t = sub(*p, c)[0] * e[0] + sub(*p, c)[1] * e[1];
            lo = lo.min(t);
            hi = hi.max(t);
        }
        let a = [c[0] + e[0] * lo, c[1] + e[1] * lo];
        let b = [c[0] + e[0] * hi, c[1] + e[1] * hi];
        work.anchor_visits += 2 * ANCHOR_COST * (features.len() as u64 + 20);
        match (
            anchor_across(a, e, features, usable),
            anchor_across(b, e, features, usable),
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
    fn follow_points(
        &mut self,
        points: &[[T; 2]],
        features: &[[T; 2]],
        usable: &[u32],
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
            work.anchor_visits += ANCHOR_COST * (features.len() as u64 + 20);
            // `projected` holds one pixel per vertex (`k < n`).
            if let Some((anchor, w)) = anchor_across(target, t, features, usable)
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
    fn advance(
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
    fn insert(&mut self, end: usize, anchor: [u32; ANCHORS], w: [T; ANCHORS]) {
        let n = self.n;
        let (Some(anchors), Some(weights)) =
            (self.anchors.get_mut(..=n), self.weights.get_mut(..=n))
        else {
            return;
        };
        let slots = if end == 0 {
            if let Some(r) = self.applied.as_mut() {
                *r = [r[0] + 1, r[1] + 1];
            }
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

/// How far ahead of a front (in maximum steps) separation points draw it.
const REACH_STEPS: f64 = 5.0;

/// Scans of the feature slots per anchoring ([`anchor_across`]: each side, then both).
const ANCHOR_COST: u64 = 3;

/// Features a vertex is anchored to: three on each side of the line.
const ANCHORS: usize = 6;

/// Anchors image point `p` on a line running along `tangent` to the features on both sides:
/// half of it follows three features on one side (their affine combination, which may
/// extrapolate a little), half three on the other. As the cut opens, each half moves with its
/// lip and the vertex stays midway between them; anchored to one triangle across the cut, it
/// would slide toward whichever lip holds more of the triangle's weight. Where one side has no
/// usable feature near (the line's end at the object's edge), the three features around `p`
/// hold it. `None` when neither works.
fn anchor_across<T: Real>(
    p: [T; 2],
    tangent: [T; 2],
    features: &[[T; 2]],
    usable: &[u32],
) -> Option<([u32; ANCHORS], [T; ANCHORS])> {
    let normal = [-tangent[1], tangent[0]];
    let side = |sign: T| {
        move |f: &[T; 2]| {
            let d = sub(*f, p);
            (d[0] * normal[0] + d[1] * normal[1]) * sign > T::zero()
        }
    };
    let half = T::of(0.5);
    match (
        anchor_where(p, features, usable, side(T::one())),
        anchor_where(p, features, usable, side(-T::one())),
    ) {
        (Some((a, wa)), Some((b, wb))) => Some((
            [a[0], a[1], a[2], b[0], b[1], b[2]],
            [
                wa[0] * half,
                wa[1] * half,
                wa[2] * half,
                wb[0] * half,
                wb[1] * half,
                wb[2] * half,
            ],
        )),
        _ => anchor_at(p, features, usable).map(|(a, w)| {
            (
                [a[0], a[1], a[2], a[0], a[1], a[2]],
                [w[0], w[1], w[2], T::zero(), T::zero(), T::zero()],
            )
        }),
    }
}

/// Anchors image point `p` to three usable features around it, as their affine combination
/// (weights sum to one): of the triangles of its six nearest usable features, the one that
/// contains `p` most centrally (largest smallest weight). A point on a cut is then held by
/// features on both lips and stays between them as the cut opens. If no triangle contains
/// `p`, the best-shaped one of the nearest is used. `None` with fewer than three usable
/// features or only collinear ones.
fn anchor_at<T: Real>(
    p: [T; 2],
    features: &[[T; 2]],
    usable: &[u32],
) -> Option<([u32; 3], [T; 3])> {
    anchor_where(p, features, usable, |_| true)
}

/// [`anchor_at`] among the features that `keep` accepts.
fn anchor_where<T: Real>(
    p: [T; 2],
    features: &[[T; 2]],
    usable: &[u32],
    keep: impl Fn(&[T; 2]) -> bool,
) -> Option<([u32; 3], [T; 3])> {
    // The six nearest usable features, by insertion into a small sorted list.
    const K: usize = 6;
    let mut near: [(T, u32); K] = [(T::max_value().unwrap_or(T::one()), u32::MAX); K];
    let mut found = 0;
    for (i, f) in features.iter().enumerate() {
        if usable.get(i).is_none_or(|&u| u == 0) || !keep(f) {
            continue;
        }
        let d = length(sub(*f, p));
        if found < K || d < near[K - 1].0 {
            // Into the last place in use (or the first free one), then down to its rank.
            let mut k = found.min(K - 1);
            if let Some(slot) = near.get_mut(k) {
                *slot = (d, i as u32);
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
            found = (found + 1).min(K);
        }
    }
    let near = near.get(..found).unwrap_or_default();
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_anchored_point_follows_its_features_affinely() {
        let features = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [50.0, 50.0]];
        let usable = [1, 1, 1, 1];
        let (anchor, w) = anchor_at([2.0, 3.0], &features, &usable).unwrap();
        let place = |f: &[[f64; 2]]| -> [f64; 2] {
            let mut p = [0.0; 2];
            for k in 0..3 {
                p[0] += w[k] * f[anchor[k] as usize][0];
                p[1] += w[k] * f[anchor[k] as usize][1];
            }
            p
        };
        let here = place(&features);
        assert!((here[0] - 2.0).abs() < 1e-12 && (here[1] - 3.0).abs() < 1e-12);
        // Stretch the features by 2 along x and shift them: the point moves the same way.
        let moved = features.map(|f| [2.0 * f[0] + 5.0, f[1] - 1.0]);
        let there = place(&moved);
        assert!((there[0] - 9.0).abs() < 1e-12 && (there[1] - 2.0).abs() < 1e-12);
        // Unusable or collinear features cannot anchor.
        assert!(anchor_at([1.0, 1.0], &features, &[1, 1, 0, 0]).is_none());
        let line = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
        assert!(anchor_at([1.0, 1.0], &line, &[1, 1, 1]).is_none());
    }

    /// Features on an 11 × 11 grid, 10 px apart.
    fn grid() -> [[f64; 2]; 121] {
        core::array::from_fn(|k| [10.0 * (k % 11) as f64, 10.0 * (k / 11) as f64])
    }

    #[test]
    fn the_line_starts_on_collinear_points_and_grows_toward_new_ones() {
        // Features on a grid; separation points along x = 50 from y = 20 to 60, then more up
        // to y = 100.
        let features = grid();
        let usable = [1u32; 121];
        let config = DetectionConfig::<f64>::paper();
        let mut reals = [0.0; 128];
        let mut indices = [0u32; 128];
        let mut rs = Slab::new(&mut reals, crate::error::Resource::RealStorage);
        let mut is = Slab::new(&mut indices, crate::error::Resource::IndexStorage);
        let mut line = CutLine::new(16, &mut rs, &mut is).unwrap();
        let mut scratch = [[0.0; 2]; 16];
        let mut points = [[0.0; 2]; 20];
        for k in 0..9 {
            points[k] = [50.0, 20.0 + 5.0 * k as f64];
        }
        // A blob away from the line must not tilt it.
        points[9] = [80.0, 80.0];
        points[10] = [82.0, 81.0];
        let r = line.update(
            3,
            &points[..11],
            &[4; 11],
            &features,
            &usable,
            &config,
            25.0,
            &mut scratch,
        );
        assert_eq!((r.detected_frame, r.vertices, r.added), (Some(3), 2, 2));
        let m = line.project(&features, &mut scratch);
        assert_eq!(m, 2);
        for p in &scratch[..2] {
            assert!((p[0] - 50.0).abs() < 1e-9, "{p:?}");
        }
        // More points further along +y: the end front advances, by at most the maximum step.
        for k in 0..8 {
            points[k] = [50.0, 65.0 + 5.0 * k as f64];
        }
        let before = line.project(&features, &mut scratch);
        let far_end = scratch[..before].iter().map(|p| p[1]).fold(0.0, f64::max);
        let r = line.update(
            4,
            &points[..8],
            &[4; 8],
            &features,
            &usable,
            &config,
            25.0,
            &mut scratch,
        );
        assert_eq!(r.added, 1);
        let m = line.project(&features, &mut scratch);
        let new_end = scratch[..m].iter().map(|p| p[1]).fold(0.0, f64::max);
        assert!(new_end > far_end && new_end <= far_end + config.max_step * 25.0 + 1e-9);
    }

    #[test]
    fn a_full_line_reports_its_cap_instead_of_growing() {
        let features = grid();
        let usable = [1u32; 121];
        let config = DetectionConfig::<f64>::paper();
        let (mut reals, mut indices) = ([0.0; 12], [0u32; 12]);
        let mut rs = Slab::new(&mut reals, crate::error::Resource::RealStorage);
        let mut is = Slab::new(&mut indices, crate::error::Resource::IndexStorage);
        // Room for two vertices only: the start.
        let mut line = CutLine::new(2, &mut rs, &mut is).unwrap();
        let mut scratch = [[0.0; 2]; 2];
        let mut points = [[0.0; 2]; 8];
        for k in 0..8 {
            points[k] = [50.0, 20.0 + 5.0 * k as f64];
        }
        let r = line.update(
            1,
            &points,
            &[1; 8],
            &features,
            &usable,
            &config,
            25.0,
            &mut scratch,
        );
        assert_eq!((r.vertices, r.capped), (2, false));
        for k in 0..8 {
            points[k] = [50.0, 60.0 + 5.0 * k as f64];
        }
        let r = line.update(
            2,
            &points,
            &[2; 8],
            &features,
            &usable,
            &config,
            25.0,
            &mut scratch,
        );
        assert_eq!((r.vertices, r.added, r.capped), (2, 0, true));
    }
}
