//! The supernodal numeric phase: a left-looking LDLᵀ over the supernodes of a [`Symbolic`]
//! analysis, with dense register-blocked kernels, and the triangular solves over the same
//! panels.
//!
//! **Layout.** A supernode `s` has columns `f .. f + w` and the row list `R = [f, f+1, …,
//! f+w−1, below…]` of `m` rows (its first column's pattern). Its values are the columns of `L`
//! in the column layout of the simplicial factor: column `f + c` holds the rows `R[c+1..m]`
//! contiguously from `l_ptr[f + c]`, so `L(R[i], f + c)` (for `i > c`) sits at
//! `l_ptr[f + c] + i − c − 1`, and the diagonal `D` lies apart. Every column of the panel is
//! thus one contiguous slice, the rows below the diagonal block at the same positions
//! `w..m` in each: the dense kernels read them as a column-major block whose leading dimension
//! changes from column to column.
//!
//! **Factorization.** For each supernode in order: load nothing (the caller has scattered `C`
//! into `L` and `D`), subtract the update of every descendant supernode that has rows in its
//! columns (found by linked lists keyed by the next supernode a descendant updates, as in
//! Ng and Peyton's left-looking method), then factor its own columns in blocks of [`NB`]: the
//! block is updated from the supernode's earlier columns by the same kernel, then factored
//! column by column. An update is the product `L_d(rows, k) · D_d · L_d(targets, k)ᵀ`, packed
//! into small fixed buffers ([`REAL_WORK_LEN`] scalars: blocks of [`MC`] rows and [`NC`]
//! target columns over [`KC`] source columns, the BLIS scheme) and computed by an
//! [`MR`] × [`NR`] micro-kernel whose accumulators stay in registers; it is subtracted from the
//! target through the rows' relative positions.

use super::symbolic::Symbolic;
use super::{NONE, ux};
use crate::error::{Error, Resource};
use crate::real::Real;
use crate::storage::{Slab, ensure_len, times};

/// Rows of the micro-kernel's accumulator tile.
pub const MR: usize = 4;
/// Target columns of the micro-kernel's accumulator tile.
pub const NR: usize = 4;
/// Source columns of one packed block.
pub const KC: usize = 64;
/// Rows of one packed block (a multiple of [`MR`]).
pub const MC: usize = 64;
/// Target columns of one packed block (a multiple of [`NR`]).
pub const NC: usize = 32;
/// Width of the column blocks a supernode's own columns are factored in.
pub const NB: usize = 32;

/// Scalars of workspace the supernodal factorization needs, whatever the matrix: the packed
/// row block and the packed target block.
pub const REAL_WORK_LEN: usize = KC * (MC + NC);

/// Indices of workspace the supernodal factorization needs for dimension `n`.
pub const fn index_work_len(n: usize) -> usize {
    times(5, n)
}

/// The supernodal structure of a [`Symbolic`] analysis.
#[derive(Clone, Copy)]
struct Panels<'s> {
    l_ptr: &'s [u32],
    l_row: &'s [u32],
    sn_ptr: &'s [u32],
}

impl<'s> Panels<'s> {
    fn new(sym: &'s Symbolic<'_>) -> Self {
        Panels {
            l_ptr: sym.l_ptr(),
            l_row: sym.l_row(),
            sn_ptr: sym.sn_ptr(),
        }
    }
    fn count(&self) -> usize {
        self.sn_ptr.len() - 1
    }
    fn first(&self, s: usize) -> usize {
        ux(self.sn_ptr[s])
    }
    fn width(&self, s: usize) -> usize {
        ux(self.sn_ptr[s + 1] - self.sn_ptr[s])
    }
    /// The rows at positions `1..m` of the row list (position 0 is the first column).
    fn below_first(&self, s: usize) -> &'s [u32] {
        let f = self.first(s);
        &self.l_row[ux(self.l_ptr[f])..ux(self.l_ptr[f + 1])]
    }
    /// The values of column `j` of `L` (strictly lower).
    fn column(&self, j: usize) -> core::ops::Range<usize> {
        ux(self.l_ptr[j])..ux(self.l_ptr[j + 1])
    }
    /// Offset of `L(R[i], f + c)` for `i > c` in a supernode whose first column is `f`.
    fn at(&self, f: usize, c: usize, i: usize) -> usize {
        ux(self.l_ptr[f + c]) + i - c - 1
    }
}

/// One update of a target supernode by columns `k0..k1` of a source supernode.
struct Update<'r> {
    /// First column of the source.
    src_f: usize,
    /// Source columns (relative to `src_f`).
    k0: usize,
    k1: usize,
    /// Position (in the source's row list) of the first row taking part.
    p0: usize,
    /// The rows taking part: the source's rows at positions `p0..m`.
    rows: &'r [u32],
    /// The first `targets` of `rows` are columns of the target.
    targets: usize,
    /// First column of the target.
    tgt_f: usize,
    /// For each of `rows`, its position in the target's row list.
    rel: &'r [u32],
}

/// The micro-kernel: `Σ_k a_k b_kᵀ` over packed `MR`-row slivers `a` and `NR`-column slivers
/// `b` of the same depth.
#[inline(always)]
fn micro<T: Real>(a: &[T], b: &[T]) -> [[T; MR]; NR] {
    let (a, _) = a.as_chunks::<MR>();
    let (b, _) = b.as_chunks::<NR>();
    let mut acc = [[T::zero(); MR]; NR];
    for (ak, bk) in a.iter().zip(b) {
        for j in 0..NR {
            for i in 0..MR {
                acc[j][i] += ak[i] * bk[j];
            }
        }
    }
    acc
}

/// Subtracts the update `u` from the target (see [`Update`]); `apack` and `bpack` hold
/// `KC · MC` and `KC · NC` scalars.
fn apply_update<T: Real>(
    l: &mut [T],
    d: &mut [T],
    pan: &Panels<'_>,
    u: &Update<'_>,
    apack: &mut [T],
    bpack: &mut [T],
) {
    let mrows = u.rows.len();
    let nt = u.targets;
    let mut kb = u.k0;
    while kb < u.k1 {
        let kc = KC.min(u.k1 - kb);
        let mut tb = 0;
        while tb < nt {
            let nc = NC.min(nt - tb);
            let ntiles = nc.div_ceil(NR);
            // Pack the targets' coefficients L(R[t], k) D(k), tile by tile, k-major in a tile.
            let bp = &mut bpack[..ntiles * kc * NR];
            for k in 0..kc {
                let col = kb + k;
                let dk = d[u.src_f + col];
                let base = pan.at(u.src_f, col, u.p0 + tb);
                let vals = &l[base..base + nc];
                for t in 0..ntiles * NR {
                    let v = vals.get(t).map_or(T::zero(), |&v| v * dk);
                    bp[((t / NR) * kc + k) * NR + t % NR] = v;
                }
            }
            // Rows from the block's first target down (rows above it meet no target's lower
            // triangle).
            let mut rb = tb;
            while rb < mrows {
                let mc = MC.min(mrows - rb);
                let nchunks = mc.div_ceil(MR);
                let ap = &mut apack[..nchunks * kc * MR];
                for k in 0..kc {
                    let col = kb + k;
                    let base = pan.at(u.src_f, col, u.p0 + rb);
                    let vals = &l[base..base + mc];
                    let (full, rest) = vals.as_chunks::<MR>();
                    let mut slivers = ap.chunks_exact_mut(kc * MR);
                    // `full` leads the zip, so a sliver is taken only for a full chunk.
                    for (src, sliver) in full.iter().zip(&mut slivers) {
                        sliver[k * MR..(k + 1) * MR].copy_from_slice(src);
                    }
                    if let Some(sliver) = slivers.next() {
                        let dst = &mut sliver[k * MR..(k + 1) * MR];
                        for (ii, x) in dst.iter_mut().enumerate() {
                            *x = rest.get(ii).copied().unwrap_or(T::zero());
                        }
                    }
                }
                for (ic, a) in ap.chunks_exact(kc * MR).enumerate() {
                    let i0 = rb + ic * MR;
                    for (jt, b) in bp.chunks_exact(kc * NR).enumerate() {
                        let t0 = tb + jt * NR;
                        if i0 + MR <= t0 {
                            // Every row of the sliver lies above every target's diagonal.
                            break;
                        }
                        let acc = micro(a, b);
                        scatter(l, d, pan, u, &acc, i0, t0);
                    }
                }
                rb += mc;
            }
            tb += nc;
        }
        kb += kc;
    }
}

/// Subtracts an accumulator tile (rows `i0..`, targets `t0..`, local to the update) from the
/// target, keeping only entries on or below each target's diagonal.
#[inline(always)]
fn scatter<T: Real>(
    l: &mut [T],
    d: &mut [T],
    pan: &Panels<'_>,
    u: &Update<'_>,
    acc: &[[T; MR]; NR],
    i0: usize,
    t0: usize,
) {
    let mrows = u.rows.len();
    // Fast path: a tile wholly below the targets' diagonals whose rows lie consecutively in
    // the target (always so within a supernode, often across): four contiguous entries per
    // target column.
    if i0 >= t0 + NR && i0 + MR <= mrows && t0 + NR <= u.targets {
        let r0 = ux(u.rel[i0]);
        if ux(u.rel[i0 + MR - 1]) == r0 + MR - 1 {
            for (jj, accj) in acc.iter().enumerate() {
                let c = ux(u.rows[t0 + jj]) - u.tgt_f;
                let at = ux(pan.l_ptr[u.tgt_f + c]) + r0 - c - 1;
                for (x, &v) in l[at..at + MR].iter_mut().zip(accj) {
                    *x -= v;
                }
            }
            return;
        }
    }
    for (jj, accj) in acc.iter().enumerate() {
        let t = t0 + jj;
        if t >= u.targets {
            break;
        }
        let c = ux(u.rows[t]) - u.tgt_f;
        // L(R[r], f + c) sits at l_ptr[f + c] + r − c − 1 (r > c).
        let col0 = ux(pan.l_ptr[u.tgt_f + c]);
        for (ii, &v) in accj.iter().enumerate() {
            let i = i0 + ii;
            if i >= mrows {
                break;
            }
            if i > t {
                l[col0 + ux(u.rel[i]) - c - 1] -= v;
            } else if i == t {
                d[u.tgt_f + c] -= v;
            }
        }
    }
}

/// `y −= Σ c_q x_q` over four columns at once.
#[inline(always)]
fn axpy4<T: Real>(y: &mut [T], x: [&[T]; 4], c: [T; 4]) {
    for ((((yi, &a), &b), &e), &g) in y.iter_mut().zip(x[0]).zip(x[1]).zip(x[2]).zip(x[3]) {
        *yi -= c[0] * a + c[1] * b + c[2] * e + c[3] * g;
    }
}

/// `y −= c x`.
#[inline(always)]
fn axpy<T: Real>(y: &mut [T], x: &[T], c: T) {
    for (yi, &xi) in y.iter_mut().zip(x) {
        *yi -= c * xi;
    }
}

/// Factors columns `b0..b1` of the supernode with first column `f`, already updated by every
/// column before `b0`: column by column, each updated by the block's earlier columns, then its
/// pivot checked and its column divided by it.
fn factor_block<T: Real>(
    l: &mut [T],
    d: &mut [T],
    pan: &Panels<'_>,
    f: usize,
    b0: usize,
    b1: usize,
) -> Result<(), Error> {
    for c in b0..b1 {
        let j = f + c;
        let range = pan.column(j);
        let (head, tail) = l.split_at_mut(range.start);
        let col = &mut tail[..range.len()];
        let mut dc = d[j];
        let mut k = b0;
        while k + 4 <= c {
            let mut coef = [T::zero(); 4];
            let mut x: [&[T]; 4] = [&[]; 4];
            for q in 0..4 {
                let lck = head[pan.at(f, k + q, c)];
                coef[q] = lck * d[f + k + q];
                dc -= coef[q] * lck;
                x[q] = &head[pan.at(f, k + q, c + 1)..ux(pan.l_ptr[f + k + q + 1])];
            }
            axpy4(col, x, coef);
            k += 4;
        }
        while k < c {
            let lck = head[pan.at(f, k, c)];
            let coef = lck * d[f + k];
            dc -= coef * lck;
            axpy(
                col,
                &head[pan.at(f, k, c + 1)..ux(pan.l_ptr[f + k + 1])],
                coef,
            );
            k += 1;
        }
        if !dc.finite() {
            return Err(Error::NotFinite { column: j });
        }
        if dc <= T::zero() {
            return Err(Error::NotPositiveDefinite { column: j });
        }
        d[j] = dc;
        let inv = T::one() / dc;
        for v in col.iter_mut() {
            *v *= inv;
        }
    }
    Ok(())
}

/// Factorizes `C = P A Pᵀ` into `l` (`nnz(L)` scalars) and `d` (`n`), supernode by supernode.
/// `work` needs [`REAL_WORK_LEN`] scalars and `iwork` [`index_work_len`]`(n)` indices; neither
/// has meaning on return, nor have `l` and `d` on error.
///
/// # Errors
/// [`Error::NotPositiveDefinite`] or [`Error::NotFinite`] naming the first failing column;
/// [`Error::Capacity`] for short workspaces.
pub(crate) fn factorize<T: Real, V: Real>(
    sym: &Symbolic<'_>,
    a_values: &[V],
    l: &mut [T],
    d: &mut [T],
    work: &mut [T],
    iwork: &mut [u32],
) -> Result<(), Error> {
    let n = sym.n();
    ensure_len(work, REAL_WORK_LEN, Resource::Workspace)?;
    ensure_len(iwork, index_work_len(n), Resource::Workspace)?;
    let (apack, bpack) = work.split_at_mut(KC * MC);
    let mut slab = Slab::new(iwork, Resource::Workspace);
    let map = slab.take(n)?;
    let head = slab.take(n)?;
    let next = slab.take(n)?;
    let cursor = slab.take(n)?;
    let rel = slab.take(n)?;

    // Load C into L and D.
    l.fill(T::zero());
    d.fill(T::zero());
    let (c_ptr, c_src, c_dst) = (sym.c_ptr(), sym.c_src(), sym.c_dst());
    for k in 0..n {
        for q in ux(c_ptr[k])..ux(c_ptr[k + 1]) {
            // Rounded to the factor's scalar type (a no-op when it is the matrix's).
            let v = T::of(a_values[ux(c_src[q])].to_f64());
            match c_dst[q] {
                NONE => d[k] += v,
                p => l[ux(p)] += v,
            }
        }
    }

    let pan = Panels::new(sym);
    let col_sn = sym.col_sn();
    head[..pan.count()].fill(NONE);
    for s in 0..pan.count() {
        let (f, w, below) = (pan.first(s), pan.width(s), pan.below_first(s));
        let m = below.len() + 1;
        map[f] = 0;
        for (i, &r) in below.iter().enumerate() {
            map[ux(r)] = (i + 1) as u32;
        }
        let end = (f + w) as u32;
        // Updates from the descendants listed for s.
        let mut desc = head[s];
        while desc != NONE {
            let dd = ux(desc);
            let after = next[dd];
            let d_below = pan.below_first(dd);
            let p0 = ux(cursor[dd]);
            let rows = &d_below[p0 - 1..];
            let targets = rows.iter().take_while(|&&r| r < end).count();
            for (ri, &r) in rel.iter_mut().zip(rows) {
                *ri = map[ux(r)];
            }
            let u = Update {
                src_f: pan.first(dd),
                k0: 0,
                k1: pan.width(dd),
                p0,
                rows,
                targets,
                tgt_f: f,
                rel: &rel[..rows.len()],
            };
            apply_update(l, d, &pan, &u, apack, bpack);
            let p1 = p0 + targets;
            if p1 <= d_below.len() {
                cursor[dd] = p1 as u32;
                let owner = ux(col_sn[ux(d_below[p1 - 1])]);
                next[dd] = head[owner];
                head[owner] = dd as u32;
            }
            desc = after;
        }
        // The supernode's own columns, in blocks.
        let mut b0 = 0;
        while b0 < w {
            let b1 = (b0 + NB).min(w);
            if b0 > 0 {
                let rows = &below[b0 - 1..];
                for (i, ri) in rel[..rows.len()].iter_mut().enumerate() {
                    *ri = (b0 + i) as u32;
                }
                let u = Update {
                    src_f: f,
                    k0: 0,
                    k1: b0,
                    p0: b0,
                    rows,
                    targets: b1 - b0,
                    tgt_f: f,
                    rel: &rel[..rows.len()],
                };
                apply_update(l, d, &pan, &u, apack, bpack);
            }
            factor_block(l, d, &pan, f, b0, b1)?;
            b0 = b1;
        }
        if m > w {
            cursor[s] = w as u32;
            let owner = ux(col_sn[ux(below[w - 1])]);
            next[s] = head[owner];
            head[owner] = s as u32;
        }
    }
    Ok(())
}

/// `Σ x_i y_i` with four partial sums, so that the loop vectorises.
#[inline(always)]
fn dot<T: Real>(x: &[T], y: &[T]) -> T {
    let (xc, xr) = x.as_chunks::<4>();
    let (yc, yr) = y.as_chunks::<4>();
    let mut s = [T::zero(); 4];
    for (a, b) in xc.iter().zip(yc) {
        for q in 0..4 {
            s[q] += a[q] * b[q];
        }
    }
    let mut tail = T::zero();
    for (&a, &b) in xr.iter().zip(yr) {
        tail += a * b;
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// `[x_q · y]` for four columns `x_q` of `y`'s length, in one pass over `y` (two partial sums
/// each, so the loop vectorises).
#[inline(always)]
fn dot4<T: Real>(x: [&[T]; 4], y: &[T]) -> [T; 4] {
    let mut s = [[T::zero(); 2]; 4];
    let (yc, yr) = y.as_chunks::<2>();
    let [x0, x1, x2, x3] = x.map(|xq| xq.as_chunks::<2>().0);
    for ((((yi, a0), a1), a2), a3) in yc.iter().zip(x0).zip(x1).zip(x2).zip(x3) {
        for (sq, a) in s.iter_mut().zip([a0, a1, a2, a3]) {
            sq[0] += a[0] * yi[0];
            sq[1] += a[1] * yi[1];
        }
    }
    let mut out = s.map(|sq| sq[0] + sq[1]);
    if let Some(&last) = yr.first() {
        for (o, xq) in out.iter_mut().zip(x) {
            *o += xq.last().copied().unwrap_or(T::zero()) * last;
        }
    }
    out
}

/// Solves `L D Lᵀ w = w` in place (permuted order) over the supernodal panels; `tmp` needs as
/// many scalars as the tallest supernode has rows below its diagonal block (`n` always do).
pub(crate) fn solve<T: Real>(sym: &Symbolic<'_>, l: &[T], d: &[T], w: &mut [T], tmp: &mut [T]) {
    let pan = Panels::new(sym);
    // Forward: L y = w.
    for s in 0..pan.count() {
        let (f, wd, below) = (pan.first(s), pan.width(s), pan.below_first(s));
        let nb = below.len() + 1 - wd;
        let t = &mut tmp[..nb];
        t.fill(T::zero());
        let mut c = 0;
        while c < wd {
            // The diagonal block: column c updates the block's later unknowns.
            let cols = if c + 4 <= wd { 4 } else { 1 };
            for q in 0..cols {
                let col = &l[pan.column(f + c + q)];
                let xc = w[f + c + q];
                axpy(&mut w[f + c + q + 1..f + wd], &col[..wd - c - q - 1], xc);
            }
            if cols == 4 {
                let x = [0, 1, 2, 3].map(|q| &l[pan.column(f + c + q)][wd - c - q - 1..]);
                let xs = [0, 1, 2, 3].map(|q| -w[f + c + q]);
                axpy4(t, x, xs);
            } else {
                let x = &l[pan.column(f + c)][wd - c - 1..];
                axpy(t, x, -w[f + c]);
            }
            c += cols;
        }
        for (&r, &tv) in below[wd - 1..].iter().zip(t.iter()) {
            w[ux(r)] -= tv;
        }
    }
    // Diagonal.
    for (wj, &dj) in w.iter_mut().zip(d) {
        *wj /= dj;
    }
    // Backward: Lᵀ x = y.
    for s in (0..pan.count()).rev() {
        let (f, wd, below) = (pan.first(s), pan.width(s), pan.below_first(s));
        let nb = below.len() + 1 - wd;
        let t = &mut tmp[..nb];
        for (tv, &r) in t.iter_mut().zip(&below[wd - 1..]) {
            *tv = w[ux(r)];
        }
        let mut c_end = wd;
        while c_end > 0 {
            // Columns c0..c_end: their products with the rows below the diagonal block first
            // (four at once share the loads of `t`), then the diagonal block, last column first.
            let c0 = c_end.saturating_sub(4);
            let mut outer = [T::zero(); 4];
            if c_end - c0 == 4 {
                let x = [0, 1, 2, 3].map(|q| &l[pan.column(f + c0 + q)][wd - c0 - q - 1..]);
                outer = dot4(x, t);
            } else {
                for (q, o) in outer.iter_mut().enumerate().take(c_end - c0) {
                    *o = dot(&l[pan.column(f + c0 + q)][wd - c0 - q - 1..], t);
                }
            }
            for c in (c0..c_end).rev() {
                let inner = &l[pan.column(f + c)][..wd - c - 1];
                w[f + c] -= outer[c - c0] + dot(inner, &w[f + c + 1..f + wd]);
            }
            c_end = c0;
        }
    }
}
