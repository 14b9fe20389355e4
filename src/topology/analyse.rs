//! The one pass from a mesh to its [`Analysis`]:
//!
//! 1. weld positions, leave out invalid and degenerate faces and build the Corner Table
//!    ([`super::built`]); count zero-area faces;
//! 2. walk **patches** (faces linked through manifold edges) with an orientation parity per face: a
//!    conflict makes the patch non-orientable; patches joined at non-manifold edges form the
//!    **components**;
//! 3. walk the **fan** of every corner (faces around its vertex linked through manifold edges): a vertex
//!    with more than one fan is non-manifold; fans also pair the border edges at each vertex, which
//!    traces the **holes** on the undirected border;
//! 4. per component: V, E, F, chi, holes, genus;
//! 5. the pairs of faces that meet ([`super::intersect`]), within and between components;
//! 6. per shell (closed, manifold component): volume, then nesting depth among the shells it does not
//!    meet, role and orientation.
//!
//! Every walk is iterative; every step is linear in the number of corners, except nesting (pruned by
//! bounding boxes).

use super::built::{build, cross2, on_every_thread, Built, LeftOut, ZeroArea};
use super::intersect::intersect_table;
use super::nesting::{depths, ShellGeometry};
use super::sets::{find, union};
use super::{Analysis, Component, Options, Role, Shell};
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

use rayon::prelude::*;

use crate::corner_table::{CornerTable, NON_MANIFOLD};
use crate::geometry::{bounding_box, by_position, cross, dist2, dot, sub};
use crate::mesh::Mesh;
use crate::pages::prefetch;

const UNSET: u32 = u32::MAX;

/// Computes every topological fact of [the definitions](crate::definitions) for one mesh.
pub fn analyse(mesh: &Mesh, options: &Options) -> Analysis {
    analyse_keeping(mesh, options).0
}

/// [`analyse`], keeping what it built.
pub fn analyse_keeping(mesh: &Mesh, options: &Options) -> (Analysis, Built) {
    let built = build(mesh, options);
    analyse_built(built, mesh.positions.len(), mesh.triangles.len(), options)
}

/// [`analyse_keeping`], freeing `mesh`'s positions and faces (left empty) as soon as the analysis
/// has built its own from them, for a caller that needs no more of the mesh than its name, notes
/// and counts: a big mesh's search for faces that meet, where a scan's memory peaks, then runs
/// without them (on an 871k-face mesh a fifth less memory, which the kernel must otherwise fault
/// in and zero).
pub fn analyse_releasing(mesh: &mut Mesh, options: &Options) -> (Analysis, Built) {
    let built = build(mesh, options);
    let (vertices, faces) = (mesh.positions.len(), mesh.triangles.len());
    mesh.positions = Vec::new();
    mesh.triangles = Vec::new();
    analyse_built(built, vertices, faces, options)
}

/// The analysis of what [`build`] made of a mesh of `vertices` positions and `faces` faces.
fn analyse_built(
    (built, left): (Built, LeftOut),
    vertices: usize,
    faces: usize,
    options: &Options,
) -> (Analysis, Built) {
    let Built { welded, table, .. } = &built;
    let points = &welded.positions;
    let mut a = Analysis {
        vertices,
        welded_vertices: points.len(),
        faces,
        invalid_vertices: welded.invalid,
        invalid_faces: left.invalid_faces,
        degenerate_faces: left.degenerate_faces,
        unreferenced_vertices: left.unreferenced_vertices,
        bbox: bounding_box(points),
        ..Analysis::default()
    };

    // A big mesh on a pool of more than one thread runs the independent passes side by side (each
    // pass is the same as on one thread, so the analysis is too).
    let big = on_every_thread(faces);
    let runs = if big { rayon::current_num_threads() } else { 1 };

    // 1. Faces: count zero-area ones (the table holds the valid, non-degenerate ones); it reads no
    // other step's result, so it runs beside the shells (below), the one step that cannot be
    // split over threads.
    let zero_area = ZeroArea::of(a.bbox);
    let faces_pass = || {
        // Areas in vertex order: neighbouring faces share vertices, so their positions are mostly
        // in cache (in input order a shuffled mesh misses it for nearly every corner).
        let (mut zero_faces, mut area) = (0, 0.0);
        for t in table.triangles() {
            // Written out: `array::map` is not inlined here.
            let [p, q, r] = [
                points[t[0] as usize],
                points[t[1] as usize],
                points[t[2] as usize],
            ];
            let cross2 = cross2(p, q, r);
            if zero_area.is_zero(cross2, p, q, r) {
                zero_faces += 1;
            }
            area += 0.5 * cross2.sqrt();
        }
        (zero_faces, area, count_duplicates(table))
    };

    // 2. Patches with orientation parity, then components.
    let mut patches = walk_patches(table, runs);
    let component_of_patch = join_patches(table, &patches, &built.source);
    a.edges = table.edge_count();
    a.border_edges = table.border_edge_count();
    a.nonmanifold_edges = table.nonmanifold_edges().len();

    let component_count = component_of_patch
        .iter()
        .map(|&c| c as usize + 1)
        .max()
        .unwrap_or(0);
    // Each face's patch becomes its component, in place: the walks below, the search for faces
    // that meet and a later repair read it.
    let mut component = std::mem::take(&mut patches.of_face);
    for c in &mut component {
        *c = component_of_patch[*c as usize];
    }
    let component_of = |t: u32| component[t as usize] as usize;

    let mut components = vec![Component::default(); component_count];
    for c in &mut components {
        c.orientable = true;
    }
    for (p, &orientable) in patches.orientable.iter().enumerate() {
        components[component_of_patch[p] as usize].orientable &= orientable;
    }
    let mut inconsistent = vec![0usize; component_count];
    for (p, counts) in patches.counts.iter().enumerate() {
        let comp = component_of_patch[p] as usize;
        inconsistent[comp] += counts.inconsistent;
        let c = &mut components[comp];
        c.faces += counts.faces;
        c.edges += counts.manifold_edges + counts.border_edges;
        c.border_edges += counts.border_edges;
    }
    for corners in table.nonmanifold_edges() {
        let comp = &mut components[component_of(CornerTable::t(corners[0]))];
        comp.edges += 1;
        comp.nonmanifold_edges += 1;
    }
    a.inconsistent_edges = inconsistent.iter().sum();

    // 3. Fans: non-manifold vertices, vertices per component, holes, then 4. the per component
    // numbers and 6. the shells' volumes (beside 1.); beside 5. the faces that meet, within a
    // component and between components (the shells' nesting, which needs those, comes after).
    let faces = Faces {
        table,
        points,
        patches: &patches,
    };
    let fans_pass = || {
        let mut fans = walk_fans(table, &component_of, runs);
        count_per_component(&mut components, &fans, &inconsistent, component_of);
        let shells_pass = || shells(&faces, &component_of, &components, &fans.fans);
        let (shells, face_counts) = side_by_side(big, shells_pass, faces_pass);
        // The list of fans (8 bytes a vertex) is the shells' alone: freed before the search for
        // faces that meet, where a one-thread analysis holds the most memory.
        fans.fans = Vec::new();
        (fans, components, shells, face_counts)
    };
    let search_pass = || {
        options.intersections.map(|search| {
            let component_of = |t: u32| component[t as usize];
            intersect_table(
                points,
                table,
                &component_of,
                zero_area,
                Some(&built.source),
                &search,
            )
        })
    };
    let ((fans, components, (mut shells, shell_of), face_counts), intersections) =
        side_by_side(big, fans_pass, search_pass);
    (a.zero_area_faces, a.area, a.duplicate_faces) = face_counts;
    a.intersections = intersections;
    a.nonmanifold_vertices = fans.nonmanifold_vertices;
    a.euler = fans.used_vertices as i64 - a.edges as i64 + table.triangle_count() as i64;

    let meeting: &[[u32; 2]] = a
        .intersections
        .as_ref()
        .map_or(&[], |i| i.component_pairs.as_slice());
    nest(&faces, &component_of, &mut shells, &shell_of, meeting);
    a.shells = shells;
    a.components = components;
    let manifold = a.nonmanifold_edges == 0 && a.nonmanifold_vertices == 0;
    (
        a,
        Built {
            manifold,
            component,
            ..built
        },
    )
}

/// `x()` and `y()`, side by side on the current pool when `big`.
fn side_by_side<A: Send, B: Send>(
    big: bool,
    x: impl FnOnce() -> A + Send,
    y: impl FnOnce() -> B + Send,
) -> (A, B) {
    if big {
        rayon::join(x, y)
    } else {
        (x(), y())
    }
}

/// Faces linked through manifold edges, each face with a parity: flipping the faces with parity
/// `true` makes every manifold edge of an orientable patch consistent.
struct Patches {
    of_face: Vec<u32>,
    flip: Vec<bool>,
    orientable: Vec<bool>,
    /// What each patch holds, counted during the walk.
    counts: Vec<PatchCounts>,
}

/// A patch's faces and edges (each manifold edge once, from its lower corner), and its
/// inconsistent (same-direction) manifold edges.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct PatchCounts {
    faces: usize,
    manifold_edges: usize,
    border_edges: usize,
    inconsistent: usize,
}

/// One word per face while walking: the patch in the low 31 bits, the parity in the top bit, so
/// reaching a neighbour costs one memory access.
const FLIP: u32 = 1 << 31;

/// The patches of `table`, walked on `runs` runs of faces side by side (one run: the plain walk).
///
/// Each run walks the patches of its own faces and keeps the manifold edges that leave it; the
/// patches of different runs that such an edge links are then joined, with the parity between
/// them, by a union-find. Its root is always a set's lowest run patch, whose seed is the joined
/// patch's lowest face, so the patches come out numbered as one walk numbers them and the flips of
/// an orientable patch as one walk sets them (those of a patch that is not orientable depend on
/// the walk, and nothing reads them).
fn walk_patches(table: &CornerTable, runs: usize) -> Patches {
    let nt = table.triangle_count();
    let mut state = vec![UNSET; nt];
    let run = nt.div_ceil(runs.max(1)).max(1);
    let walked: Vec<RunPatches> = if runs > 1 {
        state
            .par_chunks_mut(run)
            .enumerate()
            .map(|(r, state)| walk_run(table, r * run, state))
            .collect()
    } else {
        state
            .chunks_mut(run)
            .enumerate()
            .map(|(r, state)| walk_run(table, r * run, state))
            .collect()
    };
    if walked.len() <= 1 {
        let RunPatches {
            orientable, counts, ..
        } = walked.into_iter().next().unwrap_or_default();
        let flip = state.iter().map(|&s| s & FLIP != 0).collect();
        for s in &mut state {
            *s &= !FLIP;
        }
        return Patches {
            of_face: state,
            flip,
            orientable,
            counts,
        };
    }

    // The runs' patches as one list (run `r`'s patch `p` is `first[r] + p`), joined across the
    // edges between runs: `parity[x]` is whether `x`'s faces flip against its parent's.
    let mut first = Vec::with_capacity(walked.len());
    let mut total = 0u32;
    for w in &walked {
        first.push(total);
        total += w.counts.len() as u32;
    }
    let mut parent: Vec<u32> = (0..total).collect();
    let mut parity = vec![false; total as usize];
    let mut conflicts = Vec::new();
    let word = |t: u32| state[t as usize];
    let patch = |t: u32| first[t as usize / run] + (word(t) & !FLIP);
    for (r, w) in walked.iter().enumerate() {
        for &(c, b) in &w.leaving {
            let (t, u) = (CornerTable::t(c), CornerTable::t(b));
            debug_assert_eq!(t as usize / run, r);
            // Across a consistent edge both faces flip alike, across an inconsistent one not.
            let flips_differ = (word(t) ^ word(u)) & FLIP != 0;
            let apart = flips_differ == table.is_consistent(c);
            let (x, y) = (patch(t), patch(u));
            if !join_with_parity(&mut parent, &mut parity, x, y, apart) {
                conflicts.push(x);
            }
        }
    }

    // One number per joined patch, in order of its root (its lowest run patch, so met first);
    // the parity of each run patch against that root.
    let mut id_of = vec![UNSET; total as usize];
    let mut to_root = vec![false; total as usize];
    let mut orientable = Vec::new();
    let mut counts: Vec<PatchCounts> = Vec::new();
    let run_patches = walked
        .iter()
        .flat_map(|w| w.orientable.iter().zip(&w.counts));
    for (x, (&ok, n)) in run_patches.enumerate() {
        let (root, p) = find_with_parity(&mut parent, &mut parity, x as u32);
        debug_assert!(root as usize <= x, "a root is its set's lowest run patch");
        to_root[x] = p;
        if root as usize == x {
            orientable.push(true);
            counts.push(PatchCounts::default());
            id_of[x] = orientable.len() as u32 - 1;
        } else {
            id_of[x] = id_of[root as usize];
        }
        let id = id_of[x] as usize;
        orientable[id] &= ok;
        counts[id].add(n);
    }
    for x in conflicts {
        orientable[id_of[x as usize] as usize] = false;
    }
    let mut flip = vec![false; nt];
    state
        .par_chunks_mut(run)
        .zip(flip.par_chunks_mut(run))
        .enumerate()
        .for_each(|(r, (state, flip))| {
            for (s, f) in state.iter_mut().zip(flip) {
                let x = (first[r] + (*s & !FLIP)) as usize;
                *f = (*s & FLIP != 0) != to_root[x];
                *s = id_of[x];
            }
        });
    Patches {
        of_face: state,
        flip,
        orientable,
        counts,
    }
}

/// The patches a run of faces (`start..start + state.len()`) walks within itself.
#[derive(Default)]
struct RunPatches {
    orientable: Vec<bool>,
    counts: Vec<PatchCounts>,
    /// Manifold edges to a face of another run, as corner pairs `(c, b)` with `c` in this run and
    /// `c < b` (so each edge is kept by one run).
    leaving: Vec<(u32, u32)>,
}

/// Walks the patches of faces `start..start + state.len()` through the manifold edges between
/// them, numbering them from 0 in `state` (with the parity bit [`FLIP`]), and counts each patch's
/// faces and edges: an edge to a face of another run is counted here when `c < b` and kept.
fn walk_run(table: &CornerTable, start: usize, state: &mut [u32]) -> RunPatches {
    let o = table.opposites();
    let end = start + state.len();
    let mut walked = RunPatches::default();
    // Breadth first, so that a face's row is fetched when the face is queued and read only when
    // the front reaches it (a walk's front on a surface holds about the square root of its
    // faces); a stack reads the row it just pushed at once and stalls on it (13 ms of the
    // Stanford dragon's 36). A face's neighbours' states are fetched a few faces before it
    // (4 ms more).
    let mut queue = std::collections::VecDeque::new();
    for seed in 0..state.len() {
        if state[seed] != UNSET {
            continue;
        }
        let id = walked.orientable.len() as u32;
        let mut ok = true;
        let mut n = PatchCounts::default();
        state[seed] = id;
        queue.push_back((start + seed) as u32);
        while let Some(t) = queue.pop_front() {
            // Eight faces on, a queued face's row has landed: fetch its neighbours' states.
            if let Some(&q) = queue.get(8) {
                for &b in &o[3 * q as usize..3 * q as usize + 3] {
                    if let Some(s) = state.get((CornerTable::t(b) as usize).wrapping_sub(start)) {
                        prefetch(s);
                    }
                }
            }
            n.faces += 1;
            let flip = state[t as usize - start] & FLIP;
            for c in 3 * t..3 * t + 3 {
                let b = o[c as usize];
                if b == c {
                    n.border_edges += 1;
                    continue;
                }
                if b == NON_MANIFOLD {
                    continue;
                }
                let u = CornerTable::t(b) as usize;
                let consistent = table.is_consistent(c);
                n.manifold_edges += usize::from(c < b);
                n.inconsistent += usize::from(!consistent && c < b);
                // `u` outside `start..end`, written so that the compiler sees the index below is
                // in `state` (15% fewer instructions in this walk).
                if u.wrapping_sub(start) >= end - start {
                    if c < b {
                        walked.leaving.push((c, b));
                    }
                    continue;
                }
                let want = id | if consistent { flip } else { flip ^ FLIP };
                let s = &mut state[u - start];
                if *s == UNSET {
                    *s = want;
                    prefetch(&o[3 * u]);
                    queue.push_back(u as u32);
                } else if *s != want {
                    ok = false;
                }
            }
        }
        walked.orientable.push(ok);
        walked.counts.push(n);
    }
    walked
}

impl PatchCounts {
    fn add(&mut self, other: &PatchCounts) {
        self.faces += other.faces;
        self.manifold_edges += other.manifold_edges;
        self.border_edges += other.border_edges;
        self.inconsistent += other.inconsistent;
    }
}

/// The root of `x` in a union-find whose links carry a parity, and `x`'s parity against it; the
/// path is pointed at the root.
fn find_with_parity(parent: &mut [u32], parity: &mut [bool], x: u32) -> (u32, bool) {
    let (mut root, mut p) = (x, false);
    while parent[root as usize] != root {
        p ^= parity[root as usize];
        root = parent[root as usize];
    }
    // Second pass: each node on the path gets its parity against the root, from `x` up.
    let (mut y, mut py) = (x, p);
    while parent[y as usize] != y {
        let (up, p_up) = (parent[y as usize], py ^ parity[y as usize]);
        parent[y as usize] = root;
        parity[y as usize] = py;
        (y, py) = (up, p_up);
    }
    (root, p)
}

/// Joins the sets of `x` and `y` with `x`'s faces flipping against `y`'s when `apart`; `false` when
/// they were one set already with the other parity (the joined patch is not orientable).
fn join_with_parity(parent: &mut [u32], parity: &mut [bool], x: u32, y: u32, apart: bool) -> bool {
    let (rx, px) = find_with_parity(parent, parity, x);
    let (ry, py) = find_with_parity(parent, parity, y);
    if rx == ry {
        return (px != py) == apart;
    }
    // x = rx ^ px, y = ry ^ py, and x ^ y = apart: so rx ^ ry = apart ^ px ^ py.
    let (low, high) = (rx.min(ry), rx.max(ry));
    parent[high as usize] = low;
    parity[high as usize] = apart != (px != py);
    true
}

/// Component of each patch: patches sharing a non-manifold edge are one component. Components are
/// numbered in order of their lowest input face.
fn join_patches(table: &CornerTable, patches: &Patches, source: &[u32]) -> Vec<u32> {
    let count = patches.orientable.len();
    let mut parent: Vec<u32> = (0..count as u32).collect();
    for corners in table.nonmanifold_edges() {
        let first = patches.of_face[CornerTable::t(corners[0]) as usize];
        for &c in &corners[1..] {
            union(
                &mut parent,
                first,
                patches.of_face[CornerTable::t(c) as usize],
            );
        }
    }
    let mut lowest = vec![u32::MAX; count];
    for (t, &p) in patches.of_face.iter().enumerate() {
        let root = find(&mut parent, p) as usize;
        lowest[root] = lowest[root].min(source[t]);
    }
    let mut roots: Vec<u32> = (0..count as u32)
        .filter(|&p| parent[p as usize] == p)
        .collect();
    roots.sort_unstable_by_key(|&r| lowest[r as usize]);
    let mut number = vec![UNSET; count];
    for (i, &r) in roots.iter().enumerate() {
        number[r as usize] = i as u32;
    }
    (0..count as u32)
        .map(|p| number[find(&mut parent, p) as usize])
        .collect()
}

/// Extra copies of faces with the same three vertices. Copies of `{x < y < z}` all bound the edge
/// `y-z` with `x` as the opposite vertex, so each set is counted once, on that edge: at a manifold
/// edge the two faces' corners at their lowest vertices face each other with one vertex; at a
/// non-manifold edge the repeated lowest vertices among its faces' corners are the extra copies.
fn count_duplicates(table: &CornerTable) -> usize {
    let mut count = 0;
    // Only a face's corner at its lowest vertex has its vertex below both ends of its edge.
    for (t, f) in table.triangles().iter().enumerate() {
        let k = if f[0] < f[1] {
            if f[0] < f[2] {
                0
            } else {
                2
            }
        } else if f[1] < f[2] {
            1
        } else {
            2
        };
        let c = (3 * t + k) as u32;
        if let Some(b) = table.opposite(c) {
            count += usize::from(c < b && table.v(b) == f[k]);
        }
    }
    count + duplicates_at_nonmanifold_edges(table)
}

/// The extra copies among the faces of non-manifold edges: the repeated opposite vertices below
/// the edge's lower end.
fn duplicates_at_nonmanifold_edges(table: &CornerTable) -> usize {
    let edge_min = |c: u32| table.v(CornerTable::n(c)).min(table.v(CornerTable::p(c)));
    let mut apex = Vec::new();
    let mut count = 0;
    for corners in table.nonmanifold_edges() {
        let low = edge_min(corners[0]);
        apex.clear();
        apex.extend(corners.iter().map(|&c| table.v(c)).filter(|&x| x < low));
        apex.sort_unstable();
        count += apex.windows(2).filter(|w| w[0] == w[1]).count();
    }
    count
}

#[derive(Debug, PartialEq)]
struct Fans {
    nonmanifold_vertices: usize,
    used_vertices: usize,
    vertices_per_component: Vec<usize>,
    /// Components that have two or more fans around one vertex (not manifold).
    split_components: Vec<usize>,
    /// One border corner per hole (boundary loop).
    hole_corners: Vec<u32>,
    /// `(vertex, component)` of every fan: each vertex of each component at least once.
    fans: Vec<(u32, u32)>,
}

/// How a fan walk ended on one side.
#[derive(Clone, Copy, PartialEq)]
enum FanEnd {
    /// At a border edge, named by the corner facing it.
    Border(u32),
    NonManifold,
    /// Back at the start: the fan is a full disk.
    Closed,
}

/// Walks the fan of every corner: the faces around `v(c)` linked through manifold edges at `v(c)`.
/// Works on any windings (see the walk in [`fans_of_run`]).
///
/// On `runs` runs of corners side by side: a run walks every fan with a corner in it and keeps the
/// fans whose lowest corner is its own (in order of that corner, as one walk of all corners finds
/// them), so each fan is kept once and the runs' lists joined are the one-run list.
fn walk_fans(
    table: &CornerTable,
    component_of: &(impl Fn(u32) -> usize + Sync),
    runs: usize,
) -> Fans {
    let nc = table.corner_count();
    let nv = table.vertex_count();
    // Runs of whole 64-corner words, so each run has its own words of `visited`.
    let run = nc.div_ceil(runs.max(1)).div_ceil(64).max(1) * 64;
    let shared = runs > 1;
    let mut visited = vec![0u64; nc.div_ceil(64)];
    let fan_count: Vec<AtomicU32> = (0..nv).map(|_| AtomicU32::new(0)).collect();
    let first_component: Vec<AtomicU32> = (0..nv).map(|_| AtomicU32::new(UNSET)).collect();
    let walk_run = |(r, visited): (usize, &mut [u64])| {
        fans_of_run(
            table,
            component_of,
            r * run,
            nc.min((r + 1) * run),
            visited,
            &|v| bump(&fan_count[v as usize], shared),
            &|v, comp| first_component[v as usize].store(comp, Relaxed),
        )
    };
    let walked: Vec<RunFans> = if shared {
        visited
            .par_chunks_mut(run / 64)
            .enumerate()
            .map(walk_run)
            .collect()
    } else {
        visited
            .chunks_mut(run / 64)
            .enumerate()
            .map(walk_run)
            .collect()
    };
    drop(visited);
    let mut vertices_per_component = Vec::new();
    let (mut multi, mut joins, mut lone, mut fans) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for w in walked {
        if vertices_per_component.len() < w.vertices_per_component.len() {
            vertices_per_component.resize(w.vertices_per_component.len(), 0);
        }
        for (n, m) in vertices_per_component
            .iter_mut()
            .zip(&w.vertices_per_component)
        {
            *n += m;
        }
        // A vertex's second fan adds its first one (its component known now every run is done).
        for (v, comp, count) in w.repeats {
            if count == 1 {
                multi.push((v, first_component[v as usize].load(Relaxed)));
            }
            multi.push((v, comp));
        }
        join(&mut joins, w.joins);
        join(&mut lone, w.lone);
        join(&mut fans, w.fans);
    }
    let fan_count: Vec<u32> = fan_count.into_iter().map(AtomicU32::into_inner).collect();
    let used_vertices = fan_count.iter().filter(|&&n| n > 0).count();
    let nonmanifold_vertices = fan_count.iter().filter(|&&n| n > 1).count();

    // A component with two fans at one vertex has one vertex fewer than fans, and is not manifold.
    multi.sort_unstable();
    let mut split_components = Vec::new();
    for w in multi.windows(2) {
        if w[0] == w[1] {
            vertices_per_component[w[0].1 as usize] -= 1;
            split_components.push(w[0].1 as usize);
        }
    }
    split_components.dedup();

    // Holes: border edges joined at their ends by fans. Where the swing stops at a non-manifold edge
    // it cannot choose the next border edge, so the lone ends of one component at one vertex are one
    // loop; lone ends of different components meeting at a vertex stay apart (a component's holes
    // are its own).
    let border: Vec<u32> = if table.border_edge_count() == 0 {
        Vec::new()
    } else if shared {
        (0..nc as u32)
            .into_par_iter()
            .filter(|&c| table.is_border(c))
            .collect()
    } else {
        (0..nc as u32).filter(|&c| table.is_border(c)).collect()
    };
    let index = |c: u32| border.binary_search(&c).expect("border corner") as u32;
    let mut parent: Vec<u32> = (0..border.len() as u32).collect();
    for &(x, y) in &joins {
        union(&mut parent, index(x), index(y));
    }
    lone.sort_unstable();
    for w in lone.windows(2) {
        if (w[0].0, w[0].1) == (w[1].0, w[1].1) {
            union(&mut parent, index(w[0].2), index(w[1].2));
        }
    }
    let hole_corners = (0..border.len() as u32)
        .filter(|&i| find(&mut parent, i) == i)
        .map(|i| border[i as usize])
        .collect();

    Fans {
        nonmanifold_vertices,
        used_vertices,
        vertices_per_component,
        split_components,
        hole_corners,
        fans,
    }
}

/// What the shell pass reads of the faces.
struct Faces<'a> {
    table: &'a CornerTable,
    points: &'a [[f64; 3]],
    patches: &'a Patches,
}

/// What a run of corners finds of the fans it keeps.
struct RunFans {
    vertices_per_component: Vec<usize>,
    /// `(vertex, component, fans at the vertex before)` of every fan that is not its vertex's
    /// first.
    repeats: Vec<(u32, u32, u32)>,
    /// Border edges whose ends are joined at a vertex, as corner pairs.
    joins: Vec<(u32, u32)>,
    /// Lone ends (a fan that ends at a border on one side and at a non-manifold edge on the
    /// other), as `(vertex, component, corner)`.
    lone: Vec<(u32, u32, u32)>,
    fans: Vec<(u32, u32)>,
}

/// The fans with a corner in `lo..hi` (whose bits of `visited` start at `lo`), keeping those whose
/// lowest corner is in the run; `count(v)` counts a kept fan at `v`, returning the count before,
/// and `first(v, comp)` records the component of a vertex's first one.
fn fans_of_run(
    table: &CornerTable,
    component_of: &impl Fn(u32) -> usize,
    lo: usize,
    hi: usize,
    visited: &mut [u64],
    count: &impl Fn(u32) -> u32,
    first: &impl Fn(u32, u32),
) -> RunFans {
    let mut found = RunFans {
        vertices_per_component: Vec::new(),
        repeats: Vec::new(),
        joins: Vec::new(),
        lone: Vec::new(),
        fans: Vec::new(),
    };
    let lo32 = lo as u32;

    // The unvisited corners in order, found a word of `visited` at a time (most corners are
    // visited by the walk of a fan started at an earlier one).
    let n = hi - lo;
    let mut next = 0usize;
    while next < n {
        let word = visited[next / 64] | ((1u64 << (next % 64)) - 1);
        if word == u64::MAX {
            next = (next / 64 + 1) * 64;
            continue;
        }
        let i = (next / 64) * 64 + (!word).trailing_zeros() as usize;
        if i >= n {
            break;
        }
        next = i + 1;
        set_bit(visited, i as u32);
        let c = (lo + i) as u32;
        let mut lowest = c;
        let ahead = walk_side(table, c, true, lo32, visited, &mut lowest);
        let behind = if ahead == FanEnd::Closed {
            FanEnd::Closed
        } else {
            walk_side(table, c, false, lo32, visited, &mut lowest)
        };
        if lowest < lo32 {
            // An earlier run keeps it.
            continue;
        }
        let v = table.v(c);
        let comp = component_of(CornerTable::t(c));
        if found.vertices_per_component.len() <= comp {
            found.vertices_per_component.resize(comp + 1, 0);
        }
        found.vertices_per_component[comp] += 1;
        found.fans.push((v, comp as u32));
        match count(v) {
            0 => first(v, comp as u32),
            before => found.repeats.push((v, comp as u32, before)),
        }
        match (ahead, behind) {
            (FanEnd::Border(x), FanEnd::Border(y)) => found.joins.push((x, y)),
            (FanEnd::Border(x), _) | (_, FanEnd::Border(x)) => found.lone.push((v, comp as u32, x)),
            _ => {}
        }
    }
    found
}

/// One side of the fan around `v(start)`: from the corner at the vertex in one face, leave through
/// the edge opposite `exit` (`p(c)` or `n(c)`), find the corner at the vertex in the face across,
/// and go on through its other edge at the vertex. With the pair consistent, leaving through the
/// edge opposite `p(c)` arrives at `p(o)`; an inconsistent pair mirrors that. So no step re-reads
/// `V`. A fan is a cycle or a path of corners, so a walk ends at a border, at a non-manifold edge
/// or back at its start. Every corner passed is marked in `visited` (whose bit 0 is corner `lo`;
/// corners past its end belong to another run) and taken into `lowest`.
#[inline(always)]
fn walk_side(
    table: &CornerTable,
    start: u32,
    exit_is_p: bool,
    lo: u32,
    visited: &mut [u64],
    lowest: &mut u32,
) -> FanEnd {
    let o = table.opposites();
    let mut exit_is_p = exit_is_p;
    let mut exit = if exit_is_p {
        CornerTable::p(start)
    } else {
        CornerTable::n(start)
    };
    let mut least = *lowest;
    // A walk passes each corner at most once; the bound only guards against a table that is not
    // one (a walk that never came back would otherwise not end).
    for _ in 0..o.len() + 1 {
        let across = o[exit as usize];
        if across == exit {
            *lowest = least;
            return FanEnd::Border(exit);
        }
        if across == NON_MANIFOLD {
            *lowest = least;
            return FanEnd::NonManifold;
        }
        exit_is_p ^= !table.is_consistent(exit);
        // The face's other two corners, `p(across)` and `n(across)`, from one division: the
        // places of a face's three corners add up to 3.
        let first = across / 3 * 3;
        let p = if across == first {
            across + 2
        } else {
            across - 1
        };
        let n = first + 3 - (across - first) - (p - first);
        let (d, next) = if exit_is_p { (p, n) } else { (n, p) };
        debug_assert_eq!(table.v(d), table.v(start));
        if d == start {
            *lowest = least;
            return FanEnd::Closed;
        }
        least = least.min(d);
        let i = d.wrapping_sub(lo);
        if let Some(word) = visited.get_mut(i as usize / 64) {
            *word |= 1 << (i % 64);
        }
        exit = next;
    }
    debug_assert!(false, "a fan walk from corner {start} did not end");
    *lowest = least;
    FanEnd::Closed
}

/// Step 4 of the analysis: each component's vertices and holes from its fans, then whether it is
/// closed, manifold and oriented, its Euler characteristic and genus.
fn count_per_component(
    components: &mut [Component],
    fans: &Fans,
    inconsistent: &[usize],
    component_of: impl Fn(u32) -> usize,
) {
    for (comp, &n) in fans.vertices_per_component.iter().enumerate() {
        components[comp].vertices = n;
    }
    for &corner in &fans.hole_corners {
        components[component_of(CornerTable::t(corner))].holes += 1;
    }
    let mut split = vec![false; components.len()];
    for &comp in &fans.split_components {
        split[comp] = true;
    }
    for (i, c) in components.iter_mut().enumerate() {
        c.closed = c.border_edges == 0 && c.nonmanifold_edges == 0;
        c.manifold = c.nonmanifold_edges == 0 && !split[i];
        c.inconsistent_edges = inconsistent[i];
        c.oriented = inconsistent[i] == 0;
        c.euler = c.vertices as i64 - c.edges as i64 + c.faces as i64;
        let twice_genus = 2 - c.euler - c.holes as i64;
        c.genus = (c.manifold && c.orientable && twice_genus >= 0 && twice_genus % 2 == 0)
            .then_some(twice_genus / 2);
    }
}

/// Appends `more` to `list`, taking it whole when `list` is empty (one run's list, on one
/// thread always) instead of copying it into fresh memory: the copy of the dragon's 3.5 MB list
/// of fans was 5% of `perf`'s samples of a cold one-thread scan (in wall time, inside the noise).
fn join<T>(list: &mut Vec<T>, mut more: Vec<T>) {
    if list.is_empty() {
        std::mem::swap(list, &mut more);
    }
    list.append(&mut more);
}

/// Adds one to `n`, returning what it was: atomically when `shared` between threads.
fn bump(n: &AtomicU32, shared: bool) -> u32 {
    if shared {
        n.fetch_add(1, Relaxed)
    } else {
        let x = n.load(Relaxed);
        n.store(x + 1, Relaxed);
        x
    }
}

/// Sets bit `i`.
fn set_bit(bits: &mut [u64], i: u32) {
    bits[i as usize / 64] |= 1 << (i % 64);
}

/// The shells (closed, manifold components) with volume and bounding box, and the shell of each
/// component ([`UNSET`] for one that is not a shell); [`nest`] gives them depth, role and
/// orientation.
fn shells(
    faces: &Faces,
    component_of: &impl Fn(u32) -> usize,
    components: &[Component],
    fans: &[(u32, u32)],
) -> (Vec<Shell>, Vec<u32>) {
    let mut shell_of = vec![UNSET; components.len()];
    let mut shells: Vec<Shell> = Vec::new();
    for (i, c) in components.iter().enumerate() {
        // A closed component that is not manifold only because a vertex is pinched (its edges
        // all have valence 2) still bounds a volume when it can be wound consistently.
        let pinched = c.closed && !c.manifold && c.orientable;
        if c.closed && c.manifold || pinched {
            shell_of[i] = shells.len() as u32;
            shells.push(Shell {
                component: i,
                faces: c.faces,
                vertices: c.vertices,
                genus: c.genus,
                orientable: c.orientable,
                oriented: c.oriented,
                pinched,
                bbox: [[f64::INFINITY; 3], [f64::NEG_INFINITY; 3]],
                ..Shell::default()
            });
        }
    }
    if shells.is_empty() {
        return (shells, shell_of);
    }
    // Bounding box and P, the mean of the shell's vertices (each fan of a vertex in the shell
    // once: a shell's vertices have one fan each, a pinched vertex one per fan, which moves P a
    // little and the volume not at all).
    let mut mean = vec![[0.0f64; 3]; shells.len()];
    let mut count = vec![0usize; shells.len()];
    for &(v, comp) in fans {
        let s = shell_of[comp as usize];
        if s != UNSET {
            let p = &faces.points[v as usize];
            let bbox = &mut shells[s as usize].bbox;
            for k in 0..3 {
                bbox[0][k] = bbox[0][k].min(p[k]);
                bbox[1][k] = bbox[1][k].max(p[k]);
                mean[s as usize][k] += p[k];
            }
            count[s as usize] += 1;
        }
    }
    for (m, &n) in mean.iter_mut().zip(&count) {
        *m = m.map(|x| x / n as f64);
    }

    // Six times the volume, `sum mp(A-P, B-P, C-P)`, with the faces of parity `true` negated: the
    // winding of the faces of parity `false`. The shell's winding is the majority's; on a tie, that of
    // the face that comes first by position (below), so no numbering decides it.
    let nt = faces.table.triangle_count() as u32;
    let flip = &faces.patches.flip;
    let triangles = faces.table.triangles();
    let mut flipped = vec![0usize; shells.len()];
    let mut six_volume = vec![0.0f64; shells.len()];
    for ((t, &[i, j, k]), &flip) in (0..nt).zip(triangles).zip(flip) {
        let s = shell_of[component_of(t)];
        if s != UNSET {
            let s = s as usize;
            // Written out: `array::map` is not inlined here.
            let point = |i: u32| sub(faces.points[i as usize], mean[s]);
            let (a, b, c) = (point(i), point(j), point(k));
            let term = dot(a, cross(b, c));
            flipped[s] += usize::from(flip);
            six_volume[s] += if flip { -term } else { term };
        }
    }
    let tied: Vec<bool> = shells
        .iter()
        .zip(&flipped)
        .map(|(shell, &f)| shell.orientable && 2 * f == shell.faces)
        .collect();
    let tie_flipped = if tied.contains(&true) {
        first_faces_flip(faces, component_of, &shell_of, &tied)
    } else {
        vec![false; shells.len()]
    };
    for (i, shell) in shells.iter_mut().enumerate() {
        if shell.orientable {
            let take_flipped = if tied[i] {
                tie_flipped[i]
            } else {
                2 * flipped[i] > shell.faces
            };
            let v = six_volume[i] / 6.0;
            shell.volume = Some(if take_flipped { -v } else { v });
        }
    }
    (shells, shell_of)
}

/// The shells' nesting among those that do not meet (`meeting`: the pairs of components whose
/// faces meet), then each shell's role and whether it is inside out.
fn nest(
    faces: &Faces,
    component_of: &impl Fn(u32) -> usize,
    shells: &mut [Shell],
    shell_of: &[u32],
    meeting: &[[u32; 2]],
) {
    let nt = faces.table.triangle_count() as u32;
    // The shells each shell meets (both components of a meeting pair are shells).
    for &[a, b] in meeting {
        let (sa, sb) = (shell_of[a as usize], shell_of[b as usize]);
        if sa != UNSET && sb != UNSET {
            shells[sa as usize].meets.push(sb as usize);
            shells[sb as usize].meets.push(sa as usize);
        }
    }
    for shell in shells.iter_mut() {
        shell.meets.sort_unstable();
    }

    let depth = if shells.len() > 1 {
        // Faces of each shell, by a counting sort on the shell.
        let mut start = vec![0u32; shells.len() + 1];
        for t in 0..nt {
            let s = shell_of[component_of(t)];
            if s != UNSET {
                start[s as usize + 1] += 1;
            }
        }
        for i in 0..shells.len() {
            start[i + 1] += start[i];
        }
        let mut list = vec![0u32; start[shells.len()] as usize];
        let mut fill = start.clone();
        for t in 0..nt {
            let s = shell_of[component_of(t)];
            if s != UNSET {
                list[fill[s as usize] as usize] = t;
                fill[s as usize] += 1;
            }
        }
        let geometry: Vec<ShellGeometry> = shells
            .iter()
            .enumerate()
            .map(|(i, s)| ShellGeometry {
                bbox: s.bbox,
                faces: &list[start[i] as usize..start[i + 1] as usize],
                bounds: s.orientable,
            })
            .collect();
        // A shell that meets another has no depth against it: crossing, neither is inside.
        let apart = |a: usize, b: usize| shells[a].meets.binary_search(&b).is_err();
        depths(faces.table, faces.points, &geometry, &apart)
    } else {
        vec![0; shells.len()]
    };
    for (shell, depth) in shells.iter_mut().zip(depth) {
        shell.depth = depth;
        shell.role = if !shell.orientable {
            Role::Neither
        } else if depth % 2 == 0 {
            Role::Solid
        } else {
            Role::Cavity
        };
        // A flat shell (a pillow of coincident faces) has a volume of rounding noise: no sign.
        let volume = shell.volume.filter(|&v| !is_flat(v, &shell.bbox));
        shell.inside_out = shell.oriented
            && match (shell.role, volume) {
                (Role::Solid, Some(v)) => v < 0.0,
                (Role::Cavity, Some(v)) => v > 0.0,
                (Role::Neither, _) | (_, None) => false,
            };
    }
}

/// For each shell marked in `tied`, the parity of its first face by position: the face whose three
/// vertex positions, each sorted by (x, y, z), come first lexicographically. Distinct welded vertices
/// have distinct positions, and in a closed manifold shell two faces on the same three vertices are a
/// two-face pillow (either face gives the same winding), so the choice depends on no vertex number,
/// face order or corner rotation.
fn first_faces_flip(
    faces: &Faces,
    component_of: &impl Fn(u32) -> usize,
    shell_of: &[u32],
    tied: &[bool],
) -> Vec<bool> {
    let key = |t: u32| {
        let mut k = faces.table.triangles()[t as usize].map(|i| faces.points[i as usize]);
        k.sort_unstable_by(by_position);
        k
    };
    let mut first: Vec<Option<(u32, [[f64; 3]; 3])>> = vec![None; tied.len()];
    for t in 0..faces.table.triangle_count() as u32 {
        let s = shell_of[component_of(t)];
        if s == UNSET || !tied[s as usize] {
            continue;
        }
        let k = key(t);
        let slot = &mut first[s as usize];
        let earlier = |best: &[[f64; 3]; 3]| {
            (0..3)
                .map(|i| by_position(&k[i], &best[i]))
                .find(|o| o.is_ne())
                .is_some_and(|o| o.is_lt())
        };
        if slot.as_ref().is_none_or(|(_, best)| earlier(best)) {
            *slot = Some((t, k));
        }
    }
    first
        .iter()
        .map(|f| f.is_some_and(|(t, _)| faces.patches.flip[t as usize]))
        .collect()
}

/// Whether a shell's volume is too small for its sign to mean anything: at most 1e-12 of its
/// bounding box's diagonal cubed (the zero-area test's threshold, one dimension up).
pub(crate) fn is_flat(volume: f64, bbox: &[[f64; 3]; 2]) -> bool {
    let diagonal = dist2(bbox[0], bbox[1]).sqrt();
    volume.abs() <= 1e-12 * diagonal.powi(3)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Analysis {
        analyse(
            &Mesh::new(positions.to_vec(), triangles.to_vec()),
            &Options::default(),
        )
    }

    /// A run's list is taken whole into an empty list (its buffer, not a copy) and appended in
    /// order to a non-empty one.
    #[test]
    fn join_takes_the_first_list_and_appends_the_rest() {
        let mut list = Vec::new();
        let first = vec![(1u32, 2u32), (3, 4)];
        let buffer = first.as_ptr();
        join(&mut list, first);
        assert_eq!(list.as_ptr(), buffer);
        join(&mut list, vec![(5, 6)]);
        join(&mut list, Vec::new());
        assert_eq!(list, [(1, 2), (3, 4), (5, 6)]);
    }

    #[rustfmt::skip]
    const CUBE_POINTS: [[f64; 3]; 8] = [
        [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0],
    ];
    /// Unit cube, counterclockwise seen from outside.
    #[rustfmt::skip]
    const CUBE: [[u32; 3]; 12] = [
        [0, 2, 1], [0, 3, 2], // z = 0
        [4, 5, 6], [4, 6, 7], // z = 1
        [0, 1, 5], [0, 5, 4], // y = 0
        [1, 2, 6], [1, 6, 5], // x = 1
        [2, 3, 7], [2, 7, 6], // y = 1
        [3, 0, 4], [3, 4, 7], // x = 0
    ];

    /// Cube: V 8, E 18, F 12, chi 2, genus 0, one outward solid of volume 1.
    #[test]
    fn unit_cube() {
        let a = run(&CUBE_POINTS, &CUBE);
        assert_eq!((a.edges, a.border_edges, a.nonmanifold_edges), (18, 0, 0));
        assert_eq!(a.euler, 2);
        assert_eq!(a.genus(), Some(0));
        assert_eq!(a.shells.len(), 1);
        assert!(a.oriented() && a.orientable());
        assert_eq!(a.inside_out_shells(), 0);
        assert!((a.volume().unwrap() - 1.0).abs() < 1e-12);
        assert!((a.shells[0].volume.unwrap() - 1.0).abs() < 1e-12);
        assert!((a.area - 6.0).abs() < 1e-12);
    }

    /// Bowtie: triangles 0-1-2 and 0-3-4 share vertex 0 only. V 5, E 6, F 2: two components, each a
    /// disk (chi 1, one hole, genus 0); vertex 0 has two fans.
    #[test]
    fn bowtie() {
        #[rustfmt::skip]
        let p = [
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 0.0, 0.0],
            [-1.0, -1.0, 0.0],
        ];
        let a = run(&p, &[[0, 1, 2], [0, 3, 4]]);
        assert_eq!(a.nonmanifold_vertices, 1);
        assert_eq!(a.components.len(), 2);
        assert!(a
            .components
            .iter()
            .all(|c| c.manifold && c.vertices == 3 && c.holes == 1));
        assert_eq!(a.holes(), 2);
        assert_eq!(a.euler, 5 - 6 + 2);
        assert_eq!(a.genus(), Some(0));
    }

    /// 2x2x2 cube with a 1x1x1 cube inside whose faces look into the void: depth 0 solid, depth 1
    /// cavity, volume 8 - 1 = 7, nothing inside out. Flipping the inner cube makes it inside out.
    #[test]
    fn cube_with_cavity() {
        let mut p: Vec<[f64; 3]> = CUBE_POINTS.iter().map(|q| q.map(|x| 2.0 * x)).collect();
        p.extend(CUBE_POINTS.iter().map(|q| q.map(|x| x + 0.5)));
        let mut t: Vec<[u32; 3]> = CUBE.to_vec();
        t.extend(CUBE.iter().map(|f| [f[0] + 8, f[2] + 8, f[1] + 8]));
        let a = run(&p, &t);
        let roles: Vec<(usize, Role)> = a.shells.iter().map(|s| (s.depth, s.role)).collect();
        assert_eq!(roles, vec![(0, Role::Solid), (1, Role::Cavity)]);
        assert_eq!(a.inside_out_shells(), 0);
        assert!((a.volume().unwrap() - 7.0).abs() < 1e-12);

        t.truncate(12);
        t.extend(CUBE.iter().map(|f| [f[0] + 8, f[1] + 8, f[2] + 8]));
        let a = run(&p, &t);
        assert_eq!(a.inside_out_shells(), 1);
        assert!(a.shells[1].inside_out);
        assert!((a.volume().unwrap() - 7.0).abs() < 1e-12);
    }

    /// Three triangles on edge 0-1: one non-manifold edge; both of its ends are non-manifold vertices
    /// (each has three fans); one component that is not manifold, so no genus.
    #[test]
    fn three_faces_on_an_edge() {
        #[rustfmt::skip]
        let p = [
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
        ];
        let a = run(&p, &[[0, 1, 2], [1, 0, 3], [0, 1, 4]]);
        assert_eq!(a.nonmanifold_edges, 1);
        assert_eq!(a.nonmanifold_vertices, 2);
        assert_eq!(a.components.len(), 1);
        let c = &a.components[0];
        assert!(!c.manifold);
        assert_eq!((c.vertices, c.edges, c.faces), (5, 7, 3));
        assert_eq!(a.genus(), None);
    }

    /// Degenerate (repeated index), duplicate (reversed copy) and an unreferenced vertex on a cube.
    #[test]
    fn degenerate_duplicate_unreferenced() {
        let mut p = CUBE_POINTS.to_vec();
        p.push([5.0, 5.0, 5.0]);
        let mut t = CUBE.to_vec();
        t.push([0, 0, 1]);
        t.push([0, 1, 2]);
        let a = run(&p, &t);
        assert_eq!(a.degenerate_faces, 1);
        assert_eq!(a.duplicate_faces, 1);
        assert_eq!(a.unreferenced_vertices, 1);
        // The copy of 0-2-1 puts three faces on edges 0-1, 1-2 and 2-0.
        assert_eq!(a.nonmanifold_edges, 3);
    }

    /// Duplicates counted corner by corner over every edge (what `count_duplicates` did before it
    /// looked only at lowest corners): the reference for the test below.
    fn duplicates_by_corners(table: &CornerTable) -> usize {
        let edge_min = |c: u32| table.v(CornerTable::n(c)).min(table.v(CornerTable::p(c)));
        let mut count = 0;
        for c in 0..table.corner_count() as u32 {
            if let Some(b) = table.opposite(c) {
                if c < b && table.v(c) == table.v(b) && table.v(c) < edge_min(c) {
                    count += 1;
                }
            }
        }
        count + duplicates_at_nonmanifold_edges(table)
    }

    /// A pillow (a face and its reversed copy: one duplicate on each of its three manifold edges,
    /// counted once), four copies of one face (three extra, on non-manifold edges), and random
    /// small meshes over six vertices, full of repeats in both windings, rotated corners and
    /// fins: counting at lowest corners agrees with counting at every corner.
    #[test]
    fn duplicates_counted_at_lowest_corners() {
        let pillow = CornerTable::build(&[[0, 1, 2], [1, 0, 2]], 3);
        assert_eq!(count_duplicates(&pillow), 1);
        let four = CornerTable::build(&[[0, 1, 2], [1, 2, 0], [2, 1, 0], [0, 2, 1]], 3);
        assert_eq!(count_duplicates(&four), 3);
        let mut x = 99u64;
        for _ in 0..500 {
            let mut faces = Vec::new();
            while faces.len() < 12 {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let t = [(x >> 20) % 6, (x >> 30) % 6, (x >> 40) % 6].map(|v| v as u32);
                if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                    faces.push(t);
                }
            }
            let table = CornerTable::build(&faces, 6);
            assert_eq!(
                count_duplicates(&table),
                duplicates_by_corners(&table),
                "{faces:?}"
            );
        }
    }

    /// A mesh with every kind of patch and fan, numbered so that runs of faces or corners cut them:
    /// a cube with one face wound the other way (inconsistent edges), a Moebius strip (not
    /// orientable: each run holds part of it, so only the join sees the conflict), three faces on
    /// one edge (non-manifold), a lone face, two triangles pinched at a vertex, and a 12 x 12 grid
    /// with 17 faces left out (two of them split the fan of a border vertex in two). Vertices are renumbered by a
    /// stride and faces interleaved, so the faces around a vertex sit far apart in the table.
    fn mixed_mesh() -> Mesh {
        let mut positions = CUBE_POINTS.to_vec();
        let mut triangles = CUBE.to_vec();
        let mut parts = vec![0];
        triangles[5].swap(1, 2);
        let strip = 9u32;
        parts.push(positions.len());
        let base = positions.len() as u32;
        for i in 0..strip {
            positions.push([10.0 + i as f64, 0.0, 0.0]);
            positions.push([10.0 + i as f64, 1.0, 0.0]);
        }
        let (a, b) = (
            |i: u32| base + 2 * (i % strip),
            |i: u32| base + 2 * (i % strip) + 1,
        );
        for i in 0..strip - 1 {
            triangles.push([a(i), b(i), b(i + 1)]);
            triangles.push([a(i), b(i + 1), a(i + 1)]);
        }
        // The half twist: the last quad joins a(8) to b(0) and b(8) to a(0).
        triangles.push([a(strip - 1), b(strip - 1), a(0)]);
        triangles.push([a(strip - 1), a(0), b(0)]);
        parts.push(positions.len());
        let base = positions.len() as u32;
        positions.extend([
            [0.0, 0.0, 5.0],
            [1.0, 0.0, 5.0],
            [0.0, 1.0, 5.0],
            [0.0, -1.0, 5.0],
        ]);
        positions.extend([
            [0.5, 0.5, 6.0],
            [20.0, 0.0, 0.0],
            [21.0, 0.0, 0.0],
            [20.0, 1.0, 0.0],
        ]);
        for apex in [2, 3, 4] {
            triangles.push([base, base + 1, base + apex]);
        }
        triangles.push([base + 5, base + 6, base + 7]);
        // The pinched pair: two triangles sharing vertex `base`.
        parts.push(positions.len());
        let base = positions.len() as u32;
        positions.extend([[30.0, 0.0, 0.0], [31.0, 0.0, 0.0], [30.0, 1.0, 0.0]]);
        positions.extend([[29.0, 0.0, 0.0], [30.0, -1.0, 0.0]]);
        triangles.push([base, base + 1, base + 2]);
        triangles.push([base, base + 3, base + 4]);
        // The grid, 13 x 13 vertices at z = 9, with every 17th face left out.
        parts.push(positions.len());
        let base = positions.len() as u32;
        let at = |i: u32, j: u32| base + 13 * j + i;
        for j in 0..13 {
            for i in 0..13 {
                positions.push([i as f64, j as f64, 9.0]);
            }
        }
        let mut grid = Vec::new();
        for j in 0..12 {
            for i in 0..12 {
                grid.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                grid.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        triangles.extend(
            grid.iter()
                .enumerate()
                .filter(|(k, _)| k % 17 != 5)
                .map(|(_, t)| *t),
        );
        // Renumber the vertices round-robin over the parts (each part's k-th vertex, part by part,
        // then the (k+1)-th), and interleave the faces.
        parts.push(positions.len());
        let mut new = vec![0u32; positions.len()];
        let mut next = 0;
        for k in 0.. {
            let mut any = false;
            for w in parts.windows(2) {
                if w[0] + k < w[1] {
                    new[w[0] + k] = next;
                    next += 1;
                    any = true;
                }
            }
            if !any {
                break;
            }
        }
        let mut renumbered = vec![[0.0; 3]; positions.len()];
        for (v, p) in positions.iter().enumerate() {
            renumbered[new[v] as usize] = *p;
        }
        assert_eq!(gcd(7, triangles.len()), 1);
        let triangles: Vec<[u32; 3]> = (0..triangles.len())
            .map(|i| triangles[(i * 7) % triangles.len()].map(|v| new[v as usize]))
            .collect();
        Mesh::new(renumbered, triangles)
    }

    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }

    /// Walking patches on runs of faces and joining them across the runs gives the patches of one
    /// walk: the same numbers, counts and orientability, and the same flips wherever a patch is
    /// orientable.
    #[test]
    fn patches_walked_in_runs_are_the_patches_of_one_walk() {
        let mesh = mixed_mesh();
        let (built, _) = build(&mesh, &Options::default());
        let one = walk_patches(&built.table, 1);
        assert_eq!(
            one.orientable.iter().filter(|&&o| !o).count(),
            1,
            "the strip"
        );
        assert!(
            one.counts.iter().any(|n| n.inconsistent == 1),
            "the cube's face"
        );
        assert_eq!(
            one.counts.len(),
            1 + 1 + 3 + 1 + 2 + 1,
            "cube, strip, three faces, lone face, pinched pair, grid"
        );
        for runs in 2..=7 {
            let many = walk_patches(&built.table, runs);
            assert_eq!(many.of_face, one.of_face, "{runs} runs");
            assert_eq!(many.orientable, one.orientable, "{runs} runs");
            assert_eq!(many.counts, one.counts, "{runs} runs");
            for (t, &p) in one.of_face.iter().enumerate() {
                if one.orientable[p as usize] {
                    assert_eq!(many.flip[t], one.flip[t], "{runs} runs, face {t}");
                }
            }
        }
    }

    /// Walking fans on runs of corners gives the fans of one walk: the same list in the same
    /// order, the same holes, vertex counts and non-manifold vertices. The mixed mesh's table has
    /// about 1,000 corners, so it is cut in runs of 64 to 192 corners.
    #[test]
    fn fans_walked_in_runs_are_the_fans_of_one_walk() {
        let mesh = mixed_mesh();
        let (built, _) = build(&mesh, &Options::default());
        let patches = walk_patches(&built.table, 1);
        let component_of_patch = join_patches(&built.table, &patches, &built.source);
        let component_of =
            |t: u32| component_of_patch[patches.of_face[t as usize] as usize] as usize;
        let one = walk_fans(&built.table, &component_of, 1);
        // The pinched pair's vertex, both ends of the edge of three faces (each face a fan there),
        // and the grid's vertices (2, 0) and (0, 8) (counted by a separate script).
        assert_eq!(one.nonmanifold_vertices, 1 + 2 + 2);
        assert!(one.hole_corners.len() > 2);
        assert!(!one.split_components.is_empty());
        for runs in 2..=16 {
            assert_eq!(
                walk_fans(&built.table, &component_of, runs),
                one,
                "{runs} runs"
            );
        }
    }
}
