//! Small synthetic scenes for tests and benchmarks: a camera looking at a mesh and observations
//! of material points. The model itself is built in the host's `ModelStorage`.

pub use incise::storage::ModelStorage;

use incise_core::{Camera, Intrinsics, Observation};
use nalgebra::{Matrix3, Vector3};

use crate::testmesh::TetMesh;

/// World-to-camera rotation and translation of a camera at `eye` looking at `target`, with
/// `up` pointing up in the image (OpenCV axes: x right, y down, z forward).
pub fn look_at(eye: [f64; 3], target: [f64; 3], up: [f64; 3]) -> (Matrix3<f64>, Vector3<f64>) {
    let eye = Vector3::from(eye);
    let z = (Vector3::from(target) - eye).normalize();
    let x = z.cross(&Vector3::from(up)).normalize();
    let y = z.cross(&x);
    let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    (r, -(r * eye))
}

/// A camera from `look_at` and square pixels.
pub fn camera(
    eye: [f64; 3],
    target: [f64; 3],
    up: [f64; 3],
    focal: f64,
    size: (u32, u32),
) -> Camera<f64> {
    let (r, t) = look_at(eye, target, up);
    let intr = Intrinsics {
        fx: focal,
        fy: focal,
        cx: f64::from(size.0) / 2.0,
        cy: f64::from(size.1) / 2.0,
        width: size.0,
        height: size.1,
    };
    Camera::new(intr, r, t, 1e-4).expect("valid camera")
}

/// Nodes of `mesh` whose coordinate `axis` equals `value` (to 1e-12).
pub fn nodes_where(mesh: &TetMesh, axis: usize, value: f64) -> Vec<u32> {
    (0..mesh.nodes.len() as u32)
        .filter(|&v| (mesh.nodes[v as usize][axis] - value).abs() < 1e-12)
        .collect()
}

/// Observations of world points through `camera`, ids `0..`.
pub fn observe(camera: &Camera<f64>, points: &[[f64; 3]]) -> Vec<Observation<f64>> {
    points
        .iter()
        .enumerate()
        .map(|(id, p)| {
            let uv = camera.project(&Vector3::from(*p), id).expect("in front");
            Observation {
                id: id as u32,
                uv: [uv.x, uv.y],
            }
        })
        .collect()
}
