//! Points in the order of a Morton curve (Z-order) through them: close points, close numbers, so
//! that walks over them find their neighbours close in memory. The face boxes of the search for
//! faces that meet and the welded vertices of a scattered soup are put in this order.

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
        let cell = |k: usize| {
            let x = (c[k] - self.lo[k]) * self.scale[k];
            (x.clamp(0.0, 1023.0) as u32).min(1023)
        };
        let spread = |k: usize| SPREAD[cell(k) as usize];
        let code = spread(0) | spread(1) << 1 | spread(2) << 2;
        u64::from(code) << 32 | u64::from(id)
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

/// Stable sort of `keys` by their bits 32..62, the codes [`Grid::key`] puts there (three passes
/// of ten bits, their counts taken in one read of the keys).
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

    /// On a grid over 0..=1023 a point's cell is its coordinates, and the code interleaves their
    /// bits: x's bit i at 3i, y's at 3i + 1, z's at 3i + 2. Points outside clamp to the border.
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
