//! Which faces of a mesh **meet**: two faces meet when their closed triangles share a point that is
//! not a vertex or an edge the two faces share in the welded mesh (crossing, touching, coplanar
//! overlap; faces on one edge only when they fold onto each other; faces on one vertex when they
//! have another common point). Zero-area faces are left out, as are faces whose three points are
//! exactly on a line.
//!
//! [`intersect`] counts the pairs of faces of one component that meet (`self_intersections`), the
//! pairs of components with faces that meet (`intersecting_components`), marks every face involved
//! and keeps the first pairs up to a cap (the counts stay exact). It runs in two phases:
//!
//! - broad (`tree`): a bounding-volume hierarchy of outward-rounded face boxes, walked against
//!   itself, gives every pair of faces whose boxes overlap, in parallel tasks on the current rayon
//!   pool for big meshes, except the pairs that share a vertex whose star is flat (`stars`: the
//!   faces around it project one to one onto a coordinate plane, so they meet only where they
//!   share that vertex or an edge; decided exactly, and true of nearly every vertex of a smooth
//!   surface, it leaves out most of the pairs neighbouring faces make), and the pairs within a
//!   tree node whose faces are a flat patch (`patches`: seen along an axis, the faces' shadows
//!   tile the inside of simple loops once, so none of them meet), and the pairs within a flat
//!   region (`regions`: faces of one plane perpendicular to an axis, joined edge to edge, that
//!   are a flat patch; the tops and bottoms of CAD plates, whose long faces the tree cannot
//!   separate), and the pairs of a region's face with a face that touches the region's plane only
//!   at the region's corners or along one of its edges (the walls standing on a plate). A tree
//!   node whose faces all share one such vertex, or all lie in one region, is not walked pair by
//!   pair (a fan of long faces around a cylinder's cap centre has every box overlap every other),
//!   nor are two nodes of which one lies in a region and the other's faces all touch it so (a
//!   plate's face node against a node of its walls, `regions::Regions::covers`);
//!   and the search stops at a budget per face ([`Search::pair_budget`]), its counts then lower
//!   bounds, so no file can hold it for hours;
//! - narrow (`meet`): exact `orient3d`/`orient2d` signs decide each such pair; the shared vertices
//!   come from the Corner Table's welded vertex ids.
//!
//! The predicates are exact as long as no product underflows or overflows; a mesh whose largest
//! coordinate is beyond 2^±100 is first scaled by a power of two, which changes no sign.

mod meet;
mod patches;
mod regions;
mod stars;
mod tree;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};

use super::built::{cross2, Built, ZeroArea};
use crate::corner_table::CornerTable;
use crate::geometry::curve;
use crate::geometry::{largest_coordinate, unit_scale};
use crate::pages::prefetch;
use tree::{Placed, Tree, Visit};

/// What the test reads of a mesh: the welded points, the Corner Table of the faces the analysis
/// keeps, each table face's edge-connected component and which faces to leave out.
pub struct Surface<'a> {
    pub points: &'a [[f64; 3]],
    pub table: &'a CornerTable,
    /// The component of table face `t`.
    pub component: &'a (dyn Fn(u32) -> u32 + Sync),
    /// The zero-area faces, which are left out.
    pub zero_area: ZeroArea,
    /// The number of table face `t` in the findings (pairs, involved faces), for instance its input
    /// face; `None`: its table number. The kept pairs are the lowest in this numbering.
    pub number: Option<&'a [u32]>,
}

/// How far the search goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Search {
    /// How many pairs of faces that meet are kept in [`Intersections::pairs`].
    pub kept_pairs: usize,
    /// Stop at the first pair found (a yes/no answer for a quick check); the counts are then not
    /// complete.
    pub first_only: bool,
    /// How much the search may do, per face of the mesh (a mesh of fewer than
    /// [`Search::FLOOR_FACES`] faces counts as that many): it looks at most `pair_budget` pairs of
    /// faces whose boxes overlap per face, and holds at most `pair_budget / 128` pairs of parts
    /// that meet per face. Past either it stops, its counts lower bounds
    /// ([`Intersections::stopped`]). Real meshes stay far below (the corpus's worst, a CAD plate
    /// of long slivers, looks at 42 pairs a face); without it, a file of long faces piled on one
    /// another takes time, and a file of parts piled on one another memory, that grow with the
    /// square of its faces (20,000 random triangles: 55 million pairs of parts that meet).
    pub pair_budget: u64,
}

impl Search {
    /// The fewest faces the budget counts a mesh as having: a small mesh may look at 8.4 million
    /// pairs with the default budget. Where every pair reaches the exact test (faces piled on one
    /// another, with coordinates the float filter cannot settle) that is about 100 ns a pair, a
    /// second on one core; a floor of 65,536 faces let a fuzzed 23,000-face OFF take 7 s.
    pub const FLOOR_FACES: u64 = 1 << 13;

    /// The pairs of faces whose boxes overlap that the search looks at in a mesh of `faces` faces,
    /// and the pairs of parts that meet that it holds.
    fn limits(&self, faces: usize) -> (u64, usize) {
        let faces = (faces as u64).max(Self::FLOOR_FACES);
        let held = (self.pair_budget / 128).saturating_mul(faces);
        (
            self.pair_budget.saturating_mul(faces),
            usize::try_from(held).unwrap_or(usize::MAX),
        )
    }
}

impl Default for Search {
    fn default() -> Search {
        Search {
            kept_pairs: 100,
            first_only: false,
            pair_budget: 1024,
        }
    }
}

/// The faces that meet.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Intersections {
    /// Unordered pairs of faces of one component that meet.
    pub self_intersections: usize,
    /// Unordered pairs of faces of different components that meet.
    pub pairs_between: usize,
    /// Pairs `[a, b]` (`a < b`) of components with at least one pair of faces that meet, sorted.
    pub component_pairs: Vec<[u32; 2]>,
    /// The lowest pairs `[f, g]` (`f < g`, sorted) of faces that meet, within or between components,
    /// at most [`Search::kept_pairs`] of them.
    pub pairs: Vec<[u32; 2]>,
    /// The search stopped at its first pair ([`Search::first_only`]) or at its budget
    /// ([`Search::pair_budget`]): the counts are lower bounds.
    pub stopped: bool,
    /// One bit per face: the face meets another face of its component (`[0]`), of another
    /// component (`[1]`).
    involved: [Vec<u64>; 2],
}

impl Intersections {
    /// Pairs of components that meet.
    pub fn intersecting_components(&self) -> usize {
        self.component_pairs.len()
    }

    /// Whether face `t` meets another face.
    pub fn involves(&self, t: u32) -> bool {
        self.involved.iter().any(|bits| {
            bits.get(t as usize / 64)
                .is_some_and(|w| w & (1 << (t % 64)) != 0)
        })
    }

    /// How many faces meet another face.
    pub fn involved_faces(&self) -> usize {
        let [within, between] = &self.involved;
        within
            .iter()
            .zip(between)
            .map(|(a, b)| (a | b).count_ones() as usize)
            .sum()
    }

    /// How many faces meet another face of their own component (`within`) or of another
    /// component: the faces of [`Intersections::self_intersections`] or of
    /// [`Intersections::component_pairs`].
    pub fn involved_faces_in(&self, within: bool) -> usize {
        self.involved[usize::from(!within)]
            .iter()
            .map(|w| w.count_ones() as usize)
            .sum()
    }

    /// The components that component `c` meets, ascending.
    pub fn met_by(&self, c: u32) -> Vec<u32> {
        let mut met: Vec<u32> = self
            .component_pairs
            .iter()
            .filter_map(|&[a, b]| match (a == c, b == c) {
                (true, _) => Some(b),
                (_, true) => Some(a),
                _ => None,
            })
            .collect();
        met.sort_unstable();
        met
    }
}

/// The faces that meet in a mesh already analysed (as the analysis finds them, with `search`),
/// from what the analysis built and its bounding box
/// ([`crate::Analysis::bbox`], which sets the zero-area threshold).
pub fn intersections_built(
    built: &Built,
    bbox: Option<[[f64; 3]; 2]>,
    search: &Search,
) -> Intersections {
    intersect_table(
        &built.welded.positions,
        &built.table,
        &|t| built.component[t as usize],
        ZeroArea::of(bbox),
        Some(&built.source),
        search,
    )
}

/// The faces of `table` (over `points`) that meet, leaving out its zero-area faces (`zero_area`,
/// of the mesh's box). `component` and
/// `number` as in [`Surface`].
pub(crate) fn intersect_table(
    points: &[[f64; 3]],
    table: &CornerTable,
    component: &(dyn Fn(u32) -> u32 + Sync),
    zero_area: ZeroArea,
    number: Option<&[u32]>,
    search: &Search,
) -> Intersections {
    let surface = Surface {
        points,
        table,
        component,
        zero_area,
        number,
    };
    intersect(&surface, search)
}

/// Finds the faces of `surface` that meet.
pub fn intersect(surface: &Surface, search: &Search) -> Intersections {
    let nt = surface.table.triangle_count();
    let triangles = surface.table.triangles();
    let scaled = scaled_points(surface.points);
    let points: &[[f64; 3]] = scaled.as_deref().unwrap_or(surface.points);
    let corners = |t: u32| triangles[t as usize].map(|v| points[v as usize]);
    let box_at = |t: u32| tree::box_of(&corners(t));
    let mut stars = stars::flat_stars(points, surface.table);
    // Pairs within a flat region (faces of one plane that tile it once) are skipped as found.
    let regions = regions::flat_regions(points, surface.table, &stars.turns, &stars.along);

    // The table faces kept, sorted along a Hilbert curve of their box centres over the points'
    // box: keys made in table order (the analysis sorts faces by vertex, so this reads points
    // nearly in order) in one loop on one thread, since runs gathered on every thread and joined
    // were no quicker on two threads (the loop is bound by memory). The boxes are not kept: each
    // is computed once more, into the tree, which costs less than holding 24 bytes a face beside
    // it.
    let grid = points_grid(points);
    let mut keys: Vec<u64> = Vec::with_capacity(nt);
    for t in 0..nt as u32 {
        // The zero-area bound is the mesh's own: measure the face in its own coordinates.
        let own = triangles[t as usize].map(|v| surface.points[v as usize]);
        let [a, b, c] = own;
        if !surface.zero_area.is_zero(cross2(a, b, c), a, b, c)
            && !stars::is_set(&stars.collinear, t)
        {
            // The middle of the face's box (any point near the face orders it as well).
            let p = if scaled.is_some() { corners(t) } else { own };
            let middle = std::array::from_fn(|k| {
                let (x, y, z) = (p[0][k], p[1][k], p[2][k]);
                (0.5 * (x.min(y).min(z) + x.max(y).max(z))) as f32
            });
            keys.push(grid.cell_key(middle, t));
        }
    }
    curve::hilbert(&mut keys);
    curve::sort_keys(&mut keys);
    // The table face at each place of the sorted order.
    let faces: Vec<u32> = keys.iter().map(|&k| k as u32).collect();
    drop(keys);
    // Faces that share a vertex with a flat star meet only there or along an edge they share: the
    // walk skips those pairs. The faces come in the curve's order, their table rows and points
    // scattered in memory: each face fetches ahead the rows of a face two leaves on and the points
    // of the face one leaf on (whose row it fetched a leaf ago), so those loads overlap instead of
    // stalling one by one.
    // The regions each face cannot meet, for whole nodes of walls standing on a plate.
    let covers = regions.covers(surface.table, points);
    let tree = Tree::build(faces.len(), |p| {
        if let Some(&u) = faces.get(p + 16) {
            prefetch(&triangles[u as usize]);
            prefetch(&stars.turns[u as usize]);
        }
        if let Some(&u) = faces.get(p + 8) {
            for v in triangles[u as usize] {
                prefetch(&points[v as usize]);
            }
        }
        let t = faces[p];
        let vertices = triangles[t as usize];
        Placed {
            bounds: box_at(t),
            vertices,
            skipped: (0..3).fold(0, |m, k| {
                m | u8::from(stars::is_set(&stars.flat, vertices[k])) << k
            }),
            bits: stars.turns[t as usize],
            region: regions.of(t),
            covers: covers
                .get(t as usize)
                .copied()
                .unwrap_or([regions::NONE; 2]),
        }
    });
    drop(covers);
    let along = std::mem::take(&mut stars.along);
    drop(stars);
    let mut place = vec![u32::MAX; nt];
    for (p, &t) in faces.iter().enumerate() {
        place[t as usize] = p as u32;
    }

    let numbers = surface
        .number
        .map_or(nt, |n| n.iter().map(|&x| x as usize + 1).max().unwrap_or(0));
    let bits = || -> Vec<AtomicU64> {
        (0..numbers.div_ceil(64))
            .map(|_| AtomicU64::new(0))
            .collect()
    };
    let involved = [bits(), bits()];
    let stop = AtomicBool::new(false);
    let (budget, held) = search.limits(nt);
    let shared = Shared {
        points,
        surface,
        faces: &faces,
        tree: &tree,
        regions: &regions,
        involved: &involved,
        stop: &stop,
        search: *search,
        spent: AtomicU64::new(0),
        budget,
        held,
    };
    let mut finder = Finder {
        shared: &shared,
        tally: Tally::default(),
        looked: 0,
        row: None,
        patches: patches::Patches::new(points, surface.table, &place, &along),
    };
    tree.walk(&mut finder);

    let mut tally = finder.tally;
    tally.tidy(search.kept_pairs);
    Intersections {
        self_intersections: tally.within,
        pairs_between: tally.between,
        component_pairs: tally.components,
        pairs: tally.pairs,
        stopped: stop.load(Relaxed),
        involved: involved.map(|bits| bits.into_iter().map(AtomicU64::into_inner).collect()),
    }
}

/// The curve's grid over the box of the finite `points`, in `f32` (rounded to nearest: the grid
/// counts a point just outside as in the border cell, so rounding only moves a face to a
/// neighbouring cell).
fn points_grid(points: &[[f64; 3]]) -> curve::Grid {
    let finite = points.iter().filter(|p| p.iter().all(|x| x.is_finite()));
    curve::Grid::around(finite.map(|p| p.map(|x| x as f32)))
}

/// The points times a power of two that brings the largest coordinate near 1, when it is beyond
/// 2^100 or below 2^-100 (where products of coordinates could overflow or underflow, or boxes
/// leave the range of `f32`); `None` when they are fine as they are. Scaling by a power of two is
/// exact, so no sign changes.
fn scaled_points(points: &[[f64; 3]]) -> Option<Vec<[f64; 3]>> {
    let [s1, s2] = unit_scale(largest_coordinate(points))?;
    Some(points.iter().map(|p| p.map(|x| x * s1 * s2)).collect())
}

/// What every task of the walk reads and the flags it sets.
struct Shared<'a> {
    points: &'a [[f64; 3]],
    surface: &'a Surface<'a>,
    /// The table face at each place of the sorted order.
    faces: &'a [u32],
    tree: &'a Tree,
    /// The flat regions ([`regions::flat_regions`]).
    regions: &'a regions::Regions,
    /// [`Intersections::involved`], as it is found.
    involved: &'a [Vec<AtomicU64>; 2],
    stop: &'a AtomicBool,
    search: Search,
    /// Pairs looked at by every task, added in batches of [`BATCH`].
    spent: AtomicU64,
    /// The pairs to look at and the pairs of parts to hold before the search stops
    /// ([`Search::pair_budget`]).
    budget: u64,
    held: usize,
}

/// A task adds the pairs it looked at to [`Shared::spent`] this many at a time.
const BATCH: u64 = 1 << 12;

impl Shared<'_> {
    /// Adds `looked` pairs to the pairs spent; past the budget, stops every task.
    fn spend(&self, looked: u64) {
        if self.spent.fetch_add(looked, Relaxed) + looked > self.budget {
            self.stop.store(true, Relaxed);
        }
    }

    /// Stops every task when one holds more distinct pairs of parts than the budget allows.
    fn hold(&self, pairs: usize) {
        if pairs > self.held {
            self.stop.store(true, Relaxed);
        }
    }
}

/// One task's findings.
#[derive(Default)]
struct Tally {
    within: usize,
    between: usize,
    /// Component pairs, deduplicated whenever the list doubles.
    components: Vec<[u32; 2]>,
    components_tidy: usize,
    /// Face pairs, cut back to the lowest `kept_pairs` whenever the list doubles.
    pairs: Vec<[u32; 2]>,
}

impl Tally {
    fn tidy(&mut self, kept: usize) {
        self.components.sort_unstable();
        self.components.dedup();
        self.components_tidy = self.components.len();
        self.pairs.sort_unstable();
        self.pairs.truncate(kept);
    }
}

struct Finder<'a> {
    shared: &'a Shared<'a>,
    tally: Tally,
    /// Pairs looked at and not yet added to [`Shared::spent`].
    looked: u64,
    /// The face of the current row of pairs and its plane.
    row: Option<(u32, meet::Plane)>,
    patches: patches::Patches<'a>,
}

impl Visit for Finder<'_> {
    fn fork(&self) -> Self {
        Finder {
            shared: self.shared,
            tally: Tally::default(),
            looked: 0,
            row: None,
            patches: self.patches.fork(),
        }
    }

    fn merge(&mut self, other: Self) {
        let (t, o) = (&mut self.tally, other.tally);
        t.within += o.within;
        t.between += o.between;
        t.components.extend(o.components);
        t.pairs.extend(o.pairs);
        t.tidy(self.shared.search.kept_pairs);
        self.looked += other.looked;
        if self.looked >= BATCH {
            self.shared.spend(std::mem::take(&mut self.looked));
        }
        self.shared.hold(t.components_tidy);
    }

    fn pair(&mut self, a: u32, b: u32) {
        let s = self.shared;
        self.looked += 1;
        if self.looked == BATCH {
            self.looked = 0;
            s.spend(BATCH);
        }
        let (ta, tb) = (s.faces[a as usize], s.faces[b as usize]);
        // Two faces of one flat region do not meet; a face of a region and a face touching it only
        // at its corners or edges are looked at below, once their points are loaded.
        let regions = if s.regions.is_empty() {
            None
        } else {
            let (ra, rb) = (s.regions.of(ta), s.regions.of(tb));
            if ra != regions::NONE && ra == rb {
                return;
            }
            (ra != regions::NONE || rb != regions::NONE).then_some((ra, rb))
        };
        let (va, vb) = (s.tree.vertices(a), s.tree.vertices(b));
        // Written out: `array::map` here costs as much as the loads.
        let corners = |[a, b, c]: [u32; 3]| {
            [
                s.points[a as usize],
                s.points[b as usize],
                s.points[c as usize],
            ]
        };
        // Pairs come in rows of one face `a` (a leaf's face against its neighbours): its plane is
        // computed once per row.
        if self.row.as_ref().is_some_and(|(r, _)| *r != a) {
            self.row = None;
        }
        let (_, plane) = self.row.get_or_insert_with(|| {
            let [p, q, r] = corners(va);
            (a, meet::Plane::of(p, q, r))
        });
        let pb = corners(vb);
        if let Some((ra, rb)) = regions {
            let (table, pa) = (s.surface.table, plane.corners());
            if (ra != regions::NONE && s.regions.apart(table, ra, pa, tb, vb, pb))
                || (rb != regions::NONE && s.regions.apart(table, rb, pb, ta, va, pa))
            {
                return;
            }
        }
        if !meet::plane_meets(meet::shared(va, vb), plane, pb) {
            return;
        }
        // What the findings need of the two faces: their components and numbers.
        let component = s.surface.component;
        let (ca, cb) = (component(ta), component(tb));
        let number = |t: u32| s.surface.number.map_or(t, |n| n[t as usize]);
        let (na, nb) = (number(ta), number(tb));
        let t = &mut self.tally;
        if ca == cb {
            t.within += 1;
        } else {
            t.between += 1;
            t.components.push([ca.min(cb), ca.max(cb)]);
            if t.components.len() >= 2 * t.components_tidy.max(512) {
                t.components.sort_unstable();
                t.components.dedup();
                t.components_tidy = t.components.len();
                s.hold(t.components_tidy);
            }
        }
        let bits = &s.involved[usize::from(ca != cb)];
        for f in [na, nb] {
            bits[f as usize / 64].fetch_or(1 << (f % 64), Relaxed);
        }
        let kept = s.search.kept_pairs;
        if kept > 0 {
            let (f, g) = (na, nb);
            t.pairs.push([f.min(g), f.max(g)]);
            if t.pairs.len() >= kept.max(256).saturating_mul(2) {
                // The lowest `kept`, in any order (the final tidy sorts them).
                t.pairs.select_nth_unstable(kept);
                t.pairs.truncate(kept);
            }
        }
        if s.search.first_only {
            s.stop.store(true, Relaxed);
        }
    }

    fn done(&self) -> bool {
        self.shared.stop.load(Relaxed)
    }

    fn no_pairs_within(&mut self, places: std::ops::Range<usize>, bits: u8) -> bool {
        let faces = self.shared.faces;
        self.patches.is_flat(places, bits, |p| faces[p])
    }
}
