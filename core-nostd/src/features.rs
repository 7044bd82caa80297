//! Virtual features: each tracked image feature is tied to a point of the model surface,
//! stored as barycentric weights in one tetrahedron (an [`Embedding`]), and pulled toward its
//! observation. This module holds the observation side (ids, the latest pixel of each feature,
//! whether it is seen in this frame) and places the features at frame 0.

use nalgebra::Vector3;

use crate::camera::Camera;
use crate::embed::{Embedding, barycentric, clamp_weights};
use crate::error::{Error, Resource};
use crate::mesh::Mesh;
use crate::real::Real;
use crate::storage::{Slab, times};

/// One observation of a tracked feature in a frame: its id and its pixel position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation<T> {
    /// Feature id, stable over the video.
    pub id: u32,
    /// Pixel position `(u, v)`, undistorted.
    pub uv: [T; 2],
}

/// What [`Features::embed`] did with the frame-0 observations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmbedReport {
    /// Features whose camera ray hit the model surface: they are now virtual features.
    pub embedded: usize,
    /// Features whose ray missed the model: they take no part (their ids are unknown later).
    pub missed: usize,
    /// The lowest id that missed, if any, for the message.
    pub first_missed: Option<u32>,
}

/// Fixed-capacity storage of the tracked features' observations.
///
/// Invariants: the first `len` entries of `lookup` are `(id, slot)` pairs sorted by id with
/// distinct ids; slots are `0..len`, and slot `k` is point `k` of the features' [`Embedding`].
#[derive(Debug)]
pub struct Features<'a, T> {
    len: usize,
    lookup: &'a mut [[u32; 2]],
    target: &'a mut [[T; 2]],
    active: &'a mut [u32],
    /// Per slot, the index in the latest frame's observations where its id stood (scratch:
    /// any value is safe, see [`Features::set_frame`]).
    seen_at: &'a mut [u32],
}

impl<'a, T: Real> Features<'a, T> {
    /// Scalars of storage for `capacity` features.
    pub const fn real_len(capacity: usize) -> usize {
        times(2, capacity)
    }

    /// Indices of storage for `capacity` features.
    pub const fn index_len(capacity: usize) -> usize {
        times(4, capacity)
    }

    /// Empty storage for `capacity` features, taken from the slabs.
    ///
    /// # Errors
    /// [`Error::Capacity`] if a slab is too short.
    pub fn new(
        capacity: usize,
        reals: &mut Slab<'a, T>,
        indices: &mut Slab<'a, u32>,
    ) -> Result<Self, Error> {
        Ok(Features {
            len: 0,
            lookup: indices.take(times(2, capacity))?.as_chunks_mut::<2>().0,
            active: indices.take(capacity)?,
            seen_at: indices.take(capacity)?,
            target: reals.take(times(2, capacity))?.as_chunks_mut::<2>().0,
        })
    }

    /// Capacity.
    pub fn capacity(&self) -> usize {
        self.active.len()
    }

    /// Number of embedded features.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Makes this a copy of `other`'s features (ids, targets, observed flags), for a caller
    /// that must give them back when a call fails. Where each slot was last seen is scratch
    /// and stays as it is (no value of it marks a slot as seen, see [`Features::set_frame`]). Copies
    /// `5 · len` entries. Both must have the same capacity (the model's copy does).
    pub(crate) fn copy_from(&mut self, other: &Features<'_, T>) {
        let n = other.len.min(self.active.len());
        copy_prefix(self.lookup, other.lookup, n);
        copy_prefix(self.target, other.target, n);
        copy_prefix(self.active, other.active, n);
        self.len = n;
    }

    /// Marks `slot` as not observed in this frame (its virtual point cannot be seen).
    #[cfg_attr(not(feature = "detect"), allow(dead_code))]
    pub(crate) fn set_unobserved(&mut self, slot: usize) {
        if slot < self.len
            && let Some(a) = self.active.get_mut(slot)
        {
            *a = 0;
        }
    }

    /// The error for the virtual feature in `slot` lying behind the camera, naming its id.
    pub(crate) fn behind_camera(&self, slot: usize) -> Error {
        Error::FeatureBehindCamera {
            slot,
            id: self.id_of(slot).unwrap_or(u32::MAX),
        }
    }

    /// Whether no feature is embedded.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Places each frame-0 observation where its camera ray first meets the model surface
    /// (`positions` are the current node positions), in `embedding`, and replaces the features
    /// held so far.
    ///
    /// Cost: observations × boundary triangles ray–triangle tests; it runs once, at frame 0.
    ///
    /// # Errors
    /// [`Error::Capacity`] for more observations than the capacity (of this storage or of
    /// `embedding`); [`Error::NonFiniteInput`], [`Error::OutsideImage`] or
    /// [`Error::DuplicateFeature`] for a bad observation. On error the features held before
    /// stay as they were.
    pub fn embed(
        &mut self,
        embedding: &mut Embedding<'_, T>,
        mesh: &Mesh<'_, T>,
        positions: &[[T; 3]],
        camera: &Camera<T>,
        obs: &[Observation<T>],
        margin: T,
    ) -> Result<EmbedReport, Error> {
        let capacity = self.capacity().min(embedding.capacity());
        if obs.len() > capacity {
            return Err(Error::Capacity {
                resource: Resource::Features,
                needed: obs.len(),
                available: capacity,
            });
        }
        check_observations(camera, obs, margin)?;
        // The duplicate check sorts the ids in the `seen_at` array, scratch between frames.
        // `obs.len()` fits the capacity, checked above.
        let ids = self.seen_at.get_mut(..obs.len()).unwrap_or_default();
        for (slot, o) in ids.iter_mut().zip(obs) {
            *slot = o.id;
        }
        ids.sort_unstable();
        let duplicate = ids
            .windows(2)
            .find(|w| w.first() == w.get(1))
            .and_then(|w| w.first().copied());
        if let Some(id) = duplicate {
            return Err(Error::DuplicateFeature { id });
        }

        let mut report = EmbedReport {
            embedded: 0,
            missed: 0,
            first_missed: None,
        };
        let mut n = 0;
        embedding.clear();
        for o in obs {
            match first_hit(mesh, positions, camera, o.uv) {
                Some((tet, weights)) => {
                    // Cannot overflow: `obs.len()` fits the embedding's capacity.
                    embedding.push(tet, weights, Resource::Features)?;
                    let overflow = Error::Capacity {
                        resource: Resource::Features,
                        needed: n + 1,
                        available: capacity,
                    };
                    *self.lookup.get_mut(n).ok_or(overflow)? = [o.id, n as u32];
                    *self.target.get_mut(n).ok_or(overflow)? = o.uv;
                    *self.active.get_mut(n).ok_or(overflow)? = 1;
                    n += 1;
                }
                None => {
                    report.missed += 1;
                    report.first_missed = Some(report.first_missed.map_or(o.id, |m| m.min(o.id)));
                }
            }
        }
        self.len = n;
        self.lookup.get_mut(..n).unwrap_or_default().sort_unstable();
        report.embedded = n;
        Ok(report)
    }

    /// Takes the observations of a new frame: features observed get their new target, the
    /// others are inactive for this frame. Returns the number observed.
    ///
    /// # Errors
    /// [`Error::EmptyFrame`], [`Error::UnknownFeature`], [`Error::DuplicateFeature`],
    /// [`Error::NonFiniteInput`] or [`Error::OutsideImage`]; the frame is checked completely
    /// before anything is written, so on error the targets are those of the previous frame.
    pub fn set_frame(
        &mut self,
        camera: &Camera<T>,
        obs: &[Observation<T>],
        margin: T,
    ) -> Result<usize, Error> {
        if obs.is_empty() {
            return Err(Error::EmptyFrame);
        }
        check_observations(camera, obs, margin)?;
        // Each slot's `seen_at` is set to where its id stands in `obs`. A slot whose
        // `seen_at` already names another observation of its own id (from this pass, or left
        // from an earlier frame: either way the id stands there in this frame too) is a
        // repeated id. Whatever a slot's `seen_at` held before, its id is observed in this
        // frame exactly when `obs[seen_at]` carries it, which the second pass reads, so no
        // stale value can mark a slot seen, and no slot is looked up twice.
        for (i, o) in obs.iter().enumerate() {
            let unknown = Error::UnknownFeature { id: o.id };
            let slot = self.slot_of(o.id).ok_or(unknown)?;
            let seen_at = self.seen_at.get_mut(slot).ok_or(unknown)?;
            if *seen_at as usize != i && obs.get(*seen_at as usize).is_some_and(|p| p.id == o.id) {
                return Err(Error::DuplicateFeature { id: o.id });
            }
            // Below the embedded features' count (known and distinct ids so far), so it fits.
            *seen_at = i as u32;
        }
        // Every id is known and appears once: from here nothing fails.
        let slots = self.lookup.get(..self.len).unwrap_or_default();
        for &[id, slot] in slots {
            let slot = slot as usize;
            let seen = self.seen_at.get(slot).and_then(|&i| obs.get(i as usize));
            if let (Some(target), Some(active)) =
                (self.target.get_mut(slot), self.active.get_mut(slot))
            {
                match seen {
                    Some(o) if o.id == id => {
                        *target = o.uv;
                        *active = 1;
                    }
                    _ => *active = 0,
                }
            }
        }
        Ok(obs.len())
    }

    /// Slot of feature `id`, if embedded.
    pub fn slot_of(&self, id: u32) -> Option<usize> {
        let lookup = self.ids();
        let k = lookup.binary_search_by_key(&id, |e| e[0]).ok()?;
        lookup.get(k).map(|e| e[1] as usize)
    }

    /// Id of the feature in `slot`.
    pub fn id_of(&self, slot: usize) -> Option<u32> {
        self.ids()
            .iter()
            .find(|e| e[1] as usize == slot)
            .map(|e| e[0])
    }

    /// `(id, slot)` pairs, sorted by id.
    pub fn ids(&self) -> &[[u32; 2]] {
        self.lookup.get(..self.len).unwrap_or_default()
    }

    /// Target pixel of each slot (the latest observation).
    pub fn targets(&self) -> &[[T; 2]] {
        self.target.get(..self.len).unwrap_or_default()
    }

    /// Whether each slot is observed in the current frame (1) or not (0).
    pub fn active(&self) -> &[u32] {
        self.active.get(..self.len).unwrap_or_default()
    }
}

/// Copies the first `n` entries of `from` into `to` (as many as both hold).
/// The bounding box `(lowest, highest)` of image points, pixels; `None` for no point.
pub(crate) fn image_bounds<T: Real>(uv: &[[T; 2]]) -> Option<([T; 2], [T; 2])> {
    let (&first, rest) = uv.split_first()?;
    let (mut lo, mut hi) = (first, first);
    for p in rest {
        for ((l, h), &c) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
            *l = l.min(c);
            *h = h.max(c);
        }
    }
    Some((lo, hi))
}

/// The feature spacing of `n` features spread over a bounding box `w × h` pixels:
/// `√(w h / n)`, the box's area taken as at least one pixel.
pub(crate) fn spacing_px<T: Real>(w: T, h: T, n: usize) -> T {
    ((w * h).max(T::one()) / T::of(n as f64)).sqrt()
}

fn copy_prefix<X: Copy>(to: &mut [X], from: &[X], n: usize) {
    for (a, b) in to.iter_mut().zip(from).take(n) {
        *a = *b;
    }
}

fn check_observations<T: Real>(
    camera: &Camera<T>,
    obs: &[Observation<T>],
    margin: T,
) -> Result<(), Error> {
    for (position, o) in obs.iter().enumerate() {
        if !(o.uv[0].finite() && o.uv[1].finite()) {
            return Err(Error::NonFiniteInput {
                resource: Resource::Observations,
                position,
            });
        }
        if !camera.in_image(o.uv[0], o.uv[1], margin) {
            return Err(Error::OutsideImage { id: o.id });
        }
    }
    Ok(())
}

/// The first boundary triangle the ray through pixel `uv` meets, as (tetrahedron, barycentric
/// weights of the hit point in it).
pub(crate) fn first_hit<T: Real>(
    mesh: &Mesh<'_, T>,
    x: &[[T; 3]],
    camera: &Camera<T>,
    uv: [T; 2],
) -> Option<(u32, [T; 4])> {
    let (origin, dir) = camera.ray(uv[0], uv[1]);
    // Node indices of the mesh are validated when it is loaded; a missing one is skipped.
    let p = |v: u32| -> Option<Vector3<T>> { x.get(v as usize).map(|q| Vector3::from(*q)) };
    let mut best: Option<(T, usize)> = None;
    for (s, tri) in mesh.surface().iter().enumerate() {
        let (Some(a), Some(b), Some(c)) = (p(tri[0]), p(tri[1]), p(tri[2])) else {
            continue;
        };
        if let Some(t) = ray_triangle(&origin, &dir, &a, &b, &c)
            && best.is_none_or(|(b, _)| t < b)
        {
            best = Some((t, s));
        }
    }
    let (t, s) = best?;
    let hit = origin + dir * t;
    let tet_index = *mesh.surface_tet().get(s)?;
    let tet = mesh.tets().get(tet_index as usize)?;
    let corners = [
        *x.get(tet[0] as usize)?,
        *x.get(tet[1] as usize)?,
        *x.get(tet[2] as usize)?,
        *x.get(tet[3] as usize)?,
    ];
    // The hit lies on a face, so one weight is zero up to rounding: clamp and renormalise.
    let w = barycentric(&corners, [hit.x, hit.y, hit.z])?;
    Some((tet_index, clamp_weights(w)?))
}

/// Distance along the unit ray to triangle `(a, b, c)` (either side), if hit in front of the
/// origin (Möller–Trumbore).
fn ray_triangle<T: Real>(
    origin: &Vector3<T>,
    dir: &Vector3<T>,
    a: &Vector3<T>,
    b: &Vector3<T>,
    c: &Vector3<T>,
) -> Option<T> {
    let e1 = b - a;
    let e2 = c - a;
    let pv = dir.cross(&e2);
    let det = e1.dot(&pv);
    let scale = e1.norm() * e2.norm();
    if det.abs() <= T::EPS * scale {
        return None;
    }
    let tv = origin - a;
    let u = tv.dot(&pv) / det;
    // A hair of slack so that a ray through a shared edge hits one of its two triangles.
    let slack = T::of(1e-9);
    if u < -slack || u > T::one() + slack {
        return None;
    }
    let qv = tv.cross(&e1);
    let v = dir.dot(&qv) / det;
    if v < -slack || u + v > T::one() + slack {
        return None;
    }
    let t = e2.dot(&qv) / det;
    (t > T::zero()).then_some(t)
}
