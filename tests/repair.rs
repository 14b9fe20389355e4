//! Repair plans (SPEC 10) on hand-built meshes. Every test analyses the repaired mesh, checks the
//! repaired defects are gone with numbers derived by hand, and repairs the result again: a second
//! repair must change nothing.

#[allow(dead_code)]
mod shapes;

use meshvet::repair::{plan, plan_with, Kind, Options, Plan};
use meshvet::{analyse, Analysis, Mesh, Role};

fn repaired(mesh: &Mesh) -> (Plan, Mesh, Analysis) {
    let p = plan(mesh, &Options::default());
    // A scan hands the planner its analysis's weld and table; the plan must be the same.
    let (_, built) = meshvet::topology::analyse_keeping(mesh, &Default::default());
    assert_eq!(
        plan_with(mesh, &Options::default(), Some(built)),
        p,
        "planning from the analysis's table changed the plan"
    );
    let out = p.apply(mesh);
    let again = plan(&out, &Options::default());
    assert!(!again.changes(), "a second repair changed {:?}", again.done);
    let a = analyse(&out, &Default::default());
    (p, out, a)
}

fn count(p: &Plan, kind: Kind) -> usize {
    p.done
        .iter()
        .find(|(k, ..)| *k == kind)
        .map_or(0, |(_, n, _)| *n)
}

fn assert_close(a: f64, b: f64) {
    assert!((a - b).abs() < 1e-9, "{a} != {b}");
}

/// A clean cube needs nothing: the plan changes nothing and keeps every face in order.
#[test]
fn clean_mesh_is_left_alone() {
    let cube = shapes::cube();
    let p = plan(&cube, &Options::default());
    assert!(!p.changes());
    assert_eq!(p.summary(), "");
    assert_eq!(
        p.apply(&cube),
        Mesh::new(cube.positions.clone(), cube.triangles.clone())
    );
}

/// Unit cube with its top two triangles removed and one side triangle flipped: the flipped face is
/// turned back (1 face, the smaller side), and the square hole (4 border edges) is filled with 2
/// triangles. Result: one closed, oriented, outward shell of volume 1 (V 8, E 18, F 12).
#[test]
fn open_box_with_a_flipped_face_becomes_a_closed_outward_cube() {
    let mut mesh = open_box();
    mesh.triangles[0].swap(1, 2);
    let (p, out, a) = repaired(&mesh);
    assert_eq!(count(&p, Kind::OrientFaces), 1);
    assert_eq!(count(&p, Kind::FillHoles), 1);
    assert_eq!(p.summary(), "orient-faces:1;fill-holes:1(2 faces)");
    assert_eq!(out.triangles.len(), 12);
    assert_eq!(
        (a.edges, a.border_edges, a.holes(), a.inconsistent_edges),
        (18, 0, 0, 0)
    );
    assert_eq!(a.shells.len(), 1);
    assert_close(a.shells[0].volume.unwrap(), 1.0);
    // Fills take their attributes from corners of the faces around the hole.
    let fills: Vec<_> = p.triangles.iter().filter(|t| t.source.is_none()).collect();
    assert_eq!(fills.len(), 2);
    for t in fills {
        for c in t.corners {
            assert_eq!(
                mesh.triangles[c.from as usize / 3][c.from as usize % 3],
                c.vertex
            );
        }
    }
}

/// A cube whose top square is four faces around a NaN vertex, repaired with `invalid-vertex` off
/// (faces with invalid vertices kept): the analysis leaves those four faces out, so it sees one
/// hole of 4 edges, but the file closes it. Filling it would lay 2 faces over the 4 kept ones:
/// the hole is left open and said so, and the copy is the source's 14 faces.
#[test]
fn holes_closed_by_kept_invalid_faces_are_not_filled() {
    let mut mesh = open_box();
    let nan = mesh.positions.len() as u32;
    mesh.positions.push([f64::NAN, 0.5, 1.0]);
    // The top square's corners in turn, counter-clockwise seen from above.
    let ring = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]].map(|[x, y]| {
        mesh.positions
            .iter()
            .position(|p| *p == [x, y, 1.0])
            .unwrap() as u32
    });
    for k in 0..4 {
        mesh.triangles.push([ring[k], ring[(k + 1) % 4], nan]);
    }
    let options = Options {
        drop_invalid_faces: false,
        ..Options::default()
    };
    let p = plan(&mesh, &options);
    assert_eq!(count(&p, Kind::FillHoles), 0);
    assert_eq!(
        p.not_repairable,
        vec![
            "1 hole left open: faces with a NaN or infinite vertex close it in the file (kept, \
             as invalid-vertex is off)"
        ]
    );
    assert_eq!(p.apply(&mesh).triangles.len(), 14);
    // With the faces dropped, the hole is the cube's top: filled with 2 faces.
    let p = plan(&mesh, &Options::default());
    assert_eq!(
        (
            count(&p, Kind::DropInvalidFaces),
            count(&p, Kind::FillHoles)
        ),
        (4, 1)
    );
    assert_eq!(p.apply(&mesh).triangles.len(), 12);
}

/// The two faces of the cube with all four vertices at z = 1.
/// The unit cube without its top two triangles (z = 1): 10 faces, one square hole.
fn open_box() -> Mesh {
    let cube = shapes::cube();
    let top = top_faces(&cube);
    let mut mesh = cube.clone();
    mesh.triangles = (0..12)
        .filter(|t| !top.contains(t))
        .map(|t| cube.triangles[t])
        .collect();
    mesh
}

fn top_faces(cube: &Mesh) -> Vec<usize> {
    (0..12)
        .filter(|&t| {
            cube.triangles[t]
                .iter()
                .all(|&v| cube.positions[v as usize][2] == 1.0)
        })
        .collect()
}

/// An inside-out cube (every face flipped): orientation is already consistent, so no face is
/// "oriented"; the whole shell (12 faces) is flipped and encloses +1.
#[test]
fn inside_out_cube_is_turned_outward() {
    let mesh = shapes::flipped(&shapes::cube());
    let (p, _, a) = repaired(&mesh);
    assert_eq!(count(&p, Kind::OrientFaces), 0);
    assert_eq!(p.summary(), "flip-inside-out-shells:1(12 faces)");
    assert!(p.triangles.iter().all(|t| t.flipped));
    assert_eq!(a.inside_out_shells(), 0);
    assert_close(a.shells[0].volume.unwrap(), 1.0);
}

/// A 2x2x2 cube with a 1x1x1 cavity whose faces point out (into the material): the cavity shell is
/// flipped to face into the void, and the volume stays 8 - 1 = 7 (trimesh's fix makes it 9).
#[test]
fn cavity_facing_out_is_turned_into_the_void() {
    let outer = shapes::cuboid([0.0; 3], [2.0; 3]);
    let inner = shapes::cuboid([0.5; 3], [1.5; 3]);
    let mesh = shapes::merge(&[outer, inner]);
    let (p, _, a) = repaired(&mesh);
    assert_eq!(p.summary(), "flip-inside-out-shells:1(12 faces)");
    let roles: Vec<Role> = a.shells.iter().map(|s| s.role).collect();
    assert_eq!(roles, vec![Role::Solid, Role::Cavity]);
    assert_eq!(a.inside_out_shells(), 0);
    assert_close(a.shells[1].volume.unwrap(), -1.0);
    assert_close(a.volume().unwrap(), 7.0);
}

/// An outward unit cube inside the walls of a projective plane ([`shapes::projective_plane`]; a
/// ray from the cube crosses them once): the plane is not orientable, so it has no inside and the
/// cube is a solid at depth 0, already outward. Nothing is repaired: the plane is left as it is (not
/// orientable), and the cube is not turned to face inwards as if it were a cavity.
#[test]
fn a_shell_within_a_non_orientable_one_is_not_turned() {
    let cube = shapes::cuboid([-0.5, -0.5, 3.5], [0.5, 0.5, 4.5]);
    let mesh = shapes::merge(&[shapes::projective_plane(), cube]);
    let p = plan(&mesh, &Options::default());
    assert_eq!(count(&p, Kind::FlipInsideOutShells), 0, "{}", p.summary());
    assert_eq!(count(&p, Kind::OrientFaces), 0, "{}", p.summary());
    let a = analyse(&p.apply(&mesh), &Default::default());
    assert_eq!((a.solids(), a.cavities(), a.inside_out_shells()), (1, 0, 0));
    assert_close(a.volume().unwrap(), 1.0);
}

/// Two unit right tetrahedra on one vertex, mirrored through it (each encloses 1/6, together 1/3),
/// placed far from the origin. The vertex is split: its copy moves 1e-5 of the model's size (its
/// box's diagonal is sqrt(12), so 3.5e-5) into its fan, which changes the volume by less than that
/// move times the fan's area (under 1e-4), along each axis. Far from the origin the move once
/// grew with the distance (1e-5 of the largest coordinate, up to a quarter of the way into the
/// fan: at x = 1e5 the volume fell to 0.291), and was rounded to f32 even where that dropped it
/// along an axis (at x = 1e5, f32's step is 1/128: the copy stayed at x = 1e5).
#[test]
fn a_split_far_from_the_origin_moves_the_copy_a_hair() {
    for offset in [
        [1e5, 0.0, 0.0],
        [0.0, 0.0, 16_777_216.0],
        [-3e7, 2e6, 123_456.789],
    ] {
        let one = shapes::tetrahedron();
        // Mirrored through the origin, which turns its faces inward: wound back outward.
        let mirrored = shapes::flipped(&Mesh::new(
            one.positions.iter().map(|p| p.map(|x| -x)).collect(),
            one.triangles.clone(),
        ));
        let both = shapes::merge(&[one, mirrored]);
        let mesh = Mesh::new(
            both.positions
                .iter()
                .map(|p| std::array::from_fn(|k| p[k] + offset[k]))
                .collect(),
            both.triangles.clone(),
        );
        let (p, out, a) = repaired(&mesh);
        assert_eq!(p.summary(), "split-non-manifold-vertices:1", "{offset:?}");
        assert_eq!(
            (a.nonmanifold_vertices, a.shell_count()),
            (0, 2),
            "{offset:?}"
        );
        // The one position of the copy that the source does not have: the shared vertex's copy.
        let new: Vec<&[f64; 3]> = out
            .positions
            .iter()
            .filter(|q| !mesh.positions.contains(q))
            .collect();
        assert_eq!(new.len(), 1, "{offset:?}");
        let moved = (0..3)
            .map(|k| (new[0][k] - offset[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            moved > 0.0 && moved < 1e-4,
            "{offset:?}: the copy moved {moved}"
        );
        // Its fan lies towards +x, +y and +z of the vertex (or -x, -y, -z): it moves along each.
        assert!(
            (0..3).all(|k| new[0][k] != offset[k]),
            "{offset:?}: the copy {:?} did not move along every axis",
            new[0]
        );
        let volume = a.volume().unwrap();
        assert!(
            (volume - 1.0 / 3.0).abs() < 1e-4,
            "{offset:?}: volume {volume}"
        );
    }
}

/// Two unit cubes sharing the edge x = y = 1: that edge has 4 faces. It keeps a consistent pair and
/// the other cube's faces are cut loose; its two endpoints then have two fans each (one per cube),
/// so 2 vertices are split. Result: two separate closed cubes (2 shells, V 16, E 36, F 24), no
/// non-manifold edge or vertex.
#[test]
fn cubes_sharing_an_edge_are_split_into_two_shells() {
    let a = shapes::cuboid([0.0; 3], [1.0; 3]);
    let b = shapes::cuboid([1.0, 1.0, 0.0], [2.0, 2.0, 1.0]);
    let mesh = shapes::merge(&[a, b]);
    let before = analyse(&mesh, &Default::default());
    assert_eq!((before.nonmanifold_edges, before.shells.len()), (1, 0));
    let (p, out, a) = repaired(&mesh);
    assert_eq!(count(&p, Kind::SplitNonManifoldEdges), 1);
    assert_eq!(count(&p, Kind::SplitNonManifoldVertices), 2);
    assert_eq!((a.nonmanifold_edges, a.nonmanifold_vertices), (0, 0));
    assert_eq!(a.shells.len(), 2);
    assert_eq!((a.welded_vertices, a.edges, a.faces), (16, 36, 24));
    assert_eq!(out.positions.len(), 16);
    // The copies moved by about 1e-5 of the model's size, so the volume moves by as little.
    assert!((a.volume().unwrap() - 2.0).abs() < 1e-4);
    // Each copy is a copy of the shared vertex it replaces, moved a hair (under 1e-3 here).
    assert_eq!(p.new_vertices.len(), 2);
    for v in &p.new_vertices {
        let original = mesh.positions[v.copy_of as usize];
        let d: f64 = (0..3)
            .map(|k| (v.position[k] - original[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(d > 0.0 && d < 1e-3, "moved {d}");
    }
}

/// Bowtie: two triangles touching at vertex 0. The vertex is split (one copy); each triangle is then
/// alone, and filling its 3-edge hole would only repeat the face, so both holes are left open and
/// reported.
#[test]
fn bowtie_vertex_is_split_and_lone_triangles_stay_open() {
    let (p, _, a) = repaired(&shapes::bowtie());
    assert_eq!(p.summary(), "split-non-manifold-vertices:1");
    assert_eq!(a.nonmanifold_vertices, 0);
    assert_eq!(a.components.len(), 2);
    assert_eq!(
        p.not_repairable,
        vec!["2 holes left open: filling would overlap existing edges"]
    );
}

/// Degenerate (repeated index), duplicate (reversed copy), NaN vertex face and an unreferenced vertex
/// on a cube: all dropped; the cube is intact (V 8, E 18, F 12) and nothing else changes.
#[test]
fn bad_faces_and_unreferenced_vertices_are_dropped() {
    let mut mesh = shapes::cube();
    let t0 = mesh.triangles[0];
    mesh.positions.push([f64::NAN, 0.0, 0.0]); // 8: invalid
    mesh.positions.push([9.0, 9.0, 9.0]); // 9: unreferenced
    mesh.triangles.push([0, 0, 1]);
    mesh.triangles.push([t0[0], t0[2], t0[1]]);
    mesh.triangles.push([0, 1, 8]);
    let (p, out, a) = repaired(&mesh);
    assert_eq!(
        p.summary(),
        "drop-invalid-faces:1;drop-degenerate-faces:1;drop-duplicate-faces:1;drop-unreferenced-vertices:2"
    );
    assert_eq!(out.positions.len(), 8);
    assert_eq!(
        (a.welded_vertices, a.edges, a.faces, a.shells.len()),
        (8, 18, 12, 1)
    );
}

/// Moebius strip: not orientable, reported and left as is; its single border loop cannot be traced
/// by direction, so it stays open too.
#[test]
fn moebius_strip_is_reported_not_repaired() {
    let mesh = shapes::moebius(10);
    let (p, _, a) = repaired(&mesh);
    assert!(
        p.not_repairable
            .iter()
            .any(|m| m.contains("1 non-orientable component")),
        "{:?}",
        p.not_repairable
    );
    assert!(!a.orientable());
    assert_eq!(count(&p, Kind::OrientFaces), 0);
}

/// An open tube of 12 vertices around and 2 rings of quads has two holes of 12 edges each: with a
/// limit of 10 both stay open and are reported; with the default limit both are capped (10 faces
/// each), giving a closed genus-0 shell wound outward.
#[test]
fn holes_over_the_limit_stay_open() {
    let mesh = shapes::tube(12, 2);
    let small = Options {
        max_hole_edges: 10,
        ..Options::default()
    };
    let p = plan(&mesh, &small);
    assert_eq!(p.not_repairable, vec!["2 holes over 10 edges left open"]);
    assert!(!p.changes());
    let (p, _, a) = repaired(&mesh);
    assert_eq!(p.summary(), "fill-holes:2(20 faces)");
    assert_eq!((a.holes(), a.shells.len(), a.genus()), (0, 1, Some(0)));
    assert!(a.shells[0].volume.unwrap() > 0.0);
}

/// A flat grid's corner quads already join two border vertices by a diagonal, so a fill of its
/// outline would repeat that edge (and lie on the grid itself): it is refused, not forced.
#[test]
fn fills_that_would_overlap_are_refused() {
    let p = plan(&shapes::grid(6, 4), &Options::default());
    assert_eq!(
        p.not_repairable,
        vec!["1 hole left open: filling would overlap existing edges"]
    );
}

/// A regular hexagon (circumradius 1) split as a fan around a centre vertex at height `apex`.
fn hexagon_fan(apex: f64) -> Mesh {
    let mut positions = vec![[0.0, 0.0, apex]];
    for k in 0..6 {
        let a = std::f64::consts::PI / 3.0 * k as f64;
        positions.push([a.cos(), a.sin(), 0.0]);
    }
    let triangles = (0..6u32).map(|k| [0, 1 + k, 1 + (k + 1) % 6]).collect();
    Mesh::new(positions, triangles)
}

/// A flat fan's outline shares no edge with a fill of it (the fan's edges all meet the centre),
/// but filling it would close the sheet into a two-sided pillow of volume 0: left open and said.
#[test]
fn a_flat_sheet_is_not_closed_into_a_pillow() {
    let p = plan(&hexagon_fan(0.0), &Options::default());
    assert_eq!(
        p.not_repairable,
        vec![
            "1 hole left open: filling would close a flat open surface into a shell with no volume"
        ]
    );
    assert!(!p.changes(), "{:?}", p.done);
}

/// Two flat fans sharing one rim vertex, with splitting off: their outlines meet at that vertex,
/// so a border loop may run through both. Nothing panics and neither is closed into a pillow.
#[test]
fn flat_fans_sharing_a_vertex_are_not_pillowed_with_splitting_off() {
    let a = hexagon_fan(0.0);
    let mut b = hexagon_fan(0.0);
    for p in &mut b.positions {
        p[0] += 2.0;
    }
    // Its rim vertex at angle 180 degrees, moved by 2, is the first fan's vertex at angle 0
    // (exactly, so the weld joins them: sin(pi) is not exactly 0).
    b.positions[4] = a.positions[1];
    let mesh = shapes::merge(&[a, b]);
    let before = analyse(&mesh, &Default::default());
    assert_eq!(before.nonmanifold_vertices, 1, "the fans share one vertex");
    let options = Options {
        split_nonmanifold: false,
        ..Options::default()
    };
    let p = plan(&mesh, &options);
    let out = analyse(&p.apply(&mesh), &Default::default());
    assert!(
        out.shells
            .iter()
            .all(|s| s.volume.is_some_and(|v| v.abs() > 1e-9)),
        "a flat pillow was made: {:?} ({:?})",
        out.shells,
        p.done
    );
}

/// The same fan with its centre raised is an open hexagonal pyramid: its base is filled (6 - 2 =
/// 4 faces), giving a closed genus-0 shell (V 7, E 15, F 10) of volume base x height / 3 =
/// (3 sqrt 3 / 2) x 1 / 3 = sqrt 3 / 2.
#[test]
fn an_open_pyramid_gets_its_base() {
    let (p, _, a) = repaired(&hexagon_fan(1.0));
    assert_eq!(p.summary(), "fill-holes:1(4 faces)");
    assert!(p.not_repairable.is_empty(), "{:?}", p.not_repairable);
    assert_eq!((a.holes(), a.shells.len(), a.genus()), (0, 1, Some(0)));
    assert_eq!((a.welded_vertices, a.edges, a.faces), (7, 15, 10));
    assert_close(a.shells[0].volume.unwrap(), 3f64.sqrt() / 2.0);
}

/// Every repair can be switched off: with all off, the plan is the input.
#[test]
fn repairs_switched_off_change_nothing() {
    let mesh = shapes::flipped(&shapes::cube());
    let off = Options {
        drop_degenerate_faces: false,
        drop_duplicate_faces: false,
        split_nonmanifold: false,
        orient_faces: false,
        flip_inside_out: false,
        fill_holes: false,
        drop_unreferenced_vertices: false,
        ..Options::default()
    };
    let p = plan(&mesh, &off);
    assert!(!p.changes());
    assert_eq!(p.apply(&mesh).triangles, mesh.triangles);
}

/// A shuffled torus with 10% of its faces flipped: orientation puts every face back (genus 1, closed,
/// oriented) by flipping exactly the flipped ones (the smaller side).
#[test]
fn torus_with_flipped_faces_is_reoriented() {
    let mut mesh = shapes::torus(20, 10, Some(7));
    let flipped: Vec<usize> = (0..mesh.triangles.len()).filter(|t| t % 10 == 3).collect();
    for &t in &flipped {
        mesh.triangles[t].swap(1, 2);
    }
    let (p, _, a) = repaired(&mesh);
    assert_eq!(p.summary(), format!("orient-faces:{}", flipped.len()));
    assert!(a.oriented());
    assert_eq!(a.genus(), Some(1));
    assert_eq!(a.inside_out_shells(), 0);
}

/// Every mesh of the shared corpus of real files (skipped when `../shared/corpus` is absent):
/// after repair no degenerate or duplicate face, no non-manifold edge or vertex, no inside-out
/// shell and no inconsistent edge in an orientable component is left, and a second repair changes
/// nothing.
#[test]
fn corpus_meshes_repair_cleanly_and_converge() {
    use meshvet::formats::{read, Format, ReadContext};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    if !root.is_dir() {
        println!("skipped: no shared corpus at {}", root.display());
        return;
    }
    let mut files = Vec::new();
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if Format::of_path(&path).is_some()
                && entry.metadata().unwrap().len() < 20_000_000
            {
                files.push(path);
            }
        }
    }
    files.sort();
    let cx = ReadContext {
        root: root.clone(),
        limits: Default::default(),
    };
    let (mut meshes, mut changed, mut failures) = (0, 0, Vec::new());
    for path in &files {
        let Ok(read) = read(path, Format::of_path(path).unwrap(), &cx) else {
            continue;
        };
        for mesh in read
            .iter()
            .filter(|m| !m.triangles.is_empty() && m.triangles.len() < 300_000)
        {
            meshes += 1;
            let p = plan(mesh, &Options::default());
            changed += usize::from(p.changes());
            let out = p.apply(mesh);
            let a = analyse(&out, &Default::default());
            let orientable_but_not_oriented =
                a.components.iter().any(|c| c.orientable && !c.oriented);
            let again = plan(&out, &Options::default());
            let left = [
                ("degenerate", a.degenerate_faces),
                ("duplicate", a.duplicate_faces),
                ("non-manifold edges", a.nonmanifold_edges),
                ("non-manifold vertices", a.nonmanifold_vertices),
                ("inside-out", a.inside_out_shells()),
                ("unoriented", usize::from(orientable_but_not_oriented)),
                ("second repair", usize::from(again.changes())),
            ];
            let left: Vec<String> = left
                .iter()
                .filter(|(_, n)| *n > 0)
                .map(|(w, n)| format!("{w} {n}"))
                .collect();
            if !left.is_empty() {
                let name = path.strip_prefix(&root).unwrap().display().to_string();
                failures.push(format!(
                    "{name} {:?}: {} (repairs {}; again {})",
                    mesh.name,
                    left.join(", "),
                    p.summary(),
                    again.summary()
                ));
            }
        }
    }
    println!(
        "corpus repair: {meshes} meshes, {changed} repaired, {} with defects left",
        failures.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Two unit cubes on the edge x = y = 1, z in [0, 1] (A in [0,1]^2, B in [1,2]^2) and a
/// triangular prism on the same edge in the free quadrant (base (1,1), (0.5,2), (0,1.5), area
/// 0.375): the edge has 6 faces. The two endpoints of the edge are the only non-manifold
/// vertices; each has three fans (one per shell), so each gets two copies (4 new vertices), but
/// 2 vertices were split and the count says 2. Result: three closed shells, V = 8 + 8 + 6 = 22
/// (18 before), volume 1 + 1 + 0.375 (less a hair for the nudged copies).
#[test]
fn each_split_vertex_counts_once_however_many_copies_it_gets() {
    let a = shapes::cuboid([0.0; 3], [1.0; 3]);
    let b = shapes::cuboid([1.0, 1.0, 0.0], [2.0, 2.0, 1.0]);
    let c = prism(&[[1.0, 1.0], [0.5, 2.0], [0.0, 1.5]], 0.0, 1.0);
    let mesh = shapes::merge(&[a, b, c]);
    let before = analyse(&mesh, &Default::default());
    assert_eq!(
        (
            before.nonmanifold_edges,
            before.nonmanifold_vertices,
            before.welded_vertices
        ),
        (1, 2, 18)
    );
    let (p, _, a) = repaired(&mesh);
    assert_eq!(
        p.summary(),
        "split-non-manifold-edges:1;split-non-manifold-vertices:2"
    );
    assert_eq!(p.new_vertices.len(), 4);
    assert_eq!((a.nonmanifold_edges, a.nonmanifold_vertices), (0, 0));
    assert_eq!((a.shells.len(), a.welded_vertices), (3, 22));
    assert!((a.volume().unwrap() - 2.375).abs() < 1e-3);
}

/// Three discs (fans around centres at z = 1, -1 and 0.5) glued along one triangle p q r, each
/// of their 9 faces wound either way (all 512 choices): every spine edge has 3 faces. Where the
/// kept pairs differ from edge to edge, a cut face stays in the kept pair's fan at both ends and
/// is detached whole. Whatever the path, `split-non-manifold-vertices` is the number of vertices
/// of the input that got a copy, counted from the output's geometry: an output vertex a hair
/// (under 1e-3) from an input vertex is a copy of it. The old count (3 per detached face, one per
/// copy) was larger whenever a vertex got two copies.
#[test]
fn split_count_is_the_number_of_vertices_that_got_copies() {
    let positions = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.3, 0.3, 1.0],
        [0.3, 0.3, -1.0],
        [0.3, 0.3, 0.5],
    ];
    let mut detached = 0;
    for variant in 0..512u32 {
        let mut triangles = Vec::new();
        for d in 0..3u32 {
            for (e, (x, y)) in [(0, 1), (1, 2), (2, 0)].into_iter().enumerate() {
                let reversed = variant >> (3 * d as usize + e) & 1 == 1;
                triangles.push(if reversed {
                    [3 + d, y, x]
                } else {
                    [3 + d, x, y]
                });
            }
        }
        let mesh = Mesh::new(positions.clone(), triangles);
        let p = plan(&mesh, &Options::default());
        let out = p.apply(&mesh);
        let a = analyse(&out, &Default::default());
        assert_eq!(
            (a.nonmanifold_edges, a.nonmanifold_vertices),
            (0, 0),
            "{variant}"
        );
        let mut copied: Vec<usize> = out
            .positions
            .iter()
            .filter_map(|q| {
                positions.iter().position(|o| {
                    let d = (0..3).map(|k| (q[k] - o[k]).powi(2)).sum::<f64>().sqrt();
                    d > 0.0 && d < 1e-3
                })
            })
            .collect();
        copied.sort_unstable();
        copied.dedup();
        assert_eq!(
            count(&p, Kind::SplitNonManifoldVertices),
            copied.len(),
            "{variant}"
        );
        // A disc centre is a manifold vertex: it gets a copy only when a face is detached whole.
        detached += usize::from(copied.iter().any(|&v| v >= 3));
    }
    assert!(detached > 0, "no variant went through the detaching path");
}

/// A cone over a loop of 7 points on the unit circle visited every third point (the star {7/3}):
/// its one hole's border crosses itself in its plane, so ear clipping finds no ear and the fan it
/// would fall back to overlaps itself. The fill is refused and the hole reported; the same for
/// the pentagram {5/2}, whose points are lifted so the loop is not flat (its fill would overlap
/// too). A simple concave loop (an arrow head of 4 points) is filled by ear clipping with 4 - 2 = 2
/// faces.
#[test]
fn holes_whose_border_crosses_itself_are_not_filled() {
    let cone = |angles: &[f64], lift: f64| {
        let n = angles.len() as u32;
        let mut positions: Vec<[f64; 3]> = angles
            .iter()
            .enumerate()
            .map(|(i, t)| [t.cos(), t.sin(), lift * i as f64])
            .collect();
        positions.push([0.0, 0.0, 1.0]);
        let triangles = (0..n).map(|i| [n, i, (i + 1) % n]).collect();
        Mesh::new(positions, triangles)
    };
    let tau = std::f64::consts::TAU;
    let star = |n: usize, step: usize| -> Vec<f64> {
        (0..n)
            .map(|i| (i * step % n) as f64 * tau / n as f64)
            .collect()
    };
    for (mesh, what) in [
        (cone(&star(7, 3), 0.0), "{7/3}"),
        (cone(&star(5, 2), 0.2), "{5/2}"),
    ] {
        let p = plan(&mesh, &Options::default());
        assert!(!p.changes(), "{what}: {}", p.summary());
        assert_eq!(
            p.not_repairable,
            vec!["1 hole left open: its border crosses or folds onto itself, so a fill could overlap itself"],
            "{what}"
        );
        let a = analyse(&p.apply(&mesh), &Default::default());
        assert_eq!(a.holes(), 1, "{what}");
    }
    // Arrow head: (2,0) tip, notch at (0.5,0), in the plane z = 0; the apex sits above it.
    let arrow = [
        [2.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.5, 0.0, 0.0],
        [0.0, -1.0, 0.0],
    ];
    let mut positions: Vec<[f64; 3]> = arrow.to_vec();
    positions.push([0.8, 0.0, 1.0]);
    let mesh = Mesh::new(positions, vec![[4, 0, 1], [4, 1, 2], [4, 2, 3], [4, 3, 0]]);
    let (p, _, a) = repaired(&mesh);
    assert_eq!(p.summary(), "fill-holes:1(2 faces)");
    assert_eq!((a.holes(), a.border_edges, a.shells.len()), (0, 0, 1));
    assert!(a.shells[0].volume.unwrap() > 0.0);
}

/// A closed prism over the counter-clockwise polygon `base` (x, y) from z = `z0` to `z1`, wound
/// outward.
fn prism(base: &[[f64; 2]], z0: f64, z1: f64) -> Mesh {
    let n = base.len() as u32;
    let mut positions = Vec::new();
    for z in [z0, z1] {
        positions.extend(base.iter().map(|p| [p[0], p[1], z]));
    }
    let mut triangles = Vec::new();
    for k in 1..n - 1 {
        triangles.push([0, k + 1, k]); // bottom, seen from below
        triangles.push([n, n + k, n + k + 1]); // top
    }
    for k in 0..n {
        let j = (k + 1) % n;
        triangles.push([k, j, n + j]);
        triangles.push([k, n + j, n + k]);
    }
    Mesh::new(positions, triangles)
}

/// A unit box without its top (the square z = 1 is a hole of 4 edges) and, beside it, a lone
/// triangle `(0.5,0.5,0.5) (0.6,0.5,1.5) (0.5,0.6,1.5)` that rises through the opening: it crosses
/// z = 1 along the segment (0.55,0.5,1)-(0.5,0.55,1), inside the square. Filling the top would
/// make two faces that meet that triangle, so the hole is left open and said; the triangle's own
/// outline cannot be filled (it would repeat the triangle). Nothing else is wrong: no repair.
#[test]
fn a_fill_that_would_cross_the_surface_is_left_open() {
    let mut open = shapes::cube();
    open.triangles.retain(|t| !t.iter().all(|&v| v & 4 != 0)); // the two faces at z = 1
    let spike = Mesh::new(
        vec![[0.5, 0.5, 0.5], [0.6, 0.5, 1.5], [0.5, 0.6, 1.5]],
        vec![[0, 1, 2]],
    );
    let mesh = shapes::merge(&[open, spike]);
    let before = analyse(&mesh, &Default::default());
    assert_eq!(
        (before.holes(), before.intersecting_components()),
        (2, Some(0))
    );
    let p = plan(&mesh, &Options::default());
    assert_eq!(
        p.not_repairable,
        vec![
            "1 hole left open: filling would overlap existing edges",
            "1 hole left open: filling would cross the rest of the surface"
        ]
    );
    assert!(!p.changes(), "{:?}", p.done);
    // The same box without the spike is filled (2 faces): only the crossing kept it open.
    let mut alone = shapes::cube();
    alone.triangles.retain(|t| !t.iter().all(|&v| v & 4 != 0));
    let (p, _, after) = repaired(&alone);
    assert_eq!(count(&p, Kind::FillHoles), 1);
    assert_eq!(
        (after.holes(), after.intersecting_components()),
        (0, Some(0))
    );
}

/// A 60 x 30 torus (3,600 faces) with twenty holes spread around it (the six faces around vertex
/// `(3k, 7k mod 30)` removed: rings of six edges, one column of faces apart) and a thin triangle
/// through the eighth hole, from half the tube's radius to one and a half along the line from the
/// tube's centre through the removed vertex: every fill of that hole is crossed by it (the fill
/// closes the tube there, and the line goes from inside to outside), no other fill is near it, and
/// the triangle touches no face left around the hole. So nineteen holes are filled, one is left
/// open for the crossing, and the triangle's own outline is left open as it would repeat the
/// triangle. The fills are checked against only the faces near them: this checks that every
/// fill is still checked, wherever it is.
#[test]
fn one_crossing_fill_among_many_is_left_open() {
    let (n, m) = (60, 30);
    let mut torus = shapes::torus(n, m, None);
    let holes: Vec<u32> = (0..20).map(|k| (3 * k * m + (7 * k) % m) as u32).collect();
    torus
        .triangles
        .retain(|t| !t.iter().any(|v| holes.contains(v)));
    let p = torus.positions[holes[7] as usize];
    let u = std::f64::consts::TAU * 21.0 / n as f64;
    let centre = [shapes::TORUS_R * u.cos(), shapes::TORUS_R * u.sin(), 0.0];
    let along = |s: f64| std::array::from_fn(|k| centre[k] + s * (p[k] - centre[k]));
    let outer: [f64; 3] = along(1.5);
    let aside = [
        outer[0] - 0.01 * u.sin(),
        outer[1] + 0.01 * u.cos(),
        outer[2],
    ];
    let spike = Mesh::new(vec![along(0.5), outer, aside], vec![[0, 1, 2]]);
    let mesh = shapes::merge(&[torus, spike]);
    let before = analyse(&mesh, &Default::default());
    assert_eq!(
        (before.holes(), before.intersecting_components()),
        (21, Some(0))
    );
    let (p, _, after) = repaired(&mesh);
    assert_eq!(count(&p, Kind::FillHoles), 19);
    assert_eq!(
        p.not_repairable,
        vec![
            "1 hole left open: filling would overlap existing edges",
            "1 hole left open: filling would cross the rest of the surface"
        ]
    );
    assert_eq!(
        (
            after.holes(),
            after.intersecting_components(),
            after.self_intersections()
        ),
        (2, Some(0), Some(0))
    );
}

/// Repairs `mesh` with `options`, checks that a second repair changes nothing, and analyses the
/// result welded as the options weld.
fn repaired_with(mesh: &Mesh, options: &Options) -> (Plan, Analysis) {
    let p = plan(mesh, options);
    let out = p.apply(mesh);
    let again = plan(&out, options);
    assert!(!again.changes(), "a second repair changed {:?}", again.done);
    let analysis = meshvet::analyse(
        &out,
        &meshvet::topology::Options {
            weld_tolerance: options.weld_tolerance,
            ..Default::default()
        },
    );
    (p, analysis)
}

/// Three lone triangles on one vertex O: the first keeps O; the other two fans have their centres
/// in one direction from O, (0.5, 0.5, 0) and (1, 1, 0), so both copies moved the same distance
/// (1e-5 of the model's size) towards them land on one point and weld together again: O stayed
/// non-manifold in the copy, and repairing the copy split it again. The second copy now moves
/// twice as far: three components, no non-manifold vertex, a second repair changes nothing.
#[test]
fn copies_of_one_vertex_towards_one_direction_stay_apart() {
    let positions = vec![
        [0.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 1.0],
        [1.0, 1.0, -1.0],
    ];
    let mesh = Mesh::new(positions, vec![[0, 1, 2], [0, 3, 4], [0, 5, 6]]);
    let (p, a) = repaired_with(&mesh, &Options::default());
    assert_eq!(p.summary(), "split-non-manifold-vertices:1");
    assert_eq!(p.new_vertices.len(), 2);
    assert_ne!(p.new_vertices[0].position, p.new_vertices[1].position);
    assert_eq!((a.nonmanifold_vertices, a.components.len()), (0, 3));
}

/// A bowtie (two triangles on vertex O, fan centres (1, 0.5, 0) and (-1, -0.5, 0), 1.118 from O)
/// welded with tolerance 0.4: a copy moved a quarter of the way to its fan's centre (0.28) is
/// within 0.4 of O and welds back onto it; moved half the way (0.56) it stays apart, and the copy
/// has no non-manifold vertex. With sliver fans whose centres lie 0.05 from O, no copy within
/// half the way is 0.4 from O: the vertex is left as it is, and the row says why. The place half
/// way, (0.6125, 0.0125, 0) for the fan O (0.45, 0, 0) (2, 0.05, 0), lies 0.16 from the fan's own
/// corner (0.45, 0, 0): a copy there would weld onto that corner and collapse the face, so that
/// fan keeps O and the other, O (0, 1, 0) (-1, 1, 0), takes the copy, half way to its centre at
/// (-0.25, 0.5, 0) (0.56 from O and from (0, 1, 0)). Three faces on an edge 0.5 long: the face cut loose cannot take copies of the edge's
/// vertices (its fans' centres lie 0.43 from them, half way is 0.22), so the edge is not counted
/// as split, and the row says so.
#[test]
fn split_copies_move_beyond_the_weld_tolerance_or_are_reported() {
    let options = Options {
        weld_tolerance: 0.4,
        ..Options::default()
    };
    let bowtie = shapes::bowtie();
    let (p, a) = repaired_with(&bowtie, &options);
    assert_eq!(p.summary(), "split-non-manifold-vertices:1");
    assert_eq!((a.nonmanifold_vertices, a.components.len()), (0, 2));

    let slivers = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [-1.0, 0.1, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.1, -1.0],
        ],
        vec![[0, 1, 2], [0, 3, 4]],
    );
    let corner = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
            [0.45, 0.0, 0.0],
            [2.0, 0.05, 0.0],
        ],
        vec![[0, 1, 2], [0, 3, 4]],
    );
    let (p, a) = repaired_with(&corner, &options);
    assert_eq!(p.new_vertices.len(), 1, "{:?}", p.new_vertices);
    assert_eq!(p.new_vertices[0].position, [-0.25, 0.5, 0.0]);
    assert_eq!((a.nonmanifold_vertices, a.degenerate_faces), (0, 0));

    let fin = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [0.5, 0.0, 0.0],
            [0.25, 0.433, 0.0],
            [0.25, -0.2165, 0.374989],
            [0.25, -0.2165, -0.374989],
        ],
        vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    );
    let (p, a) = repaired_with(&fin, &options);
    assert_eq!(count(&p, Kind::SplitNonManifoldEdges), 0);
    assert_eq!(a.nonmanifold_edges, 1);
    assert!(
        p.not_repairable.iter().any(|n| n
            .starts_with("1 non-manifold edge left as it is: a face on it could not be cut loose")),
        "{:?}",
        p.not_repairable
    );

    let (p, a) = repaired_with(&slivers, &options);
    assert_eq!(count(&p, Kind::SplitNonManifoldVertices), 0);
    assert!(p.new_vertices.is_empty());
    assert_eq!(a.nonmanifold_vertices, 1);
    assert!(
        p.not_repairable.contains(
            &"1 non-manifold vertex left as it is: a fan around it is too small to move a copy \
              of the vertex clear of it (the copy would weld back; lower weld_tolerance)"
                .to_owned()
        ),
        "{:?}",
        p.not_repairable
    );
}

/// A triangle and a sliver on one vertex O, welded with tolerance 0.4: the sliver's fan centre
/// lies 0.05 from O, too near for a copy of O to move clear of it, while the triangle's lies 1.118
/// away (half way is 0.56 from O and from its corners). Whichever fan comes first in the file,
/// the triangle takes the copy and the sliver keeps O: split, no non-manifold vertex left.
#[test]
fn the_split_does_not_hang_on_which_fan_comes_first() {
    let options = Options {
        weld_tolerance: 0.4,
        ..Options::default()
    };
    let positions = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.1, -1.0],
    ];
    for faces in [vec![[0, 1, 2], [0, 3, 4]], vec![[0, 3, 4], [0, 1, 2]]] {
        let mesh = Mesh::new(positions.clone(), faces.clone());
        let (p, a) = repaired_with(&mesh, &options);
        assert_eq!(p.summary(), "split-non-manifold-vertices:1", "{faces:?}");
        assert_eq!(a.nonmanifold_vertices, 0, "{faces:?}");
    }
}

/// Holes are traced within their fans at a vertex they share: the bowtie left unsplit
/// (`split_nonmanifold` off) has two border loops of three edges through its pinch vertex, as the
/// analysis counts them (`holes` 2), and each fill would repeat its triangle: "2 holes left open".
/// Two open boxes touching at a corner of their rims, (1, 1, 1): each rim, a 4-edge loop through
/// the pinch, is filled (2 faces each); the pinch stays.
#[test]
fn holes_are_traced_within_their_fans_at_a_pinch() {
    let options = Options {
        split_nonmanifold: false,
        ..Options::default()
    };
    let bowtie = shapes::bowtie();
    assert_eq!(analyse(&bowtie, &Default::default()).holes(), 2);
    let p = plan(&bowtie, &options);
    assert_eq!(
        p.not_repairable,
        ["2 holes left open: filling would overlap existing edges"]
    );

    let open = |lo: f64, keep: fn(&[u32; 3]) -> bool| {
        let mut box_ = shapes::cuboid([lo; 3], [lo + 1.0; 3]);
        box_.triangles.retain(keep);
        box_
    };
    // Vertices 4-7 are the top (z = hi), 0-3 the bottom.
    let no_top = open(0.0, |t| !t.iter().all(|&v| v >= 4));
    let no_bottom = open(1.0, |t| !t.iter().all(|&v| v < 4));
    let boxes = shapes::merge(&[no_top, no_bottom]);
    let p = plan(&boxes, &options);
    assert_eq!(p.summary(), "fill-holes:2(4 faces)");
    assert!(p.not_repairable.is_empty(), "{:?}", p.not_repairable);
    let a = analyse(&p.apply(&boxes), &Default::default());
    assert_eq!((a.holes(), a.nonmanifold_vertices), (0, 1));
}

/// Two square holes meeting corner to corner: the 2 x 2 plate (a closed slab) with the top faces
/// of its cells (0, 0) and (1, 1) removed. Traced around their fans the two borders are one loop
/// through the top centre (1, 1) twice, a figure-eight; split there, each 4-edge square is filled
/// with 2 faces, and the slab is closed again, its centre vertex manifold (before: one hole, or
/// none, was filled).
#[test]
fn holes_meeting_corner_to_corner_are_both_filled() {
    let mut slab = shapes::plate(2, 2, &[]);
    // Top vertex (x, y) is 3 y + x.
    let cell = |x: u32, y: u32| [3 * y + x, 3 * y + x + 1, 3 * y + x + 4, 3 * y + x + 3];
    slab.triangles.retain(|t| {
        ![cell(0, 0), cell(1, 1)]
            .iter()
            .any(|c| t.iter().all(|v| c.contains(v)))
    });
    assert_eq!(slab.triangles.len(), 28);
    let options = Options {
        split_nonmanifold: false,
        ..Options::default()
    };
    let p = plan(&slab, &options);
    assert_eq!(p.summary(), "fill-holes:2(4 faces)");
    let a = analyse(&p.apply(&slab), &Default::default());
    assert_eq!(
        (a.border_edges, a.holes(), a.nonmanifold_vertices),
        (0, 0, 0)
    );
    let again = plan(&p.apply(&slab), &options);
    assert!(!again.changes(), "{:?}", again.done);
}

/// A triangle and a small fan on one vertex O, welded with tolerance 0.4: the small fan
/// (O (0.5, 0.2, 0) (0.3, 0.55, 0), centre 0.55 from O) cannot take a copy (half way is 0.27 from
/// O), so the triangle (O (3, 0, 0) (3, 1, 0), fan centre (3, 0.5, 0)) takes it. A quarter of the
/// way, (0.75, 0.125, 0), is clear of O but 0.26 from the small fan's corner (0.5, 0.2, 0): a copy
/// there would weld onto it and pinch again (before: a split was claimed, the copy still pinched,
/// and a second repair moved it again). The copy must keep clear of every fan's corners: half way,
/// (1.5, 0.25, 0), 1.0 from that corner.
#[test]
fn a_split_copy_keeps_clear_of_every_fan_of_its_vertex() {
    let options = Options {
        weld_tolerance: 0.4,
        ..Options::default()
    };
    let mesh = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [3.0, 1.0, 0.0],
            [0.5, 0.2, 0.0],
            [0.3, 0.55, 0.0],
        ],
        vec![[0, 1, 2], [0, 3, 4]],
    );
    let (p, a) = repaired_with(&mesh, &options);
    assert_eq!(p.summary(), "split-non-manifold-vertices:1");
    assert_eq!(p.new_vertices.len(), 1);
    assert_eq!(p.new_vertices[0].position, [1.5, 0.25, 0.0]);
    assert_eq!(a.nonmanifold_vertices, 0);
}

/// A bowtie whose coordinates lie far beyond `f32`'s range (1e300): the split's copy is placed a
/// fraction of the way to its fan's centre, about 1e299 from the origin. Rounded to `f32` it would
/// be infinite, so the copy keeps its exact `f64` place and stays finite (and apart from O).
#[test]
fn a_split_far_beyond_f32_range_places_a_finite_copy() {
    let mut bowtie = shapes::bowtie();
    for p in &mut bowtie.positions {
        *p = p.map(|x| x * 1e300);
    }
    let p = plan(&bowtie, &Options::default());
    assert_eq!(p.summary(), "split-non-manifold-vertices:1");
    assert_eq!(p.new_vertices.len(), 1);
    let copy = p.new_vertices[0].position;
    assert!(copy.iter().all(|x| x.is_finite()), "copy at {copy:?}");
    assert_ne!(copy, [0.0; 3]);
}
