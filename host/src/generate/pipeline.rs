//! `incise gen`: simulate the scenario's real object frame by frame and write the scene.

use std::fmt;
use std::io::Write;
use std::path::{Component, Path, PathBuf};

use incise_core::Camera;
use incise_core::nalgebra::{Rotation3, Unit, Vector3};
use indicatif::{ProgressBar, ProgressStyle};

use crate::generate::live::{self, NEVER, OPEN};
use crate::generate::object::{
    Slit, TetMesh, cut_slit, cut_slit_where, dome_parameters_error, interpolate, signed_volume6,
};
use crate::generate::scenario::{CameraSpec, GraspSpec, Scenario};
use crate::generate::sim::Simulator;
use crate::generate::tracking::{DepthBuffer, observe_frame, sample_features};
use crate::metrics::dice;
use crate::msh;
use crate::render::silhouette;
use crate::rng::Rng;
use crate::scene::{
    CameraSection, GroundTruthSection, ModelSection, SceneFile, silhouette_path, write_obj,
    write_tracks,
};
use crate::vtu::read_vtu;

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

/// What was generated.
#[derive(Clone, Debug)]
pub struct Generated {
    /// The scene directory.
    pub dir: PathBuf,
    /// Frames written.
    pub frames: u32,
    /// Features sampled.
    pub features: usize,
    /// Nodes and tetrahedra of the real (fine) mesh.
    pub fine_size: (usize, usize),
    /// Nodes and tetrahedra of the model mesh.
    pub model_size: (usize, usize),
    /// First frame at which the slit has opened by a pixel.
    pub cut_open_frame: Option<u32>,
    /// Dice of the rest silhouettes of the model and the real object
    /// ([`rest_silhouette_dice`]).
    pub rest_silhouette_dice: f64,
}

/// The camera of a scenario.
pub fn scenario_camera(s: &Scenario) -> Result<Camera<f64>, GenError> {
    spec_camera(&s.camera).map_err(|e| GenError(format!("[camera]: {}", e.0)))
}

/// The pinhole camera of a `[camera]` section: principal point at the image centre, square
/// pixels.
///
/// # Errors
/// A [`GenError`] for a degenerate pose or bad intrinsics.
pub fn spec_camera(c: &CameraSpec) -> Result<Camera<f64>, GenError> {
    let eye = Vector3::from(c.eye);
    let z = (Vector3::from(c.target) - eye).normalize();
    let x = z.cross(&Vector3::from(c.up)).normalize();
    let y = z.cross(&x);
    let r =
        incise_core::nalgebra::Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    Camera::new(
        incise_core::Intrinsics {
            fx: c.focal,
            fy: c.focal,
            cx: f64::from(c.width) / 2.0,
            cy: f64::from(c.height) / 2.0,
            width: c.width,
            height: c.height,
        },
        r,
        -(r * eye),
        1e-4,
    )
    .map_err(err)
}

fn in_box(p: [f64; 3], b: &[[f64; 3]; 2]) -> bool {
    (0..3).all(|k| p[k] >= b[0][k] && p[k] <= b[1][k])
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

/// `target` relative to `base` (both existing paths or their parents), for scene.toml.
fn relative_path(target: &Path, base: &Path) -> PathBuf {
    let (t, b) = match (target.canonicalize(), base.canonicalize()) {
        (Ok(t), Ok(b)) => (t, b),
        _ => return target.to_path_buf(),
    };
    let tc: Vec<Component> = t.components().collect();
    let bc: Vec<Component> = b.components().collect();
    let common = tc.iter().zip(&bc).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..bc.len() {
        out.push("..");
    }
    for c in &tc[common..] {
        out.push(c.as_os_str());
    }
    out
}

/// The real object simulated over every frame, in memory: what the scene's files, its
/// pictures and its video are made from.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// The scenario.
    pub scenario: Scenario,
    /// The camera.
    pub camera: Camera<f64>,
    /// The model mesh (coarse, uncut).
    pub model: TetMesh,
    /// Nodes of the model held at rest.
    pub model_fixed: Vec<u32>,
    /// The model's Gmsh file, for a scenario made from a mesh file.
    pub model_mesh_file: Option<PathBuf>,
    /// The real mesh (fine, with the slit's nodes duplicated).
    pub real: TetMesh,
    /// The fine mesh before the slit (its boundary is the object's outer surface).
    pub fine: TetMesh,
    /// `(original, duplicate)` nodes along the slit's lips.
    pub lips: Vec<(u32, u32)>,
    /// The frame from which each pair of `lips` is open ([`live::OPEN`] for a pre-cut slit;
    /// a live cut's pairs are tied before it, see [`live`]).
    pub release: Vec<u32>,
    /// Nodes of the slit's front, where its lips meet.
    pub slit_front: Vec<u32>,
    /// Boundary triangles of the real mesh (outward) with their tetrahedra.
    pub boundary: Vec<([u32; 3], usize)>,
    /// Node positions of the real mesh, every frame (frame 0 is rest).
    pub positions: Vec<Vec<[f64; 3]>>,
    /// Depth tolerance of the visibility test, metres.
    pub tolerance: f64,
}

impl Simulation {
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
        let tet = self.real.tets[t];
        let q = tet.map(|v| Vector3::from(x[v as usize]));
        let m =
            incise_core::nalgebra::Matrix3::from_columns(&[q[1] - q[0], q[2] - q[0], q[3] - q[0]]);
        let l = m.try_inverse()? * (hit - q[0]);
        Some((t, [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]))
    }

    /// Pixel of a material point in `frame`.
    pub fn project(&self, frame: usize, point: (usize, [f64; 4])) -> Option<[f64; 2]> {
        let x = self.positions.get(frame)?;
        let p = interpolate(x, self.real.tets[point.0], point.1);
        let uv = self.camera.project(&Vector3::from(p), 0).ok()?;
        Some([uv.x, uv.y])
    }
}

/// The real object and the model of a scenario at rest, before any frame is simulated.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The scenario.
    pub scenario: Scenario,
    /// The camera.
    pub camera: Camera<f64>,
    /// The model mesh (coarse, uncut).
    pub model: TetMesh,
    /// Nodes of the model held at rest.
    pub model_fixed: Vec<u32>,
    /// The model's Gmsh file, for a scenario made from a mesh file.
    pub model_mesh_file: Option<PathBuf>,
    /// The real mesh (fine, with the slit's nodes duplicated).
    pub real: TetMesh,
    /// The fine mesh before the slit.
    pub fine: TetMesh,
    /// `(original, duplicate)` nodes along the slit's lips.
    pub lips: Vec<(u32, u32)>,
    /// The frame from which each pair of `lips` is open ([`live::OPEN`] for a pre-cut slit).
    pub release: Vec<u32>,
    /// Nodes of the slit's front, where its lips meet.
    pub slit_front: Vec<u32>,
    /// Prescribed nodes of the real mesh, each with the grasp that moves it (`None`: held).
    pub prescribed: Vec<(u32, Option<usize>)>,
}

impl Prepared {
    /// Dice of the rest silhouettes of the model and of the real object through the camera,
    /// roughly the best a model can score against the ground truth: about 1 when the real
    /// object is the model refined, less for an independent real mesh (SOFA's fine liver).
    pub fn rest_silhouette_dice(&self) -> f64 {
        rest_silhouette_dice(&self.camera, &self.model, &self.real)
    }
}

/// Dice of the silhouettes of `model` (rendered as `incise run` renders the model) and `real`
/// (rendered as the ground truth is) at rest, through `camera`.
pub fn rest_silhouette_dice(camera: &Camera<f64>, model: &TetMesh, real: &TetMesh) -> f64 {
    let model_triangles: Vec<[u32; 3]> = model.boundary().iter().map(|b| b.0).collect();
    let real_triangles: Vec<[u32; 3]> = real.boundary().iter().map(|b| b.0).collect();
    let m = silhouette(camera, &model.nodes, &model_triangles);
    let r = DepthBuffer::render(camera, &real.nodes, &real_triangles).mask();
    dice(&m, &r)
}

/// A tetrahedral mesh file, Gmsh (`.msh`) or VTK XML (`.vtu`), scaled to metres and oriented.
fn read_tet_mesh(path: &Path, scale: f64) -> Result<TetMesh, GenError> {
    let is_vtu = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vtu"));
    let (nodes, tets) = if is_vtu {
        let m = read_vtu(path).map_err(err)?;
        (m.nodes, m.tets)
    } else {
        let m = msh::read_msh(path).map_err(err)?;
        (m.nodes, m.tets)
    };
    let mut mesh = TetMesh {
        nodes: nodes.iter().map(|p| p.map(|c| c * scale)).collect(),
        tets,
    };
    mesh.orient_positive();
    Ok(mesh)
}

/// The camera an image slit is given in: its own `[slit.camera]`, else the scene's.
fn slit_camera(s: &Scenario, camera: &Camera<f64>) -> Result<Camera<f64>, GenError> {
    match s.slit.as_ref().and_then(|sl| sl.camera.as_ref()) {
        Some(c) => spec_camera(c).map_err(|e| GenError(format!("[slit.camera]: {}", e.0))),
        None => Ok(*camera),
    }
}

/// The slit of a scenario cut into `fine`, or `None` without a `[slit]`; `camera` is the
/// camera an image slit is given in.
fn make_slit(s: &Scenario, fine: &TetMesh, camera: &Camera<f64>) -> Result<Option<Slit>, GenError> {
    let Some(sl) = &s.slit else {
        return Ok(None);
    };
    let in_region = |p: [f64; 3]| sl.region.as_ref().is_none_or(|b| in_box(p, b));
    let cut = match (sl.image, sl.point, sl.normal) {
        (Some([a, b]), None, None) => {
            // The plane through the camera centre and the rays through both ends; the slit is
            // the part of it that projects between the ends.
            let (eye, d0) = camera.ray(a[0], a[1]);
            let (_, d1) = camera.ray(b[0], b[1]);
            let normal = d0.cross(&d1);
            if normal.norm() < 1e-12 || (b[0] - a[0]).hypot(b[1] - a[1]) < 1.0 {
                return Err(GenError(
                    "[slit] image: the two ends must be at least a pixel apart".into(),
                ));
            }
            let ab = [b[0] - a[0], b[1] - a[1]];
            let len2 = ab[0] * ab[0] + ab[1] * ab[1];
            cut_slit_where(fine, [eye.x, eye.y, eye.z], normal.into(), |p| {
                camera.project(&Vector3::from(p), 0).is_ok_and(|uv| {
                    let t = ((uv.x - a[0]) * ab[0] + (uv.y - a[1]) * ab[1]) / len2;
                    (0.0..=1.0).contains(&t)
                }) && in_region(p)
            })
        }
        (None, Some(point), Some(normal)) => {
            let Some(region) = sl.region else {
                return Err(GenError("[slit] a plane slit needs a region".into()));
            };
            cut_slit(fine, point, normal, region)
        }
        _ => {
            return Err(GenError(
                "[slit] give either point, normal and region, or image (and maybe region)".into(),
            ));
        }
    };
    if cut.faces == 0 {
        return Err(GenError(
            "[slit] region holds no mesh face: nothing is cut".into(),
        ));
    }
    Ok(Some(cut))
}

/// The model mesh, the real mesh before any slit (finer) and, for a scenario made from a mesh
/// file, that file, of scenario `s` whose mesh paths are relative to `base`.
///
/// # Errors
/// A [`GenError`] for an unknown shape, bad dome parameters or a mesh that cannot be read.
pub fn object_meshes(
    s: &Scenario,
    base: &Path,
) -> Result<(TetMesh, TetMesh, Option<PathBuf>), GenError> {
    let o = &s.object;
    Ok(match o.shape.as_str() {
        "band" => (
            TetMesh::band(o.size, o.model_cells),
            TetMesh::band(o.size, o.fine_cells),
            None,
        ),
        "dome" => {
            for cells in [o.model_cells, o.fine_cells] {
                if let Some(e) = dome_parameters_error(o.size, o.radius, cells) {
                    return Err(GenError(format!("[object] {e}")));
                }
            }
            (
                TetMesh::dome(o.size, o.radius, o.model_cells),
                TetMesh::dome(o.size, o.radius, o.fine_cells),
                None,
            )
        }
        "mesh" => {
            let path = base.join(&o.mesh);
            let model = read_tet_mesh(&path, o.scale)?;
            // The refinement has eight times the tetrahedra: check the model first.
            s.check_meshes(model.nodes.len(), 0).map_err(err)?;
            let fine = if o.real_mesh.is_empty() {
                model.refine()
            } else {
                read_tet_mesh(&base.join(&o.real_mesh), o.real_scale.unwrap_or(o.scale))?
            };
            (model, fine, Some(path))
        }
        other => {
            return Err(GenError(format!(
                "[object] shape must be \"band\", \"dome\" or \"mesh\", not {other:?}"
            )));
        }
    })
}

/// Builds the model and the real object (with its slit) of the scenario at `scenario_path`,
/// at rest.
///
/// # Errors
/// A [`GenError`] for a bad scenario or a mesh that cannot be read; it names the scenario file
/// (once).
pub fn prepare(scenario_path: &Path) -> Result<Prepared, GenError> {
    // A load error names the file itself.
    let s = Scenario::load(scenario_path).map_err(err)?;
    prepare_scenario(s, scenario_path.parent().unwrap_or(Path::new(".")))
        .map_err(|e| at_file(scenario_path)(&e))
}

/// [`prepare`] for a scenario in memory whose mesh paths are relative to `base`.
///
/// # Errors
/// A [`GenError`] for a bad scenario or a mesh that cannot be read.
pub fn prepare_scenario(s: Scenario, base: &Path) -> Result<Prepared, GenError> {
    // Sizes and values first (a scenario read from a file was checked as it was read; one
    // made in memory, a family's variant, is checked here), then the meshes.
    s.check().map_err(err)?;
    let (model, fine, model_mesh_ref) = object_meshes(&s, base)?;
    s.check_meshes(model.nodes.len(), fine.nodes.len())
        .map_err(err)?;
    let camera = scenario_camera(&s)?;
    let cut_camera = slit_camera(&s, &camera)?;
    let (real, pairs, slit_front, release) = match make_slit(&s, &fine, &cut_camera)? {
        Some(cut) => {
            let release = match s.slit.as_ref().and_then(|sl| sl.grow) {
                None => vec![OPEN; cut.pairs.len()],
                Some([start, end]) => {
                    if start >= end || end >= s.frames {
                        return Err(GenError(format!(
                            "[slit] grow = [{start}, {end}]: need start < end < frames ({})",
                            s.frames
                        )));
                    }
                    let sl = s.slit.as_ref().expect("a slit was cut");
                    let growth = live::growth(sl, &fine.nodes, &cut_camera)
                        .map_err(|e| GenError(format!("[slit] grow: {e}")))?;
                    live::release_frames(&cut, &cut.mesh.nodes, &growth, [start, end])
                }
            };
            (cut.mesh, cut.pairs, cut.front, release)
        }
        None => (fine.clone(), vec![], vec![], vec![]),
    };

    // Held and grasped nodes of the real mesh; the model holds its nodes in the held boxes.
    let mut prescribed = vec![];
    for (v, &p) in real.nodes.iter().enumerate() {
        if s.motion.held.iter().any(|b| in_box(p, b)) {
            prescribed.push((v as u32, None));
        } else if let Some(g) = s.motion.grasp.iter().position(|g| in_box(p, &g.region)) {
            prescribed.push((v as u32, Some(g)));
        }
    }
    let model_fixed: Vec<u32> = (0..model.nodes.len() as u32)
        .filter(|&v| {
            s.motion
                .held
                .iter()
                .any(|b| in_box(model.nodes[v as usize], b))
        })
        .collect();
    if model_fixed.is_empty() {
        return Err(GenError("[motion] no model node lies in a held box".into()));
    }
    for (k, b) in s.motion.held.iter().enumerate() {
        if !prescribed
            .iter()
            .any(|&(v, g)| g.is_none() && in_box(real.nodes[v as usize], b))
        {
            return Err(GenError(format!(
                "[motion] held box {k} holds no node of the real object"
            )));
        }
    }
    if prescribed.iter().all(|(_, g)| g.is_none()) {
        return Err(GenError("[motion] no node lies in a grasped box".into()));
    }
    Ok(Prepared {
        scenario: s,
        camera,
        model,
        model_fixed,
        model_mesh_file: model_mesh_ref,
        real,
        fine,
        lips: pairs,
        release,
        slit_front,
        prescribed,
    })
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
        model,
        model_fixed,
        model_mesh_file,
        real,
        fine,
        lips,
        release,
        slit_front,
        prescribed,
    } = prepared;
    let prescribed_nodes: Vec<u32> = prescribed.iter().map(|p| p.0).collect();
    let build = |frame: u32| {
        Simulator::new(
            &real.nodes,
            &live::tied_tets(&real.tets, &lips, &release, frame),
            &prescribed_nodes,
            s.object.young,
            s.object.poisson,
        )
        .map_err(|e| GenError(format!("simulator: {e}")))
    };
    let mut simulator = build(0)?;
    let mut open = live::released(&release, 0);
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
        let now_open = live::released(&release, frame);
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
        for (&(v, d), &r) in lips.iter().zip(&release) {
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
        model,
        model_fixed,
        model_mesh_file,
        real,
        fine,
        lips,
        release,
        slit_front,
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
/// `incise gen out/scenario.toml` would. `base` is the directory the scenario's mesh paths
/// are relative to (the directory of the file it was read from). Creates `out` if needed.
///
/// # Errors
/// As [`generate`], and a [`GenError`] if the scenario cannot be written.
pub fn generate_scenario(
    s: &Scenario,
    base: &Path,
    out: &Path,
    progress: bool,
) -> Result<Generated, GenError> {
    let sim = simulate_scenario(s, base, progress)?;
    std::fs::create_dir_all(out).map_err(|e| at_file(out)(&e))?;
    let mut written = s.clone();
    rebase_mesh_paths(&mut written, base, out);
    let file = out.join("scenario.toml");
    let text = format!(
        "# The scenario of this scene, written by incise: `incise gen` on this file \
         regenerates the scene beside it.\n{}",
        written.to_toml().map_err(GenError)?
    );
    write_file(&file, text)?;
    write_scene(&sim, &file, out, progress)
}

/// Makes the mesh paths of `s` (`[object] mesh`, `real_mesh`), relative to `from`, relative
/// to `to` instead (both directories must exist; a path that cannot be resolved is joined to
/// `from` as it is).
pub fn rebase_mesh_paths(s: &mut Scenario, from: &Path, to: &Path) {
    for p in [&mut s.object.mesh, &mut s.object.real_mesh] {
        if !p.is_empty() && Path::new(p.as_str()).is_relative() {
            *p = relative_path(&from.join(&*p), to)
                .to_string_lossy()
                .into_owned();
        }
    }
}

/// Writes the scene of a simulation into `out`: `scene.toml`, the model mesh, `tracks.csv`
/// and the ground truth. `gt/cut.csv` holds, each frame, the part of the slit that is open
/// (all of it for a pre-cut slit, the released pairs of a live cut) and its front, where the
/// lips still meet (for a live cut, the next pairs to be released); nothing while a live cut
/// has not started.
///
/// # Errors
/// A [`GenError`] naming the file that cannot be written, or the scenario file if its
/// features cannot be placed.
pub fn write_scene(
    sim: &Simulation,
    scenario_path: &Path,
    out: &Path,
    progress: bool,
) -> Result<Generated, GenError> {
    let s = &sim.scenario;
    let (real, fine, camera, tolerance) = (&sim.real, &sim.fine, &sim.camera, sim.tolerance);
    let (boundary, pairs) = (&sim.boundary, &sim.lips);
    let triangles = sim.triangles();
    let model = &sim.model;
    let model_fixed = sim.model_fixed.clone();
    let model_mesh_ref = &sim.model_mesh_file;
    let silhouettes = out.join("gt").join("silhouettes");
    std::fs::create_dir_all(&silhouettes).map_err(|e| at_file(&silhouettes)(&e))?;
    let mut rng = Rng::new(s.seed);
    let depth0 = DepthBuffer::render(camera, &real.nodes, &triangles);
    let t = &s.tracking;
    let features = sample_features(
        real,
        boundary,
        camera,
        &depth0,
        tolerance,
        t.features,
        s.frames,
        t.outlier_fraction,
        t.outlier_jump_px,
        &mut rng,
    )
    .map_err(|e| at_file(scenario_path)(&e))?;
    let targets = sample_targets(real, s.object.targets, &mut rng);

    // The true cut line: lips on the original surface, seen at rest, ordered along the slit;
    // at its front the lips meet, and the front node is its own midpoint.
    let fine_boundary: std::collections::HashSet<u32> =
        fine.boundary().iter().flat_map(|b| b.0).collect();
    let mut lips: Vec<(u32, u32)> = pairs
        .iter()
        .copied()
        .chain(sim.slit_front.iter().map(|&v| (v, v)))
        .filter(|&(v, _)| fine_boundary.contains(&v))
        .filter(|&(v, _)| {
            depth0
                .visible(camera, real.nodes[v as usize], tolerance)
                .is_some()
        })
        .collect();
    order_along_image_line(&mut lips, &real.nodes, camera);
    // The frame each lip opens; the front never does.
    let opens: std::collections::HashMap<(u32, u32), u32> = pairs
        .iter()
        .copied()
        .zip(sim.release.iter().copied())
        .collect();
    let lip_release: Vec<u32> = lips
        .iter()
        .map(|l| opens.get(l).copied().unwrap_or(NEVER))
        .collect();

    let mut bar = Progress::new(progress, &s.name, "writing", u64::from(s.frames))?;
    let mut tracks = vec![];
    let mut target_rows = String::from("frame,id,x,y,z\n");
    let mut cut_rows = String::from("frame,u,v\n");
    let mut cut_open_frame = None;
    for frame in 0..s.frames {
        let x = &sim.positions[frame as usize];
        let depth = if frame == 0 {
            None
        } else {
            Some(DepthBuffer::render(camera, x, &triangles))
        };
        let depth = depth.as_ref().unwrap_or(&depth0);
        tracks.push(observe_frame(
            frame, &features, real, x, camera, depth, tolerance, t.noise_px, t.dropout, &mut rng,
        ));
        let png = silhouette_path(out, frame as usize);
        depth.mask().save_png(&png).map_err(|e| at_file(&png)(&e))?;
        for (id, (tet, w)) in targets.iter().enumerate() {
            let p = interpolate(x, real.tets[*tet], *w);
            target_rows.push_str(&format!(
                "{frame},{id},{:.7},{:.7},{:.7}\n",
                p[0], p[1], p[2]
            ));
        }
        let mut opening: f64 = 0.0;
        for &(a, b) in pairs {
            if let (Ok(pa), Ok(pb)) = (
                camera.project(&Vector3::from(x[a as usize]), 0),
                camera.project(&Vector3::from(x[b as usize]), 0),
            ) {
                opening = opening.max((pa - pb).norm());
            }
        }
        if cut_open_frame.is_none() && opening >= 1.0 {
            cut_open_frame = Some(frame);
        }
        // The open part and its front: the lips that have not opened yet and open next.
        let started = sim.release.iter().any(|&r| r <= frame);
        let front = lip_release
            .iter()
            .copied()
            .filter(|&r| r > frame)
            .min()
            .unwrap_or(NEVER);
        for (&(a, b), &r) in lips.iter().zip(&lip_release) {
            if !started || (r > frame && r != front) {
                continue;
            }
            let m = [0, 1, 2].map(|k| (x[a as usize][k] + x[b as usize][k]) / 2.0);
            if let Ok(uv) = camera.project(&Vector3::from(m), 0) {
                cut_rows.push_str(&format!("{frame},{:.3},{:.3}\n", uv.x, uv.y));
            }
        }
        bar.inc();
    }
    bar.finish();

    // The scene.
    let mesh_field = match &model_mesh_ref {
        Some(path) => relative_path(path, out).to_string_lossy().into_owned(),
        None => {
            let file = out.join("model.msh");
            msh::write_msh22(&file, &model.nodes, &model.tets).map_err(|e| at_file(&file)(&e))?;
            "model.msh".into()
        }
    };
    let r = camera.rotation();
    let scene = SceneFile {
        name: s.name.clone(),
        description: s.description.clone(),
        model: ModelSection {
            mesh: mesh_field,
            scale: if model_mesh_ref.is_some() {
                s.object.scale
            } else {
                1.0
            },
            fixed: model_fixed,
            young: s.model.young,
            poisson: s.model.poisson,
        },
        camera: CameraSection {
            fx: camera.intrinsics().fx,
            fy: camera.intrinsics().fy,
            cx: camera.intrinsics().cx,
            cy: camera.intrinsics().cy,
            width: camera.intrinsics().width,
            height: camera.intrinsics().height,
            rotation: [0, 1, 2].map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]),
            translation: [0, 1, 2].map(|k| camera.translation()[k]),
            near: 1e-4,
        },
        solver: s.solver.clone(),
        detection: s.detection.clone(),
        capacities: s.capacities.clone(),
        ground_truth: GroundTruthSection {
            cut_open_frame,
            frames: s.frames,
        },
    };
    let header = format!(
        "# Generated by `incise gen` from {}: edit the scenario, not this file.\n",
        scenario_path.file_name().map_or_else(
            || "the scenario".into(),
            |n| n.to_string_lossy().into_owned()
        )
    );
    let body = toml::to_string(&scene).map_err(|e| at_file(&out.join("scene.toml"))(&e))?;
    write_file(&out.join("scene.toml"), header + &body)?;
    write_file(&out.join("tracks.csv"), write_tracks(&tracks))?;
    write_file(&out.join("gt").join("targets.csv"), target_rows)?;
    write_file(&out.join("gt").join("cut.csv"), cut_rows)?;
    write_file(
        &out.join("gt").join("surface.obj"),
        write_obj(&sim.positions[sim.positions.len() - 1], &triangles),
    )?;
    Ok(Generated {
        dir: out.to_path_buf(),
        frames: s.frames,
        features: features.len(),
        fine_size: (real.nodes.len(), real.tets.len()),
        model_size: (model.nodes.len(), model.tets.len()),
        cut_open_frame,
        rest_silhouette_dice: rest_silhouette_dice(camera, model, real),
    })
}

/// Random points inside the mesh (volume-weighted tetrahedron, uniform inside it).
fn sample_targets(mesh: &TetMesh, count: usize, rng: &mut Rng) -> Vec<(usize, [f64; 4])> {
    let mut cumulative = Vec::with_capacity(mesh.tets.len());
    let mut total = 0.0;
    for t in &mesh.tets {
        let p = |v: u32| mesh.nodes[v as usize];
        total += signed_volume6(p(t[0]), p(t[1]), p(t[2]), p(t[3])).abs();
        cumulative.push(total);
    }
    (0..count)
        .map(|_| {
            let r = rng.uniform() * total;
            let t = cumulative
                .partition_point(|&c| c < r)
                .min(mesh.tets.len() - 1);
            // Uniform in a tetrahedron: normalised exponentials (Dirichlet(1, 1, 1, 1)).
            let e: [f64; 4] = [0; 4].map(|_| -(1.0 - rng.uniform()).ln());
            let sum: f64 = e.iter().sum();
            (t, e.map(|x| x / sum))
        })
        .collect()
}

/// Orders lip pairs along the main direction of their projections at rest.
fn order_along_image_line(lips: &mut [(u32, u32)], nodes: &[[f64; 3]], camera: &Camera<f64>) {
    let uv: Vec<[f64; 2]> = lips
        .iter()
        .map(|&(v, _)| {
            camera
                .project(&Vector3::from(nodes[v as usize]), 0)
                .map_or([0.0, 0.0], |p| [p.x, p.y])
        })
        .collect();
    if uv.len() < 2 {
        return;
    }
    let n = uv.len() as f64;
    let mean = [
        uv.iter().map(|p| p[0]).sum::<f64>() / n,
        uv.iter().map(|p| p[1]).sum::<f64>() / n,
    ];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in &uv {
        let (dx, dy) = (p[0] - mean[0], p[1] - mean[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let dir = [angle.cos(), angle.sin()];
    let mut keyed: Vec<(f64, (u32, u32))> = lips
        .iter()
        .zip(&uv)
        .map(|(&l, p)| ((p[0] - mean[0]) * dir[0] + (p[1] - mean[1]) * dir[1], l))
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (slot, (_, l)) in lips.iter_mut().zip(keyed) {
        *slot = l;
    }
}

#[cfg(test)]
mod tests {
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
        let p = prepare(&path).unwrap();
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
        let q = prepare(&plane).unwrap();
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
        let p = prepare(&live_path).unwrap();
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
        assert_eq!(live.lips, cut.lips);
        let opening = |sim: &Simulation, f: usize| {
            sim.lips
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

    /// The liver scene: the model is SOFA's coarse liver, the real object SOFA's fine liver
    /// (an independent mesh of the same organ, read where it lies); seen from the scene's
    /// camera their rest silhouettes must agree well above the Dice a registered model is
    /// asked to reach (0.97).
    #[test]
    fn liver_model_and_real_object_agree_at_rest() {
        let scenario =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/liver-lobe/scenario.toml");
        let p = prepare(&scenario).unwrap();
        assert_eq!((p.model.nodes.len(), p.model.tets.len()), (181, 596));
        assert_eq!((p.fine.nodes.len(), p.fine.tets.len()), (4293, 22019));
        let d = p.rest_silhouette_dice();
        eprintln!("liver rest silhouette Dice, model vs real: {d:.4}");
        assert!(d >= 0.985, "{d}");
    }
}
