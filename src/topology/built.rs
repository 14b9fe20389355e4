//! The one way from a mesh to its Corner Table, shared by the analysis, the places a picture marks
//! and the repair planner: weld the positions, leave out the faces that cannot be in a table (one
//! with an invalid vertex, or two corners on one welded vertex), order the rest by their lowest
//! vertex and build the table.
//!
//! The order matters for speed, not for any count: files usually number vertices in a spatially
//! coherent order even when their faces are shuffled, so walking faces by their lowest vertex keeps
//! neighbours close in memory (the walks are bound by cache misses, not arithmetic). It made the
//! analysis of a shuffled 1M-face torus several times faster.

use super::Options;
use crate::corner_table::CornerTable;
use crate::geometry::{dist2, norm2, normal};
use crate::mesh::Mesh;
use crate::weld::{weld, Welded, INVALID};

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

/// The largest [`cross2`] of a zero-area face in a mesh with this bounding box: a face's area is at
/// most 1e-12 x (bounding-box diagonal)^2, that is `|cross|^2 <= (2e-12 d^2)^2`.
pub(crate) fn zero_area_bound(bbox: Option<[[f64; 3]; 2]>) -> f64 {
    let diagonal2 = bbox.map_or(0.0, |[lo, hi]| dist2(lo, hi));
    (2e-12 * diagonal2).powi(2)
}

/// `|(b - a) x (c - a)|^2`: four times the squared area of triangle `a b c`.
pub(crate) fn cross2(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    norm2(normal(a, b, c))
}

/// The welded corners of an input face (`INVALID` for an index the weld does not know).
#[inline]
pub(crate) fn welded_face(map: &[u32], t: &[u32; 3]) -> [u32; 3] {
    t.map(|i| map.get(i as usize).copied().unwrap_or(INVALID))
}

/// Welds `mesh` and builds the table of the faces that can be in one.
pub fn build(mesh: &Mesh, options: &Options) -> (Built, LeftOut) {
    let welded = weld(&mesh.positions, options.weld_tolerance);
    let mut left = LeftOut::default();
    let mut referenced = vec![false; welded.positions.len()];
    let mut faces: Vec<[u32; 3]> = Vec::with_capacity(mesh.triangles.len());
    let mut source: Vec<u32> = Vec::with_capacity(mesh.triangles.len());
    for (index, t) in mesh.triangles.iter().enumerate() {
        let w = welded_face(&welded.map, t);
        for &x in w.iter().filter(|&&x| x != INVALID) {
            referenced[x as usize] = true;
        }
        match FaceKind::of(&w) {
            FaceKind::Invalid => left.invalid_faces += 1,
            FaceKind::Degenerate => left.degenerate_faces += 1,
            FaceKind::Table => {
                faces.push(w);
                source.push(index as u32);
            }
        }
    }
    left.unreferenced_vertices = referenced.iter().filter(|&&r| !r).count();
    drop(referenced);
    let (table, source) = table_of(faces, source, welded.positions.len());
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

/// The table of `faces` (welded, each of [`FaceKind::Table`]) over `vertex_count` vertices, faces
/// ordered by their lowest vertex; `source[i]` names face `i` for its caller and comes back in the
/// table's order.
pub(crate) fn table_of(
    faces: Vec<[u32; 3]>,
    source: Vec<u32>,
    vertex_count: usize,
) -> (CornerTable, Vec<u32>) {
    let order = vertex_order(&faces, vertex_count);
    let faces: Vec<[u32; 3]> = order.iter().map(|&i| faces[i as usize]).collect();
    let source: Vec<u32> = order.iter().map(|&i| source[i as usize]).collect();
    drop(order);
    (CornerTable::from_triangles(faces, vertex_count), source)
}

/// An order of the faces by their lowest vertex (a counting sort).
fn vertex_order(triangles: &[[u32; 3]], vertex_count: usize) -> Vec<u32> {
    let lowest = |t: &[u32; 3]| t[0].min(t[1]).min(t[2]) as usize;
    let mut start = vec![0u32; vertex_count + 1];
    for t in triangles {
        start[lowest(t) + 1] += 1;
    }
    for i in 0..vertex_count {
        start[i + 1] += start[i];
    }
    let mut order = vec![0u32; triangles.len()];
    for (i, t) in triangles.iter().enumerate() {
        let slot = &mut start[lowest(t)];
        order[*slot as usize] = i as u32;
        *slot += 1;
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Faces 0-1-2 (kept), 0-0-1 (degenerate), 3-1-2 with vertex 3 at NaN (invalid), and vertex 4
    /// used by nothing; vertex 5 sits at vertex 0's position and welds onto it, so face 5-2-1 is kept
    /// as 0-2-1. The table holds faces 0 and 3, by lowest vertex (both 0: input order).
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
        ];
        let mesh = Mesh::new(positions, vec![[0, 1, 2], [0, 0, 1], [3, 1, 2], [5, 2, 1]]);
        let (built, left) = build(&mesh, &Options::default());
        assert_eq!(
            left,
            LeftOut {
                invalid_faces: 1,
                degenerate_faces: 1,
                unreferenced_vertices: 1,
            }
        );
        assert_eq!(built.source, [0, 3]);
        assert_eq!(built.table.triangles(), [[0, 1, 2], [0, 2, 1]]);
        assert_eq!(FaceKind::of(&[1, 2, INVALID]), FaceKind::Invalid);
    }

    /// Faces whose lowest vertices are 2, 0, 1 come out in the order 0, 1, 2.
    #[test]
    fn faces_come_by_lowest_vertex() {
        let faces = vec![[2, 3, 4], [4, 0, 3], [3, 1, 2]];
        assert_eq!(vertex_order(&faces, 5), [1, 2, 0]);
    }
}
