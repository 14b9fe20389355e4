//! Polygon -> triangles, shared by the OBJ, STL, PLY and OFF readers and the hole fill
//! ([definitions](crate::definitions#faces): a fan for convex polygons, ear clipping for concave ones).
//!
//! The polygon is projected onto the coordinate plane most parallel to its best-fit plane (the one
//! whose axis is the largest component of the Newell normal). Dropping a coordinate is exact, so the
//! 2D orientation tests run on the stored numbers with `robust::orient2d`. An n-gon always gives
//! exactly n - 2 triangles: when the polygon is degenerate (collinear, zero area, NaN coordinates) or
//! ear clipping finds no ear (self-intersection), the remaining vertices are split as a fan, which
//! always terminates. Nothing here panics: indices are checked by the caller, and are checked again
//! here (an index out of range counts as a degenerate polygon).

use robust::{orient2d, Coord};

/// How a polygon was split; readers count the non-trivial cases into `Mesh::notes`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Split {
    /// Fewer than 3 vertices: nothing was emitted.
    TooFew,
    /// Already a triangle.
    Triangle,
    /// Convex polygon: a fan from its first vertex.
    Fan,
    /// Concave polygon: split by ear clipping.
    EarClipped,
    /// Degenerate (zero area, non-finite coordinates) or self-intersecting: split (at least
    /// partly) as a fan because no proper triangulation exists.
    Fallback,
    /// Concave but with more than [`MAX_EAR_CLIP_VERTICES`] vertices: split as a fan, unchecked.
    Large,
}

/// Above this many vertices a concave polygon is split by a fan: ear clipping costs O(n^2) (about
/// 4n^2 point tests on a hostile polygon, a few milliseconds at this size) and such polygons (cap
/// faces of scanned data) are rare. The split must stay a pure function of the polygon: the
/// repaired-copy writers split polygons again and expect the same triangles.
pub(crate) const MAX_EAR_CLIP_VERTICES: usize = 1024;

/// Appends the triangles of polygon `poly` (indices into `positions`) to `out`: `poly.len() - 2`
/// triangles, or none when the polygon has fewer than 3 vertices.
pub(crate) fn triangulate(poly: &[u32], positions: &[[f64; 3]], out: &mut Vec<[u32; 3]>) -> Split {
    let n = poly.len();
    match n {
        0..=2 => return Split::TooFew,
        3 => {
            out.push([poly[0], poly[1], poly[2]]);
            return Split::Triangle;
        }
        _ => {}
    }
    let Some(points) = project(poly, positions) else {
        fan(poly, out);
        return Split::Fallback;
    };
    if is_convex(&points) {
        fan(poly, out);
        return Split::Fan;
    }
    if n > MAX_EAR_CLIP_VERTICES {
        fan(poly, out);
        return Split::Large;
    }
    if ear_clip(poly, &points, out) {
        Split::EarClipped
    } else {
        Split::Fallback
    }
}

fn fan(poly: &[u32], out: &mut Vec<[u32; 3]>) {
    for i in 1..poly.len() - 1 {
        out.push([poly[0], poly[i], poly[i + 1]]);
    }
}

/// The polygon in 2D, oriented counter-clockwise (positive area), or `None` when it has a
/// non-finite coordinate, an index out of range or no usable plane (zero Newell normal).
pub(crate) fn project(poly: &[u32], positions: &[[f64; 3]]) -> Option<Vec<Coord<f64>>> {
    let mut pts = Vec::with_capacity(poly.len());
    for &i in poly {
        let p = *positions.get(i as usize)?;
        if !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        pts.push(p);
    }
    let normal = newell(&pts);
    let abs = normal.map(f64::abs);
    if !abs.iter().all(|c| c.is_finite()) || abs.iter().all(|&c| c == 0.0) {
        return None;
    }
    // Drop the dominant axis; keep (u, v) so that the projected polygon is counter-clockwise.
    let axis = if abs[0] >= abs[1] && abs[0] >= abs[2] {
        0
    } else if abs[1] >= abs[2] {
        1
    } else {
        2
    };
    let (u, v) = match axis {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    };
    let flip = normal[axis] < 0.0;
    Some(
        pts.iter()
            .map(|p| {
                if flip {
                    Coord { x: p[v], y: p[u] }
                } else {
                    Coord { x: p[u], y: p[v] }
                }
            })
            .collect(),
    )
}

/// The Newell normal of a closed polygon: twice its vector area, so also a best-fit plane normal
/// for a polygon that is not planar.
pub(crate) fn newell(points: &[[f64; 3]]) -> [f64; 3] {
    let mut normal = [0.0f64; 3];
    for (k, a) in points.iter().enumerate() {
        let b = points[(k + 1) % points.len()];
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    normal
}

/// True for a convex, counter-clockwise, simple polygon with no collinear corner: every turn is
/// strictly left and the x and y directions each change sign at most twice (which rules out star
/// polygons whose turns are all left). Collinear corners go to ear clipping, which avoids fans of
/// zero-area triangles.
fn is_convex(pts: &[Coord<f64>]) -> bool {
    let n = pts.len();
    let mut x_changes = 0;
    let mut y_changes = 0;
    let mut last_dx = 0.0f64;
    let mut last_dy = 0.0f64;
    for k in 0..n {
        let a = pts[k];
        let b = pts[(k + 1) % n];
        let c = pts[(k + 2) % n];
        if orient2d(a, b, c) <= 0.0 {
            return false;
        }
        let dx = b.x - a.x;
        let dy = b.y - a.y;
        if dx != 0.0 {
            if last_dx != 0.0 && (dx > 0.0) != (last_dx > 0.0) {
                x_changes += 1;
            }
            last_dx = dx;
        }
        if dy != 0.0 {
            if last_dy != 0.0 && (dy > 0.0) != (last_dy > 0.0) {
                y_changes += 1;
            }
            last_dy = dy;
        }
    }
    // The loop does not compare the last direction with the first; a closed convex polygon has
    // exactly two changes per axis counted cyclically, so at most two here.
    x_changes <= 2 && y_changes <= 2
}

/// Ear clipping on the projected, counter-clockwise polygon. Returns false when it had to clip a
/// vertex that is not a proper ear (self-intersecting or degenerate input); it still emits exactly
/// n - 2 triangles.
///
/// Worst case O(n^2) whatever the input: a hostile polygon (an outward spiral whose every corner
/// hides the earlier ones) must not cost O(n^3). Each corner remembers that it is not an ear, and
/// only the two neighbours of a clip forget it (in a simple polygon no other corner's status can
/// change). So `is_ear` (O(n)) runs at most 4n times: once per clip, once per corner found not to be
/// an ear, once again per neighbour of a clip. Walking the ring to the next candidate is O(n) per
/// clip. A lap with no candidate (stale memory on a polygon that crosses or touches itself) forgets
/// everything at most twice per polygon, then clips the most convex-looking corner, found in O(n).
fn ear_clip(poly: &[u32], pts: &[Coord<f64>], out: &mut Vec<[u32; 3]>) -> bool {
    let n = pts.len();
    // Doubly linked ring of the remaining vertices.
    let mut next: Vec<usize> = (0..n).map(|i| (i + 1) % n).collect();
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    // Corners known not to be ears (as of the last time they were tested).
    let mut not_ear = vec![false; n];
    let mut remaining = n;
    let mut cur = 0;
    let mut clean = true;
    let mut forgets = 2;
    while remaining > 3 {
        // The first corner from `cur` that is an ear; at most one lap.
        let mut found = None;
        let mut c = cur;
        for _ in 0..remaining {
            if !not_ear[c] {
                if is_ear(prev[c], c, next[c], pts, &next) {
                    found = Some(c);
                    break;
                }
                not_ear[c] = true;
            }
            c = next[c];
        }
        if found.is_none() && forgets > 0 {
            forgets -= 1;
            not_ear.iter_mut().for_each(|e| *e = false);
            continue;
        }
        let clip = found.unwrap_or_else(|| {
            // No proper ear: clip the most convex-looking corner (one vertex goes, so this ends).
            clean = false;
            let mut best = c;
            let mut best_turn = f64::NEG_INFINITY;
            for _ in 0..remaining {
                let t = orient2d(pts[prev[c]], pts[c], pts[next[c]]);
                if t > best_turn {
                    best_turn = t;
                    best = c;
                }
                c = next[c];
            }
            best
        });
        let (p, q) = (prev[clip], next[clip]);
        out.push([poly[p], poly[clip], poly[q]]);
        next[p] = q;
        prev[q] = p;
        remaining -= 1;
        not_ear[p] = false;
        not_ear[q] = false;
        cur = q;
    }
    let p = prev[cur];
    let q = next[cur];
    out.push([poly[p], poly[cur], poly[q]]);
    clean
}

/// Corner `b` (between `a` and `c`) is an ear when it turns strictly left and no other remaining
/// vertex lies inside or on the triangle (vertices at the same position as a corner are ignored:
/// polygons that touch themselves at a vertex are common and clipping there is fine).
fn is_ear(a: usize, b: usize, c: usize, pts: &[Coord<f64>], next: &[usize]) -> bool {
    #[cfg(test)]
    tests::EAR_TESTS.with(|t| t.set(t.get() + 1));
    let (pa, pb, pc) = (pts[a], pts[b], pts[c]);
    if orient2d(pa, pb, pc) <= 0.0 {
        return false;
    }
    let same = |p: Coord<f64>, q: Coord<f64>| p.x == q.x && p.y == q.y;
    let mut k = next[c];
    while k != a {
        let p = pts[k];
        if !(same(p, pa) || same(p, pb) || same(p, pc))
            && orient2d(pa, pb, p) >= 0.0
            && orient2d(pb, pc, p) >= 0.0
            && orient2d(pc, pa, p) >= 0.0
        {
            return false;
        }
        k = next[k];
    }
    true
}

/// Tally of the polygons a reader split, turned into `Mesh::notes` at the end of the file.
#[derive(Debug, Default)]
pub(crate) struct SplitTally {
    ear_clipped: u64,
    fallback: u64,
    too_few: u64,
    large: u64,
    /// 1-based line (or face number, see `unit`) of the first polygon in each class.
    first_ear_clipped: u64,
    first_fallback: u64,
    first_too_few: u64,
    first_large: u64,
}

impl SplitTally {
    /// Records how the polygon found at `at` (a line or face number) was split.
    pub(crate) fn add(&mut self, split: Split, at: u64) {
        let (count, first) = match split {
            Split::Triangle | Split::Fan => return,
            Split::EarClipped => (&mut self.ear_clipped, &mut self.first_ear_clipped),
            Split::Fallback => (&mut self.fallback, &mut self.first_fallback),
            Split::TooFew => (&mut self.too_few, &mut self.first_too_few),
            Split::Large => (&mut self.large, &mut self.first_large),
        };
        if *count == 0 {
            *first = at;
        }
        *count += 1;
    }

    /// Notes for the user; `unit` is "line" or "face", the meaning of the numbers given to `add`.
    pub(crate) fn notes(&self, unit: &str, notes: &mut Vec<String>) {
        if self.ear_clipped > 0 {
            notes.push(format!(
                "{} concave polygon(s) split into triangles by ear clipping (first at {unit} {})",
                self.ear_clipped, self.first_ear_clipped
            ));
        }
        if self.fallback > 0 {
            notes.push(format!(
                "{} degenerate or self-intersecting polygon(s) (zero area, collinear, NaN or crossing \
                 edges) split as a fan (first at {unit} {}); check them in a modelling tool",
                self.fallback, self.first_fallback
            ));
        }
        if self.large > 0 {
            notes.push(format!(
                "{} concave polygon(s) with more than {MAX_EAR_CLIP_VERTICES} vertices split as a fan \
                 (first at {unit} {}): some of their triangles may overlap or face the wrong way; \
                 split them into smaller polygons in a modelling tool",
                self.large, self.first_large
            ));
        }
        if self.too_few > 0 {
            notes.push(format!(
                "{} face(s) with fewer than 3 vertices skipped (first at {unit} {})",
                self.too_few, self.first_too_few
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    thread_local! {
        /// Calls of `is_ear` on this thread, to check the cost of a split without timing it.
        pub(super) static EAR_TESTS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    }

    fn split(poly: &[u32], positions: &[[f64; 3]]) -> (Vec<[u32; 3]>, Split) {
        let mut out = Vec::new();
        let s = triangulate(poly, positions, &mut out);
        (out, s)
    }

    /// Signed area of a triangle of points in the z = 0 plane.
    fn area(t: [u32; 3], p: &[[f64; 3]]) -> f64 {
        let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
        0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    }

    #[test]
    fn triangle_and_too_few() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(split(&[0, 1, 2], &p), (vec![[0, 1, 2]], Split::Triangle));
        assert_eq!(split(&[0, 1], &p), (vec![], Split::TooFew));
        assert_eq!(split(&[], &p), (vec![], Split::TooFew));
    }

    #[test]
    fn convex_quad_is_a_fan() {
        #[rustfmt::skip]
        let p = [
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0],
        ];
        assert_eq!(
            split(&[0, 1, 2, 3], &p),
            (vec![[0, 1, 2], [0, 2, 3]], Split::Fan)
        );
    }

    #[test]
    fn clockwise_quad_keeps_its_winding() {
        // Same square listed clockwise: the fan keeps the stored order (winding is the file's).
        #[rustfmt::skip]
        let p = [
            [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 0.0],
        ];
        let (t, s) = split(&[0, 1, 2, 3], &p);
        assert_eq!(s, Split::Fan);
        assert!(t.iter().all(|&t| area(t, &p) < 0.0));
    }

    /// L-shaped hexagon (the unit square [1,2]x[1,2] missing from [0,2]x[0,2]), listed from
    /// vertex 0 = (2,1) so that its neighbour 1 = (1,1) is the reflex corner:
    ///
    ///     3 +---+ 2
    ///       |   |
    ///       |   +---+ 0      a fan from 0 makes (0,1,2), which turns clockwise (outside the L)
    ///       |   1   |
    ///     4 +-------+ 5
    ///
    /// Area 3, so the four triangles must be counter-clockwise and add up to 3.
    #[test]
    fn l_shaped_hexagon_is_ear_clipped() {
        let p = [
            [2.0, 1.0, 0.0], // 0
            [1.0, 1.0, 0.0], // 1 reflex
            [1.0, 2.0, 0.0], // 2
            [0.0, 2.0, 0.0], // 3
            [0.0, 0.0, 0.0], // 4
            [2.0, 0.0, 0.0], // 5
        ];
        let (t, s) = split(&[0, 1, 2, 3, 4, 5], &p);
        assert_eq!(s, Split::EarClipped);
        assert_eq!(t.len(), 4);
        // Every triangle is counter-clockwise and the areas add up to the L's area, 3.
        assert!(t.iter().all(|&t| area(t, &p) > 0.0), "{t:?}");
        let total: f64 = t.iter().map(|&t| area(t, &p)).sum();
        assert!((total - 3.0).abs() < 1e-12, "{total}");
        // The fan would have produced a clockwise (inverted) triangle.
        let mut fan_out = Vec::new();
        fan(&[0, 1, 2, 3, 4, 5], &mut fan_out);
        assert!(fan_out.iter().any(|&t| area(t, &p) <= 0.0));
    }

    #[test]
    fn concave_polygon_in_a_tilted_plane() {
        // The L above in the plane x = z (normal along (1,0,-1)), listed clockwise seen from +z.
        let l: [[f64; 2]; 6] = [[2., 1.], [1., 1.], [1., 2.], [0., 2.], [0., 0.], [2., 0.]];
        let p: Vec<[f64; 3]> = l.iter().rev().map(|q| [q[0], q[1], q[0]]).collect();
        let (t, s) = split(&[0, 1, 2, 3, 4, 5], &p);
        assert_eq!(s, Split::EarClipped);
        assert_eq!(t.len(), 4);
        // Projected to xy every triangle keeps the polygon's (clockwise) winding; total area 3.
        let total: f64 = t.iter().map(|&t| area(t, &p)).sum();
        assert!(t.iter().all(|&t| area(t, &p) < 0.0));
        assert!((total + 3.0).abs() < 1e-12, "{total}");
    }

    #[test]
    fn degenerate_inputs_fall_back_to_a_fan() {
        #[rustfmt::skip]
        let collinear = [
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0],
        ];
        assert_eq!(split(&[0, 1, 2, 3], &collinear).1, Split::Fallback);
        let same = [[1.0, 1.0, 1.0]; 5];
        let (t, s) = split(&[0, 1, 2, 3, 4], &same);
        assert_eq!((t.len(), s), (3, Split::Fallback));
        let nan = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [f64::NAN, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        assert_eq!(split(&[0, 1, 2, 3], &nan).0.len(), 2);
        let inf = [
            [0.0, 0.0, 0.0],
            [f64::INFINITY, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        assert_eq!(split(&[0, 1, 2, 3], &inf).0.len(), 2);
        // An index out of range (callers check, but this must not panic either).
        assert_eq!(split(&[0, 1, 2, 99], &collinear).0.len(), 2);
        // Repeated indices.
        assert_eq!(split(&[0, 1, 1, 2, 2, 0], &nan[..2].repeat(2)).0.len(), 4);
    }

    #[test]
    fn self_intersecting_polygons_give_n_minus_2_triangles() {
        // Bowtie quad and a pentagram (all turns left, winding twice).
        #[rustfmt::skip]
        let bowtie = [
            [0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
        ];
        assert_eq!(split(&[0, 1, 2, 3], &bowtie).0.len(), 2);
        let star: Vec<[f64; 3]> = (0..5)
            .map(|k| {
                let a = (k * 2) as f64 * std::f64::consts::TAU / 5.0;
                [a.cos(), a.sin(), 0.0]
            })
            .collect();
        let (t, s) = split(&[0, 1, 2, 3, 4], &star);
        assert_eq!(t.len(), 3);
        assert_ne!(s, Split::Fan, "a pentagram is not convex");
    }

    #[test]
    fn collinear_corners_avoid_zero_area_triangles() {
        // Square with midpoints on two edges: a fan from vertex 0 would make zero-area triangles.
        #[rustfmt::skip]
        let p = [
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let (t, _) = split(&[0, 1, 2, 3, 4, 5], &p);
        assert_eq!(t.len(), 4);
        assert!(t.iter().all(|&t| area(t, &p) > 0.0), "{t:?}");
    }

    /// An outward spiral turning a little more than 120 degrees per corner: every corner's
    /// triangle holds all the earlier (smaller) vertices, found only at the end of each test, and
    /// no corner is a proper ear. Lap-by-lap ear clipping with a per-lap fallback took O(n^3)
    /// (over 5 s for 2000 vertices in release, minutes in debug); now O(n^2).
    fn spiral(n: usize) -> Vec<[f64; 3]> {
        (0..n)
            .map(|i| {
                let (a, r) = (i as f64 * 2.1, 1.004f64.powi(i as i32));
                [r * a.cos(), r * a.sin(), 0.0]
            })
            .collect()
    }

    #[test]
    fn hostile_spiral_is_split_in_quadratic_time() {
        let n = MAX_EAR_CLIP_VERTICES;
        let p = spiral(n);
        let poly: Vec<u32> = (0..n as u32).collect();
        EAR_TESTS.with(|t| t.set(0));
        let (t, s) = split(&poly, &p);
        assert_eq!(t.len(), n - 2);
        assert_eq!(s, Split::Fallback);
        // At most 4n ear tests of O(n) each, plus two rounds of forgetting (the old clipper made
        // about 390n on this polygon).
        let tests = EAR_TESTS.with(|t| t.get());
        assert!(tests <= 6 * n as u64, "{tests} ear tests for {n} vertices");
        // One more vertex: a fan, with its own note.
        let p = spiral(n + 1);
        let poly: Vec<u32> = (0..=n as u32).collect();
        EAR_TESTS.with(|t| t.set(0));
        let (t, s) = split(&poly, &p);
        assert_eq!((t.len(), s), (n - 1, Split::Large));
        assert_eq!(EAR_TESTS.with(|t| t.get()), 0);
        let mut tally = SplitTally::default();
        tally.add(s, 7);
        let mut notes = Vec::new();
        tally.notes("line", &mut notes);
        assert!(notes[0].contains("more than 1024 vertices") && notes[0].contains("line 7"));
    }

    #[test]
    fn many_random_polygons_terminate_with_n_minus_2() {
        let mut bits = super::super::xorshift(0x2545_f491_4f6c_dd1d);
        let mut rnd = || (bits() % 7) as f64 - 3.0;
        for n in 3..40 {
            for _ in 0..20 {
                let p: Vec<[f64; 3]> = (0..n).map(|_| [rnd(), rnd(), rnd() * 0.0]).collect();
                let poly: Vec<u32> = (0..n as u32).collect();
                assert_eq!(split(&poly, &p).0.len(), n - 2);
            }
        }
    }
}
