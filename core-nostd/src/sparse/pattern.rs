//! Sparse patterns: the upper triangle of a symmetric matrix, and the adjacency graph of mesh
//! nodes from which the stiffness pattern is built.

use super::{NONE, ux};
use crate::error::{Error, PatternProblem, Resource};
use crate::storage::{Slab, ensure_exact_len, ensure_len, prefix_mut, sum, times};

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
        for (j, (&start, &end)) in col_ptr.iter().zip(col_ptr.iter().skip(1)).enumerate() {
            // `None` when `start > end` or `end > row_idx.len()`.
            let Some(rows) = row_idx.get(ux(start)..ux(end)) else {
                return Err(Error::Pattern {
                    column: j,
                    problem: PatternProblem::ColumnPointers,
                });
            };
            if increasing_pairs(rows).any(|(r0, r1)| r0 >= r1) {
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
        // The invariants keep the range inside `row_idx`.
        self.row_idx
            .get(r)?
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
        for (v, (&s, &e)) in ptr.iter().zip(ptr.iter().skip(1)).enumerate() {
            // `None` when `s > e` or `e > adj.len()`.
            if adj.get(ux(s)..ux(e)).is_none() {
                return Err(Error::Pattern {
                    column: v,
                    problem: PatternProblem::ColumnPointers,
                });
            }
        }
        let g = Graph { n, ptr, adj };
        for v in 0..n {
            let list = g.neighbours(v);
            if increasing_pairs(list).any(|(a, b)| a >= b) {
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
        let ptr = prefix_mut(ptr, n_free + 1, Resource::ColumnPointers)?;
        let (inc_ptr, inc, mark) = incidence(tets, free, n_free, work)?;
        // Count first so that a short `adj` is reported before anything is written.
        let mut total = 0usize;
        if let Some((first, rest)) = ptr.split_first_mut() {
            *first = 0;
            for (j, end) in rest.iter_mut().enumerate() {
                total += for_each_neighbour(j, tets, free, inc_ptr, inc, mark, |_| {});
                *end = total as u32;
            }
        }
        let adj = prefix_mut(adj, total, Resource::GraphEntries)?;
        mark.fill(NONE);
        // The lists fill `adj` exactly as counted: every write is in range.
        for (j, &start) in ptr.iter().take(n_free).enumerate() {
            let mut at = ux(start);
            for_each_neighbour(j, tets, free, inc_ptr, inc, mark, |u| {
                if let Some(slot) = adj.get_mut(at) {
                    *slot = u;
                }
                at += 1;
            });
            if let Some(list) = adj.get_mut(ux(start)..at) {
                list.sort_unstable();
            }
        }
        let ptr: &'a [u32] = ptr;
        let adj: &'a [u32] = adj;
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
        let ptr = prefix_mut(ptr, n + 1, Resource::ColumnPointers)?;
        let adj = prefix_mut(adj, 2 * off, Resource::GraphEntries)?;
        let count = prefix_mut(work, n, Resource::Workspace)?;
        count.fill(0);
        // The pattern's invariants keep every row below `n` (rows never exceed their column),
        // so no increment below is skipped.
        let bump = |count: &mut [u32], v: usize| {
            if let Some(c) = count.get_mut(v) {
                *c += 1;
            }
        };
        for j in 0..n {
            for &i in column_rows(a, j) {
                if ux(i) != j {
                    bump(count, ux(i));
                    bump(count, j);
                }
            }
        }
        if let Some((first, rest)) = ptr.split_first_mut() {
            *first = 0;
            let mut start = 0;
            for (end, c) in rest.iter_mut().zip(count.iter_mut()) {
                *end = start + *c;
                *c = start;
                start = *end;
            }
        }
        // Lower neighbours of `v` are appended while column `v` is read, upper ones later in
        // increasing column order, so every list comes out sorted. The counts make the lists
        // fill `adj` exactly: every write is in range.
        let mut append = |count: &mut [u32], v: usize, u: usize| {
            if let Some(c) = count.get_mut(v) {
                if let Some(slot) = adj.get_mut(ux(*c)) {
                    *slot = u as u32;
                }
                *c += 1;
            }
        };
        for j in 0..n {
            for &i in column_rows(a, j) {
                let i = ux(i);
                if i != j {
                    append(count, i, j);
                    append(count, j, i);
                }
            }
        }
        let ptr: &'a [u32] = ptr;
        let adj: &'a [u32] = adj;
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
    let seen = prefix_mut(work, n_free, Resource::Workspace)?;
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
    // [`check_free_map`] has checked every node against `free` and every compact index against
    // `n_free`, and the counts make the lists fill `inc` exactly: no lookup below fails and no
    // write is skipped.
    let free_of = |v: u32| free.get(ux(v)).copied().unwrap_or(NONE);
    for tet in tets {
        for &v in tet {
            let f = free_of(v);
            if f != NONE
                && let Some(c) = inc_ptr.get_mut(ux(f) + 1)
            {
                *c += 1;
            }
        }
    }
    let mut start = 0;
    for c in inc_ptr.iter_mut() {
        *c += start;
        start = *c;
    }
    // `mark` doubles as the fill cursor here, then is reset.
    for (m, &c) in mark.iter_mut().zip(inc_ptr.iter()) {
        *m = c;
    }
    for (t, tet) in tets.iter().enumerate() {
        for &v in tet {
            let f = free_of(v);
            if f != NONE
                && let Some(at) = mark.get_mut(ux(f))
            {
                if let Some(slot) = inc.get_mut(ux(*at)) {
                    *slot = t as u32;
                }
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
    // [`check_free_map`] and [`incidence`] keep every index below in range; were one not,
    // it would be skipped.
    let mut count = 0;
    if let Some(m) = mark.get_mut(j) {
        *m = j as u32;
    }
    let incident = match (inc_ptr.get(j), inc_ptr.get(j + 1)) {
        (Some(&s), Some(&e)) => inc.get(ux(s)..ux(e)).unwrap_or_default(),
        _ => &[],
    };
    for &t in incident {
        for &v in tets.get(ux(t)).into_iter().flatten() {
            let f = free.get(ux(v)).copied().unwrap_or(NONE);
            if f != NONE
                && let Some(m) = mark.get_mut(ux(f))
                && *m != j as u32
            {
                *m = j as u32;
                visit(f);
                count += 1;
            }
        }
    }
    count
}

/// Writes `value` at `out[*at]` (if in range) and moves `at` on.
fn push(out: &mut [u32], at: &mut usize, value: usize) {
    if let Some(slot) = out.get_mut(*at) {
        *slot = value as u32;
    }
    *at += 1;
}

/// Consecutive pairs `(s[k], s[k + 1])` of `s`.
fn increasing_pairs(s: &[u32]) -> impl Iterator<Item = (u32, u32)> + '_ {
    s.iter().copied().zip(s.iter().copied().skip(1))
}

/// The row indices of column `j` of `a` (the invariants keep them inside `row_idx`).
fn column_rows<'a>(a: &UpperCsc<'a>, j: usize) -> &'a [u32] {
    a.row_idx().get(a.column_range(j)).unwrap_or_default()
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
    let col_ptr = prefix_mut(col_ptr, n + 1, Resource::ColumnPointers)?;
    let row_idx = prefix_mut(row_idx, nnz, Resource::MatrixEntries)?;
    let mut at = 0usize;
    // `row_idx` holds the `nnz` entries [`block_upper_len`] counts, exactly what is written
    // (`at` ends at `nnz`), so no write is skipped; were one, [`UpperCsc::new`] would refuse
    // the pattern.
    if let Some((first, rest)) = col_ptr.split_first_mut() {
        *first = 0;
        // Column `v·b + c` ends at `rest[v·b + c]`.
        let mut ends = rest.iter_mut();
        for v in 0..graph.n() {
            for c in 0..b {
                // Neighbours below `v` (sorted, so rows increase), then `v`'s own block down to
                // the diagonal.
                for &u in graph.neighbours(v).iter().take_while(|&&u| ux(u) < v) {
                    for r in 0..b {
                        push(row_idx, &mut at, ux(u) * b + r);
                    }
                }
                for r in 0..=c {
                    push(row_idx, &mut at, v * b + r);
                }
                if let Some(end) = ends.next() {
                    *end = at as u32;
                }
            }
        }
    }
    let col_ptr: &'a [u32] = col_ptr;
    let row_idx: &'a [u32] = row_idx;
    let row_idx = row_idx.get(..at).unwrap_or_default();
    UpperCsc::new(n, col_ptr, row_idx)
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
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
