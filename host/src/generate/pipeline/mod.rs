//! `incise gen`: simulate the scenario's real object frame by frame and write the scene.
//!
//! Here: simulating a scenario frame by frame ([`simulate`]) and generating its scene
//! ([`generate`]); `prepare`: the real object and the model at rest, before the first frame
//! (meshes, slit, camera); `write`: the scene's files ([`write_scene`]).

mod prepare;
mod trace;
mod write;

pub use prepare::{
    Meshes, Prepared, held_nodes, object_meshes, prepare, prepare_scenario, rest_silhouette_dice,
    scenario_camera, spec_camera,
};
pub use write::{Generated, header_prefix, rebase_mesh_paths, write_scene};

use std::fmt;
use std::io::Write;
use std::path::Path;

use incise_core::Camera;
use incise_core::nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use indicatif::{ProgressBar, ProgressStyle};

use crate::generate::live::{self};
use crate::generate::object::{interpolate, signed_volume6};
use crate::generate::scenario::{GraspSpec, Scenario};
use crate::generate::sim::Simulator;

/// A failure of the generator, with what it was doing.
#[derive(Debug)]
pub struct GenError(pub String);

impl fmt::Display for GenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for GenError {}

fn err(e: impl fmt::Display) -> GenError {
    GenError(e.to_string())
}

/// An error about the file at `path`: `path: e`.
fn at_file(path: &Path) -> impl Fn(&dyn fmt::Display) -> GenError + '_ {
    move |e| GenError(format!("{}: {e}", path.display()))
}

/// Writes `contents` to `path`; an error names the file.
fn write_file(path: &Path, contents: impl AsRef<[u8]>) -> Result<(), GenError> {
    std::fs::write(path, contents).map_err(|e| at_file(path)(&e))
}

/// Cosine ramp from 0 at `start` to 1 at `end`.
fn ramp(frame: u32, start: u32, end: u32) -> f64 {
    if frame <= start {
        0.0
    } else if frame >= end {
        1.0
    } else {
        let t = f64::from(frame - start) / f64::from(end - start);
        0.5 * (1.0 - (std::f64::consts::PI * t).cos())
    }
}

/// Where a grasped node at rest position `p` is at `frame`.
fn grasped_position(g: &GraspSpec, p: [f64; 3], frame: u32) -> [f64; 3] {
    let s = ramp(frame, g.start, g.end);
    let c = [0, 1, 2].map(|k| (g.region[0][k] + g.region[1][k]) / 2.0);
    let axis = Unit::new_normalize(Vector3::from(g.axis));
    let rot = Rotation3::from_axis_angle(&axis, s * g.rotation_degrees.to_radians());
    let q = rot * (Vector3::from(p) - Vector3::from(c)) + Vector3::from(c);
    [0, 1, 2].map(|k| q[k] + s * g.displacement[k])
}

/// The real object simulated over every frame, in memory: what the scene's files, its
/// pictures and its video are made from.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// The scenario.
    pub scenario: Scenario,
    /// The camera.
    pub camera: Camera<f64>,
    /// The model and the real object, at rest.
    pub meshes: Meshes,
    /// Boundary triangles of the real mesh (outward) with their tetrahedra.
    pub boundary: Vec<([u32; 3], usize)>,
    /// Node positions of the real mesh, every frame (frame 0 is rest).
    pub positions: Vec<Vec<[f64; 3]>>,
    /// Depth tolerance of the visibility test, metres.
    pub tolerance: f64,
}

/// Which mesh models the object in the scene written from a simulation (`incise gen
/// --model-mesh`, the report's mesh-resolution axis): the truth, the tracks and the camera
/// stay the same, so that models of one object can be compared against one ground truth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelMesh {
    /// The scenario's own model mesh.
    Scenario,
    /// The scenario's model mesh with every tetrahedron split into eight.
    Refined,
    /// The real object's own fine mesh before its slit (for the liver, SOFA's fine liver),
    /// which the ground truth is simulated on.
    Fine,
}

impl ModelMesh {
    /// Its value of `--model-mesh`, `None` for the scenario's own (the option left out).
    pub fn option(self) -> Option<&'static str> {
        match self {
            ModelMesh::Scenario => None,
            ModelMesh::Refined => Some("refined"),
            ModelMesh::Fine => Some("fine"),
        }
    }
}

impl Simulation {
    /// Models the object by `mesh` instead of the scenario's model mesh: its held nodes found
    /// anew, and the room for a cut's new nodes and tetrahedra grown with the cut's area in
    /// elements (the node ratio to the power 2/3), from the scenario's own capacities.
    pub fn remodel(&mut self, mesh: ModelMesh) {
        let coarse = &self.meshes.model;
        let model = match mesh {
            ModelMesh::Scenario => return,
            ModelMesh::Refined => coarse.refine(),
            ModelMesh::Fine => self.meshes.fine.clone(),
        };
        let growth = (model.nodes.len() as f64 / coarse.nodes.len() as f64).powf(2.0 / 3.0);
        let capacities = &mut self.scenario.capacities;
        capacities.cut_nodes = (capacities.cut_nodes as f64 * growth).ceil() as usize;
        capacities.cut_tets = (capacities.cut_tets as f64 * growth).ceil() as usize;
        self.meshes.model_fixed = held_nodes(&model.nodes, &self.scenario.motion.held);
        self.meshes.model = model;
        // Written beside the scene as `model.msh`.
        self.meshes.model_mesh_file = None;
    }

    /// How far the real object is stretched ([`principal_stretch`] of each tetrahedron; 1 at
    /// rest): the largest stretch over every element and frame, the frame it is reached in, and
    /// the stretch that 1 % of the object's volume exceeds in that frame. The largest is where
    /// strain concentrates (at a slit's tip, at the edge of a grasped region); the volume share
    /// says how much of the tissue is stretched that far. What a scene asks of its tissue, to
    /// hold against what the tissue bears (`fixtures/README.md`).
    pub fn stretch(&self) -> Stretch {
        let real = &self.meshes.real;
        let corners = |x: &[[f64; 3]], t: &[u32; 4]| t.map(|v| x[v as usize]);
        let stretches = |x: &[[f64; 3]]| {
            real.tets
                .iter()
                .map(|t| principal_stretch(corners(&real.nodes, t), corners(x, t)))
                .collect::<Vec<_>>()
        };
        let mut largest = (1.0, 0);
        for (frame, x) in self.positions.iter().enumerate() {
            for stretch in stretches(x).into_iter().flatten() {
                if stretch > largest.0 {
                    largest = (stretch, frame);
                }
            }
        }
        // The elements of that frame from the most stretched down, until 1 % of the volume.
        let mut by_stretch: Vec<(f64, f64)> = stretches(&self.positions[largest.1])
            .into_iter()
            .zip(&real.tets)
            .filter_map(|(s, t)| {
                let [a, b, c, d] = corners(&real.nodes, t);
                Some((s?, (signed_volume6(a, b, c, d) / 6.0).abs()))
            })
            .collect();
        by_stretch.sort_by(|x, y| y.0.total_cmp(&x.0));
        let volume: f64 = by_stretch.iter().map(|e| e.1).sum();
        let mut above = 0.0;
        let mut one_percent = 1.0;
        for (stretch, v) in by_stretch {
            above += v;
            one_percent = stretch;
            if above >= 0.01 * volume {
                break;
            }
        }
        Stretch {
            largest: largest.0,
            frame: largest.1,
            one_percent,
        }
    }

    /// Boundary triangles of the real mesh.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        self.boundary.iter().map(|b| b.0).collect()
    }

    /// The material point of the real surface seen at pixel `uv` in frame 0, as (tetrahedron,
    /// barycentric weights): where a tracked feature found at `uv` really is.
    pub fn material_point(&self, uv: [f64; 2]) -> Option<(usize, [f64; 4])> {
        let (origin, dir) = self.camera.ray(uv[0], uv[1]);
        let x = &self.positions[0];
        let mut best: Option<(f64, usize)> = None;
        for &(tri, t) in &self.boundary {
            let p = tri.map(|v| Vector3::from(x[v as usize]));
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            let h = dir.cross(&e2);
            let det = e1.dot(&h);
            if det.abs() < 1e-18 {
                continue;
            }
            let sv = origin - p[0];
            let u = sv.dot(&h) / det;
            let q = sv.cross(&e1);
            let v = dir.dot(&q) / det;
            let dist = e2.dot(&q) / det;
            if u >= 0.0
                && v >= 0.0
                && u + v <= 1.0
                && dist > 0.0
                && best.is_none_or(|(b, _)| dist < b)
            {
                best = Some((dist, t));
            }
        }
        let (dist, t) = best?;
        let hit = origin + dir * dist;
        let tet = self.meshes.real.tets[t];
        let q = tet.map(|v| Vector3::from(x[v as usize]));
        let m =
            incise_core::nalgebra::Matrix3::from_columns(&[q[1] - q[0], q[2] - q[0], q[3] - q[0]]);
        let l = m.try_inverse()? * (hit - q[0]);
        Some((t, [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]))
    }

    /// Pixel of a material point in `frame`.
    pub fn project(&self, frame: usize, point: (usize, [f64; 4])) -> Option<[f64; 2]> {
        let x = self.positions.get(frame)?;
        let p = interpolate(x, self.meshes.real.tets[point.0], point.1);
        let uv = self.camera.project(&Vector3::from(p), 0).ok()?;
        Some([uv.x, uv.y])
    }
}

/// How far a simulation stretches its real object ([`Simulation::stretch`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stretch {
    /// The largest principal stretch of any element in any frame (1 at rest).
    pub largest: f64,
    /// The frame it is reached in.
    pub frame: usize,
    /// The principal stretch that 1 % of the object's volume exceeds in that frame.
    pub one_percent: f64,
}

/// The largest principal stretch of a tetrahedron moved from corners `rest` to `now`: the
/// largest singular value of its deformation gradient `F = Ds Dm⁻¹` (the square root of the
/// largest eigenvalue of `FᵀF`), 1 for a rigid motion. `None` for a degenerate rest element.
pub fn principal_stretch(rest: [[f64; 3]; 4], now: [[f64; 3]; 4]) -> Option<f64> {
    let edges = |p: [[f64; 3]; 4]| {
        let p = p.map(Vector3::from);
        Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]])
    };
    let f = edges(now) * edges(rest).try_inverse()?;
    Some(
        (f.transpose() * f)
            .symmetric_eigenvalues()
            .max()
            .max(0.0)
            .sqrt(),
    )
}

/// Builds the real object of the scenario at `scenario_path` and simulates every frame.
///
/// # Errors
/// A [`GenError`] for a bad scenario, a mesh that cannot be read, or a simulation that does
/// not converge; it names the scenario file.
pub fn simulate(scenario_path: &Path, progress: bool) -> Result<Simulation, GenError> {
    simulate_prepared(prepare(scenario_path)?, progress).map_err(|e| at_file(scenario_path)(&e))
}

/// [`simulate`] for a scenario in memory whose mesh paths are relative to `base`.
///
/// # Errors
/// As [`simulate`].
pub fn simulate_scenario(
    s: &Scenario,
    base: &Path,
    progress: bool,
) -> Result<Simulation, GenError> {
    simulate_prepared(prepare_scenario(s.clone(), base)?, progress)
}

/// Simulates every frame of a prepared scenario. A live cut's pairs are tied until their
/// release frame (see [`live`]): the simulator is rebuilt with the connectivity of the frame
/// whenever pairs are released, and carries on from the previous frame's positions.
///
/// # Errors
/// A [`GenError`] if the simulation does not converge.
pub fn simulate_prepared(prepared: Prepared, progress: bool) -> Result<Simulation, GenError> {
    let Prepared {
        scenario: s,
        camera,
        meshes,
        prescribed,
    } = prepared;
    let (real, lips, release) = (&meshes.real, &meshes.lips, &meshes.release);
    let prescribed_nodes: Vec<u32> = prescribed.iter().map(|p| p.0).collect();
    let build = |frame: u32| {
        Simulator::new(
            &real.nodes,
            &live::tied_tets(&real.tets, lips, release, frame),
            &prescribed_nodes,
            s.object.young,
            s.object.poisson,
        )
        .map_err(|e| GenError(format!("simulator: {e}")))
    };
    let mut simulator = build(0)?;
    let mut open = live::released(release, 0);
    let boundary = real.boundary();
    // Depth tolerance: a fraction of the object's smallest extent.
    let extent = (0..3)
        .map(|k| {
            let (lo, hi) = real
                .nodes
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(p[k]), hi.max(p[k]))
                });
            hi - lo
        })
        .fold(f64::INFINITY, f64::min);
    let tolerance = 0.05 * extent;

    let mut bar = Progress::new(
        progress,
        &s.name,
        "simulating",
        u64::from(s.frames.saturating_sub(1)),
    )?;
    let mut positions = vec![real.nodes.clone()];
    for frame in 1..s.frames {
        let now_open = live::released(release, frame);
        if now_open != open {
            // Pairs released: the new connectivity, from the last frame's state (where each
            // released duplicate still sits on its original).
            open = now_open;
            let last = &positions[positions.len() - 1];
            simulator = build(frame)?;
            let u: Vec<[f64; 3]> = last
                .iter()
                .zip(&real.nodes)
                .map(|(x, r)| [0, 1, 2].map(|k| x[k] - r[k]))
                .collect();
            simulator
                .set_displacements(&u)
                .map_err(|e| GenError(format!("frame {frame}: releasing the cut: {e}")))?;
        }
        let goal: Vec<[f64; 3]> = prescribed
            .iter()
            .map(|&(v, g)| {
                let p = real.nodes[v as usize];
                match g {
                    Some(g) => grasped_position(&s.motion.grasp[g], p, frame),
                    None => p,
                }
            })
            .collect();
        simulator
            .solve(&goal, 60)
            .map_err(|e| GenError(format!("frame {frame}: simulation failed: {e}")))?;
        let mut x = simulator.positions().to_vec();
        // A tied duplicate is in no tetrahedron: it goes where its original goes.
        for (&(v, d), &r) in lips.iter().zip(release) {
            if r > frame {
                x[d as usize] = x[v as usize];
            }
        }
        positions.push(x);
        bar.inc();
    }
    bar.finish();
    Ok(Simulation {
        scenario: s,
        camera,
        meshes,
        boundary,
        positions,
        tolerance,
    })
}

/// Progress over the frames of a phase of `incise gen`: a bar on a terminal; elsewhere (a log,
/// CI) a line on standard error every [`Progress::PLAIN_EVERY`], so that a long run is never
/// silent (a short one prints nothing).
struct Progress {
    bar: ProgressBar,
    /// Without a terminal: what to call the phase, the frames, and when a line was last
    /// printed.
    plain: Option<(String, u64, std::time::Instant)>,
}

impl Progress {
    /// Time between two lines without a terminal.
    const PLAIN_EVERY: std::time::Duration = std::time::Duration::from_secs(10);

    /// Progress of phase `what` of scenario `name` over `len` frames; nothing shown unless
    /// `progress`.
    fn new(progress: bool, name: &str, what: &str, len: u64) -> Result<Progress, GenError> {
        use std::io::IsTerminal;
        if !progress {
            return Ok(Progress {
                bar: ProgressBar::hidden(),
                plain: None,
            });
        }
        if !std::io::stderr().is_terminal() {
            return Ok(Progress {
                bar: ProgressBar::hidden(),
                plain: Some((format!("{name}: {what}"), len, std::time::Instant::now())),
            });
        }
        let b = ProgressBar::new(len);
        b.set_style(
            ProgressStyle::with_template("{prefix:>16} [{bar:30}] {pos}/{len} frames {msg}")
                .map_err(err)?
                .progress_chars("=> "),
        );
        b.set_prefix(name.to_string());
        b.set_message(what.to_string());
        Ok(Progress {
            bar: b,
            plain: None,
        })
    }

    /// One more frame done.
    fn inc(&mut self) {
        self.bar.inc(1);
        if let Some((label, len, last)) = &mut self.plain
            && last.elapsed() >= Self::PLAIN_EVERY
        {
            *last = std::time::Instant::now();
            // Standard error may be closed: progress is not worth an error.
            let _ = writeln!(
                std::io::stderr(),
                "{label}: {}/{len} frames",
                self.bar.position()
            );
        }
    }

    /// The phase is over: the bar goes.
    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// Runs the scenario at `scenario_path` and writes the scene into `out`.
///
/// # Errors
/// A [`GenError`] saying what failed: a bad scenario, a mesh that cannot be read, a
/// simulation that does not converge, a file that cannot be written.
pub fn generate(scenario_path: &Path, out: &Path, progress: bool) -> Result<Generated, GenError> {
    let sim = simulate(scenario_path, progress)?;
    write_scene(&sim, scenario_path, out, progress)
}

/// Generates the scene of a scenario in memory into `out`: writes `out/scenario.toml` (the
/// scenario, its mesh paths made relative to `out`) and then the scene, exactly as
/// `incise gen out/scenario.toml --model-mesh …` would, the object modelled by `mesh`.
/// `base` is the directory the scenario's mesh paths are relative to (the directory of the
/// file it was read from). Creates `out` if needed.
///
/// # Errors
/// As [`generate`], and a [`GenError`] if the scenario cannot be written.
pub fn generate_scenario(
    s: &Scenario,
    base: &Path,
    out: &Path,
    mesh: ModelMesh,
    progress: bool,
) -> Result<Generated, GenError> {
    let mut sim = simulate_scenario(s, base, progress)?;
    sim.remodel(mesh);
    std::fs::create_dir_all(out).map_err(|e| at_file(out)(&e))?;
    // A scene from an earlier scenario goes first: `write_scene` writes `scene.toml` last, so
    // that an interrupted run leaves none, and this one must not leave the old one beside the
    // new scenario, where it would pass for the scene of it (`incise eval` reuses such scenes).
    let old = out.join("scene.toml");
    match std::fs::remove_file(&old) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(at_file(&old)(&e)),
        _ => {}
    }
    let mut written = s.clone();
    rebase_mesh_paths(&mut written, base, out);
    let file = out.join("scenario.toml");
    let option = mesh
        .option()
        .map_or(String::new(), |m| format!(" --model-mesh {m}"));
    let text = format!(
        "# The scenario of this scene, written by incise: `incise gen` on this file{option} \
         regenerates the scene beside it.\n{}",
        written.to_toml().map_err(GenError)?
    );
    write_file(&file, text)?;
    write_scene(&sim, &file, out, progress)
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;

    /// A small band scenario with a camera 20 cm above it, and the given `[slit]` lines.
    fn band_scenario(dir: &Path, slit: &str) -> PathBuf {
        let path = dir.join("scenario.toml");
        std::fs::write(
            &path,
            format!(
                r#"name = "t"
seed = 1
frames = 2
[object]
shape = "band"
size = [0.04, 0.02, 0.006]
fine_cells = [16, 8, 3]
model_cells = [4, 2, 1]
young = 1.0e5
poisson = 0.45
[slit]
{slit}
[motion]
held = [[[-0.001, -0.001, -0.001], [0.0001, 0.021, 0.007]]]
[[motion.grasp]]
region = [[0.0399, -0.001, -0.001], [0.041, 0.021, 0.007]]
displacement = [0.01, 0.0, 0.0]
start = 0
end = 1
[camera]
eye = [0.02, 0.01, 0.2]
target = [0.02, 0.01, 0.0]
up = [0.0, 1.0, 0.0]
focal = 2000.0
width = 640
height = 480
[tracking]
features = 10
noise_px = 0.0
dropout = 0.0
outlier_fraction = 0.0
outlier_jump_px = 0.0
[model]
young = 1.0e5
poisson = 0.45
[solver]
strategy = "refactor"
newton_iterations = 1
line_search_steps = 1
spring_stiffness = 1.0e-4
damping = 0.01
"#
            ),
        )
        .unwrap();
        path
    }

    #[test]
    fn image_slit_runs_along_the_camera_rays_through_the_whole_thickness() {
        let dir = tempfile::tempdir().unwrap();
        // The camera sees x = 0.02 at u = 320 and 10 px per mm; y = 0.01 at v = 240 (v grows
        // toward -y). The segment: from below the band's lower edge (y = 0) to y = 0.015.
        let path = band_scenario(dir.path(), "image = [[320.0, 360.0], [320.0, 190.0]]");
        let p = prepare(&path).unwrap().meshes;
        assert!(!p.lips.is_empty());
        let x = &p.real.nodes;
        // The lips lie in the plane x = 0.02 (the cells are 2.5 mm long), from y = 0 to the
        // slit's end at 15 mm, and through the whole thickness.
        assert!(p.lips.iter().all(|&(v, c)| {
            let q = x[v as usize];
            x[c as usize] == q && (q[0] - 0.02).abs() < 1e-12 && q[1] < 0.0151
        }));
        for z in [0.0, 0.002, 0.004, 0.006] {
            assert!(
                p.lips
                    .iter()
                    .any(|&(v, _)| (x[v as usize][2] - z).abs() < 1e-12),
                "no lip at depth {z}"
            );
        }
        // The slit reaches the end of the segment (the cells are 2.5 mm wide), and beyond it
        // the band stays joined (no lip above 15 mm, checked above).
        assert!(p.lips.iter().any(|&(v, _)| x[v as usize][1] > 0.0124));
        // The same slit as a plane and a box.
        let plane = band_scenario(
            dir.path(),
            "point = [0.02, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\n\
             region = [[0.019, -0.001, -0.001], [0.021, 0.015, 0.007]]",
        );
        let q = prepare(&plane).unwrap().meshes;
        assert_eq!(q.lips, p.lips);
    }

    #[test]
    fn a_slit_is_a_plane_or_an_image_segment_not_both() {
        let dir = tempfile::tempdir().unwrap();
        let both = band_scenario(
            dir.path(),
            "point = [0.02, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\n\
             image = [[320.0, 360.0], [320.0, 190.0]]",
        );
        let e = prepare(&both).unwrap_err();
        assert!(e.0.contains("either"), "{e}");
        let short = band_scenario(dir.path(), "image = [[320.0, 360.0], [320.2, 360.0]]");
        let e = prepare(&short).unwrap_err();
        assert!(e.0.contains("apart"), "{e}");
        let outside = band_scenario(dir.path(), "image = [[10.0, 10.0], [20.0, 10.0]]");
        let e = prepare(&outside).unwrap_err();
        assert!(e.0.contains("nothing is cut"), "{e}");
    }

    /// [`band_scenario`] with a side slit over 75% of the width at x = 2 cm, 8 frames, the far
    /// end pulled 1 cm over frames 0 to 7, and the extra `[slit]` lines `extra`.
    fn side_slit_scenario(dir: &Path, extra: &str) -> PathBuf {
        let path = band_scenario(
            dir,
            &format!(
                "point = [0.02, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\n\
                 region = [[0.019, -0.001, -0.001], [0.021, 0.015, 0.007]]\n{extra}"
            ),
        );
        let text = std::fs::read_to_string(&path)
            .unwrap()
            .replace("frames = 2", "frames = 8")
            .replace("start = 0\nend = 1", "start = 0\nend = 7");
        std::fs::write(&path, text).unwrap();
        path
    }

    /// Rows of `gt/cut.csv` per frame.
    fn cut_rows(dir: &Path, frames: usize) -> Vec<usize> {
        let text = std::fs::read_to_string(dir.join("gt").join("cut.csv")).unwrap();
        let mut rows = vec![0; frames];
        for line in text.lines().skip(1) {
            rows[line.split(',').next().unwrap().parse::<usize>().unwrap()] += 1;
        }
        rows
    }

    #[test]
    fn a_live_cut_opens_as_it_grows_and_ends_where_the_pre_cut_does() {
        let dir = tempfile::tempdir().unwrap();
        let live_dir = dir.path().join("live");
        let cut_dir = dir.path().join("cut");
        std::fs::create_dir_all(&live_dir).unwrap();
        std::fs::create_dir_all(&cut_dir).unwrap();
        let live_path = side_slit_scenario(&live_dir, "grow = [2, 6]");
        let cut_path = side_slit_scenario(&cut_dir, "");

        // Release frames: the slit runs from the band's edge (y = 0) to its front at
        // y = 15 mm (rows every 2.5 mm); the front crosses it over frames 2 to 6, and a pair
        // opens at the first frame the front has reached it (never before frame 3).
        let p = prepare(&live_path).unwrap().meshes;
        assert_eq!(p.release.len(), p.lips.len());
        for (&(v, _), &r) in p.lips.iter().zip(&p.release) {
            let y = p.real.nodes[v as usize][1];
            let want = 2 + ((4.0 * y / 0.015 - 1e-9).ceil() as u32).max(1);
            assert_eq!(r, want, "pair at y = {y}");
        }
        assert_eq!(p.release.iter().min(), Some(&3));
        assert_eq!(p.release.iter().max(), Some(&6));

        let live = simulate(&live_path, false).unwrap();
        let cut = simulate(&cut_path, false).unwrap();
        assert_eq!(live.meshes.lips, cut.meshes.lips);
        let opening = |sim: &Simulation, f: usize| {
            sim.meshes
                .lips
                .iter()
                .map(|&(v, d)| {
                    let (a, b) = (sim.positions[f][v as usize], sim.positions[f][d as usize]);
                    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
                })
                .fold(0.0f64, f64::max)
        };
        // Tied up to the start (the pre-cut slit is already open), open afterwards.
        for f in 0..=2 {
            assert_eq!(opening(&live, f), 0.0, "frame {f}");
        }
        assert!(opening(&cut, 2) > 1e-4);
        for f in 3..8 {
            assert!(opening(&live, f) > 1e-4, "frame {f}");
        }
        // Quasi-static equilibrium does not remember the path: once the whole slit is open
        // and the grasp has stopped, the live cut is where the pre-cut one is.
        let worst = live.positions[7]
            .iter()
            .zip(&cut.positions[7])
            .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs()))
            .fold(0.0f64, f64::max);
        assert!(worst < 1e-8, "{worst:e} m");

        // The true line: nothing before the cut starts, then longer and longer, the whole
        // (pre-cut) line at the end.
        let out_live = dir.path().join("scene-live");
        let out_cut = dir.path().join("scene-cut");
        let g = write_scene(&live, &live_path, &out_live, false).unwrap();
        write_scene(&cut, &cut_path, &out_cut, false).unwrap();
        let (rows_live, rows_cut) = (cut_rows(&out_live, 8), cut_rows(&out_cut, 8));
        assert_eq!(&rows_live[..3], &[0, 0, 0]);
        assert!(rows_live[3] >= 2, "{rows_live:?}");
        assert!(rows_live.windows(2).all(|w| w[0] <= w[1]), "{rows_live:?}");
        assert!(rows_live[3] < rows_live[6], "{rows_live:?}");
        assert_eq!(rows_live[6], rows_cut[6]);
        assert_eq!(rows_live[7], rows_cut[7]);
        assert!(
            g.cut_open_frame.is_some_and(|f| f >= 3),
            "{:?}",
            g.cut_open_frame
        );
    }

    /// The true cut follows the slit's trace on the surface in order: within a part, no
    /// step jumps across the slit (the old order along the image's main direction zig-zagged
    /// wherever the trace was not straight in the image); closed at rest, open once pulled.
    #[test]
    fn the_true_cut_runs_along_the_slit_and_opens_when_pulled() {
        let dir = tempfile::tempdir().unwrap();
        let path = side_slit_scenario(dir.path(), "");
        let sim = simulate(&path, false).unwrap();
        let out = dir.path().join("scene");
        write_scene(&sim, &path, &out, false).unwrap();
        let file = out.join("gt").join("cut.csv");
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(text.starts_with("frame,part,u,v,open\n"));
        let frames = crate::scene::read_cut_csv(&text, &file).unwrap();
        assert_eq!(frames.len(), 8);
        for (f, parts) in frames.iter().enumerate() {
            assert!(!parts.is_empty(), "frame {f}: no true cut");
            for part in parts {
                let steps: Vec<f64> = part
                    .windows(2)
                    .map(|w| (w[1].uv[0] - w[0].uv[0]).hypot(w[1].uv[1] - w[0].uv[1]))
                    .collect();
                let mut sorted = steps.clone();
                sorted.sort_by(f64::total_cmp);
                if let Some(&median) = sorted.get(sorted.len() / 2) {
                    let longest = sorted.last().copied().unwrap_or(0.0);
                    assert!(
                        longest <= 3.0 * median.max(1.0),
                        "frame {f}: a step of {longest:.1} px, median {median:.1}"
                    );
                }
            }
        }
        let open = |f: usize| frames[f].iter().flatten().filter(|p| p.open).count();
        assert_eq!(open(0), 0, "the slit is closed at rest");
        assert!(open(7) >= 3, "{} open points once pulled", open(7));
    }

    #[test]
    fn a_live_cut_needs_a_start_at_the_boundary_and_a_grow_range_in_the_frames() {
        let dir = tempfile::tempdir().unwrap();
        let late = side_slit_scenario(dir.path(), "grow = [2, 8]");
        let e = prepare(&late).unwrap_err();
        assert!(e.0.contains("start < end < frames"), "{e}");
        let middle = band_scenario(
            dir.path(),
            "point = [0.02, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\n\
             region = [[0.019, 0.005, -0.001], [0.021, 0.015, 0.007]]\ngrow = [0, 1]",
        );
        let e = prepare(&middle).unwrap_err();
        assert!(e.0.contains("cannot tell where the slit starts"), "{e}");
    }

    /// A tetrahedron stretched by 1.5 along one axis, squeezed to 0.8 along another and turned
    /// about a third: its largest principal stretch is 1.5 whatever the turn; a rigid motion
    /// gives 1 and a flat rest element nothing.
    #[test]
    fn principal_stretch_is_the_largest_singular_value() {
        let rest = [
            [0.0, 0.0, 0.0],
            [1.0, 0.1, 0.0],
            [0.2, 1.0, 0.1],
            [0.1, 0.3, 1.0],
        ];
        let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.7);
        let map = |scale: [f64; 3]| {
            rest.map(|p| {
                let q = turn * Vector3::new(scale[0] * p[0], scale[1] * p[1], scale[2] * p[2]);
                [q.x + 0.3, q.y - 2.0, q.z + 1.0]
            })
        };
        let stretched = principal_stretch(rest, map([1.5, 0.8, 1.0])).unwrap();
        assert!((stretched - 1.5).abs() < 1e-12, "{stretched}");
        let rigid = principal_stretch(rest, map([1.0, 1.0, 1.0])).unwrap();
        assert!((rigid - 1.0).abs() < 1e-12, "{rigid}");
        let flat = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        assert_eq!(principal_stretch(flat, flat), None);
    }

    /// The liver scene: the model is SOFA's coarse liver, the real object SOFA's fine liver
    /// (an independent mesh of the same organ, read where it lies); seen from the scene's
    /// camera their rest silhouettes must agree well above the Dice a registered model is
    /// asked to reach (0.97).
    #[test]
    fn liver_model_and_real_object_agree_at_rest() {
        let scenario =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/liver-lobe/scenario.toml");
        let p = prepare(&scenario).unwrap();
        let m = &p.meshes;
        assert_eq!((m.model.nodes.len(), m.model.tets.len()), (181, 596));
        assert_eq!((m.fine.nodes.len(), m.fine.tets.len()), (4293, 22019));
        let d = p.rest_silhouette_dice();
        eprintln!("liver rest silhouette Dice, model vs real: {d:.4}");
        assert!(d >= 0.985, "{d}");
    }
}
