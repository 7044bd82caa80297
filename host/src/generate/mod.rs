//! The synthetic-scene generator: the *real* object behind a scene, its scripted motion and its
//! images, with the ground truth the model is scored against.
//!
//! - [`neohookean`]: compressible Neo-Hookean elasticity on linear tetrahedra (energy, forces,
//!   positive semidefinite Hessian), the real object's law, deliberately not the model's SVK.
//! - [`sim`]: the quasi-static simulator of the real object, driven frame by frame through
//!   prescribed (held or grasped) nodes.
//! - [`object`]: the real object's mesh (a fine band or dome, an organ's own fine mesh such as
//!   SOFA's `liverFine.vtu`, or the organ model refined eight-fold) and the slit, made by
//!   duplicating nodes on a surface of mesh faces.
//! - [`live`]: live cuts, whose slit grows while the object is filmed.
//! - [`tracking`]: what a tracker would report: features on the visible surface, hidden when
//!   occluded, with noise, drop-outs and jumps.
//! - [`scenario`]: the `scenario.toml` a scene is generated from.
//! - [`texture`]: the textured pictures of the real object (the video the OpenCV path tracks).
//! - [`pipeline`]: `incise gen` itself, frame by frame, and the files it writes.
//! - [`family`]: families of scene variants drawn around a base scenario (`incise gen
//!   --family`).

pub mod family;
pub mod live;
pub mod neohookean;
pub mod object;
pub mod pipeline;
pub mod scenario;
pub mod sim;
pub mod texture;
pub mod tracking;

/// A camera the generator's tests look through: 100 × 100 pixels, focal 100, at `z = -1`
/// looking along `+z` (world `z = 0` is one unit in front of it).
#[cfg(test)]
pub(crate) fn test_camera() -> incise_core::Camera<f64> {
    incise_core::Camera::new(
        incise_core::Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 50.0,
            cy: 50.0,
            width: 100,
            height: 100,
        },
        incise_core::nalgebra::Matrix3::identity(),
        incise_core::nalgebra::Vector3::new(0.0, 0.0, 1.0),
        1e-4,
    )
    .unwrap()
}
