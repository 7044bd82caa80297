//! Separating the mesh along its cut faces: the faces on the separation surface between
//! tetrahedra of opposite sides, inside the surface's extent. Each node on a cut face is
//! duplicated once per extra group of its tetrahedra that stay joined through faces that are
//! not cut; a node at the end of a partial cut keeps a single group and is not duplicated, so
//! the material stays joined beyond the cut.

use crate::error::{Error, Resource};
use crate::mesh::Mesh;
use crate::real::Real;
use crate::sparse::NONE;

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
        if ptr.len() < n_nodes + 1 || list.len() < 4 * tets.len() {
            return Err(Error::Capacity {
                resource: Resource::Workspace,
                needed: n_nodes + 1 + 4 * tets.len(),
                available: ptr.len() + list.len(),
            });
        }
        let ptr = &mut ptr[..n_nodes + 1];
        ptr.fill(0);
        for tet in tets {
            for &v in tet {
                ptr[v as usize + 1] += 1;
            }
        }
        for v in 0..n_nodes {
            ptr[v + 1] += ptr[v];
        }
        // Fill from the back so the pointers end up at the starts again.
        for (t, tet) in tets.iter().enumerate().rev() {
            for &v in tet {
                let at = &mut ptr[v as usize + 1];
                *at -= 1;
                list[*at as usize] = t as u32;
            }
        }
        // `ptr[v + 1]` now holds the start of node v; shift it back into place.
        for v in 0..n_nodes {
            ptr[v] = ptr[v + 1];
        }
        ptr[n_nodes] = 4 * tets.len() as u32;
        Ok(Incidence {
            ptr,
            tets: &list[..4 * tets.len()],
        })
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
    let mut f = [tet[(l + 1) % 4], tet[(l + 2) % 4], tet[(l + 3) % 4]];
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
    let faces = faces.get_mut(..4 * tets.len()).ok_or(Error::Capacity {
        resource: Resource::Workspace,
        needed: 4 * tets.len(),
        available,
    })?;
    for (t, tet) in tets.iter().enumerate() {
        for l in 0..4 {
            let f = face_key(tet, l);
            faces[4 * t + l] = [f[0], f[1], f[2], t as u32];
        }
    }
    faces.sort_unstable();
    let mut n = 0;
    let mut k = 0;
    while k + 1 < faces.len() {
        let (a, b) = (faces[k], faces[k + 1]);
        if a[..3] != b[..3] {
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

fn find(parent: &mut [u32], mut i: usize) -> usize {
    while parent[i] as usize != i {
        let up = parent[i] as usize;
        parent[i] = parent[up];
        i = up;
    }
    i
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
        if 3 * m > scratch.faces.len() || m > scratch.parent.len() {
            return Err(Error::Capacity {
                resource: Resource::Workspace,
                needed: 3 * m,
                available: scratch.faces.len(),
            });
        }
        let faces = &mut scratch.faces[..3 * m];
        let parent = &mut scratch.parent[..m];
        for (i, &t) in star.iter().enumerate() {
            parent[i] = i as u32;
            let tet = mesh.tets()[t as usize];
            let mut k = 0;
            for &u in &tet {
                if u != v && k < 3 {
                    // The face at v without node u: the other two nodes.
                    let others = tet.iter().copied().filter(|&w| w != v && w != u);
                    let mut pair = [NONE; 2];
                    for (slot, w) in pair.iter_mut().zip(others) {
                        *slot = w;
                    }
                    pair.sort_unstable();
                    faces[3 * i + k] = [pair[0], pair[1], i as u32];
                    k += 1;
                }
            }
        }
        faces.sort_unstable();
        *work_entries += 3 * m as u64;
        for k in 0..faces.len().saturating_sub(1) {
            let (a, b) = (faces[k], faces[k + 1]);
            if a[..2] != b[..2] {
                continue;
            }
            let mut key = [v, a[0], a[1]];
            key.sort_unstable();
            if cut.binary_search(&key).is_ok() {
                continue;
            }
            let (ra, rb) = (find(parent, a[2] as usize), find(parent, b[2] as usize));
            if ra != rb {
                parent[ra.max(rb)] = ra.min(rb) as u32;
            }
        }
        // Group roots are their smallest member, so group 0 is the first tetrahedron's.
        for i in 0..m {
            let r = find(parent, i);
            parent[i] = r as u32;
        }
        for root in 1..m {
            if parent[root] as usize != root {
                continue;
            }
            let copy = copy_node(mesh, v)?;
            copies += 1;
            for i in root..m {
                if parent[i] as usize == root {
                    let t = star[i] as usize;
                    let mut tet = mesh.tets()[t];
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
