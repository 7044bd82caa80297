//! The true cut in the image (`gt/cut.csv`): where the slit meets the object's surface, as
//! chains of lip pairs ordered along that trace, shown where the camera sees it.
//!
//! The trace is ordered by the mesh, not by the image: two lip nodes follow each other when
//! an edge of a boundary triangle that is also an edge of a slit face joins them. Ordering
//! them along the main direction of their projections (what this replaced) zig-zags wherever
//! the trace is not a straight line in the image, which a slit seen obliquely never is: the
//! liver family's true cuts crossed their lobe back and forth, and a detected line along the
//! real cut was measured against segments that were no cut at all.

use std::collections::{BTreeMap, BTreeSet};

use incise_core::Camera;
use incise_core::nalgebra::Vector3;

use crate::generate::live::NEVER;
use crate::generate::object::TetMesh;
use crate::generate::tracking::DepthBuffer;

/// Lips apart by at least this many pixels in the image count as open (the same rule as the
/// scene's `cut_open_frame`).
pub const OPEN_PX: f64 = 1.0;

/// The slit's trace on the surface of the uncut object: chains of `(original, duplicate)` lip
/// pairs (a node of the slit's front, where the lips meet, is its own pair), each with the
/// frame its lips are released (a live cut) or [`crate::generate::live::OPEN`].
#[derive(Clone, Debug, Default)]
pub struct CutTrace {
    chains: Vec<Vec<((u32, u32), u32)>>,
    /// The trace nodes on the filmed surface (see [`CutTrace::film`]); all when `None`.
    filmed: Option<BTreeSet<u32>>,
}

/// One row of `gt/cut.csv`: a point of the true cut in the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceRow {
    /// Which piece of the true cut (consecutive rows of one piece form a polyline).
    pub part: usize,
    /// The midpoint of the lips, pixels.
    pub uv: [f64; 2],
    /// Whether the lips there are at least [`OPEN_PX`] apart.
    pub open: bool,
}

impl CutTrace {
    /// The trace of the lips `pairs` (released at `release`, one per pair) and the front
    /// nodes `front` on the surface of `fine` (the object before the slit): two of its nodes
    /// follow each other where an edge of a boundary triangle joins them that is also an edge
    /// of one of the slit's `faces`. Any boundary edge between two trace nodes is not enough:
    /// where the surface's triangles are large against the slit (SOFA's liver), an edge may
    /// join two lip nodes across a face the slit never meets, and the chains then looped over
    /// chords of the lobe that no cut follows (a chord of 220 px in one liver variant).
    pub fn new(
        fine: &TetMesh,
        pairs: &[(u32, u32)],
        release: &[u32],
        front: &[u32],
        faces: &[[u32; 3]],
    ) -> Self {
        let boundary = fine.boundary();
        let on_surface: BTreeSet<u32> = boundary.iter().flat_map(|b| b.0).collect();
        // Each trace node (the original of a lip pair, or a front node) with its pair and
        // release frame.
        let mut node: BTreeMap<u32, ((u32, u32), u32)> = BTreeMap::new();
        for (&(a, b), &r) in pairs.iter().zip(release) {
            if on_surface.contains(&a) {
                node.insert(a, ((a, b), r));
            }
        }
        for &v in front {
            if on_surface.contains(&v) {
                node.entry(v).or_insert(((v, v), NEVER));
            }
        }
        let key = |u: u32, v: u32| (u.min(v), u.max(v));
        let slit_edges: BTreeSet<(u32, u32)> = faces
            .iter()
            .flat_map(|f| [key(f[0], f[1]), key(f[1], f[2]), key(f[2], f[0])])
            .collect();
        let mut adjacent: BTreeMap<u32, BTreeSet<u32>> =
            node.keys().map(|&v| (v, BTreeSet::new())).collect();
        for (tri, _) in &boundary {
            for k in 0..3 {
                let (u, v) = (tri[k], tri[(k + 1) % 3]);
                if node.contains_key(&u) && node.contains_key(&v) && slit_edges.contains(&key(u, v))
                {
                    adjacent.entry(u).or_default().insert(v);
                    adjacent.entry(v).or_default().insert(u);
                }
            }
        }
        let chains = walk_chains(&adjacent, &fine.nodes)
            .into_iter()
            .map(|chain| chain.iter().map(|v| node[v]).collect())
            .collect();
        CutTrace {
            chains,
            filmed: None,
        }
    }

    /// Keeps the trace to the surface the camera films: the lip pairs whose node the camera
    /// sees at frame 0 (positions `x0`, depth buffer `depth0`), where the slit is closed and
    /// the tracker's features are sampled. The slit also meets the surfaces facing away (a
    /// band's underside, a lobe's far face), whose trace shows through the opening once the
    /// lips part; no feature lies there, and measured against it a line drawn along the cut
    /// on the filmed surface stood off by the object's thickness as the image shows it (about
    /// 30 px on the band family, 4 % of its diagonal).
    pub fn film(
        &mut self,
        x0: &[[f64; 3]],
        camera: &Camera<f64>,
        depth0: &DepthBuffer,
        tolerance: f64,
    ) {
        let filmed = self
            .chains
            .iter()
            .flatten()
            .map(|&((a, _), _)| a)
            .filter(|&a| {
                x0.get(a as usize)
                    .is_some_and(|&p| depth0.visible(camera, p, tolerance).is_some())
            })
            .collect();
        self.filmed = Some(filmed);
    }

    /// The true cut at `frame` (node positions `x`, seen through `camera` with this frame's
    /// `depth`): the lip pairs shown, split into parts where the chain leaves the view. Shown
    /// are the pairs the camera sees (either lip within `tolerance` of the depth buffer) that
    /// have opened by this frame, and the front, where the lips still meet (for a live cut,
    /// the next pairs to be released); nothing while a live cut has not started.
    pub fn rows(
        &self,
        frame: u32,
        x: &[[f64; 3]],
        camera: &Camera<f64>,
        depth: &DepthBuffer,
        tolerance: f64,
    ) -> Vec<TraceRow> {
        let releases = self.chains.iter().flatten().map(|&(_, r)| r);
        let started = releases.clone().any(|r| r != NEVER && r <= frame);
        let front = releases.filter(|&r| r > frame).min().unwrap_or(NEVER);
        let mut rows = vec![];
        let mut part = 0;
        for chain in &self.chains {
            let mut in_part = false;
            for &((a, b), r) in chain {
                let filmed = self.filmed.as_ref().is_none_or(|f| f.contains(&a));
                let shown_now = filmed && started && (r <= frame || r == front);
                let seen = |v: u32| depth.visible(camera, x[v as usize], tolerance).is_some();
                let project = |v: u32| {
                    camera
                        .project(&Vector3::from(x[v as usize]), 0)
                        .ok()
                        .map(|p| [p.x, p.y])
                };
                let point = match (project(a), project(b)) {
                    (Some(pa), Some(pb)) if shown_now && (seen(a) || seen(b)) => Some((pa, pb)),
                    _ => None,
                };
                match point {
                    Some((pa, pb)) => {
                        rows.push(TraceRow {
                            part,
                            uv: [(pa[0] + pb[0]) / 2.0, (pa[1] + pb[1]) / 2.0],
                            open: (pa[0] - pb[0]).hypot(pa[1] - pb[1]) >= OPEN_PX,
                        });
                        in_part = true;
                    }
                    None if in_part => {
                        part += 1;
                        in_part = false;
                    }
                    None => {}
                }
            }
            if in_part {
                part += 1;
            }
        }
        rows
    }
}

/// The chains of a graph (`adjacent`, symmetric) that together cover every edge once: each
/// starts at a node whose number of neighbours is not two (an end, or a branch), then at any
/// node left (a closed loop), and goes on while an edge is unused, at a branch the one that
/// turns least (the nodes' rest positions `at`). A node without neighbours is a chain of one.
fn walk_chains(adjacent: &BTreeMap<u32, BTreeSet<u32>>, at: &[[f64; 3]]) -> Vec<Vec<u32>> {
    let mut used: BTreeSet<(u32, u32)> = BTreeSet::new();
    let key = |u: u32, v: u32| (u.min(v), u.max(v));
    let ends = adjacent
        .iter()
        .filter(|(_, n)| n.len() != 2)
        .map(|(&v, _)| v);
    let others = adjacent
        .iter()
        .filter(|(_, n)| n.len() == 2)
        .map(|(&v, _)| v);
    let mut chains = vec![];
    for start in ends.chain(others) {
        let isolated = adjacent[&start].is_empty();
        if isolated {
            chains.push(vec![start]);
            continue;
        }
        loop {
            let mut chain = vec![start];
            let mut current = start;
            let mut came_from: Option<u32> = None;
            while let Some(next) = adjacent[&current]
                .iter()
                .copied()
                .filter(|&n| !used.contains(&key(current, n)))
                .min_by(|&p, &q| {
                    turn(came_from, current, p, at).total_cmp(&turn(came_from, current, q, at))
                })
            {
                used.insert(key(current, next));
                chain.push(next);
                came_from = Some(current);
                current = next;
            }
            if chain.len() == 1 {
                break;
            }
            chains.push(chain);
        }
    }
    chains
}

/// How far the path `from → via → to` turns (1 − cos of the angle; 0 without `from`).
fn turn(from: Option<u32>, via: u32, to: u32, at: &[[f64; 3]]) -> f64 {
    let Some(from) = from else {
        return 0.0;
    };
    let p = |v: u32| Vector3::from(at[v as usize]);
    let (d0, d1) = (p(via) - p(from), p(to) - p(via));
    let n = d0.norm() * d1.norm();
    if n > 0.0 { 1.0 - d0.dot(&d1) / n } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn graph(edges: &[(u32, u32)], n: u32) -> BTreeMap<u32, BTreeSet<u32>> {
        let mut g: BTreeMap<u32, BTreeSet<u32>> = (0..n).map(|v| (v, BTreeSet::new())).collect();
        for &(u, v) in edges {
            g.get_mut(&u).unwrap().insert(v);
            g.get_mut(&v).unwrap().insert(u);
        }
        g
    }

    #[test]
    fn a_path_is_one_chain_in_order_whatever_the_numbering() {
        // 3 - 0 - 4 - 1 - 2 along x.
        let at = [
            [1.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [4.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
        ];
        let g = graph(&[(3, 0), (0, 4), (4, 1), (1, 2)], 5);
        let chains = walk_chains(&g, &at);
        assert_eq!(chains, vec![vec![2, 1, 4, 0, 3]]);
    }

    #[test]
    fn a_branch_continues_straight_and_the_side_arm_is_its_own_chain() {
        // 0 - 1 - 2 along x, 3 off node 1 along y.
        let at = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        let g = graph(&[(0, 1), (1, 2), (1, 3)], 4);
        let chains = walk_chains(&g, &at);
        assert_eq!(chains, vec![vec![0, 1, 2], vec![1, 3]]);
        // Every edge once.
        let edges: usize = chains.iter().map(|c| c.len() - 1).sum();
        assert_eq!(edges, 3);
    }

    #[test]
    fn the_trace_keeps_to_the_surface_filmed_at_rest() {
        use crate::generate::live::OPEN;
        // A camera at z = -1 looking along +z. Two lip pairs on the face it films (z = 0) and
        // two on a face behind it (z = 0.5), hidden at rest by a triangle of the front face.
        let camera = crate::generate::test_camera();
        let x = [
            [-0.05, 0.0, 0.0],
            [-0.04, 0.0, 0.0],
            [0.05, 0.0, 0.0],
            [0.06, 0.0, 0.0],
            [-0.05, 0.0, 0.5],
            [-0.04, 0.0, 0.5],
            [0.05, 0.0, 0.5],
            [0.06, 0.0, 0.5],
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let at_rest = DepthBuffer::render(&camera, &x, &[[8, 9, 10]]);
        // Later the lips part and the far face shows through the opening.
        let opened = DepthBuffer::render(&camera, &x, &[]);
        let chain = vec![
            ((0, 1), OPEN),
            ((2, 3), OPEN),
            ((6, 7), OPEN),
            ((4, 5), OPEN),
        ];
        let mut trace = CutTrace {
            chains: vec![chain],
            filmed: None,
        };
        let all = trace.rows(1, &x, &camera, &opened, 1e-3);
        assert_eq!(all.len(), 4);
        trace.film(&x, &camera, &at_rest, 1e-3);
        let filmed = trace.rows(1, &x, &camera, &opened, 1e-3);
        let uv: Vec<[f64; 2]> = filmed.iter().map(|r| r.uv).collect();
        assert_eq!(uv, [[45.5, 50.0], [55.5, 50.0]]);
        assert!(filmed.iter().all(|r| r.part == 0 && r.open));
    }

    #[test]
    fn only_the_slit_s_own_edges_join_the_trace() {
        use crate::generate::live::OPEN;
        // A 4 × 4 × 1 band slit at x = 0.5 from its edge y = 0 up to the front at y = 0.5.
        let (band, slit) = crate::generate::object::half_side_slit();
        let at = |p: [f64; 3]| {
            band.nodes
                .iter()
                .position(|q| (0..3).all(|k| (q[k] - p[k]).abs() < 1e-9))
                .unwrap() as u32
        };
        let release = vec![OPEN; slit.pairs.len()];
        // A node beside the slit, joined to its lip node at (0.5, 0, 0.25) by an edge of the
        // top face that no slit face has, is given as a front node: it stays a chain of its own.
        let beside = at([0.75, 0.0, 0.25]);
        let mut front = slit.front.clone();
        front.push(beside);
        let trace = CutTrace::new(&band, &slit.pairs, &release, &front, &slit.faces);
        let chains: Vec<Vec<u32>> = trace
            .chains
            .iter()
            .map(|c| c.iter().map(|&((a, _), _)| a).collect())
            .collect();
        assert!(chains.contains(&vec![beside]));
        // The top face's trace runs along the slit, edge to front.
        let top = [
            at([0.5, 0.0, 0.25]),
            at([0.5, 0.25, 0.25]),
            at([0.5, 0.5, 0.25]),
        ];
        assert!(chains.iter().any(|c| {
            c.windows(3)
                .any(|w| w == top || w.iter().rev().eq(top.iter()))
        }));
        // No chain steps off the slit's plane.
        for c in &chains {
            for w in c.windows(2) {
                assert!(w.iter().all(|&v| band.nodes[v as usize][0] == 0.5), "{c:?}");
            }
        }
    }

    #[test]
    fn a_loop_and_a_lone_node() {
        let at = [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [5.0, 5.0, 5.0]];
        let g = graph(&[(0, 1), (1, 2), (2, 0)], 4);
        let chains = walk_chains(&g, &at);
        assert_eq!(chains, vec![vec![3], vec![0, 1, 2, 0]]);
    }
}
