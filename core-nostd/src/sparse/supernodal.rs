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
//!
//! **Bounds.** Every index the kernels follow comes from the [`Symbolic`] analysis, whose
//! invariants keep it inside `L`, `D` and the workspaces; each is still looked up with `get`,
//! once per slice where a loop follows. The factorization and the solves report one that
//! reaches outside as an error (the solves with `w` then partly solved), never skip it.

use core::ops::Range;

use super::symbolic::Symbolic;
use super::{NONE, ux};
use crate::error::{Error, Resource};
use crate::real::Real;
use crate::storage::{Slab, ensure_len, prefix_mut, times};

/// Rows of the micro-kernel's accumulator tile: one vector register's worth of rows per
/// target column, twice, so that `2 NR` independent multiply-adds are in flight. With 128-bit
/// vectors (x86-64's baseline SSE2) that is 4 rows, with 256-bit ones (a build for AVX, e.g.
/// `-C target-cpu=x86-64-v3`) 8: chosen when the core is compiled, from the target's features,
/// without any run-time dispatch (which would need `unsafe`). Wider tiles than that spill the
/// accumulators out of the registers (16 × 4 and 8 × 8 ran 8 to 10 times slower under
/// AVX-512), and 8 rows under SSE2 ran a little slower than 4. Each entry's sum runs over the
/// same source columns in the same order whatever the tile, so the factor is the same bit for
/// bit.
pub const MR: usize = if cfg!(target_feature = "avx") { 8 } else { 4 };
/// Target columns of the micro-kernel's accumulator tile.
pub const NR: usize = 4;
/// Source columns of one packed block.
pub const KC: usize = 64;
/// Rows of one packed block (a multiple of [`MR`]): half as many where the target block holds
/// its coefficients twice ([`DUP`]), so that the two blocks take the same room in every build.
pub const MC: usize = 64 / DUP;
/// Copies of each target coefficient in the packed target block. Under SSE2 the micro-kernel
/// multiplies a vector of rows by one coefficient in both lanes; packed as a pair, that vector
/// is one load, where a single copy needed a load and a shuffle (`unpcklpd`) on the same
/// floating-point pipes as the multiply-adds: 28 instructions per source column of the 4 × 4
/// tile instead of 32, and the factorization 5–16 % faster (`cargo bench --bench factor`).
/// With AVX a broadcast from memory is a load already, and other targets (NEON's multiply by
/// a lane) need no copy either: one copy. An `f32` factor gains nothing (its four lanes would
/// need four copies; the liver's `--real f32` frame costs 0.4 % more instructions).
pub const DUP: usize = if cfg!(all(target_arch = "x86_64", not(target_feature = "avx"))) {
    2
} else {
    1
};
/// Target columns of one packed block (a multiple of [`NR`]).
pub const NC: usize = 32;
/// Width of the column blocks a supernode's own columns are factored in.
pub const NB: usize = 32;

/// Scalars of workspace the supernodal factorization needs, whatever the matrix: the packed
/// row block and the packed target block.
pub const REAL_WORK_LEN: usize = KC * (MC + DUP * NC);

/// Indices of workspace the supernodal factorization needs for dimension `n`.
pub const fn index_work_len(n: usize) -> usize {
    times(5, n)
}

/// The error for `index`, met at column (or supernode) `at` of the permuted order, that lies
/// outside `resource` of `bound` entries. A [`Symbolic`] built or loaded by this crate, with
/// storage of its sizes, never gives one.
const fn outside(resource: Resource, at: usize, index: usize, bound: usize) -> Error {
    Error::IndexOutOfRange {
        resource,
        position: at,
        index,
        bound,
    }
}

/// The supernodal structure of a [`Symbolic`] analysis.
#[derive(Clone, Copy)]
struct Panels<'s> {
    l_ptr: &'s [u32],
    l_row: &'s [u32],
    sn_ptr: &'s [u32],
}

impl<'s> Panels<'s> {
    /// The panels of `sym`.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] naming [`Resource::ColumnPointers`] unless the supernode
    /// pointers run from column 0 to `n` and the column pointers of `L` and `C` have `n + 1`
    /// entries (the analysis's invariants): a short array would otherwise make the loops over
    /// the supernodes end early without a word.
    fn new(sym: &'s Symbolic<'_>) -> Result<Self, Error> {
        let (n, sn_ptr) = (sym.n(), sym.sn_ptr());
        let spans_all = sn_ptr.first() == Some(&0) && sn_ptr.last().map(|&e| ux(e)) == Some(n);
        if !spans_all && n > 0 {
            return Err(outside(Resource::ColumnPointers, 0, n, sn_ptr.len()));
        }
        for ptr in [sym.l_ptr(), sym.c_ptr()] {
            if ptr.len() != n + 1 {
                return Err(outside(Resource::ColumnPointers, n, n, ptr.len()));
            }
        }
        Ok(Panels {
            l_ptr: sym.l_ptr(),
            l_row: sym.l_row(),
            sn_ptr,
        })
    }
    fn count(&self) -> usize {
        self.sn_ptr.len().saturating_sub(1)
    }
    /// First column `f` and width `w` of supernode `s`.
    fn span(&self, s: usize) -> Result<(usize, usize), Error> {
        match (self.sn_ptr.get(s), self.sn_ptr.get(s + 1)) {
            (Some(&f), Some(&e)) if f <= e => Ok((ux(f), ux(e - f))),
            _ => Err(outside(
                Resource::ColumnPointers,
                s,
                s + 1,
                self.sn_ptr.len(),
            )),
        }
    }
    /// Offsets of column `j`'s values (strictly lower) in `L`.
    fn range(&self, j: usize) -> Result<Range<usize>, Error> {
        match (self.l_ptr.get(j), self.l_ptr.get(j + 1)) {
            (Some(&s), Some(&e)) => Ok(ux(s)..ux(e)),
            _ => Err(outside(
                Resource::ColumnPointers,
                j,
                j + 1,
                self.l_ptr.len(),
            )),
        }
    }
    /// The rows at positions `1..m` of the row list of the supernode whose first column is `f`
    /// (position 0 is `f`).
    fn below_first(&self, f: usize) -> Result<&'s [u32], Error> {
        let r = self.range(f)?;
        let bound = self.l_row.len();
        self.l_row
            .get(r.clone())
            .ok_or_else(|| outside(Resource::FactorEntries, f, r.end, bound))
    }
    /// The values of column `j` of `L` (strictly lower) in `l`.
    fn column<'l, T>(&self, l: &'l [T], j: usize) -> Result<&'l [T], Error> {
        let r = self.range(j)?;
        l.get(r.clone())
            .ok_or_else(|| outside(Resource::FactorEntries, j, r.end, l.len()))
    }
    /// `L(R[i..i + len], f + c)` (`i > c`) in a supernode whose first column is `f`: the `len`
    /// values of column `f + c` from `l_ptr[f + c] + i − c − 1`.
    #[inline]
    fn run<'l, T>(
        &self,
        l: &'l [T],
        f: usize,
        c: usize,
        i: usize,
        len: usize,
    ) -> Result<&'l [T], Error> {
        let j = f + c;
        let Some(&p) = self.l_ptr.get(j) else {
            return Err(outside(Resource::ColumnPointers, j, j, self.l_ptr.len()));
        };
        let at = ux(p) + i - c - 1;
        match l.get(at..at + len) {
            Some(vals) => Ok(vals),
            None => Err(outside(Resource::FactorEntries, j, at + len, l.len())),
        }
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
/// `b` of the same depth, each coefficient of `b` packed [`DUP`] times: lane `p` of a group of
/// `DUP` rows is multiplied by copy `p` (the same value).
#[inline(always)]
fn micro<T: Real>(a: &[T], b: &[T]) -> [[T; MR]; NR] {
    let (a, _) = a.as_chunks::<MR>();
    let (b, _) = b.as_chunks::<{ NR * DUP }>();
    let mut acc = [[T::zero(); MR]; NR];
    for (ak, bk) in a.iter().zip(b) {
        let (ak, _) = ak.as_chunks::<DUP>();
        let (bk, _) = bk.as_chunks::<DUP>();
        for (accj, bkj) in acc.iter_mut().zip(bk) {
            let (accj, _) = accj.as_chunks_mut::<DUP>();
            for (x, aki) in accj.iter_mut().zip(ak) {
                for ((x, &a), &b) in x.iter_mut().zip(aki).zip(bkj) {
                    *x += a * b;
                }
            }
        }
    }
    acc
}

/// Row `k` (of `W` scalars) of a packed sliver.
///
/// # Errors
/// [`Error::IndexOutOfRange`] naming [`Resource::Workspace`] past its end (the packing loops
/// size every sliver for the rows they write).
#[inline(always)]
fn packed_row<T, const W: usize>(sliver: &mut [T], k: usize) -> Result<&mut [T; W], Error> {
    let rows = sliver.len() / W;
    sliver
        .as_chunks_mut::<W>()
        .0
        .get_mut(k)
        .ok_or(outside(Resource::Workspace, k, k, rows))
}

/// Subtracts the update `u` from the target (see [`Update`]); `apack` and `bpack` hold
/// `KC · MC` and `KC · NC · DUP` scalars.
///
/// # Errors
/// [`Error::IndexOutOfRange`] if the analysis places a source entry outside `l` or `d`;
/// [`Error::Capacity`] if a packing buffer is short.
fn apply_update<T: Real>(
    l: &mut [T],
    d: &mut [T],
    pan: &Panels<'_>,
    u: &Update<'_>,
    apack: &mut [T],
    bpack: &mut [T],
) -> Result<(), Error> {
    let mrows = u.rows.len();
    let nt = u.targets;
    let mut kb = u.k0;
    while kb < u.k1 {
        let kc = KC.min(u.k1 - kb);
        let mut tb = 0;
        while tb < nt {
            let nc = NC.min(nt - tb);
            let ntiles = nc.div_ceil(NR);
            // One packed target tile: `kc` rows of `NR` coefficients, each `DUP` times.
            let tile_len = kc * NR * DUP;
            // Pack the targets' coefficients L(R[t], k) D(k), tile by tile, k-major in a tile.
            let bp = prefix_mut(bpack, ntiles * tile_len, Resource::Workspace)?;
            for k in 0..kc {
                let col = kb + k;
                let j = u.src_f + col;
                let Some(&dk) = d.get(j) else {
                    return Err(outside(Resource::Unknowns, j, j, d.len()));
                };
                let mut vals = pan.run(l, u.src_f, col, u.p0 + tb, nc)?.iter();
                // Every tile has row `k` (k < kc); the targets past `nc` pad with zeros.
                for tile in bp.chunks_exact_mut(tile_len) {
                    let dst = packed_row::<T, { NR * DUP }>(tile, k)?;
                    for x in dst.as_chunks_mut::<DUP>().0 {
                        let v = vals.next().map_or(T::zero(), |&v| v * dk);
                        x.fill(v);
                    }
                }
            }
            // Rows from the block's first target down (rows above it meet no target's lower
            // triangle).
            let mut rb = tb;
            while rb < mrows {
                let mc = MC.min(mrows - rb);
                let nchunks = mc.div_ceil(MR);
                let ap = prefix_mut(apack, nchunks * kc * MR, Resource::Workspace)?;
                for k in 0..kc {
                    let vals = pan.run(l, u.src_f, kb + k, u.p0 + rb, mc)?;
                    let (full, rest) = vals.as_chunks::<MR>();
                    let mut slivers = ap.chunks_exact_mut(kc * MR);
                    // `full` leads the zip, so a sliver is taken only for a full chunk. Every
                    // sliver has row `k` (k < kc).
                    for (src, sliver) in full.iter().zip(&mut slivers) {
                        *packed_row::<T, MR>(sliver, k)? = *src;
                    }
                    if let Some(sliver) = slivers.next() {
                        let dst = packed_row::<T, MR>(sliver, k)?;
                        let mut rest = rest.iter();
                        for x in dst.iter_mut() {
                            *x = rest.next().copied().unwrap_or(T::zero());
                        }
                    }
                }
                for (ic, a) in ap.chunks_exact(kc * MR).enumerate() {
                    let i0 = rb + ic * MR;
                    for (jt, b) in bp.chunks_exact(tile_len).enumerate() {
                        let t0 = tb + jt * NR;
                        if i0 + MR <= t0 {
                            // Every row of the sliver lies above every target's diagonal.
                            break;
                        }
                        let acc = micro(a, b);
                        scatter(l, d, pan, u, &acc, i0, t0)?;
                    }
                }
                rb += mc;
            }
            tb += nc;
        }
        kb += kc;
    }
    Ok(())
}

/// Subtracts an accumulator tile (rows `i0..`, targets `t0..`, local to the update) from the
/// target, keeping only entries on or below each target's diagonal.
///
/// # Errors
/// [`Error::IndexOutOfRange`] for an entry of the tile outside `l` or `d`, or a row outside the
/// update's lists. The analysis keeps every one inside (the target's pattern holds the
/// source's rows); an entry outside is reported, never skipped.
#[inline(always)]
fn scatter<T: Real>(
    l: &mut [T],
    d: &mut [T],
    pan: &Panels<'_>,
    u: &Update<'_>,
    acc: &[[T; MR]; NR],
    i0: usize,
    t0: usize,
) -> Result<(), Error> {
    let mrows = u.rows.len();
    let (l_len, d_len) = (l.len(), d.len());
    // Target column `f + c` is row `r` of the update, and column `f + c` of `L` starts at
    // `l_ptr[r]`.
    let column_start = |r: usize| -> Result<usize, Error> {
        pan.l_ptr.get(r).map(|&p| ux(p)).ok_or(outside(
            Resource::ColumnPointers,
            u.tgt_f,
            r,
            pan.l_ptr.len(),
        ))
    };
    // Fast path: a tile wholly below the targets' diagonals whose rows lie consecutively in
    // the target (always so within a supernode, often across): four contiguous entries per
    // target column.
    if i0 >= t0 + NR
        && i0 + MR <= mrows
        && t0 + NR <= u.targets
        && let (Some(&first), Some(&last), Some(tgt_rows)) = (
            u.rel.get(i0),
            u.rel.get(i0 + MR - 1),
            u.rows.get(t0..t0 + NR),
        )
    {
        let r0 = ux(first);
        if ux(last) == r0 + MR - 1 {
            for (accj, &r) in acc.iter().zip(tgt_rows) {
                // L(R[r0], f + c) sits at l_ptr[f + c] + r0 − c − 1.
                let c = ux(r) - u.tgt_f;
                let at = column_start(ux(r))? + r0 - c - 1;
                let dst = l.get_mut(at..at + MR).ok_or(outside(
                    Resource::FactorEntries,
                    u.tgt_f,
                    at + MR,
                    l_len,
                ))?;
                for (x, &v) in dst.iter_mut().zip(accj) {
                    *x -= v;
                }
            }
            return Ok(());
        }
    }
    for (jj, accj) in acc.iter().enumerate() {
        let t = t0 + jj;
        if t >= u.targets {
            break;
        }
        let &r = u
            .rows
            .get(t)
            .ok_or(outside(Resource::FactorEntries, u.tgt_f, t, mrows))?;
        let c = ux(r) - u.tgt_f;
        // L(R[r], f + c) sits at l_ptr[f + c] + r − c − 1 (r > c); column f + c is row `r`.
        let col0 = column_start(ux(r))?;
        for (ii, &v) in accj.iter().enumerate() {
            let i = i0 + ii;
            if i >= mrows {
                break;
            }
            if i > t {
                let &ri =
                    u.rel
                        .get(i)
                        .ok_or(outside(Resource::Workspace, u.tgt_f, i, u.rel.len()))?;
                let at = col0 + ux(ri) - c - 1;
                *l.get_mut(at)
                    .ok_or(outside(Resource::FactorEntries, u.tgt_f, at, l_len))? -= v;
            } else if i == t {
                *d.get_mut(ux(r))
                    .ok_or(outside(Resource::Unknowns, u.tgt_f, ux(r), d_len))? -= v;
            }
        }
    }
    Ok(())
}

/// `y −= Σ c_q x_q` over four columns at once.
#[inline(always)]
fn axpy4<T: Real>(y: &mut [T], x: [&[T]; 4], c: [T; 4]) {
    for ((((yi, &a), &b), &e), &g) in y.iter_mut().zip(x[0]).zip(x[1]).zip(x[2]).zip(x[3]) {
        *yi -= c[0] * a + c[1] * b + c[2] * e + c[3] * g;
    }
}

/// `y −= c_0 x_0`, then `y −= c_1 x_1`, … in one pass: each entry takes the four products
/// in that order, as four calls of [`axpy`] would subtract them.
#[inline(always)]
fn axpy4_in_order<T: Real>(y: &mut [T], x: [&[T]; 4], c: [T; 4]) {
    for ((((yi, &a), &b), &e), &g) in y.iter_mut().zip(x[0]).zip(x[1]).zip(x[2]).zip(x[3]) {
        *yi = (((*yi - c[0] * a) - c[1] * b) - c[2] * e) - c[3] * g;
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
///
/// # Errors
/// [`Error::NotFinite`] or [`Error::NotPositiveDefinite`] naming the failing column;
/// [`Error::IndexOutOfRange`] if the analysis places an entry outside `l` or `d`.
fn factor_block<T: Real>(
    l: &mut [T],
    d: &mut [T],
    pan: &Panels<'_>,
    f: usize,
    b0: usize,
    b1: usize,
) -> Result<(), Error> {
    let d_len = d.len();
    let Some(d_panel) = d.get_mut(f..f + b1) else {
        return Err(outside(Resource::Unknowns, f, f + b1, d_len));
    };
    let l_len = l.len();
    for c in b0..b1 {
        let j = f + c;
        let range = pan.range(j)?;
        // The columns before `j` lie in `head`, column `j` at the start of `tail`.
        let (Some((head, tail)), Some(len)) = (
            l.split_at_mut_checked(range.start),
            range.end.checked_sub(range.start),
        ) else {
            return Err(outside(Resource::FactorEntries, j, range.end, l_len));
        };
        let Some(col) = tail.get_mut(..len) else {
            return Err(outside(Resource::FactorEntries, j, range.end, l_len));
        };
        // `d_before[k]` is D(f + k), `d_j` is D(j).
        let Some((d_before, [d_j, ..])) = d_panel.split_at_mut_checked(c) else {
            return Err(outside(Resource::Unknowns, j, j, d_len));
        };
        let mut dc = *d_j;
        // Column `f + k` from `L(R[c], f + k)` down: `L(R[c], f + k)`, then the rows that
        // update column `j`.
        let from_row_c = |k: usize| -> Result<(T, &[T], T), Error> {
            let src = pan.column(head, f + k)?;
            match (src.split_at_checked(c - k - 1), d_before.get(k)) {
                (Some((_, [lck, rest @ ..])), Some(&dk)) => Ok((*lck, rest, dk)),
                _ => Err(outside(Resource::FactorEntries, f + k, c - k, src.len())),
            }
        };
        let mut k = b0;
        while k + 4 <= c {
            let mut coef = [T::zero(); 4];
            let mut x: [&[T]; 4] = [&[]; 4];
            for (q, (cq, xq)) in coef.iter_mut().zip(x.iter_mut()).enumerate() {
                let (lck, rest, dk) = from_row_c(k + q)?;
                *cq = lck * dk;
                dc -= *cq * lck;
                *xq = rest;
            }
            axpy4(col, x, coef);
            k += 4;
        }
        while k < c {
            let (lck, rest, dk) = from_row_c(k)?;
            let coef = lck * dk;
            dc -= coef * lck;
            axpy(col, rest, coef);
            k += 1;
        }
        if !dc.finite() {
            return Err(Error::NotFinite { column: j });
        }
        if dc <= T::zero() {
            return Err(Error::NotPositiveDefinite { column: j });
        }
        *d_j = dc;
        let inv = T::one() / dc;
        for v in col.iter_mut() {
            *v *= inv;
        }
    }
    Ok(())
}

/// Links supernode `s` into the list of the supernode owning row `r`, the next one it updates.
fn link(head: &mut [u32], next: &mut [u32], col_sn: &[u32], s: usize, r: u32) -> Result<(), Error> {
    let Some(&owner) = col_sn.get(ux(r)) else {
        return Err(outside(Resource::Unknowns, s, ux(r), col_sn.len()));
    };
    let bound = head.len();
    match (head.get_mut(ux(owner)), next.get_mut(s)) {
        (Some(h), Some(nx)) => {
            *nx = *h;
            *h = s as u32;
            Ok(())
        }
        _ => Err(outside(Resource::Workspace, s, ux(owner), bound)),
    }
}

/// Factorizes `C = P A Pᵀ` into `l` (`nnz(L)` scalars) and `d` (`n`), supernode by supernode.
/// `work` needs [`REAL_WORK_LEN`] scalars and `iwork` [`index_work_len`]`(n)` indices; neither
/// has meaning on return, nor have `l` and `d` on error.
///
/// # Errors
/// [`Error::NotPositiveDefinite`] or [`Error::NotFinite`] naming the first failing column;
/// [`Error::Capacity`] for short workspaces, `l` or `d`; [`Error::IndexOutOfRange`] naming the
/// column whose indices reach outside `a_values`, `l`, `d` or the workspaces, which an
/// analysis built or loaded by [`Symbolic`] never does.
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
    ensure_len(l, sym.nnz_l(), Resource::FactorEntries)?;
    ensure_len(d, n, Resource::Unknowns)?;
    let mut rslab = Slab::new(work, Resource::Workspace);
    let apack = rslab.take(KC * MC)?;
    let bpack = rslab.take(KC * NC * DUP)?;
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
    let l_len = l.len();
    for (k, (dk, (&start, &end))) in d
        .iter_mut()
        .zip(c_ptr.iter().zip(c_ptr.iter().skip(1)))
        .enumerate()
    {
        let entries = ux(start)..ux(end);
        let (Some(src), Some(dst)) = (c_src.get(entries.clone()), c_dst.get(entries.clone()))
        else {
            return Err(outside(
                Resource::MatrixEntries,
                k,
                entries.end,
                c_src.len(),
            ));
        };
        for (&q, &p) in src.iter().zip(dst) {
            let Some(&a) = a_values.get(ux(q)) else {
                return Err(outside(Resource::MatrixEntries, k, ux(q), a_values.len()));
            };
            // Rounded to the factor's scalar type (a no-op when it is the matrix's).
            let v = T::of(a.to_f64());
            match p {
                NONE => *dk += v,
                p => match l.get_mut(ux(p)) {
                    Some(x) => *x += v,
                    None => return Err(outside(Resource::FactorEntries, k, ux(p), l_len)),
                },
            }
        }
    }

    let pan = Panels::new(sym)?;
    let col_sn = sym.col_sn();
    prefix_mut(head, pan.count(), Resource::Workspace)?.fill(NONE);
    for s in 0..pan.count() {
        let (f, w) = pan.span(s)?;
        let below = pan.below_first(f)?;
        let n_map = map.len();
        for (i, r) in core::iter::once(f)
            .chain(below.iter().map(|&r| ux(r)))
            .enumerate()
        {
            match map.get_mut(r) {
                Some(slot) => *slot = i as u32,
                None => return Err(outside(Resource::Workspace, f, r, n_map)),
            }
        }
        let end = (f + w) as u32;
        // Updates from the descendants listed for s (`head` holds an entry per supernode,
        // checked above).
        let mut desc = head.get(s).copied().unwrap_or(NONE);
        while desc != NONE {
            let dd = ux(desc);
            let (Some(&after), Some(&p0)) = (next.get(dd), cursor.get(dd)) else {
                return Err(outside(Resource::Workspace, f, dd, n));
            };
            let (src_f, src_w) = pan.span(dd)?;
            let d_below = pan.below_first(src_f)?;
            let p0 = ux(p0);
            // The source's rows from position `p0` (its row list is `src_f` then `d_below`).
            let Some(rows) = p0.checked_sub(1).and_then(|p| d_below.get(p..)) else {
                return Err(outside(Resource::FactorEntries, src_f, p0, d_below.len()));
            };
            let targets = rows.iter().take_while(|&&r| r < end).count();
            let Some(rel) = rel.get_mut(..rows.len()) else {
                return Err(outside(Resource::Workspace, f, rows.len(), n));
            };
            for (ri, &r) in rel.iter_mut().zip(rows) {
                match map.get(ux(r)) {
                    Some(&i) => *ri = i,
                    None => return Err(outside(Resource::Workspace, f, ux(r), n_map)),
                }
            }
            let u = Update {
                src_f,
                k0: 0,
                k1: src_w,
                p0,
                rows,
                targets,
                tgt_f: f,
                rel,
            };
            apply_update(l, d, &pan, &u, apack, bpack)?;
            // Row `rows[targets]` (position `p0 + targets`, if the source has one) is the
            // next the source updates.
            if let Some(&r) = rows.get(targets) {
                let cursors = cursor.len();
                *cursor
                    .get_mut(dd)
                    .ok_or(outside(Resource::Workspace, f, dd, cursors))? = (p0 + targets) as u32;
                link(head, next, col_sn, dd, r)?;
            }
            desc = after;
        }
        // The supernode's own columns, in blocks.
        let mut b0 = 0;
        while b0 < w {
            let b1 = (b0 + NB).min(w);
            if b0 > 0 {
                let Some(rows) = below.get(b0 - 1..) else {
                    return Err(outside(Resource::FactorEntries, f, b0, below.len()));
                };
                let Some(rel) = rel.get_mut(..rows.len()) else {
                    return Err(outside(Resource::Workspace, f, rows.len(), n));
                };
                for (i, ri) in rel.iter_mut().enumerate() {
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
                    rel,
                };
                apply_update(l, d, &pan, &u, apack, bpack)?;
            }
            factor_block(l, d, &pan, f, b0, b1)?;
            b0 = b1;
        }
        // Row `R[w]` (position `w` of the row list), if the supernode has rows below its
        // diagonal block, is the first it updates.
        if let Some(&r) = w.checked_sub(1).and_then(|p| below.get(p)) {
            let cursors = cursor.len();
            *cursor
                .get_mut(s)
                .ok_or(outside(Resource::Workspace, f, s, cursors))? = w as u32;
            link(head, next, col_sn, s, r)?;
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
        for ((sq, &aq), &bq) in s.iter_mut().zip(a).zip(b) {
            *sq += aq * bq;
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
///
/// # Errors
/// [`Error::IndexOutOfRange`] or [`Error::Capacity`] at the first index outside `l`, `d`, `w`
/// or `tmp`, with `w` then partly solved. The callers pass `l`, `d` and `w` of the analysis'
/// sizes and `n` scalars of `tmp`, and the analysis keeps every index inside them.
pub(crate) fn solve<T: Real>(
    sym: &Symbolic<'_>,
    l: &[T],
    d: &[T],
    w: &mut [T],
    tmp: &mut [T],
) -> Result<(), Error> {
    let pan = Panels::new(sym)?;
    let (w_len, tmp_len) = (w.len(), tmp.len());
    // The rows below the diagonal block of the supernode with first column `f` and width `wd`
    // (positions `wd..m` of its row list).
    let rows_below = |f: usize, wd: usize| -> Result<&[u32], Error> {
        let below = pan.below_first(f)?;
        wd.checked_sub(1)
            .and_then(|p| below.get(p..))
            .ok_or_else(|| outside(Resource::FactorEntries, f, wd, below.len()))
    };
    // Forward: L y = w.
    for s in 0..pan.count() {
        let (f, wd) = pan.span(s)?;
        let below = rows_below(f, wd)?;
        let Some(t) = tmp.get_mut(..below.len()) else {
            return Err(outside(Resource::Workspace, f, below.len(), tmp_len));
        };
        t.fill(T::zero());
        let Some(wb) = w.get_mut(f..f + wd) else {
            return Err(outside(Resource::Vector, f, f + wd, w_len));
        };
        // The diagonal block: column c updates the block's later unknowns, and the rows
        // below it gather in `t`. Four columns at a time: their own triangle in straight
        // lines, then the block's rows below the four take the four columns' updates in one
        // pass, each entry in column order (as a pass per column gave them, the same value
        // bit for bit), and `t` the four's products with the rows below the block.
        let mut c = 0;
        while c + 4 <= wd {
            let mut x: [&[T]; 4] = [&[]; 4];
            let mut rest: [&[T]; 4] = [&[]; 4];
            let mut tri = [T::zero(); 6];
            for (q, (xq, rq)) in x.iter_mut().zip(rest.iter_mut()).enumerate() {
                let cq = c + q;
                let col = pan.column(l, f + cq)?;
                // Rows `cq + 1 .. c + 4` (the four's triangle), `c + 4 .. wd` (the block's rows
                // below the four), then the rows below the block.
                let Some(((mine, below_four), outer)) = col
                    .split_at_checked(wd - cq - 1)
                    .and_then(|(inner, outer)| Some((inner.split_at_checked(3 - q)?, outer)))
                else {
                    return Err(outside(Resource::FactorEntries, f + cq, wd, col.len()));
                };
                // The triangle's entries column by column: 3 of column c (from slot 0), 2 (from
                // slot 3), 1 (slot 5), none.
                let at = q * (7 - q) / 2;
                for (slot, &v) in tri.iter_mut().skip(at).zip(mine) {
                    *slot = v;
                }
                (*xq, *rq) = (outer, below_four);
            }
            let Some([w0, w1, w2, w3]) = wb
                .get_mut(c..c + 4)
                .and_then(|four| <&mut [T; 4]>::try_from(four).ok())
            else {
                return Err(outside(Resource::Vector, f + c, c + 4, wd));
            };
            let [l10, l20, l30, l21, l31, l32] = tri;
            let x0 = *w0;
            *w1 -= x0 * l10;
            *w2 -= x0 * l20;
            *w3 -= x0 * l30;
            let x1 = *w1;
            *w2 -= x1 * l21;
            *w3 -= x1 * l31;
            let x2 = *w2;
            *w3 -= x2 * l32;
            let xc = [x0, x1, x2, *w3];
            if let Some(below_four) = wb.get_mut(c + 4..) {
                axpy4_in_order(below_four, rest, xc);
            }
            axpy4(t, x, xc.map(|v| -v));
            c += 4;
        }
        // The last columns one at a time.
        while c < wd {
            let col = pan.column(l, f + c)?;
            let (Some((inner, outer)), Some(([.., xc], later))) = (
                col.split_at_checked(wd - c - 1),
                wb.split_at_mut_checked(c + 1),
            ) else {
                return Err(outside(Resource::FactorEntries, f + c, wd, col.len()));
            };
            let xc = *xc;
            axpy(later, inner, xc);
            axpy(t, outer, -xc);
            c += 1;
        }
        for (&r, &tv) in below.iter().zip(t.iter()) {
            match w.get_mut(ux(r)) {
                Some(wr) => *wr -= tv,
                None => return Err(outside(Resource::Vector, f, ux(r), w_len)),
            }
        }
    }
    // Diagonal.
    for (wj, &dj) in w.iter_mut().zip(d) {
        *wj /= dj;
    }
    // Backward: Lᵀ x = y.
    for s in (0..pan.count()).rev() {
        let (f, wd) = pan.span(s)?;
        let below = rows_below(f, wd)?;
        let Some(t) = tmp.get_mut(..below.len()) else {
            return Err(outside(Resource::Workspace, f, below.len(), tmp_len));
        };
        for (tv, &r) in t.iter_mut().zip(below) {
            match w.get(ux(r)) {
                Some(&wr) => *tv = wr,
                None => return Err(outside(Resource::Vector, f, ux(r), w_len)),
            }
        }
        let Some(wb) = w.get_mut(f..f + wd) else {
            return Err(outside(Resource::Vector, f, f + wd, w_len));
        };
        let mut c_end = wd;
        while c_end > 0 {
            // Columns c0..c_end, each looked up once and split into its rows in the diagonal
            // block and those below it: their products with the rows below first (four at once
            // share the loads of `t`), then the diagonal block, last column first.
            let c0 = c_end.saturating_sub(4);
            let width = c_end - c0;
            let mut inner: [&[T]; 4] = [&[]; 4];
            let mut x: [&[T]; 4] = [&[]; 4];
            for (q, (iq, xq)) in inner.iter_mut().zip(x.iter_mut()).enumerate().take(width) {
                let c = c0 + q;
                let col = pan.column(l, f + c)?;
                let Some((diagonal_block, below_it)) = col.split_at_checked(wd - c - 1) else {
                    return Err(outside(Resource::FactorEntries, f + c, wd, col.len()));
                };
                (*iq, *xq) = (diagonal_block, below_it);
            }
            let mut outer = [T::zero(); 4];
            if width == 4 {
                outer = dot4(x, t);
            } else {
                for (o, xq) in outer.iter_mut().zip(&x).take(width) {
                    *o = dot(xq, t);
                }
            }
            for (q, (&oc, iq)) in outer.iter().zip(&inner).enumerate().take(width).rev() {
                let c = c0 + q;
                let Some(([.., wc], later)) = wb.split_at_mut_checked(c + 1) else {
                    return Err(outside(Resource::Vector, f + c, c + 1, wd));
                };
                *wc -= oc + dot(iq, later);
            }
            c_end = c0;
        }
    }
    Ok(())
}
