//! The numeric phase: up-looking LDLᵀ over a stored pattern, and the solves.

use super::pattern::UpperCsc;
use super::supernodal;
use super::symbolic::{Symbolic, SymbolicSize};
use super::ux;
use crate::error::{Error, Resource};
use crate::real::Real;
use crate::storage::{Slab, ensure_exact_len, ensure_len, sum, times};

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
        self.active.map(|(a, s)| &self.l[a][..s.nnz_l])
    }

    /// Diagonal `D` in service (permuted order).
    pub fn d_values(&self) -> Option<&[T]> {
        self.active.map(|(a, s)| &self.d[a][..s.n])
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
    /// [`Error::Length`] / [`Error::Capacity`] for wrong buffer lengths. On any error the
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
        ensure_len(work, n, Resource::Workspace)?;
        ensure_len(cursor, n, Resource::Workspace)?;
        let target = self.spare_set();
        let outcome = up_looking(
            sym,
            a_values,
            &mut self.l[target][..],
            &mut self.d[target][..],
            &mut work[..n],
            &mut cursor[..n],
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
    pub fn factorize_supernodal<V: Real>(
        &mut self,
        sym: &Symbolic<'_>,
        a_values: &[V],
        work: &mut [T],
        iwork: &mut [u32],
    ) -> Result<(), Error> {
        let size = self.check_sizes(sym, a_values)?;
        let target = self.spare_set();
        let outcome = supernodal::factorize(
            sym,
            a_values,
            &mut self.l[target][..size.nnz_l],
            &mut self.d[target][..size.n],
            work,
            iwork,
        );
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
        Ok((&self.l[a][..size.nnz_l], &self.d[a][..size.n]))
    }

    /// Solves `L w = w` in place (permuted order).
    ///
    /// # Errors
    /// [`Error::NotFactored`], [`Error::SymbolicMismatch`], or [`Error::Length`] if `w` does
    /// not have `n` entries.
    pub fn solve_lower_in_place(&self, sym: &Symbolic<'_>, w: &mut [T]) -> Result<(), Error> {
        let (l, _) = self.in_service(sym, w)?;
        let (l_ptr, l_row) = (sym.l_ptr(), sym.l_row());
        for j in 0..sym.n() {
            let wj = w[j];
            let cols = ux(l_ptr[j])..ux(l_ptr[j + 1]);
            for (&r, &lv) in l_row[cols.clone()].iter().zip(&l[cols]) {
                w[ux(r)] -= lv * wj;
            }
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
        for j in (0..sym.n()).rev() {
            let mut wj = w[j];
            let cols = ux(l_ptr[j])..ux(l_ptr[j + 1]);
            for (&r, &lv) in l_row[cols.clone()].iter().zip(&l[cols]) {
                wj -= lv * w[ux(r)];
            }
            w[j] = wj;
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
    pub fn solve_in_place(
        &self,
        sym: &Symbolic<'_>,
        b: &mut [T],
        work: &mut [T],
    ) -> Result<(), Error> {
        self.in_service(sym, b)?;
        let n = sym.n();
        ensure_len(work, n, Resource::Workspace)?;
        let w = &mut work[..n];
        for (wk, &p) in w.iter_mut().zip(sym.perm()) {
            *wk = b[ux(p)];
        }
        let (l, d) = self.in_service(sym, b)?;
        supernodal::solve(sym, l, d, w, b);
        for (&wk, &p) in w.iter().zip(sym.perm()) {
            b[ux(p)] = wk;
        }
        Ok(())
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
    pub fn solve_converting<V: Real>(
        &self,
        sym: &Symbolic<'_>,
        b: &mut [V],
        work: &mut [T],
    ) -> Result<(), Error> {
        let (l, d) = self.in_service(sym, b)?;
        let n = sym.n();
        ensure_len(work, times(2, n), Resource::Workspace)?;
        let (w, tmp) = work.split_at_mut(n);
        for (wk, &p) in w.iter_mut().zip(sym.perm()) {
            *wk = T::of(b[ux(p)].to_f64());
        }
        supernodal::solve(sym, l, d, w, &mut tmp[..n]);
        for (&wk, &p) in w.iter().zip(sym.perm()) {
            b[ux(p)] = V::of(wk.to_f64());
        }
        Ok(())
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
    cursor.copy_from_slice(&sym.l_ptr()[..n]);
    let (c_ptr, c_row, c_src) = (sym.c_ptr(), sym.c_row(), sym.c_src());
    let (l_ptr, l_row, lt_ptr, lt_col) = (sym.l_ptr(), sym.l_row(), sym.lt_ptr(), sym.lt_col());
    for k in 0..n {
        // Row k of L solves L(0..k, 0..k) D y = C(0..k, k): scatter column k of C, then
        // eliminate along the stored row pattern (increasing columns are a topological
        // order of the elimination tree).
        for q in ux(c_ptr[k])..ux(c_ptr[k + 1]) {
            y[ux(c_row[q])] += T::of(a_values[ux(c_src[q])].to_f64());
        }
        let mut dk = y[k];
        y[k] = T::zero();
        for &i in &lt_col[ux(lt_ptr[k])..ux(lt_ptr[k + 1])] {
            let i = ux(i);
            let yi = y[i];
            y[i] = T::zero();
            let (start, end) = (ux(l_ptr[i]), ux(cursor[i]));
            for (&r, &lv) in l_row[start..end].iter().zip(&l[start..end]) {
                y[ux(r)] -= lv * yi;
            }
            let lki = yi / d[i];
            dk -= lki * yi;
            l[end] = lki;
            cursor[i] += 1;
        }
        if !dk.finite() {
            return Err(Error::NotFinite { column: k });
        }
        if dk <= T::zero() {
            return Err(Error::NotPositiveDefinite { column: k });
        }
        d[k] = dk;
    }
    Ok(())
}

/// `y = A x` for a symmetric `A` stored as its upper triangle.
///
/// # Errors
/// [`Error::Length`] if a slice does not match the pattern.
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
    for j in 0..a.n() {
        for p in a.column_range(j) {
            let i = ux(a.row_idx()[p]);
            y[i] += values[p] * x[j];
            if i != j {
                y[j] += values[p] * x[i];
            }
        }
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
    ensure_len(work, a.n(), Resource::Workspace)?;
    let ax = &mut work[..a.n()];
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
