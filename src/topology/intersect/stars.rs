//! Vertices whose **star** (the faces around them) is flat enough to need no test: the faces of
//! such a vertex meet one another only where they share that vertex or an edge, so the search
//! leaves out every pair of faces that shares one (on a smooth surface, almost all of its pairs).
//!
//! A star is flat when it projects one to one onto a plane: dropping coordinate `k` (exact, no
//! arithmetic), or, for a closed star no axis flattens (a CAD corner or crease), along a direction
//! of its own near its normal ([`along_own_axes`], with exact `orient3d`), every face around `v`
//! keeps its orientation sign and the faces go around `v` exactly once. Then the faces are the graph of a function over the plane around `v`,
//! their shadows are wedges that touch only along the spokes they share, and two faces have no
//! common point but the shadows' common part lifted back: `v`, or their shared edge.
//!
//! Decided exactly, face by face in any order, with no walk around the vertex:
//!
//! - every edge at `v` is a manifold edge whose two faces agree on its direction, so the faces'
//!   outer edges (`a -> b` of face `v a b`) join into closed loops around `v`, one per fan;
//! - for some axis `k`, every face's projected orientation (`orient2d`, exact) has one sign, not
//!   zero: each outer edge passes `v` on the same side, so each loop winds around `v` at least once;
//! - the loops' winding numbers add up to 1: counted as the outer edges crossing the ray from `v`
//!   along the second kept axis, each crossing in the loop's own direction (`a.y <= v.y < b.y`
//!   for counter-clockwise faces, with the half-open rule that counts a spoke on the ray once).
//!   With every edge passing `v` on one side, no edge crosses the ray the other way, so the count
//!   is the sum of the windings: one loop, winding once.
//!
//! One winding means the wedges' angles sum to one full turn and follow each other, so their
//! insides are apart. A vertex on a border, a bowtie (two fans), a fold, a fan that turns twice,
//! or a flipped neighbour is not flat, and its pairs are tested as before.

use rayon::prelude::*;

use crate::corner_table::CornerTable;

use super::meet::{cross, o3, sub, turns, Point, AXES};
use super::patches::turn_bits;

/// Per axis `k`, five bits of a vertex's state: some face of its star turns counter-clockwise,
/// clockwise, not at all in that projection; one crossing seen; a second crossing seen.
const COUNTER: u16 = 1;
const CLOCKWISE: u16 = 2;
const ZERO: u16 = 4;
const ONE: u16 = 8;
const TWO: u16 = 16;
/// An edge at the vertex that is a border, non-manifold, or whose faces disagree on its direction.
const OPEN: u16 = 1 << 15;
/// [`ONE`] on every axis.
const ONES: u16 = ONE | ONE << 5 | ONE << 10;

/// What the search learns of a mesh's faces before it pairs them.
pub(super) struct Stars {
    /// One bit per vertex of the table: its star is flat (see the module docs).
    pub(super) flat: Vec<u64>,
    /// One bit per face: its three points are exactly on a line (every projection of it has zero
    /// area), which the search leaves out.
    pub(super) collinear: Vec<u64>,
    /// Per face, its turn bits ([`super::patches::turn_bits`]).
    pub(super) turns: Vec<u8>,
    /// Per vertex of the table, bit `k`: its star is flat dropping coordinate `k` (the pinches of
    /// a flat patch need it along the patch's axis, [`super::patches`]). `flat` is set where this
    /// is not zero and where the star is flat only along its own axis; it stays a bit vector, an
    /// eighth of this, for the tree build's three lookups a face.
    pub(super) along: Vec<u8>,
}

/// The flat stars and collinear faces of `table` over `points`. Faces are read in parallel runs
/// on the current rayon pool, each corner's part of its vertex's state written apart; one pass in
/// corner order then joins them.
pub(super) fn flat_stars(points: &[Point], table: &CornerTable) -> Stars {
    flat_stars_with(points, table, true)
}

/// [`flat_stars`]; without `own_axis`, only the coordinate axes are tried.
fn flat_stars_with(points: &[Point], table: &CornerTable, own_axis: bool) -> Stars {
    const RUN: usize = 1 << 12;
    let triangles = table.triangles();
    let mut parts = vec![[0u16; 3]; triangles.len()];
    let mut collinear = vec![0u64; triangles.len().div_ceil(64)];
    let mut turns = vec![0u8; triangles.len()];
    parts
        .par_chunks_mut(RUN)
        .zip(collinear.par_chunks_mut(RUN / 64))
        .zip(turns.par_chunks_mut(RUN))
        .enumerate()
        .for_each(|(r, ((parts, collinear), turns))| {
            for (i, (part, bits)) in parts.iter_mut().zip(turns).enumerate() {
                let t = r * RUN + i;
                let (p, turn) = corner_parts(points, table, t);
                *part = p;
                *bits = turn_bits(turn);
                collinear[i / 64] |= u64::from(turn == [0.0; 3]) << (i % 64);
            }
        });
    let mut state = vec![0u16; table.vertex_count()];
    for (tri, part) in triangles.iter().zip(&parts) {
        for j in 0..3 {
            let (s, add) = (&mut state[tri[j] as usize], part[j]);
            // A crossing seen twice becomes TWO (one bit above ONE on every axis).
            *s |= add | (*s & add & ONES) << 1;
        }
    }
    let mut flat = vec![0u64; state.len().div_ceil(64)];
    let mut along = vec![0u8; state.len()];
    let mut closed_not_flat = Vec::new();
    for (v, &s) in state.iter().enumerate() {
        if s & OPEN == 0 {
            along[v] = (0..3).fold(0, |m, k| m | u8::from(once_around(s >> (5 * k))) << k);
            if along[v] != 0 {
                flat[v / 64] |= 1 << (v % 64);
            } else {
                closed_not_flat.push(v as u32);
            }
        }
    }
    if own_axis && !closed_not_flat.is_empty() {
        along_own_axes(points, table, &closed_not_flat, &mut flat);
    }
    Stars {
        flat,
        collinear,
        turns,
        along,
    }
}

/// Whether one axis's five bits say its faces all turn one way and cross the ray once.
fn once_around(s: u16) -> bool {
    let turns = s & (COUNTER | CLOCKWISE | ZERO);
    (turns == COUNTER || turns == CLOCKWISE) && s & (ONE | TWO) == ONE
}

/// The second chance of the closed stars that no coordinate axis flattens (the corners and creases
/// of CAD models, whose faces lie in the axes' planes): each is looked at along a direction of its
/// own, near its normal. The projection is along `e - v` for a point `e` taken near `v + normal`
/// (any point off `v` will do: the direction is whatever `e - v` exactly is), so a face's turn is
/// the exact `orient3d(v, a, b, e)`, and the ray is the side of the plane through `v`, `e` and a
/// third point `h`: `orient3d(v, e, h, x)` is the side of the projected line that `x` falls on.
/// The count of crossings is then the same as along an axis: with every outer edge passing `v` on
/// one side, the edges crossing that line one way are the edges crossing one half of it.
fn along_own_axes(points: &[Point], table: &CornerTable, candidates: &[u32], flat: &mut [u64]) {
    let triangles = table.triangles();
    let mut slot = vec![u32::MAX; table.vertex_count()];
    for (i, &v) in candidates.iter().enumerate() {
        slot[v as usize] = i as u32;
    }
    // The candidates' corners, in face order: (face, corner, candidate). Found by their ids
    // alone; points are read for these only (a smooth scan has a handful of candidates).
    let corners: Vec<(usize, usize, usize)> = triangles
        .iter()
        .enumerate()
        .flat_map(|(t, tri)| {
            let slot = &slot;
            (0..3).filter_map(move |j| {
                let i = slot[tri[j] as usize];
                (i != u32::MAX).then_some((t, j, i as usize))
            })
        })
        .collect();
    let at = |t: usize| triangles[t].map(|v| points[v as usize]);
    // The candidates' directions: the sums of their faces' normals, and the sums of their spokes'
    // lengths (floating point; only which way they point matters, and not even that for
    // exactness).
    let mut normal = vec![([0.0f64; 3], 0.0f64); candidates.len()];
    for &(t, j, i) in &corners {
        let p = at(t);
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        let (sum, length) = &mut normal[i];
        for k in 0..3 {
            sum[k] += n[k];
        }
        *length += norm(sub(p[(j + 1) % 3], p[j]));
    }
    // A frame that is not finite (a normal too small for its spokes) leaves its vertex as it is.
    let frames: Vec<Option<(Point, Point)>> = candidates
        .iter()
        .zip(&normal)
        .map(|(&v, &(n, length))| {
            let v = points[v as usize];
            let scale = length / norm(n).max(f64::MIN_POSITIVE);
            let e: Point = std::array::from_fn(|k| v[k] + n[k] * scale);
            // A direction across n: n times the axis n is least along.
            let least = (0..3).fold(0, |m, k| if n[k].abs() < n[m].abs() { k } else { m });
            let mut axis = [0.0; 3];
            axis[least] = 1.0;
            let u = cross(n, axis);
            let scale = length / norm(u).max(f64::MIN_POSITIVE);
            let h: Point = std::array::from_fn(|k| v[k] + u[k] * scale);
            e.iter().chain(&h).all(|x| x.is_finite()).then_some((e, h))
        })
        .collect();
    let mut state = vec![0u16; candidates.len()];
    for &(t, j, i) in &corners {
        let Some((e, h)) = frames[i] else {
            continue;
        };
        let p = at(t);
        let (v, a, b) = (p[j], p[(j + 1) % 3], p[(j + 2) % 3]);
        let turn = o3(v, a, b, e);
        let (sa, sb) = (o3(v, e, h, a), o3(v, e, h, b));
        let (bits, crosses) = if turn > 0.0 {
            (COUNTER, sa <= 0.0 && 0.0 < sb)
        } else if turn < 0.0 {
            (CLOCKWISE, sb <= 0.0 && 0.0 < sa)
        } else {
            (ZERO, false)
        };
        let add = bits | if crosses { ONE } else { 0 };
        let s = &mut state[i];
        *s |= add | (*s & add & ONE) << 1;
    }
    for ((&v, &s), frame) in candidates.iter().zip(&state).zip(&frames) {
        if frame.is_some() && once_around(s) {
            flat[v as usize / 64] |= 1 << (v % 64);
        }
    }
}

fn norm(a: Point) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// What face `t` adds to the state of each of its corners' vertices, and its turns (all zero:
/// collinear).
#[inline]
fn corner_parts(points: &[Point], table: &CornerTable, t: usize) -> ([u16; 3], [f64; 3]) {
    let tri = table.triangles()[t];
    let p = tri.map(|v| points[v as usize]);
    // A face turns the same way seen from each of its corners.
    let turn = turns(p[0], p[1], p[2]);
    // Edge `j` (opposite corner `j`) joins corners `j + 1` and `j + 2`: when it is open, so are
    // they.
    let mut parts = [0u16; 3];
    for j in 0..3 {
        if !closed(table, (3 * t + j) as u32) {
            parts[(j + 1) % 3] |= OPEN;
            parts[(j + 2) % 3] |= OPEN;
        }
    }
    for (j, part) in parts.iter_mut().enumerate() {
        let (v, a, b) = (p[j], p[(j + 1) % 3], p[(j + 2) % 3]);
        for (k, axes) in AXES.iter().enumerate() {
            // Without branches: a face's turn along an axis near its plane is a coin toss the
            // processor would mispredict.
            let y = axes.1;
            let (counter, clockwise) = (turn[k] > 0.0, turn[k] < 0.0);
            let (from, to) = if counter { (a[y], b[y]) } else { (b[y], a[y]) };
            let crosses = (counter | clockwise) & (from <= v[y]) & (v[y] < to);
            let bits = (u16::from(counter) * COUNTER)
                | (u16::from(clockwise) * CLOCKWISE)
                | (u16::from(!counter & !clockwise) * ZERO)
                | (u16::from(crosses) * ONE);
            *part |= bits << (5 * k);
        }
    }
    // Collinear: no projection has area (as `meet::collinear` says).
    (parts, turn)
}

/// Whether the edge opposite corner `c` is a manifold edge whose two faces traverse it in opposite
/// directions.
fn closed(table: &CornerTable, c: u32) -> bool {
    table.opposite(c).is_some() && table.is_consistent(c)
}

/// Whether vertex `v` is set in `bits`.
pub(super) fn is_set(bits: &[u64], v: u32) -> bool {
    bits[v as usize / 64] & (1 << (v % 64)) != 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::intersect::meet::{collinear, faces_meet};

    fn flat_of(points: &[Point], triangles: &[[u32; 3]]) -> Vec<bool> {
        let table = CornerTable::build(triangles, points.len());
        let bits = flat_stars(points, &table).flat;
        (0..points.len() as u32).map(|v| is_set(&bits, v)).collect()
    }

    /// The closed fan `0 s_i s_{i+1}` around vertex 0 over `spokes` (vertices 1..), plus a cap
    /// `1 s_{i+1} s_i`... not needed: the rim's edges are borders, so only vertex 0 can be flat.
    fn fan(spokes: &[Point]) -> (Vec<Point>, Vec<[u32; 3]>) {
        let mut points = vec![[0.0; 3]];
        points.extend_from_slice(spokes);
        let n = spokes.len() as u32;
        let triangles = (0..n).map(|i| [0, 1 + i, 1 + (i + 1) % n]).collect();
        (points, triangles)
    }

    /// Whether two faces meet ([`faces_meet`], no stars), or `None` when a face is collinear (the
    /// search leaves those out).
    fn any_pair_meets(points: &[Point], triangles: &[[u32; 3]]) -> Option<bool> {
        let at = |t: [u32; 3]| t.map(|v| points[v as usize]);
        if triangles.iter().any(|&t| {
            let [a, b, c] = at(t);
            collinear(a, b, c)
        }) {
            return None;
        }
        Some((0..triangles.len()).any(|i| {
            (i + 1..triangles.len()).any(|j| {
                let (f, g) = (triangles[i], triangles[j]);
                faces_meet(f, at(f), g, at(g))
            })
        }))
    }

    /// Spokes at the given angles (degrees), radius 1, alternating heights: a fan that turns
    /// counter-clockwise seen from +z.
    fn spokes(angles: &[f64]) -> Vec<Point> {
        angles
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let a = a.to_radians();
                [a.cos(), a.sin(), if i % 2 == 0 { 0.25 } else { -0.25 }]
            })
            .collect()
    }

    #[test]
    fn a_fan_once_around_is_flat_and_its_rim_is_not() {
        let (points, triangles) = fan(&spokes(&[0.0, 60.0, 120.0, 180.0, 240.0, 300.0]));
        let flat = flat_of(&points, &triangles);
        assert!(flat[0]);
        assert!(
            flat[1..].iter().all(|&f| !f),
            "rim vertices are on a border"
        );
        // Turned the other way (every face clockwise from +z): still flat.
        let turned: Vec<[u32; 3]> = triangles.iter().map(|&[a, b, c]| [a, c, b]).collect();
        assert!(flat_of(&points, &turned)[0]);
    }

    /// Five wedges of 144 degrees go around twice: every face turns the same way, but the count of
    /// crossings is 2.
    #[test]
    fn a_fan_twice_around_is_not_flat() {
        let (points, triangles) = fan(&spokes(&[0.0, 144.0, 288.0, 72.0, 216.0]));
        assert!(!flat_of(&points, &triangles)[0]);
    }

    /// One spoke pulled back past its neighbour: that face turns the other way in every projection
    /// kept near z, and along x and y the fan does not go around once.
    #[test]
    fn a_fan_with_a_face_turned_back_is_not_flat() {
        let (points, triangles) = fan(&spokes(&[0.0, 90.0, 60.0, 180.0, 270.0]));
        assert!(!flat_of(&points, &triangles)[0]);
    }

    /// The octahedron: every vertex's star projects one to one along the axis through it. With one
    /// face's winding reversed, the three vertices of that face have an edge whose faces disagree.
    #[test]
    fn octahedron_stars_are_flat_unless_a_face_is_flipped() {
        let points = vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let mut triangles = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        assert_eq!(flat_of(&points, &triangles), vec![true; 6]);
        triangles[0] = [0, 4, 2];
        let flat = flat_of(&points, &triangles);
        assert_eq!(flat, vec![false, true, false, true, false, true]);
    }

    /// Two tetrahedra on one welded vertex (a bowtie): that vertex has two fans, whose crossings add
    /// up to 2 (or whose faces turn both ways); the other vertices are flat.
    #[test]
    fn the_vertex_of_a_bowtie_is_not_flat() {
        let points = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.1, 0.2],
            [0.2, 1.0, 0.1],
            [0.1, 0.2, 1.0],
            [-1.0, -0.1, -0.2],
            [-0.2, -1.0, -0.1],
            [-0.1, -0.2, -1.0],
        ];
        let tetra = |[a, b, c]: [u32; 3]| [[0, b, a], [0, c, b], [0, a, c], [a, b, c]];
        let mut triangles = tetra([1, 2, 3]).to_vec();
        triangles.extend(tetra([4, 6, 5]));
        let flat = flat_of(&points, &triangles);
        assert!(!flat[0]);
        assert!(flat[1..].iter().all(|&f| f), "{flat:?}");
    }

    /// A cube's corners: along every coordinate axis some of a corner's faces have no area, so no
    /// axis flattens its star; along its own normal (the diagonal, or near it) every corner is flat.
    #[test]
    fn cube_corners_are_flat_along_their_own_axis_only() {
        let points: Vec<Point> = (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .collect();
        let triangles = [
            [0, 2, 3],
            [0, 3, 1],
            [4, 5, 7],
            [4, 7, 6],
            [0, 1, 5],
            [0, 5, 4],
            [2, 6, 7],
            [2, 7, 3],
            [0, 4, 6],
            [0, 6, 2],
            [1, 3, 7],
            [1, 7, 5],
        ];
        let table = CornerTable::build(&triangles, points.len());
        let along_axes = flat_stars_with(&points, &table, false).flat;
        let along_own = flat_stars(&points, &table).flat;
        assert_eq!(along_axes, vec![0]);
        assert_eq!(along_own, vec![0xff]);
    }

    /// The claim the search rests on, tested on 30,000 random closed fans whose spokes lie on a
    /// small integer grid (so that faces are often exactly coplanar, fold onto an edge or touch
    /// along a spoke), most going around once, some with two spokes swapped or turned around an
    /// axis: where the star is flat, no two of its faces meet ([`faces_meet`], which tests them
    /// without stars). Both kinds must be common for the test to mean something.
    #[test]
    fn faces_of_a_flat_star_never_meet() {
        let mut bits = crate::geometry::xorshift(0x51a7_57a2);
        let mut below = |n: u64| bits() % n;
        let (mut flat_fans, mut meeting_fans) = (0, 0);
        for _ in 0..30_000 {
            let n = 3 + below(6) as usize;
            let mut spokes: Vec<Point> = (0..n)
                .map(|_| {
                    let mut c = |r: u64| below(2 * r + 1) as f64 - r as f64;
                    [c(3), c(3), c(2)]
                })
                .filter(|p| p[0] != 0.0 || p[1] != 0.0)
                .collect();
            spokes.sort_by(|p, q| p[1].atan2(p[0]).total_cmp(&q[1].atan2(q[0])));
            spokes.dedup();
            if spokes.len() < 3 {
                continue;
            }
            if below(4) == 0 {
                let (i, j) = (below(spokes.len() as u64), below(spokes.len() as u64));
                spokes.swap(i as usize, j as usize);
            }
            // Turn the whole fan so that the axis it goes around is x, y or z.
            let turn = below(3) as usize;
            for p in &mut spokes {
                p.rotate_left(turn);
            }
            let (points, triangles) = fan(&spokes);
            let Some(meets) = any_pair_meets(&points, &triangles) else {
                continue;
            };
            let flat = flat_of(&points, &triangles)[0];
            assert!(!(flat && meets), "{spokes:?}");
            flat_fans += usize::from(flat);
            meeting_fans += usize::from(meets);
        }
        assert!(
            flat_fans > 3000 && meeting_fans > 3000,
            "{flat_fans} flat, {meeting_fans} meeting"
        );
    }

    /// The same claim for stars no coordinate axis flattens: 30,000 random closed fans with spokes
    /// on a small integer grid in every direction, going around a random grid direction (most
    /// once, some with two spokes swapped), so that faces often lie in the axes' planes, fold,
    /// touch or cross. Where the star is flat along its own axis, no two of its faces meet; many
    /// stars are flat that way only, and many have faces that meet.
    #[test]
    fn faces_of_a_star_flat_along_its_own_axis_never_meet() {
        let mut next = crate::geometry::xorshift(0x0c0f_fee5);
        let c = |r: u64, x: u64| (x % (2 * r + 1)) as f64 - r as f64;
        let (mut own_only, mut meeting_fans) = (0, 0);
        for _ in 0..30_000 {
            let d = [c(2, next()), c(2, next()), c(2, next())];
            if d == [0.0; 3] {
                continue;
            }
            // A frame across d, only to sort the spokes around it.
            let least = (0..3).fold(0, |m, k| if d[k].abs() < d[m].abs() { k } else { m });
            let mut axis = [0.0; 3];
            axis[least] = 1.0;
            let (x, y) = (cross(d, axis), cross(d, cross(d, axis)));
            let dot = |a: Point, b: Point| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            let n = 3 + (next() % 6) as usize;
            let mut spokes: Vec<Point> = (0..n)
                .map(|_| [c(3, next()), c(3, next()), c(3, next())])
                .filter(|p| norm(cross(*p, d)) > 0.0)
                .collect();
            spokes.sort_by(|p, q| {
                let angle = |p: &Point| dot(*p, y).atan2(dot(*p, x));
                angle(p).total_cmp(&angle(q))
            });
            spokes.dedup();
            if spokes.len() < 3 {
                continue;
            }
            if next().is_multiple_of(4) {
                let len = spokes.len() as u64;
                let (i, j) = (next() % len, next() % len);
                spokes.swap(i as usize, j as usize);
            }
            let (points, triangles) = fan(&spokes);
            let Some(meets) = any_pair_meets(&points, &triangles) else {
                continue;
            };
            let table = CornerTable::build(&triangles, points.len());
            let flat = is_set(&flat_stars(&points, &table).flat, 0);
            let along_axes = is_set(&flat_stars_with(&points, &table, false).flat, 0);
            assert!(!(flat && meets), "{spokes:?}");
            own_only += usize::from(flat && !along_axes);
            meeting_fans += usize::from(meets);
        }
        assert!(
            own_only > 1000 && meeting_fans > 3000,
            "{own_only} flat along their own axis only, {meeting_fans} meeting"
        );
    }
}
