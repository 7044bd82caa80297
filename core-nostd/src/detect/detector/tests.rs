//! Unit tests of the detector on synthetic grids of features.

use super::*;

/// Features on a grid, `n × n`, `spacing` pixels apart.
fn grid(n: usize, spacing: f64) -> [[f64; 2]; 400] {
    let mut uv = [[0.0; 2]; 400];
    for k in 0..n * n {
        uv[k] = [spacing * (k % n) as f64, spacing * (k / n) as f64];
    }
    uv
}

struct Store {
    reals: [f64; 16384],
    indices: [u32; 32768],
}

fn store() -> Store {
    Store {
        reals: [0.0; 16384],
        indices: [0; 32768],
    }
}

fn detector(s: &mut Store, features: usize, pairs: usize) -> Detector<'_, f64> {
    let mut rs = Slab::new(&mut s.reals, Resource::RealStorage);
    let mut is = Slab::new(&mut s.indices, Resource::IndexStorage);
    Detector::new(features, pairs, &mut rs, &mut is).unwrap()
}

fn config() -> DetectionConfig<f64> {
    DetectionConfig {
        radius_px: 15.0,
        ..DetectionConfig::paper()
    }
}

#[test]
fn grid_pairs_are_the_close_ones() {
    let mut s = store();
    let mut det = detector(&mut s, 400, 2000);
    let uv = grid(20, 10.0);
    det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
    // Within 15 px of a grid point 10 px apart: 4 axis and 4 diagonal neighbours (14.1 px):
    // 2·19·20 axis pairs and 2·19·19 diagonal ones.
    assert_eq!(det.pairs().len(), 2 * 19 * 20 + 2 * 19 * 19);
    assert!(det.pairs().iter().all(|&[i, j]| i < j));
}

#[test]
fn features_apart_on_the_object_are_not_paired() {
    let mut s = store();
    let mut det = detector(&mut s, 400, 2000);
    let uv = grid(20, 10.0);
    // A fold along the middle: the two halves of the grid touch in the image only.
    let half = |k: usize| uv[k][0] < 95.0;
    det.init_on_surface(&uv, &[[0.0; 2]; 400], &config(), |i, j, l| {
        assert!(l > 0.0 && l < 15.0);
        half(i) != half(j)
    })
    .unwrap();
    // Each half (10 columns × 20 rows) pairs as a grid of its own.
    let per_half = (9 * 20 + 10 * 19) + 2 * 9 * 19;
    assert_eq!(det.pairs().len(), 2 * per_half);
    assert!(
        det.pairs()
            .iter()
            .all(|&[i, j]| half(i as usize) == half(j as usize))
    );
}

#[test]
fn a_surface_ratio_below_one_is_refused() {
    for (ratio, ok) in [
        (0.0, true),
        (1.0, true),
        (3.0, true),
        (0.5, false),
        (f64::NAN, false),
    ] {
        let c = DetectionConfig {
            max_surface_ratio: ratio,
            ..config()
        };
        assert_eq!(c.validate().is_ok(), ok, "ratio {ratio}");
    }
}

#[test]
fn rigid_motion_gives_no_outlier() {
    let mut s = store();
    let mut det = detector(&mut s, 400, 2000);
    let uv = grid(20, 10.0);
    det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
    // Every residual the same (the model lags a rigid shift by the same amount everywhere).
    let d = [[3.0, -2.0]; 400];
    for _ in 0..5 {
        let r = det.update(0, &d, &[1; 400], &uv, &config());
        assert_eq!(r.outliers, 0);
        assert_eq!(r.split, 0);
    }
}

#[test]
fn a_clean_jump_across_a_line_gives_separation_points_on_it() {
    let mut s = store();
    let mut det = detector(&mut s, 400, 2000);
    let uv = grid(20, 10.0);
    det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
    // Residuals jump across the vertical line x = 95 (between columns 9 and 10), with a
    // small smooth variation elsewhere.
    let mut d = [[0.0; 2]; 400];
    for k in 0..400 {
        let x = uv[k][0];
        d[k] = if x > 95.0 { [6.0, 0.0] } else { [-6.0, 0.0] };
        d[k][1] = 0.01 * uv[k][1];
    }
    let mut last = DetectionReport::default();
    for frame in 0..3 {
        // Reach the final residuals in one step then hold: the temporal filter sees the
        // same change everywhere, so nothing is filtered.
        let dd = if frame == 0 { [[0.0; 2]; 400] } else { d };
        last = det.update(0, &dd, &[1; 400], &uv, &config());
    }
    assert_eq!(last.features_filtered, 0);
    assert!(last.split > 0);
    for p in det.points() {
        assert!((p[0] - 95.0).abs() <= 5.0 + 1e-12, "{p:?}");
    }
}

/// The measures a caller reads back give the outlier flags again, by the rule written out:
/// every measured pair, a frame with a jump across a line and a smooth stretch.
#[test]
fn the_pair_measures_give_the_outliers_by_the_rule() {
    let mut s = store();
    let mut det = detector(&mut s, 400, 2000);
    let uv = grid(20, 10.0);
    let config = DetectionConfig {
        opening_only: false,
        ..config()
    };
    det.init(&uv, &[[0.0; 2]; 400], &config).unwrap();
    let mut d = [[0.0; 2]; 400];
    for k in 0..400 {
        let x = uv[k][0];
        d[k] = [
            if x > 95.0 { 6.0 } else { -6.0 } + 0.02 * x,
            0.03 * uv[k][1],
        ];
    }
    // One feature unobserved: its pairs are not measured.
    let mut observed = [1; 400];
    observed[37] = 0;
    let r = det.update(1, &d, &observed, &uv, &config);
    let margin = (config.outlier_sigmas * r.deviation_px).max(config.min_difference_px);
    let (mut measured, mut outliers) = (0, 0);
    for (k, &[i, j]) in det.pairs().iter().enumerate() {
        let Some(m) = det.pair_measure(k) else {
            assert!(i == 37 || j == 37, "pair {k} unmeasured");
            continue;
        };
        measured += 1;
        let (a, b) = (uv[i as usize], uv[j as usize]);
        assert!((m.length - ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()).abs() < 1e-12);
        let mu = ((d[i as usize][0] - d[j as usize][0]).powi(2)
            + (d[i as usize][1] - d[j as usize][1]).powi(2))
        .sqrt();
        assert!((m.difference - mu).abs() < 1e-12);
        let out = m.difference > r.median_difference_px.max(m.smooth) + margin;
        assert_eq!(det.is_outlier(k), out, "pair {k}: {m:?}");
        outliers += usize::from(out);
    }
    assert_eq!(measured, r.pairs_active);
    assert_eq!(outliers, r.outliers);
    assert!(outliers > 0);
    assert_eq!(det.pair_measure(det.pairs().len()), None);
}

#[test]
#[cfg(feature = "temporal-filter")]
fn a_single_jumping_feature_is_filtered_and_cuts_nothing() {
    let mut s = store();
    let mut det = detector(&mut s, 400, 2000);
    let uv = grid(20, 10.0);
    det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
    let mut d = [[0.0; 2]; 400];
    // Noise-like residuals, then feature 210 jumps by 20 px for three frames.
    for frame in 0..8 {
        for k in 0..400 {
            // Uniform noise in ±0.5 px from a multiplicative hash.
            let h = |salt: u64| {
                let x =
                    ((k as u64 * 40_503 + frame as u64 * 9_973 + salt) * 2_654_435_761) % 1_000_003;
                x as f64 / 1_000_003.0 - 0.5
            };
            d[k] = [h(1), h(7)];
        }
        if (2..5).contains(&frame) {
            d[210][0] += 20.0;
        }
        let r = det.update(0, &d, &[1; 400], &uv, &config());
        assert_eq!(r.split, 0, "frame {frame}");
    }
    let r = det.update(0, &d, &[1; 400], &uv, &config());
    assert_eq!(r.features_filtered, 1);
    // It is feature 210, and no other slot (nor one past the detector's) reads as filtered.
    assert!(det.is_filtered(210));
    assert_eq!((0..401).filter(|&k| det.is_filtered(k)).count(), 1);
    // Feature 210 had 8 neighbours within 15 px.
    assert_eq!(r.pairs_lost, 8);
}

/// Frame `frame`'s residuals of a cut opening under the camera on grid `uv`: half a pixel of
/// noise everywhere, and from frame 2 on the right half (x > 95 px) 12 px to the right, all
/// together, as a lip does when the scissor passes.
fn lip_residuals(uv: &[[f64; 2]; 400], frame: u32, d: &mut [[f64; 2]; 400]) {
    for (k, dk) in d.iter_mut().enumerate() {
        let h = |salt: u64| {
            let x =
                ((k as u64 * 40_503 + u64::from(frame) * 9_973 + salt) * 2_654_435_761) % 1_000_003;
            x as f64 / 1_000_003.0 - 0.5
        };
        *dk = [h(1), h(7)];
        if frame >= 2 && uv[k][0] > 95.0 {
            dk[0] += 12.0;
        }
    }
}

#[test]
#[cfg(feature = "temporal-filter")]
fn a_lip_that_jumps_together_is_kept_and_splits() {
    // A cut opening under the camera ([`lip_residuals`]). Each of its features has neighbours on its own lip that moved alike: none
    // is a tracking failure, and the pairs across the cut split.
    let mut s = store();
    let mut det = detector(&mut s, 400, 2000);
    let uv = grid(20, 10.0);
    det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
    let mut d = [[0.0; 2]; 400];
    let mut split = 0;
    for frame in 0..8 {
        lip_residuals(&uv, frame, &mut d);
        let r = det.update(frame, &d, &[1; 400], &uv, &config());
        assert_eq!(r.features_filtered, 0, "frame {frame}");
        split = r.split;
    }
    assert!(split > 0);
    // The separation points lie between the columns at x = 90 and x = 100.
    for p in det.points() {
        assert!((p[0] - 95.0).abs() <= 5.0, "{p:?}");
    }
}

#[test]
fn the_split_pairs_the_cut_line_reads_are_those_counted_as_split() {
    // The lip of [`lip_residuals`] jumps from frame 2 on; frames 6 and 7 observe nothing (split
    // pairs stay split unmeasured). After every frame the list the detector hands the cut line
    // is the pairs whose state says split, in the pairs' order; after a new start, none.
    let mut s = store();
    let mut det = detector(&mut s, 400, 2000);
    let uv = grid(20, 10.0);
    det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
    let mut d = [[0.0; 2]; 400];
    let mut listed = 0;
    for frame in 0..8 {
        lip_residuals(&uv, frame, &mut d);
        let observed = if frame < 6 { [1; 400] } else { [0; 400] };
        let r = det.update(frame, &d, &observed, &uv, &config());
        let split = det.split_pairs();
        let expected = det
            .pairs()
            .iter()
            .enumerate()
            .filter(|&(k, _)| det.is_split(k))
            .map(|(_, p)| *p);
        assert!(split.iter().eq(expected), "frame {frame}");
        assert_eq!(split.scanned(), split.iter().count());
        if frame >= 6 {
            // Nothing measured: no pair is split this frame, and those split before stay.
            assert_eq!(r.split, 0);
            assert_eq!(split.scanned(), listed, "frame {frame}");
        }
        listed = split.scanned();
    }
    assert!(listed > 0);
    det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap();
    assert_eq!(det.split_pairs().iter().count(), 0);
}

#[test]
fn too_many_pairs_is_a_capacity_error() {
    let mut s = store();
    let mut det = detector(&mut s, 400, 100);
    let uv = grid(20, 10.0);
    let err = det.init(&uv, &[[0.0; 2]; 400], &config()).unwrap_err();
    assert!(matches!(
        err,
        Error::Capacity {
            resource: Resource::Pairs,
            available: 100,
            ..
        }
    ));
    assert!(det.pairs().is_empty());
}

#[test]
fn each_features_tertile_is_its_measured_slopes_own() {
    // An 11 × 11 grid 10 px apart paired within 46 px: the nine middle features have 65 to
    // 68 pairs (what the selections once took apart from the others), the corners 21.
    // Residuals that differ from feature to feature, the last row unobserved (its pairs
    // unmeasured), and feature 0 too, so that it has no measured pair at all.
    let (side, n) = (11usize, 121usize);
    let uv = grid(side, 10.0);
    let config = DetectionConfig {
        radius_px: 46.0,
        ..DetectionConfig::paper()
    };
    let mut observed = [1u32; 400];
    for (k, o) in observed.iter_mut().enumerate().take(n) {
        if k == 0 || k >= n - side {
            *o = 0;
        }
    }
    let residual = |k: usize, frame: usize| {
        let x = (k * 7 + frame * 3) as f64;
        [
            1.5 * libm::sin(x * 1.3) + 0.02 * uv[k][0],
            libm::cos(x * 0.7),
        ]
    };
    let mut s = store();
    let mut det = detector(&mut s, n, 2800);
    let d0: [[f64; 2]; 400] = core::array::from_fn(|k| residual(k, 0));
    det.init(&uv[..n], &d0[..n], &config).unwrap();
    let degree = |f: usize| {
        det.pairs()
            .iter()
            .filter(|p| p.contains(&(f as u32)))
            .count()
    };
    assert!(
        (0..n).any(|f| degree(f) > RANK_MAX),
        "a feature past 64 pairs"
    );
    for frame in 1..4 {
        let d: [[f64; 2]; 400] = core::array::from_fn(|k| residual(k, frame));
        det.update(frame as u32, &d[..n], &observed[..n], &uv[..n], &config);
        let mut measured_somewhere = false;
        let mut most_m = 0;
        for f in 0..n {
            let mut slopes = [0.0f64; 144];
            let mut m = 0;
            for (k, pair) in det.pairs().iter().enumerate() {
                let mu = det.difference[k];
                if pair.contains(&(f as u32)) && mu >= 0.0 {
                    slopes[m] = mu / det.length[k].max(f64::EPSILON);
                    m += 1;
                }
            }
            let expected = if m >= 3 {
                quantile_of(&mut slopes[..m], m, 1.0 / 3.0, &mut []).0
            } else {
                0.0
            };
            assert_eq!(
                det.slope[f].to_bits(),
                expected.to_bits(),
                "frame {frame}, feature {f} of {m} measured pairs: {} against {expected}",
                det.slope[f]
            );
            measured_somewhere |= m > RANK_MAX;
            most_m = most_m.max(m);
        }
        assert!(
            measured_somewhere,
            "a tertile over more than 64 pairs ({most_m} at most)"
        );
        assert_eq!(det.slope[0], 0.0);
    }
}
