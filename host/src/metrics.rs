//! The metrics of DESIGN.md, the same everywhere: Dice of silhouettes, surface RMS distance,
//! target registration error, and the distance between cut polylines.

use crate::render::Mask;

/// Dice coefficient `2 |A ∩ B| / (|A| + |B|)` of two masks of the same size (1 when both are
/// empty).
///
/// # Panics
/// If the masks differ in size (a programming error: both come from the same camera).
pub fn dice(a: &Mask, b: &Mask) -> f64 {
    assert_eq!(
        (a.width, a.height),
        (b.width, b.height),
        "Dice of masks of different sizes"
    );
    let (mut both, mut na, mut nb) = (0usize, 0usize, 0usize);
    for (&x, &y) in a.data.iter().zip(&b.data) {
        let (x, y) = (x != 0, y != 0);
        both += usize::from(x && y);
        na += usize::from(x);
        nb += usize::from(y);
    }
    if na + nb == 0 {
        1.0
    } else {
        2.0 * both as f64 / (na + nb) as f64
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Distance from `p` to the closed triangle `(a, b, c)` (Ericson's closest-point regions).
pub fn point_triangle_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let closest = closest_on_triangle(p, a, b, c);
    let d = sub(p, closest);
    dot(d, d).sqrt()
}

fn closest_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let lerp =
        |o: [f64; 3], d: [f64; 3], t: f64| [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return lerp(a, ab, d1 / (d1 - d3));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return lerp(a, ac, d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return lerp(b, sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    [
        a[0] + ab[0] * v + ac[0] * w,
        a[1] + ab[1] * v + ac[1] * w,
        a[2] + ab[2] * v + ac[2] * w,
    ]
}

/// Distance from `p` to the nearest of `triangles` over `positions`.
pub fn point_surface_distance(p: [f64; 3], positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            point_triangle_distance(
                p,
                positions[t[0] as usize],
                positions[t[1] as usize],
                positions[t[2] as usize],
            )
        })
        .fold(f64::INFINITY, f64::min)
}

/// Root-mean-square distance from `points` to a triangulated surface (metres in, metres out).
/// The cost is points × triangles, fine for the scenes' few thousand of each.
pub fn surface_rms(points: &[[f64; 3]], positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let sum: f64 = points
        .iter()
        .map(|&p| point_surface_distance(p, positions, triangles).powi(2))
        .sum();
    (sum / points.len() as f64).sqrt()
}

/// Root-mean-square distance between paired points (target registration error when `a` are
/// the model's predictions of internal targets and `b` their true positions).
///
/// # Panics
/// If the slices differ in length.
pub fn paired_rms(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    assert_eq!(a.len(), b.len(), "paired points of different counts");
    if a.is_empty() {
        return 0.0;
    }
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| dot(sub(*p, *q), sub(*p, *q)))
        .sum();
    (sum / a.len() as f64).sqrt()
}

/// The centroid of `points` and the unit direction of their principal axis, the line that
/// fits them best in total least squares (from the angle of their 2 × 2 scatter matrix); `None`
/// for fewer than two points. The direction's sign is the angle's.
pub fn principal_axis(points: &[[f64; 2]]) -> Option<([f64; 2], [f64; 2])> {
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let mean = [
        points.iter().map(|p| p[0]).sum::<f64>() / n,
        points.iter().map(|p| p[1]).sum::<f64>() / n,
    ];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - mean[0], p[1] - mean[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some((mean, [angle.cos(), angle.sin()]))
}

/// Distance from `p` to the segment `a–b` in the image plane.
pub fn point_segment_distance_2d(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    distance_2d(p, closest_on_segment(p, a, b))
}

/// Distance between two image points.
pub fn distance_2d(p: [f64; 2], q: [f64; 2]) -> f64 {
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    (dx * dx + dy * dy).sqrt()
}

/// The point of segment `ab` nearest `p`.
fn closest_on_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    [a[0] + t * dx, a[1] + t * dy]
}

/// The point of `line` nearest `p` and its distance; `None` for an empty line.
fn closest_on_polyline(p: [f64; 2], line: &[[f64; 2]]) -> Option<([f64; 2], f64)> {
    let nearest = |q: [f64; 2]| (q, distance_2d(p, q));
    match line {
        [] => None,
        [a] => Some(nearest(*a)),
        _ => line
            .windows(2)
            .map(|w| nearest(closest_on_segment(p, w[0], w[1])))
            .min_by(|x, y| x.1.total_cmp(&y.1)),
    }
}

/// Where along `line` the point of it nearest `p` lies (its arc length from the line's first
/// point) and how far `p` is from it; `None` for an empty line.
pub fn arc_position(p: [f64; 2], line: &[[f64; 2]]) -> Option<(f64, f64)> {
    let first = *line.first()?;
    let mut best = (0.0, distance_2d(p, first));
    let mut walked = 0.0;
    for w in line.windows(2) {
        let q = closest_on_segment(p, w[0], w[1]);
        let d = distance_2d(p, q);
        if d < best.1 {
            best = (walked + distance_2d(w[0], q), d);
        }
        walked += distance_2d(w[0], w[1]);
    }
    Some(best)
}

/// The point at arc length `s` along `line` from its first point, clamped to its ends; `None`
/// for an empty line.
pub fn point_at_arc(line: &[[f64; 2]], s: f64) -> Option<[f64; 2]> {
    let mut walked = 0.0;
    for w in line.windows(2) {
        let length = distance_2d(w[0], w[1]);
        if length > 0.0 && walked + length >= s {
            let t = ((s - walked) / length).clamp(0.0, 1.0);
            return Some([
                w[0][0] + t * (w[1][0] - w[0][0]),
                w[0][1] + t * (w[1][1] - w[0][1]),
            ]);
        }
        walked += length;
    }
    line.last().copied()
}

fn point_polyline_distance(p: [f64; 2], line: &[[f64; 2]]) -> f64 {
    closest_on_polyline(p, line).map_or(f64::INFINITY, |(_, d)| d)
}

/// Directed distance `sup_{p ∈ a} d(p, b)`, with `a` sampled every `step` pixels along its
/// segments (the supremum over a segment is not always at a vertex).
fn directed_hausdorff(a: &[[f64; 2]], b: &[[f64; 2]], step: f64) -> f64 {
    let mut worst: f64 = 0.0;
    sample_polyline(a, step, |p| {
        worst = worst.max(point_polyline_distance(p, b))
    });
    worst
}

/// Calls `visit` on the points of polyline `a` every `step` pixels along each segment, both
/// ends included (on its one point for a single point, on nothing for none).
fn sample_polyline(a: &[[f64; 2]], step: f64, mut visit: impl FnMut([f64; 2])) {
    match a {
        [] => {}
        [p] => visit(*p),
        _ => {
            for w in a.windows(2) {
                let len = ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
                let n = (len / step).ceil().max(1.0) as usize;
                for k in 0..=n {
                    let t = k as f64 / n as f64;
                    visit([
                        w[0][0] + t * (w[1][0] - w[0][0]),
                        w[0][1] + t * (w[1][1] - w[0][1]),
                    ]);
                }
            }
        }
    }
}

/// Symmetric Hausdorff distance between two polylines in the image (pixels), evaluated on
/// points every 0.25 pixel along each (so exact to that resolution). Infinite if exactly one
/// of them is empty, 0 if both are.
pub fn hausdorff_polyline(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    match (a.is_empty(), b.is_empty()) {
        (true, true) => 0.0,
        (true, false) | (false, true) => f64::INFINITY,
        _ => directed_hausdorff(a, b, 0.25).max(directed_hausdorff(b, a, 0.25)),
    }
}

/// The two directed halves of the Hausdorff distance between a detected line and the true
/// cut: how far the line strays from the cut (`line_to_cut`, the worst point of the line) and
/// how much of the cut it leaves uncovered (`cut_to_line`, the worst point of the cut). The
/// distance itself is the larger ([`DirectedHausdorff::distance`]); apart, they tell a line
/// fitted off the cut from a line that is on it but too short. Where each is attained is kept
/// too, for the overlays to point at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectedHausdorff {
    /// `sup` over the line of the distance to the nearest part of the cut, pixels.
    pub line_to_cut: f64,
    /// `sup` over the cut's parts of the distance to the line, pixels.
    pub cut_to_line: f64,
    /// The line's point farthest from the cut, and the point of the cut nearest it.
    pub line_worst: [[f64; 2]; 2],
    /// The cut's point farthest from the line, and the point of the line nearest it.
    pub cut_worst: [[f64; 2]; 2],
}

impl DirectedHausdorff {
    /// The symmetric Hausdorff distance: the larger half.
    pub fn distance(&self) -> f64 {
        self.line_to_cut.max(self.cut_to_line)
    }
}

/// Both directed halves between a polyline `a` and a set of polylines taken as one (pixels,
/// sampled as [`hausdorff_polyline`]): from `a` to the nearest of the parts, and from every
/// part to `a`. `None` if either side is empty.
pub fn directed_hausdorff_to_parts(
    a: &[[f64; 2]],
    parts: &[Vec<[f64; 2]>],
) -> Option<DirectedHausdorff> {
    let parts: Vec<&[[f64; 2]]> = parts
        .iter()
        .map(Vec::as_slice)
        .filter(|p| !p.is_empty())
        .collect();
    if a.is_empty() || parts.is_empty() {
        return None;
    }
    // The farthest sample of `from` from its nearest point on `to` (nearest over `to`'s
    // parts): its distance, the sample and that nearest point.
    let farthest = |from: &[&[[f64; 2]]], to: &[&[[f64; 2]]]| {
        let mut worst = (-1.0, [[0.0; 2]; 2]);
        for line in from {
            sample_polyline(line, 0.25, |p| {
                let nearest = to
                    .iter()
                    .filter_map(|b| closest_on_polyline(p, b))
                    .min_by(|x, y| x.1.total_cmp(&y.1));
                if let Some((q, d)) = nearest
                    && d > worst.0
                {
                    worst = (d, [p, q]);
                }
            });
        }
        worst
    };
    let (line_to_cut, line_worst) = farthest(&[a], &parts);
    let (cut_to_line, cut_worst) = farthest(&parts, &[a]);
    Some(DirectedHausdorff {
        line_to_cut,
        cut_to_line,
        line_worst,
        cut_worst,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dice_on_hand_made_masks() {
        let a = Mask::from_fn(10, 10, |x, _| x < 5);
        assert_eq!(dice(&a, &a), 1.0);
        let b = Mask::from_fn(10, 10, |x, _| x >= 5);
        assert_eq!(dice(&a, &b), 0.0);
        // Half of a overlaps all of c: |A| = 50, |C| = 25, |A ∩ C| = 25 → 50/75.
        let c = Mask::from_fn(10, 10, |x, y| x < 5 && y < 5);
        assert!((dice(&a, &c) - 2.0 / 3.0).abs() < 1e-15);
        // Bands of 5 columns sharing 3: 2·30 / (50 + 50).
        let d = Mask::from_fn(10, 10, |x, _| (3..8).contains(&x));
        let e = Mask::from_fn(10, 10, |x, _| (5..10).contains(&x));
        assert!((dice(&d, &e) - 0.6).abs() < 1e-15);
        assert_eq!(dice(&Mask::new(3, 3), &Mask::new(3, 3)), 1.0);
    }

    #[test]
    fn half_overlap_is_one_half() {
        let a = Mask::from_fn(8, 8, |x, _| x < 4);
        let b = Mask::from_fn(8, 8, |x, _| (2..6).contains(&x));
        assert!((dice(&a, &b) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn point_triangle_regions() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert!((point_triangle_distance([0.2, 0.2, 3.0], a, b, c) - 3.0).abs() < 1e-15);
        assert!((point_triangle_distance([-1.0, -1.0, 0.0], a, b, c) - 2f64.sqrt()).abs() < 1e-15);
        assert!((point_triangle_distance([0.5, -2.0, 0.0], a, b, c) - 2.0).abs() < 1e-15);
        assert!((point_triangle_distance([1.0, 1.0, 0.0], a, b, c) - 0.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(point_triangle_distance([0.1, 0.1, 0.0], a, b, c), 0.0);
    }

    #[test]
    fn arc_positions_along_a_bent_line() {
        let line = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]];
        let (s, d) = arc_position([4.0, 2.0], &line).unwrap();
        assert!((s - 4.0).abs() < 1e-12 && (d - 2.0).abs() < 1e-12);
        let (s, d) = arc_position([13.0, 6.0], &line).unwrap();
        assert!((s - 16.0).abs() < 1e-12 && (d - 3.0).abs() < 1e-12);
        assert_eq!(
            arc_position([1.0, 1.0], &[[0.0, 0.0]]),
            Some((0.0, 2f64.sqrt()))
        );
        assert_eq!(arc_position([1.0, 1.0], &[]), None);
        assert_eq!(point_at_arc(&line, 16.0), Some([10.0, 6.0]));
        assert_eq!(point_at_arc(&line, -3.0), Some([0.0, 0.0]));
        assert_eq!(point_at_arc(&line, 99.0), Some([10.0, 10.0]));
        assert_eq!(point_at_arc(&[], 1.0), None);
    }

    #[test]
    fn polyline_hausdorff() {
        let a = [[0.0, 0.0], [10.0, 0.0]];
        let b = [[0.0, 1.0], [10.0, 1.0]];
        assert!((hausdorff_polyline(&a, &b) - 1.0).abs() < 1e-12);
        // A longer line: the extra 5 pixels count.
        let c = [[0.0, 0.0], [15.0, 0.0]];
        assert!((hausdorff_polyline(&a, &c) - 5.0).abs() < 1e-12);
        // The supremum inside a segment, not at a vertex: a tent against a flat line.
        let tent = [[0.0, 0.0], [5.0, 4.0], [10.0, 0.0]];
        assert!((hausdorff_polyline(&a, &tent) - 4.0).abs() < 1e-12);
        assert_eq!(hausdorff_polyline(&[], &[]), 0.0);
        assert!(hausdorff_polyline(&a, &[]).is_infinite());
    }

    #[test]
    fn hausdorff_to_parts_takes_the_parts_as_one() {
        let h = |a: &[[f64; 2]], parts: &[Vec<[f64; 2]>]| {
            directed_hausdorff_to_parts(a, parts).map(|d| d.distance())
        };
        let a = [[0.0, 0.0], [10.0, 0.0]];
        // Two parts under the line with a gap between them: each part is within 1 of the
        // line, and the line's point over the gap √2 from the nearer part's end.
        let parts = vec![vec![[0.0, 1.0], [4.0, 1.0]], vec![[6.0, 1.0], [10.0, 1.0]]];
        assert!((h(&a, &parts).unwrap() - 2.0f64.sqrt()).abs() < 1e-12);
        // A point between the parts: each part counts from its own side, up to its far end
        // (√(5² + 1)).
        let mid = [[5.0, 0.0], [5.0, 0.0]];
        assert!((h(&mid, &parts).unwrap() - 26.0f64.sqrt()).abs() < 1e-12);
        // A far part counts from its own side.
        let far = vec![vec![[0.0, 1.0], [10.0, 1.0]], vec![[0.0, 7.0]]];
        assert!((h(&a, &far).unwrap() - 7.0).abs() < 1e-12);
        // As one part, the same as the polyline distance.
        let one = vec![vec![[0.0, 1.0], [10.0, 1.0]]];
        assert_eq!(h(&a, &one), Some(hausdorff_polyline(&a, &one[0])));
        // Nothing to measure on either side (empty parts do not count).
        assert_eq!(h(&a, &[]), None);
        assert_eq!(h(&a, &[vec![]]), None);
        assert_eq!(h(&[], &one), None);
    }

    #[test]
    fn directed_halves_tell_a_short_line_from_a_line_off_the_cut() {
        let cut = vec![vec![[0.0, 0.0], [20.0, 0.0]]];
        // On the cut but covering its first quarter only: near it, most of it uncovered.
        let short = [[0.0, 0.0], [5.0, 0.0]];
        let h = directed_hausdorff_to_parts(&short, &cut).unwrap();
        assert!(h.line_to_cut.abs() < 1e-12);
        assert!((h.cut_to_line - 15.0).abs() < 1e-12);
        assert_eq!(h.cut_worst, [[20.0, 0.0], [5.0, 0.0]]);
        // As long as the cut, 3 px beside it, and running on 4 px past its end (5 from it).
        let off = [[0.0, 3.0], [24.0, 3.0]];
        let h = directed_hausdorff_to_parts(&off, &cut).unwrap();
        assert!((h.line_to_cut - 5.0).abs() < 1e-12);
        assert!((h.cut_to_line - 3.0).abs() < 1e-12);
        // Where: the line's far end and the cut's end below it; the cut's first point (a
        // vertex, the first sample at 3 px) and the line's point above it.
        let near = |p: [f64; 2], q: [f64; 2]| (p[0] - q[0]).hypot(p[1] - q[1]) < 1e-9;
        assert!(near(h.line_worst[0], [24.0, 3.0]) && near(h.line_worst[1], [20.0, 0.0]));
        assert!(near(h.cut_worst[0], [0.0, 0.0]) && near(h.cut_worst[1], [0.0, 3.0]));
        // The symmetric distance is the larger half.
        assert!((h.distance() - 5.0).abs() < 1e-12);
    }

    #[test]
    fn rms_helpers() {
        let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let tris = [[0u32, 1, 2]];
        let pts = [[0.1, 0.1, 0.3], [0.1, 0.1, -0.4]];
        let rms = surface_rms(&pts, &pos, &tris);
        assert!((rms - ((0.09 + 0.16) / 2.0f64).sqrt()).abs() < 1e-15);
        assert!((paired_rms(&[[0.0; 3]], &[[3.0, 4.0, 0.0]]) - 5.0).abs() < 1e-15);
    }
}
