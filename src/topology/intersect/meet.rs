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
#[cfg(test)]
pub(super) fn faces_meet(f_ids: [u32; 3], f: [Point; 3], g_ids: [u32; 3], g: [Point; 3]) -> bool {
    faces_meet_with::<true>(shared(f_ids, g_ids), &Plane::of(f[0], f[1], f[2]), g)
}

/// [`faces_meet`] with f given by its plane ([`Plane::of`] its corners in order), which a caller
/// testing one face against many computes once, and the vertices the faces share ([`shared`]).
pub(super) fn plane_meets(shared: u32, f: &Plane, g: [Point; 3]) -> bool {
    faces_meet_with::<true>(shared, f, g)
}

/// Which vertices faces `f` and `g` share: bit `3 i + j` set when f's vertex `i` is g's vertex `j`.
#[inline]
pub(super) fn shared(f_ids: [u32; 3], g_ids: [u32; 3]) -> u32 {
    let mut shared = 0u32;
    for (i, &v) in f_ids.iter().enumerate() {
        for (j, &w) in g_ids.iter().enumerate() {
            shared |= u32::from(v == w) << (3 * i + j);
        }
    }
    shared
}

/// [`faces_meet`], with or without the shortcuts (the normals' dot product for faces on one edge,
/// the projections for the others; `false`: only the side tests, which the tests hold the
/// shortcuts to).
fn faces_meet_with<const SHORTCUTS: bool>(shared: u32, plane: &Plane, g: [Point; 3]) -> bool {
    let f = plane.corners();
    match shared.count_ones() {
        0 => disjoint_meet::<SHORTCUTS>(plane, g),
        1 => {
            let bit = shared.trailing_zeros() as usize;
            let (i, j) = (bit / 3, bit % 3);
            vertex_meet::<SHORTCUTS>(plane, f[i], f[NEXT[i]], f[PREV[i]], g[NEXT[j]], g[PREV[j]])
        }
        2 => {
            // The row of f and the column of g without a shared vertex.
            let rows = (0..3).map(|i| (shared >> (3 * i)) & 7);
            let i = rows.clone().position(|r| r == 0).unwrap_or(0);
            let columns = rows.fold(0, |c, r| c | r);
            let s = (!columns & 7).trailing_zeros() as usize;
            edge_meet::<SHORTCUTS>(f[NEXT[i]], f[PREV[i]], f[i], g[s.min(2)])
        }
        _ => true,
    }
}

/// The next and the previous corner of a triangle.
const NEXT: [usize; 3] = [1, 2, 0];
const PREV: [usize; 3] = [2, 0, 1];

/// Faces `p q r` and `p q s` sharing edge `p q`: they meet only when they fold onto each other,
/// lying in one plane with `r` and `s` on the same side of the edge.
///
/// Most such pairs are neighbours on a surface, far from folded: the normals of `p q r` and
/// `p q s`, `(q - p) x (r - p)` and `(q - p) x (s - p)`, point apart (`r` and `s` on opposite sides
/// of the edge, in the plane when there is one), which a dot product beyond its rounding error
/// says without `orient3d`; exactly flat neighbours (a quad split in two) would each need the
/// exact predicate otherwise.
fn edge_meet<const SHORTCUTS: bool>(p: Point, q: Point, r: Point, s: Point) -> bool {
    let (e, u, w) = (sub(q, p), sub(r, p), sub(s, p));
    let (nu, nw) = (cross(e, u), cross(e, w));
    let apart = nu[0] * nw[0] + nu[1] * nw[1] + nu[2] * nw[2];
    let size = |a: Point, k: usize| {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        (e[i] * a[j]).abs() + (e[j] * a[i]).abs()
    };
    let permanent: f64 = (0..3).map(|k| size(u, k) * size(w, k)).sum();
    // The bound assumes no product underflowed. Faces that reach here are not zero-area, so a
    // normal component too small for that has a partner just as small when the faces fold (the
    // only case the answer could flip); the permanent above 2^-900 guards the rest.
    if SHORTCUTS && permanent > 1e-271 && apart < -FOLD_ERROR * permanent {
        return false;
    }
    if Plane::of(p, q, r).side(s) != 0.0 {
        return false;
    }
    let axes = plane_axes(p, q, r);
    let (p, q, r, s) = (axes.of(p), axes.of(q), axes.of(r), axes.of(s));
    strictly_same_side(o2(p, q, r), o2(p, q, s))
}

/// Bounds the rounding error of the dot product of two cross products of rounded differences
/// relative to its permanent (the same sum of products of magnitudes): each of its terms passes
/// through at most eleven roundings of relative error 2^-53 (the three differences, the products
/// and subtractions of the cross products, the product of the two components, the sum of
/// three), about 1.2e-15; this is eight times that.
const FOLD_ERROR: f64 = 1e-14;

/// Faces `v a b` and `v c d` sharing vertex `v`: they meet when they have another common point,
/// which is when segment `c d` meets `v a b` or segment `a b` meets `v c d`.
///
/// Where floating point cannot tell a side (faces of one flat fan, common in CAD meshes), the
/// exact predicate is slow; the faces' projections along f's normal often show first, exactly,
/// that they share only `v` ([`cones_apart`]).
///
/// `f` is the plane of `v a b` from any of its corners ([`Plane::of`] `v a b`, `a b v` or `b v a`:
/// the same signs).
fn vertex_meet<const SHORTCUTS: bool>(
    f: &Plane,
    v: Point,
    a: Point,
    b: Point,
    c: Point,
    d: Point,
) -> bool {
    let (qc, qd) = (f.quick_side(c), f.quick_side(d));
    match (qc, qd) {
        (Some(sc), Some(sd)) if strictly_same_side(sc, sd) => return false,
        (Some(_), Some(_)) => {}
        _ if SHORTCUTS && cones_apart(f.flat(), v, a, b, c, d) => return false,
        _ => {}
    }
    let sc = qc.unwrap_or_else(|| f.side(c));
    let sd = qd.unwrap_or_else(|| f.side(d));
    if strictly_same_side(sc, sd) {
        // g touches f's plane only at v.
        return false;
    }
    if sc == 0.0 && sd == 0.0 {
        // One plane (then f's vertices are on g's plane too: no need to ask).
        return segment_meets_triangle(c, d, 0.0, 0.0, [v, a, b])
            || segment_meets_triangle(a, b, 0.0, 0.0, [v, c, d]);
    }
    let g = Plane::of(v, c, d);
    let (sa, sb) = (g.side(a), g.side(b));
    if strictly_same_side(sa, sb) {
        return false;
    }
    if strictly_opposite(sc, sd) && strictly_opposite(sa, sb) {
        // Each face crosses the other's plane: the planes meet in a line through v, which leaves f
        // at a point X of a b and g at a point Y of c d. f and g share [v, X] and [v, Y] of it, so
        // they meet when X and Y lie on the same side of v, that is when Y (where c d crosses f's
        // plane) lies in f's angle at v: on the inner side of the lines v a and b v, or on them.
        // Y is strictly outside an edge's line when the edge's Plücker sign has the sign of c's
        // side (see `segment_meets_triangle`). Those signs are sides already known: v a against
        // c d is `orient3d(c, d, v, a)`, a's side of g's plane (c d v is v c d turned), and b v is
        // `orient3d(c, d, b, v) = -orient3d(v, c, d, b)`, minus b's side, which has a's sign here.
        // So both lines agree, and one comparison decides.
        return !strictly_same_side(sa, sc);
    }
    segment_meets_triangle(c, d, sc, sd, [v, a, b])
        || segment_meets_triangle(a, b, sa, sb, [v, c, d])
}

/// Whether faces `v a b` and `v c d` share only `v`, shown in the projection `axes`: there `v a b`
/// must stay a triangle (so no other point of its plane falls onto `v`), and a line through `v`
/// along one of the four edges at `v` must have one face's other corner strictly on one side and
/// both of the other face's strictly on the other. Then the projected faces share only `v`, and so
/// do the faces. `false` says nothing.
fn cones_apart(axes: Axes, v: Point, a: Point, b: Point, c: Point, d: Point) -> bool {
    let [v, a, b, c, d] = [axes.of(v), axes.of(a), axes.of(b), axes.of(c), axes.of(d)];
    let turn = o2(v, a, b);
    if turn == 0.0 {
        return false;
    }
    let beyond = |edge: [f64; 2], own: f64, x: [f64; 2], y: [f64; 2]| {
        strictly_opposite(o2(v, edge, x), own) && strictly_opposite(o2(v, edge, y), own)
    };
    if beyond(a, turn, c, d) || beyond(b, -turn, c, d) {
        return true;
    }
    let other = o2(v, c, d);
    other != 0.0 && (beyond(c, other, a, b) || beyond(d, -other, a, b))
}

/// Faces with no shared vertex: they meet when an edge of one meets the other.
///
/// As in [`vertex_meet`], where floating point cannot tell a side, disjoint projections along f's
/// normal settle it first (two triangles whose shadows are apart are apart).
fn disjoint_meet<const SHORTCUTS: bool>(plane: &Plane, g: [Point; 3]) -> bool {
    let f = plane.corners();
    let quick = each(g, |x| plane.quick_side(x));
    if let [Some(x), Some(y), Some(z)] = quick {
        if one_strict_side([x, y, z]) {
            return false;
        }
    } else if SHORTCUTS {
        let axes = plane.flat();
        let (f2, g2) = (each(f, |x| axes.of(x)), each(g, |x| axes.of(x)));
        if separates(f2, &g2) || separates(g2, &f2) {
            return false;
        }
    }
    let sg: [f64; 3] = std::array::from_fn(|k| quick[k].unwrap_or_else(|| plane.side(g[k])));
    if one_strict_side(sg) {
        return false;
    }
    if sg == [0.0; 3] {
        // One plane (then f's vertices are on g's plane too: no need to ask).
        let axes = plane.axes();
        return coplanar_triangles_meet(each(f, |x| axes.of(x)), each(g, |x| axes.of(x)));
    }
    if let Some(touch) = touching(g, sg, plane) {
        return touch;
    }
    let plane = Plane::of(g[0], g[1], g[2]);
    let sf = each(f, |x| plane.side(x));
    if one_strict_side(sf) {
        return false;
    }
    if let Some(touch) = touching(f, sf, &plane) {
        return touch;
    }
    (0..3).any(|k| {
        let l = (k + 1) % 3;
        segment_meets_triangle(f[k], f[l], sf[k], sf[l], g)
            || segment_meets_triangle(g[k], g[l], sg[k], sg[l], f)
    })
}

/// When triangle `t` only touches `plane`, another triangle's (given the sides `s` of `t`'s
/// vertices, not all zero, not all strictly on one side), whether the two meet: with one vertex on
/// the plane and the other two strictly on one side, `t` meets the plane only at that vertex; with
/// two on it, only along that edge. `None` when `t` crosses the plane.
fn touching(t: [Point; 3], s: [f64; 3], plane: &Plane) -> Option<bool> {
    let zeros = s.iter().filter(|&&x| x == 0.0).count();
    let k = s.iter().position(|&x| x == 0.0)?;
    let (l, m) = ((k + 1) % 3, (k + 2) % 3);
    let other = plane.corners();
    let axes = || plane.axes();
    match zeros {
        1 if strictly_same_side(s[l], s[m]) => {
            let axes = axes();
            Some(point_in_triangle_2d(
                axes.of(t[k]),
                each(other, |x| axes.of(x)),
            ))
        }
        2 => {
            // The other vertex is off the plane; the two on it are an edge of t.
            let (p, q) = if s[l] == 0.0 {
                (t[k], t[l])
            } else {
                (t[m], t[k])
            };
            let axes = axes();
            Some(segment_meets_triangle_2d(
                axes.of(p),
                axes.of(q),
                each(other, |x| axes.of(x)),
            ))
        }
        _ => None,
    }
}

/// The plane of triangle `p q r`, kept in the form its side tests filter best: `n = (q - p) x
/// (r - p)` and, per axis, the sum of the magnitudes of the two products that make `n`'s
/// component.
pub(super) struct Plane {
    p: Point,
    q: Point,
    r: Point,
    n: [f64; 3],
    magnitude: [f64; 3],
    /// `q - p` or `r - p` has a tiny component ([`has_tiny`]).
    tiny: bool,
    /// [`plane_axes`] of the triangle, found when first asked.
    axes: std::cell::OnceCell<Axes>,
}

/// Bounds the rounding error of `(s - p) . n` relative to its permanent: Shewchuk's first
/// `orient3d` bound, `(7 + 56 eps) eps`, rounded up. The expression has the same shape as the one
/// his bound is derived for (a sum of three rounded differences, each times a difference of two
/// products of rounded differences), only expanded along another row.
const SIDE_ERROR: f64 = 7.8e-16;

impl Plane {
    pub(super) fn of(p: Point, q: Point, r: Point) -> Plane {
        let (u, w) = (sub(q, p), sub(r, p));
        Plane {
            p,
            q,
            r,
            n: cross(u, w),
            magnitude: [
                (u[1] * w[2]).abs() + (u[2] * w[1]).abs(),
                (u[2] * w[0]).abs() + (u[0] * w[2]).abs(),
                (u[0] * w[1]).abs() + (u[1] * w[0]).abs(),
            ],
            tiny: has_tiny(&[u, w]),
            axes: std::cell::OnceCell::new(),
        }
    }

    /// The triangle's corners, in order.
    pub(super) fn corners(&self) -> [Point; 3] {
        [self.p, self.q, self.r]
    }

    /// A projection that keeps this triangle a triangle ([`plane_axes`]), computed once.
    fn axes(&self) -> Axes {
        *self.axes.get_or_init(|| plane_axes(self.p, self.q, self.r))
    }

    /// `orient3d(p, q, r, s)` in sign (the same sign as `-(s - p) . n`): decided in floating point
    /// when the value is beyond its error bound, else by the exact predicate.
    #[inline]
    fn side(&self, s: Point) -> f64 {
        self.quick_side(s)
            .unwrap_or_else(|| o3(self.p, self.q, self.r, s))
    }

    /// [`Plane::side`] when floating point settles it; `None` when only the exact predicate can.
    #[inline]
    fn quick_side(&self, s: Point) -> Option<f64> {
        let d = sub(s, self.p);
        let det = d[0] * self.n[0] + d[1] * self.n[1] + d[2] * self.n[2];
        let permanent = d[0].abs() * self.magnitude[0]
            + d[1].abs() * self.magnitude[1]
            + d[2].abs() * self.magnitude[2];
        if det.abs() > SIDE_ERROR * permanent {
            return Some(-det);
        }
        if permanent == 0.0 && !self.tiny && !has_tiny(&[d]) {
            return Some(0.0);
        }
        None
    }

    /// The projection along the axis where this plane's normal is largest (in floating point).
    fn flat(&self) -> Axes {
        let [x, y, z] = self.n.map(f64::abs);
        AXES[if x >= y && x >= z {
            0
        } else if y >= z {
            1
        } else {
            2
        }]
    }
}

/// Whether closed segment `p q` meets closed triangle `t`, given the signs `sp`, `sq` of
/// `orient3d(t, p)` and `orient3d(t, q)` (the triangle's plane against each end).
fn segment_meets_triangle(p: Point, q: Point, sp: f64, sq: f64, t: [Point; 3]) -> bool {
    if strictly_same_side(sp, sq) {
        return false;
    }
    if sp == 0.0 || sq == 0.0 {
        let axes = plane_axes(t[0], t[1], t[2]);
        let t2 = each(t, |x| axes.of(x));
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
    // The inner side of every edge: the triangle's turn, the same exact sign from each corner.
    let inside = o2(t[0], t[1], t[2]);
    (0..3).any(|k| {
        let (a, b) = (t[k], t[(k + 1) % 3]);
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
    !one_strict_side(each(t, |x| o2(p, q, x)))
}

/// Whether `p` lies in the closed triangle `t` (in one plane, projected).
fn point_in_triangle_2d(p: [f64; 2], t: [[f64; 2]; 3]) -> bool {
    !mixed([o2(t[0], t[1], p), o2(t[1], t[2], p), o2(t[2], t[0], p)])
}

/// The signs of triangle `a b c`'s area in the three projections along the axes (exact
/// `orient2d`, [`AXES`] order): the components of its normal `(b - a) x (c - a)` in sign.
pub(super) fn turns(a: Point, b: Point, c: Point) -> [f64; 3] {
    // Written out: `array::map` here costs more than the three filters.
    let [x, y, z] = AXES;
    [
        o2(x.of(a), x.of(b), x.of(c)),
        o2(y.of(a), y.of(b), y.of(c)),
        o2(z.of(a), z.of(b), z.of(c)),
    ]
}

/// Whether the exact triangle `a b c` is collinear (zero area; three distinct points on a line):
/// every projection of it has zero area.
#[cfg(test)]
pub(super) fn collinear(a: Point, b: Point, c: Point) -> bool {
    turns(a, b, c) == [0.0; 3]
}

/// The two coordinates kept when a plane is projected along the third.
#[derive(Debug, Clone, Copy)]
pub(super) struct Axes(pub(super) usize, pub(super) usize);

pub(super) const AXES: [Axes; 3] = [Axes(1, 2), Axes(2, 0), Axes(0, 1)];

impl Axes {
    pub(super) fn of(self, p: Point) -> [f64; 2] {
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

/// Whether a difference is nonzero but so small that a product of three such could round to zero
/// (below 2^-340). Without one, a permanent (a sum of magnitudes of such products) that is zero
/// in floating point is zero exactly, every term of the determinant with it: the determinant is
/// exactly zero, which is the common case of points on an axis-aligned plane, and the exact
/// predicate need not be asked.
fn has_tiny(differences: &[Point]) -> bool {
    const TINY: f64 = 4.5e-103; // 2^-340
    differences
        .iter()
        .flatten()
        .any(|&x| x != 0.0 && x.abs() < TINY)
}

/// `f` of each of three values, written out: `array::map` is not always inlined here, and a call
/// per pair of faces costs as much as the tests.
#[inline(always)]
fn each<T: Copy, U>(a: [T; 3], f: impl Fn(T) -> U) -> [U; 3] {
    [f(a[0]), f(a[1]), f(a[2])]
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
pub(super) fn strictly_opposite(a: f64, b: f64) -> bool {
    (a > 0.0 && b < 0.0) || (a < 0.0 && b > 0.0)
}

/// Some sign strictly positive and some strictly negative.
fn mixed(s: [f64; 3]) -> bool {
    s.iter().any(|&x| x > 0.0) && s.iter().any(|&x| x < 0.0)
}

/// `orient3d(a, b, c, d)`: its floating-point value when beyond Shewchuk's first error bound
/// (the same test `robust` makes first, here inline), else `robust`'s exact answer.
#[inline]
pub(super) fn o3(a: Point, b: Point, c: Point, d: Point) -> f64 {
    let (ad, bd, cd) = (sub(a, d), sub(b, d), sub(c, d));
    let (bc, cb) = (bd[0] * cd[1], cd[0] * bd[1]);
    let (ca, ac) = (cd[0] * ad[1], ad[0] * cd[1]);
    let (ab, ba) = (ad[0] * bd[1], bd[0] * ad[1]);
    let det = ad[2] * (bc - cb) + bd[2] * (ca - ac) + cd[2] * (ab - ba);
    let permanent = (bc.abs() + cb.abs()) * ad[2].abs()
        + (ca.abs() + ac.abs()) * bd[2].abs()
        + (ab.abs() + ba.abs()) * cd[2].abs();
    if det.abs() > SIDE_ERROR * permanent {
        return det;
    }
    if permanent == 0.0 && !has_tiny(&[ad, bd, cd]) {
        return 0.0;
    }
    let p = |p: Point| Coord3D {
        x: p[0],
        y: p[1],
        z: p[2],
    };
    orient3d(p(a), p(b), p(c), p(d))
}

/// `orient2d(a, b, c)`: its floating-point value when beyond Shewchuk's first error bound, zero
/// when that is exact (see [`has_tiny`]), else `robust`'s exact answer.
#[inline]
pub(super) fn o2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    let (ac, bc) = ([a[0] - c[0], a[1] - c[1]], [b[0] - c[0], b[1] - c[1]]);
    let (left, right) = (ac[0] * bc[1], ac[1] * bc[0]);
    let det = left - right;
    let detsum = left.abs() + right.abs();
    if det.abs() > 3.4e-16 * detsum {
        return det;
    }
    if detsum == 0.0 && !has_tiny(&[[ac[0], ac[1], 0.0], [bc[0], bc[1], 0.0]]) {
        return 0.0;
    }
    let p = |p: [f64; 2]| Coord { x: p[0], y: p[1] };
    orient2d(p(a), p(b), p(c))
}

pub(super) fn sub(a: Point, b: Point) -> Point {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn cross(a: Point, b: Point) -> Point {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shortcuts never change an answer: pairs of faces on a coarse integer grid (so that many
    /// are exactly coplanar, fold, touch, or put a corner exactly on the other's plane), sharing
    /// no vertex or one (the projections) or two (the normals' dot product), and the same pairs
    /// turned by an angle (so that floating point cannot tell the sides and the projections
    /// run), each decided with and without them.
    #[test]
    fn shortcuts_agree_with_the_side_tests() {
        let mut bits = crate::geometry::xorshift(0x5eed_cafe);
        let mut coordinate = || (bits() % 5) as f64;
        let (s, c) = (0.6f64, 0.8f64);
        let (mut met, mut apart) = (0, 0);
        for round in 0..60_000 {
            let mut p: [Point; 6] =
                std::array::from_fn(|_| [coordinate(), coordinate(), coordinate()]);
            if round % 2 == 1 {
                // A rotation about x and z by angles whose sines and cosines are not all exact.
                for q in &mut p {
                    let [x, y, z] = *q;
                    let (y, z) = (c * y - s * z + 0.1, s * y + c * z);
                    *q = [x * 0.28 - y * 0.96, x * 0.96 + y * 0.28, z];
                }
            }
            let shared = round % 3;
            let f_ids = [0, 1, 2];
            let g_ids: [u32; 3] = match shared {
                0 => [3, 4, 5],
                1 => [0, 4, 5],
                _ => [1, 0, 5],
            };
            let at = |i: u32| p[i as usize];
            let (f, g) = (f_ids.map(at), g_ids.map(at));
            let distinct = |t: [u32; 3]| {
                let q = t.map(at);
                q[0] != q[1] && q[1] != q[2] && q[0] != q[2] && !collinear(q[0], q[1], q[2])
            };
            let welded = (0..6).all(|i| (i + 1..6).all(|j| p[i] != p[j]));
            if !distinct(f_ids) || !distinct(g_ids) || !welded {
                continue;
            }
            let plane = Plane::of(f[0], f[1], f[2]);
            let ids = super::shared(f_ids, g_ids);
            let quick = faces_meet_with::<true>(ids, &plane, g);
            assert_eq!(
                quick,
                faces_meet_with::<false>(ids, &plane, g),
                "{f:?} {g:?}"
            );
            if quick {
                met += 1;
            } else {
                apart += 1;
            }
        }
        assert!(met > 1000 && apart > 1000, "{met} met, {apart} apart");
    }

    /// A corner: welded vertex id and position.
    type Corner = (u32, Point);

    /// Whether `f` and `g` meet, asserting that the answer is the same for every rotation of
    /// either face's corners, both windings of each, and the two faces swapped.
    fn meets(f: [Corner; 3], g: [Corner; 3]) -> bool {
        let variants = |t: [Corner; 3]| {
            let mut all = Vec::new();
            for r in 0..3 {
                let turned = [t[r], t[(r + 1) % 3], t[(r + 2) % 3]];
                all.push(turned);
                all.push([turned[0], turned[2], turned[1]]);
            }
            all
        };
        let answer = |f: [Corner; 3], g: [Corner; 3]| {
            faces_meet(
                f.map(|c| c.0),
                f.map(|c| c.1),
                g.map(|c| c.0),
                g.map(|c| c.1),
            )
        };
        let first = answer(f, g);
        for fv in variants(f) {
            for gv in variants(g) {
                assert_eq!(answer(fv, gv), first, "{fv:?} {gv:?}");
                assert_eq!(answer(gv, fv), first, "{gv:?} {fv:?}");
            }
        }
        first
    }

    /// The face f of every test: `(0,0,0) (4,0,0) (0,4,0)` in the plane z = 0, vertices 0, 1, 2.
    /// Its points are `x, y >= 0, x + y <= 4`.
    const F: [Corner; 3] = [
        (0, [0.0, 0.0, 0.0]),
        (1, [4.0, 0.0, 0.0]),
        (2, [0.0, 4.0, 0.0]),
    ];

    /// A face of new vertices 10, 11, 12 (no vertex shared with F).
    fn apart(a: Point, b: Point, c: Point) -> [Corner; 3] {
        [(10, a), (11, b), (12, c)]
    }

    /// g = (1,1,-1) (1,1,1) (-2,-2,0) lies in the plane x = y and cuts z = 0 along the segment from
    /// (-2,-2,0) (a vertex) to (1,1,0) (its vertical edge's midpoint); F holds (0,0,0)..(2,2,0) of
    /// that line, so they share (0,0,0)..(1,1,0): a crossing. Moved by +4 in x, the cut is
    /// (2,-2,0)..(5,1,0) on y = x - 4, which meets F's region only where y >= 0 and x + y <= 4,
    /// that is x >= 4 and x <= 4: the point (4,0,0), F's vertex, inside g: a touch. Moved by +5,
    /// y = x - 5 needs x >= 5 and x <= 4.5: apart.
    #[test]
    fn crossing_touching_and_apart() {
        let g = |dx: f64| {
            apart(
                [1.0 + dx, 1.0, -1.0],
                [1.0 + dx, 1.0, 1.0],
                [-2.0 + dx, -2.0, 0.0],
            )
        };
        assert!(meets(F, g(0.0)));
        assert!(meets(F, g(4.0)));
        assert!(!meets(F, g(5.0)));
    }

    /// g = (1,1,h) (1,2,1) (2,1,1): for h = 0 its vertex (1,1,0) is inside F (1 + 1 < 4) and the
    /// rest is above z = 0: one common point, they meet. For h = 1e-9 (or -1e-9 seen from below,
    /// with the other two vertices at z = -1) no point of g is on z = 0: no contact, however close.
    #[test]
    fn vertex_on_the_interior_and_a_gap_of_1e_9() {
        let g = |h: f64, up: f64| apart([1.0, 1.0, h], [1.0, 2.0, up], [2.0, 1.0, up]);
        assert!(meets(F, g(0.0, 1.0)));
        assert!(!meets(F, g(1e-9, 1.0)));
        assert!(meets(F, g(0.0, -1.0)));
        assert!(!meets(F, g(-1e-9, -1.0)));
    }

    /// g = (2,-1,1) (2,1,-1) (2,-1,-1) lies in the plane x = 2; its edge from (2,-1,1) to (2,1,-1)
    /// passes through (2,0,0) on F's edge from (0,0,0) to (4,0,0), and g meets z = 0 only along
    /// (2,-1,0)..(2,0,0), which F holds only at y = 0: an edge touching an edge at one point. Moved
    /// by -2^-30 in y, g's points on z = 0 all have y < 0: apart.
    #[test]
    fn edge_touching_an_edge() {
        let g = |dy: f64| {
            apart(
                [2.0, -1.0 + dy, 1.0],
                [2.0, 1.0 + dy, -1.0],
                [2.0, -1.0 + dy, -1.0],
            )
        };
        assert!(meets(F, g(0.0)));
        assert!(!meets(F, g(-(2f64.powi(-30)))));
    }

    /// g with an edge in F's plane and its third vertex above it meets z = 0 only along that
    /// edge. The edge (-1,1,0)..(2,1,0) runs through F (y = 1, 0 <= x <= 3): they meet. The edge
    /// (-1,-1,0)..(-2,1,0) has x < 0 all along: apart. The edge (2,2,0)..(3,3,0) starts on F's
    /// edge x + y = 4 and leaves it: one common point, they meet.
    #[test]
    fn edge_lying_in_the_plane() {
        assert!(meets(
            F,
            apart([-1.0, 1.0, 0.0], [2.0, 1.0, 0.0], [0.0, 1.0, 1.0])
        ));
        assert!(!meets(
            F,
            apart([-1.0, -1.0, 0.0], [-2.0, 1.0, 0.0], [0.0, 0.0, 1.0])
        ));
        assert!(meets(
            F,
            apart([2.0, 2.0, 0.0], [3.0, 3.0, 0.0], [3.0, 2.0, 1.0])
        ));
    }

    /// In the plane z = 0: g = (1,1) (5,1) (1,5) overlaps F around (1.5, 1.5); g = (2,2) (5,2) (2,5)
    /// has its vertex (2,2) on F's edge x + y = 4 and the rest beyond it: they touch at one point;
    /// g = (3,3) (6,3) (3,6) has x + y >= 6 > 4 everywhere: apart. And g = (1,1) (2,1) (1,2) lies
    /// inside F: no edges cross, they overlap.
    #[test]
    fn coplanar_overlap_touch_apart_and_inside() {
        let g = |a: f64, b: f64| apart([a, a, 0.0], [b, a, 0.0], [a, b, 0.0]);
        assert!(meets(F, g(1.0, 5.0)));
        assert!(meets(F, g(2.0, 5.0)));
        assert!(!meets(F, g(3.0, 6.0)));
        assert!(meets(F, g(1.0, 2.0)));
    }

    /// Sharing the edge (0,0,0)-(4,0,0) (vertices 0 and 1) with s the other vertex of g: s =
    /// (2,2,0) is in F's plane on F's side of the edge (y > 0): g folds onto F, they meet. s =
    /// (2,-2,0) is on the other side: a flat continuation, only the edge is common. s = (2,2,1) or
    /// (2,2,1e-9) is off the plane: the planes cross along the edge's line, only the edge is common.
    #[test]
    fn shared_edge_fold_or_not() {
        let g = |s: Point| [F[0], F[1], (12, s)];
        assert!(meets(F, g([2.0, 2.0, 0.0])));
        assert!(!meets(F, g([2.0, -2.0, 0.0])));
        assert!(!meets(F, g([2.0, 2.0, 1.0])));
        assert!(!meets(F, g([2.0, 2.0, 1e-9])));
    }

    /// Sharing vertex 0 at the origin, g = (0,0,0) c d:
    /// - c = (-1,0,1), d = (0,-1,1): g is above z = 0 except at the origin: only the vertex is
    ///   common;
    /// - c = (1,1,-1), d = (1,1,1): g cuts z = 0 along (0,0,0)..(1,1,0), inside F: they cross
    ///   through their only shared vertex;
    /// - c = (2,1,0), d = (1,2,0): g lies in F (coplanar overlap);
    /// - c = (-1,0,0), d = (0,-1,0): coplanar, in the opposite quadrant: only the vertex;
    /// - c = (2,0,0), d = (2,-2,0): coplanar, g's edge to (2,0,0) runs along F's edge to (4,0,0):
    ///   they share that segment;
    /// - c = (2,2,1), d = (2,2,-1): g's edge c d crosses F's edge x + y = 4 at (2,2,0), and g holds
    ///   the whole segment from the origin to it, which F holds too;
    /// - c = (-1,-1,-1), d = (-1,-1,1): each face crosses the other's plane (c, d on either side of
    ///   z = 0; (4,0,0), (0,4,0) on either side of x = y), but g cuts z = 0 along (0,0,0)..(-1,-1,0),
    ///   away from F, which holds (0,0,0)..(2,2,0) of that line: only the vertex;
    /// - c = (-1,-1,-1), d = (3,3,1): the same planes, g's cut now runs from the origin to (1,1,0)
    ///   (where c d crosses z = 0), into F: they cross.
    #[test]
    fn shared_vertex_with_and_without_another_common_point() {
        let g = |c: Point, d: Point| [F[0], (11, c), (12, d)];
        assert!(!meets(F, g([-1.0, 0.0, 1.0], [0.0, -1.0, 1.0])));
        assert!(meets(F, g([1.0, 1.0, -1.0], [1.0, 1.0, 1.0])));
        assert!(meets(F, g([2.0, 1.0, 0.0], [1.0, 2.0, 0.0])));
        assert!(!meets(F, g([-1.0, 0.0, 0.0], [0.0, -1.0, 0.0])));
        assert!(meets(F, g([2.0, 0.0, 0.0], [2.0, -2.0, 0.0])));
        assert!(meets(F, g([2.0, 2.0, 1.0], [2.0, 2.0, -1.0])));
        assert!(!meets(F, g([-1.0, -1.0, -1.0], [-1.0, -1.0, 1.0])));
        assert!(meets(F, g([-1.0, -1.0, -1.0], [3.0, 3.0, 1.0])));
    }

    /// The sign rule the crossing tests rest on: p = (0.2,0.2,-1) below t = (0,0,0) (1,0,0)
    /// (0,1,0) has `orient3d(t, p) > 0`, and the segment up to (0.2,0.2,1) crosses t's interior,
    /// where each edge's Plücker sign is negative, `-0.4` for the edge t0 t1 (the determinant of
    /// the rows p - t1, q - t1, t0 - t1).
    #[test]
    fn plucker_signs_inside_oppose_the_near_end() {
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let (p, q) = ([0.2, 0.2, -1.0], [0.2, 0.2, 1.0]);
        assert!(o3(t[0], t[1], t[2], p) > 0.0);
        assert!((o3(p, q, t[0], t[1]) + 0.4).abs() < 1e-12);
        assert!(o3(p, q, t[1], t[2]) < 0.0 && o3(p, q, t[2], t[0]) < 0.0);
    }

    /// A face on the same three vertices (either winding) covers F: they meet.
    #[test]
    fn same_three_vertices() {
        assert!(meets(F, F));
    }

    /// The filtered side test and the inline `orient3d` have the sign of `robust`'s exact
    /// `orient3d` (which flips when the first point moves to the end) for points on and near a
    /// plane: points `a + s (b - a) + t (c - a)` moved off it by 0, a few ulps or more, where
    /// a plain floating-point determinant can get the sign wrong. For the triangle (0.1, 0.2,
    /// 0.3) (1.7, 0.4, 0.9) (0.3, 1.9, 0.6) the points are rounded off the plane; for (1, 2, 3)
    /// (9, -2, 5) (-3, 7, 1) with s, t multiples of 1/8 they are exactly on it.
    #[test]
    fn filtered_side_agrees_with_orient3d() {
        let sign = |x: f64| (x > 0.0) as i8 - (x < 0.0) as i8;
        let mut decided = [0usize; 3];
        for (a, b, c, step) in [
            (
                [0.1, 0.2, 0.3],
                [1.7, 0.4, 0.9],
                [0.3, 1.9, 0.6],
                1.0 / 13.0,
            ),
            (
                [1.0, 2.0, 3.0],
                [9.0, -2.0, 5.0],
                [-3.0, 7.0, 1.0],
                1.0 / 8.0,
            ),
        ] {
            let plane = Plane::of(a, b, c);
            for i in 0..40 {
                for j in 0..40 {
                    let (s, t) = (i as f64 * step - 1.0, j as f64 * step - 2.0);
                    let on: Point =
                        std::array::from_fn(|k| a[k] + s * (b[k] - a[k]) + t * (c[k] - a[k]));
                    for off in [0.0, 1e-17, -3e-16, 1e-15, -1e-12, 1e-6] {
                        let x = [on[0], on[1], on[2] + off];
                        let c3 = |p: Point| Coord3D {
                            x: p[0],
                            y: p[1],
                            z: p[2],
                        };
                        let exact = sign(orient3d(c3(a), c3(b), c3(c), c3(x)));
                        assert_eq!(sign(plane.side(x)), exact, "{x:?}");
                        assert_eq!(sign(o3(a, b, c, x)), exact, "{x:?}");
                        assert_eq!(sign(o3(x, a, b, c)), -exact, "{x:?}");
                        decided[(exact + 1) as usize] += 1;
                    }
                }
            }
        }
        assert!(decided.iter().all(|&n| n > 1000), "{decided:?}");
    }

    /// (0,0,0) (1,1,1) (3,3,3) are on one line; (0,0,0) (1,1,1) (3,3,3 + 2^-40) are not, though
    /// their area is tiny.
    #[test]
    fn collinear_points() {
        let (a, b) = ([0.0; 3], [1.0; 3]);
        assert!(collinear(a, b, [3.0; 3]));
        assert!(!collinear(a, b, [3.0, 3.0, 3.0 + 2f64.powi(-40)]));
    }
}
