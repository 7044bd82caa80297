//! The pinhole camera: projection of model points into the image, its Jacobian, and the rays
//! through pixels that place virtual features at frame 0.
//!
//! Conventions (OpenCV's): a world point `x` (metres) has camera coordinates `x_c = R x + t`,
//! with `z_c` pointing away from the camera, `x_c` to the right and `y_c` down the image; its
//! pixel is `u = fx·x_c/z_c + cx`, `v = fy·y_c/z_c + cy`. Lens distortion is the host's concern
//! (it undistorts tracked points before they reach the core).

#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

use nalgebra::{Matrix2x3, Matrix3, Vector2, Vector3};

use crate::error::{Error, Parameter};
use crate::real::Real;

/// Intrinsic parameters of a pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics<T> {
    /// Focal length along `u`, pixels.
    pub fx: T,
    /// Focal length along `v`, pixels.
    pub fy: T,
    /// Principal point, pixels.
    pub cx: T,
    /// Principal point, pixels.
    pub cy: T,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

/// A calibrated pinhole camera with its pose.
///
/// Built by [`Camera::new`], which checks the parameters once; projection then only fails for a
/// point at or behind the near plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera<T: Real> {
    intrinsics: Intrinsics<T>,
    rotation: Matrix3<T>,
    translation: Vector3<T>,
    /// Camera centre in world coordinates, `−Rᵀ t`.
    centre: Vector3<T>,
    /// Points with `z_c` at or below this depth (metres) are "behind" the camera.
    near: T,
}

impl<T: Real> Camera<T> {
    /// A camera with intrinsics, world-to-camera rotation `R` and translation `t` (metres).
    /// Points closer than `near` metres along the optical axis cannot be projected.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] with [`Parameter::Intrinsics`] for non-positive or non-finite
    /// focal lengths, a non-finite principal point or an empty image; with [`Parameter::Pose`]
    /// for a non-finite pose, a rotation that is not orthonormal with determinant 1, or a
    /// negative or non-finite `near`.
    pub fn new(
        intrinsics: Intrinsics<T>,
        rotation: Matrix3<T>,
        translation: Vector3<T>,
        near: T,
    ) -> Result<Self, Error> {
        let Intrinsics {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        } = intrinsics;
        let finite = fx.finite() && fy.finite() && cx.finite() && cy.finite();
        if !finite || fx <= T::zero() || fy <= T::zero() || width == 0 || height == 0 {
            return Err(Error::InvalidParameter {
                parameter: Parameter::Intrinsics,
            });
        }
        let pose_finite = rotation
            .iter()
            .chain(translation.iter())
            .all(|v| v.finite());
        // Loose enough for a rotation written with six decimals, tight enough to catch a skew.
        let tol = T::of(1e-5);
        let orthonormal = pose_finite
            && (rotation.transpose() * rotation - Matrix3::identity())
                .iter()
                .all(|e| e.abs() <= tol)
            && rotation.determinant() > T::zero();
        if !orthonormal || !near.finite() || near < T::zero() {
            return Err(Error::InvalidParameter {
                parameter: Parameter::Pose,
            });
        }
        Ok(Camera {
            intrinsics,
            rotation,
            translation,
            centre: -(rotation.transpose() * translation),
            near,
        })
    }

    /// The intrinsics.
    pub fn intrinsics(&self) -> &Intrinsics<T> {
        &self.intrinsics
    }

    /// World-to-camera rotation `R`.
    pub fn rotation(&self) -> &Matrix3<T> {
        &self.rotation
    }

    /// World-to-camera translation `t`, metres.
    pub fn translation(&self) -> &Vector3<T> {
        &self.translation
    }

    /// Depth (metres along the optical axis) at or below which a point cannot be projected.
    pub fn near(&self) -> T {
        self.near
    }

    /// Camera centre in world coordinates, metres.
    pub fn centre(&self) -> &Vector3<T> {
        &self.centre
    }

    /// The optical axis (viewing direction) in world coordinates, unit length.
    pub fn view_direction(&self) -> Vector3<T> {
        self.rotation.row(2).transpose()
    }

    /// Camera coordinates of a world point.
    pub fn to_camera(&self, x: &Vector3<T>) -> Vector3<T> {
        self.rotation * x + self.translation
    }

    /// Pixel of world point `x`; `index` names the point in the error.
    ///
    /// # Errors
    /// [`Error::BehindCamera`] if `x` lies at or behind the near plane (or is not finite).
    pub fn project(&self, x: &Vector3<T>, index: usize) -> Result<Vector2<T>, Error> {
        let xc = self.to_camera(x);
        let z = self.depth(&xc, index)?;
        Ok(Vector2::new(
            self.intrinsics.fx * xc.x / z + self.intrinsics.cx,
            self.intrinsics.fy * xc.y / z + self.intrinsics.cy,
        ))
    }

    /// Pixel of `x` and the Jacobian `∂(u, v)/∂x` (pixels per metre, `2 × 3`).
    ///
    /// # Errors
    /// As [`Camera::project`].
    pub fn project_with_jacobian(
        &self,
        x: &Vector3<T>,
        index: usize,
    ) -> Result<(Vector2<T>, Matrix2x3<T>), Error> {
        let xc = self.to_camera(x);
        let z = self.depth(&xc, index)?;
        let (fx, fy) = (self.intrinsics.fx, self.intrinsics.fy);
        let uv = Vector2::new(
            fx * xc.x / z + self.intrinsics.cx,
            fy * xc.y / z + self.intrinsics.cy,
        );
        let z2 = z * z;
        let jc = Matrix2x3::new(
            fx / z,
            T::zero(),
            -fx * xc.x / z2,
            T::zero(),
            fy / z,
            -fy * xc.y / z2,
        );
        Ok((uv, jc * self.rotation))
    }

    /// The ray through pixel `(u, v)`: origin (the camera centre) and unit direction, world
    /// coordinates.
    pub fn ray(&self, u: T, v: T) -> (Vector3<T>, Vector3<T>) {
        let dc = Vector3::new(
            (u - self.intrinsics.cx) / self.intrinsics.fx,
            (v - self.intrinsics.cy) / self.intrinsics.fy,
            T::one(),
        );
        let d = self.rotation.transpose() * dc;
        (self.centre, d / d.norm())
    }

    /// Whether pixel `(u, v)` lies within `margin` pixels of the image rectangle.
    pub fn in_image(&self, u: T, v: T, margin: T) -> bool {
        let w = T::of(f64::from(self.intrinsics.width));
        let h = T::of(f64::from(self.intrinsics.height));
        u >= -margin && v >= -margin && u <= w + margin && v <= h + margin
    }

    fn depth(&self, xc: &Vector3<T>, index: usize) -> Result<T, Error> {
        if xc.z > self.near && xc.x.finite() && xc.y.finite() && xc.z.finite() {
            Ok(xc.z)
        } else {
            Err(Error::BehindCamera { index })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera<f64> {
        // Looking down the world −z axis from 0.3 m above the origin, tilted about x.
        let a: f64 = 0.2;
        let tilt = Matrix3::new(1.0, 0.0, 0.0, 0.0, a.cos(), -a.sin(), 0.0, a.sin(), a.cos());
        let flip = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
        let r = tilt * flip;
        let centre = Vector3::new(0.01, -0.02, 0.3);
        let intr = Intrinsics {
            fx: 800.0,
            fy: 780.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        };
        Camera::new(intr, r, -(r * centre), 1e-4).unwrap()
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let cam = camera();
        let x = Vector3::new(0.02, 0.01, 0.03);
        let (_, j) = cam.project_with_jacobian(&x, 0).unwrap();
        let h = 1e-7;
        for k in 0..3 {
            let mut e = Vector3::zeros();
            e[k] = h;
            let d =
                (cam.project(&(x + e), 0).unwrap() - cam.project(&(x - e), 0).unwrap()) / (2.0 * h);
            for r in 0..2 {
                assert!(
                    (d[r] - j[(r, k)]).abs() <= 1e-6 * j.abs().max(),
                    "{d} vs {j}"
                );
            }
        }
    }

    #[test]
    fn ray_through_a_projection_passes_through_the_point() {
        let cam = camera();
        let x = Vector3::new(-0.03, 0.02, 0.01);
        let uv = cam.project(&x, 0).unwrap();
        let (o, d) = cam.ray(uv.x, uv.y);
        let along = (x - o).dot(&d);
        assert!((o + d * along - x).norm() < 1e-12);
        assert!(along > 0.0);
        assert!((cam.centre() - Vector3::new(0.01, -0.02, 0.3)).norm() < 1e-15);
    }

    #[test]
    fn points_behind_are_an_error() {
        let cam = camera();
        assert_eq!(
            cam.project(&Vector3::new(0.0, 0.0, 0.5), 7),
            Err(Error::BehindCamera { index: 7 })
        );
        assert_eq!(
            cam.project(&Vector3::new(f64::NAN, 0.0, 0.0), 3),
            Err(Error::BehindCamera { index: 3 })
        );
    }

    #[test]
    fn bad_parameters_are_rejected() {
        let intr = Intrinsics {
            fx: 0.0,
            fy: 1.0,
            cx: 0.0,
            cy: 0.0,
            width: 1,
            height: 1,
        };
        let err = Camera::new(intr, Matrix3::identity(), Vector3::zeros(), 0.0);
        assert_eq!(
            err,
            Err(Error::InvalidParameter {
                parameter: Parameter::Intrinsics
            })
        );
        let intr = Intrinsics { fx: 1.0, ..intr };
        let skew = Matrix3::new(1.0, 0.1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert_eq!(
            Camera::new(intr, skew, Vector3::zeros(), 0.0),
            Err(Error::InvalidParameter {
                parameter: Parameter::Pose
            })
        );
    }
}
