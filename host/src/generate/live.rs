//! Live cuts: a slit that grows while the object is filmed, like scissors advancing.
//!
//! The whole slit is cut into the real mesh once, as for a pre-cut ([`super::object`]). Each
//! `(original, duplicate)` node pair of its lips then gets a *release frame* from its place
//! along the slit's growth direction ([`Growth`]): the front starts where the slit meets the
//! object's boundary and moves at constant speed to the slit's far end, which it reaches at
//! the last frame of `grow` ([`release_frames`]). Until its release frame a pair is *tied*:
//! the duplicate is replaced by the original in every tetrahedron ([`tied_tets`]), so the mesh
//! is the uncut one there, and the duplicate (in no tetrahedron) is moved with the original.
//! The simulator is rebuilt with the new connectivity whenever pairs are released and carries
//! on from the previous frame's positions: at release the two lips coincide, so the state is
//! the same body with fewer ties, and the next solve lets the lips come apart.

use incise_core::Camera;
use incise_core::nalgebra::Vector3;

use crate::generate::object::Slit;
use crate::generate::scenario::SlitSection;

/// Release frame of a pair that is open from the start (a pre-cut slit).
pub const OPEN: u32 = 0;

/// Release frame of a node that never opens (the slit's front, where its lips meet).
pub const NEVER: u32 = u32::MAX;

/// The direction along which a slit grows, and the coordinate that measures it.
#[derive(Clone, Debug)]
pub enum Growth {
    /// An image slit: pixels along the segment from its first end, seen through `camera` at
    /// rest.
    Image {
        /// The camera the segment is given in.
        camera: Camera<f64>,
        /// The first end (pixels).
        from: [f64; 2],
        /// Unit direction from the first end to the second.
        dir: [f64; 2],
    },
    /// A plane slit: metres along a coordinate axis, from the side of the region that reaches
    /// past the object.
    Axis {
        /// 0, 1, 2 for x, y, z.
        axis: usize,
        /// +1 to grow toward increasing coordinates, −1 toward decreasing ones.
        sign: f64,
    },
}

impl Growth {
    /// The growth coordinate of a rest position: larger is reached later.
    pub fn coordinate(&self, p: [f64; 3]) -> f64 {
        match self {
            Growth::Image { camera, from, dir } => {
                camera.project(&Vector3::from(p), 0).map_or(0.0, |uv| {
                    (uv.x - from[0]) * dir[0] + (uv.y - from[1]) * dir[1]
                })
            }
            Growth::Axis { axis, sign } => sign * p[*axis],
        }
    }
}

/// How a plane slit's region lies along one coordinate axis against the object.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RegionSides {
    /// The axis.
    pub axis: usize,
    /// The region reaches past the object's smallest coordinate along it.
    pub past_min: bool,
    /// The region reaches past the object's largest coordinate along it.
    pub past_max: bool,
}

/// The axes that lie in a slit plane of normal `normal` (those along which the normal has at
/// most half its length), with how `region` lies against the object's bounding box `extent`
/// (`[min, max]`) along each.
pub fn region_sides(
    normal: [f64; 3],
    region: &[[f64; 3]; 2],
    extent: &[[f64; 3]; 2],
) -> Vec<RegionSides> {
    let len = normal.iter().map(|c| c * c).sum::<f64>().sqrt();
    (0..3)
        .filter(|&k| normal[k].abs() <= 0.5 * len)
        .map(|axis| RegionSides {
            axis,
            past_min: region[0][axis] <= extent[0][axis],
            past_max: region[1][axis] >= extent[1][axis],
        })
        .collect()
}

/// The in-plane axis along which a plane slit starts at the object's boundary: the one axis
/// along which its region reaches past the object on exactly one side.
///
/// # Errors
/// A message when no axis or several qualify (a slit across the middle, or through a corner).
pub fn plane_growth_axis(
    normal: [f64; 3],
    region: &[[f64; 3]; 2],
    extent: &[[f64; 3]; 2],
) -> Result<RegionSides, String> {
    let one_sided: Vec<RegionSides> = region_sides(normal, region, extent)
        .into_iter()
        .filter(|s| s.past_min != s.past_max)
        .collect();
    match one_sided.as_slice() {
        [s] => Ok(*s),
        _ => Err(format!(
            "cannot tell where the slit starts: its region must reach past the object on \
             exactly one side along exactly one axis in the slit's plane ({} do)",
            one_sided.len()
        )),
    }
}

/// The bounding box `[min, max]` of `nodes`.
pub fn extent(nodes: &[[f64; 3]]) -> [[f64; 3]; 2] {
    let mut e = [[f64::INFINITY; 3], [f64::NEG_INFINITY; 3]];
    for p in nodes {
        for k in 0..3 {
            e[0][k] = e[0][k].min(p[k]);
            e[1][k] = e[1][k].max(p[k]);
        }
    }
    e
}

/// The growth direction of the slit `sl` cut into an object whose rest nodes are `nodes`;
/// `camera` is the camera an image slit is given in.
///
/// # Errors
/// A message for a plane slit whose start cannot be told ([`plane_growth_axis`]) or a slit
/// given neither way.
pub fn growth(
    sl: &SlitSection,
    nodes: &[[f64; 3]],
    camera: &Camera<f64>,
) -> Result<Growth, String> {
    match (sl.image, sl.normal, sl.region) {
        (Some([a, b]), _, _) => {
            let len = (b[0] - a[0]).hypot(b[1] - a[1]);
            Ok(Growth::Image {
                camera: *camera,
                from: a,
                dir: [(b[0] - a[0]) / len, (b[1] - a[1]) / len],
            })
        }
        (None, Some(normal), Some(region)) => {
            let s = plane_growth_axis(normal, &region, &extent(nodes))?;
            Ok(Growth::Axis {
                axis: s.axis,
                sign: if s.past_min { 1.0 } else { -1.0 },
            })
        }
        _ => Err("a slit is either a plane with a region or an image segment".into()),
    }
}

/// The release frame of every lip pair of `slit` (in the order of `slit.pairs`) for a cut
/// that grows over `grow = [start, end]`: a pair at distance `d` along the growth direction
/// from the slit's first node opens at `start + max(1, ⌈(end − start) d / L⌉)`, `L` the
/// slit's full length (its first to its last node, front included). `nodes` are the rest
/// positions.
pub fn release_frames(
    slit: &Slit,
    nodes: &[[f64; 3]],
    growth: &Growth,
    grow: [u32; 2],
) -> Vec<u32> {
    let coordinate = |v: u32| growth.coordinate(nodes[v as usize]);
    let all = slit
        .pairs
        .iter()
        .map(|p| p.0)
        .chain(slit.front.iter().copied());
    let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        let c = coordinate(v);
        (lo.min(c), hi.max(c))
    });
    let [start, end] = grow;
    let span = f64::from(end - start);
    let length = hi - lo;
    slit.pairs
        .iter()
        .map(|&(v, _)| {
            let fraction = if length > 0.0 {
                (coordinate(v) - lo) / length
            } else {
                0.0
            };
            // A tiny allowance so that rounding in the coordinate does not delay a pair that
            // sits exactly on a frame's front by a whole frame.
            let steps = (span * fraction - 1e-9).ceil().clamp(1.0, span) as u32;
            start + steps
        })
        .collect()
}

/// The tetrahedra of the real mesh at `frame`: every duplicate of a pair not yet released
/// (`release[i] > frame`) replaced by its original.
pub fn tied_tets(
    tets: &[[u32; 4]],
    pairs: &[(u32, u32)],
    release: &[u32],
    frame: u32,
) -> Vec<[u32; 4]> {
    let tied: std::collections::HashMap<u32, u32> = pairs
        .iter()
        .zip(release)
        .filter(|&(_, &r)| r > frame)
        .map(|(&(v, d), _)| (d, v))
        .collect();
    if tied.is_empty() {
        return tets.to_vec();
    }
    tets.iter()
        .map(|t| t.map(|v| tied.get(&v).copied().unwrap_or(v)))
        .collect()
}

/// Pairs released by `frame`.
pub fn released(release: &[u32], frame: u32) -> usize {
    release.iter().filter(|&&r| r <= frame).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::object::{TetMesh, cut_slit};

    #[test]
    fn a_side_slit_grows_from_the_edge_and_is_whole_at_the_end() {
        // 8 × 4 × 1 cells over 1 × 1 × 0.25; slit at x = 0.5 from y = 0 to y = 0.75.
        let band = TetMesh::band([1.0, 1.0, 0.25], [8, 4, 1]);
        let region = [[0.4, -0.1, -0.1], [0.6, 0.76, 1.0]];
        let normal = [1.0, 0.0, 0.0];
        let slit = cut_slit(&band, [0.5, 0.0, 0.0], normal, region);
        let sl = SlitSection {
            point: Some([0.5, 0.0, 0.0]),
            normal: Some(normal),
            region: Some(region),
            image: None,
            camera: None,
            grow: Some([5, 11]),
        };
        let camera = crate::generate::test_camera();
        let g = growth(&sl, &band.nodes, &camera).unwrap();
        assert!(matches!(g, Growth::Axis { axis: 1, sign } if sign == 1.0));
        let release = release_frames(&slit, &slit.mesh.nodes, &g, [5, 11]);
        // Rows y = 0, 0.25, 0.5 are split; y = 0.75 is the front: distances 0, 1/3, 2/3.
        for (&(v, _), &r) in slit.pairs.iter().zip(&release) {
            let y = slit.mesh.nodes[v as usize][1];
            let want = match (4.0 * y).round() as u32 {
                0 => 6,
                1 => 7,
                2 => 9,
                other => panic!("unexpected row {other}"),
            };
            assert_eq!(r, want, "pair at y = {y}");
        }
        assert_eq!(released(&release, 5), 0);
        assert_eq!(released(&release, 11), slit.pairs.len());
        // Tied, the mesh is the uncut band; released, it is the slit mesh.
        assert_eq!(
            tied_tets(&slit.mesh.tets, &slit.pairs, &release, 5),
            band.tets
        );
        assert_eq!(
            tied_tets(&slit.mesh.tets, &slit.pairs, &release, 11),
            slit.mesh.tets
        );
        // A region past the object on both sides in the plane (or on none) has no start.
        let middle = [[0.4, 0.2, -0.1], [0.6, 0.8, 1.0]];
        assert!(plane_growth_axis(normal, &middle, &extent(&band.nodes)).is_err());
    }
}
