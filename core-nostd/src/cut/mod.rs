//! Cutting the volume mesh along the separation surface (paper §2.3, last paragraph): the
//! model is separated where the cut was detected, so that it can follow the organ again.
//!
//! The surface is the cut polyline of the image extruded along the camera rays
//! (`surface.rs`). One cut event, on a copy of the mesh (the model swaps it in only when the
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
//! 5. **Split** (`split.rs`): a new node on each crossed edge (shared by every tetrahedron
//!    around it), each crossed tetrahedron replaced by its pieces.
//! 6. **Separate** (`separate.rs`): the faces on the surface between pieces of opposite sides,
//!    inside the extent, are cut (at an end inside the object, also those reaching past the
//!    extent by up to their own size whose nodes lie before the end's plane, so the crack
//!    front runs through the thickness where the end is, not slanted behind it); their nodes are duplicated where the tetrahedra around them
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

mod place;
mod reembed;
mod report;
pub(crate) mod separate;
pub(crate) mod split;
pub(crate) mod surface;

use crate::camera::Camera;
use crate::embed::{Embedding, gather};
use crate::error::{Error, Resource};
use crate::mesh::Mesh;
use crate::real::Real;
use crate::solve::WorkCount;
use crate::storage::{Slab, sum, times};

pub use report::{CutEvent, CutReport, CutWork};
use separate::{
    EdgeScratch, Incidence, StarScratch, cut_faces, duplicate_nodes, keep_edges_manifold,
};
use split::Sign;
use surface::{REALS_PER_VERTEX, SeparationSurface};

/// Snapping tolerance: a crossing closer to a node than this fraction of the edge puts the
/// node on the surface instead of splitting the edge. At 0.25, the pieces of a split are
/// rarely below a tenth of their parent's quality (1st percentile over random tetrahedra and
/// planes), and the line's drift between frames is absorbed.
pub const SNAP_TOLERANCE: f64 = 0.25;

/// Quality floor of every tetrahedron a cut creates or moves, in [`crate::mesh::shape_quality`]: 0.02 is
/// the quality of a tetrahedron whose volume is 2% of the regular one with the same edges.
/// Below it the element's stiffness is too ill-conditioned to be worth its cost; SOFA's coarse
/// liver, the worst mesh shipped, has none below 0.079.
pub const QUALITY_FLOOR: f64 = 0.02;

/// Indices of workspace a cut needs for meshes of up to `nodes` nodes and `tets` tetrahedra.
pub const fn work_len(nodes: usize, tets: usize) -> usize {
    // Marks per node, incidence, a word and the former nodes per tetrahedron, crossed edges
    // (first the snapping's boundary stars, three entries per boundary triangle, at most four
    // triangles per tetrahedron), the face sort (first the stars' starts and stamps, then the
    // stars of the separation), the cut faces.
    sum(&[
        nodes,
        nodes,
        1,
        times(4, tets),
        tets,
        times(4, tets),
        times(12, tets),
        face_room(nodes, tets),
        times(6, tets),
        8,
    ])
}

/// Indices of the face sort's room: four per face slot, and no fewer than the snapping's
/// boundary stars take from it before (a start and a stamp per node, and one more start).
const fn face_room(nodes: usize, tets: usize) -> usize {
    let faces = times(16, tets);
    let stars = sum(&[times(2, nodes), 4]);
    if faces > stars { faces } else { stars }
}

/// Scalars of scratch a cut needs: `φ` and the two ends' `ψ` per node, and a plane per
/// polyline segment.
pub const fn real_len(nodes: usize, cut_vertices: usize) -> usize {
    sum(&[times(3, nodes), times(REALS_PER_VERTEX, cut_vertices)])
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
            pairs: indices.take(times(2, capacity))?.as_chunks_mut::<2>().0,
            len: 0,
        })
    }

    /// The pairs `(node, copy)`.
    pub fn pairs(&self) -> &[[u32; 2]] {
        self.pairs.get(..self.len).unwrap_or_default()
    }

    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    pub(crate) fn copy_from(&mut self, other: &Lips<'_>) {
        let n = other.len.min(self.pairs.len());
        if let (Some(to), Some(from)) = (self.pairs.get_mut(..n), other.pairs.get(..n)) {
            to.copy_from_slice(from);
        }
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

pub(crate) fn sign<T: Real>(phi: T) -> Sign {
    if phi > T::zero() {
        1
    } else if phi < T::zero() {
        -1
    } else {
        0
    }
}

pub(crate) fn lerp<T: Real>(a: [T; 3], b: [T; 3], t: T) -> [T; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

/// Copies entry `from` of `s` to entry `to` (the data of a node to its copy).
fn copy_entry<P: Copy>(s: &mut [P], from: usize, to: usize) -> Result<(), Error> {
    let value = *s.get(from).ok_or(Error::IndexOutOfRange {
        resource: Resource::Nodes,
        position: to,
        index: from,
        bound: s.len(),
    })?;
    let available = s.len();
    *s.get_mut(to).ok_or(Error::Capacity {
        resource: Resource::Nodes,
        needed: to.saturating_add(1),
        available,
    })? = value;
    Ok(())
}

/// Side of a tetrahedron: the sign its nodes share (0 if all are on the surface or one is
/// unknown).
pub(crate) fn side_of<T: Real>(phi: &[T], tet: &[u32; 4]) -> Sign {
    let mut s: Sign = 0;
    for &v in tet {
        let Some(&p) = phi.get(v as usize) else {
            return 0;
        };
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

/// Where the cut crosses edge `(a, b)`: the fraction from `a` (0 for a node out of range).
pub(crate) fn crossing<T: Real>(phi: &[T], a: u32, b: u32) -> T {
    match (phi.get(a as usize), phi.get(b as usize)) {
        (Some(&pa), Some(&pb)) => pa / (pa - pb),
        _ => T::zero(),
    }
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
    let mut rs = Slab::new(reals, Resource::RealStorage);
    let phi = rs.take(cap_nodes)?;
    let psi_store = rs.take(2 * cap_nodes)?;
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
    let status = ws.take(cap_tets)?;
    let parents = ws.take(4 * cap_tets)?.as_chunks_mut::<4>().0;
    let edges = ws.take(12 * cap_tets)?.as_chunks_mut::<2>().0;
    let faces = ws
        .take(face_room(cap_nodes, cap_tets))?
        .as_chunks_mut::<4>()
        .0;
    let cut_store = ws.take(6 * cap_tets)?.as_chunks_mut::<3>().0;
    let (n0, t0) = (mesh.n_nodes(), mesh.n_tets());

    // 1. The level set, with the lips of earlier cuts on the surface.
    let short = |available: usize, needed: usize| Error::Capacity {
        resource: Resource::Nodes,
        needed,
        available,
    };
    let (x_len, phi_len) = (x.len(), phi.len());
    level_set(
        &sep,
        x.get(..n0).ok_or(short(x_len, n0))?,
        lips,
        phi.get_mut(..n0).ok_or(short(phi_len, n0))?,
        &mut event.work,
    );
    let incidence = Incidence::build(mesh.tets(), n0, inc_ptr, inc_list)?;
    // 2–4. Nodes onto the surface, the tetrahedra to split, and where the split stops.
    place::snap_nodes(
        mesh,
        x,
        previous,
        phi,
        &sep,
        &incidence,
        faces.as_flattened_mut(),
        edges.as_flattened_mut(),
        &mut event,
    )?;
    place::select(mesh, x, phi, &sep, status, &mut event.work);
    place::stop_at_extent_ends(mesh, phi, &incidence, status, &mut event);
    place::keep_above_floor(mesh, phi, status, &mut event);
    // 5. Split, then 6. the points of split tetrahedra into their pieces.
    split::split_selected(
        mesh,
        x,
        previous,
        phi,
        status,
        parents,
        edges,
        &mut [],
        &mut event,
    )?;
    reembed::into_pieces(
        mesh,
        [&mut *features, &mut *targets],
        status,
        parents,
        t0,
        &mut event,
    );
    // 6b. At an end inside the object, the cut ends exactly on the end's plane: the
    // tetrahedra whose faces on the surface it crosses are split by it too (`ψ`, the second
    // level set of a crack's tip).
    let (psi0, psi1) = psi_store.split_at_mut(cap_nodes);
    let mut psi: [Option<&mut [T]>; 2] = [None, None];
    for (k, psi_k) in [psi0, psi1].into_iter().enumerate() {
        let Some(plane) = sep.tip(k) else {
            continue;
        };
        event.ends_inside += 1;
        let n = mesh.n_nodes();
        for (p, xv) in psi_k.iter_mut().zip(x.get(..n).ok_or(short(x_len, n))?) {
            *p = plane[0] * xv[0] + plane[1] * xv[1] + plane[2] * xv[2] - plane[3];
        }
        let t_before = mesh.n_tets();
        let split_before = event.tets_split;
        let incidence = Incidence::build(mesh.tets(), n, inc_ptr, inc_list)?;
        place::select_at_tip(mesh, x, phi, psi_k, &sep, k, status, edges, &mut event.work);
        place::stop_at_extent_ends(mesh, psi_k, &incidence, status, &mut event);
        place::keep_above_floor(mesh, psi_k, status, &mut event);
        // The level sets the new edge nodes interpolate: `φ`, and the first end's `ψ` when
        // this is the second end.
        let (mut both, mut only_phi);
        let carried: &mut [&mut [T]] = match psi[0].as_deref_mut() {
            Some(psi_other) => {
                both = [&mut *phi, psi_other];
                &mut both
            }
            None => {
                only_phi = [&mut *phi];
                &mut only_phi
            }
        };
        split::split_selected(
            mesh, x, previous, psi_k, status, parents, edges, carried, &mut event,
        )?;
        event.tets_split_at_ends += event.tets_split - split_before;
        let points = [&mut *features, &mut *targets];
        reembed::into_pieces(mesh, points, status, parents, t_before, &mut event);
        if let Some(slot) = psi.get_mut(k) {
            *slot = Some(psi_k);
        }
    }
    let before_tips = |key: &[u32; 3]| {
        psi.iter().flatten().all(|p| {
            key.iter()
                .all(|&v| p.get(v as usize).is_some_and(|&pv| pv <= T::zero()))
        })
    };

    // 7. Separate along the cut faces. A piece with all four nodes on the surface (possible
    // where nodes were declared on it) takes the side of its centroid.
    let on_surface = |v: u32| phi.get(v as usize).is_some_and(|&p| p == T::zero());
    let side = |t: usize| {
        let Some(tet) = mesh.tets().get(t) else {
            return 0;
        };
        let s = side_of(phi, tet);
        if s != 0 || !tet.iter().all(|&v| on_surface(v)) {
            return s;
        }
        let Some(corners) = gather(x, tet) else {
            return 0;
        };
        let sum = corners.iter().fold([T::zero(); 3], |a, p| {
            [a[0] + p[0], a[1] + p[1], a[2] + p[2]]
        });
        let c = sum.map(|a| a / T::of(4.0));
        sep.classify(&c).map_or(0, |(_, p)| sign(p))
    };
    let n_cut = cut_faces(
        mesh,
        on_surface,
        side,
        |key| {
            let Some([a, b, c]) = gather(x, key) else {
                return false;
            };
            let third = T::of(3.0);
            let centre = [
                (a[0] + b[0] + c[0]) / third,
                (a[1] + b[1] + c[1]) / third,
                (a[2] + b[2] + c[2]) / third,
            ];
            // Past an end inside the object, by up to the face's own size, the end's plane
            // decides (`before_tips`): a face whose far nodes were declared on that plane
            // reaches past the extent, and left joined it would hold the lips together
            // there (the crack front would run slanted through the thickness).
            let inside =
                sep.in_extent(&centre) || sep.near_inner_end(&centre, sep.image_size(&[a, b, c]));
            inside && before_tips(key)
        },
        faces,
        cut_store,
    )?;
    event.work.faces_sorted += 4 * mesh.n_tets() as u64;
    // 7b. Faces whose separation would leave two sides touching along an edge only stay
    // joined (see `keep_edges_manifold`).
    let n_found = n_cut;
    let n_cut = if n_cut == 0 {
        0
    } else {
        let found = cut_store.get(..n_cut).unwrap_or_default();
        let on_cut = nodes_on(found, mesh.n_nodes(), mark);
        let incidence = Incidence::build(mesh.tets(), mesh.n_nodes(), inc_ptr, inc_list)?;
        let (star_faces, star_parent) = faces.as_flattened_mut().split_at_mut(12 * cap_tets);
        let (ring, ring_parent) = edges.as_flattened_mut().split_at_mut(8 * cap_tets);
        let mut stars = StarScratch {
            faces: star_faces.as_chunks_mut::<3>().0,
            parent: star_parent,
        };
        let mut scratch = EdgeScratch {
            groups: parents.as_flattened_mut(),
            stars: &mut stars,
            ring: ring.as_chunks_mut::<2>().0,
            ring_parent,
        };
        keep_edges_manifold(
            mesh,
            &incidence,
            cut_store,
            n_cut,
            on_cut,
            &mut scratch,
            &mut event.work.star_entries,
        )?
    };
    event.faces_kept_joined = n_found - n_cut;
    event.faces_cut = n_cut;
    if n_cut == 0 {
        if event.tets_split > 0 || event.nodes_moved > 0 {
            mesh.finish_edit(work)?;
        }
        count_surface_tests(&sep, mesh, &mut event.work);
        return Ok(event);
    }
    let available = cut_store.len();
    let cut = cut_store.get(..n_cut).ok_or(Error::Capacity {
        resource: Resource::Workspace,
        needed: n_cut,
        available,
    })?;
    let on_cut = nodes_on(cut, mesh.n_nodes(), mark);
    let incidence = Incidence::build(mesh.tets(), mesh.n_nodes(), inc_ptr, inc_list)?;
    // The face sort is done with: its room holds the stars.
    let (star_faces, star_parent) = faces.as_flattened_mut().split_at_mut(12 * cap_tets);
    let mut stars = StarScratch {
        faces: star_faces.as_chunks_mut::<3>().0,
        parent: star_parent,
    };
    event.nodes_duplicated = duplicate_nodes(
        mesh,
        &incidence,
        cut,
        on_cut,
        &mut stars,
        |mesh, v| {
            let vi = v as usize;
            let rest = *mesh.rest().get(vi).ok_or(Error::IndexOutOfRange {
                resource: Resource::Nodes,
                position: 0,
                index: vi,
                bound: mesh.n_nodes(),
            })?;
            let copy = mesh.push_node(rest, mesh.is_fixed(vi))? as usize;
            copy_entry(x, vi, copy)?;
            copy_entry(previous, vi, copy)?;
            if let Some(p) = phi.get_mut(copy) {
                *p = T::zero();
            }
            lips.push([v, copy as u32])?;
            Ok(copy as u32)
        },
        &mut event.work.star_entries,
    )?;
    mesh.finish_edit(work)?;

    // 8. Features on the wrong side of the cut go to their own.
    reembed::features_to_their_side(
        mesh,
        x,
        features,
        observed,
        &sep,
        surface.camera,
        phi,
        &mut event,
    );
    count_surface_tests(&sep, mesh, &mut event.work);
    Ok(event)
}

/// Adds what the surface counted to `work`: its point–segment tests beyond the level set's,
/// and its rays (each over every boundary triangle; the boundary is the one the rays were
/// cast at, no larger than the mesh's now).
fn count_surface_tests<T: Real>(
    sep: &SeparationSurface<'_, T>,
    mesh: &Mesh<'_, T>,
    work: &mut CutWork,
) {
    work.segment_tests += sep.segment_tests() - work.node_tests;
    work.triangle_tests += sep.rays() * mesh.surface().len() as u64;
}

/// `φ` of every node: its signed distance to the plane of the segment nearest to its image
/// (NaN behind the camera: no side, never cut). Nodes a cut has already separated stay on the
/// surface: a later part continues the cut through them instead of cutting a sliver off
/// beside it.
fn level_set<T: Real>(
    sep: &SeparationSurface<'_, T>,
    x: &[[T; 3]],
    lips: &Lips<'_>,
    phi: &mut [T],
    work: &mut CutWork,
) {
    let before = sep.segment_tests();
    for (p, xv) in phi.iter_mut().zip(x) {
        *p = match sep.classify(xv) {
            Some((_, p)) => p,
            None => T::zero() / T::zero(),
        };
    }
    // The level set's own tests (a node behind the camera is not tested); the surface counts
    // the others, [`CutWork::segment_tests`].
    work.node_tests += sep.segment_tests() - before;
    for pair in lips.pairs() {
        for &v in pair {
            if let Some(p) = phi.get_mut(v as usize) {
                *p = T::zero();
            }
        }
    }
}

/// The nodes of the cut faces, each once, in increasing order, written to the front of `mark`
/// (at least `n_nodes` entries).
fn nodes_on<'m>(cut: &[[u32; 3]], n_nodes: usize, mark: &'m mut [u32]) -> &'m [u32] {
    let n = n_nodes.min(mark.len());
    let Some(mark) = mark.get_mut(..n) else {
        return &[];
    };
    mark.fill(0);
    for key in cut {
        for &v in key {
            if let Some(m) = mark.get_mut(v as usize) {
                *m = 1;
            }
        }
    }
    // Compacted in place: entry `len` lies at or before `v`, already read.
    let mut len = 0;
    for v in 0..n {
        if mark.get(v) == Some(&1) {
            if let Some(m) = mark.get_mut(len) {
                *m = v as u32;
            }
            len += 1;
        }
    }
    let mark: &'m [u32] = mark;
    mark.get(..len).unwrap_or_default()
}

/// Signs of the nodes of `tet` (`None` if one is unknown).
pub(crate) fn signs_of<T: Real>(phi: &[T], tet: &[u32; 4]) -> Option<[Sign; 4]> {
    let mut s = [0; 4];
    for (sk, &v) in s.iter_mut().zip(tet) {
        let p = *phi.get(v as usize)?;
        if !p.finite() {
            return None;
        }
        *sk = sign(p);
    }
    Some(s)
}
