//! The cut line (paper §2.2, Fig. 2) and the separation surface it spans.
//!
//! Once enough separation points exist, a line is fitted to them — robustly first (the line
//! through two points with the most points near it), then by total least squares on those
//! points; its two ends become fronts that advance on their own, each only toward separation
//! points inside an angle `α` of its direction, by a step between a minimum and a maximum, and
//! only when enough points ahead support it.
//!
//! A vertex is anchored to tracked features around it when it is placed (three on each lip;
//! the vertex is an affine combination of their six image positions), so the line moves with the real
//! object rather than with the model, which, uncut, cannot follow the opening lips. The separation surface is made
//! on demand: each vertex is carried onto the model surface along its camera ray and the line is
//! extruded along the camera direction, or a configured depth vector, through the model.

use nalgebra::Vector3;

use crate::camera::Camera;
use crate::detect::{DetectionConfig, SplitPairs};
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
    /// Split pairs, feature slots and triangles visited to anchor a vertex (see
    /// [`LineWork::bound`]).
    pub anchor_visits: u64,
}

impl LineWork {
    /// The most work of one frame with `vertices` vertices of capacity, `points` separation
    /// points (the pair capacity) and `features` slots, whichever of
    /// starting or growing the line the frame does:
    /// - starting: `F (F − 1) / 2 · 5 F + 3 F` fit tests with `F = min(points, FIT_POINTS)`
    ///   (every candidate line through two points against every point, and, for a candidate
    ///   with more support than the best so far, the [`CARRIED_BY_ONE_VISITS`] passes that
    ///   check no single feature carries it; then three passes over the inliers), and two
    ///   anchorings;
    /// - growing: each vertex follows its evidence (`points` visits) and each front
    ///   looks ahead (`points`), with one anchoring per vertex and per front.
    ///
    /// An anchoring scans the split pairs once (for those near the point; at most `points`,
    /// the pair capacity) and the slots at most four times: each lip's features alone, both
    /// sides in one scan, then all around, each scan followed by the 20 triangles of the six
    /// nearest and the one for both sides by 20 more (`anchor_cost`).
    pub const fn bound(vertices: u64, points: u64, features: u64) -> LineWork {
        let f = if points < FIT_POINTS as u64 {
            points
        } else {
            FIT_POINTS as u64
        };
        let start_fit = f * f.saturating_sub(1) / 2 * (1 + CARRIED_BY_ONE_VISITS) * f + 3 * f;
        let grow_points = (vertices + 2) * points;
        let anchor = anchor_cost(features, points);
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

/// What the line anchors its vertices to: the features' latest image positions (one per
/// slot), which slots may anchor a vertex, and the pairs the detector found split.
struct Tracked<'s, T> {
    features: &'s [[T; 2]],
    /// The features' residuals (pixels, one per slot): how a split pair's lips part.
    residuals: &'s [[T; 2]],
    usable: &'s [u32],
    split: SplitPairs<'s>,
}

impl<T> Tracked<'_, T> {
    /// The visits of one anchoring ([`anchor_cost`]) on these features and split pairs.
    fn anchor_cost(&self) -> u64 {
        anchor_cost(self.features.len() as u64, self.split.scanned() as u64)
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
    /// How far from a point the split pairs whose lips anchor it lie: two maximum steps.
    lip_reach: T,
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
            lip_reach: T::of(2.0) * config.max_step * spacing,
        }
    }
}

/// Separation points considered when the line is started: bounds the robust fit's cost to
/// `5 FIT_POINTS³ / 2` distance evaluations ([`LineWork::bound`]).
pub const FIT_POINTS: usize = 64;

/// The polyline in fixed storage: each vertex anchored to six feature slots, three on each
/// lip.
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
    /// The vertices the line had when it was last applied to the mesh (0 before): it only
    /// grows, so it has grown since exactly when it holds more.
    applied: usize,
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
            applied: 0,
        })
    }

    /// Hashes every buffer of the line's state.
    pub(crate) fn fingerprint_into(&self, h: &mut crate::storage::Fingerprint) {
        h.words(self.anchors.iter().take(self.n).flatten());
        h.reals(self.weights.iter().take(self.n).flatten());
        h.reals(self.direction.iter().flatten());
        let detected = self.detected_frame.unwrap_or(u32::MAX);
        h.words([self.n as u32, detected, u32::from(self.capped)].iter());
        h.words([self.applied as u32].iter().chain(self.moved.iter()));
    }

    /// Forgets the line.
    pub fn reset(&mut self) {
        self.n = 0;
        self.detected_frame = None;
        self.capped = false;
        self.applied = 0;
    }

    /// Whether the line has grown since it was last applied to the mesh ([`Self::mark_applied`]),
    /// or has started and was never applied: then a cut event is due.
    pub fn grown(&self) -> bool {
        self.n >= 2 && self.n > self.applied
    }

    /// Records that the whole line as it is now has been applied to the mesh.
    pub fn mark_applied(&mut self) {
        if self.n >= 2 {
            self.applied = self.n;
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
    /// cannot follow, cannot push a front along frame after frame. `pairs[k]` is point `k`'s
    /// pair in `split` ([`SplitPairs::slots`]). `features` are the latest image positions of the feature
    /// slots (vertices are anchored to them) and `residuals` theirs (tracked less model, one per
    /// slot); `usable[i] != 0` marks slots that may anchor a
    /// new vertex; `scratch` holds the projected vertices (at least the capacity); `spacing`
    /// is the features' spacing at frame 0 (pixels), the unit of the configured lengths.
    #[allow(clippy::too_many_arguments)]
    pub fn update(
        &mut self,
        frame: u32,
        points: &[[T; 2]],
        since: &[u32],
        pairs: &[u32],
        split: SplitPairs<'_>,
        features: &[[T; 2]],
        residuals: &[[T; 2]],
        usable: &[u32],
        config: &DetectionConfig<T>,
        spacing: T,
        scratch: &mut [[T; 2]],
    ) -> CutLineReport {
        let rules = Rules::new(config, spacing);
        let tracked = Tracked {
            features,
            residuals,
            usable,
            split,
        };
        let mut work = LineWork::default();
        let mut added = 0;
        if self.n == 0 {
            if points.len() >= rules.init_points && self.anchors.len() >= 2 {
                added = self.start(frame, points, pairs, &tracked, &rules, &mut work);
            }
        } else {
            // `project` writes at most `scratch.len()` vertices.
            let m = self.project(features, scratch);
            if m == self.n {
                let projected = scratch.get(..m).unwrap_or_default();
                self.follow_points(points, &tracked, &rules, projected, &mut work);
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
                        work.anchor_visits += tracked.anchor_cost();
                        if let Some((anchor, w)) = anchor_across(p, dir, &tracked, rules.lip_reach)
                        {
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
}

/// How far ahead of a front (in maximum steps) separation points draw it.
const REACH_STEPS: f64 = 5.0;

/// Scans of the feature slots per anchoring ([`anchor_across`]: each lip on the split pairs'
/// features alone, both sides again in one scan with the others split by the line, then all
/// around).
const ANCHOR_COST: u64 = 4;

/// The visits of one anchoring with `features` slots and `pairs` split pairs (at most the
/// neighbour pairs, which the bound counts): a scan of the split pairs for those near the
/// point, then at most [`ANCHOR_COST`] scans of the slots, each followed by the 20 triangles
/// of the six nearest, and 20 more after the scan that fills both sides (the six nearest of
/// each: 40 triangles). A slot's lip is looked up among at most `2 LIP_PAIRS` features, part
/// of its visit. A bound: the two scans among the lips' features alone visit those features
/// only (at most `2 LIP_PAIRS` each, and no more than the slots).
const fn anchor_cost(features: u64, pairs: u64) -> u64 {
    ANCHOR_COST * (features + 20) + 20 + pairs
}

/// Features a vertex is anchored to: three on each side of the line.
const ANCHORS: usize = 6;

mod grow;

pub use grow::CARRIED_BY_ONE_VISITS;
use grow::anchor_across;

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests;
