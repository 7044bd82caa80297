//! What a tracker would report for the real object: features sampled on its visible surface
//! at frame 0, followed as material points, hidden when occluded or out of the image, with
//! Gaussian noise, drop-outs and a few features that jump.

use incise_core::nalgebra::Vector3;
use incise_core::{Camera, Observation};

use crate::generate::object::{TetMesh, interpolate};
use crate::render::{Mask, project_triangle, rasterize_triangle};
use crate::rng::Rng;

/// Camera depth of the nearest surface at every pixel (infinity where there is none).
pub struct DepthBuffer {
    width: u32,
    height: u32,
    depth: Vec<f64>,
}

impl DepthBuffer {
    /// Renders the depth of `triangles` over `positions`.
    pub fn render(camera: &Camera<f64>, positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Self {
        let (width, height) = (camera.intrinsics().width, camera.intrinsics().height);
        let mut depth = vec![f64::INFINITY; width as usize * height as usize];
        for &tri in triangles {
            let Some(t) = project_triangle(camera, positions, tri) else {
                continue;
            };
            let z = tri.map(|v| camera.to_camera(&Vector3::from(positions[v as usize])).z);
            rasterize_triangle(width, height, t, |x, y, w| {
                // Perspective-correct depth: interpolate 1/z in the image.
                let inv = w[0] / z[0] + w[1] / z[1] + w[2] / z[2];
                let d = &mut depth[(y * width + x) as usize];
                *d = d.min(1.0 / inv);
            });
        }
        DepthBuffer {
            width,
            height,
            depth,
        }
    }

    /// Whether world point `p` is seen: in the image and not behind the surface by more than
    /// `tolerance` metres.
    pub fn visible(&self, camera: &Camera<f64>, p: [f64; 3], tolerance: f64) -> Option<[f64; 2]> {
        let v = Vector3::from(p);
        let uv = camera.project(&v, 0).ok()?;
        let (x, y) = (uv.x.floor(), uv.y.floor());
        if x < 0.0 || y < 0.0 || x >= f64::from(self.width) || y >= f64::from(self.height) {
            return None;
        }
        let d = self.depth[(y as u32 * self.width + x as u32) as usize];
        let z = camera.to_camera(&v).z;
        (z <= d + tolerance).then_some([uv.x, uv.y])
    }
}

/// A feature: a material point of the real object's surface.
#[derive(Clone, Copy, Debug)]
pub struct Feature {
    /// Tetrahedron of the fine mesh.
    pub tet: u32,
    /// Barycentric weights in it.
    pub weights: [f64; 4],
    /// The frame it jumps at and for how many frames, with the jump (pixels), if it is an
    /// outlier.
    pub jump: Option<(u32, u32, [f64; 2])>,
}

/// Samples `count` features on the visible part of the surface (area-weighted), at rest.
///
/// # Errors
/// A message if the visible surface is too small to hold them.
#[allow(clippy::too_many_arguments)]
pub fn sample_features(
    mesh: &TetMesh,
    boundary: &[([u32; 3], usize)],
    camera: &Camera<f64>,
    depth: &DepthBuffer,
    tolerance: f64,
    count: usize,
    frames: u32,
    outlier_fraction: f64,
    outlier_jump_px: f64,
    rng: &mut Rng,
) -> Result<Vec<Feature>, String> {
    // Area of each boundary triangle that faces the camera.
    let eye = *camera.centre();
    let mut cumulative = Vec::with_capacity(boundary.len());
    let mut total = 0.0;
    for (tri, _) in boundary {
        let p = tri.map(|v| Vector3::from(mesh.nodes[v as usize]));
        let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
        let facing = n.dot(&(eye - p[0])) > 0.0;
        if facing {
            total += n.norm() / 2.0;
        }
        cumulative.push(total);
    }
    if total <= 0.0 {
        return Err("no surface faces the camera".into());
    }
    let mut features = Vec::with_capacity(count);
    let mut attempts = 0;
    while features.len() < count {
        attempts += 1;
        if attempts > 200 * count.max(1) {
            return Err(format!(
                "only {} of {count} features found on the visible surface",
                features.len()
            ));
        }
        let r = rng.uniform() * total;
        let k = cumulative
            .partition_point(|&c| c < r)
            .min(boundary.len() - 1);
        let (tri, t) = boundary[k];
        // Uniform point in the triangle.
        let (mut a, mut b) = (rng.uniform(), rng.uniform());
        if a + b > 1.0 {
            a = 1.0 - a;
            b = 1.0 - b;
        }
        let tw = [1.0 - a - b, a, b];
        let tet = mesh.tets[t];
        let mut weights = [0.0; 4];
        for (c, &v) in tri.iter().enumerate() {
            let slot = tet
                .iter()
                .position(|&u| u == v)
                .expect("face of its tetrahedron");
            weights[slot] = tw[c];
        }
        let p = interpolate(&mesh.nodes, tet, weights);
        if depth.visible(camera, p, tolerance).is_none() {
            continue;
        }
        features.push(Feature {
            tet: t as u32,
            weights,
            jump: None,
        });
    }
    // Outliers: a few features jump somewhere wrong for 2 to 5 frames.
    let outliers = (outlier_fraction * count as f64).round() as usize;
    for _ in 0..outliers.min(count) {
        let i = (rng.next_u64() % count as u64) as usize;
        let start = 1 + (rng.next_u64() % u64::from(frames.saturating_sub(2).max(1))) as u32;
        let length = 2 + (rng.next_u64() % 4) as u32;
        let angle = rng.uniform() * std::f64::consts::TAU;
        features[i].jump = Some((
            start,
            length,
            [outlier_jump_px * angle.cos(), outlier_jump_px * angle.sin()],
        ));
    }
    Ok(features)
}

/// The tracker's report of one frame: features visible in the image, with noise, drop-outs
/// (frame 0 has none: it defines the features) and jumps.
#[allow(clippy::too_many_arguments)]
pub fn observe_frame(
    frame: u32,
    features: &[Feature],
    mesh: &TetMesh,
    positions: &[[f64; 3]],
    camera: &Camera<f64>,
    depth: &DepthBuffer,
    tolerance: f64,
    noise_px: f64,
    dropout: f64,
    rng: &mut Rng,
) -> Vec<Observation<f64>> {
    let mut out = vec![];
    for (id, f) in features.iter().enumerate() {
        // Draw every random number whether or not it is used, so that one feature's
        // visibility does not shift the others' noise.
        let (nu, nv, drop) = (rng.normal(), rng.normal(), rng.uniform());
        let p = interpolate(positions, mesh.tets[f.tet as usize], f.weights);
        let Some(uv) = depth.visible(camera, p, tolerance) else {
            continue;
        };
        if frame > 0 && drop < dropout {
            continue;
        }
        let mut uv = [uv[0] + noise_px * nu, uv[1] + noise_px * nv];
        if let Some((start, length, jump)) = f.jump
            && frame >= start
            && frame < start + length
        {
            uv[0] += jump[0];
            uv[1] += jump[1];
        }
        out.push(Observation { id: id as u32, uv });
    }
    out
}

impl DepthBuffer {
    /// The silhouette: pixels where some surface was drawn.
    pub fn mask(&self) -> Mask {
        Mask {
            width: self.width,
            height: self.height,
            data: self.depth.iter().map(|d| u8::from(d.is_finite())).collect(),
        }
    }
}
