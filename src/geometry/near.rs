//! Which boxes come near a few given ones: [`Near`] answers, for any box, whether it may overlap
//! one of them, in constant time. A repair asks it of every face of a mesh to find the few a hole's
//! fill could meet, so that the exact search runs on those instead of on the whole surface again.
//!
//! The given boxes are marked on a grid of cells over their union, and a summed-volume table of
//! the marks tells whether a range of cells holds a mark in eight lookups. Cells are found by a
//! monotone map of each coordinate, so two boxes that overlap get cell ranges that overlap: a box
//! that overlaps a given box is always answered yes. One that only comes near may be too.

type Box3 = [[f64; 3]; 2];

/// The grid of the given boxes' cells (see the module docs).
pub(crate) struct Near {
    /// The union of the given boxes.
    union: Box3,
    /// Cells per unit length along each axis (0 where the union has no extent or an infinite one).
    scale: [f64; 3],
    /// Cells along each axis.
    cells: usize,
    /// `sums[(i, j, k)]`: the marked cells below `i`, `j`, `k`, in a `(cells + 1)^3` block.
    sums: Vec<u32>,
}

impl Near {
    /// The grid of `boxes` (each `[min, max]`, finite), `None` when there are none. About four
    /// cells per cube root of the boxes along each axis, at most 64.
    pub(crate) fn new(boxes: &[Box3]) -> Option<Near> {
        let first = *boxes.first()?;
        let mut union = first;
        for b in boxes {
            for k in 0..3 {
                union[0][k] = union[0][k].min(b[0][k]);
                union[1][k] = union[1][k].max(b[1][k]);
            }
        }
        let cells = ((4.0 * (boxes.len() as f64).cbrt()).ceil() as usize).clamp(2, 64);
        let scale = std::array::from_fn(|k| {
            let s = cells as f64 / (union[1][k] - union[0][k]);
            if s.is_finite() {
                s
            } else {
                0.0
            }
        });
        let mut near = Near {
            union,
            scale,
            cells,
            sums: Vec::new(),
        };
        // How many boxes cover each cell, as differences at the corners of each box's cell range,
        // then summed along the three axes; then the marks (covered or not) summed the same way,
        // one cell further, for the table.
        let side = cells + 1;
        let at = |i: usize, j: usize, k: usize| (i * side + j) * side + k;
        let mut count = vec![0i32; side * side * side];
        for b in boxes {
            let [lo, hi] = [near.cell(b[0]), near.cell(b[1])];
            for corner in 0..8 {
                let pick = |axis: usize| {
                    if corner >> axis & 1 == 0 {
                        lo[axis]
                    } else {
                        hi[axis] + 1
                    }
                };
                let sign = if (corner as u32).count_ones().is_multiple_of(2) {
                    1
                } else {
                    -1
                };
                count[at(pick(0), pick(1), pick(2))] += sign;
            }
        }
        sum_along_axes(&mut count, side);
        let mut sums = vec![0u32; side * side * side];
        for i in 0..cells {
            for j in 0..cells {
                for k in 0..cells {
                    sums[at(i + 1, j + 1, k + 1)] = u32::from(count[at(i, j, k)] > 0);
                }
            }
        }
        sum_along_axes(&mut sums, side);
        near.sums = sums;
        Some(near)
    }

    /// Whether `b` (`[min, max]`) may overlap one of the boxes: always when it does.
    pub(crate) fn may_overlap(&self, b: Box3) -> bool {
        let [lo, hi] = self.union;
        if (0..3).any(|k| b[1][k] < lo[k] || b[0][k] > hi[k]) {
            return false;
        }
        let [a, z] = [self.cell(b[0]), self.cell(b[1])];
        let side = self.cells + 1;
        let s = |i: usize, j: usize, k: usize| self.sums[(i * side + j) * side + k];
        let (z0, z1, z2) = (z[0] + 1, z[1] + 1, z[2] + 1);
        // Inclusion and exclusion over the eight corners; wrapping, as the true sum is small.
        let marked = s(z0, z1, z2)
            .wrapping_sub(s(a[0], z1, z2))
            .wrapping_sub(s(z0, a[1], z2))
            .wrapping_sub(s(z0, z1, a[2]))
            .wrapping_add(s(a[0], a[1], z2))
            .wrapping_add(s(a[0], z1, a[2]))
            .wrapping_add(s(z0, a[1], a[2]))
            .wrapping_sub(s(a[0], a[1], a[2]));
        marked > 0
    }

    /// The cell of point `p`, clamped into the grid: monotone in each coordinate.
    fn cell(&self, p: [f64; 3]) -> [usize; 3] {
        std::array::from_fn(|k| {
            let [lo, hi] = [self.union[0][k], self.union[1][k]];
            // `max` turns NaN into `lo`, and an infinite coordinate clamps to the union.
            let x = p[k].max(lo).min(hi);
            (((x - lo) * self.scale[k]) as usize).min(self.cells - 1)
        })
    }
}

/// Running sums of a `side^3` block along each of its three axes.
fn sum_along_axes<T: Copy + std::ops::Add<Output = T>>(block: &mut [T], side: usize) {
    for stride in [side * side, side, 1] {
        for i in 0..block.len() {
            // The cell before along this axis, when there is one.
            if (i / stride) % side > 0 {
                block[i] = block[i] + block[i - stride];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::xorshift;

    fn overlaps(a: Box3, b: Box3) -> bool {
        (0..3).all(|k| a[0][k] <= b[1][k] && b[0][k] <= a[1][k])
    }

    #[test]
    fn every_overlapping_box_is_found_and_far_ones_are_not() {
        let mut next = xorshift(0x9e37_79b9);
        let mut unit = || (next() >> 11) as f64 / (1u64 << 53) as f64;
        let mut boxes = Vec::new();
        for _ in 0..50 {
            let c: [f64; 3] = std::array::from_fn(|_| unit() * 100.0);
            let r: [f64; 3] = std::array::from_fn(|_| unit());
            boxes.push([
                std::array::from_fn(|k| c[k] - r[k]),
                std::array::from_fn(|k| c[k] + r[k]),
            ]);
        }
        let near = Near::new(&boxes).unwrap();
        let (mut found, mut far_said_near, mut far) = (0, 0, 0);
        for i in 0..20_000 {
            // Every other box placed near a given one, the rest anywhere.
            let c: [f64; 3] = if i % 2 == 0 {
                let b = boxes[(unit() * 50.0) as usize];
                std::array::from_fn(|k| b[0][k] + unit() * 6.0 - 3.0)
            } else {
                std::array::from_fn(|_| unit() * 110.0 - 5.0)
            };
            let r: [f64; 3] = std::array::from_fn(|_| unit() * 2.0);
            let q: Box3 = [
                std::array::from_fn(|k| c[k] - r[k]),
                std::array::from_fn(|k| c[k] + r[k]),
            ];
            if boxes.iter().any(|&b| overlaps(b, q)) {
                assert!(near.may_overlap(q), "{q:?} overlaps a box");
                found += 1;
            } else if i % 2 == 1 {
                far += 1;
                far_said_near += usize::from(near.may_overlap(q));
            }
        }
        assert!(found > 1000, "the test boxes overlap some: {found}");
        // Fifty small boxes in a big cube: the grid's cells turn most boxes placed anywhere away.
        assert!(far_said_near * 4 < far, "{far_said_near} of {far}");
    }

    #[test]
    fn boxes_touching_at_a_face_or_a_corner_overlap() {
        let near = Near::new(&[[[0.0; 3], [1.0; 3]], [[5.0; 3], [6.0; 3]]]).unwrap();
        assert!(near.may_overlap([[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]));
        assert!(near.may_overlap([[-1.0, 0.5, 0.5], [0.0, 0.6, 0.6]]));
        assert!(near.may_overlap([[6.0, 6.0, 6.0], [9.0, 9.0, 9.0]]));
        assert!(!near.may_overlap([[7.0, 0.0, 0.0], [8.0, 1.0, 1.0]]));
        assert!(!near.may_overlap([[-3.0, -3.0, -3.0], [-2.0, 9.0, 9.0]]));
    }

    #[test]
    fn flat_and_single_point_boxes_have_cells() {
        // A union flat along z (a hole in a plane), and one that is a single point.
        let flat = Near::new(&[[[0.0, 0.0, 2.0], [1.0, 1.0, 2.0]]]).unwrap();
        assert!(flat.may_overlap([[0.5, 0.5, 1.0], [0.6, 0.6, 3.0]]));
        assert!(!flat.may_overlap([[0.5, 0.5, 2.5], [0.6, 0.6, 3.0]]));
        let point = Near::new(&[[[1.0; 3], [1.0; 3]]]).unwrap();
        assert!(point.may_overlap([[0.0; 3], [1.0; 3]]));
        assert!(!point.may_overlap([[1.5; 3], [2.0; 3]]));
        assert!(Near::new(&[]).is_none());
    }

    #[test]
    fn huge_coordinates_do_not_overflow_the_cells() {
        // An extent of 2e307 (cells of 6e305) and one of 2e308, which overflows to infinity
        // (every box then in one cell).
        let near = Near::new(&[[[-1e307; 3], [-1e307; 3]], [[1e307; 3], [1e307; 3]]]).unwrap();
        assert!(near.may_overlap([[1e307; 3], [1e308; 3]]));
        assert!(near.may_overlap([[-1e308; 3], [-1e307; 3]]));
        assert!(!near.may_overlap([[-1e306; 3], [1e306; 3]]));
        let near = Near::new(&[[[-1e308; 3], [-1e308; 3]], [[1e308; 3], [1e308; 3]]]).unwrap();
        assert!(near.may_overlap([[1e308; 3], [1e308; 3]]));
        assert!(near.may_overlap([[-1e308; 3], [-1e307; 3]]));
    }
}
