//! The camera calibration file: OpenCV's `FileStorage` format (YAML or XML) as OpenCV's
//! calibration tools write it, read by the host itself.
//!
//! Why not OpenCV's own reader: fed damaged files (the reader fuzz test), OpenCV 4.6's
//! `FileStorage` crashes the process with a segmentation fault on some of them, for instance an
//! XML file cut short inside a tag; no Rust crate reads this dialect (its YAML starts with
//! `%YAML:1.0` and tags matrices `!!opencv-matrix`, which YAML parsers refuse). Only four keys
//! matter, so the reader is small: it finds `camera_matrix`, `dist_coeffs` (or
//! `distortion_coefficients`), `image_width` and `image_height` at the top level, skips every
//! other key, and reports every problem with the file and line.
//!
//! Invariants of a [`CalibrationFile`]: `fx, fy > 0`, no skew, last row `0 0 1`, every number
//! finite; 0, 4, 5, 8, 12 or 14 distortion coefficients.
//!
//! With the `opencv` feature, `Calibration` is a calibration in use: it undistorts tracked
//! points and gives its intrinsics to the scene's camera.

use std::path::Path;
#[cfg(feature = "opencv")]
use std::path::PathBuf;

#[cfg(feature = "opencv")]
use opencv::calib3d;
#[cfg(feature = "opencv")]
use opencv::core::{self as cvcore, Mat, Point2d, TermCriteria, Vector};

#[cfg(feature = "opencv")]
use crate::scene::CameraSection;
use crate::scene::SceneError;
#[cfg(feature = "opencv")]
use crate::track::{TrackError, cv};

/// A calibration as read: the pinhole matrix, the distortion coefficients and the picture size.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrationFile {
    /// `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`, pixels.
    pub camera_matrix: [[f64; 3]; 3],
    /// `k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, τx, τy]]]]`.
    pub dist_coeffs: Vec<f64>,
    /// The calibrated picture size (`image_width`, `image_height`), if the file states it.
    pub image_size: Option<(u32, u32)>,
}

/// Largest calibration file read, bytes: real ones are a few kilobytes.
pub const MAX_BYTES: u64 = 1 << 20;

/// Most entries of a matrix the reader keeps (a 3 × 3 camera matrix, 14 coefficients).
const MAX_ENTRIES: usize = 16;

/// Reads the calibration file at `path` (YAML when it starts with `%YAML`, XML when it starts
/// with `<?xml`).
///
/// # Errors
/// A [`SceneError`] naming the file and line (0 for the whole file): missing or unreadable, too large, neither
/// format, a key absent, a matrix of the wrong shape or with a non-finite number, intrinsics
/// the core cannot represent (skew, non-positive focal length).
pub fn read_calibration(path: &Path) -> Result<CalibrationFile, SceneError> {
    let fail = |line: usize, message: String| SceneError::new(path, line, message);
    let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => fail(0, "no such file".into()),
        _ => fail(0, e.to_string()),
    })?;
    if !meta.is_file() {
        return Err(fail(0, "not a file".into()));
    }
    if meta.len() > MAX_BYTES {
        return Err(fail(
            0,
            format!(
                "{} bytes; a calibration file is at most {MAX_BYTES} bytes",
                meta.len()
            ),
        ));
    }
    let text = std::fs::read_to_string(path).map_err(|e| fail(0, e.to_string()))?;
    parse_calibration(&text).map_err(|(line, message)| fail(line, message))
}

/// Parses the text of a calibration file; errors are `(line, message)`.
///
/// # Errors
/// As [`read_calibration`].
pub fn parse_calibration(text: &str) -> Result<CalibrationFile, (usize, String)> {
    let start = text.trim_start();
    let entries = if start.starts_with("%YAML") {
        yaml_entries(text)?
    } else if start.starts_with("<?xml") || start.starts_with("<opencv_storage") {
        xml_entries(text)?
    } else {
        return Err((
            1,
            "neither OpenCV YAML (%YAML:1.0) nor XML (<?xml …>)".into(),
        ));
    };
    let get = |key: &str| entries.iter().find(|e| e.key == key);
    let k = get("camera_matrix").ok_or((0, "no camera_matrix".to_string()))?;
    let k_data = k.matrix()?;
    if k_data.len() != 9 {
        return Err((
            k.line,
            format!("camera_matrix must be 3×3, it has {} entries", k_data.len()),
        ));
    }
    let d = get("dist_coeffs")
        .or_else(|| get("distortion_coefficients"))
        .ok_or((
            0,
            "no dist_coeffs (nor distortion_coefficients)".to_string(),
        ))?;
    let dist = d.matrix()?;
    if ![0, 4, 5, 8, 12, 14].contains(&dist.len()) {
        return Err((
            d.line,
            format!(
                "{} must hold 4, 5, 8, 12 or 14 numbers, not {}",
                d.key,
                dist.len()
            ),
        ));
    }
    let m = [
        [k_data[0], k_data[1], k_data[2]],
        [k_data[3], k_data[4], k_data[5]],
        [k_data[6], k_data[7], k_data[8]],
    ];
    let [fx, fy] = [m[0][0], m[1][1]];
    if !(fx > 0.0 && fy > 0.0) {
        return Err((
            k.line,
            format!("camera_matrix: focal lengths must be positive (fx {fx}, fy {fy})"),
        ));
    }
    if m[0][1].abs() > 1e-9 * fx {
        return Err((
            k.line,
            format!(
                "camera_matrix: skew {} is not supported (the model's camera has none)",
                m[0][1]
            ),
        ));
    }
    if m[1][0] != 0.0 || m[2] != [0.0, 0.0, 1.0] {
        return Err((
            k.line,
            "camera_matrix is not a pinhole matrix [[fx 0 cx] [0 fy cy] [0 0 1]]".into(),
        ));
    }
    let size = |key: &str| -> Result<Option<u32>, (usize, String)> {
        let Some(e) = get(key) else {
            return Ok(None);
        };
        let Value::Scalar(s) = &e.value else {
            return Err((e.line, format!("{key} must be a number, not a matrix")));
        };
        match s.parse::<u32>() {
            Ok(v) if v > 0 => Ok(Some(v)),
            _ => Err((
                e.line,
                format!("{key} must be a positive whole number, not {s:?}"),
            )),
        }
    };
    let image_size = match (size("image_width")?, size("image_height")?) {
        (Some(w), Some(h)) => Some((w, h)),
        (None, None) => None,
        _ => {
            return Err((
                0,
                "image_width and image_height go together: one is missing".into(),
            ));
        }
    };
    Ok(CalibrationFile {
        camera_matrix: m,
        dist_coeffs: dist,
        image_size,
    })
}

/// A top-level value: a scalar's text, or a matrix's fields as written.
#[derive(Debug)]
enum Value {
    Scalar(String),
    Matrix {
        rows: Option<String>,
        cols: Option<String>,
        data: Option<String>,
    },
}

/// One top-level key of interest, with the line it starts on.
#[derive(Debug)]
struct Entry {
    key: &'static str,
    line: usize,
    value: Value,
}

/// The keys the reader keeps; every other top-level key is skipped.
const KEYS: [&str; 5] = [
    "camera_matrix",
    "dist_coeffs",
    "distortion_coefficients",
    "image_width",
    "image_height",
];

impl Entry {
    /// The matrix's numbers, checked against its `rows × cols`.
    fn matrix(&self) -> Result<Vec<f64>, (usize, String)> {
        let key = self.key;
        let Value::Matrix { rows, cols, data } = &self.value else {
            return Err((self.line, format!("{key} is not a matrix (opencv-matrix)")));
        };
        let dim = |name: &str, v: &Option<String>| -> Result<usize, (usize, String)> {
            let v = v
                .as_deref()
                .ok_or_else(|| (self.line, format!("{key} has no {name}")))?;
            v.trim()
                .parse::<usize>()
                .ok()
                .filter(|&n| n <= MAX_ENTRIES)
                .ok_or_else(|| {
                    (
                        self.line,
                        format!("{key}: {name} {v:?} is not a whole number up to {MAX_ENTRIES}"),
                    )
                })
        };
        let (r, c) = (dim("rows", rows)?, dim("cols", cols)?);
        let data = data
            .as_deref()
            .ok_or_else(|| (self.line, format!("{key} has no data")))?;
        let mut v = Vec::new();
        for token in data
            .split(|ch: char| ch == ',' || ch.is_whitespace())
            .filter(|t| !t.is_empty())
        {
            if v.len() == MAX_ENTRIES {
                return Err((
                    self.line,
                    format!("{key} holds more than {MAX_ENTRIES} numbers"),
                ));
            }
            let x: f64 = token
                .parse()
                .map_err(|_| (self.line, format!("{key}: {token:?} is not a number")))?;
            if !x.is_finite() {
                return Err((self.line, format!("{key} holds a non-finite number")));
            }
            v.push(x);
        }
        if v.len() != r * c {
            return Err((
                self.line,
                format!("{key} is {r}×{c} but holds {} numbers", v.len()),
            ));
        }
        Ok(v)
    }
}

fn known(key: &str) -> Option<&'static str> {
    KEYS.iter().copied().find(|k| *k == key)
}

/// The entries of OpenCV's YAML: `key: value` at the start of a line, a matrix as
/// `key: !!opencv-matrix` followed by indented `rows:`, `cols:`, `dt:` and `data: [ … ]` (the
/// data may run over several lines up to its `]`).
fn yaml_entries(text: &str) -> Result<Vec<Entry>, (usize, String)> {
    let mut entries: Vec<Entry> = Vec::new();
    // The matrix being read (index into `entries`) and an open `data: [` list.
    let mut matrix: Option<usize> = None;
    let mut open_data = false;
    let mut skipping = false;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let body = raw.trim_end();
        let trimmed = body.trim_start();
        if open_data {
            let Some(Entry {
                value: Value::Matrix { data, .. },
                ..
            }) = matrix.and_then(|m| entries.get_mut(m))
            else {
                return Err((line, "a matrix's data outside a matrix".into()));
            };
            let (part, done) = match trimmed.find(']') {
                Some(end) => (&trimmed[..end], true),
                None => (trimmed, false),
            };
            if let Some(d) = data.as_mut() {
                d.push(' ');
                d.push_str(part);
            }
            open_data = !done;
            continue;
        }
        if trimmed.is_empty()
            || trimmed.starts_with('#')
            || trimmed.starts_with('%')
            || trimmed == "---"
        {
            continue;
        }
        let indented = body.len() != trimmed.len();
        if indented && skipping {
            continue;
        }
        let (key, rest) = match trimmed.split_once(':') {
            Some((k, r)) => (k.trim(), r.trim()),
            None => return Err((line, format!("expected `key: value`, found {trimmed:?}"))),
        };
        if !indented {
            matrix = None;
            skipping = false;
            let Some(key) = known(key) else {
                // Another key (OpenCV's tools write the calibration time, the error, the
                // views' extrinsics…): skipped with whatever is indented under it.
                skipping = true;
                continue;
            };
            if entries.iter().any(|e| e.key == key) {
                return Err((line, format!("{key} appears twice")));
            }
            let value = if rest.starts_with("!!opencv-matrix") {
                if rest != "!!opencv-matrix" {
                    return Err((
                        line,
                        format!("{key}: write the matrix's fields on their own lines"),
                    ));
                }
                matrix = Some(entries.len());
                Value::Matrix {
                    rows: None,
                    cols: None,
                    data: None,
                }
            } else {
                Value::Scalar(rest.trim_matches('"').to_string())
            };
            entries.push(Entry { key, line, value });
            continue;
        }
        let Some(Entry {
            value: Value::Matrix { rows, cols, data },
            ..
        }) = matrix.and_then(|m| entries.get_mut(m))
        else {
            return Err((line, format!("unexpected indented line {trimmed:?}")));
        };
        match key {
            "rows" => *rows = Some(rest.to_string()),
            "cols" => *cols = Some(rest.to_string()),
            "dt" => {}
            "data" => {
                let Some(list) = rest.strip_prefix('[') else {
                    return Err((line, "a matrix's data must be a list `[ … ]`".into()));
                };
                match list.find(']') {
                    Some(end) => *data = Some(list[..end].to_string()),
                    None => {
                        *data = Some(list.to_string());
                        open_data = true;
                    }
                }
            }
            other => return Err((line, format!("unknown matrix field {other:?}"))),
        }
    }
    if open_data {
        return Err((0, "the file ends inside a matrix's data".into()));
    }
    Ok(entries)
}

/// The text between `<name>` (or `<name …>`) and `</name>` at or after `from`, with the offset
/// of its opening tag.
fn xml_element<'t>(text: &'t str, name: &str, from: usize) -> Option<(usize, &'t str)> {
    let mut at = from;
    loop {
        let open = at + text.get(at..)?.find(&format!("<{name}"))?;
        let after = open + 1 + name.len();
        let next = text.get(after..)?.chars().next()?;
        if next == '>' || next.is_whitespace() {
            let body_start = after + text.get(after..)?.find('>')? + 1;
            let close = body_start + text.get(body_start..)?.find(&format!("</{name}>"))?;
            return Some((open, text.get(body_start..close)?));
        }
        at = after;
    }
}

/// The entries of OpenCV's XML: `<key>value</key>` and
/// `<key type_id="opencv-matrix"><rows>…</rows><cols>…</cols><dt>…</dt><data>…</data></key>`
/// inside `<opencv_storage>`.
fn xml_entries(text: &str) -> Result<Vec<Entry>, (usize, String)> {
    let line_of = |offset: usize| {
        text.get(..offset)
            .map_or(0, |t| t.matches('\n').count() + 1)
    };
    let Some((root, storage)) = xml_element(text, "opencv_storage", 0) else {
        return Err((
            0,
            "no <opencv_storage> … </opencv_storage> element (the file may be cut short)".into(),
        ));
    };
    let base = root
        + text
            .get(root..)
            .map_or(0, |t| t.find('>').map_or(0, |e| e + 1));
    let mut entries = Vec::new();
    for key in KEYS {
        let Some((at, body)) = xml_element(storage, key, 0) else {
            continue;
        };
        let line = line_of(base + at);
        let field = |name: &str| xml_element(body, name, 0).map(|(_, v)| v.trim().to_string());
        let value = if body.contains('<') {
            Value::Matrix {
                rows: field("rows"),
                cols: field("cols"),
                data: field("data"),
            }
        } else {
            Value::Scalar(body.trim().to_string())
        };
        entries.push(Entry { key, line, value });
    }
    Ok(entries)
}

/// A calibration as OpenCV's calibration sample writes it in YAML (with keys the reader skips),
/// the same camera as [`EXAMPLE_XML`].
pub const EXAMPLE_YAML: &str = "%YAML:1.0
---
calibration_time: \"Mon Nov 23\"
image_width: 640
image_height: 400
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 500., 0., 320., 0., 510.,
       200., 0., 0., 1. ]
extrinsic_parameters: !!opencv-matrix
   rows: 2
   cols: 6
   dt: d
   data: [ 1, 2, 3, 4, 5, 6,
       1, 2, 3, 4, 5, 6 ]
dist_coeffs: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.2, 0.05, 0.001, -0.002, 0.01 ]
";

/// The calibration of [`EXAMPLE_YAML`] in OpenCV's XML.
pub const EXAMPLE_XML: &str = "<?xml version=\"1.0\"?>
<opencv_storage>
<image_width>640</image_width>
<image_height>400</image_height>
<camera_matrix type_id=\"opencv-matrix\">
  <rows>3</rows>
  <cols>3</cols>
  <dt>d</dt>
  <data>
    500. 0. 320. 0. 510. 200. 0. 0. 1.</data></camera_matrix>
<distortion_coefficients type_id=\"opencv-matrix\">
  <rows>5</rows>
  <cols>1</cols>
  <dt>d</dt>
  <data>
    -0.2 0.05 0.001 -0.002 0.01</data></distortion_coefficients>
</opencv_storage>
";

/// A camera calibration: the pinhole matrix and OpenCV's lens-distortion coefficients.
///
/// Invariants established by [`Calibration::load`]: `fx, fy > 0`, no skew, last row
/// `0 0 1`, all finite; 0, 4, 5, 8, 12 or 14 distortion coefficients.
#[cfg(feature = "opencv")]
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

#[cfg(feature = "opencv")]
impl Calibration {
    /// Reads a calibration file in OpenCV's `FileStorage` format (YAML or XML) with the
    /// matrices `camera_matrix` and `dist_coeffs` (or `distortion_coefficients`, as OpenCV's
    /// calibration sample writes), and optionally `image_width` and `image_height`; read by the
    /// host's own reader (the module's documentation says why not OpenCV's).
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_opencv_yaml_and_xml_alike() {
        let a = parse_calibration(EXAMPLE_YAML).unwrap();
        let b = parse_calibration(EXAMPLE_XML).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.camera_matrix[1], [0.0, 510.0, 200.0]);
        assert_eq!(a.dist_coeffs, [-0.2, 0.05, 0.001, -0.002, 0.01]);
        assert_eq!(a.image_size, Some((640, 400)));
    }

    #[test]
    fn errors_name_the_line() {
        let bad = EXAMPLE_YAML.replace("510.,", "x,");
        assert_eq!(parse_calibration(&bad).unwrap_err().0, 6);
        let skew = EXAMPLE_YAML.replace("500., 0., 320.", "500., 3., 320.");
        let (line, m) = parse_calibration(&skew).unwrap_err();
        assert_eq!(line, 6, "{m}");
        assert!(m.contains("skew"), "{m}");
        let short = EXAMPLE_YAML.replace("cols: 5", "cols: 4");
        let (line, m) = parse_calibration(&short).unwrap_err();
        assert_eq!(line, 18, "{m}");
        let cut = &EXAMPLE_XML[..EXAMPLE_XML
            .find("<distortion_coefficients type_id=")
            .unwrap()
            + 20];
        assert!(parse_calibration(cut).is_err());
        let nan = EXAMPLE_XML.replace("-0.2", "nan");
        assert!(
            parse_calibration(&nan)
                .unwrap_err()
                .1
                .contains("non-finite")
        );
        assert!(parse_calibration("camera_matrix: 1").is_err());
    }
}
