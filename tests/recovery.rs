//! Recovery: runs of bad frames injected into a cut scene are refused by the core one frame at
//! a time, the model keeps its state through them, and the run ends as well as the clean one.
//!
//! Injected after the cut has been detected (frame 20 of 40), in this order:
//! - five frames in which every feature is lost (empty frames);
//! - a frame in which every point is NaN;
//! - a frame in which every feature jumps 50 px to the right (points that leave the image
//!   make the core refuse the whole frame; points that stay pull the model for one frame).
//!
//! The final Dice must be within 0.01 of the clean run's, and every refused frame reported.
//! (That a refused frame leaves the model's state bit-identical is the core's promise, checked
//! by its own state tests.)

use std::path::Path;

use incise::run::{Trace, run_once};
use incise::scene::Scene;

const LOST: std::ops::Range<usize> = 20..25;
const NAN: usize = 27;
const JUMP: usize = 29;
const JUMP_PX: f64 = 50.0;

fn load(name: &str) -> Scene {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name);
    Scene::load(&dir).unwrap_or_else(|e| panic!("{e}"))
}

fn run(scene: &Scene) -> Trace {
    run_once(scene, true, None, false).unwrap_or_else(|e| panic!("{}: {e}", scene.file.name))
}

fn corrupt(scene: &mut Scene) {
    assert!(scene.frames.len() > JUMP + 5, "the scene is too short");
    for f in LOST {
        scene.frames[f].clear();
    }
    for o in &mut scene.frames[NAN] {
        o.uv = [f64::NAN; 2];
    }
    for o in &mut scene.frames[JUMP] {
        o.uv[0] += JUMP_PX;
    }
}

fn recovers(name: &str) {
    let mut scene = load(name);
    let clean = run(&scene);
    assert!(clean.rejected.is_empty(), "{name}: {:?}", clean.rejected);
    corrupt(&mut scene);
    let hurt = run(&scene);

    // Every lost frame and the NaN frame are refused, each with the core's reason; the jump
    // frame is refused only if a point left the image.
    let refused: Vec<usize> = hurt.rejected.iter().map(|(f, _)| *f).collect();
    let mut expected: Vec<usize> = LOST.chain([NAN]).collect();
    if refused.contains(&JUMP) {
        expected.push(JUMP);
        let (_, why) = &hurt.rejected[expected.len() - 1];
        assert!(
            why.contains("outside"),
            "{name}: jump frame refused for {why}"
        );
    }
    assert_eq!(refused, expected, "{name}: {:?}", hurt.rejected);
    for (f, why) in &hurt.rejected {
        assert!(
            !why.is_empty(),
            "{name}: frame {f} refused without a reason"
        );
    }
    assert!(
        hurt.rejected[..LOST.len()]
            .iter()
            .all(|(_, why)| why.contains("no observation") || why.contains("empty")),
        "{name}: {:?}",
        hurt.rejected
    );
    // The injection took effect: the accepted jump pulled the model off for a frame.
    if !refused.contains(&JUMP) {
        assert_ne!(
            hurt.frames[JUMP].dice.to_bits(),
            clean.frames[JUMP].dice.to_bits(),
            "{name}: the jump frame changed nothing"
        );
    }
    // Every frame ran, and the run ends where the clean one does.
    assert_eq!(hurt.frames.len(), clean.frames.len());
    assert!(hurt.frames.iter().all(|r| r.dice.is_finite()));
    let gap = (hurt.dice_final - clean.dice_final).abs();
    eprintln!(
        "{name}: final Dice clean {:.4}, with bad frames {:.4}; refused {:?}; Dice at the jump {:.4} (clean {:.4})",
        clean.dice_final, hurt.dice_final, refused, hurt.frames[JUMP].dice, clean.frames[JUMP].dice
    );
    assert!(
        gap <= 0.01,
        "{name}: final Dice {:.4} against {:.4} clean",
        hurt.dice_final,
        clean.dice_final
    );
}

#[test]
fn band_side_cut_recovers_from_bad_frames() {
    recovers("band-side-cut");
}

#[test]
fn liver_lobe_recovers_from_bad_frames() {
    recovers("liver-lobe");
}
