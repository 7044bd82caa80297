//! Tetrahedral meshes for tests: a structured box split into tetrahedra.

use crate::rng::Rng;

pub use incise::generate::object::TetMesh;

/// The box `[0, lx] × [0, ly] × [0, lz]` cut into `nx × ny × nz` cells, each split into six
/// tetrahedra around its main diagonal (Kuhn's subdivision, conforming across cells), node
/// `(i, j, k)` at index `i + (nx + 1)·(j + (ny + 1)·k)`: the generator's band.
pub fn box_mesh(n: [usize; 3], l: [f64; 3]) -> TetMesh {
    TetMesh::band(l, n)
}

/// Six times the signed volume of tetrahedron `t`.
pub fn signed_volume(nodes: &[[f64; 3]], t: [u32; 4]) -> f64 {
    let p = |k: usize| nodes[t[k] as usize];
    let (a, b, c, d) = (p(0), p(1), p(2), p(3));
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
        + u[2] * (v[0] * w[1] - v[1] * w[0])
}

/// Renumbers the nodes of `mesh` by a random permutation, so that orderings are not handed the
/// structured numbering for free.
pub fn shuffle_nodes(mesh: &TetMesh, rng: &mut Rng) -> TetMesh {
    let n = mesh.nodes.len();
    let mut new_of_old: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        new_of_old.swap(i, j);
    }
    let mut nodes = vec![[0.0; 3]; n];
    for (old, &new) in new_of_old.iter().enumerate() {
        nodes[new as usize] = mesh.nodes[old];
    }
    let tets = mesh
        .tets
        .iter()
        .map(|t| t.map(|v| new_of_old[v as usize]))
        .collect();
    TetMesh { nodes, tets }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_mesh_volumes_add_up() {
        let m = box_mesh([3, 2, 4], [1.5, 1.0, 2.0]);
        assert_eq!(m.nodes.len(), 4 * 3 * 5);
        assert_eq!(m.tets.len(), 6 * 24);
        let total: f64 = m
            .tets
            .iter()
            .map(|&t| signed_volume(&m.nodes, t) / 6.0)
            .sum();
        assert!((total - 3.0).abs() < 1e-12);
        assert!(m.tets.iter().all(|&t| signed_volume(&m.nodes, t) > 0.0));
    }
}
