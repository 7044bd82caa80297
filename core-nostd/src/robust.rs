//! Robust statistics in caller storage: a bounded in-place sort and selection, quantiles and
//! the median absolute deviation.
//!
//! The detector calibrates its thresholds from the data of each frame (see
//! [`crate::detect`]); the median and the median absolute deviation (MAD) ignore the few large
//! values a cut or a tracking failure produces, where the mean and the standard deviation
//! follow them. Both need one value of known rank, not the whole order, and
//! [`select_rounded`] finds it, rounded to single precision (a noise level needs no more; see
//! there), in one of three ways, each doing the same work whatever the data:
//! - on up to [`RANK_MAX`] values by counting, for every value,
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
//! detector orders all the values once instead, by [`radix_order`] (stable, from the lowest
//! of four digits, every pass over every key), and reads each list's rank off a walk in that
//! order: about 125 instructions a pair on the liver (the sort 75 of them), where sorting
//! networks pruned to the lowest third, four lists at a time, took about 140.
//!
//! Neither recursion nor storage beyond the caller's, two arrays of [`RADIX_BINS`] counts and
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
/// many on the stack. On 20 to 30 values this took about as many instructions as the heap on
/// order keys it replaced (about 2,000 a selection), whose comparisons (`2 m ⌈log₂ m⌉`) each
/// branched on the data and swapped.
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

/// Most steps [`select_rounded`] makes on any number of values up to `n`: [`select_bound`] is
/// not monotone (the rank count on 64 values takes more steps than the heap on 65, the heap on
/// 299 more than the radix on 300), and a caller that selects among the slots it has in use
/// is bounded by its capacity through this envelope. `select_bound` rises within each of its
/// three ranges, so the largest over `0..=n` is that at `n` or at the end of a range below it.
pub const fn select_bound_up_to(n: u64) -> u64 {
    let (rank_end, heap_end) = (RANK_MAX as u64, RADIX_MIN as u64 - 1);
    let mut most = select_bound(n);
    if n > rank_end && select_bound(rank_end) > most {
        most = select_bound(rank_end);
    }
    if n > heap_end && select_bound(heap_end) > most {
        most = select_bound(heap_end);
    }
    most
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
/// Why rounded: the detector's medians and deviations (and its tertiles, which
/// [`single_value`] rounds alike) are noise levels, for which
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

/// Steps of [`radix_order`] on `n` keys: a pass to count the lowest digit, four to scatter by
/// each digit (counting the next one on the way), and the four digits' counts turned into
/// starts.
pub const fn radix_order_steps(n: u64) -> u64 {
    5 * n + 4 * RADIX_BINS as u64
}

/// Writes to `order` the indices `0 .. keys.len()` in ascending order of their keys (equal
/// keys in ascending index: the sort is stable), by radix from the lowest digit, with `spare`
/// (as long) as the second buffer the passes alternate with; returns its steps
/// ([`radix_order_steps`]). Every pass visits every key, so the work is the same for any
/// data. Nothing is written when either buffer is shorter than `keys`.
///
/// Each pass counts the next digit of the keys it moves, so that one pass over the keys
/// before the first is the only one that moves nothing, with two arrays of counts on the
/// stack.
pub fn radix_order(keys: &[u32], order: &mut [u32], spare: &mut [u32]) -> u64 {
    let n = keys.len();
    // The indices and the counts are `u32`: more keys than they count are refused too.
    let (Some(order), Some(spare), Ok(last)) =
        (order.get_mut(..n), spare.get_mut(..n), u32::try_from(n))
    else {
        return 0;
    };
    let [mut now, mut next] = [[0u32; RADIX_BINS]; 2];
    for &key in keys {
        count(&mut now, key);
    }
    // From the identity into `spare`, then back and forth; the fourth pass ends in `order`.
    scatter_by_digit(keys, 0..last, 0, &mut now, &mut next, spare);
    scatter_by_digit(keys, spare.iter().copied(), 1, &mut next, &mut now, order);
    scatter_by_digit(keys, order.iter().copied(), 2, &mut now, &mut next, spare);
    scatter_by_digit(keys, spare.iter().copied(), 3, &mut next, &mut now, order);
    radix_order_steps(n as u64)
}

/// One pass of [`radix_order`]: the indices of `from`, in that order, to `to` by their keys'
/// digit `digit` (from the lowest), whose counts `counts` holds on entry; counts digit
/// `digit + 1` of the same keys into `next` (emptied first), if the keys have one.
fn scatter_by_digit(
    keys: &[u32],
    from: impl Iterator<Item = u32>,
    digit: u32,
    counts: &mut [u32; RADIX_BINS],
    next: &mut [u32; RADIX_BINS],
    to: &mut [u32],
) {
    // The counts turned into the first slot of each digit's run.
    let mut start = 0;
    for c in counts.iter_mut() {
        (*c, start) = (start, start + *c);
    }
    next.fill(0);
    let shift = digit * RADIX_BITS;
    let counting = shift + RADIX_BITS < u32::BITS;
    for k in from {
        // `k` indexes `keys` (the indices moved are those of `keys`).
        let key = keys.get(k as usize).copied().unwrap_or(0);
        if let Some(slot) = counts.get_mut(((key >> shift) as usize) & (RADIX_BINS - 1)) {
            if let Some(to) = to.get_mut(*slot as usize) {
                *to = k;
            }
            *slot += 1;
        }
        if counting {
            count(next, key.checked_shr(shift + RADIX_BITS).unwrap_or(0));
        }
    }
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

/// `x` rounded to single precision ([`round_single`], `-0.0` as `+0.0`), every non-finite
/// value `+∞`, as an `f32`. Two values order as their [`single_key`]s do and are equal
/// exactly when the keys are, so the rank `k` of these is [`select_rounded`]'s of the same
/// values ([`from_single_value`]); and the bits of a non-negative one order as the values do,
/// so that [`radix_order`] sorts them as keys.
#[inline]
pub fn single_value<T: Real>(x: T) -> f32 {
    if x.finite() {
        to_single(x) + 0.0
    } else {
        f32::INFINITY
    }
}

/// The value of `T` that [`select_rounded`] returns for the rank whose [`single_value`] is
/// `x`.
pub fn from_single_value<T: Real>(x: f32) -> T {
    T::of(f64::from(x))
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
    fn radix_order_sorts_stably_in_its_steps() {
        // Keys with long runs of duplicates, every byte of them in use, and the extremes.
        for n in [0usize, 1, 2, 7, 300, 1000] {
            let keys: [u32; 1000] = core::array::from_fn(|k| match k % 5 {
                0 => 0,
                1 => u32::MAX,
                _ => (k as u32).wrapping_mul(2_654_435_761) >> (k % 3 * 8),
            });
            let keys = &keys[..n];
            let (mut order, mut spare) = ([u32::MAX; 1000], [0u32; 1000]);
            assert_eq!(
                radix_order(keys, &mut order, &mut spare),
                radix_order_steps(n as u64)
            );
            for w in order[..n].windows(2) {
                let (a, b) = (keys[w[0] as usize], keys[w[1] as usize]);
                assert!(a < b || (a == b && w[0] < w[1]), "{n}: {w:?}");
            }
            // A permutation: every index once.
            let mut seen = [false; 1000];
            for &k in &order[..n] {
                assert!(!seen[k as usize]);
                seen[k as usize] = true;
            }
        }
        // Either buffer too short: nothing written.
        let mut short = [7u32; 2];
        assert_eq!(radix_order(&[3, 2, 1], &mut short, &mut [0; 3]), 0);
        assert_eq!(short, [7, 7]);
        let mut order = [7u32; 3];
        assert_eq!(radix_order(&[3, 2, 1], &mut order, &mut [0; 2]), 0);
        assert_eq!(order, [7, 7, 7]);
    }

    #[test]
    fn the_envelope_bounds_every_selection_up_to_its_count() {
        // `select_bound` falls where the rank count gives way to the heap (64 → 65) and the
        // heap to the radix (299 → 300); the envelope bounds every count up to its own.
        assert!(select_bound(65) < select_bound(64));
        assert!(select_bound(300) < select_bound(299));
        let mut most = 0;
        for n in 0..5000u64 {
            most = most.max(select_bound(n));
            assert_eq!(select_bound_up_to(n), most, "{n}");
        }
    }

    #[test]
    fn single_values_sorted_as_keys_give_the_selections_ranks() {
        // Non-negative values (the detector's slopes), duplicates and `+∞` among them: the
        // rank `k` of their `single_value` bits, ordered by `radix_order`, is the value
        // `select_rounded` finds.
        // Besides the shuffles' integers: a subnormal, values past `f32`'s range, and values
        // that single precision rounds together.
        let odd = [
            1e-310,
            4e38,
            1e300,
            1.0 + 1e-12,
            1.0,
            1.0 - 1e-12,
            0.1,
            0.1 + 1e-17,
        ];
        for n in 1..=64 {
            let mut v =
                shuffled(n, n, n % 3 == 0).map(|x: f64| if x.is_nan() { x } else { x.abs() });
            for (k, &x) in odd.iter().enumerate().filter(|&(k, _)| n > 8 && k < n / 8) {
                v[(k * 5 + n) % n] = x;
            }
            let keys: [u32; 64] = core::array::from_fn(|k| single_value(v[k]).to_bits());
            let (mut order, mut spare) = ([0u32; 64], [0u32; 64]);
            radix_order(&keys[..n], &mut order, &mut spare);
            for k in 0..n {
                let (expected, _) = select_rounded(&mut { v }[..n], k, &mut []);
                let got: f64 = from_single_value(f32::from_bits(keys[order[k] as usize]));
                assert!(
                    same_in_order(got, expected),
                    "n {n} rank {k}: {got} against {expected}"
                );
                if expected.is_finite() {
                    assert_eq!(got.to_bits(), (expected + 0.0).to_bits());
                }
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
