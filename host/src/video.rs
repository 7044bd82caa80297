//! Video input and output through OpenCV (the `opencv` feature): frames are read and written one
//! at a time, so a video is never held whole in memory.
//!
//! Pictures cross this module as [`image::RgbImage`] (RGB, 8 bits a channel); OpenCV's BGR
//! order stays inside.

use std::fmt;
use std::path::{Path, PathBuf};

use image::RgbImage;
use opencv::core::{Mat, Size, Vec3b};
use opencv::imgproc;
use opencv::prelude::*;
use opencv::videoio::{self, VideoCapture, VideoWriter};

use crate::run::{FrameSink, RunError};

/// A failure to read or write a video: the file and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VideoError {
    /// The video file.
    pub path: PathBuf,
    /// What is wrong.
    pub message: String,
}

impl VideoError {
    fn new(path: &Path, message: impl Into<String>) -> Self {
        VideoError {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}

impl fmt::Display for VideoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.message)
    }
}

impl std::error::Error for VideoError {}

/// An OpenCV failure as a [`VideoError`] about `path`, saying what was being done.
fn cv<'a>(path: &'a Path, doing: &'static str) -> impl Fn(opencv::Error) -> VideoError + 'a {
    move |e| VideoError::new(path, format!("{doing}: {}", e.message))
}

/// An RGB picture as an OpenCV matrix borrowing its pixels (`CV_8UC3`, in RGB order).
pub(crate) fn rgb_mat(image: &RgbImage) -> opencv::Result<opencv::boxed_ref::BoxedRef<'_, Mat>> {
    let (w, h) = image.dimensions();
    Mat::new_rows_cols_with_bytes::<Vec3b>(h as i32, w as i32, image.as_raw())
}

/// A video file read frame by frame.
///
/// Invariant: every frame returned has the size [`VideoSource::size`] (the first frame's).
pub struct VideoSource {
    path: PathBuf,
    capture: VideoCapture,
    size: (u32, u32),
    fps: f64,
    frame_count: Option<usize>,
    /// Frame 0, read by [`VideoSource::open`] to learn the size and check the file decodes.
    pending: Option<RgbImage>,
    bgr: Mat,
}

impl VideoSource {
    /// Opens `path` and decodes its first frame (kept for [`VideoSource::next_frame`]).
    ///
    /// # Errors
    /// A [`VideoError`] naming the file when it does not exist, OpenCV cannot open it as a
    /// video (unreadable or unsupported format), it holds no frame, or its pixels are not
    /// 8-bit colour.
    pub fn open(path: &Path) -> Result<Self, VideoError> {
        if !path.exists() {
            return Err(VideoError::new(path, "no such file"));
        }
        if path.is_dir() {
            return Err(VideoError::new(path, "is a directory, not a video"));
        }
        let unsupported = || {
            VideoError::new(
                path,
                "cannot open as a video (unreadable or unsupported format)",
            )
        };
        let capture = VideoCapture::from_file(path, videoio::CAP_ANY).map_err(|_| unsupported())?;
        if !capture.is_opened().unwrap_or(false) {
            return Err(unsupported());
        }
        let fps = capture
            .get(videoio::CAP_PROP_FPS)
            .ok()
            .filter(|f| f.is_finite() && *f > 0.0)
            .unwrap_or(0.0);
        let frame_count = capture
            .get(videoio::CAP_PROP_FRAME_COUNT)
            .ok()
            .filter(|n| n.is_finite() && *n >= 1.0)
            .map(|n| n.round() as usize);
        let mut source = VideoSource {
            path: path.to_path_buf(),
            capture,
            size: (0, 0),
            fps,
            frame_count,
            pending: None,
            bgr: Mat::default(),
        };
        let first = source.decode()?.ok_or_else(|| {
            VideoError::new(path, "holds no frame (unreadable or unsupported video)")
        })?;
        source.size = first.dimensions();
        source.pending = Some(first);
        Ok(source)
    }

    /// Width and height, pixels.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// Frames per second as the file states it; 0 when it states none.
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// Number of frames as the file states it, if it does (containers may be approximate).
    pub fn frame_count(&self) -> Option<usize> {
        self.frame_count
    }

    /// The video file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The next frame (RGB), `None` at the end of the video.
    ///
    /// # Errors
    /// A [`VideoError`] if a frame cannot be decoded or its size differs from the first's.
    pub fn next_frame(&mut self) -> Result<Option<RgbImage>, VideoError> {
        if let Some(frame) = self.pending.take() {
            return Ok(Some(frame));
        }
        let Some(frame) = self.decode()? else {
            return Ok(None);
        };
        if frame.dimensions() != self.size {
            return Err(VideoError::new(
                &self.path,
                format!(
                    "a frame is {}×{}, the first was {}×{}",
                    frame.width(),
                    frame.height(),
                    self.size.0,
                    self.size.1
                ),
            ));
        }
        Ok(Some(frame))
    }

    /// Decodes one frame and converts it from BGR to RGB.
    fn decode(&mut self) -> Result<Option<RgbImage>, VideoError> {
        let path = self.path.as_path();
        let more = self
            .capture
            .read(&mut self.bgr)
            .map_err(cv(path, "cannot decode a frame"))?;
        if !more || self.bgr.empty() {
            return Ok(None);
        }
        if self.bgr.typ() != Vec3b::opencv_type() {
            return Err(VideoError::new(
                path,
                "frames are not 8-bit colour (3 channels)",
            ));
        }
        let (w, h) = (self.bgr.cols() as u32, self.bgr.rows() as u32);
        let mut rgb = RgbImage::new(w, h);
        {
            let mut dst = Mat::new_rows_cols_with_bytes_mut::<Vec3b>(h as i32, w as i32, &mut rgb)
                .map_err(cv(path, "cannot convert a frame"))?;
            imgproc::cvt_color(&self.bgr, &mut dst, imgproc::COLOR_BGR2RGB, 0)
                .map_err(cv(path, "cannot convert a frame"))?;
        }
        Ok(Some(rgb))
    }
}

/// A video file written frame by frame: Motion-JPEG in AVI (`.avi`, always available) or
/// MPEG-4 (`.mp4`, when OpenCV's FFmpeg backend has the codec).
pub struct VideoSink {
    path: PathBuf,
    writer: VideoWriter,
    size: (u32, u32),
    bgr: Mat,
}

impl VideoSink {
    /// Creates `path` for `width × height` frames at `fps` frames per second. AVI files are
    /// written as Motion-JPEG at the highest quality the backend offers (compression costs
    /// tracking accuracy).
    ///
    /// # Errors
    /// A [`VideoError`] naming the file for an extension other than `.avi` or `.mp4`, a zero
    /// size, a non-positive frame rate, or a file OpenCV cannot create (an `.mp4` when no
    /// MPEG-4 encoder is available, say).
    pub fn create(path: &Path, width: u32, height: u32, fps: f64) -> Result<Self, VideoError> {
        if width == 0 || height == 0 || width > i32::MAX as u32 || height > i32::MAX as u32 {
            return Err(VideoError::new(
                path,
                format!("cannot write {width}×{height} frames"),
            ));
        }
        if !(fps.is_finite() && fps > 0.0) {
            return Err(VideoError::new(
                path,
                format!("frame rate must be positive, not {fps}"),
            ));
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let size = Size::new(width as i32, height as i32);
        let fourcc = |c: [char; 4]| {
            VideoWriter::fourcc(c[0], c[1], c[2], c[3]).map_err(cv(path, "bad codec"))
        };
        // Backends to try in order: OpenCV's own MJPEG writer honours the quality setting.
        let (codec, backends) = match ext.as_deref() {
            Some("avi") => (
                fourcc(['M', 'J', 'P', 'G'])?,
                &[videoio::CAP_OPENCV_MJPEG, videoio::CAP_ANY][..],
            ),
            Some("mp4") => (fourcc(['m', 'p', '4', 'v'])?, &[videoio::CAP_ANY][..]),
            _ => {
                return Err(VideoError::new(
                    path,
                    "unsupported video extension: use .avi (Motion-JPEG) or .mp4",
                ));
            }
        };
        let mut writer = None;
        for &backend in backends {
            if let Ok(w) = VideoWriter::new_with_backend(path, backend, codec, fps, size, true)
                && w.is_opened().unwrap_or(false)
            {
                writer = Some(w);
                break;
            }
        }
        let Some(mut writer) = writer else {
            return Err(VideoError::new(
                path,
                if ext.as_deref() == Some("mp4") {
                    "cannot create an MPEG-4 video (no encoder in this OpenCV?): write .avi instead"
                } else {
                    "cannot create the video (is the directory writable?)"
                },
            ));
        };
        // Not every backend knows the setting; a refusal is not an error.
        let _ = writer.set(videoio::VIDEOWRITER_PROP_QUALITY, 100.0);
        Ok(VideoSink {
            path: path.to_path_buf(),
            writer,
            size: (width, height),
            bgr: Mat::default(),
        })
    }

    /// The video file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends one frame.
    ///
    /// # Errors
    /// A [`VideoError`] if the frame's size is not the video's or it cannot be encoded.
    pub fn write(&mut self, frame: &RgbImage) -> Result<(), VideoError> {
        let path = self.path.as_path();
        if frame.dimensions() != self.size {
            return Err(VideoError::new(
                path,
                format!(
                    "a frame is {}×{}, the video {}×{}",
                    frame.width(),
                    frame.height(),
                    self.size.0,
                    self.size.1
                ),
            ));
        }
        let rgb = rgb_mat(frame).map_err(cv(path, "cannot convert a frame"))?;
        imgproc::cvt_color(&rgb, &mut self.bgr, imgproc::COLOR_RGB2BGR, 0)
            .map_err(cv(path, "cannot convert a frame"))?;
        self.writer
            .write(&self.bgr)
            .map_err(cv(path, "cannot write a frame"))
    }

    /// Closes the file (dropping the sink closes it too, silently).
    ///
    /// # Errors
    /// A [`VideoError`] if the file cannot be finalised.
    pub fn finish(mut self) -> Result<(), VideoError> {
        self.writer
            .release()
            .map_err(cv(&self.path, "cannot finish the video"))
    }
}

impl FrameSink for VideoSink {
    fn write(&mut self, picture: &RgbImage) -> Result<(), RunError> {
        VideoSink::write(self, picture).map_err(|e| RunError::Output(e.to_string()))
    }
}
