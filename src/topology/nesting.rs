//! Shell nesting (SPEC 8): shell A lies inside shell B when a vertex of A is inside the solid bounded
//! by B. The depth of a shell is the number of shells containing it.
//!
//! Candidates are pruned first: A can only lie inside B when A's bounding box lies inside B's, found
//! by a sweep over the boxes sorted on their lowest x, so 10,000 disjoint shells cost a few
//! thousand box tests, not 10^8. The survivors get an exact point-in-solid test: the parity of the
//! crossings of a segment from the point to far outside B, decided with exact `orient3d` predicates.
//! A segment that grazes an edge, a vertex or a face's plane is never guessed at: another direction is
//! tried, and a point lying on B's surface is replaced by another vertex of A.

use robust::{orient2d, orient3d, Coord, Coord3D};

use crate::corner_table::CornerTable;

/// What nesting needs of a shell.
pub(crate) struct ShellGeometry<'a> {
    pub bbox: [[f64; 3]; 2],
    /// Triangles of the shell (indices into the table).
    pub faces: &'a [u32],
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

/// How many vertices of a shell are tried before giving up on a containment test (all of them lying
/// on the other shell's surface means the shells touch, which is not containment).
const ATTEMPTS: usize = 12;

/// The depth of every shell.
pub(crate) fn depths(
    table: &CornerTable,
    points: &[[f64; 3]],
    shells: &[ShellGeometry],
) -> Vec<usize> {
    let mut depth = vec![0usize; shells.len()];
    if shells.len() < 2 {
        return depth;
    }
    let mut order: Vec<usize> = (0..shells.len()).collect();
    order.sort_by(|&a, &b| shells[a].bbox[0][0].total_cmp(&shells[b].bbox[0][0]));

    // Sweep on x: `active` holds the shells whose x-range reaches the current lowest x.
    let mut active: Vec<usize> = Vec::new();
    let mut next = 0;
    for &a in &order {
        let [lo, hi] = shells[a].bbox;
        while next < order.len() && shells[order[next]].bbox[0][0] <= lo[0] {
            active.push(order[next]);
            next += 1;
        }
        active.retain(|&b| shells[b].bbox[1][0] >= lo[0]);
        for &b in &active {
            let [blo, bhi] = shells[b].bbox;
            let boxed = b != a && (0..3).all(|k| blo[k] <= lo[k] && hi[k] <= bhi[k]);
            if boxed && contains(table, points, &shells[b], &shells[a]) {
                depth[a] += 1;
            }
        }
    }
    depth
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
    // vertices are numbered.
    let corners = || inner.faces.iter().flat_map(|&t| 3 * t..3 * t + 3);
    let lowest = corners()
        .map(|c| points[table.v(c) as usize])
        .min_by(|a, b| {
            a[0].total_cmp(&b[0])
                .then(a[1].total_cmp(&b[1]))
                .then(a[2].total_cmp(&b[2]))
        });
    let others = corners()
        .take(ATTEMPTS)
        .map(|c| points[table.v(c) as usize]);
    for q in lowest.into_iter().chain(others) {
        if let Some(inside) = point_in_solid(table, points, outer, q) {
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
            let [a, b, c] = [0, 1, 2].map(|k| points[table.v(3 * t + k) as usize]);
            if (0..3).any(|k| {
                a[k].max(b[k]).max(c[k]) < seg_lo[k] || a[k].min(b[k]).min(c[k]) > seg_hi[k]
            }) {
                continue;
            }
            let s_near = orient3d(p3(a), p3(b), p3(c), p3(q));
            let s_far = orient3d(p3(a), p3(b), p3(c), p3(far));
            if s_near == 0.0 {
                if in_triangle_coplanar(q, a, b, c) {
                    return None;
                }
                continue; // the segment touches this plane only at q, outside the face
            }
            if s_far == 0.0 {
                continue 'directions;
            }
            if (s_near > 0.0) == (s_far > 0.0) {
                continue;
            }
            let e = [
                orient3d(p3(q), p3(far), p3(a), p3(b)),
                orient3d(p3(q), p3(far), p3(b), p3(c)),
                orient3d(p3(q), p3(far), p3(c), p3(a)),
            ];
            if e.contains(&0.0) {
                continue 'directions;
            }
            if (e[0] > 0.0) == (e[1] > 0.0) && (e[1] > 0.0) == (e[2] > 0.0) {
                crossings += 1;
            }
        }
        return Some(crossings % 2 == 1);
    }
    None
}

/// Whether `q`, in the plane of `a b c`, lies in the closed triangle (exact, projected on the plane's
/// dominant axis).
fn in_triangle_coplanar(q: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> bool {
    let n = super::analyse::normal(&a, &b, &c);
    let drop = (0..3)
        .max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs()))
        .unwrap_or(2);
    let (i, j) = match drop {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    };
    let p2 = |p: [f64; 3]| Coord { x: p[i], y: p[j] };
    let d = [
        orient2d(p2(a), p2(b), p2(q)),
        orient2d(p2(b), p2(c), p2(q)),
        orient2d(p2(c), p2(a), p2(q)),
    ];
    let has_neg = d.iter().any(|&x| x < 0.0);
    let has_pos = d.iter().any(|&x| x > 0.0);
    !(has_neg && has_pos)
}

fn p3(p: [f64; 3]) -> Coord3D<f64> {
    Coord3D {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}
