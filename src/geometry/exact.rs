//! Exact tests in the plane, on top of `robust`'s adaptive `orient2d` (exact for any finite
//! `f64` input, fast when the answer is clear): segments that touch, points in triangles, and the
//! projection that turns a question about a plane in space into one in a coordinate plane.
//!
//! Projecting by dropping one coordinate is exact (no arithmetic), so a 3D question about points
//! known to lie in one plane keeps its exact answer in 2D, provided the dropped axis is not parallel
//! to the plane: [`dominant_axes`] drops the axis along which the plane's normal is largest.

use robust::{orient2d, Coord, Coord3D};

/// `robust`'s 3D point.
#[inline]
pub fn p3(p: [f64; 3]) -> Coord3D<f64> {
    Coord3D {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}

/// The two coordinates kept when projecting points of the plane of `a b c` along the axis its
/// normal is largest on (for a flat triangle, `(0, 1)`: any projection then errs only towards
/// "touches").
pub fn dominant_axes(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> (usize, usize) {
    let n = super::normal(a, b, c);
    let drop = (0..3)
        .max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs()))
        .unwrap_or(2);
    match drop {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    }
}

/// Whether closed segments `p1 p2` and `p3 p4` share a point.
pub fn segments_touch(p1: Coord<f64>, p2: Coord<f64>, p3: Coord<f64>, p4: Coord<f64>) -> bool {
    let d1 = orient2d(p1, p2, p3);
    let d2 = orient2d(p1, p2, p4);
    let d3 = orient2d(p3, p4, p1);
    let d4 = orient2d(p3, p4, p2);
    if d1 == 0.0 && d2 == 0.0 {
        // Collinear: do their extents overlap?
        let overlap = |f: fn(&Coord<f64>) -> f64| {
            f(&p1).min(f(&p2)) <= f(&p3).max(f(&p4)) && f(&p3).min(f(&p4)) <= f(&p1).max(f(&p2))
        };
        return overlap(|p| p.x) && overlap(|p| p.y);
    }
    let apart = |x: f64, y: f64| (x > 0.0 && y > 0.0) || (x < 0.0 && y < 0.0);
    !apart(d1, d2) && !apart(d3, d4)
}

/// Whether `q` lies in the closed triangle `a b c` (either winding; a flat triangle holds the
/// points of its hull's lines that no edge test rules out).
pub fn in_triangle_2d(q: Coord<f64>, [a, b, c]: [Coord<f64>; 3]) -> bool {
    let d = [orient2d(a, b, q), orient2d(b, c, q), orient2d(c, a, q)];
    let has_neg = d.iter().any(|&x| x < 0.0);
    let has_pos = d.iter().any(|&x| x > 0.0);
    !(has_neg && has_pos)
}

/// Whether `q`, a point of the plane of `a b c`, lies in the closed triangle.
pub fn in_triangle_coplanar(q: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> bool {
    let (i, j) = dominant_axes(a, b, c);
    let p2 = |p: [f64; 3]| Coord { x: p[i], y: p[j] };
    in_triangle_2d(p2(q), [p2(a), p2(b), p2(c)])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(x: f64, y: f64) -> Coord<f64> {
        Coord { x, y }
    }

    /// Crossing, touching at an end, collinear overlapping, collinear apart, parallel apart.
    #[test]
    fn segments() {
        assert!(segments_touch(c(0., 0.), c(2., 2.), c(0., 2.), c(2., 0.)));
        assert!(segments_touch(c(0., 0.), c(1., 1.), c(1., 1.), c(2., 0.)));
        assert!(segments_touch(c(0., 0.), c(2., 0.), c(1., 0.), c(3., 0.)));
        assert!(!segments_touch(c(0., 0.), c(1., 0.), c(2., 0.), c(3., 0.)));
        assert!(!segments_touch(c(0., 0.), c(1., 0.), c(0., 1.), c(1., 1.)));
    }

    /// Inside, on an edge, on a vertex, outside; and the triangle x + y <= 1 of the plane z = x.
    #[test]
    fn points_in_triangles() {
        let t = [c(0., 0.), c(1., 0.), c(0., 1.)];
        assert!(in_triangle_2d(c(0.25, 0.25), t));
        assert!(in_triangle_2d(c(0.5, 0.0), t));
        assert!(in_triangle_2d(c(0.0, 1.0), t));
        assert!(!in_triangle_2d(c(0.6, 0.6), t));
        let (a, b, cc) = ([0., 0., 0.], [1., 0., 1.], [0., 1., 0.]);
        // Normal (-1, 0, 1): x and z tie, the later axis (z) is dropped.
        assert_eq!(dominant_axes(a, b, cc), (0, 1));
        assert!(in_triangle_coplanar([0.25, 0.25, 0.25], a, b, cc));
        assert!(!in_triangle_coplanar([0.75, 0.75, 0.75], a, b, cc));
    }
}
