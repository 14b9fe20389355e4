//! **Flat patches**: runs of faces in the walk's order that no pair of their own can meet in, so the
//! walk skips every pair within them without looking (the runs are the tree's nodes).
//!
//! A set `S` of faces is a flat patch along axis `k` when:
//!
//! - every face of `S` turns the same way, not zero, when coordinate `k` is dropped (exact
//!   `orient2d`);
//! - every edge of a face of `S` either has its other face outside `S` (a border edge of `S`), or
//!   is a manifold edge whose two faces, both in `S`, traverse it in opposite directions;
//! - the border edges of `S` join into closed loops, at most [`MAX_LOOPS`], each passing a vertex
//!   once, whose shadows are simple polygons apart from each other: edges that do not follow each
//!   other share no point, and edges that do follow each other do not fold back (exact `orient2d`
//!   and comparisons). The one exception is a **pinch**: a vertex that starts two border edges
//!   (two fans of `S` meet there; never three), whose whole star is flat along `k`
//!   ([`super::stars`]). Its spokes point different ways, so edges that end at it meet only there,
//!   and the two fans' shadows are wedges apart: its two incoming edges are joined to its two
//!   outgoing ones (either way; a path that comes back to a pinch closes a loop there), and the
//!   loops through it touch there without crossing;
//! - on the faces' side of every loop, the loops wind once: the loop's own turn (1 for a loop
//!   around its faces, 0 for a hole's; from its lowest point, a convex corner) plus the other
//!   loops' winding numbers around a point of it that is no pinch (so on none of them) is 1.
//!
//! Why no two faces of such a set meet. Count, for a point `q` of the plane on no projected edge,
//! the faces whose shadows hold it: each face adds the winding number of its shadow's outline
//! around `q`, which is 1 (every outline turns the same way; signs taken that way), and the
//! outlines add up to the loops', because every edge inside `S` is walked once each way and
//! cancels. The loops' winding number is constant between them, and every region between them
//! borders a loop, on its faces' side (where it is 1, checked) or on the other (one less). So no
//! point is under two shadows: the shadows have disjoint insides. Nor do they touch anywhere but
//! along what their faces share: where two shadows touch at a point that is not the shadow of a
//! vertex or edge the faces share, the faces around that point either cover some nearby point
//! twice (impossible, as just shown) or leave gaps whose sides are border edges of `S` passing
//! through that point from different places of the loops, which simple loops apart do not do but
//! at a pinch, where every face around is on the pinch itself. So two faces have a common point
//! only over the shadow of a vertex or an edge they share; the projection is one to one on each
//! face, so the common point is that vertex or edge.
//!
//! Loops that touch at pinches without crossing still split the plane as loops apart do: along a
//! loop, every other loop is wholly on one side of it, so the winding on the loop's faces' side
//! is the same all along, and one point of it tells. Pinches are where runs of the walk's order
//! meet themselves across a corner; taking them lets whole halves of a smooth mesh be one patch.

use std::cmp::Ordering;

use crate::corner_table::{CornerTable, NON_MANIFOLD};

use super::meet::{o2, strictly_opposite, Axes, Point, AXES};
use crate::pages::prefetch;

/// Bits of a face's turn: bit `2k`, counter-clockwise when coordinate `k` is dropped; bit
/// `2k + 1`, clockwise. A set can be a flat patch along `k` only when all its faces share one of
/// those bits.
pub(super) fn turn_bits(turn: [f64; 3]) -> u8 {
    // Without branches (as `stars::corner_parts`).
    (0..3).fold(0, |m, k| {
        m | (u8::from(turn[k] > 0.0) | u8::from(turn[k] < 0.0) << 1) << (2 * k)
    })
}

/// What the test reads of the mesh, and its scratch space (one per task of the walk).
pub(super) struct Patches<'a> {
    pub(super) points: &'a [Point],
    pub(super) table: &'a CornerTable,
    /// The walk's place of every table face (`u32::MAX`: not in the walk).
    pub(super) place: &'a [u32],
    /// Per vertex, bit `k`: its star is flat dropping coordinate `k`
    /// ([`super::stars::Stars::along`]).
    pub(super) along: &'a [u8],
    /// Border edges `(from, to)`.
    edges: Vec<(u32, u32)>,
    /// The edges that start at each vertex ([`slot_of`]): the vertex, its first edge and its
    /// second ([`EMPTY`] for none; a second one makes the vertex a pinch).
    starts: Vec<[u32; 3]>,
    /// The vertices that start two border edges, ascending, and where each is on `path`
    /// (`u32::MAX`: not on it).
    pinches: Vec<u32>,
    pinch_at: Vec<u32>,
    /// The open path of the loop being followed: its points' vertices.
    path: Vec<u32>,
    /// The loops' points, loop after loop, each point's vertex and the next point of its loop.
    shadow: Vec<[f64; 2]>,
    ids: Vec<u32>,
    next: Vec<u32>,
    /// Where each loop starts in `shadow`.
    loops: Vec<u32>,
    /// The most loops a flat patch may have here ([`MAX_LOOPS`] unless set).
    max_loops: usize,
    used: Vec<bool>,
    /// The sweep's edges by their lowest coordinate, and those in view.
    spans: Vec<Span>,
    active: Vec<Span>,
}

/// An edge of the loops in a sweep ([`Patches::sweep`]): its span along the sweep's axis, its span
/// across it, and its first point.
#[derive(Clone, Copy)]
struct Span {
    low: f64,
    high: f64,
    across: [f64; 2],
    edge: u32,
}

impl<'a> Patches<'a> {
    pub(super) fn new(
        points: &'a [Point],
        table: &'a CornerTable,
        place: &'a [u32],
        along: &'a [u8],
    ) -> Self {
        Patches {
            points,
            table,
            place,
            along,
            edges: Vec::new(),
            starts: Vec::new(),
            pinches: Vec::new(),
            pinch_at: Vec::new(),
            path: Vec::new(),
            shadow: Vec::new(),
            ids: Vec::new(),
            next: Vec::new(),
            loops: Vec::new(),
            max_loops: MAX_LOOPS,
            used: Vec::new(),
            spans: Vec::new(),
            active: Vec::new(),
        }
    }

    /// The same, allowing flat patches of up to `loops` loops (the test's last step costs the
    /// loops times their points).
    pub(super) fn with_max_loops(mut self, loops: usize) -> Self {
        self.max_loops = loops;
        self
    }

    /// A copy with its own scratch space, for a parallel task.
    pub(super) fn fork(&self) -> Self {
        Patches::new(self.points, self.table, self.place, self.along).with_max_loops(self.max_loops)
    }

    /// Whether the faces at places `places` (table faces `face(p)`), whose turn bits all share
    /// `bits`, are a flat patch (module docs).
    pub(super) fn is_flat(
        &mut self,
        places: std::ops::Range<usize>,
        bits: u8,
        face: impl Fn(usize) -> u32,
    ) -> bool {
        if bits == 0 {
            return false;
        }
        let k = bits.trailing_zeros() as usize / 2;
        let (lo, hi) = (places.start as u32, places.end as u32);
        let table = self.table;
        self.edges.clear();
        // The faces' rows are scattered in the table: fetch ahead the rows of a face 16 places on
        // and the places of the neighbours of a face 8 on (whose rows came 8 faces ago).
        let (triangles, opposites) = (table.triangles(), table.opposites());
        for p in places {
            if p + 16 < hi as usize {
                let u = face(p + 16) as usize;
                prefetch(&triangles[u]);
                prefetch(&opposites[3 * u]);
            }
            if p + 8 < hi as usize {
                let u = face(p + 8) as usize;
                for &o in &opposites[3 * u..3 * u + 3] {
                    if let Some(q) = self.place.get(CornerTable::t(o) as usize) {
                        prefetch(q);
                    }
                }
            }
            let t = face(p);
            let tri = triangles[t as usize];
            for j in 0..3 {
                let c = 3 * t + j as u32;
                let o = table.o(c);
                if o == NON_MANIFOLD {
                    return false;
                }
                if o != c {
                    let q = self.place[CornerTable::t(o) as usize];
                    if (lo..hi).contains(&q) {
                        if table.is_consistent(c) {
                            continue;
                        }
                        return false;
                    }
                }
                self.edges.push((tri[(j + 1) % 3], tri[(j + 2) % 3]));
            }
        }
        if self.edges.len() < 3 {
            return false;
        }
        // The edges by their first vertex, in a table open-addressed by it. Pinches: a vertex may
        // start two border edges (two fans of the patch meet there) when its whole star is flat
        // along this axis, so that the fans' shadows are wedges apart; never three.
        let size = (2 * self.edges.len()).next_power_of_two();
        self.starts.clear();
        self.starts.resize(size, [EMPTY; 3]);
        self.pinches.clear();
        for (i, &(v, _)) in self.edges.iter().enumerate() {
            let slot = slot_of(&mut self.starts, v);
            if slot[0] == EMPTY {
                *slot = [v, i as u32, EMPTY];
            } else if slot[2] == EMPTY && self.along[v as usize] & (1 << k) != 0 {
                slot[2] = i as u32;
                self.pinches.push(v);
            } else {
                return false;
            }
        }
        self.pinches.sort_unstable();
        self.follow_loops(AXES[k]) && self.simple() && self.wound_once(bits & (1 << (2 * k)) != 0)
    }

    /// Joins the border edges into loops that pass each vertex once: each edge is followed by an
    /// unused edge starting where it ends, and a path that comes back to a pinch it passed
    /// already closes there as a loop of its own. At a pinch (two fans, whose wedges are apart)
    /// either way of joining its two incoming edges to its two outgoing ones gives loops that
    /// touch there without crossing. False when the edges do not close into at most
    /// [`MAX_LOOPS`] loops.
    fn follow_loops(&mut self, axes: Axes) -> bool {
        self.shadow.clear();
        self.ids.clear();
        self.next.clear();
        self.loops.clear();
        self.used.clear();
        self.used.resize(self.edges.len(), false);
        self.pinch_at.clear();
        self.pinch_at.resize(self.pinches.len(), u32::MAX);
        for first in 0..self.edges.len() {
            if self.used[first] {
                continue;
            }
            let start = self.edges[first].0;
            self.path.clear();
            let mut at = first;
            loop {
                self.used[at] = true;
                let (from, to) = self.edges[at];
                if let Ok(p) = self.pinches.binary_search(&from) {
                    let on_path = self.pinch_at[p];
                    if on_path != u32::MAX && !self.close(on_path as usize, axes) {
                        return false;
                    }
                    self.pinch_at[p] = self.path.len() as u32;
                }
                self.path.push(from);
                // Its point is read when the loop closes: fetched now, the load has the rest
                // of the loop's walk to land (it missed the cache on nearly every point).
                prefetch(&self.points[from as usize]);
                if to == start {
                    break;
                }
                let [_, a, b] = *slot_of(&mut self.starts, to);
                match [a, b]
                    .into_iter()
                    .find(|&i| i != EMPTY && !self.used[i as usize])
                {
                    Some(i) => at = i as usize,
                    None => return false,
                }
            }
            if !self.close(0, axes) {
                return false;
            }
        }
        true
    }

    /// Ends the path's points from `from` on as a loop; false past [`MAX_LOOPS`] loops, or for a
    /// loop of fewer than three points (which no border of faces on manifold edges makes).
    fn close(&mut self, from: usize, axes: Axes) -> bool {
        if self.loops.len() == self.max_loops || self.path.len() - from < 3 {
            return false;
        }
        let begin = self.shadow.len() as u32;
        self.loops.push(begin);
        for &v in &self.path[from..] {
            self.shadow.push(axes.of(self.points[v as usize]));
            self.ids.push(v);
            self.next.push(self.shadow.len() as u32);
        }
        *self.next.last_mut().expect("a point") = begin;
        for v in self.path.drain(from..) {
            if let Ok(p) = self.pinches.binary_search(&v) {
                self.pinch_at[p] = u32::MAX;
            }
        }
        true
    }

    /// Whether the closed polygons `shadow` (point `i` is followed by `next[i]`) are simple and
    /// apart: a sweep over their edges' spans along one axis of the shadow, the edges whose boxes
    /// overlap tested exactly. A sweep that would compare more than [`SWEEP_WORK`] pairs of
    /// edges a point gives up and the other axis is swept; when both give up the polygons are
    /// not proven simple (the walk then pairs the faces as usual). Edges of one span along an
    /// axis (a strip of walls seen from the side has all its lower edges at one height) would
    /// otherwise make that sweep compare every pair of them.
    fn simple(&mut self) -> bool {
        let (s, next) = (&self.shadow, &self.next);
        // Edges that follow each other share their common point only: not collinear going back.
        for i in 0..s.len() {
            let j = next[i] as usize;
            let (u, v, w) = (s[i], s[j], s[next[j] as usize]);
            if o2(u, v, w) == 0.0 && same_way(v, u, w) {
                return false;
            }
        }
        (0..2).any(|axis| self.sweep(axis) == Some(true))
    }

    /// [`Patches::simple`] by a sweep along shadow axis `axis`: `Some(false)` when two edges
    /// meet, `None` when it gives up.
    fn sweep(&mut self, axis: usize) -> Option<bool> {
        let (s, ids, next) = (&self.shadow, &self.ids, &self.next);
        let n = s.len();
        let other = 1 - axis;
        let edge = |i: usize| (s[i], s[next[i] as usize]);
        // The edges' spans side by side, so that the sweep's tests of the edges in view read no
        // points until two boxes overlap (with the points read through `next` at every test,
        // this sweep was half of the flat-patch proofs' time on the Stanford dragon).
        self.spans.clear();
        self.spans.extend((0..n).map(|i| {
            let (p, q) = edge(i);
            Span {
                low: p[axis].min(q[axis]),
                high: p[axis].max(q[axis]),
                across: [p[other].min(q[other]), p[other].max(q[other])],
                edge: i as u32,
            }
        }));
        self.spans.sort_unstable_by(|a, b| a.low.total_cmp(&b.low));
        self.active.clear();
        let mut work = SWEEP_WORK.saturating_mul(n);
        for e in &self.spans {
            self.active.retain(|a| a.high >= e.low);
            work = work.checked_sub(self.active.len())?;
            let i = e.edge as usize;
            for a in &self.active {
                if e.across[1] < a.across[0] || a.across[1] < e.across[0] {
                    continue;
                }
                let j = a.edge as usize;
                if next[i] as usize == j || next[j] as usize == i {
                    continue;
                }
                // Two spokes of one pinch: apart but for it (its star is flat, so its spokes
                // point different ways).
                if let Some(v) = shared_end(ids, i, j, next) {
                    if self.pinches.binary_search(&v).is_ok() {
                        continue;
                    }
                }
                let ((p, q), (c, d)) = (edge(i), edge(j));
                if segments_meet(p, q, c, d) {
                    return Some(false);
                }
            }
            self.active.push(*e);
        }
        Some(true)
    }

    /// For simple polygons that are apart, whether no point is inside more of them (each counted
    /// with its winding) than one: the faces' side of every loop is wound once. With `counter`,
    /// the faces turn counter-clockwise and lie left of the loops; else right.
    fn wound_once(&self, counter: bool) -> bool {
        let (s, next) = (&self.shadow, &self.next);
        let end = |l: usize| self.loops.get(l + 1).map_or(s.len(), |&b| b as usize);
        let way = if counter { 1 } else { -1 };
        (0..self.loops.len()).all(|l| {
            let points = self.loops[l] as usize..end(l);
            // The loop's own way round, from its lowest point (a convex corner). Compared by value,
            // so that -0 and 0 are one x; the shadow's points are finite (their faces turn).
            let low = points
                .clone()
                .min_by(|&a, &b| s[a].partial_cmp(&s[b]).unwrap_or(Ordering::Equal))
                .expect("a point");
            let before = points
                .clone()
                .find(|&i| next[i] as usize == low)
                .expect("a loop");
            let turn = o2(s[before], s[low], s[next[low] as usize]);
            let own = i32::from(turn.signum() as i32 == way);
            // The other loops' winding is taken at a point of this loop that is on none of them:
            // any but a pinch, which loops touching there share. Near it, on the faces' side,
            // they wind as much.
            let Some(at) = points
                .clone()
                .find(|&i| self.pinches.binary_search(&self.ids[i]).is_err())
            else {
                return false;
            };
            let p = s[at];
            let others: i32 = (0..self.loops.len())
                .filter(|&m| m != l)
                .map(|m| winding(s, next, self.loops[m] as usize..end(m), p))
                .sum();
            own + way * others == 1
        })
    }
}

/// A free place in [`Patches::starts`].
const EMPTY: u32 = u32::MAX;

/// The slot of vertex `v` in `starts` (a power of two long, less than half full): its own, or the
/// free one it would take. Probing from a multiplicative hash instead of a sort and binary searches
/// over the edges (a patch of a few hundred faces has about sixty).
fn slot_of(starts: &mut [[u32; 3]], v: u32) -> &mut [u32; 3] {
    let mask = starts.len() - 1;
    let mut i = (v.wrapping_mul(0x9e37_79b9) >> 7) as usize & mask;
    while starts[i][0] != EMPTY && starts[i][0] != v {
        i = (i + 1) & mask;
    }
    &mut starts[i]
}

/// The most loops a flat patch may have (in the walk's tree nodes, whose tries mostly fail).
const MAX_LOOPS: usize = 8;

/// The most edges a sweep over a patch's loops keeps in view, summed over its steps, per point of
/// the loops ([`Patches::simple`]); the loops of real patches keep a handful.
const SWEEP_WORK: usize = 32;

/// The winding number of the closed polygon `points` (point `i` followed by `next[i]`) around
/// `p`, which is on none of its edges (exact: the crossings of the ray from `p` along +x).
fn winding(s: &[[f64; 2]], next: &[u32], points: std::ops::Range<usize>, p: [f64; 2]) -> i32 {
    points
        .map(|i| {
            let (a, b) = (s[i], s[next[i] as usize]);
            if a[1] <= p[1] && p[1] < b[1] && o2(a, b, p) > 0.0 {
                1
            } else if b[1] <= p[1] && p[1] < a[1] && o2(a, b, p) < 0.0 {
                -1
            } else {
                0
            }
        })
        .sum()
}

/// The vertex that edges `i` and `j` (point `i` to point `next[i]`) both end at, if any.
fn shared_end(ids: &[u32], i: usize, j: usize, next: &[u32]) -> Option<u32> {
    let (a, b) = (ids[i], ids[next[i] as usize]);
    let (c, d) = (ids[j], ids[next[j] as usize]);
    [a, b].into_iter().find(|&v| v == c || v == d)
}

/// Whether `a` and `b`, on one line through `v` (neither at `v`), lie on the same side of it.
fn same_way(v: [f64; 2], a: [f64; 2], b: [f64; 2]) -> bool {
    (0..2).all(|c| a[c].partial_cmp(&v[c]) == b[c].partial_cmp(&v[c]))
}

/// Whether the closed segments `p q` and `a b` share a point (exact).
fn segments_meet(p: [f64; 2], q: [f64; 2], a: [f64; 2], b: [f64; 2]) -> bool {
    let (d1, d2) = (o2(a, b, p), o2(a, b, q));
    let (d3, d4) = (o2(p, q, a), o2(p, q, b));
    if strictly_opposite(d1, d2) && strictly_opposite(d3, d4) {
        return true;
    }
    let within = |s: [f64; 2], t: [f64; 2], x: [f64; 2]| {
        (0..2).all(|c| s[c].min(t[c]) <= x[c] && x[c] <= s[c].max(t[c]))
    };
    (d1 == 0.0 && within(a, b, p))
        || (d2 == 0.0 && within(a, b, q))
        || (d3 == 0.0 && within(p, q, a))
        || (d4 == 0.0 && within(p, q, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::intersect::meet::{faces_meet, turns};
    use crate::topology::intersect::stars::flat_stars;

    /// Whether all of `triangles` (in this order, all in the walk) are a flat patch, with the turn
    /// bits they share.
    fn flat(points: &[Point], triangles: &[[u32; 3]]) -> bool {
        let table = CornerTable::build(triangles, points.len());
        let bits = triangles.iter().fold(u8::MAX, |m, t| {
            m & turn_bits(turns(
                points[t[0] as usize],
                points[t[1] as usize],
                points[t[2] as usize],
            ))
        });
        let place: Vec<u32> = (0..triangles.len() as u32).collect();
        let along = flat_stars(points, &table).along;
        Patches::new(points, &table, &place, &along).is_flat(0..triangles.len(), bits, |p| p as u32)
    }

    /// An `n` by `n` grid of squares, two faces each, counter-clockwise seen from +z, at heights
    /// `z(i, j)`; the squares `skip` says are left out.
    fn grid(
        n: u32,
        z: impl Fn(u32, u32) -> f64,
        skip: impl Fn(u32, u32) -> bool,
    ) -> (Vec<Point>, Vec<[u32; 3]>) {
        let points = (0..=n)
            .flat_map(|j| (0..=n).map(move |i| (i, j)))
            .map(|(i, j)| [f64::from(i), f64::from(j), z(i, j)])
            .collect();
        let at = |i: u32, j: u32| j * (n + 1) + i;
        let mut triangles = Vec::new();
        for j in 0..n {
            for i in 0..n {
                if !skip(i, j) {
                    triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
        (points, triangles)
    }

    #[test]
    fn a_height_field_is_flat_and_so_is_one_with_a_hole() {
        let bumpy = |i: u32, j: u32| f64::from((i * 7 + j * 3) % 5);
        let (points, triangles) = grid(6, bumpy, |_, _| false);
        assert!(flat(&points, &triangles));
        // Turned over (every face clockwise): still flat.
        let turned: Vec<[u32; 3]> = triangles.iter().map(|&[a, b, c]| [a, c, b]).collect();
        assert!(flat(&points, &turned));
        // A square hole in the middle: two loops, the inner one wound the other way.
        let (points, triangles) = grid(6, bumpy, |i, j| (2..4).contains(&i) && (2..4).contains(&j));
        assert!(flat(&points, &triangles));
        // Two pieces apart: two outer loops side by side.
        let (points, triangles) = grid(6, bumpy, |i, _| i == 3);
        assert!(flat(&points, &triangles));
    }

    /// A strip one square wide and 3,000 long (a row of walls seen from the side): its loop's
    /// 3,000 edges on each long side share one span along x, so a sweep along x would keep all
    /// of them in view at once (4.5 million comparisons); that sweep gives up at its work bound,
    /// and the sweep along y proves the strip flat.
    #[test]
    fn a_long_strip_is_swept_along_its_length() {
        let long = 3_000;
        let points: Vec<Point> = (0..=long)
            .flat_map(|j| [[0.0, f64::from(j), 0.0], [1.0, f64::from(j), 0.0]])
            .collect();
        let triangles: Vec<[u32; 3]> = (0..long)
            .flat_map(|j| {
                let (a, b, c, d) = (2 * j, 2 * j + 1, 2 * j + 3, 2 * j + 2);
                [[a, b, c], [a, c, d]]
            })
            .collect();
        let table = CornerTable::build(&triangles, points.len());
        let place: Vec<u32> = (0..triangles.len() as u32).collect();
        let along = flat_stars(&points, &table).along;
        let mut patches = Patches::new(&points, &table, &place, &along);
        let bits = turn_bits(turns(points[0], points[1], points[3]));
        assert!(patches.is_flat(0..triangles.len(), bits, |p| p as u32));
        assert_eq!(patches.shadow.len(), 2 * long as usize + 2);
        assert_eq!(patches.sweep(0), None);
        assert_eq!(patches.sweep(1), Some(true));
    }

    /// A small grid above a big one, inside its shadow: both loops are apart and simple, but the
    /// points under the small one are inside two loops wound the same way.
    #[test]
    fn a_patch_over_another_is_not_flat() {
        let (mut points, mut triangles) = grid(6, |_, _| 0.0, |_, _| false);
        let (top, top_triangles) = grid(2, |_, _| 1.0, |_, _| false);
        let base = points.len() as u32;
        points.extend(top.iter().map(|p| [p[0] + 2.0, p[1] + 2.0, p[2]]));
        triangles.extend(top_triangles.iter().map(|t| t.map(|v| v + base)));
        assert!(!flat(&points, &triangles));
    }

    /// A strip wound one and a half times around the z axis, rising: every face turns the same
    /// way seen from +z and every inner vertex is flat, but the strip's shadow lies over itself.
    #[test]
    fn a_ramp_around_twice_is_not_flat() {
        let steps = 36;
        let mut points = Vec::new();
        for s in 0..=steps {
            let a = f64::from(s) * 15f64.to_radians();
            let z = f64::from(s) * 0.1;
            points.push([a.cos() * 2.0, a.sin() * 2.0, z]);
            points.push([a.cos() * 3.0, a.sin() * 3.0, z]);
        }
        let triangles: Vec<[u32; 3]> = (0..steps)
            .flat_map(|s| {
                let (i, o, i2, o2) = (2 * s, 2 * s + 1, 2 * s + 2, 2 * s + 3);
                [[i, o, o2], [i, o2, i2]]
            })
            .collect();
        assert!(!flat(&points, &triangles));
        // One turn less a step is flat.
        assert!(flat(&points, &triangles[..2 * 23]));
    }

    /// Random bumpy grids with their points pushed sideways (so that faces fold over each other,
    /// turn back or touch) and random runs of their faces: no run called flat has two faces that
    /// meet (by the narrow phase, pair by pair).
    #[test]
    fn no_two_faces_of_a_flat_run_meet() {
        let mut bits = crate::geometry::xorshift(0x2545_f491_4f6c_dd1d);
        let mut next = move |n: u64| bits() % n;
        let (mut flat_runs, mut tried) = (0, 0);
        for _ in 0..3000 {
            let n = 4;
            let (mut points, triangles) = grid(n, |_, _| 0.0, |_, _| false);
            let push = 1 + next(3);
            for p in &mut points {
                p[0] = p[0] * 4.0 + (next(2 * push + 1) as f64 - push as f64);
                p[1] = p[1] * 4.0 + (next(2 * push + 1) as f64 - push as f64);
                p[2] = next(3) as f64;
            }
            let lo = next(triangles.len() as u64 - 2) as usize;
            let hi = lo + 2 + next((triangles.len() - lo - 1) as u64) as usize;
            let run = &triangles[lo..hi.min(triangles.len())];
            let table = CornerTable::build(&triangles, points.len());
            let at = |t: [u32; 3]| t.map(|v| points[v as usize]);
            let bits = run.iter().fold(u8::MAX, |m, &t| {
                let [a, b, c] = at(t);
                m & turn_bits(turns(a, b, c))
            });
            if bits == 0 {
                continue;
            }
            tried += 1;
            let place: Vec<u32> = (0..triangles.len() as u32).collect();
            let along = flat_stars(&points, &table).along;
            let mut patches = Patches::new(&points, &table, &place, &along);
            if !patches.is_flat(lo..lo + run.len(), bits, |p| p as u32) {
                continue;
            }
            flat_runs += 1;
            for (i, &f) in run.iter().enumerate() {
                for &g in &run[i + 1..] {
                    assert!(!faces_meet(f, at(f), g, at(g)), "{f:?} {g:?} in {run:?}");
                }
            }
        }
        assert!(
            flat_runs > 300 && tried - flat_runs > 300,
            "{flat_runs} of {tried}"
        );
    }

    /// Whether the faces `part` of `triangles` (all of them in the table, so that stars inside
    /// are closed) are a flat patch, and whether some vertex starts two of its border edges.
    fn part_flat(points: &[Point], triangles: &[[u32; 3]], part: &[u32]) -> (bool, bool) {
        let table = CornerTable::build(triangles, points.len());
        let mut order: Vec<u32> = part.to_vec();
        order.extend((0..triangles.len() as u32).filter(|t| !part.contains(t)));
        let mut place = vec![0; triangles.len()];
        for (p, &t) in order.iter().enumerate() {
            place[t as usize] = p as u32;
        }
        let bits = part.iter().fold(u8::MAX, |m, &t| {
            let [a, b, c] = triangles[t as usize].map(|v| points[v as usize]);
            m & turn_bits(turns(a, b, c))
        });
        let along = flat_stars(points, &table).along;
        let mut patches = Patches::new(points, &table, &place, &along);
        let flat = patches.is_flat(0..part.len(), bits, |p| order[p]);
        let mut starts: Vec<u32> = patches.edges.iter().map(|e| e.0).collect();
        starts.sort_unstable();
        (flat, starts.windows(2).any(|w| w[0] == w[1]))
    }

    /// The faces of the squares `(i, j)` of a [`grid`] of `n` that `keep` says.
    fn squares(n: u32, keep: impl Fn(u32, u32) -> bool) -> Vec<u32> {
        (0..n * n)
            .filter(|s| keep(s % n, s / n))
            .flat_map(|s| [2 * s, 2 * s + 1])
            .collect()
    }

    /// The faces of two 2 x 2 blocks of squares of a [`grid`] of 6 that meet at vertex (3, 3).
    fn two_blocks() -> Vec<u32> {
        let block =
            |i: u32, j: u32, lo: u32| (lo..lo + 2).contains(&i) && (lo..lo + 2).contains(&j);
        squares(6, |i, j| block(i, j, 1) || block(i, j, 3))
    }

    /// Two blocks of squares meeting at one corner (a pinch: the vertex starts two border edges),
    /// and a ring of squares around a hole whose ends meet at one of the hole's corners: both are
    /// flat, turned over too. They were turned down before pinches were taken.
    #[test]
    fn patches_pinched_at_a_vertex_are_flat() {
        let bumpy = |i: u32, j: u32| f64::from((i * 7 + j * 3) % 5);
        let (points, triangles) = grid(6, bumpy, |_, _| false);
        let turned: Vec<[u32; 3]> = triangles.iter().map(|&[a, b, c]| [a, c, b]).collect();
        let corners = two_blocks();
        let ring = squares(6, |i, j| {
            let around = (1..4).contains(&i) && (1..4).contains(&j) && (i, j) != (2, 2);
            around && (i, j) != (1, 3)
        });
        for part in [&corners, &ring] {
            assert_eq!(part_flat(&points, &triangles, part), (true, true));
            assert_eq!(part_flat(&points, &turned, part), (true, true));
        }
    }

    /// A pinch whose star is open (here a face beside it, outside the patch, is cut loose) is
    /// turned down: that the fans' wedges are apart rests on the star being flat.
    #[test]
    fn a_pinch_needs_a_flat_star() {
        let (mut points, mut triangles) = grid(6, |_, _| 0.0, |_, _| false);
        let corners = two_blocks();
        assert_eq!(part_flat(&points, &triangles, &corners), (true, true));
        // Face 1 of square (3, 2) is (3, 2), (4, 3), (3, 3): its corner on the pinch (3, 3)
        // becomes a vertex of its own.
        let pinch = 3 * 7 + 3;
        let face = &mut triangles[2 * (2 * 6 + 3) + 1];
        assert_eq!(face[2], pinch);
        face[2] = points.len() as u32;
        points.push(points[pinch as usize]);
        assert_eq!(part_flat(&points, &triangles, &corners), (false, true));
    }

    /// Three faces around one vertex with a face between each two: three fans meet there, so the
    /// vertex starts three border edges, which no flat patch has (even on a flat star).
    #[test]
    fn three_fans_at_a_vertex_are_not_a_flat_patch() {
        let (points, triangles) = grid(6, |_, _| 0.0, |_, _| false);
        // Around vertex (3, 3), in turn: 28, 31, 42, 43, 40, 29; every other one of them.
        let vertex = 3 * 7 + 3;
        let part = [28, 42, 40];
        assert!(part
            .iter()
            .all(|&t| triangles[t as usize].contains(&vertex)));
        assert_eq!(part_flat(&points, &triangles, &part), (false, true));
        // Two of them are a pinch on a flat star: flat.
        assert_eq!(part_flat(&points, &triangles, &part[..2]), (true, true));
    }

    /// Random bumpy grids with their points pushed sideways, and random sets of their faces (so
    /// that many of them are pinched): no set called flat has two faces that meet.
    #[test]
    fn no_two_faces_of_a_flat_set_meet() {
        let mut bits = crate::geometry::xorshift(0x9e37_79b9_7f4a_7c15);
        let mut next = move |n: u64| bits() % n;
        let (mut flat_sets, mut pinched, mut tried) = (0, 0, 0);
        for _ in 0..4000 {
            let n = 5;
            let (mut points, triangles) = grid(n, |_, _| 0.0, |_, _| false);
            let push = next(3);
            for p in &mut points {
                p[0] = p[0] * 4.0 + (next(2 * push + 1) as f64 - push as f64);
                p[1] = p[1] * 4.0 + (next(2 * push + 1) as f64 - push as f64);
                p[2] = next(3) as f64;
            }
            let keep = 3 + next(6);
            let part: Vec<u32> = (0..triangles.len() as u32)
                .filter(|_| next(10) < keep)
                .collect();
            if part.len() < 2 {
                continue;
            }
            tried += 1;
            let (flat, pinch) = part_flat(&points, &triangles, &part);
            if !flat {
                continue;
            }
            flat_sets += 1;
            pinched += usize::from(pinch);
            let at = |t: u32| triangles[t as usize].map(|v| points[v as usize]);
            for (i, &f) in part.iter().enumerate() {
                for &g in &part[i + 1..] {
                    let (tf, tg) = (triangles[f as usize], triangles[g as usize]);
                    assert!(
                        !faces_meet(tf, at(f), tg, at(g)),
                        "{tf:?} {tg:?} in {part:?}"
                    );
                }
            }
        }
        assert!(
            pinched > 200 && tried - flat_sets > 300,
            "{flat_sets} flat ({pinched} pinched) of {tried}"
        );
    }
}
