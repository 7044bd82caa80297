//! A symbolic analysis computed ahead of time (by `incise codegen`, from the same mesh) and
//! checked, not recomputed, on the device: a firmware build then links neither the ordering
//! nor the analysis ([`crate::Model::from_precomputed`]).
//!
//! The check is linear in the factor's entries and needs no ordering or analysis code. It
//! proves what the numeric phase relies on: every index in range and every list sorted; the
//! permuted pattern `C` is exactly `P A Pᵀ` of the matrix it is loaded for; the pattern of `L`
//! holds every entry of `C` and is closed under elimination (each column's pattern, less its
//! parent, is in its parent's), so the numeric factorization never reaches outside it and gives
//! the factor of `A` whatever ordering was chosen; the row and column patterns of `L` are each
//! other's transpose; and the supernodes are the ones the analysis would find. A checksum over
//! the arrays ([`PrecomputedAnalysis::compute_checksum`]) catches generated data that was
//! damaged or edited by hand.

use super::pattern::UpperCsc;
use super::symbolic::SymbolicSize;
use super::{NONE, ux};
use crate::error::{Error, PrecomputedProblem, Resource};
use crate::storage::Slab;

/// The arrays of a [`super::Symbolic`] analysis, borrowed (from `static` data in a firmware
/// build). [`super::Symbolic::precomputed`] exports one; [`super::Symbolic::load`] checks one and
/// takes it in. The inverse permutation is not stored: loading derives it, which also proves
/// `perm` is a permutation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrecomputedAnalysis<'p> {
    /// Dimension, stored entries of `A`, entries of `L`.
    pub size: SymbolicSize,
    /// `perm[k]`: the column of `A` that comes `k`-th (`n`).
    pub perm: &'p [u32],
    /// Parent of each column in the elimination tree, [`NONE`] for a root (`n`).
    pub etree: &'p [u32],
    /// Column pointers of the upper pattern of `C = P A Pᵀ` (`n + 1`).
    pub c_ptr: &'p [u32],
    /// Its row indices (`nnz_a`).
    pub c_row: &'p [u32],
    /// Per entry of `C`, the position of its value in `A` (`nnz_a`).
    pub c_src: &'p [u32],
    /// Per entry of `C`, the position of its value in `L`, [`NONE`] on the diagonal (`nnz_a`).
    pub c_dst: &'p [u32],
    /// Column pointers of `L` (`n + 1`).
    pub l_ptr: &'p [u32],
    /// Row indices of `L`, column by column (`nnz_l`).
    pub l_row: &'p [u32],
    /// Row pointers of `L` (`n + 1`).
    pub lt_ptr: &'p [u32],
    /// Column indices of `L`, row by row (`nnz_l`).
    pub lt_col: &'p [u32],
    /// First column of each supernode, then `n` (supernodes + 1).
    pub sn_ptr: &'p [u32],
    /// Supernode of each column (`n`).
    pub col_sn: &'p [u32],
    /// [`PrecomputedAnalysis::compute_checksum`] of the above, as generated.
    pub checksum: u64,
}

/// Length of the `u32` workspace [`super::Symbolic::load`] needs: at most
/// [`super::analyse_work_len`], which a model's workspace holds anyway.
pub const fn check_work_len(n: usize, nnz_a: usize) -> usize {
    crate::storage::sum(&[crate::storage::times(2, n), crate::storage::times(2, nnz_a)])
}

const fn problem(problem: PrecomputedProblem) -> Error {
    Error::Precomputed { problem }
}

/// `x.get(i)` as a `usize`, or the structure error.
fn at(x: &[u32], i: usize) -> Result<usize, Error> {
    x.get(i)
        .map(|&v| ux(v))
        .ok_or(problem(PrecomputedProblem::Structure))
}

/// The entries `ptr[j]..ptr[j + 1]` of `idx`.
fn column<'x>(ptr: &[u32], idx: &'x [u32], j: usize) -> Result<&'x [u32], Error> {
    idx.get(at(ptr, j)?..at(ptr, j + 1)?)
        .ok_or(problem(PrecomputedProblem::Structure))
}

/// Column pointers: `len + 1` of them from 0 to `total`, never decreasing.
fn check_pointers(ptr: &[u32], total: usize) -> Result<(), Error> {
    let ok = ptr.first() == Some(&0)
        && ptr.last().map(|&v| ux(v)) == Some(total)
        && ptr.windows(2).all(|w| matches!(w, [a, b] if a <= b));
    if ok {
        Ok(())
    } else {
        Err(problem(PrecomputedProblem::Structure))
    }
}

/// Strictly increasing, every entry in `low..high`.
fn sorted_within(list: &[u32], low: usize, high: usize) -> bool {
    list.windows(2).all(|w| matches!(w, [a, b] if a < b))
        && list.first().is_none_or(|&v| ux(v) >= low)
        && list.last().is_none_or(|&v| ux(v) < high)
}

impl PrecomputedAnalysis<'_> {
    /// FNV-1a over the sizes and every array, in declaration order.
    pub fn compute_checksum(&self) -> u64 {
        let mut h = crate::storage::Fingerprint::new();
        let s = self.size;
        for v in [s.n, s.nnz_a, s.nnz_l] {
            h.words(&[v as u32, (v as u64 >> 32) as u32]);
        }
        for array in self.arrays() {
            h.words(&[array.len() as u32]);
            h.words(array);
        }
        h.finish()
    }

    fn arrays(&self) -> [&[u32]; 12] {
        [
            self.perm,
            self.etree,
            self.c_ptr,
            self.c_row,
            self.c_src,
            self.c_dst,
            self.l_ptr,
            self.l_row,
            self.lt_ptr,
            self.lt_col,
            self.sn_ptr,
            self.col_sn,
        ]
    }

    /// Number of supernodes.
    pub fn supernodes(&self) -> usize {
        self.sn_ptr.len().saturating_sub(1)
    }

    /// Checks the analysis against `a` (see the module documentation) and writes the inverse
    /// permutation into the first `n` entries of `work` ([`check_work_len`]).
    ///
    /// # Errors
    /// [`Error::Precomputed`] naming what does not hold; [`Error::Capacity`] for a short
    /// `work`.
    pub(crate) fn check(&self, a: &UpperCsc<'_>, work: &mut [u32]) -> Result<(), Error> {
        let SymbolicSize { n, nnz_a, nnz_l } = self.size;
        if n != a.n() || nnz_a != a.nnz() {
            return Err(problem(PrecomputedProblem::Matrix));
        }
        let lengths = [
            (self.perm.len(), n),
            (self.etree.len(), n),
            (self.c_ptr.len(), n + 1),
            (self.c_row.len(), nnz_a),
            (self.c_src.len(), nnz_a),
            (self.c_dst.len(), nnz_a),
            (self.l_ptr.len(), n + 1),
            (self.l_row.len(), nnz_l),
            (self.lt_ptr.len(), n + 1),
            (self.lt_col.len(), nnz_l),
            (self.col_sn.len(), n),
        ];
        if lengths.iter().any(|(found, expected)| found != expected) || self.sn_ptr.is_empty() {
            return Err(problem(PrecomputedProblem::Lengths));
        }
        if self.compute_checksum() != self.checksum {
            return Err(problem(PrecomputedProblem::Checksum));
        }
        let mut slab = Slab::new(work, Resource::Workspace);
        let iperm = slab.take(n)?;
        let mark = slab.take(n)?;
        let a_col = slab.take(nnz_a)?;
        let used = slab.take(nnz_a)?;

        // The permutation, inverted.
        iperm.fill(NONE);
        for (k, &p) in self.perm.iter().enumerate() {
            match iperm.get_mut(ux(p)) {
                Some(slot) if *slot == NONE => *slot = k as u32,
                _ => return Err(problem(PrecomputedProblem::Structure)),
            }
        }
        check_pointers(self.c_ptr, nnz_a)?;
        check_pointers(self.l_ptr, nnz_l)?;
        check_pointers(self.lt_ptr, nnz_l)?;
        check_pointers(self.sn_ptr, n)?;

        // C is P A Pᵀ: each entry of A is the source of exactly one entry of C, at the
        // permuted place.
        for j in 0..n {
            for p in a.column_range(j) {
                *a_col
                    .get_mut(p)
                    .ok_or(problem(PrecomputedProblem::Structure))? = j as u32;
            }
        }
        used.fill(0);
        for k in 0..n {
            let rows = column(self.c_ptr, self.c_row, k)?;
            if !sorted_within(rows, 0, k + 1) {
                return Err(problem(PrecomputedProblem::Structure));
            }
            let start = at(self.c_ptr, k)?;
            for (q, &r) in (start..).zip(rows) {
                let src = at(self.c_src, q)?;
                let seen = used
                    .get_mut(src)
                    .ok_or(problem(PrecomputedProblem::Structure))?;
                if *seen != 0 {
                    return Err(problem(PrecomputedProblem::Matrix));
                }
                *seen = 1;
                let (i, j) = (at(a.row_idx(), src)?, at(a_col, src)?);
                let (pr, pk) = (at(self.perm, ux(r))?, at(self.perm, k)?);
                if !((pr == i && pk == j) || (pr == j && pk == i)) {
                    return Err(problem(PrecomputedProblem::Matrix));
                }
                // Where C(r, k) lands in L: L(k, r) in column r, or nowhere on the diagonal.
                let dst = *self
                    .c_dst
                    .get(q)
                    .ok_or(problem(PrecomputedProblem::Structure))?;
                let lands = if ux(r) == k {
                    dst == NONE
                } else {
                    let col = at(self.l_ptr, ux(r))?..at(self.l_ptr, ux(r) + 1)?;
                    col.contains(&ux(dst)) && at(self.l_row, ux(dst))? == k
                };
                if !lands {
                    return Err(problem(PrecomputedProblem::Structure));
                }
            }
        }

        // L's columns: sorted below the diagonal, the first row is the parent in the tree, and
        // the rest lies in the parent's column (closed under elimination). `mark[r] == j` while
        // column j is checked: row r is in its parent's column.
        mark.fill(NONE);
        for j in 0..n {
            let rows = column(self.l_ptr, self.l_row, j)?;
            if !sorted_within(rows, j + 1, n) {
                return Err(problem(PrecomputedProblem::Structure));
            }
            let parent = *self
                .etree
                .get(j)
                .ok_or(problem(PrecomputedProblem::Structure))?;
            let Some((&first, rest)) = rows.split_first() else {
                if parent != NONE {
                    return Err(problem(PrecomputedProblem::Structure));
                }
                continue;
            };
            if parent != first {
                return Err(problem(PrecomputedProblem::Structure));
            }
            for &r in column(self.l_ptr, self.l_row, ux(parent))? {
                *mark
                    .get_mut(ux(r))
                    .ok_or(problem(PrecomputedProblem::Structure))? = j as u32;
            }
            if rest.iter().any(|&r| mark.get(ux(r)) != Some(&(j as u32))) {
                return Err(problem(PrecomputedProblem::Fill));
            }
        }

        // L's rows are the transpose of its columns: walking the rows in order meets each
        // column's rows in order.
        for (cursor, &p) in mark.iter_mut().zip(self.l_ptr) {
            *cursor = p;
        }
        for k in 0..n {
            let cols = column(self.lt_ptr, self.lt_col, k)?;
            if !sorted_within(cols, 0, k) {
                return Err(problem(PrecomputedProblem::Structure));
            }
            for &j in cols {
                let cursor = mark
                    .get_mut(ux(j))
                    .ok_or(problem(PrecomputedProblem::Structure))?;
                if ux(*cursor) >= at(self.l_ptr, ux(j) + 1)? || at(self.l_row, ux(*cursor))? != k {
                    return Err(problem(PrecomputedProblem::Structure));
                }
                *cursor += 1;
            }
        }
        for j in 0..n {
            if mark.get(j).map(|&c| ux(c)) != Some(at(self.l_ptr, j + 1)?) {
                return Err(problem(PrecomputedProblem::Structure));
            }
        }

        // Supernodes: column j continues the one of j − 1 exactly when j is its parent and
        // their columns nest (one entry fewer).
        let count = |j: usize| -> Result<usize, Error> {
            Ok(at(self.l_ptr, j + 1)?.saturating_sub(at(self.l_ptr, j)?))
        };
        let mut s = 0usize;
        for j in 0..n {
            let continues = j > 0
                && at(self.etree, j - 1)? == j
                && count(j - 1)? == count(j)?.saturating_add(1);
            if !continues {
                if at(self.sn_ptr, s)? != j {
                    return Err(problem(PrecomputedProblem::Structure));
                }
                s += 1;
            }
            if at(self.col_sn, j)?.saturating_add(1) != s {
                return Err(problem(PrecomputedProblem::Structure));
            }
        }
        if s != self.supernodes() {
            return Err(problem(PrecomputedProblem::Structure));
        }
        Ok(())
    }
}
