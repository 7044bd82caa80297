//! Sparse patterns: the upper triangle of a symmetric matrix, and the adjacency graph of mesh
//! nodes from which the stiffness pattern is built.

use super::{NONE, ux};
use crate::error::{Error, PatternProblem, Resource};
use crate::storage::{Slab, ensure_exact_len, ensure_len, sum, times};

/// Largest dimension or entry count the `u32` indices can hold (one value is kept for [`NONE`]).
pub const MAX_INDEX: usize = (u32::MAX - 1) as usize;

/// The upper triangle (diagonal included) of a symmetric `n × n` matrix in compressed-column
/// form: the rows of column `j` are `row_idx[col_ptr[j]..col_ptr[j + 1]]`.
///
/// Invariants, checked once by [`UpperCsc::new`]: `col_ptr` has `n + 1` entries, starts at 0,
/// never decreases and ends at `row_idx.len()`; the rows of each column increase strictly, none
/// exceeds its column, and the diagonal entry is present (so it is the column's last entry).
/// Every accessor can rely on them and none can fail.
#[derive(Clone, Copy, Debug)]
pub struct UpperCsc<'a> {
    n: usize,
    col_ptr: &'a [u32],
    row_idx: &'a [u32],
}

impl<'a> UpperCsc<'a> {
    /// Checks the invariants and wraps the arrays.
    ///
    /// # Errors
    /// [`Error::Length`] if `col_ptr` does not have `n + 1` entries, [`Error::Pattern`] naming the
    /// first offending column otherwise.
    pub fn new(n: usize, col_ptr: &'a [u32], row_idx: &'a [u32]) -> Result<Self, Error> {
        if n > MAX_INDEX || row_idx.len() > MAX_INDEX {
            return Err(Error::Pattern {
                column: 0,
                problem: PatternProblem::TooLarge,
            });
        }
        ensure_exact_len(col_ptr, n + 1, Resource::ColumnPointers)?;
        if col_ptr.first() != Some(&0) || col_ptr.last().map(|&e| ux(e)) != Some(row_idx.len()) {
            return Err(Error::Pattern {
                column: 0,
                problem: PatternProblem::ColumnPointers,
            });
        }
        for (j, w) in col_ptr.windows(2).enumerate() {
            let (start, end) = (ux(w[0]), ux(w[1]));
            if start > end || end > row_idx.len() {
                return Err(Error::Pattern {
                    column: j,
                    problem: PatternProblem::ColumnPointers,
                });
            }
            let rows = &row_idx[start..end];
            if rows.windows(2).any(|r| r[0] >= r[1]) {
                return Err(Error::Pattern {
                    column: j,
                    problem: PatternProblem::Unsorted,
                });
            }
            match rows.last() {
                Some(&last) if ux(last) == j => {}
                Some(&last) if ux(last) > j => {
                    return Err(Error::Pattern {
                        column: j,
                        problem: PatternProblem::BelowDiagonal,
                    });
                }
                _ => {
                    return Err(Error::Pattern {
                        column: j,
                        problem: PatternProblem::MissingDiagonal,
                    });
                }
            }
        }
        Ok(UpperCsc {
            n,
            col_ptr,
            row_idx,
        })
    }

    /// Dimension `n`.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of stored entries (upper triangle with diagonal).
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Column pointers, `n + 1` entries.
    pub fn col_ptr(&self) -> &'a [u32] {
        self.col_ptr
    }

    /// Row indices, `nnz` entries.
    pub fn row_idx(&self) -> &'a [u32] {
        self.row_idx
    }

    /// Range of column `j`'s entries in `row_idx` (empty when `j >= n`).
    pub fn column_range(&self, j: usize) -> core::ops::Range<usize> {
        match (self.col_ptr.get(j), self.col_ptr.get(j + 1)) {
            (Some(&s), Some(&e)) => ux(s)..ux(e),
            _ => 0..0,
        }
    }

    /// Position of entry `(i, j)` with `i <= j` in `row_idx`, if stored.
    pub fn find(&self, i: usize, j: usize) -> Option<usize> {
        let r = self.column_range(j);
        let start = r.start;
        self.row_idx[r]
            .binary_search(&(i as u32))
            .ok()
            .map(|k| start + k)
    }
}

/// The adjacency of an undirected graph in compressed form: the neighbours of vertex `v` are
/// `adj[ptr[v]..ptr[v + 1]]`, sorted, without `v` itself, and the relation is symmetric.
///
/// [`Graph::new`] checks all of this once; accessors then cannot fail.
#[derive(Clone, Copy, Debug)]
pub struct Graph<'a> {
    n: usize,
    ptr: &'a [u32],
    adj: &'a [u32],
}

/// Length of the `u32` workspace that [`Graph::from_tets`] needs.
pub const fn tet_graph_work_len(n_nodes: usize, n_tets: usize) -> usize {
    sum(&[times(2, n_nodes), 1, times(4, n_tets)])
}

impl<'a> Graph<'a> {
    /// Checks the invariants (sorted, no self-loops, indices in range, symmetric) and wraps the
    /// arrays.
    ///
    /// # Errors
    /// [`Error::Length`] if `ptr` does not have `n + 1` entries; [`Error::Pattern`] naming the
    /// first vertex whose list is inconsistent.
    pub fn new(n: usize, ptr: &'a [u32], adj: &'a [u32]) -> Result<Self, Error> {
        if n > MAX_INDEX || adj.len() > MAX_INDEX {
            return Err(Error::Pattern {
                column: 0,
                problem: PatternProblem::TooLarge,
            });
        }
        ensure_exact_len(ptr, n + 1, Resource::ColumnPointers)?;
        if ptr.first() != Some(&0) || ptr.last().map(|&e| ux(e)) != Some(adj.len()) {
            return Err(Error::Pattern {
                column: 0,
                problem: PatternProblem::ColumnPointers,
            });
        }
        for v in 0..n {
            let (s, e) = (ux(ptr[v]), ux(ptr[v + 1]));
            if s > e || e > adj.len() {
                return Err(Error::Pattern {
                    column: v,
                    problem: PatternProblem::ColumnPointers,
                });
            }
        }
        let g = Graph { n, ptr, adj };
        for v in 0..n {
            let list = g.neighbours(v);
            if list.windows(2).any(|w| w[0] >= w[1]) {
                return Err(Error::Pattern {
                    column: v,
                    problem: PatternProblem::Unsorted,
                });
            }
            for &u in list {
                let u = ux(u);
                if u >= n || u == v || g.neighbours(u).binary_search(&(v as u32)).is_err() {
                    return Err(Error::Pattern {
                        column: v,
                        problem: PatternProblem::Unsorted,
                    });
                }
            }
        }
        Ok(g)
    }

    /// Number of vertices.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of stored adjacency entries (twice the number of edges).
    pub fn nnz(&self) -> usize {
        self.adj.len()
    }

    /// Pointers, `n + 1` entries.
    pub fn ptr(&self) -> &'a [u32] {
        self.ptr
    }

    /// Adjacency entries.
    pub fn adj(&self) -> &'a [u32] {
        self.adj
    }

    /// Neighbours of `v`, sorted (empty when `v >= n`).
    pub fn neighbours(&self, v: usize) -> &'a [u32] {
        match (self.ptr.get(v), self.ptr.get(v + 1)) {
            (Some(&s), Some(&e)) => self.adj.get(ux(s)..ux(e)).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Counts the adjacency entries of the graph of mesh nodes joined by a tetrahedron, over
    /// the nodes that `free` maps to a compact index (`free[v] == NONE` leaves node `v` out,
    /// as for a fixed node). `work` needs [`tet_graph_work_len`]`(n_free, tets.len())` entries,
    /// where `n_free` is the number of mapped nodes.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a tetrahedron node `>= free.len()`, or a compact index
    /// `>= n_free`; [`Error::NotAPermutation`] if two nodes share a compact index;
    /// [`Error::Capacity`] if `work` is too short.
    pub fn tets_nnz(tets: &[[u32; 4]], free: &[u32], work: &mut [u32]) -> Result<usize, Error> {
        let n_free = check_free_map(tets, free, work)?;
        let (inc_ptr, inc, mark) = incidence(tets, free, n_free, work)?;
        let mut total = 0usize;
        for j in 0..n_free {
            total += for_each_neighbour(j, tets, free, inc_ptr, inc, mark, |_| {});
        }
        Ok(total)
    }

    /// Builds the adjacency graph that [`Graph::tets_nnz`] counts into `ptr` (`n_free + 1`
    /// entries) and `adj` (at least the count), vertices numbered by `free`.
    ///
    /// # Errors
    /// As [`Graph::tets_nnz`], and [`Error::Capacity`] if `ptr` or `adj` is too short.
    pub fn from_tets(
        tets: &[[u32; 4]],
        free: &[u32],
        ptr: &'a mut [u32],
        adj: &'a mut [u32],
        work: &mut [u32],
    ) -> Result<Graph<'a>, Error> {
        let n_free = check_free_map(tets, free, work)?;
        ensure_len(ptr, n_free + 1, Resource::ColumnPointers)?;
        let (inc_ptr, inc, mark) = incidence(tets, free, n_free, work)?;
        // Count first so that a short `adj` is reported before anything is written.
        let mut total = 0usize;
        ptr[0] = 0;
        for j in 0..n_free {
            total += for_each_neighbour(j, tets, free, inc_ptr, inc, mark, |_| {});
            ptr[j + 1] = total as u32;
        }
        ensure_len(adj, total, Resource::GraphEntries)?;
        mark.fill(NONE);
        for j in 0..n_free {
            let mut at = ux(ptr[j]);
            for_each_neighbour(j, tets, free, inc_ptr, inc, mark, |u| {
                adj[at] = u;
                at += 1;
            });
            adj[ux(ptr[j])..at].sort_unstable();
        }
        let ptr: &'a [u32] = &ptr[..n_free + 1];
        let adj: &'a [u32] = &adj[..total];
        Ok(Graph {
            n: n_free,
            ptr,
            adj,
        })
    }

    /// The adjacency graph of a symmetric pattern: `i` and `j` are neighbours when entry
    /// `(i, j)`, `i != j`, is stored. `ptr` needs `n + 1` entries, `adj` twice the number of
    /// off-diagonal entries of `a`, `work` `n` entries.
    ///
    /// # Errors
    /// [`Error::Capacity`] if a buffer is too short.
    pub fn from_upper(
        a: &UpperCsc<'_>,
        ptr: &'a mut [u32],
        adj: &'a mut [u32],
        work: &mut [u32],
    ) -> Result<Graph<'a>, Error> {
        let n = a.n();
        let off = a.nnz() - n; // every column stores its diagonal
        ensure_len(ptr, n + 1, Resource::ColumnPointers)?;
        ensure_len(adj, 2 * off, Resource::GraphEntries)?;
        ensure_len(work, n, Resource::Workspace)?;
        let count = &mut work[..n];
        count.fill(0);
        for j in 0..n {
            for &i in &a.row_idx()[a.column_range(j)] {
                if ux(i) != j {
                    count[ux(i)] += 1;
                    count[j] += 1;
                }
            }
        }
        ptr[0] = 0;
        for v in 0..n {
            ptr[v + 1] = ptr[v] + count[v];
            count[v] = ptr[v];
        }
        // Lower neighbours of `v` are appended while column `v` is read, upper ones later in
        // increasing column order, so every list comes out sorted.
        for j in 0..n {
            for &i in &a.row_idx()[a.column_range(j)] {
                let i = ux(i);
                if i != j {
                    adj[ux(count[i])] = j as u32;
                    count[i] += 1;
                    adj[ux(count[j])] = i as u32;
                    count[j] += 1;
                }
            }
        }
        let ptr: &'a [u32] = &ptr[..n + 1];
        let adj: &'a [u32] = &adj[..2 * off];
        Ok(Graph { n, ptr, adj })
    }
}

/// Validates the free-node map against the tetrahedra; returns the number of free nodes.
fn check_free_map(tets: &[[u32; 4]], free: &[u32], work: &mut [u32]) -> Result<usize, Error> {
    let n_free = free.iter().filter(|&&f| f != NONE).count();
    if n_free > MAX_INDEX || tets.len() > MAX_INDEX / 4 {
        return Err(Error::Pattern {
            column: 0,
            problem: PatternProblem::TooLarge,
        });
    }
    ensure_len(
        work,
        tet_graph_work_len(n_free, tets.len()),
        Resource::Workspace,
    )?;
    let seen = &mut work[..n_free];
    seen.fill(0);
    for (position, &f) in free.iter().enumerate() {
        if f == NONE {
            continue;
        }
        let slot = seen.get_mut(ux(f)).ok_or(Error::IndexOutOfRange {
            resource: Resource::Nodes,
            position,
            index: ux(f),
            bound: n_free,
        })?;
        if *slot != 0 {
            return Err(Error::NotAPermutation { position });
        }
        *slot = 1;
    }
    for (t, tet) in tets.iter().enumerate() {
        for (k, &v) in tet.iter().enumerate() {
            if ux(v) >= free.len() {
                return Err(Error::IndexOutOfRange {
                    resource: Resource::Tetrahedra,
                    position: 4 * t + k,
                    index: ux(v),
                    bound: free.len(),
                });
            }
        }
    }
    Ok(n_free)
}

/// Node-to-tetrahedron incidence of the free nodes, carved from `work`; `mark` comes back
/// filled with [`NONE`].
#[allow(clippy::type_complexity)]
fn incidence<'w>(
    tets: &[[u32; 4]],
    free: &[u32],
    n_free: usize,
    work: &'w mut [u32],
) -> Result<(&'w [u32], &'w [u32], &'w mut [u32]), Error> {
    let mut slab = Slab::new(work, Resource::Workspace);
    let inc_ptr = slab.take(n_free + 1)?;
    let inc = slab.take(4 * tets.len())?;
    let mark = slab.take(n_free)?;
    inc_ptr.fill(0);
    for tet in tets {
        for &v in tet {
            let f = free[ux(v)];
            if f != NONE {
                inc_ptr[ux(f) + 1] += 1;
            }
        }
    }
    for v in 0..n_free {
        inc_ptr[v + 1] += inc_ptr[v];
    }
    // `mark` doubles as the fill cursor here, then is reset.
    mark.copy_from_slice(&inc_ptr[..n_free]);
    for (t, tet) in tets.iter().enumerate() {
        for &v in tet {
            let f = free[ux(v)];
            if f != NONE {
                let at = &mut mark[ux(f)];
                inc[ux(*at)] = t as u32;
                *at += 1;
            }
        }
    }
    mark.fill(NONE);
    Ok((inc_ptr, inc, mark))
}

/// Calls `visit` once for each free neighbour of free node `j` (in no particular order) and
/// returns their number. `mark` must not hold `j` on entry.
fn for_each_neighbour(
    j: usize,
    tets: &[[u32; 4]],
    free: &[u32],
    inc_ptr: &[u32],
    inc: &[u32],
    mark: &mut [u32],
    mut visit: impl FnMut(u32),
) -> usize {
    let mut count = 0;
    mark[j] = j as u32;
    for &t in &inc[ux(inc_ptr[j])..ux(inc_ptr[j + 1])] {
        for &v in &tets[ux(t)] {
            let f = free[ux(v)];
            if f != NONE && mark[ux(f)] != j as u32 {
                mark[ux(f)] = j as u32;
                visit(f);
                count += 1;
            }
        }
    }
    count
}

/// Entries of the upper triangle of the matrix with a dense `b × b` block on the diagonal and
/// on every edge of `graph` (the stiffness pattern with `b = 3` unknowns per node).
pub fn block_upper_len(graph: &Graph<'_>, b: usize) -> usize {
    // `b (b + 1) / 2` entries per vertex (halving the even factor keeps it exact), `b²` per
    // edge; saturated at `usize::MAX` ([`times`]).
    let triangle = if b.is_multiple_of(2) {
        times(b / 2, sum(&[b, 1]))
    } else {
        times(b, sum(&[b, 1]) / 2)
    };
    sum(&[
        times(graph.n(), triangle),
        times(graph.nnz() / 2, times(b, b)),
    ])
}

/// Builds the pattern that [`block_upper_len`] counts: vertex `v` owns rows and columns
/// `b·v .. b·v + b`. `col_ptr` needs `b·n + 1` entries, `row_idx` [`block_upper_len`].
///
/// # Errors
/// [`Error::Capacity`] if a buffer is too short; [`Error::Pattern`] if the size overflows the
/// `u32` indices.
pub fn block_upper_pattern<'a>(
    graph: &Graph<'_>,
    b: usize,
    col_ptr: &'a mut [u32],
    row_idx: &'a mut [u32],
) -> Result<UpperCsc<'a>, Error> {
    let n = times(graph.n(), b);
    let nnz = block_upper_len(graph, b);
    if n > MAX_INDEX || nnz > MAX_INDEX {
        return Err(Error::Pattern {
            column: 0,
            problem: PatternProblem::TooLarge,
        });
    }
    ensure_len(col_ptr, n + 1, Resource::ColumnPointers)?;
    ensure_len(row_idx, nnz, Resource::MatrixEntries)?;
    let mut at = 0usize;
    col_ptr[0] = 0;
    for v in 0..graph.n() {
        for c in 0..b {
            // Neighbours below `v` (sorted, so rows increase), then `v`'s own block down to the
            // diagonal.
            for &u in graph.neighbours(v).iter().take_while(|&&u| ux(u) < v) {
                for r in 0..b {
                    row_idx[at] = (ux(u) * b + r) as u32;
                    at += 1;
                }
            }
            for r in 0..=c {
                row_idx[at] = (v * b + r) as u32;
                at += 1;
            }
            col_ptr[v * b + c + 1] = at as u32;
        }
    }
    let col_ptr: &'a [u32] = &col_ptr[..n + 1];
    let row_idx: &'a [u32] = &row_idx[..at];
    UpperCsc::new(n, col_ptr, row_idx)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two tetrahedra sharing the face (1, 2, 3).
    const TWO_TETS: [[u32; 4]; 2] = [[0, 1, 2, 3], [1, 2, 3, 4]];

    #[test]
    fn tet_graph_of_two_tets() {
        let free = [0, 1, 2, 3, 4];
        let mut work = [0u32; 32];
        assert_eq!(Graph::tets_nnz(&TWO_TETS, &free, &mut work), Ok(18));
        let (mut ptr, mut adj) = ([0u32; 6], [0u32; 18]);
        let g = Graph::from_tets(&TWO_TETS, &free, &mut ptr, &mut adj, &mut work).unwrap();
        assert_eq!(g.neighbours(0), &[1, 2, 3]);
        assert_eq!(g.neighbours(1), &[0, 2, 3, 4]);
        assert_eq!(g.neighbours(4), &[1, 2, 3]);
        let (p, a) = (g.ptr(), g.adj());
        assert!(Graph::new(5, p, a).is_ok());
    }

    #[test]
    fn fixed_nodes_are_left_out() {
        let free = [NONE, 0, 1, 2, NONE];
        let mut work = [0u32; 32];
        let (mut ptr, mut adj) = ([0u32; 4], [0u32; 6]);
        let g = Graph::from_tets(&TWO_TETS, &free, &mut ptr, &mut adj, &mut work).unwrap();
        assert_eq!(g.n(), 3);
        assert_eq!(g.neighbours(0), &[1, 2]);
    }

    #[test]
    fn bad_tet_index_is_an_error() {
        let free = [0, 1, 2, 3];
        let mut work = [0u32; 32];
        assert!(matches!(
            Graph::tets_nnz(&TWO_TETS, &free, &mut work),
            Err(Error::IndexOutOfRange { index: 4, .. })
        ));
    }

    #[test]
    fn block_pattern_counts_and_validates() {
        let free = [0, 1, 2, 3, 4];
        let mut work = [0u32; 32];
        let (mut ptr, mut adj) = ([0u32; 6], [0u32; 18]);
        let g = Graph::from_tets(&TWO_TETS, &free, &mut ptr, &mut adj, &mut work).unwrap();
        let nnz = block_upper_len(&g, 3);
        assert_eq!(nnz, 5 * 6 + 9 * 9);
        let (mut cp, mut ri) = ([0u32; 16], [0u32; 111]);
        let a = block_upper_pattern(&g, 3, &mut cp, &mut ri).unwrap();
        assert_eq!(a.n(), 15);
        assert_eq!(a.nnz(), nnz);
        assert_eq!(a.find(0, 14), None);
        assert!(a.find(3, 14).is_some());
    }

    #[test]
    fn upper_csc_rejects_broken_patterns() {
        let cp = [0u32, 1, 2];
        assert_eq!(
            UpperCsc::new(2, &cp, &[0, 0]).err(),
            Some(Error::Pattern {
                column: 1,
                problem: PatternProblem::MissingDiagonal
            })
        );
        assert_eq!(
            UpperCsc::new(2, &[0, 1, 3], &[0, 1, 0]).err(),
            Some(Error::Pattern {
                column: 1,
                problem: PatternProblem::Unsorted
            })
        );
        assert_eq!(
            UpperCsc::new(1, &[0, 2], &[0, 1]).err(),
            Some(Error::Pattern {
                column: 0,
                problem: PatternProblem::BelowDiagonal
            })
        );
        assert!(UpperCsc::new(0, &[0], &[]).is_ok());
    }
}
