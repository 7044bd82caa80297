//! The symbolic phase: permuted pattern, elimination tree, column counts and the row and column
//! patterns of the factor `L`, computed once per pattern.

use super::pattern::{MAX_INDEX, UpperCsc};
use super::precomputed::{PrecomputedAnalysis, check_work_len};
use super::{NONE, ux};
use crate::error::{Error, PatternProblem, PrecomputedProblem, Resource};
use crate::storage::{Slab, ensure_exact_len, ensure_len, prefix, prefix_mut, sum, times};

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
/// It also partitions the columns into *supernodes*: runs of consecutive columns `f, f+1, …,
/// f+w−1`, each the parent of the one before in the elimination tree, whose patterns nest,
/// `struct(L(:, j)) = {j+1} ∪ struct(L(:, j+1))` (Liu, Ng and Peyton's supernodes, without the
/// one-child condition of fundamental ones, which a left-looking factorization does not
/// need). The supernodes are *relaxed*, as CHOLMOD's and faer's are: where a chain of the
/// tree runs over consecutive columns (an ordering from [`super::fill_reducing_order`] is
/// postordered, so it does), small supernodes are merged while the explicit zeros this adds
/// stay a small share of the merged panel. `L`'s stored pattern then holds
/// those zeros: it is still closed under elimination, with the same elimination tree, so the
/// column-by-column factorization and the solves work on it unchanged and compute exact zeros
/// there, while the supernodal one ([`crate::sparse::LdlFactor::factorize_supernodal`]) gets
/// wider panels for its dense kernels. [`Symbolic::size`] counts the stored entries,
/// [`Symbolic::exact_nnz_l`] the factor's own. A supernode's row list is its first column's,
/// `f` and then [`Symbolic::l_row`] of column `f`; its columns are stored one after the other
/// in `L`'s column layout, so the supernodal factorization writes exactly the values the
/// column-by-column one does, and needs no storage beyond `nnz(L) + n`. For each entry of `C`
/// the analysis also stores where it lands in `L` ([`Symbolic::c_dst`]), so the numeric phase
/// loads `C` into `L` in one pass.
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
        Self::counted(a, perm, work, true)
    }

    /// The entries of the strictly lower factor of `A` under `perm`, without the explicit zeros
    /// of relaxed supernodes that [`Symbolic::size`] counts: the ordering's fill. `work` as
    /// there.
    ///
    /// # Errors
    /// As [`Symbolic::size`].
    pub fn exact_nnz_l(a: &UpperCsc<'_>, perm: &[u32], work: &mut [u32]) -> Result<usize, Error> {
        Ok(Self::counted(a, perm, work, false)?.nnz_l)
    }

    /// [`Symbolic::size`], the counts relaxed or not.
    fn counted(
        a: &UpperCsc<'_>,
        perm: &[u32],
        work: &mut [u32],
        relax: bool,
    ) -> Result<SymbolicSize, Error> {
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
        if relax {
            relax_counts(parent, counts);
        }
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
        // Each pointer array holds `capacity.n + 1 >= 1` entries, so none is skipped.
        for ptr in [
            &mut sym.c_ptr,
            &mut sym.l_ptr,
            &mut sym.lt_ptr,
            &mut sym.sn_ptr,
        ] {
            if let Some(first) = ptr.first_mut() {
                *first = 0;
            }
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
    /// capacity. (Every index into the arrays the analysis builds is checked as well, with
    /// [`Error::IndexOutOfRange`] or [`Error::Capacity`]; once `A` and `perm` have passed, none
    /// of those checks fails.)
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
        // The storage was sized for the capacity, which `size` fits: no prefix below is short.
        let (perm_s, iperm, etree) = (
            live_mut(self.perm, n)?,
            live_mut(self.iperm, n)?,
            live_mut(self.etree, n)?,
        );
        let (c_ptr, c_row, c_src) = (
            live_mut(self.c_ptr, n + 1)?,
            live_mut(self.c_row, size.nnz_a)?,
            live_mut(self.c_src, size.nnz_a)?,
        );
        let (l_ptr, l_row, lt_ptr, lt_col) = (
            live_mut(self.l_ptr, n + 1)?,
            live_mut(self.l_row, size.nnz_l)?,
            live_mut(self.lt_ptr, n + 1)?,
            live_mut(self.lt_col, size.nnz_l)?,
        );
        let (c_dst, sn_ptr, col_sn) = (
            live_mut(self.c_dst, size.nnz_a)?,
            live_mut(self.sn_ptr, n + 1)?,
            live_mut(self.col_sn, n)?,
        );
        // `Symbolic::size` checked that `perm` has `n` entries.
        perm_s.copy_from_slice(perm);
        invert_permutation(perm, iperm)?;

        let mut wslab = Slab::new(work, Resource::Workspace);
        let mark = wslab.take(n)?;
        let col_count = wslab.take(n)?;
        let relaxed = wslab.take(n)?;
        permute_upper(a, iperm, c_ptr, c_row, c_src, mark)?;
        elimination_tree(c_ptr, c_row, etree, mark);
        row_and_column_counts(c_ptr, c_row, etree, mark, col_count, Some(lt_ptr))?;
        relaxed.copy_from_slice(col_count);
        relax_counts(etree, relaxed);
        let merged = relaxed != col_count;

        // The exact pattern first: column pointers from the exact counts, the row patterns
        // (sorted) by walking the elimination tree from each entry of `C`, then the column
        // patterns by scattering rows in increasing order, so every column comes out sorted
        // too. Row k's walks fill its slots `lt_ptr[k]..lt_ptr[k + 1]` exactly, as they did
        // when they were counted. The storage holds the relaxed pattern, which is no smaller.
        column_pointers(col_count, l_ptr);
        for (k, ((cs, ce), (ls, le))) in pairs(c_ptr).zip(pairs(lt_ptr)).enumerate() {
            let row = segment_mut(lt_col, ls, le, k, Resource::FactorEntries)?;
            let mut slots = row.iter_mut();
            *at_mut(mark, k, k)? = k as u32;
            for &r in segment(c_row, cs, ce, k, Resource::MatrixEntries)? {
                let mut i = r;
                while i != NONE {
                    let seen = at_mut(mark, ux(i), k)?;
                    if *seen == k as u32 {
                        break;
                    }
                    *seen = k as u32;
                    *slots.next().ok_or(Error::Capacity {
                        resource: Resource::FactorEntries,
                        needed: le - ls + 1,
                        available: le - ls,
                    })? = i;
                    i = at(etree, ux(i), k)?;
                }
            }
            row.sort_unstable();
        }
        let mut places = Places {
            c_ptr,
            c_row,
            c_dst,
        };
        columns_from_rows(&mut places, lt_ptr, lt_col, l_ptr, l_row, col_count, mark)?;
        // Then the relaxed pattern, where supernodes were merged ([`relax_counts`]): the
        // columns moved to their relaxed places, those of a merged supernode given its rows,
        // and the row patterns and the places of `C` redone from them.
        let supernodes = if merged {
            // `col_count` now holds where each exact column ends.
            column_pointers(relaxed, l_ptr);
            let supernodes = find_supernodes(etree, l_ptr, sn_ptr, col_sn);
            relax_columns(l_ptr, l_row, col_count, sn_ptr, col_sn)?;
            rows_from_columns(l_ptr, l_row, lt_ptr, lt_col, mark)?;
            columns_from_rows(&mut places, lt_ptr, lt_col, l_ptr, l_row, col_count, mark)?;
            supernodes
        } else {
            find_supernodes(etree, l_ptr, sn_ptr, col_sn)
        };
        let flops = factor_flops(l_ptr);
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
        // The whole array is built, every prefix taken, before anything is copied.
        for (dst, src) in [
            (live_mut(self.perm, n)?, pre.perm),
            (
                live_mut(self.iperm, n)?,
                prefix(work, n, Resource::Workspace)?,
            ),
            (live_mut(self.etree, n)?, pre.etree),
            (live_mut(self.c_ptr, n + 1)?, pre.c_ptr),
            (live_mut(self.c_row, size.nnz_a)?, pre.c_row),
            (live_mut(self.c_src, size.nnz_a)?, pre.c_src),
            (live_mut(self.c_dst, size.nnz_a)?, pre.c_dst),
            (live_mut(self.l_ptr, n + 1)?, pre.l_ptr),
            (live_mut(self.l_row, size.nnz_l)?, pre.l_row),
            (live_mut(self.lt_ptr, n + 1)?, pre.lt_ptr),
            (live_mut(self.lt_col, size.nnz_l)?, pre.lt_col),
            (live_mut(self.sn_ptr, supernodes + 1)?, pre.sn_ptr),
            (live_mut(self.col_sn, n)?, pre.col_sn),
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
    /// Entries stored for the strictly lower triangle of `L` (the explicit zeros of relaxed
    /// supernodes included).
    pub fn nnz_l(&self) -> usize {
        self.size.nnz_l
    }
    /// `perm[k]` is the column of `A` that comes `k`-th.
    pub fn perm(&self) -> &[u32] {
        live(self.perm, self.size.n)
    }
    /// Inverse permutation: `iperm[perm[k]] == k`.
    pub fn iperm(&self) -> &[u32] {
        live(self.iperm, self.size.n)
    }
    /// Parent of each column in the elimination tree of `C` ([`NONE`] for a root).
    pub fn etree(&self) -> &[u32] {
        live(self.etree, self.size.n)
    }
    /// Column pointers of `L` (`n + 1`).
    pub fn l_ptr(&self) -> &[u32] {
        live(self.l_ptr, self.size.n + 1)
    }
    /// Row indices of `L`, column by column, increasing.
    pub fn l_row(&self) -> &[u32] {
        live(self.l_row, self.size.nnz_l)
    }
    /// Row pointers of `L` (`n + 1`).
    pub fn lt_ptr(&self) -> &[u32] {
        live(self.lt_ptr, self.size.n + 1)
    }
    /// Column indices of `L`, row by row, increasing.
    pub fn lt_col(&self) -> &[u32] {
        live(self.lt_col, self.size.nnz_l)
    }
    /// Upper pattern of `C = P A Pᵀ`: column pointers.
    pub fn c_ptr(&self) -> &[u32] {
        live(self.c_ptr, self.size.n + 1)
    }
    /// Upper pattern of `C`: row indices, increasing per column.
    pub fn c_row(&self) -> &[u32] {
        live(self.c_row, self.size.nnz_a)
    }
    /// For each entry of `C`, the position of its value in `A`'s value array.
    pub fn c_src(&self) -> &[u32] {
        live(self.c_src, self.size.nnz_a)
    }
    /// For each entry of `C` (in [`Symbolic::c_row`] order), the position of its value in
    /// `L`'s values ([`Symbolic::l_row`] order), or [`NONE`] for a diagonal entry.
    pub fn c_dst(&self) -> &[u32] {
        live(self.c_dst, self.size.nnz_a)
    }
    /// Number of supernodes.
    pub fn supernodes(&self) -> usize {
        self.supernodes
    }
    /// First column of each supernode, then `n` (`supernodes() + 1` entries, increasing).
    pub fn sn_ptr(&self) -> &[u32] {
        live(self.sn_ptr, self.supernodes + 1)
    }
    /// The supernode each column belongs to.
    pub fn col_sn(&self) -> &[u32] {
        live(self.col_sn, self.size.n)
    }
    /// Multiply-adds (and divisions) of one numeric factorization over the stored pattern (the
    /// explicit zeros included: the kernels multiply them too): a data-independent count.
    pub fn factor_flops(&self) -> u64 {
        self.factor_flops
    }
    /// Multiply-adds of one solve (forward, diagonal and backward).
    pub fn solve_flops(&self) -> u64 {
        2 * self.size.nnz_l as u64 + self.size.n as u64
    }
}

/// The first `len` entries of an array of the analysis. An analysis is recorded only once its
/// sizes have passed [`Symbolic::check_capacity`], and every array was sized for the capacity,
/// so the prefix always exists; the empty fallback is never taken.
fn live(array: &[u32], len: usize) -> &[u32] {
    array.get(..len).unwrap_or_default()
}

/// The first `len` entries of an array of the analysis, mutable, or [`Error::Capacity`] naming
/// [`Resource::IndexStorage`] (never, once the sizes passed [`Symbolic::check_capacity`]).
fn live_mut(array: &mut [u32], len: usize) -> Result<&mut [u32], Error> {
    prefix_mut(array, len, Resource::IndexStorage)
}

/// The consecutive pairs `(ptr[k], ptr[k + 1])` of a pointer array, as `usize`.
fn pairs(ptr: &[u32]) -> impl Iterator<Item = (usize, usize)> + '_ {
    ptr.iter()
        .zip(ptr.iter().skip(1))
        .map(|(&s, &e)| (ux(s), ux(e)))
}

/// The entries `idx[start..end]` of column (or row) `k`, or [`Error::IndexOutOfRange`] naming
/// `resource` if the pointers do not delimit a part of `idx`.
fn segment(
    idx: &[u32],
    start: usize,
    end: usize,
    k: usize,
    resource: Resource,
) -> Result<&[u32], Error> {
    let bound = idx.len();
    idx.get(start..end).ok_or(Error::IndexOutOfRange {
        resource,
        position: k,
        index: end,
        bound,
    })
}

/// [`segment`], mutable.
fn segment_mut(
    idx: &mut [u32],
    start: usize,
    end: usize,
    k: usize,
    resource: Resource,
) -> Result<&mut [u32], Error> {
    let bound = idx.len();
    idx.get_mut(start..end).ok_or(Error::IndexOutOfRange {
        resource,
        position: k,
        index: end,
        bound,
    })
}

/// `x[i]`, read while column `k` is processed, or [`Error::IndexOutOfRange`] naming
/// [`Resource::Unknowns`]: `x` is indexed by a row or column of `C`.
fn at(x: &[u32], i: usize, k: usize) -> Result<u32, Error> {
    x.get(i).copied().ok_or(Error::IndexOutOfRange {
        resource: Resource::Unknowns,
        position: k,
        index: i,
        bound: x.len(),
    })
}

/// [`at`], mutable.
fn at_mut(x: &mut [u32], i: usize, k: usize) -> Result<&mut u32, Error> {
    let bound = x.len();
    x.get_mut(i).ok_or(Error::IndexOutOfRange {
        resource: Resource::Unknowns,
        position: k,
        index: i,
        bound,
    })
}

/// Column pointers (`n + 1`) from column counts (`n`).
fn column_pointers(counts: &[u32], ptr: &mut [u32]) {
    if let Some((first, rest)) = ptr.split_first_mut() {
        *first = 0;
        let mut start = 0;
        for (end, &count) in rest.iter_mut().zip(counts) {
            *end = start + count;
            start = *end;
        }
    }
}

/// The upper pattern of `C` and, per entry, where its value lands in `L`
/// ([`Symbolic::c_dst`]), which [`columns_from_rows`] writes.
struct Places<'p> {
    c_ptr: &'p [u32],
    c_row: &'p [u32],
    c_dst: &'p mut [u32],
}

/// The column patterns of `L` (`l_row`, under `l_ptr`) from its row patterns (`lt_ptr`,
/// `lt_col`), and where each entry `C(j, k)` (`j < k`, that is `L(k, j)`) lands in `L`. Row
/// `k`'s entries are placed in increasing column order, so every column comes out sorted;
/// `cursor` (`n`) ends with where each column ends, and `mark[j]` keeps the place of
/// `L(k, j)` while row `k` is open.
///
/// # Errors
/// [`Error::IndexOutOfRange`] for an index outside the lists (never for the analysis's own).
fn columns_from_rows(
    places: &mut Places<'_>,
    lt_ptr: &[u32],
    lt_col: &[u32],
    l_ptr: &[u32],
    l_row: &mut [u32],
    cursor: &mut [u32],
    mark: &mut [u32],
) -> Result<(), Error> {
    for (c, &start) in cursor.iter_mut().zip(l_ptr.iter()) {
        *c = start;
    }
    let nnz_l = l_row.len();
    for (k, ((cs, ce), (ls, le))) in pairs(places.c_ptr).zip(pairs(lt_ptr)).enumerate() {
        for &j in segment(lt_col, ls, le, k, Resource::FactorEntries)? {
            let j = ux(j);
            let c = at_mut(cursor, j, k)?;
            let place = *c;
            *c += 1;
            *at_mut(mark, j, k)? = place;
            *l_row.get_mut(ux(place)).ok_or(Error::IndexOutOfRange {
                resource: Resource::FactorEntries,
                position: k,
                index: ux(place),
                bound: nnz_l,
            })? = k as u32;
        }
        let rows = segment(places.c_row, cs, ce, k, Resource::MatrixEntries)?;
        let dsts = segment_mut(places.c_dst, cs, ce, k, Resource::MatrixEntries)?;
        for (dst, &j) in dsts.iter_mut().zip(rows) {
            *dst = if ux(j) == k {
                NONE
            } else {
                at(mark, ux(j), k)?
            };
        }
    }
    Ok(())
}

/// The row patterns of `L` (`lt_ptr`, `lt_col`) as the transpose of its column patterns,
/// columns in increasing order within each row; `count` (`n`) is workspace.
///
/// # Errors
/// [`Error::IndexOutOfRange`] for an index outside the lists (never for the analysis's own).
fn rows_from_columns(
    l_ptr: &[u32],
    l_row: &[u32],
    lt_ptr: &mut [u32],
    lt_col: &mut [u32],
    count: &mut [u32],
) -> Result<(), Error> {
    count.fill(0);
    for (j, (s, e)) in pairs(l_ptr).enumerate() {
        for &r in segment(l_row, s, e, j, Resource::FactorEntries)? {
            *at_mut(count, ux(r), j)? += 1;
        }
    }
    column_pointers(count, lt_ptr);
    for (c, &start) in count.iter_mut().zip(lt_ptr.iter()) {
        *c = start;
    }
    for (j, (s, e)) in pairs(l_ptr).enumerate() {
        for &r in segment(l_row, s, e, j, Resource::FactorEntries)? {
            let c = at_mut(count, ux(r), j)?;
            *at_mut(lt_col, ux(*c), j)? = j as u32;
            *c += 1;
        }
    }
    Ok(())
}

/// Widths up to which a chain of supernodes is merged whatever explicit zeros it adds, and
/// up to which it is merged while the zeros stay below a share of the merged panel: the
/// thresholds of CHOLMOD's relaxed amalgamation (`nrelax`, `zrelax`), which serve its
/// supernodal factorization on meshes like ours.
const RELAX_ALWAYS: u64 = 4;
const RELAX_WIDTHS: [u64; 2] = [16, 48];
/// Zero shares (per mille) allowed up to each of [`RELAX_WIDTHS`], and beyond.
const RELAX_ZEROS_PER_MILLE: [u64; 3] = [800, 100, 50];

/// Relaxed supernodes: the column counts of `L` (exact on entry) raised to those of merged
/// supernodes. Scanning the columns in order, a supernode is merged into the next one when
/// that one's first column is the parent of its last (a chain in the elimination tree, so
/// the merged columns nest: each takes the rows of the merged supernode below it), and the
/// merged panel is narrow or gains few explicit zeros ([`RELAX_ALWAYS`], [`RELAX_WIDTHS`],
/// [`RELAX_ZEROS_PER_MILLE`]). The pattern stays closed under elimination and the
/// elimination tree is unchanged, so every numeric phase works on it as on the exact one;
/// the factor's values there are exact zeros. Wider panels make the supernodal kernels' fixed
/// costs (packing, the scatter through relative rows) smaller per multiply-add.
///
/// Only a supernode's last column keeps its exact count, so a column's count within a
/// merged supernode `[f, e)` is `(e − 1 − j) + count(e − 1)`.
fn relax_counts(parent: &[u32], counts: &mut [u32]) {
    let n = counts.len();
    // The supernode being grown: columns `f..e`, its explicit zeros so far.
    let (mut f, mut e, mut zeros) = (0usize, 0usize, 0u64);
    let count = |counts: &[u32], j: usize| counts.get(j).map_or(0, |&c| u64::from(c));
    while e < n {
        // The fundamental supernode `e..next` ([`find_supernodes`]' rule on exact counts).
        let mut next = e + 1;
        while next < n
            && parent.get(next - 1).is_some_and(|&p| ux(p) == next)
            && count(counts, next - 1) == count(counts, next) + 1
        {
            next += 1;
        }
        // Merged when the next one's first column is the parent of the grown one's last.
        let chained = e > f && parent.get(e - 1).is_some_and(|&p| ux(p) == e);
        // Rows of the grown supernode and of the next (their columns and those below), and
        // the explicit zeros merging adds: each grown column gains `m − mc` rows (`m ≥ mc`,
        // the grown one's rows being in the next one's when the two chain).
        let (wc, wp) = ((e - f) as u64, (next - e) as u64);
        let last = |j: usize| count(counts, j.saturating_sub(1));
        let (mc, mp) = (wc + last(e), wp + last(next));
        let (w, m) = (wc + wp, wc + mp);
        let total = zeros.saturating_add(wc.saturating_mul(m.saturating_sub(mc)));
        let entries = w
            .saturating_mul(m)
            .saturating_sub(w.saturating_mul(w.saturating_sub(1)) / 2);
        let share_below =
            |per_mille: u64| total.saturating_mul(1000) < per_mille.saturating_mul(entries);
        let merge = chained
            && (w <= RELAX_ALWAYS
                || (w <= RELAX_WIDTHS[0] && share_below(RELAX_ZEROS_PER_MILLE[0]))
                || (w <= RELAX_WIDTHS[1] && share_below(RELAX_ZEROS_PER_MILLE[1]))
                || share_below(RELAX_ZEROS_PER_MILLE[2]));
        if merge {
            zeros = total;
        } else {
            finish_supernode(counts, f, e);
            f = e;
            zeros = 0;
        }
        e = next;
    }
    finish_supernode(counts, f, e);
}

/// Gives the columns of supernode `f..e` the counts of its nested pattern.
fn finish_supernode(counts: &mut [u32], f: usize, e: usize) {
    if e == 0 {
        return;
    }
    let last = counts.get(e - 1).copied().unwrap_or(0);
    if let Some(columns) = counts.get_mut(f..e) {
        for (above_last, c) in columns.iter_mut().rev().enumerate() {
            *c = last + above_last as u32;
        }
    }
}

/// Moves the exact column patterns of `L` (column `j` ending at `exact_end[j]` in `l_row`)
/// to the relaxed places `l_ptr`, and gives each column of a supernode whose pattern is not
/// exact the supernode's rows below it: `{j + 1, …, e − 1}` and the last column's pattern.
/// Columns are visited from the last: a relaxed place starts at or after the exact one, so
/// nothing not yet moved is overwritten.
///
/// # Errors
/// [`Error::IndexOutOfRange`] for an index outside the lists (never for the analysis's own).
fn relax_columns(
    l_ptr: &[u32],
    l_row: &mut [u32],
    exact_end: &[u32],
    sn_ptr: &[u32],
    col_sn: &[u32],
) -> Result<(), Error> {
    let outside = |j: usize, index: usize, bound: usize| Error::IndexOutOfRange {
        resource: Resource::FactorEntries,
        position: j,
        index,
        bound,
    };
    let n = col_sn.len();
    for j in (0..n).rev() {
        let start = ux(at(l_ptr, j, j)?);
        let end = ux(at(l_ptr, j + 1, j)?);
        let s = ux(at(col_sn, j, j)?);
        let last = ux(at(sn_ptr, s + 1, j)?) - 1;
        if j == last {
            let exact_start = if j == 0 {
                0
            } else {
                ux(at(exact_end, j - 1, j)?)
            };
            let exact_stop = ux(at(exact_end, j, j)?);
            if exact_stop - exact_start != end - start || end > l_row.len() {
                return Err(outside(j, end, l_row.len()));
            }
            l_row.copy_within(exact_start..exact_stop, start);
        } else {
            let inside = last - j;
            let below_start = ux(at(l_ptr, last, j)?);
            let below_end = ux(at(l_ptr, last + 1, j)?);
            if start + inside + (below_end - below_start) != end || below_end > l_row.len() {
                return Err(outside(j, end, l_row.len()));
            }
            for (slot, row) in l_row
                .get_mut(start..start + inside)
                .ok_or(outside(j, start + inside, 0))?
                .iter_mut()
                .zip(j + 1..)
            {
                *slot = row as u32;
            }
            l_row.copy_within(below_start..below_end, start + inside);
        }
    }
    Ok(())
}

/// Multiply-adds (and divisions) of the up-looking numeric factorization with the column
/// pointers `l_ptr` of `L`: row k of column j costs one multiply-add per entry of column j
/// above row k.
fn factor_flops(l_ptr: &[u32]) -> u64 {
    l_ptr
        .iter()
        .zip(l_ptr.iter().skip(1))
        .map(|(&start, &end)| {
            let c = u64::from(end - start);
            c * c.saturating_sub(1) / 2 + 2 * c
        })
        .sum()
}

/// Supernodes from the elimination tree and the column pointers of `L`: column `j` continues
/// the supernode of `j − 1` when `j` is the parent of `j − 1` and `|L(:, j−1)| = |L(:, j)| + 1`
/// (then `struct(L(:, j−1)) = {j} ∪ struct(L(:, j))`). Writes the first column of each
/// supernode (then `n`) into `sn_ptr` (`n + 1`) and the supernode of each column into `col_sn`
/// (`n`); returns their number.
///
/// The lengths above are the analysis's own (`l_ptr` has `n + 1` entries), so every column is
/// visited and no supernode start is dropped.
fn find_supernodes(etree: &[u32], l_ptr: &[u32], sn_ptr: &mut [u32], col_sn: &mut [u32]) -> usize {
    let counts = l_ptr.iter().zip(l_ptr.iter().skip(1)).map(|(&s, &e)| e - s);
    let mut starts = sn_ptr.iter_mut();
    let mut s = 0usize;
    // Parent and column count of column `j − 1`.
    let mut previous: Option<(u32, u32)> = None;
    for (j, ((sn, &parent), count)) in col_sn.iter_mut().zip(etree).zip(counts).enumerate() {
        let continues = matches!(previous, Some((p, c)) if ux(p) == j && c == count + 1);
        if !continues {
            if let Some(start) = starts.next() {
                *start = j as u32;
            }
            s += 1;
        }
        *sn = (s - 1) as u32;
        previous = Some((parent, count));
    }
    if let Some(end) = starts.next() {
        *end = etree.len() as u32;
    }
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
///
/// # Errors
/// [`Error::Length`] if `c_ptr` does not have `n + 1` entries, [`Error::IndexOutOfRange`] if
/// `iperm` is not a permutation of `0..n` or another buffer is shorter than stated (neither
/// happens in the analysis, which sizes the buffers and checks `iperm` first).
fn permute_upper(
    a: &UpperCsc<'_>,
    iperm: &[u32],
    c_ptr: &mut [u32],
    c_row: &mut [u32],
    c_src: &mut [u32],
    work: &mut [u32],
) -> Result<(), Error> {
    let n = a.n();
    ensure_exact_len(c_ptr, n + 1, Resource::ColumnPointers)?;
    let count = work;
    count.fill(0);
    // Entry `p` of `A`, in column `j`, goes to column `max(iperm[i], iperm[j])` of `C`, row
    // the other.
    let column = |j: usize| -> Result<&[u32], Error> {
        let range = a.column_range(j);
        segment(
            a.row_idx(),
            range.start,
            range.end,
            j,
            Resource::MatrixEntries,
        )
    };
    let place = |i: u32, j: usize| -> Result<(u32, u32), Error> {
        let (ci, cj) = (at(iperm, ux(i), j)?, at(iperm, j, j)?);
        Ok((ci.min(cj), ci.max(cj)))
    };
    for j in 0..n {
        for &i in column(j)? {
            let (_, col) = place(i, j)?;
            *at_mut(count, ux(col), j)? += 1;
        }
    }
    if let Some((first, rest)) = c_ptr.split_first_mut() {
        *first = 0;
        let mut start = 0;
        for (end, c) in rest.iter_mut().zip(count.iter_mut()) {
            *end = start + *c;
            *c = start;
            start = *end;
        }
    }
    for j in 0..n {
        for (p, &i) in a.column_range(j).zip(column(j)?) {
            let (row, col) = place(i, j)?;
            let cursor = at_mut(count, ux(col), j)?;
            let slot = ux(*cursor);
            *cursor += 1;
            let bound = c_row.len().min(c_src.len());
            let out_of_range = Error::IndexOutOfRange {
                resource: Resource::MatrixEntries,
                position: j,
                index: slot,
                bound,
            };
            *c_row.get_mut(slot).ok_or(out_of_range)? = row;
            *c_src.get_mut(slot).ok_or(out_of_range)? = p as u32;
        }
    }
    // Sort each column by row, moving the source positions along: columns are short (a few
    // dozen entries for a tetrahedral mesh), so an insertion sort in place is the simple choice.
    for (k, (s, e)) in pairs(c_ptr).enumerate() {
        let rows = segment_mut(c_row, s, e, k, Resource::MatrixEntries)?;
        let srcs = segment_mut(c_src, s, e, k, Resource::MatrixEntries)?;
        insertion_sort_by_row(rows, srcs);
    }
    Ok(())
}

/// Sorts `rows` increasing by insertion, applying the same moves to `srcs` (as long).
fn insertion_sort_by_row(rows: &mut [u32], srcs: &mut [u32]) {
    for x in 1..rows.len() {
        // Entry `x` moves down past the entries before it that are larger (the prefix is
        // sorted), and those move up one place. `x < rows.len() == srcs.len()`: every range
        // below exists.
        let Some((&r, sorted)) = rows.get(..=x).and_then(|run| run.split_last()) else {
            return;
        };
        let y = sorted.iter().rposition(|&v| v <= r).map_or(0, |q| q + 1);
        if let (Some(run), Some(src_run)) = (rows.get_mut(y..=x), srcs.get_mut(y..=x)) {
            run.rotate_right(1);
            src_run.rotate_right(1);
        }
    }
}

/// Elimination tree of the matrix with upper pattern `(c_ptr, c_row)` (Liu's algorithm with
/// path compression); `ancestor` is `n` entries of scratch.
///
/// The pattern is [`permute_upper`]'s: its pointers delimit `c_row` and its rows are below
/// `n`, so no column is skipped and every walk stays inside `parent` and `ancestor`.
fn elimination_tree(c_ptr: &[u32], c_row: &[u32], parent: &mut [u32], ancestor: &mut [u32]) {
    // Column k's walks only reach columns below k, which earlier iterations initialised, so
    // every entry can start as a root up front.
    parent.fill(NONE);
    ancestor.fill(NONE);
    for (k, (s, e)) in pairs(c_ptr).take(parent.len()).enumerate() {
        for &r in c_row.get(s..e).unwrap_or_default() {
            let mut i = r;
            while i != NONE
                && ux(i) < k
                && let Some(a) = ancestor.get_mut(ux(i))
            {
                let next = *a;
                *a = k as u32;
                if next == NONE
                    && let Some(p) = parent.get_mut(ux(i))
                {
                    *p = k as u32;
                }
                i = next;
            }
        }
    }
}

/// Column counts of `L` (strictly lower) into `col_count`, and, if asked, row pointers of `L`
/// into `row_ptr` (`n + 1`), by walking the row subtrees of the elimination tree.
///
/// # Errors
/// [`Error::Pattern`] with [`PatternProblem::TooLarge`] if `L` would not fit the `u32`
/// indices; [`Error::Length`] or [`Error::IndexOutOfRange`] if the pattern, the tree and the
/// buffers disagree on `n` (never for the analysis's own).
fn row_and_column_counts(
    c_ptr: &[u32],
    c_row: &[u32],
    parent: &[u32],
    mark: &mut [u32],
    col_count: &mut [u32],
    row_ptr: Option<&mut [u32]>,
) -> Result<(), Error> {
    let n = parent.len();
    ensure_exact_len(c_ptr, n + 1, Resource::ColumnPointers)?;
    col_count.fill(0);
    mark.fill(NONE);
    let mut total: usize = 0;
    // Row pointers: 0, then the running total after each row.
    let mut row_ends = row_ptr.and_then(|rp| {
        let (first, rest) = rp.split_first_mut()?;
        *first = 0;
        Some(rest.iter_mut())
    });
    for (k, (s, e)) in pairs(c_ptr).enumerate() {
        *at_mut(mark, k, k)? = k as u32;
        for &r in segment(c_row, s, e, k, Resource::MatrixEntries)? {
            let mut i = r;
            while i != NONE {
                let seen = at_mut(mark, ux(i), k)?;
                if *seen == k as u32 {
                    break;
                }
                *seen = k as u32;
                *at_mut(col_count, ux(i), k)? += 1;
                total += 1;
                i = at(parent, ux(i), k)?;
            }
        }
        if total > MAX_INDEX {
            return Err(Error::Pattern {
                column: k,
                problem: PatternProblem::TooLarge,
            });
        }
        if let Some(end) = row_ends.as_mut().and_then(Iterator::next) {
            *end = total as u32;
        }
    }
    Ok(())
}
