//! Where the cut goes through the mesh, before anything is split: nodes put on the surface
//! (snapped), the crossed tetrahedra inside the extent selected, the split stopped where the
//! extent ends, and crossings that would make a piece below the quality floor snapped instead.
//!
//! Everything here only moves nodes (snapping, checked against the floor) or sets `φ = 0`
//! (declaring a node on the surface, which never changes geometry and never creates a
//! crossing), so each step can only simplify what the next one splits.

use crate::embed::gather;
use crate::error::{Error, Resource};
use crate::mesh::{Mesh, orientation, shape_quality};
use crate::real::Real;

use super::separate::Incidence;
use super::split::{Sign, Vertex, crosses, split};
use super::surface::SeparationSurface;
use super::{CutEvent, CutWork, QUALITY_FLOOR, SNAP_TOLERANCE, crossing, lerp, sign, signs_of};

/// Marks a selected tetrahedron in the status array.
pub(super) const SELECTED: u32 = 1;

/// Snapping: where the surface crosses an edge within [`SNAP_TOLERANCE`] of a node (inside
/// the extent), the node goes on the surface — moved there along the nearest such edge when
/// every tetrahedron around it stays above [`QUALITY_FLOOR`] (or no worse than it was) and
/// keeps its orientation in the current configuration, else only declared on it. A node on the
/// boundary moves only along a boundary edge, so that the organ's surface keeps its shape;
/// fixed nodes never move. `stars` is scratch of two entries per node and one, `star_list` of
/// three per boundary triangle (the boundary-edge test's, which [`super::work_len`] sizes).
#[allow(clippy::too_many_arguments)]
pub(super) fn snap_nodes<T: Real>(
    mesh: &mut Mesh<'_, T>,
    x: &mut [[T; 3]],
    previous: &mut [[T; 3]],
    phi: &mut [T],
    sep: &SeparationSurface<'_, T>,
    incidence: &Incidence<'_>,
    stars: &mut [u32],
    star_list: &mut [u32],
    event: &mut CutEvent,
) -> Result<(), Error> {
    let (floor, tau) = (T::of(QUALITY_FLOOR), T::of(SNAP_TOLERANCE));
    let n0 = mesh.n_nodes();
    // Each node's boundary triangles (none for an interior node), and a stamp per node: the
    // nodes of the triangles at the node being snapped carry its stamp, so that whether an
    // edge from it lies on the boundary is one lookup. Twice over the boundary to build, once
    // more for the stamps at most.
    let stars_len = stars.len();
    let (start, stamp) = stars.split_at_mut(stars_len.min(n0 + 1));
    let stamp = stamp.get_mut(..n0).ok_or(short(2 * n0 + 1, stars_len))?;
    stamp.fill(0);
    let boundary = Incidence::build(mesh.surface(), n0, start, star_list)?;
    event.work.triangle_tests += 2 * mesh.surface().len() as u64;
    for v in 0..n0 {
        let Some(&pv) = phi.get(v) else {
            continue;
        };
        if !(pv.finite() && pv != T::zero()) {
            continue;
        }
        // The crossings on the edges at `v`: (fraction of the edge from the node, the node at
        // its other end).
        let crossings = || {
            incidence
                .of(v)
                .iter()
                .filter_map(|&t| mesh.tets().get(t as usize))
                .flatten()
                .filter_map(|&w| {
                    let &pw = phi.get(w as usize)?;
                    (pw.finite() && sign(pw) == -sign(pv)).then(|| (pv / (pv - pw), w))
                })
        };
        // The nearest crossing on any edge.
        let mut nearest: Option<(T, u32)> = None;
        for (t_cross, w) in crossings() {
            if nearest.is_none_or(|(b, _)| t_cross < b) {
                nearest = Some((t_cross, w));
            }
        }
        let Some((t_near, w_near)) = nearest else {
            continue;
        };
        let (Some(&xv), Some(&xw)) = (x.get(v), x.get(w_near as usize)) else {
            continue;
        };
        if !(t_near < tau && sep.in_extent(&lerp(xv, xw, t_near))) {
            continue;
        }
        // The node goes on the surface: the nearest crossing on an edge it may move along (a
        // boundary node along a boundary edge only, an edge of one of its boundary triangles).
        let interior = boundary.of(v).is_empty();
        if !interior {
            let own = v as u32 + 1;
            for &k in boundary.of(v) {
                for &u in mesh.surface().get(k as usize).into_iter().flatten() {
                    if let Some(m) = stamp.get_mut(u as usize) {
                        *m = own;
                    }
                }
            }
            event.work.triangle_tests += boundary.of(v).len() as u64;
        }
        let mut along: Option<(T, u32)> = None;
        for (t_cross, w) in crossings() {
            let allowed = interior || stamp.get(w as usize) == Some(&(v as u32 + 1));
            if allowed && along.is_none_or(|(b, _)| t_cross < b) {
                along = Some((t_cross, w));
            }
        }
        let movable = |(t_cross, w): (T, u32)| -> bool {
            let wi = w as usize;
            if !(t_cross < tau) || mesh.is_fixed(v) {
                return false;
            }
            let rest = mesh.rest();
            let (Some(&rv), Some(&rw), Some(&xv), Some(&xw)) =
                (rest.get(v), rest.get(wi), x.get(v), x.get(wi))
            else {
                return false;
            };
            let moved_rest = lerp(rv, rw, t_cross);
            let moved_x = lerp(xv, xw, t_cross);
            incidence.of(v).iter().all(|&t| {
                let Some(&tet) = mesh.tets().get(t as usize) else {
                    return false;
                };
                // The corners of `tet` in `p`, node `v` at `q`.
                let at = |p: &[[T; 3]], q: [T; 3]| -> Option<[[T; 3]; 4]> {
                    let mut corners = [q; 4];
                    for (c, &u) in corners.iter_mut().zip(&tet) {
                        if u as usize != v {
                            *c = *p.get(u as usize)?;
                        }
                    }
                    Some(corners)
                };
                let (Some(r_old), Some(r_new), Some(c_old), Some(c_new)) = (
                    at(rest, rv),
                    at(rest, moved_rest),
                    at(x, xv),
                    at(x, moved_x),
                ) else {
                    return false;
                };
                let q_old = shape_quality(&r_old);
                let q_new = shape_quality(&r_new);
                let keeps_orientation = orientation(c_old[0], c_old[1], c_old[2], c_old[3])
                    <= T::zero()
                    || orientation(c_new[0], c_new[1], c_new[2], c_new[3]) > T::zero();
                (q_new >= floor || q_new >= q_old) && keeps_orientation
            })
        };
        match along.filter(|&a| movable(a)) {
            Some((t_cross, w)) => {
                let wi = w as usize;
                if let (Some(&rv), Some(&rw)) = (mesh.rest().get(v), mesh.rest().get(wi)) {
                    mesh.set_rest(v, lerp(rv, rw, t_cross));
                }
                move_toward(x, v, wi, t_cross);
                move_toward(previous, v, wi, t_cross);
                event.nodes_moved += 1;
            }
            None => event.nodes_declared += 1,
        }
        if let Some(p) = phi.get_mut(v) {
            *p = T::zero();
        }
    }
    Ok(())
}

/// The workspace error of a scratch slice of `available` entries where `needed` are.
fn short(needed: usize, available: usize) -> Error {
    Error::Capacity {
        resource: Resource::Workspace,
        needed,
        available,
    }
}

/// Moves entry `v` of `s` the fraction `t` of the way to entry `w`.
fn move_toward<T: Real>(s: &mut [[T; 3]], v: usize, w: usize, t: T) {
    if let (Some(&sv), Some(&sw)) = (s.get(v), s.get(w))
        && let Some(slot) = s.get_mut(v)
    {
        *slot = lerp(sv, sw, t);
    }
}

/// The pairs `(p[a], p[b])`, `a < b`, in the order of the nested loops over `a` then `b`.
fn pairs<P: Copy, const N: usize>(p: &[P; N]) -> impl Iterator<Item = (P, P)> + '_ {
    p.iter()
        .enumerate()
        .flat_map(move |(a, &pa)| p.iter().skip(a + 1).map(move |&pb| (pa, pb)))
}

/// The nodes of `tet` with their signs.
fn with_signs(s: &[Sign; 4], tet: &[u32; 4]) -> [(Sign, u32); 4] {
    [
        (s[0], tet[0]),
        (s[1], tet[1]),
        (s[2], tet[2]),
        (s[3], tet[3]),
    ]
}

/// Marks in `status` ([`SELECTED`], else 0) the crossed tetrahedra whose crossing (a point where
/// the surface crosses an edge, or a node on it) lies inside the extent — or, at an end inside
/// the object, within the tetrahedron's own size of it: the surface is split a little past
/// such an end, and the plane the cut ends on then cuts it exactly
/// ([`select_at_tip`]).
pub(super) fn select<T: Real>(
    mesh: &Mesh<'_, T>,
    x: &[[T; 3]],
    phi: &[T],
    sep: &SeparationSurface<'_, T>,
    status: &mut [u32],
    work: &mut CutWork,
) {
    for (tet, st) in mesh.tets().iter().zip(status.iter_mut()) {
        *st = 0;
        let Some(s) = signs_of(phi, tet) else {
            continue;
        };
        if !crosses(&s) {
            continue;
        }
        // The tetrahedron's size in the image.
        let size = gather(x, tet).map_or(T::zero(), |corners| sep.image_size(&corners));
        let counts = |p: &[T; 3]| sep.in_extent(p) || sep.near_inner_end(p, size);
        let nodes = with_signs(&s, tet);
        let mut inside = false;
        for ((sa, va), (sb, vb)) in pairs(&nodes) {
            if sa * sb < 0
                && let (Some(&xa), Some(&xb)) = (x.get(va as usize), x.get(vb as usize))
            {
                inside |= counts(&lerp(xa, xb, crossing(phi, va, vb)));
            }
        }
        for &(sa, va) in &nodes {
            if sa == 0
                && let Some(p) = x.get(va as usize)
            {
                inside |= counts(p);
            }
        }
        if inside {
            *st = SELECTED;
        }
    }
    work.element_tests += mesh.n_tets() as u64;
}

/// Marks in `status` ([`SELECTED`], else 0) the tetrahedra the plane of end `k` (`psi`) must
/// split for the cut to end on it: the faces on the surface (`phi = 0` at three nodes) that the
/// plane crosses near the end (within two tube widths in the image, or the face's own size),
/// and every tetrahedron around their crossed edges, so that those edges are split in all
/// their tetrahedra. `edges` is scratch of six entries per tetrahedron.
#[allow(clippy::too_many_arguments)]
pub(super) fn select_at_tip<T: Real>(
    mesh: &Mesh<'_, T>,
    x: &[[T; 3]],
    phi: &[T],
    psi: &[T],
    sep: &SeparationSurface<'_, T>,
    k: usize,
    status: &mut [u32],
    edges: &mut [[u32; 2]],
    work: &mut CutWork,
) {
    let reach = T::of(2.0) * sep.tube_px();
    let mut n_edges = 0;
    for tet in mesh.tets() {
        // The face on the surface (the nodes with φ = 0), if the tetrahedron has one.
        let mut face = [0u32; 3];
        let mut n = 0;
        for &v in tet {
            if phi.get(v as usize) == Some(&T::zero())
                && let Some(f) = face.get_mut(n)
            {
                *f = v;
                n += 1;
            }
        }
        if n < 3 {
            continue;
        }
        let fs = face.map(|v| psi.get(v as usize).map_or(0, |&p| sign(p)));
        if !(fs.contains(&1) && fs.contains(&-1)) {
            continue;
        }
        // Where the plane crosses the face lies on the ray through the end if the face lies
        // on the surface, off it by up to the face's size if its nodes were declared on it.
        let size = face
            .iter()
            .filter_map(|&v| x.get(v as usize).and_then(|p| sep.distance_to_end(k, p)))
            .fold(reach, |m, d| m.max(d));
        let nodes = [(fs[0], face[0]), (fs[1], face[1]), (fs[2], face[2])];
        for ((sa, va), (sb, vb)) in pairs(&nodes) {
            if sa * sb >= 0 {
                continue;
            }
            let (Some(&xa), Some(&xb)) = (x.get(va as usize), x.get(vb as usize)) else {
                continue;
            };
            let cross = lerp(xa, xb, crossing(psi, va, vb));
            let near = sep.distance_to_end(k, &cross).is_some_and(|d| d <= size);
            if near && let Some(slot) = edges.get_mut(n_edges) {
                *slot = [va.min(vb), va.max(vb)];
                n_edges += 1;
            }
        }
    }
    let edges = edges.get_mut(..n_edges).unwrap_or_default();
    edges.sort_unstable();
    for (tet, st) in mesh.tets().iter().zip(status.iter_mut()) {
        let around = pairs(tet).any(|(va, vb)| {
            let key = [va.min(vb), va.max(vb)];
            edges.binary_search(&key).is_ok()
        });
        *st = if around { SELECTED } else { 0 };
    }
    work.element_tests += 2 * mesh.n_tets() as u64;
}

/// Stops the split where the extent ends: a crossed edge of a selected tetrahedron that is
/// shared with a crossed tetrahedron not selected (beyond the end of a partial cut) gets its
/// node nearer the crossing declared on the surface, so every crossed edge left is split in all
/// its tetrahedra and the mesh stays conforming.
pub(super) fn stop_at_extent_ends<T: Real>(
    mesh: &Mesh<'_, T>,
    phi: &mut [T],
    incidence: &Incidence<'_>,
    status: &[u32],
    event: &mut CutEvent,
) {
    let selected = |t: u32| status.get(t as usize) == Some(&SELECTED);
    for (t, tet) in mesh.tets().iter().enumerate() {
        if !selected(t as u32) {
            continue;
        }
        for (va, vb) in pairs(tet) {
            let (Some(&pa), Some(&pb)) = (phi.get(va as usize), phi.get(vb as usize)) else {
                continue;
            };
            if sign(pa) * sign(pb) >= 0 {
                continue;
            }
            let outside = incidence.of(va as usize).iter().any(|&u| {
                !selected(u) && mesh.tets().get(u as usize).is_some_and(|o| o.contains(&vb))
            });
            if outside {
                let near = if crossing(phi, va, vb) < T::of(0.5) {
                    va
                } else {
                    vb
                };
                if let Some(p) = phi.get_mut(near as usize) {
                    *p = T::zero();
                    event.nodes_declared += 1;
                }
            }
        }
    }
}

/// Where a split would leave a piece below [`QUALITY_FLOOR`], declares the tetrahedron's most
/// lopsided crossing on the surface (its node nearer the crossing), and tries again, until no
/// selected split has such a piece. Declaring never changes geometry, so this ends — at worst
/// with no crossing left — in at most one pass per node.
pub(super) fn keep_above_floor<T: Real>(
    mesh: &Mesh<'_, T>,
    phi: &mut [T],
    status: &[u32],
    event: &mut CutEvent,
) {
    let floor = T::of(QUALITY_FLOOR);
    let rest = mesh.rest();
    let rest_of = |phi: &[T], v: Vertex| -> Option<[T; 3]> {
        match v {
            Vertex::Node(n) => rest.get(n as usize).copied(),
            Vertex::Edge(a, b) => Some(lerp(
                *rest.get(a as usize)?,
                *rest.get(b as usize)?,
                crossing(phi, a, b),
            )),
        }
    };
    // A piece with a corner out of range counts as flat.
    let quality = |phi: &[T], c: &[Vertex; 4]| -> T {
        let [a, b, c, d] = c.map(|v| rest_of(phi, v));
        match (a, b, c, d) {
            (Some(a), Some(b), Some(c), Some(d)) => shape_quality(&[a, b, c, d]).abs(),
            _ => T::zero(),
        }
    };
    for _pass in 0..=mesh.n_nodes() {
        let mut changed = false;
        for (t, &tet) in mesh.tets().iter().enumerate() {
            if status.get(t) != Some(&SELECTED) {
                continue;
            }
            event.work.element_tests += 1;
            let Some(s) = signs_of(phi, &tet) else {
                continue;
            };
            if !crosses(&s) {
                continue;
            }
            let worst = split(&tet, &s)
                .as_slice()
                .iter()
                .map(|c| quality(phi, c))
                .fold(T::one(), |m, q| m.min(q));
            if worst >= floor {
                continue;
            }
            let mut pick: Option<(T, u32)> = None;
            for ((sa, va), (sb, vb)) in pairs(&with_signs(&s, &tet)) {
                if sa * sb < 0 {
                    let t_ab = crossing(phi, va, vb);
                    let (d, node) = if t_ab < T::of(0.5) {
                        (t_ab, va)
                    } else {
                        (T::one() - t_ab, vb)
                    };
                    if pick.is_none_or(|(best, _)| d < best) {
                        pick = Some((d, node));
                    }
                }
            }
            if let Some((_, node)) = pick
                && let Some(p) = phi.get_mut(node as usize)
            {
                *p = T::zero();
                event.nodes_declared += 1;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Incidence;

    #[test]
    fn the_incidence_of_boundary_triangles_lists_each_nodes_triangles() {
        // A tetrahedron's boundary and a second, detached triangle; node 4 on no triangle.
        let surface = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2], [5, 6, 7]];
        let n = 8;
        let (mut start, mut list) = ([9u32; 9], [9u32; 15]);
        let stars = Incidence::build(&surface, n, &mut start, &mut list).unwrap();
        for v in 0..n {
            let mut got: [u32; 4] = [u32::MAX; 4];
            for (g, &k) in got.iter_mut().zip(stars.of(v)) {
                *g = k;
            }
            got.sort_unstable();
            let mut expected = [u32::MAX; 4];
            let with_v =
                (0..surface.len() as u32).filter(|&k| surface[k as usize].contains(&(v as u32)));
            for (e, k) in expected.iter_mut().zip(with_v) {
                *e = k;
            }
            assert_eq!(got, expected, "node {v}");
        }
        // Too little room: refused, not cut short.
        assert!(Incidence::build(&surface, n, &mut [0; 8], &mut [0; 15]).is_err());
        assert!(Incidence::build(&surface, n, &mut [0; 9], &mut [0; 14]).is_err());
    }
}
