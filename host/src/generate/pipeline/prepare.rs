//! The real object and the model of a scenario at rest, before any frame is simulated: the
//! meshes (read, refined or built), the slit, and the scenario's camera.

use std::path::{Path, PathBuf};

use incise_core::Camera;
use incise_core::nalgebra::Vector3;

use crate::generate::live::{self, OPEN};
use crate::generate::object::{Slit, TetMesh, cut_slit, cut_slit_where, dome_parameters_error};
use crate::generate::scenario::{CameraSpec, Scenario};
use crate::generate::tracking::DepthBuffer;
use crate::metrics::dice;
use crate::msh;
use crate::render::silhouette;
use crate::vtu::read_vtu;

use super::{GenError, at_file, err};

/// The camera of a scenario.
///
/// # Errors
/// A [`GenError`] naming `[camera]` when its values make no valid camera.
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

/// The nodes (of a model mesh) that lie in one of the `held` boxes: the nodes it holds fixed.
pub fn held_nodes(nodes: &[[f64; 3]], held: &[[[f64; 3]; 2]]) -> Vec<u32> {
    (0u32..)
        .zip(nodes)
        .filter(|&(_, &p)| held.iter().any(|b| in_box(p, b)))
        .map(|(v, _)| v)
        .collect()
}

/// The meshes of a scenario at rest: the model, and the real object with its slit. What
/// [`Prepared`] builds and [`super::Simulation`] keeps, frame after frame.
#[derive(Clone, Debug)]
pub struct Meshes {
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
    /// The faces of `fine` that form the slit.
    pub slit_faces: Vec<[u32; 3]>,
}

/// The real object and the model of a scenario at rest, before any frame is simulated.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The scenario.
    pub scenario: Scenario,
    /// The camera.
    pub camera: Camera<f64>,
    /// The model and the real object.
    pub meshes: Meshes,
    /// Prescribed nodes of the real mesh, each with the grasp that moves it (`None`: held).
    pub prescribed: Vec<(u32, Option<usize>)>,
}

impl Prepared {
    /// Dice of the rest silhouettes of the model and of the real object through the camera,
    /// roughly the best a model can score against the ground truth: about 1 when the real
    /// object is the model refined, less for an independent real mesh (SOFA's fine liver).
    pub fn rest_silhouette_dice(&self) -> f64 {
        rest_silhouette_dice(&self.camera, &self.meshes.model, &self.meshes.real)
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
    if cut.faces.is_empty() {
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
    let (real, pairs, slit_front, slit_faces, release) = match make_slit(&s, &fine, &cut_camera)? {
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
            (cut.mesh, cut.pairs, cut.front, cut.faces, release)
        }
        None => (fine.clone(), vec![], vec![], vec![], vec![]),
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
    let model_fixed = held_nodes(&model.nodes, &s.motion.held);
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
        meshes: Meshes {
            model,
            model_fixed,
            model_mesh_file: model_mesh_ref,
            real,
            fine,
            lips: pairs,
            release,
            slit_front,
            slit_faces,
        },
        prescribed,
    })
}
