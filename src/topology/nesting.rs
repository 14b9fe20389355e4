//! Shell nesting ([definitions](crate::definitions#volume-and-nesting)): shell A lies inside shell B when a vertex of A is inside the solid bounded
//! by B. The depth of a shell is the number of shells containing it.
//!
//! Candidates are pruned first: A can only lie inside B when A's bounding box lies inside B's, found
//! by a sweep over the boxes sorted on their lowest coordinate along the axis where the box centres
//! spread most, so 10,000 disjoint shells cost a few thousand box tests, not 10^8, whichever way they
//! are lined up. The survivors get an exact point-in-solid test: the parity of the crossings of a
//! segment from the point to far outside B, decided with exact `orient3d` predicates. A segment that
//! grazes an edge, a vertex or lies in a face's plane across the face is never guessed at: another
//! direction is tried, and a point lying on B's surface is replaced by another vertex of A.

use robust::{orient3d, Coord};

use crate::geometry::by_position;
use crate::geometry::exact::{
    dominant_axes, in_triangle_2d, in_triangle_coplanar, p3, segments_touch,
};

use crate::corner_table::CornerTable;

/// What nesting needs of a shell.
pub(crate) struct ShellGeometry<'a> {
    pub bbox: [[f64; 3]; 2],
    /// Triangles of the shell (indices into the table).
    pub faces: &'a [u32],
    /// Whether the shell bounds a solid, so that other shells can lie inside it: false for a shell
    /// that is not orientable, which has no inside (a point's parity against it says nothing).
    pub bounds: bool,
}

/// Segment directions: nearly axis-aligned (so the segment's box is thin and prunes most faces), with
/// small irrational tilts so that hitting an edge or vertex exactly is unlikely; each is tried in
/// turn when the previous one grazed something.
const DIRECTIONS: [[f64; 3]; 6] = [
    [1.0, 1.234_567_891e-4, 2.718_281_828e-4],
    [-3.141_592_653e-4, 1.0, 1.414_213_562e-4],
    [1.732_050_807e-4, -2.236_067_977e-4, 1.0],
    [-1.0, 4.142_135_623e-4, -1.618_033_988e-4],
    [0.577_350_269, 0.577_350_269_1, -0.577_350_268_9],
    [-0.267_261_241, 0.534_522_483, 0.801_783_725_7],
];

/// How many more distinct vertices of a shell are tried when the first lies on the other shell's
/// surface, before giving up on a containment test (all of them lying there means the shells
/// touch, which is not containment). Vertices the two shells share are passed over without a
/// test and not counted ([`contains`]).
const ATTEMPTS: usize = 12;

/// The depth of every shell: how many shells contain it, among those it is `apart` from (shells
/// whose surfaces meet are never inside one another: parity says nothing about crossing shells)
/// and that bound a solid ([`ShellGeometry::bounds`]).
pub(crate) fn depths(
    table: &CornerTable,
    points: &[[f64; 3]],
    shells: &[ShellGeometry],
    apart: &dyn Fn(usize, usize) -> bool,
) -> Vec<usize> {
    let mut depth = vec![0usize; shells.len()];
    let boxes: Vec<[[f64; 3]; 2]> = shells.iter().map(|s| s.bbox).collect();
    boxed_pairs(&boxes, |inner, outer| {
        if shells[outer].bounds
            && apart(inner, outer)
            && contains(table, points, &shells[outer], &shells[inner])
        {
            depth[inner] += 1;
        }
    });
    depth
}

/// Calls `visit(a, b)` for every pair of distinct boxes with box `a` inside box `b` (closed boxes).
///
/// A sweep along one axis: boxes sorted on their lowest coordinate, `active` holding those whose range
/// reaches the current box's lowest coordinate. The axis is the one along which the box centres
/// spread most, so shells lined up along y or z prune as well as along x.
pub(crate) fn boxed_pairs(boxes: &[[[f64; 3]; 2]], mut visit: impl FnMut(usize, usize)) {
    if boxes.len() < 2 {
        return;
    }
    let centre = |b: &[[f64; 3]; 2], k: usize| 0.5 * b[0][k] + 0.5 * b[1][k];
    let spread = |k: usize| {
        let (lo, hi) = boxes
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), b| {
                (lo.min(centre(b, k)), hi.max(centre(b, k)))
            });
        hi - lo
    };
    let spreads = [spread(0), spread(1), spread(2)];
    let axis = (0..3)
        .max_by(|&i, &j| spreads[i].total_cmp(&spreads[j]).then(j.cmp(&i)))
        .unwrap_or(0);

    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_by(|&a, &b| boxes[a][0][axis].total_cmp(&boxes[b][0][axis]));
    let mut active: Vec<usize> = Vec::new();
    let mut next = 0;
    for &a in &order {
        let [lo, hi] = boxes[a];
        while next < order.len() && boxes[order[next]][0][axis] <= lo[axis] {
            active.push(order[next]);
            next += 1;
        }
        active.retain(|&b| boxes[b][1][axis] >= lo[axis]);
        #[cfg(test)]
        SWEEP_TESTS.with(|n| n.set(n.get() + active.len()));
        for &b in &active {
            let [blo, bhi] = boxes[b];
            if b != a && (0..3).all(|k| blo[k] <= lo[k] && hi[k] <= bhi[k]) {
                visit(a, b);
            }
        }
    }
}

#[cfg(test)]
thread_local! {
    /// Box tests made by [`boxed_pairs`] on this thread (tests only).
    static SWEEP_TESTS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// Whether a vertex of `inner` lies inside the solid bounded by `outer`.
fn contains(
    table: &CornerTable,
    points: &[[f64; 3]],
    outer: &ShellGeometry,
    inner: &ShellGeometry,
) -> bool {
    // The lowest vertex (by x, then y, then z) first: for shells that intersect, "inside" depends on
    // the vertex tested, and choosing it by position makes the answer independent of how faces and
    // vertices are numbered. When it lies on `outer`'s surface, up to `ATTEMPTS` other distinct
    // vertices follow, in face order, leaving out those `outer` has too: where the faces of two
    // shells do not meet (the only shells whose depth is asked), a vertex of one lies on the
    // other's surface only where they share it, so any other vertex decides, however many they
    // share (a fan over points of `outer`'s surface around an apex inside it shares all but one).
    let vertices = || {
        inner
            .faces
            .iter()
            .flat_map(|&t| table.triangles()[t as usize])
    };
    let lowest = vertices().min_by(|&a, &b| by_position(&points[a as usize], &points[b as usize]));
    let Some(lowest) = lowest else { return false };
    if let Some(inside) = point_in_solid(table, points, outer, points[lowest as usize]) {
        return inside;
    }
    let mut shared: Vec<u32> = outer
        .faces
        .iter()
        .flat_map(|&t| table.triangles()[t as usize])
        .collect();
    shared.sort_unstable();
    shared.dedup();
    let mut tried: Vec<u32> = Vec::with_capacity(ATTEMPTS + 1);
    tried.push(lowest);
    for v in vertices() {
        if tried.len() > ATTEMPTS {
            break;
        }
        if tried.contains(&v) || shared.binary_search(&v).is_ok() {
            continue;
        }
        tried.push(v);
        if let Some(inside) = point_in_solid(table, points, outer, points[v as usize]) {
            return inside;
        }
    }
    false
}

/// Parity of the crossings of segments from `q` out of the shell; `None` when `q` lies on the shell's
/// surface or every direction grazed an edge, a vertex or a plane.
fn point_in_solid(
    table: &CornerTable,
    points: &[[f64; 3]],
    shell: &ShellGeometry,
    q: [f64; 3],
) -> Option<bool> {
    let [lo, hi] = shell.bbox;
    if (0..3).any(|k| q[k] < lo[k] || q[k] > hi[k]) {
        return Some(false);
    }
    let reach = 2.0 * (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max) + 1.0;
    'directions: for dir in DIRECTIONS {
        let far = [0, 1, 2].map(|k| q[k] + reach * dir[k]);
        let seg_lo = [0, 1, 2].map(|k| q[k].min(far[k]));
        let seg_hi = [0, 1, 2].map(|k| q[k].max(far[k]));
        let mut crossings = 0usize;
        for &t in shell.faces {
            let [a, b, c] = table.triangles()[t as usize].map(|i| points[i as usize]);
            if (0..3).any(|k| {
                a[k].max(b[k]).max(c[k]) < seg_lo[k] || a[k].min(b[k]).min(c[k]) > seg_hi[k]
            }) {
                continue;
            }
            match segment_meets_triangle([q, far], [a, b, c]) {
                Meeting::Miss => {}
                Meeting::Cross => crossings += 1,
                Meeting::Graze => continue 'directions,
                Meeting::OnSurface => return None,
            }
        }
        return Some(crossings % 2 == 1);
    }
    None
}

/// How the segment from `q` to `far` (a point outside the shell) meets one closed triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Meeting {
    /// No common point.
    Miss,
    /// Through the triangle's interior, from one side of its plane to the other.
    Cross,
    /// Through an edge or a vertex, along the plane, or ending on it: the parity would be a guess.
    Graze,
    /// `q` itself lies on the triangle.
    OnSurface,
}

fn segment_meets_triangle([q, far]: [[f64; 3]; 2], [a, b, c]: [[f64; 3]; 3]) -> Meeting {
    let s_near = orient3d(p3(a), p3(b), p3(c), p3(q));
    let s_far = orient3d(p3(a), p3(b), p3(c), p3(far));
    if s_near == 0.0 && s_far == 0.0 {
        // The segment lies in the triangle's plane (or the triangle is flat): crossing it, if it does,
        // means running along the surface.
        return if in_triangle_coplanar(q, a, b, c) {
            Meeting::OnSurface
        } else if coplanar_segment_meets_triangle([q, far], [a, b, c]) {
            Meeting::Graze
        } else {
            Meeting::Miss
        };
    }
    if s_near == 0.0 {
        // The segment touches the plane only at q.
        return if in_triangle_coplanar(q, a, b, c) {
            Meeting::OnSurface
        } else {
            Meeting::Miss
        };
    }
    if s_far == 0.0 {
        return Meeting::Graze;
    }
    if (s_near > 0.0) == (s_far > 0.0) {
        return Meeting::Miss;
    }
    // The segment crosses the plane at one point; which side of each edge's plane (through the
    // segment) decides whether that point is inside, on the boundary of, or outside the triangle.
    let e = [
        orient3d(p3(q), p3(far), p3(a), p3(b)),
        orient3d(p3(q), p3(far), p3(b), p3(c)),
        orient3d(p3(q), p3(far), p3(c), p3(a)),
    ];
    let positive = e.iter().filter(|&&x| x > 0.0).count();
    let negative = e.iter().filter(|&&x| x < 0.0).count();
    match (positive, negative) {
        (3, 0) | (0, 3) => Meeting::Cross,
        // Zeros with the nonzero signs agreeing: the crossing point is on an edge or a vertex.
        (_, 0) | (0, _) => Meeting::Graze,
        _ => Meeting::Miss,
    }
}

/// Whether the segment `q far`, lying in the plane of `a b c`, touches the closed triangle (exact, in
/// the projection on the plane's dominant axis; a flat triangle is projected on z, which can only err
/// towards "touches").
fn coplanar_segment_meets_triangle([q, far]: [[f64; 3]; 2], [a, b, c]: [[f64; 3]; 3]) -> bool {
    let (i, j) = dominant_axes(a, b, c);
    let p2 = |p: [f64; 3]| Coord { x: p[i], y: p[j] };
    let (q2, f2) = (p2(q), p2(far));
    let corners = [p2(a), p2(b), p2(c)];
    if in_triangle_2d(f2, corners) {
        return true;
    }
    (0..3).any(|k| segments_touch(q2, f2, corners[k], corners[(k + 1) % 3]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 2,000 unit boxes `[0,1] x [0,1] x [2i, 2i+1]`, lined up along z with equal x and y ranges. No
    /// box lies inside another, and a sweep along z sees at most the previous box still active: fewer
    /// than 2 box tests per box. A sweep along x would keep all of them active: about n^2/2 = 2,000,000.
    #[test]
    fn boxes_lined_up_along_z_are_swept_along_z() {
        let boxes: Vec<[[f64; 3]; 2]> = (0..2000)
            .map(|i| {
                let z = 2.0 * i as f64;
                [[0.0, 0.0, z], [1.0, 1.0, z + 1.0]]
            })
            .collect();
        let mut pairs = 0;
        let mut tests = 0;
        boxed_pairs_counting(&boxes, &mut tests, |_, _| pairs += 1);
        assert_eq!(pairs, 0);
        assert!(tests < 2 * boxes.len(), "{tests} box tests");
    }

    /// The same along y, and 10 boxes inside one big box along y: the 10 pairs (small, big) are found.
    #[test]
    fn boxes_inside_a_box_along_y_are_found() {
        let mut boxes: Vec<[[f64; 3]; 2]> = (0..10)
            .map(|i| {
                let y = 2.0 * i as f64;
                [[0.0, y, 0.0], [1.0, y + 1.0, 1.0]]
            })
            .collect();
        boxes.push([[-1.0, -1.0, -1.0], [2.0, 20.0, 2.0]]);
        let mut pairs = Vec::new();
        let mut tests = 0;
        boxed_pairs_counting(&boxes, &mut tests, |a, b| pairs.push((a, b)));
        pairs.sort_unstable();
        assert_eq!(pairs, (0..10).map(|a| (a, 10)).collect::<Vec<_>>());
    }

    /// [`boxed_pairs`], also counting the box tests the sweep makes (pairs it looks at).
    fn boxed_pairs_counting(
        boxes: &[[[f64; 3]; 2]],
        tests: &mut usize,
        mut visit: impl FnMut(usize, usize),
    ) {
        SWEEP_TESTS.with(|n| n.set(0));
        boxed_pairs(boxes, &mut visit);
        *tests = SWEEP_TESTS.with(|n| n.get());
    }

    const A: [f64; 3] = [0.0, 0.0, 0.0];
    const B: [f64; 3] = [1.0, 0.0, 0.0];
    const C: [f64; 3] = [0.0, 1.0, 0.0];

    /// Segments against the triangle `(0,0,0) (1,0,0) (0,1,0)` in the plane z = 0.
    #[test]
    fn segment_meetings() {
        let meet = |q: [f64; 3], far: [f64; 3]| segment_meets_triangle([q, far], [A, B, C]);
        // Through the interior point (0.25, 0.25, 0), from below to above.
        assert_eq!(meet([0.25, 0.25, -1.0], [0.25, 0.25, 1.0]), Meeting::Cross);
        // Through (0.5, 0, 0), on edge A B.
        assert_eq!(meet([0.5, 0.0, -1.0], [0.5, 0.0, 1.0]), Meeting::Graze);
        // Through vertex C.
        assert_eq!(meet([0.0, 1.0, -1.0], [0.0, 1.0, 1.0]), Meeting::Graze);
        // Through (1, 1, 0), outside (x + y = 2 > 1), though on the line of no edge.
        assert_eq!(meet([1.0, 1.0, -1.0], [1.0, 1.0, 1.0]), Meeting::Miss);
        // Through (2, 0, 0): on the line of edge A B, beyond B: outside.
        assert_eq!(meet([2.0, 0.0, -1.0], [2.0, 0.0, 1.0]), Meeting::Miss);
        // Starting on the plane inside the triangle: q is on the surface.
        assert_eq!(
            meet([0.25, 0.25, 0.0], [0.25, 0.25, 1.0]),
            Meeting::OnSurface
        );
        // Starting on the plane outside the triangle, leaving it: touches the plane only at q.
        assert_eq!(meet([-1.0, 0.25, 0.0], [-1.0, 0.25, 1.0]), Meeting::Miss);
        // Lying in the plane, from (-1, 0.25, 0) to (2, 0.25, 0): across the triangle, along the
        // surface. (Skipping it, as a segment that touches the plane only at q, is the bug.)
        assert_eq!(meet([-1.0, 0.25, 0.0], [2.0, 0.25, 0.0]), Meeting::Graze);
        // Lying in the plane and passing beside the triangle (y = 2): no common point.
        assert_eq!(meet([-1.0, 2.0, 0.0], [2.0, 2.0, 0.0]), Meeting::Miss);
        // Ending on the plane: a graze (the far point is never on the shell in practice).
        assert_eq!(meet([0.25, 0.25, -1.0], [5.0, 5.0, 0.0]), Meeting::Graze);
    }

    /// The construction of `first_segment_through_an_edge_or_a_corner_of_the_outer_box` in
    /// tests/topology.rs really grazes: from the origin, with the box's largest side 4, the first
    /// segment ends at `9 x DIRECTIONS[0] = (9, fy, fz)` and passes exactly through `(2.25, fy/4,
    /// fz/4)`, which is on the box's vertical edge `x = 2.25, y = fy/4` (a triangle of the face
    /// x = 2.25 holding that edge), or is the box's corner (a triangle of that face on that corner).
    #[test]
    fn first_direction_meets_the_edge_and_the_corner_of_the_test_box() {
        let reach = 2.0 * 4.0 + 1.0;
        let q = [0.0; 3];
        let far = [0, 1, 2].map(|k| q[k] + reach * DIRECTIONS[0][k]);
        let (y, z) = (far[1] / 4.0, far[2] / 4.0);
        let edge = [[2.25, y, -2.0], [2.25, y, 2.0], [2.25, y - 2.0, 2.0]];
        assert_eq!(segment_meets_triangle([q, far], edge), Meeting::Graze);
        let corner = [[2.25, y, z], [2.25, y - 2.0, z], [2.25, y - 2.0, z - 2.0]];
        assert_eq!(segment_meets_triangle([q, far], corner), Meeting::Graze);
    }
}
