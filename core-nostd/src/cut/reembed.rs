//! Moving the points a cut affects: features and targets in a split tetrahedron go to the
//! piece holding their material point; a feature whose piece lies on the other side of the cut
//! than its observation goes to the surface of its own side.

use crate::camera::Camera;
use crate::embed::{Embedding, barycentric, clamp_weights, gather, interpolate};
use crate::mesh::{Mesh, orientation};
use crate::real::Real;
use crate::sparse::NONE;

use super::split::Sign;
use super::surface::SeparationSurface;
use super::{CutEvent, side_of, sign};

/// Re-embeds the points of the split tetrahedra (`status` and `parents` as
/// [`super::split::split_selected`] leaves them; `t0` tetrahedra before the split) in the piece
/// holding their material point: the point in the parent as snapped (its former nodes, at their
/// rest positions now), located among the parent's pieces by its barycentric weights.
pub(super) fn into_pieces<T: Real>(
    mesh: &Mesh<'_, T>,
    embeddings: [&mut Embedding<'_, T>; 2],
    status: &[u32],
    parents: &[[u32; 4]],
    t0: usize,
    event: &mut CutEvent,
) {
    for embedding in embeddings {
        for k in 0..embedding.len() {
            let (Some(&t), Some(&w)) = (embedding.tets().get(k), embedding.weights().get(k)) else {
                continue;
            };
            let t = t as usize;
            let first = status.get(t).copied().unwrap_or(NONE);
            if t >= t0 || first == NONE {
                continue;
            }
            let Some(p) = parents
                .get(t)
                .and_then(|parent| interpolate(mesh.rest(), parent, &w))
            else {
                continue;
            };
            let mut best: Option<(T, u32, [T; 4])> = None;
            let (start, count) = ((first >> 3) as usize, (first & 7) as usize);
            for child in core::iter::once(t).chain(start..start + count) {
                let Some(corners) = mesh
                    .tets()
                    .get(child)
                    .and_then(|tet| gather(mesh.rest(), tet))
                else {
                    continue;
                };
                event.work.embed_tests += 1;
                if let Some(w) = barycentric(&corners, p) {
                    let score = w.iter().fold(T::one(), |m, &c| m.min(c));
                    if best.as_ref().is_none_or(|(b, _, _)| score > *b) {
                        best = Some((score, child as u32, w));
                    }
                }
            }
            if let Some((_, c, w)) = best
                && let Some(w) = clamp_weights(w)
            {
                embedding.set(k, c, w);
                event.points_reembedded += 1;
            }
        }
    }
}

/// A feature whose observation (`observed`, by slot) lies beside the cut line, clearly on one
/// side, but whose piece lies on the other (its piece can reach over the line: snapping bends
/// the cut by up to the snapping tolerance) goes to the nearest point, in the image, of the
/// boundary of its own side that faces the camera.
#[allow(clippy::too_many_arguments)]
pub(super) fn features_to_their_side<T: Real>(
    mesh: &Mesh<'_, T>,
    x: &[[T; 3]],
    features: &mut Embedding<'_, T>,
    observed: &[[T; 2]],
    sep: &SeparationSurface<'_, T>,
    camera: &Camera<T>,
    phi: &[T],
    event: &mut CutEvent,
) {
    for (k, &uv) in observed.iter().enumerate().take(features.len()) {
        let Some(foot) = sep.foot(uv) else {
            continue;
        };
        if !foot.inside || foot.signed_px.abs() < T::one() {
            continue;
        }
        let seen: Sign = sign(foot.signed_px);
        let Some(tet) = features
            .tets()
            .get(k)
            .and_then(|&t| mesh.tets().get(t as usize))
        else {
            continue;
        };
        if side_of(phi, tet) == seen {
            continue;
        }
        event.work.embed_tests += mesh.surface().len() as u64;
        let near = nearest_visible_point(mesh, x, camera, uv, |tet| {
            mesh.tets()
                .get(tet as usize)
                .is_some_and(|tet| side_of(phi, tet) == seen)
        });
        if let Some((tet, w)) = near {
            features.set(k, tet, w);
            event.features_moved_across += 1;
        }
    }
}

/// The point of the boundary surface, on a triangle facing the camera whose tetrahedron
/// `accept` takes, whose image is nearest to pixel `uv`: as (tetrahedron, barycentric weights).
/// Cost: one projection per boundary triangle.
fn nearest_visible_point<T: Real>(
    mesh: &Mesh<'_, T>,
    x: &[[T; 3]],
    camera: &Camera<T>,
    uv: [T; 2],
    accept: impl Fn(u32) -> bool,
) -> Option<(u32, [T; 4])> {
    let mut best: Option<(T, u32, [T; 3])> = None;
    'triangles: for (tri, &tet) in mesh.surface().iter().zip(mesh.surface_tet()) {
        if !accept(tet) {
            continue;
        }
        let Some(p) = gather(x, tri) else {
            continue;
        };
        // Facing the camera: the camera lies on the outer side of the triangle.
        let eye = camera.viewpoint_for(&nalgebra::Vector3::new(p[0][0], p[0][1], p[0][2]));
        if orientation(p[0], p[1], p[2], [eye.x, eye.y, eye.z]) <= T::zero() {
            continue;
        }
        let mut q = [[T::zero(); 2]; 3];
        for (qk, pk) in q.iter_mut().zip(&p) {
            // A corner the camera cannot project (behind it): the triangle has no image.
            let Ok(image) = camera.project(&nalgebra::Vector3::new(pk[0], pk[1], pk[2]), 0) else {
                continue 'triangles;
            };
            *qk = [image.x, image.y];
        }
        let (d2, b) = closest_in_triangle(q, uv);
        if best.as_ref().is_none_or(|(bd, _, _)| d2 < *bd) {
            let at = |c0: T, c1: T, c2: T| c0 * b[0] + c1 * b[1] + c2 * b[2];
            let [p0, p1, p2] = p;
            let point = [
                at(p0[0], p1[0], p2[0]),
                at(p0[1], p1[1], p2[1]),
                at(p0[2], p1[2], p2[2]),
            ];
            best = Some((d2, tet, point));
        }
    }
    let (_, tet, point) = best?;
    let corners = gather(x, mesh.tets().get(tet as usize)?)?;
    Some((tet, clamp_weights(barycentric(&corners, point)?)?))
}

/// Squared distance from `p` to the triangle `q` in the plane, and the barycentric weights of
/// the closest point.
fn closest_in_triangle<T: Real>(q: [[T; 2]; 3], p: [T; 2]) -> (T, [T; 3]) {
    let d = |a: [T; 2], b: [T; 2]| (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]);
    let (e1, e2) = (
        [q[1][0] - q[0][0], q[1][1] - q[0][1]],
        [q[2][0] - q[0][0], q[2][1] - q[0][1]],
    );
    let det = e1[0] * e2[1] - e1[1] * e2[0];
    if det.abs() > T::EPS {
        let w = [p[0] - q[0][0], p[1] - q[0][1]];
        let b1 = (w[0] * e2[1] - w[1] * e2[0]) / det;
        let b2 = (e1[0] * w[1] - e1[1] * w[0]) / det;
        if b1 >= T::zero() && b2 >= T::zero() && b1 + b2 <= T::one() {
            return (T::zero(), [T::one() - b1 - b2, b1, b2]);
        }
    }
    // Outside (or degenerate): the nearest point of the three edges.
    let mut best = (d(p, q[0]), [T::one(), T::zero(), T::zero()]);
    // Edge `k` runs from corner `k` to corner `k + 1` (mod 3).
    let edges = [(q[0], q[1]), (q[1], q[2]), (q[2], q[0])];
    for (k, (a, b)) in edges.into_iter().enumerate() {
        let e = [b[0] - a[0], b[1] - a[1]];
        let len2 = e[0] * e[0] + e[1] * e[1];
        let t = if len2 > T::EPS {
            (((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / len2)
                .max(T::zero())
                .min(T::one())
        } else {
            T::zero()
        };
        let c = [a[0] + e[0] * t, a[1] + e[1] * t];
        let dist = d(p, c);
        if dist < best.0 {
            let (s, o) = (T::one() - t, T::zero());
            let w = match k {
                0 => [s, t, o],
                1 => [o, s, t],
                _ => [t, o, s],
            };
            best = (dist, w);
        }
    }
    best
}
