//! A small SVG drawing of a mesh for the HTML report, made while the mesh is in memory: two fixed
//! orthographic views (from the front-right-above and from the back-left-below, Y up), faces
//! depth-sorted back to front (painter's algorithm) and flat-shaded by their normal, with the
//! problem places of [`Places`] drawn on top.
//!
//! Colours: faces seen from their front are blue-grey, faces seen from behind (through a hole, or
//! flipped) plain grey, faces of inside-out shells violet, faces that meet another face (they cross
//! or touch where the mesh does not join them) gold; border edges orange; non-manifold edges
//! and vertices red; inconsistently wound edges (a face flipped against its neighbour) dashed teal.
//! A shell that holds a deeper shell (by the analysis's nesting: a solid around its cavity, a
//! housing around an inner part) is drawn translucent, so what is inside shows.
//!
//! Every face is written with its corners clockwise on screen. Faces of one shade share one
//! `<path>`, filled by the nonzero rule: with every outline turning the same way, the winding
//! number inside any face is at least one, so no face cancels another where they overlap (a
//! back face under a front face of an inside-out shell would otherwise leave a hole).
//!
//! Size: a picture must stay small because a report holds thousands. A mesh of more than
//! [`MAX_FACES`] faces is simplified by vertex clustering (a grid coarse enough to leave at most that
//! many faces); coordinates are integers on a 240-unit square per view; consecutive faces of one
//! shade share one `<path>`; shades are quantized to eight levels; marks are one path per colour and
//! view, at most [`MAX_MARKS`] segments each (evenly sampled beyond). Attributes use single quotes (the
//! SVG fits in a JSON string unescaped); the styles shared by every picture are in [`STYLE`], which
//! the page that shows pictures includes once. A cube draws in ~1 KB, a mesh simplified to
//! [`MAX_FACES`] in ~70-150 KB. No `xmlns`: the page's HTML parser puts inline `<svg>` in the SVG
//! namespace.

use std::fmt::Write;

use rustc_hash::{FxHashMap, FxHashSet};

use crate::geometry::{largest_coordinate, unit_scale};
use crate::topology::{Places, NO_SHELL};

/// The most faces drawn; bigger meshes are simplified.
pub const MAX_FACES: usize = 1500;

/// The most segments (or dots) drawn per mark colour and view.
pub const MAX_MARKS: usize = 1500;

/// The side of one view in SVG units, and the gap between the two.
const SIDE: f64 = 240.0;
const GAP: f64 = 10.0;
const MARGIN: f64 = 10.0;
/// Shade levels per face colour.
const LEVELS: usize = 8;
/// Face colours (front, behind, inside-out, meeting another face) times shade levels: keys at or
/// above this are the same colours drawn translucent.
const OPAQUE_KEYS: u16 = 4 * LEVELS as u16;
/// The most parts tried as holders of another part (the ones with the biggest boxes).
const MAX_HOLDERS: usize = 16;

/// Per-face look flags: the face belongs to an inside-out shell; the face is drawn translucent.
const INSIDE_OUT: u8 = 1;
const SEE_THROUGH: u8 = 2;
/// The face meets another (crosses or touches it where the mesh does not join them).
const MEETS: u8 = 4;

/// The style the drawing needs from the page that shows it: faces take their `color` as fill and
/// stroke (stroked in their own colour so no seam shows between neighbours), class `g` for the
/// translucent ones; marks are classes `b` (border edges), `i` (inconsistently wound edges, with a
/// halo `w` at each one's middle), `n` (non-manifold edges) and `v` (non-manifold vertices, drawn
/// as round dots). Kept out of each picture to save ~300 bytes a mesh.
pub const STYLE: &str =
    ".pic path{fill:currentColor;stroke:currentColor;stroke-width:.6;stroke-linejoin:round}\
.pic .g{opacity:.3}\
.pic .b,.pic .i,.pic .w,.pic .n,.pic .v{fill:none;stroke-linecap:round}\
.pic .b{stroke:#e80;stroke-width:2}.pic .i{stroke:#087;stroke-width:2.5;stroke-dasharray:5 3}\
.pic .w{stroke:#087;stroke-width:11;opacity:.4}\
.pic .n{stroke:#d11;stroke-width:2.5}.pic .v{stroke:#d11;stroke-width:7}";

/// The views: (azimuth, elevation) in degrees, Y up.
const VIEWS: [(f64, f64); 2] = [(35.0, 25.0), (215.0, -25.0)];

/// Draws `places` (from [`crate::topology::places`]); `None` when there is no face to draw.
pub fn draw(places: &Places) -> Option<String> {
    if places.triangles.is_empty() {
        return None;
    }
    // Far from 1 (past 2^±100), projections, normals and the fit overflow or underflow: draw
    // the places times a power of two, which changes nothing but the units.
    let rescaled;
    let places = match in_range(places) {
        Some(scaled) => {
            rescaled = scaled;
            &rescaled
        }
        None => places,
    };
    let looks = looks(places);
    let simplified;
    let (points, triangles, looks) = if places.triangles.len() > MAX_FACES {
        simplified = simplify(&places.points, &places.triangles, &looks);
        (&simplified.0[..], &simplified.1[..], &simplified.2[..])
    } else {
        (&places.points[..], &places.triangles[..], &looks[..])
    };
    let width = 2.0 * SIDE + GAP;
    let mut svg = format!(
        "<svg viewBox='0 0 {width} {SIDE}' class='pic' data-faces='{}' data-drawn='{}'>",
        places.triangles.len(),
        triangles.len()
    );
    for (i, &(azimuth, elevation)) in VIEWS.iter().enumerate() {
        let camera = Camera::new(azimuth, elevation);
        let offset = i as f64 * (SIDE + GAP);
        if offset > 0.0 {
            let _ = write!(svg, "<g transform='translate({offset})'>");
        } else {
            svg.push_str("<g>");
        }
        // Framed on the full mesh, which the marks sit on (a simplified mesh's cluster means lie
        // a little inside it).
        let screen = camera.fit(&places.points, &places.triangles);
        draw_faces(&mut svg, &camera, &screen, points, triangles, looks);
        draw_marks(&mut svg, &screen, places);
        svg.push_str("</g>");
    }
    svg.push_str("</svg>");
    Some(svg)
}

/// `places` with every point and shell box times the power of two that brings the largest
/// coordinate near 1 ([`unit_scale`]); `None` when they are in range as they are.
fn in_range(places: &Places) -> Option<Places> {
    let [s1, s2] = unit_scale(largest_coordinate(&places.points))?;
    let scale = |p: [f64; 3]| p.map(|x| x * s1 * s2);
    let mut scaled = places.clone();
    for p in &mut scaled.points {
        *p = scale(*p);
    }
    for (_, [lo, hi]) in &mut scaled.shells {
        (*lo, *hi) = (scale(*lo), scale(*hi));
    }
    Some(scaled)
}

/// The look flags of every face of `places`.
fn looks(places: &Places) -> Vec<u8> {
    let see_through = see_through(places);
    (0..places.triangles.len())
        .map(|i| {
            let inside_out = places.inside_out.get(i).copied().unwrap_or(false);
            let meets = places.meets.get(i).copied().unwrap_or(false);
            u8::from(inside_out) * INSIDE_OUT
                + u8::from(see_through[i]) * SEE_THROUGH
                + u8::from(meets) * MEETS
        })
        .collect()
}

/// Per face: it belongs to a shell that holds a deeper shell inside its box (a solid around its
/// cavity, a housing around an inner part), by the analysis's nesting. Only the [`MAX_HOLDERS`]
/// shells with the biggest boxes are tried.
fn see_through(places: &Places) -> Vec<bool> {
    let shells = &places.shells;
    let mut holds = vec![false; shells.len()];
    if shells.iter().any(|&(depth, _)| depth > 0) {
        let size = |b: &[[f64; 3]; 2]| (0..3).map(|k| b[1][k] - b[0][k]).product::<f64>();
        let inside = |a: &[[f64; 3]; 2], b: &[[f64; 3]; 2]| {
            (0..3).all(|k| b[0][k] < a[0][k] && a[1][k] < b[1][k])
        };
        let mut holders: Vec<usize> = (0..shells.len()).collect();
        holders.sort_by(|&a, &b| size(&shells[b].1).total_cmp(&size(&shells[a].1)));
        holders.truncate(MAX_HOLDERS);
        for h in holders {
            let (depth, bbox) = &shells[h];
            holds[h] = shells.iter().any(|(d, b)| d > depth && inside(b, bbox));
        }
    }
    places
        .shell
        .iter()
        .map(|&s| s != NO_SHELL && holds[s as usize])
        .collect()
}

/// An orthographic camera: screen axes `right`, `up`, and `toward` the viewer.
struct Camera {
    right: [f64; 3],
    up: [f64; 3],
    toward: [f64; 3],
    light: [f64; 3],
}

/// How a view maps world points to its integer screen square.
struct Screen<'a> {
    camera: &'a Camera,
    centre: [f64; 2],
    scale: f64,
}

impl Screen<'_> {
    fn at(&self, p: &[f64; 3]) -> (i32, i32) {
        let x = dot(p, &self.camera.right) - self.centre[0];
        let y = dot(p, &self.camera.up) - self.centre[1];
        (
            (SIDE / 2.0 + x * self.scale).round() as i32,
            (SIDE / 2.0 - y * self.scale).round() as i32,
        )
    }
}

impl Camera {
    fn new(azimuth: f64, elevation: f64) -> Camera {
        let (a, e) = (azimuth.to_radians(), elevation.to_radians());
        let toward = [e.cos() * a.sin(), e.sin(), e.cos() * a.cos()];
        let right = normalized(cross(&[0.0, 1.0, 0.0], &toward));
        let up = cross(&toward, &right);
        // Light from the upper left, behind the viewer.
        let light = normalized(add3(&[
            scale3(&right, -0.35),
            scale3(&up, 0.55),
            scale3(&toward, 0.75),
        ]));
        Camera {
            right,
            up,
            toward,
            light,
        }
    }

    /// The screen that fits the drawn vertices into the view with a margin.
    fn fit<'a>(&'a self, points: &[[f64; 3]], triangles: &[[u32; 3]]) -> Screen<'a> {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for t in triangles {
            for &i in t {
                let p = &points[i as usize];
                let s = [dot(p, &self.right), dot(p, &self.up)];
                for k in 0..2 {
                    lo[k] = lo[k].min(s[k]);
                    hi[k] = hi[k].max(s[k]);
                }
            }
        }
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let scale = if extent > 0.0 && extent.is_finite() {
            (SIDE - 2.0 * MARGIN) / extent
        } else {
            1.0
        };
        Screen {
            camera: self,
            centre: [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])],
            scale,
        }
    }
}

/// Faces back to front, consecutive faces of one colour merged into one path, every face's corners
/// clockwise on screen.
fn draw_faces(
    svg: &mut String,
    camera: &Camera,
    screen: &Screen,
    points: &[[f64; 3]],
    triangles: &[[u32; 3]],
    looks: &[u8],
) {
    // (depth, screen corners, colour) of every face that covers some of the screen.
    type Face = (f64, [(i32, i32); 3], u16);
    let mut faces: Vec<Face> = Vec::with_capacity(triangles.len());
    for (i, t) in triangles.iter().enumerate() {
        let [a, b, c] = t.map(|v| &points[v as usize]);
        let n = normalized(cross(&sub(b, a), &sub(c, a)));
        let facing = dot(&n, &camera.toward);
        let seen = if facing >= 0.0 { n } else { scale3(&n, -1.0) };
        // Lambert with an ambient term, so faces turned from the light stay readable.
        let light = 0.3 + 0.7 * dot(&seen, &camera.light).max(0.0);
        let level = (light * (LEVELS - 1) as f64).round() as u16;
        let look = looks.get(i).copied().unwrap_or(0);
        let kind = if look & MEETS != 0 {
            3
        } else if look & INSIDE_OUT != 0 {
            2
        } else if facing >= 0.0 {
            0
        } else {
            1
        };
        let depth = dot(a, &camera.toward) + dot(b, &camera.toward) + dot(c, &camera.toward);
        let mut corners = [screen.at(a), screen.at(b), screen.at(c)];
        let [(x0, y0), (x1, y1), (x2, y2)] = corners;
        // Twice the signed area with y down: positive is clockwise on screen.
        let turn = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0);
        if turn == 0 {
            continue; // edge-on or smaller than a unit: nothing to see
        }
        if turn < 0 {
            corners.swap(1, 2);
        }
        let see_through = u16::from(look & SEE_THROUGH != 0);
        let key = see_through * OPAQUE_KEYS + kind * LEVELS as u16 + level;
        faces.push((depth, corners, key));
    }
    faces.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut current = u16::MAX;
    for (_, corners, colour) in &faces {
        if *colour != current {
            if current != u16::MAX {
                svg.push_str("'/>");
            }
            let class = if *colour >= OPAQUE_KEYS {
                " class='g'"
            } else {
                ""
            };
            let _ = write!(
                svg,
                "<path{class} color='{}' d='",
                face_colour(*colour % OPAQUE_KEYS)
            );
            current = *colour;
        }
        let [(x0, y0), (x1, y1), (x2, y2)] = corners;
        let _ = write!(svg, "M{x0} {y0} {x1} {y1} {x2} {y2}z");
    }
    if current != u16::MAX {
        svg.push_str("'/>");
    }
}

/// `#rgb` of a face colour: kind (front, back, inside-out, meeting another face) and shade level.
fn face_colour(colour: u16) -> String {
    const BASE: [[f64; 3]; 4] = [
        [0.62, 0.74, 0.9],
        [0.66, 0.66, 0.62],
        [0.88, 0.5, 0.86],
        [0.95, 0.78, 0.1],
    ];
    let base = BASE[colour as usize / LEVELS];
    let level = (colour as usize % LEVELS) as f64 / (LEVELS - 1) as f64;
    let brightness = 0.45 + 0.6 * level;
    let digit = |x: f64| {
        let d = (x * brightness * 15.0).round().clamp(0.0, 15.0) as u32;
        char::from_digit(d, 16).expect("a hex digit")
    };
    format!("#{}{}{}", digit(base[0]), digit(base[1]), digit(base[2]))
}

/// Border edges, inconsistently wound edges, non-manifold edges and non-manifold vertices over
/// the faces.
fn draw_marks(svg: &mut String, screen: &Screen, places: &Places) {
    let points = &places.points;
    let edges = |svg: &mut String, edges: &[[u32; 2]], class: &str| {
        if edges.is_empty() {
            return;
        }
        let _ = write!(svg, "<path class='{class}' d='");
        for e in sampled(edges, MAX_MARKS) {
            let (x0, y0) = screen.at(&points[e[0] as usize]);
            let (x1, y1) = screen.at(&points[e[1] as usize]);
            let _ = write!(svg, "M{x0} {y0} {x1} {y1}");
        }
        svg.push_str("'/>");
    };
    edges(svg, &places.border_edges, "b");
    edges(svg, &places.inconsistent_edges, "i");
    if !places.inconsistent_edges.is_empty() {
        // A halo at each one's middle: flipped faces are often tiny, and so are their edges.
        svg.push_str("<path class='w' d='");
        for e in sampled(&places.inconsistent_edges, MAX_MARKS) {
            let (x0, y0) = screen.at(&points[e[0] as usize]);
            let (x1, y1) = screen.at(&points[e[1] as usize]);
            let _ = write!(svg, "M{} {}h0", (x0 + x1) / 2, (y0 + y1) / 2);
        }
        svg.push_str("'/>");
    }
    edges(svg, &places.nonmanifold_edges, "n");
    if !places.nonmanifold_vertices.is_empty() {
        svg.push_str("<path class='v' d='");
        for &v in sampled(&places.nonmanifold_vertices, MAX_MARKS) {
            let (x, y) = screen.at(&points[v as usize]);
            let _ = write!(svg, "M{x} {y}h0");
        }
        svg.push_str("'/>");
    }
}

/// At most `max` items, evenly spread over `items`.
fn sampled<T>(items: &[T], max: usize) -> impl Iterator<Item = &T> {
    let step = items.len().div_ceil(max.max(1)).max(1);
    items.iter().step_by(step)
}

/// Vertex clustering: snaps the vertices to a grid coarse enough to leave at most [`MAX_FACES`]
/// faces, each cluster at the mean of its vertices; faces that collapse or repeat are dropped. Falls
/// back to an even sample of the faces if even a 2-cell grid leaves too many.
#[allow(clippy::type_complexity)]
fn simplify(
    points: &[[f64; 3]],
    triangles: &[[u32; 3]],
    looks: &[u8],
) -> (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<u8>) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for t in triangles {
        for &i in t {
            for k in 0..3 {
                lo[k] = lo[k].min(points[i as usize][k]);
                hi[k] = hi[k].max(points[i as usize][k]);
            }
        }
    }
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    let mut cells = 128.0_f64;
    for _ in 0..12 {
        let result = cluster(points, triangles, looks, lo, extent / cells);
        if result.1.len() <= MAX_FACES {
            return result;
        }
        if cells <= 2.0 {
            break;
        }
        let shrink = (MAX_FACES as f64 / result.1.len() as f64).sqrt() * 0.9;
        cells = (cells * shrink).floor().clamp(2.0, cells - 1.0);
    }
    let step = triangles.len().div_ceil(MAX_FACES);
    let faces = triangles.iter().step_by(step).copied().collect();
    let flags = looks.iter().step_by(step).copied().collect();
    (points.to_vec(), faces, flags)
}

#[allow(clippy::type_complexity)]
fn cluster(
    points: &[[f64; 3]],
    triangles: &[[u32; 3]],
    looks: &[u8],
    lo: [f64; 3],
    cell: f64,
) -> (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<u8>) {
    let cell = if cell > 0.0 && cell.is_finite() {
        cell
    } else {
        1.0
    };
    let mut id_of_cell: FxHashMap<u64, u32> = FxHashMap::default();
    let mut id_of_point = vec![u32::MAX; points.len()];
    let mut sums: Vec<([f64; 3], u32)> = Vec::new();
    let mut id = |v: u32| -> u32 {
        let slot = &mut id_of_point[v as usize];
        if *slot == u32::MAX {
            let p = &points[v as usize];
            let key = (0..3).fold(0u64, |key, k| {
                let i = ((p[k] - lo[k]) / cell).floor().clamp(0.0, 2_097_151.0) as u64;
                key << 21 | i
            });
            let next = sums.len() as u32;
            let id = *id_of_cell.entry(key).or_insert(next);
            if id == next {
                sums.push(([0.0; 3], 0));
            }
            let sum = &mut sums[id as usize];
            for (total, x) in sum.0.iter_mut().zip(p) {
                *total += x;
            }
            sum.1 += 1;
            *slot = id;
        }
        *slot
    };
    let mut seen: FxHashSet<[u32; 3]> = FxHashSet::default();
    let mut faces = Vec::new();
    let mut flags = Vec::new();
    for (i, t) in triangles.iter().enumerate() {
        let w = t.map(&mut id);
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            continue;
        }
        let mut key = w;
        key.sort_unstable();
        if seen.insert(key) {
            faces.push(w);
            flags.push(looks.get(i).copied().unwrap_or(0));
        }
    }
    let positions = sums
        .iter()
        .map(|(s, n)| s.map(|x| x / f64::from(*n)))
        .collect();
    (positions, faces, flags)
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn scale3(a: &[f64; 3], s: f64) -> [f64; 3] {
    a.map(|x| x * s)
}

fn add3(vs: &[[f64; 3]]) -> [f64; 3] {
    vs.iter()
        .fold([0.0; 3], |s, v| [s[0] + v[0], s[1] + v[1], s[2] + v[2]])
}

fn normalized(a: [f64; 3]) -> [f64; 3] {
    let n = dot(&a, &a).sqrt();
    if n > 0.0 {
        a.map(|x| x / n)
    } else {
        [0.0, 0.0, 1.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::{analyse, analyse_keeping, places, Options};
    use crate::Mesh;

    fn picture(mesh: &Mesh) -> Option<String> {
        let (analysis, built) = analyse_keeping(mesh, &Options::default());
        draw(&places(&built, &analysis))
    }

    /// A unit cube without its top: two triangles per side, five sides.
    fn open_box() -> Mesh {
        let positions = (0..8)
            .map(|i| [(i & 1) as f64, (i >> 1 & 1) as f64, (i >> 2 & 1) as f64])
            .collect();
        let triangles = vec![
            [0, 2, 1],
            [1, 2, 3], // z = 0
            [4, 5, 6],
            [5, 7, 6], // z = 1
            [0, 1, 4],
            [1, 5, 4], // y = 0
            [0, 4, 2],
            [2, 4, 6], // x = 0
            [1, 3, 5],
            [3, 7, 5], // x = 1
        ];
        Mesh::new(positions, triangles)
    }

    /// The closed cube `[lo, lo + side]^3`: the open box's ten faces and its top (y = lo + side,
    /// `2 6 3` and `3 6 7`, normal +y), all wound outward.
    fn cube(lo: f64, side: f64) -> Mesh {
        let mut mesh = open_box();
        mesh.triangles.extend([[2, 6, 3], [3, 6, 7]]);
        for p in &mut mesh.positions {
            *p = p.map(|x| lo + side * x);
        }
        mesh
    }

    fn flipped(mesh: Mesh) -> Mesh {
        let triangles = mesh.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect();
        Mesh::new(mesh.positions, triangles)
    }

    fn merged(parts: &[Mesh]) -> Mesh {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for part in parts {
            let base = positions.len() as u32;
            positions.extend_from_slice(&part.positions);
            triangles.extend(part.triangles.iter().map(|t| t.map(|v| v + base)));
        }
        Mesh::new(positions, triangles)
    }

    /// Every face outline drawn: (translucent, its three screen corners).
    fn faces_drawn(svg: &str) -> Vec<(bool, [(i32, i32); 3])> {
        let mut faces = Vec::new();
        for element in svg.split("<path").skip(1) {
            if !element.contains(" color='") {
                continue; // a mark
            }
            let translucent = element.starts_with(" class='g'");
            let d = element
                .split("d='")
                .nth(1)
                .unwrap()
                .split('\'')
                .next()
                .unwrap();
            for outline in d.split('z').filter(|o| !o.is_empty()) {
                let n: Vec<i32> = outline
                    .trim_start_matches('M')
                    .split(' ')
                    .map(|x| x.parse().unwrap())
                    .collect();
                assert_eq!(n.len(), 6, "{outline}");
                faces.push((translucent, [(n[0], n[1]), (n[2], n[3]), (n[4], n[5])]));
            }
        }
        faces
    }

    /// Twice the signed area of a screen triangle, y down: positive when clockwise on screen.
    fn turn([(x0, y0), (x1, y1), (x2, y2)]: [(i32, i32); 3]) -> i32 {
        (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    }

    /// Winding number of a triangle around a point: +1 inside a clockwise (screen) outline, -1
    /// inside an anticlockwise one, 0 outside.
    fn winding(corners: [(i32, i32); 3], p: [f64; 2]) -> i32 {
        let side = |a: (i32, i32), b: (i32, i32)| {
            let (ax, ay) = (f64::from(a.0), f64::from(a.1));
            let (bx, by) = (f64::from(b.0), f64::from(b.1));
            (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax)
        };
        let s = [
            side(corners[0], corners[1]),
            side(corners[1], corners[2]),
            side(corners[2], corners[0]),
        ];
        if s.iter().all(|&x| x > 0.0) {
            1
        } else if s.iter().all(|&x| x < 0.0) {
            -1
        } else {
            0
        }
    }

    /// A cube drawn at 2^1000 (near the largest `f64`) and at 2^-1070 (subnormal) is drawn as
    /// the unit cube: the picture scales the places by a power of two first, exactly. Before, the
    /// projections overflowed or underflowed and the faces were drawn as garbage or not at all.
    #[test]
    fn a_cube_at_an_extreme_scale_is_drawn_as_the_unit_cube() {
        let unit = picture(&cube(0.0, 1.0)).unwrap();
        for k in [1000, -1070] {
            let side = 2f64.powi(k);
            assert!(side > 0.0 && side.is_finite());
            assert_eq!(picture(&cube(0.0, side)).unwrap(), unit, "2^{k}");
        }
    }

    /// A cube wound inward is one inside-out shell: all twelve faces are violet, those turned
    /// toward the viewer and those turned away alike. Seen from outside, every point of its outline
    /// is covered by a face turned toward the viewer and one turned away, whose stored windings run
    /// opposite ways on screen; where two such faces share a shade they share a path, and the
    /// nonzero fill rule gives winding number 0 where they overlap: a hole in the picture. Written
    /// clockwise, every outline turns the same way, so the winding number of the centre of every
    /// face, summed over the outlines of its path, is at least one.
    #[test]
    fn no_face_cancels_another() {
        let svg = picture(&flipped(cube(0.0, 1.0))).unwrap();
        let faces = faces_drawn(&svg);
        // Per view: six faces in front, six behind, none edge-on from these directions.
        assert_eq!(faces.len(), 24, "{svg}");
        for (_, corners) in &faces {
            assert!(turn(*corners) > 0, "{corners:?} is not clockwise");
        }
        for element in svg
            .split("<path")
            .skip(1)
            .filter(|e| e.contains(" color='"))
        {
            let outlines = faces_drawn(&format!("<path{element}"));
            for (_, face) in &outlines {
                let centre = [0, 1]
                    .map(|k| face.iter().map(|c| f64::from([c.0, c.1][k])).sum::<f64>() / 3.0);
                let winding: i32 = outlines.iter().map(|(_, o)| winding(*o, centre)).sum();
                assert!(winding >= 1, "a face of {element} is cancelled");
            }
        }
    }

    /// Faces `0 1 2` and `1 2 3` both run 1 -> 2 along their shared edge, so it is the one
    /// inconsistently wound edge: one dashed mark of one segment in each view. Wound `2 1 3`, the
    /// second face runs 2 -> 1 and nothing is marked.
    #[test]
    fn inconsistent_edges_are_marked() {
        #[rustfmt::skip]
        let positions = vec![
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.2],
        ];
        let svg = picture(&Mesh::new(positions.clone(), vec![[0, 1, 2], [1, 2, 3]])).unwrap();
        let marks: Vec<&str> = svg.split("<path class='i' d='").skip(1).collect();
        assert_eq!(marks.len(), 2, "one in each view: {svg}");
        for m in marks {
            let d = m.split('\'').next().unwrap();
            assert_eq!(d.matches('M').count(), 1, "one segment: {d}");
        }
        assert_eq!(
            svg.matches("<path class='w' d='M").count(),
            2,
            "a halo in each view"
        );
        assert!(
            STYLE.contains(".pic .i{stroke:"),
            "the mark has its own colour"
        );
        let consistent = picture(&Mesh::new(positions, vec![[0, 1, 2], [2, 1, 3]])).unwrap();
        assert!(!consistent.contains("class='i'"), "{consistent}");
    }

    /// The hollow block: the cube `[0,2]^3` around the cube `[0.5,1.5]^3`, both wound outward,
    /// so the inner one is an inside-out cavity. Drawn opaque, the outer cube hides it from every
    /// side. The outer cube is closed and its box strictly holds the inner one: its 12 faces are
    /// drawn translucent in both views (24 outlines), the inner cube's 24 opaque.
    #[test]
    fn a_shell_around_another_is_drawn_translucent() {
        let hollow = merged(&[cube(0.0, 2.0), cube(0.5, 1.0)]);
        let inside_out = analyse(&hollow, &Options::default())
            .shells
            .iter()
            .filter(|s| s.inside_out)
            .count();
        assert_eq!(inside_out, 1);
        let faces = faces_drawn(&picture(&hollow).unwrap());
        assert_eq!(faces.len(), 48);
        assert_eq!(faces.iter().filter(|f| f.0).count(), 24, "the outer cube's");
        // The outer cube is twice the inner one's size, so its faces span further on screen.
        let span = |f: &[(i32, i32); 3]| {
            f.iter().map(|c| c.0).max().unwrap() - f.iter().map(|c| c.0).min().unwrap()
        };
        let widest = |translucent: bool| {
            faces
                .iter()
                .filter(|f| f.0 == translucent)
                .map(|f| span(&f.1))
                .max()
                .unwrap()
        };
        assert!(widest(true) > widest(false));
    }

    /// Nothing is translucent when no closed part holds another: two cubes side by side, or an open
    /// box (its top missing, so not closed) around a cube.
    #[test]
    fn parts_side_by_side_or_in_an_open_box_stay_opaque() {
        let side_by_side = merged(&[cube(0.0, 1.0), cube(2.0, 1.0)]);
        assert!(!picture(&side_by_side).unwrap().contains("class='g'"));
        let mut open = open_box();
        for p in &mut open.positions {
            *p = p.map(|x| 2.0 * x);
        }
        let boxed = merged(&[open, cube(0.5, 1.0)]);
        assert!(!picture(&boxed).unwrap().contains("class='g'"));
    }

    /// The two overlapping unit cubes of `sample_assets/rules/intersecting-components.obj`: 12 of
    /// their 24 faces meet a face of the other cube (the analysis says so), and exactly those are
    /// drawn gold (kind 3), in both views; two cubes apart have no gold face.
    #[test]
    fn faces_that_meet_are_drawn_in_their_own_colour() {
        let mesh = merged(&[cube(0.0, 1.0), cube(0.5, 1.0)]);
        let (analysis, built) = analyse_keeping(&mesh, &Options::default());
        assert_eq!(
            analysis.intersections.as_ref().unwrap().involved_faces(),
            12
        );
        let places = places(&built, &analysis);
        assert_eq!(places.meets.iter().filter(|&&m| m).count(), 12);
        let gold: Vec<String> = (0..LEVELS as u16)
            .map(|l| face_colour(3 * LEVELS as u16 + l))
            .collect();
        let svg = draw(&places).unwrap();
        let gold_faces = |svg: &str| {
            svg.split("<path")
                .filter(|e| gold.iter().any(|g| e.contains(&format!("color='{g}'"))))
                .map(|e| e.matches('M').count())
                .sum::<usize>()
        };
        // Both views draw every face they see edge-on or better: at most 12 each, at least some.
        let n = gold_faces(&svg);
        assert!(n > 0 && n <= 24, "{n} gold faces");
        let apart = merged(&[cube(0.0, 1.0), cube(2.0, 1.0)]);
        assert_eq!(gold_faces(&picture(&apart).unwrap()), 0);
    }

    /// A cube in the hole of a ring lies inside the ring's box but not inside the ring: the
    /// analysis gives both depth 0, so nothing is translucent. The ring is a square torus of 8 x 4
    /// quads (major radius 3, minor radius 1: its box is [-4, 4] x [-4, 4] x [-1, 1]), the cube
    /// [-0.5, 0.5]^3 sits at its centre, 1.5 from the ring's inner side.
    #[test]
    fn a_part_in_a_rings_hole_stays_opaque() {
        let (major, minor) = (8u32, 4u32);
        let mut positions = Vec::new();
        for i in 0..major {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(major);
            for j in 0..minor {
                let b = std::f64::consts::TAU * f64::from(j) / f64::from(minor);
                let r = 3.0 + b.cos();
                positions.push([r * a.cos(), r * a.sin(), b.sin()]);
            }
        }
        let at = |i: u32, j: u32| (i % major) * minor + j % minor;
        let mut triangles = Vec::new();
        for i in 0..major {
            for j in 0..minor {
                let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                triangles.extend([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
            }
        }
        let ring = Mesh::new(positions, triangles);
        let mesh = merged(&[ring, cube(-0.5, 1.0)]);
        let depths: Vec<usize> = analyse(&mesh, &Options::default())
            .shells
            .iter()
            .map(|s| s.depth)
            .collect();
        assert_eq!(depths, [0, 0]);
        assert!(!picture(&mesh).unwrap().contains("class='g'"));
    }

    #[test]
    fn an_open_box_draws_faces_and_its_border() {
        let svg = picture(&open_box()).unwrap();
        assert!(svg.starts_with("<svg viewBox='0 0 490 240'"), "{svg}");
        assert!(svg.ends_with("</svg>"));
        assert_eq!(svg.matches("<g").count(), 2, "two views");
        assert_eq!(
            svg.matches("<path class='b'").count(),
            2,
            "the border in each view"
        );
        assert!(!svg.contains("class='n'") && !svg.contains("class='v'"));
        assert!(!svg.contains('"'), "single quotes only");
        assert!(svg.matches("<path color=").count() >= 2);
        assert!(svg.len() < 3000, "{} bytes", svg.len());
    }

    #[test]
    fn nothing_to_draw_without_faces() {
        assert_eq!(
            picture(&Mesh::new(vec![[0.0; 3]; 3], vec![[0, 0, 1]])),
            None
        );
        assert_eq!(picture(&Mesh::default()), None);
    }

    /// A 200 x 200 grid (80,000 faces) is clustered to at most MAX_FACES and stays small.
    #[test]
    fn big_meshes_are_simplified() {
        let n = 200u32;
        let positions = (0..=n)
            .flat_map(|j| (0..=n).map(move |i| [i as f64, j as f64, ((i * j) as f64 * 0.01).sin()]))
            .collect();
        let mut triangles = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let v = j * (n + 1) + i;
                triangles.push([v, v + 1, v + n + 1]);
                triangles.push([v + 1, v + n + 2, v + n + 1]);
            }
        }
        let svg = picture(&Mesh::new(positions, triangles)).unwrap();
        let drawn: usize = svg
            .split("data-drawn='")
            .nth(1)
            .unwrap()
            .split('\'')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(drawn <= MAX_FACES && drawn > MAX_FACES / 4, "{drawn}");
        assert!(svg.len() < 80_000, "{} bytes", svg.len());
    }

    #[test]
    fn colours_are_short_hex() {
        for c in 0..(3 * LEVELS) as u16 {
            let s = face_colour(c);
            assert_eq!(s.len(), 4, "{s}");
        }
        assert_ne!(face_colour(0), face_colour(LEVELS as u16 - 1));
    }
}
