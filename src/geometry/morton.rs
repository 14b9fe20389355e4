//! Points in the order of a Morton curve (Z-order) through them: close points, close numbers, so
//! that walks over them find their neighbours close in memory. The face boxes of the search for
//! faces that meet and the welded vertices of a scattered soup are put in this order.

use rayon::prelude::*;

/// The order of `n` points (`centre(i)` the i-th) along a Morton curve over their bounding box,
/// 1024 cells a side; points in one cell keep their order.
pub(crate) fn order(n: usize, centre: impl Fn(usize) -> [f32; 3] + Sync) -> Vec<u32> {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for i in 0..n {
        let c = centre(i);
        for k in 0..3 {
            lo[k] = lo[k].min(c[k]);
            hi[k] = hi[k].max(c[k]);
        }
    }
    let scale: [f32; 3] = std::array::from_fn(|k| {
        let extent = hi[k] - lo[k];
        if extent > 0.0 && extent.is_finite() {
            1023.0 / extent
        } else {
            0.0
        }
    });
    let mut keys: Vec<u64> = (0..n)
        .into_par_iter()
        .with_min_len(1 << 14)
        .map(|i| {
            let c = centre(i);
            let cell = |k: usize| {
                let x = (c[k] - lo[k]) * scale[k];
                // NaN (an infinite box) and out-of-range values clamp into the grid.
                (x.clamp(0.0, 1023.0) as u32).min(1023)
            };
            let code = spread(cell(0)) | spread(cell(1)) << 1 | spread(cell(2)) << 2;
            u64::from(code) << 32 | i as u64
        })
        .collect();
    radix_sort_high(&mut keys);
    keys.iter().map(|&k| k as u32).collect()
}

/// The 10 low bits of `x`, two zero bits after each.
fn spread(x: u32) -> u32 {
    let mut x = x & 0x3ff;
    x = (x | x << 16) & 0x030000ff;
    x = (x | x << 8) & 0x0300f00f;
    x = (x | x << 4) & 0x030c30c3;
    x = (x | x << 2) & 0x09249249;
    x
}

/// Stable sort of `keys` by their bits 32..62 (three passes of ten bits).
fn radix_sort_high(keys: &mut Vec<u64>) {
    let mut other = vec![0u64; keys.len()];
    for pass in 0..3 {
        let shift = 32 + 10 * pass;
        let digit = |k: u64| ((k >> shift) & 0x3ff) as usize;
        let mut start = [0usize; 1025];
        for &k in keys.iter() {
            start[digit(k) + 1] += 1;
        }
        for i in 0..1024 {
            start[i + 1] += start[i];
        }
        for &k in keys.iter() {
            let slot = &mut start[digit(k)];
            other[*slot] = k;
            *slot += 1;
        }
        std::mem::swap(keys, &mut other);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The radix sort is a stable sort by the code in the high bits: random codes with many ties
    /// (few distinct ones per digit), the index below, as `order` makes them.
    #[test]
    fn radix_sort_is_stable_by_code() {
        let mut bits = crate::geometry::xorshift(0x51ed_2701_9b3a_c4e5);
        for size in [0, 1, 7, 1000, 70_000] {
            let mut keys: Vec<u64> = (0..size as u64)
                .map(|i| {
                    let r = bits();
                    // Each ten-bit digit takes one of four values, so ties are common.
                    let code = (0..3).fold(0u64, |c, d| c | ((r >> (8 * d)) & 3) << (10 * d + 3));
                    code << 32 | i
                })
                .collect();
            let mut expected = keys.clone();
            expected.sort_by_key(|k| k >> 32);
            radix_sort_high(&mut keys);
            assert_eq!(keys, expected, "{size} keys");
        }
    }
}
