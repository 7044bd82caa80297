//! Drawing one variant of a family: the draws of its stream, the base scenario's geometry it
//! varies, the variant derived from the base (noise, motion, camera, slit), and the checks it
//! must pass to be accepted.

use std::fmt::Write as _;
use std::path::Path;

use incise_core::Camera;
use incise_core::nalgebra::{Rotation3, Unit, Vector3};

use crate::generate::live::{extent, plane_growth_axis, region_sides};
use crate::generate::pipeline::{prepare_scenario, spec_camera};
use crate::generate::scenario::{CameraSpec, Scenario, SlitSection};
use crate::generate::tracking::DepthBuffer;
use crate::render::silhouette;
use crate::rng::Rng;

use super::{Family, Kind};

/// The uniform draws of one attempt at a variant, in `[0, 1)`, always all taken in this
/// order so that a range left out does not shift the others.
pub(super) struct Draws {
    noise: f64,
    dropout: f64,
    outliers: f64,
    pull: f64,
    oblique: f64,
    oblique_axis: f64,
    shift: f64,
    length: f64,
    seed: u64,
}

impl Draws {
    pub(super) fn take(rng: &mut Rng) -> Draws {
        Draws {
            noise: rng.uniform(),
            dropout: rng.uniform(),
            outliers: rng.uniform(),
            pull: rng.uniform(),
            oblique: rng.uniform(),
            oblique_axis: rng.uniform(),
            shift: rng.uniform(),
            length: rng.uniform(),
            // Small enough to read in a scenario file.
            seed: rng.next_u64() >> 32,
        }
    }
}

pub(super) fn lerp(range: [f64; 2], t: f64) -> f64 {
    range[0] + (range[1] - range[0]) * t
}

/// What the family needs to know of the base's object once: its model, the real object's
/// bounding box, and how much of it the base camera sees.
pub(super) struct BaseGeometry {
    /// The model's rest nodes.
    pub(super) model_nodes: Vec<[f64; 3]>,
    /// The model's boundary triangles.
    pub(super) model_triangles: Vec<[u32; 3]>,
    /// Bounding box of the real object before the slit.
    pub(super) real_extent: [[f64; 3]; 2],
    /// Pixels of the object's rest silhouette in the base camera.
    pub(super) seen: usize,
}

/// The first frame any grasp starts.
pub(super) fn first_start(s: &Scenario) -> Option<u32> {
    s.motion.grasp.iter().map(|g| g.start).min()
}

/// One variant from one set of draws (not yet checked).
pub(super) fn derive(
    family: &Family,
    base: &Scenario,
    geometry: &BaseGeometry,
    index: usize,
    kind: Kind,
    d: &Draws,
) -> Result<Scenario, String> {
    let mut s = base.clone();
    s.name = family.variant_name(index);
    s.seed = d.seed;
    let mut notes = String::new();
    let t = &mut s.tracking;
    if let Some(r) = family.noise_px {
        t.noise_px = lerp(r, d.noise);
    }
    if let Some(r) = family.dropout {
        t.dropout = lerp(r, d.dropout);
    }
    if let Some(r) = family.outlier_fraction {
        t.outlier_fraction = lerp(r, d.outliers);
    }
    let _ = write!(
        notes,
        "noise {:.2} px, dropout {:.1} %, outliers {:.1} %",
        t.noise_px,
        100.0 * t.dropout,
        100.0 * t.outlier_fraction
    );

    // Retime the pull: every grasp's start and end scaled about the first start.
    let first = first_start(base).unwrap_or(0);
    let last = base.motion.grasp.iter().map(|g| g.end).max().unwrap_or(0);
    let span = last.saturating_sub(first);
    let pull = match family.pull_frames {
        Some([lo, hi]) => (lo + (d.pull * f64::from(hi - lo + 1)) as u32).min(hi),
        None => span,
    };
    let retime = |frame: u32| -> u32 {
        if span == 0 {
            return frame;
        }
        let scaled = f64::from(first)
            + (f64::from(frame) - f64::from(first)) * f64::from(pull) / f64::from(span);
        scaled.round().max(0.0) as u32
    };
    if family.pull_frames.is_some() {
        for g in &mut s.motion.grasp {
            if span == 0 {
                g.end = g.start + pull;
            } else {
                g.start = retime(g.start);
                g.end = retime(g.end).max(g.start);
            }
        }
        let _ = write!(notes, ", pull over {pull} frames");
    }

    // An intact variant's grasps move the given share of the base's motion.
    let f = family.intact_pull;
    if kind == Kind::Intact && f != 1.0 {
        for g in &mut s.motion.grasp {
            g.displacement = g.displacement.map(|x| x * f);
            g.rotation_degrees *= f;
        }
        let _ = write!(notes, ", grasps moved ×{f:.2}");
    }

    // Turn the camera about its target.
    if let Some(r) = family.oblique_degrees {
        let angle = lerp(r, d.oblique);
        s.camera = turned(
            &base.camera,
            angle,
            2.0 * std::f64::consts::PI * d.oblique_axis,
        );
        let _ = write!(notes, ", camera turned {angle:.1}°");
    }

    s.slit = match kind {
        Kind::Intact => None,
        Kind::PreCut | Kind::Live => {
            let mut sl = base.slit.clone().expect("checked: the base has a slit");
            if sl.image.is_some() && sl.camera.is_none() && s.camera != base.camera {
                sl.camera = Some(base.camera.clone());
            }
            let slit_camera = spec_camera(sl.camera.as_ref().unwrap_or(&s.camera))
                .map_err(|e| format!("[slit] camera: {e}"))?;
            if let Some(r) = family.cut_length {
                let f = lerp(r, d.length);
                shorten(&mut sl, f, geometry, &slit_camera)?;
                let _ = write!(notes, ", cut length ×{f:.2}");
            }
            if let Some(r) = family.cut_shift {
                let f = lerp(r, d.shift);
                shift(&mut sl, f, geometry, &slit_camera);
                let _ = write!(notes, ", cut shifted {f:+.3}");
            }
            sl.grow = match kind {
                Kind::Live => {
                    let [a, b] = match base.slit.as_ref().and_then(|b| b.grow) {
                        Some([a, b]) if family.pull_frames.is_some() => [retime(a), retime(b)],
                        Some(g) => g,
                        None => [
                            first + (0.1 * f64::from(pull)).round() as u32,
                            first + (0.9 * f64::from(pull)).round() as u32,
                        ],
                    };
                    let end = b.max(a + 1).min(s.frames - 1);
                    let start = a.min(end.saturating_sub(1));
                    let _ = write!(notes, ", cut grows over frames {start}–{end}");
                    Some([start, end])
                }
                _ => None,
            };
            Some(sl)
        }
    };
    let what = match kind {
        Kind::Live => "live cut",
        k => k.name(),
    };
    s.description = format!("{} variant {index} ({what}): {notes}", family.name);
    Ok(s)
}

/// `c` turned by `degrees` about its target, about the axis across the view at angle `phi`
/// (radians) from the image's x axis; its up vector turns with it.
pub(super) fn turned(c: &CameraSpec, degrees: f64, phi: f64) -> CameraSpec {
    let eye = Vector3::from(c.eye);
    let target = Vector3::from(c.target);
    let z = (target - eye).normalize();
    let x = z.cross(&Vector3::from(c.up)).normalize();
    let y = z.cross(&x);
    let axis = Unit::new_normalize(x * phi.cos() + y * phi.sin());
    let rot = Rotation3::from_axis_angle(&axis, degrees.to_radians());
    let e = target + rot * (eye - target);
    let up = rot * Vector3::from(c.up);
    CameraSpec {
        eye: [e.x, e.y, e.z],
        up: [up.x, up.y, up.z],
        ..c.clone()
    }
}

/// Pixels of the model's rest nodes through `camera`.
pub(super) fn projected(nodes: &[[f64; 3]], camera: &Camera<f64>) -> Vec<[f64; 2]> {
    nodes
        .iter()
        .filter_map(|p| camera.project(&Vector3::from(*p), 0).ok())
        .map(|uv| [uv.x, uv.y])
        .collect()
}

/// Shortens the slit to `fraction` of its length (see [`Family::cut_length`]).
pub(super) fn shorten(
    sl: &mut SlitSection,
    fraction: f64,
    geometry: &BaseGeometry,
    camera: &Camera<f64>,
) -> Result<(), String> {
    match (sl.image, sl.normal, sl.region) {
        (Some([a, b]), _, _) => {
            // Where the segment enters the object's rest silhouette.
            let mask = silhouette(camera, &geometry.model_nodes, &geometry.model_triangles);
            let steps = ((b[0] - a[0]).hypot(b[1] - a[1]).ceil() as usize).max(1);
            let entry = (0..=steps)
                .map(|i| i as f64 / steps as f64)
                .find(|&t| {
                    let (u, v) = (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]));
                    u >= 0.0 && v >= 0.0 && mask.get(u as u32, v as u32)
                })
                .ok_or("cut_length: the slit's image segment misses the object")?;
            let t = entry + fraction * (1.0 - entry);
            sl.image = Some([a, [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]]);
            Ok(())
        }
        (None, Some(normal), Some(mut region)) => {
            let e = &geometry.real_extent;
            if let Ok(s) = plane_growth_axis(normal, &region, e) {
                let k = s.axis;
                if s.past_min {
                    region[1][k] = e[0][k] + fraction * (region[1][k] - e[0][k]);
                } else {
                    region[0][k] = e[1][k] - fraction * (e[1][k] - region[0][k]);
                }
            } else {
                let k = region_sides(normal, &region, e)
                    .into_iter()
                    .filter(|s| !s.past_min && !s.past_max)
                    .map(|s| s.axis)
                    .max_by(|&i, &j| {
                        (region[1][i] - region[0][i]).total_cmp(&(region[1][j] - region[0][j]))
                    })
                    .ok_or(
                        "cut_length: the slit's region neither starts at the object's boundary \
                         nor lies inside it along any axis in its plane",
                    )?;
                let (c, h) = (
                    (region[0][k] + region[1][k]) / 2.0,
                    (region[1][k] - region[0][k]) / 2.0,
                );
                region[0][k] = c - fraction * h;
                region[1][k] = c + fraction * h;
            }
            sl.region = Some(region);
            Ok(())
        }
        _ => Err("cut_length: the base slit is neither an image segment nor a plane".into()),
    }
}

/// Moves the slit across itself by `fraction` of the object's size across it (see
/// [`Family::cut_shift`]).
pub(super) fn shift(
    sl: &mut SlitSection,
    fraction: f64,
    geometry: &BaseGeometry,
    camera: &Camera<f64>,
) {
    if let Some([a, b]) = sl.image {
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let m = [-(b[1] - a[1]) / len, (b[0] - a[0]) / len];
        let across = projected(&geometry.model_nodes, camera)
            .iter()
            .map(|p| p[0] * m[0] + p[1] * m[1])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
                (lo.min(c), hi.max(c))
            });
        let delta = fraction * (across.1 - across.0);
        let moved = |p: [f64; 2]| [p[0] + delta * m[0], p[1] + delta * m[1]];
        sl.image = Some([moved(a), moved(b)]);
    } else if let (Some(point), Some(normal)) = (sl.point, sl.normal) {
        let n = Vector3::from(normal).normalize();
        let along = geometry
            .model_nodes
            .iter()
            .map(|p| Vector3::from(*p).dot(&n))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
                (lo.min(c), hi.max(c))
            });
        let delta = n * (fraction * (along.1 - along.0));
        let moved = |p: [f64; 3]| [p[0] + delta.x, p[1] + delta.y, p[2] + delta.z];
        sl.point = Some(moved(point));
        sl.region = sl.region.map(|r| [moved(r[0]), moved(r[1])]);
    }
}

/// Whether a variant makes sense (see the module documentation); the reason if not.
pub(super) fn sensible(
    s: &Scenario,
    base_dir: &Path,
    geometry: &BaseGeometry,
) -> Result<(), String> {
    let p = prepare_scenario(s.clone(), base_dir).map_err(|e| e.0)?;
    let meshes = &p.meshes;
    let seen = silhouette(&p.camera, &geometry.model_nodes, &geometry.model_triangles).count();
    if 2 * seen < geometry.seen {
        return Err(format!(
            "the camera sees {seen} pixels of the object at rest, less than half of the base \
             camera's {}",
            geometry.seen
        ));
    }
    if meshes.lips.is_empty() {
        return Ok(());
    }
    let prescribed: std::collections::HashSet<u32> = p.prescribed.iter().map(|q| q.0).collect();
    // A pair in a held or grasped box is pinned shut (both lips sit in the box); a slit
    // moved into a box would not open. A few are tolerated: a slit next to a grasp (the
    // liver's, cut into a coarse mesh) may touch it.
    let pinned = meshes
        .lips
        .iter()
        .filter(|&&(v, c)| prescribed.contains(&v) || prescribed.contains(&c))
        .count();
    if 10 * pinned > meshes.lips.len() {
        return Err(format!(
            "{pinned} of the slit's {} node pairs are held or grasped: it cannot open",
            meshes.lips.len()
        ));
    }
    let triangles: Vec<[u32; 3]> = meshes.real.boundary().iter().map(|b| b.0).collect();
    let depth = DepthBuffer::render(&p.camera, &meshes.real.nodes, &triangles);
    let e = extent(&meshes.real.nodes);
    let tolerance = 0.05
        * (0..3)
            .map(|k| e[1][k] - e[0][k])
            .fold(f64::INFINITY, f64::min);
    let outer: std::collections::HashSet<u32> =
        meshes.fine.boundary().iter().flat_map(|b| b.0).collect();
    let seen_lips = meshes
        .lips
        .iter()
        .filter(|&&(v, _)| outer.contains(&v))
        .filter(|&&(v, _)| {
            depth
                .visible(&p.camera, meshes.real.nodes[v as usize], tolerance)
                .is_some()
        })
        .count();
    if seen_lips < 2 {
        return Err(format!(
            "{seen_lips} lip(s) of the slit are seen at rest: the cut line is not in view"
        ));
    }
    Ok(())
}
