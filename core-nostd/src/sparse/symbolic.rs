//! The symbolic phase: permuted pattern, elimination tree, column counts and the row and column
//! patterns of the factor `L`, computed once per pattern.

use super::pattern::{MAX_INDEX, UpperCsc};
use super::precomputed::{PrecomputedAnalysis, check_work_len};
use super::{NONE, ux};
use crate::error::{Error, PatternProblem, PrecomputedProblem, Resource};
use crate::storage::{Slab, ensure_exact_len, ensure_len, sum, times};

/// Sizes of a symbolic factorization: what the storage of [`Symbolic`] and of the numeric
/// factor ([`crate::sparse::LdlFactor`]) depends on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SymbolicSize {
    /// Dimension.
    pub n: usize,
    /// Stored entries of `A`'s upper triangle (diagonal included).
    pub nnz_a: usize,
    /// Entries of the strictly lower triangle of `L` (its unit diagonal is not stored).
    pub nnz_l: usize,
}

impl SymbolicSize {
    /// Length of the `u32` storage [`Symbolic::new`] needs.
    pub const fn index_len(&self) -> usize {
        sum(&[
            times(4, self.n),
            times(4, sum(&[self.n, 1])),
            times(3, self.nnz_a),
            times(2, self.nnz_l),
        ])
    }
}

/// Length of the `u32` workspace [`Symbolic::size`] and [`Symbolic::new`] need.
pub const fn analyse_work_len(n: usize, nnz_a: usize) -> usize {
    sum(&[times(2, nnz_a), times(5, n), 1])
}

/// The symbolic factorization of `C = P A Pᵀ`, where `C(k, l) = A(perm[k], perm[l])`.
///
/// Holds the permutation and its inverse, the upper pattern of `C` with, for each of its
/// entries, the position of the value in `A`'s value array (so the numeric phase reads `A`'s
/// values directly), the elimination tree, the column pattern of `L` (strictly lower, rows
/// increasing) and its row pattern (columns increasing).
///
/// It also partitions the columns into *supernodes*: maximal runs of consecutive columns `f,
/// f+1, …, f+w−1`, each the parent of the one before in the elimination tree, whose patterns
/// nest, `struct(L(:, j)) = {j+1} ∪ struct(L(:, j+1))` (Liu, Ng and Peyton's supernodes,
/// without the one-child condition of fundamental ones, which a left-looking factorization does
/// not need). A supernode's row list is its first column's, `f` and then
/// [`Symbolic::l_row`] of column `f`; its columns are stored one after the other in `L`'s
/// column layout, so the supernodal factorization ([`crate::sparse::LdlFactor::
/// factorize_supernodal`]) writes exactly the values the column-by-column one does, and needs
/// no storage beyond `nnz(L) + n`. (Relaxed supernodes, which admit explicit zeros, would need
/// more and are not built.) For each entry of `C` the analysis also stores where it lands in
/// `L` ([`Symbolic::c_dst`]), so the numeric phase loads `C` into `L` in one pass.
///
/// The storage is sized once for a *capacity* ([`Symbolic::with_capacity`]) and the analysis
/// can be rebuilt in it for any pattern that fits ([`Symbolic::analyse`]), which is what a mesh
/// that gets cut needs. Every accessor relies on the invariants the last successful analysis
/// established and none can fail.
#[derive(Debug)]
pub struct Symbolic<'a> {
    capacity: SymbolicSize,
    size: SymbolicSize,
    perm: &'a mut [u32],
    iperm: &'a mut [u32],
    etree: &'a mut [u32],
    c_ptr: &'a mut [u32],
    c_row: &'a mut [u32],
    c_src: &'a mut [u32],
    l_ptr: &'a mut [u32],
    l_row: &'a mut [u32],
    lt_ptr: &'a mut [u32],
    lt_col: &'a mut [u32],
    c_dst: &'a mut [u32],
    sn_ptr: &'a mut [u32],
    col_sn: &'a mut [u32],
    supernodes: usize,
    factor_flops: u64,
}

impl<'a> Symbolic<'a> {
    /// Computes the sizes of the factorization of `A` under `perm` (`perm[k]` = column of `A`
    /// that comes `k`-th), using `work` ([`analyse_work_len`]`(n, nnz)` entries, no meaning on
    /// return). Allocate [`SymbolicSize::index_len`] entries of storage, then call
    /// [`Symbolic::new`].
    ///
    /// # Errors
    /// [`Error::Length`] / [`Error::NotAPermutation`] / [`Error::IndexOutOfRange`] for a bad
    /// `perm`, [`Error::Capacity`] if `work` is too short.
    pub fn size(a: &UpperCsc<'_>, perm: &[u32], work: &mut [u32]) -> Result<SymbolicSize, Error> {
        let n = a.n();
        ensure_len(work, analyse_work_len(n, a.nnz()), Resource::Workspace)?;
        let mut slab = Slab::new(work, Resource::Workspace);
        let iperm = slab.take(n)?;
        invert_permutation(perm, iperm)?;
        let c_ptr = slab.take(n + 1)?;
        let c_row = slab.take(a.nnz())?;
        let c_src = slab.take(a.nnz())?;
        let parent = slab.take(n)?;
        let mark = slab.take(n)?;
        permute_upper(a, iperm, c_ptr, c_row, c_src, mark)?;
        elimination_tree(c_ptr, c_row, parent, mark);
        let counts = slab.take(n)?;
        row_and_column_counts(c_ptr, c_row, parent, mark, counts, None)?;
        let nnz_l = counts.iter().map(|&c| ux(c)).sum::<usize>();
        if nnz_l > MAX_INDEX {
            return Err(Error::Pattern {
                column: n,
                problem: PatternProblem::TooLarge,
            });
        }
        Ok(SymbolicSize {
            n,
            nnz_a: a.nnz(),
            nnz_l,
        })
    }

    /// An empty analysis (dimension 0) whose storage holds any pattern up to `capacity`:
    /// `storage` needs [`SymbolicSize::index_len`]`(capacity)` entries.
    ///
    /// # Errors
    /// [`Error::Capacity`] if `storage` is too short.
    pub fn with_capacity(capacity: SymbolicSize, storage: &'a mut [u32]) -> Result<Self, Error> {
        ensure_len(storage, capacity.index_len(), Resource::IndexStorage)?;
        let n = capacity.n;
        let mut slab = Slab::new(storage, Resource::IndexStorage);
        let mut sym = Symbolic {
            capacity,
            size: SymbolicSize {
                n: 0,
                nnz_a: 0,
                nnz_l: 0,
            },
            perm: slab.take(n)?,
            iperm: slab.take(n)?,
            etree: slab.take(n)?,
            c_ptr: slab.take(n + 1)?,
            c_row: slab.take(capacity.nnz_a)?,
            c_src: slab.take(capacity.nnz_a)?,
            l_ptr: slab.take(n + 1)?,
            l_row: slab.take(capacity.nnz_l)?,
            lt_ptr: slab.take(n + 1)?,
            lt_col: slab.take(capacity.nnz_l)?,
            c_dst: slab.take(capacity.nnz_a)?,
            sn_ptr: slab.take(n + 1)?,
            col_sn: slab.take(n)?,
            supernodes: 0,
            factor_flops: 0,
        };
        for ptr in [
            &mut sym.c_ptr,
            &mut sym.l_ptr,
            &mut sym.lt_ptr,
            &mut sym.sn_ptr,
        ] {
            ptr[0] = 0;
        }
        Ok(sym)
    }

    /// Builds the symbolic factorization of `A` under `perm` in `storage` (at least
    /// [`SymbolicSize::index_len`] entries for the size [`Symbolic::size`] reports), using
    /// `work` as there.
    ///
    /// # Errors
    /// As [`Symbolic::size`], and [`Error::Capacity`] if `storage` is too short.
    pub fn new(
        a: &UpperCsc<'_>,
        perm: &[u32],
        storage: &'a mut [u32],
        work: &mut [u32],
    ) -> Result<Self, Error> {
        let size = Self::size(a, perm, work)?;
        let mut sym = Self::with_capacity(size, storage)?;
        sym.analyse(a, perm, work)?;
        Ok(sym)
    }

    /// Replaces the analysis with that of `A` under `perm`, in this storage; `work` as for
    /// [`Symbolic::size`].
    ///
    /// Transactional: the sizes are computed and checked against the capacity before anything
    /// is written, so on error the previous analysis is intact.
    ///
    /// # Errors
    /// As [`Symbolic::size`]; [`Error::Capacity`] naming [`Resource::Unknowns`],
    /// [`Resource::MatrixEntries`] or [`Resource::FactorEntries`] when the pattern exceeds the
    /// capacity.
    // Kept out of line so that a firmware build's symbols show whether it is linked
    // (tests/firmware.rs).
    #[inline(never)]
    pub fn analyse(
        &mut self,
        a: &UpperCsc<'_>,
        perm: &[u32],
        work: &mut [u32],
    ) -> Result<(), Error> {
        let size = Self::size(a, perm, work)?;
        self.check_capacity(&size)?;
        let n = size.n;
        let (perm_s, iperm, etree) = (
            &mut self.perm[..n],
            &mut self.iperm[..n],
            &mut self.etree[..n],
        );
        let (c_ptr, c_row, c_src) = (
            &mut self.c_ptr[..n + 1],
            &mut self.c_row[..size.nnz_a],
            &mut self.c_src[..size.nnz_a],
        );
        let (l_ptr, l_row, lt_ptr, lt_col) = (
            &mut self.l_ptr[..n + 1],
            &mut self.l_row[..size.nnz_l],
            &mut self.lt_ptr[..n + 1],
            &mut self.lt_col[..size.nnz_l],
        );
        let (c_dst, sn_ptr, col_sn) = (
            &mut self.c_dst[..size.nnz_a],
            &mut self.sn_ptr[..n + 1],
            &mut self.col_sn[..n],
        );
        perm_s.copy_from_slice(perm);
        invert_permutation(perm, iperm)?;

        let mut wslab = Slab::new(work, Resource::Workspace);
        let mark = wslab.take(n)?;
        let col_count = wslab.take(n)?;
        permute_upper(a, iperm, c_ptr, c_row, c_src, mark)?;
        elimination_tree(c_ptr, c_row, etree, mark);
        row_and_column_counts(c_ptr, c_row, etree, mark, col_count, Some(lt_ptr))?;

        // Column pointers of L from the column counts; the flop count of the up-looking
        // numeric phase follows from them: row k of column j costs one multiply-add per entry
        // of column j above row k.
        l_ptr[0] = 0;
        for j in 0..n {
            l_ptr[j + 1] = l_ptr[j] + col_count[j];
        }
        let flops = factor_flops(l_ptr);
        // Row patterns (sorted), then the column patterns by scattering rows in increasing
        // order, so every column comes out sorted too.
        for k in 0..n {
            let mut at = ux(lt_ptr[k]);
            mark[k] = k as u32;
            for &r in &c_row[ux(c_ptr[k])..ux(c_ptr[k + 1])] {
                let mut i = r;
                while i != NONE && mark[ux(i)] != k as u32 {
                    lt_col[at] = i;
                    at += 1;
                    mark[ux(i)] = k as u32;
                    i = etree[ux(i)];
                }
            }
            lt_col[ux(lt_ptr[k])..at].sort_unstable();
        }
        let supernodes = find_supernodes(etree, l_ptr, sn_ptr, col_sn);
        // Column patterns; on the way, where each entry C(j, k) (j < k, that is L(k, j)) lands
        // in L's values: row k's entries are placed in increasing column order, `mark[j]` keeps
        // the place of L(k, j) while row k is open.
        col_count.copy_from_slice(&l_ptr[..n]);
        for k in 0..n {
            for &j in &lt_col[ux(lt_ptr[k])..ux(lt_ptr[k + 1])] {
                let j = ux(j);
                mark[j] = col_count[j];
                l_row[ux(col_count[j])] = k as u32;
                col_count[j] += 1;
            }
            for q in ux(c_ptr[k])..ux(c_ptr[k + 1]) {
                let j = c_row[q];
                c_dst[q] = if ux(j) == k { NONE } else { mark[ux(j)] };
            }
        }
        self.size = size;
        self.supernodes = supernodes;
        self.factor_flops = flops;
        Ok(())
    }

    /// Replaces the analysis with a precomputed one of `A` ([`PrecomputedAnalysis`], made by
    /// [`Symbolic::precomputed`] ahead of time), checked against `a` but not recomputed: no
    /// ordering and no analysis code runs, so a build that only loads links neither. `work`
    /// needs [`check_work_len`]`(n, nnz_a)` entries (no meaning on return).
    ///
    /// Transactional: everything is checked before anything is written.
    ///
    /// # Errors
    /// [`Error::Capacity`] as for [`Symbolic::analyse`] when it exceeds the capacity or `work`
    /// is short; [`Error::Precomputed`] when it does not belong to `a` or is inconsistent
    /// (see [`super::precomputed`]).
    pub fn load(
        &mut self,
        a: &UpperCsc<'_>,
        pre: &PrecomputedAnalysis<'_>,
        work: &mut [u32],
    ) -> Result<(), Error> {
        let size = pre.size;
        if size.n != a.n() || size.nnz_a != a.nnz() {
            return Err(Error::Precomputed {
                problem: PrecomputedProblem::Matrix,
            });
        }
        self.check_capacity(&size)?;
        ensure_len(
            work,
            check_work_len(size.n, size.nnz_a),
            Resource::Workspace,
        )?;
        pre.check(a, work)?;
        // Checked: every array has the length its size says, and the sizes fit the capacity.
        let n = size.n;
        let supernodes = pre.supernodes();
        for (dst, src) in [
            (&mut self.perm[..n], pre.perm),
            (&mut self.iperm[..n], &work[..n]),
            (&mut self.etree[..n], pre.etree),
            (&mut self.c_ptr[..n + 1], pre.c_ptr),
            (&mut self.c_row[..size.nnz_a], pre.c_row),
            (&mut self.c_src[..size.nnz_a], pre.c_src),
            (&mut self.c_dst[..size.nnz_a], pre.c_dst),
            (&mut self.l_ptr[..n + 1], pre.l_ptr),
            (&mut self.l_row[..size.nnz_l], pre.l_row),
            (&mut self.lt_ptr[..n + 1], pre.lt_ptr),
            (&mut self.lt_col[..size.nnz_l], pre.lt_col),
            (&mut self.sn_ptr[..supernodes + 1], pre.sn_ptr),
            (&mut self.col_sn[..n], pre.col_sn),
        ] {
            dst.copy_from_slice(src);
        }
        self.size = size;
        self.supernodes = supernodes;
        self.factor_flops = factor_flops(pre.l_ptr);
        Ok(())
    }

    /// The current analysis as a [`PrecomputedAnalysis`] (checksum included), for code
    /// generation: [`Symbolic::load`] takes it back.
    pub fn precomputed(&self) -> PrecomputedAnalysis<'_> {
        let mut pre = PrecomputedAnalysis {
            size: self.size,
            perm: self.perm(),
            etree: self.etree(),
            c_ptr: self.c_ptr(),
            c_row: self.c_row(),
            c_src: self.c_src(),
            c_dst: self.c_dst(),
            l_ptr: self.l_ptr(),
            l_row: self.l_row(),
            lt_ptr: self.lt_ptr(),
            lt_col: self.lt_col(),
            sn_ptr: self.sn_ptr(),
            col_sn: self.col_sn(),
            checksum: 0,
        };
        pre.checksum = pre.compute_checksum();
        pre
    }

    /// `Err(Capacity)` naming the first of the unknowns, matrix entries and factor entries of
    /// `size` that exceeds the storage.
    fn check_capacity(&self, size: &SymbolicSize) -> Result<(), Error> {
        let cap = self.capacity;
        for (resource, needed, available) in [
            (Resource::Unknowns, size.n, cap.n),
            (Resource::MatrixEntries, size.nnz_a, cap.nnz_a),
            (Resource::FactorEntries, size.nnz_l, cap.nnz_l),
        ] {
            if needed > available {
                return Err(Error::Capacity {
                    resource,
                    needed,
                    available,
                });
            }
        }
        Ok(())
    }

    /// The sizes of the current analysis.
    pub fn size_info(&self) -> SymbolicSize {
        self.size
    }
    /// The largest sizes the storage holds.
    pub fn capacity(&self) -> SymbolicSize {
        self.capacity
    }
    /// Dimension.
    pub fn n(&self) -> usize {
        self.size.n
    }
    /// Entries of the strictly lower triangle of `L`.
    pub fn nnz_l(&self) -> usize {
        self.size.nnz_l
    }
    /// `perm[k]` is the column of `A` that comes `k`-th.
    pub fn perm(&self) -> &[u32] {
        &self.perm[..self.size.n]
    }
    /// Inverse permutation: `iperm[perm[k]] == k`.
    pub fn iperm(&self) -> &[u32] {
        &self.iperm[..self.size.n]
    }
    /// Parent of each column in the elimination tree of `C` ([`NONE`] for a root).
    pub fn etree(&self) -> &[u32] {
        &self.etree[..self.size.n]
    }
    /// Column pointers of `L` (`n + 1`).
    pub fn l_ptr(&self) -> &[u32] {
        &self.l_ptr[..self.size.n + 1]
    }
    /// Row indices of `L`, column by column, increasing.
    pub fn l_row(&self) -> &[u32] {
        &self.l_row[..self.size.nnz_l]
    }
    /// Row pointers of `L` (`n + 1`).
    pub fn lt_ptr(&self) -> &[u32] {
        &self.lt_ptr[..self.size.n + 1]
    }
    /// Column indices of `L`, row by row, increasing.
    pub fn lt_col(&self) -> &[u32] {
        &self.lt_col[..self.size.nnz_l]
    }
    /// Upper pattern of `C = P A Pᵀ`: column pointers.
    pub fn c_ptr(&self) -> &[u32] {
        &self.c_ptr[..self.size.n + 1]
    }
    /// Upper pattern of `C`: row indices, increasing per column.
    pub fn c_row(&self) -> &[u32] {
        &self.c_row[..self.size.nnz_a]
    }
    /// For each entry of `C`, the position of its value in `A`'s value array.
    pub fn c_src(&self) -> &[u32] {
        &self.c_src[..self.size.nnz_a]
    }
    /// For each entry of `C` (in [`Symbolic::c_row`] order), the position of its value in
    /// `L`'s values ([`Symbolic::l_row`] order), or [`NONE`] for a diagonal entry.
    pub fn c_dst(&self) -> &[u32] {
        &self.c_dst[..self.size.nnz_a]
    }
    /// Number of supernodes.
    pub fn supernodes(&self) -> usize {
        self.supernodes
    }
    /// First column of each supernode, then `n` (`supernodes() + 1` entries, increasing).
    pub fn sn_ptr(&self) -> &[u32] {
        &self.sn_ptr[..self.supernodes + 1]
    }
    /// The supernode each column belongs to.
    pub fn col_sn(&self) -> &[u32] {
        &self.col_sn[..self.size.n]
    }
    /// Multiply-adds (and divisions) of one numeric factorization: a data-independent count.
    pub fn factor_flops(&self) -> u64 {
        self.factor_flops
    }
    /// Multiply-adds of one solve (forward, diagonal and backward).
    pub fn solve_flops(&self) -> u64 {
        2 * self.size.nnz_l as u64 + self.size.n as u64
    }
}

/// Multiply-adds (and divisions) of the up-looking numeric factorization with the column
/// pointers `l_ptr` of `L`: row k of column j costs one multiply-add per entry of column j
/// above row k.
fn factor_flops(l_ptr: &[u32]) -> u64 {
    l_ptr
        .windows(2)
        .map(|w| {
            let c = u64::from(w[1] - w[0]);
            c * c.saturating_sub(1) / 2 + 2 * c
        })
        .sum()
}

/// Supernodes from the elimination tree and the column pointers of `L`: column `j` continues
/// the supernode of `j − 1` when `j` is the parent of `j − 1` and `|L(:, j−1)| = |L(:, j)| + 1`
/// (then `struct(L(:, j−1)) = {j} ∪ struct(L(:, j))`). Writes the first column of each
/// supernode (then `n`) into `sn_ptr` (`n + 1`) and the supernode of each column into `col_sn`
/// (`n`); returns their number.
fn find_supernodes(etree: &[u32], l_ptr: &[u32], sn_ptr: &mut [u32], col_sn: &mut [u32]) -> usize {
    let count = |j: usize| l_ptr[j + 1] - l_ptr[j];
    let mut s = 0usize;
    for j in 0..etree.len() {
        let continues = j > 0 && ux(etree[j - 1]) == j && count(j - 1) == count(j) + 1;
        if !continues {
            sn_ptr[s] = j as u32;
            s += 1;
        }
        col_sn[j] = (s - 1) as u32;
    }
    sn_ptr[s] = etree.len() as u32;
    s
}

/// Writes the inverse of `perm` into `iperm` (same length), checking that `perm` is one.
fn invert_permutation(perm: &[u32], iperm: &mut [u32]) -> Result<(), Error> {
    let n = iperm.len();
    ensure_exact_len(perm, n, Resource::Permutation)?;
    iperm.fill(NONE);
    for (k, &p) in perm.iter().enumerate() {
        let slot = iperm.get_mut(ux(p)).ok_or(Error::IndexOutOfRange {
            resource: Resource::Permutation,
            position: k,
            index: ux(p),
            bound: n,
        })?;
        if *slot != NONE {
            return Err(Error::NotAPermutation { position: k });
        }
        *slot = k as u32;
    }
    Ok(())
}

/// The upper pattern of `C = P A Pᵀ`, rows sorted per column, with the source position of each
/// entry in `A`. `work` needs `n` entries.
fn permute_upper(
    a: &UpperCsc<'_>,
    iperm: &[u32],
    c_ptr: &mut [u32],
    c_row: &mut [u32],
    c_src: &mut [u32],
    work: &mut [u32],
) -> Result<(), Error> {
    let n = a.n();
    let count = work;
    count.fill(0);
    for j in 0..n {
        for &i in &a.row_idx()[a.column_range(j)] {
            let col = iperm[ux(i)].max(iperm[j]);
            count[ux(col)] += 1;
        }
    }
    c_ptr[0] = 0;
    for k in 0..n {
        c_ptr[k + 1] = c_ptr[k] + count[k];
        count[k] = c_ptr[k];
    }
    for j in 0..n {
        for p in a.column_range(j) {
            let (ci, cj) = (iperm[ux(a.row_idx()[p])], iperm[j]);
            let (row, col) = (ci.min(cj), ci.max(cj));
            let at = ux(count[ux(col)]);
            c_row[at] = row;
            c_src[at] = p as u32;
            count[ux(col)] += 1;
        }
    }
    // Sort each column by row, moving the source positions along: columns are short (a few
    // dozen entries for a tetrahedral mesh), so an insertion sort in place is the simple choice.
    for k in 0..n {
        let (s, e) = (ux(c_ptr[k]), ux(c_ptr[k + 1]));
        for x in s + 1..e {
            let (r, src) = (c_row[x], c_src[x]);
            let mut y = x;
            while y > s && c_row[y - 1] > r {
                c_row[y] = c_row[y - 1];
                c_src[y] = c_src[y - 1];
                y -= 1;
            }
            c_row[y] = r;
            c_src[y] = src;
        }
    }
    Ok(())
}

/// Elimination tree of the matrix with upper pattern `(c_ptr, c_row)` (Liu's algorithm with
/// path compression); `ancestor` is `n` entries of scratch.
fn elimination_tree(c_ptr: &[u32], c_row: &[u32], parent: &mut [u32], ancestor: &mut [u32]) {
    let n = parent.len();
    for k in 0..n {
        parent[k] = NONE;
        ancestor[k] = NONE;
        for &r in &c_row[ux(c_ptr[k])..ux(c_ptr[k + 1])] {
            let mut i = r;
            while i != NONE && ux(i) < k {
                let next = ancestor[ux(i)];
                ancestor[ux(i)] = k as u32;
                if next == NONE {
                    parent[ux(i)] = k as u32;
                }
                i = next;
            }
        }
    }
}

/// Column counts of `L` (strictly lower) into `col_count`, and, if asked, row pointers of `L`
/// into `row_ptr` (`n + 1`), by walking the row subtrees of the elimination tree.
fn row_and_column_counts(
    c_ptr: &[u32],
    c_row: &[u32],
    parent: &[u32],
    mark: &mut [u32],
    col_count: &mut [u32],
    mut row_ptr: Option<&mut [u32]>,
) -> Result<(), Error> {
    let n = parent.len();
    col_count.fill(0);
    mark.fill(NONE);
    let mut total: usize = 0;
    if let Some(rp) = row_ptr.as_deref_mut() {
        rp[0] = 0;
    }
    for k in 0..n {
        mark[k] = k as u32;
        for &r in &c_row[ux(c_ptr[k])..ux(c_ptr[k + 1])] {
            let mut i = r;
            while i != NONE && mark[ux(i)] != k as u32 {
                col_count[ux(i)] += 1;
                total += 1;
                mark[ux(i)] = k as u32;
                i = parent[ux(i)];
            }
        }
        if total > MAX_INDEX {
            return Err(Error::Pattern {
                column: k,
                problem: PatternProblem::TooLarge,
            });
        }
        if let Some(rp) = row_ptr.as_deref_mut() {
            rp[k + 1] = total as u32;
        }
    }
    Ok(())
}
