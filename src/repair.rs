//! Repair ([definitions](crate::definitions#repairs)): changes a mesh's triangles so the defects that can be fixed are gone, and says
//! exactly where every corner of the result comes from, so a format writer can keep the asset's UVs,
//! normals, colours, materials and groups. Writes nothing.
//!
//! The result is a [`Plan`] in the input's own numbering: final triangles over input vertices (plus
//! copies of input vertices made to split non-manifold vertices), each corner naming the input corner
//! whose per-corner attributes it carries. Repairs run in this order:
//!
//! 1. drop faces with invalid vertices, degenerate faces, and duplicate faces (the first copy stays);
//! 2. split non-manifold edges (each keeps the two faces that agree best in orientation) and vertices
//!    (one copy per extra fan, nudged a hair into its fan so welding does not merge it back);
//! 3. orient every orientable component consistently, flipping the fewer faces;
//! 4. fill holes of at most `max_hole_edges` edges (ear clipping in the loop's best-fit plane, a fan
//!    only for a loop convex in that plane; a loop that crosses itself in that plane, one where
//!    ear clipping finds no ear, and a concave one over 1,024 edges are left open, as is one
//!    through a corner of a face with an invalid vertex that step 1 kept),
//!    new faces wound like their neighbours, their corners carrying the attributes of the border
//!    corners (the writers give a corner the fill's own normal where the border corner's is more
//!    than 60 degrees from it: [`crate::formats::write`]);
//! 5. flip closed shells whose volume sign is wrong for their nesting depth (after the fills, so a
//!    shell a fill closed is judged too; the `repairs` column still lists it before the fills, in the
//!    documented order);
//! 6. drop unreferenced vertices (the writer renumbers; [`Plan::used_vertices`] says which stay).

use std::rc::Rc;

use robust::orient2d;
use rustc_hash::{FxHashMap, FxHashSet};

use crate::corner_table::{CornerTable, NON_MANIFOLD};
use crate::geometry::bounding_box;
use crate::geometry::exact::segments_touch;
use crate::geometry::near::Near;
use crate::geometry::polygon::{newell, project, triangulate, Split};
use crate::mesh::Mesh;
use crate::topology::analyse::is_flat;
use crate::topology::built::{table_of, welded_face, FaceKind, ZeroArea};
use crate::topology::intersect::{intersect_table, Search};
use crate::topology::nesting::{depths, ShellGeometry};
use crate::topology::sets::{find, union};
use crate::topology::Built;
use crate::weld::{weld, INVALID};

/// Which repairs run.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Faces with a NaN or infinite vertex (no config key of its own: `drop_degenerate_faces`
    /// switches both, and each runs only while its rule is on, [`crate::config::Settings`]).
    pub drop_invalid_faces: bool,
    pub drop_degenerate_faces: bool,
    pub drop_duplicate_faces: bool,
    pub split_nonmanifold: bool,
    pub orient_faces: bool,
    pub flip_inside_out: bool,
    pub fill_holes: bool,
    /// Holes with more border edges than this are left open and reported.
    pub max_hole_edges: usize,
    pub drop_unreferenced_vertices: bool,
    /// The weld tolerance of the analysis (copies of split vertices move further than this).
    pub weld_tolerance: f64,
    /// The copy stores positions as 32-bit floats (STL, glTF; each format says so in its entry of
    /// the format table): a split vertex's copy then moves beyond that rounding at the model's
    /// largest coordinate, however far that is beyond the model's size.
    pub single_precision: bool,
}

impl Default for Options {
    fn default() -> Options {
        Options {
            drop_invalid_faces: true,
            drop_degenerate_faces: true,
            drop_duplicate_faces: true,
            split_nonmanifold: true,
            orient_faces: true,
            flip_inside_out: true,
            fill_holes: true,
            max_hole_edges: 100,
            drop_unreferenced_vertices: true,
            weld_tolerance: 0.0,
            single_precision: false,
        }
    }
}

/// One kind of repair, with the stable name used in the report's `repairs` column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    DropInvalidFaces,
    DropDegenerateFaces,
    DropDuplicateFaces,
    SplitNonManifoldEdges,
    SplitNonManifoldVertices,
    OrientFaces,
    FlipInsideOutShells,
    FillHoles,
    DropUnreferencedVertices,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::DropInvalidFaces => "drop-invalid-faces",
            Kind::DropDegenerateFaces => "drop-degenerate-faces",
            Kind::DropDuplicateFaces => "drop-duplicate-faces",
            Kind::SplitNonManifoldEdges => "split-non-manifold-edges",
            Kind::SplitNonManifoldVertices => "split-non-manifold-vertices",
            Kind::OrientFaces => "orient-faces",
            Kind::FlipInsideOutShells => "flip-inside-out-shells",
            Kind::FillHoles => "fill-holes",
            Kind::DropUnreferencedVertices => "drop-unreferenced-vertices",
        }
    }
}

/// A corner of a final triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Corner {
    /// Input vertex (`< mesh.positions.len()`) or new vertex (`positions.len() + i` for
    /// `Plan::new_vertices[i]`).
    pub vertex: u32,
    /// The input corner (`3 * triangle + k`) whose per-corner attributes (OBJ `vt`/`vn`) this corner
    /// carries. For a kept face it is the face's own corner; for a hole-filling face, the corner of a
    /// bordering face at the same vertex.
    pub from: u32,
}

/// A vertex the repair added: a copy of an input vertex (all its attributes) at a new position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewVertex {
    pub copy_of: u32,
    pub position: [f64; 3],
}

/// A final triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Triangle {
    pub corners: [Corner; 3],
    /// The input triangle it comes from, `None` for a hole-filling face (then `near` is the input
    /// triangle across its first border edge: its material, group and primitive are the ones to use).
    pub source: Option<u32>,
    /// An input triangle whose material/group/primitive this triangle takes (its source, or a
    /// neighbour for a fill).
    pub near: u32,
    /// Wound against its source (its stored normals must be negated).
    pub flipped: bool,
}

/// What the repair did, in input numbering.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Plan {
    /// The final triangles. Kept faces stay in input order; fills come last.
    pub triangles: Vec<Triangle>,
    pub new_vertices: Vec<NewVertex>,
    /// Whether each vertex (input, then new) is kept in the output. All `true` unless unreferenced
    /// vertices are dropped.
    pub used_vertices: Vec<bool>,
    /// Repairs done, with counts (zero counts left out), in the documented order ([`Kind`]), and
    /// the faces they added or turned where that is more than the count says (holes filled,
    /// shells flipped).
    pub done: Vec<(Kind, usize, Option<usize>)>,
    /// Defects left in place, in words (non-orientable components, holes over the limit).
    pub not_repairable: Vec<String>,
}

impl Plan {
    /// Whether the plan changes anything.
    pub fn changes(&self) -> bool {
        !self.done.is_empty()
    }

    /// The `repairs` cell: `drop-degenerate-faces:2;orient-faces:14;fill-holes:1(6 faces)`.
    pub fn summary(&self) -> String {
        let parts: Vec<String> = self
            .done
            .iter()
            .map(|(kind, n, faces)| match faces {
                Some(f) => format!("{}:{n}({f} faces)", kind.name()),
                None => format!("{}:{n}", kind.name()),
            })
            .collect();
        parts.join(";")
    }

    /// The repaired mesh's positions and triangles (unused vertices removed when the plan drops them),
    /// for analysing the result without writing it.
    pub fn apply(&self, mesh: &Mesh) -> Mesh {
        let mut index = vec![u32::MAX; self.used_vertices.len()];
        let mut positions = Vec::new();
        for (i, &used) in self.used_vertices.iter().enumerate() {
            if used {
                index[i] = positions.len() as u32;
                positions.push(self.position(mesh, i as u32));
            }
        }
        let triangles = self
            .triangles
            .iter()
            .map(|t| t.corners.map(|c| index[c.vertex as usize]))
            .collect();
        Mesh {
            name: mesh.name.clone(),
            positions,
            triangles,
            ..Mesh::default()
        }
    }

    /// The position of an input or new vertex.
    pub fn position(&self, mesh: &Mesh, vertex: u32) -> [f64; 3] {
        let n = mesh.positions.len();
        match (vertex as usize).checked_sub(n) {
            Some(i) => self.new_vertices[i].position,
            None => mesh.positions[vertex as usize],
        }
    }
}

/// Plans the repair of one mesh.
pub fn plan(mesh: &Mesh, options: &Options) -> Plan {
    plan_with(mesh, options, None)
}

/// [`plan`], starting from the weld and Corner Table the scan's analysis of `mesh` built (when
/// given and built with this weld tolerance) instead of building them again.
pub fn plan_with(mesh: &Mesh, options: &Options, built: Option<Built>) -> Plan {
    let mut work = Work::new(mesh, options, built);
    let mut done: Vec<(Kind, usize, Option<usize>)> = Vec::new();
    let mut not_repairable = Vec::new();

    let [invalid, degenerate, duplicate] = work.drop_faces(options);
    done.push((Kind::DropInvalidFaces, invalid, None));
    done.push((Kind::DropDegenerateFaces, degenerate, None));
    done.push((Kind::DropDuplicateFaces, duplicate, None));

    if options.split_nonmanifold {
        let (edges, vertices) = work.split_nonmanifold(options);
        done.push((Kind::SplitNonManifoldEdges, edges, None));
        done.push((Kind::SplitNonManifoldVertices, vertices, None));
        // What is left: a fan too small to move a copy of its vertex clear of the vertex, its
        // other copies and the fan's corners.
        let why = if options.weld_tolerance > 0.0 {
            "the copy would weld back; lower weld_tolerance"
        } else {
            "the copy would land on another vertex"
        };
        let n = work.edges_left;
        if n > 0 {
            not_repairable.push(format!(
                "{n} non-manifold edge{} left as {}: a face on {} could not be cut loose, as a \
                 copy of its vertices could not move clear of them ({why})",
                plural(n),
                if n == 1 { "it is" } else { "they are" },
                if n == 1 { "it" } else { "each" }
            ));
        }
        let n = work.unsplittable.len();
        if n > 0 {
            not_repairable.push(format!(
                "{n} non-manifold vert{} left as {}: a fan around {} is too small to move a \
                 copy of the vertex clear of it ({why})",
                if n == 1 { "ex" } else { "ices" },
                if n == 1 { "it is" } else { "they are" },
                if n == 1 { "it" } else { "each" }
            ));
        }
    }
    if options.orient_faces || options.flip_inside_out {
        let (flipped, non_orientable) = work.orient(options.orient_faces);
        done.push((Kind::OrientFaces, flipped, None));
        if non_orientable > 0 {
            not_repairable.push(format!(
                "{non_orientable} non-orientable component{} left as is",
                plural(non_orientable)
            ));
        }
    }
    if options.fill_holes {
        let fill = work.fill_holes(options.max_hole_edges);
        done.push((Kind::FillHoles, fill.holes, Some(fill.faces)));
        if fill.too_large > 0 {
            not_repairable.push(format!(
                "{} hole{} over {} edges left open",
                fill.too_large,
                plural(fill.too_large),
                options.max_hole_edges
            ));
        }
        let n = fill.invalid;
        if n > 0 {
            not_repairable.push(format!(
                "{n} hole{} left open: faces with a NaN or infinite vertex close {} in the file \
                 (kept, as invalid-vertex is off)",
                plural(n),
                if n == 1 { "it" } else { "them" }
            ));
        }
        for (n, why) in [
            (fill.blocked, "would overlap existing edges"),
            (
                fill.flat,
                "would close a flat open surface into a shell with no volume",
            ),
            (fill.crossing, "would cross the rest of the surface"),
            (
                fill.unchecked,
                "the faces near it are too many to check that the fill would not cross them",
            ),
        ] {
            if n > 0 {
                not_repairable.push(format!("{n} hole{} left open: filling {why}", plural(n)));
            }
        }
        if fill.no_triangulation > 0 {
            not_repairable.push(format!(
                "{} hole{} left open: {} border crosses or folds onto itself, so a fill could overlap itself",
                fill.no_triangulation,
                plural(fill.no_triangulation),
                if fill.no_triangulation == 1 { "its" } else { "their" }
            ));
        }
    }
    // Flipping whole shells commutes with filling other components' holes, so one pass at the end
    // sees every shell, including those the fills closed and those whose depth a fill changed.
    if options.flip_inside_out {
        let (shells, faces) = work.flip_inside_out();
        done.push((Kind::FlipInsideOutShells, shells, Some(faces)));
    }

    let mut used_vertices = vec![!options.drop_unreferenced_vertices; work.vertex_count()];
    for t in &work.triangles {
        for c in &t.corners {
            used_vertices[c.vertex as usize] = true;
        }
    }
    // Counted by position: an input vertex whose welded vertex is still used (an STL facet corner
    // replaced by a split copy, a glTF seam twin) was not an unreferenced vertex of the mesh.
    let mut position_used = vec![false; work.points.len()];
    for t in &work.triangles {
        for c in &t.corners {
            if let Some(&w) = work
                .welded
                .get(c.vertex as usize)
                .filter(|&&w| w != INVALID)
            {
                position_used[w as usize] = true;
            }
        }
    }
    let unused = (0..used_vertices.len())
        .filter(|&v| !used_vertices[v])
        .filter(|&v| {
            work.welded
                .get(v)
                .is_none_or(|&w| w == INVALID || !position_used[w as usize])
        })
        .count();
    done.push((Kind::DropUnreferencedVertices, unused, None));

    // The documented order, repairs that did nothing left out.
    done.retain(|(_, n, _)| *n > 0);
    done.sort_by_key(|(kind, ..)| *kind);
    Plan {
        triangles: work.triangles,
        new_vertices: work.new_vertices,
        used_vertices,
        done,
        not_repairable,
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// The mesh being repaired: triangles over input and new vertices, and the welded vertex of each.
struct Work<'a> {
    mesh: &'a Mesh,
    triangles: Vec<Triangle>,
    new_vertices: Vec<NewVertex>,
    /// Welded vertex of every input and new vertex (`INVALID` for NaN/infinite ones).
    welded: Vec<u32>,
    /// Positions of the welded vertices.
    points: Vec<[f64; 3]>,
    /// The Corner Table of the current triangles (those that can be in one) and their indices in
    /// `triangles`; `None` once faces or vertices change. `wound` says whether its windings are
    /// still the current ones (flipping faces keeps the adjacency but not the windings).
    table: Option<Rc<(CornerTable, Vec<u32>)>>,
    wound: bool,
    /// The table is the analysis's and the analysis found no non-manifold edge or vertex (so
    /// there is nothing to split); cleared when faces change.
    manifold: bool,
    /// The weld tolerance: a vertex copy must end at least this far from its vertex and from the
    /// vertex's other copies (at tolerance 0: anywhere else), or the copy read back welds onto it.
    tolerance: f64,
    /// The positions of the copies made of each welded vertex so far.
    copies_of: FxHashMap<u32, Vec<[f64; 3]>>,
    /// Welded vertices with a fan that could not be given a copy far enough away to stay apart.
    unsplittable: FxHashSet<u32>,
    /// Non-manifold edges left after splitting (a face on them could not be cut loose).
    edges_left: usize,
    /// How far the search for fills that cross the surface goes (the analysis's default).
    fill_search: Search,
}

impl<'a> Work<'a> {
    fn new(mesh: &'a Mesh, options: &Options, built: Option<Built>) -> Work<'a> {
        // The analysis's table is the one `build_table` would build now: the same faces (valid,
        // not degenerate), in the same order, indexed by input face as `triangles` is here.
        let built = built.filter(|b| {
            b.tolerance == options.weld_tolerance
                && b.welded.map.len() == mesh.positions.len()
                && b.source.len() == b.table.triangle_count()
        });
        let (w, table, manifold) = match built {
            Some(b) => (b.welded, Some(Rc::new((b.table, b.source))), b.manifold),
            None => (weld(&mesh.positions, options.weld_tolerance), None, false),
        };
        let triangles = mesh
            .triangles
            .iter()
            .enumerate()
            .map(|(i, t)| Triangle {
                corners: [0, 1, 2].map(|k| Corner {
                    vertex: t[k],
                    from: 3 * i as u32 + k as u32,
                }),
                source: Some(i as u32),
                near: i as u32,
                flipped: false,
            })
            .collect();
        Work {
            mesh,
            triangles,
            new_vertices: Vec::new(),
            welded: w.map,
            points: w.positions,
            wound: table.is_some(),
            table,
            manifold,
            tolerance: options.weld_tolerance,
            copies_of: FxHashMap::default(),
            unsplittable: FxHashSet::default(),
            edges_left: 0,
            fill_search: Search::default(),
        }
    }

    /// The current table, rebuilt when faces changed, or (with `windings`) when faces were flipped.
    fn current(&mut self, windings: bool) -> Rc<(CornerTable, Vec<u32>)> {
        match &self.table {
            Some(t) if self.wound || !windings => t.clone(),
            _ => {
                let t = Rc::new(self.build_table());
                self.table = Some(t.clone());
                self.wound = true;
                t
            }
        }
    }

    /// Forgets the table after faces or vertices changed.
    fn changed(&mut self) {
        self.table = None;
        self.manifold = false;
    }

    fn vertex_count(&self) -> usize {
        self.mesh.positions.len() + self.new_vertices.len()
    }

    fn welded_of(&self, t: &Triangle) -> [u32; 3] {
        welded_face(&self.welded, &t.corners.map(|c| c.vertex))
    }

    /// Drops faces with invalid vertices, degenerate faces and later copies of duplicate faces (as
    /// the options allow): counts `[invalid, degenerate, duplicate]`.
    fn drop_faces(&mut self, options: &Options) -> [usize; 3] {
        let mut counts = [0; 3];
        let welded = &self.welded;
        self.triangles.retain(|t| {
            let (kind, drop) =
                match FaceKind::of(&welded_face(welded, &t.corners.map(|c| c.vertex))) {
                    FaceKind::Invalid => (0, options.drop_invalid_faces),
                    FaceKind::Degenerate => (1, options.drop_degenerate_faces),
                    FaceKind::Table => return true,
                };
            counts[kind] += usize::from(drop);
            !drop
        });
        if counts.iter().any(|&n| n > 0) {
            // Table indices are positions in `triangles`: they moved.
            self.changed();
        }
        if options.drop_duplicate_faces {
            counts[2] = self.drop_duplicates();
        }
        if counts.iter().any(|&n| n > 0) {
            self.changed();
        }
        counts
    }

    /// Drops every copy of a face but the first. Copies of `{x < y < z}` all bound the edge `y-z`
    /// with `x` opposite (as in the analysis), so the table finds them without hashing every face.
    fn drop_duplicates(&mut self) -> usize {
        let shared = self.current(false);
        let (table, index) = (&shared.0, &shared.1);
        let edge_min = |c: u32| table.v(CornerTable::n(c)).min(table.v(CornerTable::p(c)));
        let mut copies: Vec<u32> = Vec::new();
        for c in 0..table.corner_count() as u32 {
            if let Some(b) = table.opposite(c) {
                if c < b && table.v(c) == table.v(b) && table.v(c) < edge_min(c) {
                    copies.push(CornerTable::t(b));
                }
            }
        }
        let mut apex: Vec<(u32, u32)> = Vec::new();
        for corners in table.nonmanifold_edges() {
            let low = edge_min(corners[0]);
            apex.clear();
            apex.extend(
                corners
                    .iter()
                    .filter(|&&c| table.v(c) < low)
                    .map(|&c| (table.v(c), CornerTable::t(c))),
            );
            apex.sort_unstable();
            copies.extend(apex.windows(2).filter(|w| w[0].0 == w[1].0).map(|w| w[1].1));
        }
        if copies.is_empty() {
            return 0;
        }
        let mut drop = vec![false; self.triangles.len()];
        for &t in &copies {
            drop[index[t as usize] as usize] = true;
        }
        let mut i = 0;
        self.triangles.retain(|_| {
            i += 1;
            !drop[i - 1]
        });
        self.changed();
        copies.len()
    }

    /// The table of the triangles that can be in one, and their indices in `self.triangles`.
    /// The faces go in by their lowest vertex, so walks stay in cache (as in the analysis).
    fn build_table(&self) -> (CornerTable, Vec<u32>) {
        let mut tris = Vec::with_capacity(self.triangles.len());
        let mut index = Vec::with_capacity(self.triangles.len());
        for (i, t) in self.triangles.iter().enumerate() {
            let w = self.welded_of(t);
            if FaceKind::of(&w) == FaceKind::Table {
                tris.push(w);
                index.push(i as u32);
            }
        }
        table_of(tris, index, self.points.len())
    }

    /// Splits non-manifold edges and vertices: each non-manifold edge keeps the two faces that
    /// traverse it in opposite directions (or its first two) and the others are cut loose; then every
    /// vertex whose faces form several fans gets a copy per extra fan. Repeats while cutting exposes
    /// more (at most a few rounds). Returns `(edges, vertices)` split: the mesh's non-manifold
    /// edges that are manifold now, and its vertices that got at least one copy (each counted once,
    /// however many copies it got and in however many rounds). The non-manifold edges left (a face
    /// that could not be cut loose, [`Work::detach_fan`]) are in `edges_left`.
    fn split_nonmanifold(&mut self, options: &Options) -> (usize, usize) {
        if self.manifold && self.table.is_some() {
            return (0, 0);
        }
        let mut edges = None;
        let mut clean = false;
        let nudge = self.nudge_distance(options.weld_tolerance, options.single_precision);
        let mut last = usize::MAX;
        for _round in 0..8 {
            let shared = self.current(false);
            let (table, index) = (&shared.0, &shared.1);
            let mut opposite = table.opposites().to_vec();
            let cut = table.nonmanifold_edges().len();
            edges.get_or_insert(cut);
            if cut > 0 && cut >= last {
                // No progress: a cut face still shares a fan with the kept pair at both ends (the
                // surface wraps onto itself). Detach such faces whole.
                self.detach_cut_faces(table, index, nudge);
                last = usize::MAX;
                continue;
            }
            last = cut;
            for corners in table.nonmanifold_edges() {
                let pair = keep_pair(table, corners);
                for &c in corners {
                    opposite[c as usize] = c;
                }
                opposite[pair.0 as usize] = pair.1;
                opposite[pair.1 as usize] = pair.0;
            }
            let split = self.split_fans(table, index, &opposite, nudge);
            if cut == 0 && split == 0 {
                clean = true;
                break;
            }
        }
        self.edges_left = if clean {
            0
        } else {
            self.current(false).0.nonmanifold_edges().len()
        };
        let mut split: Vec<u32> = self.new_vertices.iter().map(|v| v.copy_of).collect();
        // By welded vertex: an STL facet's three corners at one point are one vertex of the mesh.
        for v in &mut split {
            *v = self.welded.get(*v as usize).copied().unwrap_or(*v);
        }
        split.sort_unstable();
        split.dedup();
        (
            edges.unwrap_or(0).saturating_sub(self.edges_left),
            split.len(),
        )
    }

    /// Gives every face on a non-manifold edge, but the pair kept there, its own three vertices
    /// (where another corner still uses the vertex: a corner left alone keeps it).
    fn detach_cut_faces(&mut self, table: &CornerTable, index: &[u32], nudge: f64) {
        let mut faces: Vec<u32> = Vec::new();
        for corners in table.nonmanifold_edges() {
            let pair = keep_pair(table, corners);
            faces.extend(
                corners
                    .iter()
                    .filter(|&&c| c != pair.0 && c != pair.1)
                    .map(|&c| CornerTable::t(c)),
            );
        }
        faces.sort_unstable();
        faces.dedup();
        // Corners still on each welded vertex: a corner that is the last one left on its vertex
        // is alone there already, so it keeps the vertex (a copy would split nothing).
        let mut left = vec![0u32; table.vertex_count()];
        for c in 0..table.corner_count() as u32 {
            left[table.v(c) as usize] += 1;
        }
        for &t in &faces {
            for c in 3 * t..3 * t + 3 {
                let v = table.v(c) as usize;
                if left[v] > 1 && self.detach_fan(table, index, &[c], nudge, &[]) {
                    left[v] -= 1;
                }
            }
        }
    }

    /// How far a vertex copy moves into its fan: 1e-5 of the model's size plus 1e-5 of its
    /// largest coordinate, beyond the weld tolerance. The coordinate counts in full only for a
    /// copy stored as 32-bit floats (`single`), whose rounding there the move must clear; for text
    /// and doubles at most as much as the size, or a model far from the origin would have its
    /// copies moved up to a quarter of the way into their fans, out of shape.
    fn nudge_distance(&self, tolerance: f64, single: bool) -> f64 {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let diagonal = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
        let magnitude = (0..3)
            .map(|k| lo[k].abs().max(hi[k].abs()))
            .fold(0.0, f64::max);
        let magnitude = if single {
            magnitude
        } else {
            magnitude.min(diagonal)
        };
        (3.0 * tolerance)
            .max(1e-5 * (diagonal + magnitude))
            .max(f64::MIN_POSITIVE)
    }

    /// Walks the fans of every vertex over `opposite` (the table's `O` with cut edges as borders);
    /// the corners of every fan after a vertex's first get new vertices. Returns the number of new
    /// welded vertices.
    fn split_fans(
        &mut self,
        table: &CornerTable,
        index: &[u32],
        opposite: &[u32],
        nudge: f64,
    ) -> usize {
        let nc = table.corner_count();
        let mut visited = vec![false; nc];
        let mut fans_at = vec![0u32; table.vertex_count()];
        // The corners of every fan, by range: each vertex's first (the one that keeps the vertex)
        // and the later ones, given copies once every fan is known.
        let mut firsts: Vec<u32> = Vec::new();
        let mut later: Vec<(u32, u32, u32)> = Vec::new();
        let mut first_of = vec![(0u32, 0u32); table.vertex_count()];
        let mut swapped = vec![false; table.vertex_count()];
        let mut split = 0;
        let mut fan = Vec::new();
        for start in 0..nc as u32 {
            if visited[start as usize] {
                continue;
            }
            let v = table.v(start);
            fan.clear();
            fan.push(start);
            visited[start as usize] = true;
            for first_exit in [CornerTable::p(start), CornerTable::n(start)] {
                let mut exit = first_exit;
                loop {
                    let o = opposite[exit as usize];
                    if o == exit || o == NON_MANIFOLD {
                        break;
                    }
                    let (d, next) = if table.v(CornerTable::n(o)) == v {
                        (CornerTable::n(o), CornerTable::p(o))
                    } else {
                        (CornerTable::p(o), CornerTable::n(o))
                    };
                    if visited[d as usize] {
                        break;
                    }
                    visited[d as usize] = true;
                    fan.push(d);
                    exit = next;
                }
                // After a closed fan the other way stops at once: its first step is visited.
            }
            let vi = v as usize;
            fans_at[vi] += 1;
            let (from, to) = (firsts.len() as u32, (firsts.len() + fan.len()) as u32);
            firsts.extend_from_slice(&fan);
            if fans_at[vi] == 1 {
                first_of[vi] = (from, to);
            } else {
                later.push((v, from, to));
            }
        }
        if later.is_empty() {
            return 0;
        }
        // Where the corners of every fan of each vertex to split lie: a copy must stay clear of
        // them all, or the copy read back welds onto one (the fan that keeps the vertex is often
        // small, its corners near the vertex).
        let mut around: FxHashMap<u32, Vec<[f64; 3]>> = FxHashMap::default();
        for &(v, ..) in &later {
            around.entry(v).or_default();
        }
        for c in 0..nc as u32 {
            if let Some(ring) = around.get_mut(&table.v(c)) {
                for k in [CornerTable::n(c), CornerTable::p(c)] {
                    ring.push(self.points[table.v(k) as usize]);
                }
            }
        }
        for &(v, from, to) in &later {
            let vi = v as usize;
            let fan = firsts[from as usize..to as usize].to_vec();
            let ring = &around[&v];
            if self.detach_fan(table, index, &fan, nudge, ring) {
                split += 1;
            } else if !swapped[vi] {
                // A fan too small to move a copy clear of the vertex keeps the vertex instead,
                // and the first fan (often the larger) takes the copy: the result does not hang
                // on which fan comes first in the file.
                swapped[vi] = true;
                let (from, to) = first_of[vi];
                let first = firsts[from as usize..to as usize].to_vec();
                if self.detach_fan(table, index, &first, nudge, ring) {
                    self.unsplittable.remove(&v);
                    split += 1;
                }
            }
        }
        split
    }

    /// Gives the corners of one fan a new welded vertex, a hair inside the fan: one new vertex per
    /// distinct input vertex among them (each keeps its own attributes). The copy moves `nudge`
    /// towards the fan's centre (at most a quarter of the way); where that leaves it within the
    /// weld tolerance of its vertex, of another copy of it, of a corner of the fan or of `around`
    /// (the corners of the vertex's other fans; a fan smaller than the tolerance, two fans in one
    /// direction), it moves twice, three, four times as far,
    /// at most half the way. Returns `false`, changing nothing, when no such place is apart from
    /// them: a copy there would weld onto one of them when the copy is read (the vertex is then
    /// listed in `unsplittable`).
    fn detach_fan(
        &mut self,
        table: &CornerTable,
        index: &[u32],
        fan: &[u32],
        nudge: f64,
        around: &[[f64; 3]],
    ) -> bool {
        let v = table.v(fan[0]);
        let origin = self.points[v as usize];
        let mut centre = [0.0; 3];
        for &c in fan {
            for k in [CornerTable::n(c), CornerTable::p(c)] {
                let p = self.points[table.v(k) as usize];
                for i in 0..3 {
                    centre[i] += p[i] / (2 * fan.len()) as f64;
                }
            }
        }
        let to_centre = [0, 1, 2].map(|i| centre[i] - origin[i]);
        let length = to_centre.iter().map(|x| x * x).sum::<f64>().sqrt();
        let base = if length > 0.0 {
            nudge.min(0.25 * length) / length
        } else {
            0.0
        };
        // Rounded to f32, as glTF, binary STL and most PLY files store it, so that the copy read
        // back has the very position the plan judged (a sliver shell's volume sign can hang on it),
        // unless rounding moves some coordinate by more than half the move (a fan far smaller than
        // an f32 step, or far from the origin: rounding could drop the move along one axis and
        // leave the copy in a plane it was meant to leave) or leaves f32's range (a coordinate
        // beyond 3.4e38 rounds to infinity). Then the exact place is kept: text and f64 formats
        // hold it, a PLY declares `double`.
        let place = |step: f64| {
            let exact = [0, 1, 2].map(|i| origin[i] + step * to_centre[i]);
            let rounded = exact.map(|x| f64::from(x as f32));
            let half = 0.5
                * (0..3)
                    .map(|i| (exact[i] - origin[i]).powi(2))
                    .sum::<f64>()
                    .sqrt();
            let faithful =
                (0..3).all(|i| rounded[i].is_finite() && (rounded[i] - exact[i]).abs() <= half);
            if faithful {
                rounded
            } else {
                exact
            }
        };
        let tolerance = self.tolerance;
        let apart = |p: &[f64; 3], q: &[f64; 3]| {
            if tolerance > 0.0 {
                !crate::weld::closer_than(p, q, tolerance)
            } else {
                p != q
            }
        };
        // Apart from the vertex, its other copies and the fan's other corners (the copy read back
        // welds onto the first of these within the tolerance, collapsing a face).
        let copies = self.copies_of.get(&v).map_or(&[][..], Vec::as_slice);
        let ring = fan
            .iter()
            .flat_map(|&c| [CornerTable::n(c), CornerTable::p(c)])
            .map(|k| self.points[table.v(k) as usize]);
        let near: Vec<[f64; 3]> = std::iter::once(origin)
            .chain(copies.iter().copied())
            .chain(ring)
            .chain(around.iter().copied())
            .collect();
        let found = (1..=4)
            .map(|k| place((f64::from(k) * base).min(0.5)))
            .find(|p| near.iter().all(|q| apart(p, q)));
        let Some(position) = found else {
            self.unsplittable.insert(v);
            return false;
        };
        self.copies_of.entry(v).or_default().push(position);
        let welded = self.points.len() as u32;
        self.points.push(position);
        let mut copies: Vec<(u32, u32)> = Vec::new();
        for &c in fan {
            let t = &mut self.triangles[index[CornerTable::t(c) as usize] as usize];
            let corner = &mut t.corners[(c % 3) as usize];
            let copy = match copies.iter().find(|(old, _)| *old == corner.vertex) {
                Some(&(_, new)) => new,
                None => {
                    let new = (self.mesh.positions.len() + self.new_vertices.len()) as u32;
                    let copy_of =
                        match (corner.vertex as usize).checked_sub(self.mesh.positions.len()) {
                            Some(i) => self.new_vertices[i].copy_of,
                            None => corner.vertex,
                        };
                    self.new_vertices.push(NewVertex { copy_of, position });
                    self.welded.push(welded);
                    copies.push((corner.vertex, new));
                    new
                }
            };
            corner.vertex = copy;
        }
        self.changed();
        true
    }

    /// Orients every orientable component consistently, flipping the smaller side (when `flip` is
    /// false only counts). Returns `(faces flipped, non-orientable components)`.
    fn orient(&mut self, flip: bool) -> (usize, usize) {
        let shared = self.current(true);
        let (table, index) = (&shared.0, &shared.1);
        let nt = table.triangle_count();
        let windings = Windings::of(table);
        // Per patch: its faces and those of odd parity.
        let mut sizes = vec![[0usize; 2]; windings.orientable.len()];
        for t in 0..nt {
            sizes[windings.patch[t] as usize][usize::from(windings.odd[t])] += 1;
        }
        // Per orientable patch, the parity whose faces are flipped: the smaller side.
        let flip_odd: Vec<Option<bool>> = sizes
            .iter()
            .zip(&windings.orientable)
            .map(|(&[even, odd], &orientable)| orientable.then_some(odd <= even))
            .collect();
        let non_orientable = windings.orientable.iter().filter(|&&o| !o).count();
        let mut flipped = 0;
        // The table's faces flipped, to flip the table with them instead of rebuilding it.
        let mut table_flips = vec![false; nt];
        if flip {
            for t in 0..nt {
                if flip_odd[windings.patch[t] as usize] == Some(windings.odd[t]) {
                    self.flip(index[t] as usize);
                    table_flips[t] = true;
                    flipped += 1;
                }
            }
        }
        drop(shared);
        if flipped > 0 {
            if let Some(table) = self.table.as_mut().and_then(Rc::get_mut) {
                table.0.flip_triangles(&table_flips);
                self.wound = true;
            }
        }
        (flipped, non_orientable)
    }

    fn flip(&mut self, t: usize) {
        let tri = &mut self.triangles[t];
        tri.corners.swap(1, 2);
        tri.flipped = !tri.flipped;
        self.wound = false;
    }

    /// Flips whole shells whose volume sign is wrong for their nesting depth: `(shells, faces)`.
    /// Shells are the closed components (after splitting, every component is manifold); as in the
    /// analysis, the orientable ones hold others for nesting depth, and only consistently wound ones
    /// have a volume sign to act on.
    fn flip_inside_out(&mut self) -> (usize, usize) {
        let shared = self.current(true);
        let (table, index) = (&shared.0, &shared.1);
        let component = components(table);
        let count = component.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut shell = vec![true; count];
        let mut wound = vec![true; count];
        for c in 0..table.corner_count() as u32 {
            let comp = component[CornerTable::t(c) as usize] as usize;
            if table.opposite(c).is_none() {
                shell[comp] = false;
            } else if !table.is_consistent(c) {
                wound[comp] = false; // no volume sign to trust
            }
        }
        if !shell.iter().any(|&s| s) {
            return (0, 0);
        }
        let centre = self.points.first().copied().unwrap_or([0.0; 3]);
        let mut sums = vec![VolumeSum::default(); count];
        let mut faces: Vec<Vec<u32>> = vec![Vec::new(); count];
        for (t, &w) in table.triangles().iter().enumerate() {
            let comp = component[t] as usize;
            if !shell[comp] {
                continue;
            }
            faces[comp].push(t as u32);
            sums[comp].add(w.map(|v| self.points[v as usize]), centre);
        }
        let shells: Vec<usize> = (0..count).filter(|&c| shell[c]).collect();
        // A shell that is not orientable has no inside: no other shell lies in it.
        let mut orientable = vec![true; count];
        if shells.len() > 1 {
            let windings = Windings::of(table);
            for (t, &comp) in component.iter().enumerate() {
                orientable[comp as usize] &= windings.orientable[windings.patch[t] as usize];
            }
        }
        let geometry: Vec<ShellGeometry> = shells
            .iter()
            .map(|&c| ShellGeometry {
                bbox: sums[c].bbox,
                faces: &faces[c],
                bounds: orientable[c],
            })
            .collect();
        // As in the analysis, shells whose faces meet have no depth against each other (so a
        // shell crossing another is not turned for it).
        let meeting = if shells.len() > 1 {
            let bound = ZeroArea::of(bounding_box(&self.points));
            let component_of = |t: u32| component[t as usize];
            let search = Search::default();
            intersect_table(&self.points, table, &component_of, bound, None, &search)
                .component_pairs
        } else {
            Vec::new()
        };
        let apart = |a: usize, b: usize| {
            let (x, y) = (shells[a] as u32, shells[b] as u32);
            meeting.binary_search(&[x.min(y), x.max(y)]).is_err()
        };
        let depth = depths(table, &self.points, &geometry, &apart);
        let mut flipped = (0, 0);
        let mut flip_faces = Vec::new();
        for (&comp, depth) in shells.iter().zip(depth) {
            if !wound[comp] || sums[comp].is_flat() {
                continue;
            }
            let six_volume = sums[comp].six_volume;
            let solid = depth % 2 == 0;
            if (solid && six_volume < 0.0) || (!solid && six_volume > 0.0) {
                flipped.0 += 1;
                flipped.1 += faces[comp].len();
                flip_faces.extend(faces[comp].iter().map(|&t| index[t as usize]));
            }
        }
        for t in flip_faces {
            self.flip(t as usize);
        }
        flipped
    }

    /// Fills border loops of at most `max_edges` edges.
    fn fill_holes(&mut self, max_edges: usize) -> Fill {
        let mut fill = Fill::default();
        let shared = self.current(true);
        let (table, index) = (&shared.0, &shared.1);
        let border: Vec<u32> = (0..table.corner_count() as u32)
            .filter(|&c| table.is_border(c))
            .collect();
        if border.is_empty() {
            return fill;
        }
        // Border edges run from v(n(c)) to v(p(c)) in their face's winding; at a manifold border
        // vertex exactly one starts.
        let mut starting: FxHashMap<u32, u32> = FxHashMap::default();
        for &c in &border {
            starting.entry(table.v(CornerTable::n(c))).or_insert(c);
        }
        // Edges and faces a fill could repeat join border vertices only: collect just those.
        let mut on_border = vec![false; table.vertex_count()];
        for &c in &border {
            on_border[table.v(CornerTable::n(c)) as usize] = true;
            on_border[table.v(CornerTable::p(c)) as usize] = true;
        }
        let mut edges: FxHashMap<(u32, u32), ()> = FxHashMap::default();
        let mut faces: FxHashMap<[u32; 3], ()> = FxHashMap::default();
        let sorted = |t: [u32; 3]| {
            let mut t = t;
            t.sort_unstable();
            t
        };
        for (t, w) in table.triangles().iter().enumerate() {
            let border_corners = w.map(|v| on_border[v as usize]);
            for k in 0..3 {
                if border_corners[(k + 1) % 3] && border_corners[(k + 2) % 3] {
                    let (a, b) = (w[(k + 1) % 3], w[(k + 2) % 3]);
                    edges.insert((a.min(b), a.max(b)), ());
                }
            }
            if border_corners.iter().all(|&b| b) {
                faces.insert(sorted(table.triangles()[t]), ());
            }
        }
        // The border edge after `c`'s, from its end `w`: found by turning around `w` from `c`'s face
        // across the faces' other edges at `w`, so that at a vertex two holes share (a pinch) the
        // loop stays in its own fan; by `starting` past a non-manifold edge. `None` when the edge
        // found does not start at `w` (a winding the orientation left inconsistent).
        let next_border = |c: u32| -> Option<u32> {
            let w = table.v(CornerTable::p(c));
            // The corner whose opposite edge is the face's other edge at `w`.
            let mut j = CornerTable::n(c);
            for _ in 0..table.corner_count() {
                let o = table.o(j);
                if o == j {
                    return (table.v(CornerTable::n(j)) == w).then_some(j);
                }
                if o == NON_MANIFOLD {
                    return starting.get(&w).copied();
                }
                j = if table.v(CornerTable::n(o)) == w {
                    CornerTable::p(o)
                } else {
                    CornerTable::n(o)
                };
            }
            None
        };
        // Faces with an invalid vertex that the repair keeps (`invalid-vertex` off) are not in the
        // table, but the file still closes the holes they leave: their other corners.
        let mut at_kept_invalid = vec![false; table.vertex_count()];
        for t in &self.triangles {
            let w = self.welded_of(t);
            if FaceKind::of(&w) == FaceKind::Invalid {
                for v in w.into_iter().filter(|&v| v != INVALID) {
                    at_kept_invalid[v as usize] = true;
                }
            }
        }
        let mut traced = vec![false; table.corner_count()];
        let mut new_triangles = Vec::new();
        let mut filled: Vec<Filled> = Vec::new();
        for &first in &border {
            if traced[first as usize] {
                continue;
            }
            let mut traced_loop = Vec::new();
            let mut c = first;
            let closed = loop {
                traced[c as usize] = true;
                traced_loop.push(c);
                match next_border(c) {
                    Some(next) if next == first => break true,
                    Some(next)
                        if !traced[next as usize] && traced_loop.len() <= table.corner_count() =>
                    {
                        c = next
                    }
                    _ => break false,
                }
            };
            if !closed {
                fill.blocked += 1;
                continue;
            }
            // A loop through a pinch twice (two holes meeting corner to corner) is two holes.
            for loop_corners in simple_loops(table, traced_loop) {
                if loop_corners
                    .iter()
                    .any(|&c| at_kept_invalid[table.v(CornerTable::n(c)) as usize])
                {
                    fill.invalid += 1;
                    continue;
                }
                if loop_corners.len() > max_edges {
                    fill.too_large += 1;
                    continue;
                }
                // The fill runs the loop backwards; its corner at each loop vertex carries the attributes
                // of the bordering face's corner there (n(c) sits at the start of c's border edge).
                let ring: Vec<u32> = loop_corners
                    .iter()
                    .rev()
                    .map(|&c| table.v(CornerTable::n(c)))
                    .collect();
                let at: FxHashMap<u32, Corner> = loop_corners
                    .iter()
                    .map(|&c| {
                        let k = CornerTable::n(c);
                        let t = &self.triangles[index[CornerTable::t(k) as usize] as usize];
                        (table.v(k), t.corners[(k % 3) as usize])
                    })
                    .collect();
                let mut tris = Vec::new();
                // A loop that does not cross itself in its plane is split by ear clipping that finds a
                // proper ear at every step (or by a fan when it is convex): the fill cannot overlap
                // itself. A loop that crosses or folds onto itself there, one where ear clipping
                // finds no ear (`triangulate` then falls back to a fan), and a concave one too long
                // to ear-clip (fanned unchecked) could: left open.
                if !simple_in_plane(&ring, &self.points)
                    || matches!(
                        triangulate(&ring, &self.points, &mut tris),
                        Split::Fallback | Split::Large
                    )
                {
                    fill.no_triangulation += 1;
                    continue;
                }
                // A diagonal that is already an edge, or a face that is already there, would make the
                // surface non-manifold: such a hole is left open.
                let overlaps = tris.iter().any(|t| {
                    faces.contains_key(&sorted(*t))
                        || (0..3).any(|k| {
                            let (a, b) = (t[k], t[(k + 1) % 3]);
                            let diagonal = !ring_neighbours(&ring, a, b);
                            diagonal && edges.contains_key(&(a.min(b), a.max(b)))
                        })
                });
                if overlaps || tris.len() + 2 != ring.len() || ring.len() < 3 {
                    fill.blocked += 1;
                    continue;
                }
                for t in &tris {
                    for k in 0..3 {
                        let (a, b) = (t[k], t[(k + 1) % 3]);
                        edges.insert((a.min(b), a.max(b)), ());
                    }
                }
                let near = index[CornerTable::t(loop_corners[0]) as usize];
                let near = self.triangles[near as usize]
                    .source
                    .unwrap_or(self.triangles[near as usize].near);
                filled.push(Filled {
                    border: loop_corners.clone(),
                    triangles: new_triangles.len()..new_triangles.len() + tris.len(),
                    plane: plane_of(&ring, &self.points),
                });
                for t in tris {
                    new_triangles.push(Triangle {
                        corners: t.map(|v| at[&v]),
                        source: None,
                        near,
                        flipped: false,
                    });
                }
                fill.holes += 1;
                fill.faces += ring.len() - 2;
            }
        }
        let flat = self.flat_closures(table, &border, &filled, &new_triangles);
        let mut keep = vec![true; new_triangles.len()];
        for &k in &flat {
            let f = &filled[k];
            keep[f.triangles.clone()].fill(false);
            fill.holes -= 1;
            fill.faces -= f.triangles.len();
            fill.flat += 1;
        }
        // A fill is kept only when the search shows it meets nothing: when the search stopped
        // at its budget, every fill still kept is left open.
        let (crossing, stopped) = self.crossing_fills(table, &filled, &new_triangles, &keep);
        let unchecked: Vec<usize> = if stopped {
            (0..filled.len())
                .filter(|&k| keep[filled[k].triangles.clone()].contains(&true))
                // `crossing` is ascending.
                .filter(|k| crossing.binary_search(k).is_err())
                .collect()
        } else {
            Vec::new()
        };
        fill.crossing = crossing.len();
        fill.unchecked = unchecked.len();
        for k in crossing.into_iter().chain(unchecked) {
            let f = &filled[k];
            keep[f.triangles.clone()].fill(false);
            fill.holes -= 1;
            fill.faces -= f.triangles.len();
        }
        if keep.contains(&false) {
            let mut i = 0;
            new_triangles.retain(|_| {
                i += 1;
                keep[i - 1]
            });
        }
        drop(shared);
        self.add_triangles(new_triangles);
        fill
    }

    /// The fills (indices into `filled`) not yet dropped (`keep`) whose faces meet the surface or
    /// another fill (a fill that crosses the rest of the mesh makes a new defect, not a repair),
    /// and whether the search stopped at its budget (then others may meet too).
    fn crossing_fills(
        &self,
        table: &CornerTable,
        filled: &[Filled],
        new_triangles: &[Triangle],
        keep: &[bool],
    ) -> (Vec<usize>, bool) {
        if !keep.contains(&true) {
            return (Vec::new(), false);
        }
        // Only a face whose box overlaps a fill's can meet it: the search runs on those faces
        // and the kept fills, not on the whole surface again (on a 1M-face mesh with a few holes,
        // 10 ms instead of 350). The table's faces keep their numbers, the fills are numbered
        // after them; vertices are renumbered densely (the search compares them only for
        // equality) so that its per-vertex work is the subset's.
        let nt = table.triangle_count() as u32;
        let box_of = |w: [u32; 3]| {
            bounding_box(w.iter().map(|&v| &self.points[v as usize])).expect("a face has points")
        };
        let fills: Vec<(u32, [u32; 3])> = (0..new_triangles.len())
            .filter(|&i| keep[i])
            .map(|i| (nt + i as u32, self.welded_of(&new_triangles[i])))
            .filter(|(_, w)| FaceKind::of(w) == FaceKind::Table)
            .collect();
        let boxes: Vec<_> = fills.iter().map(|&(_, w)| box_of(w)).collect();
        let Some(near) = Near::new(&boxes) else {
            return (Vec::new(), false);
        };
        let mut faces = Vec::new();
        let mut number = Vec::new();
        for (t, &w) in table.triangles().iter().enumerate() {
            if near.may_overlap(box_of(w)) {
                faces.push(w);
                number.push(t as u32);
            }
        }
        for (n, w) in fills {
            faces.push(w);
            number.push(n);
        }
        let mut dense = vec![INVALID; self.points.len()];
        let mut points = Vec::new();
        for w in &mut faces {
            for v in w {
                if dense[*v as usize] == INVALID {
                    dense[*v as usize] = points.len() as u32;
                    points.push(self.points[*v as usize]);
                }
                *v = dense[*v as usize];
            }
        }
        let (all, number) = table_of(faces, number, points.len());
        // The zero-area threshold is the whole mesh's, as in the analysis.
        let bound = ZeroArea::of(bounding_box(&self.points));
        let met = intersect_table(
            &points,
            &all,
            &|_| 0,
            bound,
            Some(&number),
            &self.fill_search,
        );
        let crossing = (0..filled.len())
            .filter(|&k| {
                filled[k]
                    .triangles
                    .clone()
                    .any(|i| keep[i] && met.involves(nt + i as u32))
            })
            .collect();
        (crossing, met.stopped)
    }

    /// Whether every vertex of the faces reachable from the hole's border face through manifold
    /// edges lies on the hole's plane (to 1e-9 of its distance or the hole's size): false as soon
    /// as one does not, which on a curved surface is within a few faces.
    fn patch_in_plane(&self, table: &CornerTable, filled: &Filled) -> bool {
        let Some((normal, centre, size)) = filled.plane else {
            return false;
        };
        let off = |v: u32| {
            let p = self.points[v as usize];
            let d = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
            let height = normal[0] * d[0] + normal[1] * d[1] + normal[2] * d[2];
            let reach = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(size);
            // NaN counts as off the plane.
            height.is_nan() || height.abs() > 1e-9 * reach
        };
        let mut seen: rustc_hash::FxHashSet<u32> = Default::default();
        let mut stack = vec![filled.face()];
        seen.insert(filled.face());
        while let Some(t) = stack.pop() {
            if table.triangles()[t as usize].iter().any(|&v| off(v)) {
                return false;
            }
            for c in 3 * t..3 * t + 3 {
                if let Some(o) = table.opposite(c) {
                    if seen.insert(CornerTable::t(o)) {
                        stack.push(CornerTable::t(o));
                    }
                }
            }
        }
        true
    }

    /// The fills (indices into `filled`) that would close a component whose closed surface then
    /// has no volume: an open sheet lying flat (a fin, a flat patch) filled over its own outline
    /// becomes a two-sided pillow, which is not a repair. Only components whose every border
    /// edge gets filled are checked.
    fn flat_closures(
        &self,
        table: &CornerTable,
        border: &[u32],
        filled: &[Filled],
        new_triangles: &[Triangle],
    ) -> Vec<usize> {
        // Most fills close curved surfaces: a short walk from the hole finds a face off the
        // hole's plane, and only the rest (flat patches) pay for components and volumes.
        let candidates: Vec<usize> = (0..filled.len())
            .filter(|&k| self.patch_in_plane(table, &filled[k]))
            .collect();
        if candidates.is_empty() {
            return Vec::new();
        }
        let component = components(table);
        let count = component.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut open_edges = vec![0usize; count];
        for &c in border {
            open_edges[component[CornerTable::t(c) as usize] as usize] += 1;
        }
        for f in filled {
            for &c in &f.border {
                let open = &mut open_edges[component[CornerTable::t(c) as usize] as usize];
                *open = open.saturating_sub(1);
            }
        }
        // A loop through a vertex two components share (when splitting is off) spans both: such
        // fills are kept as they are.
        let own = |f: &Filled| component[f.face() as usize];
        let closes = |f: &Filled| {
            f.border
                .iter()
                .all(|&c| component[CornerTable::t(c) as usize] == own(f))
                && open_edges[own(f) as usize] == 0
        };
        if !filled.iter().any(closes) {
            return Vec::new();
        }
        // Six times the signed volume and the box of each component that the fills close: its
        // faces, then its fills (about a point of it, so far-away coordinates cancel less).
        let mut closing = vec![false; count];
        for f in filled.iter().filter(|f| closes(f)) {
            closing[component[f.face() as usize] as usize] = true;
        }
        let mut centre: Vec<Option<[f64; 3]>> = vec![None; count];
        let mut sums = vec![VolumeSum::default(); count];
        let mut add = |comp: usize, w: [u32; 3]| {
            let points = w.map(|v| self.points[v as usize]);
            let origin = *centre[comp].get_or_insert(points[0]);
            sums[comp].add(points, origin);
        };
        for (t, &w) in table.triangles().iter().enumerate() {
            let comp = component[t] as usize;
            if closing[comp] {
                add(comp, w);
            }
        }
        for f in filled.iter().filter(|f| closes(f)) {
            let comp = component[f.face() as usize] as usize;
            for t in &new_triangles[f.triangles.clone()] {
                add(comp, self.welded_of(t));
            }
        }
        candidates
            .into_iter()
            .filter(|&k| closes(&filled[k]))
            .filter(|&k| {
                let comp = component[filled[k].face() as usize] as usize;
                sums[comp].is_flat()
            })
            .collect()
    }

    /// Adds fill triangles, adding them to the current table too where it can take them (no edge
    /// becomes non-manifold), so the next step does not rebuild it.
    fn add_triangles(&mut self, new: Vec<Triangle>) {
        if new.is_empty() {
            return;
        }
        let first = self.triangles.len() as u32;
        let welded: Vec<[u32; 3]> = new.iter().map(|t| self.welded_of(t)).collect();
        self.triangles.extend(new);
        let appended = welded.iter().all(|w| FaceKind::of(w) == FaceKind::Table)
            && self.wound
            && self
                .table
                .as_mut()
                .and_then(Rc::get_mut)
                .is_some_and(|(table, index)| {
                    let ok = table.append_triangles(&welded);
                    if ok {
                        index.extend(first..first + welded.len() as u32);
                    }
                    ok
                });
        if !appended {
            self.changed();
        }
    }
}

/// The two corners of a non-manifold edge whose faces stay joined there: the first pair that
/// traverses the edge in opposite directions, else the first two.
fn keep_pair(table: &CornerTable, corners: &[u32]) -> (u32, u32) {
    corners
        .iter()
        .enumerate()
        .flat_map(|(i, &a)| corners[i + 1..].iter().map(move |&b| (a, b)))
        .find(|&(a, b)| table.v(CornerTable::n(a)) == table.v(CornerTable::p(b)))
        .unwrap_or((corners[0], corners[1]))
}

/// Whether the closed loop `ring` (indices into `points`), projected onto the coordinate plane
/// most parallel to its best-fit plane (the largest component of its Newell normal, as the polygon
/// splitter does), is a simple polygon: no two of its edges cross or touch except neighbours at
/// their shared end, and no neighbours fold back onto each other. False for a loop with no plane
/// (zero Newell normal) or a non-finite coordinate. O(n^2) for n edges (holes are small).
fn simple_in_plane(ring: &[u32], points: &[[f64; 3]]) -> bool {
    let n = ring.len();
    // The splitter's projection (mirrored when that makes it counter-clockwise, which changes
    // nothing here).
    let Some(p) = project(ring, points) else {
        return false;
    };
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        // The next edge folds back along this one.
        let c = p[(i + 2) % n];
        if n > 2
            && orient2d(a, b, c) == 0.0
            && (c.x - b.x) * (a.x - b.x) + (c.y - b.y) * (a.y - b.y) > 0.0
        {
            return false;
        }
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue; // neighbours across the loop's start
            }
            if segments_touch(a, b, p[j], p[(j + 1) % n]) {
                return false;
            }
        }
    }
    true
}

/// Whether `a` and `b` are neighbours on the ring (a loop edge, not a diagonal).
fn ring_neighbours(ring: &[u32], a: u32, b: u32) -> bool {
    let n = ring.len();
    (0..n).any(|i| {
        let (x, y) = (ring[i], ring[(i + 1) % n]);
        (x == a && y == b) || (x == b && y == a)
    })
}

#[derive(Debug, Default)]
struct Fill {
    holes: usize,
    faces: usize,
    too_large: usize,
    blocked: usize,
    /// Loops with no triangulation that is sure not to overlap itself.
    no_triangulation: usize,
    /// Loops whose fill would close a flat open surface into a shell with no volume.
    flat: usize,
    /// Loops whose fill would cross the rest of the surface (or another fill).
    crossing: usize,
    /// Loops whose fill could not be checked against the surface: the search for faces that
    /// meet stopped at its budget among the faces near the fills.
    unchecked: usize,
    /// Loops through a corner of a face with an invalid vertex that the repair keeps.
    invalid: usize,
}

/// Six times the signed volume of a set of triangles (about an origin) and their bounding box.
#[derive(Debug, Clone, Copy)]
struct VolumeSum {
    six_volume: f64,
    bbox: [[f64; 3]; 2],
}

impl Default for VolumeSum {
    fn default() -> VolumeSum {
        VolumeSum {
            six_volume: 0.0,
            bbox: [[f64::INFINITY; 3], [f64::NEG_INFINITY; 3]],
        }
    }
}

impl VolumeSum {
    /// Adds triangle `[a, b, c]`, its volume taken about `origin` (a point near the triangles, so
    /// far-away coordinates cancel less).
    fn add(&mut self, [a, b, c]: [[f64; 3]; 3], origin: [f64; 3]) {
        for p in [a, b, c] {
            for (k, x) in p.into_iter().enumerate() {
                self.bbox[0][k] = self.bbox[0][k].min(x);
                self.bbox[1][k] = self.bbox[1][k].max(x);
            }
        }
        let [a, b, c] = [a, b, c].map(|p| [0, 1, 2].map(|k| p[k] - origin[k]));
        self.six_volume += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]);
    }

    /// Whether the volume is zero for the box's size ([`is_flat`]).
    fn is_flat(&self) -> bool {
        is_flat(self.six_volume / 6.0, &self.bbox)
    }
}

/// One hole filled: its border corners (one per border edge, in loop order) and where its fill
/// triangles are in the new triangles.
struct Filled {
    border: Vec<u32>,
    triangles: std::ops::Range<usize>,
    /// The hole's plane: unit normal, centre and size (see [`plane_of`]).
    plane: Option<([f64; 3], [f64; 3], f64)>,
}

impl Filled {
    /// A table face on the hole's border.
    fn face(&self) -> u32 {
        CornerTable::t(self.border[0])
    }
}

/// A closed border loop (corners whose opposite edges run it in order) split at the vertices it
/// passes more than once, into loops that pass each vertex once: a figure-eight through a pinch
/// (two holes meeting corner to corner) gives its two holes. Each edge `c` starts at `v(n(c))`.
fn simple_loops(table: &CornerTable, corners: Vec<u32>) -> Vec<Vec<u32>> {
    let start = |c: u32| table.v(CornerTable::n(c));
    let mut out = Vec::new();
    let mut stack: Vec<u32> = Vec::with_capacity(corners.len());
    // The place in `stack` of the edge starting at each vertex.
    let mut at: FxHashMap<u32, usize> = FxHashMap::default();
    for c in corners {
        let s = start(c);
        if let Some(i) = at.get(&s).copied() {
            // The edges from the one starting at `s` to here run from `s` back to `s`.
            let cycle: Vec<u32> = stack.drain(i..).collect();
            for &k in &cycle {
                at.remove(&start(k));
            }
            out.push(cycle);
        }
        at.insert(s, stack.len());
        stack.push(c);
    }
    if !stack.is_empty() {
        out.push(stack);
    }
    out
}

/// The best-fit plane of loop `ring`: its unit Newell normal, the mean of its points and the
/// diagonal of their box; `None` without a normal (or with a non-finite point).
fn plane_of(ring: &[u32], points: &[[f64; 3]]) -> Option<([f64; 3], [f64; 3], f64)> {
    let p: Vec<[f64; 3]> = ring.iter().map(|&v| points[v as usize]).collect();
    let normal = newell(&p);
    let mut centre = [0.0f64; 3];
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for a in &p {
        for i in 0..3 {
            centre[i] += a[i] / p.len() as f64;
            lo[i] = lo[i].min(a[i]);
            hi[i] = hi[i].max(a[i]);
        }
    }
    let length = (normal[0].powi(2) + normal[1].powi(2) + normal[2].powi(2)).sqrt();
    let size = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt();
    (length > 0.0 && length.is_finite() && size.is_finite())
        .then(|| (normal.map(|x| x / length), centre, size))
}

/// How the faces of a table can be wound alike: each face's patch (faces linked through manifold
/// edges) and its parity there (`odd`: flipping it, or every face of the other parity, makes its
/// edges in the patch consistent), and per patch whether such a winding exists (it is
/// orientable; a Moebius strip or a Klein bottle is not).
struct Windings {
    patch: Vec<u32>,
    odd: Vec<bool>,
    orientable: Vec<bool>,
}

impl Windings {
    fn of(table: &CornerTable) -> Windings {
        let nt = table.triangle_count();
        let mut patch = vec![u32::MAX; nt];
        let mut odd = vec![false; nt];
        let mut orientable = Vec::new();
        let mut stack = Vec::new();
        for seed in 0..nt {
            if patch[seed] != u32::MAX {
                continue;
            }
            let id = orientable.len() as u32;
            patch[seed] = id;
            stack.push(seed as u32);
            let mut ok = true;
            while let Some(t) = stack.pop() {
                let mine = odd[t as usize];
                for c in 3 * t..3 * t + 3 {
                    let Some(b) = table.opposite(c) else { continue };
                    let u = CornerTable::t(b) as usize;
                    let want = mine ^ !table.is_consistent(c);
                    if patch[u] == u32::MAX {
                        patch[u] = id;
                        odd[u] = want;
                        stack.push(u as u32);
                    } else {
                        ok &= odd[u] == want;
                    }
                }
            }
            orientable.push(ok);
        }
        Windings {
            patch,
            odd,
            orientable,
        }
    }
}

/// Component of every table triangle, numbered by lowest triangle, linked through edges of any
/// valence (the analysis' definition).
fn components(table: &CornerTable) -> Vec<u32> {
    let nt = table.triangle_count();
    let mut parent: Vec<u32> = (0..nt as u32).collect();
    let mut join = |a: u32, b: u32| union(&mut parent, a, b);
    for c in 0..table.corner_count() as u32 {
        if let Some(b) = table.opposite(c) {
            join(CornerTable::t(c), CornerTable::t(b));
        }
    }
    for corners in table.nonmanifold_edges() {
        for &c in &corners[1..] {
            join(CornerTable::t(corners[0]), CornerTable::t(c));
        }
    }
    let mut number = vec![u32::MAX; nt];
    let mut next = 0;
    (0..nt as u32)
        .map(|t| {
            let root = find(&mut parent, t) as usize;
            if number[root] == u32::MAX {
                number[root] = next;
                next += 1;
            }
            number[root]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit box without its top (one hole of four edges, at z = 1) and a pile of 400 long
    /// slivers beside its top edge at x = 1, in parallel planes `y - 0.6 z = c`: each runs from
    /// `(1.7, y, 0.5)` to `(0.7, y + 0.6, 1.5)`, crossing z = 1 at x = 1.2 (beyond the top) and
    /// x = 1 at z = 1.2 (above the wall), so none meets the box, the fill or another sliver, but
    /// every sliver's box overlaps the fill's and every other's: 79,800 pairs of boxes. With the
    /// default budget the search finishes and the top is filled; with a budget of one pair a face
    /// (8,192 pairs, a small mesh counting as 8,192 faces) it stops, and the fill is left open
    /// as unchecked rather than kept unchecked. Each sliver's own outline would repeat it: blocked.
    #[test]
    fn a_fill_the_search_could_not_finish_checking_is_left_open() {
        let mut positions: Vec<[f64; 3]> = (0..8)
            .map(|v| [v & 1, (v >> 1) & 1, (v >> 2) & 1].map(f64::from))
            .collect();
        let mut triangles: Vec<[u32; 3]> = vec![
            [0, 2, 3],
            [0, 3, 1],
            [0, 1, 5],
            [0, 5, 4],
            [1, 3, 7],
            [1, 7, 5],
            [3, 2, 6],
            [3, 6, 7],
            [2, 0, 4],
            [2, 4, 6],
        ];
        for i in 0..400 {
            let y = 0.2 + f64::from(i) * 0.0005;
            let first = positions.len() as u32;
            positions.extend([[1.7, y, 0.5], [0.7, y + 0.6, 1.5], [1.701, y, 0.5]]);
            triangles.push([first, first + 1, first + 2]);
        }
        let mesh = Mesh::new(positions, triangles);
        let fill = |pair_budget: u64| {
            let mut work = Work::new(&mesh, &Options::default(), None);
            work.fill_search.pair_budget = pair_budget;
            let fill = work.fill_holes(100);
            (fill.holes, fill.crossing, fill.unchecked, fill.blocked)
        };
        assert_eq!(fill(Search::default().pair_budget), (1, 0, 0, 400));
        assert_eq!(fill(1), (0, 0, 1, 400));
    }
}
