//! The tetrahedral volume mesh of the model: rest positions, tetrahedra, fixed nodes and the
//! boundary surface, in fixed-capacity storage.

use crate::error::{Error, Resource};
use crate::material::ElementRest;
use crate::real::Real;
use crate::sparse::NONE;
use crate::storage::{Slab, ensure_len};

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
        3 * self.nodes + ELEMENT_REST_LEN * self.tets
    }

    /// Indices of storage [`Mesh::new`] takes from its index slab.
    pub const fn index_len(&self) -> usize {
        4 * self.tets + self.nodes + 4 * self.surface_triangles
    }

    /// Length of the `u32` workspace [`Mesh::new`] needs.
    pub const fn work_len(&self) -> usize {
        let faces = 16 * self.tets;
        let edges = 6 * self.surface_triangles;
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
    /// Validates `input`, copies it into storage taken from the slabs (sizes from
    /// [`MeshCapacity::real_len`] / [`MeshCapacity::index_len`]) and extracts the boundary
    /// surface, using `work` ([`MeshCapacity::work_len`] entries, no meaning on return).
    ///
    /// # Errors
    /// [`Error::Capacity`] if the mesh exceeds `capacity` or a slab or `work` is too short;
    /// [`Error::NonFiniteInput`] for a non-finite coordinate; [`Error::IndexOutOfRange`] for a
    /// bad node index in a tetrahedron or the fixed list; [`Error::DegenerateElement`] /
    /// [`Error::InvertedElement`] for a bad rest tetrahedron; [`Error::NoFixedNodes`];
    /// [`Error::NonManifold`] for a face shared by more than two tetrahedra or a boundary edge
    /// not shared by exactly two boundary triangles.
    pub fn new(
        input: &MeshInput<'_, T>,
        capacity: &MeshCapacity,
        reals: &mut Slab<'a, T>,
        indices: &mut Slab<'a, u32>,
        work: &mut [u32],
    ) -> Result<Self, Error> {
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
            ElementRest::new(&tet.map(|v| input.rest[v as usize]), t)?;
        }

        let rest = reals.take(3 * capacity.nodes)?.as_chunks_mut::<3>().0;
        let element_rest = reals
            .take(ELEMENT_REST_LEN * capacity.tets)?
            .as_chunks_mut::<ELEMENT_REST_LEN>()
            .0;
        let tets = indices.take(4 * capacity.tets)?.as_chunks_mut::<4>().0;
        let free_index = indices.take(capacity.nodes)?;
        let surface = indices
            .take(3 * capacity.surface_triangles)?
            .as_chunks_mut::<3>()
            .0;
        let surface_tet = indices.take(capacity.surface_triangles)?;

        rest[..n_nodes].copy_from_slice(input.rest);
        tets[..n_tets].copy_from_slice(input.tets);
        free_index.fill(0);
        for &f in input.fixed {
            free_index[f as usize] = NONE;
        }
        let mut n_free = 0u32;
        for f in free_index[..n_nodes].iter_mut() {
            if *f != NONE {
                *f = n_free;
                n_free += 1;
            }
        }
        let mut mesh = Mesh {
            capacity: *capacity,
            n_nodes,
            n_tets,
            n_surface: 0,
            n_free: n_free as usize,
            rest,
            element_rest,
            tets,
            free_index,
            surface,
            surface_tet,
        };
        for t in 0..n_tets {
            mesh.update_element_rest(t)?;
        }
        mesh.extract_surface(work)?;
        Ok(mesh)
    }

    fn update_element_rest(&mut self, t: usize) -> Result<(), Error> {
        let x = self.tets[t].map(|v| self.rest[v as usize]);
        let e = ElementRest::new(&x, t)?;
        let slot = &mut self.element_rest[t];
        slot[..9].copy_from_slice(e.dm_inv.as_slice());
        slot[9] = e.volume;
        Ok(())
    }

    /// Finds the faces that belong to one tetrahedron only, orients them outward and checks
    /// that they close up.
    fn extract_surface(&mut self, work: &mut [u32]) -> Result<(), Error> {
        let faces = work[..16 * self.n_tets].as_chunks_mut::<4>().0;
        for (t, tet) in self.tets[..self.n_tets].iter().enumerate() {
            for l in 0..4 {
                let mut f = [tet[(l + 1) % 4], tet[(l + 2) % 4], tet[(l + 3) % 4]];
                f.sort_unstable();
                faces[4 * t + l] = [f[0], f[1], f[2], (4 * t + l) as u32];
            }
        }
        faces.sort_unstable();
        let mut n_surface = 0usize;
        let mut k = 0;
        while k < faces.len() {
            let mut run = 1;
            while k + run < faces.len() && faces[k + run][..3] == faces[k][..3] {
                run += 1;
            }
            match run {
                1 => {
                    let code = faces[k][3] as usize;
                    let (t, l) = (code / 4, code % 4);
                    if n_surface >= self.capacity.surface_triangles {
                        return Err(Error::Capacity {
                            resource: Resource::SurfaceTriangles,
                            needed: n_surface + 1,
                            available: self.capacity.surface_triangles,
                        });
                    }
                    let tet = self.tets[t];
                    let mut tri = [tet[(l + 1) % 4], tet[(l + 2) % 4], tet[(l + 3) % 4]];
                    // Outward: the opposite node lies on the negative side of the normal.
                    let p = |v: u32| self.rest[v as usize];
                    if orientation(p(tri[0]), p(tri[1]), p(tri[2]), p(tet[l])) > T::zero() {
                        tri.swap(1, 2);
                    }
                    self.surface[n_surface] = tri;
                    self.surface_tet[n_surface] = t as u32;
                    n_surface += 1;
                }
                2 => {}
                _ => {
                    return Err(Error::NonManifold {
                        a: faces[k][0] as usize,
                        b: faces[k][1] as usize,
                    });
                }
            }
            k += run;
        }
        // Every boundary edge must be shared by exactly two boundary triangles.
        let edges = work[..6 * n_surface].as_chunks_mut::<2>().0;
        for (s, tri) in self.surface[..n_surface].iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                edges[3 * s + e] = [a.min(b), a.max(b)];
            }
        }
        edges.sort_unstable();
        let mut k = 0;
        while k < edges.len() {
            let mut run = 1;
            while k + run < edges.len() && edges[k + run] == edges[k] {
                run += 1;
            }
            if run != 2 {
                return Err(Error::NonManifold {
                    a: edges[k][0] as usize,
                    b: edges[k][1] as usize,
                });
            }
            k += run;
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
        &self.rest[..self.n_nodes]
    }
    /// Tetrahedra.
    pub fn tets(&self) -> &[[u32; 4]] {
        &self.tets[..self.n_tets]
    }
    /// Compact index of each node among the free nodes, [`NONE`] for a fixed node.
    pub fn free_index(&self) -> &[u32] {
        &self.free_index[..self.n_nodes]
    }
    /// Boundary triangles, oriented outward.
    pub fn surface(&self) -> &[[u32; 3]] {
        &self.surface[..self.n_surface]
    }
    /// The tetrahedron each boundary triangle belongs to.
    pub fn surface_tet(&self) -> &[u32] {
        &self.surface_tet[..self.n_surface]
    }
    /// Rest geometry of tetrahedron `t` (`None` if out of range).
    pub fn element_rest(&self, t: usize) -> Option<ElementRest<T>> {
        let e = self.element_rest[..self.n_tets].get(t)?;
        Some(ElementRest {
            dm_inv: nalgebra::Matrix3::from_column_slice(&e[..9]),
            volume: e[9],
        })
    }
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

#[cfg(test)]
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
