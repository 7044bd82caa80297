//! The elements' share of the gradient where the nodes stand, kept from one frame to the next
//! by [`Strategy::QuasiNewton`](super::Strategy::QuasiNewton) with one line-search trial.
//!
//! **Why.** The elastic energy depends on the positions alone. A frame ends where its last
//! step's assembled trial put the nodes and the next frame starts there: only the springs (new
//! observations), the damping and the depth prior (a new reference) have changed. A strategy
//! that assembles no tangents can start the frame from the elements' share of the last
//! assembly and evaluate the rest, one pass over the elements less per frame (on the liver, a
//! third of its element work).
//!
//! **When it is valid.** Exactly while the positions and the mesh are those it was kept at:
//! every accepted step keeps its trial's share ([`KeptElements::accept`]), the frozen factor's
//! assembly and a cut's rebuild keep theirs once they succeed, and whatever else moves the
//! nodes or changes the strategy forgets it ([`KeptElements::forget`]); a frame whose share
//! is not valid evaluates it (a one-off cost, like the frozen factor's after a switch).
//!
//! **All or nothing.** [`KeptElements::checkpoint`] copies it aside before a frame and
//! [`KeptElements::rollback`] puts it back when the frame fails, bit for bit.

use crate::error::Error;
use crate::error::Resource;
use crate::real::Real;
use crate::solve::assembly::ElementSums;
use crate::storage::{Fingerprint, Slab, copy_front, prefix, prefix_mut, times};

/// The elements' gradient share and sums at the positions in service, a trial's (scratch
/// between calls) and a checkpoint's copy, in caller storage (see the module documentation).
#[derive(Debug)]
pub(crate) struct KeptElements<'a, T> {
    gradient: &'a mut [T],
    sums: ElementSums<T>,
    valid: bool,
    /// Where an assembly whose positions may not be taken keeps its share (no meaning
    /// between calls).
    trial: &'a mut [T],
    trial_sums: ElementSums<T>,
    saved: &'a mut [T],
    saved_sums: ElementSums<T>,
    saved_valid: bool,
}

impl<'a, T: Real> KeptElements<'a, T> {
    /// Scalars of storage for up to `unknowns` unknowns: the share, a trial's and the copy.
    pub(crate) const fn real_len(unknowns: usize) -> usize {
        times(3, unknowns)
    }

    /// Nothing kept, for up to `unknowns` unknowns, from `reals` ([`KeptElements::real_len`]
    /// of them).
    ///
    /// # Errors
    /// [`Error::Capacity`] if the slab is too short.
    pub(crate) fn new(unknowns: usize, reals: &mut Slab<'a, T>) -> Result<Self, Error> {
        Ok(KeptElements {
            gradient: reals.take(unknowns)?,
            sums: ElementSums::default(),
            valid: false,
            trial: reals.take(unknowns)?,
            trial_sums: ElementSums::default(),
            saved: reals.take(unknowns)?,
            saved_sums: ElementSums::default(),
            saved_valid: false,
        })
    }

    /// The share kept for `n` unknowns, if it is valid.
    pub(crate) fn current(&self, n: usize) -> Option<(&[T], ElementSums<T>)> {
        if !self.valid {
            return None;
        }
        prefix(self.gradient, n, Resource::Unknowns)
            .ok()
            .map(|g| (g, self.sums))
    }

    /// Where an assembly of `n` unknowns keeps the share of positions not yet taken.
    ///
    /// # Errors
    /// [`Error::Capacity`] for more unknowns than the storage holds.
    pub(crate) fn trial_mut(&mut self, n: usize) -> Result<(&mut [T], &mut ElementSums<T>), Error> {
        Ok((
            prefix_mut(self.trial, n, Resource::Unknowns)?,
            &mut self.trial_sums,
        ))
    }

    /// The positions of the trial's share of `n` unknowns are taken: it becomes the share in
    /// service. Returns the scalars copied.
    pub(crate) fn accept(&mut self, n: usize) -> u64 {
        copy_front(self.gradient, self.trial, n);
        self.sums = self.trial_sums;
        self.valid = true;
        n as u64
    }

    /// The nodes moved, or the mesh changed, without an assembly keeping its share.
    pub(crate) fn forget(&mut self) {
        self.valid = false;
    }

    /// Copies the share of `n` unknowns aside. Returns the scalars copied.
    pub(crate) fn checkpoint(&mut self, n: usize) -> u64 {
        copy_front(self.saved, self.gradient, n);
        self.saved_sums = self.sums;
        self.saved_valid = self.valid;
        Self::copies(n)
    }

    /// Puts back what [`KeptElements::checkpoint`] copied for the same `n`.
    pub(crate) fn rollback(&mut self, n: usize) {
        copy_front(self.gradient, self.saved, n);
        self.sums = self.saved_sums;
        self.valid = self.saved_valid;
    }

    /// Scalars a checkpoint of `n` unknowns copies.
    pub(crate) const fn copies(n: usize) -> u64 {
        n as u64
    }

    /// Hashes the share of `n` unknowns and whether it is valid.
    pub(crate) fn fingerprint_into(&self, n: usize, h: &mut Fingerprint) {
        h.words(core::iter::once(&u32::from(self.valid)));
        if self.valid {
            h.reals(self.gradient.iter().take(n));
            h.reals([self.sums.energy, self.sums.force_sum].iter());
        }
    }
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;

    const N: usize = 4;

    fn fingerprint(kept: &KeptElements<'_, f64>) -> u64 {
        let mut h = Fingerprint::new();
        kept.fingerprint_into(N, &mut h);
        h.finish()
    }

    /// Keeps `values` as a trial's share and takes it.
    fn keep(kept: &mut KeptElements<'_, f64>, values: [f64; N], energy: f64) {
        let (share, sums) = kept.trial_mut(N).unwrap();
        share.copy_from_slice(&values);
        *sums = ElementSums {
            energy,
            force_sum: 1.0,
        };
        kept.accept(N);
    }

    #[test]
    fn a_share_is_valid_from_its_acceptance_to_a_forget_and_a_rollback_restores_it() {
        let mut reals = [0.0; KeptElements::<f64>::real_len(N)];
        let mut slab = Slab::new(&mut reals, Resource::RealStorage);
        let mut kept = KeptElements::new(N, &mut slab).unwrap();
        assert!(kept.current(N).is_none());
        // A trial not taken is not the share.
        kept.trial_mut(N).unwrap().0.fill(7.0);
        assert!(kept.current(N).is_none());
        keep(&mut kept, [1.0, 2.0, 3.0, 4.0], 5.0);
        let (share, sums) = kept.current(N).unwrap();
        assert_eq!(share, &[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(sums.energy, 5.0);
        // A checkpoint, a share taken and a forget after it: the rollback gives back the
        // share and its validity bit for bit.
        let before = fingerprint(&kept);
        assert_eq!(kept.checkpoint(N), KeptElements::<f64>::copies(N));
        keep(&mut kept, [9.0; N], 6.0);
        assert_ne!(fingerprint(&kept), before);
        kept.forget();
        assert!(kept.current(N).is_none());
        kept.rollback(N);
        assert_eq!(fingerprint(&kept), before);
        assert_eq!(kept.current(N).unwrap().0, &[1.0, 2.0, 3.0, 4.0]);
        // A share of more unknowns than the storage holds is refused.
        assert!(kept.trial_mut(N + 1).is_err());
        assert!(kept.current(N + 1).is_none());
    }
}
