//! The files of a generated scene: `scene.toml`, the model mesh, `tracks.csv` and the ground
//! truth.

use std::path::{Component, Path, PathBuf};

use incise_core::nalgebra::Vector3;

use crate::generate::object::{TetMesh, interpolate, signed_volume6};
use crate::generate::scenario::Scenario;
use crate::generate::tracking::{DepthBuffer, observe_frame, sample_features};
use crate::msh;
use crate::rng::Rng;
use crate::scene::{
    CameraSection, GroundTruthSection, ModelSection, SceneFile, TrueOutlier, silhouette_path,
    write_obj, write_outliers_csv, write_tracks,
};

use super::prepare::rest_silhouette_dice;
use super::trace::CutTrace;
use super::{GenError, Progress, Simulation, at_file, write_file};

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
/// and the ground truth. `gt/cut.csv` holds, each frame, the slit's trace on the surface where
/// the camera sees it (`trace::CutTrace::rows`): all of it for a pre-cut slit, the released pairs
/// of a live cut and its front, where the lips still meet (the next pairs to be released);
/// nothing while a live cut has not started.
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
    let meshes = &sim.meshes;
    let (real, fine, camera, tolerance) = (&meshes.real, &meshes.fine, &sim.camera, sim.tolerance);
    let (boundary, pairs) = (&sim.boundary, &meshes.lips);
    let triangles = sim.triangles();
    let model = &meshes.model;
    let model_fixed = meshes.model_fixed.clone();
    let model_mesh_ref = &meshes.model_mesh_file;
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

    // The true cut: the slit's trace on the surface, in chains along it (`trace`).
    let trace = CutTrace::new(fine, pairs, &meshes.release, &meshes.slit_front);

    let mut bar = Progress::new(progress, &s.name, "writing", u64::from(s.frames))?;
    let mut tracks = vec![];
    let mut target_rows = String::from("frame,id,x,y,z\n");
    let mut cut_rows = String::from("frame,part,u,v,open\n");
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
        for row in trace.rows(frame, x, camera, depth, tolerance) {
            cut_rows.push_str(&format!(
                "{frame},{},{:.3},{:.3},{}\n",
                row.part,
                row.uv[0],
                row.uv[1],
                u8::from(row.open)
            ));
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
            inversion_barrier: true,
            law: s.model.law,
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
            projection: "perspective".into(),
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
    write_file(&out.join("tracks.csv"), write_tracks(&tracks))?;
    write_file(&out.join("gt").join("targets.csv"), target_rows)?;
    write_file(&out.join("gt").join("cut.csv"), cut_rows)?;
    let outliers: Vec<TrueOutlier> = features
        .iter()
        .enumerate()
        .filter_map(|(id, f)| {
            f.jump.map(|(start, frames, jump)| TrueOutlier {
                id: id as u32,
                start,
                frames,
                jump,
            })
        })
        .collect();
    write_file(
        &out.join("gt").join("outliers.csv"),
        write_outliers_csv(&outliers),
    )?;
    write_file(
        &out.join("gt").join("surface.obj"),
        write_obj(&sim.positions[sim.positions.len() - 1], &triangles),
    )?;
    // Last: a directory with a `scene.toml` is a whole scene (`incise eval` reuses one when
    // its scenario matches), so an interrupted run never leaves one that looks complete.
    write_file(&out.join("scene.toml"), header + &body)?;
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
