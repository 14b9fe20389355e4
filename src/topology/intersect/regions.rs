//! **Flat regions**: the faces of one plane perpendicular to an axis (`x`, `y` or `z` constant)
//! that join edge to edge, which no pair of their own can meet in when they are a flat patch; the
//! search skips those pairs as it finds them.
//!
//! CAD exports and print models are made of plates whose top and bottom are such a plane each,
//! cut into long thin faces. Their boxes overlap by the hundred thousand, and every such pair is
//! exactly coplanar, the narrow phase's most expensive case. The tree's flat patches
//! ([`super::patches`]) do not cover them: a tree node of a thin plate holds faces of its top,
//! its bottom and its sides, which turn different ways.
//!
//! A region is a class of the relation "share a manifold edge that both traverse in opposite
//! directions, and both faces turn along axis `k` only, the same way". A face that turns along
//! `k` only has an exact normal along `k`, so its three points share coordinate `k`; two such
//! faces on one edge share it too, so a region lies in one plane `x_k = c` (a face folded back
//! onto its neighbour turns the other way and is not joined). A region of at least [`MIN_FACES`]
//! faces that passes the flat-patch test is a **flat region**: two of its faces share a point
//! only where they share a vertex or an edge (the argument of [`super::patches`], which holds for
//! any set of faces, not only a node of the tree), so they do not meet. What makes the skip exact
//! is the flat-patch test alone: the grouping only chooses which sets are worth testing.
//!
//! A face outside a flat region that touches the region's plane only at corners of the region
//! meets none of its faces either, and the search skips those pairs too ([`Regions::apart`]): the
//! walls of an extruded profile touch its end caps along their end edges and at their far corners,
//! and their boxes overlap the caps' long faces by the hundred thousand. Let `g` touch the plane
//! of region `R` only at its vertex `v`, a corner of some face `D` of `R` (its other two vertices
//! strictly on one side of the plane), and let `C` be a face of `R` with a point of `g`: that
//! point is `v`, which `C` and `D` have in common, so (as two faces of a flat patch) it is a vertex
//! or on an edge they share, and being `D`'s corner it is a shared vertex, `v` itself. Then `C`
//! and `g` have only their shared vertex in common: they do not meet. If `g` touches the plane only
//! along its edge `a b`, the edge of a face `D` of `R`, a common point of `g` and `C` is on `a b`,
//! so again a point of `D`: a vertex or a point of an edge `C` and `D` share, which on `a b` is `a`,
//! `b`, or the edge `a b` itself; `C` and `g` share that vertex or that edge, and with `g`'s third
//! vertex off the plane they do not fold onto each other. Which vertices and edges are the
//! region's comes from the Corner Table (vertex ids, and the face across `g`'s edge), never from
//! positions; the sides are exact comparisons of coordinate `k`.
//!
//! Tilted planes are not looked for. Their exact test is an `orient3d` whose fast filter fails on
//! points exactly in one plane, and its exact fallback ran on the diagonal of every planar quad of
//! a smooth mesh: on an 871k-face torus made of quads it cost more (+27% of the search's
//! instructions) than the regions saved anywhere in the corpus. A face is in a plane
//! perpendicular to axis `k` exactly when it turns along `k` only (its exact normal has no other
//! component), which its turn bits, computed by the stars' pass, already say: the test costs a
//! byte a face, and a mesh with no joins allocates nothing.

use std::cmp::Ordering;

use crate::corner_table::{CornerTable, NON_MANIFOLD};
use crate::topology::sets::{find, union};

use super::meet::Point;
use super::patches::Patches;

/// Regions smaller than this are not tested (their few pairs cost less than the test).
const MIN_FACES: usize = 3;

/// The most loops (outline and holes) a flat region may have.
const MAX_LOOPS: usize = 64;

/// No flat region.
pub(super) const NONE: u32 = u32::MAX;

/// The flat regions of a mesh: each face's region, and the regions each vertex is a corner of.
#[derive(Default)]
pub(super) struct Regions {
    /// Per table face, its flat region ([`NONE`] when it is in none); empty when the mesh has none.
    face: Vec<u32>,
    /// The regions with a face at vertex `v` are `ids[start[v]..start[v + 1]]`, each once.
    start: Vec<u32>,
    ids: Vec<u32>,
}

impl Regions {
    /// The regions of `face` (per table face of `table`, as [`Regions::face`]), with their
    /// corners.
    fn new(face: Vec<u32>, table: &CornerTable) -> Regions {
        if face.is_empty() {
            return Regions::default();
        }
        // Per vertex, a slot for each corner of a region's face at it, filled with its regions
        // each once (the slots a repeat would take stay NONE, which no region equals).
        let corners = || {
            table
                .triangles()
                .iter()
                .zip(&face)
                .filter(|&(_, &r)| r != NONE)
                .flat_map(|(tri, &r)| tri.map(|v| (v as usize, r)))
        };
        let mut start = vec![0u32; table.vertex_count() + 1];
        for (v, _) in corners() {
            start[v + 1] += 1;
        }
        for v in 0..table.vertex_count() {
            start[v + 1] += start[v];
        }
        let mut ids = vec![NONE; start[table.vertex_count()] as usize];
        for (v, r) in corners() {
            let slots = &mut ids[start[v] as usize..start[v + 1] as usize];
            if let Some(free) = slots.iter().position(|&x| x == r || x == NONE) {
                slots[free] = r;
            }
        }
        // Without the empty slots each vertex lists only its distinct regions, a few at most; a
        // fan of many faces of one region at a vertex no longer makes every look-up there long.
        let mut kept = 0;
        for v in 0..table.vertex_count() {
            let (lo, hi) = (start[v] as usize, start[v + 1] as usize);
            start[v] = kept as u32;
            for i in lo..hi {
                if ids[i] == NONE {
                    break;
                }
                ids[kept] = ids[i];
                kept += 1;
            }
        }
        start[table.vertex_count()] = kept as u32;
        ids.truncate(kept);
        Regions { face, start, ids }
    }

    /// Whether the mesh has no flat region.
    pub(super) fn is_empty(&self) -> bool {
        self.face.is_empty()
    }

    /// The flat region of table face `t` ([`NONE`]: none, as for every face when
    /// [`Regions::is_empty`]).
    #[inline]
    pub(super) fn of(&self, t: u32) -> u32 {
        self.face.get(t as usize).copied().unwrap_or(NONE)
    }

    /// Per table face, up to two regions none of whose faces it can meet ([`NONE`] in unused
    /// places): the region it is in, or regions it touches only at their corners or along their
    /// edges ([`Regions::apart`]; a wall standing on a plate and under another). Empty when the
    /// mesh has no flat region.
    pub(super) fn covers(&self, table: &CornerTable, points: &[Point]) -> Vec<[u32; 2]> {
        // Worth a pass over every face only where regions are a good part of the mesh (CAD
        // plates), not for a few flat spots of a scan.
        let in_regions = self.face.iter().filter(|&&r| r != NONE).count();
        if in_regions < self.face.len() / 8 {
            return Vec::new();
        }
        // A face of each region, whose points give the region's plane.
        let mut sample: rustc_hash::FxHashMap<u32, u32> = Default::default();
        for (t, &r) in self.face.iter().enumerate() {
            if r != NONE {
                sample.entry(r).or_insert(t as u32);
            }
        }
        let triangles = table.triangles();
        let at = |t: u32| triangles[t as usize].map(|v| points[v as usize]);
        (0..self.face.len() as u32)
            .map(|g| {
                let own = self.face[g as usize];
                if own != NONE {
                    return [own, NONE];
                }
                let ids = triangles[g as usize];
                let mut out = [NONE; 2];
                let mut found = 0;
                for v in ids {
                    let (lo, hi) = (self.start[v as usize], self.start[v as usize + 1]);
                    for &r in &self.ids[lo as usize..hi as usize] {
                        if found == 2 || out.contains(&r) {
                            continue;
                        }
                        if self.apart(table, r, at(sample[&r]), g, ids, at(g)) {
                            out[found] = r;
                            found += 1;
                        }
                    }
                }
                out
            })
            .collect()
    }

    /// Whether vertex `v` is a corner of a face of region `r`.
    fn has_corner(&self, r: u32, v: u32) -> bool {
        let (lo, hi) = (self.start[v as usize], self.start[v as usize + 1]);
        self.ids[lo as usize..hi as usize].contains(&r)
    }

    /// Whether table face `g` (its vertices `ids` at `points`) touches the plane of region `r`
    /// only at a corner of the region, or only along an edge of one of its faces, so that it meets
    /// no face of `r` (see the module docs). `plane`: the points of a face of `r`.
    #[inline]
    pub(super) fn apart(
        &self,
        table: &CornerTable,
        r: u32,
        plane: [Point; 3],
        g: u32,
        ids: [u32; 3],
        points: [Point; 3],
    ) -> bool {
        let [p, q, s] = plane;
        // The region's plane is `x_k = p[k]`.
        let Some(k) = (0..3).find(|&k| p[k] == q[k] && q[k] == s[k]) else {
            return false;
        };
        let side = points.map(|x| x[k].partial_cmp(&p[k]));
        let on: [bool; 3] = side.map(|s| s == Some(Ordering::Equal));
        match on.iter().filter(|&&o| o).count() {
            1 => {
                let i = on.iter().position(|&o| o).unwrap_or(0);
                let (j, m) = ((i + 1) % 3, (i + 2) % 3);
                side[j] == side[m] && side[j].is_some() && self.has_corner(r, ids[i])
            }
            2 => {
                // The edge on the plane is the one opposite the corner off it.
                let m = on.iter().position(|&o| !o).unwrap_or(0);
                side[m].is_some()
                    && table
                        .opposite(3 * g + m as u32)
                        .is_some_and(|o| self.face[CornerTable::t(o) as usize] == r)
            }
            _ => false,
        }
    }
}

/// The flat regions of `table` over `points`. `turns`: the faces' turn bits
/// ([`super::patches::turn_bits`]); `along`: per vertex, the axes its star is flat along
/// ([`super::stars::Stars::along`]).
pub(super) fn flat_regions(
    points: &[Point],
    table: &CornerTable,
    turns: &[u8],
    along: &[u8],
) -> Regions {
    Regions::new(face_regions(points, table, turns, along), table)
}

/// Per table face, its flat region ([`NONE`] when it is in none); empty when the mesh has none.
fn face_regions(points: &[Point], table: &CornerTable, turns: &[u8], along: &[u8]) -> Vec<u32> {
    let nt = table.triangle_count();
    // The joins: pairs of faces on a coplanar consistent manifold edge (few on most meshes).
    let mut joins: Vec<(u32, u32)> = Vec::new();
    for t in 0..nt as u32 {
        // In a plane perpendicular to axis `k` exactly when the face turns along `k` only: its
        // exact normal has no other component.
        if !one_axis(turns[t as usize]) {
            continue;
        }
        for c in 3 * t..3 * t + 3 {
            let o = table.o(c);
            if o == c || o == NON_MANIFOLD {
                continue;
            }
            let u = CornerTable::t(o);
            // A neighbour that also turns along `k` only has its three points at one coordinate
            // `k`, which its two on the shared edge fix at the plane's: it is in the plane.
            if u > t && turns[t as usize] == turns[u as usize] && table.is_consistent(c) {
                joins.push((t, u));
            }
        }
    }
    if joins.len() + 1 < MIN_FACES {
        return Vec::new();
    }

    let members = classes(joins);
    if members.is_empty() {
        return Vec::new();
    }
    let mut place = vec![u32::MAX; nt];
    for (p, &(_, t)) in members.iter().enumerate() {
        place[t as usize] = p as u32;
    }

    let mut region = Vec::new();
    // A plate's top has a loop per hole: allow many (the test is run once per region).
    let mut patches = Patches::new(points, table, &place, along).with_max_loops(MAX_LOOPS);
    let mut first = 0;
    while first < members.len() {
        let r = members[first].0;
        let end = first + members[first..].partition_point(|m| m.0 == r);
        let bits = members[first..end]
            .iter()
            .fold(u8::MAX, |m, &(_, t)| m & turns[t as usize]);
        if patches.is_flat(first..end, bits, |p| members[p].1) {
            if region.is_empty() {
                region = vec![NONE; nt];
            }
            for &(_, t) in &members[first..end] {
                region[t as usize] = r;
            }
        }
        first = end;
    }
    region
}

/// The faces of the classes of at least [`MIN_FACES`] faces that `joins` make (union-find over
/// the faces that take part), as `(class, face)` sorted: each class a run.
fn classes(joins: Vec<(u32, u32)>) -> Vec<(u32, u32)> {
    let mut ids: Vec<u32> = joins.iter().flat_map(|&(t, u)| [t, u]).collect();
    ids.sort_unstable();
    ids.dedup();
    let rank = |t: u32| ids.binary_search(&t).expect("a face of a join") as u32;
    let mut parent: Vec<u32> = (0..ids.len() as u32).collect();
    for &(t, u) in &joins {
        union(&mut parent, rank(t), rank(u));
    }
    drop(joins);
    let mut size = vec![0u32; ids.len()];
    for i in 0..ids.len() as u32 {
        let r = find(&mut parent, i);
        parent[i as usize] = r;
        size[r as usize] += 1;
    }
    let mut members: Vec<(u32, u32)> = (0..ids.len())
        .filter(|&i| size[parent[i] as usize] as usize >= MIN_FACES)
        .map(|i| (parent[i], ids[i]))
        .collect();
    members.sort_unstable();
    members
}

/// Whether `bits` (turn bits, [`super::patches::turn_bits`]) have a turn along one axis only.
#[inline]
fn one_axis(bits: u8) -> bool {
    // One bit per axis that has any turn.
    ((bits | bits >> 1) & 0b01_0101).is_power_of_two()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::built::cross2;
    use crate::topology::intersect::meet::{faces_meet, turns};
    use crate::topology::intersect::stars::flat_stars;
    use crate::topology::intersect::{intersect_table, Search};

    fn regions_of(points: &[Point], triangles: &[[u32; 3]]) -> Vec<u32> {
        let table = CornerTable::build(triangles, points.len());
        let stars = flat_stars(points, &table);
        flat_regions(points, &table, &stars.turns, &stars.along).face
    }

    /// An `n` x `n` grid of squares in the plane `z = h`, each cut into two faces, turning
    /// counter-clockwise seen from +z (or clockwise with `down`); vertex ids from `base`.
    fn grid(n: u32, h: f64, down: bool, base: u32) -> (Vec<Point>, Vec<[u32; 3]>) {
        let id = |i: u32, j: u32| base + i * (n + 1) + j;
        let points = (0..=n)
            .flat_map(|i| (0..=n).map(move |j| [f64::from(j), f64::from(i), h]))
            .collect();
        let mut triangles = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let (a, b, c, d) = (id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j));
                for t in [[a, b, c], [a, c, d]] {
                    triangles.push(if down { [t[0], t[2], t[1]] } else { t });
                }
            }
        }
        (points, triangles)
    }

    /// A flat grid is one flat region; its faces are all in it.
    #[test]
    fn a_flat_grid_is_one_region() {
        let (points, triangles) = grid(4, 0.0, false, 0);
        let regions = regions_of(&points, &triangles);
        assert_eq!(regions.len(), triangles.len());
        assert!(regions.iter().all(|&r| r != NONE && r == regions[0]));
    }

    /// Lifting one inner vertex by 1e-300 breaks the plane: none of its six faces is
    /// coplanar with a neighbour (each has two points in the plane and the lifted one off it),
    /// so none is in a region; the rest, a grid with a hexagonal hole, is still one flat region.
    #[test]
    fn a_vertex_off_the_plane_splits_the_region() {
        let (mut points, triangles) = grid(4, 0.0, false, 0);
        let lifted = 2 * 5 + 2;
        points[lifted][2] = 1e-300;
        let regions = regions_of(&points, &triangles);
        assert_eq!(regions.len(), triangles.len());
        let (around, away): (Vec<usize>, Vec<usize>) =
            (0..triangles.len()).partition(|&t| triangles[t].contains(&(lifted as u32)));
        assert_eq!(around.len(), 6);
        assert!(around.iter().all(|&t| regions[t] == NONE));
        assert!(away
            .iter()
            .all(|&t| regions[t] != NONE && regions[t] == regions[away[0]]));
    }

    /// Faces on one centre turning the same way around it, a spoke every quarter turn, each
    /// further out (spoke `i` at radius `i` along +x, +y, -x, -y, +x, ...): coplanar neighbours
    /// that agree on every edge, so one class. Three faces turn three quarters: a flat region.
    /// Four close the turn with spoke 5 along +x over spoke 1, so the fourth face's edge runs
    /// over the first's: they touch there, and the flat-patch test turns the class down; eight go
    /// round twice and overlap.
    #[test]
    fn faces_winding_twice_are_no_region() {
        let mut points: Vec<Point> = vec![[0.0; 3]];
        for i in 1..=9u32 {
            let r = f64::from(i);
            points.push(
                [[r, 0.0, 0.0], [0.0, r, 0.0], [-r, 0.0, 0.0], [0.0, -r, 0.0]]
                    [(i as usize - 1) % 4],
            );
        }
        let triangles: Vec<[u32; 3]> = (1..9).map(|i| [0, i, i + 1]).collect();
        let regions = regions_of(&points, &triangles[..3]);
        assert_eq!(regions.len(), 3);
        assert!(regions.iter().all(|&r| r != NONE && r == regions[0]));
        assert!(regions_of(&points, &triangles[..4]).is_empty());
        assert!(regions_of(&points, &triangles).is_empty());
    }

    /// A face folded back onto the grid across a border edge is coplanar and agrees with its
    /// neighbour on the edge's direction, but turns the other way: it is not joined, and the
    /// grid stays a flat region.
    #[test]
    fn a_face_folded_onto_the_plane_is_not_joined() {
        let (mut points, mut triangles) = grid(3, 0.0, false, 0);
        points.push([0.5, 0.25, 0.0]);
        triangles.push([1, 0, 16]);
        let regions = regions_of(&points, &triangles);
        let fold = triangles.len() - 1;
        assert_eq!(regions[fold], NONE);
        assert!(regions[..fold]
            .iter()
            .all(|&r| r != NONE && r == regions[0]));
    }

    /// Random plane meshes built to break the regions: a jittered grid in one axis plane
    /// (either diagonal, some faces missing or flipped, a few vertices lifted off the plane),
    /// T-junctions, unwelded copies of a vertex, random extra faces (folds, overlaps,
    /// non-manifold edges), a duplicate face, then turned onto a random axis, mirrored or not.
    /// No two faces of one flat region meet (exact `faces_meet` on every such pair), and the
    /// search finds exactly the pairs a test of every pair of faces finds. Checked to fail when
    /// the flat-patch test is taken out of `flat_regions`.
    #[test]
    fn random_plane_meshes_have_no_meeting_pair_in_a_region() {
        let mut bits = crate::geometry::xorshift(0x1234_5678_9abc_def1);
        let mut next = move |n: u64| bits() % n.max(1);
        let (mut with_regions, mut region_pairs) = (0, 0);
        for round in 0..1500 {
            let (points, triangles) = plane_mesh(&mut next);
            let table = CornerTable::build(&triangles, points.len());
            let stars = flat_stars(&points, &table);
            let regions = flat_regions(&points, &table, &stars.turns, &stars.along).face;
            let at = |t: usize| triangles[t].map(|v| points[v as usize]);
            let meet = |t: usize, u: usize| faces_meet(triangles[t], at(t), triangles[u], at(u));
            with_regions += usize::from(!regions.is_empty());
            for t in 0..regions.len() {
                for u in t + 1..regions.len() {
                    if regions[t] != NONE && regions[t] == regions[u] {
                        region_pairs += 1;
                        assert!(
                            !meet(t, u),
                            "round {round}: faces {t} and {u} in one region"
                        );
                    }
                }
            }
            let (every, found) = every_pair_and_search(&points, &triangles);
            assert_eq!(found, every, "round {round}");
        }
        assert!(
            with_regions > 300 && region_pairs > 5000,
            "{with_regions} meshes with regions, {region_pairs} pairs in regions"
        );
    }

    /// One mesh of [`random_plane_meshes_have_no_meeting_pair_in_a_region`].
    fn plane_mesh(next: &mut impl FnMut(u64) -> u64) -> (Vec<Point>, Vec<[u32; 3]>) {
        let n = 3 + next(3) as u32;
        let push = next(3);
        let mut points: Vec<Point> = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let mut jitter = || next(2 * push + 1) as f64 - push as f64;
                let (dx, dy) = (jitter(), jitter());
                let lifted = if next(40) == 0 { 1.0 } else { 0.0 };
                points.push([f64::from(j) * 4.0 + dx, f64::from(i) * 4.0 + dy, lifted]);
            }
        }
        let id = |i: u32, j: u32| i * (n + 1) + j;
        let mut triangles = Vec::new();
        let diagonal = next(2) == 0;
        for i in 0..n {
            for j in 0..n {
                let (a, b, c, d) = (id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j));
                let pair = if diagonal {
                    [[a, b, c], [a, c, d]]
                } else {
                    [[a, b, d], [b, c, d]]
                };
                for t in pair {
                    if next(12) != 0 {
                        triangles.push(if next(30) == 0 { [t[0], t[2], t[1]] } else { t });
                    }
                }
            }
        }
        // T-junctions: one face split at the midpoint of one of its edges.
        for _ in 0..next(3) {
            if triangles.is_empty() {
                break;
            }
            let f = next(triangles.len() as u64) as usize;
            let [a, b, c] = triangles[f];
            let (pa, pb) = (points[a as usize], points[b as usize]);
            let m = points.len() as u32;
            points.push(std::array::from_fn(|k| 0.5 * (pa[k] + pb[k])));
            triangles[f] = [a, m, c];
            triangles.push([m, b, c]);
        }
        // Unwelded copies of a vertex in some of its faces.
        for _ in 0..next(3) {
            let v = next(points.len() as u64) as u32;
            let copy = points.len() as u32;
            points.push(points[v as usize]);
            for t in triangles.iter_mut() {
                if t.contains(&v) && next(2) == 0 {
                    *t = t.map(|x| if x == v { copy } else { x });
                }
            }
        }
        // Extra faces on random vertices, and a duplicate face.
        for _ in 0..next(4) {
            let np = points.len() as u64;
            let t = [next(np) as u32, next(np) as u32, next(np) as u32];
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                triangles.push(t);
            }
        }
        if next(8) == 0 && !triangles.is_empty() {
            triangles.push(triangles[next(triangles.len() as u64) as usize]);
        }
        // Onto a random axis, mirrored or not.
        let (k, mirror) = (next(3), next(2) == 0);
        for p in &mut points {
            let [x, y, z] = *p;
            let x = if mirror { -x } else { x };
            *p = match k {
                0 => [z + 7.0, x, y],
                1 => [y, z - 3.0, x],
                _ => [x, y, z + 0.5],
            };
        }
        (points, triangles)
    }

    /// A plate's top with nine square holes (a 7 x 7 grid without the cells at odd rows and
    /// columns, apart from each other and from the outline): ten loops, more than the tree's
    /// patches allow, and one flat region.
    #[test]
    fn a_plate_with_nine_holes_is_one_region() {
        let (points, triangles) = grid(7, 0.0, false, 0);
        let hole = |t: usize| {
            let (i, j) = (t / 2 / 7, t / 2 % 7);
            i % 2 == 1 && j % 2 == 1
        };
        let kept: Vec<[u32; 3]> = (0..triangles.len())
            .filter(|&t| !hole(t))
            .map(|t| triangles[t])
            .collect();
        assert_eq!(kept.len(), 98 - 18);
        let regions = regions_of(&points, &kept);
        assert_eq!(regions.len(), kept.len());
        assert!(regions.iter().all(|&r| r != NONE && r == regions[0]));
    }

    /// Every pair of faces of `points` and `triangles` that meet, by the exact test of each pair,
    /// and the number the search finds; the faces the search leaves out (zero-area and collinear
    /// ones; here: no area at all) are left out.
    fn every_pair_and_search(points: &[Point], triangles: &[[u32; 3]]) -> (usize, usize) {
        let at = |t: usize| triangles[t].map(|v| points[v as usize]);
        let kept: Vec<usize> = (0..triangles.len())
            .filter(|&t| {
                let [a, b, c] = at(t);
                cross2(a, b, c) > 0.0 && turns(a, b, c) != [0.0; 3]
            })
            .collect();
        let meet = |t: usize, u: usize| faces_meet(triangles[t], at(t), triangles[u], at(u));
        let mut every = 0;
        for (i, &t) in kept.iter().enumerate() {
            every += kept[i + 1..].iter().filter(|&&u| meet(t, u)).count();
        }
        let table = CornerTable::build(triangles, points.len());
        let search = Search {
            kept_pairs: 0,
            first_only: false,
            ..Search::default()
        };
        let found = intersect_table(
            points,
            &table,
            &|_| 0,
            crate::topology::built::ZeroArea::at_most(0.0),
            None,
            &search,
        );
        (every, found.self_intersections)
    }

    /// A 2 x 2 plate in `z = 0` (one flat region) and walls on it, hand-placed: a wall on a
    /// border edge and one on a corner touch the plane only at the region's corners and edges and
    /// are apart from the region; walls touching it at a point of a face's inside, at a copy of an
    /// inner vertex (another id at its position), or along a diagonal through an inner vertex are
    /// not, and each of them meets the plate.
    #[test]
    fn walls_on_a_plate_are_apart_only_where_they_touch_its_corners_and_edges() {
        let (mut points, mut triangles) = grid(2, 0.0, false, 0);
        let plate = triangles.len();
        let mut wall = |corners: [Point; 3], on: &[(usize, u32)]| {
            let mut ids = [0; 3];
            for (k, p) in corners.iter().enumerate() {
                ids[k] = on.iter().find(|&&(j, _)| j == k).map_or_else(
                    || {
                        points.push(*p);
                        points.len() as u32 - 1
                    },
                    |&(_, v)| v,
                );
            }
            triangles.push(ids);
            triangles.len() - 1
        };
        let o = [0.0; 3];
        // On the border edge 0 -> 1 of face [0, 1, 4], traversed the other way.
        let edge = wall([o, o, [0.5, -0.5, 1.0]], &[(0, 1), (1, 0)]);
        // On corner 8, leaning out.
        let corner = wall([o, [2.5, 3.0, 1.0], [3.0, 2.5, 2.0]], &[(0, 8)]);
        // At (0.75, 0.25, 0), inside face [0, 1, 4], with a vertex of its own.
        let inside = wall(
            [[0.75, 0.25, 0.0], [0.75, 0.25, 1.0], [1.5, 0.25, 1.0]],
            &[],
        );
        // At a copy of inner vertex 4.
        let copy = wall([[1.0, 1.0, 0.0], [1.0, 1.5, 1.0], [1.5, 1.0, 1.0]], &[]);
        // Along the diagonal 0 - 8, which passes through vertex 4 and is no edge.
        let diagonal = wall([o, o, [1.0, 0.0, 1.0]], &[(0, 0), (1, 8)]);

        let copy_of_4 = triangles[copy][0];
        let table = CornerTable::build(&triangles, points.len());
        let stars = flat_stars(&points, &table);
        let regions = flat_regions(&points, &table, &stars.turns, &stars.along);
        let r = regions.of(0);
        assert_ne!(r, NONE);
        assert!((0..plate as u32).all(|t| regions.of(t) == r));
        // Inner vertex 4 is a corner of six faces of the region: it lists the region once.
        assert_eq!(regions.start[5] - regions.start[4], 1);
        assert!(regions.has_corner(r, 4) && !regions.has_corner(r, copy_of_4));
        let at = |t: usize| triangles[t].map(|v| points[v as usize]);
        let apart = |g: usize| regions.apart(&table, r, at(0), g as u32, triangles[g], at(g));
        let meets_plate =
            |g: usize| (0..plate).any(|t| faces_meet(triangles[t], at(t), triangles[g], at(g)));
        for g in [edge, corner] {
            assert!(apart(g), "wall {g}");
            assert!(!meets_plate(g), "wall {g}");
        }
        for g in [inside, copy, diagonal] {
            assert!(!apart(g), "wall {g}");
            assert!(meets_plate(g), "wall {g}");
        }
        let (every, found) = every_pair_and_search(&points, &triangles);
        assert_eq!(found, every);
    }

    /// Random plates (as [`random_plane_meshes_have_no_meeting_pair_in_a_region`] makes them)
    /// with random walls: on border edges, on vertices, crossing the plane, lying in it, touching
    /// it at points of their own or at copies of the plate's vertices. No face that
    /// [`Regions::apart`] says is apart from a region meets one of its faces, by the exact test
    /// of each pair, and the search finds what that test finds. Checked to fail when `apart` takes
    /// any single corner on the plane, or any edge of the wall on it, as the region's.
    #[test]
    fn random_walls_apart_from_a_region_meet_none_of_its_faces() {
        let mut bits = crate::geometry::xorshift(0x0dd5_ca1e_7a11_5eed);
        let mut next = move |n: u64| bits() % n.max(1);
        let (mut skipped, mut kinds) = (0, [0usize; 2]);
        for round in 0..600 {
            let (mut points, mut triangles) = plane_mesh(&mut next);
            let plate = triangles.len();
            // The plate's border edges, as their faces traverse them.
            let mut edges: Vec<(u32, u32)> = triangles
                .iter()
                .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
                .collect();
            edges.sort_unstable_by_key(|&(a, b)| (a.min(b), a.max(b)));
            let border: Vec<(u32, u32)> = edges
                .chunk_by(|x, y| (x.0.min(x.1), x.0.max(x.1)) == (y.0.min(y.1), y.0.max(y.1)))
                .filter(|run| run.len() == 1)
                .map(|run| run[0])
                .collect();
            let span = 4 * 6 + 8;
            for _ in 0..1 + next(8) {
                let point = |points: &mut Vec<Point>, z: f64, next: &mut dyn FnMut(u64) -> u64| {
                    let x = next(span) as f64 - 4.0;
                    let y = next(span) as f64 - 4.0;
                    points.push([x, y, z]);
                    points.len() as u32 - 1
                };
                let height = |next: &mut dyn FnMut(u64) -> u64| {
                    let h = 1.0 + next(4) as f64;
                    if next(2) == 0 {
                        h
                    } else {
                        -h
                    }
                };
                let wall = match next(6) {
                    // On a border edge, the other way round (sometimes lying in the plane).
                    0 | 1 if !border.is_empty() => {
                        let (a, b) = border[next(border.len() as u64) as usize];
                        let z = if next(8) == 0 { 0.0 } else { height(&mut next) };
                        [b, a, point(&mut points, z, &mut next)]
                    }
                    // On a vertex of the plate: the other two on one side, or across.
                    2 | 3 => {
                        let v = next(points.len() as u64) as u32;
                        let z = height(&mut next);
                        let w = if next(4) == 0 { -z } else { z };
                        [
                            v,
                            point(&mut points, z, &mut next),
                            point(&mut points, w, &mut next),
                        ]
                    }
                    // On a point of its own in the plane, or on a copy of a vertex.
                    4 => {
                        let v = if next(2) == 0 {
                            point(&mut points, 0.0, &mut next)
                        } else {
                            let copy = points[next(points.len() as u64) as usize];
                            points.push(copy);
                            points.len() as u32 - 1
                        };
                        let z = height(&mut next);
                        [
                            v,
                            point(&mut points, z, &mut next),
                            point(&mut points, z, &mut next),
                        ]
                    }
                    // Two vertices of the plate, joined or not by an edge.
                    _ => {
                        let n = points.len() as u64;
                        let (a, b) = (next(n) as u32, next(n) as u32);
                        let z = height(&mut next);
                        [a, b, point(&mut points, z, &mut next)]
                    }
                };
                if wall[0] != wall[1] && wall[1] != wall[2] && wall[0] != wall[2] {
                    triangles.push(wall);
                }
            }
            let table = CornerTable::build(&triangles, points.len());
            let stars = flat_stars(&points, &table);
            let regions = flat_regions(&points, &table, &stars.turns, &stars.along);
            if regions.is_empty() {
                continue;
            }
            let at = |t: usize| triangles[t].map(|v| points[v as usize]);
            for t in 0..plate {
                let r = regions.of(t as u32);
                if r == NONE {
                    continue;
                }
                for g in 0..triangles.len() {
                    if regions.of(g as u32) == r
                        || !regions.apart(&table, r, at(t), g as u32, triangles[g], at(g))
                    {
                        continue;
                    }
                    skipped += 1;
                    kinds[usize::from(g >= plate)] += 1;
                    assert!(
                        !faces_meet(triangles[t], at(t), triangles[g], at(g)),
                        "round {round}: face {g} is apart from region {r} but meets its face {t}"
                    );
                }
            }
            let (every, found) = every_pair_and_search(&points, &triangles);
            assert_eq!(found, every, "round {round}");
        }
        assert!(
            skipped > 5000 && kinds.iter().all(|&k| k > 500),
            "{skipped} pairs apart, {kinds:?} (plate faces, walls)"
        );
    }

    /// A mesh with no two coplanar neighbours has no regions (and allocates nothing per face).
    #[test]
    fn a_tetrahedron_has_no_regions() {
        let points = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let triangles = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        assert!(regions_of(&points, &triangles).is_empty());
    }
}
