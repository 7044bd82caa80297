//! Robust statistics in caller storage: a bounded in-place sort and selection, quantiles and
//! the median absolute deviation.
//!
//! The detector calibrates its thresholds from the data of each frame (see
//! [`crate::detect`]); the median and the median absolute deviation (MAD) ignore the few large
//! values a cut or a tracking failure produces, where the mean and the standard deviation
//! follow them. Both need one value of known rank, not the whole order: [`select`] finds it
//! with a heap of the `h` values nearest that end (`h` at most half the values), bounded by
//! `2 n ⌈log₂ n⌉` comparisons whatever the data: for a median about half of [`sort`]'s
//! heapsort (`2 n ⌈log₂ n⌉ + 2 n`), since the heap is half as large and no value is taken
//! out of it again. Neither recursion nor extra storage.

use crate::real::Real;

/// `⌈log₂ n⌉` for `n ≥ 1` (0 for 0 and 1).
pub const fn ceil_log2(n: u64) -> u64 {
    if n <= 1 {
        0
    } else {
        64 - (n - 1).leading_zeros() as u64
    }
}

/// Most comparisons [`sort`] makes on `n` values.
pub const fn sort_bound(n: u64) -> u64 {
    2 * n * ceil_log2(n) + 2 * n
}

/// Sorts `v` ascending in place (heapsort: bounded, not stable); returns the comparisons made.
/// A NaN compares as larger than everything, so it cannot stall the sort.
pub fn sort<T: Real>(v: &mut [T]) -> u64 {
    let mut comparisons = 0u64;
    let n = v.len();
    // A max-heap of v[..end], its largest moved behind it one by one.
    let larger_first = |a: T, b: T| less(b, a);
    for root in (0..n / 2).rev() {
        sift(v, root, n, false, larger_first, &mut comparisons);
    }
    for end in (1..n).rev() {
        v.swap(0, end);
        sift(v, 0, end, false, larger_first, &mut comparisons);
    }
    comparisons
}

/// Moves `v[root]` down the heap `v[..end]` whose root is first in `root_first` order; with
/// `whole`, walks on to a leaf along the children `root_first` prefers even where the heap
/// already holds (it then swaps nothing). Adds its comparisons to `comparisons`.
fn sift<T: Real>(
    v: &mut [T],
    mut root: usize,
    end: usize,
    whole: bool,
    root_first: impl Fn(T, T) -> bool,
    comparisons: &mut u64,
) {
    loop {
        let mut child = 2 * root + 1;
        if child >= end {
            break;
        }
        if let (Some(&a), Some(&b)) = (v.get(child), v.get(child + 1))
            && child + 1 < end
        {
            *comparisons += 1;
            if root_first(b, a) {
                child += 1;
            }
        }
        *comparisons += 1;
        match (v.get(root), v.get(child)) {
            (Some(&r), Some(&c)) if root_first(c, r) => v.swap(root, child),
            _ if whole => {}
            _ => break,
        }
        root = child;
    }
}

/// Most comparisons [`select`] makes on `n` values, whatever the rank.
pub const fn select_bound(n: u64) -> u64 {
    2 * n * ceil_log2(n)
}

/// Whether `a` orders before `b`: ascending, with every non-finite value (`±∞`, NaN) after
/// every finite one, so that a NaN cannot stall an ordering.
fn less<T: Real>(a: T, b: T) -> bool {
    a < b || (!b.finite() && a.finite())
}

/// The value of rank `k` (0-based, ascending as [`sort`] orders) of `v`, and the comparisons
/// made; zero (and none) when `k` is out of range. `v` is reordered.
///
/// A heap holds the `h = min(k + 1, n − k)` values nearest the nearer end, the rank-`k` one at
/// its root (a max-heap of the `k + 1` smallest, or a min-heap of the `n − k` largest); each
/// other value is compared with the root once and enters only if it belongs nearer that end.
/// Building the heap takes at most `2 h` comparisons and each later value `1 + 2 ⌊log₂ h⌋`,
/// so with `h ≤ ⌈n/2⌉` the total stays within [`select_bound`].
pub fn select<T: Real>(v: &mut [T], k: usize) -> (T, u64) {
    let n = v.len();
    if k >= n {
        return (T::zero(), 0);
    }
    let comparisons = if k < n - k {
        // Keeps the `k + 1` smallest; the largest of them at the root.
        heap_select(v, k + 1, |a, b| less(b, a))
    } else {
        // Keeps the `n − k` largest; the smallest of them at the root.
        heap_select(v, n - k, less)
    };
    (v.first().copied().unwrap_or_else(T::zero), comparisons)
}

/// Arranges `v[..h]` as a heap whose root is first in `root_first` order among them, then
/// lets in each later value that `root_first` puts after the root (in place of the root).
/// Returns the comparisons made.
///
/// After each later value the root is sifted down the whole depth of the heap, whether the
/// value entered or not (the walk then swaps nothing: the heap already holds): a frame costs
/// the same however many values enter, which depends on their order, so the detector's work
/// does not follow its data (see `median_mad_of`). Stopping where nothing entered made the
/// liver's steady frame 4 % cheaper (42.0 against 43.8 million instructions) but let its
/// steady frames vary by 2.1 % instead of 1.4 % (issue 14 asks for at most 2 %; heapsort's
/// 1.7 %).
fn heap_select<T: Real>(v: &mut [T], h: usize, root_first: impl Fn(T, T) -> bool) -> u64 {
    let mut comparisons = 0u64;
    for root in (0..h / 2).rev() {
        sift(v, root, h, false, &root_first, &mut comparisons);
    }
    for i in h..v.len() {
        comparisons += 1;
        if let (Some(&top), Some(&x)) = (v.first(), v.get(i))
            && root_first(top, x)
        {
            v.swap(0, i);
        }
        sift(v, 0, h, true, &root_first, &mut comparisons);
    }
    comparisons
}

/// The index of fraction `q` ∈ [0, 1] in `count` sorted values: the lower one of two
/// neighbours, `⌊q (count − 1)⌋`.
pub fn quantile_index<T: Real>(count: usize, q: T) -> usize {
    let last = count.saturating_sub(1);
    let k = libm::floor(q.to_f64().clamp(0.0, 1.0) * last as f64) as usize;
    k.min(last)
}

/// The value at fraction `q` ∈ [0, 1] of sorted `v` ([`quantile_index`]); zero for an empty
/// slice.
pub fn quantile_sorted<T: Real>(v: &[T], q: T) -> T {
    v.get(quantile_index(v.len(), q))
        .copied()
        .unwrap_or_else(T::zero)
}

/// The value at fraction `q` of the first `count` values of `v` (as [`quantile_sorted`] of
/// them sorted), and the comparisons made; zero for `count` 0. The values from `count` on are
/// overwritten with `+∞` and take part, so that the work depends on `v.len()`, not on `count`
/// (see [`median_mad_of`]); `v` is reordered.
pub fn quantile_of<T: Real>(v: &mut [T], count: usize, q: T) -> (T, u64) {
    let count = count.min(v.len());
    pad(v, count);
    let (value, comparisons) = select(v, quantile_index(count, q));
    if count == 0 {
        (T::zero(), comparisons)
    } else {
        (value, comparisons)
    }
}

/// Median and MAD of `v` (reordered and then overwritten with the absolute deviations);
/// returns `(median, mad, comparisons)`. The MAD of normally distributed values is 0.6745
/// standard deviations.
pub fn median_mad<T: Real>(v: &mut [T]) -> (T, T, u64) {
    let n = v.len();
    median_mad_of(v, n)
}

/// Median and MAD of the first `count` values of `v`, as [`median_mad`]; the values after them
/// are overwritten with `+∞` and take part in both selections. The work then depends on
/// `v.len()`, not on `count`: a caller that passes all the slots it has in use makes every
/// frame select among as many, however many of them it measured. The `+∞`s order after every
/// finite value, and their deviations from a finite median are `+∞` again (from any other
/// median, NaN: still after every finite value), so the result is [`median_mad`] of
/// `v[..count]`.
pub fn median_mad_of<T: Real>(v: &mut [T], count: usize) -> (T, T, u64) {
    let count = count.min(v.len());
    let (median, mut comparisons) = quantile_of(v, count, T::of(0.5));
    // Every slot, not only the first `count`: `select` has moved the values about.
    for x in v.iter_mut() {
        *x = (*x - median).abs();
    }
    let (mad, more) = select(v, quantile_index(count, T::of(0.5)));
    comparisons += more;
    if count == 0 {
        (T::zero(), T::zero(), comparisons)
    } else {
        (median, mad, comparisons)
    }
}

/// Sets the values of `v` from `count` on to `+∞`.
pub fn pad<T: Real>(v: &mut [T], count: usize) {
    for x in v.iter_mut().skip(count) {
        *x = T::of(f64::INFINITY);
    }
}

/// Standard deviations per MAD for normally distributed values (`1 / Φ⁻¹(3/4)`).
pub const MAD_TO_SIGMA: f64 = 1.482_602_218_505_602;

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;

    #[test]
    fn sorts_within_its_bound() {
        // A deterministic shuffle of 0..200 with duplicates and a NaN.
        let mut v = [0.0f64; 201];
        for (k, x) in v.iter_mut().enumerate() {
            *x = ((k * 73) % 200) as f64 / 2.0;
        }
        v[17] = f64::NAN;
        let c = sort(&mut v);
        assert!(c <= sort_bound(201), "{c}");
        assert!(v[..200].windows(2).all(|w| w[0] <= w[1]));
        assert!(v[200].is_nan());
        let mut empty: [f64; 0] = [];
        assert_eq!(sort(&mut empty), 0);
    }

    /// A deterministic shuffle of `n` values with runs of duplicates, a `-0.0` beside `0.0`,
    /// and (with `non_finite`) a NaN and a `+∞` among them.
    fn shuffled(n: usize, seed: usize, non_finite: bool) -> [f64; 64] {
        let mut v = [0.0f64; 64];
        for (k, x) in v.iter_mut().take(n).enumerate() {
            *x = (((k + seed) * 37) % 23) as f64 - 11.0;
        }
        if n > 5 {
            v[(seed * 7) % n] = -0.0;
        }
        if non_finite && n > 2 {
            v[(seed * 5) % n] = f64::NAN;
            v[(seed * 11 + 1) % n] = f64::INFINITY;
        }
        v
    }

    #[test]
    fn select_finds_the_sorted_value_of_every_rank_within_its_bound() {
        for n in 0..=64 {
            for seed in 0..4 {
                let mut sorted = shuffled(n, seed, seed % 2 == 1);
                sort(&mut sorted[..n]);
                for k in 0..=n {
                    let mut v = shuffled(n, seed, seed % 2 == 1);
                    let (got, comparisons) = select(&mut v[..n], k);
                    let expected = sorted.get(k).filter(|_| k < n).copied().unwrap_or(0.0);
                    // The same value of the order (a `±0.0` or a non-finite value may be
                    // another of its equals).
                    assert!(
                        got == expected || !(got.is_finite() || expected.is_finite()),
                        "n {n} seed {seed} rank {k}: {got} against {expected}"
                    );
                    assert!(
                        comparisons <= select_bound(n as u64),
                        "{n} {k} {comparisons}"
                    );
                    // The values are only moved about (sorted again, equals may swap).
                    let mut after = v;
                    sort(&mut after[..n]);
                    let same = |(a, b): (&f64, &f64)| a == b || !(a.is_finite() || b.is_finite());
                    assert!(after[..n].iter().zip(&sorted[..n]).all(same));
                }
            }
        }
    }

    #[test]
    fn select_costs_less_than_a_sort_and_the_same_whatever_the_order() {
        // 4001 values scrambled (as the detector's differences come), ascending and
        // descending: the median's comparisons against the heapsort's on the same values.
        let scrambled: [f64; 4001] = core::array::from_fn(|k| ((k * 2_654_435_761) % 4001) as f64);
        let ascending: [f64; 4001] = core::array::from_fn(|k| k as f64);
        let descending: [f64; 4001] = core::array::from_fn(|k| (4000 - k) as f64);
        let mut w = scrambled;
        let sorted = sort(&mut w);
        let counts = [scrambled, ascending, descending].map(|mut v| {
            let (median, comparisons) = select(&mut v, 2000);
            assert_eq!(median, 2000.0);
            comparisons
        });
        let (lo, hi) = (counts.iter().min().unwrap(), counts.iter().max().unwrap());
        assert!(*hi < sorted * 3 / 5, "{counts:?} against {sorted}");
        // Only the heap's build depends on the order.
        assert!(hi - lo <= 2 * 2001, "{counts:?}");
    }

    #[test]
    fn padded_median_and_mad_equal_those_of_the_values_alone() {
        let values = [4.0, -1.5, 9.25, 3.0, 3.0, 0.5, 12.0];
        for count in 0..=values.len() {
            let mut alone = values;
            let expected = median_mad(&mut alone[..count]);
            let mut padded = [0.0f64; 20];
            padded[..count].copy_from_slice(&values[..count]);
            let got = median_mad_of(&mut padded, count);
            assert_eq!(got.0.to_bits(), expected.0.to_bits(), "{count}");
            assert_eq!(got.1.to_bits(), expected.1.to_bits(), "{count}");
            assert!(got.2 <= 2 * select_bound(20), "{count}");
            // And the padded quantile equals the sorted values' one.
            let mut sorted = values;
            sort(&mut sorted[..count]);
            let mut padded = [0.0f64; 20];
            padded[..count].copy_from_slice(&values[..count]);
            let third = quantile_of(&mut padded, count, 1.0 / 3.0);
            assert_eq!(
                third.0,
                quantile_sorted(&sorted[..count], 1.0 / 3.0),
                "{count}"
            );
            assert!(third.1 <= select_bound(20));
        }
    }

    #[test]
    fn median_and_mad_ignore_a_few_large_values() {
        // 1..=9 with the largest replaced by 1e6: median 5, MAD 2, as for 1..=9.
        let mut v = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 1e6];
        let (m, mad, _) = median_mad(&mut v);
        assert_eq!((m, mad), (5.0, 2.0));
        assert_eq!(quantile_sorted(&[1.0, 2.0, 3.0, 4.0], 1.0 / 3.0), 2.0);
        assert_eq!(quantile_sorted::<f64>(&[], 0.5), 0.0);
        assert_eq!((ceil_log2(1), ceil_log2(2), ceil_log2(5)), (0, 1, 3));
    }
}
