//! Where a mesh's problems are, as geometry a picture can mark: border edges, non-manifold edges and
//! vertices, inconsistently wound edges, and the faces of inside-out shells, over the welded
//! vertices.
//!
//! [`analyse`](super::analyse) only counts; this pass reads the table the analysis built
//! ([`Built`], kept by scans that draw) and names the places. It is only run for reports that draw
//! meshes, so plain scans never pay for it. Its counts equal the analysis's (a test checks every
//! rule fixture):
//!
//! - a border edge is an edge with `O[c] == c`; a non-manifold edge one listed by
//!   [`CornerTable::nonmanifold_edges`]; an inconsistent edge a manifold edge whose two faces
//!   traverse it in the same direction (`O[c]` set, `c` not consistent with it);
//! - a non-manifold vertex has two or more **fans**: sets of its corners linked through manifold
//!   edges at the vertex (union-find over corners);
//! - components are faces linked through manifold and non-manifold edges, numbered in order of their
//!   lowest input face, exactly as [`Analysis::components`]; a face is inside-out when its component's
//!   shell is.

use super::sets::{find, union};
use super::{Analysis, Built};
use crate::corner_table::CornerTable;

/// The marked places of one mesh. Vertex indices refer to [`Places::points`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Places {
    /// Welded vertex positions.
    pub points: Vec<[f64; 3]>,
    /// The faces of the Corner Table (invalid and degenerate faces left out), as stored.
    pub triangles: Vec<[u32; 3]>,
    /// Per face of [`Places::triangles`]: it belongs to an inside-out shell.
    pub inside_out: Vec<bool>,
    /// Per face of [`Places::triangles`]: it meets another face (crosses or touches it where the
    /// mesh does not join them); all `false` when the analysis did not look.
    pub meets: Vec<bool>,
    /// Per face of [`Places::triangles`]: the index in [`Places::shells`] of the shell it belongs
    /// to, or [`NO_SHELL`] when its component is not a shell.
    pub shell: Vec<u32>,
    /// The nesting depth and bounding box of every shell, in [`Analysis::shells`] order.
    pub shells: Vec<(usize, [[f64; 3]; 2])>,
    /// Edges bounding one face, lower vertex first, sorted.
    pub border_edges: Vec<[u32; 2]>,
    /// Edges bounding three or more faces, lower vertex first, sorted.
    pub nonmanifold_edges: Vec<[u32; 2]>,
    /// Manifold edges whose two faces traverse them in the same direction (one of the two faces is
    /// flipped relative to the other), lower vertex first, sorted.
    pub inconsistent_edges: Vec<[u32; 2]>,
    /// Vertices with two or more fans, sorted.
    pub nonmanifold_vertices: Vec<u32>,
}

/// [`Places::shell`] of a face that is in no shell.
pub const NO_SHELL: u32 = u32::MAX;

/// Finds the problem places of a mesh from what its analysis built and found (`analysis` is read
/// for the inside-out shells).
pub fn places(built: &Built, analysis: &Analysis) -> Places {
    let table = &built.table;
    let edge = |c: u32| {
        let (a, b) = (table.v(CornerTable::n(c)), table.v(CornerTable::p(c)));
        [a.min(b), a.max(b)]
    };

    let corners = table.corner_count() as u32;
    let mut border_edges: Vec<[u32; 2]> = (0..corners)
        .filter(|&c| table.is_border(c))
        .map(edge)
        .collect();
    border_edges.sort_unstable();
    let mut nonmanifold_edges: Vec<[u32; 2]> =
        table.nonmanifold_edges().map(|cs| edge(cs[0])).collect();
    nonmanifold_edges.sort_unstable();
    let mut inconsistent_edges: Vec<[u32; 2]> = (0..corners)
        .filter(|&c| {
            table
                .opposite(c)
                .is_some_and(|o| c < o && !table.is_consistent(c))
        })
        .map(edge)
        .collect();
    inconsistent_edges.sort_unstable();

    // Fans: across each manifold edge, the corners at its two ends are in one fan.
    let mut fan: Vec<u32> = (0..corners).collect();
    let corner_at = |t: u32, vertex: u32| {
        (3 * t..3 * t + 3)
            .find(|&c| table.v(c) == vertex)
            .expect("a face across an edge has both its ends")
    };
    for c in 0..corners {
        if let Some(o) = table.opposite(c) {
            if c < o {
                for end in [CornerTable::n(c), CornerTable::p(c)] {
                    let across = corner_at(CornerTable::t(o), table.v(end));
                    union(&mut fan, end, across);
                }
            }
        }
    }
    let mut vertex_fans: Vec<(u32, u32)> = (0..corners)
        .map(|c| (table.v(c), find(&mut fan, c)))
        .collect();
    vertex_fans.sort_unstable();
    vertex_fans.dedup();
    let mut nonmanifold_vertices: Vec<u32> = vertex_fans
        .windows(2)
        .filter(|w| w[0].0 == w[1].0)
        .map(|w| w[0].0)
        .collect();
    nonmanifold_vertices.dedup();

    // Components: faces linked through manifold and non-manifold edges; numbered like the analysis's,
    // in order of their lowest input face.
    let faces = table.triangle_count();
    let mut component: Vec<u32> = (0..faces as u32).collect();
    for c in 0..corners {
        if let Some(o) = table.opposite(c) {
            union(&mut component, CornerTable::t(c), CornerTable::t(o));
        }
    }
    for cs in table.nonmanifold_edges() {
        for &c in &cs[1..] {
            union(&mut component, CornerTable::t(cs[0]), CornerTable::t(c));
        }
    }
    let mut lowest = vec![u32::MAX; faces];
    for t in 0..faces as u32 {
        let root = find(&mut component, t) as usize;
        lowest[root] = lowest[root].min(built.source[t as usize]);
    }
    let mut roots: Vec<u32> = (0..faces as u32)
        .filter(|&t| component[t as usize] == t)
        .collect();
    roots.sort_unstable_by_key(|&r| lowest[r as usize]);
    let mut number = vec![u32::MAX; faces];
    for (i, &r) in roots.iter().enumerate() {
        number[r as usize] = i as u32;
    }
    let next = roots.len();
    let mut shell_of_component = vec![NO_SHELL; next];
    for (i, s) in analysis.shells.iter().enumerate() {
        if let Some(slot) = shell_of_component.get_mut(s.component) {
            *slot = i as u32;
        }
    }
    let shell: Vec<u32> = (0..faces as u32)
        .map(|t| shell_of_component[number[find(&mut component, t) as usize] as usize])
        .collect();
    let inside_out = shell
        .iter()
        .map(|&s| s != NO_SHELL && analysis.shells[s as usize].inside_out)
        .collect();

    let meets = match &analysis.intersections {
        Some(i) => built.source.iter().map(|&s| i.involves(s)).collect(),
        None => vec![false; faces],
    };
    Places {
        points: built.welded.positions.clone(),
        meets,
        triangles: table.triangles().to_vec(),
        inside_out,
        shell,
        shells: analysis.shells.iter().map(|s| (s.depth, s.bbox)).collect(),
        border_edges,
        nonmanifold_edges,
        inconsistent_edges,
        nonmanifold_vertices,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;
    use crate::topology::{analyse_keeping, Options};

    fn check(mesh: &Mesh) -> Places {
        let (a, built) = analyse_keeping(mesh, &Options::default());
        let p = places(&built, &a);
        assert_eq!(p.border_edges.len(), a.border_edges);
        assert_eq!(p.nonmanifold_edges.len(), a.nonmanifold_edges);
        assert_eq!(p.nonmanifold_vertices.len(), a.nonmanifold_vertices);
        assert_eq!(p.inconsistent_edges.len(), a.inconsistent_edges);
        let inside_out_faces: usize = a
            .shells
            .iter()
            .filter(|s| s.inside_out)
            .map(|s| s.faces)
            .sum();
        assert_eq!(
            p.inside_out.iter().filter(|&&f| f).count(),
            inside_out_faces
        );
        p
    }

    /// A tetrahedron wound inward beside an outward one: the first shell's four faces are marked.
    #[test]
    fn inside_out_faces_follow_their_shell() {
        #[rustfmt::skip]
        let mut positions = vec![
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0],
        ];
        positions.extend(positions.clone().iter().map(|p| [p[0] + 5.0, p[1], p[2]]));
        let outward = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
        let mut triangles: Vec<[u32; 3]> = outward.iter().map(|t| [t[0], t[2], t[1]]).collect();
        triangles.extend(outward.iter().map(|t| t.map(|i| i + 4)));
        let p = check(&Mesh::new(positions, triangles));
        assert_eq!(
            p.inside_out,
            [true, true, true, true, false, false, false, false]
        );
    }

    /// A bowtie (two triangles touching at vertex 0) and three faces on edge 0-1.
    #[test]
    fn bowtie_and_fin_are_marked() {
        #[rustfmt::skip]
        let positions = vec![
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 0.0, 0.0],
            [-1.0, -1.0, 0.0],
        ];
        let bowtie = check(&Mesh::new(positions.clone(), vec![[0, 1, 2], [0, 3, 4]]));
        assert_eq!(bowtie.nonmanifold_vertices, [0]);
        assert_eq!(bowtie.border_edges.len(), 6);
        let fin = check(&Mesh::new(positions, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]));
        assert_eq!(fin.nonmanifold_edges, [[0, 1]]);
    }

    /// Two triangles over edge 1-2, both traversing it from 1 to 2 (`0 1 2` has 1->2, `1 2 3` has
    /// 1->2 too): the one manifold edge is inconsistent; the four outer edges are borders.
    #[test]
    fn a_flipped_neighbour_marks_the_shared_edge() {
        #[rustfmt::skip]
        let positions = vec![
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0],
        ];
        let p = check(&Mesh::new(positions, vec![[0, 1, 2], [1, 2, 3]]));
        assert_eq!(p.inconsistent_edges, [[1, 2]]);
        assert_eq!(p.border_edges.len(), 4);
    }

    /// Every rule fixture: the places agree with the analysis's counts.
    #[test]
    fn fixtures_agree_with_the_analysis() {
        use crate::formats::{self, ReadContext};
        use crate::walk::{walk, Filter};
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_assets");
        let mut meshes = 0;
        let mut inconsistent = 0;
        for source in walk(std::slice::from_ref(&root), &Filter::everything()) {
            let Some(format) = source.format else {
                continue;
            };
            let context = ReadContext {
                root: source.root.to_path_buf(),
                limits: Default::default(),
            };
            for mesh in formats::read(&source.path, format, &context).unwrap_or_default() {
                inconsistent += check(&mesh).inconsistent_edges.len();
                meshes += 1;
            }
        }
        assert!(meshes >= 20, "{meshes} meshes");
        assert!(
            inconsistent >= 3,
            "the inconsistent-winding fixture has three"
        );
    }
}
