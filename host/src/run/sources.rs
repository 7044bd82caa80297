//! Where the frames of a run come from: observations held in memory (a scene's `tracks.csv`,
//! a recorded run) or, with the `opencv` feature, a video tracked on the fly; and the model's
//! rest silhouette, where a tracker looks for features at frame 0.

#[cfg(feature = "opencv")]
use std::path::Path;

use image::RgbImage;
use incise_core::mesh::{Mesh, MeshCapacity};
use incise_core::storage::Slab;
use incise_core::{Observation, Resource};

#[cfg(feature = "opencv")]
use crate::calibration::Calibration;
use crate::render::{Mask, silhouette};
use crate::run::{RunError, core};
use crate::scene::Scene;
#[cfg(feature = "opencv")]
use crate::track::{TrackError, Tracker, TrackerConfig};
#[cfg(feature = "opencv")]
use crate::video::VideoSource;

/// One frame of input: the tracked features and, when the input is a video, its picture.
#[derive(Clone, Debug, Default)]
pub struct SourceFrame {
    /// Tracked features (undistorted pixels).
    pub observations: Vec<Observation<f64>>,
    /// The camera's picture, if any (drawn under the overlay).
    pub image: Option<RgbImage>,
}

/// Where the frames of a run come from: a scene's `tracks.csv`, or a video tracked on the fly
/// (the `opencv` feature). Frames are pulled one at a time, so a video is never held whole.
pub trait FrameSource {
    /// Number of frames, if known in advance (for the progress bar).
    fn len_hint(&self) -> Option<usize>;
    /// The next frame, `None` at the end. `model_silhouette` is the model's silhouette at rest
    /// (where a tracker should look for features at frame 0).
    ///
    /// # Errors
    /// A [`RunError`] if the input cannot be read.
    fn next_frame(&mut self, model_silhouette: &Mask) -> Result<Option<SourceFrame>, RunError>;
}

/// Frames from observations held in memory (a scene's `tracks.csv`, or a recorded run).
pub struct TrackSource<'s> {
    frames: &'s [Vec<Observation<f64>>],
    next: usize,
}

impl<'s> TrackSource<'s> {
    /// Frames from `frames`, frame 0 first.
    pub fn new(frames: &'s [Vec<Observation<f64>>]) -> Self {
        TrackSource { frames, next: 0 }
    }
}

impl FrameSource for TrackSource<'_> {
    fn len_hint(&self) -> Option<usize> {
        Some(self.frames.len())
    }

    fn next_frame(&mut self, _: &Mask) -> Result<Option<SourceFrame>, RunError> {
        let frame = self.frames.get(self.next).map(|obs| SourceFrame {
            observations: obs.clone(),
            image: None,
        });
        self.next += 1;
        Ok(frame)
    }
}

#[cfg(feature = "opencv")]
/// Frames of a video tracked on the fly: a [`FrameSource`] for [`super::run_pass`].
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

#[cfg(feature = "opencv")]
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

#[cfg(feature = "opencv")]
impl FrameSource for VideoFrames {
    fn len_hint(&self) -> Option<usize> {
        self.source.frame_count()
    }

    fn next_frame(&mut self, model_silhouette: &Mask) -> Result<Option<SourceFrame>, RunError> {
        Ok(self.next(model_silhouette)?)
    }
}

/// The model's silhouette at rest in the scene's camera: where features are looked for at
/// frame 0 (the mask [`super::run_pass`] hands its frame source).
///
/// # Errors
/// A [`RunError`] for a camera or mesh the core refuses.
pub fn rest_silhouette(scene: &Scene) -> Result<Mask, RunError> {
    let config = scene.model_config()?;
    // The core's own mesh, checked and with its boundary surface, as a run loads it: the
    // mesh alone, not a whole model with its factor.
    let input = scene.mesh_input();
    let capacity = MeshCapacity::exact(&input);
    let mut reals = vec![0.0; capacity.real_len()];
    let mut indices = vec![0; capacity.index_len()];
    let mut work = vec![0; capacity.work_len()];
    let mesh = Mesh::new(
        &input,
        &capacity,
        &mut Slab::new(&mut reals, Resource::Nodes),
        &mut Slab::new(&mut indices, Resource::Nodes),
        &mut work,
    )
    .map_err(core("loading the model's mesh"))?;
    Ok(silhouette(&config.camera, &scene.rest, mesh.surface()))
}
