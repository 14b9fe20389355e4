//! The broad phase: a bounding-volume hierarchy over face boxes, and the pairs of faces whose boxes
//! overlap, found by walking the tree against itself. Pairs of faces that share a vertex the
//! caller marks as skipped (a vertex with a flat star, [`super::stars`]) are left out where the
//! leaves are compared, before the narrow phase sees them.
//!
//! Faces come sorted along a Hilbert curve (a 30-bit code of their box centre, radix-sorted,
//! [`crate::geometry::curve`]), so faces close in the order are close in space. Runs of [`LEAF`]
//! faces are the leaves; level `k + 1` joins the nodes `2i` and `2i + 1` of level `k`, up to one
//! root. Boxes are `f32`, rounded outward from the exact `f64` boxes, so two faces whose closed
//! triangles share a point always have overlapping boxes here too. A leaf keeps its faces' boxes on
//! a grid of its own, 256 lines per axis across the leaf's box, a byte a coordinate, rounded
//! outward again (lowest corners down to a line, highest up): the leaves are most of the search's
//! memory, and this makes them 22.5 bytes a face instead of 37. The walk reads the lines back
//! exactly as they were placed (one `f32` multiply and add, [`grid_line`]), so overlapping boxes
//! still overlap; it may also pair faces whose boxes only come within a line of each other, which
//! the narrow phase then finds apart.
//!
//! The walk: within a node, the pairs within each child and the pairs between the two children;
//! between two nodes whose boxes overlap, the pairs between their children. Every unordered pair of
//! faces is looked at once, where the walk first separates them, except inside a node (of
//! `LEAF << PATCH_LEVEL` faces or more, all sharing a turn bit) that the visitor finds free of
//! pairs ([`Visit::no_pairs_within`], the flat patches), which is not walked, and except the
//! pairs within a node, or between two nodes, whose faces all share one skipped vertex or one
//! flat region, and between a node in one region and a node whose faces all cover that region
//! ([`Marks`]; such pairs in mixed nodes are the visitor's to drop). Near
//! the root the three parts run as parallel tasks (`rayon::join`) on the current pool; each task
//! adds its findings to its own [`Visit`] and the tasks' findings are merged, so the answer does
//! not depend on the thread count.

use glam::{BVec4A, Vec4};

use rayon::prelude::*;

/// Faces per leaf.
pub(super) const LEAF: usize = 8;

/// Nodes of this level and above (with at least `LEAF << PATCH_LEVEL` faces) are offered to
/// [`Visit::no_pairs_within`] when their faces share a turn bit.
const PATCH_LEVEL: usize = 2;

/// A node with at least this many faces splits its work into parallel tasks.
const PARALLEL_FACES: usize = 1 << 13;

/// Lowest corner then highest corner.
pub(super) type Box3 = [f32; 6];

/// The outward-rounded `f32` box of a triangle's finite points.
#[inline]
pub(super) fn box_of(points: &[[f64; 3]; 3]) -> Box3 {
    let mut b = [0.0f32; 6];
    for k in 0..3 {
        let [x, y, z] = [points[0][k], points[1][k], points[2][k]];
        let lo = if x < y { x } else { y };
        let lo = if lo < z { lo } else { z };
        let hi = if x > y { x } else { y };
        let hi = if hi > z { hi } else { z };
        b[k] = down(lo);
        b[k + 3] = up(hi);
    }
    b
}

/// An `f32` at most `x` (finite `x` below 2^100 in size, as the search's points are): `x`
/// rounded, less at least one unit in its last place, in arithmetic without branches (whether
/// rounding went up is a coin toss the processor would mispredict).
#[inline]
fn down(x: f64) -> f32 {
    let y = x as f32;
    y - widening(y)
}

/// An `f32` at least `x` (as [`down`]).
#[inline]
fn up(x: f64) -> f32 {
    let y = x as f32;
    y + widening(y)
}

/// At least one unit in the last place of `y` (2^-23 of it, or the least normal `f32`, whichever
/// is more): `x` rounded to `y` is within half of that, so `y` less or plus it is past `x`.
#[inline]
fn widening(y: f32) -> f32 {
    y.abs() * f32::EPSILON + f32::MIN_POSITIVE
}

/// Whether two closed boxes share a point.
#[inline]
pub(super) fn overlap(a: &Box3, b: &Box3) -> bool {
    a[0] <= b[3] && b[0] <= a[3] && a[1] <= b[4] && b[1] <= a[4] && a[2] <= b[5] && b[2] <= a[5]
}

fn join(a: &Box3, b: &Box3) -> Box3 {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].min(b[2]),
        a[3].max(b[3]),
        a[4].max(b[4]),
        a[5].max(b[5]),
    ]
}

/// The levels of a binary tree over `leaves`, leaves first, up to one root: node `i` of level
/// `k + 1` joins nodes `2i` and `2i + 1` of level `k` (a last node alone is kept as it is).
fn levels_above<T: Copy>(leaves: Vec<T>, join: impl Fn(T, T) -> T) -> Vec<Vec<T>> {
    let mut levels = vec![leaves];
    while levels.last().is_some_and(|l| l.len() > 1) {
        let below = levels.last().expect("a level");
        let up = below
            .chunks(2)
            .map(|c| c[1..].iter().fold(c[0], |a, &b| join(a, b)))
            .collect();
        levels.push(up);
    }
    levels
}

/// The centre of a box.
#[cfg(test)]
fn centre(b: &Box3) -> [f32; 3] {
    std::array::from_fn(|k| 0.5 * b[k] + 0.5 * b[k + 3])
}

/// What the walk calls for each pair of faces (positions in the sorted order) with overlapping
/// boxes, and the state it merges across parallel tasks.
pub(super) trait Visit: Send + Sized {
    /// A new, empty state for a parallel task.
    fn fork(&self) -> Self;
    /// Adds a finished task's state.
    fn merge(&mut self, other: Self);
    /// Faces `a` and `b` (sorted positions, `a != b`) have overlapping boxes.
    fn pair(&mut self, a: u32, b: u32);
    /// The walk may stop now.
    fn done(&self) -> bool;
    /// Whether no two of the faces at `places` can meet, so that the walk skips their pairs;
    /// `bits`: the turn bits they all share ([`super::patches::turn_bits`]), not zero.
    fn no_pairs_within(&mut self, _places: std::ops::Range<usize>, _bits: u8) -> bool {
        false
    }
}

/// The faces of one leaf, coordinate by coordinate, so that one face is tested against all of them
/// at once. A face's box is kept on the leaf's own grid, a byte a coordinate (6 bytes a face where
/// `f32`s take 24; the tree's leaves are most of the search's memory): its lowest corner rounded
/// down to a line of the grid, its highest rounded up, so the box read back holds the face's box.
struct Leaf {
    /// Per axis, the grid's first line (the leaf box's lowest coordinate) and its step
    /// ([`grid_step`]).
    origin: [f32; 3],
    step: [f32; 3],
    /// `[c][j]`: coordinate `c` of the box of face `j` as a line of the grid along axis `c % 3`,
    /// lowest x, y, z then highest x, y, z.
    grid: [[u8; LEAF]; 6],
    /// `[i][j]`: vertex `i` of face `j` ([`FREE`] in free places).
    vertices: [[u32; LEAF]; 3],
    /// Bit `k` of `skipped[j]`: pairs of face `j` with faces on its vertex `k` are skipped.
    skipped: [u8; LEAF],
    /// Bit `j`: place `j` holds a face (the last leaf can have fewer than [`LEAF`]).
    used: u8,
}

impl Leaf {
    /// Puts the faces' boxes (`boxes[c][j]`: coordinate `c` of face `j`; free places repeat a
    /// face's) on the leaf's grid, returning the leaf's box. Kept out of line so that the tree
    /// build's loop, which reads the faces, stays small enough to take their reader inline.
    #[inline(never)]
    fn place(&mut self, boxes: &[[f32; LEAF]; 6]) -> Box3 {
        let bounds: Box3 = std::array::from_fn(|c| {
            let [a, b] = [0, 4].map(|h| Vec4::from_slice(&boxes[c][h..h + 4]));
            if c < 3 {
                a.min(b).min_element()
            } else {
                a.max(b).max_element()
            }
        });
        for k in 0..3 {
            let (origin, step) = (bounds[k], grid_step(bounds[k], bounds[k + 3]));
            self.origin[k] = origin;
            self.step[k] = step;
            self.grid[k] = lines(origin, step, &boxes[k], false);
            self.grid[k + 3] = lines(origin, step, &boxes[k + 3], true);
        }
        bounds
    }
}

/// The boxes of a leaf's faces read back from its grid, four faces to a vector.
struct Lanes {
    /// `[c][h]`: coordinate `c` of the boxes of faces `4h..4h + 4`, as [`Leaf::grid`].
    rows: [[Vec4; 2]; 6],
    /// As [`Leaf::used`].
    used: u8,
}

/// Lines `row` of the grid from `origin` by `step` ([`grid_line`] of each), four to a vector.
#[cfg(target_arch = "x86_64")]
#[inline]
fn row_lines(origin: f32, step: f32, row: [u8; LEAF]) -> [Vec4; 2] {
    use std::arch::x86_64::{
        _mm_cvtepi32_ps, _mm_cvtsi64_si128, _mm_setzero_si128, _mm_unpackhi_epi16,
        _mm_unpacklo_epi16, _mm_unpacklo_epi8,
    };
    // The bytes widened to 32-bit integers, then converted (exactly) to f32; the multiply and
    // add are those of `grid_line`, lane by lane.
    // SAFETY: SSE2 is part of x86-64 itself (every x86-64 processor has it), and these touch
    // only values, no memory.
    let [low, high] = unsafe {
        let zero = _mm_setzero_si128();
        let words = _mm_unpacklo_epi8(_mm_cvtsi64_si128(i64::from_le_bytes(row)), zero);
        [
            _mm_cvtepi32_ps(_mm_unpacklo_epi16(words, zero)),
            _mm_cvtepi32_ps(_mm_unpackhi_epi16(words, zero)),
        ]
    };
    let (o, s) = (Vec4::splat(origin), Vec4::splat(step));
    [low, high].map(|q| o + Vec4::from(q) * s)
}

/// [`row_lines`] elsewhere, lane by lane.
#[cfg(not(target_arch = "x86_64"))]
#[inline]
fn row_lines(origin: f32, step: f32, row: [u8; LEAF]) -> [Vec4; 2] {
    let line = |j: usize| grid_line(origin, step, row[j]);
    [0, 4].map(|h| Vec4::new(line(h), line(h + 1), line(h + 2), line(h + 3)))
}

/// The lines of a leaf's grid along one axis: line `q` is at `origin + q * step`, computed in
/// `f32` this one way (a multiply, then an add, which Rust never fuses) wherever a line is
/// placed or read, so that both see the same value.
#[inline]
fn grid_line(origin: f32, step: f32, q: u8) -> f32 {
    origin + f32::from(q) * step
}

/// The step of a grid from `lo` whose last line is at `hi` or beyond (`lo <= hi`, finite).
fn grid_step(lo: f32, hi: f32) -> f32 {
    let mut step = (hi - lo) / f32::from(u8::MAX);
    // Each rounding is within half a unit in the last place, so a few units more always reach.
    while grid_line(lo, step, u8::MAX) < hi {
        step = step.next_up();
    }
    step
}

/// The lines of the grid from `origin` by `step` nearest to a row of coordinates and past them:
/// at or below each (`up` false, for the lowest corners) or at or above each (`up`, for the
/// highest; every coordinate at most the grid's last line, as [`grid_step`] makes it).
#[inline]
fn lines(origin: f32, step: f32, row: &[f32; LEAF], up: bool) -> [u8; LEAF] {
    let (o, s) = (Vec4::splat(origin), Vec4::splat(step));
    // Finite even for a zero step or one too small to invert, so that no guess is a NaN.
    let inverse = Vec4::splat((1.0 / step).min(f32::MAX));
    let mut out = [0u8; LEAF];
    for (half, out) in row.chunks_exact(4).zip(out.chunks_exact_mut(4)) {
        let x = Vec4::from_slice(half);
        // A guess, then one exact correction: rounding leaves the guess at most one line off
        // near the origin.
        let mut q = ((x - o) * inverse).max(Vec4::ZERO).min(Vec4::splat(255.0));
        // Rounded to a whole number: past 2^23 an f32 holds nothing finer.
        q = (q + Vec4::splat(8_388_608.0)) - Vec4::splat(8_388_608.0);
        let line = o + q * s;
        q = if up {
            (q + Vec4::select(line.cmplt(x), Vec4::ONE, Vec4::ZERO)).min(Vec4::splat(255.0))
        } else {
            (q - Vec4::select(line.cmpgt(x), Vec4::ONE, Vec4::ZERO)).max(Vec4::ZERO)
        };
        let line = o + q * s;
        let off = if up { line.cmplt(x) } else { line.cmpgt(x) };
        // Whole numbers up to 255 plus 2^23 are exact, with the number in the low byte of their
        // bits (a plain `as u8` would saturate each lane on its own).
        let bits = (q + Vec4::splat(8_388_608.0)).to_array();
        for (out, b) in out.iter_mut().zip(bits) {
            *out = b.to_bits() as u8;
        }
        // Far from the origin (a coordinate's rounding worth more than a line) or for a step
        // too small to invert, the guess can be further off: search the lines there.
        let mut off = off.bitmask();
        while off != 0 {
            let j = off.trailing_zeros() as usize;
            off &= off - 1;
            out[j] = line_by_search(origin, step, half[j], up);
        }
    }
    out
}

/// The line [`lines`] wants for `x`, by a binary search over the 256 lines (their positions
/// rise with their number): the highest at or below `x` (line 0, the origin, is), or with `up`
/// the lowest at or above it (line 255 is).
fn line_by_search(origin: f32, step: f32, x: f32, up: bool) -> u8 {
    // Invariant: the answer is in lo..=hi.
    let (mut lo, mut hi) = (0u8, u8::MAX);
    while lo < hi {
        if up {
            let mid = lo + (hi - lo) / 2;
            if grid_line(origin, step, mid) >= x {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        } else {
            let mid = hi - (hi - lo) / 2;
            if grid_line(origin, step, mid) <= x {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
    }
    lo
}

/// The vertex id of a free place in a leaf.
const FREE: u32 = u32::MAX - 1;
/// The id standing in for a vertex whose pairs are not skipped (matches no vertex).
const NONE: u32 = u32::MAX;

/// What the tree holds of one face.
#[derive(Clone, Copy)]
pub(super) struct Placed {
    pub(super) bounds: Box3,
    /// Its vertex ids (below [`crate::corner_table::MAX_VERTICES`]).
    pub(super) vertices: [u32; 3],
    /// Bit `k`: pairs of faces sharing its vertex `k` are skipped (a property of the vertex, the
    /// same from every face that has it).
    pub(super) skipped: u8,
    /// Its turn bits ([`super::patches::turn_bits`]).
    pub(super) bits: u8,
    /// The flat region it belongs to ([`super::regions`]), or [`NONE`]: pairs of faces of one
    /// region are skipped.
    pub(super) region: u32,
    /// Up to two regions whose faces it cannot meet: the region it is in, or regions it touches
    /// only at their corners or along their edges ([`super::regions::Regions::covers`]); [`NONE`]
    /// in unused places.
    pub(super) covers: [u32; 2],
}

/// What all faces of a node have in common that rules out pairs among them: `[hub, region,
/// cover, cover]`, a vertex every face has whose pairs are skipped, the region every face belongs
/// to, and up to two regions no face of the node can meet ([`Placed::covers`]; [`NONE`] where
/// there is none). Two nodes with the same hub or region have no pair between them to report,
/// nor do a node whose faces all belong to a region and one that covers that region; a node with
/// a hub or a region has none within.
type Marks = [u32; 4];

/// The vertices of `vertices` that bit `k` of `bits` marks as skipped, [`NONE`] for the others.
#[inline]
fn skipped_of(bits: u8, vertices: [u32; 3]) -> [u32; 3] {
    std::array::from_fn(|k| {
        if bits & (1 << k) != 0 {
            vertices[k]
        } else {
            NONE
        }
    })
}

/// The marks of a node made of two nodes.
fn join_marks(a: Marks, b: Marks) -> Marks {
    let [c, d] = common_covers([a[2], a[3]], [b[2], b[3]]);
    [
        if a[0] == b[0] { a[0] } else { NONE },
        if a[1] == b[1] { a[1] } else { NONE },
        c,
        d,
    ]
}

/// The regions both cover sets hold ([`NONE`] in unused places).
#[inline]
fn common_covers(a: [u32; 2], b: [u32; 2]) -> [u32; 2] {
    a.map(|r| if r != NONE && b.contains(&r) { r } else { NONE })
}

/// Whether the nodes marked `a` and `b` share a hub or a region.
#[inline]
fn marked_apart(a: Marks, b: Marks) -> bool {
    (a[0] != NONE && a[0] == b[0])
        || (a[1] != NONE && (a[1] == b[1] || a[1] == b[2] || a[1] == b[3]))
        || (b[1] != NONE && (b[1] == a[2] || b[1] == a[3]))
}

/// The tree over sorted face boxes.
pub(super) struct Tree {
    leaves: Vec<Leaf>,
    /// The boxes of every level, leaves first, the root last.
    levels: Vec<Vec<Box3>>,
    /// The turn bits all faces of a node share, level by level as `levels`.
    bits: Vec<Vec<u8>>,
    /// Each node's [`Marks`], level by level as `levels`.
    marks: Vec<Vec<Marks>>,
    /// The number of faces.
    faces: usize,
}

impl Tree {
    /// The tree over `n` faces in their sorted order, `face(p)` the one at place `p`. The tree
    /// keeps what it needs of them, so the caller need not hold the boxes while it is built.
    pub(super) fn build(n: usize, face: impl Fn(usize) -> Placed + Sync) -> Tree {
        type Built = (Vec<Leaf>, (Vec<Box3>, (Vec<u8>, Vec<Marks>)));
        let (leaves, (leaf_boxes, (leaf_bits, leaf_marks))): Built = (0..n.div_ceil(LEAF))
            .into_par_iter()
            .with_min_len(1 << 12)
            .map(|l| {
                let mut leaf = Leaf {
                    origin: [0.0; 3],
                    step: [0.0; 3],
                    grid: [[0; LEAF]; 6],
                    vertices: [[FREE; LEAF]; 3],
                    skipped: [0; LEAF],
                    used: 0,
                };
                // The faces' boxes coordinate by coordinate (free places repeat the first face's).
                let first = face(LEAF * l);
                let mut boxes = first.bounds.map(|x| [x; LEAF]);
                let mut all = u8::MAX;
                // The first face's skipped vertices, kept while every face has them.
                let mut hubs = skipped_of(first.skipped, first.vertices);
                let mut region = first.region;
                let mut covers = first.covers;
                for j in 0..LEAF.min(n - LEAF * l) {
                    let f = if j == 0 { first } else { face(LEAF * l + j) };
                    for (row, x) in boxes.iter_mut().zip(f.bounds) {
                        row[j] = x;
                    }
                    for (row, v) in leaf.vertices.iter_mut().zip(f.vertices) {
                        row[j] = v;
                    }
                    leaf.skipped[j] = f.skipped;
                    leaf.used |= 1 << j;
                    all &= f.bits;
                    for h in &mut hubs {
                        if !f.vertices.contains(h) {
                            *h = NONE;
                        }
                    }
                    if f.region != region {
                        region = NONE;
                    }
                    covers = common_covers(covers, f.covers);
                }
                let bounds = leaf.place(&boxes);
                let hub = hubs.into_iter().find(|&h| h != NONE).unwrap_or(NONE);
                (leaf, (bounds, (all, [hub, region, covers[0], covers[1]])))
            })
            .unzip();
        let levels = levels_above(leaf_boxes, |a, b| join(&a, &b));
        let bits = levels_above(leaf_bits, |a, b| a & b);
        let marks = levels_above(leaf_marks, join_marks);
        Tree {
            leaves,
            levels,
            bits,
            marks,
            faces: n,
        }
    }

    /// The vertex ids of the face at place `p`.
    #[inline]
    pub(super) fn vertices(&self, p: u32) -> [u32; 3] {
        let (leaf, j) = (&self.leaves[p as usize / LEAF], p as usize % LEAF);
        std::array::from_fn(|k| leaf.vertices[k][j])
    }

    /// Calls `visit.pair` once for every unordered pair of faces whose boxes overlap.
    pub(super) fn walk<V: Visit>(&self, visit: &mut V) {
        if self.leaves.is_empty() {
            return;
        }
        self.within(self.levels.len() - 1, 0, visit);
    }

    fn parallel(&self, k: usize) -> bool {
        LEAF << k >= PARALLEL_FACES
    }

    /// The boxes of `leaf`'s faces, read back from its grid.
    #[inline]
    fn lanes(leaf: &Leaf) -> Lanes {
        Lanes {
            rows: std::array::from_fn(|c| {
                row_lines(leaf.origin[c % 3], leaf.step[c % 3], leaf.grid[c])
            }),
            used: leaf.used,
        }
    }

    /// Bit `j` set: face `j` of `leaf` (boxes `lanes`) is a pair to report with face `f` of
    /// `other` (boxes `other_lanes`): their boxes overlap and they share no skipped vertex of
    /// `f`'s.
    #[inline]
    fn pairing(leaf: &Leaf, lanes: &Lanes, other: &Leaf, other_lanes: &Lanes, f: usize) -> u32 {
        let mut hits = Self::overlapping(lanes, &Self::face_box(other_lanes, f));
        let bits = other.skipped[f];
        if bits == 0 {
            return hits;
        }
        let skipped = skipped_of(bits, std::array::from_fn(|k| other.vertices[k][f]));
        // Few boxes overlap: test their faces one by one.
        let mut pairs = hits;
        while hits != 0 {
            let j = hits.trailing_zeros() as usize;
            hits &= hits - 1;
            let shares = leaf.vertices.iter().any(|row| skipped.contains(&row[j]));
            pairs &= !(u32::from(shares) << j);
        }
        pairs
    }

    /// Bit `j` set: place `j` holds a face whose box overlaps `b`.
    #[inline]
    fn overlapping(lanes: &Lanes, b: &Box3) -> u32 {
        // Four lanes at a time in glam's vector type (SSE on x86-64): six compares, five ands and
        // one move of the lanes' signs into bits per half (plain loops over the lanes were only
        // partly vectorised, the rest compared and combined lane by lane).
        let half = |k: usize| {
            let mut hit = BVec4A::splat(true);
            for axis in 0..3 {
                hit &= lanes.rows[axis][k].cmple(Vec4::splat(b[axis + 3]));
                hit &= Vec4::splat(b[axis]).cmple(lanes.rows[axis + 3][k]);
            }
            hit.bitmask()
        };
        (half(0) | half(1) << 4) & u32::from(lanes.used)
    }

    fn face_box(lanes: &Lanes, j: usize) -> Box3 {
        std::array::from_fn(|c| lanes.rows[c][j / 4][j % 4])
    }

    /// Pairs within node `i` of level `k`.
    fn within<V: Visit>(&self, k: usize, i: usize, visit: &mut V) {
        let marks = self.marks[k][i];
        if visit.done() || marks[0] != NONE || marks[1] != NONE {
            return;
        }
        let bits = self.bits[k][i];
        if k >= PATCH_LEVEL && bits != 0 {
            let places = (LEAF << k) * i..self.faces.min((LEAF << k) * (i + 1));
            if visit.no_pairs_within(places, bits) {
                return;
            }
        }
        if k == 0 {
            let leaf = &self.leaves[i];
            let lanes = Self::lanes(leaf);
            let base = (LEAF * i) as u32;
            for j in 0..LEAF - 1 {
                let mut hits = Self::pairing(leaf, &lanes, leaf, &lanes, j) & !((2 << j) - 1);
                while hits != 0 {
                    let other = hits.trailing_zeros();
                    hits &= hits - 1;
                    visit.pair(base + j as u32, base + other);
                }
            }
            return;
        }
        let (c0, c1) = (2 * i, 2 * i + 1);
        if c1 >= self.levels[k - 1].len() {
            self.within(k - 1, c0, visit);
        } else if self.parallel(k) {
            self.within_in_parallel(k, c0, c1, visit);
        } else {
            self.within(k - 1, c0, visit);
            self.within(k - 1, c1, visit);
            self.between(k - 1, c0, c1, visit);
        }
    }

    /// [`Tree::within`] for a big node with children `c0` and `c1`: three parallel tasks. Kept out
    /// of line so that the many small calls do not carry the forks' stack frame.
    #[inline(never)]
    fn within_in_parallel<V: Visit>(&self, k: usize, c0: usize, c1: usize, visit: &mut V) {
        let (mut v1, mut v2) = (visit.fork(), visit.fork());
        rayon::join(
            || self.within(k - 1, c0, visit),
            || {
                rayon::join(
                    || self.within(k - 1, c1, &mut v1),
                    || self.between(k - 1, c0, c1, &mut v2),
                )
            },
        );
        visit.merge(v1);
        visit.merge(v2);
    }

    /// Pairs between nodes `a` and `b` of level `k` (different faces).
    fn between<V: Visit>(&self, k: usize, a: usize, b: usize, visit: &mut V) {
        if visit.done()
            || !overlap(&self.levels[k][a], &self.levels[k][b])
            || marked_apart(self.marks[k][a], self.marks[k][b])
        {
            return;
        }
        if k == 0 {
            self.between_leaves(a, b, visit);
            return;
        }
        if self.parallel(k) {
            self.between_in_parallel(k, a, b, visit);
            return;
        }
        // Both nodes split: up to four pairs of children.
        let below = &self.levels[k - 1];
        let (a1, b1) = (
            (2 * a + 1).min(below.len() - 1),
            (2 * b + 1).min(below.len() - 1),
        );
        for x in 2 * a..=a1 {
            for y in 2 * b..=b1 {
                if k == 1 {
                    let marks = &self.marks[0];
                    if overlap(&below[x], &below[y]) && !marked_apart(marks[x], marks[y]) {
                        self.between_leaves(x, y, visit);
                    }
                } else {
                    self.between(k - 1, x, y, visit);
                }
            }
        }
    }

    /// The pairs of faces of leaves `a` and `b` whose boxes overlap.
    #[inline]
    fn between_leaves<V: Visit>(&self, a: usize, b: usize, visit: &mut V) {
        let (leaf_a, leaf_b) = (&self.leaves[a], &self.leaves[b]);
        let (base_a, base_b) = ((LEAF * a) as u32, (LEAF * b) as u32);
        // The faces of a that overlap b's box, then each against b's faces.
        let lanes_a = Self::lanes(leaf_a);
        let mut near = Self::overlapping(&lanes_a, &self.levels[0][b]);
        if near == 0 {
            return;
        }
        let lanes_b = Self::lanes(leaf_b);
        while near != 0 {
            let j = near.trailing_zeros();
            near &= near - 1;
            let mut hits = Self::pairing(leaf_b, &lanes_b, leaf_a, &lanes_a, j as usize);
            while hits != 0 {
                let other = hits.trailing_zeros();
                hits &= hits - 1;
                visit.pair(base_a + j, base_b + other);
            }
        }
    }

    /// [`Tree::between`] for big nodes: the pairs of children as four parallel tasks.
    #[inline(never)]
    fn between_in_parallel<V: Visit>(&self, k: usize, a: usize, b: usize, visit: &mut V) {
        let below = self.levels[k - 1].len();
        let children = |i: usize| [Some(2 * i), (2 * i + 1 < below).then_some(2 * i + 1)];
        let ([x0, x1], [y0, y1]) = (children(a), children(b));
        let pairs = [(x0, y0), (x0, y1), (x1, y0), (x1, y1)].map(|(x, y)| x.zip(y));
        let mut forks = [visit.fork(), visit.fork(), visit.fork()];
        let [f1, f2, f3] = &mut forks;
        let go = |pair: Option<(usize, usize)>, v: &mut V| {
            if let Some((x, y)) = pair {
                self.between(k - 1, x, y, v);
            }
        };
        rayon::join(
            || rayon::join(|| go(pairs[0], visit), || go(pairs[1], f1)),
            || rayon::join(|| go(pairs[2], f2), || go(pairs[3], f3)),
        );
        for v in forks {
            visit.merge(v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::curve;

    /// Collects the pairs the walk reports, as (lower, higher) sorted positions.
    struct Pairs(Vec<(u32, u32)>);

    impl Pairs {
        /// The pairs as (lower, higher) input numbers (`order[p]`: the input at place `p`),
        /// sorted.
        fn in_input_order(&self, order: &[u32]) -> Vec<(u32, u32)> {
            let mut pairs: Vec<(u32, u32)> = self
                .0
                .iter()
                .map(|&(a, b)| {
                    let (a, b) = (order[a as usize], order[b as usize]);
                    (a.min(b), a.max(b))
                })
                .collect();
            pairs.sort_unstable();
            pairs
        }
    }

    impl Visit for Pairs {
        fn fork(&self) -> Self {
            Pairs(Vec::new())
        }
        fn merge(&mut self, other: Self) {
            self.0.extend(other.0);
        }
        fn pair(&mut self, a: u32, b: u32) {
            self.0.push((a.min(b), a.max(b)));
        }
        fn done(&self) -> bool {
            false
        }
    }

    /// 10,000 random boxes (so the walk runs as parallel tasks) of sides up to 0.06 in the unit
    /// cube, plus a few long thin ones, their faces on vertices numbered along x (so that many
    /// overlapping pairs share one), half the vertices skipped, and a third of the faces in
    /// regions (by their box's x, so that whole leaves and nodes are in one): the walk reports
    /// every overlapping pair that shares no skipped vertex and no region, as a test of all
    /// n(n-1)/2 pairs finds them, each once. Pairs of one region it leaves out only where whole
    /// nodes are in the region; the rest the visitor drops (as the search does), and so does
    /// this test. The faces of two slices beside region 0 (and region 3) cover both regions (as
    /// walls standing on a plate cover it): pairs of a region's face and a face that covers the
    /// region may be left out too, and are dropped by this test; no other pair is missed.
    /// Leaves keep boxes on their grid, rounded outward, so it may add pairs whose boxes come
    /// within a line of the grid (a leaf here is at most about 1.1 across: under 0.0045 a line, two of
    /// them within the 0.005 the test widens boxes by), and only a few
    /// (under a tenth as many as the overlapping pairs).
    #[test]
    fn walk_finds_every_overlapping_pair_once_but_those_on_skipped_vertices() {
        let mut bits = crate::geometry::xorshift(0x9e37_79b9_7f4a_7c15);
        let mut next = || (bits() >> 11) as f64 / (1u64 << 53) as f64;
        let mut boxes: Vec<Box3> = (0..10_000)
            .map(|_| {
                let lo = [next(), next(), next()];
                let side = [0.06 * next(), 0.06 * next(), 0.06 * next()];
                box_of(&[lo, std::array::from_fn(|k| lo[k] + side[k]), lo])
            })
            .collect();
        for k in 0..3 {
            let mut hi = [0.51; 3];
            hi[k] = 1.0;
            boxes.push(box_of(&[[0.5; 3], hi, hi]));
        }
        let skipped: Vec<bool> = (0..300).map(|_| next() < 0.5).collect();
        let vertices: Vec<[u32; 3]> = boxes
            .iter()
            .map(|b| {
                // Near boxes get near vertices, so that overlapping pairs often share one.
                let base = (b[0] * 200.0) as u32;
                let a = base + (next() * 6.0) as u32;
                let b = a + 1 + (next() * 6.0) as u32;
                [a, b, b + 1 + (next() * 6.0) as u32]
            })
            .collect();
        let regions: Vec<u32> = boxes
            .iter()
            .map(|b| {
                let r = (b[0] * 6.0) as u32;
                if r.is_multiple_of(3) {
                    r
                } else {
                    NONE
                }
            })
            .collect();
        let covers: Vec<[u32; 2]> = boxes
            .iter()
            .zip(&regions)
            .map(|(b, &r)| match (b[0] * 6.0) as u32 {
                _ if r != NONE => [r, NONE],
                1 | 4 => [0, 3],
                _ => [NONE; 2],
            })
            .collect();
        // A pair of a region's face and a face outside it that covers the region.
        let covered = |a: usize, b: usize| {
            regions[a] != regions[b]
                && ((regions[a] != NONE && covers[b].contains(&regions[a]))
                    || (regions[b] != NONE && covers[a].contains(&regions[b])))
        };
        let order = curve::order(boxes.len(), |i| centre(&boxes[i]));
        let faces = |p: usize| {
            let v = vertices[order[p] as usize];
            let skipped = (0..3).fold(0, |m, k| m | u8::from(skipped[v[k] as usize]) << k);
            Placed {
                bounds: boxes[order[p] as usize],
                vertices: v,
                skipped,
                bits: 0,
                region: regions[order[p] as usize],
                covers: covers[order[p] as usize],
            }
        };
        let mut found = Pairs(Vec::new());
        let tree = Tree::build(boxes.len(), faces);
        for p in 0..boxes.len() {
            assert_eq!(tree.vertices(p as u32), vertices[order[p] as usize]);
        }
        tree.walk(&mut found);
        let mut found = found.in_input_order(&order);
        assert!(found.windows(2).all(|w| w[0] != w[1]), "a pair twice");
        found.retain(|&(a, b)| {
            (regions[a as usize] == NONE || regions[a as usize] != regions[b as usize])
                && !covered(a as usize, b as usize)
        });
        let widened = |b: &Box3| std::array::from_fn(|c| b[c] + if c < 3 { -0.005 } else { 0.005 });
        let (mut all, mut near, mut left_out, mut all_covered) = (Vec::new(), Vec::new(), 0, 0);
        for a in 0..boxes.len() {
            for b in a + 1..boxes.len() {
                let on_vertex = vertices[a]
                    .iter()
                    .any(|v| skipped[*v as usize] && vertices[b].contains(v));
                let on_skipped =
                    on_vertex || (regions[a] != NONE && regions[a] == regions[b]) || covered(a, b);
                if overlap(&boxes[a], &boxes[b]) {
                    all_covered += usize::from(covered(a, b) && !on_vertex);
                    if on_skipped {
                        left_out += 1;
                    } else {
                        all.push((a as u32, b as u32));
                    }
                }
                if !on_skipped && overlap(&widened(&boxes[a]), &widened(&boxes[b])) {
                    near.push((a as u32, b as u32));
                }
            }
        }
        assert!(
            all.len() > 1000 && left_out > 1000,
            "{} pairs, {left_out} left out",
            all.len()
        );
        let missed: Vec<_> = all
            .iter()
            .filter(|p| found.binary_search(p).is_err())
            .collect();
        assert!(missed.is_empty(), "missed {missed:?}");
        let far: Vec<_> = found
            .iter()
            .filter(|p| near.binary_search(p).is_err())
            .collect();
        assert!(far.is_empty(), "pairs of far boxes {far:?}");
        assert!(all_covered > 200, "{all_covered} covered pairs");
        let extra = found.len() - all.len();
        assert!(extra < all.len() / 10, "{extra} extra of {}", all.len());
    }

    /// Walls standing on a plate: 1,024 long faces of one flat region (boxes 0.5 x 1 x 0, all
    /// overlapping in y) and 1,024 walls (boxes 0.01 x 0.01 x 1 from the plate up) that cover the
    /// region (they touch its plane only at its corners or along its edges), every vertex its own.
    /// Sorted along the curve, the plate's faces (box centres at z = 0) and the walls' (z = 0.5)
    /// fill nodes of their own but for a few leaves where the curve passes from one to the other,
    /// so the walk leaves the plate-wall pairs out as whole nodes: it reports under a tenth of the
    /// plate-wall pairs whose boxes overlap (a test of all pairs counts them; all were reported
    /// without the covers), and every overlapping pair of two walls.
    #[test]
    fn walls_covering_a_plate_are_left_out_as_whole_nodes() {
        let mut bits = crate::geometry::xorshift(0x3c6e_f372_fe94_f82b);
        let mut next = || (bits() >> 11) as f64 / (1u64 << 53) as f64;
        let n = 1024;
        let mut boxes: Vec<Box3> = (0..n)
            .map(|_| {
                let x = next();
                box_of(&[[x, 0.0, 0.0], [x + 0.5, 1.0, 0.0], [x, 1.0, 0.0]])
            })
            .collect();
        boxes.extend((0..n).map(|_| {
            let (x, y) = (next(), next());
            box_of(&[[x, y, 0.0], [x + 0.01, y + 0.01, 1.0], [x, y, 1.0]])
        }));
        let wall = |i: usize| i >= n;
        let order = curve::order(boxes.len(), |i| centre(&boxes[i]));
        let tree = Tree::build(boxes.len(), |p| {
            let i = order[p] as usize;
            Placed {
                bounds: boxes[i],
                vertices: [3 * i as u32, 3 * i as u32 + 1, 3 * i as u32 + 2],
                skipped: 0,
                bits: 0,
                region: if wall(i) { NONE } else { 7 },
                covers: [7, NONE],
            }
        });
        let mut found = Pairs(Vec::new());
        tree.walk(&mut found);
        let found = found.in_input_order(&order);
        let reported = |a: usize, b: usize| found.binary_search(&(a as u32, b as u32)).is_ok();
        let (mut plate_walls, mut reported_plate_walls) = (0, 0);
        for a in 0..boxes.len() {
            for b in a + 1..boxes.len() {
                if !overlap(&boxes[a], &boxes[b]) {
                    continue;
                }
                match (wall(a), wall(b)) {
                    (false, true) => {
                        plate_walls += 1;
                        reported_plate_walls += usize::from(reported(a, b));
                    }
                    (true, true) => assert!(reported(a, b), "walls {a} and {b}"),
                    _ => {}
                }
            }
        }
        assert!(plate_walls > 10_000, "{plate_walls}");
        assert!(
            reported_plate_walls * 10 < plate_walls,
            "{reported_plate_walls} of {plate_walls}"
        );
    }

    /// Counts the nodes the walk visits (every visit asks whether it is done) and the pairs it
    /// reports, those of two faces of a group (`grouped`, by place) apart.
    struct Visits<'a> {
        visits: std::cell::Cell<usize>,
        pairs: usize,
        within_group: usize,
        grouped: &'a [bool],
    }

    impl Visit for Visits<'_> {
        fn fork(&self) -> Self {
            Visits {
                visits: Default::default(),
                pairs: 0,
                within_group: 0,
                grouped: self.grouped,
            }
        }
        fn merge(&mut self, other: Self) {
            self.visits.set(self.visits.get() + other.visits.get());
            self.pairs += other.pairs;
            self.within_group += other.within_group;
        }
        fn pair(&mut self, a: u32, b: u32) {
            if self.grouped[a as usize] && self.grouped[b as usize] {
                self.within_group += 1;
            } else {
                self.pairs += 1;
            }
        }
        fn done(&self) -> bool {
            self.visits.set(self.visits.get() + 1);
            false
        }
    }

    /// A fan of 4,096 long faces around one vertex (the cap of a finely divided cylinder), and
    /// a small face at the outer edge of each (its wall, on vertices of its own): every fan box
    /// holds the centre, so every pair of them overlaps, and the walls make the nodes near the
    /// root mixed. With the centre skipped, or the fan one region, the walk leaves the fan's
    /// pairs out where two nodes (or one) first share the centre or the region, in a few
    /// thousand visits, and still reports each wall with its two fan faces (a test of all pairs
    /// finds no other; the leaves' grids add some near ones); with neither, it reports the fan's
    /// 8,386,560 pairs too.
    #[test]
    fn a_fan_on_a_skipped_vertex_or_in_one_region_is_not_walked_pair_by_pair() {
        let n = 4_096u32;
        let rim = |i: u32| {
            let a = std::f64::consts::TAU * f64::from(i % n) / f64::from(n);
            [a.cos(), a.sin(), 0.0]
        };
        let mut boxes: Vec<Box3> = (0..n)
            .map(|i| box_of(&[[0.0; 3], rim(i), rim(i + 1)]))
            .collect();
        boxes.extend((0..n).map(|i| {
            let [x, y, _] = rim(i);
            box_of(&[[x, y, 0.0], [x, y, 1.0], [x * 1.001, y * 1.001, 0.5]])
        }));
        let order = curve::order(boxes.len(), |i| centre(&boxes[i]));
        let walk = |skipped: u8, region: u32| {
            let tree = Tree::build(boxes.len(), |p| {
                let i = order[p];
                let fan = i < n;
                Placed {
                    bounds: boxes[i as usize],
                    vertices: if fan {
                        [0, 1 + i, 1 + (i + 1) % n]
                    } else {
                        [3 * i, 3 * i + 1, 3 * i + 2]
                    },
                    skipped: if fan { skipped } else { 0 },
                    bits: 0,
                    region: if fan { region } else { NONE },
                    covers: [if fan { region } else { NONE }, NONE],
                }
            });
            let grouped: Vec<bool> = order.iter().map(|&i| i < n).collect();
            let mut visits = Visits {
                visits: Default::default(),
                pairs: 0,
                within_group: 0,
                grouped: &grouped,
            };
            tree.walk(&mut visits);
            (visits.visits.get(), visits.pairs, visits.within_group)
        };
        let fan_pairs = (n * (n - 1) / 2) as usize;
        let mut others = 0;
        for a in 0..boxes.len() {
            for b in (a + 1).max(n as usize)..boxes.len() {
                others += usize::from(overlap(&boxes[a], &boxes[b]));
            }
        }
        // Each wall's box touches its two fan faces' boxes; each sticker's overlaps the boxes
        // of the fan faces of its quadrant that reach past it.
        assert!(others >= 2 * n as usize, "{others}");
        // The leaves' grids may add pairs of boxes a grid line apart: a wall's box is rounded
        // out to its leaf's lines, 1/256 of a leaf that holds long fan faces, wider than the
        // 0.0015 between walls.
        let few = |pairs: usize, all: usize| (all..4 * all).contains(&pairs);
        let (_, pairs, fan) = walk(0, NONE);
        assert!(few(pairs, others), "{pairs} pairs");
        assert_eq!(fan, fan_pairs);
        for (skipped, region) in [(1, NONE), (0, 7)] {
            let (visits, pairs, fan) = walk(skipped, region);
            assert!(few(pairs, others), "{pairs} pairs");
            // Pairs of the fan within leaves (or nodes) shared with walls are reported when
            // they share a region, not a skipped vertex: the search drops those.
            assert!(fan < 16 * n as usize, "{fan} fan pairs");
            assert!(visits < 8 * n as usize, "{visits} visits");
        }
    }

    /// A leaf's grid holds its faces' boxes: a row's lines, read back as the walk reads them
    /// ([`row_lines`]), are at or below each lowest coordinate and at or above each highest, and
    /// the lowest line is the grid's origin. Random rows of every size: leaves near the origin
    /// and far from it (where a line is less than a unit in the last place of the coordinates),
    /// wide and narrow (down to a step too small to invert in `f32`, as a tiny face's box near
    /// zero has), with repeated values, -0.0 beside a grid from 0.0, a row of one value (a zero
    /// step), and grids that start below the row and end above it (a leaf's highest corners,
    /// on a grid from its lowest). Where the lines are searched, the search finds the nearest
    /// line, as a look at all 256 does.
    #[test]
    fn grid_lines_hold_the_boxes() {
        let mut bits = crate::geometry::xorshift(0x5851_f42d_4c95_7f2d);
        let mut unit = || (bits() >> 40) as f32 / (1u32 << 24) as f32;
        for round in 0..20_000 {
            let centre = [0.0, 1.0, -3.0, 1e6, -1e12, 1e-30, 1e29][round % 7] * (1.0 + unit());
            let span = [0.0, 3e-38, 1e-30, 1e-6, 1.0, 1e3, 1e25][round / 7 % 7] * unit();
            let mut row: [f32; LEAF] = std::array::from_fn(|_| centre + span * unit());
            if round % 5 == 0 {
                row[3] = row[1];
            }
            let mut lo = row.iter().copied().fold(f32::INFINITY, f32::min);
            let mut hi = row.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            if round % 3 == 1 {
                (lo, hi) = (lo - span * unit(), hi + span * unit());
            }
            if round % 7 == 0 && round % 11 == 0 {
                row[2] = -0.0;
                (lo, hi) = (0.0, hi.max(0.0));
            }
            let step = grid_step(lo, hi);
            assert!(grid_line(lo, step, u8::MAX) >= hi, "{lo} {hi} {step}");
            let [below, above] = [false, true].map(|up| lines(lo, step, &row, up));
            let read = |q: [u8; LEAF]| {
                let [a, b] = row_lines(lo, step, q);
                let lanes: Vec<f32> = a.to_array().into_iter().chain(b.to_array()).collect();
                lanes
            };
            let (down, up) = (read(below), read(above));
            for j in 0..LEAF {
                assert!(
                    down[j] <= row[j] && row[j] <= up[j],
                    "{lo} {step} {row:?}: {j} {down:?} {up:?}"
                );
                assert_eq!(down[j], grid_line(lo, step, below[j]));
                assert_eq!(up[j], grid_line(lo, step, above[j]));
            }
            assert_eq!(grid_line(lo, step, 0), lo);
            if round % 10 == 0 {
                for &x in &row {
                    let lines = (0..=u8::MAX).map(|q| (q, grid_line(lo, step, q)));
                    let (floor, _) = lines.clone().rev().find(|l| l.1 <= x).unwrap();
                    let (ceiling, _) = lines.clone().find(|l| l.1 >= x).unwrap();
                    assert_eq!(line_by_search(lo, step, x, false), floor, "{lo} {step} {x}");
                    assert_eq!(
                        line_by_search(lo, step, x, true),
                        ceiling,
                        "{lo} {step} {x}"
                    );
                }
            }
        }
    }

    /// Rounded outward, a coordinate stays within its box's ends, which are a few units in the
    /// last place of an `f32` from it: random values of every size and sign below 2^100, values
    /// an `f32` holds exactly, halfway between two, zero and the smallest ones.
    #[test]
    fn ends_are_outside_and_near() {
        let mut bits = crate::geometry::xorshift(0x2545_f491_4f6c_dd1d);
        let mut values = vec![0.0, -0.0, 1e-300, -1e-300, 1e-40, 0.1, 2f64.powi(99)];
        values.extend([1.0f32, 3.5, 1e-30].map(f64::from));
        // Halfway between 1 and the next f32: rounds to even, down.
        values.push(1.0 + f64::from(f32::EPSILON) / 2.0);
        for _ in 0..100_000 {
            let r = bits();
            let mantissa = (r >> 11) as f64 / (1u64 << 53) as f64;
            let exponent = (r % 200) as i32 - 100;
            let sign = if r & (1 << 8) == 0 { 1.0 } else { -1.0 };
            values.push(sign * mantissa * 2f64.powi(exponent));
        }
        for x in values {
            let (lo, hi) = (down(x), up(x));
            assert!(f64::from(lo) <= x && x <= f64::from(hi), "{x}: {lo} {hi}");
            let near = |e: f32| (e - x as f32).abs() <= 3.0 * widening(x as f32);
            assert!(near(lo) && near(hi), "{x}: {lo} {hi}");
        }
    }

    /// `f64` boxes that touch at one coordinate still touch after rounding to `f32`: 0.1 is not an
    /// `f32`, and the box ending at 0.1 and the one starting there both keep it.
    #[test]
    fn rounding_keeps_touching_boxes_touching() {
        let a = box_of(&[[0.0; 3], [0.1; 3], [0.0; 3]]);
        let b = box_of(&[[0.1; 3], [0.2; 3], [0.2; 3]]);
        assert!(overlap(&a, &b));
        assert!(f64::from(a[3]) >= 0.1 && f64::from(b[0]) <= 0.1);
    }
}
