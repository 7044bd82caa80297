//! What a cut reports: its work against the bound of the capacities, the event (what was
//! snapped, split and separated), and the report of one attempt, applied or refused.

use super::*;

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
    /// Point–segment tests of the image points classified against the polyline outside the
    /// level set (which [`CutWork::node_tests`] counts): the snapping's, the selection's and
    /// the cut faces' extent checks, and the features' sides.
    pub segment_tests: u64,
    /// Visits of the boundary triangles: the surface's construction (the rays through its
    /// vertices, ends and tips to the model, each over every triangle) and the snapping (the
    /// boundary triangles at each node, which tell whether an edge lies on the boundary).
    pub triangle_tests: u64,
}

impl CutWork {
    /// The most an event can cost for a model of `nodes` nodes, `tets` tetrahedra, `triangles`
    /// boundary triangles (all at capacity), `segments` polyline segments, `features` and
    /// `targets`: every node tested against every segment; three splits (the surface, then the
    /// planes of up to two ends), each visiting every tetrahedron to select, to split, and once
    /// per quality pass (at most one pass per node, each declaring one node on the level set);
    /// all faces sorted; every node's star sorted, once to duplicate the nodes and in each
    /// pass of the edge check (the stars again, the edges at each node, the ring around each
    /// edge: 48 entries per tetrahedron a pass); every point re-embedded after each split, and
    /// every feature checked against every boundary triangle; outside the level set, every
    /// node, every feature and sixteen points per tetrahedron (ten crossings or nodes of its
    /// selection, two sides and a face centre for each of its faces) classified against every
    /// segment; `3 s + 6` rays to the model (one per segment and three in a depth extrusion,
    /// two per end), each over every boundary triangle, and the snapping's boundary stars:
    /// built in two passes over the boundary, each node's read at most once (every triangle
    /// three times in all).
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
            element_tests: 3 * tets * (4 + nodes),
            faces_sorted: 4 * tets,
            star_entries: 12 * tets + 48 * tets * separate::MANIFOLD_PASSES as u64,
            embed_tests: 3 * (features + targets) * split::MAX_CHILDREN as u64
                + features * triangles,
            segment_tests: segments * (nodes + 16 * tets + features),
            triangle_tests: (3 * segments + 11) * triangles,
        }
    }

    /// Whether every count is at most `bound`'s.
    pub fn within(&self, bound: &CutWork) -> bool {
        self.node_tests <= bound.node_tests
            && self.element_tests <= bound.element_tests
            && self.faces_sorted <= bound.faces_sorted
            && self.star_entries <= bound.star_entries
            && self.embed_tests <= bound.embed_tests
            && self.segment_tests <= bound.segment_tests
            && self.triangle_tests <= bound.triangle_tests
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
    /// Tetrahedra split (along the surface, and where the cut ends inside the object).
    pub tets_split: usize,
    /// Of those, the ones split by the plane an end inside the object ends on.
    pub tets_split_at_ends: usize,
    /// Ends of the cut inside the object (where it stops, on a plane across the line).
    pub ends_inside: usize,
    /// Tetrahedra added by the splits.
    pub tets_added: usize,
    /// Nodes added on crossed edges.
    pub edge_nodes: usize,
    /// Faces separated.
    pub faces_cut: usize,
    /// Faces on the surface left joined because separating them would have left the two
    /// sides touching along an edge only (a non-manifold boundary).
    pub faces_kept_joined: usize,
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
