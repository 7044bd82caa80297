//! The OpenCV path against ground truth (needs `--features opencv`): the textured video of
//! `band-side-cut` is rendered from the same simulation as the committed scene, tracked with
//! KLT, and (1) every tracked position is compared with the true projection of the material
//! point it started on, (2) running the scene on the video gives the same uncut Dice as running
//! it on the committed tracks, and cutting the mesh improves it there too.
#![cfg(feature = "opencv")]

use std::path::{Path, PathBuf};

use incise::generate::pipeline::simulate;
use incise::generate::texture::render_frame;
use incise::run::{RunOptions, VideoFrames, rest_silhouette, run_scene, run_scene_with};
use incise::scene::Scene;
use incise::track::{Tracker, TrackerConfig};
use incise::video::{VideoSink, VideoSource};

fn scene_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/band-side-cut")
}

fn percentile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

#[test]
fn tracking_the_rendered_video_matches_the_truth_and_the_fixture_run() {
    let sim = simulate(&scene_dir().join("scenario.toml"), false).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let video = tmp.path().join("band-side-cut.avi");
    let cam = sim.camera.intrinsics();
    let mut sink = VideoSink::create(&video, cam.width, cam.height, 25.0).unwrap();
    for f in 0..sim.positions.len() {
        sink.write(&render_frame(&sim, f)).unwrap();
    }
    sink.finish().unwrap();

    // (1) Tracked positions against the true projections of the material points.
    let scene = Scene::load(&scene_dir()).unwrap();
    let mask = rest_silhouette(&scene).unwrap();
    let mut source = VideoSource::open(&video).unwrap();
    let first = source.next_frame().unwrap().unwrap();
    let mut tracker = Tracker::start(&first, &mask, TrackerConfig::default()).unwrap();
    let start = tracker.observations();
    let points: Vec<Option<(usize, [f64; 4])>> =
        start.iter().map(|o| sim.material_point(o.uv)).collect();
    let on_surface = points.iter().filter(|p| p.is_some()).count();
    assert!(
        on_surface * 10 >= start.len() * 9,
        "{on_surface} of {} features on the object",
        start.len()
    );
    let mut errors = vec![];
    let mut frame = 0;
    loop {
        for o in tracker.observations() {
            if let Some(p) = points[o.id as usize]
                && let Some(truth) = sim.project(frame, p)
            {
                errors.push((o.uv[0] - truth[0]).hypot(o.uv[1] - truth[1]));
            }
        }
        match source.next_frame().unwrap() {
            Some(image) => {
                tracker.track(&image).unwrap();
                frame += 1;
            }
            None => break,
        }
    }
    assert_eq!(frame + 1, sim.positions.len());
    let alive = tracker.observations().len();
    let median = percentile(&mut errors, 0.5);
    let p95 = percentile(&mut errors, 0.95);
    eprintln!(
        "{} features, {alive} alive at the end, {} positions: error median {median:.3} px, 95th percentile {p95:.3} px",
        start.len(),
        errors.len()
    );
    assert!(median <= 0.5, "median {median}");
    assert!(p95 <= 2.0, "95th percentile {p95}");
    assert!(alive * 2 >= start.len(), "most features should survive");

    // (2) The same scene run on the video and on the committed tracks.
    let (on_tracks, _) = run_scene(&scene, &RunOptions::default()).unwrap();
    let mut frames = VideoFrames::open(&video, &scene, None).unwrap();
    let (on_video, _) = run_scene_with(&scene, &mut frames, None, &RunOptions::default()).unwrap();
    eprintln!(
        "Dice at the last frame, uncut: tracks {:.4}, video {:.4}; cut: tracks {:.4}, video {:.4}; cut detected at {:?} and {:?}, line {:.1} and {:.1} px from the truth",
        on_tracks.dice_final_uncut,
        on_video.dice_final_uncut,
        on_tracks.dice_final,
        on_video.dice_final,
        on_tracks.cut_detected_frame,
        on_video.cut_detected_frame,
        on_tracks.cut_hausdorff_px.unwrap_or(f64::NAN),
        on_video.cut_hausdorff_px.unwrap_or(f64::NAN),
    );
    // The driver: the model fits the video as well as the committed tracks (the uncut runs,
    // which depend on tracking alone).
    assert!((on_tracks.dice_final_uncut - on_video.dice_final_uncut).abs() <= 0.02);
    // The cut is found on the video too, and cutting the mesh improves the fit there. How much
    // it improves depends on the detected line, which lies farther from the truth on the
    // video's denser features than on the tracks (issue 11), so the cut runs are not compared.
    let open = on_video.cut_open_frame.expect("a cut scene");
    let detected = on_video
        .cut_detected_frame
        .expect("cut detected on the video");
    assert!(detected >= open && detected <= open + 5, "{detected}");
    assert!(on_video.cut_events >= 1);
    assert!(
        on_video.dice_final > on_video.dice_final_uncut,
        "{} against {}",
        on_video.dice_final,
        on_video.dice_final_uncut
    );
    assert_eq!(on_video.frames, on_tracks.frames);
}
