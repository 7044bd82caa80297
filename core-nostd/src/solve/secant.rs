//! The secant memory of [`Strategy::QuasiNewton`](super::Strategy::QuasiNewton): the last
//! [`SECANT_PAIRS`] steps `s_k` and the gradient changes `y_k` they made, and the two-loop
//! recursion of limited-memory BFGS (Nocedal and Wright, *Numerical Optimization*, Alg. 7.4)
//! that turns a gradient into a step around one solve with the frozen factor.
//!
//! **Fixed cost.** The recursion runs over every slot, filled or not: an empty slot holds
//! zeros (`s = y = 0`, `1 / sᵀy` stored as 0), through which a vector passes unchanged, so a
//! frame costs the same before the memory has filled as after. A pair whose curvature `sᵀy`
//! is not positive (the energy not convex along the step) is not stored, so the matrix the
//! recursion applies stays positive definite.
//!
//! **Step scale.** Each step is the recursion's times a scale the memory keeps across frames:
//! halved after a step the line search refused, lengthened by a quarter (up to 1) after one it
//! took whole ([`SecantMemory::rescale`]), so that a frozen factor far softer than the body
//! where it stands now (whose steps overshoot) cannot make it refuse the same step forever.
//!
//! **Layout.** Slot `k` of the steps and of the changes lies at `k n .. (k + 1) n`, `n` the
//! unknowns of the topology in service; a cut changes `n`, and the memory is cleared with the
//! frozen factor then.
//!
//! **All or nothing.** [`SecantMemory::checkpoint`] copies the memory aside before a frame and
//! [`SecantMemory::rollback`] puts it back when the frame fails, bit for bit.

use crate::error::{Error, Resource};
use crate::real::Real;
use crate::solve::dot;
use crate::storage::{Fingerprint, Slab, prefix, prefix_mut, sum, times};

/// Pairs the quasi-Newton strategy remembers. On the liver, five did better than two and about
/// as well as ten (target error 1.61 against 2.03 and 1.62 mm with one step of one trial a
/// frame; twenty, 1.54 mm for four times the memory); each costs `4 n` multiply-adds a step.
pub const SECANT_PAIRS: usize = 5;

/// The shortest share of the recursion's step that refusals cut a step down to (2⁻²⁰: twenty
/// refusals in a row).
const MIN_SCALE: f64 = 9.5367431640625e-7;

/// How much longer the next step may be after a whole one: three whole steps to climb back
/// to a length refused before (1.25³ ≈ 2), so that a frozen factor that keeps overshooting has
/// a step refused about once in four rather than every other one (with 2, the liver's
/// quasi-Newton copy refused 30 of its 78 steps and the beam of
/// `a_quasi_newton_model_keeps_moving_after_its_line_search_refuses_a_step` stood still in 13
/// of its 40 frames; with 1.25, 20 and 3).
const GROWTH: f64 = 1.25;

/// The last [`SECANT_PAIRS`] steps and gradient changes, in caller storage (see the module
/// documentation).
#[derive(Debug)]
pub(crate) struct SecantMemory<'a, T> {
    /// The steps `s_k`.
    steps: &'a mut [T],
    /// The gradient changes `y_k`.
    changes: &'a mut [T],
    /// `1 / s_kᵀ y_k`, 0 for an empty slot.
    rho: &'a mut [T],
    /// The recursion's `α_k` (no meaning between calls).
    alpha: &'a mut [T],
    /// The slot the next pair goes to.
    next: usize,
    /// The length of the next step as a share of the recursion's (see
    /// [`SecantMemory::rescale`]).
    scale: T,
    /// What [`SecantMemory::checkpoint`] copied.
    saved_steps: &'a mut [T],
    saved_changes: &'a mut [T],
    saved_rho: &'a mut [T],
    saved_next: usize,
    saved_scale: T,
}

impl<'a, T: Real> SecantMemory<'a, T> {
    /// Scalars of storage for up to `unknowns` unknowns: the pairs, their copy, `1 / sᵀy`,
    /// its copy and the recursion's coefficients.
    pub(crate) const fn real_len(unknowns: usize) -> usize {
        sum(&[
            times(4, times(SECANT_PAIRS, unknowns)),
            times(3, SECANT_PAIRS),
        ])
    }

    /// An empty memory for up to `unknowns` unknowns, from `reals`
    /// ([`SecantMemory::real_len`] of them).
    ///
    /// # Errors
    /// [`Error::Capacity`] if the slab is too short.
    pub(crate) fn new(unknowns: usize, reals: &mut Slab<'a, T>) -> Result<Self, Error> {
        let pairs = times(SECANT_PAIRS, unknowns);
        let mut memory = SecantMemory {
            steps: reals.take(pairs)?,
            changes: reals.take(pairs)?,
            rho: reals.take(SECANT_PAIRS)?,
            alpha: reals.take(SECANT_PAIRS)?,
            next: 0,
            scale: T::one(),
            saved_steps: reals.take(pairs)?,
            saved_changes: reals.take(pairs)?,
            saved_rho: reals.take(SECANT_PAIRS)?,
            saved_next: 0,
            saved_scale: T::one(),
        };
        memory.clear();
        Ok(memory)
    }

    /// Forgets every pair (a new frozen factor, a cut).
    pub(crate) fn clear(&mut self) {
        for x in [&mut *self.steps, &mut *self.changes, &mut *self.rho] {
            x.fill(T::zero());
        }
        self.next = 0;
        self.scale = T::one();
    }

    /// The share of the recursion's step the next step takes (`1` unless steps were refused,
    /// see [`SecantMemory::rescale`]).
    pub(crate) fn scale(&self) -> T {
        self.scale
    }

    /// Follows the line search's verdict on a step: refused (`alpha` 0), the next step is half
    /// as long (down to [`MIN_SCALE`]); taken whole (`alpha` 1), [`GROWTH`] times as long, up
    /// to the recursion's own; taken shortened, as long.
    ///
    /// Why: the frozen factor is the Hessian where it was taken (at rest, or at a cut), and a
    /// body stretched far from there is stiffer (Saint Venant–Kirchhoff stiffens in tension,
    /// and the inversion barrier rises), so the recursion's step can overshoot. The pairs
    /// correct it only along the steps taken, and a refused step stores none: the next frame's
    /// step came out as long, was refused again, and the model stopped moving for good while
    /// its features moved on (the liver's quasi-Newton copy from its tenth frame; a beam pulled
    /// 40 px with stiff springs from its first, `tests/model_solve.rs`). With one trial
    /// nothing else shortens a step.
    pub(crate) fn rescale(&mut self, alpha: T) {
        if alpha == T::zero() {
            self.scale = (self.scale * T::of(0.5)).max(T::of(MIN_SCALE));
        } else if alpha >= T::one() {
            self.scale = (self.scale * T::of(GROWTH)).min(T::one());
        }
    }

    /// Stores the pair of a step `s` (`step`) that took the gradient from `before` to `after`
    /// (each `n` long), over the oldest, if its curvature `sᵀy` is positive. Returns whether it
    /// was stored.
    ///
    /// # Errors
    /// [`Error::Capacity`] if a vector or the memory is shorter than `n` unknowns need (not for
    /// a model built by its constructors).
    pub(crate) fn push(
        &mut self,
        n: usize,
        step: &[T],
        before: &[T],
        after: &[T],
    ) -> Result<bool, Error> {
        let (step, before, after) = (
            prefix(step, n, Resource::Unknowns)?,
            prefix(before, n, Resource::Unknowns)?,
            prefix(after, n, Resource::Unknowns)?,
        );
        let (mut sy, mut ss, mut yy) = (T::zero(), T::zero(), T::zero());
        for ((&s, &b), &a) in step.iter().zip(before).zip(after) {
            let y = a - b;
            sy += s * y;
            ss += s * s;
            yy += y * y;
        }
        // A curvature lost in the rounding of `y` is none.
        if !(sy > T::EPS * (ss * yy).sqrt()) {
            return Ok(false);
        }
        let slot = self.next;
        let at = times(slot, n);
        let s_slot = prefix_mut(
            self.steps.get_mut(at..).unwrap_or_default(),
            n,
            Resource::Unknowns,
        )?;
        let y_slot = prefix_mut(
            self.changes.get_mut(at..).unwrap_or_default(),
            n,
            Resource::Unknowns,
        )?;
        let Some(rho) = self.rho.get_mut(slot) else {
            return Err(Error::Capacity {
                resource: Resource::Unknowns,
                needed: slot + 1,
                available: SECANT_PAIRS,
            });
        };
        for (((s_out, y_out), &s), (&b, &a)) in s_slot
            .iter_mut()
            .zip(y_slot.iter_mut())
            .zip(step)
            .zip(before.iter().zip(after))
        {
            *s_out = s;
            *y_out = a - b;
        }
        *rho = T::one() / sy;
        self.next = (slot + 1) % SECANT_PAIRS;
        Ok(true)
    }

    /// Turns the gradient in `q` (`n` long) into `H q`, `H` the inverse of the frozen matrix
    /// corrected by the stored pairs: the two-loop recursion, with `solve` applying the frozen
    /// factor's inverse in place. The caller negates it for the step.
    ///
    /// # Errors
    /// What `solve` returns; [`Error::Capacity`] as in [`SecantMemory::push`].
    pub(crate) fn apply(
        &mut self,
        n: usize,
        q: &mut [T],
        solve: impl FnOnce(&mut [T]) -> Result<(), Error>,
    ) -> Result<(), Error> {
        let q = prefix_mut(q, n, Resource::Unknowns)?;
        // Newest first: slots next − 1, next − 2, … (mod the pairs).
        for back in 1..=SECANT_PAIRS {
            let slot = (self.next + SECANT_PAIRS - back) % SECANT_PAIRS;
            let (s, y) = slot_of(self.steps, self.changes, slot, n)?;
            let (Some(&rho), Some(alpha)) = (self.rho.get(slot), self.alpha.get_mut(slot)) else {
                continue;
            };
            let a = rho * dot(s, q);
            *alpha = a;
            for (qi, &yi) in q.iter_mut().zip(y) {
                *qi -= a * yi;
            }
        }
        solve(q)?;
        // Oldest first.
        for back in (1..=SECANT_PAIRS).rev() {
            let slot = (self.next + SECANT_PAIRS - back) % SECANT_PAIRS;
            let (s, y) = slot_of(self.steps, self.changes, slot, n)?;
            let (Some(&rho), Some(&alpha)) = (self.rho.get(slot), self.alpha.get(slot)) else {
                continue;
            };
            let c = alpha - rho * dot(y, q);
            for (qi, &si) in q.iter_mut().zip(s) {
                *qi += c * si;
            }
        }
        Ok(())
    }

    /// Multiply-adds of a step's two-loop recursion over `n` unknowns (two dot products and
    /// two vector updates per pair), besides its solve.
    pub(crate) const fn step_flops(n: usize) -> u64 {
        times(4, times(SECANT_PAIRS, n)) as u64
    }

    /// Multiply-adds of storing a pair of `n` unknowns (its three sums).
    pub(crate) const fn pair_flops(n: usize) -> u64 {
        times(3, n) as u64
    }

    /// Copies the memory of `n` unknowns aside. Returns the scalars copied.
    pub(crate) fn checkpoint(&mut self, n: usize) -> u64 {
        let len = times(SECANT_PAIRS, n);
        crate::storage::copy_front(self.saved_steps, self.steps, len);
        crate::storage::copy_front(self.saved_changes, self.changes, len);
        crate::storage::copy_front(self.saved_rho, self.rho, SECANT_PAIRS);
        self.saved_next = self.next;
        self.saved_scale = self.scale;
        Self::copies(n)
    }

    /// Puts back what [`SecantMemory::checkpoint`] copied for the same `n`.
    pub(crate) fn rollback(&mut self, n: usize) {
        let len = times(SECANT_PAIRS, n);
        crate::storage::copy_front(self.steps, self.saved_steps, len);
        crate::storage::copy_front(self.changes, self.saved_changes, len);
        crate::storage::copy_front(self.rho, self.saved_rho, SECANT_PAIRS);
        self.next = self.saved_next;
        self.scale = self.saved_scale;
    }

    /// Scalars a checkpoint of `n` unknowns copies.
    pub(crate) const fn copies(n: usize) -> u64 {
        // The pairs, `1 / sᵀy`, and the step scale.
        (times(2, times(SECANT_PAIRS, n)) + SECANT_PAIRS + 1) as u64
    }

    /// Hashes the memory of `n` unknowns.
    pub(crate) fn fingerprint_into(&self, n: usize, h: &mut Fingerprint) {
        let len = times(SECANT_PAIRS, n);
        h.reals(self.steps.iter().take(len));
        h.reals(self.changes.iter().take(len));
        h.reals(self.rho.iter());
        h.words(core::iter::once(&(self.next as u32)));
        h.reals(core::iter::once(&self.scale));
    }
}

/// The step and the change of `slot` (`n` each) in the memory's `steps` and `changes`.
fn slot_of<'m, T>(
    steps: &'m [T],
    changes: &'m [T],
    slot: usize,
    n: usize,
) -> Result<(&'m [T], &'m [T]), Error> {
    let at = times(slot, n);
    Ok((
        prefix(steps.get(at..).unwrap_or_default(), n, Resource::Unknowns)?,
        prefix(changes.get(at..).unwrap_or_default(), n, Resource::Unknowns)?,
    ))
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;

    const N: usize = 6;

    /// A symmetric positive definite `A` (a tridiagonal stiffness), `A x`.
    fn a_times(x: &[f64]) -> [f64; N] {
        let mut y = [0.0; N];
        for i in 0..N {
            y[i] = (3.0 + i as f64) * x[i];
            if i > 0 {
                y[i] -= x[i - 1];
            }
            if i + 1 < N {
                y[i] -= x[i + 1];
            }
        }
        y
    }

    /// The initial inverse: the inverse of `A`'s diagonal (a frozen matrix that is not `A`).
    fn diagonal_solve(q: &mut [f64]) -> Result<(), Error> {
        for (i, x) in q.iter_mut().enumerate() {
            *x /= 3.0 + i as f64;
        }
        Ok(())
    }

    fn h_times(memory: &mut SecantMemory<'_, f64>, x: &[f64; N]) -> [f64; N] {
        let mut q = *x;
        memory.apply(N, &mut q, diagonal_solve).unwrap();
        q
    }

    /// Each stored pair of a quadratic energy (`y = A s`) makes the newest satisfy the secant
    /// equation `H y = s` (the defining property of the BFGS update), `H` stays symmetric and
    /// positive definite, an empty memory applies the initial inverse alone, and a pair of
    /// negative curvature is refused without a trace.
    #[test]
    fn the_recursion_satisfies_the_secant_equation_and_stays_positive_definite() {
        let mut reals = [0.0; SecantMemory::<f64>::real_len(N)];
        let mut slab = Slab::new(&mut reals, Resource::RealStorage);
        let mut memory = SecantMemory::new(N, &mut slab).unwrap();
        let e = |k: usize| {
            let mut x = [0.0; N];
            x[k % N] = 1.0;
            x
        };
        // Empty: the initial inverse alone.
        let x = [1.0, -2.0, 0.5, 3.0, -1.0, 2.0];
        let mut d = x;
        diagonal_solve(&mut d).unwrap();
        assert_eq!(h_times(&mut memory, &x), d);
        let zero = [0.0; N];
        for k in 0..2 * SECANT_PAIRS {
            // Steps that are not eigenvectors of `A`, so that every pair corrects `H`.
            let s: [f64; N] = core::array::from_fn(|i| ((i * 7 + k * 3) % 5) as f64 - 1.7);
            let y = a_times(&s);
            assert!(memory.push(N, &s, &zero, &y).unwrap());
            let hy = h_times(&mut memory, &y);
            for (a, b) in hy.iter().zip(&s) {
                assert!(
                    (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                    "pair {k}: H y {a} s {b}"
                );
            }
            // Symmetric and positive definite on the unit vectors and their sums.
            for i in 0..N {
                let hi = h_times(&mut memory, &e(i));
                assert!(hi[i] > 0.0);
                for j in 0..N {
                    let hj = h_times(&mut memory, &e(j));
                    assert!((hi[j] - hj[i]).abs() <= 1e-12 * (hi[j].abs() + 1.0));
                    let mut sum = e(i);
                    sum[j] += 1.0;
                    let hs = h_times(&mut memory, &sum);
                    assert!(hs.iter().zip(&sum).map(|(a, b)| a * b).sum::<f64>() > 0.0);
                }
            }
        }
        // Negative curvature (`y = −s`): refused, the memory unchanged.
        let mut before = Fingerprint::new();
        memory.fingerprint_into(N, &mut before);
        let s = [1.0; N];
        let y = s.map(|v| -v);
        assert!(!memory.push(N, &s, &zero, &y).unwrap());
        let mut after = Fingerprint::new();
        memory.fingerprint_into(N, &mut after);
        assert_eq!(before.finish(), after.finish());
        // A checkpoint and a rollback give the memory back bit for bit after more pairs.
        memory.checkpoint(N);
        let s = [0.3, 0.1, -0.2, 0.4, 0.0, 1.0];
        assert!(memory.push(N, &s, &zero, &a_times(&s)).unwrap());
        memory.rollback(N);
        let mut rolled = Fingerprint::new();
        memory.fingerprint_into(N, &mut rolled);
        assert_eq!(before.finish(), rolled.finish());
        // Cleared: the initial inverse alone again.
        memory.clear();
        assert_eq!(h_times(&mut memory, &x), d);
    }

    /// The step scale: halved by each refused step down to its floor, lengthened by each whole
    /// step up to 1, kept by a shortened one; part of the fingerprint, put back by a rollback,
    /// reset by a clear.
    #[test]
    fn refused_steps_shorten_the_next_and_whole_ones_lengthen_it_back() {
        let mut reals = [0.0; SecantMemory::<f64>::real_len(N)];
        let mut slab = Slab::new(&mut reals, Resource::RealStorage);
        let mut memory = SecantMemory::new(N, &mut slab).unwrap();
        assert_eq!(memory.scale(), 1.0);
        memory.rescale(1.0);
        assert_eq!(memory.scale(), 1.0);
        memory.rescale(0.0);
        memory.rescale(0.0);
        assert_eq!(memory.scale(), 0.25);
        memory.rescale(0.5);
        assert_eq!(memory.scale(), 0.25);
        let mut before = Fingerprint::new();
        memory.fingerprint_into(N, &mut before);
        memory.checkpoint(N);
        memory.rescale(1.0);
        assert_eq!(memory.scale(), 0.25 * GROWTH);
        let mut grown = Fingerprint::new();
        memory.fingerprint_into(N, &mut grown);
        assert_ne!(before.finish(), grown.finish());
        memory.rollback(N);
        assert_eq!(memory.scale(), 0.25);
        for _ in 0..100 {
            memory.rescale(0.0);
        }
        assert_eq!(memory.scale(), MIN_SCALE);
        for _ in 0..200 {
            memory.rescale(1.0);
        }
        assert_eq!(memory.scale(), 1.0);
        memory.rescale(0.0);
        memory.clear();
        assert_eq!(memory.scale(), 1.0);
    }
}
