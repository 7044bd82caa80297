//! The camera: projection of model points into the image, its Jacobian, and the rays through
//! pixels that place virtual features at frame 0.
//!
//! Conventions (OpenCV's): a world point `x` (metres) has camera coordinates `x_c = R x + t`,
//! with `z_c` pointing away from the camera, `x_c` to the right and `y_c` down the image. A
//! pinhole camera ([`Projection::Perspective`], feature `perspective`) puts it at pixel
//! `u = fx·x_c/z_c + cx`, `v = fy·y_c/z_c + cy`; an orthographic one
//! ([`Projection::Orthographic`], feature `orthographic`: a telecentric lens, or a camera far
//! from a small scene) at `u = fx·x_c + cx`, `v = fy·y_c + cy`, with `fx`, `fy` in pixels per
//! metre and every ray parallel to the optical axis. Lens distortion is the host's concern (it
//! undistorts tracked points before they reach the core).

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

/// How a camera maps camera coordinates to pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Projection {
    /// The pinhole: rays through the camera centre (feature `perspective`).
    Perspective,
    /// Parallel rays along the optical axis; `fx`, `fy` in pixels per metre (feature
    /// `orthographic`).
    Orthographic,
}

impl Projection {
    /// Whether this core was built with the projection (features `perspective`,
    /// `orthographic`).
    pub const fn is_built(&self) -> bool {
        match self {
            Projection::Perspective => cfg!(feature = "perspective"),
            Projection::Orthographic => cfg!(feature = "orthographic"),
        }
    }
}

/// A calibrated camera with its pose.
///
/// Built by [`Camera::new`] (pinhole) or [`Camera::orthographic`], which check the parameters
/// once; projection then only fails for a point at or behind the near plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera<T: Real> {
    projection: Projection,
    intrinsics: Intrinsics<T>,
    rotation: Matrix3<T>,
    translation: Vector3<T>,
    /// Camera centre in world coordinates, `−Rᵀ t` (for an orthographic camera, the origin of
    /// its frame, on the plane the rays start from).
    centre: Vector3<T>,
    /// Points with `z_c` at or below this depth (metres) are "behind" the camera.
    near: T,
}

impl<T: Real> Camera<T> {
    /// A pinhole camera with intrinsics, world-to-camera rotation `R` and translation `t`
    /// (metres). Points closer than `near` metres along the optical axis cannot be projected.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] with [`Parameter::Intrinsics`] for non-positive or non-finite
    /// focal lengths, a non-finite principal point or an empty image; with [`Parameter::Pose`]
    /// for a non-finite pose, a rotation that is not orthonormal with determinant 1, or a
    /// negative or non-finite `near`; with [`Parameter::Projection`] in a core built without
    /// the `perspective` feature.
    pub fn new(
        intrinsics: Intrinsics<T>,
        rotation: Matrix3<T>,
        translation: Vector3<T>,
        near: T,
    ) -> Result<Self, Error> {
        Self::with_projection(
            Projection::Perspective,
            intrinsics,
            rotation,
            translation,
            near,
        )
    }

    /// An orthographic camera: as [`Camera::new`], with `fx`, `fy` in pixels per metre.
    ///
    /// # Errors
    /// As [`Camera::new`]; [`Parameter::Projection`] in a core built without the
    /// `orthographic` feature.
    pub fn orthographic(
        intrinsics: Intrinsics<T>,
        rotation: Matrix3<T>,
        translation: Vector3<T>,
        near: T,
    ) -> Result<Self, Error> {
        Self::with_projection(
            Projection::Orthographic,
            intrinsics,
            rotation,
            translation,
            near,
        )
    }

    /// The same camera in another scalar type (each value rounded to it).
    ///
    /// # Errors
    /// As [`Camera::with_projection`], for values that do not fit `U` (a focal length or a
    /// distance beyond its range).
    pub fn cast<U: Real>(&self) -> Result<Camera<U>, Error> {
        let c = |x: T| U::of(x.to_f64());
        let i = &self.intrinsics;
        Camera::with_projection(
            self.projection,
            Intrinsics {
                fx: c(i.fx),
                fy: c(i.fy),
                cx: c(i.cx),
                cy: c(i.cy),
                width: i.width,
                height: i.height,
            },
            self.rotation.map(c),
            self.translation.map(c),
            c(self.near),
        )
    }

    /// A camera of either projection ([`Camera::new`], [`Camera::orthographic`]).
    ///
    /// # Errors
    /// As [`Camera::new`].
    pub fn with_projection(
        projection: Projection,
        intrinsics: Intrinsics<T>,
        rotation: Matrix3<T>,
        translation: Vector3<T>,
        near: T,
    ) -> Result<Self, Error> {
        if !projection.is_built() {
            return Err(Error::InvalidParameter {
                parameter: Parameter::Projection,
            });
        }
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
            projection,
            intrinsics,
            rotation,
            translation,
            centre: -(rotation.transpose() * translation),
            near,
        })
    }

    /// The projection.
    pub fn projection(&self) -> Projection {
        self.projection
    }

    /// Whether the camera is orthographic; a constant `false` in a core built without the
    /// `orthographic` feature, so that its branches leave the build.
    #[inline]
    fn is_orthographic(&self) -> bool {
        cfg!(feature = "orthographic") && self.projection == Projection::Orthographic
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

    /// Camera centre in world coordinates, metres (for an orthographic camera, the origin of its
    /// frame).
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
        Ok(self.pixel(&xc, z))
    }

    /// The pixel of camera coordinates `xc` at depth `z` (checked in front).
    fn pixel(&self, xc: &Vector3<T>, z: T) -> Vector2<T> {
        let i = &self.intrinsics;
        if self.is_orthographic() {
            Vector2::new(i.fx * xc.x + i.cx, i.fy * xc.y + i.cy)
        } else {
            Vector2::new(i.fx * xc.x / z + i.cx, i.fy * xc.y / z + i.cy)
        }
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
        let jc = if self.is_orthographic() {
            Matrix2x3::new(fx, T::zero(), T::zero(), T::zero(), fy, T::zero())
        } else {
            let z2 = z * z;
            Matrix2x3::new(
                fx / z,
                T::zero(),
                -fx * xc.x / z2,
                T::zero(),
                fy / z,
                -fy * xc.y / z2,
            )
        };
        Ok((self.pixel(&xc, z), jc * self.rotation))
    }

    /// The ray through pixel `(u, v)`: origin (the camera centre; for an orthographic camera,
    /// the pixel's point on the plane `z_c = 0`) and unit direction, world coordinates.
    pub fn ray(&self, u: T, v: T) -> (Vector3<T>, Vector3<T>) {
        if self.is_orthographic() {
            let on_plane = Vector3::new(
                (u - self.intrinsics.cx) / self.intrinsics.fx,
                (v - self.intrinsics.cy) / self.intrinsics.fy,
                T::zero(),
            );
            let origin = self.rotation.transpose() * (on_plane - self.translation);
            return (origin, self.view_direction());
        }
        let dc = Vector3::new(
            (u - self.intrinsics.cx) / self.intrinsics.fx,
            (v - self.intrinsics.cy) / self.intrinsics.fy,
            T::one(),
        );
        let d = self.rotation.transpose() * dc;
        (self.centre, d / d.norm())
    }

    /// Unit direction of the ray through world point `q`, away from the camera.
    pub fn ray_direction_through(&self, q: &Vector3<T>) -> Vector3<T> {
        if self.is_orthographic() {
            return self.view_direction();
        }
        let r = q - self.centre;
        let n = r.norm();
        if n > T::zero() { r / n } else { r }
    }

    /// A point the camera sees `p` from, to tell which side of a surface through `p` faces it:
    /// the centre of a pinhole camera, or a point one metre back along the optical axis for an
    /// orthographic one.
    pub fn viewpoint_for(&self, p: &Vector3<T>) -> Vector3<T> {
        if self.is_orthographic() {
            p - self.view_direction()
        } else {
            self.centre
        }
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

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;

    fn camera() -> Camera<f64> {
        camera_of(Projection::Perspective)
    }

    /// Both projections, in a core that has them.
    fn cameras() -> impl Iterator<Item = Camera<f64>> {
        [Projection::Perspective, Projection::Orthographic]
            .into_iter()
            .filter(Projection::is_built)
            .map(camera_of)
    }

    fn camera_of(projection: Projection) -> Camera<f64> {
        // Looking down the world −z axis from 0.3 m above the origin, tilted about x; the
        // orthographic camera sees the scene at the pinhole's scale at 0.3 m.
        let a: f64 = 0.2;
        let tilt = Matrix3::new(1.0, 0.0, 0.0, 0.0, a.cos(), -a.sin(), 0.0, a.sin(), a.cos());
        let flip = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
        let r = tilt * flip;
        let centre = Vector3::new(0.01, -0.02, 0.3);
        let scale = match projection {
            Projection::Perspective => 1.0,
            Projection::Orthographic => 1.0 / 0.3,
        };
        let intr = Intrinsics {
            fx: 800.0 * scale,
            fy: 780.0 * scale,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        };
        Camera::with_projection(projection, intr, r, -(r * centre), 1e-4).unwrap()
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        for cam in cameras() {
            jacobian_of(&cam);
        }
    }

    fn jacobian_of(cam: &Camera<f64>) {
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
        for cam in cameras() {
            let x = Vector3::new(-0.03, 0.02, 0.01);
            let uv = cam.project(&x, 0).unwrap();
            let (o, d) = cam.ray(uv.x, uv.y);
            let along = (x - o).dot(&d);
            assert!((o + d * along - x).norm() < 1e-12);
            assert!(along > 0.0);
            assert!((cam.centre() - Vector3::new(0.01, -0.02, 0.3)).norm() < 1e-15);
            // The ray through the point is the one `ray_direction_through` gives, and the
            // viewpoint lies back along it.
            assert!((cam.ray_direction_through(&x) - d).norm() < 1e-12);
            let eye = cam.viewpoint_for(&x);
            assert!(((x - eye).normalize() - d).norm() < 1e-12);
        }
    }

    #[test]
    fn the_orthographic_camera_maps_metres_to_pixels_at_any_depth() {
        if !Projection::Orthographic.is_built() {
            return;
        }
        let cam = camera_of(Projection::Orthographic);
        // Two points on one ray, at different depths: one pixel; a step across the ray of a
        // millimetre moves it by fx · 1 mm.
        let x = Vector3::new(0.01, 0.02, 0.0);
        let d = cam.view_direction();
        let a = cam.project(&x, 0).unwrap();
        let b = cam.project(&(x + d * 0.05), 0).unwrap();
        assert!((a - b).norm() < 1e-9);
        let right = cam.rotation().row(0).transpose();
        let c = cam.project(&(x + right * 1e-3), 0).unwrap();
        assert!((c.x - a.x - cam.intrinsics().fx * 1e-3).abs() < 1e-9);
    }

    #[test]
    fn a_projection_not_built_is_refused() {
        let intr = Intrinsics {
            fx: 1.0,
            fy: 1.0,
            cx: 0.0,
            cy: 0.0,
            width: 1,
            height: 1,
        };
        for projection in [Projection::Perspective, Projection::Orthographic] {
            let camera = Camera::with_projection(
                projection,
                intr,
                Matrix3::identity(),
                Vector3::zeros(),
                0.0,
            );
            assert_eq!(
                camera.is_ok(),
                projection.is_built(),
                "{projection:?}: {camera:?}"
            );
            if !projection.is_built() {
                assert_eq!(
                    camera,
                    Err(Error::InvalidParameter {
                        parameter: Parameter::Projection
                    })
                );
            }
        }
    }

    #[test]
    fn points_behind_are_an_error() {
        if !Projection::Perspective.is_built() {
            return;
        }
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
        let err = Camera::orthographic(intr, Matrix3::identity(), Vector3::zeros(), 0.0)
            .and_then(|_| Camera::new(intr, Matrix3::identity(), Vector3::zeros(), 0.0));
        assert!(matches!(err, Err(Error::InvalidParameter { .. })));
        let both = |intr, r| {
            [Projection::Perspective, Projection::Orthographic]
                .into_iter()
                .filter(Projection::is_built)
                .map(move |p| Camera::with_projection(p, intr, r, Vector3::zeros(), 0.0))
        };
        for err in both(intr, Matrix3::identity()) {
            assert_eq!(
                err,
                Err(Error::InvalidParameter {
                    parameter: Parameter::Intrinsics
                })
            );
        }
        let intr = Intrinsics { fx: 1.0, ..intr };
        let skew = Matrix3::new(1.0, 0.1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        for err in both(intr, skew) {
            assert_eq!(
                err,
                Err(Error::InvalidParameter {
                    parameter: Parameter::Pose
                })
            );
        }
    }
}
