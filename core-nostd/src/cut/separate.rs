//! Separating the mesh along its cut faces: the faces on the separation surface between
//! tetrahedra of opposite sides that the caller selects (inside the surface's extent, and
//! past an end inside the object up to the end's plane; see the module `cut`). Each node on a cut face is
//! duplicated once per extra group of its tetrahedra that stay joined through faces that are
//! not cut; a node at the end of a partial cut keeps a single group and is not duplicated, so
//! the material stays joined beyond the cut.

use crate::error::{Error, Resource};
use crate::mesh::Mesh;
use crate::real::Real;
use crate::sparse::NONE;
use crate::storage::{sum, times};

/// Node → element incidence (the tetrahedra, or the boundary triangles, at each node), in
/// compressed form, built into caller storage.
pub(crate) struct Incidence<'w> {
    pub ptr: &'w [u32],
    pub tets: &'w [u32],
}

impl<'w> Incidence<'w> {
    /// Builds the incidence of the `N`-node elements `tets` (tetrahedra, or triangles) over
    /// `n_nodes` nodes into `ptr` (`n_nodes + 1`) and `list` (`N · tets.len()`).
    pub fn build<const N: usize>(
        tets: &[[u32; N]],
        n_nodes: usize,
        ptr: &'w mut [u32],
        list: &'w mut [u32],
    ) -> Result<Self, Error> {
        let (n_ptr, n_list) = (sum(&[n_nodes, 1]), times(N, tets.len()));
        let available = ptr.len().saturating_add(list.len());
        let (Some(ptr), Some(list)) = (ptr.get_mut(..n_ptr), list.get_mut(..n_list)) else {
            return Err(Error::Capacity {
                resource: Resource::Workspace,
                needed: sum(&[n_ptr, n_list]),
                available,
            });
        };
        let out_of_range = |t: usize, v: u32| Error::IndexOutOfRange {
            resource: if N == 4 {
                Resource::Tetrahedra
            } else {
                Resource::SurfaceTriangles
            },
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

    /// Elements around node `v`.
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

/// Groups the tetrahedra around node `v` (its `star`) that stay joined through faces at `v`
/// that are not `cut`: on return `scratch.parent[i]` is the group of `star[i]`, numbered by its
/// smallest member (so group 0 is the first tetrahedron's). Returns the work, in face entries.
fn star_groups<T: Real>(
    mesh: &Mesh<'_, T>,
    v: u32,
    star: &[u32],
    cut: &[[u32; 3]],
    scratch: &mut StarScratch<'_>,
) -> Result<u64, Error> {
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
        // The three faces at v, each without one node u: the other two nodes.
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
    // Roots are their group's smallest member: flatten every tree onto its root.
    for i in 0..m {
        let r = find(parent, i);
        if let Some(p) = parent.get_mut(i) {
            *p = r as u32;
        }
    }
    Ok(times(3, m) as u64)
}

/// Passes of [`keep_edges_manifold`]: each leaves uncut one face per edge found to join two
/// sides along that edge only, and a pass that changes nothing ends the check. Leaving a face
/// uncut can only join groups, so a later pass finds what an earlier one's changes caused; on
/// the committed scenes and in the property test one pass with changes and one without
/// suffice. A cut still wrong after them is refused by the mesh's own check
/// ([`Error::NonManifold`]).
pub(crate) const MANIFOLD_PASSES: usize = 4;

/// Scratch of [`keep_edges_manifold`]: the star groups of every node on the cut, one per
/// entry of the incidence list (`4 · tets`); the stars ([`StarScratch`]), whose face room then
/// holds the edges at one node (`[other node, group here, group there, tetrahedron]`, three per
/// tetrahedron of the star); and the ring around one edge (`[node, member]`, two per
/// tetrahedron, and a union-find forest).
pub(crate) struct EdgeScratch<'s, 'w> {
    pub groups: &'w mut [u32],
    pub stars: &'s mut StarScratch<'w>,
    pub ring: &'w mut [[u32; 2]],
    pub ring_parent: &'w mut [u32],
}

/// Leaves uncut the cut faces (`cut[..n]`, sorted keys) that would make the cut mesh
/// non-manifold along an edge, and returns how many remain.
///
/// Nodes are duplicated per group of tetrahedra joined through faces at the node
/// ([`duplicate_nodes`]). Where the surface folds or ends inside a face fan, two cut faces
/// can meet along an edge whose tetrahedra fall apart into groups around the edge, while at
/// both of its ends those groups stay joined through other faces: neither end is duplicated,
/// and four boundary triangles would meet along the edge. Leaving one of those cut faces
/// uncut keeps the material joined there, as at the end of a partial cut, one face short of
/// where the surface goes.
///
/// # Errors
/// [`Error::Capacity`] (workspace) when a star outgrows the scratch, or
/// [`Error::IndexOutOfRange`] for a tetrahedron out of range; the cut faces are then
/// unspecified (the caller drops the whole event).
pub(crate) fn keep_edges_manifold<T: Real>(
    mesh: &Mesh<'_, T>,
    incidence: &Incidence<'_>,
    cut: &mut [[u32; 3]],
    mut n: usize,
    on_cut: &[u32],
    scratch: &mut EdgeScratch<'_, '_>,
    work_entries: &mut u64,
) -> Result<usize, Error> {
    let workspace = |needed: usize, available: usize| Error::Capacity {
        resource: Resource::Workspace,
        needed,
        available,
    };
    let start = |v: u32| incidence.ptr.get(v as usize).map_or(0, |&p| p as usize);
    for _ in 0..MANIFOLD_PASSES {
        // The groups around every node on the cut, as the cut stands.
        for &v in on_cut {
            let star = incidence.of(v as usize);
            let live = cut.get(..n).unwrap_or_default();
            *work_entries += star_groups(mesh, v, star, live, scratch.stars)?;
            let (at, m) = (start(v), star.len());
            let available = scratch.groups.len();
            let to = scratch
                .groups
                .get_mut(at..at + m)
                .ok_or(workspace(at + m, available))?;
            to.copy_from_slice(scratch.stars.parent.get(..m).unwrap_or_default());
        }
        let mut changed = false;
        for &a in on_cut {
            let star = incidence.of(a as usize);
            let entries = scratch
                .stars
                .faces
                .as_flattened_mut()
                .as_chunks_mut::<4>()
                .0;
            let mut count = 0;
            for (i, &t) in star.iter().enumerate() {
                let Some(&tet) = mesh.tets().get(t as usize) else {
                    continue;
                };
                let here = scratch.groups.get(start(a) + i).copied().unwrap_or(NONE);
                for b in tet {
                    if b <= a || on_cut.binary_search(&b).is_err() {
                        continue;
                    }
                    let there = group_of(incidence, scratch.groups, b, t);
                    let available = entries.len();
                    *entries
                        .get_mut(count)
                        .ok_or(workspace(count + 1, available))? = [b, here, there, t];
                    count += 1;
                }
            }
            let entries = entries.get_mut(..count).unwrap_or_default();
            entries.sort_unstable();
            *work_entries += count as u64;
            for run in entries.chunk_by(|x, y| x[0] == y[0]) {
                let b = run.first().map_or(NONE, |e| e[0]);
                let live = cut.get(..n).unwrap_or_default();
                let groups = &*scratch.groups;
                let group_at = |w: u32, t: u32| group_of(incidence, groups, w, t);
                let ring = (&mut *scratch.ring, &mut *scratch.ring_parent);
                let split_at =
                    edge_split_to_mend(mesh, [a, b], run, live, group_at, ring, work_entries)?;
                if let Some(face) = split_at
                    && let Ok(k) = live.binary_search(&face)
                {
                    cut.copy_within(k + 1..n, k);
                    n -= 1;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    Ok(n)
}

/// The group of tetrahedron `t` around node `v` (`groups`, one entry per entry of the
/// incidence list), [`NONE`] if `t` is not around `v`.
fn group_of(incidence: &Incidence<'_>, groups: &[u32], v: u32, t: u32) -> u32 {
    let start = incidence.ptr.get(v as usize).map_or(0, |&p| p as usize);
    incidence
        .of(v as usize)
        .binary_search(&t)
        .ok()
        .and_then(|j| groups.get(start + j).copied())
        .unwrap_or(NONE)
}

/// Around edge `[a, b]` (its tetrahedra `run`, each `[b, group at a, group at b, tet]`, sorted),
/// the groups that stay joined through faces on the edge once the nodes are duplicated: a face
/// `(a, b, w)` separates its two tetrahedra only if it is `cut` and they fall in different
/// groups at `w` (`group_of(w, tet)`; otherwise no node of the face is duplicated across it
/// and it stays inside the mesh). If two of these groups share their groups at both ends,
/// returns a separating face on the edge to leave uncut.
fn edge_split_to_mend<T: Real>(
    mesh: &Mesh<'_, T>,
    [a, b]: [u32; 2],
    run: &[[u32; 4]],
    cut: &[[u32; 3]],
    group_of: impl Fn(u32, u32) -> u32,
    (ring, parent): (&mut [[u32; 2]], &mut [u32]),
    work_entries: &mut u64,
) -> Result<Option<[u32; 3]>, Error> {
    let k = run.len();
    let (available, needed) = (ring.len().min(2 * parent.len()), 2 * k);
    let (Some(ring), Some(parent)) = (ring.get_mut(..needed), parent.get_mut(..k)) else {
        return Err(Error::Capacity {
            resource: Resource::Workspace,
            needed,
            available,
        });
    };
    let face = |w: u32| {
        let mut key = [a, b, w];
        key.sort_unstable();
        key
    };
    let mut any_cut = false;
    for (j, (entry, (p, two))) in run
        .iter()
        .zip(parent.iter_mut().zip(ring.chunks_exact_mut(2)))
        .enumerate()
    {
        *p = j as u32;
        let tet = mesh
            .tets()
            .get(entry[3] as usize)
            .copied()
            .unwrap_or([NONE; 4]);
        let mut others = tet.iter().copied().filter(|&w| w != a && w != b);
        for slot in two.iter_mut() {
            let w = others.next().unwrap_or(NONE);
            *slot = [w, j as u32];
            any_cut = any_cut || cut.binary_search(&face(w)).is_ok();
        }
    }
    *work_entries += needed as u64;
    // No cut face on the edge: its tetrahedra stay one group.
    if !any_cut {
        return Ok(None);
    }
    ring.sort_unstable();
    let tet_of = |j: u32| run.get(j as usize).map_or(NONE, |e| e[3]);
    let mut to_mend = None;
    for two in ring.windows(2) {
        let &[x, y] = two else {
            continue;
        };
        if x[0] != y[0] {
            continue;
        }
        let w = x[0];
        if cut.binary_search(&face(w)).is_ok()
            && group_of(w, tet_of(x[1])) != group_of(w, tet_of(y[1]))
        {
            to_mend = to_mend.or(Some(face(w)));
            continue;
        }
        let (rx, ry) = (find(parent, x[1] as usize), find(parent, y[1] as usize));
        if rx != ry
            && let Some(p) = parent.get_mut(rx.max(ry))
        {
            *p = rx.min(ry) as u32;
        }
    }
    // The run is sorted by the groups at both ends: tetrahedra that share them are adjacent,
    // and must also share their group around the edge.
    for (j, pair) in run.windows(2).enumerate() {
        let &[x, y] = pair else {
            continue;
        };
        if (x[1], x[2]) == (y[1], y[2]) && find(parent, j) != find(parent, j + 1) {
            return Ok(to_mend);
        }
    }
    Ok(None)
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
        *work_entries += star_groups(mesh, v, star, cut, scratch)?;
        let parent = scratch.parent.get(..m).unwrap_or_default();
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

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;
    use crate::mesh::{MeshCapacity, MeshInput, orientation};
    use crate::storage::Slab;

    /// Edge `a = 0`, `b = 1` along z with four tetrahedra around it (ring nodes 2–5), capped
    /// below `a` by four tetrahedra on node 6 and above `b` by four on node 7: around `a`
    /// (and `b`) the ring's tetrahedra also hang together through the caps.
    fn capped_ring() -> ([[f64; 3]; 8], [[u32; 4]; 12]) {
        let rest = [
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.5],
            [0.0, 1.0, 0.5],
            [-1.0, 0.0, 0.5],
            [0.0, -1.0, 0.5],
            [0.0, 0.0, -1.0],
            [0.0, 0.0, 2.0],
        ];
        let mut tets = [[0u32; 4]; 12];
        for i in 0..4u32 {
            let (w, w_next) = (2 + i, 2 + (i + 1) % 4);
            tets[i as usize] = [0, 1, w, w_next];
            tets[4 + i as usize] = [6, 0, w, w_next];
            tets[8 + i as usize] = [7, 1, w, w_next];
        }
        for tet in &mut tets {
            let p = |v: u32| rest[v as usize];
            if orientation(p(tet[0]), p(tet[1]), p(tet[2]), p(tet[3])) < 0.0 {
                tet.swap(2, 3);
            }
        }
        (rest, tets)
    }

    /// Cuts the capped ring along `faces_cut`: runs the edge check (when `check`), duplicates
    /// the nodes and rebuilds the boundary. Returns the faces left cut and the mesh's verdict.
    fn separate_ring(faces_cut: &[[u32; 3]], check: bool) -> (usize, Result<(), Error>) {
        let (rest, tets) = capped_ring();
        let input = MeshInput {
            rest: &rest,
            tets: &tets,
            fixed: &[6],
        };
        // Room for a copy of every node.
        let cap = MeshCapacity {
            nodes: 16,
            ..MeshCapacity::exact(&input)
        };
        let (mut r, mut i, mut w) = ([0.0; 256], [0u32; 512], [0u32; 2048]);
        let mut rs = Slab::new(&mut r, Resource::RealStorage);
        let mut is = Slab::new(&mut i, Resource::IndexStorage);
        let mut mesh = Mesh::new(&input, &cap, &mut rs, &mut is, &mut w).unwrap();
        let (mut ptr, mut list) = ([0u32; 9], [0u32; 48]);
        let incidence = Incidence::build(mesh.tets(), 8, &mut ptr, &mut list).unwrap();
        let mut store = [[0u32; 3]; 8];
        let cut = &mut store[..faces_cut.len()];
        cut.copy_from_slice(faces_cut);
        cut.iter_mut().for_each(|k| k.sort_unstable());
        cut.sort_unstable();
        let (mut nodes, mut n_on) = ([0u32; 8], 0);
        for v in 0..8 {
            if cut.iter().flatten().any(|&u| u == v) {
                nodes[n_on] = v;
                n_on += 1;
            }
        }
        let on_cut = &nodes[..n_on];
        let (mut faces, mut parent) = ([[0u32; 3]; 48], [0u32; 48]);
        let mut stars = StarScratch {
            faces: &mut faces,
            parent: &mut parent,
        };
        let (mut groups, mut ring, mut ring_parent) = ([0u32; 48], [[0u32; 2]; 48], [0u32; 48]);
        let mut work = 0;
        let mut n = cut.len();
        if check {
            let mut scratch = EdgeScratch {
                groups: &mut groups,
                stars: &mut stars,
                ring: &mut ring,
                ring_parent: &mut ring_parent,
            };
            n = keep_edges_manifold(&mesh, &incidence, cut, n, on_cut, &mut scratch, &mut work)
                .unwrap();
            assert!(work > 0);
        }
        let copy = |mesh: &mut Mesh<'_, f64>, v: u32| {
            let rest = mesh.rest()[v as usize];
            mesh.push_node(rest, false)
        };
        duplicate_nodes(
            &mut mesh,
            &incidence,
            &cut[..n],
            on_cut,
            &mut stars,
            copy,
            &mut work,
        )
        .unwrap();
        (n, mesh.finish_edit(&mut w))
    }

    /// The faces the edge check leaves cut; the cut mesh is then valid.
    fn mend(faces_cut: &[[u32; 3]]) -> usize {
        let (n, verdict) = separate_ring(faces_cut, true);
        assert_eq!(verdict, Ok(()));
        n
    }

    #[test]
    fn an_edge_whose_ends_stay_joined_between_two_separated_faces_is_mended() {
        // Nodes 2 and 4 are each cut loose along a path through their star (3 → 0 → 1 → 5
        // and 5 → 0 → 1 → 3), so both faces (0, 1, 2) and (0, 1, 4) come apart, while around
        // nodes 0 and 1 the cut is an open path and they stay whole: four boundary triangles
        // would meet along edge (0, 1). One of its two faces stays joined.
        let two_flaps = [
            [0, 2, 3],
            [0, 1, 2],
            [1, 2, 5],
            [0, 4, 5],
            [0, 1, 4],
            [1, 4, 3],
        ];
        assert!(matches!(
            separate_ring(&two_flaps, false),
            (6, Err(Error::NonManifold { a: 0, b: 1 }))
        ));
        assert_eq!(mend(&two_flaps), 5);
        // Two faces on the edge whose nodes all stay whole separate nothing: nothing to mend.
        assert_eq!(mend(&[[0, 1, 2], [0, 1, 4]]), 2);
    }

    #[test]
    fn a_cut_that_separates_an_end_is_kept() {
        // The ring's faces on the edge and the caps' faces below `a` on the same plane (x = 0
        // through nodes 3 and 5): `a` is separated, so nothing is mended.
        let through = [[0, 1, 3], [0, 1, 5], [0, 6, 3], [0, 6, 5]];
        assert_eq!(mend(&through), 4);
        // A single face is a chain around the edge: one group, nothing to mend.
        assert_eq!(mend(&[[0, 1, 2]]), 1);
    }
}
