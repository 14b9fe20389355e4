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
//! `O` is built in linear time: a counting sort of corners by the lower vertex of their opposite edge,
//! then a sort of each (small) bucket by the higher vertex. Runs of equal edges are the edges; their
//! lengths are the valences.

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
        assert!(
            triangles.len() <= MAX_TRIANGLES,
            "{} triangles exceed the corner table's limit of {MAX_TRIANGLES}",
            triangles.len()
        );
        assert!(
            vertex_count <= MAX_VERTICES,
            "{vertex_count} vertices exceed the corner table's limit of {MAX_VERTICES}"
        );
        let corners = 3 * triangles.len();

        // Counting sort of corners by the lower vertex of their opposite edge.
        let mut start = vec![0u32; vertex_count + 1];
        for t in &triangles {
            for k in 0..3 {
                let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
                start[a.min(b) as usize + 1] += 1;
            }
        }
        for i in 0..vertex_count {
            start[i + 1] += start[i];
        }
        // Each slot holds `higher vertex << 33 | rising << 32 | corner`: sorting a bucket groups the
        // corners by edge; `rising` says the corner's face runs the edge from its lower vertex up.
        let mut keys = vec![0u64; corners];
        let mut fill = start.clone();
        for (i, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
                let slot = &mut fill[a.min(b) as usize];
                let rising = u64::from(a < b) << 32;
                keys[*slot as usize] = (u64::from(a.max(b)) << 33) | rising | (3 * i + k) as u64;
                *slot += 1;
            }
        }
        drop(fill);

        let mut o = vec![0u32; corners];
        let mut same_direction = vec![0u64; corners.div_ceil(64)];
        let mut edge_count = 0;
        let mut border_count = 0;
        let mut nm_corners = Vec::new();
        let mut nm_offsets = vec![0u32];
        for w in start.windows(2) {
            let bucket = &mut keys[w[0] as usize..w[1] as usize];
            if bucket.len() > 1 {
                bucket.sort_unstable();
            }
            let mut i = 0;
            while i < bucket.len() {
                let hi = bucket[i] >> 33;
                let mut j = i + 1;
                while j < bucket.len() && bucket[j] >> 33 == hi {
                    j += 1;
                }
                let corner = |k: usize| bucket[k] as u32;
                match j - i {
                    1 => {
                        o[corner(i) as usize] = corner(i);
                        border_count += 1;
                    }
                    2 => {
                        let (a, b) = (corner(i), corner(i + 1));
                        o[a as usize] = b;
                        o[b as usize] = a;
                        if (bucket[i] ^ bucket[i + 1]) & (1 << 32) == 0 {
                            for c in [a, b] {
                                same_direction[c as usize / 64] |= 1 << (c % 64);
                            }
                        }
                    }
                    _ => {
                        for k in i..j {
                            o[corner(k) as usize] = NON_MANIFOLD;
                            nm_corners.push(corner(k));
                        }
                        let first = nm_corners.len() - (j - i);
                        nm_corners[first..].sort_unstable();
                        nm_offsets.push(nm_corners.len() as u32);
                    }
                }
                edge_count += 1;
                i = j;
            }
        }
        CornerTable {
            v: triangles,
            o,
            same_direction,
            vertex_count,
            edge_count,
            border_count,
            nm_corners,
            nm_offsets,
        }
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

#[cfg(test)]
mod tests {
    use super::*;

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
