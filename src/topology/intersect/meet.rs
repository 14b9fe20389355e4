//! Whether two faces **meet**: their closed triangles share a point that is not a vertex or an edge
//! the two faces share in the welded mesh. Which vertices they share comes from their welded vertex
//! ids, never from comparing positions; everything else is decided with exact `orient3d` and
//! `orient2d` signs (the `robust` crate, whose own float filter answers most calls in a few
//! operations), never with a tolerance: a gap of 1e-9 is a gap, an exact contact is a contact.
//!
//! Both triangles must be non-degenerate (three distinct, non-collinear points); the caller leaves
//! the others out. Four cases, by the number of shared vertices:
//!
//! ```text
//!   3 shared: one face on top of the other          -> they meet
//!   2 shared (edge p q): f = p q r, g = p q s       -> meet iff coplanar and r, s on one side of p q
//!   1 shared (vertex v): f = v a b, g = v c d       -> meet iff segment a b meets g or c d meets f
//!   0 shared                                        -> meet iff an edge of one meets the other
//! ```
//!
//! Why the segment tests are enough: the common part K of two triangles is convex. Where the planes
//! differ, K lies on the line where they cross, and each end of K is an end of one triangle's piece
//! of that line, so a point of that triangle's boundary: an edge of one meets the other. In one
//! plane, the boundary of K lies on the two triangles' boundaries, so again an edge of one meets
//! the other. With a shared vertex v, an edge through v can only add points of K beyond v when K is
//! a segment along it, and that segment's far end is on an edge opposite v (the argument is spelled
//! out in the tests).

use robust::{orient2d, orient3d, Coord, Coord3D};

pub(super) type Point = [f64; 3];

/// Whether faces `f` and `g` (welded vertex ids and their positions) meet.
pub(super) fn faces_meet(f_ids: [u32; 3], f: [Point; 3], g_ids: [u32; 3], g: [Point; 3]) -> bool {
    // `at[i]`: the corner of g on f's vertex i, if any.
    let at = f_ids.map(|v| g_ids.iter().position(|&w| w == v));
    match at.iter().flatten().count() {
        0 => disjoint_meet(f, g),
        1 => {
            let i = at
                .iter()
                .position(Option::is_some)
                .expect("one shared vertex");
            let j = at[i].expect("one shared vertex");
            let (v, a, b) = (f[i], f[(i + 1) % 3], f[(i + 2) % 3]);
            let (c, d) = (g[(j + 1) % 3], g[(j + 2) % 3]);
            vertex_meet(v, a, b, c, d)
        }
        2 => {
            let i = at
                .iter()
                .position(Option::is_none)
                .expect("one vertex not shared");
            let s = (0..3)
                .find(|&k| !at.contains(&Some(k)))
                .expect("one vertex not shared");
            edge_meet(f[(i + 1) % 3], f[(i + 2) % 3], f[i], g[s])
        }
        _ => true,
    }
}

/// Faces `p q r` and `p q s` sharing edge `p q`: they meet only when they fold onto each other,
/// lying in one plane with `r` and `s` on the same side of the edge.
fn edge_meet(p: Point, q: Point, r: Point, s: Point) -> bool {
    if o3(p, q, r, s) != 0.0 {
        return false;
    }
    let axes = plane_axes(p, q, r);
    let (p, q, r, s) = (axes.of(p), axes.of(q), axes.of(r), axes.of(s));
    strictly_same_side(o2(p, q, r), o2(p, q, s))
}

/// Faces `v a b` and `v c d` sharing vertex `v`: they meet when they have another common point,
/// which is when segment `c d` meets `v a b` or segment `a b` meets `v c d`.
fn vertex_meet(v: Point, a: Point, b: Point, c: Point, d: Point) -> bool {
    let (sc, sd) = (o3(v, a, b, c), o3(v, a, b, d));
    if strictly_same_side(sc, sd) {
        // g touches f's plane only at v.
        return false;
    }
    let (sa, sb) = (o3(v, c, d, a), o3(v, c, d, b));
    if strictly_same_side(sa, sb) {
        return false;
    }
    segment_meets_triangle(c, d, sc, sd, [v, a, b])
        || segment_meets_triangle(a, b, sa, sb, [v, c, d])
}

/// Faces with no shared vertex: they meet when an edge of one meets the other.
fn disjoint_meet(f: [Point; 3], g: [Point; 3]) -> bool {
    let sg = g.map(|x| o3(f[0], f[1], f[2], x));
    if one_strict_side(sg) {
        return false;
    }
    let sf = f.map(|x| o3(g[0], g[1], g[2], x));
    if one_strict_side(sf) {
        return false;
    }
    if sg == [0.0; 3] {
        let axes = plane_axes(f[0], f[1], f[2]);
        return coplanar_triangles_meet(f.map(|x| axes.of(x)), g.map(|x| axes.of(x)));
    }
    (0..3).any(|k| {
        let l = (k + 1) % 3;
        segment_meets_triangle(f[k], f[l], sf[k], sf[l], g)
            || segment_meets_triangle(g[k], g[l], sg[k], sg[l], f)
    })
}

/// Whether closed segment `p q` meets closed triangle `t`, given the signs `sp`, `sq` of
/// `orient3d(t, p)` and `orient3d(t, q)` (the triangle's plane against each end).
fn segment_meets_triangle(p: Point, q: Point, sp: f64, sq: f64, t: [Point; 3]) -> bool {
    if strictly_same_side(sp, sq) {
        return false;
    }
    if sp == 0.0 || sq == 0.0 {
        let axes = plane_axes(t[0], t[1], t[2]);
        let t2 = t.map(|x| axes.of(x));
        return match (sp == 0.0, sq == 0.0) {
            (true, true) => segment_meets_triangle_2d(axes.of(p), axes.of(q), t2),
            (true, false) => point_in_triangle_2d(axes.of(p), t2),
            _ => point_in_triangle_2d(axes.of(q), t2),
        };
    }
    // The ends are strictly on either side of the plane: the crossing point is in the closed
    // triangle when the line p q passes no edge on the other side from the rest (Plücker signs).
    let e = [
        o3(p, q, t[0], t[1]),
        o3(p, q, t[1], t[2]),
        o3(p, q, t[2], t[0]),
    ];
    !mixed(e)
}

/// Two triangles in one plane (projected): they meet unless an edge of one has the whole other
/// triangle strictly on its outer side (for closed convex polygons, a separating line can always be
/// taken along an edge of one of them).
fn coplanar_triangles_meet(f: [[f64; 2]; 3], g: [[f64; 2]; 3]) -> bool {
    !(separates(f, &g) || separates(g, &f))
}

/// Whether an edge of triangle `t` has every point of `others` strictly outside it.
fn separates(t: [[f64; 2]; 3], others: &[[f64; 2]]) -> bool {
    (0..3).any(|k| {
        let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
        let inside = o2(a, b, c);
        others
            .iter()
            .all(|&x| strictly_opposite(o2(a, b, x), inside))
    })
}

/// Closed segment `p q` against a closed triangle, in one plane (projected): separated by an edge of
/// the triangle, or by the segment's own line (the triangle strictly on one side of it), or they
/// meet.
fn segment_meets_triangle_2d(p: [f64; 2], q: [f64; 2], t: [[f64; 2]; 3]) -> bool {
    if separates(t, &[p, q]) {
        return false;
    }
    !one_strict_side(t.map(|x| o2(p, q, x)))
}

/// Whether `p` lies in the closed triangle `t` (in one plane, projected).
fn point_in_triangle_2d(p: [f64; 2], t: [[f64; 2]; 3]) -> bool {
    !mixed([o2(t[0], t[1], p), o2(t[1], t[2], p), o2(t[2], t[0], p)])
}

/// Whether the exact triangle `a b c` is collinear (zero area; three distinct points on a line).
pub(super) fn collinear(a: Point, b: Point, c: Point) -> bool {
    AXES.iter()
        .all(|axes| o2(axes.of(a), axes.of(b), axes.of(c)) == 0.0)
}

/// The two coordinates kept when a plane is projected along the third.
#[derive(Debug, Clone, Copy)]
struct Axes(usize, usize);

const AXES: [Axes; 3] = [Axes(1, 2), Axes(2, 0), Axes(0, 1)];

impl Axes {
    fn of(self, p: Point) -> [f64; 2] {
        [p[self.0], p[self.1]]
    }
}

/// A projection that keeps triangle `a b c` a triangle, so that in its plane every incidence is the
/// same before and after: the axis along which its normal is largest (in floating point), checked
/// exactly, else another axis where the exact projected area is not zero.
fn plane_axes(a: Point, b: Point, c: Point) -> Axes {
    let n = cross(sub(b, a), sub(c, a));
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| n[j].abs().total_cmp(&n[i].abs()));
    order
        .iter()
        .map(|&k| AXES[k])
        .find(|axes| o2(axes.of(a), axes.of(b), axes.of(c)) != 0.0)
        .unwrap_or(AXES[order[0]])
}

/// The three signs are all strictly positive or all strictly negative.
fn one_strict_side(s: [f64; 3]) -> bool {
    (s[0] > 0.0 && s[1] > 0.0 && s[2] > 0.0) || (s[0] < 0.0 && s[1] < 0.0 && s[2] < 0.0)
}

/// Both strictly positive or both strictly negative. (Signs, not a product: the product of two
/// tiny determinants can round to zero.)
fn strictly_same_side(a: f64, b: f64) -> bool {
    (a > 0.0 && b > 0.0) || (a < 0.0 && b < 0.0)
}

/// One strictly positive, the other strictly negative.
fn strictly_opposite(a: f64, b: f64) -> bool {
    (a > 0.0 && b < 0.0) || (a < 0.0 && b > 0.0)
}

/// Some sign strictly positive and some strictly negative.
fn mixed(s: [f64; 3]) -> bool {
    s.iter().any(|&x| x > 0.0) && s.iter().any(|&x| x < 0.0)
}

fn o3(a: Point, b: Point, c: Point, d: Point) -> f64 {
    let p = |p: Point| Coord3D {
        x: p[0],
        y: p[1],
        z: p[2],
    };
    orient3d(p(a), p(b), p(c), p(d))
}

fn o2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    let p = |p: [f64; 2]| Coord { x: p[0], y: p[1] };
    orient2d(p(a), p(b), p(c))
}

fn sub(a: Point, b: Point) -> Point {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: Point, b: Point) -> Point {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
