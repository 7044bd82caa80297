//! Carving caller-owned storage into the pieces a structure needs.
//!
//! The core never allocates: a constructor takes one slice per element type (`&mut [u32]` for
//! indices, `&mut [T]` for scalars) whose required length a sibling `*_len` function reports
//! before anything is built, and splits it with a [`Slab`].

use crate::error::{Error, Resource};

/// Hands out consecutive, disjoint pieces of one caller-owned slice.
pub struct Slab<'a, X> {
    rest: &'a mut [X],
    resource: Resource,
    needed: usize,
    total: usize,
}

impl<'a, X> Slab<'a, X> {
    /// Wraps `buf`; errors name `resource` when it runs out.
    pub fn new(buf: &'a mut [X], resource: Resource) -> Self {
        let total = buf.len();
        Slab {
            rest: buf,
            resource,
            needed: 0,
            total,
        }
    }

    /// Takes the next `n` entries.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming the slab's resource when fewer than `n` entries remain; the
    /// slab is unchanged then.
    pub fn take(&mut self, n: usize) -> Result<&'a mut [X], Error> {
        if n > self.rest.len() {
            return Err(Error::Capacity {
                resource: self.resource,
                needed: self.needed.saturating_add(n),
                available: self.total,
            });
        }
        let rest = core::mem::take(&mut self.rest);
        let (head, tail) = rest.split_at_mut(n);
        self.rest = tail;
        // At most the slab's length: `needed` counts entries handed out of it.
        self.needed = self.needed.saturating_add(n);
        Ok(head)
    }

    /// Entries not handed out yet.
    pub fn remaining(&self) -> usize {
        self.rest.len()
    }

    /// Entries handed out so far.
    pub fn used(&self) -> usize {
        self.needed
    }
}

/// `k · x`, saturated at `usize::MAX`.
///
/// Storage lengths are sums of products of the caller's capacities, and every `*_len` function
/// of the core computes them with [`times`] and [`sum`]. Both saturate, and saturating `+` and
/// `·` never give less than the true value (or less than `usize::MAX` when the true value does
/// not fit), so a length that overflows becomes `usize::MAX`, which no slice of a sized type
/// can have: the [`ensure_len`] or [`Slab::take`] that follows refuses it with
/// [`Error::Capacity`] instead of panicking or wrapping to a short length. A length that does
/// not saturate is exact, and so is every term of it.
pub const fn times(k: usize, x: usize) -> usize {
    k.saturating_mul(x)
}

/// The sum of `terms`, saturated at `usize::MAX` (see [`times`]).
pub const fn sum(terms: &[usize]) -> usize {
    let mut total = 0usize;
    let mut rest = terms;
    while let [first, tail @ ..] = rest {
        total = total.saturating_add(*first);
        rest = tail;
    }
    total
}

/// Checks that `slice` has at least `needed` entries.
///
/// # Errors
/// [`Error::Capacity`] naming `resource` otherwise.
pub fn ensure_len<X>(slice: &[X], needed: usize, resource: Resource) -> Result<(), Error> {
    if slice.len() < needed {
        Err(Error::Capacity {
            resource,
            needed,
            available: slice.len(),
        })
    } else {
        Ok(())
    }
}

/// Copies the first `n` entries of `from` over those of `to`, as far as both reach: the callers
/// have checked both lengths, and a shorter slice would copy less rather than panic.
pub(crate) fn copy_front<X: Copy>(to: &mut [X], from: &[X], n: usize) {
    for (t, f) in to.iter_mut().zip(from).take(n) {
        *t = *f;
    }
}

/// The first `len` entries of `slice`.
///
/// # Errors
/// [`Error::Capacity`] naming `resource` if `slice` is shorter (as [`ensure_len`]).
pub(crate) fn prefix<X>(slice: &[X], len: usize, resource: Resource) -> Result<&[X], Error> {
    slice.get(..len).ok_or(Error::Capacity {
        resource,
        needed: len,
        available: slice.len(),
    })
}

/// The first `len` entries of `slice`, mutable.
///
/// # Errors
/// [`Error::Capacity`] naming `resource` if `slice` is shorter (as [`ensure_len`]).
pub(crate) fn prefix_mut<X>(
    slice: &mut [X],
    len: usize,
    resource: Resource,
) -> Result<&mut [X], Error> {
    let available = slice.len();
    slice.get_mut(..len).ok_or(Error::Capacity {
        resource,
        needed: len,
        available,
    })
}

/// Checks that `slice` has exactly `expected` entries.
///
/// # Errors
/// [`Error::Length`] naming `resource` otherwise.
pub fn ensure_exact_len<X>(slice: &[X], expected: usize, resource: Resource) -> Result<(), Error> {
    if slice.len() != expected {
        Err(Error::Length {
            resource,
            expected,
            found: slice.len(),
        })
    } else {
        Ok(())
    }
}

/// FNV-1a over the bits of a model's state buffers ([`crate::Model::fingerprint`]).
pub(crate) struct Fingerprint(u64);

impl Fingerprint {
    pub fn new() -> Self {
        Fingerprint(0xcbf2_9ce4_8422_2325)
    }

    fn byte_word(&mut self, w: u64) {
        for b in w.to_le_bytes() {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// Hashes index words.
    pub fn words<'w>(&mut self, words: impl IntoIterator<Item = &'w u32>) {
        for &w in words {
            self.byte_word(u64::from(w));
        }
    }

    /// Hashes scalars by their bits (as `f64`, exact for `f32`).
    pub fn reals<'r, T: crate::Real + 'r>(&mut self, reals: impl IntoIterator<Item = &'r T>) {
        for &r in reals {
            self.byte_word(r.to_f64().to_bits());
        }
    }

    pub fn finish(&self) -> u64 {
        self.0
    }
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;

    #[test]
    fn slab_hands_out_disjoint_pieces_and_reports_overflow() {
        let mut buf = [0u32; 5];
        let mut slab = Slab::new(&mut buf, Resource::IndexStorage);
        let a = slab.take(2).unwrap();
        let b = slab.take(3).unwrap();
        a[0] = 1;
        b[2] = 7;
        assert_eq!(
            slab.take(1),
            Err(Error::Capacity {
                resource: Resource::IndexStorage,
                needed: 6,
                available: 5
            })
        );
        assert_eq!(buf, [1, 0, 0, 0, 7]);
    }
}
