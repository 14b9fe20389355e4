//! The one way from a mesh to its Corner Table, shared by the analysis, the places a picture marks
//! and the repair planner: weld the positions, leave out the faces that cannot be in a table (one
//! with an invalid vertex, or two corners on one welded vertex), order the rest by their lowest
//! vertex and build the table.
//!
//! The order matters for speed, not for any count: files usually number vertices in a spatially
//! coherent order even when their faces are shuffled, so walking faces by their lowest vertex keeps
//! neighbours close in memory (the walks are bound by cache misses, not arithmetic). It made the
//! analysis of a shuffled 1M-face torus several times faster.
//!
//! Three passes over the faces do it all. The first welds each face's corners (keeping the welded
//! face), sorts it into invalid, degenerate or kept, and sorts the kept ones by lowest vertex (a
//! radix sort of the welded faces themselves, [`by_lowest_vertex`], so no pass writes or reads
//! faces at random). The second joins the runs of several threads in that order; a sweep over the
//! faces then marks their vertices as used (in table order, so close in memory). The third buckets
//! each face's lowest corner by its middle vertex, which is everything the table's pairing reads
//! (no sort of corners). Each input face's corners are looked up in the weld once: on a shuffled
//! mesh those lookups are cache misses.
//!
//! Vertex numbers matter for the same reason: a triangle soup (STL) numbers its welded vertices by
//! first appearance, so one whose facets come in random order has them at random, and the build
//! then renumbers them along space (a Morton order) before the passes.
//!
//! A big mesh (at least [`PARALLEL_FACES`] faces, on a pool of more than one thread) has its weld,
//! the passes (each thread on its own run of faces, slots counted so that the order is the
//! one-thread order) and the pairing spread over the pool.

use std::sync::atomic::{AtomicBool, Ordering::Relaxed};

use rayon::prelude::*;

use super::Options;
use crate::corner_table::{Apexes, CornerTable};
use crate::geometry::{curve, dist2, norm2, normal};
use crate::mesh::Mesh;
use crate::weld::{weld, weld_parallel, Welded, INVALID};

/// The fewest faces for which [`build`] and the analysis use every thread of the pool.
pub const PARALLEL_FACES: usize = 500_000;

/// Whether a mesh of `faces` faces is built and analysed on every thread: it is big and the
/// current pool has more than one.
pub(crate) fn on_every_thread(faces: usize) -> bool {
    faces >= PARALLEL_FACES && rayon::current_num_threads() > 1
}

/// What an analysis builds that a picture or a repair of the same mesh needs again: the weld and
/// the Corner Table. A scan that draws or repairs keeps it ([`super::analyse_keeping`]).
#[derive(Debug)]
pub struct Built {
    /// The weld tolerance these were built with.
    pub tolerance: f64,
    pub welded: Welded,
    /// The table of the faces that can be in one (valid, not degenerate), by lowest vertex.
    pub table: CornerTable,
    /// The input face of every table face.
    pub source: Vec<u32>,
    /// Whether the table has no non-manifold edge or vertex (set by the analysis; `false` until
    /// it has looked).
    pub manifold: bool,
    /// The component (index into [`super::Analysis::components`]) of every table face (set by the
    /// analysis; empty until it has looked).
    pub component: Vec<u32>,
}

/// The faces [`build`] left out of the table, and the vertices no face uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LeftOut {
    /// Faces using a vertex with a NaN or infinite coordinate.
    pub invalid_faces: usize,
    /// Faces with two corners on one welded vertex.
    pub degenerate_faces: usize,
    /// Valid welded vertices that no face (kept or degenerate) refers to.
    pub unreferenced_vertices: usize,
}

/// Where a face goes, by its welded corners.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FaceKind {
    /// A corner's vertex has a NaN or infinite coordinate.
    Invalid,
    /// Two corners share a welded vertex.
    Degenerate,
    /// Three distinct valid vertices: a face of the table.
    Table,
}

impl FaceKind {
    pub(crate) fn of(w: &[u32; 3]) -> FaceKind {
        if w.contains(&INVALID) {
            FaceKind::Invalid
        } else if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            FaceKind::Degenerate
        } else {
            FaceKind::Table
        }
    }
}

/// The zero-area test of a mesh with a given bounding box: a face's area is at most 1e-12 x
/// (bounding-box diagonal)^2, that is `|cross|^2 <= (2e-12 d^2)^2`. Both sides are fourth powers
/// of lengths, which overflow past about 1e77 and underflow below about 1e-77 (a tetrahedron at
/// 1e200 or 1e-300 had every face "zero-area"): a box whose largest coordinate is beyond 2^±100
/// is measured with every point times a power of two that brings it near 1, which is exact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZeroArea {
    /// The largest [`cross2`] of a zero-area face, in scaled coordinates.
    bound: f64,
    /// The power of two, in two factors (so neither overflows); both 1 when the box is in range.
    scale: [f64; 2],
}

impl ZeroArea {
    /// The test for a mesh with this bounding box (`None`: no finite vertex).
    pub(crate) fn of(bbox: Option<[[f64; 3]; 2]>) -> ZeroArea {
        let largest = bbox.map_or(0.0, |b| crate::geometry::largest_coordinate(&b));
        let scale = crate::geometry::unit_scale(largest).unwrap_or([1.0, 1.0]);
        let scaled = |p: [f64; 3]| p.map(|x| x * scale[0] * scale[1]);
        let diagonal2 = bbox.map_or(0.0, |[lo, hi]| dist2(scaled(lo), scaled(hi)));
        ZeroArea {
            bound: (2e-12 * diagonal2).powi(2),
            scale,
        }
    }

    /// A test that leaves out the faces whose [`cross2`] is at most `bound` (in the points' own
    /// coordinates).
    #[cfg(test)]
    pub(crate) fn at_most(bound: f64) -> ZeroArea {
        ZeroArea {
            bound,
            scale: [1.0, 1.0],
        }
    }

    /// Whether triangle `a b c`, whose [`cross2`] is `cross2`, has zero area.
    #[inline]
    pub(crate) fn is_zero(&self, cross2_abc: f64, a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> bool {
        if self.scale == [1.0, 1.0] {
            cross2_abc <= self.bound
        } else {
            let s = |p: [f64; 3]| p.map(|x| x * self.scale[0] * self.scale[1]);
            cross2(s(a), s(b), s(c)) <= self.bound
        }
    }
}

/// `|(b - a) x (c - a)|^2`: four times the squared area of triangle `a b c`.
pub(crate) fn cross2(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    norm2(normal(a, b, c))
}

/// The welded corners of an input face (`INVALID` for an index the weld does not know).
#[inline]
pub(crate) fn welded_face(map: &[u32], t: &[u32; 3]) -> [u32; 3] {
    // Written out: `array::map` is not always inlined.
    let at = |i: u32| map.get(i as usize).copied().unwrap_or(INVALID);
    [at(t[0]), at(t[1]), at(t[2])]
}

/// Welds `mesh` and builds the table of the faces that can be in one.
pub fn build(mesh: &Mesh, options: &Options) -> (Built, LeftOut) {
    let parallel = on_every_thread(mesh.triangles.len());
    let mut welded = if parallel {
        weld_parallel(&mesh.positions, options.weld_tolerance)
    } else {
        weld(&mesh.positions, options.weld_tolerance)
    };
    if scattered(&mesh.triangles, &welded) {
        renumber_along_space(&mut welded);
    }
    let (table, source, left) = group(
        &mesh.triangles,
        |t| welded_face(&welded.map, t),
        |i| i as u32,
        welded.positions.len(),
        parallel,
    );
    let built = Built {
        tolerance: options.weld_tolerance,
        welded,
        table,
        source,
        manifold: false,
        component: Vec::new(),
    };
    (built, left)
}

/// The fewest welded vertices for which [`build`] looks at how they are numbered: below it the
/// positions fit in cache whatever their order.
const SCATTER_VERTICES: usize = 1 << 16;

/// Whether the welded vertices of `faces` are numbered with no regard to space: most of a sample
/// of faces span more than a sixteenth of all vertex numbers. A triangle soup (STL) numbers its
/// welded vertices by first appearance, so one whose facets come in random order does this, and
/// every walk over its table then misses the cache at nearly every step (the analysis of a
/// shuffled 1M-face soup took six to eight times as long as that of the same mesh indexed).
fn scattered(faces: &[[u32; 3]], welded: &Welded) -> bool {
    let n = welded.positions.len();
    if n < SCATTER_VERTICES || faces.is_empty() {
        return false;
    }
    let sample = faces.len().min(4096);
    let wide = (0..sample)
        .map(|i| welded_face(&welded.map, &faces[i * faces.len() / sample]))
        .filter(|w| FaceKind::of(w) == FaceKind::Table)
        .filter(|w| {
            let (lo, hi) = (w.iter().min(), w.iter().max());
            hi.zip(lo)
                .is_some_and(|(hi, lo)| (hi - lo) as usize > n / 16)
        })
        .count();
    2 * wide > sample
}

/// Renumbers the welded vertices along a Morton curve through their positions, so that the faces
/// around a place get close numbers. Counts do not depend on vertex numbers; sums over faces or
/// vertices (area, volume) are taken in another order, so their last digit can differ from a
/// build without it.
fn renumber_along_space(welded: &mut Welded) {
    let points = &welded.positions;
    let order = curve::order(points.len(), |v| points[v].map(|x| x as f32));
    let mut new = vec![0u32; order.len()];
    for (rank, &old) in order.iter().enumerate() {
        new[old as usize] = rank as u32;
    }
    welded.positions = order.iter().map(|&old| points[old as usize]).collect();
    for w in &mut welded.map {
        if *w != INVALID {
            *w = new[*w as usize];
        }
    }
}

/// The table of `faces` (welded, each of [`FaceKind::Table`]) over `vertex_count` vertices, faces
/// ordered by their lowest vertex; `source[i]` names face `i` for its caller and comes back in the
/// table's order.
pub(crate) fn table_of(
    faces: Vec<[u32; 3]>,
    source: Vec<u32>,
    vertex_count: usize,
) -> (CornerTable, Vec<u32>) {
    let (table, source, _) = group(&faces, |t| *t, |i| source[i], vertex_count, false);
    (table, source)
}

/// The passes of the module docs over `faces` (welded by `welded`, named by `name`): the table of
/// the kept ones by lowest vertex, their names in that order, and what was left out.
fn group(
    faces: &[[u32; 3]],
    welded: impl Fn(&[u32; 3]) -> [u32; 3] + Sync,
    name: impl Fn(usize) -> u32 + Sync,
    vertex_count: usize,
    parallel: bool,
) -> (CornerTable, Vec<u32>, LeftOut) {
    let n = vertex_count;
    let threads = if parallel {
        rayon::current_num_threads()
    } else {
        1
    };
    // Runs of input faces, one per thread (one in all on one thread).
    let run = faces.len().div_ceil(threads).max(1);

    // Pass 1, per run of input faces: each face welded and sorted into invalid, degenerate or
    // kept, and the kept ones, with their indices in the run, sorted by lowest vertex.
    let referenced: Vec<AtomicBool> = (0..n).map(|_| AtomicBool::new(false)).collect();
    let sort_run = |run_faces: &[[u32; 3]]| {
        let mut left = LeftOut::default();
        let mut kept = Vec::with_capacity(run_faces.len());
        for (i, t) in run_faces.iter().enumerate() {
            let w = welded(t);
            match FaceKind::of(&w) {
                FaceKind::Table => kept.push([w[0], w[1], w[2], i as u32]),
                kind => {
                    // A kept face's vertices are marked after pass 2, in table order (close in
                    // memory).
                    for &x in w.iter().filter(|&&x| x != INVALID) {
                        referenced[x as usize].store(true, Relaxed);
                    }
                    if kind == FaceKind::Invalid {
                        left.invalid_faces += 1;
                    } else {
                        left.degenerate_faces += 1;
                    }
                }
            }
        }
        let (faces, index, bounds) = by_lowest_vertex(kept, n);
        Sorted {
            left,
            faces,
            index,
            bounds,
        }
    };
    let mut runs: Vec<Sorted> = if parallel {
        faces.par_chunks(run).map(sort_run).collect()
    } else {
        faces.chunks(run).map(sort_run).collect()
    };
    let mut left = LeftOut::default();
    for r in &runs {
        left.invalid_faces += r.left.invalid_faces;
        left.degenerate_faces += r.left.degenerate_faces;
    }

    // Pass 2, in table order: the runs' sorted faces joined vertex by vertex (runs one after the
    // other within a vertex), each index replaced by the caller's name. One run is in that order
    // already.
    let (table_faces, names, lowest) = if runs.len() == 1 {
        let Sorted {
            faces: table_faces,
            index: mut names,
            bounds,
            ..
        } = runs.pop().expect("one run");
        for i in &mut names {
            *i = name(*i as usize);
        }
        (table_faces, names, bounds)
    } else {
        let lowest: Vec<u32> = (0..=n)
            .into_par_iter()
            .map(|x| runs.iter().map(|r| r.bounds[x]).sum())
            .collect();
        let kept = lowest[n] as usize;
        let mut table_faces = vec![[0u32; 3]; kept];
        let mut names = vec![0u32; kept];
        let cuts = cut(&lowest, PIECE);
        let mut pieces = Vec::with_capacity(cuts.len());
        let (mut rest_faces, mut rest_names) = (table_faces.as_mut_slice(), names.as_mut_slice());
        for w in cuts.windows(2) {
            let size = (lowest[w[1]] - lowest[w[0]]) as usize;
            let (f, tail_faces) = rest_faces.split_at_mut(size);
            let (m, tail_names) = rest_names.split_at_mut(size);
            pieces.push((w[0]..w[1], f, m));
            (rest_faces, rest_names) = (tail_faces, tail_names);
        }
        pieces.into_par_iter().for_each(|(vertices, f, m)| {
            let mut slot = 0;
            for x in vertices {
                for (k, r) in runs.iter().enumerate() {
                    for j in r.bounds[x] as usize..r.bounds[x + 1] as usize {
                        f[slot] = r.faces[j];
                        m[slot] = name(k * run + r.index[j] as usize);
                        slot += 1;
                    }
                }
            }
        });
        (table_faces, names, lowest)
    };

    // The kept faces' vertices marked as used, in table order (close in memory; in the gather's
    // loop these stores held up its cache misses).
    let mark = |faces: &[[u32; 3]]| {
        for x in faces.iter().flatten() {
            referenced[*x as usize].store(true, Relaxed);
        }
    };
    if parallel {
        table_faces.par_chunks(PIECE).for_each(mark);
    } else {
        mark(&table_faces);
    }
    left.unreferenced_vertices = referenced.iter().filter(|r| !r.load(Relaxed)).count();
    drop(referenced);

    // Pass 3, per run of table faces (so mostly in cache): each face's lowest corner by its
    // middle vertex.
    let apex_run = table_faces.len().div_ceil(threads).max(1);
    let apexes: Vec<Apexes> = if parallel {
        table_faces
            .par_chunks(apex_run)
            .enumerate()
            .map(|(r, run_faces)| Apexes::of(run_faces, r * apex_run, n))
            .collect()
    } else {
        vec![Apexes::of(&table_faces, 0, n)]
    };
    let table = CornerTable::from_grouped(table_faces, n, &lowest, &apexes, parallel);
    (table, names, left)
}

/// How many faces a piece of the parallel gather covers, at least.
const PIECE: usize = 1 << 16;

/// A run of input faces after pass 1: its kept faces, welded, by lowest vertex (in input order
/// within a vertex), vertex `x`'s at `bounds[x]..bounds[x + 1]`.
struct Sorted {
    left: LeftOut,
    faces: Vec<[u32; 3]>,
    /// Each kept face's index in the run.
    index: Vec<u32>,
    bounds: Vec<u32>,
}

/// Sorts `kept` faces (`[a, b, c, index]`, vertices below `n`) by their lowest vertex, keeping
/// their order within a vertex: the faces, their indices, and each vertex's bounds (`bounds[x]..
/// bounds[x + 1]`, `n + 1` of them).
///
/// A radix sort of the faces themselves, in as few passes of at most [`DIGIT_BITS`] bits as the
/// vertex numbers need (two up to 4M vertices), each pass reading in order and writing to one
/// place per digit; a counting sort over all vertices instead wrote each face to a random place,
/// and the faces then had to be gathered in that order (on a shuffled 1M-face mesh both were
/// cache misses at nearly every face).
fn by_lowest_vertex(kept: Vec<[u32; 4]>, n: usize) -> (Vec<[u32; 3]>, Vec<u32>, Vec<u32>) {
    let low = |r: &[u32; 4]| r[0].min(r[1]).min(r[2]);
    let bits = usize::BITS - n.saturating_sub(1).leading_zeros();
    let passes = bits.div_ceil(DIGIT_BITS).max(1);
    let width = bits.div_ceil(passes);
    let mask = (1usize << width) - 1;
    let digit = |r: &[u32; 4], pass: u32| (low(r) as usize >> (pass * width)) & mask;
    // Each pass's first slot of each digit.
    let mut starts = vec![vec![0u32; mask + 2]; passes as usize];
    for r in &kept {
        for (pass, start) in starts.iter_mut().enumerate() {
            start[digit(r, pass as u32) + 1] += 1;
        }
    }
    for start in &mut starts {
        for d in 1..start.len() {
            start[d] += start[d - 1];
        }
    }
    // Each pass scatters the records from one array to the other; the last lands in `kept`'s
    // own memory when the passes are even.
    let mut from = kept;
    let mut to = vec![[0u32; 4]; from.len()];
    for (pass, start) in starts.iter_mut().enumerate() {
        for r in &from {
            let slot = &mut start[digit(r, pass as u32)];
            to[*slot as usize] = *r;
            *slot += 1;
        }
        std::mem::swap(&mut from, &mut to);
    }
    drop(to);
    let mut bounds = vec![0u32; n + 1];
    let mut next = 0;
    for (j, r) in from.iter().enumerate() {
        let x = low(r) as usize;
        if x >= next {
            bounds[next..=x].fill(j as u32);
            next = x + 1;
        }
    }
    bounds[next..].fill(from.len() as u32);
    let faces: Vec<[u32; 3]> = from.iter().map(|r| [r[0], r[1], r[2]]).collect();
    let index: Vec<u32> = from.iter().map(|r| r[3]).collect();
    (faces, index, bounds)
}

/// The most bits of a vertex number one pass of [`by_lowest_vertex`] sorts by.
const DIGIT_BITS: u32 = 11;

/// Cuts vertices `0..n` (with `bounds[x]..bounds[x + 1]` the faces of `x`) into ranges of whole
/// vertices holding at least `size` faces each (the last may hold fewer).
fn cut(bounds: &[u32], size: usize) -> Vec<usize> {
    let n = bounds.len() - 1;
    let mut cuts = vec![0usize];
    let mut next = size;
    for x in 0..n {
        if bounds[x + 1] as usize >= next {
            cuts.push(x + 1);
            next = bounds[x + 1] as usize + size;
        }
    }
    if *cuts.last().expect("starts at 0") != n {
        cuts.push(n);
    }
    cuts
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Faces 0-1-2 (kept), 0-0-1 (degenerate), 3-1-2 with vertex 3 at NaN (invalid), and vertex 4
    /// used by nothing; vertex 5 sits at vertex 0's position and welds onto it, so face 5-2-1 is kept
    /// as 0-2-1; vertex 6 is used only by the degenerate face 6-6-2, which still counts as a use
    /// (kept faces mark their vertices in a later pass than the others). The table holds faces 0
    /// and 3, by lowest vertex (both 0: input order).
    #[test]
    fn faces_are_sorted_into_table_and_left_out() {
        let nan = f64::NAN;
        let positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [nan, 0.0, 0.0],
            [5.0, 5.0, 5.0],
            [0.0, 0.0, 0.0],
            [7.0, 7.0, 7.0],
        ];
        let faces = vec![[0, 1, 2], [0, 0, 1], [3, 1, 2], [5, 2, 1], [6, 6, 2]];
        let mesh = Mesh::new(positions, faces);
        let (built, left) = build(&mesh, &Options::default());
        assert_eq!(
            left,
            LeftOut {
                invalid_faces: 1,
                degenerate_faces: 2,
                unreferenced_vertices: 1,
            }
        );
        assert_eq!(built.source, [0, 3]);
        assert_eq!(built.table.triangles(), [[0, 1, 2], [0, 2, 1]]);
        assert_eq!(FaceKind::of(&[1, 2, INVALID]), FaceKind::Invalid);
    }

    /// Faces whose lowest vertices are 2, 0, 1 come out in the order 0, 1, 2 (named 10, 11, 12 by
    /// their caller), whether one run or several threads place them.
    #[test]
    fn faces_come_by_lowest_vertex() {
        let faces = vec![[2, 3, 4], [4, 0, 3], [3, 1, 2]];
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        for parallel in [false, true] {
            let (table, names, _) =
                pool.install(|| group(&faces, |t| *t, |i| 10 + i as u32, 5, parallel));
            assert_eq!(names, [11, 12, 10]);
            assert_eq!(table.triangles(), [[4, 0, 3], [3, 1, 2], [2, 3, 4]]);
        }
    }

    /// The radix sort by lowest vertex is the stable sort by it, with one, two and three passes
    /// (vertex numbers of up to 10, 20 and 23 bits), and its bounds are each vertex's range.
    #[test]
    fn faces_sort_by_lowest_vertex_stably() {
        let mut bits = crate::geometry::xorshift(0x2c1b_9e37_79b9_7f4a);
        for n in [1usize, 3, 1000, 700_000, 5_000_000] {
            // Few distinct lowest vertices, so that ties are common.
            let hubs: Vec<u32> = (0..7).map(|_| (bits() % n as u64) as u32).collect();
            let kept: Vec<[u32; 4]> = (0..3000u32)
                .map(|i| {
                    let hub = hubs[(bits() % 7) as usize];
                    let other = |r: u64| hub.max((r % n as u64) as u32);
                    [other(bits()), hub, other(bits()), i]
                })
                .collect();
            let low = |r: &[u32; 4]| r[0].min(r[1]).min(r[2]);
            let mut expected = kept.clone();
            expected.sort_by_key(low);
            let (faces, index, bounds) = by_lowest_vertex(kept, n);
            let got: Vec<[u32; 4]> = faces
                .iter()
                .zip(&index)
                .map(|(f, &i)| [f[0], f[1], f[2], i])
                .collect();
            assert_eq!(got, expected, "{n} vertices");
            assert_eq!(bounds.len(), n + 1);
            for x in 0..n {
                let range = bounds[x] as usize..bounds[x + 1] as usize;
                assert!(faces[range]
                    .iter()
                    .all(|f| f.iter().min() == Some(&(x as u32))));
            }
            assert_eq!(bounds[n] as usize, faces.len());
        }
    }

    /// A 300 x 250 grid torus (150,000 faces) with every kind of face the passes sort: every 97th
    /// face dropped (holes, so border edges), a fin on every 89th face's first edge (three faces
    /// on an edge), a copy of every 83rd face, a degenerate face and a face on an invalid vertex
    /// every 79th; vertex numbers scrambled in blocks of 1,000 (so a face's corners sit in other
    /// threads' ranges) and faces shuffled. Several threads give the table, names and counts of one
    /// thread, and that table is the one a plain build of its triangles gives.
    #[test]
    fn threads_build_the_one_thread_table() {
        const BAD: u32 = u32::MAX - 7;
        let (n, m) = (300u32, 250u32);
        let scramble = |v: u32| (v / 1000) * 1000 + (v % 1000) * 7 % 1000;
        let vertex_count = (n * m + 200_000) as usize;
        let mut faces = Vec::new();
        let mut extra = n * m;
        let mut f = 0;
        for i in 0..n {
            for j in 0..m {
                let id = |a: u32, b: u32| scramble((a % n) * m + b % m);
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                for t in [[a, b, c], [a, c, d]] {
                    f += 1;
                    if f % 97 == 0 {
                        continue;
                    }
                    faces.push(t);
                    if f % 89 == 0 {
                        faces.push([t[1], t[0], extra]);
                        extra += 1;
                    }
                    if f % 83 == 0 {
                        faces.push([t[0], t[2], t[1]]);
                    }
                    if f % 79 == 0 {
                        faces.push([t[0], t[0], t[1]]);
                        faces.push([t[0], BAD, t[1]]);
                    }
                }
            }
        }
        let mut x = 12345u64;
        for i in (1..faces.len()).rev() {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            faces.swap(i, (x >> 33) as usize % (i + 1));
        }
        let welded = |t: &[u32; 3]| t.map(|v| if v == BAD { INVALID } else { v });
        let name = |i: usize| 3 * i as u32 + 1;
        let (table, names, left) = group(&faces, welded, name, vertex_count, false);
        assert!(table.nonmanifold_edges().len() > 0 && table.border_edge_count() > 0);
        assert!(left.invalid_faces > 0 && left.degenerate_faces > 0);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        let (t3, n3, l3) = pool.install(|| group(&faces, welded, name, vertex_count, true));
        assert_eq!(l3, left);
        assert_eq!(n3, names);
        assert_eq!(t3, table);
        assert_eq!(CornerTable::build(table.triangles(), vertex_count), table);
    }
}
