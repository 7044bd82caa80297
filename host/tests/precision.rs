//! The whole pipeline in `f32`, and in mixed precision (the model in `f64`, its factor in
//! `f32`), against `f64` on every committed scene, through the same code (`Scene::precision`,
//! `incise run --real f32` / `--real mixed`): the core is rounded to single precision, the
//! host measures in `f64` either way.
//!
//! Stated tolerance (issue 14): the last frame's Dice within 0.005 and its target error within
//! 0.5 mm of the `f64` run's without cutting and with the mesh cut along the true cut (the same
//! cut in both precisions: what rounding alone changes); the cut found in the same frame and no
//! frame refused in either. With the detected cut, the same tolerance wherever both runs end
//! with the same mesh. Where they do not, the line differed by a pixel somewhere and a cut event
//! rounded to other nodes (a discrete decision, not an accuracy): `band-middle-cut` in `f32`
//! (its line's lower end advances at frame 24 instead of 30, and the mesh ends with 264 nodes
//! against 244, Dice 0.960 against 0.974); each run must then still improve on its own uncut
//! model.

mod common;

use common::committed_scenes;
use incise::run::{RunOptions, run_scene};
use incise::scene::{Precision, Scene};

#[test]
fn every_committed_scene_runs_in_f32_and_mixed_within_the_stated_tolerance_of_f64() {
    let dirs = committed_scenes();
    assert!(dirs.len() >= 7, "{dirs:?}");
    for (dir, precision) in dirs
        .iter()
        .flat_map(|d| [(d, Precision::F32), (d, Precision::Mixed)])
    {
        let mut scene = Scene::load(dir).unwrap();
        let options = RunOptions {
            true_cut: true,
            ..RunOptions::default()
        };
        let (double, _) = run_scene(&scene, &options).unwrap();
        scene.precision = precision;
        let (single, _) = run_scene(&scene, &options).unwrap();
        let name = &format!("{} ({})", double.scene, precision.name());
        eprintln!(
            "{name}: Dice {:.5} / {:.5}, uncut {:.5} / {:.5}; target error {:.4} / {:.4} mm, \
             uncut {:.4} / {:.4} mm (f64 / other)",
            double.dice_final,
            single.dice_final,
            double.dice_final_uncut,
            single.dice_final_uncut,
            double.tre_mm_final,
            single.tre_mm_final,
            double.tre_mm_final_uncut,
            single.tre_mm_final_uncut,
        );
        assert_eq!(double.precision, Precision::F64);
        assert_eq!(single.precision, precision);
        assert_eq!(
            (double.frames_rejected, single.frames_rejected),
            (0, 0),
            "{name}"
        );
        assert_eq!(
            double.cut_detected_frame, single.cut_detected_frame,
            "{name}"
        );
        assert_eq!(
            double.dice_final_true_cut.is_some(),
            double.cut_detected_frame.is_some(),
            "{name}: a cut scene runs along its true cut too"
        );
        assert_eq!(
            double.dice_final_true_cut.is_some(),
            single.dice_final_true_cut.is_some(),
            "{name}: both precisions run along the true cut"
        );
        let same_mesh =
            (double.nodes_final, double.tets_final) == (single.nodes_final, single.tets_final);
        // The one divergence the header states; any other is a regression to look at.
        assert!(
            same_mesh || (double.scene == "band-middle-cut" && precision == Precision::F32),
            "{name}: the detected cut ends with another mesh ({} / {} nodes)",
            double.nodes_final,
            single.nodes_final
        );
        let mut dice = vec![(double.dice_final_uncut, single.dice_final_uncut)];
        let mut tre = vec![(double.tre_mm_final_uncut, single.tre_mm_final_uncut)];
        if let (Some(a), Some(b)) = (double.dice_final_true_cut, single.dice_final_true_cut) {
            dice.push((a, b));
        }
        if let (Some(a), Some(b)) = (double.tre_mm_final_true_cut, single.tre_mm_final_true_cut) {
            tre.push((a, b));
        }
        if same_mesh {
            dice.push((double.dice_final, single.dice_final));
            tre.push((double.tre_mm_final, single.tre_mm_final));
        } else {
            eprintln!(
                "{name}: the detected cut ends with another mesh ({} / {} nodes)",
                double.nodes_final, single.nodes_final
            );
            for run in [&double, &single] {
                assert!(
                    run.dice_final > run.dice_final_uncut
                        && run.tre_mm_final < run.tre_mm_final_uncut,
                    "{name}: the {} run's cut does not improve on its uncut model",
                    run.precision.name()
                );
            }
        }
        for (a, b) in dice {
            assert!((a - b).abs() <= 0.005, "{name}: Dice {a} (f64) against {b}");
        }
        for (a, b) in tre {
            assert!(
                (a - b).abs() <= 0.5,
                "{name}: target error {a} mm (f64) against {b} mm"
            );
        }
        // The springs were derived in each precision from the same scene (a mean over the
        // features, summed in the precision of the core).
        let k = (double.spring_stiffness, single.spring_stiffness);
        assert!((k.0 - k.1).abs() <= 1e-4 * k.0, "{name}: {k:?}");
    }
}
