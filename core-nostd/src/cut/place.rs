//! Where the cut goes through the mesh, before anything is split: nodes put on the surface
//! (snapped), the crossed tetrahedra inside the extent selected, the split stopped where the
//! extent ends, and crossings that would make a piece below the quality floor snapped instead.
//!
//! Everything here only moves nodes (snapping, checked against the floor) or sets `φ = 0`
//! (declaring a node on the surface, which never changes geometry and never creates a
//! crossing), so each step can only simplify what the next one splits.

// Not yet free of indexing: exempt from the `deny` of `cut/mod.rs`.
#![allow(clippy::indexing_slicing)]

use crate::mesh::{Mesh, orientation, shape_quality};
use crate::real::Real;

use super::separate::Incidence;
use super::split::{Vertex, crosses, split};
use super::surface::SeparationSurface;
use super::{CutEvent, CutWork, QUALITY_FLOOR, SNAP_TOLERANCE, crossing, lerp, sign, signs_of};

/// Marks a selected tetrahedron in the status array.
pub(super) const SELECTED: u32 = 1;

/// Snapping: where the surface crosses an edge within [`SNAP_TOLERANCE`] of a node (inside
/// the extent), the node goes on the surface — moved there along the nearest such edge when
/// every tetrahedron around it stays above [`QUALITY_FLOOR`] (or no worse than it was) and
/// keeps its orientation in the current configuration, else only declared on it. A node on the
/// boundary moves only along a boundary edge, so that the organ's surface keeps its shape;
/// fixed nodes never move. `mark` is scratch of one entry per node.
#[allow(clippy::too_many_arguments)]
pub(super) fn snap_nodes<T: Real>(
    mesh: &mut Mesh<'_, T>,
    x: &mut [[T; 3]],
    previous: &mut [[T; 3]],
    phi: &mut [T],
    sep: &SeparationSurface<'_, T>,
    incidence: &Incidence<'_>,
    mark: &mut [u32],
    event: &mut CutEvent,
) {
    let (floor, tau) = (T::of(QUALITY_FLOOR), T::of(SNAP_TOLERANCE));
    let n0 = mesh.n_nodes();
    let on_boundary = &mut mark[..n0];
    on_boundary.fill(0);
    for tri in mesh.surface() {
        for &v in tri {
            on_boundary[v as usize] = 1;
        }
    }
    let boundary_edge = |mesh: &Mesh<'_, T>, a: u32, b: u32| {
        mesh.surface()
            .iter()
            .any(|tri| tri.contains(&a) && tri.contains(&b))
    };
    for v in 0..n0 {
        let pv = phi[v];
        if !(pv.finite() && pv != T::zero()) {
            continue;
        }
        // The nearest crossing on any edge, and on an edge the node may move along: (fraction
        // of the edge from the node, the node at its other end).
        let mut nearest: Option<(T, u32)> = None;
        let mut along: Option<(T, u32)> = None;
        for &t in incidence.of(v) {
            for &w in &mesh.tets()[t as usize] {
                let pw = phi[w as usize];
                if !(pw.finite() && sign(pw) == -sign(pv)) {
                    continue;
                }
                let t_cross = pv / (pv - pw);
                if nearest.is_none_or(|(b, _)| t_cross < b) {
                    nearest = Some((t_cross, w));
                }
                let allowed = on_boundary[v] == 0
                    || (on_boundary[w as usize] == 1 && boundary_edge(mesh, v as u32, w));
                if allowed && along.is_none_or(|(b, _)| t_cross < b) {
                    along = Some((t_cross, w));
                }
            }
        }
        let Some((t_near, w_near)) = nearest else {
            continue;
        };
        if !(t_near < tau && sep.in_extent(&lerp(x[v], x[w_near as usize], t_near))) {
            continue;
        }
        let movable = |(t_cross, w): (T, u32)| -> bool {
            let wi = w as usize;
            if !(t_cross < tau) || mesh.is_fixed(v) {
                return false;
            }
            let moved_rest = lerp(mesh.rest()[v], mesh.rest()[wi], t_cross);
            let moved_x = lerp(x[v], x[wi], t_cross);
            incidence.of(v).iter().all(|&t| {
                let tet = mesh.tets()[t as usize];
                let at = |p: &[[T; 3]], q: [T; 3]| {
                    tet.map(|u| if u as usize == v { q } else { p[u as usize] })
                };
                let q_old = shape_quality(&at(mesh.rest(), mesh.rest()[v]));
                let q_new = shape_quality(&at(mesh.rest(), moved_rest));
                let (c_old, c_new) = (at(x, x[v]), at(x, moved_x));
                let keeps_orientation = orientation(c_old[0], c_old[1], c_old[2], c_old[3])
                    <= T::zero()
                    || orientation(c_new[0], c_new[1], c_new[2], c_new[3]) > T::zero();
                (q_new >= floor || q_new >= q_old) && keeps_orientation
            })
        };
        match along.filter(|&a| movable(a)) {
            Some((t_cross, w)) => {
                let wi = w as usize;
                let moved_rest = lerp(mesh.rest()[v], mesh.rest()[wi], t_cross);
                mesh.set_rest(v, moved_rest);
                x[v] = lerp(x[v], x[wi], t_cross);
                previous[v] = lerp(previous[v], previous[wi], t_cross);
                event.nodes_moved += 1;
            }
            None => event.nodes_declared += 1,
        }
        phi[v] = T::zero();
    }
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
    for (t, tet) in mesh.tets().iter().enumerate() {
        status[t] = 0;
        let Some(s) = signs_of(phi, tet) else {
            continue;
        };
        if !crosses(&s) {
            continue;
        }
        // The tetrahedron's size in the image: the largest distance between two of its
        // nodes' images (0 if one cannot be projected).
        let image = tet.map(|v| sep.project(&x[v as usize]));
        let mut size = T::zero();
        for a in 0..4 {
            for b in a + 1..4 {
                if let (Some(p), Some(q)) = (image[a], image[b]) {
                    let d = [p[0] - q[0], p[1] - q[1]];
                    size = size.max((d[0] * d[0] + d[1] * d[1]).sqrt());
                }
            }
        }
        let counts = |p: &[T; 3]| sep.in_extent(p) || sep.near_inner_end(p, size);
        let mut inside = false;
        for a in 0..4 {
            for b in (a + 1)..4 {
                if s[a] * s[b] < 0 {
                    let (va, vb) = (tet[a], tet[b]);
                    let p = lerp(x[va as usize], x[vb as usize], crossing(phi, va, vb));
                    inside |= counts(&p);
                }
            }
            if s[a] == 0 {
                inside |= counts(&x[tet[a] as usize]);
            }
        }
        if inside {
            status[t] = SELECTED;
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
            if phi[v as usize] == T::zero() && n < 3 {
                face[n] = v;
                n += 1;
            }
        }
        if n < 3 {
            continue;
        }
        let fs = face.map(|v| sign(psi[v as usize]));
        if !(fs.contains(&1) && fs.contains(&-1)) {
            continue;
        }
        // Where the plane crosses the face lies on the ray through the end if the face lies
        // on the surface, off it by up to the face's size if its nodes were declared on it.
        let size = face
            .iter()
            .filter_map(|&v| sep.distance_to_end(k, &x[v as usize]))
            .fold(reach, |m, d| m.max(d));
        for a in 0..3 {
            for b in a + 1..3 {
                let (va, vb) = (face[a], face[b]);
                if fs[a] * fs[b] >= 0 {
                    continue;
                }
                let cross = lerp(x[va as usize], x[vb as usize], crossing(psi, va, vb));
                let near = sep.distance_to_end(k, &cross).is_some_and(|d| d <= size);
                if near && n_edges < edges.len() {
                    edges[n_edges] = [va.min(vb), va.max(vb)];
                    n_edges += 1;
                }
            }
        }
    }
    let edges = &mut edges[..n_edges];
    edges.sort_unstable();
    for (t, tet) in mesh.tets().iter().enumerate() {
        status[t] = 0;
        let around = (0..4).any(|a| {
            (a + 1..4).any(|b| {
                let key = [tet[a].min(tet[b]), tet[a].max(tet[b])];
                edges.binary_search(&key).is_ok()
            })
        });
        if around {
            status[t] = SELECTED;
        }
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
    for t in 0..mesh.n_tets() {
        if status[t] != SELECTED {
            continue;
        }
        let tet = mesh.tets()[t];
        for a in 0..4 {
            for b in (a + 1)..4 {
                let (va, vb) = (tet[a], tet[b]);
                if sign(phi[va as usize]) * sign(phi[vb as usize]) >= 0 {
                    continue;
                }
                let outside = incidence.of(va as usize).iter().any(|&u| {
                    status[u as usize] != SELECTED && mesh.tets()[u as usize].contains(&vb)
                });
                if outside {
                    let near = if crossing(phi, va, vb) < T::of(0.5) {
                        va
                    } else {
                        vb
                    };
                    phi[near as usize] = T::zero();
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
    let rest_of = |phi: &[T], v: Vertex| -> [T; 3] {
        match v {
            Vertex::Node(n) => mesh.rest()[n as usize],
            Vertex::Edge(a, b) => lerp(
                mesh.rest()[a as usize],
                mesh.rest()[b as usize],
                crossing(phi, a, b),
            ),
        }
    };
    for _pass in 0..=mesh.n_nodes() {
        let mut changed = false;
        for t in 0..mesh.n_tets() {
            if status[t] != SELECTED {
                continue;
            }
            event.work.element_tests += 1;
            let tet = mesh.tets()[t];
            let Some(s) = signs_of(phi, &tet) else {
                continue;
            };
            if !crosses(&s) {
                continue;
            }
            let worst = split(&tet, &s)
                .as_slice()
                .iter()
                .map(|c| shape_quality(&c.map(|v| rest_of(phi, v))).abs())
                .fold(T::one(), |m, q| m.min(q));
            if worst >= floor {
                continue;
            }
            let mut pick: Option<(T, u32)> = None;
            for a in 0..4 {
                for b in (a + 1)..4 {
                    if s[a] * s[b] < 0 {
                        let t_ab = crossing(phi, tet[a], tet[b]);
                        let (d, node) = if t_ab < T::of(0.5) {
                            (t_ab, tet[a])
                        } else {
                            (T::one() - t_ab, tet[b])
                        };
                        if pick.is_none_or(|(best, _)| d < best) {
                            pick = Some((d, node));
                        }
                    }
                }
            }
            if let Some((_, node)) = pick {
                phi[node as usize] = T::zero();
                event.nodes_declared += 1;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
}
