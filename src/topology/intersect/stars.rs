//! Vertices whose **star** (the faces around them) is flat enough to need no test: the faces of
//! such a vertex meet one another only where they share that vertex or an edge, so the search
//! leaves out every pair of faces that shares one (on a smooth surface, almost all of its pairs).
//!
//! A star is flat when it projects one to one onto a coordinate plane: dropping coordinate `k`
//! (exact, no arithmetic), every face around `v` keeps its orientation sign and the faces go
//! around `v` exactly once. Then the faces are the graph of a function over the plane around `v`,
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

use super::meet::{turns, Point, AXES};

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
}

/// The flat stars and collinear faces of `table` over `points`. Faces are read in parallel runs
/// on the current rayon pool, each corner's part of its vertex's state written apart; one pass in
/// corner order then joins them.
pub(super) fn flat_stars(points: &[Point], table: &CornerTable) -> Stars {
    const RUN: usize = 1 << 12;
    let triangles = table.triangles();
    let mut parts = vec![[0u16; 3]; triangles.len()];
    let mut collinear = vec![0u64; triangles.len().div_ceil(64)];
    parts
        .par_chunks_mut(RUN)
        .zip(collinear.par_chunks_mut(RUN / 64))
        .enumerate()
        .for_each(|(r, (parts, collinear))| {
            for (i, part) in parts.iter_mut().enumerate() {
                let t = r * RUN + i;
                let (p, flat) = corner_parts(points, table, t);
                *part = p;
                collinear[i / 64] |= u64::from(flat) << (i % 64);
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
    for (v, &s) in state.iter().enumerate() {
        let one_way = (0..3).any(|k| {
            let s = s >> (5 * k);
            let turns = s & (COUNTER | CLOCKWISE | ZERO);
            (turns == COUNTER || turns == CLOCKWISE) && s & (ONE | TWO) == ONE
        });
        if s & OPEN == 0 && one_way {
            flat[v / 64] |= 1 << (v % 64);
        }
    }
    Stars { flat, collinear }
}

/// What face `t` adds to the state of each of its corners' vertices, and whether it is collinear.
#[inline]
fn corner_parts(points: &[Point], table: &CornerTable, t: usize) -> ([u16; 3], bool) {
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
            let y = axes.1;
            let (bits, crosses) = if turn[k] > 0.0 {
                (COUNTER, a[y] <= v[y] && v[y] < b[y])
            } else if turn[k] < 0.0 {
                (CLOCKWISE, b[y] <= v[y] && v[y] < a[y])
            } else {
                (ZERO, false)
            };
            *part |= (bits | if crosses { ONE } else { 0 }) << (5 * k);
        }
    }
    // Collinear: no projection has area (as `meet::collinear` says).
    (parts, turn == [0.0; 3])
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
            if triangles.iter().any(|t| {
                let [a, b, c] = t.map(|v| points[v as usize]);
                collinear(a, b, c)
            }) {
                continue;
            }
            let meets = (0..triangles.len()).any(|i| {
                (i + 1..triangles.len()).any(|j| {
                    let (f, g) = (triangles[i], triangles[j]);
                    let at = |t: [u32; 3]| t.map(|v| points[v as usize]);
                    faces_meet(f, at(f), g, at(g))
                })
            });
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
}
