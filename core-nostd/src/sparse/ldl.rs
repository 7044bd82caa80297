//! The numeric phase: up-looking LDLᵀ over a stored pattern, and the solves.

use super::pattern::UpperCsc;
use super::supernodal;
use super::symbolic::{Symbolic, SymbolicSize};
use super::ux;
use crate::error::{Error, Resource};
use crate::real::Real;
use crate::storage::{
    Slab, copy_front, ensure_exact_len, ensure_len, prefix, prefix_mut, sum, times,
};

/// The numeric factor `C = L D Lᵀ` of `C = P A Pᵀ`, `L` unit lower triangular (its strictly lower
/// part stored in the column pattern of a [`Symbolic`]) and `D` diagonal and positive.
///
/// The storage is sized for a capacity (any analysis up to it can be factored, so a factor
/// survives a change of pattern) and holds two sets of values: a factorization writes the set
/// not in service and puts it in service only when it succeeds, so a failed factorization
/// leaves the previous factor usable. Memory: `2 · (nnz(L) + n)` scalars of the capacity
/// ([`LdlFactor::storage_len`]).
#[derive(Debug)]
pub struct LdlFactor<'a, T> {
    capacity: SymbolicSize,
    l: [&'a mut [T]; 2],
    d: [&'a mut [T]; 2],
    /// The value set in service and the sizes of the analysis it was computed for.
    active: Option<(usize, SymbolicSize)>,
    /// The factor in service at [`LdlFactor::checkpoint`], kept until the checkpoint ends.
    checkpoint: Option<Option<(usize, SymbolicSize)>>,
}

impl<'a, T: Real> LdlFactor<'a, T> {
    /// Scalars of storage a factor of capacity `size` needs.
    pub const fn storage_len(size: &SymbolicSize) -> usize {
        times(2, sum(&[size.nnz_l, size.n]))
    }

    /// An empty factor (nothing in service yet) in `storage`, for analyses up to `capacity`.
    ///
    /// # Errors
    /// [`Error::Capacity`] if `storage` is shorter than [`LdlFactor::storage_len`].
    pub fn new(capacity: &SymbolicSize, storage: &'a mut [T]) -> Result<Self, Error> {
        ensure_len(storage, Self::storage_len(capacity), Resource::RealStorage)?;
        let mut slab = Slab::new(storage, Resource::RealStorage);
        let l0 = slab.take(capacity.nnz_l)?;
        let l1 = slab.take(capacity.nnz_l)?;
        let d0 = slab.take(capacity.n)?;
        let d1 = slab.take(capacity.n)?;
        Ok(LdlFactor {
            capacity: *capacity,
            l: [l0, l1],
            d: [d0, d1],
            active: None,
            checkpoint: None,
        })
    }

    /// Keeps the factor now in service, unchanged, until [`LdlFactor::commit`] or
    /// [`LdlFactor::rollback`]: factorizations in between write only the other value set (each
    /// one in service once it succeeds), so that a caller running several factorizations (the
    /// Newton steps of a frame) can give the factor back as it was when the whole fails. A
    /// factorization that fails inside a checkpoint puts the checkpoint's factor back in
    /// service. Costs nothing: the two value sets exist anyway.
    pub fn checkpoint(&mut self) {
        self.checkpoint = Some(self.active);
    }

    /// Ends a checkpoint and keeps the factor in service.
    pub fn commit(&mut self) {
        self.checkpoint = None;
    }

    /// Ends a checkpoint and puts its factor back in service, bit for bit (nothing has written
    /// its value set since). Without a checkpoint, nothing happens.
    pub fn rollback(&mut self) {
        if let Some(active) = self.checkpoint.take() {
            self.active = active;
        }
    }

    /// Whether a successful factorization is in service.
    pub fn is_factored(&self) -> bool {
        self.active.is_some()
    }

    /// Strictly lower values of `L` in service, in the order of [`Symbolic::l_row`].
    pub fn l_values(&self) -> Option<&[T]> {
        // A size goes into service only after it was checked against the capacity, which the
        // value sets hold: the prefix exists whenever a factor is in service.
        self.active
            .and_then(|(a, s)| pick(&self.l, a).get(..s.nnz_l))
    }

    /// Diagonal `D` in service (permuted order).
    pub fn d_values(&self) -> Option<&[T]> {
        // As in `l_values`: the prefix exists whenever a factor is in service.
        self.active.and_then(|(a, s)| pick(&self.d, a).get(..s.n))
    }

    /// Scalars of workspace [`LdlFactor::factorize_supernodal`] needs, whatever the matrix.
    pub const SUPERNODAL_WORK_LEN: usize = supernodal::REAL_WORK_LEN;

    /// Indices of workspace [`LdlFactor::factorize_supernodal`] needs for `n` unknowns.
    pub const fn supernodal_index_work_len(n: usize) -> usize {
        supernodal::index_work_len(n)
    }

    /// Factorizes `A` (values `a_values` in the order of the pattern the symbolic analysis was
    /// built from, in any scalar type: rounded to the factor's, so that an `f32` factor can be
    /// computed from an `f64` matrix) column by column (up-looking). `work` needs `n` scalars and `cursor` `n`
    /// indices; they have no meaning on return. The cost is [`Symbolic::factor_flops`],
    /// independent of the values. [`LdlFactor::factorize_supernodal`] computes the same factor
    /// faster on all but the smallest matrices.
    ///
    /// # Errors
    /// [`Error::NotPositiveDefinite`] or [`Error::NotFinite`] naming the first failing column
    /// of the permuted matrix; [`Error::Capacity`] naming [`Resource::FactorEntries`] or
    /// [`Resource::Unknowns`] if `sym` is larger than this factor's capacity;
    /// [`Error::Length`] / [`Error::Capacity`] for wrong buffer lengths;
    /// [`Error::IndexOutOfRange`] if the analysis held an index outside its sizes (its
    /// invariants rule this out). On any error the
    /// factor in service (if any) stays in service, unchanged; inside a
    /// [`LdlFactor::checkpoint`], the checkpoint's factor is in service again.
    pub fn factorize<V: Real>(
        &mut self,
        sym: &Symbolic<'_>,
        a_values: &[V],
        work: &mut [T],
        cursor: &mut [u32],
    ) -> Result<(), Error> {
        let size = self.check_sizes(sym, a_values)?;
        let n = size.n;
        let work = prefix_mut(work, n, Resource::Workspace)?;
        let cursor = prefix_mut(cursor, n, Resource::Workspace)?;
        let target = self.spare_set();
        let outcome = up_looking(
            sym,
            a_values,
            pick_mut(&mut self.l, target),
            pick_mut(&mut self.d, target),
            work,
            cursor,
        );
        self.settle(outcome, target, size)
    }

    /// Factorizes `A` as [`LdlFactor::factorize`] does, supernode by supernode (left-looking,
    /// dense register-blocked kernels on the supernodes' panels), into the same storage and
    /// layout, so the solves and [`LdlFactor::l_values`] serve either. `work` needs
    /// [`LdlFactor::SUPERNODAL_WORK_LEN`] scalars and `iwork`
    /// [`LdlFactor::supernodal_index_work_len`]`(n)` indices; they have no meaning on return.
    /// The arithmetic is [`Symbolic::factor_flops`] multiply-adds plus a bounded overhead of
    /// packing and padded tiles, independent of the values.
    ///
    /// # Errors
    /// As [`LdlFactor::factorize`]; on any error the factor in service (if any) stays in
    /// service, unchanged; inside a [`LdlFactor::checkpoint`], the checkpoint's factor is in
    /// service again.
    // Out of line (a few calls per frame) so that profilers and the stage split of
    // `benches/cut_event.rs` can tell it from the Newton loop around it.
    #[inline(never)]
    pub fn factorize_supernodal<V: Real>(
        &mut self,
        sym: &Symbolic<'_>,
        a_values: &[V],
        work: &mut [T],
        iwork: &mut [u32],
    ) -> Result<(), Error> {
        let size = self.check_sizes(sym, a_values)?;
        let target = self.spare_set();
        // `check_sizes` has held the sizes to the capacity, which the value sets hold.
        let l = prefix_mut(
            pick_mut(&mut self.l, target),
            size.nnz_l,
            Resource::FactorEntries,
        )?;
        let d = prefix_mut(pick_mut(&mut self.d, target), size.n, Resource::Unknowns)?;
        let outcome = supernodal::factorize(sym, a_values, l, d, work, iwork);
        self.settle(outcome, target, size)
    }

    /// Checks `sym` against the capacity and `a_values` against `sym`.
    fn check_sizes<V>(&self, sym: &Symbolic<'_>, a_values: &[V]) -> Result<SymbolicSize, Error> {
        let size = sym.size_info();
        for (resource, needed, available) in [
            (Resource::Unknowns, size.n, self.capacity.n),
            (Resource::FactorEntries, size.nnz_l, self.capacity.nnz_l),
        ] {
            if needed > available {
                return Err(Error::Capacity {
                    resource,
                    needed,
                    available,
                });
            }
        }
        ensure_exact_len(a_values, size.nnz_a, Resource::MatrixEntries)?;
        Ok(size)
    }

    /// The value set not in service, which a factorization writes.
    /// Ends a factorization into value set `target`: on success its factor goes into service;
    /// on failure the one in service stays (inside a checkpoint: the checkpoint's).
    fn settle(
        &mut self,
        outcome: Result<(), Error>,
        target: usize,
        size: SymbolicSize,
    ) -> Result<(), Error> {
        match outcome {
            Ok(()) => {
                self.active = Some((target, size));
                Ok(())
            }
            Err(e) => {
                if let Some(active) = self.checkpoint {
                    self.active = active;
                }
                Err(e)
            }
        }
    }

    /// The value set a factorization writes: not the one in service, and never a
    /// checkpoint's.
    fn spare_set(&self) -> usize {
        let keep = match (self.checkpoint, self.active) {
            (Some(Some((set, _))), _) | (None, Some((set, _))) => Some(set),
            _ => None,
        };
        if keep == Some(0) { 1 } else { 0 }
    }

    fn in_service<V>(&self, sym: &Symbolic<'_>, v: &[V]) -> Result<(&[T], &[T]), Error> {
        let (a, size) = self.active.ok_or(Error::NotFactored)?;
        if sym.size_info() != size {
            return Err(Error::SymbolicMismatch);
        }
        ensure_exact_len(v, size.n, Resource::Vector)?;
        // A size goes into service only after it was checked against the capacity, which the
        // value sets hold: neither prefix can be short.
        let l = prefix(pick(&self.l, a), size.nnz_l, Resource::FactorEntries)?;
        let d = prefix(pick(&self.d, a), size.n, Resource::Unknowns)?;
        Ok((l, d))
    }

    /// Solves `L w = w` in place (permuted order).
    ///
    /// # Errors
    /// [`Error::NotFactored`], [`Error::SymbolicMismatch`], or [`Error::Length`] if `w` does
    /// not have `n` entries, all before `w` is touched; [`Error::IndexOutOfRange`] if the
    /// analysis held an index outside its sizes (its invariants rule this out), with `w` then
    /// partly solved.
    pub fn solve_lower_in_place(&self, sym: &Symbolic<'_>, w: &mut [T]) -> Result<(), Error> {
        let (l, _) = self.in_service(sym, w)?;
        let (l_ptr, l_row) = (sym.l_ptr(), sym.l_row());
        let n = w.len();
        // The analysis's invariants (built by `Symbolic::analyse`, checked by `Symbolic::load`)
        // keep every index in range; were one outside, the error below names it.
        for j in 0..sym.n() {
            let wj = *w.get(j).ok_or(out_of_range(Resource::Unknowns, j, j, n))?;
            let (_, rows) = column(l_ptr, l_row, j)?;
            let (_, vals) = column(l_ptr, l, j)?;
            sub_scaled(w, rows, vals, wj)?;
        }
        Ok(())
    }

    /// Solves `D w = w` in place (permuted order).
    ///
    /// # Errors
    /// As [`LdlFactor::solve_lower_in_place`].
    pub fn solve_diagonal_in_place(&self, sym: &Symbolic<'_>, w: &mut [T]) -> Result<(), Error> {
        let (_, d) = self.in_service(sym, w)?;
        for (wj, &dj) in w.iter_mut().zip(d) {
            *wj /= dj;
        }
        Ok(())
    }

    /// Solves `Lᵀ w = w` in place (permuted order).
    ///
    /// # Errors
    /// As [`LdlFactor::solve_lower_in_place`].
    pub fn solve_upper_in_place(&self, sym: &Symbolic<'_>, w: &mut [T]) -> Result<(), Error> {
        let (l, _) = self.in_service(sym, w)?;
        let (l_ptr, l_row) = (sym.l_ptr(), sym.l_row());
        let n = w.len();
        // The analysis's invariants (built by `Symbolic::analyse`, checked by `Symbolic::load`)
        // keep every index in range; were one outside, the error below names it.
        for j in (0..sym.n()).rev() {
            let wj = *w.get(j).ok_or(out_of_range(Resource::Unknowns, j, j, n))?;
            let (_, rows) = column(l_ptr, l_row, j)?;
            let (_, vals) = column(l_ptr, l, j)?;
            let wj = sub_dot(wj, rows, vals, w)?;
            *w.get_mut(j)
                .ok_or(out_of_range(Resource::Unknowns, j, j, n))? = wj;
        }
        Ok(())
    }

    /// Solves `A x = b` in place (`b` becomes `x`, original order); `work` needs `n` scalars.
    /// Cost: [`Symbolic::solve_flops`]. The solves run supernode by supernode (dense kernels
    /// over the panels, `b` serving as their scratch), whichever factorization wrote the
    /// factor.
    ///
    /// # Errors
    /// As [`LdlFactor::solve_lower_in_place`], and [`Error::Capacity`] for a short `work`.
    // Out of line (a few calls per frame) so that profilers and the stage split of
    // `benches/cut_event.rs` can tell it from the Newton loop around it.
    #[inline(never)]
    pub fn solve_in_place(
        &self,
        sym: &Symbolic<'_>,
        b: &mut [T],
        work: &mut [T],
    ) -> Result<(), Error> {
        self.in_service(sym, b)?;
        let n = sym.n();
        let w = prefix_mut(work, n, Resource::Workspace)?;
        gather(w, sym.perm(), b, |v| v)?;
        let (l, d) = self.in_service(sym, b)?;
        supernodal::solve(sym, l, d, w, b)?;
        scatter(w, sym.perm(), b, |v| v)
    }

    /// Solves `A x = b` in place as [`LdlFactor::solve_in_place`] does, for a right-hand side in
    /// another scalar type `V` (mixed precision: an `f64` residual through an `f32` factor):
    /// `b` is rounded to the factor's type on the way in and widened on the way out, and the
    /// solves run in the factor's type in `work` (`2 n` scalars). With `V` the factor's own
    /// type the result is [`LdlFactor::solve_in_place`]'s, bit for bit.
    ///
    /// # Errors
    /// As [`LdlFactor::solve_in_place`], and [`Error::Capacity`] for a `work` shorter than
    /// `2 n`.
    // Out of line (a few calls per frame) so that profilers and the stage split of
    // `benches/cut_event.rs` can tell it from the Newton loop around it.
    #[inline(never)]
    pub fn solve_converting<V: Real>(
        &self,
        sym: &Symbolic<'_>,
        b: &mut [V],
        work: &mut [T],
    ) -> Result<(), Error> {
        let (l, d) = self.in_service(sym, b)?;
        let n = sym.n();
        ensure_len(work, times(2, n), Resource::Workspace)?;
        let mut slab = Slab::new(work, Resource::Workspace);
        let w = slab.take(n)?;
        let tmp = slab.take(n)?;
        gather(w, sym.perm(), b, |v| T::of(v.to_f64()))?;
        supernodal::solve(sym, l, d, w, tmp)?;
        scatter(w, sym.perm(), b, |v| V::of(v.to_f64()))
    }
}

/// The numeric loop of [`LdlFactor::factorize`] into one value set `l`, `d` (lengths checked by
/// the caller); `y` and `cursor` hold `n` entries of workspace.
fn up_looking<T: Real, V: Real>(
    sym: &Symbolic<'_>,
    a_values: &[V],
    l: &mut [T],
    d: &mut [T],
    y: &mut [T],
    cursor: &mut [u32],
) -> Result<(), Error> {
    let n = y.len();
    y.fill(T::zero());
    copy_front(cursor, sym.l_ptr(), n);
    let (c_ptr, c_row, c_src) = (sym.c_ptr(), sym.c_row(), sym.c_src());
    let (l_ptr, l_row, lt_ptr, lt_col) = (sym.l_ptr(), sym.l_row(), sym.lt_ptr(), sym.lt_col());
    // The analysis's invariants keep every index below in range (rows and columns below `n`,
    // pointers inside their lists, `l_ptr[i] <= cursor[i] < l_ptr[i + 1]` while row `k`
    // eliminates column `i`), and the caller has held `l` and `d` to the capacity. Were one
    // outside, the factorization stops with an error naming it, in the spare value set: the
    // factor in service is untouched.
    for k in 0..n {
        // Row k of L solves L(0..k, 0..k) D y = C(0..k, k): scatter column k of C, then
        // eliminate along the stored row pattern (increasing columns are a topological
        // order of the elimination tree).
        let (c_start, rows) = column(c_ptr, c_row, k)?;
        let (_, srcs) = column(c_ptr, c_src, k)?;
        for (q, (&r, &src)) in (c_start..).zip(rows.iter().zip(srcs)) {
            let &v = a_values.get(ux(src)).ok_or(out_of_range(
                Resource::MatrixEntries,
                q,
                ux(src),
                a_values.len(),
            ))?;
            let yr = y
                .get_mut(ux(r))
                .ok_or(out_of_range(Resource::Unknowns, q, ux(r), n))?;
            *yr += T::of(v.to_f64());
        }
        let yk = y
            .get_mut(k)
            .ok_or(out_of_range(Resource::Unknowns, k, k, n))?;
        let mut dk = core::mem::replace(yk, T::zero());
        let (lt_start, cols) = column(lt_ptr, lt_col, k)?;
        for (p, &i) in (lt_start..).zip(cols) {
            let i = ux(i);
            let bad_column = out_of_range(Resource::Unknowns, p, i, n);
            let yi = core::mem::replace(y.get_mut(i).ok_or(bad_column)?, T::zero());
            let &di = d.get(i).ok_or(bad_column)?;
            let &start = l_ptr.get(i).ok_or(bad_column)?;
            let cursor_i = cursor.get_mut(i).ok_or(bad_column)?;
            let (start, end) = (ux(start), ux(*cursor_i));
            // Column i's values computed so far, `l[start..end]`, and the slot `l[end]` of
            // the one row k adds.
            let bad_cursor = out_of_range(Resource::FactorEntries, i, end, l_row.len());
            let rows = l_row.get(start..end).ok_or(bad_cursor)?;
            let (lki_slot, vals) = l
                .get_mut(start..=end)
                .and_then(<[T]>::split_last_mut)
                .ok_or(bad_cursor)?;
            sub_scaled(y, rows, vals, yi)?;
            let lki = yi / di;
            dk -= lki * yi;
            *lki_slot = lki;
            *cursor_i += 1;
        }
        if !dk.finite() {
            return Err(Error::NotFinite { column: k });
        }
        if dk <= T::zero() {
            return Err(Error::NotPositiveDefinite { column: k });
        }
        let bad_diagonal = out_of_range(Resource::Unknowns, k, k, d.len());
        *d.get_mut(k).ok_or(bad_diagonal)? = dk;
    }
    Ok(())
}

/// `y = A x` for a symmetric `A` stored as its upper triangle.
///
/// # Errors
/// [`Error::Length`] if a slice does not match the pattern; [`Error::IndexOutOfRange`] for an
/// index outside it (the pattern's invariants rule this out), with `y` then partly computed.
// Kept out of line (it is called a few times per frame at most) so that profilers can tell
// the PCG products from the rest of the Newton loop.
#[inline(never)]
pub fn sym_matvec<T: Real>(
    a: &UpperCsc<'_>,
    values: &[T],
    x: &[T],
    y: &mut [T],
) -> Result<(), Error> {
    ensure_exact_len(values, a.nnz(), Resource::MatrixEntries)?;
    ensure_exact_len(x, a.n(), Resource::Vector)?;
    ensure_exact_len(y, a.n(), Resource::Vector)?;
    y.fill(T::zero());
    // The pattern's invariants keep every column inside `row_idx` (as long as `values`); were
    // an index outside, the error below names it.
    for (j, &xj) in x.iter().enumerate() {
        let (_, rows) = column(a.col_ptr(), a.row_idx(), j)?;
        let (_, vals) = column(a.col_ptr(), values, j)?;
        column_product(y, x, rows, vals, j, xj)?;
    }
    Ok(())
}

/// Relative residual `‖A x − b‖₂ / ‖b‖₂` (or the absolute residual when `b = 0`); `work` needs
/// `n` scalars.
///
/// # Errors
/// As [`sym_matvec`], and [`Error::Capacity`] for a short `work`.
pub fn relative_residual<T: Real>(
    a: &UpperCsc<'_>,
    values: &[T],
    x: &[T],
    b: &[T],
    work: &mut [T],
) -> Result<T, Error> {
    ensure_exact_len(b, a.n(), Resource::Vector)?;
    let ax = prefix_mut(work, a.n(), Resource::Workspace)?;
    sym_matvec(a, values, x, ax)?;
    let (mut r2, mut b2) = (T::zero(), T::zero());
    for (&axi, &bi) in ax.iter().zip(b) {
        r2 += (axi - bi) * (axi - bi);
        b2 += bi * bi;
    }
    Ok(if b2 > T::zero() {
        (r2 / b2).sqrt()
    } else {
        r2.sqrt()
    })
}

/// Value set `set` of a pair: the first for 0, the second otherwise (a set is only ever 0 or
/// 1).
fn pick<'s, T>(pair: &'s [&mut [T]; 2], set: usize) -> &'s [T] {
    let [first, second] = pair;
    if set == 0 { first } else { second }
}

/// Value set `set` of a pair, mutable, as [`pick`].
fn pick_mut<'s, T>(pair: &'s mut [&mut [T]; 2], set: usize) -> &'s mut [T] {
    let [first, second] = pair;
    if set == 0 { first } else { second }
}

/// `y[r] -= v · s` for the rows `r` and values `v` of one column of `L`, in order.
///
/// # Errors
/// [`Error::IndexOutOfRange`] naming the first row outside `y` (the analysis keeps every row
/// below `n`, so this is a broken invariant, reported rather than skipped). The rows in range
/// are still updated: the loop only notes a miss, because leaving the innermost loop of the
/// factorization and the solves early made the up-looking factorization 15 to 50 % slower.
fn sub_scaled<T: Real>(y: &mut [T], rows: &[u32], vals: &[T], s: T) -> Result<(), Error> {
    let mut missed = false;
    for (&r, &v) in rows.iter().zip(vals) {
        match y.get_mut(ux(r)) {
            Some(yr) => *yr -= v * s,
            None => missed = true,
        }
    }
    first_outside(missed, rows, y.len())
}

/// `s − Σ v · w[r]` over the rows `r` and values `v` of one column of `L`, subtracted in order.
///
/// # Errors
/// As [`sub_scaled`], for a row outside `w`.
fn sub_dot<T: Real>(mut s: T, rows: &[u32], vals: &[T], w: &[T]) -> Result<T, Error> {
    let mut missed = false;
    for (&r, &v) in rows.iter().zip(vals) {
        match w.get(ux(r)) {
            Some(&wr) => s -= v * wr,
            None => missed = true,
        }
    }
    first_outside(missed, rows, w.len()).map(|()| s)
}

/// Column `j` of a symmetric matrix's upper triangle (rows `rows`, values `vals`) applied to
/// `x`: `y[i] += v · x[j]` and, off the diagonal, `y[j] += v · x[i]`.
///
/// # Errors
/// As [`sub_scaled`], for a row outside `x` or `y` or a column `j` outside `y` (the pattern's
/// invariants keep every row at most `j`, below `n`).
fn column_product<T: Real>(
    y: &mut [T],
    x: &[T],
    rows: &[u32],
    vals: &[T],
    j: usize,
    xj: T,
) -> Result<(), Error> {
    let mut missed = false;
    for (&i, &v) in rows.iter().zip(vals) {
        let i = ux(i);
        match y.get_mut(i) {
            Some(yi) => *yi += v * xj,
            None => missed = true,
        }
        if i != j {
            match (x.get(i), y.get_mut(j)) {
                (Some(&xi), Some(yj)) => *yj += v * xi,
                _ => missed = true,
            }
        }
    }
    if missed && j >= y.len() {
        return Err(out_of_range(Resource::Unknowns, j, j, y.len()));
    }
    first_outside(missed, rows, x.len().min(y.len()))
}

/// `Ok` when nothing was `missed`; otherwise [`Error::IndexOutOfRange`] naming the first of
/// `rows` not below `bound` (found again here, off the hot path).
fn first_outside(missed: bool, rows: &[u32], bound: usize) -> Result<(), Error> {
    if !missed {
        return Ok(());
    }
    let (position, index) = rows
        .iter()
        .map(|&r| ux(r))
        .enumerate()
        .find(|&(_, r)| r >= bound)
        .unwrap_or((0, bound));
    Err(out_of_range(Resource::Unknowns, position, index, bound))
}

/// [`Error::IndexOutOfRange`]: `index` at `position` of its input, which must be below `bound`.
fn out_of_range(resource: Resource, position: usize, index: usize, bound: usize) -> Error {
    Error::IndexOutOfRange {
        resource,
        position,
        index,
        bound,
    }
}

/// Column (or row) `j` of a compressed pattern: the entries `ptr[j]..ptr[j + 1]` of `list`
/// (its indices, or values laid out as they are), with the position of the first.
///
/// # Errors
/// [`Error::IndexOutOfRange`] naming [`Resource::ColumnPointers`] if `ptr` has no entry
/// `j + 1`, or its entries `j` and `j + 1` decrease or leave `list`: the invariants of a
/// [`Symbolic`] or an [`UpperCsc`] rule all of this out.
fn column<'x, X>(ptr: &[u32], list: &'x [X], j: usize) -> Result<(usize, &'x [X]), Error> {
    let (Some(&start), Some(&end)) = (ptr.get(j), ptr.get(j + 1)) else {
        return Err(out_of_range(
            Resource::ColumnPointers,
            j + 1,
            j + 1,
            ptr.len(),
        ));
    };
    let (start, end) = (ux(start), ux(end));
    match list.get(start..end) {
        Some(entries) => Ok((start, entries)),
        // `ptr[j]` must not exceed `ptr[j + 1]`.
        None if start > end => Err(out_of_range(
            Resource::ColumnPointers,
            j,
            start,
            end.saturating_add(1),
        )),
        None => Err(out_of_range(
            Resource::ColumnPointers,
            j + 1,
            end,
            list.len().saturating_add(1),
        )),
    }
}

/// `w[k] = convert(b[perm[k]])`: the right-hand side in the permuted order.
///
/// # Errors
/// [`Error::IndexOutOfRange`] naming [`Resource::Permutation`] for an entry of `perm` outside
/// `b`: the analysis's permutation, checked when it was built, rules it out.
fn gather<T, V: Copy>(
    w: &mut [T],
    perm: &[u32],
    b: &[V],
    convert: impl Fn(V) -> T,
) -> Result<(), Error> {
    for (k, (wk, &p)) in w.iter_mut().zip(perm).enumerate() {
        let &v = b
            .get(ux(p))
            .ok_or(out_of_range(Resource::Permutation, k, ux(p), b.len()))?;
        *wk = convert(v);
    }
    Ok(())
}

/// `b[perm[k]] = convert(w[k])`: the solution back in the original order.
///
/// # Errors
/// [`Error::IndexOutOfRange`] naming [`Resource::Permutation`] for an entry of `perm` outside
/// `b` ([`gather`] has found every one in range before; nothing is skipped unsaid).
fn scatter<T: Copy, V>(
    w: &[T],
    perm: &[u32],
    b: &mut [V],
    convert: impl Fn(T) -> V,
) -> Result<(), Error> {
    let n = b.len();
    for (k, (&wk, &p)) in w.iter().zip(perm).enumerate() {
        let bp = b
            .get_mut(ux(p))
            .ok_or(out_of_range(Resource::Permutation, k, ux(p), n))?;
        *bp = convert(wk);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    // The analysis keeps these rows in range, so the public API cannot reach a miss: the
    // kernels are called directly with a row outside the vector, which must be reported (with
    // the row and its position), not skipped.

    #[test]
    fn sub_scaled_reports_a_row_outside() {
        let mut y = [1.0, 1.0, 1.0];
        let err = sub_scaled(&mut y, &[0, 5, 2], &[1.0, 1.0, 1.0], 2.0);
        assert_eq!(
            err,
            Err(out_of_range(Resource::Unknowns, 1, 5, 3)),
            "the missed row is named"
        );
        assert_eq!(y, [-1.0, 1.0, -1.0], "the rows in range are updated");
        assert_eq!(sub_scaled(&mut y, &[1], &[1.0], 1.0), Ok(()));
    }

    #[test]
    fn sub_dot_reports_a_row_outside() {
        let w = [1.0, 2.0];
        assert_eq!(sub_dot(10.0, &[0, 1], &[1.0, 1.0], &w), Ok(7.0));
        assert_eq!(
            sub_dot(10.0, &[1, 2], &[1.0, 1.0], &w),
            Err(out_of_range(Resource::Unknowns, 1, 2, 2))
        );
    }

    #[test]
    fn column_product_reports_a_row_outside() {
        let (x, mut y) = ([1.0, 2.0], [0.0, 0.0]);
        assert_eq!(
            column_product(&mut y, &x, &[0, 1], &[3.0, 4.0], 1, 2.0),
            Ok(())
        );
        assert_eq!(y, [6.0, 4.0 * 2.0 + 3.0 * 1.0]);
        assert_eq!(
            column_product(&mut y, &x, &[0, 3], &[1.0, 1.0], 1, 2.0),
            Err(out_of_range(Resource::Unknowns, 1, 3, 2))
        );
    }

    #[test]
    fn scatter_reports_a_permutation_entry_outside() {
        let mut b = [0.0; 2];
        assert_eq!(scatter(&[1.0, 2.0], &[1, 0], &mut b, |v| v), Ok(()));
        assert_eq!(b, [2.0, 1.0]);
        assert_eq!(
            scatter(&[1.0, 2.0], &[1, 4], &mut b, |v| v),
            Err(out_of_range(Resource::Permutation, 1, 4, 2))
        );
    }
}
