//! Cutting the volume mesh along the separation surface (paper §2.3, last paragraph): the
//! model is separated where the cut was detected, so that it can follow the organ again.
//!
//! The surface is the cut polyline of the image extruded along the camera rays
//! ([`surface`]). One cut event, on a copy of the mesh (the model swaps it in only when the
//! whole rebuild succeeds):
//!
//! 1. **Level set.** Every node gets `φ`, its signed distance to the plane of the segment
//!    nearest to its image.
//! 2. **Snap** (Nienhuys and van der Stappen). Where the surface crosses an edge within
//!    [`SNAP_TOLERANCE`] of a node, the node is put on the surface (`φ = 0`): moved there along
//!    that edge when every tetrahedron around it stays above [`QUALITY_FLOOR`] (and keeps its
//!    orientation in the current configuration), or else only declared on it. Snapping keeps
//!    slivers from being cut off and absorbs the small drift of the line between frames.
//! 3. **Select.** The crossed tetrahedra whose crossing lies inside the surface's extent are
//!    split. Where a crossed edge is shared with a crossed tetrahedron outside the extent (at
//!    the end of a partial cut), the node nearer the crossing is declared on the surface, so
//!    the split stops there and the mesh stays conforming.
//! 4. **Quality.** A split whose pieces would fall below the floor has its most lopsided
//!    crossing snapped instead (declared), and is tried again: declaring never changes
//!    geometry, so this always ends, with every piece above the floor.
//! 5. **Split** ([`split`]): a new node on each crossed edge (shared by every tetrahedron
//!    around it), each crossed tetrahedron replaced by its pieces.
//! 6. **Separate** ([`separate`]): the faces on the surface between pieces of opposite sides,
//!    inside the extent, are cut; their nodes are duplicated where the tetrahedra around them
//!    fall into groups no longer joined, so a partial cut leaves the material joined beyond
//!    its end (which the composite-FEM method the paper cites cannot do).
//! 7. **Re-embed.** Features and targets in a split tetrahedron move to the piece holding their
//!    material point; a feature whose piece lies on the other side of the cut than its
//!    observation in the image is moved to the surface of its own side.
//!
//! Progressive: each frame the line may have grown, and the next event cuts the rest; what is
//! already cut has its nodes on the surface and is not cut again. New nodes and tetrahedra
//! come from the capacities reserved for them; an overflow is an [`Error::Capacity`].
//!
//! Cost of an event: `O(n · s)` for the level set (`n` nodes, `s` segments), `O(t)` to select
//! and split, a sort of the `4 t` faces, and the stars of the nodes on the cut; it is counted in
//! [`CutWork`] and bounded by [`CutWork::bound`].

pub(crate) mod separate;
pub(crate) mod split;
pub(crate) mod surface;

use crate::camera::Camera;
use crate::embed::{Embedding, barycentric, clamp_weights, interpolate};
use crate::error::{Error, Resource};
use crate::mesh::{Mesh, orientation, shape_quality};
use crate::real::Real;
use crate::solve::WorkCount;
use crate::sparse::NONE;
use crate::storage::Slab;

use separate::{Incidence, StarScratch, cut_faces, duplicate_nodes};
use split::{Children, Sign, Vertex, crosses, split};
use surface::{REALS_PER_VERTEX, SeparationSurface};

/// Snapping tolerance: a crossing closer to a node than this fraction of the edge puts the
/// node on the surface instead of splitting the edge. At 0.25, the pieces of a split are
/// rarely below a tenth of their parent's quality (1st percentile over random tetrahedra and
/// planes), and the line's drift between frames is absorbed.
pub const SNAP_TOLERANCE: f64 = 0.25;

/// Quality floor of every tetrahedron a cut creates or moves, in [`shape_quality`]: 0.02 is
/// the quality of a tetrahedron whose volume is 2% of the regular one with the same edges.
/// Below it the element's stiffness is too ill-conditioned to be worth its cost; SOFA's coarse
/// liver, the worst mesh shipped, has none below 0.079.
pub const QUALITY_FLOOR: f64 = 0.02;

/// Indices of workspace a cut needs for meshes of up to `nodes` nodes and `tets` tetrahedra.
pub const fn work_len(nodes: usize, tets: usize) -> usize {
    // Marks per node, incidence, a word and the former nodes per tetrahedron, crossed edges,
    // the face sort (reused for the stars), the cut faces.
    nodes + (nodes + 1) + 4 * tets + tets + 4 * tets + 12 * tets + 16 * tets + 6 * tets + 8
}

/// Scalars of scratch a cut needs: `φ` per node and a plane per polyline segment.
pub const fn real_len(nodes: usize, cut_vertices: usize) -> usize {
    nodes + REALS_PER_VERTEX * cut_vertices
}

/// The separation surface as the model hands it to [`apply`].
pub(crate) struct Surface<'s, T: Real> {
    /// The cut polyline in the image, pixels (at least two vertices).
    pub polyline: &'s [[T; 2]],
    pub camera: &'s Camera<T>,
    /// Extrude along this direction instead of the camera rays.
    pub depth: Option<[T; 3]>,
    /// The detector sees a cut only to within a feature spacing of its ends: each open end is
    /// extended by this much, which is also the half-width of the surface's extent.
    pub extension_px: T,
    /// Which ends are open (an end that continues a cut already made is not extended).
    pub extend: [bool; 2],
}

/// The parts of a model a cut changes (the spare half, a copy of the one in service).
pub(crate) struct Pieces<'m, 'a, T> {
    pub mesh: &'m mut Mesh<'a, T>,
    pub x: &'m mut [[T; 3]],
    pub previous: &'m mut [[T; 3]],
    pub features: &'m mut Embedding<'a, T>,
    pub targets: &'m mut Embedding<'a, T>,
    pub lips: &'m mut Lips<'a>,
}

/// The node pairs a cut has separated: a node on the cut and its copy on the other lip. Their
/// midpoints in the image are where the cut is seen now, which the cut line follows once the
/// model no longer spans the opening ([`crate::cutline`]).
#[derive(Debug)]
pub struct Lips<'a> {
    pairs: &'a mut [[u32; 2]],
    len: usize,
}

impl<'a> Lips<'a> {
    /// Room for `capacity` pairs.
    pub(crate) fn with_capacity(
        capacity: usize,
        indices: &mut Slab<'a, u32>,
    ) -> Result<Self, Error> {
        Ok(Lips {
            pairs: indices.take(2 * capacity)?.as_chunks_mut::<2>().0,
            len: 0,
        })
    }

    /// The pairs `(node, copy)`.
    pub fn pairs(&self) -> &[[u32; 2]] {
        &self.pairs[..self.len]
    }

    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    pub(crate) fn copy_from(&mut self, other: &Lips<'_>) {
        let n = other.len.min(self.pairs.len());
        self.pairs[..n].copy_from_slice(&other.pairs[..n]);
        self.len = n;
    }

    fn push(&mut self, pair: [u32; 2]) -> Result<(), Error> {
        let available = self.pairs.len();
        let slot = self.pairs.get_mut(self.len).ok_or(Error::Capacity {
            resource: Resource::Nodes,
            needed: self.len + 1,
            available,
        })?;
        *slot = pair;
        self.len += 1;
        Ok(())
    }
}

/// Work of a cut event, in data-independent units.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct CutWork {
    /// Node–segment distance tests of the level set.
    pub node_tests: u64,
    /// Tetrahedron visits (selection, quality passes, splitting).
    pub element_tests: u64,
    /// Faces sorted to find the cut faces.
    pub faces_sorted: u64,
    /// Face entries sorted around the nodes on the cut.
    pub star_entries: u64,
    /// Point-in-piece and ray–triangle tests of the re-embedding.
    pub embed_tests: u64,
}

impl CutWork {
    /// The most an event can cost for a model of `nodes` nodes, `tets` tetrahedra, `triangles`
    /// boundary triangles (all at capacity), `segments` polyline segments, `features` and
    /// `targets`: every node tested against every segment, every tetrahedron visited once per
    /// quality pass (at most one pass per node, each declaring one node on the surface), all
    /// faces sorted, every node's star sorted, and every point re-embedded.
    pub fn bound(
        nodes: u64,
        tets: u64,
        triangles: u64,
        segments: u64,
        features: u64,
        targets: u64,
    ) -> Self {
        CutWork {
            node_tests: nodes * segments,
            element_tests: tets * (3 + nodes),
            faces_sorted: 4 * tets,
            star_entries: 12 * tets,
            embed_tests: (features + targets) * split::MAX_CHILDREN as u64 + features * triangles,
        }
    }

    /// Whether every count is at most `bound`'s.
    pub fn within(&self, bound: &CutWork) -> bool {
        self.node_tests <= bound.node_tests
            && self.element_tests <= bound.element_tests
            && self.faces_sorted <= bound.faces_sorted
            && self.star_entries <= bound.star_entries
            && self.embed_tests <= bound.embed_tests
    }
}

/// What a cut event did to the mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct CutEvent {
    /// Nodes moved onto the surface.
    pub nodes_moved: usize,
    /// Nodes declared on the surface without moving (a move would have spoilt an element, the
    /// node is fixed, or the split stops there).
    pub nodes_declared: usize,
    /// Tetrahedra split.
    pub tets_split: usize,
    /// Tetrahedra added by the splits.
    pub tets_added: usize,
    /// Nodes added on crossed edges.
    pub edge_nodes: usize,
    /// Faces separated.
    pub faces_cut: usize,
    /// Node copies made to separate them.
    pub nodes_duplicated: usize,
    /// Features and targets moved to a piece of a split tetrahedron.
    pub points_reembedded: usize,
    /// Features moved to the surface of their own side.
    pub features_moved_across: usize,
    /// Lowest quality of the tetrahedra created or moved (1 if none).
    pub min_quality_milli: u32,
    /// The work of the geometry.
    pub work: CutWork,
}

impl CutEvent {
    /// Whether the event separates anything (else the model discards it).
    pub fn changes_mesh(&self) -> bool {
        self.faces_cut > 0
    }

    /// Adds the counts of `other` (the next part of one event).
    pub fn merge(&mut self, other: &CutEvent) {
        self.nodes_moved += other.nodes_moved;
        self.nodes_declared += other.nodes_declared;
        self.tets_split += other.tets_split;
        self.tets_added += other.tets_added;
        self.edge_nodes += other.edge_nodes;
        self.faces_cut += other.faces_cut;
        self.nodes_duplicated += other.nodes_duplicated;
        self.points_reembedded += other.points_reembedded;
        self.features_moved_across += other.features_moved_across;
        self.min_quality_milli = if self.tets_split == other.tets_split {
            other.min_quality_milli
        } else {
            self.min_quality_milli.min(other.min_quality_milli)
        };
        let (w, o) = (&mut self.work, &other.work);
        w.node_tests += o.node_tests;
        w.element_tests += o.element_tests;
        w.faces_sorted += o.faces_sorted;
        w.star_entries += o.star_entries;
        w.embed_tests += o.embed_tests;
    }
}

/// A cut event as [`crate::Model::step`] reports it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct CutReport {
    /// Whether a new topology went into service.
    pub applied: bool,
    /// The error that made the model refuse the cut (it stays as it was).
    pub refused: Option<Error>,
    /// The geometry of the event.
    pub event: CutEvent,
    /// The work of rebuilding the linear system (assembly, factorization), apart from the
    /// steady frame; the ordering and symbolic analysis are counted in
    /// [`WorkCount::factor_flops`]'s terms by their result only.
    pub work: WorkCount,
}

impl CutReport {
    /// A refused cut.
    pub fn refused(e: Error) -> Self {
        CutReport {
            refused: Some(e),
            ..CutReport::default()
        }
    }
}

fn sign<T: Real>(phi: T) -> Sign {
    if phi > T::zero() {
        1
    } else if phi < T::zero() {
        -1
    } else {
        0
    }
}

fn lerp<T: Real>(a: [T; 3], b: [T; 3], t: T) -> [T; 3] {
    [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * t)
}

/// Side of a tetrahedron: the sign its nodes share (0 if all are on the surface or one is
/// unknown).
fn side_of<T: Real>(phi: &[T], tet: &[u32; 4]) -> Sign {
    let mut s: Sign = 0;
    for &v in tet {
        let p = phi[v as usize];
        if !p.finite() {
            return 0;
        }
        let sv = sign(p);
        if sv != 0 {
            if s != 0 && s != sv {
                return 0;
            }
            s = sv;
        }
    }
    s
}

/// Where the cut crosses edge `(a, b)`: the fraction from `a`.
fn crossing<T: Real>(phi: &[T], a: u32, b: u32) -> T {
    let (pa, pb) = (phi[a as usize], phi[b as usize]);
    pa / (pa - pb)
}

/// Cuts `pieces` (the mesh, its positions and embeddings) along `surface`; `observed` are the
/// features' latest pixels (slot by slot). `reals` and `work` are scratch ([`real_len`],
/// [`work_len`]).
///
/// # Errors
/// [`Error::Capacity`] when the cut needs more nodes, tetrahedra or boundary triangles than
/// the mesh holds; [`Error::NonManifold`] if the cut mesh's boundary does not close. The pieces
/// are then inconsistent and must be dropped (the model keeps the half in service).
pub(crate) fn apply<T: Real>(
    surface: &Surface<'_, T>,
    observed: &[[T; 2]],
    pieces: Pieces<'_, '_, T>,
    reals: &mut [T],
    work: &mut [u32],
) -> Result<CutEvent, Error> {
    let Pieces {
        mesh,
        x,
        previous,
        features,
        targets,
        lips,
    } = pieces;
    let cap = *mesh.capacity();
    let (cap_nodes, cap_tets) = (cap.nodes, cap.tets);
    let mut event = CutEvent {
        min_quality_milli: 1000,
        ..CutEvent::default()
    };
    let floor = T::of(QUALITY_FLOOR);
    let tau = T::of(SNAP_TOLERANCE);

    let mut rs = Slab::new(reals, Resource::RealStorage);
    let phi = rs.take(cap_nodes)?;
    let plane_store = rs.take(rs.remaining())?;
    let sep = SeparationSurface::new(
        surface.polyline,
        surface.camera,
        surface.depth,
        surface.extension_px,
        surface.extend,
        mesh,
        x,
        plane_store,
    )?;
    if sep.segments() == 0 {
        return Ok(event);
    }

    if work.len() < work_len(cap_nodes, cap_tets) {
        return Err(Error::Capacity {
            resource: Resource::Workspace,
            needed: work_len(cap_nodes, cap_tets),
            available: work.len(),
        });
    }
    let mut ws = Slab::new(work, Resource::Workspace);
    let mark = ws.take(cap_nodes)?;
    let inc_ptr = ws.take(cap_nodes + 1)?;
    let inc_list = ws.take(4 * cap_tets)?;
    // Per original tetrahedron: NONE if untouched, else where its appended pieces start.
    let status = ws.take(cap_tets)?;
    // The nodes each split tetrahedron had before (its material points are located in them).
    let parents = ws.take(4 * cap_tets)?.as_chunks_mut::<4>().0;
    let edges = ws.take(12 * cap_tets)?.as_chunks_mut::<2>().0;
    let faces = ws.take(16 * cap_tets)?.as_chunks_mut::<4>().0;
    let cut_store = ws.take(6 * cap_tets)?.as_chunks_mut::<3>().0;

    // 1. Level set.
    let n0 = mesh.n_nodes();
    let t0 = mesh.n_tets();
    for v in 0..n0 {
        phi[v] = match sep.classify(&x[v]) {
            Some((_, p)) => p,
            // Behind the camera: no side, never cut.
            None => T::zero() / T::zero(),
        };
    }
    event.work.node_tests += (n0 * sep.segments()) as u64;
    // Nodes a cut has already separated stay on the surface: a later part continues the cut
    // through them instead of cutting a sliver off beside it.
    for pair in lips.pairs() {
        for &v in pair {
            if let Some(p) = phi.get_mut(v as usize) {
                *p = T::zero();
            }
        }
    }

    let incidence = Incidence::build(mesh.tets(), n0, inc_ptr, inc_list)?;

    // 2. Snap. A node on the boundary moves only along a boundary edge, so that the organ's
    // surface keeps its shape; inside, along any edge.
    mark[..n0].fill(0);
    for tri in mesh.surface() {
        for &v in tri {
            mark[v as usize] = 1;
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
        let on_boundary = mark[v] == 1;
        let (mut nearest, mut along): (Option<T>, Option<(T, u32)>) = (None, None);
        for &t in incidence.of(v) {
            for &w in &mesh.tets()[t as usize] {
                let pw = phi[w as usize];
                if pw.finite() && sign(pw) == -sign(pv) {
                    let t_cross = pv / (pv - pw);
                    if nearest.is_none_or(|b| t_cross < b) {
                        nearest = Some(t_cross);
                    }
                    let allowed =
                        !on_boundary || (mark[w as usize] == 1 && boundary_edge(mesh, v as u32, w));
                    if allowed && along.is_none_or(|(b, _)| t_cross < b) {
                        along = Some((t_cross, w));
                    }
                }
            }
        }
        let Some(t_near) = nearest else {
            continue;
        };
        // Where the surface passes: along the nearest crossing edge.
        let near_point = incidence
            .of(v)
            .iter()
            .flat_map(|&t| mesh.tets()[t as usize])
            .find(|&w| {
                let pw = phi[w as usize];
                pw.finite() && sign(pw) == -sign(pv) && pv / (pv - pw) == t_near
            })
            .map(|w| lerp(x[v], x[w as usize], t_near));
        if !(t_near < tau && near_point.is_some_and(|p| sep.in_extent(&p))) {
            continue;
        }
        let vi = v;
        let movable = |(t_cross, w): (T, u32)| -> bool {
            let wi = w as usize;
            if !(t_cross < tau) || mesh.is_fixed(vi) {
                return false;
            }
            let moved_rest = lerp(mesh.rest()[vi], mesh.rest()[wi], t_cross);
            let moved_x = lerp(x[vi], x[wi], t_cross);
            incidence.of(v).iter().all(|&t| {
                let tet = mesh.tets()[t as usize];
                let at = |p: &[[T; 3]], q: [T; 3]| {
                    tet.map(|u| if u as usize == vi { q } else { p[u as usize] })
                };
                let q_old = shape_quality(&at(mesh.rest(), mesh.rest()[vi]));
                let q_new = shape_quality(&at(mesh.rest(), moved_rest));
                let cur_old = at(x, x[vi]);
                let cur_new = at(x, moved_x);
                let keeps_orientation = orientation(cur_old[0], cur_old[1], cur_old[2], cur_old[3])
                    <= T::zero()
                    || orientation(cur_new[0], cur_new[1], cur_new[2], cur_new[3]) > T::zero();
                (q_new >= floor || q_new >= q_old) && keeps_orientation
            })
        };
        match along.filter(|&a| movable(a)) {
            Some((t_cross, w)) => {
                let wi = w as usize;
                let moved_rest = lerp(mesh.rest()[vi], mesh.rest()[wi], t_cross);
                mesh.set_rest(vi, moved_rest);
                x[vi] = lerp(x[vi], x[wi], t_cross);
                previous[vi] = lerp(previous[vi], previous[wi], t_cross);
                event.nodes_moved += 1;
            }
            None => event.nodes_declared += 1,
        }
        phi[vi] = T::zero();
    }

    // 3. Select the crossed tetrahedra inside the extent.
    let signs_of = |phi: &[T], tet: &[u32; 4]| -> Option<[Sign; 4]> {
        let mut s = [0; 4];
        for (k, &v) in tet.iter().enumerate() {
            let p = phi[v as usize];
            if !p.finite() {
                return None;
            }
            s[k] = sign(p);
        }
        Some(s)
    };
    const SELECTED: u32 = 1;
    for (t, tet) in mesh.tets().iter().enumerate() {
        status[t] = 0;
        let Some(s) = signs_of(phi, tet) else {
            continue;
        };
        if !crosses(&s) {
            continue;
        }
        let mut inside = false;
        for a in 0..4 {
            for b in (a + 1)..4 {
                if s[a] * s[b] < 0 {
                    let (va, vb) = (tet[a], tet[b]);
                    let p = lerp(x[va as usize], x[vb as usize], crossing(phi, va, vb));
                    inside |= sep.in_extent(&p);
                }
            }
            if s[a] == 0 {
                inside |= sep.in_extent(&x[tet[a] as usize]);
            }
        }
        if inside {
            status[t] = SELECTED;
        }
    }
    event.work.element_tests += t0 as u64;

    // 3b. Stop the split where the extent ends: a crossed edge shared with a crossed
    // tetrahedron that is not selected gets its nearer node declared on the surface.
    for t in 0..t0 {
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

    // 4. Quality: a split with a piece below the floor gets its most lopsided crossing
    // declared on the surface, until none has.
    let rest_of = |mesh: &Mesh<'_, T>, phi: &[T], v: Vertex| -> [T; 3] {
        match v {
            Vertex::Node(n) => mesh.rest()[n as usize],
            Vertex::Edge(a, b) => lerp(
                mesh.rest()[a as usize],
                mesh.rest()[b as usize],
                crossing(phi, a, b),
            ),
        }
    };
    for _pass in 0..=n0 {
        let mut changed = false;
        for t in 0..t0 {
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
            let children = split(&tet, &s);
            let worst = children
                .as_slice()
                .iter()
                .map(|c| shape_quality(&c.map(|v| rest_of(mesh, phi, v))).abs())
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

    // 5. Split: new nodes on the crossed edges, in the order of their keys.
    let mut n_edges = 0;
    for t in 0..t0 {
        if status[t] != SELECTED {
            continue;
        }
        let tet = mesh.tets()[t];
        let Some(s) = signs_of(phi, &tet) else {
            continue;
        };
        if !crosses(&s) {
            continue;
        }
        for a in 0..4 {
            for b in (a + 1)..4 {
                if s[a] * s[b] < 0 {
                    edges[n_edges] = [tet[a].min(tet[b]), tet[a].max(tet[b])];
                    n_edges += 1;
                }
            }
        }
    }
    let edges = &mut edges[..n_edges];
    edges.sort_unstable();
    let mut unique = 0;
    for k in 0..edges.len() {
        if k == 0 || edges[k] != edges[k - 1] {
            edges[unique] = edges[k];
            unique += 1;
        }
    }
    let edges = &edges[..unique];
    if n0 + unique > cap_nodes {
        return Err(Error::Capacity {
            resource: Resource::Nodes,
            needed: n0 + unique,
            available: cap_nodes,
        });
    }
    for &[a, b] in edges {
        let t_ab = crossing(phi, a, b);
        let (ai, bi) = (a as usize, b as usize);
        let fixed = mesh.is_fixed(ai) && mesh.is_fixed(bi);
        let v = mesh.push_node(lerp(mesh.rest()[ai], mesh.rest()[bi], t_ab), fixed)? as usize;
        x[v] = lerp(x[ai], x[bi], t_ab);
        previous[v] = lerp(previous[ai], previous[bi], t_ab);
        phi[v] = T::zero();
    }
    event.edge_nodes = unique;
    let node_of = |v: Vertex| -> u32 {
        match v {
            Vertex::Node(n) => n,
            Vertex::Edge(a, b) => edges
                .binary_search(&[a, b])
                .map_or(NONE, |k| (n0 + k) as u32),
        }
    };
    let mut min_quality = T::one();
    for t in 0..t0 {
        let split_here =
            status[t] == SELECTED && signs_of(phi, &mesh.tets()[t]).is_some_and(|s| crosses(&s));
        if !split_here {
            status[t] = NONE;
            continue;
        }
        let tet = mesh.tets()[t];
        let Some(s) = signs_of(phi, &tet) else {
            status[t] = NONE;
            continue;
        };
        let children: Children = split(&tet, &s);
        parents[t] = tet;
        // Where this tetrahedron's appended pieces start, and how many (at most five).
        status[t] = ((mesh.n_tets() as u32) << 3) | (children.len as u32 - 1);
        for (k, child) in children.as_slice().iter().enumerate() {
            let mut nodes = child.map(node_of);
            let corners = nodes.map(|v| mesh.rest()[v as usize]);
            if orientation(corners[0], corners[1], corners[2], corners[3]) < T::zero() {
                nodes.swap(2, 3);
            }
            let corners = nodes.map(|v| mesh.rest()[v as usize]);
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

    // 6. Re-embed the points of split tetrahedra in the piece holding them.
    for embedding in [&mut *features, &mut *targets] {
        for k in 0..embedding.len() {
            let t = embedding.tets()[k] as usize;
            let first = status.get(t).copied().unwrap_or(NONE);
            if t >= t0 || first == NONE {
                continue;
            }
            // The material point in the parent as snapped (its original nodes, rest now).
            let parent = parents[t];
            let Some(p) = interpolate(mesh.rest(), &parent, &embedding.weights()[k]) else {
                continue;
            };
            let mut best: Option<(T, u32, [T; 4])> = None;
            let (start, count) = ((first >> 3) as usize, (first & 7) as usize);
            for child in core::iter::once(t).chain(start..start + count) {
                let corners = mesh.tets()[child].map(|v| mesh.rest()[v as usize]);
                event.work.embed_tests += 1;
                if let Some(w) = barycentric(&corners, p) {
                    let score = w.iter().fold(T::one(), |m, &c| m.min(c));
                    if best.as_ref().is_none_or(|(b, _, _)| score > *b) {
                        best = Some((score, child as u32, w));
                    }
                }
            }
            if let Some((_, c, w)) = best
                && let Some(w) = clamp_weights(w)
            {
                embedding.set(k, c, w);
                event.points_reembedded += 1;
            }
        }
    }

    // 7. Separate along the cut faces. A piece with all four nodes on the surface (possible
    // where nodes were declared on it) takes the side of its centroid.
    let n1 = mesh.n_nodes();
    let side = |t: usize| {
        let tet = mesh.tets()[t];
        let s = side_of(phi, &tet);
        if s != 0 || !tet.iter().all(|&v| phi[v as usize] == T::zero()) {
            return s;
        }
        let c = [0, 1, 2]
            .map(|k| tet.iter().fold(T::zero(), |a, &v| a + x[v as usize][k]) / T::of(4.0));
        sep.classify(&c).map_or(0, |(_, p)| sign(p))
    };
    let n_cut = cut_faces(
        mesh,
        |v| phi[v as usize] == T::zero(),
        side,
        |key| {
            let c = [0, 1, 2].map(|k| {
                (x[key[0] as usize][k] + x[key[1] as usize][k] + x[key[2] as usize][k]) / T::of(3.0)
            });
            sep.in_extent(&c)
        },
        faces,
        cut_store,
    )?;
    event.work.faces_sorted += 4 * mesh.n_tets() as u64;
    event.faces_cut = n_cut;
    if n_cut == 0 {
        if event.tets_split > 0 || event.nodes_moved > 0 {
            mesh.finish_edit(work)?;
        }
        return Ok(event);
    }
    let cut = &cut_store[..n_cut];
    // Nodes on the cut, each once, in increasing order.
    mark[..n1].fill(0);
    for key in cut {
        for &v in key {
            mark[v as usize] = 1;
        }
    }
    let mut on_cut_len = 0;
    for v in 0..n1 {
        if mark[v] == 1 {
            mark[on_cut_len] = v as u32;
            on_cut_len += 1;
        }
    }
    let on_cut = &mark[..on_cut_len];
    let incidence = Incidence::build(mesh.tets(), n1, inc_ptr, inc_list)?;
    // The face sort is done with: its room holds the stars.
    let star_room = faces.as_flattened_mut();
    let (star_faces, star_parent) = star_room.split_at_mut(12 * cap_tets);
    let mut scratch = StarScratch {
        faces: star_faces.as_chunks_mut::<3>().0,
        parent: star_parent,
    };
    let x_ref = &mut *x;
    let prev_ref = &mut *previous;
    let phi_ref = &mut *phi;
    event.nodes_duplicated = duplicate_nodes(
        mesh,
        &incidence,
        cut,
        on_cut,
        &mut scratch,
        |mesh, v| {
            let vi = v as usize;
            let copy = mesh.push_node(mesh.rest()[vi], mesh.is_fixed(vi))? as usize;
            x_ref[copy] = x_ref[vi];
            prev_ref[copy] = prev_ref[vi];
            phi_ref[copy] = T::zero();
            lips.push([v, copy as u32])?;
            Ok(copy as u32)
        },
        &mut event.work.star_entries,
    )?;

    mesh.finish_edit(work)?;

    // A feature on the wrong side of the cut (its piece against its observation) goes to
    // the nearest point of the surface of its own side that faces the camera, as seen in the
    // image. (Its piece can reach over the line: snapping bends the cut by up to the snapping
    // tolerance.)
    for k in 0..features.len().min(observed.len()) {
        let Some(foot) = sep.foot(observed[k]) else {
            continue;
        };
        if !foot.inside || foot.signed_px.abs() < T::one() {
            continue;
        }
        let seen: Sign = sign(foot.signed_px);
        let t = features.tets()[k] as usize;
        let here = side_of(phi, &mesh.tets()[t]);
        if here == seen {
            continue;
        }
        event.work.embed_tests += mesh.surface().len() as u64;
        let near = nearest_visible_point(mesh, x, surface.camera, observed[k], |tet| {
            side_of(phi, &mesh.tets()[tet as usize]) == seen
        });
        if let Some((tet, w)) = near {
            features.set(k, tet, w);
            event.features_moved_across += 1;
        }
    }

    event.min_quality_milli = (min_quality.to_f64() * 1000.0).clamp(0.0, 1000.0) as u32;
    Ok(event)
}

/// The point of the boundary surface, on a triangle facing the camera whose tetrahedron
/// `accept` takes, whose image is nearest to pixel `uv`: as (tetrahedron, barycentric weights).
/// Cost: one projection per boundary triangle.
fn nearest_visible_point<T: Real>(
    mesh: &Mesh<'_, T>,
    x: &[[T; 3]],
    camera: &Camera<T>,
    uv: [T; 2],
    accept: impl Fn(u32) -> bool,
) -> Option<(u32, [T; 4])> {
    let centre = *camera.centre();
    let mut best: Option<(T, u32, [T; 3])> = None;
    for (tri, &tet) in mesh.surface().iter().zip(mesh.surface_tet()) {
        if !accept(tet) {
            continue;
        }
        let p = tri.map(|v| x[v as usize]);
        // Facing the camera: the camera lies on the outer side of the triangle.
        if orientation(p[0], p[1], p[2], [centre.x, centre.y, centre.z]) <= T::zero() {
            continue;
        }
        let mut q = [[T::zero(); 2]; 3];
        for (qk, pk) in q.iter_mut().zip(&p) {
            let Ok(image) = camera.project(&nalgebra::Vector3::new(pk[0], pk[1], pk[2]), 0) else {
                continue;
            };
            *qk = [image.x, image.y];
        }
        let (d2, b) = closest_in_triangle(q, uv);
        if best.as_ref().is_none_or(|(bd, _, _)| d2 < *bd) {
            let point = [0, 1, 2].map(|c| p[0][c] * b[0] + p[1][c] * b[1] + p[2][c] * b[2]);
            best = Some((d2, tet, point));
        }
    }
    let (_, tet, point) = best?;
    let corners = mesh.tets().get(tet as usize)?.map(|v| x[v as usize]);
    Some((tet, clamp_weights(barycentric(&corners, point)?)?))
}

/// Squared distance from `p` to the triangle `q` in the plane, and the barycentric weights of
/// the closest point.
fn closest_in_triangle<T: Real>(q: [[T; 2]; 3], p: [T; 2]) -> (T, [T; 3]) {
    let d = |a: [T; 2], b: [T; 2]| (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]);
    let (e1, e2) = (
        [q[1][0] - q[0][0], q[1][1] - q[0][1]],
        [q[2][0] - q[0][0], q[2][1] - q[0][1]],
    );
    let det = e1[0] * e2[1] - e1[1] * e2[0];
    if det.abs() > T::EPS {
        let w = [p[0] - q[0][0], p[1] - q[0][1]];
        let b1 = (w[0] * e2[1] - w[1] * e2[0]) / det;
        let b2 = (e1[0] * w[1] - e1[1] * w[0]) / det;
        if b1 >= T::zero() && b2 >= T::zero() && b1 + b2 <= T::one() {
            return (T::zero(), [T::one() - b1 - b2, b1, b2]);
        }
    }
    // Outside (or degenerate): the nearest point of the three edges.
    let mut best = (d(p, q[0]), [T::one(), T::zero(), T::zero()]);
    for k in 0..3 {
        let (a, b) = (q[k], q[(k + 1) % 3]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let len2 = e[0] * e[0] + e[1] * e[1];
        let t = if len2 > T::EPS {
            (((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / len2)
                .max(T::zero())
                .min(T::one())
        } else {
            T::zero()
        };
        let c = [a[0] + e[0] * t, a[1] + e[1] * t];
        let dist = d(p, c);
        if dist < best.0 {
            let mut w = [T::zero(); 3];
            w[k] = T::one() - t;
            w[(k + 1) % 3] = t;
            best = (dist, w);
        }
    }
    best
}
