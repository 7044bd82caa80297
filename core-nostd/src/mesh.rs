//! The tetrahedral volume mesh of the model: rest positions, tetrahedra, fixed nodes and the
//! boundary surface, in fixed-capacity storage.

use crate::error::{Error, Resource};
use crate::material::ElementRest;
use crate::real::Real;
use crate::sparse::NONE;
use crate::storage::{Slab, ensure_len, sum, times};

/// A mesh as the caller hands it over: rest positions (metres), tetrahedra (node indices,
/// positively oriented: `(X1 − X0) · ((X2 − X0) × (X3 − X0)) > 0`) and the fixed nodes.
#[derive(Clone, Copy, Debug)]
pub struct MeshInput<'m, T> {
    /// Rest positions of the nodes, metres.
    pub rest: &'m [[T; 3]],
    /// Tetrahedra.
    pub tets: &'m [[u32; 4]],
    /// Indices of the nodes held at their rest position.
    pub fixed: &'m [u32],
}

/// How many nodes, tetrahedra and boundary triangles the mesh storage holds at most.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MeshCapacity {
    /// Nodes.
    pub nodes: usize,
    /// Tetrahedra.
    pub tets: usize,
    /// Boundary triangles.
    pub surface_triangles: usize,
}

impl MeshCapacity {
    /// Exactly what `mesh` needs (boundary triangles bounded by four per tetrahedron).
    pub fn exact<T>(mesh: &MeshInput<'_, T>) -> Self {
        MeshCapacity {
            nodes: mesh.rest.len(),
            tets: mesh.tets.len(),
            surface_triangles: 4 * mesh.tets.len(),
        }
    }

    /// Scalars of storage [`Mesh::new`] takes from its scalar slab.
    pub const fn real_len(&self) -> usize {
        sum(&[times(3, self.nodes), times(ELEMENT_REST_LEN, self.tets)])
    }

    /// Indices of storage [`Mesh::new`] takes from its index slab.
    pub const fn index_len(&self) -> usize {
        sum(&[
            times(4, self.tets),
            self.nodes,
            times(4, self.surface_triangles),
        ])
    }

    /// Length of the `u32` workspace [`Mesh::new`] needs.
    pub const fn work_len(&self) -> usize {
        let faces = times(16, self.tets);
        let edges = times(6, self.surface_triangles);
        if faces > edges { faces } else { edges }
    }
}

/// Scalars stored per tetrahedron: `Dm⁻¹` (9, column-major) and the rest volume.
pub const ELEMENT_REST_LEN: usize = 10;

/// The validated mesh.
///
/// Invariants established by [`Mesh::new`]: every tetrahedron has positive rest volume and
/// indices below [`Mesh::n_nodes`]; `free_index` maps each node to its compact index among the
/// free nodes or to [`NONE`] for a fixed node; at least one node is fixed; the boundary surface
/// is a closed 2-manifold (every boundary edge in exactly two boundary triangles), each
/// triangle oriented with its normal pointing out of the tetrahedron that owns it.
#[derive(Debug)]
pub struct Mesh<'a, T> {
    capacity: MeshCapacity,
    n_nodes: usize,
    n_tets: usize,
    n_surface: usize,
    n_free: usize,
    rest: &'a mut [[T; 3]],
    element_rest: &'a mut [[T; ELEMENT_REST_LEN]],
    tets: &'a mut [[u32; 4]],
    free_index: &'a mut [u32],
    surface: &'a mut [[u32; 3]],
    surface_tet: &'a mut [u32],
}

impl<'a, T: Real> Mesh<'a, T> {
    /// An empty mesh (no node, no tetrahedron) in storage taken from the slabs (sizes from
    /// [`MeshCapacity::real_len`] / [`MeshCapacity::index_len`]), to be filled by
    /// [`Mesh::load`].
    ///
    /// # Errors
    /// [`Error::Capacity`] if a slab is too short.
    pub fn with_capacity(
        capacity: &MeshCapacity,
        reals: &mut Slab<'a, T>,
        indices: &mut Slab<'a, u32>,
    ) -> Result<Self, Error> {
        Ok(Mesh {
            capacity: *capacity,
            n_nodes: 0,
            n_tets: 0,
            n_surface: 0,
            n_free: 0,
            rest: reals.take(times(3, capacity.nodes))?.as_chunks_mut::<3>().0,
            element_rest: reals
                .take(times(ELEMENT_REST_LEN, capacity.tets))?
                .as_chunks_mut::<ELEMENT_REST_LEN>()
                .0,
            tets: indices
                .take(times(4, capacity.tets))?
                .as_chunks_mut::<4>()
                .0,
            free_index: indices.take(capacity.nodes)?,
            surface: indices
                .take(times(3, capacity.surface_triangles))?
                .as_chunks_mut::<3>()
                .0,
            surface_tet: indices.take(capacity.surface_triangles)?,
        })
    }

    /// Validates `input`, copies it into storage taken from the slabs and extracts the
    /// boundary surface: [`Mesh::with_capacity`] then [`Mesh::load`].
    ///
    /// # Errors
    /// As [`Mesh::with_capacity`] and [`Mesh::load`].
    pub fn new(
        input: &MeshInput<'_, T>,
        capacity: &MeshCapacity,
        reals: &mut Slab<'a, T>,
        indices: &mut Slab<'a, u32>,
        work: &mut [u32],
    ) -> Result<Self, Error> {
        let mut mesh = Self::with_capacity(capacity, reals, indices)?;
        mesh.load(input, work)?;
        Ok(mesh)
    }

    /// Validates `input`, replaces this mesh with it and extracts the boundary surface, using
    /// `work` ([`MeshCapacity::work_len`] entries, no meaning on return).
    ///
    /// # Errors
    /// [`Error::Capacity`] if the mesh exceeds the capacity or `work` is too short;
    /// [`Error::NonFiniteInput`] for a non-finite coordinate; [`Error::IndexOutOfRange`] for a
    /// bad node index in a tetrahedron or the fixed list; [`Error::DegenerateElement`] /
    /// [`Error::InvertedElement`] for a bad rest tetrahedron; [`Error::NoFixedNodes`];
    /// [`Error::NonManifold`] for a face shared by more than two tetrahedra or a boundary edge
    /// not shared by exactly two boundary triangles. Everything but the surface is checked
    /// before anything is written; a surface that does not close leaves the mesh empty.
    pub fn load(&mut self, input: &MeshInput<'_, T>, work: &mut [u32]) -> Result<(), Error> {
        let capacity = self.capacity;
        let (n_nodes, n_tets) = (input.rest.len(), input.tets.len());
        check_capacity(Resource::Nodes, n_nodes, capacity.nodes)?;
        check_capacity(Resource::Tetrahedra, n_tets, capacity.tets)?;
        ensure_len(work, capacity.work_len(), Resource::Workspace)?;
        for (position, p) in input.rest.iter().enumerate() {
            if !p.iter().all(|c| c.finite()) {
                return Err(Error::NonFiniteInput {
                    resource: Resource::Nodes,
                    position,
                });
            }
        }
        for (t, tet) in input.tets.iter().enumerate() {
            for (k, &v) in tet.iter().enumerate() {
                if v as usize >= n_nodes {
                    return Err(Error::IndexOutOfRange {
                        resource: Resource::Tetrahedra,
                        position: 4 * t + k,
                        index: v as usize,
                        bound: n_nodes,
                    });
                }
            }
        }
        if input.fixed.is_empty() {
            return Err(Error::NoFixedNodes);
        }
        for (position, &f) in input.fixed.iter().enumerate() {
            if f as usize >= n_nodes {
                return Err(Error::IndexOutOfRange {
                    resource: Resource::Nodes,
                    position,
                    index: f as usize,
                    bound: n_nodes,
                });
            }
        }
        // Element geometry: rejects degenerate and inverted tetrahedra before anything is kept.
        for (t, tet) in input.tets.iter().enumerate() {
            ElementRest::new(&corners(input.rest, tet)?, t)?;
        }

        copy_prefix(self.rest, input.rest, Resource::Nodes)?;
        copy_prefix(self.tets, input.tets, Resource::Tetrahedra)?;
        for f in self.free_index.iter_mut().take(n_nodes) {
            *f = 0;
        }
        for &f in input.fixed {
            if let Some(slot) = self.free_index.get_mut(f as usize) {
                *slot = NONE;
            }
        }
        self.n_nodes = n_nodes;
        self.n_tets = n_tets;
        let done = self.finish_edit(work);
        if done.is_err() {
            self.n_nodes = 0;
            self.n_tets = 0;
            self.n_surface = 0;
            self.n_free = 0;
        }
        done
    }

    /// Makes this mesh a copy of `other` (same capacities: the two halves of one model).
    #[cfg_attr(not(feature = "cut"), allow(dead_code))]
    pub(crate) fn copy_from(&mut self, other: &Mesh<'_, T>) {
        // Same capacities: every prefix fits (`zip` stops at the shorter otherwise).
        let copy = |to: &mut [u32], from: &[u32]| {
            to.iter_mut().zip(from).for_each(|(a, &b)| *a = b);
        };
        self.rest
            .iter_mut()
            .zip(other.rest())
            .for_each(|(a, &b)| *a = b);
        self.element_rest
            .iter_mut()
            .zip(other.element_rest.iter().take(other.n_tets))
            .for_each(|(a, &b)| *a = b);
        self.tets
            .iter_mut()
            .zip(other.tets())
            .for_each(|(a, &b)| *a = b);
        copy(self.free_index, other.free_index());
        self.surface
            .iter_mut()
            .zip(other.surface())
            .for_each(|(a, &b)| *a = b);
        copy(self.surface_tet, other.surface_tet());
        self.n_nodes = other.n_nodes.min(self.rest.len());
        self.n_tets = other.n_tets.min(self.tets.len());
        self.n_surface = other.n_surface.min(self.surface.len());
        self.n_free = other.n_free;
    }

    /// Appends a node at rest position `rest` (held at rest if `fixed`); its free index is
    /// assigned by [`Mesh::finish_edit`].
    ///
    /// # Errors
    /// [`Error::Capacity`] naming [`Resource::Nodes`] when the capacity is full.
    #[cfg_attr(not(feature = "cut"), allow(dead_code))]
    pub(crate) fn push_node(&mut self, rest: [T; 3], fixed: bool) -> Result<u32, Error> {
        check_capacity(Resource::Nodes, self.n_nodes + 1, self.capacity.nodes)?;
        let v = self.n_nodes;
        match (self.rest.get_mut(v), self.free_index.get_mut(v)) {
            (Some(r), Some(f)) => {
                *r = rest;
                *f = if fixed { NONE } else { 0 };
            }
            _ => return Err(full(Resource::Nodes, v + 1, self.rest.len())),
        }
        self.n_nodes += 1;
        Ok(v as u32)
    }

    /// Moves the rest position of node `v` (element data follows in [`Mesh::finish_edit`]).
    #[cfg_attr(not(feature = "cut"), allow(dead_code))]
    pub(crate) fn set_rest(&mut self, v: usize, p: [T; 3]) {
        if v < self.n_nodes
            && let Some(slot) = self.rest.get_mut(v)
        {
            *slot = p;
        }
    }

    /// Replaces the nodes of tetrahedron `t`.
    #[cfg_attr(not(feature = "cut"), allow(dead_code))]
    pub(crate) fn set_tet(&mut self, t: usize, tet: [u32; 4]) {
        if t < self.n_tets
            && let Some(slot) = self.tets.get_mut(t)
        {
            *slot = tet;
        }
    }

    /// Appends a tetrahedron.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming [`Resource::Tetrahedra`] when the capacity is full.
    #[cfg_attr(not(feature = "cut"), allow(dead_code))]
    pub(crate) fn push_tet(&mut self, tet: [u32; 4]) -> Result<u32, Error> {
        check_capacity(Resource::Tetrahedra, self.n_tets + 1, self.capacity.tets)?;
        let t = self.n_tets;
        let slot =
            self.tets
                .get_mut(t)
                .ok_or(full(Resource::Tetrahedra, t + 1, self.capacity.tets))?;
        *slot = tet;
        self.n_tets += 1;
        Ok(t as u32)
    }

    /// After nodes or tetrahedra changed: numbers the free nodes, recomputes the rest geometry
    /// of every tetrahedron and extracts the boundary surface; `work` as for [`Mesh::load`].
    ///
    /// # Errors
    /// [`Error::DegenerateElement`] / [`Error::InvertedElement`], [`Error::NonManifold`],
    /// [`Error::Capacity`] for the surface or a short `work`. The mesh is then inconsistent:
    /// callers edit a spare copy and drop it on error.
    pub(crate) fn finish_edit(&mut self, work: &mut [u32]) -> Result<(), Error> {
        ensure_len(work, self.capacity.work_len(), Resource::Workspace)?;
        let mut n_free = 0u32;
        for f in self.free_index.iter_mut().take(self.n_nodes) {
            if *f != NONE {
                *f = n_free;
                n_free += 1;
            }
        }
        self.n_free = n_free as usize;
        if n_free as usize == self.n_nodes {
            return Err(Error::NoFixedNodes);
        }
        for t in 0..self.n_tets {
            self.update_element_rest(t)?;
        }
        self.extract_surface(work)
    }

    fn update_element_rest(&mut self, t: usize) -> Result<(), Error> {
        let tet = self.tets().get(t).ok_or(Error::IndexOutOfRange {
            resource: Resource::Tetrahedra,
            position: t,
            index: t,
            bound: self.n_tets,
        })?;
        let e = ElementRest::new(&corners(self.rest(), tet)?, t)?;
        let slot = self.element_rest.get_mut(t).ok_or(full(
            Resource::Tetrahedra,
            t + 1,
            self.capacity.tets,
        ))?;
        let [dm @ .., volume] = slot;
        dm.copy_from_slice(e.dm_inv.as_slice());
        *volume = e.volume;
        Ok(())
    }

    /// Finds the faces that belong to one tetrahedron only, orients them outward and checks
    /// that they close up.
    fn extract_surface(&mut self, work: &mut [u32]) -> Result<(), Error> {
        let n_tets = self.n_tets;
        let work_len = work.len();
        let faces = work
            .get_mut(..16 * n_tets)
            .ok_or(full(Resource::Workspace, 16 * n_tets, work_len))?
            .as_chunks_mut::<4>()
            .0;
        for ((t, tet), four) in self
            .tets()
            .iter()
            .enumerate()
            .zip(faces.chunks_exact_mut(4))
        {
            for (l, face) in four.iter_mut().enumerate() {
                let [a, b, c] = opposite(tet, l);
                let mut f = [a, b, c];
                f.sort_unstable();
                *face = [f[0], f[1], f[2], (4 * t + l) as u32];
            }
        }
        faces.sort_unstable();
        let mut n_surface = 0usize;
        for run in faces.chunk_by(|a, b| a[..3] == b[..3]) {
            match run {
                [one] => {
                    let code = one[3] as usize;
                    let (t, l) = (code / 4, code % 4);
                    let tet = *self
                        .tets()
                        .get(t)
                        .ok_or(full(Resource::Tetrahedra, t, n_tets))?;
                    let mut tri = opposite(&tet, l);
                    // Outward: the opposite node lies on the negative side of the normal.
                    let [p0, p1, p2] = corners(self.rest(), &tri)?;
                    let [far] = corners(self.rest(), &[opposite(&tet, l + 3)[0]])?;
                    if orientation(p0, p1, p2, far) > T::zero() {
                        tri.swap(1, 2);
                    }
                    match (
                        self.surface.get_mut(n_surface),
                        self.surface_tet.get_mut(n_surface),
                    ) {
                        (Some(s), Some(st)) if n_surface < self.capacity.surface_triangles => {
                            *s = tri;
                            *st = t as u32;
                        }
                        _ => {
                            return Err(full(
                                Resource::SurfaceTriangles,
                                n_surface + 1,
                                self.capacity.surface_triangles,
                            ));
                        }
                    }
                    n_surface += 1;
                }
                [_, _] => {}
                [first, ..] => {
                    return Err(Error::NonManifold {
                        a: first[0] as usize,
                        b: first[1] as usize,
                    });
                }
                [] => {}
            }
        }
        // Every boundary edge must be shared by exactly two boundary triangles.
        let edges = work
            .get_mut(..6 * n_surface)
            .ok_or(full(Resource::Workspace, 6 * n_surface, work_len))?
            .as_chunks_mut::<2>()
            .0;
        let surface = self.surface.iter().take(n_surface);
        for (tri, three) in surface.zip(edges.chunks_exact_mut(3)) {
            let [t0, t1, t2] = *tri;
            for (edge, (a, b)) in three.iter_mut().zip([(t0, t1), (t1, t2), (t2, t0)]) {
                *edge = [a.min(b), a.max(b)];
            }
        }
        edges.sort_unstable();
        for run in edges.chunk_by(|a, b| a == b) {
            if let [first, ..] = run
                && run.len() != 2
            {
                return Err(Error::NonManifold {
                    a: first[0] as usize,
                    b: first[1] as usize,
                });
            }
        }
        self.n_surface = n_surface;
        Ok(())
    }

    /// The capacities this mesh was built with.
    pub fn capacity(&self) -> &MeshCapacity {
        &self.capacity
    }
    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.n_nodes
    }
    /// Number of tetrahedra.
    pub fn n_tets(&self) -> usize {
        self.n_tets
    }
    /// Number of free (not fixed) nodes.
    pub fn n_free(&self) -> usize {
        self.n_free
    }
    /// Rest positions, metres.
    pub fn rest(&self) -> &[[T; 3]] {
        self.rest.get(..self.n_nodes).unwrap_or_default()
    }
    /// Tetrahedra.
    pub fn tets(&self) -> &[[u32; 4]] {
        self.tets.get(..self.n_tets).unwrap_or_default()
    }
    /// Compact index of each node among the free nodes, [`NONE`] for a fixed node.
    pub fn free_index(&self) -> &[u32] {
        self.free_index.get(..self.n_nodes).unwrap_or_default()
    }
    /// Boundary triangles, oriented outward.
    pub fn surface(&self) -> &[[u32; 3]] {
        self.surface.get(..self.n_surface).unwrap_or_default()
    }
    /// The tetrahedron each boundary triangle belongs to.
    pub fn surface_tet(&self) -> &[u32] {
        self.surface_tet.get(..self.n_surface).unwrap_or_default()
    }
    /// Whether node `v` is held at rest (`false` out of range).
    pub fn is_fixed(&self, v: usize) -> bool {
        self.free_index().get(v).is_some_and(|&f| f == NONE)
    }
    /// Rest geometry of tetrahedron `t` (`None` if out of range).
    pub fn element_rest(&self, t: usize) -> Option<ElementRest<T>> {
        if t >= self.n_tets {
            return None;
        }
        let [dm @ .., volume] = self.element_rest.get(t)?;
        Some(ElementRest {
            dm_inv: nalgebra::Matrix3::from_column_slice(dm),
            volume: *volume,
        })
    }
}

/// The capacity error for `resource`.
fn full(resource: Resource, needed: usize, available: usize) -> Error {
    Error::Capacity {
        resource,
        needed,
        available,
    }
}

/// The positions of nodes `nodes` (an error for a node out of range).
fn corners<T: Real, const N: usize>(
    rest: &[[T; 3]],
    nodes: &[u32; N],
) -> Result<[[T; 3]; N], Error> {
    let mut x = [[T::zero(); 3]; N];
    for (k, (xk, &v)) in x.iter_mut().zip(nodes).enumerate() {
        *xk = *rest.get(v as usize).ok_or(Error::IndexOutOfRange {
            resource: Resource::Nodes,
            position: k,
            index: v as usize,
            bound: rest.len(),
        })?;
    }
    Ok(x)
}

/// The face of `tet` opposite its node `l`, in the order that keeps the orientation rule.
fn opposite(tet: &[u32; 4], l: usize) -> [u32; 3] {
    let at = |k: usize| match k % 4 {
        0 => tet[0],
        1 => tet[1],
        2 => tet[2],
        _ => tet[3],
    };
    [at(l + 1), at(l + 2), at(l + 3)]
}

/// Copies `from` into the start of `to` (a capacity error if it does not fit).
fn copy_prefix<X: Copy>(to: &mut [X], from: &[X], resource: Resource) -> Result<(), Error> {
    let available = to.len();
    to.get_mut(..from.len())
        .ok_or(full(resource, from.len(), available))?
        .copy_from_slice(from);
    Ok(())
}

fn check_capacity(resource: Resource, needed: usize, available: usize) -> Result<(), Error> {
    if needed > available {
        Err(Error::Capacity {
            resource,
            needed,
            available,
        })
    } else {
        Ok(())
    }
}

/// Shape quality of a tetrahedron: `6√2 · V / ℓ³`, `V` its signed volume and `ℓ` the root
/// mean square of its six edge lengths. It is 1 for the regular tetrahedron, falls to 0 as the
/// tetrahedron flattens (whatever the way: needle, wedge, sliver or cap) and is negative when it
/// is inverted; it does not depend on the size. The cut keeps every element it creates or moves
/// above a floor of this measure ([`crate::cut::QUALITY_FLOOR`]).
pub fn shape_quality<T: Real>(x: &[[T; 3]; 4]) -> T {
    let mut sum_sq = T::zero();
    for (a, xa) in x.iter().enumerate() {
        for xb in x.iter().skip(a + 1) {
            let d = [xb[0] - xa[0], xb[1] - xa[1], xb[2] - xa[2]];
            sum_sq += d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        }
    }
    let rms = (sum_sq / T::of(6.0)).sqrt();
    let volume = orientation(x[0], x[1], x[2], x[3]) / T::of(6.0);
    let scale = rms * rms * rms;
    if !(scale > T::zero()) {
        return T::zero();
    }
    T::of(6.0 * core::f64::consts::SQRT_2) * volume / scale
}

/// `(b − a) × (c − a) · (d − a)`: positive when `d` lies on the side the normal of `(a, b, c)`
/// points to.
pub(crate) fn orientation<T: Real>(a: [T; 3], b: [T; 3], c: [T; 3], d: [T; 3]) -> T {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    (u[1] * v[2] - u[2] * v[1]) * w[0]
        + (u[2] * v[0] - u[0] * v[2]) * w[1]
        + (u[0] * v[1] - u[1] * v[0]) * w[2]
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;

    /// Two tetrahedra sharing face (1, 2, 3), with node 4 on the other side of node 0.
    const REST: [[f64; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ];
    const TETS: [[u32; 4]; 2] = [[0, 1, 2, 3], [1, 2, 3, 4]];

    fn build(
        input: &MeshInput<'_, f64>,
        reals: &mut [f64],
        idx: &mut [u32],
        work: &mut [u32],
    ) -> Result<(usize, usize, usize), Error> {
        let cap = MeshCapacity::exact(input);
        let mut rs = Slab::new(reals, Resource::RealStorage);
        let mut is = Slab::new(idx, Resource::IndexStorage);
        let m = Mesh::new(input, &cap, &mut rs, &mut is, work)?;
        // Every boundary triangle points away from its tetrahedron's centroid.
        for (tri, &t) in m.surface().iter().zip(m.surface_tet()) {
            let tet = m.tets()[t as usize];
            let mut c = [0.0; 3];
            for v in tet {
                for k in 0..3 {
                    c[k] += m.rest()[v as usize][k] / 4.0;
                }
            }
            let p = |v: u32| m.rest()[v as usize];
            assert!(orientation(p(tri[0]), p(tri[1]), p(tri[2]), c) < 0.0);
        }
        Ok((m.n_surface, m.n_free(), m.n_tets()))
    }

    #[test]
    fn two_tets_have_six_outward_boundary_triangles() {
        let input = MeshInput {
            rest: &REST,
            tets: &TETS,
            fixed: &[0],
        };
        let (mut r, mut i, mut w) = ([0.0; 64], [0u32; 64], [0u32; 64]);
        assert_eq!(build(&input, &mut r, &mut i, &mut w), Ok((6, 4, 2)));
    }

    #[test]
    fn validation_errors() {
        let (mut r, mut i, mut w) = ([0.0; 64], [0u32; 64], [0u32; 64]);
        let no_fixed = MeshInput {
            rest: &REST,
            tets: &TETS,
            fixed: &[],
        };
        assert_eq!(
            build(&no_fixed, &mut r, &mut i, &mut w),
            Err(Error::NoFixedNodes)
        );
        let inverted = MeshInput {
            rest: &REST,
            tets: &[[0, 2, 1, 3]],
            fixed: &[0],
        };
        assert_eq!(
            build(&inverted, &mut r, &mut i, &mut w),
            Err(Error::InvertedElement { tet: 0 })
        );
        let flat = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        let degenerate = MeshInput {
            rest: &flat,
            tets: &[[0, 1, 2, 3]],
            fixed: &[0],
        };
        assert_eq!(
            build(&degenerate, &mut r, &mut i, &mut w),
            Err(Error::DegenerateElement { tet: 0 })
        );
        let out_of_range = MeshInput {
            rest: &REST,
            tets: &[[0, 1, 2, 9]],
            fixed: &[0],
        };
        assert!(matches!(
            build(&out_of_range, &mut r, &mut i, &mut w),
            Err(Error::IndexOutOfRange { index: 9, .. })
        ));
        let nan = [[f64::NAN, 0.0, 0.0]; 4];
        let non_finite = MeshInput {
            rest: &nan,
            tets: &[[0, 1, 2, 3]],
            fixed: &[0],
        };
        assert!(matches!(
            build(&non_finite, &mut r, &mut i, &mut w),
            Err(Error::NonFiniteInput { position: 0, .. })
        ));
    }

    #[test]
    fn tets_touching_along_an_edge_are_not_manifold() {
        // Two tetrahedra sharing only the edge (0, 1).
        let rest = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, -1.0],
        ];
        let input = MeshInput {
            rest: &rest,
            tets: &[[0, 1, 2, 3], [0, 1, 4, 5]],
            fixed: &[0],
        };
        let (mut r, mut i, mut w) = ([0.0; 64], [0u32; 64], [0u32; 64]);
        assert_eq!(
            build(&input, &mut r, &mut i, &mut w),
            Err(Error::NonManifold { a: 0, b: 1 })
        );
    }
}
