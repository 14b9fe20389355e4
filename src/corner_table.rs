//! The Corner Table ([definitions](crate::definitions#corner-table)): two flat arrays over
//! corners `c = 3t + k`.
//!
//! ```text
//!            v(p(c))                 V[c]  the welded vertex of corner c
//!             /\                     O[c]  the corner facing c across the edge opposite c
//!            /  \                          (the edge v(n(c)) - v(p(c)))
//!           / t  \
//!      v(c) ------ v(n(c))           n(c) next corner of t(c), p(c) = n(n(c))
//!           \    /                   l(c) = o(n(c)), r(c) = o(p(c)), s(c) = p(r(c)) (swing)
//!            \  /
//!             \/
//!           v(o(c))
//! ```
//!
//! Sentinels, as in parry's topology arrays:
//! - a **border** corner (its opposite edge bounds one face) has `O[c] == c`;
//! - a corner whose opposite edge bounds three or more faces has `O[c] == NON_MANIFOLD`. It never gets
//!   a made-up opposite; the faces of such an edge are listed by [`CornerTable::nonmanifold_edges`].
//!
//! A manifold edge is paired whatever the windings of its two faces: `O` records adjacency, and
//! [`CornerTable::is_consistent`] says whether the pair traverses the edge in opposite directions
//! (a bit per corner, found during the build, so walks never re-read `V` to decide it).
//!
//! `O` is built in linear time by bucketing corners by the lower vertex of their opposite edge and
//! sorting each (small) bucket by the higher vertex: runs of equal keys are the edges, their lengths
//! the valences. Faces in any order ([`CornerTable::build`]) get a counting sort of the corners
//! themselves. Faces ordered by their lowest vertex (as the analysis orders them) need only a
//! counting sort of faces: the corners whose opposite edge has lower vertex `x` are the two other
//! corners of each face whose lowest vertex is `x`, plus the corners at the lowest vertex of faces
//! whose middle vertex is `x`, grouped by that one sort. Buckets of different vertices are
//! independent, so a big ordered table is paired on every thread of the current rayon pool.

/// `O[c]` for a corner whose opposite edge bounds three or more faces.
pub const NON_MANIFOLD: u32 = u32::MAX;

/// The largest number of triangles a table holds (corners and the sentinel must fit in `u32`).
pub const MAX_TRIANGLES: usize = (u32::MAX as usize - 2) / 3;

/// The largest number of vertices a table is built over (a vertex, a direction bit and a corner share
/// one `u64` sort key).
pub const MAX_VERTICES: usize = 1 << 31;

/// `V` and `O` for a set of triangles over welded vertices.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CornerTable {
    /// `V`, one `[u32; 3]` per triangle: `V[c] = v[c / 3][c % 3]`.
    v: Vec<[u32; 3]>,
    o: Vec<u32>,
    /// Bit `c` set: the manifold edge opposite `c` is traversed in the same direction by both faces.
    same_direction: Vec<u64>,
    vertex_count: usize,
    edge_count: usize,
    border_count: usize,
    /// Corners of the non-manifold edges, edge after edge (CSR with `nm_offsets`).
    nm_corners: Vec<u32>,
    nm_offsets: Vec<u32>,
}

impl CornerTable {
    /// Builds the table for triangles over vertices `0..vertex_count`.
    ///
    /// Each triangle must have three distinct vertices below `vertex_count` (the analysis leaves
    /// degenerate faces out before building), and there must be at most [`MAX_TRIANGLES`].
    pub fn build(triangles: &[[u32; 3]], vertex_count: usize) -> CornerTable {
        CornerTable::from_triangles(triangles.to_vec(), vertex_count)
    }

    /// [`CornerTable::build`], keeping the triangle list as `V` instead of copying it.
    pub fn from_triangles(triangles: Vec<[u32; 3]>, vertex_count: usize) -> CornerTable {
        check_size(&triangles, vertex_count);
        // Faces in any order: a counting sort of the corners themselves by the lower vertex of
        // their opposite edge, each slot holding the corner's bucket key.
        let mut lower = Bounds::new(vertex_count);
        for t in &triangles {
            for k in 0..3 {
                let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
                lower.count(a.min(b) as usize);
            }
        }
        lower.open();
        let mut keys = vec![0u64; 3 * triangles.len()];
        for (f, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
                keys[lower.slot(a.min(b) as usize)] = key_of(a, b, (3 * f + k) as u32);
            }
        }
        let mut o = vec![0u32; keys.len()];
        let mut out = Paired::default();
        let mut set = |_: &mut Paired, c: u32, to: u32| o[c as usize] = to;
        for w in lower.close().windows(2) {
            let bucket = &mut keys[w[0] as usize..w[1] as usize];
            sort_small(bucket);
            pair_bucket(bucket, &mut out, &mut set);
        }
        drop(keys);
        assemble(o, vertex_count, vec![out]).with_triangles(triangles)
    }

    /// The table of triangles already ordered by their lowest vertex, given the bounds of each
    /// vertex's faces (`lowest[x]..lowest[x + 1]`) and, in runs, the corners at the faces' lowest
    /// vertices grouped by the lower vertex of their opposite edge (what the analysis sorts while
    /// it welds the faces). With `parallel`, the buckets are paired on every thread of the current
    /// rayon pool; the table is the same.
    pub(crate) fn from_grouped(
        triangles: Vec<[u32; 3]>,
        vertex_count: usize,
        lowest: &[u32],
        apexes: &[Apexes],
        parallel: bool,
    ) -> CornerTable {
        check_size(&triangles, vertex_count);
        let groups = Groups { lowest, apexes };
        let table = pair(&triangles, vertex_count, &groups, parallel);
        table.with_triangles(triangles)
    }

    fn with_triangles(mut self, triangles: Vec<[u32; 3]>) -> CornerTable {
        self.v = triangles;
        self
    }

    /// Reverses the winding of every triangle `t` with `flip[t]`: its corners 1 and 2 swap places,
    /// as a build from the flipped triangles numbers them. Adjacency does not change, so the table
    /// is updated in one pass over the corners instead of rebuilt: each corner moves to its new
    /// place with its opposite renamed the same way, and a manifold edge's direction bit toggles
    /// when exactly one of its two faces flips. The result equals a build of the flipped triangles.
    pub fn flip_triangles(&mut self, flip: &[bool]) {
        assert_eq!(flip.len(), self.v.len(), "one flag per triangle");
        let moved = |c: u32| -> u32 {
            match (flip[c as usize / 3], c % 3) {
                (true, 1) => c + 1,
                (true, 2) => c - 1,
                _ => c,
            }
        };
        let mut o = vec![0u32; self.o.len()];
        let mut same_direction = vec![0u64; self.same_direction.len()];
        for c in 0..self.o.len() as u32 {
            let x = self.o[c as usize];
            let d = moved(c);
            o[d as usize] = if x == NON_MANIFOLD {
                NON_MANIFOLD
            } else if x == c {
                d
            } else {
                let toggled = flip[c as usize / 3] != flip[x as usize / 3];
                if self.is_consistent(c) == toggled {
                    same_direction[d as usize / 64] |= 1 << (d % 64);
                }
                moved(x)
            };
        }
        self.o = o;
        self.same_direction = same_direction;
        for (t, &f) in self.v.iter_mut().zip(flip) {
            if f {
                t.swap(1, 2);
            }
        }
        for w in self.nm_offsets.windows(2) {
            let edge = &mut self.nm_corners[w[0] as usize..w[1] as usize];
            for c in edge.iter_mut() {
                *c = moved(*c);
            }
            edge.sort_unstable();
        }
    }

    /// Adds `triangles` after the table's own, as a build of all of them in that order would,
    /// when none of their edges would bound three or more faces: each new edge pairs with the one
    /// face of an old border edge, or with another new triangle, or is a border. Returns `false`,
    /// leaving the table unchanged, when an edge would become non-manifold (the caller rebuilds).
    /// Costs one pass over the corners plus the new triangles: filling a few holes in a large mesh
    /// no longer rebuilds its table.
    pub fn append_triangles(&mut self, triangles: &[[u32; 3]]) -> bool {
        if triangles.is_empty() {
            return true;
        }
        if self.v.len() + triangles.len() > MAX_TRIANGLES
            || triangles
                .iter()
                .flatten()
                .any(|&v| v as usize >= self.vertex_count)
            || triangles
                .iter()
                .any(|t| t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
        {
            return false;
        }
        let edge = |a: u32, b: u32| (a.min(b), a.max(b));
        // The corners of every edge between vertices of the new triangles, old and new.
        let mut touched = vec![false; self.vertex_count];
        for &v in triangles.iter().flatten() {
            touched[v as usize] = true;
        }
        let mut corners: rustc_hash::FxHashMap<(u32, u32), Vec<u32>> = Default::default();
        for (t, tri) in self.v.iter().chain(triangles).enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                if touched[a as usize] && touched[b as usize] {
                    corners
                        .entry(edge(a, b))
                        .or_default()
                        .push((3 * t + k) as u32);
                }
            }
        }
        let first_new = 3 * self.v.len() as u32;
        // Every edge a new triangle has: at most two faces, and an old one only on an old border.
        for list in corners.values() {
            let new = list.iter().any(|&c| c >= first_new);
            if new && (list.len() > 2 || list.iter().any(|&c| c < first_new && !self.is_border(c)))
            {
                return false;
            }
        }
        self.v.extend_from_slice(triangles);
        self.o.resize(3 * self.v.len(), 0);
        self.same_direction
            .resize((3 * self.v.len()).div_ceil(64), 0);
        for list in corners.values() {
            if !list.iter().any(|&c| c >= first_new) {
                continue;
            }
            match *list.as_slice() {
                [c] => {
                    self.o[c as usize] = c;
                    self.edge_count += 1;
                    self.border_count += 1;
                }
                [a, b] => {
                    self.o[a as usize] = b;
                    self.o[b as usize] = a;
                    if a < first_new {
                        self.border_count -= 1; // an old border edge, closed
                    } else {
                        self.edge_count += 1;
                    }
                    if self.v(Self::n(a)) == self.v(Self::n(b)) {
                        for c in [a, b] {
                            self.same_direction[c as usize / 64] |= 1 << (c % 64);
                        }
                    }
                }
                _ => unreachable!("checked above: at most two faces"),
            }
        }
        true
    }

    /// Number of triangles.
    #[inline]
    pub fn triangle_count(&self) -> usize {
        self.v.len()
    }

    /// Number of corners (`3 x triangles`).
    #[inline]
    pub fn corner_count(&self) -> usize {
        3 * self.v.len()
    }

    /// Number of vertices the table was built over (some may be used by no triangle).
    #[inline]
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// Number of edges (distinct unordered vertex pairs of the triangles).
    pub fn edge_count(&self) -> usize {
        self.edge_count
    }

    /// Number of edges bounding exactly one triangle.
    pub fn border_edge_count(&self) -> usize {
        self.border_count
    }

    /// The corners of each non-manifold edge (three or more, sorted), one slice per edge.
    pub fn nonmanifold_edges(&self) -> impl ExactSizeIterator<Item = &[u32]> + '_ {
        self.nm_offsets
            .windows(2)
            .map(|w| &self.nm_corners[w[0] as usize..w[1] as usize])
    }

    /// The `V` array: the vertex of every corner.
    pub fn vertices(&self) -> &[u32] {
        self.v.as_flattened()
    }

    /// The `V` array, as one `[u32; 3]` per triangle.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.v
    }

    /// The `O` array, with the sentinels described in the module docs.
    pub fn opposites(&self) -> &[u32] {
        &self.o
    }

    /// Triangle of corner `c`.
    #[inline]
    pub fn t(c: u32) -> u32 {
        c / 3
    }

    /// Next corner around `t(c)`.
    #[inline]
    pub fn n(c: u32) -> u32 {
        if c % 3 == 2 {
            c - 2
        } else {
            c + 1
        }
    }

    /// Previous corner around `t(c)`.
    #[inline]
    pub fn p(c: u32) -> u32 {
        if c.is_multiple_of(3) {
            c + 2
        } else {
            c - 1
        }
    }

    /// Vertex of corner `c`.
    #[inline]
    pub fn v(&self, c: u32) -> u32 {
        self.v[c as usize / 3][c as usize % 3]
    }

    /// Raw `O[c]`: the opposite corner, `c` itself on a border, or [`NON_MANIFOLD`].
    #[inline]
    pub fn o(&self, c: u32) -> u32 {
        self.o[c as usize]
    }

    /// The opposite corner, or `None` on a border or non-manifold edge.
    #[inline]
    pub fn opposite(&self, c: u32) -> Option<u32> {
        let o = self.o[c as usize];
        (o != c && o != NON_MANIFOLD).then_some(o)
    }

    /// Whether the edge opposite `c` bounds one triangle.
    #[inline]
    pub fn is_border(&self, c: u32) -> bool {
        self.o[c as usize] == c
    }

    /// Whether the edge opposite `c` bounds three or more triangles.
    #[inline]
    pub fn is_nonmanifold(&self, c: u32) -> bool {
        self.o[c as usize] == NON_MANIFOLD
    }

    /// Left neighbour `o(n(c))`, or `None` across a non-manifold edge (on a border it is `n(c)`).
    #[inline]
    pub fn l(&self, c: u32) -> Option<u32> {
        let x = self.o(Self::n(c));
        (x != NON_MANIFOLD).then_some(x)
    }

    /// Right neighbour `o(p(c))`, or `None` across a non-manifold edge (on a border it is `p(c)`).
    #[inline]
    pub fn r(&self, c: u32) -> Option<u32> {
        let x = self.o(Self::p(c));
        (x != NON_MANIFOLD).then_some(x)
    }

    /// Swing `p(r(c))`: the next corner around `v(c)` on an oriented manifold mesh. When the edge
    /// `v(c)-v(p(c))` is a border it is `n(c)`, the next vertex along the border, so repeated swings
    /// walk around a hole. `None` across a non-manifold edge.
    ///
    /// (Texts differ on the names: with `l = o(n)` and `r = o(p)`, as here, the swing that turns
    /// around `v(c)` is `p(r(c))`; texts that call `o(p(c))` `l(c)` write it `p(l(c))`.)
    #[inline]
    pub fn s(&self, c: u32) -> Option<u32> {
        self.r(c).map(Self::p)
    }

    /// Whether the manifold edge opposite `c` is traversed in opposite directions by its two faces
    /// (`v(n(c)) == v(p(o(c)))`: the two faces agree which side is out). Border and non-manifold edges are not
    /// manifold edges and give `true`.
    #[inline]
    pub fn is_consistent(&self, c: u32) -> bool {
        self.same_direction[c as usize / 64] & (1 << (c % 64)) == 0
    }
}

fn check_size(triangles: &[[u32; 3]], vertex_count: usize) {
    assert!(
        triangles.len() <= MAX_TRIANGLES,
        "{} triangles exceed the corner table's limit of {MAX_TRIANGLES}",
        triangles.len()
    );
    assert!(
        vertex_count <= MAX_VERTICES,
        "{vertex_count} vertices exceed the corner table's limit of {MAX_VERTICES}"
    );
}

/// A triangle's lowest vertex, the place `k` of that vertex in it, and its middle vertex (the
/// lower end of the edge opposite corner `k`).
#[inline]
pub(crate) fn lowest_and_middle(t: &[u32; 3]) -> (usize, usize, usize) {
    let k = if t[0] < t[1] {
        if t[0] < t[2] {
            0
        } else {
            2
        }
    } else if t[1] < t[2] {
        1
    } else {
        2
    };
    let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
    (t[k] as usize, k, a.min(b) as usize)
}

/// A counting sort's bounds over keys `0..n`: count each key, [`Bounds::open`], take a slot per
/// key, [`Bounds::close`]; then key `x`'s items are at `bounds[x]..bounds[x + 1]`.
pub(crate) struct Bounds(Vec<u32>);

impl Bounds {
    pub(crate) fn new(n: usize) -> Bounds {
        Bounds(vec![0; n + 2])
    }

    #[inline]
    pub(crate) fn count(&mut self, key: usize) {
        self.0[key + 2] += 1;
    }

    /// After counting: `self.0[x + 1]` becomes the first slot of key `x`.
    pub(crate) fn open(&mut self) {
        for i in 2..self.0.len() {
            self.0[i] += self.0[i - 1];
        }
    }

    #[inline]
    pub(crate) fn slot(&mut self, key: usize) -> usize {
        let slot = &mut self.0[key + 1];
        *slot += 1;
        *slot as usize - 1
    }

    /// After every slot is taken, `self.0[x + 1]` is the end of key `x`, so `[..n + 1]` holds
    /// each key's start followed by the end.
    pub(crate) fn close(&self) -> &[u32] {
        &self.0[..self.0.len() - 1]
    }

    /// [`Bounds::close`], owned.
    pub(crate) fn into_bounds(mut self) -> Vec<u32> {
        self.0.pop();
        self.0
    }
}

/// Sorts a bucket: by insertion when small (a vertex's bucket usually holds about six corners),
/// else by the library sort.
fn sort_small(bucket: &mut [u64]) {
    if bucket.len() > 16 {
        bucket.sort_unstable();
        return;
    }
    if bucket.len() <= 8 {
        // Compare-exchanges without branches: how far an insertion moves a key is a coin toss the
        // processor mispredicts once a key.
        for i in 1..bucket.len() {
            for j in (0..i).rev() {
                let (a, b) = (bucket[j], bucket[j + 1]);
                bucket[j] = a.min(b);
                bucket[j + 1] = a.max(b);
            }
        }
        return;
    }
    for i in 1..bucket.len() {
        let key = bucket[i];
        let mut j = i;
        while j > 0 && bucket[j - 1] > key {
            bucket[j] = bucket[j - 1];
            j -= 1;
        }
        bucket[j] = key;
    }
}

/// The corner at the lowest vertex of each of a run of faces, grouped by the lower vertex of its
/// opposite edge (the face's middle vertex): `corners[bounds[x]..bounds[x + 1]]` for vertex `x`.
pub(crate) struct Apexes {
    corners: Vec<u32>,
    bounds: Vec<u32>,
}

impl Apexes {
    /// The apexes of `run`, faces numbered from `first`, by a counting sort.
    pub(crate) fn of(run: &[[u32; 3]], first: usize, vertex_count: usize) -> Apexes {
        let mut bounds = Bounds::new(vertex_count);
        for t in run {
            bounds.count(lowest_and_middle(t).2);
        }
        bounds.open();
        let mut corners = vec![0u32; run.len()];
        for (i, t) in run.iter().enumerate() {
            let (_, k, middle) = lowest_and_middle(t);
            corners[bounds.slot(middle)] = (3 * (first + i) + k) as u32;
        }
        Apexes {
            corners,
            bounds: bounds.into_bounds(),
        }
    }

    fn of_vertex(&self, x: usize) -> &[u32] {
        &self.corners[self.bounds[x] as usize..self.bounds[x + 1] as usize]
    }
}

/// What [`pair`] reads: faces ordered by lowest vertex, `lowest[x]..lowest[x + 1]` the faces of
/// vertex `x`, and the apexes of every run of faces.
struct Groups<'a> {
    lowest: &'a [u32],
    apexes: &'a [Apexes],
}

/// How many faces a thread pairs at once (the buckets of whole vertices).
const PART_FACES: usize = 1 << 16;

/// One range of vertices' buckets paired: what a part of [`pair`] found.
#[derive(Default)]
struct Paired {
    edge_count: usize,
    border_count: usize,
    /// Corners whose manifold edge is traversed in the same direction by both faces.
    same_direction: Vec<u32>,
    nm_corners: Vec<u32>,
    /// Ends of each non-manifold edge's corners in `nm_corners`.
    nm_ends: Vec<u32>,
    /// `O` of corners outside the part's own faces (an apex of an earlier part's face), as
    /// (corner, opposite).
    foreign: Vec<(u32, u32)>,
}

/// Pairs the corners of each vertex's bucket (the module docs) into `O`, with the counts and the
/// non-manifold edges; `v` is left empty for the caller to fill.
///
/// In parallel the vertices are cut into ranges of about [`PART_FACES`] faces; a range's faces are
/// a run of the triangles (they are ordered by lowest vertex), so each part writes the `O` of its
/// own faces in place, and hands back the few it found for corners of earlier faces.
fn pair(
    triangles: &[[u32; 3]],
    vertex_count: usize,
    groups: &Groups,
    parallel: bool,
) -> CornerTable {
    let corners = 3 * triangles.len();
    let mut o = vec![0u32; corners];
    let key = |c: u32| {
        let t = &triangles[c as usize / 3];
        let k = c as usize % 3;
        key_of(t[(k + 1) % 3], t[(k + 2) % 3], c)
    };
    // Pairs the buckets of `vertices`, whose own corners are `own` (starting at corner `base`).
    let pair_range = |vertices: std::ops::Range<usize>, own: &mut [u32], base: usize| -> Paired {
        let mut out = Paired::default();
        let mut set = |out: &mut Paired, c: u32, to: u32| match own
            .get_mut((c as usize).wrapping_sub(base))
        {
            Some(slot) => *slot = to,
            None => out.foreign.push((c, to)),
        };
        let mut bucket: Vec<u64> = Vec::new();
        for x in vertices {
            bucket.clear();
            let lowest = x as u32;
            let first = groups.lowest[x] as usize;
            let run = &triangles[first..groups.lowest[x + 1] as usize];
            for (f, t) in (first..).zip(run) {
                // With `x = t[k]` the lowest vertex: corner k + 1 faces the edge from t[k + 2]
                // down to x, corner k + 2 the edge from x up to t[k + 1].
                let k = if t[0] == lowest {
                    0
                } else if t[1] == lowest {
                    1
                } else {
                    2
                };
                let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
                let c = 3 * f as u32;
                bucket.push((u64::from(t[k2]) << 33) | u64::from(c + k1 as u32));
                bucket.push((u64::from(t[k1]) << 33) | (1 << 32) | u64::from(c + k2 as u32));
            }
            for apexes in groups.apexes {
                bucket.extend(apexes.of_vertex(x).iter().map(|&c| key(c)));
            }
            sort_small(&mut bucket);
            pair_bucket(&bucket, &mut out, &mut set);
        }
        out
    };
    let parts: Vec<Paired> = if parallel && triangles.len() > 2 * PART_FACES {
        use rayon::prelude::*;
        // Vertex ranges holding about PART_FACES faces each (a vertex's faces are never split),
        // with their own corners cut from `o`.
        let mut cuts = vec![0usize];
        let mut next = PART_FACES;
        for x in 0..vertex_count {
            if groups.lowest[x + 1] as usize >= next {
                cuts.push(x + 1);
                next = groups.lowest[x + 1] as usize + PART_FACES;
            }
        }
        if *cuts.last().expect("starts at 0") != vertex_count {
            cuts.push(vertex_count);
        }
        let mut pieces = Vec::with_capacity(cuts.len());
        let mut rest = o.as_mut_slice();
        for w in cuts.windows(2) {
            let faces = (groups.lowest[w[1]] - groups.lowest[w[0]]) as usize;
            let (own, tail) = rest.split_at_mut(3 * faces);
            pieces.push((w[0]..w[1], own, 3 * groups.lowest[w[0]] as usize));
            rest = tail;
        }
        pieces
            .into_par_iter()
            .map(|(vertices, own, base)| pair_range(vertices, own, base))
            .collect()
    } else {
        vec![pair_range(0..vertex_count, &mut o, 0)]
    };
    assemble(o, vertex_count, parts)
}

/// A bucket key: the higher vertex of the corner's opposite edge `a -> b` (as its face runs it),
/// whether that edge rises, and the corner.
#[inline]
fn key_of(a: u32, b: u32, corner: u32) -> u64 {
    (u64::from(a.max(b)) << 33) | (u64::from(a < b) << 32) | u64::from(corner)
}

/// Pairs the corners of one sorted bucket (keys of [`key_of`], one lower vertex): each run of
/// one higher vertex is an edge, paired, a border or non-manifold by its length.
fn pair_bucket(bucket: &[u64], out: &mut Paired, set: &mut impl FnMut(&mut Paired, u32, u32)) {
    let corner = |k: usize| bucket[k] as u32;
    for run in crate::weld::runs(bucket, 33) {
        let i = run.start;
        match run.len() {
            1 => {
                set(out, corner(i), corner(i));
                out.border_count += 1;
            }
            2 => {
                let (a, b) = (corner(i), corner(i + 1));
                set(out, a, b);
                set(out, b, a);
                if (bucket[i] ^ bucket[i + 1]) & (1 << 32) == 0 {
                    out.same_direction.extend([a, b]);
                }
            }
            _ => {
                let first = out.nm_corners.len();
                for k in run {
                    set(out, corner(k), NON_MANIFOLD);
                    out.nm_corners.push(corner(k));
                }
                out.nm_corners[first..].sort_unstable();
                out.nm_ends.push(out.nm_corners.len() as u32);
            }
        }
        out.edge_count += 1;
    }
}

/// The table (without `V`) from `O` and what the parts of the pairing found, in vertex order.
fn assemble(o: Vec<u32>, vertex_count: usize, parts: Vec<Paired>) -> CornerTable {
    let mut same_direction = vec![0u64; o.len().div_ceil(64)];
    let mut table = CornerTable {
        v: Vec::new(),
        o,
        same_direction: Vec::new(),
        vertex_count,
        edge_count: 0,
        border_count: 0,
        nm_corners: Vec::new(),
        nm_offsets: vec![0],
    };
    for part in parts {
        table.edge_count += part.edge_count;
        table.border_count += part.border_count;
        for c in part.same_direction {
            same_direction[c as usize / 64] |= 1 << (c % 64);
        }
        for (c, to) in part.foreign {
            table.o[c as usize] = to;
        }
        let base = table.nm_corners.len() as u32;
        table
            .nm_offsets
            .extend(part.nm_ends.iter().map(|&e| base + e));
        table.nm_corners.extend(part.nm_corners);
    }
    table.same_direction = same_direction;
    table
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Buckets of every length up to the library sort's, both paths (compare-exchanges up to
    /// eight keys, insertion above), with repeated keys, end up in the library sort's order.
    #[test]
    fn small_buckets_sort_as_the_library_sorts() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % 11
        };
        for len in 0..=20 {
            for _ in 0..200 {
                let bucket: Vec<u64> = (0..len).map(|_| next()).collect();
                let (mut ours, mut theirs) = (bucket.clone(), bucket);
                sort_small(&mut ours);
                theirs.sort_unstable();
                assert_eq!(ours, theirs);
            }
        }
    }

    /// Tetrahedron, outward: every corner has an opposite, `o(o(c)) == c`, and swinging three times
    /// around any vertex returns to the start (each vertex has 3 faces).
    #[test]
    fn tetrahedron_is_closed_and_swings_around() {
        let t = CornerTable::build(&[[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]], 4);
        assert_eq!(t.edge_count(), 6);
        assert_eq!(t.border_edge_count(), 0);
        assert_eq!(t.nonmanifold_edges().len(), 0);
        for c in 0..12 {
            let o = t.opposite(c).expect("closed mesh");
            assert_eq!(t.opposite(o), Some(c));
            assert!(t.is_consistent(c));
            assert_eq!(t.v(CornerTable::n(c)), t.v(CornerTable::p(o)));
            let mut d = c;
            for _ in 0..3 {
                d = t.s(d).unwrap();
                assert_eq!(t.v(d), t.v(c));
            }
            assert_eq!(d, c);
        }
    }

    /// Flipping in place gives the table a build of the flipped triangles gives, for every subset
    /// of flipped faces, on a mesh with manifold, border and non-manifold edges (a tetrahedron
    /// missing a face, plus two fins on its edge 0-1 and a loose triangle).
    #[test]
    fn flipping_in_place_equals_rebuilding() {
        #[rustfmt::skip]
        let triangles = [
            [0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 1, 4], [1, 0, 5], [6, 7, 8],
        ];
        for mask in 0..1u32 << triangles.len() {
            let flip: Vec<bool> = (0..triangles.len()).map(|t| mask >> t & 1 == 1).collect();
            let mut table = CornerTable::build(&triangles, 9);
            table.flip_triangles(&flip);
            let flipped: Vec<[u32; 3]> = triangles
                .iter()
                .zip(&flip)
                .map(|(&[a, b, c], &f)| if f { [a, c, b] } else { [a, b, c] })
                .collect();
            assert_eq!(table, CornerTable::build(&flipped, 9), "mask {mask:b}");
        }
    }

    /// Appending triangles gives the table a build of all of them gives: a hole in a tetrahedron
    /// filled, a fin added on a border edge, a loose pair of triangles; and an append that would
    /// make an edge non-manifold is refused, leaving the table as it was.
    #[test]
    fn appending_equals_rebuilding_or_is_refused() {
        let open = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [5, 6, 7]];
        let cases: [&[[u32; 3]]; 4] = [
            &[[2, 0, 3]],             // closes the tetrahedron (consistently)
            &[[0, 2, 3]],             // closes it with the opposite winding
            &[[0, 3, 4]],             // a fin on the border edge 0-3
            &[[4, 8, 9], [8, 4, 10]], // two new triangles sharing an edge
        ];
        for new in cases {
            let mut table = CornerTable::build(&open, 11);
            assert!(table.append_triangles(new), "{new:?}");
            let all: Vec<[u32; 3]> = open.iter().chain(new).copied().collect();
            assert_eq!(table, CornerTable::build(&all, 11), "{new:?}");
        }
        // Edge 0-1 already bounds two faces: a third would be non-manifold.
        let mut table = CornerTable::build(&open, 11);
        assert!(!table.append_triangles(&[[1, 0, 4]]));
        assert_eq!(table, CornerTable::build(&open, 11));
        // Three new faces on one new edge, and a vertex out of range.
        assert!(!table.append_triangles(&[[4, 8, 9], [8, 4, 10], [4, 8, 5]]));
        assert!(!table.append_triangles(&[[4, 8, 11]]));
        assert!(!table.append_triangles(&[[4, 8, 4]]));
        assert_eq!(table, CornerTable::build(&open, 11));
    }

    /// One triangle: three border edges, each corner its own opposite.
    #[test]
    fn single_triangle_is_all_border() {
        let t = CornerTable::build(&[[0, 1, 2]], 3);
        assert_eq!(t.edge_count(), 3);
        assert_eq!(t.border_edge_count(), 3);
        for c in 0..3 {
            assert!(t.is_border(c));
            assert_eq!(
                t.s(c),
                Some(CornerTable::n(c)),
                "a swing on a border steps along it"
            );
        }
    }

    /// Three triangles on edge 0-1: one non-manifold edge with three corners, marked, never paired.
    #[test]
    fn three_faces_on_an_edge_are_marked_nonmanifold() {
        let t = CornerTable::build(&[[0, 1, 2], [1, 0, 3], [0, 1, 4]], 5);
        // Edges: 01 (x3), 12, 20, 03, 31, 14, 40 -> 7 edges, 6 border.
        assert_eq!(t.edge_count(), 7);
        assert_eq!(t.border_edge_count(), 6);
        let nm: Vec<&[u32]> = t.nonmanifold_edges().collect();
        assert_eq!(nm, vec![&[2u32, 5, 8][..]]);
        for c in [2, 5, 8] {
            assert!(t.is_nonmanifold(c));
            assert_eq!(t.opposite(c), None);
        }
    }

    /// Two triangles over edge 0-1 with the same winding: paired, but inconsistent.
    #[test]
    fn same_direction_pair_is_inconsistent() {
        let t = CornerTable::build(&[[0, 1, 2], [0, 1, 3]], 4);
        assert_eq!(t.opposite(2), Some(5));
        assert!(!t.is_consistent(2));
        assert!(!t.is_consistent(5));
        let u = CornerTable::build(&[[0, 1, 2], [1, 0, 3]], 4);
        assert!(u.is_consistent(2));
    }

    #[test]
    fn empty_table() {
        let t = CornerTable::build(&[], 0);
        assert_eq!(t.corner_count(), 0);
        assert_eq!(t.edge_count(), 0);
    }
}
