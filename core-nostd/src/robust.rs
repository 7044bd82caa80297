//! Robust statistics in caller storage: a bounded in-place sort, quantiles and the median
//! absolute deviation.
//!
//! The detector calibrates its thresholds from the data of each frame (see
//! [`crate::detect`]); the median and the median absolute deviation (MAD) ignore the few large
//! values a cut or a tracking failure produces, where the mean and the standard deviation
//! follow them. Heapsort keeps the cost bounded by `2 n ⌈log₂ n⌉ + 2 n` comparisons whatever the
//! data, with no recursion and no extra storage.

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
    let less = |a: T, b: T| a < b || (!b.finite() && a.finite());
    let mut comparisons = 0u64;
    let n = v.len();
    // Moves v[root] down the max-heap v[..end].
    let sift = |v: &mut [T], mut root: usize, end: usize, comparisons: &mut u64| {
        loop {
            let mut child = 2 * root + 1;
            if child >= end {
                break;
            }
            if let (Some(&a), Some(&b)) = (v.get(child), v.get(child + 1))
                && child + 1 < end
            {
                *comparisons += 1;
                if less(a, b) {
                    child += 1;
                }
            }
            *comparisons += 1;
            match (v.get(root), v.get(child)) {
                (Some(&r), Some(&c)) if less(r, c) => {}
                _ => break,
            }
            v.swap(root, child);
            root = child;
        }
    };
    for root in (0..n / 2).rev() {
        sift(v, root, n, &mut comparisons);
    }
    for end in (1..n).rev() {
        v.swap(0, end);
        sift(v, 0, end, &mut comparisons);
    }
    comparisons
}

/// The value at fraction `q` ∈ [0, 1] of sorted `v` (the lower one of two neighbours); zero
/// for an empty slice.
pub fn quantile_sorted<T: Real>(v: &[T], q: T) -> T {
    if v.is_empty() {
        return T::zero();
    }
    let last = v.len().saturating_sub(1);
    let k = libm::floor(q.to_f64().clamp(0.0, 1.0) * last as f64) as usize;
    v.get(k.min(last)).copied().unwrap_or_else(T::zero)
}

/// Median and MAD of `v` (reordered and then overwritten with the absolute deviations);
/// returns `(median, mad, comparisons)`. The MAD of normally distributed values is 0.6745
/// standard deviations.
pub fn median_mad<T: Real>(v: &mut [T]) -> (T, T, u64) {
    let n = v.len();
    median_mad_of(v, n)
}

/// Median and MAD of the first `count` values of `v`, as [`median_mad`]; the values after them
/// are overwritten with `+∞` and sorted along. The work then depends on `v.len()`, not on
/// `count`: a caller that passes all the slots it has in use makes every frame sort as much,
/// however many of them it measured (the finite values sort ahead of the `+∞`s, so the
/// result is [`median_mad`] of `v[..count]`, bit for bit).
pub fn median_mad_of<T: Real>(v: &mut [T], count: usize) -> (T, T, u64) {
    let count = count.min(v.len());
    pad(v, count);
    let mut comparisons = sort(v);
    let median = quantile_sorted(v.get(..count).unwrap_or_default(), T::of(0.5));
    for x in v.iter_mut().take(count) {
        *x = (*x - median).abs();
    }
    pad(v, count);
    comparisons += sort(v);
    let mad = quantile_sorted(v.get(..count).unwrap_or_default(), T::of(0.5));
    (median, mad, comparisons)
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
            assert!(got.2 <= 2 * sort_bound(20), "{count}");
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
