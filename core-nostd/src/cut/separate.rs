//! Separating the mesh along its cut faces: the faces on the separation surface between
//! tetrahedra of opposite sides, inside the surface's extent. Each node on a cut face is
//! duplicated once per extra group of its tetrahedra that stay joined through faces that are
//! not cut; a node at the end of a partial cut keeps a single group and is not duplicated, so
//! the material stays joined beyond the cut.

#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

use crate::error::{Error, Resource};
use crate::mesh::Mesh;
use crate::real::Real;
use crate::sparse::NONE;
use crate::storage::{sum, times};

/// Node → tetrahedra incidence, in compressed form, built into caller storage.
pub(crate) struct Incidence<'w> {
    pub ptr: &'w [u32],
    pub tets: &'w [u32],
}

impl<'w> Incidence<'w> {
    /// Builds the incidence of `tets` over `n_nodes` nodes into `ptr` (`n_nodes + 1`) and
    /// `list` (`4 · tets.len()`).
    pub fn build(
        tets: &[[u32; 4]],
        n_nodes: usize,
        ptr: &'w mut [u32],
        list: &'w mut [u32],
    ) -> Result<Self, Error> {
        let (n_ptr, n_list) = (sum(&[n_nodes, 1]), times(4, tets.len()));
        let available = ptr.len().saturating_add(list.len());
        let (Some(ptr), Some(list)) = (ptr.get_mut(..n_ptr), list.get_mut(..n_list)) else {
            return Err(Error::Capacity {
                resource: Resource::Workspace,
                needed: sum(&[n_ptr, n_list]),
                available,
            });
        };
        let out_of_range = |t: usize, v: u32| Error::IndexOutOfRange {
            resource: Resource::Tetrahedra,
            position: t,
            index: v as usize,
            bound: n_nodes,
        };
        ptr.fill(0);
        for (t, tet) in tets.iter().enumerate() {
            for &v in tet {
                *ptr.get_mut(v as usize + 1).ok_or(out_of_range(t, v))? += 1;
            }
        }
        // Running sums: `ptr[v + 1]` is the end of node v's list (`ptr[0]` stays 0).
        let mut running = 0u32;
        for p in ptr.iter_mut() {
            running += *p;
            *p = running;
        }
        // Fill from the back so the pointers end up at the starts again.
        for (t, tet) in tets.iter().enumerate().rev() {
            for &v in tet {
                let at = ptr.get_mut(v as usize + 1).ok_or(out_of_range(t, v))?;
                *at -= 1;
                *list.get_mut(*at as usize).ok_or(out_of_range(t, v))? = t as u32;
            }
        }
        // `ptr[v + 1]` now holds the start of node v; shift it back into place.
        ptr.copy_within(1.., 0);
        if let Some(end) = ptr.last_mut() {
            *end = n_list as u32;
        }
        Ok(Incidence { ptr, tets: list })
    }

    /// Tetrahedra around node `v`.
    pub fn of(&self, v: usize) -> &[u32] {
        match (self.ptr.get(v), self.ptr.get(v + 1)) {
            (Some(&s), Some(&e)) => self.tets.get(s as usize..e as usize).unwrap_or(&[]),
            _ => &[],
        }
    }
}

/// The three nodes of face `l` of `tet` (the face opposite local node `l`), sorted.
pub(crate) fn face_key(tet: &[u32; 4], l: usize) -> [u32; 3] {
    let [a, b, c, d] = *tet;
    let mut f = match l % 4 {
        0 => [b, c, d],
        1 => [c, d, a],
        2 => [d, a, b],
        _ => [a, b, c],
    };
    f.sort_unstable();
    f
}

/// Finds the cut faces: interior faces whose three nodes lie on the surface (`on_surface`),
/// whose two tetrahedra lie on opposite sides (`side`), and that `inside` accepts. Writes their
/// sorted keys, in increasing order, into `out` and returns how many; `faces` is scratch of
/// `4 · tets` entries of four indices.
pub(crate) fn cut_faces<T: Real>(
    mesh: &Mesh<'_, T>,
    on_surface: impl Fn(u32) -> bool,
    side: impl Fn(usize) -> i8,
    inside: impl Fn(&[u32; 3]) -> bool,
    faces: &mut [[u32; 4]],
    out: &mut [[u32; 3]],
) -> Result<usize, Error> {
    let tets = mesh.tets();
    let available = faces.len();
    let needed = times(4, tets.len());
    let faces = faces.get_mut(..needed).ok_or(Error::Capacity {
        resource: Resource::Workspace,
        needed,
        available,
    })?;
    for (four, (t, tet)) in faces.chunks_exact_mut(4).zip(tets.iter().enumerate()) {
        for (l, slot) in four.iter_mut().enumerate() {
            let f = face_key(tet, l);
            *slot = [f[0], f[1], f[2], t as u32];
        }
    }
    faces.sort_unstable();
    let mut n = 0;
    let mut k = 0;
    while let (Some(&a), Some(&b)) = (faces.get(k), faces.get(k + 1)) {
        if (a[0], a[1], a[2]) != (b[0], b[1], b[2]) {
            k += 1;
            continue;
        }
        let key = [a[0], a[1], a[2]];
        let (sa, sb) = (side(a[3] as usize), side(b[3] as usize));
        if key.iter().all(|&v| on_surface(v)) && sa * sb < 0 && inside(&key) {
            let available = out.len();
            let slot = out.get_mut(n).ok_or(Error::Capacity {
                resource: Resource::Workspace,
                needed: n + 1,
                available,
            })?;
            *slot = key;
            n += 1;
        }
        k += 2;
    }
    Ok(n)
}

/// Scratch of [`duplicate_nodes`] for a node with up to `star` tetrahedra around it: the
/// faces at the node (three per tetrahedron, each `[other node, other node, tetrahedron]`) and
/// a union-find forest.
pub(crate) struct StarScratch<'w> {
    pub faces: &'w mut [[u32; 3]],
    pub parent: &'w mut [u32],
}

/// The root of `i`, halving the path on the way (an index out of range is its own root).
fn find(parent: &mut [u32], mut i: usize) -> usize {
    loop {
        let up = match parent.get(i) {
            Some(&up) if up as usize != i => up as usize,
            _ => return i,
        };
        let grandparent = parent.get(up).copied().unwrap_or(up as u32);
        if let Some(p) = parent.get_mut(i) {
            *p = grandparent;
        }
        i = up;
    }
}

/// Duplicates the nodes on the cut faces (`cut`, sorted keys) so that the two sides come apart:
/// around each such node, the tetrahedra joined through faces that are not cut form groups;
/// the group of the first tetrahedron keeps the node, each other group gets a copy (same rest
/// and current position, same fixed state) through `copy_node`. Returns the number of copies.
pub(crate) fn duplicate_nodes<T: Real>(
    mesh: &mut Mesh<'_, T>,
    incidence: &Incidence<'_>,
    cut: &[[u32; 3]],
    on_cut: &[u32],
    scratch: &mut StarScratch<'_>,
    mut copy_node: impl FnMut(&mut Mesh<'_, T>, u32) -> Result<u32, Error>,
    work_entries: &mut u64,
) -> Result<usize, Error> {
    let mut copies = 0;
    for &v in on_cut {
        let star = incidence.of(v as usize);
        let m = star.len();
        let needed = times(3, m);
        let available = scratch.faces.len();
        let (Some(faces), Some(parent)) =
            (scratch.faces.get_mut(..needed), scratch.parent.get_mut(..m))
        else {
            return Err(Error::Capacity {
                resource: Resource::Workspace,
                needed,
                available,
            });
        };
        let n_tets = mesh.n_tets();
        for ((i, &t), (p, three)) in star
            .iter()
            .enumerate()
            .zip(parent.iter_mut().zip(faces.chunks_exact_mut(3)))
        {
            *p = i as u32;
            let tet = *mesh.tets().get(t as usize).ok_or(Error::IndexOutOfRange {
                resource: Resource::Tetrahedra,
                position: i,
                index: t as usize,
                bound: n_tets,
            })?;
            // The first three faces at v, each without one node u: the other two nodes.
            let mut slots = three.iter_mut();
            for &u in &tet {
                if u != v
                    && let Some(slot) = slots.next()
                {
                    let others = tet.iter().copied().filter(|&w| w != v && w != u);
                    let mut pair = [NONE; 2];
                    for (end, w) in pair.iter_mut().zip(others) {
                        *end = w;
                    }
                    pair.sort_unstable();
                    *slot = [pair[0], pair[1], i as u32];
                }
            }
        }
        faces.sort_unstable();
        *work_entries += 3 * m as u64;
        for two in faces.windows(2) {
            let &[a, b] = two else {
                continue;
            };
            if (a[0], a[1]) != (b[0], b[1]) {
                continue;
            }
            let mut key = [v, a[0], a[1]];
            key.sort_unstable();
            if cut.binary_search(&key).is_ok() {
                continue;
            }
            let (ra, rb) = (find(parent, a[2] as usize), find(parent, b[2] as usize));
            if ra != rb
                && let Some(p) = parent.get_mut(ra.max(rb))
            {
                *p = ra.min(rb) as u32;
            }
        }
        // Group roots are their smallest member, so group 0 is the first tetrahedron's.
        for i in 0..m {
            let r = find(parent, i);
            if let Some(p) = parent.get_mut(i) {
                *p = r as u32;
            }
        }
        for root in 1..m {
            if parent.get(root).map(|&p| p as usize) != Some(root) {
                continue;
            }
            let copy = copy_node(mesh, v)?;
            copies += 1;
            for (&group, &t) in parent.iter().zip(star).skip(root) {
                if group as usize == root
                    && let Some(&tet) = mesh.tets().get(t as usize)
                {
                    let t = t as usize;
                    let mut tet = tet;
                    for w in tet.iter_mut() {
                        if *w == v {
                            *w = copy;
                        }
                    }
                    mesh.set_tet(t, tet);
                }
            }
        }
    }
    Ok(copies)
}
