//! The data files of a scene besides `scene.toml`: `tracks.csv` (tracked features), and the
//! ground truth's `gt/targets.csv`, `gt/cut.csv` and `gt/surface.obj`.

use std::path::Path;

use incise_core::Observation;

use super::SceneError;
use crate::limits;

/// Reads `tracks.csv` (`frame,id,u,v` with a header line): observations grouped by frame, frame
/// 0 first. Frames with no row are empty.
///
/// # Errors
/// A [`SceneError`] with the line for a malformed row, a non-numeric or non-finite value, a
/// frame number that goes backwards, or an id repeated within a frame.
pub fn read_tracks(text: &str, file: &Path) -> Result<Vec<Vec<Observation<f64>>>, SceneError> {
    let mut frames: Vec<Vec<Observation<f64>>> = vec![];
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, header)) if header.trim() == "frame,id,u,v" => {}
        Some((_, other)) => {
            return Err(SceneError::new(
                file,
                1,
                format!("expected the header \"frame,id,u,v\", found {other:?}"),
            ));
        }
        None => return Err(SceneError::new(file, 1, "empty file: no header")),
    }
    for (i, line) in lines {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 4 {
            return Err(SceneError::new(
                file,
                n,
                format!("expected 4 fields (frame,id,u,v), found {}", fields.len()),
            ));
        }
        let frame: usize = fields[0].parse().map_err(|_| {
            SceneError::new(
                file,
                n,
                format!("frame {:?} is not a whole number", fields[0]),
            )
        })?;
        let id: u32 = fields[1].parse().map_err(|_| {
            SceneError::new(file, n, format!("id {:?} is not a whole number", fields[1]))
        })?;
        let mut uv = [0.0; 2];
        for (k, name) in ["u", "v"].iter().enumerate() {
            let v: f64 = fields[2 + k].parse().map_err(|_| {
                SceneError::new(
                    file,
                    n,
                    format!("{name} {:?} is not a number", fields[2 + k]),
                )
            })?;
            if !v.is_finite() {
                return Err(SceneError::new(file, n, format!("{name} is not finite")));
            }
            uv[k] = v;
        }
        if frame + 1 < frames.len() {
            return Err(SceneError::new(
                file,
                n,
                format!(
                    "frame {frame} comes after frame {}: rows must be in frame order",
                    frames.len() - 1
                ),
            ));
        }
        if frame as u64 >= limits::MAX_FRAMES {
            return Err(SceneError::new(
                file,
                n,
                format!(
                    "frame {frame} is beyond the bound of {} frames",
                    limits::MAX_FRAMES
                ),
            ));
        }
        frames.resize_with(frames.len().max(frame + 1), Vec::new);
        let current = &mut frames[frame];
        if current.iter().any(|o| o.id == id) {
            return Err(SceneError::new(
                file,
                n,
                format!("feature {id} appears twice in frame {frame}"),
            ));
        }
        current.push(Observation { id, uv });
    }
    if frames.is_empty() {
        return Err(SceneError::new(file, 0, "no observations"));
    }
    Ok(frames)
}

/// Writes observations as `tracks.csv` (pixel positions to 1/1000 px).
pub fn write_tracks(frames: &[Vec<Observation<f64>>]) -> String {
    let mut out = String::from("frame,id,u,v\n");
    for (f, obs) in frames.iter().enumerate() {
        for o in obs {
            out.push_str(&format!("{f},{},{:.3},{:.3}\n", o.id, o.uv[0], o.uv[1]));
        }
    }
    out
}

/// Reads a CSV of `frame,id,x,y,z` rows (`gt/targets.csv`) into per-frame point lists.
///
/// # Errors
/// A [`SceneError`] with the line for a malformed row, a value that is not a finite number, or
/// a frame or id that is not a whole number below its bound ([`limits::MAX_FRAMES`],
/// [`limits::MAX_TARGETS`]).
pub fn read_points_csv(text: &str, file: &Path) -> Result<Vec<Vec<[f64; 3]>>, SceneError> {
    let mut frames: Vec<Vec<[f64; 3]>> = vec![];
    for (i, line) in text.lines().enumerate().skip(1) {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 5 {
            return Err(SceneError::new(
                file,
                n,
                format!("expected 5 fields (frame,id,x,y,z), found {}", f.len()),
            ));
        }
        let num = |k: usize| -> Result<f64, SceneError> {
            f[k].parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    SceneError::new(file, n, format!("{:?} is not a finite number", f[k]))
                })
        };
        let frame = whole(f[0], "frame", limits::MAX_FRAMES, file, n)?;
        let id = whole(f[1], "target id", limits::MAX_TARGETS, file, n)?;
        frames.resize_with(frames.len().max(frame + 1), Vec::new);
        if id != frames[frame].len() {
            return Err(SceneError::new(
                file,
                n,
                format!("target ids must run 0, 1, … within a frame; found {id}"),
            ));
        }
        frames[frame].push([num(2)?, num(3)?, num(4)?]);
    }
    Ok(frames)
}

/// A frame number or id of a ground-truth CSV: a whole number below `bound` (written as an
/// integer or, as some tools do, `12.0`).
fn whole(
    text: &str,
    what: &str,
    bound: u64,
    file: &Path,
    line: usize,
) -> Result<usize, SceneError> {
    let value = text.parse::<f64>().ok().filter(|v| v.fract() == 0.0);
    match value {
        Some(v) if v >= 0.0 && v < bound as f64 => Ok(v as usize),
        _ => Err(SceneError::new(
            file,
            line,
            format!("{what} {text:?} is not a whole number below {bound}"),
        )),
    }
}

/// A point of the true cut in the image (`gt/cut.csv`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutPoint {
    /// The midpoint of the slit's two lips, pixels.
    pub uv: [f64; 2],
    /// Whether the lips there are apart by at least a pixel (the rule of `cut_open_frame`).
    pub open: bool,
}

/// The true cut of one frame: its parts (the slit's trace on the surface, split where the
/// camera does not see it), each a polyline.
pub type CutParts = Vec<Vec<CutPoint>>;

/// Reads `gt/cut.csv` (`frame,part,u,v,open`: the true cut per frame, each part a polyline in
/// row order; `open` 1 where the lips are apart by a pixel or more). The older `frame,u,v`
/// (one part, every point open) is read too.
///
/// # Errors
/// A [`SceneError`] with the line for a malformed row, or a frame or part that is not a whole
/// number below [`limits::MAX_FRAMES`] or [`limits::MAX_CUT_VERTICES`].
pub fn read_cut_csv(text: &str, file: &Path) -> Result<Vec<CutParts>, SceneError> {
    let mut frames: Vec<CutParts> = vec![];
    let header = text.lines().next().unwrap_or_default();
    let with_parts = header
        .split(',')
        .map(str::trim)
        .eq(["frame", "part", "u", "v", "open"]);
    for (i, line) in text.lines().enumerate().skip(1) {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let parsed: Option<Vec<f64>> = f
            .iter()
            .map(|s| s.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect();
        let (part, u, v, open) = match (with_parts, parsed.as_deref()) {
            (true, Some([_, _, u, v, open])) if *open == 0.0 || *open == 1.0 => (
                whole(f[1], "part", limits::MAX_CUT_VERTICES, file, n)?,
                *u,
                *v,
                *open == 1.0,
            ),
            (false, Some([_, u, v])) => (0, *u, *v, true),
            _ => {
                let expected = if with_parts {
                    "expected frame,part,u,v,open as numbers (open 0 or 1)"
                } else {
                    "expected frame,u,v as numbers"
                };
                return Err(SceneError::new(file, n, expected));
            }
        };
        let frame = whole(f[0], "frame", limits::MAX_FRAMES, file, n)?;
        frames.resize_with(frames.len().max(frame + 1), Vec::new);
        let parts = &mut frames[frame];
        parts.resize_with(parts.len().max(part + 1), Vec::new);
        parts[part].push(CutPoint { uv: [u, v], open });
    }
    // A part with no row (numbers skipped) is dropped.
    for parts in &mut frames {
        parts.retain(|p| !p.is_empty());
    }
    Ok(frames)
}

/// A feature the generator made jump (`gt/outliers.csv`): a tracking failure by construction,
/// which the detector's temporal filter is there to take out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrueOutlier {
    /// The feature's id, as in `tracks.csv`.
    pub id: u32,
    /// The first frame it is reported off its true position.
    pub start: u32,
    /// Frames it stays off (then it is reported where it is again).
    pub frames: u32,
    /// What is added to its observation meanwhile, pixels.
    pub jump: [f64; 2],
}

impl TrueOutlier {
    /// Whether it is reported off its true position at `frame`.
    pub fn is_off_at(&self, frame: u32) -> bool {
        frame >= self.start && frame - self.start < self.frames
    }
}

const OUTLIERS_HEADER: &str = "id,start,frames,du,dv";

/// Writes `gt/outliers.csv` (`id,start,frames,du,dv`, one row per jumping feature, by id).
pub fn write_outliers_csv(outliers: &[TrueOutlier]) -> String {
    let mut rows: Vec<&TrueOutlier> = outliers.iter().collect();
    rows.sort_by_key(|o| o.id);
    let mut out = format!("{OUTLIERS_HEADER}\n");
    for o in rows {
        out.push_str(&format!(
            "{},{},{},{:.3},{:.3}\n",
            o.id, o.start, o.frames, o.jump[0], o.jump[1]
        ));
    }
    out
}

/// Reads `gt/outliers.csv` ([`write_outliers_csv`]).
///
/// # Errors
/// A [`SceneError`] with the line for another header, a malformed row, an id, start or length
/// that is not a whole number (ids below [`limits::MAX_FEATURES`], frames below
/// [`limits::MAX_FRAMES`]), a jump that is not a finite number, or an id listed twice.
pub fn read_outliers_csv(text: &str, file: &Path) -> Result<Vec<TrueOutlier>, SceneError> {
    let header = text.lines().next().unwrap_or_default();
    if !header
        .split(',')
        .map(str::trim)
        .eq(OUTLIERS_HEADER.split(','))
    {
        return Err(SceneError::new(
            file,
            1,
            format!("expected the header {OUTLIERS_HEADER}"),
        ));
    }
    let mut out: Vec<TrueOutlier> = vec![];
    for (i, line) in text.lines().enumerate().skip(1) {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let [id, start, frames, du, dv] = f.as_slice() else {
            return Err(SceneError::new(file, n, "expected id,start,frames,du,dv"));
        };
        let jump = [du, dv].map(|s| s.parse::<f64>().ok().filter(|v| v.is_finite()));
        let [Some(du), Some(dv)] = jump else {
            return Err(SceneError::new(file, n, "du and dv must be finite numbers"));
        };
        let outlier = TrueOutlier {
            id: whole(id, "id", limits::MAX_FEATURES, file, n)? as u32,
            start: whole(start, "start", limits::MAX_FRAMES, file, n)? as u32,
            frames: whole(frames, "frames", limits::MAX_FRAMES, file, n)? as u32,
            jump: [du, dv],
        };
        if out.iter().any(|o| o.id == outlier.id) {
            return Err(SceneError::new(
                file,
                n,
                format!("feature {} is listed twice", outlier.id),
            ));
        }
        out.push(outlier);
    }
    Ok(out)
}

/// A triangulated surface.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Triangles (0-based vertex indices).
    pub triangles: Vec<[u32; 3]>,
}

/// Reads a triangle surface from a minimal OBJ (`v x y z`, `f a b c`, 1-based).
///
/// # Errors
/// A [`SceneError`] with the line for a malformed record or an index out of range.
pub fn read_obj(text: &str, file: &Path) -> Result<Surface, SceneError> {
    let (mut v, mut f) = (vec![], vec![]);
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Option<Vec<f64>> = it
                    .map(|s| s.parse().ok().filter(|x: &f64| x.is_finite()))
                    .collect();
                match c.as_deref() {
                    Some([x, y, z]) => v.push([*x, *y, *z]),
                    _ => {
                        return Err(SceneError::new(
                            file,
                            n,
                            "a vertex needs three finite numbers",
                        ));
                    }
                }
            }
            Some("f") => {
                let c: Option<Vec<u32>> = it
                    .map(|s| s.split('/').next().and_then(|k| k.parse::<u32>().ok()))
                    .collect();
                match c.as_deref() {
                    Some([a, b, c]) if [*a, *b, *c].iter().all(|&k| k >= 1) => {
                        f.push([a - 1, b - 1, c - 1])
                    }
                    _ => {
                        return Err(SceneError::new(
                            file,
                            n,
                            "a face needs three 1-based vertex indices",
                        ));
                    }
                }
            }
            _ => {}
        }
    }
    if let Some((k, _)) = f
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&i| i as usize >= v.len()))
    {
        return Err(SceneError::new(
            file,
            0,
            format!(
                "face {} refers to a vertex beyond the {} given",
                k + 1,
                v.len()
            ),
        ));
    }
    Ok(Surface {
        positions: v,
        triangles: f,
    })
}

/// Writes a triangle surface as OBJ (coordinates to 1 µm when in metres).
pub fn write_obj(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> String {
    let mut out = String::new();
    for p in positions {
        out.push_str(&format!("v {:.7} {:.7} {:.7}\n", p[0], p[1], p[2]));
    }
    for t in triangles {
        out.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tracks_round_trip_and_errors_name_the_line() {
        let frames = vec![
            vec![
                Observation {
                    id: 0,
                    uv: [1.0, 2.0],
                },
                Observation {
                    id: 3,
                    uv: [4.5, 6.25],
                },
            ],
            vec![Observation {
                id: 3,
                uv: [4.0, 6.0],
            }],
        ];
        let text = write_tracks(&frames);
        let back = read_tracks(&text, Path::new("t.csv")).unwrap();
        assert_eq!(back, frames);
        let err = read_tracks(
            "frame,id,u,v\n0,1,2.0,3.0\n0,2,abc,3.0\n",
            Path::new("t.csv"),
        )
        .unwrap_err();
        assert_eq!(err.line, 3);
        assert!(err.message.contains("abc"), "{err}");
        let err = read_tracks("frame,id,u,v\n0,1,2.0\n", Path::new("t.csv")).unwrap_err();
        assert_eq!(err.line, 2);
        let err = read_tracks("frame,id,u,v\n1,1,2,2\n0,1,2,2\n", Path::new("t.csv")).unwrap_err();
        assert_eq!(err.line, 3);
        let err = read_tracks("frame,id,u,v\n0,1,2,2\n0,1,3,3\n", Path::new("t.csv")).unwrap_err();
        assert!(err.message.contains("twice"));
        assert_eq!(
            err.to_string(),
            "t.csv:3: feature 1 appears twice in frame 0"
        );
    }

    #[test]
    fn ground_truth_frames_and_ids_are_bounded() {
        // Once cast to an index, 1e19 overflowed `frame + 1`; 1e12 asked for a terabyte.
        for row in [
            "1e19,0,0,0,0",
            "1000000000000,0,0,0,0",
            "-1,0,0,0,0",
            "0.5,0,0,0,0",
        ] {
            let text = format!("frame,id,x,y,z\n0,0,0,0,0\n{row}\n");
            let err = read_points_csv(&text, Path::new("t.csv")).unwrap_err();
            assert_eq!(err.line, 3, "{err}");
            assert!(err.message.contains("frame"), "{err}");
        }
        let err =
            read_points_csv("frame,id,x,y,z\n0,1e19,0,0,0\n", Path::new("t.csv")).unwrap_err();
        assert!(err.message.contains("target id"), "{err}");
        let err = read_cut_csv("frame,u,v\n1e12,1,2\n", Path::new("c.csv")).unwrap_err();
        assert_eq!(
            (err.line, err.file.as_path()),
            (2, Path::new("c.csv")),
            "{err}"
        );
        let err =
            read_cut_csv("frame,part,u,v,open\n0,1e9,1,2,1\n", Path::new("c.csv")).unwrap_err();
        assert!(err.message.contains("part"), "{err}");
        let err =
            read_cut_csv("frame,part,u,v,open\n0,0,1,2,0.5\n", Path::new("c.csv")).unwrap_err();
        assert!(err.message.contains("open 0 or 1"), "{err}");
        let ok = read_points_csv("frame,id,x,y,z\n1.0,0.0,1,2,3\n", Path::new("t.csv")).unwrap();
        assert_eq!(ok, vec![vec![], vec![[1.0, 2.0, 3.0]]]);
    }

    #[test]
    fn cut_csv_parts_and_the_older_format() {
        let text = "frame,part,u,v,open\n0,0,1,2,0\n0,0,3,4,1\n0,1,5,6,1\n2,0,7,8,0\n";
        let frames = read_cut_csv(text, Path::new("c.csv")).unwrap();
        let p = |u: f64, v: f64, open: bool| CutPoint { uv: [u, v], open };
        assert_eq!(
            frames,
            vec![
                vec![
                    vec![p(1.0, 2.0, false), p(3.0, 4.0, true)],
                    vec![p(5.0, 6.0, true)]
                ],
                vec![],
                vec![vec![p(7.0, 8.0, false)]],
            ]
        );
        let old = read_cut_csv("frame,u,v\n1,1,2\n1,3,4\n", Path::new("c.csv")).unwrap();
        assert_eq!(
            old,
            vec![vec![], vec![vec![p(1.0, 2.0, true), p(3.0, 4.0, true)]]]
        );
    }

    #[test]
    fn obj_round_trip() {
        let pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]];
        let tri = vec![[0, 1, 2]];
        let s = read_obj(&write_obj(&pos, &tri), Path::new("s.obj")).unwrap();
        assert_eq!((s.positions, s.triangles), (pos, tri));
        assert!(read_obj("v 0 0 0\nf 1 2 3\n", Path::new("s.obj")).is_err());
    }

    #[test]
    fn outliers_round_trip_and_errors_name_the_line() {
        let listed = vec![
            TrueOutlier {
                id: 7,
                start: 3,
                frames: 2,
                jump: [1.5, -12.25],
            },
            TrueOutlier {
                id: 2,
                start: 10,
                frames: 5,
                jump: [-3.0, 0.0],
            },
        ];
        let text = write_outliers_csv(&listed);
        assert!(text.starts_with("id,start,frames,du,dv\n2,10,"), "{text}");
        let read = read_outliers_csv(&text, Path::new("o.csv")).unwrap();
        assert_eq!(read, vec![listed[1], listed[0]]);
        assert!(read[1].is_off_at(3) && read[1].is_off_at(4));
        assert!(!read[1].is_off_at(2) && !read[1].is_off_at(5));
        // None listed: the header alone.
        assert_eq!(
            read_outliers_csv(&write_outliers_csv(&[]), Path::new("o.csv")),
            Ok(vec![])
        );
        for (text, line, says) in [
            ("frame,id\n", 1, "header"),
            ("id,start,frames,du,dv\n1,2,3,4\n", 2, "expected"),
            ("id,start,frames,du,dv\n1,2,3,4,nan\n", 2, "finite"),
            ("id,start,frames,du,dv\n1.5,2,3,4,5\n", 2, "id"),
            (
                "id,start,frames,du,dv\n1,2,3,4,5\n\n1,4,3,4,5\n",
                4,
                "twice",
            ),
        ] {
            let e = read_outliers_csv(text, Path::new("o.csv")).unwrap_err();
            assert_eq!(e.line, line, "{text:?}: {e}");
            assert!(e.to_string().contains(says), "{text:?}: {e}");
        }
    }
}
