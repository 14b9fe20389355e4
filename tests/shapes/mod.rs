//! Hand-built meshes with explicit positions, for the topology tests and the benchmark.
//!
//! Every generator returns a [`meshvet::Mesh`] whose counts (V, E, F, holes, volume) the caller can
//! derive by hand; the derivations live in the doc comments of the generators and of the tests that
//! use them. Windings are counterclockwise seen from outside (positive volume) unless a name says
//! otherwise.
//!
//! This file is included with `mod shapes;` from `tests/` and with
//! `#[path = "../tests/shapes/mod.rs"] mod shapes;` from `benches/`, so it depends on nothing but
//! `meshvet` and `std`. Each includer uses part of it, so it puts `#[allow(dead_code)]` on its `mod`.

use std::f64::consts::TAU;

use meshvet::Mesh;

/// A tiny deterministic generator (xorshift64*) for shuffles; no `rand` crate.
#[derive(Debug, Clone)]
pub struct XorShift(u64);

impl XorShift {
    pub fn new(seed: u64) -> XorShift {
        // Any seed works; zero is the one fixed point of xorshift, so move it.
        XorShift((seed ^ 0x9E37_79B9_7F4A_7C15) | 1)
    }

    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// A number in `0..bound` (`bound > 0`); the modulo bias is irrelevant for shuffling tests.
    pub fn below(&mut self, bound: usize) -> usize {
        (self.next_u64() % bound as u64) as usize
    }

    /// Fisher-Yates shuffle in place.
    pub fn shuffle<T>(&mut self, items: &mut [T]) {
        for i in (1..items.len()).rev() {
            let j = self.below(i + 1);
            items.swap(i, j);
        }
    }
}

/// A bowtie: the triangles `(0,0,0) (1,0,0) (1,1,0)` and `(0,0,0) (-1,0,0) (-1,-1,0)`, touching
/// only at vertex 0 (one non-manifold vertex; fan centres `(1, 0.5, 0)` and `(-1, -0.5, 0)`).
pub fn bowtie() -> Mesh {
    Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
            [-1.0, -1.0, 0.0],
        ],
        vec![[0, 1, 2], [0, 3, 4]],
    )
}

/// The unit corner tetrahedron `(0,0,0) (1,0,0) (0,1,0) (0,0,1)`, outward.
///
/// V 4, E 6, F 4, chi 2, genus 0; volume 1/6 (base 1/2 x height 1 / 3); area 3 x 1/2 + sqrt(3)/2.
pub fn tetrahedron() -> Mesh {
    Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
        // z=0 face seen from below, y=0 face from -y, x=0 face from -x, slanted face from (1,1,1).
        vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
}

/// The twelve outward triangles of a box over corners numbered `x + 2y + 4z` (bit 0: x at max, bit 1:
/// y at max, bit 2: z at max). Each square side `a b c d` (counterclockwise from outside) is split
/// along `a c` into `a b c` and `a c d`. Diagonals: 0-3, 4-7, 0-5, 2-7, 0-6, 1-7 (all distinct), so
/// E = 12 box edges + 6 diagonals = 18.
#[rustfmt::skip]
pub const BOX_TRIANGLES: [[u32; 3]; 12] = [
    [0, 2, 3],
    [0, 3, 1], // z = min, seen from -z
    [4, 5, 7],
    [4, 7, 6], // z = max, seen from +z
    [0, 1, 5],
    [0, 5, 4], // y = min, seen from -y
    [2, 6, 7],
    [2, 7, 3], // y = max, seen from +y
    [0, 4, 6],
    [0, 6, 2], // x = min, seen from -x
    [1, 3, 7],
    [1, 7, 5], // x = max, seen from +x
];

/// An axis-aligned box from `lo` to `hi`, outward: V 8, E 18, F 12, chi 2, genus 0, volume the
/// product of its sides.
pub fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> Mesh {
    let positions = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ]
        })
        .collect();
    Mesh::new(positions, BOX_TRIANGLES.to_vec())
}

/// The unit cube `[0,1]^3`, outward: V 8, E 18, F 12, chi 2, volume 1, area 6.
pub fn cube() -> Mesh {
    cuboid([0.0; 3], [1.0; 3])
}

/// The cube `[lo, lo + side]^3`, outward.
pub fn cube_at(lo: f64, side: f64) -> Mesh {
    cuboid([lo; 3], [lo + side; 3])
}

/// The same triangles with the winding of every face reversed (`a b c` -> `a c b`).
pub fn flipped(mesh: &Mesh) -> Mesh {
    let triangles = mesh.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect();
    Mesh::new(mesh.positions.clone(), triangles)
}

/// A triangle soup: every triangle gets three input vertices of its own (as STL stores it). Welding
/// by position gives the original mesh back.
pub fn soup(mesh: &Mesh) -> Mesh {
    let mut positions = Vec::with_capacity(3 * mesh.triangles.len());
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for t in &mesh.triangles {
        let base = positions.len() as u32;
        positions.extend(t.iter().map(|&v| mesh.positions[v as usize]));
        triangles.push([base, base + 1, base + 2]);
    }
    Mesh::new(positions, triangles)
}

/// Several meshes as one: positions concatenated, indices offset. Equal positions in different parts
/// weld together in the analysis.
pub fn merge(parts: &[Mesh]) -> Mesh {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for part in parts {
        let base = positions.len() as u32;
        positions.extend_from_slice(&part.positions);
        triangles.extend(part.triangles.iter().map(|t| t.map(|v| v + base)));
    }
    Mesh::new(positions, triangles)
}

/// A flat `nx` x `ny` grid of unit squares in the plane z = 0, each split into two triangles,
/// counterclockwise seen from +z. Vertex `(x, y)` is `y (nx + 1) + x`.
///
/// V = (nx+1)(ny+1); E = nx(ny+1) + ny(nx+1) + nx ny (rows, columns, diagonals); F = 2 nx ny;
/// chi = 1; one hole of 2(nx + ny) border edges.
pub fn grid(nx: usize, ny: usize) -> Mesh {
    let mut positions = Vec::with_capacity((nx + 1) * (ny + 1));
    for y in 0..=ny {
        for x in 0..=nx {
            positions.push([x as f64, y as f64, 0.0]);
        }
    }
    let id = |x: usize, y: usize| (y * (nx + 1) + x) as u32;
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for y in 0..ny {
        for x in 0..nx {
            let (a, b, c, d) = (id(x, y), id(x + 1, y), id(x + 1, y + 1), id(x, y + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh::new(positions, triangles)
}

/// A plate of thickness 1 (z from 0 to 1): the `nx` x `ny` grid of unit cells minus the cells in
/// `holes`, with a top copy (counterclockwise from +z), a bottom copy (reversed) and a wall of two
/// triangles under every cell side that has no kept cell beside it. Outward everywhere.
///
/// With a planar region R of V0 vertices, E0 edges, F0 triangles (chi(R) = 1 - #holes when the
/// holes touch neither each other nor the border) and B border edges (= B border vertices): V = 2 V0,
/// E = 2 E0 + B (vertical edges) + B (wall diagonals), F = 2 F0 + 2 B, so chi = 2 chi(R) and the
/// genus is the number of holes. Volume: number of kept cells.
///
/// Top vertex `(x, y)` is `y (nx + 1) + x`; its bottom copy is that plus `(nx + 1)(ny + 1)`.
pub fn plate(nx: usize, ny: usize, holes: &[(usize, usize)]) -> Mesh {
    let layer = (nx + 1) * (ny + 1);
    let mut positions = Vec::with_capacity(2 * layer);
    for z in [1.0, 0.0] {
        for y in 0..=ny {
            for x in 0..=nx {
                positions.push([x as f64, y as f64, z]);
            }
        }
    }
    let kept = |x: isize, y: isize| {
        x >= 0
            && y >= 0
            && (x as usize) < nx
            && (y as usize) < ny
            && !holes.contains(&(x as usize, y as usize))
    };
    let top = |x: usize, y: usize| (y * (nx + 1) + x) as u32;
    let bottom = |x: usize, y: usize| (layer + y * (nx + 1) + x) as u32;
    let mut triangles = Vec::new();
    for y in 0..ny {
        for x in 0..nx {
            if !kept(x as isize, y as isize) {
                continue;
            }
            // Cell corners counterclockwise from +z.
            let corners = [(x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1)];
            let [a, b, c, d] = corners.map(|(x, y)| top(x, y));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
            let [a, b, c, d] = corners.map(|(x, y)| bottom(x, y));
            triangles.push([a, c, b]);
            triangles.push([a, d, c]);
            // Sides in counterclockwise order, each with the cell beside it. The region is on the
            // left of p -> q, so the wall p q q' p' (bottom p, bottom q, top q, top p) faces out.
            let (xi, yi) = (x as isize, y as isize);
            let sides = [
                (0, 1, xi, yi - 1),
                (1, 2, xi + 1, yi),
                (2, 3, xi, yi + 1),
                (3, 0, xi - 1, yi),
            ];
            for (i, j, nx_, ny_) in sides {
                if kept(nx_, ny_) {
                    continue;
                }
                let (p, q) = (corners[i], corners[j]);
                let (pb, qb, qt, pt) = (
                    bottom(p.0, p.1),
                    bottom(q.0, q.1),
                    top(q.0, q.1),
                    top(p.0, p.1),
                );
                triangles.push([pb, qb, qt]);
                triangles.push([pb, qt, pt]);
            }
        }
    }
    Mesh::new(positions, triangles)
}

/// Torus radii: the tube's centre circle and the tube.
pub const TORUS_R: f64 = 2.0;
pub const TORUS_TUBE: f64 = 1.0;

/// An `n` x `m` quad grid on a torus (`n` steps around the z axis, `m` around the tube; both >= 3),
/// each quad split into two triangles, outward. Vertex `(i, j)` is `i m + j`, at angles
/// `u = 2 pi i / n`, `v = 2 pi j / m`.
///
/// Each quad `(i,j)` owns one edge along u, one along v and its diagonal: V = nm, E = 3nm, F = 2nm,
/// chi = 0, closed, genus 1.
///
/// `shuffle_seed` shuffles the order of the faces deterministically (Fisher-Yates with
/// [`XorShift`]), so a traversal cannot rely on neighbours being stored close together.
/// Built without per-face allocation: it is used for meshes of millions of triangles.
pub fn torus(n: usize, m: usize, shuffle_seed: Option<u64>) -> Mesh {
    assert!(
        n >= 3 && m >= 3,
        "a grid torus needs at least 3 x 3 vertices"
    );
    let (su, cu): (Vec<f64>, Vec<f64>) = (0..n)
        .map(|i| (TAU * i as f64 / n as f64).sin_cos())
        .unzip();
    let (sv, cv): (Vec<f64>, Vec<f64>) = (0..m)
        .map(|j| (TAU * j as f64 / m as f64).sin_cos())
        .unzip();
    let mut positions = Vec::with_capacity(n * m);
    for i in 0..n {
        for j in 0..m {
            let radius = TORUS_R + TORUS_TUBE * cv[j];
            positions.push([radius * cu[i], radius * su[i], TORUS_TUBE * sv[j]]);
        }
    }
    let mut triangles = Vec::with_capacity(2 * n * m);
    for i in 0..n {
        let i1 = (i + 1) % n;
        for j in 0..m {
            let j1 = (j + 1) % m;
            // d(u) x d(v) points out of the tube, so u-then-v order is counterclockwise from outside.
            let (a, b, c, d) = (i * m + j, i1 * m + j, i1 * m + j1, i * m + j1);
            triangles.push([a as u32, b as u32, c as u32]);
            triangles.push([a as u32, c as u32, d as u32]);
        }
    }
    if let Some(seed) = shuffle_seed {
        XorShift::new(seed).shuffle(&mut triangles);
    }
    Mesh::new(positions, triangles)
}

/// An open tube: `n` (>= 3) vertices around the unit circle, `h` (>= 1) rings of quads up the z axis,
/// outward, both ends open. Vertex `(j, k)` (j around, k up) is `k n + j`.
///
/// V = n(h+1); E = n(h+1) (around) + nh (up) + nh (diagonals); F = 2nh; chi = 0; 2 holes (the end
/// rings, n border edges each); genus (2 - 0 - 2)/2 = 0.
pub fn tube(n: usize, h: usize) -> Mesh {
    let mut positions = Vec::with_capacity(n * (h + 1));
    for k in 0..=h {
        for j in 0..n {
            let (s, c) = (TAU * j as f64 / n as f64).sin_cos();
            positions.push([c, s, k as f64]);
        }
    }
    let mut triangles = Vec::with_capacity(2 * n * h);
    for k in 0..h {
        for j in 0..n {
            let j1 = (j + 1) % n;
            // d(theta) x d(z) = (cos, sin, 0): outward.
            let (a, b, c, d) = (k * n + j, k * n + j1, (k + 1) * n + j1, (k + 1) * n + j);
            triangles.push([a as u32, b as u32, c as u32]);
            triangles.push([a as u32, c as u32, d as u32]);
        }
    }
    Mesh::new(positions, triangles)
}

/// A Moebius strip of `n` (>= 3) quads, one quad wide. Vertex `(i, s)` (s = 0, 1 across) is `2i + s`,
/// at `((2 + w cos(u/2)) cos u, (2 + w cos(u/2)) sin u, w sin(u/2))` with `u = 2 pi i / n` and
/// `w = -1/2` (s = 0) or `+1/2` (s = 1); at `u = 2 pi` the side `w` arrives at `(0, -w)`, so the last
/// quad joins `(n-1, 0), (n-1, 1)` to `(0, 1), (0, 0)`.
///
/// Quad `i` has corners `a = (i,0), b = next of a, c = next of d, d = (i,1)` and triangles `a b c`,
/// `a c d`. Each quad owns one rung (`a d`), two long edges (`a b`, `d c`) and a diagonal (`a c`):
/// V = 2n, E = 4n, F = 2n, chi = 0. The long edges are the border: one loop of 2n edges, 1 hole.
/// Rung 0 is traversed `(0,1) -> (0,0)` by both quad 0 (`d -> a`) and the last quad (`b -> c`): the
/// only inconsistent edge. Not orientable, so genus undefined.
pub fn moebius(n: usize) -> Mesh {
    assert!(n >= 3);
    let mut positions = Vec::with_capacity(2 * n);
    for i in 0..n {
        let u = TAU * i as f64 / n as f64;
        for w in [-0.5, 0.5] {
            let radius = 2.0 + w * (u / 2.0).cos();
            positions.push([radius * u.cos(), radius * u.sin(), w * (u / 2.0).sin()]);
        }
    }
    let id = |i: usize, s: usize| (2 * i + s) as u32;
    let mut triangles = Vec::with_capacity(2 * n);
    for i in 0..n {
        let (a, d) = (id(i, 0), id(i, 1));
        let (b, c) = if i + 1 < n {
            (id(i + 1, 0), id(i + 1, 1))
        } else {
            (id(0, 1), id(0, 0))
        };
        triangles.push([a, b, c]);
        triangles.push([a, c, d]);
    }
    Mesh::new(positions, triangles)
}

/// A Klein bottle: an `n` x `m` quad grid (both >= 3) glued like the torus along `j`, and along `i`
/// with a flip: column `n` is column 0 read backwards, `(n, j) = (0, m-1-j)`.
///
/// Positions: the figure-8 immersion `((R + a) cos u, (R + a) sin u, b)` with
/// `a = cos(u/2) sin v - sin(u/2) sin 2v`, `b = sin(u/2) sin v + cos(u/2) sin 2v`, R = 3,
/// `u = 2 pi i / n`, `v = 2 pi (j + 1/2) / m`. At `u + 2 pi` the pair `(a, b)` at v equals the pair at
/// `-v`, which is row `m-1-j`: the flip. The half step keeps v off 0 and pi, where the figure 8
/// crosses itself, so the n m vertex positions are distinct.
///
/// Each quad owns one edge along i, one along j and its diagonal: V = nm, E = 3nm, F = 2nm, chi 0,
/// closed, not orientable. Quads are wound `a b c`, `a c d` in (i, j) order, so column 0's m edges
/// are traversed downwards (j+1 -> j) both by column 0's quads and by the glued last column's quads:
/// exactly m inconsistent edges.
pub fn klein(n: usize, m: usize) -> Mesh {
    assert!(n >= 3 && m >= 3);
    let big_r = 3.0;
    let mut positions = Vec::with_capacity(n * m);
    for i in 0..n {
        let u = TAU * i as f64 / n as f64;
        for j in 0..m {
            let v = TAU * (j as f64 + 0.5) / m as f64;
            let a = (u / 2.0).cos() * v.sin() - (u / 2.0).sin() * (2.0 * v).sin();
            let b = (u / 2.0).sin() * v.sin() + (u / 2.0).cos() * (2.0 * v).sin();
            positions.push([(big_r + a) * u.cos(), (big_r + a) * u.sin(), b]);
        }
    }
    let id = |i: usize, j: usize| (i * m + j) as u32;
    let mut triangles = Vec::with_capacity(2 * n * m);
    for i in 0..n {
        for j in 0..m {
            let j1 = (j + 1) % m;
            let (a, d) = (id(i, j), id(i, j1));
            let (b, c) = if i + 1 < n {
                (id(i + 1, j), id(i + 1, j1))
            } else {
                (id(0, m - 1 - j), id(0, m - 1 - j1))
            };
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh::new(positions, triangles)
}

/// The projective plane's six-vertex triangulation, placed in space: the apex `(0, 0, 10)` joined to
/// the pentagon `(10, 0, 0)`, `(3, 9, 0)`, `(-8, 6, 0)`, `(-8, -6, 0)`, `(3, -9, 0)` (a pyramid
/// without its base), and the pentagon's five star triangles `i, i+1, i+3` lying over each other
/// in its plane. V 6, E 15 (5 walls' edges, 5 sides, 5 diagonals, each in two faces), F 10: closed,
/// chi = 1, so not orientable (a closed orientable surface has an even chi). Like any closed
/// non-orientable surface in space it passes through itself (here the star triangles overlap).
pub fn projective_plane() -> Mesh {
    let positions = vec![
        [0.0, 0.0, 10.0],
        [10.0, 0.0, 0.0],
        [3.0, 9.0, 0.0],
        [-8.0, 6.0, 0.0],
        [-8.0, -6.0, 0.0],
        [3.0, -9.0, 0.0],
    ];
    let mut triangles = Vec::new();
    for i in 0..5u32 {
        triangles.push([0, 1 + i, 1 + (i + 1) % 5]);
        triangles.push([1 + i, 1 + (i + 1) % 5, 1 + (i + 3) % 5]);
    }
    Mesh::new(positions, triangles)
}
