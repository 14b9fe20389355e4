//! Pure functions from a mesh to the numbers of [the definitions](crate::definitions) (welding,
//! faces, edges and vertices, components, volume and nesting). One pass, [`analyse`], computes
//! an [`Analysis`] with every count the report needs plus per-component and per-shell tables; the
//! rules decide later what those facts mean for a user.

pub(crate) mod analyse;
pub(crate) mod built;
pub mod intersect;
pub(crate) mod nesting;
mod places;
pub(crate) mod sets;

pub use analyse::{analyse, analyse_keeping, analyse_releasing};
pub use built::{build, Built, LeftOut};
pub use intersect::{intersect, intersections_built, Intersections, Search, Surface};
pub use places::{places, Places, NO_SHELL};

/// How the analysis [welds](crate::definitions#welding) vertices, and whether it looks for
/// faces that [meet](crate::definitions#intersections).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// `0.0`: weld only exactly equal positions (-0.0 equals 0.0). Otherwise positions closer than this
    /// distance are one vertex.
    pub weld_tolerance: f64,
    /// How far the search for faces that meet goes; `None`: no search (the counts are undefined).
    pub intersections: Option<Search>,
}

impl Default for Options {
    /// Exact welding, and the search for faces that meet, as a scan does by default.
    fn default() -> Options {
        Options {
            weld_tolerance: 0.0,
            intersections: Some(Search::default()),
        }
    }
}

/// Every topological fact about one mesh (the report's columns without the file columns).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Analysis {
    /// Input vertices as the file stores them.
    pub vertices: usize,
    /// Distinct valid positions after welding (unreferenced ones included).
    pub welded_vertices: usize,
    /// Input triangles.
    pub faces: usize,
    /// Faces with two corners on one welded vertex; left out of the table.
    pub degenerate_faces: usize,
    /// Faces with three distinct vertices but area <= 1e-12 x diagonal^2; kept.
    pub zero_area_faces: usize,
    /// Extra copies of a face with the same three welded vertices (either winding); kept.
    pub duplicate_faces: usize,
    /// Input vertices with a NaN or infinite coordinate.
    pub invalid_vertices: usize,
    /// Faces left out because they use an invalid vertex.
    pub invalid_faces: usize,
    /// Valid welded vertices that no face refers to.
    pub unreferenced_vertices: usize,
    /// Unordered vertex pairs bounding at least one face of the table.
    pub edges: usize,
    pub border_edges: usize,
    pub nonmanifold_edges: usize,
    pub nonmanifold_vertices: usize,
    /// Manifold edges whose two faces traverse them in the same direction.
    pub inconsistent_edges: usize,
    /// `V - E + F` over the table (V: vertices used by the table's faces).
    pub euler: i64,
    /// Total area of the table's faces.
    pub area: f64,
    /// Bounding box of the valid vertices, `None` when there are none.
    pub bbox: Option<[[f64; 3]; 2]>,
    /// Edge-connected components, in order of their lowest face.
    pub components: Vec<Component>,
    /// Closed manifold components (and pinched solids, [`Shell::pinched`]), in component order.
    pub shells: Vec<Shell>,
    /// The faces that meet (faces numbered as in the mesh, components as in
    /// [`Analysis::components`]); `None` when the options asked for no search.
    pub intersections: Option<Intersections>,
}

/// A maximal set of faces connected through shared edges of any valence
/// ([definitions](crate::definitions#components)).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Component {
    pub faces: usize,
    pub vertices: usize,
    pub edges: usize,
    pub border_edges: usize,
    pub nonmanifold_edges: usize,
    /// Boundary loops.
    pub holes: usize,
    /// Every edge has valence 2.
    pub closed: bool,
    /// Edges of valence <= 2 and one fan of the component's faces around each of its vertices.
    pub manifold: bool,
    /// Windings exist that make every manifold edge consistent.
    pub orientable: bool,
    /// Every manifold edge is consistent as stored.
    pub oriented: bool,
    /// Manifold edges whose two faces run them the same way (the mesh's `inconsistent_edges`,
    /// counted in this component).
    pub inconsistent_edges: usize,
    /// `V - E + F` of the component.
    pub euler: i64,
    /// `(2 - chi - holes) / 2`; `None` unless manifold and orientable.
    pub genus: Option<i64>,
}

#[cfg(test)]
impl Component {
    /// An orientable, consistently wound component with `holes` boundary loops (for the tests of
    /// what reads an analysis).
    pub(crate) fn with_holes(holes: usize) -> Component {
        Component {
            holes,
            orientable: true,
            oriented: true,
            ..Component::default()
        }
    }
}

/// Whether a shell bounds material from outside or a void inside material
/// ([definitions](crate::definitions#volume-and-nesting)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Role {
    #[default]
    Solid,
    Cavity,
    /// A shell that is not orientable (a Klein bottle, a projective plane, which in space always
    /// pass through themselves) has no inside: it bounds neither material nor a void, has no
    /// volume and holds no other shell.
    Neither,
}

/// A closed, manifold component with its place in the nesting
/// ([definitions](crate::definitions#volume-and-nesting)); or a closed, orientable component that
/// is not manifold only because a vertex is pinched ([`Shell::pinched`]), which bounds a volume
/// all the same.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Shell {
    /// Index into [`Analysis::components`].
    pub component: usize,
    pub faces: usize,
    pub vertices: usize,
    pub genus: Option<i64>,
    pub orientable: bool,
    pub oriented: bool,
    /// Not a shell but a pinched solid: closed, orientable, non-manifold only at vertices. Counted
    /// in `solids`, `cavities`, `inside_out_shells` and `volume`, not in `shells`.
    pub pinched: bool,
    /// Signed volume, `(1/6) sum mp(A-P, B-P, C-P)` with P the mean of the shell's vertices,
    /// with the faces taken in a consistent winding: the stored one when the shell is oriented, else
    /// the winding of the majority of its faces, and on a tie the winding of its first face by
    /// position (vertex positions sorted by x, y, z, compared lexicographically), so that no vertex
    /// or face numbering decides the sign. `None` when not orientable.
    pub volume: Option<f64>,
    /// How many other shells contain this one (only orientable shells contain others).
    pub depth: usize,
    /// Solid for even depth, cavity for odd; neither when not orientable.
    pub role: Role,
    /// Oriented, with a volume sign wrong for its role (solids need positive, cavities negative). A
    /// flat shell (|volume| <= 1e-12 x bbox diagonal cubed) has no sign and is never inside out.
    pub inside_out: bool,
    /// Bounding box of the shell's vertices.
    pub bbox: [[f64; 3]; 2],
    /// The other shells (indices into [`Analysis::shells`]) that this one meets: faces of the two
    /// cross or touch. Nesting ignores them (no depth from a shell it crosses).
    pub meets: Vec<usize>,
}

impl Analysis {
    /// Boundary loops over all components.
    pub fn holes(&self) -> usize {
        self.components.iter().map(|c| c.holes).sum()
    }

    /// Every component orientable (true for an empty mesh).
    pub fn orientable(&self) -> bool {
        self.components.iter().all(|c| c.orientable)
    }

    /// Every manifold edge consistent as stored.
    pub fn oriented(&self) -> bool {
        self.inconsistent_edges == 0
    }

    /// Sum of the components' genus, `None` when any component's genus is undefined or there are none.
    pub fn genus(&self) -> Option<i64> {
        if self.components.is_empty() {
            return None;
        }
        self.components.iter().map(|c| c.genus).sum()
    }

    /// Closed, manifold components (the pinched solids in [`Analysis::shells`] left out).
    pub fn shell_count(&self) -> usize {
        self.shells.iter().filter(|s| !s.pinched).count()
    }

    /// Pairs of faces of one component that meet; `None` without a search.
    pub fn self_intersections(&self) -> Option<usize> {
        self.intersections.as_ref().map(|i| i.self_intersections)
    }

    /// Pairs of components with faces that meet; `None` without a search.
    pub fn intersecting_components(&self) -> Option<usize> {
        self.intersections
            .as_ref()
            .map(Intersections::intersecting_components)
    }

    /// Pairs of shells that meet, whose overlap `volume` counts twice.
    pub fn overlapping_shells(&self) -> usize {
        self.shells.iter().map(|s| s.meets.len()).sum::<usize>() / 2
    }

    pub fn solids(&self) -> usize {
        self.shells.iter().filter(|s| s.role == Role::Solid).count()
    }

    pub fn cavities(&self) -> usize {
        self.shells
            .iter()
            .filter(|s| s.role == Role::Cavity)
            .count()
    }

    pub fn inside_out_shells(&self) -> usize {
        self.shells.iter().filter(|s| s.inside_out).count()
    }

    /// Sum of the shells' volumes, each with the sign its role demands (solids +, cavities -); `None`
    /// when no shell has a volume.
    pub fn volume(&self) -> Option<f64> {
        let mut any = false;
        let mut sum = 0.0;
        for s in &self.shells {
            if let Some(v) = s.volume {
                any = true;
                sum += match s.role {
                    Role::Solid => v.abs(),
                    Role::Cavity => -v.abs(),
                    Role::Neither => 0.0,
                };
            }
        }
        any.then_some(sum)
    }
}
