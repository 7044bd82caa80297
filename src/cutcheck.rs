//! Checks of a cut model, shared by the scene tests and the property tests: each returns a
//! description of the first violation it finds.

use std::collections::HashMap;

use incise_core::Model;
use incise_core::cut::QUALITY_FLOOR;
use incise_core::mesh::{Mesh, shape_quality};
use incise_core::nalgebra::Vector3;

use crate::oracle::faer_solve;

/// Every tetrahedron positive and above the cut's quality floor (or, for one the cut never
/// touched, at least as good as the worst of the input: `floor` is the smaller of the two);
/// no face shared by more than two tetrahedra; the boundary surface closed and manifold
/// (every boundary edge in exactly two boundary triangles) and oriented outward.
pub fn check_mesh(mesh: &Mesh<'_, f64>, floor: f64) -> Result<(), String> {
    let rest = mesh.rest();
    for (t, tet) in mesh.tets().iter().enumerate() {
        let q = shape_quality(&tet.map(|v| rest[v as usize]));
        if q.is_nan() || q < floor {
            return Err(format!(
                "tetrahedron {t} {tet:?} has quality {q:.4} < {floor}"
            ));
        }
    }
    let mut faces: HashMap<[u32; 3], usize> = HashMap::new();
    for tet in mesh.tets() {
        for l in 0..4 {
            let mut f = [tet[(l + 1) % 4], tet[(l + 2) % 4], tet[(l + 3) % 4]];
            f.sort_unstable();
            *faces.entry(f).or_default() += 1;
        }
    }
    if let Some((f, n)) = faces.iter().find(|(_, n)| **n > 2) {
        return Err(format!("face {f:?} shared by {n} tetrahedra"));
    }
    let boundary = faces.values().filter(|&&n| n == 1).count();
    if boundary != mesh.surface().len() {
        return Err(format!(
            "{boundary} faces belong to one tetrahedron, the surface has {}",
            mesh.surface().len()
        ));
    }
    let mut edges: HashMap<[u32; 2], usize> = HashMap::new();
    for (tri, &t) in mesh.surface().iter().zip(mesh.surface_tet()) {
        for e in 0..3 {
            let (a, b) = (tri[e], tri[(e + 1) % 3]);
            *edges.entry([a.min(b), a.max(b)]).or_default() += 1;
        }
        let tet = mesh.tets()[t as usize];
        let opposite = tet.iter().find(|v| !tri.contains(v)).copied();
        let Some(o) = opposite else {
            return Err(format!(
                "boundary triangle {tri:?} is not a face of tetrahedron {t}"
            ));
        };
        let p = |v: u32| Vector3::from(rest[v as usize]);
        let n = (p(tri[1]) - p(tri[0])).cross(&(p(tri[2]) - p(tri[0])));
        if n.dot(&(p(o) - p(tri[0]))) >= 0.0 {
            return Err(format!(
                "boundary triangle {tri:?} points into its tetrahedron"
            ));
        }
    }
    if let Some((e, n)) = edges.iter().find(|(_, n)| **n != 2) {
        return Err(format!("boundary edge {e:?} is in {n} boundary triangles"));
    }
    Ok(())
}

/// The lowest quality of the input tetrahedra and the cut's floor, whichever is smaller: what
/// [`check_mesh`] must find of a mesh the cut may have left some input tetrahedra in.
pub fn quality_floor(rest: &[[f64; 3]], tets: &[[u32; 4]]) -> f64 {
    tets.iter()
        .map(|t| shape_quality(&t.map(|v| rest[v as usize])))
        .fold(QUALITY_FLOOR, f64::min)
}

/// Face-connected groups of tetrahedra.
pub fn components(tets: &[[u32; 4]]) -> usize {
    let mut parent: Vec<usize> = (0..tets.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    let mut faces: HashMap<[u32; 3], usize> = HashMap::new();
    for (t, tet) in tets.iter().enumerate() {
        for l in 0..4 {
            let mut f = [tet[(l + 1) % 4], tet[(l + 2) % 4], tet[(l + 3) % 4]];
            f.sort_unstable();
            if let Some(&u) = faces.get(&f) {
                let (a, b) = (find(&mut parent, t), find(&mut parent, u));
                parent[a.max(b)] = a.min(b);
            } else {
                faces.insert(f, t);
            }
        }
    }
    (0..tets.len())
        .filter(|&t| find(&mut parent, t) == t)
        .count()
}

/// The factor in service solves the system the model assembles now as faer does: relative
/// difference of the solutions for the current gradient, at most `tol`.
pub fn check_factor(model: &mut Model<'_, f64>, tol: f64) -> Result<f64, String> {
    let lin = model.linearize().map_err(|e| e.to_string())?;
    let (g, h) = (lin.gradient.to_vec(), lin.hessian.to_vec());
    let (col_ptr, row_idx) = (
        lin.pattern.col_ptr().to_vec(),
        lin.pattern.row_idx().to_vec(),
    );
    let a = incise_core::sparse::UpperCsc::new(g.len(), &col_ptr, &row_idx)
        .map_err(|e| e.to_string())?;
    let expected = faer_solve(&a, &h, &g);
    let mut ours = g.clone();
    let mut work = vec![0.0; g.len()];
    model
        .factor()
        .solve_in_place(model.symbolic(), &mut ours, &mut work)
        .map_err(|e| format!("solve with the factor in service: {e}"))?;
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let diff: Vec<f64> = ours.iter().zip(&expected).map(|(a, b)| a - b).collect();
    let rel = norm(&diff) / norm(&expected).max(f64::MIN_POSITIVE);
    if rel <= tol {
        Ok(rel)
    } else {
        Err(format!("factor and faer differ by {rel:.3e}"))
    }
}

/// Every embedded point (features and targets) sits in its tetrahedron (weights non-negative,
/// summing to one).
pub fn check_embeddings(model: &Model<'_, f64>) -> Result<(), String> {
    for (what, e) in [
        ("feature", model.feature_embedding()),
        ("target", model.target_embedding()),
    ] {
        for (k, (t, w)) in e.tets().iter().zip(e.weights()).enumerate() {
            if *t as usize >= model.mesh().n_tets() {
                return Err(format!(
                    "{what} {k} names tetrahedron {t} of {}",
                    model.mesh().n_tets()
                ));
            }
            let sum: f64 = w.iter().sum();
            if w.iter().any(|&x| x < -1e-12) || (sum - 1.0).abs() > 1e-9 {
                return Err(format!("{what} {k} has weights {w:?}"));
            }
        }
    }
    Ok(())
}

/// Each target's material point (its rest position in the mesh) is where it was embedded, up to
/// `tol` metres (snapping moves nodes, and the points in their tetrahedra with them).
pub fn check_targets_stay(
    model: &Model<'_, f64>,
    rest_points: &[[f64; 3]],
    tol: f64,
) -> Result<(), String> {
    let e = model.target_embedding();
    for (k, p) in rest_points.iter().enumerate() {
        let Some(now) = e.position(k, model.mesh(), model.mesh().rest()) else {
            return Err(format!("target {k} is not embedded"));
        };
        let d = (Vector3::from(now) - Vector3::from(*p)).norm();
        if d > tol {
            return Err(format!(
                "target {k} moved {d:.2e} m in the material (tolerance {tol:.2e})"
            ));
        }
    }
    Ok(())
}

/// Signed distance of pixel `q` to the polyline (positive on its left, `u` right and `v` down,
/// from the first vertex to the last), when its nearest point lies inside a segment (beside a
/// vertex the side is ambiguous where the line turns back).
pub fn side_of_polyline(line: &[[f64; 2]], q: [f64; 2]) -> Option<f64> {
    let mut best: Option<(f64, f64, bool)> = None;
    for k in 0..line.len().checked_sub(1)? {
        let (a, b) = (line[k], line[k + 1]);
        let t = [b[0] - a[0], b[1] - a[1]];
        let len2 = t[0] * t[0] + t[1] * t[1];
        if len2 <= 0.0 {
            continue;
        }
        let w = [q[0] - a[0], q[1] - a[1]];
        let s = (w[0] * t[0] + w[1] * t[1]) / len2;
        let sc = s.clamp(0.0, 1.0);
        let d = ((w[0] - t[0] * sc).powi(2) + (w[1] - t[1] * sc).powi(2)).sqrt();
        let signed = (t[0] * w[1] - t[1] * w[0]) / len2.sqrt();
        if best.is_none_or(|(bd, _, _)| d < bd) {
            best = Some((d, signed, s > 0.0 && s < 1.0));
        }
    }
    best.filter(|b| b.2).map(|b| b.1)
}

/// Every feature whose observation lies beside a segment of the cut line (not beside a vertex)
/// and more than `margin` pixels off it has its virtual feature on the same side of the line (the cut may bend by the snapping
/// tolerance of an element, which `margin` must cover). Returns how many features were checked.
pub fn check_feature_sides(
    model: &Model<'_, f64>,
    line: &[[f64; 2]],
    margin: f64,
) -> Result<usize, String> {
    let mut checked = 0;
    for slot in 0..model.features().len() {
        let obs = model.features().targets()[slot];
        let Some(seen) = side_of_polyline(line, obs) else {
            continue;
        };
        if seen.abs() <= margin {
            continue;
        }
        let uv = model.projected_feature(slot).map_err(|e| e.to_string())?;
        let here = side_of_polyline(line, uv).unwrap_or(0.0);
        if here * seen < 0.0 {
            return Err(format!(
                "feature {slot} is seen at {obs:?} ({seen:.1} px off the line) but its virtual \
                 feature is at {uv:?}, on the other side"
            ));
        }
        checked += 1;
    }
    Ok(checked)
}

/// The longest edge of the mesh, metres.
pub fn longest_edge(rest: &[[f64; 3]], tets: &[[u32; 4]]) -> f64 {
    let mut longest: f64 = 0.0;
    for t in tets {
        for a in 0..4 {
            for b in a + 1..4 {
                let d = (Vector3::from(rest[t[a] as usize]) - Vector3::from(rest[t[b] as usize]))
                    .norm();
                longest = longest.max(d);
            }
        }
    }
    longest
}
