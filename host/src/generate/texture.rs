//! Pictures of the real object as an endoscope would film it: its surface carries a speckle
//! texture fixed to the material (so a tracker finds corners that move with it), lit from the
//! camera, rendered with a depth buffer and 2 × 2 supersampling.

use image::{Rgb, RgbImage};
use incise_core::nalgebra::Vector3;

use crate::generate::pipeline::Simulation;
use crate::render::rasterize_triangle;

/// Hash of an integer lattice point to `[0, 1)`.
fn lattice(i: i64, j: i64, k: i64, seed: u64) -> f64 {
    let mut h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (k as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
        ^ seed;
    h ^= h >> 31;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 27;
    h = h.wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^= h >> 31;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth value noise in `[0, 1]` at `p` (lattice units).
fn value_noise(p: [f64; 3], seed: u64) -> f64 {
    let cell = p.map(f64::floor);
    let f = [0, 1, 2].map(|c| p[c] - cell[c]);
    let s = f.map(|t| t * t * (3.0 - 2.0 * t));
    let (i, j, k) = (cell[0] as i64, cell[1] as i64, cell[2] as i64);
    let mut v = 0.0;
    for dk in 0..2 {
        for dj in 0..2 {
            for di in 0..2 {
                let w = (if di == 1 { s[0] } else { 1.0 - s[0] })
                    * (if dj == 1 { s[1] } else { 1.0 - s[1] })
                    * (if dk == 1 { s[2] } else { 1.0 - s[2] });
                v += w * lattice(i + di, j + dj, k + dk, seed);
            }
        }
    }
    v
}

/// The speckle at a material point (rest position, metres): two octaves of value noise, about
/// 1.5 mm and 0.6 mm across, sharpened so that blobs have edges, in `[0, 1]`.
pub fn speckle(rest: [f64; 3]) -> f64 {
    let coarse = value_noise(rest.map(|c| c / 1.5e-3), 0x5EED);
    let fine = value_noise(rest.map(|c| c / 0.6e-3), 0xF00D);
    let v = 0.65 * coarse + 0.35 * fine;
    // A soft threshold around the mean turns smooth noise into speckles.
    (0.5 + 2.2 * (v - 0.5)).clamp(0.0, 1.0)
}

const BACKGROUND: [f64; 3] = [18.0, 16.0, 20.0];
const TISSUE: [f64; 3] = [214.0, 128.0, 116.0];

/// Renders frame `frame` of the simulation at the camera's resolution.
pub fn render_frame(sim: &Simulation, frame: usize) -> RgbImage {
    const SS: u32 = 2;
    let cam = &sim.camera;
    let (w, h) = (cam.intrinsics().width, cam.intrinsics().height);
    let (sw, sh) = (w * SS, h * SS);
    let x = &sim.positions[frame.min(sim.positions.len() - 1)];
    let rest = &sim.positions[0];
    let mut depth = vec![f64::INFINITY; (sw * sh) as usize];
    let mut colour = vec![BACKGROUND; (sw * sh) as usize];
    let eye = *cam.centre();
    for &(tri, _) in &sim.boundary {
        let p = tri.map(|v| Vector3::from(x[v as usize]));
        let normal = (p[1] - p[0]).cross(&(p[2] - p[0]));
        let to_eye = eye - p[0];
        // Back faces are hidden by the front ones; skipping them halves the work.
        if normal.dot(&to_eye) <= 0.0 {
            continue;
        }
        let mut uv = [[0.0; 2]; 3];
        let mut z = [0.0; 3];
        let mut ok = true;
        for k in 0..3 {
            match cam.project(&p[k], 0) {
                Ok(q) => uv[k] = [q.x * f64::from(SS), q.y * f64::from(SS)],
                Err(_) => ok = false,
            }
            z[k] = cam.to_camera(&p[k]).z;
        }
        if !ok {
            continue;
        }
        // Lambertian light from the camera, kept mild so that brightness barely changes as
        // the surface turns (a tracker assumes constant brightness).
        let shade = 0.8 + 0.2 * (normal.normalize().dot(&to_eye.normalize())).abs();
        let r = tri.map(|v| rest[v as usize]);
        rasterize_triangle(sw, sh, uv, |px, py, b| {
            // Perspective-correct interpolation: the weights of 1/z.
            let inv = [b[0] / z[0], b[1] / z[1], b[2] / z[2]];
            let sum = inv[0] + inv[1] + inv[2];
            let d = 1.0 / sum;
            let i = (py * sw + px) as usize;
            if d < depth[i] {
                depth[i] = d;
                let m = [0, 1, 2]
                    .map(|c| (inv[0] * r[0][c] + inv[1] * r[1][c] + inv[2] * r[2][c]) / sum);
                let t = 0.25 + 0.75 * speckle(m);
                colour[i] = TISSUE.map(|c| c * t * shade);
            }
        });
    }
    RgbImage::from_fn(w, h, |px, py| {
        let mut acc = [0.0; 3];
        for dy in 0..SS {
            for dx in 0..SS {
                let c = colour[((py * SS + dy) * sw + px * SS + dx) as usize];
                for k in 0..3 {
                    acc[k] += c[k];
                }
            }
        }
        let n = f64::from(SS * SS);
        Rgb(acc.map(|v| (v / n).round().clamp(0.0, 255.0) as u8))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speckle_is_deterministic_and_varied() {
        let a = speckle([0.01, 0.02, 0.003]);
        assert_eq!(a, speckle([0.01, 0.02, 0.003]));
        let samples: Vec<f64> = (0..1000)
            .map(|k| speckle([k as f64 * 1.3e-4, k as f64 * 0.7e-4, 0.0]))
            .collect();
        let mean = samples.iter().sum::<f64>() / samples.len() as f64;
        let var = samples.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / samples.len() as f64;
        assert!((0.3..0.7).contains(&mean), "{mean}");
        assert!(var > 0.02, "{var}");
        assert!(samples.iter().all(|v| (0.0..=1.0).contains(v)));
    }
}
