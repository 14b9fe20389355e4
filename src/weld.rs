//! Positions -> welded vertices (SPEC 3). Topology is about positions: input vertices at the same
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
    let mut out = Welded {
        map: Vec::with_capacity(positions.len()),
        ..Welded::default()
    };
    for p in positions {
        if !is_valid(p) {
            out.invalid += 1;
            out.map.push(INVALID);
            continue;
        }
        // Adding 0.0 turns -0.0 into 0.0, so both have one bit pattern.
        let q = p.map(|x| x + 0.0);
        let key = q.map(f64::to_bits);
        let mut h = hash(key) >> (64 - bits);
        let id = loop {
            let id = slots[h as usize];
            if id == INVALID {
                let id = out.positions.len() as u32;
                slots[h as usize] = id;
                out.positions.push(q);
                break id;
            }
            if out.positions[id as usize].map(f64::to_bits) == key {
                break id;
            }
            h = (h + 1) & mask as u64;
        };
        out.map.push(id);
    }
    out
}

/// Mixes the three coordinates' bits; the top bits of the result index the table.
fn hash(key: [u64; 3]) -> u64 {
    const K: u64 = 0x9E37_79B9_7F4A_7C15;
    let h = key[0].wrapping_mul(K).rotate_left(29) ^ key[1];
    let h = h.wrapping_mul(K).rotate_left(29) ^ key[2];
    h.wrapping_mul(K)
}

fn weld_within(positions: &[[f64; 3]], tolerance: f64) -> Welded {
    let cell = |p: &[f64; 3]| p.map(|x| (x / tolerance).floor() as i64);
    let mut grid: FxHashMap<[i64; 3], Vec<u32>> = FxHashMap::default();
    let mut out = Welded {
        map: Vec::with_capacity(positions.len()),
        ..Welded::default()
    };
    let tol2 = tolerance * tolerance;
    for p in positions {
        if !is_valid(p) {
            out.invalid += 1;
            out.map.push(INVALID);
            continue;
        }
        let k = cell(p);
        let mut found = INVALID;
        for dx in -1..=1i64 {
            for dy in -1..=1i64 {
                for dz in -1..=1i64 {
                    let key = [
                        k[0].saturating_add(dx),
                        k[1].saturating_add(dy),
                        k[2].saturating_add(dz),
                    ];
                    for &id in grid.get(&key).map(Vec::as_slice).unwrap_or(&[]) {
                        let q = &out.positions[id as usize];
                        let d2 = (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>();
                        if d2 < tol2 && id < found {
                            found = id;
                        }
                    }
                }
            }
        }
        if found == INVALID {
            found = out.positions.len() as u32;
            out.positions.push(*p);
            grid.entry(k).or_default().push(found);
        }
        out.map.push(found);
    }
    out
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
        let pts = [
            [0.3, 0.0, 0.0],
            [0.7, 0.0, 0.0],
            [1.3, 0.0, 0.0],
            [0.3, 0.0, 0.0],
        ];
        let w = weld(&pts, 0.5);
        assert_eq!(w.map, vec![0, 0, 1, 0]);
    }
}
