//! Geometry on plain `[f64; 3]` points, the ground floor every other layer builds on: vector
//! arithmetic, face normals, the position order used to break ties, bounding boxes, exact 2D tests
//! on top of `robust`'s predicates ([`exact`]), polygon triangulation ([`polygon`]), the order
//! of points along space-filling curves (`curve`) and which boxes come near a few others (`near`).
//!
//! Points are `[f64; 3]` everywhere (readers, weld, table, repair, writers) so that nothing converts
//! on the hot paths; these functions take and return them by value (they are `Copy` and inline).

pub(crate) mod curve;
pub mod exact;
pub(crate) mod near;
pub mod polygon;

/// `a - b`.
#[inline]
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The cross product `a x b`.
#[inline]
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The dot product `a . b`.
#[inline]
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `|a|^2`.
#[inline]
pub fn norm2(a: [f64; 3]) -> f64 {
    dot(a, a)
}

/// `|a - b|^2`.
#[inline]
pub fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm2(sub(a, b))
}

/// A (not normalised) normal of triangle `a b c`: `(b - a) x (c - a)`, twice the triangle's area
/// long, pointing to the side from which `a b c` runs counterclockwise.
#[inline]
pub fn normal(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    cross(sub(b, a), sub(c, a))
}

/// Orders points by x, then y, then z (a total order: `-0.0 < 0.0`, NaN last). Used wherever a
/// choice must not depend on how vertices or faces are numbered.
pub fn by_position(p: &[f64; 3], q: &[f64; 3]) -> std::cmp::Ordering {
    p[0].total_cmp(&q[0])
        .then(p[1].total_cmp(&q[1]))
        .then(p[2].total_cmp(&q[2]))
}

/// The bounding box `[min, max]` of some points, `None` when there are none.
pub fn bounding_box<'a>(points: impl IntoIterator<Item = &'a [f64; 3]>) -> Option<[[f64; 3]; 2]> {
    let mut bbox: Option<[[f64; 3]; 2]> = None;
    for p in points {
        let b = bbox.get_or_insert([*p, *p]);
        for k in 0..3 {
            b[0][k] = b[0][k].min(p[k]);
            b[1][k] = b[1][k].max(p[k]);
        }
    }
    bbox
}

/// The power of two (in two factors, so that neither overflows) that brings `largest`, the
/// largest absolute coordinate of some points, near 1, when it is beyond 2^±100 (where products
/// of coordinates could overflow or underflow); `None` when it is in range, zero or not finite.
/// Multiplying by a power of two is exact (short of the subnormal range), so signs and ratios
/// computed on scaled points are the points' own.
pub(crate) fn unit_scale(largest: f64) -> Option<[f64; 2]> {
    if largest == 0.0
        || !largest.is_finite()
        || (2f64.powi(-100)..=2f64.powi(100)).contains(&largest)
    {
        return None;
    }
    let e = largest.log2().floor() as i32;
    Some([2f64.powi(-e / 2), 2f64.powi(-(e - e / 2))])
}

/// The largest finite absolute coordinate of `points` (0 when there is none).
pub(crate) fn largest_coordinate<'a>(points: impl IntoIterator<Item = &'a [f64; 3]>) -> f64 {
    points
        .into_iter()
        .flatten()
        .map(|x| x.abs())
        .filter(|x| x.is_finite())
        .fold(0.0, f64::max)
}

/// A tiny deterministic xorshift generator of 64-bit words for the unit tests: no dependency, no
/// flakiness.
#[cfg(test)]
pub(crate) fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The normal of the unit right triangle in z = 0, counterclockwise from +z, is (0, 0, 1): twice
    /// its area of 1/2, pointing up.
    #[test]
    fn normal_points_where_the_triangle_runs_counterclockwise() {
        let n = normal([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(n, [0.0, 0.0, 1.0]);
        assert_eq!(
            normal([0.0; 3], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]),
            [0.0, 0.0, -1.0]
        );
        assert_eq!(dist2([1.0, 2.0, 3.0], [1.0, 0.0, 0.0]), 13.0);
    }

    #[test]
    fn positions_order_by_x_then_y_then_z() {
        use std::cmp::Ordering::*;
        assert_eq!(by_position(&[0.0, 5.0, 5.0], &[1.0, 0.0, 0.0]), Less);
        assert_eq!(by_position(&[1.0, 0.0, 5.0], &[1.0, 1.0, 0.0]), Less);
        assert_eq!(by_position(&[1.0, 1.0, 1.0], &[1.0, 1.0, 0.0]), Greater);
        assert_eq!(
            bounding_box(&[[1.0, -2.0, 0.0], [-1.0, 3.0, 0.5]]),
            Some([[-1.0, -2.0, 0.0], [1.0, 3.0, 0.5]])
        );
        assert_eq!(bounding_box(&[]), None);
    }
}
