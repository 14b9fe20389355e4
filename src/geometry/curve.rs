//! Points in the order of a space-filling curve through a grid over them: close points, close
//! numbers, so that walks over them find their neighbours close in memory. The welded vertices of
//! a scattered soup are put in the order of a Morton curve (Z-order: a cell's number interleaves
//! the bits of its coordinates, cheap to compute); the faces of the search for faces that meet in
//! the order of a Hilbert curve, whose runs of numbers are blocks of cells joined face to face,
//! so that the search tree's nodes, runs of that order, are compact pieces of the surface (on the
//! Stanford dragon its walk compares 296,000 pairs of leaves instead of 564,000 over a Morton
//! order, and takes a sixth less time).

use rayon::prelude::*;

/// The order of `n` points (`centre(i)` the i-th) along a Morton curve over their bounding box,
/// 1024 cells a side; points in one cell keep their order.
pub(crate) fn order(n: usize, centre: impl Fn(usize) -> [f32; 3] + Sync) -> Vec<u32> {
    let grid = Grid::around((0..n).map(&centre));
    let mut keys: Vec<u64> = (0..n)
        .into_par_iter()
        .with_min_len(1 << 14)
        .map(|i| grid.key(centre(i), i as u32))
        .collect();
    sort_keys(&mut keys);
    keys.iter().map(|&k| k as u32).collect()
}

/// A grid of 1024 cells a side over a box, numbering its cells along a Morton curve.
#[derive(Clone, Copy)]
pub(crate) struct Grid {
    lo: [f32; 3],
    scale: [f32; 3],
}

impl Grid {
    /// The grid over the box from `lo` to `hi` (an empty or infinite extent: one cell that way).
    pub(crate) fn new(lo: [f32; 3], hi: [f32; 3]) -> Grid {
        let scale = std::array::from_fn(|k| {
            let extent = hi[k] - lo[k];
            if extent > 0.0 && extent.is_finite() {
                1023.0 / extent
            } else {
                0.0
            }
        });
        Grid { lo, scale }
    }

    /// The grid over the bounding box of `points` (NaN coordinates left out).
    pub(crate) fn around(points: impl Iterator<Item = [f32; 3]>) -> Grid {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for c in points {
            for k in 0..3 {
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
        }
        Grid::new(lo, hi)
    }

    /// The sort key of item `id` at point `c`: the Morton code of its cell in the high 32 bits,
    /// `id` in the low ones ([`sort_keys`] orders by the code and keeps ties in their order).
    /// A point outside the box counts as in the nearest cell; a NaN coordinate as 0.
    #[inline]
    pub(crate) fn key(&self, c: [f32; 3], id: u32) -> u64 {
        let spread = |k: usize| SPREAD[self.cell(c, k) as usize];
        let code = spread(0) | spread(1) << 1 | spread(2) << 2;
        u64::from(code) << 32 | u64::from(id)
    }

    /// The cell of point `c` along axis `k`, 0 to 1023 (as [`Grid::key`] says).
    #[inline]
    fn cell(&self, c: [f32; 3], k: usize) -> u32 {
        let x = (c[k] - self.lo[k]) * self.scale[k];
        (x.clamp(0.0, 1023.0) as u32).min(1023)
    }

    /// The sort key of item `id` at point `c` along a Hilbert curve, in two steps: this gives its
    /// cell's three 10-bit coordinates packed in the high 32 bits, and [`hilbert`] turns those
    /// into the cell's place on the curve (a loop of its own over the keys, which keeps the
    /// transform's long chain of dependent steps away from the loads of the points). Consecutive
    /// places are cells that share a face, so runs of places are blocks of cells joined face to
    /// face (a Morton run can be two blocks apart).
    #[inline]
    pub(crate) fn cell_key(&self, c: [f32; 3], id: u32) -> u64 {
        let cells = self.cell(c, 0) | self.cell(c, 1) << 10 | self.cell(c, 2) << 20;
        u64::from(cells) << 32 | u64::from(id)
    }
}

/// Keys of [`Grid::cell_key`] with their cells' places on a Hilbert curve through the grid, in
/// the high 32 bits, as [`Grid::key`] puts a Morton code there: Skilling's transform
/// ("Programming the Hilbert curve", 2004) of the three coordinates, its bits then interleaved.
/// One key's transform is a long chain of dependent steps; on x86-64 eight keys go side by side
/// in the vector unit's lanes (871k keys: 6.4 ms, against 24 ms one by one).
pub(crate) fn hilbert(keys: &mut [u64]) {
    // Eight at a time in vector lanes on x86-64, the rest (all of them elsewhere) one by one.
    #[cfg(target_arch = "x86_64")]
    let keys = {
        let mut chunks = keys.chunks_exact_mut(8);
        for chunk in &mut chunks {
            let c: [[u32; 3]; 8] = std::array::from_fn(|i| cells(chunk[i]));
            let x: [[[u32; 4]; 3]; 2] = std::array::from_fn(|g| {
                std::array::from_fn(|axis| std::array::from_fn(|l| c[4 * g + l][axis]))
            });
            // SAFETY: SSE2 is part of x86-64 itself: every x86-64 processor has it.
            let places = unsafe { lanes::places(x) };
            for (k, &place) in chunk.iter_mut().zip(places.as_flattened()) {
                *k = with_code(*k, place);
            }
        }
        chunks.into_remainder()
    };
    for k in keys {
        *k = with_code(*k, place(transform(cells(*k))));
    }
}

/// The three cell coordinates a key of [`Grid::cell_key`] packs in its high 32 bits.
fn cells(key: u64) -> [u32; 3] {
    let c = (key >> 32) as u32;
    [c & 0x3ff, c >> 10 & 0x3ff, c >> 20 & 0x3ff]
}

/// `key` with `code` in its high 32 bits, its id kept.
fn with_code(key: u64, code: u32) -> u64 {
    u64::from(code) << 32 | (key & 0xffff_ffff)
}

/// The transformed coordinates of a cell ([`hilbert`]), one by one.
fn transform([mut x0, mut x1, mut x2]: [u32; 3]) -> [u32; 3] {
    // From the top bit down: where a coordinate's bit is set, reflect x0's lower bits; else
    // exchange them with the coordinate's.
    for bit in (1..10).rev() {
        let p = (1u32 << bit) - 1;
        if x0 >> bit & 1 != 0 {
            x0 ^= p;
        }
        for xi in [&mut x1, &mut x2] {
            if *xi >> bit & 1 != 0 {
                x0 ^= p;
            } else {
                let t = (x0 ^ *xi) & p;
                x0 ^= t;
                *xi ^= t;
            }
        }
    }
    [x0, x1, x2]
}

/// The place on the curve of a cell whose coordinates went through [`transform`]: Gray encoded,
/// then every bit of `t` the parity of the bits of `x2` above it, then interleaved.
fn place([x0, x1, x2]: [u32; 3]) -> u32 {
    let x1 = x1 ^ x0;
    let x2 = x2 ^ x1;
    let mut t = x2 & 0x3fe;
    t ^= t >> 1;
    t ^= t >> 2;
    t ^= t >> 4;
    t ^= t >> 8;
    let t = t >> 1;
    SPREAD[(x2 ^ t) as usize] | SPREAD[(x1 ^ t) as usize] << 1 | SPREAD[(x0 ^ t) as usize] << 2
}

/// [`transform`] and [`place`] on eight cells at once, in two groups of four SSE2 lanes (two
/// groups, so that each step has independent work beside it).
#[cfg(target_arch = "x86_64")]
mod lanes {
    use std::arch::x86_64::*;

    /// The places of `G` groups of four cells, `x[group][axis][lane]` their coordinates.
    #[target_feature(enable = "sse2")]
    pub(super) fn places<const G: usize>(x: [[[u32; 4]; 3]; G]) -> [[u32; 4]; G] {
        let mut x = x.map(|axes| {
            axes.map(|[a, b, c, d]| _mm_set_epi32(d as i32, c as i32, b as i32, a as i32))
        });
        for bit in (1..10).rev() {
            let up = _mm_cvtsi32_si128(31 - bit);
            let p = _mm_set1_epi32((1 << bit) - 1);
            for [x0, x1, x2] in &mut x {
                // All ones in the lanes whose `bit` is set.
                let set = |x: __m128i| _mm_srai_epi32::<31>(_mm_sll_epi32(x, up));
                *x0 = _mm_xor_si128(*x0, _mm_and_si128(set(*x0), p));
                for xi in [x1, x2] {
                    let s = set(*xi);
                    // (x0 ^ xi) & p in the lanes whose bit is clear.
                    let t = _mm_andnot_si128(s, _mm_and_si128(_mm_xor_si128(*x0, *xi), p));
                    *x0 = _mm_xor_si128(*x0, _mm_or_si128(_mm_and_si128(s, p), t));
                    *xi = _mm_xor_si128(*xi, t);
                }
            }
        }
        x.map(|[x0, x1, x2]| {
            // Gray encode; then every bit of `t` is the parity of the bits of `x2` above it.
            let x1 = _mm_xor_si128(x1, x0);
            let x2 = _mm_xor_si128(x2, x1);
            let mut t = _mm_and_si128(x2, _mm_set1_epi32(0x3fe));
            t = _mm_xor_si128(t, _mm_srli_epi32::<1>(t));
            t = _mm_xor_si128(t, _mm_srli_epi32::<2>(t));
            t = _mm_xor_si128(t, _mm_srli_epi32::<4>(t));
            t = _mm_xor_si128(t, _mm_srli_epi32::<8>(t));
            t = _mm_srli_epi32::<1>(t);
            // Interleaved as `super::spread` does.
            let spread = |x: __m128i| {
                let mask = |m: u32| _mm_set1_epi32(m as i32);
                let mut x = _mm_xor_si128(x, t);
                x = _mm_and_si128(_mm_or_si128(x, _mm_slli_epi32::<16>(x)), mask(0x030000ff));
                x = _mm_and_si128(_mm_or_si128(x, _mm_slli_epi32::<8>(x)), mask(0x0300f00f));
                x = _mm_and_si128(_mm_or_si128(x, _mm_slli_epi32::<4>(x)), mask(0x030c30c3));
                _mm_and_si128(_mm_or_si128(x, _mm_slli_epi32::<2>(x)), mask(0x09249249))
            };
            let code = _mm_or_si128(
                spread(x2),
                _mm_or_si128(
                    _mm_slli_epi32::<1>(spread(x1)),
                    _mm_slli_epi32::<2>(spread(x0)),
                ),
            );
            [
                _mm_cvtsi128_si32(code),
                _mm_cvtsi128_si32(_mm_shuffle_epi32::<1>(code)),
                _mm_cvtsi128_si32(_mm_shuffle_epi32::<2>(code)),
                _mm_cvtsi128_si32(_mm_shuffle_epi32::<3>(code)),
            ]
            .map(|x| x as u32)
        })
    }
}

/// [`spread`] of every cell number, looked up (4 KiB) rather than computed per point.
static SPREAD: [u32; 1024] = {
    let mut table = [0; 1024];
    let mut x = 0;
    while x < 1024 {
        table[x] = spread(x as u32);
        x += 1;
    }
    table
};

/// The 10 low bits of `x`, two zero bits after each.
const fn spread(x: u32) -> u32 {
    let mut x = x & 0x3ff;
    x = (x | x << 16) & 0x030000ff;
    x = (x | x << 8) & 0x0300f00f;
    x = (x | x << 4) & 0x030c30c3;
    x = (x | x << 2) & 0x09249249;
    x
}

/// Stable sort of `keys` by their bits 32..62, the codes [`Grid::key`] or [`hilbert`] put there
/// (three passes of ten bits, their counts taken in one read of the keys).
pub(crate) fn sort_keys(keys: &mut Vec<u64>) {
    const PASSES: usize = 3;
    let digit = |k: u64, pass: usize| ((k >> (32 + 10 * pass)) & 0x3ff) as usize;
    let mut starts = vec![[0usize; 1025]; PASSES];
    for &k in keys.iter() {
        for (pass, start) in starts.iter_mut().enumerate() {
            start[digit(k, pass) + 1] += 1;
        }
    }
    let mut other = Vec::with_capacity(keys.len());
    for (pass, start) in starts.iter_mut().enumerate() {
        // A digit every key shares moves nothing.
        if start.contains(&keys.len()) {
            continue;
        }
        for i in 0..1024 {
            start[i + 1] += start[i];
        }
        other.clear();
        let spare = &mut other.spare_capacity_mut()[..keys.len()];
        for &k in keys.iter() {
            let slot = &mut start[digit(k, pass)];
            spare[*slot].write(k);
            *slot += 1;
        }
        // SAFETY: the counts of the digits sum to `keys.len()`, so the slots written above are
        // each of `0..keys.len()` once.
        unsafe { other.set_len(keys.len()) };
        std::mem::swap(keys, &mut other);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vector lanes and the one-by-one path (which other processors take for every key)
    /// give the same places, and the ids stay.
    #[test]
    fn hilbert_in_lanes_and_one_by_one_agree() {
        let mut bits = crate::geometry::xorshift(0x1234_5678_9abc_def1);
        let keys: Vec<u64> = (0..1003u64)
            .map(|i| (bits() & 0x3fff_ffff) << 32 | i)
            .collect();
        let mut in_lanes = keys.clone();
        hilbert(&mut in_lanes);
        for (&k, &h) in keys.iter().zip(&in_lanes) {
            assert_eq!(h, with_code(k, place(transform(cells(k)))), "{k:#x}");
        }
    }

    /// The curve's first 16 x 16 x 16 cells (its lowest four levels), and an 8 x 8 x 8 grid of
    /// blocks of 128 cells a side (its highest three): every cell once, each next code one cell
    /// (or block) over, as a Hilbert curve goes (a Morton curve jumps).
    #[test]
    fn hilbert_codes_step_between_cells_that_share_a_face() {
        let grid = Grid::new([0.0; 3], [1023.0; 3]);
        for (side, size, shift) in [(16, 1, 0), (8, 128, 21)] {
            let mut cells: Vec<(u64, [i32; 3])> = Vec::new();
            for x in 0..side {
                for y in 0..side {
                    for z in 0..side {
                        let c = [x, y, z].map(|v| (v * size) as f32);
                        cells.push((grid.cell_key(c, 0), [x, y, z]));
                    }
                }
            }
            let mut keys: Vec<u64> = cells.iter().map(|c| c.0).collect();
            hilbert(&mut keys);
            for (c, k) in cells.iter_mut().zip(keys) {
                c.0 = k >> 32 >> shift;
            }
            cells.sort_unstable();
            let codes: Vec<u64> = cells.iter().map(|c| c.0).collect();
            assert_eq!(codes, (0..side.pow(3) as u64).collect::<Vec<u64>>());
            for w in cells.windows(2) {
                let step: i32 = (0..3).map(|k| (w[0].1[k] - w[1].1[k]).abs()).sum();
                assert_eq!(step, 1, "{:?} then {:?}", w[0], w[1]);
            }
        }
    }

    #[test]
    fn keys_interleave_the_cells_bits() {
        let grid = Grid::new([0.0; 3], [1023.0; 3]);
        let code = |c: [f32; 3]| grid.key(c, 7) >> 32;
        assert_eq!(grid.key([0.0; 3], 7), 7);
        assert_eq!(code([1.0, 0.0, 0.0]), 1);
        assert_eq!(code([0.0, 1.0, 0.0]), 2);
        assert_eq!(code([0.0, 0.0, 1.0]), 4);
        assert_eq!(code([2.0, 0.0, 0.0]), 8);
        // x = 101, y = 011: bits (z y x) from the lowest: 011, 010, 001.
        assert_eq!(code([5.0, 3.0, 0.0]), 0b001_010_011);
        assert_eq!(code([512.0, 0.0, 512.0]), 0b101 << 27);
        assert_eq!(code([1023.0; 3]), (1 << 30) - 1);
        assert_eq!(code([-5.0, 2000.0, f32::NAN]), code([0.0, 1023.0, 0.0]));
    }

    /// The radix sort is a stable sort by the code in the high bits: random codes with many ties
    /// (few distinct ones per digit), an id below, as [`Grid::key`] makes them.
    #[test]
    fn radix_sort_is_stable_by_code() {
        let mut bits = crate::geometry::xorshift(0x51ed_2701_9b3a_c4e5);
        // Digits left varying: all three, or one or two of them (the passes of the others,
        // where every key has the same digit, are skipped).
        for varying in [0b111, 0b101, 0b010, 0b100] {
            for size in [0, 1, 7, 1000, 70_000] {
                let mut keys: Vec<u64> = (0..size as u64)
                    .map(|i| {
                        let r = bits();
                        // Each varying ten-bit digit takes one of four values, so ties are
                        // common; the others are all 5.
                        let code = (0..3).fold(0u64, |c, d| {
                            let digit = if varying >> d & 1 == 1 {
                                ((r >> (8 * d)) & 3) << 3
                            } else {
                                5
                            };
                            c | digit << (10 * d)
                        });
                        code << 32 | (i * 7919 % (size as u64).max(1))
                    })
                    .collect();
                let mut expected = keys.clone();
                expected.sort_by_key(|k| k >> 32);
                sort_keys(&mut keys);
                assert_eq!(keys, expected, "{size} keys, digits {varying:03b}");
            }
        }
    }
}
