//! The topology engine on hand-built meshes (SPEC sections 3-8).
//!
//! Every expected number comes from the derivation in the test's doc comment: V, E, F counted by hand,
//! `chi = V - E + F`, holes `b`, genus `g = (2 - chi - b) / 2`, volumes by elementary geometry. None of
//! them was read off the program's output.
//!
//! Conventions used in the derivations:
//! - the star of a vertex is the faces and edges it bounds (seed 003), so a vertex is non-manifold when
//!   an edge *at* it has valence 3 or more, or its faces split into several edge-connected fans;
//! - "inside" in the nesting rule means in the interior of the other solid: a vertex on its surface is
//!   not inside;
//! - `welded_vertices` counts valid positions, `unreferenced_vertices` valid welded vertices no face
//!   uses, and `euler` (like every table count) is over the faces the table keeps.

#[allow(dead_code)]
mod shapes;

use std::collections::HashMap;

use meshvet::corner_table::CornerTable;
use meshvet::{analyse, Analysis, Mesh, Options, Role};
use proptest::prelude::*;

use shapes::{cube, cube_at, cuboid, flipped, merge, soup, tetrahedron, XorShift, BOX_TRIANGLES};

// ---------------------------------------------------------------------------------------------------
// Harness
// ---------------------------------------------------------------------------------------------------

fn run(mesh: &Mesh) -> Analysis {
    analyse(mesh, &Options::default())
}

/// The plain counters of an analysis, compared as one value so a failure shows every difference.
#[derive(Debug, Clone, PartialEq, Default)]
struct Counts {
    vertices: usize,
    welded_vertices: usize,
    faces: usize,
    degenerate_faces: usize,
    zero_area_faces: usize,
    duplicate_faces: usize,
    invalid_vertices: usize,
    invalid_faces: usize,
    unreferenced_vertices: usize,
    edges: usize,
    border_edges: usize,
    nonmanifold_edges: usize,
    nonmanifold_vertices: usize,
    inconsistent_edges: usize,
    euler: i64,
    components: usize,
    shells: usize,
}

fn counts(a: &Analysis) -> Counts {
    Counts {
        vertices: a.vertices,
        welded_vertices: a.welded_vertices,
        faces: a.faces,
        degenerate_faces: a.degenerate_faces,
        zero_area_faces: a.zero_area_faces,
        duplicate_faces: a.duplicate_faces,
        invalid_vertices: a.invalid_vertices,
        invalid_faces: a.invalid_faces,
        unreferenced_vertices: a.unreferenced_vertices,
        edges: a.edges,
        border_edges: a.border_edges,
        nonmanifold_edges: a.nonmanifold_edges,
        nonmanifold_vertices: a.nonmanifold_vertices,
        inconsistent_edges: a.inconsistent_edges,
        euler: a.euler,
        components: a.components.len(),
        shells: a.shell_count(),
    }
}

/// Counts of a clean mesh: every input vertex its own welded vertex, every face in the table.
fn clean(vertices: usize, edges: usize, faces: usize) -> Counts {
    Counts {
        vertices,
        welded_vertices: vertices,
        faces,
        edges,
        euler: vertices as i64 - edges as i64 + faces as i64,
        ..Counts::default()
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * b.abs().max(1.0)
}

#[track_caller]
fn assert_close(actual: f64, expected: f64) {
    assert!(close(actual, expected), "expected {expected}, got {actual}");
}

#[track_caller]
fn assert_volume(actual: Option<f64>, expected: Option<f64>) {
    match (actual, expected) {
        (Some(a), Some(e)) => assert_close(a, e),
        (a, e) => assert_eq!(a, e, "volume"),
    }
}

/// Depth, role and signed volume of every shell, in shell order.
#[track_caller]
fn assert_shells(a: &Analysis, expected: &[(usize, Role, Option<f64>)]) {
    let got: Vec<(usize, Role)> = a.shells.iter().map(|s| (s.depth, s.role)).collect();
    let want: Vec<(usize, Role)> = expected.iter().map(|&(d, r, _)| (d, r)).collect();
    assert_eq!(got, want, "shell depths and roles");
    for (s, &(_, _, v)) in a.shells.iter().zip(expected) {
        assert_volume(s.volume, v);
    }
}

/// The facts of a closed, oriented, outward mesh of `shells` genus-0 solids at depth 0.
#[track_caller]
fn assert_outward_spheres(a: &Analysis, shells: usize) {
    assert_eq!(a.holes(), 0);
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable());
    assert!(a.oriented());
    assert_eq!(
        (a.solids(), a.cavities(), a.inside_out_shells()),
        (shells, 0, 0)
    );
    for c in &a.components {
        assert!(
            c.closed && c.manifold && c.orientable && c.oriented,
            "{c:?}"
        );
        assert_eq!((c.euler, c.genus, c.holes), (2, Some(0), 0));
    }
}

// ---------------------------------------------------------------------------------------------------
// Closed, clean surfaces
// ---------------------------------------------------------------------------------------------------

/// Unit corner tetrahedron `(0,0,0) (1,0,0) (0,1,0) (0,0,1)`, outward.
///
/// V 4, E 6 (every pair), F 4; chi = 4 - 6 + 4 = 2; closed so b = 0; g = (2 - 2 - 0)/2 = 0
/// (seed: T/4 - V/2 + 1 = 1 - 2 + 1 = 0). One shell at depth 0, a solid; volume = base 1/2 x height 1
/// / 3 = 1/6; area = three right triangles of 1/2 plus the equilateral one of side sqrt 2:
/// sqrt(3)/4 x 2 = sqrt(3)/2. Bounding box the unit cube.
#[test]
fn tetrahedron_is_one_outward_solid() {
    let a = run(&tetrahedron());
    assert_eq!(
        counts(&a),
        Counts {
            components: 1,
            shells: 1,
            ..clean(4, 6, 4)
        }
    );
    assert_outward_spheres(&a, 1);
    assert_shells(&a, &[(0, Role::Solid, Some(1.0 / 6.0))]);
    assert_volume(a.volume(), Some(1.0 / 6.0));
    assert_close(a.area, 1.5 + 3f64.sqrt() / 2.0);
    assert_eq!(a.bbox, Some([[0.0; 3], [1.0; 3]]));
    let s = &a.shells[0];
    assert_eq!(
        (s.component, s.faces, s.vertices, s.genus),
        (0, 4, 4, Some(0))
    );
    assert!(s.orientable && s.oriented && !s.inside_out);
    assert_eq!(s.bbox, [[0.0; 3], [1.0; 3]]);
    let c = &a.components[0];
    assert_eq!(
        (
            c.faces,
            c.vertices,
            c.edges,
            c.border_edges,
            c.nonmanifold_edges
        ),
        (4, 4, 6, 0, 0)
    );
}

/// Unit cube, 6 squares split into 12 triangles, outward.
///
/// V 8, E = 12 cube edges + 6 diagonals = 18, F 12; chi = 8 - 18 + 12 = 2; b 0; g 0
/// (T/4 - V/2 + 1 = 3 - 4 + 1 = 0). One solid; volume 1; area 6.
#[test]
fn cube_is_one_outward_solid() {
    let a = run(&cube());
    assert_eq!(
        counts(&a),
        Counts {
            components: 1,
            shells: 1,
            ..clean(8, 18, 12)
        }
    );
    assert_outward_spheres(&a, 1);
    assert_shells(&a, &[(0, Role::Solid, Some(1.0))]);
    assert_volume(a.volume(), Some(1.0));
    assert_close(a.area, 6.0);
    let c = &a.components[0];
    assert_eq!((c.faces, c.vertices, c.edges), (12, 8, 18));
}

/// The cube as a triangle soup (STL style): 12 triangles x 3 = 36 input vertices, which weld to the
/// cube's 8 corners. After welding it is the cube: E 18, F 12, chi 2, one solid of volume 1.
#[test]
fn cube_soup_welds_to_the_cube() {
    let a = run(&soup(&cube()));
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 36,
            components: 1,
            shells: 1,
            ..clean(8, 18, 12)
        }
    );
    assert_outward_spheres(&a, 1);
    assert_volume(a.volume(), Some(1.0));
}

/// Grid torus, n = 6 around the axis, m = 4 around the tube.
///
/// Each quad owns one edge along each direction and its diagonal: V = nm = 24, E = 3nm = 72,
/// F = 2nm = 48; chi = 24 - 72 + 48 = 0; closed, b = 0; g = (2 - 0 - 0)/2 = 1
/// (T/4 - V/2 + 1 = 12 - 12 + 1 = 1). One shell, oriented, outward: its volume is positive (the exact
/// value of a polyhedral torus is not elementary; only the sign is asserted).
#[test]
fn torus_grid_has_genus_one() {
    let a = run(&shapes::torus(6, 4, None));
    assert_eq!(
        counts(&a),
        Counts {
            components: 1,
            shells: 1,
            ..clean(24, 72, 48)
        }
    );
    assert_eq!(a.holes(), 0);
    assert_eq!(a.genus(), Some(1));
    assert!(a.orientable() && a.oriented());
    let c = &a.components[0];
    assert!(c.closed && c.manifold && c.orientable && c.oriented);
    assert_eq!((c.euler, c.genus), (0, Some(1)));
    assert_eq!(a.shells[0].genus, Some(1));
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (1, 0, 0));
    assert!(a.shells[0].volume.expect("orientable shell") > 0.0);
}

/// The smallest grid torus, 3 x 3: V 9, E 27, F 18, chi 0, genus 1 (T/4 - V/2 + 1 = 4.5 - 4.5 + 1).
/// Shuffling its faces changes nothing.
#[test]
fn smallest_grid_torus_has_genus_one() {
    for seed in [None, Some(1), Some(2)] {
        let a = run(&shapes::torus(3, 3, seed));
        assert_eq!(
            counts(&a),
            Counts {
                components: 1,
                shells: 1,
                ..clean(9, 27, 18)
            },
            "seed {seed:?}"
        );
        assert_eq!(a.genus(), Some(1));
        assert!(a.oriented());
    }
}

/// A square frame: the 3 x 3 plate of unit cells minus the centre, 1 thick.
///
/// Planar region: 4 x 4 = 16 grid points; 24 unit edges + 8 diagonals = 32 edges; 16 triangles;
/// chi(R) = 0 (an annulus); border B = 12 outside + 4 around the hole = 16.
/// Solid: V = 2 x 16 = 32, E = 2 x 32 + 16 vertical + 16 wall diagonals = 96, F = 2 x 16 + 2 x 16 = 64;
/// chi = 32 - 96 + 64 = 0; genus 1. Volume: 8 unit cells.
#[test]
fn square_frame_has_genus_one_and_volume_eight() {
    let a = run(&shapes::plate(3, 3, &[(1, 1)]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 1,
            shells: 1,
            ..clean(32, 96, 64)
        }
    );
    assert_eq!(a.holes(), 0);
    assert_eq!(a.genus(), Some(1));
    assert!(a.orientable() && a.oriented());
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (1, 0, 0));
    assert_shells(&a, &[(0, Role::Solid, Some(8.0))]);
    assert_volume(a.volume(), Some(8.0));
}

/// A 5 x 3 plate with two holes, at cells (1,1) and (3,1), 1 thick: a closed surface of genus 2.
///
/// Planar region: 6 x 4 = 24 grid points; unit edges 5 x 4 + 6 x 3 = 38; 13 cells -> 26 triangles and
/// 13 diagonals, E0 = 51; chi(R) = 24 - 51 + 26 = -1; border B = 2(5 + 3) + 4 + 4 = 24.
/// Solid: V = 48, E = 2 x 51 + 24 + 24 = 150, F = 2 x 26 + 2 x 24 = 100; chi = 48 - 150 + 100 = -2;
/// g = (2 + 2 - 0)/2 = 2 (T/4 - V/2 + 1 = 25 - 24 + 1 = 2). Volume: 13 cells.
#[test]
fn plate_with_two_holes_has_genus_two() {
    let a = run(&shapes::plate(5, 3, &[(1, 1), (3, 1)]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 1,
            shells: 1,
            ..clean(48, 150, 100)
        }
    );
    assert_eq!(a.holes(), 0);
    assert_eq!(a.genus(), Some(2));
    assert_eq!(a.components[0].genus, Some(2));
    assert_eq!(a.shells[0].genus, Some(2));
    assert!(a.orientable() && a.oriented());
    assert_shells(&a, &[(0, Role::Solid, Some(13.0))]);
    assert_volume(a.volume(), Some(13.0));
}

/// A 7 x 3 plate with three holes at cells (1,1), (3,1), (5,1), 1 thick: genus 3.
///
/// Planar region: 8 x 4 = 32 grid points; unit edges 7 x 4 + 8 x 3 = 52; 18 cells -> 36 triangles and
/// 18 diagonals, E0 = 70; chi(R) = 32 - 70 + 36 = -2; border B = 2(7 + 3) + 3 x 4 = 32.
/// Solid: V = 64, E = 140 + 32 + 32 = 204, F = 72 + 64 = 136; chi = 64 - 204 + 136 = -4;
/// g = (2 + 4)/2 = 3 (T/4 - V/2 + 1 = 34 - 32 + 1 = 3). Volume: 18 cells.
#[test]
fn plate_with_three_holes_has_genus_three() {
    let a = run(&shapes::plate(7, 3, &[(1, 1), (3, 1), (5, 1)]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 1,
            shells: 1,
            ..clean(64, 204, 136)
        }
    );
    assert_eq!(a.holes(), 0);
    assert_eq!(a.genus(), Some(3));
    assert!(a.orientable() && a.oriented());
    assert_shells(&a, &[(0, Role::Solid, Some(18.0))]);
    assert_volume(a.volume(), Some(18.0));
}

/// Two genus-2 plates and a torus side by side: genera add up, 2 + 2 + 1 = 5.
///
/// Plates at x in [0,5] and x in [10,15] (disjoint), the torus (centre radius 2, tube 1) moved to
/// x = 30. Components 3, shells 3, all at depth 0.
#[test]
fn genus_adds_over_components() {
    let mut second = shapes::plate(5, 3, &[(1, 1), (3, 1)]);
    second.positions.iter_mut().for_each(|p| p[0] += 10.0);
    let mut ring = shapes::torus(6, 4, None);
    ring.positions.iter_mut().for_each(|p| p[0] += 30.0);
    let a = run(&merge(&[
        shapes::plate(5, 3, &[(1, 1), (3, 1)]),
        second,
        ring,
    ]));
    assert_eq!(a.components.len(), 3);
    assert_eq!(a.genus(), Some(5));
    assert_eq!(a.euler, -2 - 2);
    assert_eq!((a.solids(), a.cavities()), (3, 0));
}

// ---------------------------------------------------------------------------------------------------
// Surfaces with borders
// ---------------------------------------------------------------------------------------------------

/// The unit cube without its two z = 1 triangles.
fn open_box() -> Mesh {
    let mut mesh = cube();
    mesh.triangles.retain(|t| !BOX_TRIANGLES[2..4].contains(t));
    mesh
}

/// The unit cube without its top (the two z = 1 triangles removed).
///
/// V 8 (the top corners still bound the walls); E = 18 - 1 (the top diagonal 4-7) = 17; F 10;
/// chi = 8 - 17 + 10 = 1; the four top edges now bound one face each: 4 border edges, one loop,
/// b = 1; g = (2 - 1 - 1)/2 = 0. Not closed: no shell, no volume.
#[test]
fn open_box_has_one_hole() {
    let a = run(&open_box());
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 4,
            components: 1,
            ..clean(8, 17, 10)
        }
    );
    assert_eq!(a.holes(), 1);
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable() && a.oriented());
    let c = &a.components[0];
    assert!(!c.closed && c.manifold);
    assert_eq!((c.holes, c.euler, c.genus), (1, 1, Some(0)));
    assert_volume(a.volume(), None);
}

/// A flat 3 x 2 grid of unit squares.
///
/// V = 4 x 3 = 12; E = 3 x 3 (rows) + 2 x 4 (columns) + 6 (diagonals) = 23; F = 12;
/// chi = 12 - 23 + 12 = 1; border 2(3 + 2) = 10 edges in one loop, b = 1; g = 0.
#[test]
fn flat_grid_is_a_disc() {
    let a = run(&shapes::grid(3, 2));
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 10,
            components: 1,
            ..clean(12, 23, 12)
        }
    );
    assert_eq!(a.holes(), 1);
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable() && a.oriented());
    assert_volume(a.volume(), None);
    assert_close(a.area, 6.0);
}

/// A flat annulus: the 3 x 3 grid without its centre cell (triangles 8 and 9).
///
/// V = 16 (every grid point still bounds a kept cell); E = 3 x 4 + 4 x 3 + 9 diagonals - 1 (the
/// centre diagonal) = 32; F = 16; chi = 16 - 32 + 16 = 0. Border: 12 outside + 4 around the centre =
/// 16 edges in 2 loops; g = (2 - 0 - 2)/2 = 0.
#[test]
fn flat_annulus_has_two_holes() {
    let mut mesh = shapes::grid(3, 3);
    mesh.triangles.drain(8..10);
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 16,
            components: 1,
            ..clean(16, 32, 16)
        }
    );
    assert_eq!(a.holes(), 2);
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable() && a.oriented());
}

/// An open tube: 5 vertices around, 2 rings of quads up, both ends open.
///
/// V = 5 x 3 = 15; E = 5 x 3 (around) + 5 x 2 (up) + 5 x 2 (diagonals) = 35; F = 20;
/// chi = 15 - 35 + 20 = 0; the two end rings are the border: 10 border edges, b = 2;
/// g = (2 - 0 - 2)/2 = 0.
#[test]
fn open_tube_has_two_holes() {
    let a = run(&shapes::tube(5, 2));
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 10,
            components: 1,
            ..clean(15, 35, 20)
        }
    );
    assert_eq!(a.holes(), 2);
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable() && a.oriented());
    assert_eq!(a.components[0].euler, 0);
    assert_volume(a.volume(), None);
}

/// A Moebius strip of 5 quads.
///
/// V = 10, E = 20 (per quad: a rung, two long edges, a diagonal), F = 10; chi = 0. The 10 long edges
/// are the border and form one loop (going once around reaches the other side): b = 1. Not
/// orientable, so the genus is undefined. Stored windings agree everywhere except across rung 0,
/// which quad 0 and quad 4 both traverse from (0,1) to (0,0): 1 inconsistent edge. Manifold, not
/// closed: no shell.
#[test]
fn moebius_strip_is_not_orientable() {
    let a = run(&shapes::moebius(5));
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 10,
            inconsistent_edges: 1,
            components: 1,
            ..clean(10, 20, 10)
        }
    );
    assert_eq!(a.holes(), 1);
    assert!(!a.orientable());
    assert!(!a.oriented());
    assert_eq!(a.genus(), None);
    let c = &a.components[0];
    assert!(c.manifold && !c.closed && !c.orientable && !c.oriented);
    assert_eq!((c.euler, c.holes, c.genus), (0, 1, None));
    assert_volume(a.volume(), None);
}

/// A Klein bottle on a 6 x 4 grid (figure-8 immersion; topology comes from the indices).
///
/// V = 24, E = 72, F = 48, chi = 0; closed (b = 0) and manifold, so it is a shell, but not orientable:
/// genus undefined, no volume. Column 0's 4 edges are traversed the same way by both of their faces:
/// 4 inconsistent edges.
#[test]
fn klein_bottle_is_a_closed_non_orientable_shell() {
    let a = run(&shapes::klein(6, 4));
    assert_eq!(
        counts(&a),
        Counts {
            inconsistent_edges: 4,
            components: 1,
            shells: 1,
            ..clean(24, 72, 48)
        }
    );
    assert_eq!(a.holes(), 0);
    assert!(!a.orientable() && !a.oriented());
    assert_eq!(a.genus(), None);
    let c = &a.components[0];
    assert!(c.closed && c.manifold && !c.orientable);
    assert_eq!((c.euler, c.genus), (0, None));
    let s = &a.shells[0];
    assert!(!s.orientable && !s.oriented && !s.inside_out);
    assert_eq!((s.genus, s.volume), (None, None));
    assert_eq!(a.inside_out_shells(), 0);
    assert_volume(a.volume(), None);
}

/// [`shapes::projective_plane`] alone, then with a unit cube (outward) centred at `(0, 0, 4)`
/// inside its pyramid of walls (at height 4.5 the walls are over 4 from the axis; the cube reaches
/// 0.71). As stored, each side `p_i p_i+1` runs the same way in its wall and its star triangle, and
/// each diagonal `p_j p_j+2` the same way in both its star triangles: 10 inconsistent edges; the
/// walls' edges at the apex are consistent. A ray from the cube to far outside crosses the walls once, so by parity alone the cube
/// would lie inside the plane and be a cavity, wound the wrong way for one. But a non-orientable
/// shell has no inside: it bounds no solid, is neither solid nor cavity, has no volume and holds no
/// shell. So the cube is a solid at depth 0 with volume 1, not inside out; the mesh has 2 shells,
/// 1 solid, 0 cavities, volume 1.
#[test]
fn a_non_orientable_shell_is_neither_solid_nor_cavity_and_holds_no_shell() {
    let alone = run(&shapes::projective_plane());
    assert_eq!(
        counts(&alone),
        Counts {
            inconsistent_edges: 10,
            components: 1,
            shells: 1,
            ..clean(6, 15, 10)
        }
    );
    assert!(!alone.orientable());
    assert_eq!(alone.components[0].euler, 1);
    assert_shells(&alone, &[(0, Role::Neither, None)]);
    assert_eq!((alone.solids(), alone.cavities()), (0, 0));
    assert_volume(alone.volume(), None);

    let cube = cuboid([-0.5, -0.5, 3.5], [0.5, 0.5, 4.5]);
    let a = run(&merge(&[shapes::projective_plane(), cube]));
    assert_eq!((a.components.len(), a.shell_count()), (2, 2));
    assert_shells(&a, &[(0, Role::Neither, None), (0, Role::Solid, Some(1.0))]);
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (1, 0, 0));
    assert_volume(a.volume(), Some(1.0));
}

// ---------------------------------------------------------------------------------------------------
// Non-manifold configurations
// ---------------------------------------------------------------------------------------------------

/// Bowtie: triangles `0 1 2` and `0 3 4` touching only at vertex 0.
///
/// V 5, E 6, F 2; chi = 1. No edge is shared: two components (single triangles, each V 3 E 3 F 1,
/// chi 1, one hole, genus (2 - 1 - 1)/2 = 0, manifold on its own). The star of vertex 0 is two fans
/// not linked by an edge: 1 non-manifold vertex. 6 border edges, b = 2, genus 0 + 0 = 0.
#[test]
fn bowtie_has_one_nonmanifold_vertex() {
    let mesh = shapes::bowtie();
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 6,
            nonmanifold_vertices: 1,
            components: 2,
            ..clean(5, 6, 2)
        }
    );
    assert_eq!(a.holes(), 2);
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable() && a.oriented());
    for c in &a.components {
        assert!(c.manifold && !c.closed);
        assert_eq!(
            (c.faces, c.vertices, c.edges, c.euler, c.holes, c.genus),
            (1, 3, 3, 1, 1, Some(0))
        );
    }
}

/// The two tetrahedra touching at one vertex: the unit corner tetrahedron and its mirror image
/// through the origin (faces reversed to stay outward).
///
/// Input vertices 8, welded 7 (the origin is shared); E 12, F 8; chi = 7 - 12 + 8 = 3. No shared
/// edge: 2 components, each a manifold closed tetrahedron (its own faces make one fan at the origin),
/// so 2 shells of genus 0 and volume 1/6. The origin's star is two fans: 1 non-manifold vertex. No
/// vertex of either lies in the other's interior (the origin is on both surfaces): depths 0, 2 solids.
#[test]
fn tetrahedra_sharing_a_vertex_are_two_shells() {
    let mut mirror = flipped(&tetrahedron());
    mirror.positions.iter_mut().for_each(|p| *p = p.map(|x| -x));
    let a = run(&merge(&[tetrahedron(), mirror]));
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 8,
            nonmanifold_vertices: 1,
            components: 2,
            shells: 2,
            ..clean(7, 12, 8)
        }
    );
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable() && a.oriented());
    for c in &a.components {
        assert!(c.closed && c.manifold);
        assert_eq!((c.euler, c.genus), (2, Some(0)));
    }
    assert_shells(
        &a,
        &[
            (0, Role::Solid, Some(1.0 / 6.0)),
            (0, Role::Solid, Some(1.0 / 6.0)),
        ],
    );
    assert_eq!(a.inside_out_shells(), 0);
    assert_volume(a.volume(), Some(1.0 / 3.0));
}

/// Three triangles on edge 0-1: `0 1 2`, `1 0 3`, `0 1 4`.
///
/// V 5; E 7 (01 with valence 3, and 12 20 03 31 14 40 with valence 1); F 3; chi = 5 - 7 + 3 = 1.
/// 1 non-manifold edge, 6 border edges. Vertices 0 and 1 have the valence-3 edge in their star: 2
/// non-manifold vertices (2, 3 and 4 each bound one triangle). One component (linked through edge
/// 01), not manifold: genus undefined, no shell. No edge has valence 2, so none is inconsistent.
///
/// Holes (SPEC 7, loops of border edges on the undirected border): the border is three paths from 0
/// to 1, `0-2-1`, `0-3-1`, `0-4-1` (each fin's two border edges, joined at its apex by the swing
/// through the fin). At 0 and at 1 the swing around the vertex stops at the non-manifold edge 01 and
/// cannot pick a next border edge, so the three border ends meeting there are one loop: the 6 border
/// edges make 1 loop, b = 1.
#[test]
fn three_triangles_on_an_edge() {
    let mesh = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
        ],
        vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    );
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 6,
            nonmanifold_edges: 1,
            nonmanifold_vertices: 2,
            components: 1,
            ..clean(5, 7, 3)
        }
    );
    let c = &a.components[0];
    assert!(!c.manifold && !c.closed);
    assert_eq!((c.nonmanifold_edges, c.euler, c.genus), (1, 1, None));
    assert_eq!((c.border_edges, c.holes), (6, 1));
    assert_eq!(a.holes(), 1);
    assert_eq!(a.genus(), None);
    assert_volume(a.volume(), None);
}

/// Two copies of [`three_triangles_on_an_edge`] touching at vertex 0 only: `0 1 2`, `1 0 3`, `0 1 4`
/// around edge 0-1 and `0 5 6`, `5 0 7`, `0 5 8` around edge 0-5 (the second fin is the first
/// mirrored through the plane x = 0).
///
/// V 9 (vertex 0 shared), E 7 + 7 = 14, F 6, chi = 9 - 14 + 6 = 1. The fins share no edge: 2
/// components, each V 5 E 7 F 3, chi 1, 6 border edges, 1 loop as derived for one fin (b = 1), not
/// manifold (genus undefined). Mesh: 12 border edges, 2 non-manifold edges, non-manifold vertices 0,
/// 1 and 5; holes 1 + 1 = 2. At vertex 0 both fins' loops have border ends stopped by a non-manifold
/// edge; they belong to different components and are different loops.
#[test]
fn fins_touching_at_a_vertex_keep_a_hole_each() {
    let mesh = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
            [-1.0, 0.0, 0.0],
            [-0.5, 1.0, 0.0],
            [-0.5, -1.0, 0.0],
            [-0.5, 0.0, 1.0],
        ],
        vec![
            [0, 1, 2],
            [1, 0, 3],
            [0, 1, 4],
            [0, 5, 6],
            [5, 0, 7],
            [0, 5, 8],
        ],
    );
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 12,
            nonmanifold_edges: 2,
            nonmanifold_vertices: 3,
            components: 2,
            ..clean(9, 14, 6)
        }
    );
    for c in &a.components {
        assert!(!c.manifold && !c.closed);
        assert_eq!(
            (
                c.vertices,
                c.edges,
                c.faces,
                c.border_edges,
                c.holes,
                c.genus
            ),
            (5, 7, 3, 6, 1, None)
        );
    }
    assert_eq!(a.holes(), 2);
}

/// Two unit cubes sharing the edge from (1,1,0) to (1,1,1): `[0,1]^3` and `[1,2] x [1,2] x [0,1]`.
///
/// Input vertices 16, welded 14; E = 18 + 18 - 1 = 35 (the shared edge is a cube edge of both, not a
/// diagonal); F 24; chi = 14 - 35 + 24 = 3. The shared edge bounds 2 + 2 = 4 faces: 1 non-manifold
/// edge, no border. Its two endpoints have it in their star: 2 non-manifold vertices. One component
/// (linked through that edge), not manifold and not closed (an edge of valence 4): no shell, genus
/// undefined, no volume. Every valence-2 edge is consistent (both cubes outward): 0 inconsistent.
#[test]
fn cubes_sharing_an_edge() {
    let a = run(&merge(&[cube(), cuboid([1.0, 1.0, 0.0], [2.0, 2.0, 1.0])]));
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 16,
            nonmanifold_edges: 1,
            nonmanifold_vertices: 2,
            components: 1,
            ..clean(14, 35, 24)
        }
    );
    assert_eq!(a.holes(), 0);
    let c = &a.components[0];
    assert!(!c.manifold && !c.closed);
    assert_eq!((c.faces, c.edges, c.euler, c.genus), (24, 35, 3, None));
    assert_eq!(a.genus(), None);
    assert_volume(a.volume(), None);
}

/// A strip of four triangles whose two ends touch at vertex 0: `A = 0 1 2`, `2 1 4`, `2 4 3`,
/// `B = 0 3 4`.
///
/// V 5; E 9 (01 12 02 14 24 34 23 03 04); F 4; chi = 5 - 9 + 4 = 0. Edges 12, 24, 34 bound two faces,
/// the 6 others one. All faces are linked through edges: 1 component. Vertex 0's faces A and B share
/// no edge: two fans, 1 non-manifold vertex, so the component itself is not manifold (SPEC 7) and its
/// genus is undefined. Windings agree across 12, 24 and 34: 0 inconsistent.
///
/// Holes: the border edges are 01 and 02 (A), 14 (`2 1 4`), 23 (`2 4 3`), 03 and 04 (B). Following the
/// border with the swing, which at each vertex goes through one fan to the border edge on its other
/// side: 01, at 1 through A and `2 1 4` to 14, at 4 through `2 1 4`, `2 4 3`, B to 04, at 0 through B
/// to 03, at 3 through B and `2 4 3` to 23, at 2 through `2 4 3`, `2 1 4`, A to 02, at 0 through A
/// back to 01: one loop of all 6 border edges, passing vertex 0 twice. b = 1.
#[test]
fn strip_pinched_at_a_vertex_is_one_nonmanifold_component() {
    let mesh = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
        ],
        vec![[0, 1, 2], [2, 1, 4], [2, 4, 3], [0, 3, 4]],
    );
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 6,
            nonmanifold_vertices: 1,
            components: 1,
            ..clean(5, 9, 4)
        }
    );
    let c = &a.components[0];
    assert!(!c.manifold && !c.closed);
    assert_eq!((c.euler, c.genus), (0, None));
    assert_eq!((c.border_edges, c.holes), (6, 1));
    assert_eq!(a.holes(), 1);
    assert_eq!(a.genus(), None);
}

/// A capsule pinched shut: a tube of 4 vertices around and one ring of quads (8 triangles), both ends
/// closed by a cone of 4 triangles onto the same apex, vertex 8 on the axis (a sphere with its two
/// poles made one point).
///
/// V 9; E = 4 + 4 (rings) + 4 (up) + 4 (diagonals) + 4 + 4 (cone edges) = 24; F = 8 + 4 + 4 = 16;
/// chi = 9 - 24 + 16 = 1. Every edge bounds exactly 2 faces: closed, no border, no non-manifold edge.
/// The apex's faces are two fans (top cone, bottom cone) sharing no edge: 1 non-manifold vertex, so
/// the component is closed but not manifold: not a shell, genus undefined. Windings agree
/// everywhere: 0 inconsistent. Pinched only at a vertex, it still bounds a volume and counts as a
/// solid: the square prism (the 4 vertices on the unit circle span a square of area 2, height 1:
/// 2) less the two cones that dip into it to the apex at mid-height (base 2, height 1/2: 1/3
/// each), 4/3.
#[test]
fn capsule_pinched_at_its_poles_is_closed_but_not_a_shell() {
    let mut mesh = shapes::tube(4, 1);
    mesh.positions.push([0.0, 0.0, 0.5]);
    for j in 0..4u32 {
        let j1 = (j + 1) % 4;
        mesh.triangles.push([4 + j, 4 + j1, 8]);
        mesh.triangles.push([j1, j, 8]);
    }
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            nonmanifold_vertices: 1,
            components: 1,
            ..clean(9, 24, 16)
        }
    );
    assert_eq!(a.holes(), 0);
    let c = &a.components[0];
    assert!(c.closed && !c.manifold);
    assert_eq!((c.euler, c.genus), (1, None));
    assert_eq!(a.genus(), None);
    assert_eq!((a.solids(), a.inside_out_shells()), (1, 0));
    assert_volume(a.volume(), Some(4.0 / 3.0));
}

/// Holes are traced on the undirected border (SPEC 7): the 3 x 2 grid with its first triangle
/// `0 1 5` stored as `0 5 1`, so one border edge (0-1) now runs against the rest of its loop.
///
/// Counts as the grid (V 12, E 23, F 12, chi 1, 10 border edges in one loop: b = 1, genus 0). The
/// flipped triangle's interior edges 1-5 and 5-0 are now traversed the same way by both faces: 2
/// inconsistent edges (its border edge 0-1 is not a manifold edge). Orientable, not oriented.
#[test]
fn grid_with_a_flipped_corner_triangle_still_has_one_hole() {
    let mut mesh = shapes::grid(3, 2);
    assert_eq!(mesh.triangles[0], [0, 1, 5]);
    mesh.triangles[0] = [0, 5, 1];
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 10,
            inconsistent_edges: 2,
            components: 1,
            ..clean(12, 23, 12)
        }
    );
    assert_eq!(a.holes(), 1);
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable() && !a.oriented());
}

/// The open tube of 6 around and 2 rings up with every odd quad (both its triangles) flipped, so the
/// border edges of each end ring alternate direction.
///
/// V = 6 x 3 = 18; E = 6 x 3 (around) + 6 x 2 (up) + 6 x 2 (diagonals) = 42; F 24; chi 0; 12 border
/// edges in 2 loops: b = 2, genus 0. Each vertical edge lies between an odd and an even quad (6 is
/// even, so also across the seam): 6 x 2 = 12 inconsistent edges; diagonals and the middle ring lie
/// between faces flipped alike. Orientable, not oriented.
#[test]
fn tube_with_alternate_quads_flipped_still_has_two_holes() {
    let mut mesh = shapes::tube(6, 2);
    for (i, t) in mesh.triangles.iter_mut().enumerate() {
        if (i / 2) % 6 % 2 == 1 {
            *t = [t[0], t[2], t[1]];
        }
    }
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 12,
            inconsistent_edges: 12,
            components: 1,
            ..clean(18, 42, 24)
        }
    );
    assert_eq!(a.holes(), 2);
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable() && !a.oriented());
}

// ---------------------------------------------------------------------------------------------------
// Orientation, nesting, volume
// ---------------------------------------------------------------------------------------------------

/// The unit cube with one triangle (`0 2 3`) stored backwards.
///
/// Counts as the cube (V 8, E 18, F 12, chi 2). The flipped triangle's 3 edges are now traversed the
/// same way by both faces: 3 inconsistent edges. Flipping it back orients everything: orientable, not
/// oriented. Still a shell (closed, manifold); its volume is taken with the majority winding (11
/// outward faces): +1. Not oriented, so not inside-out.
#[test]
fn cube_with_one_flipped_triangle() {
    let mut mesh = cube();
    mesh.triangles[0] = [0, 3, 2];
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            inconsistent_edges: 3,
            components: 1,
            shells: 1,
            ..clean(8, 18, 12)
        }
    );
    assert!(a.orientable());
    assert!(!a.oriented());
    assert_eq!(a.genus(), Some(0));
    let s = &a.shells[0];
    assert!(s.orientable && !s.oriented && !s.inside_out);
    assert_eq!(a.inside_out_shells(), 0);
    assert_shells(&a, &[(0, Role::Solid, Some(1.0))]);
    assert_volume(a.volume(), Some(1.0));
}

/// The unit cube with the triangles of three of its sides reversed: a tie, 6 of 12 faces each way.
fn cube_with_half_reversed(sides: [usize; 3]) -> Mesh {
    let mut mesh = cube();
    for side in sides {
        for t in [2 * side, 2 * side + 1] {
            let [a, b, c] = mesh.triangles[t];
            mesh.triangles[t] = [a, c, b];
        }
    }
    mesh
}

/// The sides (pairs of [`BOX_TRIANGLES`]) meeting at corner (0,0,0): z = 0, y = 0, x = 0.
const LOW_SIDES: [usize; 3] = [0, 2, 4];
/// The sides meeting at corner (1,1,1): z = 1, y = 1, x = 1.
const HIGH_SIDES: [usize; 3] = [1, 3, 5];

/// The unit cube with the 6 triangles of its three sides at (0,0,0) reversed, and the same with the
/// three sides at (1,1,1) reversed: exactly half of the faces each way, so neither winding is the
/// majority's and the volume takes the tie-break winding (SPEC 8 needs a consistent winding; the
/// choice must not depend on how vertices are numbered).
///
/// Counts as the cube (V 8, E 18, F 12, chi 2, genus 0, a shell). Reversing both faces of a pair of
/// adjacent sides keeps their shared edge consistent; the edges between a reversed and a kept side
/// are the 6 cube edges of the hexagon between the two corners (for the low corner: 2-3, 1-3, 4-5,
/// 1-5, 4-6, 2-6 in [`BOX_TRIANGLES`]' numbering): 6 inconsistent edges. Orientable, not oriented,
/// so never inside out.
///
/// Tie-break: the winding of the face whose vertex positions, sorted (x, then y, then z), come first.
/// Every face on (0,0,0) starts with it; the next positions in that order are (0,0,1) (faces `0 5 4`
/// and `0 4 6`) and then (0,1,1) < (1,0,1): face `0 4 6`, on the x = 0 side. With the low sides
/// reversed it looks into the cube: volume -1; with the high sides reversed it is as stored: +1.
/// Relabelling vertices, permuting faces or rotating corners changes neither (the mesh volume, by
/// role, is 1 in both).
#[test]
fn cube_with_half_its_faces_reversed_takes_a_tie_break_no_numbering_decides() {
    for (sides, expected) in [(LOW_SIDES, -1.0), (HIGH_SIDES, 1.0)] {
        let mesh = cube_with_half_reversed(sides);
        let a = run(&mesh);
        assert_eq!(
            counts(&a),
            Counts {
                inconsistent_edges: 6,
                components: 1,
                shells: 1,
                ..clean(8, 18, 12)
            }
        );
        assert!(a.orientable() && !a.oriented());
        assert_shells(&a, &[(0, Role::Solid, Some(expected))]);
        assert_eq!(a.inside_out_shells(), 0);
        assert_volume(a.volume(), Some(1.0));
        let mut rng = XorShift::new(7);
        for round in 0..32 {
            let moved = match round % 3 {
                0 => relabel_vertices(&mesh, &mut rng),
                1 => permute_faces(&relabel_vertices(&mesh, &mut rng), &mut rng),
                _ => rotate_corners(&relabel_vertices(&mesh, &mut rng), &mut rng),
            };
            let b = run(&moved);
            assert_volume(b.shells[0].volume, Some(expected));
        }
    }
}

/// The unit cube with every face reversed: oriented (all edges consistent), raw volume -1 at depth 0
/// (a solid needs +): 1 inside-out shell. The mesh volume takes each shell with its role's sign
/// (SPEC 8): |-1| = +1.
#[test]
fn inside_out_cube() {
    let a = run(&flipped(&cube()));
    assert_eq!(
        counts(&a),
        Counts {
            components: 1,
            shells: 1,
            ..clean(8, 18, 12)
        }
    );
    assert!(a.orientable() && a.oriented());
    assert_eq!(a.inside_out_shells(), 1);
    assert!(a.shells[0].inside_out);
    assert_shells(&a, &[(0, Role::Solid, Some(-1.0))]);
    assert_volume(a.volume(), Some(1.0));
}

/// A 2 x 2 x 2 cube `[0,2]^3` (outward) with a unit cavity `[0.5,1.5]^3` whose faces look into the
/// void (reversed).
///
/// V 16, E 36, F 24, chi 4; 2 components, 2 shells of genus 0. The cavity's vertices lie inside the
/// big cube: depths 0 and 1, solid and cavity. Raw volumes +8 and -1, both right for their role:
/// 0 inside-out. Mesh volume 8 - 1 = 7.
#[test]
fn cube_with_inward_cavity() {
    let a = run(&merge(&[cube_at(0.0, 2.0), flipped(&cube_at(0.5, 1.0))]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 2,
            shells: 2,
            ..clean(16, 36, 24)
        }
    );
    assert_eq!(a.genus(), Some(0));
    assert!(a.orientable() && a.oriented());
    assert_shells(
        &a,
        &[(0, Role::Solid, Some(8.0)), (1, Role::Cavity, Some(-1.0))],
    );
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (1, 1, 0));
    assert_volume(a.volume(), Some(7.0));
}

/// As [`cube_with_inward_cavity`] but the cavity's faces look out of the void (into the material):
/// raw volume +1 at depth 1, where a cavity needs -: 1 inside-out shell. The mesh volume takes the
/// cavity with its role's sign: 8 - |+1| = 7.
#[test]
fn cube_with_outward_cavity_is_inside_out() {
    let a = run(&merge(&[cube_at(0.0, 2.0), cube_at(0.5, 1.0)]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 2,
            shells: 2,
            ..clean(16, 36, 24)
        }
    );
    assert!(a.oriented());
    assert_shells(
        &a,
        &[(0, Role::Solid, Some(8.0)), (1, Role::Cavity, Some(1.0))],
    );
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (1, 1, 1));
    assert!(!a.shells[0].inside_out && a.shells[1].inside_out);
    assert_volume(a.volume(), Some(7.0));
}

/// Nesting does not depend on the order of the shells: the cavity listed first is still at depth 1.
#[test]
fn cavity_listed_first_is_still_a_cavity() {
    let a = run(&merge(&[flipped(&cube_at(0.5, 1.0)), cube_at(0.0, 2.0)]));
    assert_shells(
        &a,
        &[(1, Role::Cavity, Some(-1.0)), (0, Role::Solid, Some(8.0))],
    );
    assert_eq!(a.inside_out_shells(), 0);
    assert_volume(a.volume(), Some(7.0));
}

/// A cavity that touches its solid at 16 vertices and reaches inside it through one. The solid: a
/// bipyramid over a convex ring of 32 integer points at z = 0 (`(k, k^2)` for k = -8..8, then
/// `(k, 128 - k^2)` for k = 7..-7, counterclockwise), apexes `(0, 64, +-64)`, outward. The cavity:
/// a pyramid over every second ring point (a convex 16-gon inside the ring, whose sides are chords,
/// not edges of the solid) with apex `(0, 64, 32)`, wound inward. The two share the 16 points and
/// nothing else (the 16-gon's plane cuts the solid's inside; its sides touch the ring only at its
/// corners), so no faces meet. Every vertex of the cavity lies on the solid's surface but the apex,
/// strictly inside: the cavity is at depth 1, wound as a cavity must be, not inside out. Volumes: a
/// pyramid is a third of base area times height, so the solid encloses `2/3 * 64 * area(ring)`
/// and the cavity `1/3 * 32 * area(16-gon)` (areas by the shoelace formula); the mesh encloses
/// their difference.
#[test]
fn a_cavity_touching_its_solid_at_many_vertices_is_still_a_cavity() {
    let ring: Vec<[f64; 2]> = (-8..=8)
        .map(|k: i32| [f64::from(k), f64::from(k * k)])
        .chain(
            (-7..=7)
                .rev()
                .map(|k: i32| [f64::from(k), f64::from(128 - k * k)]),
        )
        .collect();
    assert_eq!(ring.len(), 32);
    let shoelace = |p: &[[f64; 2]]| {
        let n = p.len();
        (0..n)
            .map(|i| p[i][0] * p[(i + 1) % n][1] - p[(i + 1) % n][0] * p[i][1])
            .sum::<f64>()
            .abs()
            / 2.0
    };
    let mut positions: Vec<[f64; 3]> = ring.iter().map(|&[x, y]| [x, y, 0.0]).collect();
    positions.extend([[0.0, 64.0, 64.0], [0.0, 64.0, -64.0], [0.0, 64.0, 32.0]]);
    let (top, bottom, apex) = (32u32, 33u32, 34u32);
    let mut triangles = Vec::new();
    for j in 0..32u32 {
        triangles.push([top, j, (j + 1) % 32]);
        triangles.push([bottom, (j + 1) % 32, j]);
    }
    let corners: Vec<u32> = (0..32).step_by(2).collect();
    // Inward: the base's fan looks up into the pyramid, the sides look in.
    for i in 1..15 {
        triangles.push([corners[0], corners[i], corners[i + 1]]);
    }
    for i in 0..16 {
        triangles.push([apex, corners[(i + 1) % 16], corners[i]]);
    }
    let a = run(&Mesh::new(positions, triangles));
    let solid = 2.0 / 3.0 * 64.0 * shoelace(&ring);
    let hexadecagon: Vec<[f64; 2]> = corners.iter().map(|&i| ring[i as usize]).collect();
    let cavity = 32.0 / 3.0 * shoelace(&hexadecagon);
    assert_eq!((a.components.len(), a.shell_count()), (2, 2));
    assert_eq!(a.self_intersections(), Some(0));
    assert_eq!(a.intersecting_components(), Some(0));
    assert_shells(
        &a,
        &[
            (0, Role::Solid, Some(solid)),
            (1, Role::Cavity, Some(-cavity)),
        ],
    );
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (1, 1, 0));
    assert_volume(a.volume(), Some(solid - cavity));
}

/// Three nested cubes `[0,6]^3` (out), `[1,5]^3` (in), `[2,4]^3` (out).
///
/// V 24, E 54, F 36, chi 6; 3 components and shells. Each lies inside all bigger ones: depths 0, 1,
/// 2; roles solid, cavity, solid. Raw volumes 216, -64, +8, all right for their roles: 0 inside-out.
/// Mesh volume 216 - 64 + 8 = 160.
#[test]
fn three_nested_cubes() {
    let a = run(&merge(&[
        cube_at(0.0, 6.0),
        flipped(&cube_at(1.0, 4.0)),
        cube_at(2.0, 2.0),
    ]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 3,
            shells: 3,
            ..clean(24, 54, 36)
        }
    );
    assert_shells(
        &a,
        &[
            (0, Role::Solid, Some(216.0)),
            (1, Role::Cavity, Some(-64.0)),
            (2, Role::Solid, Some(8.0)),
        ],
    );
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (2, 1, 0));
    assert_eq!(a.genus(), Some(0));
    assert_volume(a.volume(), Some(160.0));
}

/// Two disjoint unit cubes, `[0,1]^3` and `[2,3]^3`: V 16, E 36, F 24, chi 4; 2 components, 2 solids
/// at depth 0 (neither contains a vertex of the other); volume 2.
#[test]
fn two_disjoint_cubes() {
    let a = run(&merge(&[cube(), cube_at(2.0, 1.0)]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 2,
            shells: 2,
            ..clean(16, 36, 24)
        }
    );
    assert_outward_spheres(&a, 2);
    assert_shells(
        &a,
        &[(0, Role::Solid, Some(1.0)), (0, Role::Solid, Some(1.0))],
    );
    assert_eq!(
        a.shells.iter().map(|s| s.component).collect::<Vec<_>>(),
        vec![0, 1]
    );
    assert_volume(a.volume(), Some(2.0));
}

/// Two unit cavities side by side in `[0,4]^3`: `[0.5,1.5]^3` and `[2.5,3.5]^3`, both facing the
/// void. V 24, E 54, F 36, chi 6. Each cavity lies in the big cube and not in the other cavity:
/// depths 0, 1, 1. Volume 64 - 1 - 1 = 62.
#[test]
fn sibling_cavities() {
    let a = run(&merge(&[
        cube_at(0.0, 4.0),
        flipped(&cube_at(0.5, 1.0)),
        flipped(&cube_at(2.5, 1.0)),
    ]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 3,
            shells: 3,
            ..clean(24, 54, 36)
        }
    );
    assert_shells(
        &a,
        &[
            (0, Role::Solid, Some(64.0)),
            (1, Role::Cavity, Some(-1.0)),
            (1, Role::Cavity, Some(-1.0)),
        ],
    );
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (1, 2, 0));
    assert_volume(a.volume(), Some(62.0));
}

/// A cube in the hole of the square frame (`plate(3, 3, [(1,1)])`, material `[0,3]^2 x [0,1]` minus
/// the hole `[1,2]^2 x [0,1]`): `[1.25,1.75]^2 x [0.25,0.75]` lies within the frame's bounding box but
/// outside its solid, so both are at depth 0 and both are solids. V 32 + 8, E 96 + 18, F 64 + 12,
/// chi = 0 + 2; genus 1 + 0 = 1; volume 8 + 0.125.
#[test]
fn cube_in_the_hole_of_a_frame_is_not_nested() {
    let a = run(&merge(&[
        shapes::plate(3, 3, &[(1, 1)]),
        cuboid([1.25, 1.25, 0.25], [1.75, 1.75, 0.75]),
    ]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 2,
            shells: 2,
            ..clean(40, 114, 76)
        }
    );
    assert_eq!(a.genus(), Some(1));
    assert_shells(
        &a,
        &[(0, Role::Solid, Some(8.0)), (0, Role::Solid, Some(0.125))],
    );
    assert_volume(a.volume(), Some(8.125));
}

/// A cavity in the material of the square frame: `[0.25,0.75]^3` (facing the void) lies inside
/// cell (0,0) of the frame: depths 0 and 1. Counts as [`cube_in_the_hole_of_a_frame_is_not_nested`];
/// volume 8 - 0.125.
#[test]
fn cavity_in_the_material_of_a_frame() {
    let a = run(&merge(&[
        shapes::plate(3, 3, &[(1, 1)]),
        flipped(&cuboid([0.25; 3], [0.75; 3])),
    ]));
    assert_eq!(
        counts(&a),
        Counts {
            components: 2,
            shells: 2,
            ..clean(40, 114, 76)
        }
    );
    assert_shells(
        &a,
        &[(0, Role::Solid, Some(8.0)), (1, Role::Cavity, Some(-0.125))],
    );
    assert_eq!(a.inside_out_shells(), 0);
    assert_volume(a.volume(), Some(7.875));
}

/// A tetrahedral cavity touching the outer surface at one point: `[0,2]^3` (outward) and the
/// tetrahedron `O = (0,0,0)`, `A = (1,.5,.5)`, `B = (.5,1,.5)`, `C = (.5,.5,1)` facing the void.
///
/// det(A, B, C) = 1(1 - .25) - .5(.5 - .25) + .5(.25 - .5) = 0.5, so its volume is 0.5/6 = 1/12.
/// Input vertices 12, welded 11 (O is the cube's corner); E 18 + 6 = 24; F 12 + 4 = 16;
/// chi = 11 - 24 + 16 = 3. No shared edge: 2 components, each manifold on its own: 2 shells. O's
/// faces are two fans: 1 non-manifold vertex. A, B, C are strictly inside the cube (O is on its
/// surface, so not "inside"): depth 1, a cavity; the cube's other corners are outside the tetrahedron:
/// depth 0. Volume 8 - 1/12.
#[test]
fn cavity_touching_the_outer_surface_at_a_vertex() {
    let mut cavity = flipped(&tetrahedron());
    cavity.positions = vec![[0.0; 3], [1.0, 0.5, 0.5], [0.5, 1.0, 0.5], [0.5, 0.5, 1.0]];
    let a = run(&merge(&[cube_at(0.0, 2.0), cavity]));
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 12,
            nonmanifold_vertices: 1,
            components: 2,
            shells: 2,
            ..clean(11, 24, 16)
        }
    );
    assert_eq!(a.genus(), Some(0));
    assert_shells(
        &a,
        &[
            (0, Role::Solid, Some(8.0)),
            (1, Role::Cavity, Some(-1.0 / 12.0)),
        ],
    );
    assert_eq!(a.inside_out_shells(), 0);
    assert_volume(a.volume(), Some(8.0 - 1.0 / 12.0));
}

/// A small cube far from the origin next to a big one far away on the other side: `[lo, hi]^3` with
/// `lo = 1e7 + 0.1` and `hi = lo + 0.7` (both rounded: neither is a dyadic number), and
/// `[-1e9, -1e9 + 10]^3`.
///
/// The small cube's side as stored is `s = hi - lo`, exact in f64 (Sterbenz: `hi / 2 <= lo <= hi`),
/// so its volume is `s^3` (about 0.343). The big cube's is 1000. Both depth 0, solids, volume sum.
/// SPEC 8 takes P as the mean of each shell's own vertices, so the small cube's terms
/// `mp(A-P, B-P, C-P)` are of the size of its own volume; an apex between the two cubes (such as the
/// centre of the mesh's bounding box, near -5e8) makes each term about 5e8 x 0.49 and the rounding
/// of their sum (ulp(5e8) is 6e-8) is far above the 1e-9 tolerance.
#[test]
fn cube_far_from_the_origin_keeps_its_volume() {
    let lo = 1e7 + 0.1;
    let hi = lo + 0.7;
    let side = hi - lo;
    let a = run(&merge(&[
        cuboid([lo; 3], [hi; 3]),
        cuboid([-1e9; 3], [-1e9 + 10.0; 3]),
    ]));
    assert_shells(
        &a,
        &[
            (0, Role::Solid, Some(side * side * side)),
            (0, Role::Solid, Some(1000.0)),
        ],
    );
    assert_eq!(a.inside_out_shells(), 0);
    assert_volume(a.volume(), Some(side * side * side + 1000.0));
}

/// 2,000 unit cubes `[0,1] x [0,1] x [2i, 2i+1]` lined up along z (equal x and y ranges, so a
/// nesting sweep along x alone prunes nothing). Each is V 8 E 18 F 12 chi 2, disjoint from the
/// others: 2,000 components and shells, all at depth 0, all solids, volume 2,000.
///
/// Then the same cubes reversed inside one box `[-1,2] x [-1,2] x [-1,4000]` (outward): every small
/// cube's vertices are strictly inside the box and outside every other cube: the box at depth 0, the
/// cubes at depth 1 (cavities, raw volume -1, right for a cavity). Volume 3 x 3 x 4001 - 2,000 =
/// 34,009.
#[test]
fn cubes_lined_up_along_z_nest_correctly() {
    let cubes: Vec<Mesh> = (0..2000)
        .map(|i| {
            let z = 2.0 * i as f64;
            cuboid([0.0, 0.0, z], [1.0, 1.0, z + 1.0])
        })
        .collect();
    let a = run(&merge(&cubes));
    assert_eq!(
        counts(&a),
        Counts {
            components: 2000,
            shells: 2000,
            ..clean(16_000, 36_000, 24_000)
        }
    );
    assert!(a
        .shells
        .iter()
        .all(|s| s.depth == 0 && s.role == Role::Solid));
    assert_eq!(
        (a.solids(), a.cavities(), a.inside_out_shells()),
        (2000, 0, 0)
    );
    assert_volume(a.volume(), Some(2000.0));

    let mut parts: Vec<Mesh> = cubes.iter().map(flipped).collect();
    parts.push(cuboid([-1.0, -1.0, -1.0], [2.0, 2.0, 4000.0]));
    let a = run(&merge(&parts));
    assert_eq!((a.shells.len(), a.solids(), a.cavities()), (2001, 1, 2000));
    let big = a.shells.last().expect("the box");
    assert_eq!((big.depth, big.role), (0, Role::Solid));
    assert!(a.shells[..2000]
        .iter()
        .all(|s| s.depth == 1 && s.role == Role::Cavity && !s.inside_out));
    assert_volume(a.volume(), Some(9.0 * 4001.0 - 2000.0));
}

/// A hexagonal pyramid cavity standing on the floor of `[0,4]^3` (outward): base `(1,2) (1.5,1)
/// (2.5,1) (3,2) (2.5,3) (1.5,3)` on z = 0, apex `(2,2,1)`, faces looking into the void. Its four base
/// triangles are listed first and all start at its lowest vertex `(1,2,0)`, so its first faces, in
/// any order the analysis walks them, use only the six base vertices, all on the cube's floor. Only
/// the apex is strictly inside the cube: containment must try distinct vertices until it reaches it.
///
/// V 8 + 7 = 15; E 18 + (6 base edges + 3 base diagonals + 6 slant edges) = 33; F 12 + 4 + 6 = 22;
/// chi = 15 - 33 + 22 = 4. 2 components, 2 shells of genus 0. Pyramid: base area = the rectangle
/// `[1.5,2.5] x [1,3]` (2) plus two triangles of base 2 and height 0.5 (0.5 each) = 3; volume
/// 3 x 1 / 3 = 1, raw -1 (facing the void). Nesting alone (no search for faces that meet): the
/// cube at depth 0, the pyramid at depth 1: volume 64 - 1 = 63.
///
/// With the search, the pyramid's base lies on the cube's floor: their faces touch, 1 pair of
/// components meets, so the pyramid has no depth against the cube. On its own it must enclose
/// positive volume, and facing the void it does not: a depth-0 solid, inside out (volume 64 + 1).
#[test]
fn cavity_whose_first_faces_lie_on_the_outer_surface() {
    let base = [
        [1.0, 2.0, 0.0],
        [1.5, 1.0, 0.0],
        [2.5, 1.0, 0.0],
        [3.0, 2.0, 0.0],
        [2.5, 3.0, 0.0],
        [1.5, 3.0, 0.0],
    ];
    let mut positions = base.to_vec();
    positions.push([2.0, 2.0, 1.0]);
    // Outward: the base seen from below, the sides counterclockwise from outside.
    let mut triangles: Vec<[u32; 3]> = (1..5).map(|i| [0, i + 1, i]).collect();
    triangles.extend((0..6).map(|i| [i, (i + 1) % 6, 6]));
    let pyramid = Mesh::new(positions, triangles);
    let mesh = merge(&[cube_at(0.0, 4.0), flipped(&pyramid)]);
    let nesting_alone = Options {
        intersections: None,
        ..Options::default()
    };
    let a = analyse(&mesh, &nesting_alone);
    assert_eq!(
        counts(&a),
        Counts {
            components: 2,
            shells: 2,
            ..clean(15, 33, 22)
        }
    );
    assert_shells(
        &a,
        &[(0, Role::Solid, Some(64.0)), (1, Role::Cavity, Some(-1.0))],
    );
    assert_eq!(a.inside_out_shells(), 0);
    assert_volume(a.volume(), Some(63.0));

    let a = run(&mesh);
    assert_eq!(a.intersecting_components(), Some(1));
    assert_shells(
        &a,
        &[(0, Role::Solid, Some(64.0)), (0, Role::Solid, Some(-1.0))],
    );
    assert_eq!(a.inside_out_shells(), 1);
    assert_volume(a.volume(), Some(65.0));
}

/// The first segment direction of the point-in-solid test, `(1, 1.234567891e-4, 2.718281828e-4)`,
/// and its length `2 x (largest side of the outer box) + 1` (see `nesting.rs`).
const FIRST_DIRECTION: [f64; 3] = [1.0, 1.234_567_891e-4, 2.718_281_828e-4];

/// A tetrahedral cavity whose lowest vertex is the origin, inside a box built so that the first
/// segment from the origin leaves the box exactly through one of its edges, or exactly through one of
/// its corners.
///
/// The box spans x in `[-1.75, 2.25]` and z in `[-2, 2]` (sides 4, the largest), so the segment is
/// 9 long and ends at `F = (9, fy, fz)` with `fy = 9 x 1.234567891e-4` and `fz = 9 x 2.718281828e-4`
/// (rounded as the test rounds them). Its point at x = 2.25 = 9 / 4 is exactly `(2.25, fy/4, fz/4)`
/// (quartering is exact). With the box's top y at `Y = fy / 4` (y in `[Y - 2, Y]`), that point is on
/// the vertical edge x = 2.25, y = Y; with also its top z at `fz / 4` (z in `[Z - 2, Z]`, x still
/// the largest side), it is the corner. The exact predicates see the segment meet that edge or
/// vertex: the parity there would be a guess, so another direction must be taken.
///
/// The cavity `(0,0,0) (1,-1,-1+dz) (1,-1.5,dz) (1,-0.5,dz)` (dz = 0.5 for the edge case, 0 for the
/// corner case) lies strictly inside the box: every vertex has x in [0, 1], y in [-1.5, 0] (and
/// 0 < Y), z in [-1, dz] (and dz < Z; -1 > Z - 2). Its lowest vertex by (x, y, z) is the origin, the
/// one tested first. Its volume: base triangle at x = 1 with a side of 1 (along y) and height 1
/// (along z): area 1/2, apex distance 1: 1/6; raw -1/6 facing the void. Box at depth 0,
/// tetrahedron at depth 1; volume 4 x 2 x 4 - 1/6 (the box's y and z sides are 2 up to the rounding
/// of `Y - 2`, far below the tolerance).
#[test]
fn first_segment_through_an_edge_or_a_corner_of_the_outer_box() {
    let reach = 9.0;
    let fy = reach * FIRST_DIRECTION[1];
    let fz = reach * FIRST_DIRECTION[2];
    for corner in [false, true] {
        let y_hi = fy / 4.0;
        let (z_lo, z_hi) = if corner {
            (fz / 4.0 - 2.0, fz / 4.0)
        } else {
            (-2.0, 2.0)
        };
        let dz = if corner { 0.0 } else { 0.5 };
        let outer = cuboid([-1.75, y_hi - 2.0, z_lo], [2.25, y_hi, z_hi]);
        // Outward: the base (x = 1) seen from +x, and the three faces on the apex.
        let tetra = Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, -1.0, -1.0 + dz],
                [1.0, -1.5, dz],
                [1.0, -0.5, dz],
            ],
            vec![[1, 3, 2], [0, 3, 1], [0, 2, 3], [0, 1, 2]],
        );
        let a = run(&merge(&[outer, flipped(&tetra)]));
        let box_volume = 4.0 * (y_hi - (y_hi - 2.0)) * (z_hi - z_lo);
        assert_shells(
            &a,
            &[
                (0, Role::Solid, Some(box_volume)),
                (1, Role::Cavity, Some(-1.0 / 6.0)),
            ],
        );
        assert_eq!(a.inside_out_shells(), 0, "corner: {corner}");
        assert_volume(a.volume(), Some(box_volume - 1.0 / 6.0));
    }
}

// ---------------------------------------------------------------------------------------------------
// Degenerate, duplicate, unreferenced and invalid input
// ---------------------------------------------------------------------------------------------------

/// The cube's triangle soup with every input vertex `k` moved by `(k + 1) x 1e-9` on each axis, so no
/// two positions are equal.
fn jittered_cube_soup() -> Mesh {
    let mut mesh = soup(&cube());
    for (k, p) in mesh.positions.iter_mut().enumerate() {
        *p = p.map(|x| x + (k + 1) as f64 * 1e-9);
    }
    mesh
}

/// Exact welding keeps the jittered soup apart: 36 welded vertices, 12 separate triangles (each V 3
/// E 3 F 1, chi 1, one hole, genus 0): E 36, border 36, chi = 36 - 36 + 12 = 12, 12 holes, no shell.
#[test]
fn exact_welding_keeps_jittered_soup_apart() {
    let a = run(&jittered_cube_soup());
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 36,
            components: 12,
            ..clean(36, 36, 12)
        }
    );
    assert_eq!(a.holes(), 12);
    assert_eq!(a.genus(), Some(0));
}

/// With a tolerance of 1e-4 the copies of each corner (at most 36e-9 x sqrt 3 apart; corners are 1
/// apart) weld into one: the cube again (welded 8, E 18, F 12, chi 2), volume 1 up to the jitter.
#[test]
fn tolerance_welds_jittered_soup_into_the_cube() {
    let a = analyse(
        &jittered_cube_soup(),
        &Options {
            weld_tolerance: 1e-4,
            ..Options::default()
        },
    );
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 36,
            components: 1,
            shells: 1,
            ..clean(8, 18, 12)
        }
    );
    assert_outward_spheres(&a, 1);
    let v = a.volume().expect("a shell");
    assert!((v - 1.0).abs() < 1e-6, "volume {v}");
}

/// The tetrahedron's counts after the extra faces and vertices a test adds are left out.
fn tetrahedron_table() -> Counts {
    Counts {
        components: 1,
        shells: 1,
        ..clean(4, 6, 4)
    }
}

/// The tetrahedron plus a face `0 0 1` with a repeated index: faces 5, 1 degenerate, left out of the
/// table; everything else is the tetrahedron (E 6, chi 2, one solid of volume 1/6).
#[test]
fn face_with_repeated_index_is_degenerate() {
    let mut mesh = tetrahedron();
    mesh.triangles.push([0, 0, 1]);
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            faces: 5,
            degenerate_faces: 1,
            ..tetrahedron_table()
        }
    );
    assert_outward_spheres(&a, 1);
    assert_volume(a.volume(), Some(1.0 / 6.0));
}

/// The tetrahedron plus input vertex 4 at the origin (vertex 0's position) and a face `4 0 1`: after
/// welding it is `0 0 1`, degenerate. Input vertices 5, welded 4 (vertex 4 is vertex 0, which faces
/// use: not unreferenced); faces 5, 1 degenerate; the table is the tetrahedron's.
#[test]
fn face_degenerate_after_welding() {
    let mut mesh = tetrahedron();
    mesh.positions.push([0.0, 0.0, 0.0]);
    mesh.triangles.push([4, 0, 1]);
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 5,
            faces: 5,
            degenerate_faces: 1,
            ..tetrahedron_table()
        }
    );
    assert_outward_spheres(&a, 1);
}

/// `-0.0` welds to `0.0` (SPEC 3): the tetrahedron with vertex 0 repeated as input vertex 4 at
/// `(-0, -0, -0)`, and face `0 1 3` stored as `4 1 3`, is still the tetrahedron (vertices 5, welded 4).
#[test]
fn negative_zero_welds_to_zero() {
    let mut mesh = tetrahedron();
    mesh.positions.push([-0.0, -0.0, -0.0]);
    mesh.triangles[1] = [4, 1, 3];
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 5,
            ..tetrahedron_table()
        }
    );
    assert_outward_spheres(&a, 1);
}

/// The tetrahedron plus a separate triangle on three distinct collinear points `(2,0,0) (3,0,0)
/// (4,0,0)`: its area is 0 (at most 1e-12 x diagonal^2): 1 zero-area face, kept.
///
/// V 7, E 9, F 5, chi = 7 - 9 + 5 = 3; 2 components; the thin triangle is V 3 E 3 F 1, chi 1, one
/// hole of 3 border edges, genus 0. One shell (the tetrahedron), volume 1/6.
#[test]
fn zero_area_face_is_counted_and_kept() {
    let mut mesh = tetrahedron();
    mesh.positions
        .extend([[2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [4.0, 0.0, 0.0]]);
    mesh.triangles.push([4, 5, 6]);
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            zero_area_faces: 1,
            border_edges: 3,
            components: 2,
            shells: 1,
            ..clean(7, 9, 5)
        }
    );
    assert_eq!(a.holes(), 1);
    assert_eq!(a.genus(), Some(0));
    assert_volume(a.volume(), Some(1.0 / 6.0));
}

/// The tetrahedron plus two separate right triangles in its box `[0,1]^3`, legs 0.8 along x and
/// h along y (area 0.4 h): h = 7.4e-12 (area 2.96e-12) at z = 0.5, h = 7.6e-12 (3.04e-12) at
/// z = 0.25.
fn tetrahedron_and_thin_triangles() -> Mesh {
    let mut mesh = tetrahedron();
    for (h, z) in [(7.4e-12, 0.5), (7.6e-12, 0.25)] {
        let base = mesh.positions.len() as u32;
        mesh.positions
            .extend([[0.1, 0.0, z], [0.9, 0.0, z], [0.1, h, z]]);
        mesh.triangles.push([base, base + 1, base + 2]);
    }
    mesh
}

/// SPEC 4's threshold, area <= 1e-12 x (bounding-box diagonal)^2, with 1% to spare either way: the
/// tetrahedron (box `[0,1]^3`, diagonal^2 = 3, threshold 3e-12) plus two separate right triangles in
/// that box, legs 0.8 along x and h along y, area 0.4 h: h = 7.4e-12 gives 2.96e-12 (zero-area),
/// h = 7.6e-12 gives 3.04e-12 (not). A factor off by 2 (area against |cross|), or the diagonal not
/// squared (threshold 1.7e-12), counts 0 or 2.
///
/// V 4 + 6 = 10, E 6 + 6 = 12, F 6, chi = 10 - 12 + 6 = 4; 3 components (the thin triangles each V 3
/// E 3 F 1, one hole, genus 0); 6 border edges; one shell, volume 1/6.
#[test]
fn zero_area_threshold_is_1e_12_diagonal_squared() {
    let mesh = tetrahedron_and_thin_triangles();
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            zero_area_faces: 1,
            border_edges: 6,
            components: 3,
            shells: 1,
            ..clean(10, 12, 6)
        }
    );
    assert_eq!(a.holes(), 2);
    assert_volume(a.volume(), Some(1.0 / 6.0));
}

/// The threshold test above with every coordinate times 2^k, k = -900, -600, 600, 900 (1e-271 to
/// 1e271): scaling by a power of two is exact, and the threshold is a ratio of areas, so the counts
/// are the same. Fourth powers of lengths at these scales overflow or underflow; before the test
/// measured faces in scaled coordinates, every face was zero-area at 1e200 and at 1e-300.
#[test]
fn zero_area_threshold_holds_at_every_scale() {
    let mesh = tetrahedron_and_thin_triangles();
    for k in [-900, -600, 600, 900] {
        let mut scaled = mesh.clone();
        for p in &mut scaled.positions {
            *p = p.map(|x| x * 2f64.powi(k));
        }
        let a = run(&scaled);
        assert_eq!(
            counts(&a),
            Counts {
                zero_area_faces: 1,
                border_edges: 6,
                components: 3,
                shells: 1,
                ..clean(10, 12, 6)
            },
            "2^{k}"
        );
        assert_eq!(a.holes(), 2, "2^{k}");
    }
}

/// A closed cube `[10,11]^3` next to the Moebius strip of [`moebius_strip_is_not_orientable`] (within
/// radius 2.5 of the origin, so no position is shared): V 8 + 10 = 18, E 18 + 20 = 38, F 12 + 10 = 22,
/// chi = 2 + 0 = 2; 2 components; the strip's 10 border edges make 1 hole; its rung 0 is the 1
/// inconsistent edge. The cube's genus is 0, the strip's undefined (not orientable), so the mesh's
/// genus, a sum "where all are defined" (SPEC 7), is undefined. One shell (the cube), volume 1.
#[test]
fn genus_is_undefined_when_one_component_is_not_orientable() {
    let a = run(&merge(&[cube_at(10.0, 1.0), shapes::moebius(5)]));
    assert_eq!(
        counts(&a),
        Counts {
            border_edges: 10,
            inconsistent_edges: 1,
            components: 2,
            shells: 1,
            ..clean(18, 38, 22)
        }
    );
    let genera: Vec<Option<i64>> = a.components.iter().map(|c| c.genus).collect();
    assert_eq!(genera, vec![Some(0), None]);
    assert_eq!(a.holes(), 1);
    assert_eq!(a.genus(), None);
    assert_volume(a.volume(), Some(1.0));
}

/// The tetrahedron with its first face `0 2 1` stored twice (same winding).
///
/// Faces 5, 1 duplicate (the extra copy), kept: edges 02, 21, 10 now bound 3 faces each: 3
/// non-manifold edges; vertices 0, 1, 2 have them in their star: 3 non-manifold vertices (vertex 3's
/// edges 03, 13, 23 keep valence 2). E 6, F 5, chi = 4 - 6 + 5 = 3. One component, not manifold: no
/// shell, genus undefined. The valence-2 edges at vertex 3 stay consistent: 0 inconsistent.
#[test]
fn duplicate_face_same_winding() {
    let mut mesh = tetrahedron();
    mesh.triangles.push([0, 2, 1]);
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            duplicate_faces: 1,
            nonmanifold_edges: 3,
            nonmanifold_vertices: 3,
            components: 1,
            ..clean(4, 6, 5)
        }
    );
    assert_eq!(a.holes(), 0);
    assert_eq!(a.genus(), None);
    assert!(!a.components[0].manifold);
    assert_volume(a.volume(), None);
}

/// As [`duplicate_face_same_winding`] with the copy reversed (`0 1 2`): "same set of three welded
/// vertices, either winding" is still a duplicate, with the same counts.
#[test]
fn duplicate_face_reversed_winding() {
    let mut mesh = tetrahedron();
    mesh.triangles.push([0, 1, 2]);
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            duplicate_faces: 1,
            nonmanifold_edges: 3,
            nonmanifold_vertices: 3,
            components: 1,
            ..clean(4, 6, 5)
        }
    );
    assert_eq!(a.genus(), None);
}

/// Every face of the cube stored three times: 36 faces, 24 extra copies; every one of the 18 edges
/// bounds 6 faces: 18 non-manifold edges, all 8 vertices non-manifold.
#[test]
fn tripled_cube_counts_every_extra_copy() {
    let mut mesh = cube();
    let once = mesh.triangles.clone();
    mesh.triangles.extend_from_slice(&once);
    mesh.triangles
        .extend(once.iter().map(|&[a, b, c]| [b, c, a]));
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            duplicate_faces: 24,
            nonmanifold_edges: 18,
            nonmanifold_vertices: 8,
            components: 1,
            ..clean(8, 18, 36)
        }
    );
}

/// A triangle and its reverse copy alone (`0 1 2`, `0 2 1`): 1 duplicate. Each of the 3 edges bounds
/// the 2 faces, traversed in opposite directions: no border, nothing non-manifold, consistent.
/// V 3, E 3, F 2, chi 2: a closed manifold component, so a genus-0 shell enclosing nothing: volume 0.
#[test]
fn face_and_its_reverse_make_a_flat_shell() {
    let mesh = Mesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2], [0, 2, 1]],
    );
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            duplicate_faces: 1,
            components: 1,
            shells: 1,
            ..clean(3, 3, 2)
        }
    );
    assert_eq!(a.genus(), Some(0));
    assert!(a.oriented());
    assert_volume(a.shells[0].volume, Some(0.0));
    assert_volume(a.volume(), Some(0.0));
}

/// A triangle stored twice with the same winding: 1 duplicate; each edge has valence 2 but both faces
/// traverse it the same way: 3 inconsistent edges; flipping one copy fixes all three: orientable, not
/// oriented. V 3, E 3, F 2, chi 2, one genus-0 shell.
#[test]
fn face_stored_twice_is_an_inconsistent_flat_shell() {
    let mesh = Mesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2], [0, 1, 2]],
    );
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            duplicate_faces: 1,
            inconsistent_edges: 3,
            components: 1,
            shells: 1,
            ..clean(3, 3, 2)
        }
    );
    assert!(a.orientable() && !a.oriented());
    assert_eq!(a.genus(), Some(0));
}

/// The tetrahedron plus an input vertex at `(5,5,5)` no face uses: vertices 5, welded 5,
/// 1 unreferenced. The table (and chi = 4 - 6 + 4) only counts used vertices. The bounding box covers
/// every valid vertex: `[0,0,0]..[5,5,5]`.
#[test]
fn unreferenced_vertex_is_counted() {
    let mut mesh = tetrahedron();
    mesh.positions.push([5.0; 3]);
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 5,
            welded_vertices: 5,
            unreferenced_vertices: 1,
            ..tetrahedron_table()
        }
    );
    assert_eq!(a.bbox, Some([[0.0; 3], [5.0; 3]]));
    assert_outward_spheres(&a, 1);
}

/// Unreferenced counts welded vertices: an unused input vertex at a used position (vertex 1's) is not
/// unreferenced (vertices 5, welded 4, 0 unreferenced); two unused input vertices at one new position
/// are one unreferenced vertex (vertices 6, welded 5, 1 unreferenced).
#[test]
fn unreferenced_counts_welded_vertices() {
    let mut mesh = tetrahedron();
    mesh.positions.push([1.0, 0.0, 0.0]);
    assert_eq!(
        counts(&run(&mesh)),
        Counts {
            vertices: 5,
            ..tetrahedron_table()
        }
    );
    let mut mesh = tetrahedron();
    mesh.positions.extend([[5.0; 3], [5.0; 3]]);
    assert_eq!(
        counts(&run(&mesh)),
        Counts {
            vertices: 6,
            welded_vertices: 5,
            unreferenced_vertices: 1,
            ..tetrahedron_table()
        }
    );
}

/// Points without faces: 3 distinct positions, all unreferenced; no edges, no components, genus and
/// volume undefined.
#[test]
fn points_only() {
    let a = run(&Mesh::new(vec![[0.0; 3], [1.0; 3], [2.0; 3]], vec![]));
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 3,
            welded_vertices: 3,
            unreferenced_vertices: 3,
            ..Counts::default()
        }
    );
    assert_eq!(a.genus(), None);
    assert_volume(a.volume(), None);
    assert_eq!(a.bbox, Some([[0.0; 3], [2.0; 3]]));
}

/// The tetrahedron plus a vertex `(NaN, 0, 0)` used by a face `0 1 4`: 1 invalid vertex, its face
/// left out (1 invalid face); faces 5 input triangles; welded 4 valid positions; the table is the
/// tetrahedron's and the bounding box ignores the NaN.
#[test]
fn nan_vertex_and_its_face_are_left_out() {
    let mut mesh = tetrahedron();
    mesh.positions.push([f64::NAN, 0.0, 0.0]);
    mesh.triangles.push([0, 1, 4]);
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 5,
            faces: 5,
            invalid_vertices: 1,
            invalid_faces: 1,
            ..tetrahedron_table()
        }
    );
    assert_eq!(a.bbox, Some([[0.0; 3], [1.0; 3]]));
    assert_outward_spheres(&a, 1);
    assert_volume(a.volume(), Some(1.0 / 6.0));
}

/// An infinite coordinate is invalid too; two faces on it are two invalid faces; an unused invalid
/// vertex is counted but leaves no face out and is not an unreferenced (valid) vertex.
#[test]
fn infinite_vertices_are_invalid() {
    let mut mesh = tetrahedron();
    mesh.positions.push([0.0, f64::INFINITY, 0.0]);
    mesh.positions.push([0.0, 0.0, f64::NEG_INFINITY]);
    mesh.triangles.push([0, 1, 4]);
    mesh.triangles.push([4, 2, 3]);
    let a = run(&mesh);
    assert_eq!(
        counts(&a),
        Counts {
            vertices: 6,
            faces: 6,
            invalid_vertices: 2,
            invalid_faces: 2,
            ..tetrahedron_table()
        }
    );
}

/// No vertices, no faces: every count 0, no components or shells, genus and volume undefined, no
/// bounding box; holes 0; vacuously orientable and oriented.
#[test]
fn empty_mesh() {
    let a = run(&Mesh::new(vec![], vec![]));
    assert_eq!(counts(&a), Counts::default());
    assert_eq!(a.genus(), None);
    assert_volume(a.volume(), None);
    assert_eq!(a.bbox, None);
    assert_eq!(a.holes(), 0);
    assert!(a.orientable() && a.oriented());
    assert_eq!(a.area, 0.0);
}

// ---------------------------------------------------------------------------------------------------
// The suite, and properties over it
// ---------------------------------------------------------------------------------------------------

/// Every small construction above, by name.
fn suite() -> Vec<(&'static str, Mesh)> {
    let mut one_flipped = cube();
    one_flipped.triangles[0] = [0, 3, 2];
    let mut mirror = flipped(&tetrahedron());
    mirror.positions.iter_mut().for_each(|p| *p = p.map(|x| -x));
    let mut duplicate = tetrahedron();
    duplicate.triangles.push([0, 1, 2]);
    let mut degenerate = tetrahedron();
    degenerate.positions.push([0.0, 0.0, 0.0]);
    degenerate.triangles.extend([[4, 0, 1], [2, 2, 3]]);
    let mut invalid = tetrahedron();
    invalid.positions.extend([[f64::NAN, 0.0, 0.0], [5.0; 3]]);
    invalid.triangles.push([0, 1, 4]);
    let mut thin = tetrahedron();
    thin.positions
        .extend([[2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [4.0, 0.0, 0.0]]);
    thin.triangles.push([4, 5, 6]);
    vec![
        ("tetrahedron", tetrahedron()),
        ("cube", cube()),
        ("cube soup", soup(&cube())),
        ("torus 6x4", shapes::torus(6, 4, None)),
        ("torus 3x3 shuffled", shapes::torus(3, 3, Some(9))),
        ("frame", shapes::plate(3, 3, &[(1, 1)])),
        ("genus 2", shapes::plate(5, 3, &[(1, 1), (3, 1)])),
        ("genus 3", shapes::plate(7, 3, &[(1, 1), (3, 1), (5, 1)])),
        ("open box", open_box()),
        ("grid", shapes::grid(3, 2)),
        ("tube", shapes::tube(5, 2)),
        ("moebius", shapes::moebius(5)),
        ("klein", shapes::klein(6, 4)),
        ("bowtie", shapes::bowtie()),
        ("tetrahedra on a vertex", merge(&[tetrahedron(), mirror])),
        (
            "three triangles on an edge",
            Mesh::new(
                vec![
                    [0.0, 0.0, 0.0],
                    [1.0, 0.0, 0.0],
                    [0.5, 1.0, 0.0],
                    [0.5, -1.0, 0.0],
                    [0.5, 0.0, 1.0],
                ],
                vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
            ),
        ),
        (
            "cubes on an edge",
            merge(&[cube(), cuboid([1.0, 1.0, 0.0], [2.0, 2.0, 1.0])]),
        ),
        ("cube with a flipped triangle", one_flipped),
        ("inside-out cube", flipped(&cube())),
        (
            "inward cavity",
            merge(&[cube_at(0.0, 2.0), flipped(&cube_at(0.5, 1.0))]),
        ),
        (
            "outward cavity",
            merge(&[cube_at(0.0, 2.0), cube_at(0.5, 1.0)]),
        ),
        (
            "nested",
            merge(&[
                cube_at(0.0, 6.0),
                flipped(&cube_at(1.0, 4.0)),
                cube_at(2.0, 2.0),
            ]),
        ),
        ("disjoint cubes", merge(&[cube(), cube_at(2.0, 1.0)])),
        ("duplicate", duplicate),
        ("degenerate", degenerate),
        ("invalid and unreferenced", invalid),
        ("zero area", thin),
        (
            "cube, low half reversed",
            cube_with_half_reversed(LOW_SIDES),
        ),
        (
            "cube, high half reversed",
            cube_with_half_reversed(HIGH_SIDES),
        ),
        ("empty", Mesh::new(vec![], vec![])),
    ]
}

/// What no relabelling, reordering or corner rotation may change: every count, every component and
/// shell (as sorted multisets, since their order follows the faces'), the volumes, area and box.
#[derive(Debug, PartialEq)]
struct Invariants {
    counts: Counts,
    holes: usize,
    genus: Option<i64>,
    orientable: bool,
    oriented: bool,
    solids: usize,
    cavities: usize,
    inside_out: usize,
    #[allow(clippy::type_complexity)]
    components: Vec<(
        usize,
        usize,
        usize,
        usize,
        usize,
        usize,
        bool,
        bool,
        bool,
        bool,
        i64,
        Option<i64>,
    )>,
    #[allow(clippy::type_complexity)]
    shells: Vec<(usize, usize, Option<i64>, bool, bool, usize, bool, bool)>,
    bbox: Option<[[f64; 3]; 2]>,
}

fn invariants(a: &Analysis) -> Invariants {
    let mut components: Vec<_> = a
        .components
        .iter()
        .map(|c| {
            (
                c.faces,
                c.vertices,
                c.edges,
                c.border_edges,
                c.nonmanifold_edges,
                c.holes,
                c.closed,
                c.manifold,
                c.orientable,
                c.oriented,
                c.euler,
                c.genus,
            )
        })
        .collect();
    components.sort();
    let mut shells: Vec<_> = a
        .shells
        .iter()
        .map(|s| {
            (
                s.faces,
                s.vertices,
                s.genus,
                s.orientable,
                s.oriented,
                s.depth,
                s.role == Role::Cavity,
                s.inside_out,
            )
        })
        .collect();
    shells.sort();
    Invariants {
        counts: counts(a),
        holes: a.holes(),
        genus: a.genus(),
        orientable: a.orientable(),
        oriented: a.oriented(),
        solids: a.solids(),
        cavities: a.cavities(),
        inside_out: a.inside_out_shells(),
        components,
        shells,
        bbox: a.bbox,
    }
}

/// Shell volumes as a sorted list (`NaN` for none), compared with a tolerance: summing in another
/// order rounds differently.
fn shell_volumes(a: &Analysis) -> Vec<f64> {
    let mut v: Vec<f64> = a
        .shells
        .iter()
        .map(|s| s.volume.unwrap_or(f64::NAN))
        .collect();
    v.sort_by(f64::total_cmp);
    v
}

fn same_volumes(x: &[f64], y: &[f64]) -> bool {
    x.len() == y.len()
        && x.iter()
            .zip(y)
            .all(|(&a, &b)| (a.is_nan() && b.is_nan()) || close(a, b))
}

fn assert_same_analysis(
    name: &str,
    before: &Analysis,
    after: &Analysis,
) -> Result<(), TestCaseError> {
    prop_assert_eq!(invariants(before), invariants(after), "{}", name);
    prop_assert!(
        same_volumes(&shell_volumes(before), &shell_volumes(after)),
        "{}: shell volumes {:?} vs {:?}",
        name,
        shell_volumes(before),
        shell_volumes(after)
    );
    match (before.volume(), after.volume()) {
        (Some(x), Some(y)) => prop_assert!(close(y, x), "{}: volume {} vs {}", name, x, y),
        (x, y) => prop_assert_eq!(x, y, "{}: volume", name),
    }
    prop_assert!(
        close(after.area, before.area),
        "{}: area {} vs {}",
        name,
        before.area,
        after.area
    );
    Ok(())
}

/// The mesh with input vertex `i` moved to index `perm[i]`.
fn relabel_vertices(mesh: &Mesh, rng: &mut XorShift) -> Mesh {
    let mut perm: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    rng.shuffle(&mut perm);
    let mut positions = vec![[0.0; 3]; mesh.positions.len()];
    for (i, p) in mesh.positions.iter().enumerate() {
        positions[perm[i] as usize] = *p;
    }
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| perm[v as usize]))
        .collect();
    Mesh::new(positions, triangles)
}

fn permute_faces(mesh: &Mesh, rng: &mut XorShift) -> Mesh {
    let mut triangles = mesh.triangles.clone();
    rng.shuffle(&mut triangles);
    Mesh::new(mesh.positions.clone(), triangles)
}

/// Each face's corners rotated by a random amount (`a b c` -> `b c a` or `c a b`): same winding.
fn rotate_corners(mesh: &Mesh, rng: &mut XorShift) -> Mesh {
    let triangles = mesh
        .triangles
        .iter()
        .map(|&t| {
            let k = rng.below(3);
            [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
        })
        .collect();
    Mesh::new(mesh.positions.clone(), triangles)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 6,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Vertex indices are names: renaming them changes no count and no volume.
    #[test]
    fn relabelling_vertices_changes_nothing(seed in any::<u64>()) {
        let mut rng = XorShift::new(seed);
        for (name, mesh) in suite() {
            assert_same_analysis(name, &run(&mesh), &run(&relabel_vertices(&mesh, &mut rng)))?;
        }
    }

    /// Face order is storage: permuting faces changes no count and no volume.
    #[test]
    fn permuting_faces_changes_nothing(seed in any::<u64>()) {
        let mut rng = XorShift::new(seed);
        for (name, mesh) in suite() {
            assert_same_analysis(name, &run(&mesh), &run(&permute_faces(&mesh, &mut rng)))?;
        }
    }

    /// Rotating a face's corners keeps its winding: no count and no volume changes.
    #[test]
    fn rotating_corners_changes_nothing(seed in any::<u64>()) {
        let mut rng = XorShift::new(seed);
        for (name, mesh) in suite() {
            assert_same_analysis(name, &run(&mesh), &run(&rotate_corners(&mesh, &mut rng)))?;
        }
    }

    /// The three at once, on a larger shuffled torus.
    #[test]
    fn torus_survives_every_relabelling(seed in any::<u64>(), n in 3usize..12, m in 3usize..12) {
        let mut rng = XorShift::new(seed);
        let mesh = shapes::torus(n, m, Some(seed));
        let relabelled = relabel_vertices(&mesh, &mut rng);
        let moved = rotate_corners(&permute_faces(&relabelled, &mut rng), &mut rng);
        let (before, after) = (run(&mesh), run(&moved));
        assert_same_analysis("torus", &before, &after)?;
        prop_assert_eq!(after.genus(), Some(1));
        prop_assert_eq!(after.edges, 3 * n * m);
    }
}

/// Flipping every face reverses every winding: no count changes (consistency of an edge compares the
/// two windings, both reversed), each component stays (non-)orientable and (non-)oriented, every
/// shell's raw volume changes sign (the stored or majority winding is reversed, so every term
/// `mp(A-P, B-P, C-P)` changes sign), so oriented shells with a nonzero volume swap inside-out-ness,
/// and the mesh volume (taken by role) stays.
#[test]
fn flipping_every_face_negates_shell_volumes() {
    for (name, mesh) in suite() {
        let (a, b) = (run(&mesh), run(&flipped(&mesh)));
        assert_eq!(counts(&a), counts(&b), "{name}");
        assert_eq!(a.components.len(), b.components.len(), "{name}");
        for (x, y) in a.components.iter().zip(&b.components) {
            assert_eq!(
                (x.orientable, x.oriented),
                (y.orientable, y.oriented),
                "{name}"
            );
        }
        assert_eq!(a.shells.len(), b.shells.len(), "{name}");
        for (x, y) in a.shells.iter().zip(&b.shells) {
            assert_eq!(
                (x.depth, x.role, x.orientable, x.oriented),
                (y.depth, y.role, y.orientable, y.oriented),
                "{name}"
            );
            match (x.volume, y.volume) {
                (Some(v), Some(w)) => {
                    assert!(close(w, -v), "{name}: {v} flipped gave {w}");
                    if x.oriented && v.abs() > 1e-9 {
                        assert_ne!(x.inside_out, y.inside_out, "{name}");
                    }
                }
                (v, w) => assert_eq!(v, w, "{name}"),
            }
        }
        match (a.volume(), b.volume()) {
            (Some(v), Some(w)) => assert!(close(w, v), "{name}: {v} vs {w}"),
            (v, w) => assert_eq!(v, w, "{name}"),
        }
    }
}

/// The Corner Table of a mesh as the analysis builds it (SPEC 3-4): weld exactly, leave out faces on
/// invalid vertices and degenerate faces.
fn table(mesh: &Mesh) -> CornerTable {
    let welded = meshvet::weld::weld(&mesh.positions, 0.0);
    let triangles: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| welded.map[v as usize]))
        .filter(|t| {
            !t.contains(&meshvet::weld::INVALID) && t[0] != t[1] && t[1] != t[2] && t[2] != t[0]
        })
        .collect();
    CornerTable::build(&triangles, welded.positions.len())
}

/// On every mesh of the suite: `o(o(c)) == c` for every corner with an opposite, the two corners face
/// the same edge from different triangles, and the table's border, manifold and non-manifold marks
/// agree with edge valences counted independently here.
#[test]
fn opposite_of_opposite_is_identity() {
    for (name, mesh) in suite() {
        let t = table(&mesh);
        let key = |c: u32| {
            let (a, b) = (t.v(CornerTable::n(c)), t.v(CornerTable::p(c)));
            (a.min(b), a.max(b))
        };
        let mut valence: HashMap<(u32, u32), usize> = HashMap::new();
        for c in 0..t.corner_count() as u32 {
            *valence.entry(key(c)).or_default() += 1;
        }
        assert_eq!(t.edge_count(), valence.len(), "{name}");
        assert_eq!(
            t.border_edge_count(),
            valence.values().filter(|&&k| k == 1).count(),
            "{name}"
        );
        assert_eq!(
            t.nonmanifold_edges().len(),
            valence.values().filter(|&&k| k >= 3).count(),
            "{name}"
        );
        for c in 0..t.corner_count() as u32 {
            let k = valence[&key(c)];
            match t.opposite(c) {
                Some(o) => {
                    assert_eq!(t.opposite(o), Some(c), "{name}: o(o({c}))");
                    assert_eq!(t.o(t.o(c)), c, "{name}");
                    assert_eq!(key(o), key(c), "{name}");
                    assert_ne!(CornerTable::t(o), CornerTable::t(c), "{name}");
                    assert_eq!(k, 2, "{name}");
                }
                None if t.is_border(c) => assert_eq!(k, 1, "{name}"),
                None => {
                    assert!(t.is_nonmanifold(c), "{name}");
                    assert!(k >= 3, "{name}");
                }
            }
        }
    }
}

/// On oriented closed manifold meshes, swinging from any corner visits the faces around its vertex and
/// is back after exactly as many steps as the vertex has faces (counted here from the triangle list).
#[test]
fn swing_returns_after_vertex_degree() {
    let meshes = [
        ("tetrahedron", tetrahedron()),
        ("cube", cube()),
        ("torus", shapes::torus(7, 5, Some(3))),
        ("genus 2", shapes::plate(5, 3, &[(1, 1), (3, 1)])),
        ("genus 3", shapes::plate(7, 3, &[(1, 1), (3, 1), (5, 1)])),
        (
            "nested",
            merge(&[
                cube_at(0.0, 6.0),
                flipped(&cube_at(1.0, 4.0)),
                cube_at(2.0, 2.0),
            ]),
        ),
    ];
    for (name, mesh) in meshes {
        let t = table(&mesh);
        let mut degree = vec![0usize; t.vertex_count()];
        for c in 0..t.corner_count() as u32 {
            degree[t.v(c) as usize] += 1;
        }
        for c in 0..t.corner_count() as u32 {
            let d = degree[t.v(c) as usize];
            let mut s = c;
            for step in 1..=d {
                s = t
                    .s(s)
                    .unwrap_or_else(|| panic!("{name}: swing from {c} hit a non-manifold edge"));
                assert_eq!(t.v(s), t.v(c), "{name}: swing left the vertex");
                assert!(
                    step == d || s != c,
                    "{name}: back at {c} after {step} of {d} steps"
                );
            }
            assert_eq!(s, c, "{name}: not back after {d} swings");
        }
    }
}

// ---------------------------------------------------------------------------------------------------
// Scale
// ---------------------------------------------------------------------------------------------------

/// A 1000 x 500 grid torus with shuffled faces: F = 2 x 500,000 = 1,000,000, V = 500,000,
/// E = 1,500,000, chi 0, closed, genus 1. Correctness at scale (no stack overflow in the traversals),
/// not a timing test.
#[test]
fn million_triangle_torus_has_genus_one() {
    let mesh = shapes::torus(1000, 500, Some(0x5EED));
    assert_eq!(mesh.triangles.len(), 1_000_000);
    let a = run(&mesh);
    assert_eq!(a.genus(), Some(1));
    assert_eq!(a.border_edges, 0);
    assert_eq!(
        counts(&a),
        Counts {
            components: 1,
            shells: 1,
            ..clean(500_000, 1_500_000, 1_000_000)
        }
    );
}

// ---------------------------------------------------------------------------------------------------
// A closed component pinched at a vertex
// ---------------------------------------------------------------------------------------------------

/// A solid pinched at one vertex: two square pyramids with their apex at the origin P and their
/// bases at x = 1 and x = -1 (`y, z` in `[-1, 1]`), joined base to base by a U-shaped tube of seven
/// 2 x 2 x 2 boxes (`y` in `[-1, 1]`; in `x, z`: `[1,3]x[-1,1]`, `[1,3]x[1,3]`, `[1,3]x[3,5]`,
/// `[-1,1]x[3,5]`, `[-3,-1]x[3,5]`, `[-3,-1]x[1,3]`, `[-3,-1]x[-1,1]`), every face wound outward.
/// Each box shows 4 of its 6 sides (2 are joints), 8 triangles; the pyramids 4 each: F = 64.
/// V = 32 tube corners (16 `(x, z)` pairs, 2 `y`) + P = 33; every edge bounds two faces, so
/// E = 3F/2 = 96 and chi = 33 - 96 + 64 = 1 (a sphere with two points made one). P has two fans,
/// one per pyramid: the component is closed but not manifold, so not a shell, and it still bounds
/// 7 x 8 + 2 x 4/3 = 176/3, counted as one solid. Wound inward, it is one inside-out solid.
#[test]
fn a_closed_component_pinched_at_a_vertex_is_a_solid_not_a_shell() {
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    // Adds the polygon `corners` wound so that its normal points away from `inside`.
    let mut face = |corners: &[[f64; 3]], inside: [f64; 3]| {
        let normal = |c: &[[f64; 3]]| {
            let (a, b, d) = (c[0], c[1], c[2]);
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
            [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ]
        };
        let n = normal(corners);
        let out = [0, 1, 2].map(|k| corners[0][k] - inside[k]);
        let mut c = corners.to_vec();
        if n[0] * out[0] + n[1] * out[1] + n[2] * out[2] < 0.0 {
            c.reverse();
        }
        let base = positions.len() as u32;
        positions.extend_from_slice(&c);
        for k in 1..c.len() as u32 - 1 {
            triangles.push([base, base + k, base + k + 1]);
        }
    };
    // (x range, z range, the two sides that are joints: 0 -x, 1 +x, 4 -z, 5 +z)
    let boxes: [([f64; 2], [f64; 2], [usize; 2]); 7] = [
        ([1.0, 3.0], [-1.0, 1.0], [0, 5]),
        ([1.0, 3.0], [1.0, 3.0], [4, 5]),
        ([1.0, 3.0], [3.0, 5.0], [4, 0]),
        ([-1.0, 1.0], [3.0, 5.0], [1, 0]),
        ([-3.0, -1.0], [3.0, 5.0], [1, 4]),
        ([-3.0, -1.0], [1.0, 3.0], [5, 4]),
        ([-3.0, -1.0], [-1.0, 1.0], [5, 1]),
    ];
    for (x, z, joints) in boxes {
        let (lo, hi) = ([x[0], -1.0, z[0]], [x[1], 1.0, z[1]]);
        let centre = [0, 1, 2].map(|k| (lo[k] + hi[k]) / 2.0);
        for side in 0..6 {
            if joints.contains(&side) {
                continue;
            }
            let (axis, at) = (side / 2, if side % 2 == 0 { lo } else { hi });
            let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
            let corner = |a: f64, b: f64| {
                let mut p = at;
                p[i] = a;
                p[j] = b;
                p
            };
            face(
                &[
                    corner(lo[i], lo[j]),
                    corner(hi[i], lo[j]),
                    corner(hi[i], hi[j]),
                    corner(lo[i], hi[j]),
                ],
                centre,
            );
        }
    }
    for x in [1.0, -1.0] {
        let square = [
            [x, -1.0, -1.0],
            [x, 1.0, -1.0],
            [x, 1.0, 1.0],
            [x, -1.0, 1.0],
        ];
        for k in 0..4 {
            face(
                &[[0.0; 3], square[k], square[(k + 1) % 4]],
                [0.75 * x, 0.0, 0.0],
            );
        }
    }
    let mesh = Mesh::new(positions, triangles);
    let a = run(&mesh);
    let mut expected = clean(33, 96, 64);
    expected.vertices = mesh.positions.len();
    expected.nonmanifold_vertices = 1;
    expected.components = 1;
    assert_eq!(counts(&a), expected);
    assert_eq!((a.holes(), a.genus()), (0, None));
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (1, 0, 0));
    assert!(close(a.volume().unwrap(), 176.0 / 3.0), "{:?}", a.volume());
    let a = run(&flipped(&mesh));
    assert_eq!((a.solids(), a.inside_out_shells()), (1, 1));
    assert!(close(a.volume().unwrap(), 176.0 / 3.0), "{:?}", a.volume());
}

// ---------------------------------------------------------------------------------------------------
// Shells that cross: no depth against each other
// ---------------------------------------------------------------------------------------------------

/// An L-shaped prism: the L `(0,0) (4,0) (4,2) (2,2) (2,4) (0,4)` (area 16 - 4 = 12, split into
/// four triangles) from z = 0 to 4, wound outward: volume 48.
fn l_prism() -> Mesh {
    let l = [
        [0.0, 0.0],
        [4.0, 0.0],
        [4.0, 2.0],
        [2.0, 2.0],
        [2.0, 4.0],
        [0.0, 4.0],
    ];
    let mut positions: Vec<[f64; 3]> = l.iter().map(|p| [p[0], p[1], 0.0]).collect();
    positions.extend(l.iter().map(|p| [p[0], p[1], 4.0]));
    let cap: [[u32; 3]; 4] = [[0, 1, 2], [0, 2, 3], [0, 3, 5], [3, 4, 5]];
    let mut triangles: Vec<[u32; 3]> = cap.iter().map(|t| [t[0], t[2], t[1]]).collect();
    triangles.extend(cap.iter().map(|t| t.map(|v| v + 6)));
    for i in 0..6u32 {
        let j = (i + 1) % 6;
        triangles.extend([[i, j, j + 6], [i, j + 6, i + 6]]);
    }
    Mesh::new(positions, triangles)
}

/// The L-prism and a unit cube `[1.5,2.5]^3` in its inner corner, both wound outward. The cube's
/// box lies in the L's box and its lowest vertex, (1.5, 1.5, 1.5), inside the L, so point-in-solid
/// parity would call it a cavity, and (wound outward) inside out. But it crosses the L's inner
/// walls (x = 2 for y in [2, 2.5], y = 2 for x in [2, 2.5]): their faces meet, 1 pair of
/// components, 0 within either, so neither has depth against the other. Both are depth-0 solids,
/// nothing is inside out, and the volume, 48 + 1 = 49, counts their overlap twice. Without the
/// search the parity guess comes back: depth 1, a cavity, inside out.
#[test]
fn shells_that_cross_have_no_depth_against_each_other() {
    let mesh = merge(&[l_prism(), cube_at(1.5, 1.0)]);
    let a = run(&mesh);
    assert_eq!(
        (a.self_intersections(), a.intersecting_components()),
        (Some(0), Some(1))
    );
    assert_shells(
        &a,
        &[(0, Role::Solid, Some(48.0)), (0, Role::Solid, Some(1.0))],
    );
    assert_eq!(
        (a.inside_out_shells(), a.cavities(), a.overlapping_shells()),
        (0, 0, 1)
    );
    assert_eq!(
        (a.shells[0].meets.as_slice(), a.shells[1].meets.as_slice()),
        (&[1][..], &[0][..])
    );
    assert_volume(a.volume(), Some(49.0));

    let blind = analyse(
        &mesh,
        &Options {
            intersections: None,
            ..Options::default()
        },
    );
    assert_eq!(blind.self_intersections(), None);
    assert_shells(
        &blind,
        &[(0, Role::Solid, Some(48.0)), (1, Role::Cavity, Some(1.0))],
    );
    assert_eq!(blind.inside_out_shells(), 1);
}

/// A unit cube inside a 3-cube (`[1,2]^3` in `[0,3]^3`), wound into the void: no face meets
/// another (a gap of 1 all round), so nesting holds as before: a solid of 27 around a correct
/// cavity of -1, volume 26.
#[test]
fn a_cavity_that_meets_nothing_is_still_a_cavity() {
    let mesh = merge(&[cube_at(0.0, 3.0), flipped(&cube_at(1.0, 1.0))]);
    let a = run(&mesh);
    assert_eq!(
        (a.self_intersections(), a.intersecting_components()),
        (Some(0), Some(0))
    );
    assert_shells(
        &a,
        &[(0, Role::Solid, Some(27.0)), (1, Role::Cavity, Some(-1.0))],
    );
    assert_eq!((a.inside_out_shells(), a.overlapping_shells()), (0, 0));
    assert_volume(a.volume(), Some(26.0));
}

/// A mesh past the size at which the analysis runs its passes side by side (and the build and the
/// search on every thread): a 520 x 500 grid torus (520,000 faces, shuffled) with one vertex
/// pushed through the tube (faces that cross), every 1,009th face dropped (holes) and a second,
/// small torus inside the tube, a quarter turn away, crossing nothing. Two threads give the analysis of one, field by
/// field, and the holes, crossings and parts are really there (so the passes had work to agree on).
#[test]
fn two_threads_analyse_a_big_mesh_as_one_does() {
    let mut big = shapes::torus(520, 500, Some(11));
    big.positions[0] = [shapes::TORUS_R - 1.2 * shapes::TORUS_TUBE, 0.0, 0.0];
    let mut f = 0;
    big.triangles.retain(|_| {
        f += 1;
        f % 1009 != 0
    });
    let mut small = shapes::torus(8, 6, None);
    for p in &mut small.positions {
        *p = p.map(|x| 0.1 * x);
        p[1] += shapes::TORUS_R;
    }
    let mesh = merge(&[big, small]);
    let pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool")
    };
    let one = pool(1).install(|| analyse(&mesh, &Options::default()));
    let two = pool(2).install(|| analyse(&mesh, &Options::default()));
    assert_eq!(one, two);
    assert_eq!(one.components.len(), 2);
    assert!(one.border_edges > 0);
    let meets = one.intersections.as_ref().expect("searched");
    assert!(meets.self_intersections > 0);
    assert_eq!(meets.intersecting_components(), 0);
}

/// A triangle soup whose facets come in random order (an STL written by a tool that shuffled
/// them) numbers its welded vertices by first appearance, that is at random. The build renumbers
/// them along space: afterwards most faces span few vertex numbers (without it, half of all
/// numbers), and the analysis is the indexed mesh's, count for count. A 300 x 250 grid torus:
/// 150,000 faces, 75,000 vertices (enough to be looked at), closed, genus 1.
#[test]
fn a_shuffled_soup_is_analysed_along_space_as_the_indexed_mesh() {
    let indexed = shapes::torus(300, 250, Some(3));
    let soup = soup(&indexed);
    let (built, _) = meshvet::topology::build(&soup, &Options::default());
    let n = built.welded.positions.len();
    assert_eq!(n, 75_000);
    let mut spans: Vec<u32> = built
        .table
        .triangles()
        .iter()
        .map(|t| t.iter().max().unwrap() - t.iter().min().unwrap())
        .collect();
    spans.sort_unstable();
    let median = spans[spans.len() / 2] as usize;
    assert!(
        median < n / 64,
        "median span {median} of {n} vertex numbers"
    );

    let (a, b) = (run(&soup), run(&indexed));
    assert_eq!(
        (a.welded_vertices, a.faces, a.edges),
        (b.welded_vertices, b.faces, b.edges)
    );
    assert_eq!((a.euler, a.genus(), a.components.len()), (0, Some(1), 1));
    assert_eq!(a.components, b.components);
    assert_eq!(a.shells.len(), 1);
    let (va, vb) = (a.volume().unwrap(), b.volume().unwrap());
    assert!((va - vb).abs() <= 1e-12 * vb.abs(), "{va} vs {vb}");
    assert!((a.area - b.area).abs() <= 1e-12 * b.area);
    assert_eq!(a.intersections, b.intersections);
}
