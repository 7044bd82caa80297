//! The separation surface as a function on space: the cut polyline of the image extruded along
//! the camera rays (or a configured depth direction), one plane per segment.
//!
//! A point's signed distance `φ` is taken to the plane of the segment nearest to its image;
//! `φ > 0` on the left of the polyline in the image (`u` right, `v` down, walking from the first
//! vertex to the last). A point is *in the extent* of the surface when its image falls beside
//! the polyline — within the tube, not beyond either end — so that a cut can stop where the
//! surface stops.

use nalgebra::Vector3;

use crate::camera::Camera;
use crate::error::{Error, Resource};
use core::cell::Cell;

use crate::features::first_hit;
use crate::mesh::Mesh;
use crate::real::Real;
use crate::storage::times;

/// Reals of scratch per polyline vertex: the plane (normal and offset) of the segment it
/// starts.
pub(crate) const REALS_PER_VERTEX: usize = 4;

fn sub<T: Real>(a: [T; 2], b: [T; 2]) -> [T; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn dot2<T: Real>(a: [T; 2], b: [T; 2]) -> T {
    a[0] * b[0] + a[1] * b[1]
}

/// Where an image point lies relative to the polyline.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Foot<T> {
    /// The nearest segment.
    pub segment: usize,
    /// Signed image distance to that segment's line, pixels (`> 0` on the left).
    pub signed_px: T,
    /// Whether the point lies beside the polyline: not beyond an end, within the tube.
    pub inside: bool,
}

/// The polyline (ends extended), its segment planes, and the camera.
pub(crate) struct SeparationSurface<'s, T: Real> {
    polyline: &'s [[T; 2]],
    /// The two end vertices after extension.
    ends: [[T; 2]; 2],
    /// For an end inside the object, the plane the cut ends on (`ψ = n · p − offset`, negative
    /// on the cut's side): through the end, across the line, along the extrusion.
    tips: [Option<[T; 4]>; 2],
    /// Per segment: unit normal and offset, `φ(p) = n · p − offset`.
    planes: &'s [[T; 4]],
    camera: &'s Camera<T>,
    tube_px: T,
    /// Point–segment tests made so far by [`SeparationSurface::foot`] (every classification
    /// goes through it), for the cut's work count.
    segment_tests: Cell<u64>,
    /// Rays cast to the model while the surface was built, each over every boundary triangle.
    rays: u64,
}

impl<'s, T: Real> SeparationSurface<'s, T> {
    /// Builds the planes of `polyline` (at least two vertices) into `scratch`
    /// (`4 · (vertices − 1)` reals). `depth`: extrude along this direction instead of the
    /// camera rays; the segment's plane then goes through the points where the rays of its
    /// vertices meet the model (`mesh` at positions `x`), or, where a ray misses it, the
    /// plane through the model's centroid across the view. An end `extend` names is extended by
    /// `extension_px` along its segment when that reaches past the model's silhouette;
    /// `extension_px` is also the tube's half-width.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming [`Resource::CutVertices`] for a short `scratch`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        polyline: &'s [[T; 2]],
        camera: &'s Camera<T>,
        depth: Option<[T; 3]>,
        extension_px: T,
        extend: [bool; 2],
        mesh: &Mesh<'_, T>,
        x: &[[T; 3]],
        scratch: &'s mut [T],
    ) -> Result<Self, Error> {
        let m = polyline.len();
        let segments = m.saturating_sub(1);
        let needed = times(4, segments);
        let available = scratch.len();
        let planes = scratch
            .get_mut(..needed)
            .ok_or(Error::Capacity {
                resource: Resource::CutVertices,
                needed,
                available,
            })?
            .as_chunks_mut::<4>()
            .0;
        let ext = if extension_px.finite() {
            extension_px.max(T::one())
        } else {
            T::one()
        };
        let open_ends = extend;
        // The detector sees a cut end only to within a feature spacing: the last separation
        // point lies up to a spacing short of it. An open end is therefore extended by half a
        // spacing (the expected shortfall), and taken through the silhouette when the model's
        // edge lies within a spacing: no feature beyond could have shown the cut going on, and
        // a bridge that thin left uncut would hold the lips together.
        // Returns the end and whether it lies inside the object (then the cut ends there).
        let rays = Cell::new(0u64);
        let extend = |from: [T; 2], toward: [T; 2], open: bool| -> ([T; 2], bool) {
            let d = sub(from, toward);
            let len = dot2(d, d).sqrt();
            if !(open && len > T::EPS) {
                return (from, false);
            }
            let along = |s: T| [from[0] + d[0] / len * s, from[1] + d[1] / len * s];
            rays.set(rays.get() + 1);
            if first_hit(mesh, x, camera, along(ext)).is_some() {
                (along(ext * T::of(0.5)), true)
            } else {
                (along(ext), false)
            }
        };
        let ((end0, inner0), (end1, inner1)) =
            if let (&[first, second, ..], &[.., before_last, last]) = (polyline, polyline) {
                (
                    extend(first, second, open_ends[0]),
                    extend(last, before_last, open_ends[1]),
                )
            } else {
                (([T::zero(); 2], false), ([T::zero(); 2], false))
            };
        let ends = [end0, end1];
        let inner = [inner0, inner1];
        let vertex = |k: usize| -> [T; 2] {
            if k == 0 {
                ends[0]
            } else if k + 1 == m {
                ends[1]
            } else {
                // `k < m` at every call.
                polyline.get(k).copied().unwrap_or([T::zero(); 2])
            }
        };
        // Across the view through the model's centroid: where a depth-extruded segment is
        // anchored when a ray misses the model.
        let n = mesh.n_nodes();
        let mut centroid = Vector3::zeros();
        let at_rest = x.get(..n).ok_or(Error::Capacity {
            resource: Resource::Nodes,
            needed: n,
            available: x.len(),
        })?;
        for p in at_rest {
            centroid += Vector3::new(p[0], p[1], p[2]);
        }
        centroid /= T::of(n.max(1) as f64);
        let view = camera.view_direction();
        let point_on_model = |uv: [T; 2]| -> Vector3<T> {
            rays.set(rays.get() + 1);
            if let Some((tet, w)) = first_hit(mesh, x, camera, uv)
                && let Some(nodes) = mesh.tets().get(tet as usize)
                && let Some(p) = crate::embed::interpolate(x, nodes, &w)
            {
                return Vector3::new(p[0], p[1], p[2]);
            }
            let (origin, dir) = camera.ray(uv[0], uv[1]);
            let denom = dir.dot(&view);
            let s = if denom.abs() > T::EPS {
                (centroid - origin).dot(&view) / denom
            } else {
                T::zero()
            };
            origin + dir * s
        };
        for (k, slot) in planes.iter_mut().enumerate() {
            let (a, b) = (vertex(k), vertex(k + 1));
            let t = sub(b, a);
            let len = dot2(t, t).sqrt();
            let mut plane = [T::zero(); 4];
            if len > T::EPS {
                let (normal, offset, probe_origin) = match depth {
                    None => {
                        let (c, ra) = camera.ray(a[0], a[1]);
                        let (_, rb) = camera.ray(b[0], b[1]);
                        let nv = ra.cross(&rb);
                        (nv, nv.dot(&c), c)
                    }
                    Some(d) => {
                        let d = Vector3::new(d[0], d[1], d[2]);
                        let (pa, pb) = (point_on_model(a), point_on_model(b));
                        let nv = (pb - pa).cross(&d);
                        (nv, nv.dot(&pa), camera.ray(a[0], a[1]).0)
                    }
                };
                let norm = normal.norm();
                if norm > T::zero() && norm.finite() {
                    let (normal, offset) = (normal / norm, offset / norm);
                    // Orientation: a point seen on the left of the segment must be positive.
                    let mid = [(a[0] + b[0]) * T::of(0.5), (a[1] + b[1]) * T::of(0.5)];
                    let left = [-t[1] / len, t[0] / len];
                    let probe = [mid[0] + left[0], mid[1] + left[1]];
                    let (_, dir) = camera.ray(probe[0], probe[1]);
                    let depth_at = (point_on_model(mid) - probe_origin).norm();
                    let p = probe_origin + dir * depth_at.max(T::EPS);
                    let sign = if normal.dot(&p) - offset < T::zero() {
                        -T::one()
                    } else {
                        T::one()
                    };
                    plane = [
                        normal.x * sign,
                        normal.y * sign,
                        normal.z * sign,
                        offset * sign,
                    ];
                }
            }
            *slot = plane;
        }
        // The planes the cut ends on, at the ends inside the object.
        let mut tips = [None, None];
        for ((k, tip), &is_inner) in tips.iter_mut().enumerate().zip(&inner) {
            if !is_inner || m < 2 {
                continue;
            }
            let (e, back) = if k == 0 {
                (ends[0], vertex(1))
            } else {
                (ends[1], vertex(m - 2))
            };
            let d = sub(e, back);
            let len = dot2(d, d).sqrt();
            if !(len > T::EPS) {
                continue;
            }
            let out = [d[0] / len, d[1] / len];
            let at_end = point_on_model(e);
            let behind = point_on_model(back);
            let (normal, offset) = match depth {
                None => {
                    let (c, r_end) = camera.ray(e[0], e[1]);
                    let (_, r_across) = camera.ray(e[0] - out[1], e[1] + out[0]);
                    let nv = r_end.cross(&r_across);
                    (nv, nv.dot(&c))
                }
                Some(dv) => {
                    let dv = Vector3::new(dv[0], dv[1], dv[2]);
                    let dn = dv / dv.norm();
                    let along = at_end - behind;
                    let nv = along - dn * along.dot(&dn);
                    (nv, nv.dot(&at_end))
                }
            };
            let norm = normal.norm();
            if !(norm > T::zero() && norm.finite()) {
                continue;
            }
            let (normal, offset) = (normal / norm, offset / norm);
            let sign = if normal.dot(&behind) - offset > T::zero() {
                -T::one()
            } else {
                T::one()
            };
            *tip = Some([
                normal.x * sign,
                normal.y * sign,
                normal.z * sign,
                offset * sign,
            ]);
        }
        Ok(SeparationSurface {
            polyline,
            ends,
            tips,
            planes,
            camera,
            tube_px: ext,
            segment_tests: Cell::new(0),
            rays: rays.get(),
        })
    }

    fn vertex(&self, k: usize) -> [T; 2] {
        let m = self.polyline.len();
        if k == 0 {
            self.ends[0]
        } else if k + 1 == m {
            self.ends[1]
        } else {
            // `k < m` at every call.
            self.polyline.get(k).copied().unwrap_or([T::zero(); 2])
        }
    }

    /// The plane the cut ends on at end `k` (0: the first vertex, 1: the last), when that
    /// end lies inside the object.
    pub fn tip(&self, k: usize) -> Option<[T; 4]> {
        self.tips.get(k).copied().flatten()
    }

    /// The image of `p`, pixels (`None` behind the camera).
    pub fn project(&self, p: &[T; 3]) -> Option<[T; 2]> {
        let uv = self
            .camera
            .project(&Vector3::new(p[0], p[1], p[2]), 0)
            .ok()?;
        Some([uv.x, uv.y])
    }

    /// The size of some points in the image, pixels: the largest distance between the images
    /// of two of them (a point that cannot be projected is left out; 0 for fewer than two).
    pub fn image_size<const N: usize>(&self, points: &[[T; 3]; N]) -> T {
        let image = points.map(|p| self.project(&p));
        let mut size = T::zero();
        for (i, p) in image.iter().enumerate() {
            for q in image.iter().skip(i + 1) {
                if let (Some(p), Some(q)) = (p, q) {
                    let d = sub(*p, *q);
                    size = size.max(dot2(d, d).sqrt());
                }
            }
        }
        size
    }

    /// Where the image of `p` lies relative to end `k` of the polyline: its distance in pixels.
    pub fn distance_to_end(&self, k: usize, p: &[T; 3]) -> Option<T> {
        let uv = self
            .camera
            .project(&Vector3::new(p[0], p[1], p[2]), 0)
            .ok()?;
        let d = sub([uv.x, uv.y], *self.ends.get(k)?);
        Some(dot2(d, d).sqrt())
    }

    /// Whether the image of `p` lies within `slack` pixels (plus the tube's half-width) of an
    /// end inside the object: the surface must reach past such an end for the plane it ends
    /// on to cut it exactly.
    pub fn near_inner_end(&self, p: &[T; 3], slack: T) -> bool {
        self.tips.iter().enumerate().any(|(k, tip)| {
            tip.is_some()
                && self
                    .distance_to_end(k, p)
                    .is_some_and(|d| d <= slack + self.tube_px)
        })
    }

    /// The tube's half-width, pixels.
    pub fn tube_px(&self) -> T {
        self.tube_px
    }

    /// Segments of the polyline.
    pub fn segments(&self) -> usize {
        self.planes.len()
    }

    /// Point–segment tests made so far ([`SeparationSurface::foot`]).
    pub fn segment_tests(&self) -> u64 {
        self.segment_tests.get()
    }

    /// Rays cast to the model while the surface was built.
    pub fn rays(&self) -> u64 {
        self.rays
    }

    /// Where image point `q` lies relative to the polyline.
    pub fn foot(&self, q: [T; 2]) -> Option<Foot<T>> {
        let last = self.segments().checked_sub(1)?;
        self.segment_tests
            .set(self.segment_tests.get() + self.segments() as u64);
        let mut best: Option<(T, usize, T, T)> = None;
        for k in 0..=last {
            let (a, b) = (self.vertex(k), self.vertex(k + 1));
            let t = sub(b, a);
            let len2 = dot2(t, t);
            if !(len2 > T::EPS) {
                continue;
            }
            let w = sub(q, a);
            let s = dot2(w, t) / len2;
            let sc = s.max(T::zero()).min(T::one());
            let d = sub(w, [t[0] * sc, t[1] * sc]);
            let dist2 = dot2(d, d);
            if best.is_none_or(|(b, ..)| dist2 < b) {
                let signed = (t[0] * w[1] - t[1] * w[0]) / len2.sqrt();
                best = Some((dist2, k, s, signed));
            }
        }
        let (dist2, k, s, signed) = best?;
        let beyond = (k == 0 && s < T::zero()) || (k == last && s > T::one());
        Some(Foot {
            segment: k,
            signed_px: signed,
            inside: !beyond && dist2.sqrt() <= self.tube_px,
        })
    }

    /// `φ` of point `p` against the plane of `segment`, metres (`None` for a segment the
    /// polyline does not have).
    pub fn phi(&self, segment: usize, p: &[T; 3]) -> Option<T> {
        let n = self.planes.get(segment)?;
        Some(n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - n[3])
    }

    /// The nearest segment of `p`'s image and `p`'s `φ` against its plane; `None` when `p`
    /// cannot be projected.
    pub fn classify(&self, p: &[T; 3]) -> Option<(Foot<T>, T)> {
        let uv = self
            .camera
            .project(&Vector3::new(p[0], p[1], p[2]), 0)
            .ok()?;
        let foot = self.foot([uv.x, uv.y])?;
        Some((foot, self.phi(foot.segment, p)?))
    }

    /// Whether the image of `p` lies beside the polyline.
    pub fn in_extent(&self, p: &[T; 3]) -> bool {
        self.classify(p).is_some_and(|(f, _)| f.inside)
    }
}
