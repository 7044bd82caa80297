//! Points carried by the mesh: each stored as one tetrahedron and four barycentric weights, so
//! that it moves with the nodes. Virtual features (on the surface) and internal targets (a
//! tumour, vessel points) are both embeddings; a cut re-embeds them in the piece of their own
//! side ([`crate::cut`]).

use crate::error::{Error, Resource};
use crate::mesh::Mesh;
use crate::real::Real;
use crate::storage::{Slab, times};

/// Fixed-capacity storage of embedded points.
///
/// Invariants: each of the first `len` entries names a tetrahedron of the mesh it was embedded
/// in, and its four weights are non-negative and sum to one.
#[derive(Debug)]
pub struct Embedding<'a, T> {
    len: usize,
    tet: &'a mut [u32],
    weights: &'a mut [[T; 4]],
}

impl<'a, T: Real> Embedding<'a, T> {
    /// Scalars of storage for `capacity` points.
    pub const fn real_len(capacity: usize) -> usize {
        times(4, capacity)
    }

    /// Indices of storage for `capacity` points.
    pub const fn index_len(capacity: usize) -> usize {
        capacity
    }

    /// Empty storage for `capacity` points, taken from the slabs.
    ///
    /// # Errors
    /// [`Error::Capacity`] if a slab is too short.
    pub fn with_capacity(
        capacity: usize,
        reals: &mut Slab<'a, T>,
        indices: &mut Slab<'a, u32>,
    ) -> Result<Self, Error> {
        Ok(Embedding {
            len: 0,
            tet: indices.take(capacity)?,
            weights: reals.take(times(4, capacity))?.as_chunks_mut::<4>().0,
        })
    }

    /// Capacity.
    pub fn capacity(&self) -> usize {
        self.tet.len()
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Tetrahedron of each point.
    pub fn tets(&self) -> &[u32] {
        self.tet.get(..self.len).unwrap_or_default()
    }

    /// Barycentric weights of each point.
    pub fn weights(&self) -> &[[T; 4]] {
        self.weights.get(..self.len).unwrap_or_default()
    }

    /// Forgets every point.
    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// Appends a point.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming `resource` when full.
    pub(crate) fn push(&mut self, tet: u32, w: [T; 4], resource: Resource) -> Result<(), Error> {
        match (self.tet.get_mut(self.len), self.weights.get_mut(self.len)) {
            (Some(t), Some(weights)) => {
                *t = tet;
                *weights = w;
                self.len += 1;
                Ok(())
            }
            _ => Err(Error::Capacity {
                resource,
                needed: self.len + 1,
                available: self.tet.len().min(self.weights.len()),
            }),
        }
    }

    /// Moves point `k` (ignored out of range).
    #[cfg_attr(not(feature = "cut"), allow(dead_code))]
    pub(crate) fn set(&mut self, k: usize, tet: u32, w: [T; 4]) {
        if k < self.len
            && let (Some(t), Some(weights)) = (self.tet.get_mut(k), self.weights.get_mut(k))
        {
            *t = tet;
            *weights = w;
        }
    }

    /// Makes this a copy of `other` (same capacity: the two halves of one model).
    #[cfg_attr(not(feature = "cut"), allow(dead_code))]
    pub(crate) fn copy_from(&mut self, other: &Embedding<'_, T>) {
        let mut n = 0;
        for ((t, w), (&ot, &ow)) in self
            .tet
            .iter_mut()
            .zip(self.weights.iter_mut())
            .zip(other.tets().iter().zip(other.weights()))
        {
            *t = ot;
            *w = ow;
            n += 1;
        }
        self.len = n;
    }

    /// Position of point `k` for node positions `x` (`None` out of range).
    pub fn position(&self, k: usize, mesh: &Mesh<'_, T>, x: &[[T; 3]]) -> Option<[T; 3]> {
        let tet = mesh.tets().get(*self.tets().get(k)? as usize)?;
        interpolate(x, tet, self.weights().get(k)?)
    }
}

/// `Σ_a w_a x[tet[a]]` (`None` for a node out of range).
pub(crate) fn interpolate<T: Real>(x: &[[T; 3]], tet: &[u32; 4], w: &[T; 4]) -> Option<[T; 3]> {
    let mut p = [T::zero(); 3];
    for (&v, &wa) in tet.iter().zip(w) {
        let xv = x.get(v as usize)?;
        for (pc, &xc) in p.iter_mut().zip(xv) {
            *pc += wa * xc;
        }
    }
    Some(p)
}

/// The points `x[nodes[a]]` of an element (`None` for a node out of range).
#[cfg(feature = "cut")]
pub(crate) fn gather<P: Copy, const N: usize>(x: &[P], nodes: &[u32; N]) -> Option<[P; N]> {
    let mut out = [*x.first()?; N];
    for (o, &v) in out.iter_mut().zip(nodes) {
        *o = *x.get(v as usize)?;
    }
    Some(out)
}

/// Barycentric coordinates of `p` in the tetrahedron with corners `x` (they sum to one; all
/// non-negative inside). `None` for a flat tetrahedron.
pub(crate) fn barycentric<T: Real>(x: &[[T; 3]; 4], p: [T; 3]) -> Option<[T; 4]> {
    let e = |xk: &[T; 3]| nalgebra::Vector3::new(xk[0] - x[0][0], xk[1] - x[0][1], xk[2] - x[0][2]);
    let m = nalgebra::Matrix3::from_columns(&[e(&x[1]), e(&x[2]), e(&x[3])]);
    let inv = m.try_inverse()?;
    let l = inv * nalgebra::Vector3::new(p[0] - x[0][0], p[1] - x[0][1], p[2] - x[0][2]);
    let w = [T::one() - l.x - l.y - l.z, l.x, l.y, l.z];
    w.iter().all(|c| c.finite()).then_some(w)
}

/// Clamps barycentric weights to be non-negative and renormalises them (`None` if nothing is
/// left).
pub(crate) fn clamp_weights<T: Real>(w: [T; 4]) -> Option<[T; 4]> {
    let mut c = w.map(|wk| wk.max(T::zero()));
    let sum = c[0] + c[1] + c[2] + c[3];
    if !(sum > T::zero()) {
        return None;
    }
    for ck in c.iter_mut() {
        *ck /= sum;
    }
    Some(c)
}

/// The tetrahedron of `mesh` that holds the rest point `p`: the one containing it, else the
/// one it lies least outside of (by the sum of its negative weights), with the weights clamped
/// to it. Cost: one barycentric solve per tetrahedron.
pub(crate) fn locate_at_rest<T: Real>(mesh: &Mesh<'_, T>, p: [T; 3]) -> Option<(u32, [T; 4])> {
    let rest = mesh.rest();
    let mut best: Option<(T, u32, [T; 4])> = None;
    for (t, tet) in mesh.tets().iter().enumerate() {
        let mut corners = [[T::zero(); 3]; 4];
        for (c, &v) in corners.iter_mut().zip(tet) {
            match rest.get(v as usize) {
                Some(&r) => *c = r,
                None => return None,
            }
        }
        let Some(w) = barycentric(&corners, p) else {
            continue;
        };
        let outside = w.iter().fold(T::zero(), |s, &wk| s + (-wk).max(T::zero()));
        if best.as_ref().is_none_or(|(b, _, _)| outside < *b) {
            best = Some((outside, t as u32, w));
            if outside == T::zero() {
                break;
            }
        }
    }
    let (_, t, w) = best?;
    Some((t, clamp_weights(w)?))
}
