//! Positions -> welded vertices ([definitions](crate::definitions#welding)). Topology is about positions: input vertices at the same
//! position are one vertex. Exact equality by default (with `-0.0 == 0.0`), or within a tolerance
//! through a spatial hash. Vertices with a NaN or infinite coordinate map to [`INVALID`].
//!
//! The exact weld sorts instead of probing a hash table: each valid vertex becomes one `u64`, the
//! top 32 bits of a hash of its coordinates' bits above its index, and the keys are sorted by a
//! radix sort (one pass on the top byte into 256 buckets, then each bucket, small enough to stay in
//! cache, by the other three bytes). Equal positions end up side by side with their indices
//! rising, so the first of each run of equal positions is the vertex the others weld onto; only
//! runs of two or more keys read positions again (to tell equal positions from hash collisions),
//! fetched a few dozen keys ahead since a soup's copies of a vertex lie far apart in its input.
//! A last pass in input order numbers the first vertices and gives the others their first's number.
//! Every step but that numbering splits into independent pieces, so [`weld_parallel`] runs them on
//! every thread of the current rayon pool and gives the same [`Welded`].

use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

use rayon::prelude::*;
use rustc_hash::FxHashMap;

use crate::pages::prefetch;

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
        weld_exact(positions, false)
    }
}

/// [`weld`], with the exact weld's steps spread over the threads of the current rayon pool (the
/// tolerance weld is greedy in input order and stays on one thread). The same result as [`weld`].
pub fn weld_parallel(positions: &[[f64; 3]], tolerance: f64) -> Welded {
    if tolerance > 0.0 && tolerance.is_finite() {
        weld_within(positions, tolerance)
    } else {
        weld_exact(positions, true)
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
    // Pushed one by one: hand back what the array grew beyond its size.
    out.positions.shrink_to_fit();
    out
}

/// A valid position's coordinates with -0.0 read as 0.0 (adding 0.0 does that), so equal
/// positions have one bit pattern.
#[inline]
fn normalised(p: &[f64; 3]) -> [f64; 3] {
    p.map(|x| x + 0.0)
}

#[inline]
fn bits(p: &[f64; 3]) -> [u64; 3] {
    normalised(p).map(f64::to_bits)
}

/// In the weld's link array: a valid vertex that no earlier vertex shares a position with (until a
/// run says otherwise, every valid vertex is one).
const FIRST: u32 = u32::MAX - 1;

/// How many positions a piece of the parallel weld's input or numbering covers.
const PIECE: usize = 1 << 16;

/// Exact welding by sorting hash-and-index keys (the module docs).
fn weld_exact(positions: &[[f64; 3]], parallel: bool) -> Welded {
    let n = positions.len();
    assert!(
        n < FIRST as usize,
        "{n} vertices exceed the weld's limit of {FIRST}"
    );
    let key =
        |(i, p): (usize, &[f64; 3])| is_valid(p).then(|| (hash(bits(p)) & !0xFFFF_FFFF) | i as u64);
    let link_of = |p: &[f64; 3]| AtomicU32::new(if is_valid(p) { FIRST } else { INVALID });
    let (keys, link): (Vec<u64>, Vec<AtomicU32>) = if parallel {
        rayon::join(
            || positions.par_iter().enumerate().filter_map(key).collect(),
            || positions.par_iter().map(link_of).collect(),
        )
    } else {
        (
            positions.iter().enumerate().filter_map(key).collect(),
            positions.iter().map(link_of).collect(),
        )
    };
    let invalid = n - keys.len();
    let (keys, buckets) = sort_keys(keys, parallel);

    // Runs of equal hashes never cross a bucket (the bucket is the hash's top byte). A run's
    // positions lie anywhere in the input (a soup writes a vertex once per face around it, far
    // apart): the positions of keys some places ahead that are in runs are fetched ahead, so
    // their cache misses overlap instead of stalling the loop one run at a time.
    let link_bucket = |bucket: &[u64]| {
        const AHEAD: usize = 64;
        let hash = |j: usize| bucket[j] >> 32;
        let in_run = |j: usize| {
            (j > 0 && hash(j - 1) == hash(j)) || (j + 1 < bucket.len() && hash(j + 1) == hash(j))
        };
        let mut fetched = 0;
        for run in runs(bucket, 32) {
            while fetched < (run.end + AHEAD).min(bucket.len()) {
                if in_run(fetched) {
                    let p = &positions[bucket[fetched] as u32 as usize];
                    prefetch(&p[0]);
                    prefetch(&p[2]);
                }
                fetched += 1;
            }
            if run.len() > 1 {
                link_run(&bucket[run], positions, &link);
            }
        }
    };
    let bucket_slices = || buckets.windows(2).map(|w| &keys[w[0]..w[1]]);
    if parallel {
        bucket_slices()
            .collect::<Vec<_>>()
            .into_par_iter()
            .for_each(link_bucket);
    } else {
        bucket_slices().for_each(link_bucket);
    }
    drop(keys);

    // `Vec<AtomicU32>` into `Vec<u32>` reuses the allocation.
    let mut link: Vec<u32> = link.into_iter().map(AtomicU32::into_inner).collect();
    let (map, positions) = if parallel {
        number_parallel(&mut link, positions)
    } else {
        let welded = number(&mut link, positions);
        (link, welded)
    };
    Welded {
        map,
        positions,
        invalid,
    }
}

/// The runs of `keys` (sorted by their bits from `shift` up) with equal bits from `shift` up, as
/// ranges, in order.
pub(crate) fn runs(keys: &[u64], shift: u32) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
    let mut i = 0;
    std::iter::from_fn(move || {
        let start = i;
        let high = keys.get(start)? >> shift;
        i += 1;
        while i < keys.len() && keys[i] >> shift == high {
            i += 1;
        }
        Some(start..i)
    })
}

/// Links every vertex of a run of equal hashes (indices rising) to the first vertex at its
/// position, leaving that one [`FIRST`]. A run longer than a few keys (a vertex shared by many
/// faces of a soup, or keys made to collide) is sorted by position, so no run costs more than a
/// sort of itself.
fn link_run(run: &[u64], positions: &[[f64; 3]], link: &[AtomicU32]) {
    const FEW: usize = 16;
    let index = |e: u64| e as u32;
    let key = |e: u64| bits(&positions[index(e) as usize]);
    // The common case, a run of one position (a soup's vertex), with no table to set up.
    let first = key(run[0]);
    let same = run[1..].iter().take_while(|&&e| key(e) == first).count();
    for &e in &run[1..=same] {
        link[index(e) as usize].store(index(run[0]), Relaxed);
    }
    if same + 1 == run.len() {
        return;
    }
    if run.len() <= FEW {
        let mut firsts = [(0u32, [0u64; 3]); FEW];
        let mut count = 0;
        for &e in run {
            let k = key(e);
            match firsts[..count].iter().find(|f| f.1 == k) {
                Some(f) => link[index(e) as usize].store(f.0, Relaxed),
                None => {
                    firsts[count] = (index(e), k);
                    count += 1;
                }
            }
        }
    } else {
        let mut sorted: Vec<([u64; 3], u32)> = run.iter().map(|&e| (key(e), index(e))).collect();
        sorted.sort_unstable();
        for group in sorted.chunk_by(|a, b| a.0 == b.0) {
            for &(_, i) in &group[1..] {
                link[i as usize].store(group[0].1, Relaxed);
            }
        }
    }
}

/// The numbering in input order: a [`FIRST`] vertex gets the next welded id (and its position is
/// kept), a linked one its first's id, which comes earlier and so is already numbered. The
/// positions are counted first, so that their array is allocated once at its size (grown by
/// pushes, it would hold up to twice that: 40 MB too many for a 5M-face mesh).
fn number(map: &mut [u32], positions: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut welded = Vec::with_capacity(map.iter().filter(|&&l| l == FIRST).count());
    for i in 0..map.len() {
        let link = map[i];
        if link == FIRST {
            map[i] = welded.len() as u32;
            welded.push(normalised(&positions[i]));
        } else if link != INVALID {
            map[i] = map[link as usize];
        }
    }
    welded
}

/// [`number`] in pieces: the firsts of each piece are counted, then numbered from their piece's
/// offset (keeping their positions, and leaving each first's id in `link` in place of
/// [`FIRST`]), then every linked vertex reads its first's id there. Firsts are only read and linked
/// vertices only written in that last step, so the pieces are independent.
fn number_parallel(link: &mut [u32], positions: &[[f64; 3]]) -> (Vec<u32>, Vec<[f64; 3]>) {
    let counts: Vec<u32> = link
        .par_chunks(PIECE)
        .map(|piece| piece.iter().filter(|&&l| l == FIRST).count() as u32)
        .collect();
    let offsets: Vec<u32> = counts
        .iter()
        .scan(0u32, |sum, &c| {
            let start = *sum;
            *sum += c;
            Some(start)
        })
        .collect();
    // Each piece writes its firsts' positions straight into its own part of the output.
    let mut map = vec![0u32; link.len()];
    let mut welded = vec![[0.0f64; 3]; counts.iter().map(|&c| c as usize).sum()];
    let mut parts = Vec::with_capacity(counts.len());
    let mut rest = welded.as_mut_slice();
    for &c in &counts {
        let (part, tail) = rest.split_at_mut(c as usize);
        parts.push(part);
        rest = tail;
    }
    map.par_chunks_mut(PIECE)
        .zip(link.par_chunks_mut(PIECE))
        .zip(positions.par_chunks(PIECE))
        .zip(parts.into_par_iter().zip(&offsets))
        .for_each(|(((ids, links), points), (out, &offset))| {
            let mut k = 0;
            for ((id, l), p) in ids.iter_mut().zip(links).zip(points) {
                *id = *l;
                if *l == FIRST {
                    *l = offset + k as u32;
                    *id = *l;
                    out[k] = normalised(p);
                    k += 1;
                } else if *l != INVALID {
                    // Linked: resolved below, once every first has its id.
                    *id = FIRST;
                }
            }
        });
    let link = &*link;
    map.par_chunks_mut(PIECE)
        .zip(link.par_chunks(PIECE))
        .for_each(|(ids, links)| {
            for (id, &l) in ids.iter_mut().zip(links) {
                if *id == FIRST {
                    *id = link[l as usize];
                }
            }
        });
    (map, welded)
}

/// Sorts the weld's keys by their top 32 bits (the hash; the index below it rises within equal
/// hashes, as it did in the input, so this is also the sort of the whole keys). Returns the keys
/// and the bounds of the 256 buckets of the hash's top byte.
///
/// One pass scatters the keys by the top byte (in parallel: each piece into its own buckets, which
/// are then put together in piece order); then each bucket is sorted by the next three bytes, least
/// significant first, in a scratch buffer of its own size.
fn sort_keys(keys: Vec<u64>, parallel: bool) -> (Vec<u64>, Vec<usize>) {
    let top = |k: u64| (k >> 56) as usize;
    let scatter = |piece: &[u64]| {
        let mut start = [0usize; 257];
        for &k in piece {
            start[top(k) + 1] += 1;
        }
        for b in 0..256 {
            start[b + 1] += start[b];
        }
        let mut out = vec![0u64; piece.len()];
        let mut fill = start;
        for &k in piece {
            let slot = &mut fill[top(k)];
            out[*slot] = k;
            *slot += 1;
        }
        (start, out)
    };
    let (buckets, mut sorted) = if parallel && keys.len() > PIECE {
        let pieces: Vec<([usize; 257], Vec<u64>)> = keys
            .par_chunks(keys.len().div_ceil(rayon::current_num_threads()))
            .map(scatter)
            .collect();
        drop(keys);
        let mut buckets = vec![0usize; 257];
        for b in 0..256 {
            buckets[b + 1] = buckets[b]
                + pieces
                    .iter()
                    .map(|(start, _)| start[b + 1] - start[b])
                    .sum::<usize>();
        }
        let mut sorted = vec![0u64; buckets[256]];
        let mut regions = Vec::with_capacity(256);
        let mut rest = sorted.as_mut_slice();
        for b in 0..256 {
            let (region, tail) = rest.split_at_mut(buckets[b + 1] - buckets[b]);
            regions.push((b, region));
            rest = tail;
        }
        regions.into_par_iter().for_each(|(b, region)| {
            let mut at = 0;
            for (start, out) in &pieces {
                let part = &out[start[b]..start[b + 1]];
                region[at..at + part.len()].copy_from_slice(part);
                at += part.len();
            }
        });
        (buckets, sorted)
    } else {
        let (start, out) = scatter(&keys);
        drop(keys);
        (start.to_vec(), out)
    };
    let sort_bucket = |bucket: &mut [u64]| radix_sort_bytes(bucket, 4..7);
    let mut regions = Vec::with_capacity(256);
    let mut rest = sorted.as_mut_slice();
    for w in buckets.windows(2) {
        let (region, tail) = rest.split_at_mut(w[1] - w[0]);
        regions.push(region);
        rest = tail;
    }
    if parallel {
        regions.into_par_iter().for_each(sort_bucket);
    } else {
        regions.into_iter().for_each(sort_bucket);
    }
    (sorted, buckets)
}

/// A stable least-significant-digit radix sort of `keys` by the bytes `bytes` (byte 0 the lowest),
/// skipping a byte that all keys share.
fn radix_sort_bytes(keys: &mut [u64], bytes: std::ops::Range<u32>) {
    if keys.len() < 2 {
        return;
    }
    if keys.len() <= 64 {
        // The callers' keys agree above `bytes` and rise below them, in input order: sorting the
        // whole keys is the stable sort by `bytes`.
        keys.sort_unstable();
        return;
    }
    let mut scratch = vec![0u64; keys.len()];
    let mut from_scratch = false;
    for b in bytes {
        let digit = |k: u64| ((k >> (8 * b)) & 0xFF) as usize;
        let (src, dst): (&mut [u64], &mut [u64]) = if from_scratch {
            (&mut scratch[..], &mut *keys)
        } else {
            (&mut *keys, &mut scratch[..])
        };
        let mut start = [0usize; 257];
        for &k in src.iter() {
            start[digit(k) + 1] += 1;
        }
        if start.contains(&src.len()) {
            continue;
        }
        for d in 0..256 {
            start[d + 1] += start[d];
        }
        for &k in src.iter() {
            let slot = &mut start[digit(k)];
            dst[*slot] = k;
            *slot += 1;
        }
        from_scratch = !from_scratch;
    }
    if from_scratch {
        keys.copy_from_slice(&scratch);
    }
}

/// Mixes the three coordinates' bits; the top 32 bits of the result are the sort key of an exact
/// weld (equal positions, equal keys; the top byte is the radix bucket).
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
pub(crate) fn closer_than(p: &[f64; 3], q: &[f64; 3], tolerance: f64) -> bool {
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

    /// The exact weld as a hash table does it (the weld before the sort): a vertex joins the first
    /// earlier vertex with the same normalised bits. The reference the sorted weld must match.
    fn weld_by_hashing(positions: &[[f64; 3]]) -> Welded {
        let mut ids: FxHashMap<[u64; 3], u32> = FxHashMap::default();
        weld_each(positions, |p, welded| {
            *ids.entry(bits(p)).or_insert_with(|| {
                welded.push(normalised(p));
                welded.len() as u32 - 1
            })
        })
    }

    /// Positions drawn from few coordinates, so most repeat (at most 7^3 = 343 distinct valid
    /// ones), with -0.0 next to 0.0; one coordinate in eight is NaN or infinite.
    fn few_values(count: usize, seed: u64) -> Vec<[f64; 3]> {
        const FINITE: [f64; 7] = [0.0, -0.0, 1.0, -1.5, 1e-300, f64::MAX, 0.1];
        let mut x = seed | 1;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        (0..count)
            .map(|_| {
                [0; 3].map(|_| match next() % 16 {
                    0 => f64::NAN,
                    1 => f64::NEG_INFINITY,
                    r => FINITE[(r % 7) as usize],
                })
            })
            .collect()
    }

    /// On random soups of repeated positions (with -0.0, NaN and infinities), the sorted weld,
    /// serial and on a pool of three threads, gives what the hash table gives, bit for bit. The
    /// large case has more than two pieces' worth of positions, so the parallel sort and numbering
    /// really split.
    #[test]
    fn sorted_weld_equals_hashing() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        for (count, seed) in [(0, 1), (1, 2), (7, 3), (1000, 4), (3 * PIECE + 17, 5)] {
            let points = few_values(count, seed);
            let reference = weld_by_hashing(&points);
            assert!(
                count < 1000 || reference.positions.len() <= 343,
                "mostly repeats"
            );
            let serial = weld(&points, 0.0);
            assert_eq!(serial.map, reference.map, "{count}");
            assert_eq!(serial.invalid, reference.invalid);
            let bits = |w: &Welded| {
                w.positions
                    .iter()
                    .map(|p| p.map(f64::to_bits))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&serial), bits(&reference));
            let parallel = pool.install(|| weld_parallel(&points, 0.0));
            assert_eq!(parallel.map, reference.map, "{count}");
            assert_eq!(parallel.invalid, reference.invalid);
            assert_eq!(bits(&parallel), bits(&reference));
        }
    }

    /// The welded positions are allocated at their size, not grown by doubling: a big mesh's weld
    /// would otherwise hold up to twice their memory through the whole analysis. 3,000 distinct
    /// positions, each twice (a push-grown array would have room for 4,096), exact and within a
    /// tolerance.
    #[test]
    fn welded_positions_have_no_spare_room() {
        let points: Vec<[f64; 3]> = (0..6000).map(|i| [(i % 3000) as f64, 0.0, 1.0]).collect();
        for tolerance in [0.0, 0.25] {
            let welded = weld(&points, tolerance);
            assert_eq!(welded.positions.len(), 3000, "{tolerance}");
            assert_eq!(welded.positions.capacity(), 3000, "{tolerance}");
        }
    }

    /// Distinct positions (a 60 x 60 x 60 grid in scrambled order, 216,000 of them) stay distinct,
    /// numbered in input order, serial and parallel: `map` is 0, 1, 2, ...
    #[test]
    fn distinct_positions_keep_input_order() {
        let mut points: Vec<[f64; 3]> = (0..216_000)
            .map(|i| {
                [
                    (i % 60) as f64,
                    (i / 60 % 60) as f64 * 0.5,
                    (i / 3600) as f64 - 7.0,
                ]
            })
            .collect();
        // A fixed scramble: 7919 is prime to 216,000, so i -> 7919 i mod 216,000 is a bijection.
        let scrambled: Vec<[f64; 3]> = (0..points.len())
            .map(|i| points[(i * 7919) % points.len()])
            .collect();
        points = scrambled;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        for w in [
            weld(&points, 0.0),
            pool.install(|| weld_parallel(&points, 0.0)),
        ] {
            assert_eq!(w.map, (0..points.len() as u32).collect::<Vec<_>>());
            assert_eq!(w.positions, points);
        }
    }

    /// Runs of one hash holding different positions (what a hash collision gives), short and long:
    /// each vertex links to the first earlier vertex at its own position, never to another's.
    /// Keys: hash 7 above indices 0..n; positions alternate between three points, so vertex i
    /// links to vertex i % 3 (vertices 0, 1, 2 stay firsts).
    #[test]
    fn colliding_hashes_link_by_position() {
        for n in [5, 16, 17, 100] {
            let points: Vec<[f64; 3]> = (0..n).map(|i| [(i % 3) as f64, 0.0, 0.0]).collect();
            let run: Vec<u64> = (0..n as u64).map(|i| 7 << 32 | i).collect();
            let link: Vec<AtomicU32> = (0..n).map(|_| AtomicU32::new(FIRST)).collect();
            link_run(&run, &points, &link);
            let link: Vec<u32> = link.into_iter().map(AtomicU32::into_inner).collect();
            let expected: Vec<u32> = (0..n as u32)
                .map(|i| if i < 3 { FIRST } else { i % 3 })
                .collect();
            assert_eq!(link, expected, "{n}");
        }
        // A run that starts as one position (the common case, linked without a table) and then
        // meets a second one, short and long: [a, a, a, b, a, b, ...].
        for n in [6, 20] {
            let points: Vec<[f64; 3]> = (0..n)
                .map(|i| [if i == 3 || i == 5 { 1.0 } else { 0.0 }, 0.0, 0.0])
                .collect();
            let run: Vec<u64> = (0..n as u64).map(|i| 7 << 32 | i).collect();
            let link: Vec<AtomicU32> = (0..n).map(|_| AtomicU32::new(FIRST)).collect();
            link_run(&run, &points, &link);
            let link: Vec<u32> = link.into_iter().map(AtomicU32::into_inner).collect();
            let expected: Vec<u32> = (0..n as u32)
                .map(|i| match i {
                    0 | 3 => FIRST,
                    5 => 3,
                    _ => 0,
                })
                .collect();
            assert_eq!(link, expected, "{n}");
        }
    }

    /// The radix sort of the weld keys sorts like `sort_unstable` (keys whose low half rises in
    /// input order, as the weld makes them), on sizes around the small-bucket cutoff and beyond.
    #[test]
    fn key_sort_matches_a_plain_sort() {
        let mut x = 0x1234_5678_9abc_def1u64;
        for n in [0usize, 1, 64, 65, 1000, 300_000] {
            let keys: Vec<u64> = (0..n as u64)
                .map(|i| {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    // Few distinct hashes in the small cases, so equal hashes meet.
                    let h = if n < 2000 {
                        x % 50 * 0x0101_0101_0000_0000
                    } else {
                        x & !0xFFFF_FFFF
                    };
                    (h & !0xFFFF_FFFF) | i
                })
                .collect();
            let mut expected = keys.clone();
            expected.sort_unstable();
            for parallel in [false, true] {
                let (sorted, buckets) = sort_keys(keys.clone(), parallel);
                assert_eq!(sorted, expected, "{n} {parallel}");
                assert_eq!(buckets.len(), 257);
                assert_eq!(buckets[256], n);
                for b in 0..256 {
                    assert!(sorted[buckets[b]..buckets[b + 1]]
                        .iter()
                        .all(|&k| (k >> 56) as usize == b));
                }
            }
        }
    }

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
