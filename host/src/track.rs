//! KLT tracking of a video (the `opencv` feature): Shi–Tomasi corners found at frame 0 inside
//! the model's projected silhouette, refined to sub-pixel accuracy, then followed frame to
//! frame by pyramidal Lucas–Kanade with a forward–backward check. A feature that fails a check
//! is lost for good: features are never re-detected and ids are never reused, as the core
//! expects (it places features on the model at frame 0 only).
//!
//! With a camera calibration, tracking runs on the raw (distorted) pictures and the tracked
//! points are undistorted before they reach the core, in pixels of the calibration's camera
//! matrix, which then replaces the scene's intrinsics.

use std::fmt;
use std::path::{Path, PathBuf};

use image::RgbImage;
use incise_core::{MeshInput, Observation};
use opencv::core::{self as cvcore, Mat, Point2d, Point2f, Size, TermCriteria, Vector};
use opencv::prelude::*;
use opencv::{calib3d, imgproc, video};

use crate::calibration::read_calibration;
use crate::render::{Mask, silhouette};
use crate::run::{FrameSource, ModelStorage, RunError, SourceFrame};
use crate::scene::{CameraSection, Scene};
use crate::video::{VideoError, VideoSource, rgb_mat};

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

fn cv(context: &'static str) -> impl Fn(opencv::Error) -> TrackError {
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

/// A camera calibration: the pinhole matrix and OpenCV's lens-distortion coefficients.
///
/// Invariants established by [`Calibration::load`]: `fx, fy > 0`, no skew, last row
/// `0 0 1`, all finite; 0, 4, 5, 8, 12 or 14 distortion coefficients.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`, pixels.
    pub camera_matrix: [[f64; 3]; 3],
    /// `k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, τx, τy]]]]`.
    pub dist_coeffs: Vec<f64>,
    /// The calibrated picture size (`image_width`, `image_height`), if the file states it.
    pub image_size: Option<(u32, u32)>,
    /// The file read.
    pub path: PathBuf,
}

impl Calibration {
    /// Reads a calibration file in OpenCV's `FileStorage` format (YAML or XML) with the
    /// matrices `camera_matrix` and `dist_coeffs` (or `distortion_coefficients`, as OpenCV's
    /// calibration sample writes), and optionally `image_width` and `image_height`; read by the
    /// host's own reader ([`crate::calibration`] says why not OpenCV's).
    ///
    /// # Errors
    /// [`TrackError::Calibration`] naming the file and line: missing, unreadable, a key absent,
    /// a matrix of the wrong shape, or intrinsics the core cannot represent (skew,
    /// non-positive focal length).
    pub fn load(path: &Path) -> Result<Self, TrackError> {
        let file = read_calibration(path).map_err(|e| TrackError::Calibration {
            path: e.file,
            message: if e.line > 0 {
                format!("line {}: {}", e.line, e.message)
            } else {
                e.message
            },
        })?;
        Ok(Calibration {
            camera_matrix: file.camera_matrix,
            dist_coeffs: file.dist_coeffs,
            image_size: file.image_size,
            path: path.to_path_buf(),
        })
    }

    /// Undistorts pixel positions of the raw picture into pixels of the same camera matrix
    /// (the ideal pinhole camera the model's camera is), by OpenCV's iterative inversion of the
    /// distortion model.
    ///
    /// # Errors
    /// [`TrackError::OpenCv`] if OpenCV fails.
    pub fn undistort_points(&self, pts: &[[f64; 2]]) -> Result<Vec<[f64; 2]>, TrackError> {
        if pts.is_empty() {
            return Ok(vec![]);
        }
        let ctx = "undistorting points";
        let src: Vector<Point2d> = pts.iter().map(|p| Point2d::new(p[0], p[1])).collect();
        let k = Mat::from_slice_2d(&self.camera_matrix).map_err(cv(ctx))?;
        let d = Mat::from_slice(&self.dist_coeffs).map_err(cv(ctx))?;
        let mut dst = Vector::<Point2d>::new();
        calib3d::undistort_points_iter(
            &src,
            &mut dst,
            &k,
            &d,
            &cvcore::no_array(),
            &k,
            TermCriteria::new(
                cvcore::TermCriteria_COUNT + cvcore::TermCriteria_EPS,
                100,
                1e-8,
            )
            .map_err(cv(ctx))?,
        )
        .map_err(cv(ctx))?;
        Ok(dst.iter().map(|p| [p.x, p.y]).collect())
    }

    /// Puts the calibration's intrinsics into `camera` (the scene's), keeping its size and pose.
    ///
    /// # Errors
    /// [`TrackError::SizeMismatch`] if the calibration states a picture size other than the
    /// camera's.
    pub fn apply_to(&self, camera: &mut CameraSection) -> Result<(), TrackError> {
        if let Some(size) = self.image_size
            && size != (camera.width, camera.height)
        {
            return Err(TrackError::SizeMismatch {
                subject: format!("the calibration {}", self.path.display()),
                size,
                reference: "the scene camera".into(),
                expected: (camera.width, camera.height),
            });
        }
        let k = &self.camera_matrix;
        (camera.fx, camera.fy, camera.cx, camera.cy) = (k[0][0], k[1][1], k[0][2], k[1][2]);
        Ok(())
    }
}

/// Frames of a video tracked on the fly: a [`FrameSource`] for [`crate::run::run_with`].
///
/// The first call to [`VideoFrames::next`] starts the tracker on frame 0 inside the model
/// silhouette it is given; later calls track. Observations are undistorted when a calibration
/// is given.
pub struct VideoFrames {
    source: VideoSource,
    config: TrackerConfig,
    calibration: Option<Calibration>,
    tracker: Option<Tracker>,
}

impl VideoFrames {
    /// Tracks `source`, whose frames must be `camera_size` (the scene camera's width and
    /// height).
    ///
    /// # Errors
    /// [`TrackError::SizeMismatch`] naming both sizes if the video's size is not the camera's
    /// or the calibration's; [`TrackError::Config`] for a bad tracker parameter.
    pub fn new(
        source: VideoSource,
        camera_size: (u32, u32),
        config: TrackerConfig,
        calibration: Option<Calibration>,
    ) -> Result<Self, TrackError> {
        config.validate()?;
        let size = source.size();
        let subject = || format!("the video {}", source.path().display());
        if size != camera_size {
            return Err(TrackError::SizeMismatch {
                subject: subject(),
                size,
                reference: "the scene camera".into(),
                expected: camera_size,
            });
        }
        if let Some(c) = &calibration
            && let Some(expected) = c.image_size
            && expected != size
        {
            return Err(TrackError::SizeMismatch {
                subject: subject(),
                size,
                reference: format!("the calibration {}", c.path.display()),
                expected,
            });
        }
        Ok(VideoFrames {
            source,
            config,
            calibration,
            tracker: None,
        })
    }

    /// Opens the video at `path` for `scene` (with the calibration's intrinsics already
    /// applied to it, if any): the tracker takes the default number of features (about the
    /// paper's 438), never more than the scene's feature capacity.
    ///
    /// # Errors
    /// As [`VideoSource::open`] and [`VideoFrames::new`].
    pub fn open(
        path: &Path,
        scene: &Scene,
        calibration: Option<Calibration>,
    ) -> Result<Self, TrackError> {
        let source = VideoSource::open(path)?;
        let config = TrackerConfig {
            max_features: TrackerConfig::default()
                .max_features
                .min(scene.file.capacities.features),
            ..TrackerConfig::default()
        };
        let camera = &scene.file.camera;
        Self::new(source, (camera.width, camera.height), config, calibration)
    }

    /// The next frame with its observations (undistorted if calibrated), `None` at the end.
    /// `model_silhouette` is where features are looked for at frame 0 (ignored afterwards).
    ///
    /// # Errors
    /// The video's errors; [`TrackError::NoFeatures`] at frame 0 when nothing is trackable
    /// inside the silhouette; the tracker's errors.
    pub fn next(&mut self, model_silhouette: &Mask) -> Result<Option<SourceFrame>, TrackError> {
        let Some(image) = self.source.next_frame()? else {
            return Ok(None);
        };
        let tracker = match &mut self.tracker {
            Some(t) => {
                t.track(&image)?;
                t
            }
            None => self.tracker.insert(Tracker::start(
                &image,
                model_silhouette,
                self.config.clone(),
            )?),
        };
        let mut observations = tracker.observations();
        if let Some(c) = &self.calibration {
            let raw: Vec<[f64; 2]> = observations.iter().map(|o| o.uv).collect();
            for (o, uv) in observations.iter_mut().zip(c.undistort_points(&raw)?) {
                o.uv = uv;
            }
        }
        Ok(Some(SourceFrame {
            observations,
            image: Some(image),
        }))
    }

    /// The tracker, once frame 0 has been read.
    pub fn tracker(&self) -> Option<&Tracker> {
        self.tracker.as_ref()
    }

    /// The video.
    pub fn source(&self) -> &VideoSource {
        &self.source
    }
}

impl FrameSource for VideoFrames {
    fn len_hint(&self) -> Option<usize> {
        self.source.frame_count()
    }

    fn next_frame(&mut self, model_silhouette: &Mask) -> Result<Option<SourceFrame>, RunError> {
        Ok(self.next(model_silhouette)?)
    }
}

/// The model's silhouette at rest in the scene's camera: where features are looked for at
/// frame 0 (the mask [`crate::run::run_with`] hands its frame source).
///
/// # Errors
/// A [`RunError`] for a camera or mesh the core refuses.
pub fn rest_silhouette(scene: &Scene) -> Result<Mask, RunError> {
    let toml = scene.dir.join("scene.toml");
    let camera = scene.file.camera(&toml)?;
    let input = MeshInput {
        rest: &scene.rest,
        tets: &scene.tets,
        fixed: &scene.file.model.fixed,
    };
    let core = |context: &str| {
        let context = context.to_string();
        move |error| RunError::Core { context, error }
    };
    // The model exactly as a run builds it, for its checked mesh and boundary surface.
    let mut storage =
        ModelStorage::<f64>::new(&input, &scene.file.capacities).map_err(|e| e.in_scene(&toml))?;
    let config = incise_core::ModelConfig {
        material: incise_core::Material {
            young: scene.file.model.young,
            poisson: scene.file.model.poisson,
        },
        camera,
        solver: scene.file.solver(&toml)?,
        detection: incise_core::DetectionConfig {
            enabled: false,
            ..scene.file.detection.config()
        },
    };
    let model = storage
        .model(&input, &config)
        .map_err(core("building the model"))?;
    Ok(silhouette(&camera, &scene.rest, model.mesh().surface()))
}
