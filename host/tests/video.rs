//! The OpenCV video driver: video round trip, KLT tracking against a known motion, calibration,
//! the `track` and `run --video` commands; and, without the `opencv` feature, a clear refusal.

use std::process::Command;

fn incise() -> Command {
    Command::new(env!("CARGO_BIN_EXE_incise"))
}

const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/band-no-cut");

#[cfg(not(feature = "opencv"))]
#[test]
fn video_options_say_the_feature_is_missing() {
    for args in [
        vec!["run", SCENE, "--video", "clip.avi"],
        vec!["track", "clip.avi", "--scene", SCENE],
    ] {
        let output = incise().args(&args).output().unwrap();
        assert_eq!(output.status.code(), Some(1), "{args:?}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            stderr.contains("built without the opencv feature; rebuild with --features opencv"),
            "{stderr}"
        );
    }
}

#[cfg(feature = "opencv")]
mod with_opencv {
    use std::path::Path;

    use image::{Rgb, RgbImage};
    use incise::calibration::Calibration;
    use incise::render::Mask;
    use incise::rng::Rng;
    use incise::run::{FrameSource, VideoFrames};
    use incise::scene::read_tracks;
    use incise::track::{TrackError, Tracker, TrackerConfig};
    use incise::video::{VideoSink, VideoSource};

    use super::{SCENE, incise};

    /// A smooth random grey texture defined everywhere: bilinear interpolation of random
    /// lattices (5 and 13 pixel cells), so that a translated picture is exact.
    struct Texture {
        layers: Vec<(f64, usize, Vec<f64>, f64)>,
    }

    impl Texture {
        fn new(seed: u64) -> Self {
            let mut rng = Rng::new(seed);
            let layers = [(5.0, 0.7), (13.0, 0.3)]
                .into_iter()
                .map(|(cell, weight)| {
                    let n = 256;
                    let values = (0..n * n).map(|_| rng.uniform()).collect();
                    (cell, n, values, weight)
                })
                .collect();
            Texture { layers }
        }

        /// Value in [0, 1] at `(x, y)` (pixels, x ≥ 0, y ≥ 0).
        fn at(&self, x: f64, y: f64) -> f64 {
            self.layers
                .iter()
                .map(|(cell, n, v, weight)| {
                    let (gx, gy) = (x / cell, y / cell);
                    let (i, j) = (gx.floor() as usize % n, gy.floor() as usize % n);
                    let (fx, fy) = (gx - gx.floor(), gy - gy.floor());
                    let (i1, j1) = ((i + 1) % n, (j + 1) % n);
                    let top = v[j * n + i] * (1.0 - fx) + v[j * n + i1] * fx;
                    let bottom = v[j1 * n + i] * (1.0 - fx) + v[j1 * n + i1] * fx;
                    weight * (top * (1.0 - fy) + bottom * fy)
                })
                .sum()
        }

        /// The texture shifted by `shift` pixels, as a `width × height` picture.
        fn picture(&self, width: u32, height: u32, shift: [f64; 2]) -> RgbImage {
            RgbImage::from_fn(width, height, |x, y| {
                let v = self.at(
                    x as f64 + 0.5 - shift[0] + 100.0,
                    y as f64 + 0.5 - shift[1] + 100.0,
                );
                let g = (v * 255.0).round().clamp(0.0, 255.0) as u8;
                Rgb([g, g, g])
            })
        }
    }

    /// Per-frame motion of the synthetic videos, pixels.
    const MOTION: [f64; 2] = [0.37, -0.23];

    /// Writes `frames` frames of the texture moving by [`MOTION`] per frame.
    fn write_video(path: &Path, width: u32, height: u32, frames: usize) {
        let texture = Texture::new(7);
        let mut sink = VideoSink::create(path, width, height, 25.0).unwrap();
        for f in 0..frames {
            let shift = [MOTION[0] * f as f64, MOTION[1] * f as f64];
            sink.write(&texture.picture(width, height, shift)).unwrap();
        }
        sink.finish().unwrap();
    }

    fn inset_mask(width: u32, height: u32, margin: u32) -> Mask {
        let mut m = Mask::new(width, height);
        for y in margin..height - margin {
            for x in margin..width - margin {
                m.data[(y * width + x) as usize] = 1;
            }
        }
        m
    }

    fn median(mut v: Vec<f64>) -> f64 {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }

    #[test]
    fn a_video_round_trips_and_tracking_recovers_the_motion() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("moving.avi");
        let (w, h, n) = (160, 120, 20);
        write_video(&path, w, h, n);

        let mut source = VideoSource::open(&path).unwrap();
        assert_eq!(source.size(), (w, h));
        assert_eq!(source.frame_count(), Some(n));
        assert!((source.fps() - 25.0).abs() < 1e-6, "{}", source.fps());
        let frame0 = source.next_frame().unwrap().unwrap();
        // Motion-JPEG at full quality stays close to the original.
        let original = Texture::new(7).picture(w, h, [0.0, 0.0]);
        let mean_error = frame0
            .pixels()
            .zip(original.pixels())
            .map(|(a, b)| (a.0[1] as f64 - b.0[1] as f64).abs())
            .sum::<f64>()
            / (w * h) as f64;
        assert!(mean_error < 3.0, "mean grey error {mean_error}");

        let config = TrackerConfig::default();
        let mut tracker = Tracker::start(&frame0, &inset_mask(w, h, 16), config).unwrap();
        let start = tracker.observations();
        assert!(start.len() >= 50, "{} features", start.len());
        assert!(
            start.iter().all(|o| o.uv[0] >= 15.0
                && o.uv[0] <= (w - 15) as f64
                && o.uv[1] >= 15.0
                && o.uv[1] <= (h - 15) as f64),
            "a feature outside the mask: {start:?}"
        );
        let mut frames = 1;
        while let Some(frame) = source.next_frame().unwrap() {
            tracker.track(&frame).unwrap();
            frames += 1;
        }
        assert_eq!(frames, n);
        let end = tracker.observations();
        assert!(
            end.len() * 2 >= start.len(),
            "{} of {} features survived",
            end.len(),
            start.len()
        );
        let moved = [MOTION[0] * (n - 1) as f64, MOTION[1] * (n - 1) as f64];
        let errors: Vec<f64> = end
            .iter()
            .map(|o| {
                let s = start.iter().find(|s| s.id == o.id).unwrap();
                let d = [o.uv[0] - s.uv[0], o.uv[1] - s.uv[1]];
                (d[0] - moved[0]).hypot(d[1] - moved[1])
            })
            .collect();
        let med = median(errors);
        assert!(med < 0.3, "median displacement error {med} px");
    }

    #[test]
    fn lost_features_stay_lost() {
        let tmp = tempfile::tempdir().unwrap();
        let (w, h) = (160, 120);
        let texture = Texture::new(3);
        let frame0 = texture.picture(w, h, [0.0, 0.0]);
        let mut tracker =
            Tracker::start(&frame0, &inset_mask(w, h, 16), TrackerConfig::default()).unwrap();
        let found = tracker.len();
        // A different picture: (nearly) every feature fails the checks, and none returns
        // when the first picture comes back.
        tracker
            .track(&Texture::new(99).picture(w, h, [0.0, 0.0]))
            .unwrap();
        let after_jump = tracker.alive();
        assert!(after_jump * 5 < found, "{after_jump} of {found} survived");
        tracker.track(&frame0).unwrap();
        assert!(tracker.alive() <= after_jump);
        assert_eq!(tracker.len(), found);
        drop(tmp);
    }

    #[test]
    fn missing_and_unreadable_videos_are_clear_errors() {
        let err = VideoSource::open(Path::new("/nonexistent/clip.avi"))
            .err()
            .unwrap();
        assert_eq!(err.to_string(), "/nonexistent/clip.avi: no such file");
        let tmp = tempfile::tempdir().unwrap();
        let junk = tmp.path().join("junk.avi");
        std::fs::write(&junk, "this is not a video").unwrap();
        let err = VideoSource::open(&junk).err().unwrap();
        assert!(
            err.to_string().starts_with(&junk.display().to_string()),
            "{err}"
        );
        assert!(
            err.message.contains("unsupported") || err.message.contains("no frame"),
            "{err}"
        );
        let err = VideoSink::create(&tmp.path().join("out.mkv"), 16, 16, 25.0)
            .err()
            .unwrap();
        assert!(err.message.contains(".avi"), "{err}");
        let mut sink = VideoSink::create(&tmp.path().join("out.avi"), 32, 16, 25.0).unwrap();
        let err = sink.write(&RgbImage::new(16, 16)).unwrap_err();
        assert!(
            err.message.contains("16×16") && err.message.contains("32×16"),
            "{err}"
        );
    }

    #[test]
    fn size_mismatches_name_both_sizes() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("small.avi");
        write_video(&path, 160, 120, 2);
        let source = VideoSource::open(&path).unwrap();
        let err = VideoFrames::new(source, (640, 400), TrackerConfig::default(), None)
            .err()
            .unwrap();
        assert!(matches!(err, TrackError::SizeMismatch { .. }));
        let text = err.to_string();
        assert!(
            text.contains("160×120") && text.contains("640×400") && text.contains("small.avi"),
            "{text}"
        );
        // The silhouette must match the frames too.
        let frame = Texture::new(1).picture(160, 120, [0.0, 0.0]);
        let err = Tracker::start(&frame, &Mask::new(80, 60), TrackerConfig::default())
            .err()
            .unwrap();
        assert!(matches!(err, TrackError::SizeMismatch { .. }), "{err}");
    }

    #[test]
    fn no_features_when_the_mask_is_empty_or_flat() {
        let (w, h) = (160, 120);
        let frame = Texture::new(1).picture(w, h, [0.0, 0.0]);
        let err = Tracker::start(&frame, &Mask::new(w, h), TrackerConfig::default())
            .err()
            .unwrap();
        assert_eq!(err, TrackError::NoFeatures { mask_pixels: 0 });
        let flat = RgbImage::from_pixel(w, h, Rgb([90, 90, 90]));
        let err = Tracker::start(&flat, &inset_mask(w, h, 16), TrackerConfig::default())
            .err()
            .unwrap();
        assert!(
            matches!(err, TrackError::NoFeatures { mask_pixels } if mask_pixels > 0),
            "{err}"
        );
        assert!(err.to_string().contains("no trackable feature"), "{err}");
    }

    #[test]
    fn the_frame_source_streams_frames_with_pictures() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("moving.avi");
        write_video(&path, 160, 120, 5);
        let source = VideoSource::open(&path).unwrap();
        let config = TrackerConfig {
            max_features: 40,
            ..TrackerConfig::default()
        };
        let mut frames = VideoFrames::new(source, (160, 120), config, None).unwrap();
        assert_eq!(frames.len_hint(), Some(5));
        let mask = inset_mask(160, 120, 16);
        let mut n = 0;
        let mut first = 0;
        while let Some(frame) = frames.next_frame(&mask).unwrap() {
            assert_eq!(
                frame.image.as_ref().map(|i| i.dimensions()),
                Some((160, 120))
            );
            if n == 0 {
                first = frame.observations.len();
                assert!(first > 0 && first <= 40, "{first}");
                let ids: Vec<u32> = frame.observations.iter().map(|o| o.id).collect();
                assert_eq!(ids, (0..first as u32).collect::<Vec<_>>());
            } else {
                assert!(frame.observations.len() <= first);
            }
            n += 1;
        }
        assert_eq!(n, 5);
    }

    /// OpenCV's distortion model (k1, k2, p1, p2, k3) applied to a pixel of the ideal camera.
    fn distort(k: [[f64; 3]; 3], d: &[f64], p: [f64; 2]) -> [f64; 2] {
        let (x, y) = ((p[0] - k[0][2]) / k[0][0], (p[1] - k[1][2]) / k[1][1]);
        let r2 = x * x + y * y;
        let radial = 1.0 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
        let xd = x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x);
        let yd = y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y;
        [k[0][0] * xd + k[0][2], k[1][1] * yd + k[1][2]]
    }

    #[test]
    fn calibration_reads_opencv_yaml_and_undistorts_to_pixels() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("camera.yml");
        std::fs::write(
            &path,
            "%YAML:1.0\n---\nimage_width: 640\nimage_height: 400\n\
             camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n\
             \x20  data: [ 500., 0., 320., 0., 510., 200., 0., 0., 1. ]\n\
             dist_coeffs: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n\
             \x20  data: [ -0.2, 0.05, 0.001, -0.002, 0.01 ]\n",
        )
        .unwrap();
        let c = Calibration::load(&path).unwrap();
        assert_eq!(c.camera_matrix[1][1], 510.0);
        assert_eq!(c.dist_coeffs.len(), 5);
        assert_eq!(c.image_size, Some((640, 400)));
        let ideal = [[320.0, 200.0], [10.0, 15.0], [600.0, 380.0], [400.0, 100.0]];
        let raw: Vec<[f64; 2]> = ideal
            .iter()
            .map(|&p| distort(c.camera_matrix, &c.dist_coeffs, p))
            .collect();
        let back = c.undistort_points(&raw).unwrap();
        for (b, i) in back.iter().zip(&ideal) {
            assert!((b[0] - i[0]).hypot(b[1] - i[1]) < 1e-3, "{b:?} vs {i:?}");
        }
        let mut camera = incise::scene::Scene::load_model(Path::new(SCENE))
            .unwrap()
            .file
            .camera;
        c.apply_to(&mut camera).unwrap();
        assert_eq!(
            (camera.fx, camera.fy, camera.cx, camera.cy),
            (500.0, 510.0, 320.0, 200.0)
        );
        camera.width = 320;
        let err = c.apply_to(&mut camera).unwrap_err();
        assert!(err.to_string().contains("640×400") && err.to_string().contains("320×400"));

        let err = Calibration::load(&tmp.path().join("none.yml")).unwrap_err();
        assert!(err.to_string().contains("no such file"), "{err}");
        let bad = tmp.path().join("bad.yml");
        std::fs::write(&bad, "%YAML:1.0\n---\nfoo: 1\n").unwrap();
        let err = Calibration::load(&bad).unwrap_err();
        assert!(err.to_string().contains("no camera_matrix"), "{err}");
    }

    #[test]
    fn track_and_run_video_commands() {
        let tmp = tempfile::tempdir().unwrap();
        let video = tmp.path().join("band.avi");
        write_video(&video, 640, 400, 4);
        let tracks = tmp.path().join("tracks.csv");
        let output = incise()
            .arg("track")
            .arg(&video)
            .args(["--scene", SCENE, "-o"])
            .arg(&tracks)
            .output()
            .unwrap();
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let frames = read_tracks(&std::fs::read_to_string(&tracks).unwrap(), &tracks).unwrap();
        assert_eq!(frames.len(), 4);
        assert!(!frames[0].is_empty());

        let out = tmp.path().join("out");
        let output = incise()
            .args(["run", SCENE, "--json", "--video"])
            .arg(&video)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
        assert_eq!(v["frames"], 4);
        assert_eq!(v["features"].as_u64(), Some(frames[0].len() as u64));
        assert!(out.join("frame_0003.png").exists());
        let overlay = VideoSource::open(&out.join("overlay.avi")).unwrap();
        assert_eq!(overlay.size(), (640, 400));
        assert_eq!(overlay.frame_count(), Some(4));

        // A video of the wrong size is refused before anything runs.
        let small = tmp.path().join("small.avi");
        write_video(&small, 160, 120, 2);
        let output = incise()
            .args(["run", SCENE, "--video"])
            .arg(&small)
            .output()
            .unwrap();
        assert_eq!(output.status.code(), Some(1));
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            stderr.contains("160×120") && stderr.contains("640×400"),
            "{stderr}"
        );
    }
}
