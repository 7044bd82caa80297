//! Capacities at and far beyond what the core can hold (issue 13): every storage size is a
//! function of the caller's capacities, so none may overflow, whatever they are.
//!
//! - Every public `*_len` function equals its formula computed in `u128`, saturated at
//!   `usize::MAX` (a saturated length is one no slice can have, so the length check after it
//!   refuses it).
//! - [`ModelSize::new`] either refuses with [`Error::TooLarge`] naming a count beyond the `u32`
//!   indices or a storage length beyond [`MAX_STORAGE_LEN`], or gives sizes that hold every
//!   part a model takes from them.
//! - Constructors handed a huge capacity and a small slab refuse with [`Error::Capacity`];
//!   the host's [`OwnedStorage::new`] refuses before it allocates.
//!
//! Capacities come from the values that break naive arithmetic (`usize::MAX`, `usize::MAX / 3`,
//! `usize::MAX / 54`, `u32::MAX + 1`, the `u32` index bound and one past it) and from random
//! values of every magnitude, each field alone and all of them together.

use incise::storage::OwnedStorage;
use incise_core::cut;
use incise_core::cutline::CutLine;
use incise_core::detect::{Detector, GRID_CELLS};
use incise_core::embed::Embedding;
use incise_core::features::Features;
use incise_core::mesh::{ELEMENT_REST_LEN, Mesh};
use incise_core::sparse::pattern::MAX_INDEX;
use incise_core::sparse::{
    Graph, LdlFactor, Symbolic, SymbolicSize, analyse_work_len, block_upper_len,
    block_upper_pattern, minimum_degree_work_len, tet_graph_work_len,
};
use incise_core::storage::Slab;
use incise_core::{
    Capacities, Error, MAX_STORAGE_LEN, MeshCapacity, ModelSize, Resource, analyse_mesh_work_len,
};
use proptest::prelude::*;

/// Values that break unguarded size arithmetic.
const HUGE: [usize; 12] = [
    usize::MAX,
    usize::MAX - 1,
    usize::MAX / 2,
    usize::MAX / 3,
    usize::MAX / 3 + 1,
    usize::MAX / 54,
    usize::MAX / 54 + 1,
    u32::MAX as usize + 1,
    MAX_INDEX,
    MAX_INDEX + 1,
    MAX_INDEX / 3,
    MAX_INDEX / 3 + 1,
];

/// `x` saturated to `usize`.
fn sat(x: u128) -> usize {
    usize::try_from(x).unwrap_or(usize::MAX)
}

fn w(x: usize) -> u128 {
    x as u128
}

fn small_caps() -> Capacities {
    Capacities {
        mesh: MeshCapacity {
            nodes: 100,
            tets: 300,
            surface_triangles: 1200,
        },
        features: 16,
        targets: 4,
        factor_entries: 4096,
        pairs: 256,
        cut_vertices: 16,
    }
}

/// The capacities with field `k` (0..8) set to `v`.
fn with_field(mut c: Capacities, k: usize, v: usize) -> Capacities {
    match k {
        0 => c.mesh.nodes = v,
        1 => c.mesh.tets = v,
        2 => c.mesh.surface_triangles = v,
        3 => c.features = v,
        4 => c.targets = v,
        5 => c.factor_entries = v,
        6 => c.pairs = v,
        _ => c.cut_vertices = v,
    }
    c
}

/// Every public length of the parts a model is made of equals its formula, saturated.
fn check_part_lengths(c: &Capacities) {
    let (n, t, s) = (c.mesh.nodes, c.mesh.tets, c.mesh.surface_triangles);
    let (f, p, v) = (c.features, c.pairs, c.cut_vertices);
    assert_eq!(
        c.mesh.real_len(),
        sat(3 * w(n) + w(ELEMENT_REST_LEN) * w(t))
    );
    assert_eq!(c.mesh.index_len(), sat(4 * w(t) + w(n) + 4 * w(s)));
    assert_eq!(c.mesh.work_len(), sat((16 * w(t)).max(6 * w(s))));
    assert_eq!(Features::<f64>::real_len(f), sat(2 * w(f)));
    assert_eq!(Features::<f64>::index_len(f), sat(4 * w(f)));
    assert_eq!(Embedding::<f64>::real_len(c.targets), sat(4 * w(c.targets)));
    assert_eq!(Embedding::<f64>::index_len(c.targets), c.targets);
    assert_eq!(
        Detector::<f64>::real_len(f, p),
        sat(5 * w(f) + 4 * w(p) + w(f.max(p)))
    );
    assert_eq!(
        Detector::<f64>::index_len(f, p),
        sat(8 * w(p) + 4 * w(f) + w(GRID_CELLS) + 1 + w(f.max(p)))
    );
    // Six anchors (nodes and weights) per vertex.
    assert_eq!(CutLine::<f64>::real_len(v), sat(6 * w(v)));
    assert_eq!(CutLine::<f64>::index_len(v), sat(6 * w(v)));
    // The face sort's room holds the snapping's boundary stars' starts and stamps first.
    assert_eq!(
        cut::work_len(n, t),
        sat(2 * w(n) + 1 + 27 * w(t) + (16 * w(t)).max(2 * w(n) + 4) + 8)
    );
    assert!(cut::real_len(n, v) >= sat(3 * w(n)));
    assert_eq!(tet_graph_work_len(n, t), sat(2 * w(n) + 1 + 4 * w(t)));
    assert_eq!(minimum_degree_work_len(n, t), sat(w(t) + 15 * w(n) + 1));
    assert_eq!(analyse_work_len(n, t), sat(2 * w(t) + 5 * w(n) + 1));
    assert_eq!(
        LdlFactor::<f64>::supernodal_index_work_len(n),
        sat(5 * w(n))
    );
    let sym = SymbolicSize {
        n,
        nnz_a: t,
        nnz_l: c.factor_entries,
    };
    assert_eq!(
        sym.index_len(),
        sat(8 * w(n) + 4 + 3 * w(t) + 2 * w(c.factor_entries))
    );
    assert_eq!(
        LdlFactor::<f64>::storage_len(&sym),
        sat(2 * (w(c.factor_entries) + w(n)))
    );
    // The workspace of `analyse_mesh` holds at least the pattern and the graph.
    assert!(analyse_mesh_work_len(n, t) >= sat(w(n) + 3 * w(n) + 1 + 6 * w(n) + 54 * w(t)));
}

/// `ModelSize::new` refuses or gives sizes that hold every part of a model.
fn check_model_size(c: &Capacities) {
    let counts = [
        (Resource::Nodes, c.mesh.nodes),
        (Resource::Tetrahedra, c.mesh.tets),
        (Resource::SurfaceTriangles, c.mesh.surface_triangles),
        (Resource::Features, c.features),
        (Resource::Targets, c.targets),
        (Resource::FactorEntries, c.factor_entries),
        (Resource::Pairs, c.pairs),
        (Resource::CutVertices, c.cut_vertices),
    ];
    let unknowns = 3 * w(c.mesh.nodes);
    let nnz_a = 6 * w(c.mesh.nodes) + 54 * w(c.mesh.tets);
    let fits = counts.iter().all(|&(_, x)| x <= MAX_INDEX)
        && unknowns <= w(MAX_INDEX)
        && nnz_a <= w(MAX_INDEX);
    match ModelSize::new(c) {
        Err(Error::TooLarge {
            resource,
            requested,
            limit,
        }) => {
            assert!(requested > limit, "{resource:?}: {requested} <= {limit}");
            match resource {
                Resource::RealStorage | Resource::IndexStorage => {
                    assert!(fits, "a count beyond the indices was not named first");
                    assert_eq!(limit, MAX_STORAGE_LEN);
                }
                Resource::Unknowns => {
                    assert_eq!((limit, requested), (MAX_INDEX, sat(unknowns)));
                }
                Resource::MatrixEntries => {
                    assert_eq!((limit, requested), (MAX_INDEX, sat(nnz_a)));
                }
                _ => {
                    assert_eq!(limit, MAX_INDEX);
                    assert!(counts.contains(&(resource, requested)), "{resource:?}");
                }
            }
        }
        Err(e) => panic!("unexpected error {e:?}"),
        Ok(size) => {
            assert!(fits, "counts beyond the u32 indices were accepted: {c:?}");
            assert_eq!(size.capacities(), c);
            assert_eq!(w(size.unknowns()), unknowns);
            assert_eq!(w(size.nnz_a()), nnz_a);
            let (real, index) = (w(size.real_len()), w(size.index_len()));
            assert!(real <= w(MAX_STORAGE_LEN) && index <= w(MAX_STORAGE_LEN));
            assert_eq!(w(size.bytes::<f64>()), 8 * real + 4 * index);
            // Disjoint parts a model takes from the scalar and the index storage.
            let (n, f) = (w(c.mesh.nodes), c.features);
            let sym = size.symbolic_capacity();
            let reals = 2 * (w(c.mesh.real_len()) + 8 * n)
                + w(size.nnz_a())
                + w(LdlFactor::<f64>::storage_len(&sym))
                + 7 * w(size.unknowns())
                + 3 * n
                + 2 * w(Features::<f64>::real_len(f))
                + w(Embedding::<f64>::real_len(f))
                + w(Detector::<f64>::real_len(f, c.pairs))
                + w(CutLine::<f64>::real_len(c.cut_vertices))
                + w(cut::real_len(c.mesh.nodes, c.cut_vertices));
            assert!(real >= reals, "{real} < {reals}");
            let indices = 2 * (w(c.mesh.index_len()) + w(sym.index_len()) + nnz_a + unknowns)
                + 2 * w(Features::<f64>::index_len(f))
                + w(Detector::<f64>::index_len(f, c.pairs))
                + w(size.work_len());
            assert!(index >= indices, "{index} < {indices}");
            assert!(w(size.work_len()) >= w(c.mesh.work_len()));
            assert!(w(size.work_len()) >= w(cut::work_len(c.mesh.nodes, c.mesh.tets)));
        }
    }
}

#[test]
fn each_capacity_alone_at_huge_values() {
    for k in 0..8 {
        for &v in &HUGE {
            let c = with_field(small_caps(), k, v);
            check_part_lengths(&c);
            check_model_size(&c);
        }
    }
}

#[test]
fn all_capacities_at_huge_values() {
    for &v in &HUGE {
        let mut c = small_caps();
        for k in 0..8 {
            c = with_field(c, k, v);
        }
        check_part_lengths(&c);
        check_model_size(&c);
        assert!(matches!(ModelSize::new(&c), Err(Error::TooLarge { .. })));
    }
}

#[test]
fn counts_beyond_the_u32_indices_are_refused_by_name() {
    let refused = |c: &Capacities| match ModelSize::new(c) {
        Err(Error::TooLarge { resource, .. }) => resource,
        other => panic!("{other:?}"),
    };
    for (k, resource) in [
        (0, Resource::Nodes),
        (1, Resource::Tetrahedra),
        (2, Resource::SurfaceTriangles),
        (3, Resource::Features),
        (4, Resource::Targets),
        (5, Resource::FactorEntries),
        (6, Resource::Pairs),
        (7, Resource::CutVertices),
    ] {
        let c = with_field(small_caps(), k, u32::MAX as usize + 1);
        assert_eq!(refused(&c), resource);
    }
    // Within the indices alone, but not what follows from them.
    let c = with_field(small_caps(), 0, MAX_INDEX / 3 + 1);
    assert_eq!(refused(&c), Resource::Unknowns);
    let c = with_field(small_caps(), 1, MAX_INDEX / 54 + 1);
    assert_eq!(refused(&c), Resource::MatrixEntries);
    // The host refuses before it allocates.
    assert!(matches!(
        OwnedStorage::<f64>::new(&with_field(small_caps(), 3, usize::MAX)),
        Err(Error::TooLarge {
            resource: Resource::Features,
            ..
        })
    ));
}

#[test]
fn constructors_refuse_huge_capacities_in_small_storage() {
    let mut reals = [0.0f64; 64];
    let mut indices = [0u32; 64];
    for &v in &HUGE {
        let mut rs = Slab::new(&mut reals, Resource::RealStorage);
        let mut is = Slab::new(&mut indices, Resource::IndexStorage);
        let capacity = |r| matches!(r, Err(Error::Capacity { .. }));
        assert!(capacity(
            Features::<f64>::new(v, &mut rs, &mut is).map(|_| ())
        ));
        assert!(capacity(
            Embedding::<f64>::with_capacity(v, &mut rs, &mut is).map(|_| ())
        ));
        assert!(capacity(
            Detector::<f64>::new(v, 1, &mut rs, &mut is).map(|_| ())
        ));
        assert!(capacity(
            Detector::<f64>::new(1, v, &mut rs, &mut is).map(|_| ())
        ));
        assert!(capacity(
            CutLine::<f64>::new(v, &mut rs, &mut is).map(|_| ())
        ));
        for k in 0..3 {
            let mut mesh = MeshCapacity {
                nodes: 1,
                tets: 1,
                surface_triangles: 1,
            };
            *[&mut mesh.nodes, &mut mesh.tets, &mut mesh.surface_triangles][k] = v;
            assert!(capacity(
                Mesh::<f64>::with_capacity(&mesh, &mut rs, &mut is).map(|_| ())
            ));
        }
        let sym = SymbolicSize {
            n: v,
            nnz_a: v,
            nnz_l: v,
        };
        assert!(capacity(LdlFactor::new(&sym, &mut reals).map(|_| ())));
        assert!(capacity(
            Symbolic::with_capacity(sym, &mut indices).map(|_| ())
        ));
    }
    // A block size that overflows the pattern's size is refused as too large for `u32`.
    let graph = Graph::new(2, &[0, 1, 2], &[1, 0]).unwrap();
    let (mut col_ptr, mut row_idx) = ([0u32; 8], [0u32; 8]);
    for &b in &HUGE {
        assert!(block_upper_len(&graph, b) > MAX_INDEX);
        assert!(matches!(
            block_upper_pattern(&graph, b, &mut col_ptr, &mut row_idx),
            Err(Error::Pattern { .. })
        ));
    }
    assert_eq!(block_upper_len(&graph, 3), 2 * 6 + 9);
}

fn capacity_value() -> impl Strategy<Value = usize> {
    prop_oneof![
        0..10_000usize,
        0..=MAX_INDEX,
        any::<usize>(),
        proptest::sample::select(HUGE.to_vec()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20_000, ..ProptestConfig::default() })]

    #[test]
    fn any_capacities_give_a_typed_refusal_or_consistent_sizes(
        fields in proptest::collection::vec(capacity_value(), 8),
    ) {
        let mut c = small_caps();
        for (k, &v) in fields.iter().enumerate() {
            c = with_field(c, k, v);
        }
        check_part_lengths(&c);
        check_model_size(&c);
    }
}
