//! KLT tracking of a video (the `opencv` feature): Shi–Tomasi corners found at frame 0 inside
//! the model's projected silhouette, refined to sub-pixel accuracy, then followed frame to
//! frame by pyramidal Lucas–Kanade with a forward–backward check. A feature that fails a check
//! is lost for good: features are never re-detected and ids are never reused, as the core
//! expects (it places features on the model at frame 0 only).
//!
//! With a camera calibration, tracking runs on the raw (distorted) pictures and the tracked
//! points are undistorted before they reach the core, in pixels of the calibration's camera
//! matrix, which then replaces the scene's intrinsics ([`crate::calibration::Calibration`]).
//! The frame source that tracks a video for a run is [`crate::run::VideoFrames`].

use std::fmt;
use std::path::PathBuf;

use image::RgbImage;
use incise_core::Observation;
use opencv::core::{self as cvcore, Mat, Point2f, Size, TermCriteria, Vector};
use opencv::prelude::*;
use opencv::{imgproc, video};

use crate::render::Mask;
use crate::run::RunError;
use crate::video::{VideoError, rgb_mat};

/// A failure of tracking.
#[derive(Clone, Debug, PartialEq)]
pub enum TrackError {
    /// The video cannot be read.
    Video(VideoError),
    /// Two pictures that must have one size do not.
    SizeMismatch {
        /// What has the wrong size ("the video clip.avi", "a frame").
        subject: String,
        /// Its size, pixels.
        size: (u32, u32),
        /// What it must match ("the scene camera of scene.toml", "the mask").
        reference: String,
        /// The reference's size, pixels.
        expected: (u32, u32),
    },
    /// No trackable corner lies inside the mask at frame 0.
    NoFeatures {
        /// Pixels set in the mask.
        mask_pixels: usize,
    },
    /// A tracker parameter is out of range.
    Config(String),
    /// The calibration file cannot be used.
    Calibration {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// OpenCV failed.
    OpenCv {
        /// What was being done.
        context: &'static str,
        /// OpenCV's message.
        message: String,
    },
}

impl fmt::Display for TrackError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TrackError::Video(e) => write!(f, "{e}"),
            TrackError::SizeMismatch {
                subject,
                size,
                reference,
                expected,
            } => write!(
                f,
                "{subject} is {}×{} pixels but {reference} is {}×{}",
                size.0, size.1, expected.0, expected.1
            ),
            TrackError::NoFeatures { mask_pixels: 0 } => write!(
                f,
                "no feature to track: the model's silhouette is empty (is the model in view?)"
            ),
            TrackError::NoFeatures { mask_pixels } => write!(
                f,
                "no trackable feature inside the model's silhouette ({mask_pixels} pixels): \
                 the picture is flat there"
            ),
            TrackError::Config(m) => write!(f, "tracker configuration: {m}"),
            TrackError::Calibration { path, message } => {
                write!(f, "{}: {message}", path.display())
            }
            TrackError::OpenCv { context, message } => write!(f, "{context}: {message}"),
        }
    }
}

impl std::error::Error for TrackError {}

impl From<VideoError> for TrackError {
    fn from(e: VideoError) -> Self {
        TrackError::Video(e)
    }
}

impl From<TrackError> for RunError {
    fn from(e: TrackError) -> Self {
        RunError::Input(e.to_string())
    }
}

/// An OpenCV error as a [`TrackError`] in `context`.
pub(crate) fn cv(context: &'static str) -> impl Fn(opencv::Error) -> TrackError {
    move |e| TrackError::OpenCv {
        context,
        message: e.message,
    }
}

/// Parameters of the tracker.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackerConfig {
    /// Most features detected at frame 0 (the core's feature capacity).
    pub max_features: usize,
    /// Shi–Tomasi quality: corners weaker than this fraction of the strongest are dropped.
    pub quality_level: f64,
    /// Smallest distance between two features at frame 0, pixels.
    pub min_distance_px: f64,
    /// Side of the neighbourhood of the corner measure, pixels.
    pub block_size: u32,
    /// Half side of the window of the sub-pixel corner refinement, pixels (0: no refinement).
    pub sub_pixel_half_window_px: u32,
    /// Side of the Lucas–Kanade window, pixels.
    pub window_px: u32,
    /// Pyramid levels above the full-resolution picture (0: no pyramid).
    pub pyramid_levels: u32,
    /// Iterations of Lucas–Kanade per level.
    pub iterations: u32,
    /// Lucas–Kanade stops when an update is shorter than this, pixels.
    pub epsilon_px: f64,
    /// Largest Lucas–Kanade error (mean absolute grey difference over the window, 0–255) of a
    /// feature kept.
    pub max_error: f64,
    /// Largest distance between a feature and its position tracked forward then back, pixels.
    pub forward_backward_px: f64,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            max_features: 500,
            quality_level: 0.01,
            min_distance_px: 7.0,
            block_size: 7,
            sub_pixel_half_window_px: 5,
            window_px: 21,
            pyramid_levels: 3,
            iterations: 30,
            epsilon_px: 0.01,
            max_error: 30.0,
            forward_backward_px: 1.0,
        }
    }
}

impl TrackerConfig {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`TrackError::Config`] naming the first parameter out of range.
    pub fn validate(&self) -> Result<(), TrackError> {
        let bad = |m: &str| Err(TrackError::Config(m.to_string()));
        if self.max_features == 0 || self.max_features > i32::MAX as usize {
            return bad("max_features must be at least 1");
        }
        if !(self.quality_level > 0.0 && self.quality_level <= 1.0) {
            return bad("quality_level must lie in (0, 1]");
        }
        if !(self.min_distance_px >= 0.0 && self.min_distance_px.is_finite()) {
            return bad("min_distance_px must be finite and not negative");
        }
        if self.block_size < 3 || self.block_size > 63 {
            return bad("block_size must lie in 3..=63");
        }
        if self.sub_pixel_half_window_px > 32 {
            return bad("sub_pixel_half_window_px must be at most 32");
        }
        if self.window_px < 3 || self.window_px > 255 {
            return bad("window_px must lie in 3..=255");
        }
        if self.pyramid_levels > 10 {
            return bad("pyramid_levels must be at most 10");
        }
        if self.iterations == 0 || self.iterations > 10_000 {
            return bad("iterations must lie in 1..=10000");
        }
        if !(self.epsilon_px > 0.0 && self.epsilon_px.is_finite()) {
            return bad("epsilon_px must be positive");
        }
        if !(self.max_error > 0.0) {
            return bad("max_error must be positive");
        }
        if !(self.forward_backward_px > 0.0) {
            return bad("forward_backward_px must be positive");
        }
        Ok(())
    }
}

/// A grey copy of an RGB picture.
fn grey(frame: &RgbImage) -> Result<Mat, TrackError> {
    let rgb = rgb_mat(frame).map_err(cv("converting a frame to grey"))?;
    let mut g = Mat::default();
    imgproc::cvt_color(&rgb, &mut g, imgproc::COLOR_RGB2GRAY, 0)
        .map_err(cv("converting a frame to grey"))?;
    Ok(g)
}

/// What one Lucas–Kanade pass returns, per input point.
struct Flow {
    /// Tracked positions, pixels.
    points: Vector<Point2f>,
    /// 1 where the flow was found.
    status: Vec<u8>,
    /// Mean absolute grey difference over the window.
    error: Vec<f32>,
}

/// A KLT tracker over the frames of one video.
///
/// Invariants: `points[id]` is the position of feature `id` in the last frame tracked (raw
/// pixels), `None` once the feature is lost; a lost feature never comes back; `pyramid` is the
/// last frame's pyramid.
pub struct Tracker {
    config: TrackerConfig,
    size: (u32, u32),
    points: Vec<Option<[f32; 2]>>,
    pyramid: Vector<Mat>,
    levels: i32,
}

impl Tracker {
    /// Detects up to `config.max_features` corners of `frame0` inside `mask` (the model's
    /// projected silhouette), strongest first, and refines them to sub-pixel accuracy. Feature
    /// `id` is the corner's index.
    ///
    /// # Errors
    /// [`TrackError::Config`] for a bad parameter; [`TrackError::SizeMismatch`] if the mask's
    /// size is not the frame's; [`TrackError::NoFeatures`] when no corner lies inside the mask;
    /// [`TrackError::OpenCv`] if OpenCV fails.
    pub fn start(
        frame0: &RgbImage,
        mask: &Mask,
        config: TrackerConfig,
    ) -> Result<Self, TrackError> {
        config.validate()?;
        let size = frame0.dimensions();
        if (mask.width, mask.height) != size {
            return Err(TrackError::SizeMismatch {
                subject: "the model's silhouette".into(),
                size: (mask.width, mask.height),
                reference: "the video frame".into(),
                expected: size,
            });
        }
        let mask_pixels = mask.count();
        if mask_pixels == 0 {
            return Err(TrackError::NoFeatures { mask_pixels });
        }
        let g = grey(frame0)?;
        let m = Mat::new_rows_cols_with_bytes::<u8>(size.1 as i32, size.0 as i32, &mask.data)
            .map_err(cv("wrapping the mask"))?;
        let mut corners = Vector::<Point2f>::new();
        imgproc::good_features_to_track(
            &g,
            &mut corners,
            config.max_features as i32,
            config.quality_level,
            config.min_distance_px,
            &m,
            config.block_size as i32,
            false,
            0.04,
        )
        .map_err(cv("detecting corners at frame 0"))?;
        if corners.is_empty() {
            return Err(TrackError::NoFeatures { mask_pixels });
        }
        let half = config.sub_pixel_half_window_px as i32;
        let mut refined = corners.clone();
        if half > 0 {
            imgproc::corner_sub_pix(
                &g,
                &mut refined,
                Size::new(half, half),
                Size::new(-1, -1),
                TermCriteria::new(
                    cvcore::TermCriteria_COUNT + cvcore::TermCriteria_EPS,
                    40,
                    0.001,
                )
                .map_err(cv("refining corners"))?,
            )
            .map_err(cv("refining corners"))?;
        }
        // The refinement is meant for saddle-like corners; on other texture it may wander.
        // Keep a refined corner only if it moved less than a pixel and stays in the mask.
        let points = corners
            .iter()
            .zip(refined.iter())
            .map(|(c, r)| {
                let near = (r.x - c.x).hypot(r.y - c.y) < 1.0;
                let inside = mask.get(r.x.max(0.0) as u32, r.y.max(0.0) as u32);
                Some(if near && inside {
                    [r.x, r.y]
                } else {
                    [c.x, c.y]
                })
            })
            .collect();
        let mut tracker = Tracker {
            config,
            size,
            points,
            pyramid: Vector::new(),
            levels: 0,
        };
        (tracker.pyramid, tracker.levels) = tracker.pyramid(&g)?;
        Ok(tracker)
    }

    /// The Lucas–Kanade pyramid of a grey picture, with its number of levels.
    fn pyramid(&self, g: &Mat) -> Result<(Vector<Mat>, i32), TrackError> {
        let mut pyramid = Vector::<Mat>::new();
        let w = self.config.window_px as i32;
        let levels = video::build_optical_flow_pyramid(
            g,
            &mut pyramid,
            Size::new(w, w),
            self.config.pyramid_levels as i32,
            true,
            cvcore::BORDER_REFLECT_101,
            cvcore::BORDER_CONSTANT,
            true,
        )
        .map_err(cv("building the image pyramid"))?;
        Ok((pyramid, levels))
    }

    /// One pyramidal Lucas–Kanade pass from `from` to `to`.
    fn flow(
        &self,
        from: &Vector<Mat>,
        to: &Vector<Mat>,
        points: &Vector<Point2f>,
    ) -> Result<Flow, TrackError> {
        let mut next = Vector::<Point2f>::new();
        let mut status = Vector::<u8>::new();
        let mut error = Vector::<f32>::new();
        let w = self.config.window_px as i32;
        video::calc_optical_flow_pyr_lk(
            from,
            to,
            points,
            &mut next,
            &mut status,
            &mut error,
            Size::new(w, w),
            self.levels,
            TermCriteria::new(
                cvcore::TermCriteria_COUNT + cvcore::TermCriteria_EPS,
                self.config.iterations as i32,
                self.config.epsilon_px,
            )
            .map_err(cv("tracking features"))?,
            0,
            1e-4,
        )
        .map_err(cv("tracking features"))?;
        Ok(Flow {
            points: next,
            status: status.to_vec(),
            error: error.to_vec(),
        })
    }

    /// Tracks the live features from the previous frame into `frame`. A feature is lost when
    /// Lucas–Kanade fails, its error exceeds `max_error`, tracking it back lands farther than
    /// `forward_backward_px` from where it was, or it leaves the picture.
    ///
    /// # Errors
    /// [`TrackError::SizeMismatch`] if `frame`'s size is not frame 0's; [`TrackError::OpenCv`]
    /// if OpenCV fails.
    pub fn track(&mut self, frame: &RgbImage) -> Result<(), TrackError> {
        if frame.dimensions() != self.size {
            return Err(TrackError::SizeMismatch {
                subject: "a frame".into(),
                size: frame.dimensions(),
                reference: "frame 0".into(),
                expected: self.size,
            });
        }
        let (pyramid, levels) = self.pyramid(&grey(frame)?)?;
        if levels != self.levels {
            return Err(TrackError::OpenCv {
                context: "building the image pyramid",
                message: format!("{levels} levels, frame 0 had {}", self.levels),
            });
        }
        let ids: Vec<usize> = (0..self.points.len())
            .filter(|&i| self.points[i].is_some())
            .collect();
        if !ids.is_empty() {
            let before: Vector<Point2f> = ids
                .iter()
                .filter_map(|&i| self.points[i].map(|[x, y]| Point2f::new(x, y)))
                .collect();
            let forward = self.flow(&self.pyramid, &pyramid, &before)?;
            let backward = self.flow(&pyramid, &self.pyramid, &forward.points)?;
            let (after, back) = (&forward.points, &backward.points);
            let (w, h) = (self.size.0 as f32, self.size.1 as f32);
            for (k, &id) in ids.iter().enumerate() {
                let (Ok(p0), Ok(p1), Ok(p2)) = (before.get(k), after.get(k), back.get(k)) else {
                    self.points[id] = None;
                    continue;
                };
                let kept = forward.status.get(k) == Some(&1)
                    && backward.status.get(k) == Some(&1)
                    && forward
                        .error
                        .get(k)
                        .is_some_and(|&e| f64::from(e) <= self.config.max_error)
                    && f64::from((p2.x - p0.x).hypot(p2.y - p0.y))
                        <= self.config.forward_backward_px
                    && (0.0..=w - 1.0).contains(&p1.x)
                    && (0.0..=h - 1.0).contains(&p1.y);
                self.points[id] = kept.then_some([p1.x, p1.y]);
            }
        }
        self.pyramid = pyramid;
        Ok(())
    }

    /// The live features in the last frame tracked (raw pixels), by increasing id.
    pub fn observations(&self) -> Vec<Observation<f64>> {
        self.points
            .iter()
            .enumerate()
            .filter_map(|(id, p)| {
                p.map(|[x, y]| Observation {
                    id: id as u32,
                    uv: [f64::from(x), f64::from(y)],
                })
            })
            .collect()
    }

    /// Features found at frame 0.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether no feature was found at frame 0 (never true: [`Tracker::start`] refuses that).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Features still tracked.
    pub fn alive(&self) -> usize {
        self.points.iter().filter(|p| p.is_some()).count()
    }

    /// Frame size, pixels.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }
}
