//! Robust statistics in caller storage: a bounded in-place sort and selection, quantiles and
//! the median absolute deviation.
//!
//! The detector calibrates its thresholds from the data of each frame (see
//! [`crate::detect`]); the median and the median absolute deviation (MAD) ignore the few large
//! values a cut or a tracking failure produces, where the mean and the standard deviation
//! follow them. Both need one value of known rank, not the whole order, and
//! [`select_rounded`] finds it, rounded to single precision (a noise level needs no more; see
//! there), in one of three ways, each doing the same work whatever the data:
//! - on up to [`RANK_MAX`] values (a feature's neighbour pairs) by counting, for every value,
//!   the values below it: `m²` comparisons of 32-bit integer keys, four at a time, no branch;
//! - on more, but fewer than [`RADIX_MIN`] (or without room for keys), with a heap of the `h`
//!   values nearest that end (`h` at most half the values): at most `2 n ⌈log₂ n⌉`
//!   comparisons, about half of [`sort`]'s heapsort (`2 n ⌈log₂ n⌉ + 2 n`), since the heap is
//!   half as large and no value is taken out of it again;
//! - on more still (all the pairs of a frame), by radix: each value's [`single_key`] is
//!   written once to the caller's key storage ([`KEY_WORDS`] per value), then read a digit of
//!   [`RADIX_BITS`] bits at a time from the top, one pass over the keys per digit counting
//!   those that share the digits found so far: `n` visits per pass and [`RADIX_BINS`] per
//!   digit, four passes; the rank's key is the value.
//!
//! Where many short lists each need a rank (every feature's lower tertile over its pairs), the
//! detector orders four of them at once instead, one to a lane of a sorting network pruned to
//! the lowest third of its ranks ([`lower_third_lanes`]): its comparators are fixed for a
//! length, taken from a table built at compile time, and each is a vector minimum and maximum
//! on the four lanes, so that four lists of 20 to 40 values cost about what one rank count
//! did.
//!
//! Neither recursion nor storage beyond the caller's, one array of [`RADIX_BINS`] counts and
//! one of [`RANK_MAX`] keys on the stack.

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
fn sift<X: Copy>(
    v: &mut [X],
    mut root: usize,
    end: usize,
    whole: bool,
    root_first: impl Fn(X, X) -> bool,
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

/// Values from which [`select_rounded`] finds a rank by radix instead of with a heap: from
/// here on the radix's fixed steps stay well below the heap's bound, and it takes fewer
/// instructions than the heap (a frame's 400 feature changes: about a third); below it the
/// per-digit count of [`RADIX_BINS`] would weigh.
pub const RADIX_MIN: usize = 300;

/// Bits of the key read per radix pass.
pub const RADIX_BITS: u32 = 8;

/// Counts per radix pass, one per digit value.
pub const RADIX_BINS: usize = 1 << RADIX_BITS;

/// Key storage per value of the radix selection: one word, the single-precision order key
/// ([`single_key`]).
pub const KEY_WORDS: usize = 1;

/// Values up to which [`select_rounded`] finds a rank by counting, for each value, the
/// values below it: `m²` comparisons of integer keys, four to a vector
/// (SSE2's `pcmpgtd`), with no branch on the data; the keys are held in an array of this
/// many on the stack. On a feature's 20 to 30 pairs this takes about as many instructions as
/// the heap on order keys it replaced (on the liver, about 2,000 a tertile), whose
/// comparisons (`2 m ⌈log₂ m⌉`) each branched on the data and swapped.
pub const RANK_MAX: usize = 64;

/// Lanes of the rank count: the keys are padded to a multiple of this many.
const RANK_LANES: usize = 4;

/// Most steps [`select_rounded`] makes on `n` values with room for their keys, whatever the
/// rank and the scalar type: up to [`RANK_MAX`] values the rank count's comparisons
/// (`n · ⌈n/4⌉·4`), below [`RADIX_MIN`] the heap's (`2 n ⌈log₂ n⌉`), and from there the
/// radix's visits: `n` to write the keys and `n + RADIX_BINS` per digit of a 32-bit key.
pub const fn select_bound(n: u64) -> u64 {
    if n <= RANK_MAX as u64 {
        rank_steps(n)
    } else if n < RADIX_MIN as u64 {
        heap_select_bound(n)
    } else {
        radix_steps(n)
    }
}

/// Most steps of [`select_rounded`] per value, over selections of at most `m` values each:
/// a bound on `Σ select_bound(mᵢ) / Σ mᵢ` for any parts `mᵢ ≤ m`. The rank count takes
/// `⌈mᵢ/4⌉·4 ≤ 64` per value, the heap `2 ⌈log₂ mᵢ⌉ < 64` and the radix fewer than 9.
pub const fn select_rate_bound(m: u64) -> u64 {
    if m <= RANK_MAX as u64 {
        m.div_ceil(RANK_LANES as u64) * RANK_LANES as u64
    } else {
        RANK_MAX as u64
    }
}

/// Comparisons of the rank count on `n` values: each against the padded `n`.
const fn rank_steps(n: u64) -> u64 {
    n * (n.div_ceil(RANK_LANES as u64) * RANK_LANES as u64)
}

/// Most comparisons of the heap selection on `n` values ([`select`]).
/// `m ↦ heap_select_bound(m) / m` grows with `m`, so it also bounds the sum of heap
/// selections on parts of `n` values.
pub const fn heap_select_bound(n: u64) -> u64 {
    2 * n * ceil_log2(n)
}

/// Steps of the radix selection on `n` values (32-bit keys).
const fn radix_steps(n: u64) -> u64 {
    (32 / RADIX_BITS) as u64 * (n + RADIX_BINS as u64) + n
}

/// Whether `a` orders before `b`: ascending, with every non-finite value (`±∞`, NaN) after
/// every finite one, so that a NaN cannot stall an ordering.
fn less<T: Real>(a: T, b: T) -> bool {
    // `a < b` alone would put `-∞` first, and also after every finite value by the second
    // clause: no order at all.
    a.finite() && (!b.finite() || a < b)
}

/// The value of rank `k` (0-based, ascending as [`sort`] orders) of `v` by the heap
/// selection (see the module's docs), and the comparisons made (within
/// [`heap_select_bound`]); zero (and none) when `k` is out of range. `v` may be reordered.
pub fn select<T: Real>(v: &mut [T], k: usize) -> (T, u64) {
    let n = v.len();
    if k >= n {
        return (T::zero(), 0);
    }
    // A heap holds the `h = min(k + 1, n − k)` values nearest the nearer end, the rank-`k`
    // one at its root (a max-heap of the `k + 1` smallest, or a min-heap of the `n − k`
    // largest); each other value is compared with the root once and enters only if it belongs
    // nearer that end. Building the heap takes at most `2 h` comparisons and each later value
    // `1 + 2 ⌊log₂ h⌋`, so with `h ≤ ⌈n/2⌉` the total stays within `2 n ⌈log₂ n⌉`.
    let comparisons = if k < n - k {
        // Keeps the `k + 1` smallest; the largest of them at the root.
        heap_select(v, k + 1, |a, b| less(b, a))
    } else {
        // Keeps the `n − k` largest; the smallest of them at the root.
        heap_select(v, n - k, less)
    };
    (v.first().copied().unwrap_or_else(T::zero), comparisons)
}

/// `x` rounded to single precision (to nearest; a finite value beyond `f32`'s range to
/// `±f32::MAX`, so that the rounding keeps the order), as a value of `T`: what
/// [`select_rounded`] returns of the rank's value. Non-finite values are left as they are;
/// the identity for `f32`.
pub fn round_single<T: Real>(x: T) -> T {
    if x.finite() {
        T::of(f64::from(to_single(x)))
    } else {
        x
    }
}

/// A finite `x` rounded to single precision, `±f32::MAX` beyond its range.
fn to_single<T: Real>(x: T) -> f32 {
    let max = f64::from(f32::MAX);
    x.to_f64().max(-max).min(max) as f32
}

/// The order key of `x` rounded to single precision ([`round_single`]): `a` orders before
/// `b` (as [`sort`] orders, `-0.0` and `+0.0` alike, every non-finite value last) only if
/// `single_key(a) <= single_key(b)`, and the keys are equal exactly when the rounded values
/// are (or both are non-finite). The rounding is monotone, so the rank `k` of the keys is the
/// key of the rounded rank-`k` value. Without a branch, so that a loop of them vectorises.
#[inline]
pub fn single_key<T: Real>(x: T) -> u32 {
    // `+ 0.0` turns `-0.0` into `+0.0`. A negative value's bits, flipped, order it before
    // the positives and reverse the order of the magnitudes; a positive one's sign bit set
    // orders it after them.
    let bits = (to_single(x) + 0.0).to_bits();
    let negative = ((bits as i32) >> 31) as u32;
    let key = bits ^ (negative | 1 << 31);
    if x.finite() { key } else { u32::MAX }
}

/// The value whose [`single_key`] is `key` (`+∞` for the non-finite values' key).
fn from_single_key<T: Real>(key: u32) -> T {
    let bits = if key == u32::MAX {
        return T::of(f64::INFINITY);
    } else if key >> 31 == 1 {
        key & !(1 << 31)
    } else {
        !key
    };
    T::of(f64::from(f32::from_bits(bits)))
}

/// The value of rank `k` of `v` rounded to single precision ([`round_single`] of the value
/// [`select`] finds; zero when `k` is out of range), and the steps made (within
/// [`select_bound`] when `keys` holds [`KEY_WORDS`] per value, whose contents are then
/// overwritten). Up to [`RANK_MAX`] values by counting ranks, from
/// [`RADIX_MIN`] on by radix, between the two (or without room for keys) with a heap. `v`
/// may be reordered.
///
/// Why rounded: the detector's medians, deviations and tertiles are noise levels, for which
/// a relative 6·10⁻⁸ is nothing, and a 32-bit key halves the radix's passes and its storage
/// against a 64-bit one and lets the rank count compare four keys at once.
pub fn select_rounded<T: Real>(v: &mut [T], k: usize, keys: &mut [u32]) -> (T, u64) {
    let n = v.len();
    if k >= n {
        return (T::zero(), 0);
    }
    if n <= RANK_MAX {
        return rank_select(v, k);
    }
    match keys.get_mut(..KEY_WORDS.saturating_mul(n)) {
        Some(keys) if n >= RADIX_MIN => radix_select(v, k, keys),
        _ => {
            let (value, comparisons) = select(v, k);
            (round_single(value), comparisons)
        }
    }
}

/// The rank-`k` value (`k < v.len() ≤ RANK_MAX`) rounded to single precision, by counting
/// for each value the values below it: the rank-`k` key is the largest key with at most `k`
/// keys below it (any larger key has the `k + 1` keys up to the rank's below it). Every
/// value is compared with every other, four keys at a time (padded with the largest key,
/// which is below none), so the work is [`rank_steps`] whatever the data, and no branch
/// depends on it. `v` is left as it was.
fn rank_select<T: Real>(v: &[T], k: usize) -> (T, u64) {
    let n = v.len();
    // Signed keys in the same order (`x ^ 2³¹`), for the signed vector comparison.
    let mut keys = [[i32::MAX; RANK_LANES]; RANK_MAX / RANK_LANES];
    for (key, &x) in keys.as_flattened_mut().iter_mut().zip(v) {
        *key = (single_key(x) ^ 1 << 31) as i32;
    }
    let keys = keys.get(..n.div_ceil(RANK_LANES)).unwrap_or_default();
    let mut rank_key = i32::MIN;
    for &x in keys.as_flattened().iter().take(n) {
        let mut below = [0i32; RANK_LANES];
        for chunk in keys {
            for (b, &y) in below.iter_mut().zip(chunk) {
                *b += i32::from(y < x);
            }
        }
        let below: i32 = below.iter().sum();
        if below as usize <= k {
            rank_key = rank_key.max(x);
        }
    }
    (
        from_single_key((rank_key as u32) ^ 1 << 31),
        rank_steps(n as u64),
    )
}

/// The rank-`k` value (`k < v.len()`) rounded to single precision, by radix on
/// [`single_key`], most significant digit first, and its steps ([`radix_steps`]); `keys`
/// holds a word per value. Every pass visits every key, so the work is the same for any
/// data; the value is the rank's key decoded, with no pass to fetch it.
fn radix_select<T: Real>(v: &[T], k: usize, keys: &mut [u32]) -> (T, u64) {
    let n = v.len();
    let mut counts = [0u32; RADIX_BINS];
    // The keys written in a loop of their own (which vectorises), then the top digit
    // counted with no test: every key shares the empty prefix.
    for (x, key) in v.iter().zip(keys.iter_mut()) {
        *key = single_key(*x);
    }
    let mut shift = 32 - RADIX_BITS;
    for &key in keys.iter() {
        count(&mut counts, key >> shift);
    }
    // The key's digits found so far, and the rank still to find among the keys that share
    // them.
    let (digit, mut rank) = digit_of_rank(&counts, k);
    let mut prefix = digit << shift;
    while shift >= RADIX_BITS {
        // The bits above the digit this pass reads.
        let known = u32::MAX << shift;
        shift -= RADIX_BITS;
        counts.fill(0);
        for &key in keys.iter() {
            if key & known == prefix {
                count(&mut counts, key >> shift);
            }
        }
        let (digit, rest) = digit_of_rank(&counts, rank);
        prefix |= digit << shift;
        rank = rest;
    }
    (from_single_key(prefix), radix_steps(n as u64))
}

/// The digit whose keys hold rank `rank` among the counted ones (the counts before it are
/// ranks below), and the rank among that digit's keys. Every count is read, found or not:
/// the instructions do not follow the data.
fn digit_of_rank(counts: &[u32; RADIX_BINS], mut rank: usize) -> (u32, usize) {
    let mut found = None;
    for (digit, &c) in counts.iter().enumerate() {
        let c = c as usize;
        if found.is_some() {
            continue;
        }
        if rank < c {
            found = Some(digit as u32);
        } else {
            rank -= c;
        }
    }
    (found.unwrap_or(0), rank)
}

/// Lanes of [`lower_third_lanes`]: as many independent orderings side by side, one per lane, four
/// `f32` to a 128-bit vector.
pub const NETWORK_LANES: usize = 4;

/// `x` as [`lower_third_lanes`] orders it: rounded to single precision ([`round_single`], `-0.0` as
/// `+0.0`), every non-finite value `+∞`. Two values order as their [`single_key`]s do and are
/// equal exactly when the keys are, so the rank `k` of these is [`select_rounded`]'s of the
/// same values ([`from_network_value`]); in `f32`, so that the network's minimum and maximum
/// are one vector instruction each.
#[inline]
pub fn network_value<T: Real>(x: T) -> f32 {
    if x.finite() {
        to_single(x) + 0.0
    } else {
        f32::INFINITY
    }
}

/// The value of `T` that [`select_rounded`] returns for the rank whose [`network_value`] is
/// `x`.
pub fn from_network_value<T: Real>(x: f32) -> T {
    T::of(f64::from(x))
}

/// The lengths the network is built for: a lane of `m` values is sorted by the network of the
/// first length at least `m` ([`network_length`]), the rows past `m` holding `+∞`. Multiples
/// of eight from 8 (and 2 and 4 below), so that a padded network does at most a few
/// comparators more per value than one of the exact length (at most 10 per value of the
/// longest lane, [`network_rate_bound`]), with every table together about 4 KiB.
pub const NETWORK_LENGTHS: [usize; 10] = [2, 4, 8, 16, 24, 32, 40, 48, 56, RANK_MAX];

/// The length of the network that sorts `m ≤ RANK_MAX` values: the first of
/// [`NETWORK_LENGTHS`] at least `m` (0 below 2, where nothing is to sort; [`RANK_MAX`] above).
pub const fn network_length(m: usize) -> usize {
    if m < 2 {
        return 0;
    }
    let mut rest: &[usize] = &NETWORK_LENGTHS;
    while let [length, tail @ ..] = rest {
        if *length >= m {
            return *length;
        }
        rest = tail;
    }
    RANK_MAX
}

/// Knuth's merge exchange on `n` values (Batcher's odd–even merge for any `n`; *The Art of
/// Computer Programming* 5.2.2, algorithm M): its comparators in order, each handed to `emit`
/// as `(i, j)` with `i < j`, the smaller value to go to `i`. A macro rather than a function so
/// that the counting and the filling of the table run the same loops in a `const` context.
macro_rules! merge_exchange {
    ($n:expr, |$i:ident, $j:ident| $emit:block) => {{
        let n: usize = $n;
        if n >= 2 {
            let t = ceil_log2(n as u64);
            let top = 1usize << (t - 1);
            let mut p = top;
            while p > 0 {
                let (mut q, mut r, mut d) = (top, 0, p);
                loop {
                    let mut $i = 0;
                    while $i + d < n {
                        if $i & p == r {
                            let $j = $i + d;
                            $emit
                        }
                        $i += 1;
                    }
                    if q == p {
                        break;
                    }
                    d = q - p;
                    q >>= 1;
                    r = p;
                }
                p >>= 1;
            }
        }
    }};
}

/// Comparators of the merge exchange on `n` values.
pub const fn network_comparators(n: usize) -> usize {
    let mut c = 0;
    merge_exchange!(n, |i, j| {
        let _ = (i, j);
        c += 1;
    });
    c
}

/// The ranks a network of `length` values orders, `0 .. lower_third(length)`: every rank the
/// detector's tertile can read in a lane of at most `length` values
/// ([`quantile_index`]`(m, 1/3) ≤ ⌊(m − 1)/3⌋ ≤ ⌊(length − 1)/3⌋`).
pub const fn lower_third(length: usize) -> usize {
    if length == 0 { 0 } else { (length - 1) / 3 + 1 }
}

/// Comparators of the longest merge exchange, [`RANK_MAX`] values.
const MERGE_EXCHANGE_MAX: usize = network_comparators(RANK_MAX);

/// The merge exchange on `n ≤ RANK_MAX` values pruned to the comparators that the ranks
/// `0 .. lower_third(n)` depend on, in order, and how many there are. Walking the network
/// backwards, a comparator stays when it writes a wire that a rank kept so far reads, and then
/// both its wires are read: a comparator left out writes only wires no kept rank reads after
/// it, so the kept ranks hold what the whole network puts there (about 15 % fewer comparators
/// on the lengths past 8). Only evaluated when the crate is compiled (an index out of range
/// fails the build); the wires are bits of a `u64`, `RANK_MAX` being 64.
#[allow(clippy::indexing_slicing)]
const fn lower_third_network(n: usize) -> ([[u8; 2]; MERGE_EXCHANGE_MAX], usize) {
    let mut full = [[0u8; 2]; MERGE_EXCHANGE_MAX];
    let mut len = 0;
    merge_exchange!(n, |i, j| {
        full[len] = [i as u8, j as u8];
        len += 1;
    });
    let kept = lower_third(n);
    let mut read: u64 = if kept >= 64 {
        u64::MAX
    } else {
        (1 << kept) - 1
    };
    let mut keep = [false; MERGE_EXCHANGE_MAX];
    let mut k = len;
    while k > 0 {
        k -= 1;
        let wires = (1u64 << full[k][0]) | (1u64 << full[k][1]);
        if read & wires != 0 {
            keep[k] = true;
            read |= wires;
        }
    }
    let mut network = [[0u8; 2]; MERGE_EXCHANGE_MAX];
    let mut m = 0;
    while k < len {
        if keep[k] {
            network[m] = full[k];
            m += 1;
        }
        k += 1;
    }
    (network, m)
}

/// Comparators of each network of [`NETWORK_LENGTHS`].
// Evaluated when the crate is compiled: an index out of range fails the build, never a call.
#[allow(clippy::indexing_slicing)]
const NETWORK_SIZES: [usize; NETWORK_LENGTHS.len()] = {
    let mut sizes = [0; NETWORK_LENGTHS.len()];
    let mut k = 0;
    while k < NETWORK_LENGTHS.len() {
        sizes[k] = lower_third_network(NETWORK_LENGTHS[k]).1;
        k += 1;
    }
    sizes
};

/// Where each network of [`NETWORK_LENGTHS`] starts in [`NETWORK_TABLE`], and its end.
// Evaluated when the crate is compiled: an index out of range fails the build, never a call.
#[allow(clippy::indexing_slicing)]
const NETWORK_STARTS: [usize; NETWORK_LENGTHS.len() + 1] = {
    let mut starts = [0; NETWORK_LENGTHS.len() + 1];
    let mut k = 0;
    while k < NETWORK_LENGTHS.len() {
        starts[k + 1] = starts[k] + NETWORK_SIZES[k];
        k += 1;
    }
    starts
};

/// Comparators of every network of [`NETWORK_LENGTHS`] together.
#[allow(clippy::indexing_slicing)] // as above, at compile time
const NETWORK_TABLE_LENGTH: usize = NETWORK_STARTS[NETWORK_LENGTHS.len()];

// What [`NETWORK_LENGTHS`] says of the tables, checked when the crate is compiled: every
// table together under 4 KiB (1,753 comparators of two bytes), at most 10 comparators per
// value of the longest lane.
const _: () = assert!(NETWORK_TABLE_LENGTH <= 1753 && network_rate_bound(RANK_MAX as u64) <= 10);

/// Every network of [`NETWORK_LENGTHS`] one after another, as row pairs, built at compile
/// time; [`network_of`] finds one.
// Evaluated when the crate is compiled: an index out of range fails the build, never a call.
#[allow(clippy::indexing_slicing)]
static NETWORK_TABLE: [[u8; 2]; NETWORK_TABLE_LENGTH] = {
    let mut table = [[0u8; 2]; NETWORK_TABLE_LENGTH];
    let mut at = 0;
    let mut k = 0;
    while k < NETWORK_LENGTHS.len() {
        let (network, len) = lower_third_network(NETWORK_LENGTHS[k]);
        let mut c = 0;
        while c < len {
            table[at] = network[c];
            at += 1;
            c += 1;
        }
        k += 1;
    }
    table
};

/// The comparators that order the lowest third of `m` values: the network of
/// [`network_length`]`(m)` (none below 2).
fn network_of(m: usize) -> &'static [[u8; 2]] {
    let length = network_length(m);
    let k = NETWORK_LENGTHS.iter().position(|&l| l == length);
    match k.and_then(|k| Some((*NETWORK_STARTS.get(k)?, *NETWORK_STARTS.get(k + 1)?))) {
        Some((start, end)) => NETWORK_TABLE.get(start..end).unwrap_or_default(),
        None => &[],
    }
}

/// Comparators of [`lower_third_lanes`] for lanes of `m` values: those of the network of
/// [`network_length`]`(m)`.
pub const fn network_comparators_of(m: usize) -> usize {
    let length = network_length(m);
    let (mut lengths, mut sizes): (&[usize], &[usize]) = (&NETWORK_LENGTHS, &NETWORK_SIZES);
    while let ([l, lengths_after @ ..], [c, sizes_after @ ..]) = (lengths, sizes) {
        if *l == length {
            return *c;
        }
        (lengths, sizes) = (lengths_after, sizes_after);
    }
    0
}

/// Most comparators of [`lower_third_lanes`] per value of the longest lane, over lanes of up
/// to `m` values: `max C(k) / k` over `2 ≤ k ≤ min(m, RANK_MAX)`, rounded up, with `C`
/// [`network_comparators_of`]. Lanes whose longest holds `k` values take `C(k)` comparators,
/// each on every lane at once.
pub const fn network_rate_bound(m: u64) -> u64 {
    let top = if m < RANK_MAX as u64 {
        m as usize
    } else {
        RANK_MAX
    };
    let mut rate = 0;
    let mut k = 2;
    while k <= top {
        let per_value = network_comparators_of(k).div_ceil(k) as u64;
        if per_value > rate {
            rate = per_value;
        }
        k += 1;
    }
    rate
}

/// Orders the lowest third of each lane of the first `m` rows: afterwards rows
/// `0 .. lower_third(network_length(m))` hold each lane's smallest values ascending, as a sort
/// would (`v[i][lane]`: value `i` of the lane; no NaN, which [`network_value`] never makes; the
/// rows from `m` to [`network_length`]`(m)` must hold `+∞`; the rows past the third are
/// left in some order). A merge-exchange network pruned to those ranks, whose comparators do
/// not depend on the data; returns how many it applied (each on every lane). The comparators
/// come from a table built at compile time, so the loop is one pair of row indices, two
/// loads, a vector minimum and maximum and two stores per comparator: where a feature's 20 to
/// 30 values took the rank count about 2,000 instructions each, the network orders four of
/// them in about 3,700 (on the liver, whose groups of four mostly pad to 32 or 40 rows).
pub fn lower_third_lanes(v: &mut [[f32; NETWORK_LANES]; RANK_MAX], m: usize) -> u64 {
    let network = network_of(m);
    for &[i, j] in network {
        exchange(v, usize::from(i), usize::from(j));
    }
    network.len() as u64
}

/// One comparator on every lane: the smaller value of rows `i` and `j` to `i`, the larger to
/// `j`. On copies of whole rows, so that the compiler makes it a vector minimum and maximum;
/// the indices taken modulo [`RANK_MAX`] (a power of two, and they are below it) so that no
/// bounds check is left.
#[inline(always)]
fn exchange(v: &mut [[f32; NETWORK_LANES]; RANK_MAX], i: usize, j: usize) {
    let (i, j) = (i % RANK_MAX, j % RANK_MAX);
    let (Some(&x), Some(&y)) = (v.get(i), v.get(j)) else {
        return;
    };
    let (mut low, mut high) = (x, y);
    for ((lo, hi), (&a, &b)) in low.iter_mut().zip(high.iter_mut()).zip(x.iter().zip(&y)) {
        if b < a {
            (*lo, *hi) = (b, a);
        }
    }
    if let Some(a) = v.get_mut(i) {
        *a = low;
    }
    if let Some(b) = v.get_mut(j) {
        *b = high;
    }
}

/// Counts one key whose digit is the low [`RADIX_BITS`] bits of `digit`.
#[inline(always)]
fn count(counts: &mut [u32; RADIX_BINS], digit: u32) {
    if let Some(c) = counts.get_mut((digit & (RADIX_BINS as u32 - 1)) as usize) {
        *c += 1;
    }
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
fn heap_select<X: Copy>(v: &mut [X], h: usize, root_first: impl Fn(X, X) -> bool) -> u64 {
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
/// them sorted, rounded to single precision), and the steps made ([`select_rounded`], with
/// `keys` its key storage); zero for
/// `count` 0. The values from `count` on are overwritten with `+∞` and take part, so that the
/// work depends on `v.len()`, not on `count` (see [`median_mad_of`]); `v` may be reordered.
pub fn quantile_of<T: Real>(v: &mut [T], count: usize, q: T, keys: &mut [u32]) -> (T, u64) {
    let count = count.min(v.len());
    pad(v, count);
    let (value, comparisons) = select_rounded(v, quantile_index(count, q), keys);
    if count == 0 {
        (T::zero(), comparisons)
    } else {
        (value, comparisons)
    }
}

/// Median and MAD of `v` (reordered and then overwritten with the absolute deviations), each
/// rounded to single precision (the MAD that of the deviations from the rounded median);
/// returns `(median, mad, comparisons)`. The MAD of normally distributed values is 0.6745
/// standard deviations.
pub fn median_mad<T: Real>(v: &mut [T]) -> (T, T, u64) {
    let n = v.len();
    median_mad_of(v, n, &mut [])
}

/// Median and MAD of the first `count` values of `v`, as [`median_mad`]; the values after them
/// are overwritten with `+∞` and take part in both selections. The work then depends on
/// `v.len()`, not on `count`: a caller that passes all the slots it has in use makes every
/// frame select among as many, however many of them it measured. The `+∞`s order after every
/// finite value, and their deviations from a finite median are `+∞` again (from any other
/// median, NaN: still after every finite value), so the result is [`median_mad`] of
/// `v[..count]`. `keys` is the selections' key storage ([`select_rounded`]).
pub fn median_mad_of<T: Real>(v: &mut [T], count: usize, keys: &mut [u32]) -> (T, T, u64) {
    let count = count.min(v.len());
    let (median, mut comparisons) = quantile_of(v, count, T::of(0.5), keys);
    // Every slot, not only the first `count`: the heap selection moves the values about.
    for x in v.iter_mut() {
        *x = (*x - median).abs();
    }
    let (mad, more) = select_rounded(v, quantile_index(count, T::of(0.5)), keys);
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

    /// Whether `got` is `expected` in the order: the same value (a `±0.0` may be the other),
    /// or both non-finite.
    fn same_in_order(got: f64, expected: f64) -> bool {
        got == expected || !(got.is_finite() || expected.is_finite())
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
                    assert!(
                        same_in_order(got, expected),
                        "n {n} seed {seed} rank {k}: {got} against {expected}"
                    );
                    assert!(
                        comparisons <= heap_select_bound(n as u64),
                        "{n} {k} {comparisons}"
                    );
                    // The values are only moved about (sorted again, equals may swap).
                    let mut after = v;
                    sort(&mut after[..n]);
                    let same = |(a, b): (&f64, &f64)| same_in_order(*a, *b);
                    assert!(after[..n].iter().zip(&sorted[..n]).all(same));
                }
            }
        }
    }

    #[test]
    fn the_rank_count_finds_the_rounded_sorted_value_of_every_rank() {
        // Up to `RANK_MAX` values: duplicates, both zeros, a NaN and `+∞`; then values that
        // single precision rounds together (a tie it makes) or beyond its range.
        for n in 0..=RANK_MAX {
            for seed in 0..4 {
                let mut sorted = shuffled(n, seed, seed % 2 == 1);
                sort(&mut sorted[..n]);
                for k in 0..=n {
                    let mut v = shuffled(n, seed, seed % 2 == 1);
                    let before = v;
                    let (got, steps) = select_rounded(&mut v[..n], k, &mut []);
                    let expected = sorted.get(k).filter(|_| k < n).copied().unwrap_or(0.0);
                    assert!(
                        same_in_order(got, round_single(expected)),
                        "n {n} seed {seed} rank {k}: {got} against {expected}"
                    );
                    if k < n {
                        assert_eq!(steps, rank_steps(n as u64));
                        assert!(steps <= select_bound(n as u64));
                    }
                    // Left as it was.
                    let same = |(a, b): (&f64, &f64)| a.to_bits() == b.to_bits();
                    assert!(v.iter().zip(&before).all(same));
                }
            }
        }
        let near = [
            1.0 + 1e-12,
            1.0,
            -3e300,
            1.0 - 1e-12,
            5e300,
            2.0,
            1.0 + 2e-12,
        ];
        let mut sorted = near;
        sort(&mut sorted);
        for k in 0..near.len() {
            let mut v = near;
            let (got, _) = select_rounded(&mut v, k, &mut []);
            assert_eq!(got, round_single(sorted[k]), "rank {k}");
        }
        assert_eq!(round_single(5e300), f64::from(f32::MAX));
        assert_eq!(round_single(1.0 + 1e-12), 1.0);
        assert!(round_single(f64::NAN).is_nan());
    }

    #[test]
    fn select_costs_less_than_a_sort_and_the_same_whatever_the_order() {
        // Values scrambled (as the detector's differences come), ascending and descending:
        // the median's steps (the radix's from `RADIX_MIN` on) against the heapsort's
        // comparisons on the same values.
        fn check<const N: usize>(radix: bool) {
            let scrambled: [f64; N] = core::array::from_fn(|k| ((k * 2_654_435_761) % N) as f64);
            let ascending: [f64; N] = core::array::from_fn(|k| k as f64);
            let descending: [f64; N] = core::array::from_fn(|k| (N - 1 - k) as f64);
            let mut w = scrambled;
            let sorted = sort(&mut w);
            let mut keys = [0u32; 4001];
            let counts = [scrambled, ascending, descending].map(|mut v| {
                let (median, steps) = select_rounded(&mut v, N / 2, &mut keys);
                assert_eq!(median, (N / 2) as f64);
                assert!(steps <= select_bound(N as u64));
                steps
            });
            let (lo, hi) = (counts.iter().min().unwrap(), counts.iter().max().unwrap());
            if radix {
                // The same steps whatever the order, and at a few thousand values (the pairs
                // of a frame) fewer than the heap's comparisons on the same values; near
                // `RADIX_MIN` it is a radix step, a count, that is cheaper than a heap's
                // comparison and swap.
                let mut v = scrambled;
                let (_, heap) = select(&mut v, N / 2);
                assert!(
                    N < 2000 || *hi < heap,
                    "{counts:?} against the heap's {heap}"
                );
                assert_eq!(lo, hi, "{counts:?}");
            } else {
                assert!(*hi < sorted, "{counts:?} against {sorted}");
                // Only the heap's build (at most `2 h`) and the depth of the leaf each later
                // value's walk ends on (one level, two comparisons) depend on the order.
                assert!(hi - lo <= 2 * N as u64, "{counts:?}");
            }
        }
        check::<4001>(true);
        check::<RADIX_MIN>(true);
        check::<{ RADIX_MIN - 1 }>(false);
    }

    fn sorted_without_non_finite(value: impl Fn(usize) -> f64) -> [f64; 700] {
        let mut v: [f64; 700] = core::array::from_fn(value);
        sort(&mut v);
        v
    }

    #[test]
    fn radix_selection_finds_the_rounded_sorted_value_of_every_rank() {
        // Values across signs and magnitudes (tiny, huge beyond single precision's range,
        // subnormal, both zeros), with duplicates, then with a NaN and infinities among them.
        let n = 700;
        let value = |k: usize| {
            let m = ((k * 7919) % 97) as f64 - 48.0;
            match k % 7 {
                0 => m * 1e-300,
                1 => m * 1e300,
                2 => m * f64::MIN_POSITIVE * 1e-3,
                3 => -0.0,
                4 => 0.0,
                5 => 1.0 + m * 1e-12,
                _ => m / 3.0,
            }
        };
        for non_finite in [false, true] {
            let mut v: [f64; 700] = core::array::from_fn(value);
            if non_finite {
                v[10] = f64::NAN;
                v[20] = f64::INFINITY;
                v[30] = f64::NEG_INFINITY;
            }
            let mut sorted = v;
            sort(&mut sorted);
            for k in (0..n).step_by(7).chain([n - 3, n - 2, n - 1]) {
                let mut w = v;
                let mut keys = [0u32; 700];
                let (got, steps) = select_rounded(&mut w, k, &mut keys);
                let expected = round_single(sorted[k]);
                assert!(
                    same_in_order(got, expected),
                    "rank {k}: {got} against {expected}"
                );
                assert_eq!(steps, select_bound(n as u64));
            }
        }
        // Without room for the keys, the heap does it.
        let mut w: [f64; 700] = core::array::from_fn(value);
        let (got, steps) = select_rounded(&mut w, 350, &mut [0u32; 699]);
        assert_eq!(got, round_single(sorted_without_non_finite(value)[350]));
        assert!(steps <= heap_select_bound(700) && steps != select_bound(700));
        // The bound stays under the heap's, from the radix's first size on.
        for n in (RADIX_MIN as u64..100_000).chain([1 << 20, 1 << 30]) {
            assert!(select_bound(n) <= heap_select_bound(n), "{n}");
        }
    }

    #[test]
    fn the_network_orders_every_lanes_lowest_third_as_the_rank_count() {
        for n in 0..=RANK_MAX {
            let mut lanes = [[f32::INFINITY; NETWORK_LANES]; RANK_MAX];
            let mut values = [[0.0f64; 64]; NETWORK_LANES];
            for (lane, v) in values.iter_mut().enumerate() {
                *v = shuffled(n, lane + n, lane % 2 == 1);
                for (row, &x) in lanes.iter_mut().zip(v.iter()).take(n) {
                    row[lane] = network_value(x);
                }
            }
            let comparators = lower_third_lanes(&mut lanes, n);
            // The padded network's comparators, fewer than the whole merge exchange's from 8
            // on, within the bound per value of the lane.
            assert_eq!(comparators, network_comparators_of(n) as u64);
            let whole = network_comparators(network_length(n)) as u64;
            assert!(
                comparators <= whole && (n <= 4 || comparators < whole),
                "{n}"
            );
            assert!(
                comparators <= n as u64 * network_rate_bound(n as u64),
                "{n}"
            );
            assert!(
                comparators <= n as u64 * network_rate_bound(RANK_MAX as u64),
                "{n}"
            );
            // Every rank of the lowest third, which holds every rank the tertile reads (one
            // value is in place without a network).
            let kept = lower_third(network_length(n).max(n));
            for m in 1..=n {
                assert!(quantile_index(m, 1.0 / 3.0) < kept, "{m} of {n}");
            }
            for (lane, v) in values.iter().enumerate() {
                for k in 0..n.min(kept) {
                    let (expected, _) = select_rounded(&mut { *v }[..n], k, &mut []);
                    let got: f64 = from_network_value(lanes[k][lane]);
                    assert!(
                        same_in_order(got, expected),
                        "n {n} lane {lane} rank {k}: {got} against {expected}"
                    );
                    if expected.is_finite() {
                        assert_eq!(got.to_bits(), (expected + 0.0).to_bits());
                    }
                }
            }
        }
    }

    #[test]
    fn the_short_networks_order_the_lowest_third_of_every_sequence_of_zeros_and_ones() {
        // The 0–1 principle (Knuth 5.3.4, exercises 11 and 16, for selection networks too):
        // a comparator network puts the lowest ranks of every input in place if it does so
        // for every input of zeros and ones; all 2¹⁶ inputs of the lengths up to 16, four to
        // a row. The longer networks are checked on shuffles above.
        for &length in NETWORK_LENGTHS.iter().filter(|&&l| l <= 16) {
            for first in (0u32..1 << length).step_by(NETWORK_LANES) {
                let mut lanes = [[f32::INFINITY; NETWORK_LANES]; RANK_MAX];
                for lane in 0..NETWORK_LANES {
                    let bits = first + lane as u32;
                    for (i, row) in lanes.iter_mut().take(length).enumerate() {
                        row[lane] = ((bits >> i) & 1) as f32;
                    }
                }
                lower_third_lanes(&mut lanes, length);
                for lane in 0..NETWORK_LANES {
                    let ones = (first + lane as u32).count_ones() as usize;
                    for (i, row) in lanes.iter().take(lower_third(length)).enumerate() {
                        let expected = if i < length - ones { 0.0 } else { 1.0 };
                        assert_eq!(row[lane], expected, "length {length} input {first}+{lane}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_rate_bound_bounds_selections_on_parts() {
        // Every part size up to 2,000 against the rate of the largest: Σ S(mᵢ) ≤ rate · Σ mᵢ
        // follows from S(m) ≤ rate(M) · m for m ≤ M.
        for largest in 1..2000u64 {
            for m in 1..=largest {
                assert!(
                    select_bound(m) <= select_rate_bound(largest) * m,
                    "{m} {largest}"
                );
            }
        }
    }

    #[test]
    fn padded_median_and_mad_equal_those_of_the_values_alone() {
        let values = [4.0, -1.5, 9.25, 3.0, 3.0, 0.5, 12.0];
        for count in 0..=values.len() {
            let mut alone = values;
            let expected = median_mad(&mut alone[..count]);
            let mut padded = [0.0f64; 20];
            padded[..count].copy_from_slice(&values[..count]);
            let got = median_mad_of(&mut padded, count, &mut []);
            assert_eq!(got.0.to_bits(), expected.0.to_bits(), "{count}");
            assert_eq!(got.1.to_bits(), expected.1.to_bits(), "{count}");
            assert!(got.2 <= 2 * select_bound(20), "{count}");
            // And the padded quantile equals the sorted values' one.
            let mut sorted = values;
            sort(&mut sorted[..count]);
            let mut padded = [0.0f64; 20];
            padded[..count].copy_from_slice(&values[..count]);
            let third = quantile_of(&mut padded, count, 1.0 / 3.0, &mut []);
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
