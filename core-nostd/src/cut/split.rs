//! Splitting one tetrahedron by the zero set of a linear function `φ` given at its nodes.
//!
//! After snapping, every node is strictly positive, strictly negative or exactly zero, and only
//! five sign patterns cross (up to symmetry); each has one split into tetrahedra:
//!
//! | nodes `+ / − / 0` | cut edges | pieces | tetrahedra |
//! | --- | --- | --- | --- |
//! | 1 / 3 / 0 (or 3 / 1) | 3 | a tetrahedron and a prism | 1 + 3 |
//! | 2 / 2 / 0 | 4 | two prisms | 3 + 3 |
//! | 1 / 2 / 1 (or 2 / 1) | 2 | a tetrahedron and a pyramid | 1 + 2 |
//! | 1 / 1 / 2 | 1 | two tetrahedra | 1 + 1 |
//!
//! The quadrilateral faces of prisms and pyramids are split along the diagonal through their
//! vertex of smallest key (Dompierre et al., "How to subdivide pyramids, prisms and hexahedra
//! into tetrahedra", 1999): the choice depends on the face alone, so two tetrahedra that share
//! it split it alike and the mesh stays conforming; and it always leaves a prism three
//! tetrahedra and a pyramid two. A vertex is keyed by what it is: a node of the mesh (by
//! index), or the new node on an edge (after every mesh node, by the edge's two nodes), which
//! is also the order the new nodes get their indices in.

use crate::embed::gather;
use crate::error::{Error, Resource};
use crate::mesh::{Mesh, orientation, shape_quality};
use crate::real::Real;
use crate::sparse::NONE;

use super::place::SELECTED;
use super::{CutEvent, crossing, lerp, signs_of};

/// A vertex of a piece: a node of the mesh, or the new node where the cut crosses an edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Vertex {
    /// Mesh node.
    Node(u32),
    /// New node on the edge between two mesh nodes (smaller first).
    Edge(u32, u32),
}

impl Vertex {
    /// The vertex on the edge `(a, b)`.
    pub fn edge(a: u32, b: u32) -> Self {
        Vertex::Edge(a.min(b), a.max(b))
    }
}

/// Sign of a node's `φ`: `1`, `-1` or `0`.
pub(crate) type Sign = i8;

/// At most six tetrahedra per split.
pub(crate) const MAX_CHILDREN: usize = 6;

/// Children of a split, in the order written (orientation not yet fixed).
pub(crate) struct Children {
    pub tets: [[Vertex; 4]; MAX_CHILDREN],
    pub len: usize,
}

impl Children {
    fn new() -> Self {
        Children {
            tets: [[Vertex::Node(0); 4]; MAX_CHILDREN],
            len: 0,
        }
    }

    fn push(&mut self, t: [Vertex; 4]) {
        if let Some(slot) = self.tets.get_mut(self.len) {
            *slot = t;
            self.len += 1;
        }
    }

    /// The tetrahedra written.
    pub fn as_slice(&self) -> &[[Vertex; 4]] {
        self.tets.get(..self.len).unwrap_or_default()
    }
}

/// Whether a tetrahedron with these signs is crossed by the zero set.
pub(crate) fn crosses(signs: &[Sign; 4]) -> bool {
    signs.contains(&1) && signs.contains(&-1)
}

/// The split of tetrahedron `tet` with node signs `signs` (`crosses(signs)` must hold, else
/// nothing is written).
pub(crate) fn split(tet: &[u32; 4], signs: &[Sign; 4]) -> Children {
    let mut out = Children::new();
    let count = |s: Sign| signs.iter().filter(|&&x| x == s).count();
    let (pos, neg, zero) = (count(1), count(-1), count(0));
    if pos == 0 || neg == 0 {
        return out;
    }
    let nodes_with = |s: Sign| {
        let mut v = [0u32; 4];
        let mut k = 0;
        for (&sa, &node) in signs.iter().zip(tet) {
            if sa == s {
                if let Some(slot) = v.get_mut(k) {
                    *slot = node;
                }
                k += 1;
            }
        }
        v
    };
    let n = Vertex::Node;
    match zero {
        0 if pos == 1 || neg == 1 => {
            // One node alone on its side: a tetrahedron at it, a prism on the other side.
            let (lone, others) = if pos == 1 {
                (nodes_with(1)[0], nodes_with(-1))
            } else {
                (nodes_with(-1)[0], nodes_with(1))
            };
            let c = [
                Vertex::edge(lone, others[0]),
                Vertex::edge(lone, others[1]),
                Vertex::edge(lone, others[2]),
            ];
            out.push([n(lone), c[0], c[1], c[2]]);
            prism(&mut out, [n(others[0]), n(others[1]), n(others[2])], c);
        }
        0 => {
            // Two and two: a prism on each side.
            let [a, b, ..] = nodes_with(1);
            let [c, d, ..] = nodes_with(-1);
            let (ac, ad, bc, bd) = (
                Vertex::edge(a, c),
                Vertex::edge(a, d),
                Vertex::edge(b, c),
                Vertex::edge(b, d),
            );
            prism(&mut out, [n(a), ac, ad], [n(b), bc, bd]);
            prism(&mut out, [n(c), ac, bc], [n(d), ad, bd]);
        }
        1 => {
            // Through one node: a tetrahedron on the lone node's side, a pyramid on the other.
            let z = nodes_with(0)[0];
            let (lone, [p1, p2, ..]) = if pos == 1 {
                (nodes_with(1)[0], nodes_with(-1))
            } else {
                (nodes_with(-1)[0], nodes_with(1))
            };
            let (c1, c2) = (Vertex::edge(lone, p1), Vertex::edge(lone, p2));
            out.push([n(lone), n(z), c1, c2]);
            pyramid(&mut out, n(z), [n(p1), n(p2), c2, c1]);
        }
        _ => {
            // Through an edge: one crossing, two tetrahedra.
            let [z1, z2, ..] = nodes_with(0);
            let (p, m) = (nodes_with(1)[0], nodes_with(-1)[0]);
            let c = Vertex::edge(p, m);
            out.push([n(z1), n(z2), n(p), c]);
            out.push([n(z1), n(z2), c, n(m)]);
        }
    }
    out
}

/// The prism with triangles `a` and `b` (edges `a[i]`–`b[i]`) as three tetrahedra.
fn prism(out: &mut Children, a: [Vertex; 3], b: [Vertex; 3]) {
    // Rotate (and, if need be, swap the two triangles) so the smallest vertex is a[0].
    let m = first_smallest(&[a[0], a[1], a[2], b[0], b[1], b[2]]);
    let (mut a, mut b) = if m < 3 { (a, b) } else { (b, a) };
    a.rotate_left(m % 3);
    b.rotate_left(m % 3);
    // The two quadrilaterals at a[0] are split through it, leaving a tetrahedron and a
    // pyramid over the third quadrilateral.
    out.push([a[0], b[0], b[1], b[2]]);
    pyramid(out, a[0], [a[1], a[2], b[2], b[1]]);
}

/// The pyramid with apex `apex` over the quadrilateral `q` (in cyclic order) as two
/// tetrahedra, split along the diagonal through `q`'s smallest vertex.
fn pyramid(out: &mut Children, apex: Vertex, mut q: [Vertex; 4]) {
    let m = first_smallest(&q);
    q.rotate_left(m);
    let [q0, q1, q2, q3] = q;
    out.push([apex, q0, q1, q2]);
    out.push([apex, q0, q2, q3]);
}

/// Position of the first smallest of `v` (0 if empty).
fn first_smallest(v: &[Vertex]) -> usize {
    let mut best: Option<(usize, Vertex)> = None;
    for (k, &x) in v.iter().enumerate() {
        if best.is_none_or(|(_, b)| x < b) {
            best = Some((k, x));
        }
    }
    best.map_or(0, |(k, _)| k)
}

/// Sets entry `v` of `s` to `f(s[a], s[b])` (a new node on the edge `(a, b)`).
fn on_edge<P: Copy>(
    s: &mut [P],
    [a, b]: [usize; 2],
    v: usize,
    f: impl Fn(P, P) -> P,
) -> Result<(), Error> {
    let (Some(&pa), Some(&pb)) = (s.get(a), s.get(b)) else {
        return Err(Error::IndexOutOfRange {
            resource: Resource::Nodes,
            position: v,
            index: a.max(b),
            bound: s.len(),
        });
    };
    let available = s.len();
    *s.get_mut(v).ok_or(Error::Capacity {
        resource: Resource::Nodes,
        needed: v.saturating_add(1),
        available,
    })? = f(pa, pb);
    Ok(())
}

/// Splits every selected tetrahedron still crossed: a new node on each crossed edge (the
/// edges sorted, so the new nodes are numbered in the order of their keys and shared by all the
/// tetrahedra around their edge; positions interpolated along the edge), and each tetrahedron
/// replaced by its pieces, the first in its place and the others appended together, each
/// positively oriented at rest. The new nodes lie on the level set (`phi = 0`); each array of
/// `carry` (other values per node) is interpolated onto them along their edge. On return
/// `status[t]` is [`NONE`] for a tetrahedron not split, else `(first appended piece << 3) |
/// appended pieces`, and `parents[t]` holds its former nodes. `edges` is scratch of six
/// entries per tetrahedron.
///
/// # Errors
/// [`Error::Capacity`] naming [`Resource::Nodes`] or [`Resource::Tetrahedra`] when the new
/// nodes or pieces do not fit.
#[allow(clippy::too_many_arguments)]
pub(super) fn split_selected<T: Real>(
    mesh: &mut Mesh<'_, T>,
    x: &mut [[T; 3]],
    previous: &mut [[T; 3]],
    phi: &mut [T],
    status: &mut [u32],
    parents: &mut [[u32; 4]],
    edges: &mut [[u32; 2]],
    carry: &mut [&mut [T]],
    event: &mut CutEvent,
) -> Result<(), Error> {
    let (n0, t0) = (mesh.n_nodes(), mesh.n_tets());
    let crossed = |mesh: &Mesh<'_, T>, phi: &[T], t: usize| -> Option<[Sign; 4]> {
        mesh.tets()
            .get(t)
            .and_then(|tet| signs_of(phi, tet))
            .filter(crosses)
    };
    let short_work = |needed: usize, available: usize| Error::Capacity {
        resource: Resource::Workspace,
        needed,
        available,
    };
    let edge_room = edges.len();
    let mut n_edges = 0;
    for (t, &st) in status.iter().enumerate().take(t0) {
        if st != SELECTED {
            continue;
        }
        let (Some(s), Some(&tet)) = (crossed(mesh, phi, t), mesh.tets().get(t)) else {
            continue;
        };
        for (a, (&sa, &va)) in s.iter().zip(&tet).enumerate() {
            for (&sb, &vb) in s.iter().zip(&tet).skip(a + 1) {
                if sa * sb < 0 {
                    *edges
                        .get_mut(n_edges)
                        .ok_or(short_work(n_edges + 1, edge_room))? = [va.min(vb), va.max(vb)];
                    n_edges += 1;
                }
            }
        }
    }
    let edges = edges
        .get_mut(..n_edges)
        .ok_or(short_work(n_edges, edge_room))?;
    edges.sort_unstable();
    // Compacted in place (sorted, so a repeat equals the last edge kept).
    let mut unique = 0;
    let mut last = None;
    for k in 0..edges.len() {
        let Some(&e) = edges.get(k) else {
            break;
        };
        if last != Some(e) {
            if let Some(slot) = edges.get_mut(unique) {
                *slot = e;
            }
            unique += 1;
            last = Some(e);
        }
    }
    let edges: &[[u32; 2]] = edges;
    let edges = edges.get(..unique).unwrap_or_default();
    let available = mesh.capacity().nodes;
    if n0 + unique > available {
        return Err(Error::Capacity {
            resource: Resource::Nodes,
            needed: n0 + unique,
            available,
        });
    }
    for &[a, b] in edges {
        let t_ab = crossing(phi, a, b);
        let (ai, bi) = (a as usize, b as usize);
        let fixed = mesh.is_fixed(ai) && mesh.is_fixed(bi);
        let Some([ra, rb]) = gather(mesh.rest(), &[a, b]) else {
            return Err(Error::IndexOutOfRange {
                resource: Resource::Nodes,
                position: 0,
                index: ai.max(bi),
                bound: mesh.n_nodes(),
            });
        };
        let v = mesh.push_node(lerp(ra, rb, t_ab), fixed)? as usize;
        on_edge(x, [ai, bi], v, |pa, pb| lerp(pa, pb, t_ab))?;
        on_edge(previous, [ai, bi], v, |pa, pb| lerp(pa, pb, t_ab))?;
        on_edge(phi, [ai, bi], v, |_, _| T::zero())?;
        for values in carry.iter_mut() {
            on_edge(values, [ai, bi], v, |pa, pb| pa + (pb - pa) * t_ab)?;
        }
    }
    event.edge_nodes += unique;
    let node_of = |v: Vertex| -> u32 {
        match v {
            Vertex::Node(n) => n,
            Vertex::Edge(a, b) => edges
                .binary_search(&[a, b])
                .map_or(NONE, |k| (n0 + k) as u32),
        }
    };
    let mut min_quality = T::one();
    let parent_room = parents.len();
    for t in 0..t0 {
        let Some(st) = status.get_mut(t) else {
            break;
        };
        let signs = if *st == SELECTED {
            crossed(mesh, phi, t)
        } else {
            None
        };
        let (Some(s), Some(&tet)) = (signs, mesh.tets().get(t)) else {
            *st = NONE;
            continue;
        };
        let children = split(&tet, &s);
        *parents.get_mut(t).ok_or(short_work(t + 1, parent_room))? = tet;
        *st = ((mesh.n_tets() as u32) << 3) | (children.len as u32 - 1);
        for (k, child) in children.as_slice().iter().enumerate() {
            let mut nodes = child.map(node_of);
            let Some(mut corners) = gather(mesh.rest(), &nodes) else {
                return Err(Error::IndexOutOfRange {
                    resource: Resource::Nodes,
                    position: t,
                    index: NONE as usize,
                    bound: mesh.n_nodes(),
                });
            };
            if orientation(corners[0], corners[1], corners[2], corners[3]) < T::zero() {
                nodes.swap(2, 3);
                corners.swap(2, 3);
            }
            min_quality = min_quality.min(shape_quality(&corners));
            if k == 0 {
                mesh.set_tet(t, nodes);
            } else {
                mesh.push_tet(nodes)?;
                event.tets_added += 1;
            }
        }
        event.tets_split += 1;
    }
    event.work.element_tests += t0 as u64;
    event.min_quality_milli = event
        .min_quality_milli
        .min((min_quality.to_f64() * 1000.0).clamp(0.0, 1000.0) as u32);
    Ok(())
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;

    /// Signed volume of a tetrahedron of points.
    fn volume(p: [[f64; 3]; 4]) -> f64 {
        let u = [0, 1, 2].map(|c| p[1][c] - p[0][c]);
        let v = [0, 1, 2].map(|c| p[2][c] - p[0][c]);
        let w = [0, 1, 2].map(|c| p[3][c] - p[0][c]);
        (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
            + u[2] * (v[0] * w[1] - v[1] * w[0]))
            / 6.0
    }

    #[test]
    fn every_pattern_tiles_the_tetrahedron_and_keeps_each_piece_on_one_side() {
        let x = [
            [0.0, 0.0, 0.0],
            [1.0, 0.1, 0.0],
            [0.2, 1.0, 0.1],
            [0.1, 0.3, 1.0],
        ];
        let tet = [4u32, 9, 2, 7];
        // φ at the nodes for each pattern; zeros are exact.
        let cases: [[f64; 4]; 7] = [
            [1.0, -1.0, -2.0, -0.5],
            [-1.0, 1.0, 2.0, 0.5],
            [1.0, 2.0, -1.0, -0.5],
            [0.0, 1.0, -1.0, -0.5],
            [0.0, -1.0, 1.0, 0.5],
            [0.0, 0.0, 1.0, -1.0],
            [1.0, 0.0, 0.0, -2.0],
        ];
        for phi in cases {
            let signs = phi.map(|p| {
                if p > 0.0 {
                    1
                } else if p < 0.0 {
                    -1
                } else {
                    0
                }
            });
            let local = |v: u32| tet.iter().position(|&t| t == v).unwrap();
            let pos = |vx: Vertex| -> ([f64; 3], f64) {
                match vx {
                    Vertex::Node(v) => (x[local(v)], phi[local(v)]),
                    Vertex::Edge(a, b) => {
                        let (ia, ib) = (local(a), local(b));
                        let t = phi[ia] / (phi[ia] - phi[ib]);
                        ([0, 1, 2].map(|c| x[ia][c] + t * (x[ib][c] - x[ia][c])), 0.0)
                    }
                }
            };
            let children = split(&tet, &signs);
            let mut total = 0.0;
            for child in children.as_slice() {
                let p = child.map(|v| pos(v).0);
                let vol = volume(p).abs();
                assert!(vol > 1e-6, "{phi:?}: flat child {child:?}");
                total += vol;
                // All of a child's nodes lie on one side (zeros allowed).
                let s = child.map(|v| pos(v).1);
                assert!(
                    s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0),
                    "{phi:?}: child {child:?} straddles"
                );
            }
            assert!((total - volume(x)).abs() < 1e-12, "{phi:?}: {total}");
        }
    }
}
