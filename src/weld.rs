//! Positions -> welded vertices ([definitions](crate::definitions#welding)). Topology is about positions: input vertices at the same
//! position are one vertex. Exact equality by default (with `-0.0 == 0.0`), or within a tolerance
//! through a spatial hash. Vertices with a NaN or infinite coordinate map to [`INVALID`].

use rustc_hash::FxHashMap;

/// The welded index of an input vertex with a NaN or infinite coordinate.
pub const INVALID: u32 = u32::MAX;

/// The result of welding.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Welded {
    /// For each input vertex, its welded vertex, or [`INVALID`].
    pub map: Vec<u32>,
    /// The welded vertices' positions (the first input vertex of each, with -0.0 read as 0.0).
    pub positions: Vec<[f64; 3]>,
    /// Input vertices with a NaN or infinite coordinate.
    pub invalid: usize,
}

/// Welds positions exactly (`tolerance == 0.0`) or within `tolerance` (greedy, in input order: a vertex
/// joins the first earlier welded vertex closer than `tolerance`).
pub fn weld(positions: &[[f64; 3]], tolerance: f64) -> Welded {
    if tolerance > 0.0 && tolerance.is_finite() {
        weld_within(positions, tolerance)
    } else {
        weld_exact(positions)
    }
}

fn is_valid(p: &[f64; 3]) -> bool {
    p.iter().all(|x| x.is_finite())
}

/// The weld's frame: invalid positions map to [`INVALID`]; `id` gives each valid one its welded
/// id, pushing a new welded position when none is close enough.
fn weld_each(
    positions: &[[f64; 3]],
    mut id: impl FnMut(&[f64; 3], &mut Vec<[f64; 3]>) -> u32,
) -> Welded {
    let mut out = Welded {
        map: Vec::with_capacity(positions.len()),
        ..Welded::default()
    };
    for p in positions {
        if is_valid(p) {
            out.map.push(id(p, &mut out.positions));
        } else {
            out.invalid += 1;
            out.map.push(INVALID);
        }
    }
    out
}

/// Exact welding through an open-addressing table of welded ids (4 bytes a slot, load at most 1/2):
/// a probe compares against the welded position itself, so the table stays small and a run of
/// coherent input hits memory it has just touched.
fn weld_exact(positions: &[[f64; 3]]) -> Welded {
    let bits = (2 * positions.len())
        .next_power_of_two()
        .max(16)
        .trailing_zeros();
    let mask = (1usize << bits) - 1;
    let mut slots = vec![INVALID; mask + 1];
    weld_each(positions, |p, welded| {
        // Adding 0.0 turns -0.0 into 0.0, so both have one bit pattern.
        let q = p.map(|x| x + 0.0);
        let key = q.map(f64::to_bits);
        let mut h = hash(key) >> (64 - bits);
        loop {
            let id = slots[h as usize];
            if id == INVALID {
                let id = welded.len() as u32;
                slots[h as usize] = id;
                welded.push(q);
                return id;
            }
            if welded[id as usize].map(f64::to_bits) == key {
                return id;
            }
            h = (h + 1) & mask as u64;
        }
    })
}

/// Mixes the three coordinates' bits; the top bits of the result index the table.
fn hash(key: [u64; 3]) -> u64 {
    const K: u64 = 0x9E37_79B9_7F4A_7C15;
    let h = key[0].wrapping_mul(K).rotate_left(29) ^ key[1];
    let h = h.wrapping_mul(K).rotate_left(29) ^ key[2];
    h.wrapping_mul(K)
}

fn weld_within(positions: &[[f64; 3]], tolerance: f64) -> Welded {
    let grid_cell = Cell::new(positions, tolerance);
    let mut grid: FxHashMap<[i64; 3], Vec<u32>> = FxHashMap::default();
    weld_each(positions, |p, welded| {
        let k = grid_cell.of(p);
        let mut found = INVALID;
        for dx in -1..=1i64 {
            for dy in -1..=1i64 {
                for dz in -1..=1i64 {
                    let key = [k[0] + dx, k[1] + dy, k[2] + dz];
                    for &id in grid.get(&key).map(Vec::as_slice).unwrap_or(&[]) {
                        let q = &welded[id as usize];
                        if id < found && closer_than(p, q, tolerance) {
                            found = id;
                        }
                    }
                }
            }
        }
        if found == INVALID {
            found = welded.len() as u32;
            // Adding 0.0 turns -0.0 into 0.0, as the exact weld does.
            welded.push(p.map(|x| x + 0.0));
            grid.entry(k).or_default().push(found);
        }
        found
    })
}

/// Whether `p` and `q` are closer than `tolerance`, measured in units of the tolerance so that neither
/// a tiny tolerance (whose square underflows) nor a huge distance (whose square overflows) decides it.
fn closer_than(p: &[f64; 3], q: &[f64; 3], tolerance: f64) -> bool {
    let d = [0, 1, 2].map(|i| (p[i] - q[i]) / tolerance);
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < 1.0
}

/// The cubic cells of the tolerance weld's spatial hash.
///
/// Points closer than the tolerance must land in the same or adjacent cells, so a cell is at least the
/// tolerance wide (with a margin for the rounding of `x / size`). It is also at least `2^-40` of the
/// largest coordinate, so cell numbers stay far inside `i64`: with a tolerance tiny next to the
/// coordinates, `x / tolerance` would saturate and put every point in one cell, making the weld
/// quadratic. Bigger cells only hold more points; they never change which points weld.
#[derive(Debug, Clone, Copy)]
struct Cell {
    size: f64,
}

impl Cell {
    fn new(positions: &[[f64; 3]], tolerance: f64) -> Cell {
        let largest = positions
            .iter()
            .filter(|p| is_valid(p))
            .flat_map(|p| p.iter().map(|x| x.abs()))
            .fold(0.0, f64::max);
        let size = tolerance.max(largest * 2f64.powi(-40)) * (1.0 + 2f64.powi(-8));
        Cell {
            size: size.min(f64::MAX),
        }
    }

    /// The cell of a valid point: `|x / size| <= 2^40`, so the floors (and their neighbours) are exact
    /// integers, and two points closer than the tolerance differ by at most 1 in each.
    fn of(&self, p: &[f64; 3]) -> [i64; 3] {
        p.map(|x| (x / self.size).floor() as i64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_weld_merges_equal_positions_and_signed_zero() {
        let w = weld(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [-0.0, 0.0, -0.0],
                [1.0, 0.0, 0.0],
            ],
            0.0,
        );
        assert_eq!(w.map, vec![0, 1, 0, 1]);
        assert_eq!(w.positions.len(), 2);
        assert_eq!(w.invalid, 0);
    }

    #[test]
    fn exact_weld_keeps_close_positions_apart() {
        let w = weld(&[[0.0, 0.0, 0.0], [1e-9, 0.0, 0.0]], 0.0);
        assert_eq!(w.map, vec![0, 1]);
    }

    #[test]
    fn invalid_positions_are_marked_and_counted() {
        let w = weld(
            &[
                [f64::NAN, 0.0, 0.0],
                [0.0, f64::INFINITY, 0.0],
                [0.0, 0.0, 0.0],
            ],
            0.0,
        );
        assert_eq!(w.map, vec![INVALID, INVALID, 0]);
        assert_eq!(w.invalid, 2);
        assert_eq!(w.positions.len(), 1);
    }

    /// Points 0.4 apart across a cell boundary weld with tolerance 0.5; a point 0.6 away does not.
    #[test]
    fn tolerance_weld_crosses_cell_boundaries() {
        #[rustfmt::skip]
        let pts = [
            [0.3, 0.0, 0.0], [0.7, 0.0, 0.0], [1.3, 0.0, 0.0], [0.3, 0.0, 0.0],
        ];
        let w = weld(&pts, 0.5);
        assert_eq!(w.map, vec![0, 0, 1, 0]);
    }

    /// The tolerance weld keeps the first input vertex's position with -0.0 read as 0.0 (the
    /// [`Welded::positions`] doc), like the exact weld: `(-0, 1, -0)` is stored as `(0, 1, 0)`, bit for
    /// bit.
    #[test]
    fn tolerance_weld_reads_negative_zero_as_zero() {
        let w = weld(&[[-0.0, 1.0, -0.0], [0.0, 1.0, 0.0]], 0.5);
        assert_eq!(w.map, vec![0, 0]);
        assert_eq!(
            w.positions[0].map(f64::to_bits),
            [0.0, 1.0, 0.0].map(f64::to_bits)
        );
    }

    /// A tolerance of 1e-300 next to coordinates up to 1e13: `x / tolerance` is about 1e313, past
    /// `i64` (and f64) range, so cells taken as `floor(x / tolerance)` would all be one saturated cell.
    /// The cells of the 1,000 points `(1e10 i, 0, 0)` must be 1,000 distinct cells.
    #[test]
    fn tiny_tolerance_keeps_far_points_in_distinct_cells() {
        let points: Vec<[f64; 3]> = (1..=1000).map(|i| [1e10 * i as f64, 0.0, 0.0]).collect();
        let cell = Cell::new(&points, 1e-300);
        let mut keys: Vec<[i64; 3]> = points.iter().map(|p| cell.of(p)).collect();
        keys.sort_unstable();
        keys.dedup();
        assert_eq!(keys.len(), points.len());
    }

    /// With that tolerance the 1,000 far points stay apart (1e10 apart), while two points near the
    /// origin 5e-301 apart (half the tolerance) weld: welded 1,001. Squared, the tolerance (1e-600) and
    /// the distance (2.5e-601) both underflow to 0, so comparing squares would keep them apart.
    #[test]
    fn tiny_tolerance_welds_by_distance_not_by_its_square() {
        let mut points: Vec<[f64; 3]> = (1..=1000).map(|i| [1e10 * i as f64, 0.0, 0.0]).collect();
        points.push([0.0, 0.0, 0.0]);
        points.push([5e-301, 0.0, 0.0]);
        let w = weld(&points, 1e-300);
        assert_eq!(w.positions.len(), 1001);
        assert_eq!(w.map[1000], w.map[1001]);
        assert_eq!(&w.map[..1000], &(0..1000).collect::<Vec<u32>>()[..]);
    }
}
