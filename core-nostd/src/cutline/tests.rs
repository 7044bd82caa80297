//! Unit tests of the cut line on synthetic separation points.

use super::grow::{anchor_across, anchor_at, carried_by_one};
use super::*;

#[test]
fn an_anchored_point_follows_its_features_affinely() {
    let features = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [50.0, 50.0]];
    let usable = [1, 1, 1, 1];
    let (anchor, w) = anchor_at([2.0, 3.0], &features, &usable).unwrap();
    let place = |f: &[[f64; 2]]| -> [f64; 2] {
        let mut p = [0.0; 2];
        for k in 0..3 {
            p[0] += w[k] * f[anchor[k] as usize][0];
            p[1] += w[k] * f[anchor[k] as usize][1];
        }
        p
    };
    let here = place(&features);
    assert!((here[0] - 2.0).abs() < 1e-12 && (here[1] - 3.0).abs() < 1e-12);
    // Stretch the features by 2 along x and shift them: the point moves the same way.
    let moved = features.map(|f| [2.0 * f[0] + 5.0, f[1] - 1.0]);
    let there = place(&moved);
    assert!((there[0] - 9.0).abs() < 1e-12 && (there[1] - 2.0).abs() < 1e-12);
    // Unusable or collinear features cannot anchor.
    assert!(anchor_at([1.0, 1.0], &features, &[1, 1, 0, 0]).is_none());
    let line = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
    assert!(anchor_at([1.0, 1.0], &line, &[1, 1, 1]).is_none());
}

/// Features on an 11 × 11 grid, 10 px apart.
fn grid() -> [[f64; 2]; 121] {
    core::array::from_fn(|k| [10.0 * (k % 11) as f64, 10.0 * (k / 11) as f64])
}

/// Pairs across the grid's column x = 50, one per row (slots `(4, r)` and `(6, r)`), then
/// two on the left of it (rows 0 and 1, slots `(0, r)` and `(1, r)`); all split.
const ACROSS: [[u32; 2]; 13] = {
    let mut p = [[0u32; 2]; 13];
    let mut r = 0;
    while r < 11 {
        p[r] = [11 * r as u32 + 4, 11 * r as u32 + 6];
        r += 1;
    }
    p[11] = [0, 1];
    p[12] = [11, 12];
    p
};

/// Point `k`'s pair is pair `k`.
const OWN_PAIR: [u32; 13] = {
    let mut k = [0u32; 13];
    let mut i = 0;
    while i < 13 {
        k[i] = i as u32;
        i += 1;
    }
    k
};

/// Residuals of the grid's features when the lips either side of x = 50 part along `dir`:
/// those left of it by `-dir`, those right of it by `dir`.
fn parting(dir: [f64; 2]) -> [[f64; 2]; 121] {
    core::array::from_fn(|k| if k % 11 <= 5 { [-dir[0], -dir[1]] } else { dir })
}

#[test]
fn the_line_starts_on_collinear_points_and_grows_toward_new_ones() {
    // Features on a grid; separation points along x = 50 from y = 20 to 60, then more up
    // to y = 100.
    let features = grid();
    let usable = [1u32; 121];
    let config = DetectionConfig::<f64>::paper();
    let mut reals = [0.0; 128];
    let mut indices = [0u32; 128];
    let mut rs = Slab::new(&mut reals, crate::error::Resource::RealStorage);
    let mut is = Slab::new(&mut indices, crate::error::Resource::IndexStorage);
    let mut line = CutLine::new(16, &mut rs, &mut is).unwrap();
    let mut scratch = [[0.0; 2]; 16];
    let mut points = [[0.0; 2]; 20];
    for k in 0..9 {
        points[k] = [50.0, 20.0 + 5.0 * k as f64];
    }
    // A blob away from the line must not tilt it.
    points[9] = [80.0, 80.0];
    points[10] = [82.0, 81.0];
    let r = line.update(
        3,
        &points[..11],
        &[4; 11],
        &OWN_PAIR[..11],
        SplitPairs::for_test(&ACROSS),
        &features,
        &parting([3.0, 0.0]),
        &usable,
        &config,
        25.0,
        &mut scratch,
    );
    assert_eq!((r.detected_frame, r.vertices, r.added), (Some(3), 2, 2));
    let m = line.project(&features, &mut scratch);
    assert_eq!(m, 2);
    for p in &scratch[..2] {
        assert!((p[0] - 50.0).abs() < 1e-9, "{p:?}");
    }
    // More points further along +y: the end front advances, by at most the maximum step.
    for k in 0..8 {
        points[k] = [50.0, 65.0 + 5.0 * k as f64];
    }
    let before = line.project(&features, &mut scratch);
    let far_end = scratch[..before].iter().map(|p| p[1]).fold(0.0, f64::max);
    let r = line.update(
        4,
        &points[..8],
        &[4; 8],
        &OWN_PAIR[..8],
        SplitPairs::for_test(&ACROSS),
        &features,
        &parting([3.0, 0.0]),
        &usable,
        &config,
        25.0,
        &mut scratch,
    );
    assert_eq!(r.added, 1);
    let m = line.project(&features, &mut scratch);
    let new_end = scratch[..m].iter().map(|p| p[1]).fold(0.0, f64::max);
    assert!(new_end > far_end && new_end <= far_end + config.max_step * 25.0 + 1e-9);
}

#[test]
fn a_full_line_reports_its_cap_instead_of_growing() {
    let features = grid();
    let usable = [1u32; 121];
    let config = DetectionConfig::<f64>::paper();
    let (mut reals, mut indices) = ([0.0; 12], [0u32; 12]);
    let mut rs = Slab::new(&mut reals, crate::error::Resource::RealStorage);
    let mut is = Slab::new(&mut indices, crate::error::Resource::IndexStorage);
    // Room for two vertices only: the start.
    let mut line = CutLine::new(2, &mut rs, &mut is).unwrap();
    let mut scratch = [[0.0; 2]; 2];
    let mut points = [[0.0; 2]; 8];
    for k in 0..8 {
        points[k] = [50.0, 20.0 + 5.0 * k as f64];
    }
    let r = line.update(
        1,
        &points,
        &[1; 8],
        &OWN_PAIR[..8],
        SplitPairs::for_test(&ACROSS),
        &features,
        &parting([3.0, 0.0]),
        &usable,
        &config,
        25.0,
        &mut scratch,
    );
    assert_eq!((r.vertices, r.capped), (2, false));
    for k in 0..8 {
        points[k] = [50.0, 60.0 + 5.0 * k as f64];
    }
    let r = line.update(
        2,
        &points,
        &[2; 8],
        &OWN_PAIR[..8],
        SplitPairs::for_test(&ACROSS),
        &features,
        &parting([3.0, 0.0]),
        &usable,
        &config,
        25.0,
        &mut scratch,
    );
    assert_eq!((r.vertices, r.added, r.capped), (2, 0, true));
}

/// The grid with the cut between x = 50 and x = 60 opened: the left lip moved 30 px left, the
/// right one 30 px right.
fn opened_grid() -> [[f64; 2]; 121] {
    grid().map(|f| {
        [
            if f[0] <= 50.0 {
                f[0] - 30.0
            } else {
                f[0] + 30.0
            },
            f[1],
        ]
    })
}

/// The pixel of a vertex anchored by `anchor_across`, with the features at `f`.
fn placed(anchor: &([u32; ANCHORS], [f64; ANCHORS]), f: &[[f64; 2]]) -> [f64; 2] {
    let mut p = [0.0; 2];
    for (slot, w) in anchor.0.iter().zip(anchor.1) {
        p[0] += w * f[*slot as usize][0];
        p[1] += w * f[*slot as usize][1];
    }
    p
}

#[test]
fn a_vertex_off_the_cut_is_held_by_both_lips_the_split_pairs_name() {
    // The grid cut between x = 50 and x = 60; the line runs along x = 44, a little to the
    // left of it, as a line fitted on few points can.
    let features = grid();
    let usable = [1u32; 121];
    let p = [44.0, 50.0];
    let up = [0.0, 1.0];
    // The pairs across the cut, (5, y) to (6, y) in grid steps, all split.
    let pairs: [[u32; 2]; 11] = core::array::from_fn(|r| [11 * r as u32 + 5, 11 * r as u32 + 6]);
    let split = SplitPairs::for_test(&pairs);
    let opened = opened_grid();
    let tracked = Tracked {
        features: &features,
        residuals: &parting([30.0, 0.0]),
        usable: &usable,
        split,
    };
    let on_lips = anchor_across(p, up, &tracked, 25.0).unwrap();
    assert!((placed(&on_lips, &features)[0] - 44.0).abs() < 1e-9);
    // Between the lips, it stays where it was: each half moved with its own lip.
    let x = placed(&on_lips, &opened)[0];
    assert!((x - 44.0).abs() < 1e-9, "{x}");
    // Split by the side of the line alone, the features at x = 50 count for the right lip:
    // both halves then follow the left lip, and the vertex leaves with it.
    let by_side_only = Tracked {
        split: SplitPairs::default(),
        ..tracked
    };
    let by_side = anchor_across(p, up, &by_side_only, 25.0).unwrap();
    let x = placed(&by_side, &opened)[0];
    assert!(x < 44.0 - 10.0, "{x}");
}

#[test]
fn features_outside_the_pairs_take_the_lip_they_move_with_or_the_pairs_place_them_on() {
    // The grid cut between x = 50 and x = 60. The line's end lies at (56, 50), tilted 40°
    // across the cut, and the only split pairs near it are a fan from one left feature,
    // (50, 50), to three on the right: no triangle on the left lip among the pairs' features,
    // so every other feature needs a lip. By the side of the tilted line, (60, 60) and
    // (60, 70) would count for the left lip and (50, 40) for the right.
    let features = grid();
    let usable = [1u32; 121];
    let p = [56.0, 50.0];
    let (s, c) = (40f64.to_radians().sin(), 40f64.to_radians().cos());
    let tangent = [s, c];
    let fan: [[u32; 2]; 3] = [[60, 50], [60, 61], [60, 72]];
    let opened = opened_grid();
    let held = |residuals: &[[f64; 2]; 121]| {
        let tracked = Tracked {
            features: &features,
            residuals,
            usable: &usable,
            split: SplitPairs::for_test(&fan),
        };
        let anchor = anchor_across(p, tangent, &tracked, 25.0).unwrap();
        assert!((placed(&anchor, &features)[0] - p[0]).abs() < 1e-9);
        placed(&anchor, &opened)[0]
    };
    // The lips move apart: every feature moves as one of the pairs' lips does, and each
    // half of the vertex goes with its own lip.
    let x = held(&parting([30.0, 0.0]));
    assert!((x - p[0]).abs() < 1e-9, "{x}");
    // No motion tells the lips apart: the side of the cut the pairs place (their midpoints'
    // mean x = 55, their directions across it) decides, with the same result here.
    let x = held(&[[0.0; 2]; 121]);
    assert!((x - p[0]).abs() < 1e-9, "{x}");
    // Without any split pair near, the side of the line decides: each half holds features of
    // both lips, and the vertex moves with the opening (3 px of the 60 the lips part here,
    // frame after frame on a cut that goes on opening).
    let tracked = Tracked {
        features: &features,
        residuals: &parting([30.0, 0.0]),
        usable: &usable,
        split: SplitPairs::default(),
    };
    let by_line = anchor_across(p, tangent, &tracked, 25.0).unwrap();
    let x = placed(&by_line, &opened)[0];
    assert!((x - p[0]).abs() > 2.0, "{x}");
}

/// Pairs between feature 60 (the grid's (5, 5), on the left lip) and the right lip's column,
/// then pairs across the cut that leave it out.
const FAN: [[u32; 2]; 11] = [
    [60, 6],
    [60, 17],
    [60, 28],
    [60, 39],
    [60, 50],
    [60, 72],
    [60, 83],
    [60, 94],
    [60, 105],
    [81, 83],
    [92, 94],
];

/// The vertices a fresh line adds when it meets separation points along x = 50, point `k`
/// on pair `pairs[k]` of `table`, with the features' residuals `residuals`.
fn start_on(table: &[[u32; 2]], pairs: &[u32], residuals: &[[f64; 2]; 121]) -> usize {
    let features = grid();
    let usable = [1u32; 121];
    let config = DetectionConfig::<f64>::paper();
    let (mut reals, mut indices) = ([0.0; 128], [0u32; 128]);
    let mut rs = Slab::new(&mut reals, crate::error::Resource::RealStorage);
    let mut is = Slab::new(&mut indices, crate::error::Resource::IndexStorage);
    let mut line = CutLine::new(16, &mut rs, &mut is).unwrap();
    let mut scratch = [[0.0; 2]; 16];
    let points: [[f64; 2]; 13] = core::array::from_fn(|k| [50.0, 20.0 + 5.0 * k as f64]);
    line.update(
        1,
        &points[..pairs.len()],
        &[1; 13][..pairs.len()],
        pairs,
        SplitPairs::for_test(table),
        &features,
        residuals,
        &usable,
        &config,
        25.0,
        &mut scratch,
    )
    .added
}

#[test]
fn a_line_starts_only_along_points_whose_pairs_open_across_it() {
    let pairs = &OWN_PAIR[..9];
    assert_eq!(start_on(&ACROSS, pairs, &parting([3.0, 0.0])), 2);
    // 45° off the line's normal is still across it (within 60°).
    assert_eq!(start_on(&ACROSS, pairs, &parting([3.0, -3.0])), 2);
    // The same points, the lips sliding along the line, as beside a cut's tip: no line.
    assert_eq!(start_on(&ACROSS, pairs, &parting([0.0, 3.0])), 0);
    assert_eq!(start_on(&ACROSS, pairs, &parting([1.0, 3.0])), 0);
    // Lips that do not part at all: no line either.
    assert_eq!(start_on(&ACROSS, pairs, &parting([0.0, 0.0])), 0);
}

#[test]
fn a_line_one_feature_carries_does_not_start() {
    let residuals = parting([3.0, 0.0]);
    // Nine points, all on pairs of feature 60: its track alone would make the cut.
    assert_eq!(start_on(&FAN, &OWN_PAIR[..9], &residuals), 0);
    // Eight of them and one pair without it: still one feature's line.
    let one_other = [0, 1, 2, 3, 4, 5, 6, 7, 9];
    assert_eq!(start_on(&FAN, &one_other, &residuals), 0);
    // Seven and two pairs without it: two points fix a line without feature 60.
    let two_others = [0, 1, 2, 3, 4, 5, 6, 9, 10];
    assert_eq!(start_on(&FAN, &two_others, &residuals), 2);
}

#[test]
fn one_carrying_feature_is_found_as_counting_every_feature_finds_it() {
    // Deterministic pseudo-random pairs of distinct features among 0..6, against the
    // oracle that counts each feature's pairs.
    let mut seed = 12345u64;
    let mut next = |m: u64| {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 33) % m
    };
    for _ in 0..2000 {
        let n = 1 + next(12) as usize;
        let mut pairs = [[0u32; 2]; 12];
        for p in pairs.iter_mut().take(n) {
            let a = next(6) as u32;
            let b = (a + 1 + next(5) as u32) % 6;
            *p = [a, b];
        }
        let pairs = &pairs[..n];
        let oracle = (0..6).any(|f| pairs.iter().filter(|p| p.contains(&f)).count() + 1 >= n);
        assert_eq!(carried_by_one(pairs), oracle, "{pairs:?}");
    }
}
