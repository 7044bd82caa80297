//! The real object's mesh: a finely meshed band or a refined organ mesh, and the pre-cut slit
//! made by duplicating the nodes on a surface of mesh faces.

use std::collections::HashMap;

/// A tetrahedral mesh (metres, positively oriented tetrahedra).
#[derive(Clone, Debug, PartialEq)]
pub struct TetMesh {
    /// Node positions.
    pub nodes: Vec<[f64; 3]>,
    /// Tetrahedra.
    pub tets: Vec<[u32; 4]>,
}

/// Six times the signed volume of the tetrahedron `(a, b, c, d)`.
pub fn signed_volume6(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
        + u[2] * (v[0] * w[1] - v[1] * w[0])
}

impl TetMesh {
    /// The box `[0, size]` cut into `cells`, each cell into six tetrahedra around its main
    /// diagonal (conforming), node `(i, j, k)` at `i + (nx + 1)(j + (ny + 1) k)`.
    pub fn band(size: [f64; 3], cells: [usize; 3]) -> TetMesh {
        let [nx, ny, nz] = cells;
        let id = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
        let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    nodes.push([
                        size[0] * i as f64 / nx as f64,
                        size[1] * j as f64 / ny as f64,
                        size[2] * k as f64 / nz as f64,
                    ]);
                }
            }
        }
        let mut tets = Vec::with_capacity(6 * nx * ny * nz);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    for path in [
                        [0, 1, 2],
                        [0, 2, 1],
                        [1, 0, 2],
                        [1, 2, 0],
                        [2, 0, 1],
                        [2, 1, 0],
                    ] {
                        let mut c = [i, j, k];
                        let mut t = [id(i, j, k); 4];
                        for (s, axis) in path.into_iter().enumerate() {
                            c[axis] += 1;
                            t[s + 1] = id(c[0], c[1], c[2]);
                        }
                        tets.push(t);
                    }
                }
            }
        }
        let mut mesh = TetMesh { nodes, tets };
        mesh.orient_positive();
        mesh
    }

    /// A dome: a thick spherical shell over a curved square, meshed as [`TetMesh::band`]
    /// bent onto the sphere. `size = [arc x, arc y, thickness]`: the mid-surface (radius
    /// `radius`) spans the arc lengths `arc x` and `arc y` along its two great circles through
    /// the apex; the thickness is split evenly about it. The mid-surface's apex is at the
    /// origin and the sphere's centre at `(0, 0, −radius)`, so the dome bulges toward +z and
    /// its rim hangs below `z = 0`.
    ///
    /// The box node `(x, y, z)` goes to `(radius + w) n − (0, 0, radius)` with
    /// `n = (tan α, tan β, 1) / |(tan α, tan β, 1)|`, `α = (x − arc x / 2) / radius`,
    /// `β = (y − arc y / 2) / radius` and `w = z − thickness / 2`: the equiangular map of
    /// one face of a cube onto the sphere, whose cells keep their shape far better than a
    /// square squeezed into a disc. Node numbering and tetrahedra are the band's.
    ///
    /// Meant for `arc / radius` well below π (half-angles up to about 60°) and a thickness
    /// below the radius; [`dome_parameters_error`] says what is out of range.
    pub fn dome(size: [f64; 3], radius: f64, cells: [usize; 3]) -> TetMesh {
        let mut mesh = TetMesh::band(size, cells);
        for p in &mut mesh.nodes {
            let a = ((p[0] - size[0] / 2.0) / radius).tan();
            let b = ((p[1] - size[1] / 2.0) / radius).tan();
            let w = p[2] - size[2] / 2.0;
            let norm = (a * a + b * b + 1.0).sqrt();
            let r = radius + w;
            *p = [r * a / norm, r * b / norm, r / norm - radius];
        }
        mesh.orient_positive();
        mesh
    }

    /// Swaps two nodes of every negatively oriented tetrahedron.
    pub fn orient_positive(&mut self) {
        for t in &mut self.tets {
            let p = |v: u32| self.nodes[v as usize];
            if signed_volume6(p(t[0]), p(t[1]), p(t[2]), p(t[3])) < 0.0 {
                t.swap(2, 3);
            }
        }
    }

    /// Uniform refinement: every tetrahedron into eight (four at the corners, four from the
    /// inner octahedron split along its shortest diagonal), new nodes at edge midpoints after
    /// the original ones, so node `v` of `self` is node `v` of the result.
    pub fn refine(&self) -> TetMesh {
        let mut nodes = self.nodes.clone();
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, nodes: &mut Vec<[f64; 3]>| -> u32 {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                let (p, q) = (nodes[a as usize], nodes[b as usize]);
                nodes.push([
                    (p[0] + q[0]) / 2.0,
                    (p[1] + q[1]) / 2.0,
                    (p[2] + q[2]) / 2.0,
                ]);
                (nodes.len() - 1) as u32
            })
        };
        let mut tets = Vec::with_capacity(8 * self.tets.len());
        for &[a, b, c, d] in &self.tets {
            let ab = midpoint(a, b, &mut nodes);
            let ac = midpoint(a, c, &mut nodes);
            let ad = midpoint(a, d, &mut nodes);
            let bc = midpoint(b, c, &mut nodes);
            let bd = midpoint(b, d, &mut nodes);
            let cd = midpoint(c, d, &mut nodes);
            tets.extend([
                [a, ab, ac, ad],
                [ab, b, bc, bd],
                [ac, bc, c, cd],
                [ad, bd, cd, d],
            ]);
            // The octahedron (ab, ac, ad, bc, bd, cd): split along the shortest of its three
            // diagonals (ab–cd, ac–bd, ad–bc) for the best-shaped children.
            let len = |p: u32, q: u32| {
                let (x, y) = (nodes[p as usize], nodes[q as usize]);
                (0..3).map(|k| (x[k] - y[k]).powi(2)).sum::<f64>()
            };
            let diagonals = [
                (ab, cd, [ac, ad, bd, bc]),
                (ac, bd, [ab, ad, cd, bc]),
                (ad, bc, [ab, ac, cd, bd]),
            ];
            let (p, q, ring) = diagonals
                .into_iter()
                .min_by(|x, y| len(x.0, x.1).total_cmp(&len(y.0, y.1)))
                .expect("three diagonals");
            // The ring around the diagonal p–q, in cyclic order: four tetrahedra share p–q.
            for k in 0..4 {
                tets.push([p, q, ring[k], ring[(k + 1) % 4]]);
            }
        }
        let mut mesh = TetMesh { nodes, tets };
        mesh.orient_positive();
        mesh
    }

    /// Centroid of tetrahedron `t`.
    pub fn centroid(&self, t: usize) -> [f64; 3] {
        let mut c = [0.0; 3];
        for &v in &self.tets[t] {
            for k in 0..3 {
                c[k] += self.nodes[v as usize][k] / 4.0;
            }
        }
        c
    }

    /// Boundary faces `(a, b, c, tet)`, oriented outward.
    pub fn boundary(&self) -> Vec<([u32; 3], usize)> {
        let mut count: HashMap<[u32; 3], Vec<(usize, usize)>> = HashMap::new();
        for (t, tet) in self.tets.iter().enumerate() {
            for l in 0..4 {
                let mut f = [tet[(l + 1) % 4], tet[(l + 2) % 4], tet[(l + 3) % 4]];
                f.sort_unstable();
                count.entry(f).or_default().push((t, l));
            }
        }
        let mut out: Vec<([u32; 3], usize)> = count
            .into_values()
            .filter(|v| v.len() == 1)
            .map(|v| {
                let (t, l) = v[0];
                let tet = self.tets[t];
                let mut tri = [tet[(l + 1) % 4], tet[(l + 2) % 4], tet[(l + 3) % 4]];
                let p = |v: u32| self.nodes[v as usize];
                if signed_volume6(p(tri[0]), p(tri[1]), p(tri[2]), p(tet[l])) > 0.0 {
                    tri.swap(1, 2);
                }
                (tri, t)
            })
            .collect();
        // Deterministic order, whatever the hash map did.
        out.sort_unstable();
        out
    }
}

/// Why dome parameters make no sense, or `None` if they do: positive sizes, at least one cell
/// along each axis, a thickness below the radius, and half-angles `arc / (2 radius)` of at
/// most 60°.
pub fn dome_parameters_error(size: [f64; 3], radius: f64, cells: [usize; 3]) -> Option<String> {
    if !(size.iter().all(|&s| s > 0.0 && s.is_finite()) && radius.is_finite() && radius > 0.0) {
        return Some(format!(
            "a dome needs a positive size and radius (size {size:?}, radius {radius})"
        ));
    }
    if cells.contains(&0) {
        return Some(format!(
            "a dome needs cells along every axis, not {cells:?}"
        ));
    }
    if size[2] >= radius {
        return Some(format!(
            "the dome's thickness {} must be below its radius {radius}",
            size[2]
        ));
    }
    let limit = 60f64.to_radians();
    if size[0] / (2.0 * radius) > limit || size[1] / (2.0 * radius) > limit {
        return Some(format!(
            "the dome's arcs {:?} span more than 120° of its sphere (radius {radius})",
            &size[..2]
        ));
    }
    None
}

/// Shape quality of a tetrahedron: `6√2 V / l³` with `l` the root mean square of its six edge
/// lengths; 1 for the regular tetrahedron, 0 for a flat one, negative when inverted.
pub fn tet_quality(p: [[f64; 3]; 4]) -> f64 {
    let mut sum = 0.0;
    for i in 0..4 {
        for j in i + 1..4 {
            sum += (0..3).map(|k| (p[i][k] - p[j][k]).powi(2)).sum::<f64>();
        }
    }
    let l = (sum / 6.0).sqrt();
    if l == 0.0 {
        return 0.0;
    }
    std::f64::consts::SQRT_2 * signed_volume6(p[0], p[1], p[2], p[3]) / (l * l * l)
}

/// The result of cutting a slit: the mesh with duplicated nodes, and for each duplicate the
/// node it was split from.
#[derive(Clone, Debug)]
pub struct Slit {
    /// The cut mesh.
    pub mesh: TetMesh,
    /// `(original, duplicate)` node pairs: the two lips of the slit.
    pub pairs: Vec<(u32, u32)>,
    /// The mesh faces that form the slit (node numbers of the mesh before it, sorted).
    pub faces: Vec<[u32; 3]>,
    /// Nodes on the slit that were not split: its front, where the lips meet.
    pub front: Vec<u32>,
}

/// Cuts `mesh` along the interior faces that separate tetrahedra whose centroids lie on
/// opposite sides of the plane `(point, normal)`, keeping those whose centroid is inside
/// `region` (`[min, max]`). A node on those faces is split into one copy per group of its
/// tetrahedra still connected through uncut faces, so the lips separate while the slit's front
/// stays attached.
pub fn cut_slit(mesh: &TetMesh, point: [f64; 3], normal: [f64; 3], region: [[f64; 3]; 2]) -> Slit {
    cut_slit_where(mesh, point, normal, |p| {
        (0..3).all(|k| p[k] >= region[0][k] && p[k] <= region[1][k])
    })
}

/// [`cut_slit`] with any region: the faces between tetrahedra on either side of the plane
/// `(point, normal)` whose centroid satisfies `inside` are cut.
pub fn cut_slit_where(
    mesh: &TetMesh,
    point: [f64; 3],
    normal: [f64; 3],
    inside: impl Fn([f64; 3]) -> bool,
) -> Slit {
    let side =
        |p: [f64; 3]| -> bool { (0..3).map(|k| (p[k] - point[k]) * normal[k]).sum::<f64>() > 0.0 };
    // Interior faces and their two tetrahedra.
    let mut faces: HashMap<[u32; 3], Vec<usize>> = HashMap::new();
    for (t, tet) in mesh.tets.iter().enumerate() {
        for l in 0..4 {
            let mut f = [tet[(l + 1) % 4], tet[(l + 2) % 4], tet[(l + 3) % 4]];
            f.sort_unstable();
            faces.entry(f).or_default().push(t);
        }
    }
    let mut cut: Vec<[u32; 3]> = faces
        .iter()
        .filter(|(f, ts)| {
            ts.len() == 2 && side(mesh.centroid(ts[0])) != side(mesh.centroid(ts[1])) && {
                let c = (0..3)
                    .map(|k| f.iter().map(|&v| mesh.nodes[v as usize][k]).sum::<f64>() / 3.0)
                    .collect::<Vec<_>>();
                inside([c[0], c[1], c[2]])
            }
        })
        .map(|(f, _)| *f)
        .collect();
    cut.sort_unstable();
    let is_cut: std::collections::HashSet<[u32; 3]> = cut.iter().copied().collect();

    // Tetrahedra around each node on the slit.
    let mut slit_nodes: Vec<u32> = cut.iter().flatten().copied().collect();
    slit_nodes.sort_unstable();
    slit_nodes.dedup();
    let mut around: HashMap<u32, Vec<usize>> = slit_nodes.iter().map(|&v| (v, vec![])).collect();
    for (t, tet) in mesh.tets.iter().enumerate() {
        for v in tet {
            if let Some(list) = around.get_mut(v) {
                list.push(t);
            }
        }
    }
    let mut out = mesh.clone();
    let mut pairs = vec![];
    let mut front = vec![];
    for &v in &slit_nodes {
        let ts = &around[&v];
        // Union-find over the tetrahedra around v, joined through shared faces not cut.
        let mut parent: Vec<usize> = (0..ts.len()).collect();
        fn find(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        for a in 0..ts.len() {
            for b in a + 1..ts.len() {
                let (ta, tb) = (mesh.tets[ts[a]], mesh.tets[ts[b]]);
                let shared: Vec<u32> = ta.iter().copied().filter(|x| tb.contains(x)).collect();
                if shared.len() == 3 {
                    let mut f = [shared[0], shared[1], shared[2]];
                    f.sort_unstable();
                    if !is_cut.contains(&f) {
                        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
                        parent[ra.max(rb)] = ra.min(rb);
                    }
                }
            }
        }
        let mut roots: Vec<usize> = (0..ts.len()).map(|i| find(&mut parent, i)).collect();
        let first = roots.iter().copied().min().unwrap_or(0);
        roots.sort_unstable();
        roots.dedup();
        if roots.len() == 1 {
            front.push(v);
        }
        for &r in roots.iter().filter(|&&r| r != first) {
            out.nodes.push(mesh.nodes[v as usize]);
            let copy = (out.nodes.len() - 1) as u32;
            pairs.push((v, copy));
            for (i, &t) in ts.iter().enumerate() {
                if find(&mut parent, i) == r {
                    for x in out.tets[t].iter_mut() {
                        if *x == v {
                            *x = copy;
                        }
                    }
                }
            }
        }
    }
    Slit {
        mesh: out,
        pairs,
        faces: cut,
        front,
    }
}

/// A point inside tetrahedron `t` of `mesh` with barycentric weights `w`.
pub fn interpolate(mesh_nodes: &[[f64; 3]], tet: [u32; 4], w: [f64; 4]) -> [f64; 3] {
    let mut p = [0.0; 3];
    for (k, &v) in tet.iter().enumerate() {
        for c in 0..3 {
            p[c] += w[k] * mesh_nodes[v as usize][c];
        }
    }
    p
}

/// A 4 × 4 × 1 band over 1 × 1 × 0.25, slit at x = 0.5 from its edge y = 0 up to y = 0.5
/// (half its width, where the slit's front is): the small slit tests cut.
#[cfg(test)]
pub(crate) fn half_side_slit() -> (TetMesh, Slit) {
    let band = TetMesh::band([1.0, 1.0, 0.25], [4, 4, 1]);
    let slit = cut_slit(
        &band,
        [0.5, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [[0.4, -0.1, -0.1], [0.6, 0.5, 1.0]],
    );
    (band, slit)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn volume(m: &TetMesh) -> f64 {
        m.tets
            .iter()
            .map(|t| {
                let p = |v: u32| m.nodes[v as usize];
                signed_volume6(p(t[0]), p(t[1]), p(t[2]), p(t[3])) / 6.0
            })
            .sum()
    }

    #[test]
    fn band_and_refinement_keep_volume_and_orientation() {
        let band = TetMesh::band([0.1, 0.03, 0.004], [5, 3, 1]);
        assert!((volume(&band) - 0.1 * 0.03 * 0.004).abs() < 1e-15);
        let fine = band.refine();
        assert_eq!(fine.tets.len(), 8 * band.tets.len());
        assert!((volume(&fine) - volume(&band)).abs() < 1e-15);
        assert!(fine.tets.iter().all(|t| {
            let p = |v: u32| fine.nodes[v as usize];
            signed_volume6(p(t[0]), p(t[1]), p(t[2]), p(t[3])) > 0.0
        }));
        // Same boundary area: no surface node moved.
        assert_eq!(&fine.nodes[..band.nodes.len()], &band.nodes[..]);
    }

    /// Every undirected boundary edge is shared by exactly two boundary triangles, which run
    /// it in opposite directions, and `V − E + F = 2`: a closed, consistently oriented surface
    /// of a ball.
    fn assert_closed_ball(m: &TetMesh) {
        let faces = m.boundary();
        let mut edges: HashMap<(u32, u32), (usize, usize)> = HashMap::new();
        for (f, _) in &faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let e = edges.entry((a.min(b), a.max(b))).or_default();
                if a < b {
                    e.0 += 1;
                } else {
                    e.1 += 1;
                }
            }
        }
        assert!(edges.values().all(|&c| c == (1, 1)), "open or misoriented");
        let mut vertices: Vec<u32> = faces.iter().flat_map(|f| f.0).collect();
        vertices.sort_unstable();
        vertices.dedup();
        let euler = vertices.len() as i64 - edges.len() as i64 + faces.len() as i64;
        assert_eq!(euler, 2);
    }

    #[test]
    fn dome_is_a_closed_positively_oriented_shell_of_the_right_volume() {
        // The dome family's base: arcs 8 × 6 cm on a 6 cm sphere, 8 mm thick.
        let (size, radius) = ([0.08, 0.06, 0.008], 0.06);
        assert_eq!(dome_parameters_error(size, radius, [20, 15, 3]), None);
        // Exact volume: the solid angle of the patch times (r_o³ − r_i³) / 3; the solid angle
        // of the gnomonic rectangle |x| ≤ X, |y| ≤ Y on the plane z = 1 is
        // 4 atan(X Y / √(1 + X² + Y²)).
        let (x, y) = (
            (size[0] / (2.0 * radius)).tan(),
            (size[1] / (2.0 * radius)).tan(),
        );
        let omega = 4.0 * (x * y / (1.0 + x * x + y * y).sqrt()).atan();
        let (ro, ri) = (radius + size[2] / 2.0, radius - size[2] / 2.0);
        let exact = omega * (ro.powi(3) - ri.powi(3)) / 3.0;
        let mut last_error = f64::INFINITY;
        for cells in [[8, 6, 1], [20, 15, 3], [40, 30, 3]] {
            let m = TetMesh::dome(size, radius, cells);
            assert_eq!(
                m.nodes.len(),
                (cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1)
            );
            assert_eq!(m.tets.len(), 6 * cells[0] * cells[1] * cells[2]);
            let worst = m
                .tets
                .iter()
                .map(|t| tet_quality(t.map(|v| m.nodes[v as usize])))
                .fold(f64::INFINITY, f64::min);
            // The band's own cells give 0.6 or so on cubes; bent and stretched a little.
            assert!(worst > 0.3, "{cells:?}: worst quality {worst}");
            assert_closed_ball(&m);
            // Flat facets under a curved surface: a little less than the exact volume, and
            // closer on finer meshes.
            let error = (exact - volume(&m)) / exact;
            assert!((0.0..0.02).contains(&error), "{cells:?}: {error}");
            assert!(error < last_error);
            last_error = error;
            // Apex of the mid-surface at the origin (a node there when the cells along x and
            // y are even), the outer surface half the thickness above it.
            let top = m
                .nodes
                .iter()
                .map(|p| p[2])
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(
                top <= size[2] / 2.0 + 1e-15 && top > size[2] / 2.0 - 1e-4,
                "{top}"
            );
            if cells[0] % 2 == 0 && cells[1] % 2 == 0 {
                assert!(
                    m.nodes
                        .iter()
                        .any(|p| p[0].abs() < 1e-15 && p[1].abs() < 1e-15)
                );
            }
        }
        assert!(dome_parameters_error(size, 0.005, [4, 4, 1]).is_some());
        assert!(dome_parameters_error([0.3, 0.06, 0.008], 0.06, [4, 4, 1]).is_some());
        assert!(dome_parameters_error(size, radius, [4, 0, 1]).is_some());
    }

    #[test]
    fn band_is_a_closed_ball() {
        assert_closed_ball(&TetMesh::band([0.1, 0.03, 0.006], [8, 3, 2]));
    }

    #[test]
    fn side_slit_duplicates_the_lips_but_not_the_front() {
        let (band, slit) = half_side_slit();
        // Faces on x = 0.5 with centroid y < 0.5: 2 cells × 2 triangles each.
        assert_eq!(slit.faces.len(), 4);
        // Nodes on x = 0.5 with y in {0, 0.25} at z = 0 and 0.25 are split; y = 0.5 (the front)
        // is not.
        assert_eq!(slit.pairs.len(), 4);
        assert!(
            slit.pairs
                .iter()
                .all(|&(v, _)| band.nodes[v as usize][1] < 0.3)
        );
        assert_eq!(slit.mesh.nodes.len(), band.nodes.len() + 4);
        assert!((volume(&slit.mesh) - volume(&band)).abs() < 1e-15);
    }
}
