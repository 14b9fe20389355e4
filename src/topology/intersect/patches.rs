//! **Flat patches**: runs of faces in the walk's order that no pair of their own can meet in, so the
//! walk skips every pair within them without looking (the runs are the tree's nodes).
//!
//! A set `S` of faces is a flat patch along axis `k` when:
//!
//! - every face of `S` turns the same way, not zero, when coordinate `k` is dropped (exact
//!   `orient2d`);
//! - every edge of a face of `S` either has its other face outside `S` (a border edge of `S`), or
//!   is a manifold edge whose two faces, both in `S`, traverse it in opposite directions;
//! - the border edges of `S` join into closed loops (each vertex starts at most one of them), at
//!   most [`MAX_LOOPS`], whose shadows are simple polygons apart from each other: edges that do
//!   not follow each other share no point, and edges that do follow each other do not fold back
//!   (exact `orient2d` and comparisons);
//! - on the faces' side of every loop, the loops wind once: the loop's own turn (1 for a loop
//!   around its faces, 0 for a hole's) plus the other loops' winding numbers around its lowest
//!   point is 1.
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
//! through that point from different places of the loops, which simple loops apart do not do. So
//! two faces have a common point only over the shadow of a vertex or an edge they share; the
//! projection is one to one on each face, so the common point is that vertex or edge.
//!
//! Not yet taken: a run whose border passes a vertex twice (two fans of the run meeting there), the
//! most common reason a run of a smooth mesh is turned down.

use std::cmp::Ordering;

use crate::corner_table::{CornerTable, NON_MANIFOLD};

use super::meet::{o2, strictly_opposite, Point, AXES};

/// Bits of a face's turn: bit `2k`, counter-clockwise when coordinate `k` is dropped; bit
/// `2k + 1`, clockwise. A set can be a flat patch along `k` only when all its faces share one of
/// those bits.
pub(super) fn turn_bits(turn: [f64; 3]) -> u8 {
    (0..3).fold(0, |m, k| {
        m | if turn[k] > 0.0 {
            1 << (2 * k)
        } else if turn[k] < 0.0 {
            2 << (2 * k)
        } else {
            0
        }
    })
}

/// What the test reads of the mesh, and its scratch space (one per task of the walk).
pub(super) struct Patches<'a> {
    pub(super) points: &'a [Point],
    pub(super) table: &'a CornerTable,
    /// The walk's place of every table face (`u32::MAX`: not in the walk).
    pub(super) place: &'a [u32],
    /// Border edges `(from, to)`, then the loop's points.
    edges: Vec<(u32, u32)>,
    shadow: Vec<[f64; 2]>,
    /// Per point of `shadow`, the next point of its loop.
    next: Vec<u32>,
    /// Where each loop starts in `shadow`.
    loops: Vec<u32>,
    used: Vec<bool>,
    by_low_x: Vec<u32>,
    active: Vec<u32>,
}

impl<'a> Patches<'a> {
    pub(super) fn new(points: &'a [Point], table: &'a CornerTable, place: &'a [u32]) -> Self {
        Patches {
            points,
            table,
            place,
            edges: Vec::new(),
            shadow: Vec::new(),
            next: Vec::new(),
            loops: Vec::new(),
            used: Vec::new(),
            by_low_x: Vec::new(),
            active: Vec::new(),
        }
    }

    /// A copy with its own scratch space, for a parallel task.
    pub(super) fn fork(&self) -> Self {
        Patches::new(self.points, self.table, self.place)
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
        for p in places {
            let t = face(p);
            let tri = table.triangles()[t as usize];
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
        self.edges.sort_unstable();
        if self.edges.len() < 3 || self.edges.windows(2).any(|w| w[0].0 == w[1].0) {
            return false;
        }
        // The loops: each border edge is followed by the one starting where it ends.
        let axes = AXES[k];
        self.shadow.clear();
        self.next.clear();
        self.loops.clear();
        self.used.clear();
        self.used.resize(self.edges.len(), false);
        for first in 0..self.edges.len() {
            if self.used[first] {
                continue;
            }
            if self.loops.len() == MAX_LOOPS {
                return false;
            }
            let begin = self.shadow.len();
            let mut at = first;
            loop {
                self.used[at] = true;
                let (from, to) = self.edges[at];
                self.shadow.push(axes.of(self.points[from as usize]));
                self.next.push(self.shadow.len() as u32);
                match self.edges.binary_search_by_key(&to, |e| e.0) {
                    Ok(i) if i == first => break,
                    Ok(i) if !self.used[i] => at = i,
                    _ => return false,
                }
            }
            *self.next.last_mut().expect("a point") = begin as u32;
            self.loops.push(begin as u32);
        }
        self.simple() && self.wound_once(bits & (1 << (2 * k)) != 0)
    }

    /// Whether the closed polygons `shadow` (point `i` is followed by `next[i]`) are simple and
    /// apart: a sweep along x over their edges' spans, the edges whose boxes overlap tested
    /// exactly.
    fn simple(&mut self) -> bool {
        let (s, next) = (&self.shadow, &self.next);
        let n = s.len();
        let edge = |i: usize| (s[i], s[next[i] as usize]);
        let low_x = |i: usize| s[i][0].min(s[next[i] as usize][0]);
        // Edges that follow each other share their common point only: not collinear going back.
        for i in 0..n {
            let j = next[i] as usize;
            let (u, v, w) = (s[i], s[j], s[next[j] as usize]);
            if o2(u, v, w) == 0.0 && same_way(v, u, w) {
                return false;
            }
        }
        self.by_low_x.clear();
        self.by_low_x.extend(0..n as u32);
        self.by_low_x
            .sort_unstable_by(|&a, &b| low_x(a as usize).total_cmp(&low_x(b as usize)));
        self.active.clear();
        for &i in &self.by_low_x {
            let (p, q) = edge(i as usize);
            let x = low_x(i as usize);
            self.active.retain(|&j| {
                let (a, b) = edge(j as usize);
                a[0].max(b[0]) >= x
            });
            for &j in &self.active {
                if next[i as usize] == j || next[j as usize] == i {
                    continue;
                }
                let (a, b) = edge(j as usize);
                let apart_y = p[1].max(q[1]) < a[1].min(b[1]) || a[1].max(b[1]) < p[1].min(q[1]);
                if !apart_y && segments_meet(p, q, a, b) {
                    return false;
                }
            }
            self.active.push(i);
        }
        true
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
            let p = s[low];
            let others: i32 = (0..self.loops.len())
                .filter(|&m| m != l)
                .map(|m| winding(s, next, self.loops[m] as usize..end(m), p))
                .sum();
            own + way * others == 1
        })
    }
}

/// The most loops a flat patch may have.
const MAX_LOOPS: usize = 8;

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
        Patches::new(points, &table, &place).is_flat(0..triangles.len(), bits, |p| p as u32)
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
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move |n: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % n
        };
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
            let mut patches = Patches::new(&points, &table, &place);
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
}
