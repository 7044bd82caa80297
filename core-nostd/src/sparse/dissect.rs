//! A fill-reducing ordering for larger meshes: nested dissection on the node graph, with
//! minimum degree on the small parts, in a fixed workspace.
//!
//! Minimum degree decides locally, one vertex at a time; on a mesh of a few thousand nodes its
//! choices add up to a fill that depends on how ties happened to break. Nested dissection
//! decides globally: it finds a small set of vertices (a *separator*) whose removal splits the
//! graph in two, orders both halves first (recursively) and the separator last, so that no fill
//! ever joins the two halves. The separators come from breadth-first level structures (George
//! and Liu): from a pseudo-peripheral vertex the levels sweep across the part, and the level
//! that halves its vertices separates the levels before it from those after it. Only the
//! vertices of that level that touch the next level need to be in the separator; the others
//! join the first half. Parts of at most [`DISSECTION_LEAF`] vertices are ordered by
//! [`minimum_degree`] on their own subgraph.
//!
//! No recursion: the parts still to split wait on an explicit stack in the workspace, each a
//! range of the permutation whose vertices carry the range's start as their label.
//! [`super::fill_reducing_order`] runs both orderings and keeps the one with less fill.

use super::order::{at, at_mut, internal, minimum_degree, minimum_degree_work_len};
use super::pattern::Graph;
use super::{NONE, ux};
use crate::error::{Error, Resource};
use crate::storage::{Slab, ensure_exact_len, sum, times};

/// Parts of at most this many vertices are ordered by minimum degree rather than split again:
/// below it a separator is a large share of the part, and minimum degree does as well.
pub const DISSECTION_LEAF: usize = 96;

/// Breadth-first searches spent looking for a pseudo-peripheral vertex (each from a vertex of
/// the last level of the one before, while the depth grows).
const PERIPHERAL_SWEEPS: usize = 4;

/// Length of the `u32` workspace [`nested_dissection`] needs for a graph of `n` vertices and
/// `nnz` adjacency entries.
pub const fn nested_dissection_work_len(n: usize, nnz: usize) -> usize {
    sum(&[times(8, n), 1, nnz, minimum_degree_work_len(n, nnz)])
}

/// The arrays of one dissection, carved from the workspace.
struct Dissection<'g, 'w> {
    graph: &'g Graph<'g>,
    /// Each vertex's part (the start of its range in the permutation), [`NONE`] once ordered.
    label: &'w mut [u32],
    /// Breadth-first level of each vertex of the part being split ([`NONE`]: not reached).
    level: &'w mut [u32],
    /// Breadth-first queue; after a search, the part's reached vertices in level order.
    queue: &'w mut [u32],
    /// Ranges `(lo, hi)` of the permutation still to split.
    stack: &'w mut [u32],
    top: usize,
    /// A leaf's local index of each of its vertices.
    local: &'w mut [u32],
    /// A leaf's subgraph, and its ordering.
    sub_ptr: &'w mut [u32],
    sub_adj: &'w mut [u32],
    sub_perm: &'w mut [u32],
    md_work: &'w mut [u32],
}

/// Computes a nested-dissection ordering of the graph's vertices: `perm[k]` is the vertex
/// eliminated `k`-th. `perm` needs exactly `graph.n()` entries and `work`
/// [`nested_dissection_work_len`]`(n, graph.nnz())`; the work has no meaning on return.
///
/// Cost: a few breadth-first searches of each part per level of the dissection (about
/// `nnz · log n`), and minimum degree on the leaves; once per mesh topology.
///
/// # Errors
/// As [`minimum_degree`]: [`Error::Length`] for `perm`, [`Error::Capacity`] for `work`.
#[inline(never)]
pub fn nested_dissection(
    graph: &Graph<'_>,
    perm: &mut [u32],
    work: &mut [u32],
) -> Result<(), Error> {
    let n = graph.n();
    ensure_exact_len(perm, n, Resource::Permutation)?;
    let mut slab = Slab::new(work, Resource::Workspace);
    let mut d = Dissection {
        graph,
        label: slab.take(n)?,
        level: slab.take(n)?,
        queue: slab.take(n)?,
        stack: slab.take(times(2, n))?,
        top: 0,
        local: slab.take(n)?,
        sub_ptr: slab.take(n + 1)?,
        sub_adj: slab.take(graph.nnz())?,
        sub_perm: slab.take(n)?,
        md_work: slab.take(minimum_degree_work_len(n, graph.nnz()))?,
    };
    for (v, (p, l)) in perm.iter_mut().zip(d.label.iter_mut()).enumerate() {
        *p = v as u32;
        *l = 0;
    }
    if n == 0 {
        return Ok(());
    }
    d.push(0, n)?;
    while let Some((lo, hi)) = d.pop()? {
        d.split(perm, lo, hi)?;
    }
    Ok(())
}

impl Dissection<'_, '_> {
    fn push(&mut self, lo: usize, hi: usize) -> Result<(), Error> {
        if lo < hi {
            *at_mut(self.stack, self.top)? = lo as u32;
            *at_mut(self.stack, self.top + 1)? = hi as u32;
            self.top += 2;
        }
        Ok(())
    }

    fn pop(&mut self) -> Result<Option<(usize, usize)>, Error> {
        if self.top == 0 {
            return Ok(None);
        }
        self.top -= 2;
        Ok(Some((
            ux(at(self.stack, self.top)?),
            ux(at(self.stack, self.top + 1)?),
        )))
    }

    /// Orders the part in `perm[lo..hi]`: as a leaf, or by splitting it into two parts and a
    /// separator (or into its first connected component and the rest) and pushing the parts.
    fn split(&mut self, perm: &mut [u32], lo: usize, hi: usize) -> Result<(), Error> {
        let size = hi - lo;
        if size <= DISSECTION_LEAF {
            return self.order_leaf(perm, lo, hi);
        }
        let part = perm.get(lo..hi).ok_or_else(internal)?;
        let lab = lo as u32;
        // A pseudo-peripheral root: from the part's first vertex, then from a vertex of least
        // degree in the last level, as long as the level structure gets deeper.
        let mut root = at(part, 0)?;
        let (mut depth, reached) = self.search(part, root, lab)?;
        if reached < size {
            return self.split_component(perm, lo, hi, reached);
        }
        for _ in 0..PERIPHERAL_SWEEPS {
            let candidate = self.last_level_root(size, depth)?;
            if candidate == root {
                break;
            }
            let (d, _) = self.search(part, candidate, lab)?;
            root = candidate;
            if d <= depth {
                depth = d;
                break;
            }
            depth = d;
        }
        if depth < 2 {
            // No level lies strictly between two others: nothing separates this part.
            return self.order_leaf(perm, lo, hi);
        }
        // The separating level: the first whose end reaches half the part, kept strictly
        // inside the structure so that both halves are non-empty.
        let mut s = 0u32;
        for (count, &v) in self
            .queue
            .get(..size)
            .ok_or_else(internal)?
            .iter()
            .enumerate()
        {
            let l = at(self.level, ux(v))?;
            if l > s && count >= size / 2 {
                break;
            }
            s = l;
        }
        let s = s.clamp(1, depth - 1);
        // Separator: the vertices of level `s` with a neighbour in level `s + 1`.
        let mut n_sep = 0usize;
        for i in 0..size {
            let v = ux(at(self.queue, i)?);
            if at(self.level, v)? != s {
                continue;
            }
            let mut touches = false;
            for &w in self.graph.neighbours(v) {
                if at(self.label, ux(w))? == lab && at(self.level, ux(w))? == s + 1 {
                    touches = true;
                    break;
                }
            }
            if touches {
                // Marked for now by a level past every other; its label goes below.
                *at_mut(self.level, v)? = NONE;
                n_sep += 1;
            }
        }
        // Lay the range out as [first half | second half | separator], each in level order.
        let n_first = self.layout(perm, lo, size, |l| l <= s)?;
        let n_second = self.layout(perm, lo + n_first, size, |l| l > s && l != NONE)?;
        self.layout(perm, lo + n_first + n_second, size, |l| l == NONE)?;
        if n_first + n_second + n_sep != size {
            return Err(internal());
        }
        self.relabel(perm, lo, lo + n_first)?;
        self.relabel(perm, lo + n_first, lo + n_first + n_second)?;
        for &v in perm.get(lo + n_first + n_second..hi).ok_or_else(internal)? {
            *at_mut(self.label, ux(v))? = NONE;
        }
        // The second half is split first, then the first: either order gives the same
        // permutation, as the ranges are disjoint.
        self.push(lo, lo + n_first)?;
        self.push(lo + n_first, lo + n_first + n_second)
    }

    /// Breadth-first search of the part (vertices labelled `lab`, listed in `part`) from
    /// `root`: fills `level` and `queue`, returns the depth (last level) and the number of
    /// vertices reached.
    fn search(&mut self, part: &[u32], root: u32, lab: u32) -> Result<(u32, usize), Error> {
        for &v in part {
            *at_mut(self.level, ux(v))? = NONE;
        }
        *at_mut(self.level, ux(root))? = 0;
        *at_mut(self.queue, 0)? = root;
        let (mut head, mut tail) = (0usize, 1usize);
        let mut depth = 0;
        while head < tail {
            let v = at(self.queue, head)?;
            head += 1;
            let l = at(self.level, ux(v))?;
            depth = l;
            for &w in self.graph.neighbours(ux(v)) {
                if at(self.label, ux(w))? == lab && at(self.level, ux(w))? == NONE {
                    *at_mut(self.level, ux(w))? = l + 1;
                    *at_mut(self.queue, tail)? = w;
                    tail += 1;
                }
            }
        }
        Ok((depth, tail))
    }

    /// A vertex of least degree among the last level (`depth`) of the search just done over
    /// `size` vertices.
    fn last_level_root(&self, size: usize, depth: u32) -> Result<u32, Error> {
        let mut best = (usize::MAX, NONE);
        for &v in self.queue.get(..size).ok_or_else(internal)?.iter().rev() {
            if at(self.level, ux(v))? != depth {
                break;
            }
            let degree = self.graph.neighbours(ux(v)).len();
            if degree <= best.0 {
                best = (degree, v);
            }
        }
        if best.1 == NONE {
            return Err(internal());
        }
        Ok(best.1)
    }

    /// Writes the vertices of the last search (`queue[..size]`) whose level satisfies `keep`
    /// into `perm` from `start`, in level order; returns how many.
    fn layout(
        &self,
        perm: &mut [u32],
        start: usize,
        size: usize,
        keep: impl Fn(u32) -> bool,
    ) -> Result<usize, Error> {
        let mut k = start;
        for &v in self.queue.get(..size).ok_or_else(internal)? {
            if keep(at(self.level, ux(v))?) {
                *at_mut(perm, k)? = v;
                k += 1;
            }
        }
        Ok(k - start)
    }

    /// Gives the vertices of `perm[lo..hi]` the label of their new range.
    fn relabel(&mut self, perm: &[u32], lo: usize, hi: usize) -> Result<(), Error> {
        for &v in perm.get(lo..hi).ok_or_else(internal)? {
            *at_mut(self.label, ux(v))? = lo as u32;
        }
        Ok(())
    }

    /// The part is not connected: its first `reached` vertices (the search's, in `queue`) form
    /// one part and the others another, with no separator between them.
    fn split_component(
        &mut self,
        perm: &mut [u32],
        lo: usize,
        hi: usize,
        reached: usize,
    ) -> Result<(), Error> {
        let size = hi - lo;
        // The unreached vertices, kept in their order, go after the reached ones.
        let part = perm.get_mut(lo..hi).ok_or_else(internal)?;
        let mut k = reached;
        for i in 0..size {
            let v = at(part, i)?;
            if at(self.level, ux(v))? == NONE {
                *at_mut(self.sub_perm, k)? = v;
                k += 1;
            }
        }
        let reached_vertices = self.queue.get(..reached).ok_or_else(internal)?;
        self.sub_perm
            .get_mut(..reached)
            .ok_or_else(internal)?
            .copy_from_slice(reached_vertices);
        part.copy_from_slice(self.sub_perm.get(..size).ok_or_else(internal)?);
        self.relabel(perm, lo, lo + reached)?;
        self.relabel(perm, lo + reached, hi)?;
        self.push(lo, lo + reached)?;
        self.push(lo + reached, hi)
    }

    /// Orders the part in `perm[lo..hi]` by minimum degree on its own subgraph.
    fn order_leaf(&mut self, perm: &mut [u32], lo: usize, hi: usize) -> Result<(), Error> {
        let size = hi - lo;
        let lab = lo as u32;
        let vertices = self.queue.get_mut(..size).ok_or_else(internal)?;
        vertices.copy_from_slice(perm.get(lo..hi).ok_or_else(internal)?);
        // In increasing order, so that each subgraph list comes out sorted.
        vertices.sort_unstable();
        for (i, &v) in vertices.iter().enumerate() {
            *at_mut(self.local, ux(v))? = i as u32;
        }
        let mut nz = 0usize;
        *at_mut(self.sub_ptr, 0)? = 0;
        for (i, &v) in vertices.iter().enumerate() {
            for &w in self.graph.neighbours(ux(v)) {
                if at(self.label, ux(w))? == lab {
                    *at_mut(self.sub_adj, nz)? = at(self.local, ux(w))?;
                    nz += 1;
                }
            }
            *at_mut(self.sub_ptr, i + 1)? = nz as u32;
        }
        let sub = Graph::new(
            size,
            self.sub_ptr.get(..=size).ok_or_else(internal)?,
            self.sub_adj.get(..nz).ok_or_else(internal)?,
        )?;
        let sub_perm = self.sub_perm.get_mut(..size).ok_or_else(internal)?;
        minimum_degree(&sub, sub_perm, self.md_work)?;
        let out = perm.get_mut(lo..hi).ok_or_else(internal)?;
        for (o, &k) in out.iter_mut().zip(sub_perm.iter()) {
            *o = at(vertices, ux(k))?;
            *at_mut(self.label, ux(*o))? = NONE;
        }
        Ok(())
    }
}

#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;
    use crate::sparse::{elimination_fill, fill_reducing_order, fill_reducing_order_work_len};

    /// The 7-point grid graph of `nx × ny × nz` vertices, vertex `(i, j, k)` at
    /// `i + nx (j + ny k)`, into `ptr` and `adj`; returns the adjacency entries used.
    fn grid(dims: [usize; 3], ptr: &mut [u32], adj: &mut [u32]) -> usize {
        let [nx, ny, nz] = dims;
        let index = |i: usize, j: usize, k: usize| (i + nx * (j + ny * k)) as u32;
        let mut e = 0;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let v = ux(index(i, j, k));
                    ptr[v] = e as u32;
                    // In increasing index order: −z, −y, −x, +x, +y, +z.
                    let mut push = |w: u32| {
                        adj[e] = w;
                        e += 1;
                    };
                    if k > 0 {
                        push(index(i, j, k - 1));
                    }
                    if j > 0 {
                        push(index(i, j - 1, k));
                    }
                    if i > 0 {
                        push(index(i - 1, j, k));
                    }
                    if i + 1 < nx {
                        push(index(i + 1, j, k));
                    }
                    if j + 1 < ny {
                        push(index(i, j + 1, k));
                    }
                    if k + 1 < nz {
                        push(index(i, j, k + 1));
                    }
                }
            }
        }
        ptr[nx * ny * nz] = e as u32;
        e
    }

    fn is_permutation(perm: &[u32]) -> bool {
        let mut seen = [false; 2048];
        perm.iter()
            .all(|&v| ux(v) < perm.len() && !core::mem::replace(&mut seen[ux(v)], true))
    }

    const N: usize = 10 * 10 * 6;
    const WORK: usize = nested_dissection_work_len(N, 6 * N) + N;

    /// The `10 × 10 × 6` grid graph of `N` vertices.
    struct Grid {
        ptr: [u32; N + 1],
        adj: [u32; 6 * N],
        nnz: usize,
    }

    impl Grid {
        fn new() -> Self {
            let (mut ptr, mut adj) = ([0u32; N + 1], [0u32; 6 * N]);
            let nnz = grid([10, 10, 6], &mut ptr, &mut adj);
            Grid { ptr, adj, nnz }
        }

        fn graph(&self) -> Graph<'_> {
            Graph::new(N, &self.ptr, &self.adj[..self.nnz]).unwrap()
        }
    }

    #[test]
    fn a_grid_is_ordered_by_a_permutation_with_its_first_separator_last() {
        let grid = Grid::new();
        let g = grid.graph();
        let mut perm = [0u32; N];
        let mut work = [0u32; WORK];
        nested_dissection(&g, &mut perm, &mut work).unwrap();
        assert!(is_permutation(&perm));
        // The first split's separator is eliminated last: the ordering falls into a first
        // half, a second half and a rest smaller than either, with no edge between the halves.
        let mut position = [0usize; N];
        for (k, &v) in perm.iter().enumerate() {
            position[ux(v)] = k;
        }
        let separated = (1..N).any(|a| {
            (a + 1..N).any(|b| {
                N - b < a.min(b - a)
                    && (0..N).all(|v| {
                        g.neighbours(v).iter().all(|&w| {
                            let (p, q) = (position[v], position[ux(w)]);
                            !(p < a && (a..b).contains(&q))
                        })
                    })
            })
        });
        assert!(separated, "no separator at the end of the ordering");
    }

    #[test]
    fn components_and_isolated_vertices_are_all_ordered() {
        // Two grids side by side with no edge between them, and isolated vertices after them.
        const M: usize = 2 * 300 + 40;
        let (mut ptr, mut adj) = ([0u32; M + 1], [0u32; 2 * 6 * 300]);
        let (mut one_ptr, mut one_adj) = ([0u32; 301], [0u32; 6 * 300]);
        let half = grid([10, 10, 3], &mut one_ptr, &mut one_adj);
        for copy in 0..2 {
            for (v, &p) in one_ptr.iter().enumerate() {
                ptr[300 * copy + v] = (half * copy) as u32 + p;
            }
            for (a, &w) in adj[half * copy..].iter_mut().zip(&one_adj[..half]) {
                *a = w + (300 * copy) as u32;
            }
        }
        for p in &mut ptr[600..] {
            *p = 2 * half as u32;
        }
        let g = Graph::new(M, &ptr, &adj[..2 * half]).unwrap();
        let mut perm = [0u32; M];
        let mut work = [0u32; nested_dissection_work_len(M, 2 * 6 * 300)];
        nested_dissection(&g, &mut perm, &mut work).unwrap();
        assert!(is_permutation(&perm));
    }

    #[test]
    fn the_kept_ordering_has_the_lesser_fill_of_the_two() {
        // Above `DISSECTION_FROM` both orderings are tried; at or below it, minimum degree's.
        const BIG: usize = 12 * 12 * 8;
        const BIG_WORK: usize = nested_dissection_work_len(BIG, 6 * BIG) + BIG;
        let (mut ptr, mut adj) = ([0u32; BIG + 1], [0u32; 6 * BIG]);
        let nnz = grid([12, 12, 8], &mut ptr, &mut adj);
        let small = Grid::new();
        for (g, n) in [
            (Graph::new(BIG, &ptr, &adj[..nnz]).unwrap(), BIG),
            (small.graph(), N),
        ] {
            let mut work = [0u32; BIG_WORK];
            let (mut md, mut nd, mut kept) = ([0u32; BIG], [0u32; BIG], [0u32; BIG]);
            let (md, nd, kept) = (&mut md[..n], &mut nd[..n], &mut kept[..n]);
            crate::sparse::minimum_degree(&g, md, &mut work).unwrap();
            nested_dissection(&g, nd, &mut work).unwrap();
            let len = fill_reducing_order_work_len(n, g.nnz());
            fill_reducing_order(&g, kept, &mut work[..len]).unwrap();
            let fill = |p: &[u32], w: &mut [u32]| elimination_fill(&g, p, w).unwrap();
            let (f_md, f_nd) = (fill(md, &mut work), fill(nd, &mut work));
            let expected = if n > crate::sparse::DISSECTION_FROM {
                f_md.min(f_nd)
            } else {
                f_md
            };
            assert_eq!(fill(kept, &mut work), expected);
            assert!(is_permutation(kept));
        }
    }

    #[test]
    fn fill_of_a_path_a_star_and_a_clique() {
        // Path 0-1-2-3: eliminated from one end, no fill: 3 entries.
        let g = Graph::new(4, &[0, 1, 3, 5, 6], &[1, 0, 2, 1, 3, 2]).unwrap();
        let mut work = [0u32; 12];
        assert_eq!(elimination_fill(&g, &[0, 1, 2, 3], &mut work), Ok(3));
        // From the middle first: 1 joins 0 and 2 (one fill entry).
        assert_eq!(elimination_fill(&g, &[1, 0, 2, 3], &mut work), Ok(4));
        // Star with centre 0: centre last gives the 3 edges, centre first the whole clique.
        let g = Graph::new(4, &[0, 3, 4, 5, 6], &[1, 2, 3, 0, 0, 0]).unwrap();
        assert_eq!(elimination_fill(&g, &[1, 2, 3, 0], &mut work), Ok(3));
        assert_eq!(elimination_fill(&g, &[0, 1, 2, 3], &mut work), Ok(6));
        // A repeated vertex and one out of range are errors.
        assert_eq!(
            elimination_fill(&g, &[0, 1, 1, 3], &mut work),
            Err(Error::NotAPermutation { position: 2 })
        );
        assert!(matches!(
            elimination_fill(&g, &[0, 1, 2, 9], &mut work),
            Err(Error::IndexOutOfRange { .. })
        ));
    }

    #[test]
    fn short_workspace_and_wrong_length_are_errors() {
        let grid = Grid::new();
        let (g, nnz) = (grid.graph(), grid.nnz);
        let mut perm = [0u32; N];
        let mut work = [0u32; WORK];
        let short = nested_dissection_work_len(N, nnz) - 1;
        assert!(matches!(
            nested_dissection(&g, &mut perm, &mut work[..short]),
            Err(Error::Capacity { .. })
        ));
        assert!(matches!(
            nested_dissection(&g, &mut perm[..N - 1], &mut work),
            Err(Error::Length { .. })
        ));
        let empty = Graph::new(0, &[0], &[]).unwrap();
        assert!(nested_dissection(&empty, &mut [], &mut work).is_ok());
        assert!(fill_reducing_order(&empty, &mut [], &mut work).is_ok());
    }
}
