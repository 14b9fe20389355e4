//! Repaired copies written by `formats::write`: for each format a small hand-made file (textured or
//! coloured where the format allows) and a hand-built plan (two faces flipped, one dropped and
//! added back as a fill, a vertex copy, an unreferenced vertex dropped). The copy is read back
//! through `formats::read` and must hold exactly `plan.apply(&mesh)` (up to vertex numbering) with
//! its attributes; sources are hashed before and after and must not change.

use std::collections::hash_map::DefaultHasher;
use std::collections::{BTreeMap, BTreeSet};
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};

use meshvet::formats::write::{write_copy, write_repaired, ScanRead, Written};
use meshvet::formats::{read, Format, Limits, ReadContext};
use meshvet::repair::{Corner, Kind, NewVertex, Plan, Triangle};
use meshvet::Mesh;
use serde_json::{json, Value};

fn cx(root: &Path) -> ReadContext {
    ReadContext {
        root: root.to_path_buf(),
        limits: Limits::default(),
    }
}

/// Every file under `dir` with a hash of its bytes.
fn hash_tree(dir: &Path) -> BTreeMap<PathBuf, u64> {
    let mut out = BTreeMap::new();
    for entry in walkdir::WalkDir::new(dir).into_iter().flatten() {
        if entry.file_type().is_file() {
            let mut h = DefaultHasher::new();
            std::fs::read(entry.path()).unwrap().hash(&mut h);
            out.insert(entry.path().to_path_buf(), h.finish());
        }
    }
    out
}

fn identity(mesh: &Mesh) -> Plan {
    Plan {
        triangles: mesh
            .triangles
            .iter()
            .enumerate()
            .map(|(t, tri)| Triangle {
                corners: [0, 1, 2].map(|k| Corner {
                    vertex: tri[k],
                    from: 3 * t as u32 + k as u32,
                }),
                source: Some(t as u32),
                near: t as u32,
                flipped: false,
            })
            .collect(),
        new_vertices: Vec::new(),
        used_vertices: vec![true; mesh.positions.len()],
        done: Vec::new(),
        not_repairable: Vec::new(),
    }
}

fn flip(t: &mut Triangle) {
    t.corners.swap(1, 2);
    t.flipped = !t.flipped;
}

/// Flips `flips`, gives corner 0 of triangle `copy` a copy of its vertex (moved a little), drops
/// triangle `drop` and adds it back at the end as a fill near `near`, and drops every vertex no
/// triangle uses.
fn hand_plan(mesh: &Mesh, flips: &[usize], copy: usize, drop: usize, near: u32) -> Plan {
    let mut p = identity(mesh);
    for &t in flips {
        flip(&mut p.triangles[t]);
    }
    let v = p.triangles[copy].corners[0].vertex;
    let q = mesh.positions[v as usize];
    p.new_vertices.push(NewVertex {
        copy_of: v,
        position: [q[0] + 0.125, q[1] + 0.25, q[2] - 0.125],
    });
    p.triangles[copy].corners[0].vertex = mesh.positions.len() as u32;
    let mut fill = p.triangles.remove(drop);
    fill.source = None;
    fill.near = near;
    p.triangles.push(fill);
    p.used_vertices = vec![false; mesh.positions.len() + 1];
    for t in &p.triangles {
        for c in &t.corners {
            p.used_vertices[c.vertex as usize] = true;
        }
    }
    let unused = p.used_vertices.iter().filter(|u| !**u).count();
    p.done = vec![(Kind::OrientFaces, flips.len(), None)];
    if unused > 0 {
        p.done.push((Kind::DropUnreferencedVertices, unused, None));
    }
    p
}

/// The triangles as position triples (f32 bits, as most formats store them), each rotated to
/// start at its smallest corner, sorted: equal for two meshes that differ only in vertex
/// numbering, triangle order or corner rotation.
fn shape(m: &Mesh) -> Vec<[[u32; 3]; 3]> {
    let mut out: Vec<[[u32; 3]; 3]> = m
        .triangles
        .iter()
        .map(|t| {
            // NaN is NaN whatever its sign bit (text formats do not keep it).
            let bits = |x: f64| {
                if x.is_nan() {
                    f32::NAN.to_bits()
                } else {
                    (x as f32).to_bits()
                }
            };
            let p = t.map(|v| m.positions[v as usize].map(bits));
            let k = (0..3).min_by_key(|&k| p[k]).unwrap();
            [p[k], p[(k + 1) % 3], p[(k + 2) % 3]]
        })
        .collect();
    out.sort();
    out
}

/// Writes `plan` for `source` to `out`, checks the source tree is untouched and the copy holds
/// the planned triangles; returns the source mesh and the copy's meshes.
fn round_trip(
    source: &Path,
    format: Format,
    plans: &[Option<Plan>],
    out: &Path,
) -> (Vec<Mesh>, Vec<Mesh>) {
    let root = source.parent().unwrap();
    let c = cx(root);
    let before = hash_tree(root);
    let meshes = read(source, format, &c).unwrap();
    let written = write_repaired(source, format, plans, out, &c).unwrap();
    assert_eq!(written[0], out);
    // A repairing scan's read keeps what the writer needs (the same meshes as a plain read);
    // the copy written from it is the same, byte for byte.
    let (kept_meshes, retained) = meshvet::formats::read_retaining(source, format, &c).unwrap();
    assert_eq!(kept_meshes, meshes);
    if format == Format::Obj {
        assert!(retained.is_some(), "an OBJ read keeps its detail");
    }
    let elsewhere = out.parent().unwrap().join("from-retained");
    let other = elsewhere.join(out.file_name().unwrap());
    let scanned = ScanRead {
        meshes: &kept_meshes,
        retained,
    };
    write_copy(source, format, plans, &other, &c, Some(scanned)).unwrap();
    assert_eq!(
        std::fs::read(&other).unwrap(),
        std::fs::read(out).unwrap(),
        "the copy written from the scan's read differs from the one written after reading again"
    );
    std::fs::remove_dir_all(&elsewhere).unwrap();
    assert_eq!(before, hash_tree(root), "the source tree changed");
    let copy = read(out, format, &cx(out.parent().unwrap())).unwrap();
    assert_eq!(copy.len(), meshes.len());
    for ((mesh, plan), again) in meshes.iter().zip(plans).zip(&copy) {
        let expected = match plan {
            Some(plan) => plan.apply(mesh),
            None => mesh.clone(),
        };
        assert_eq!(shape(again), shape(&expected));
    }
    (meshes, copy)
}

fn dirs() -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("src");
    let out = dir.path().join("out");
    std::fs::create_dir_all(src.join("tex")).unwrap();
    (dir, src, out)
}

/// A repairing scan reads an OBJ once: its copy is written from what the scan's read kept, not
/// from the file read again. Here the file changes between the read and the write, and the copy
/// is still of what was read: a cube of quads without its top (10 triangles, one hole of four
/// edges), its hole filled with 2 triangles.
#[test]
fn obj_copy_is_written_from_the_scans_read() {
    let (_dir, src, out) = dirs();
    let source = src.join("box.obj");
    let [open_box, _] = open_box_and_triangle(Format::Obj);
    std::fs::write(&source, open_box).unwrap();
    let c = cx(&src);
    let (mut meshes, retained) =
        meshvet::formats::read_retaining(&source, Format::Obj, &c).unwrap();
    let mesh = meshes.remove(0);
    assert_eq!(mesh.triangles.len(), 10);
    let plan = meshvet::repair::plan(&mesh, &Default::default());
    assert_eq!(plan.summary(), "fill-holes:1(2 faces)");
    std::fs::write(&source, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let copy = out.join("box.obj");
    let scanned = ScanRead {
        meshes: std::slice::from_ref(&mesh),
        retained,
    };
    write_copy(
        &source,
        Format::Obj,
        &[Some(plan)],
        &copy,
        &c,
        Some(scanned),
    )
    .expect("the copy is written from the read the scan kept");
    let again = read(&copy, Format::Obj, &cx(&out)).unwrap().remove(0);
    assert_eq!((again.positions.len(), again.triangles.len()), (8, 12));
}

/// The cube's quads without its top (`QUADS` but `4 5 6 7`), 0-based.
fn open_box() -> Vec<[u32; 4]> {
    QUADS.into_iter().filter(|q| *q != [4, 5, 6, 7]).collect()
}

/// The open box as a file of `format` (text encodings), and one triangle as the same format.
fn open_box_and_triangle(format: Format) -> [String; 2] {
    let points = |n: usize| -> String {
        CUBE[..n]
            .iter()
            .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
            .collect()
    };
    // Each quad as a line of `prefix` and its numbers from `base`.
    let quads = |prefix: &str, base: u32| -> String {
        open_box()
            .iter()
            .map(|q| format!("{prefix} {}\n", q.map(|v| (v + base).to_string()).join(" ")))
            .collect()
    };
    let ply = |v: usize, f: usize| {
        format!("ply\nformat ascii 1.0\nelement vertex {v}\nproperty float x\nproperty float y\nproperty float z\nelement face {f}\nproperty list uchar int vertex_indices\nend_header\n")
    };
    let stl = |triangles: &[[u32; 3]]| {
        let mut text = "solid box\n".to_owned();
        for t in triangles {
            text.push_str("facet normal 0 0 0\nouter loop\n");
            for &v in t {
                let p = CUBE[v as usize];
                text.push_str(&format!("vertex {} {} {}\n", p[0], p[1], p[2]));
            }
            text.push_str("endloop\nendfacet\n");
        }
        text + "endsolid box\n"
    };
    let obj_points = |n| {
        points(n)
            .lines()
            .map(|l| format!("v {l}\n"))
            .collect::<String>()
    };
    match format {
        Format::Obj => [obj_points(8) + &quads("f", 1), obj_points(3) + "f 1 2 3\n"],
        Format::Off => [
            "OFF\n8 5 0\n".to_owned() + &points(8) + &quads("4", 0),
            "OFF\n3 1 0\n".to_owned() + &points(3) + "3 0 1 2\n",
        ],
        Format::Ply => [
            ply(8, 5) + &points(8) + &quads("4", 0),
            ply(3, 1) + &points(3) + "3 0 1 2\n",
        ],
        _ => {
            let split: Vec<[u32; 3]> = open_box()
                .iter()
                .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
                .collect();
            [stl(&split), stl(&[[0, 1, 2]])]
        }
    }
}

/// A writer that reads its source again refuses the copy when the file changed after the scan
/// read it (the plans were made for what the scan read): an open box is read and planned (its
/// hole filled), then the file is replaced by one triangle before the copy is written. No copy
/// is written, and the message says why and what to do.
#[test]
fn a_source_changed_after_the_scan_read_it_is_not_copied() {
    for format in [Format::Obj, Format::Off, Format::Ply, Format::Stl] {
        let (_dir, src, out) = dirs();
        let source = src.join(format!("box.{}", format.name()));
        let [open_box, triangle] = open_box_and_triangle(format);
        std::fs::write(&source, open_box).unwrap();
        let c = cx(&src);
        let meshes = read(&source, format, &c).unwrap();
        assert_eq!(meshes[0].triangles.len(), 10, "{format:?}");
        let plan = meshvet::repair::plan(&meshes[0], &Default::default());
        assert_eq!(plan.summary(), "fill-holes:1(2 faces)", "{format:?}");
        std::fs::write(&source, triangle).unwrap();
        let copy = out.join(source.file_name().unwrap());
        let scanned = ScanRead {
            meshes: &meshes,
            retained: None,
        };
        let refused = write_copy(&source, format, &[Some(plan)], &copy, &c, Some(scanned));
        assert_eq!(
            refused.map_err(|e| e.to_string()),
            Err("the file changed after the scan read it: scan it again to repair it".into()),
            "{format:?}"
        );
        assert!(!copy.exists(), "{format:?}");
    }
}

/// Unit cube corners and its six outward quads (counter-clockwise seen from outside).
const CUBE: [[f64; 3]; 8] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [1.0, 1.0, 1.0],
    [0.0, 1.0, 1.0],
];
const QUADS: [[u32; 4]; 6] = [
    [0, 3, 2, 1],
    [4, 5, 6, 7],
    [0, 1, 5, 4],
    [2, 3, 7, 6],
    [0, 4, 7, 3],
    [1, 2, 6, 5],
];
const NORMALS: [[i32; 3]; 6] = [
    [0, 0, -1],
    [0, 0, 1],
    [0, -1, 0],
    [0, 1, 0],
    [-1, 0, 0],
    [1, 0, 0],
];

fn lines_with<'a>(text: &'a str, keyword: &str) -> Vec<&'a str> {
    text.lines()
        .filter(|l| l.split_whitespace().next() == Some(keyword))
        .collect()
}

/// Writes `obj` as `m.obj` in `tree` (the scanned tree), reads it (one triangle) and writes its
/// copy unchanged to `out/m.obj`; the files written.
fn copy_obj_unchanged(tree: &Path, obj: &str, out: &Path) -> Vec<PathBuf> {
    let source = tree.join("m.obj");
    std::fs::write(&source, obj).unwrap();
    let mesh = read(&source, Format::Obj, &cx(tree)).unwrap().remove(0);
    assert_eq!(mesh.triangles.len(), 1);
    let plans = [Some(identity(&mesh))];
    write_repaired(&source, Format::Obj, &plans, &out.join("m.obj"), &cx(tree)).unwrap()
}

/// A copy's material libraries and textures are read as the reader reads them: a library or
/// texture that is a link to a file outside the scanned tree is neither read nor copied (the
/// reader refuses it too), and a library named on many lines is copied once.
#[cfg(unix)]
#[test]
fn obj_copies_no_linked_file_from_outside_the_tree_and_each_library_once() {
    let dir = tempfile::tempdir().unwrap();
    let (tree, out) = (dir.path().join("tree"), dir.path().join("out"));
    std::fs::create_dir_all(&tree).unwrap();
    let secret = dir.path().join("secret.txt");
    std::fs::write(&secret, "outside the tree").unwrap();
    std::os::unix::fs::symlink(&secret, tree.join("linked.mtl")).unwrap();
    std::os::unix::fs::symlink(&secret, tree.join("linked.png")).unwrap();
    std::fs::write(
        tree.join("real.mtl"),
        "newmtl m\nKd 1 1 1\nmap_Kd linked.png\nmap_Ks in.png\n",
    )
    .unwrap();
    std::fs::write(tree.join("in.png"), "inside").unwrap();
    let mut obj = "mtllib linked.mtl\nmtllib real.mtl\n".repeat(1000);
    obj += "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n";
    let files = copy_obj_unchanged(&tree, &obj, &out);
    let names: Vec<String> = files
        .iter()
        .map(|f| f.strip_prefix(&out).unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["m.obj", "real.mtl", "in.png"]);
    for entry in walkdir::WalkDir::new(&out).into_iter().flatten() {
        if entry.file_type().is_file() {
            let bytes = std::fs::read(entry.path()).unwrap();
            assert_ne!(bytes, b"outside the tree", "{}", entry.path().display());
        }
    }
}

/// An OBJ and its library with bare-CR (classic Mac OS) line ends, as the reader takes them: the
/// copy gets the library and the texture it names.
#[test]
fn obj_copy_of_a_bare_cr_file_keeps_its_library_and_texture() {
    let (_dir, src, out) = dirs();
    std::fs::write(src.join("m.mtl"), "newmtl m\rKd 1 1 1\rmap_Kd tex/m.png\r").unwrap();
    std::fs::write(src.join("tex/m.png"), "texture").unwrap();
    let obj = "mtllib m.mtl\rv 0 0 0\rv 1 0 0\rv 0 1 0\rusemtl m\rf 1 2 3\r";
    let files = copy_obj_unchanged(&src, obj, &out);
    assert_eq!(
        files,
        [out.join("m.obj"), out.join("m.mtl"), out.join("tex/m.png")]
    );
}

/// Libraries and textures reached through `../` (shared folders of the scanned tree) are copied
/// beside the file that names them, under their file names, and the names are rewritten: the
/// copy's `mtllib ../materials/shared.mtl` becomes `mtllib shared.mtl`, the copied `box.mtl`'s
/// `map_Kd ../textures/wood.png` becomes `map_Kd wood.png` (the same file `shared.mtl` names as
/// `../textures/wood.png` from its own folder: copied once), and `../other/box.mtl`, whose name is
/// taken by the copy's own `box.mtl`, becomes `box-1.mtl`. A texture below a moved library's folder
/// keeps its name (`metal.png`), one below the OBJ's folder its place (`tex/local.png`). What
/// cannot be copied (a missing library, a texture outside the tree) keeps its name, with a note.
/// The copy, read again from the output tree alone, finds every library.
#[test]
fn obj_copy_brings_libraries_and_textures_from_shared_folders() {
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    for d in ["models/tex", "materials", "textures", "other"] {
        std::fs::create_dir_all(tree.join(d)).unwrap();
    }
    std::fs::write(dir.path().join("outside.png"), "outside the tree").unwrap();
    std::fs::write(
        tree.join("models/box.mtl"),
        "newmtl wood\r\nKd 1 1 1\r\nmap_Kd ../textures/wood.png\r\nmap_Ks -s 1 1 1 tex/local.png\r\nbump ../../outside.png\r\n",
    )
    .unwrap();
    std::fs::write(tree.join("models/tex/local.png"), "local").unwrap();
    std::fs::write(
        tree.join("materials/shared.mtl"),
        "newmtl metal\nKd 0.5 0.5 0.5\nmap_Kd metal.png\nmap_Ks ../textures/wood.png\n",
    )
    .unwrap();
    std::fs::write(tree.join("materials/metal.png"), "metal").unwrap();
    std::fs::write(tree.join("textures/wood.png"), "wood").unwrap();
    std::fs::write(tree.join("other/box.mtl"), "newmtl other\nKd 0 1 0\n").unwrap();
    let source = tree.join("models/box.obj");
    std::fs::write(
        &source,
        "mtllib box.mtl\nmtllib ../materials/shared.mtl\nmtllib ../materials/missing.mtl\nmtllib ../other/box.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl wood\nf 1 2 3\n",
    )
    .unwrap();
    let before = hash_tree(&tree);
    let mesh = read(&source, Format::Obj, &cx(&tree)).unwrap().remove(0);
    let out = dir.path().join("out/models");
    let written = write_copy(
        &source,
        Format::Obj,
        &[Some(identity(&mesh))],
        &out.join("box.obj"),
        &cx(&tree),
        None,
    )
    .unwrap();
    assert_eq!(hash_tree(&tree), before, "the sources changed");
    let files: BTreeSet<String> = written
        .files
        .iter()
        .map(|f| f.strip_prefix(&out).unwrap().to_string_lossy().into_owned())
        .collect();
    let expected: BTreeSet<String> = [
        "box.obj",
        "box.mtl",
        "wood.png",
        "tex/local.png",
        "shared.mtl",
        "metal.png",
        "box-1.mtl",
    ]
    .map(String::from)
    .into();
    assert_eq!(files, expected);
    let text = std::fs::read_to_string(out.join("box.obj")).unwrap();
    assert_eq!(
        lines_with(&text, "mtllib"),
        [
            "mtllib box.mtl",
            "mtllib shared.mtl",
            "mtllib ../materials/missing.mtl",
            "mtllib box-1.mtl"
        ]
    );
    assert_eq!(
        std::fs::read_to_string(out.join("box.mtl")).unwrap(),
        "newmtl wood\r\nKd 1 1 1\r\nmap_Kd wood.png\r\nmap_Ks -s 1 1 1 tex/local.png\r\nbump ../../outside.png\r\n"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("shared.mtl")).unwrap(),
        "newmtl metal\nKd 0.5 0.5 0.5\nmap_Kd metal.png\nmap_Ks wood.png\n"
    );
    for (file, bytes) in [
        ("wood.png", "wood"),
        ("tex/local.png", "local"),
        ("metal.png", "metal"),
        ("box-1.mtl", "newmtl other\nKd 0 1 0\n"),
    ] {
        assert_eq!(
            std::fs::read_to_string(out.join(file)).unwrap(),
            bytes,
            "{file}"
        );
    }
    assert_eq!(written.notes.len(), 2, "{:?}", written.notes);
    assert!(
        written.notes[0].starts_with("texture `../../outside.png` (named in `box.mtl`) is not copied: its path is absolute or leaves the scanned tree"),
        "{:?}",
        written.notes
    );
    assert!(
        written.notes[1].starts_with(
            "material library `../materials/missing.mtl` is not copied: there is no such file"
        ),
        "{:?}",
        written.notes
    );
    // Read from the output tree alone, the copy finds its libraries (only the missing one is
    // noted, as in the source).
    let again = read(&out.join("box.obj"), Format::Obj, &cx(&out)).unwrap();
    let mtl_notes: Vec<&String> = again[0]
        .notes
        .iter()
        .filter(|n| n.contains("material library"))
        .collect();
    assert_eq!(mtl_notes.len(), 1, "{mtl_notes:?}");
    assert!(
        mtl_notes[0].contains("`../materials/missing.mtl`"),
        "{mtl_notes:?}"
    );
}

/// A textured OBJ cube in two groups and materials, with an unreferenced vertex; quad 0 flipped
/// whole (written back as the reversed quad), one triangle of quad 1 flipped (written as
/// triangles), one triangle of quad 2 dropped and filled, a vertex copy on quad 3.
#[test]
fn obj_keeps_uvs_normals_groups_and_materials() {
    let (_dir, src, out) = dirs();
    let mut obj = String::from("# test cube\nmtllib cube.mtl\n");
    for p in CUBE {
        obj += &format!("v {} {} {} 0.5 0.5 0.5\n", p[0], p[1], p[2]);
    }
    obj += "v 9 9 9\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n";
    for n in NORMALS {
        obj += &format!("vn {} {} {}\n", n[0], n[1], n[2]);
    }
    obj += "o cube\ng sides\nusemtl red\ns 1\n";
    for (f, q) in QUADS.iter().enumerate() {
        if f == 4 {
            obj += "g top\nusemtl blue\n";
        }
        obj += "f";
        for (k, v) in q.iter().enumerate() {
            obj += &format!(" {}/{}/{}", v + 1, k + 1, f + 1);
        }
        obj += "\n";
    }
    std::fs::write(src.join("cube.obj"), &obj).unwrap();
    std::fs::write(
        src.join("cube.mtl"),
        "newmtl red\nKd 1 0 0\nmap_Kd -s 1 1 1 tex/red.png\nnewmtl blue\nKd 0 0 1\nmap_Kd ../../etc/passwd\n",
    )
    .unwrap();
    std::fs::write(src.join("tex/red.png"), b"not really a png").unwrap();

    let mesh = read(&src.join("cube.obj"), Format::Obj, &cx(&src))
        .unwrap()
        .remove(0);
    let plan = hand_plan(&mesh, &[0, 1, 2], 6, 4, 5);
    let copy_path = out.join("cube.obj");
    let (_, copy) = round_trip(
        &src.join("cube.obj"),
        Format::Obj,
        &[Some(plan.clone())],
        &copy_path,
    );
    // Vertices: 8 kept + 1 copy, the unreferenced one dropped.
    assert_eq!(copy[0].positions.len(), 9);
    let text = std::fs::read_to_string(&copy_path).unwrap();
    assert_eq!(lines_with(&text, "vt").len(), 4, "{text}");
    // Quad 0 flipped whole: its normal (0 0 -1) now disagrees with the winding and gets a
    // negated copy; quad 1's flipped triangle negates its normal at the corner only it uses.
    let vn = lines_with(&text, "vn");
    assert_eq!(vn.len(), 8, "{text}");
    assert!(
        vn.contains(&"vn 0 0 1") && vn.contains(&"vn -0 -0 1"),
        "{vn:?}"
    );
    assert!(vn.contains(&"vn -0 -0 -1"), "{vn:?}");
    // Vertex colours kept, also on the copy.
    assert_eq!(
        lines_with(&text, "v")
            .iter()
            .filter(|l| l.ends_with("0.5 0.5 0.5"))
            .count(),
        9
    );
    assert_eq!(lines_with(&text, "usemtl"), ["usemtl red", "usemtl blue"]);
    assert_eq!(lines_with(&text, "g"), ["g sides", "g top"]);
    assert_eq!(lines_with(&text, "o"), ["o cube"]);
    assert_eq!(lines_with(&text, "mtllib"), ["mtllib cube.mtl"]);
    // Quad 0 is one reversed quad with its own corners; quads 3-5 whole; 1 and 2 as triangles.
    let faces = lines_with(&text, "f");
    assert_eq!(faces[0], "f 1/1/7 2/4/7 3/3/7 4/2/7", "{text}");
    assert_eq!(
        faces
            .iter()
            .filter(|f| f.split_whitespace().count() == 5)
            .count(),
        3,
        "{text}"
    );
    assert_eq!(faces.len(), 3 + 6);
    // The fill comes right after the rest of its group (sides), before `g top`.
    let fill_at = text.find("g top").unwrap();
    assert!(
        text[..fill_at]
            .trim_end()
            .ends_with("\nf 1/1/3 2/2/3 6/3/3"),
        "{text}"
    );
    // Material library and the texture it names are copied; the path out of the folder is not.
    assert!(out.join("cube.mtl").is_file() && out.join("tex/red.png").is_file());
    assert!(!out.join("../etc/passwd").exists());
    // Every corner keeps its texture coordinate: same (position, vt) pairs as the source.
    let uv_pairs = |text: &str| -> BTreeSet<(String, String)> {
        let v = lines_with(text, "v");
        lines_with(text, "f")
            .iter()
            .flat_map(|f| f.split_whitespace().skip(1))
            .map(|c| {
                let mut parts = c.split('/');
                let p = v[parts.next().unwrap().parse::<usize>().unwrap() - 1].to_string();
                (p, parts.next().unwrap().to_string())
            })
            .collect()
    };
    let before = uv_pairs(&obj);
    let after = uv_pairs(&text);
    assert!(
        after
            .iter()
            .filter(|(p, _)| p.starts_with("v 1.125"))
            .count()
            == 1
    );
    assert!(after
        .iter()
        .all(|pair| before.contains(pair) || pair.0.starts_with("v 1.125")));
}

/// PLY with colours, normals and a custom property, in all three encodings.
fn ply_bytes(encoding: &str) -> Vec<u8> {
    let mut header = format!(
        "ply\nformat {encoding} 1.0\ncomment made by a test\nelement vertex 9\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty float quality\nelement face 6\nproperty list uchar int vertex_indices\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    );
    let mut positions = CUBE.to_vec();
    positions.push([9.0, 9.0, 9.0]);
    let vertex_normal = |p: [f64; 3]| p.map(|x| (x - 0.5) as f32);
    let mut body = Vec::new();
    let big = encoding == "binary_big_endian";
    let put = |b: &mut Vec<u8>, bytes: &[u8]| {
        if big {
            b.extend(bytes.iter().rev());
        } else {
            b.extend_from_slice(bytes);
        }
    };
    for (i, p) in positions.iter().enumerate() {
        let n = vertex_normal(*p);
        let colour = [10 * i as u8, 100, 200];
        if encoding == "ascii" {
            header += &format!(
                "{} {} {} {} {} {} {} {} {} {}\n",
                p[0],
                p[1],
                p[2],
                n[0],
                n[1],
                n[2],
                colour[0],
                colour[1],
                colour[2],
                i as f32 / 4.0
            );
        } else {
            for x in p.iter().map(|&x| x as f32).chain(n) {
                put(&mut body, &x.to_le_bytes());
            }
            body.extend_from_slice(&colour);
            put(&mut body, &(i as f32 / 4.0).to_le_bytes());
        }
    }
    for (f, q) in QUADS.iter().enumerate() {
        let colour = [f as u8, 2 * f as u8, 3 * f as u8];
        if encoding == "ascii" {
            header += &format!(
                "4 {} {} {} {} {} {} {}\n",
                q[0], q[1], q[2], q[3], colour[0], colour[1], colour[2]
            );
        } else {
            body.push(4);
            for v in q {
                put(&mut body, &(*v as i32).to_le_bytes());
            }
            body.extend_from_slice(&colour);
        }
    }
    let mut out = header.into_bytes();
    out.extend(body);
    out
}

#[test]
fn ply_keeps_every_property_in_every_encoding() {
    for encoding in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let (_dir, src, out) = dirs();
        std::fs::write(src.join("cube.ply"), ply_bytes(encoding)).unwrap();
        let mesh = read(&src.join("cube.ply"), Format::Ply, &cx(&src))
            .unwrap()
            .remove(0);
        let plan = hand_plan(&mesh, &[0, 1, 2], 6, 4, 5);
        let copy_path = out.join("cube.ply");
        let (_, copy) = round_trip(
            &src.join("cube.ply"),
            Format::Ply,
            &[Some(plan)],
            &copy_path,
        );
        assert_eq!(copy[0].positions.len(), 9);
        let bytes = std::fs::read(&copy_path).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        assert!(
            text.starts_with(&format!(
                "ply\nformat {encoding} 1.0\ncomment made by a test\n"
            )),
            "{text}"
        );
        assert!(
            text.contains("element vertex 9\n") && text.contains("element face 9\n"),
            "{text}"
        );
        assert!(
            text.contains("property float quality\n") && text.contains("property uchar blue\n")
        );
        if encoding == "ascii" {
            let body: Vec<&str> = text.split("end_header\n").nth(1).unwrap().lines().collect();
            // Vertex 0 (position 0 0 0): its colour, quality and its normal, negated because the
            // bottom quad's flip leaves all faces around it ... (three faces, one flipped: the
            // sum still agrees, so it stays).
            assert_eq!(body[0], "0 0 0 -0.5 -0.5 -0.5 0 100 200 0", "{text}");
            // The copy of vertex 5 (corner 0 of triangle 6) carries vertex 5's properties.
            assert_eq!(
                body[8], "1.125 1.25 -0.125 0.5 0.5 -0.5 20 100 200 0.5",
                "{text}"
            );
            // Faces keep their colours: quad 0 reversed, the fill takes quad 2's colour.
            assert_eq!(body[9], "4 0 1 2 3 0 0 0", "{text}");
            assert_eq!(body.last().unwrap(), &"3 0 1 5 2 4 6");
        }
    }
}

#[test]
fn off_keeps_vertex_and_face_colours() {
    let (_dir, src, out) = dirs();
    let mut off = String::from("COFF\n# a comment\n9 6 0\n");
    for (i, p) in CUBE.iter().chain(&[[9.0, 9.0, 9.0]]).enumerate() {
        off += &format!("{} {} {} {} 0.5 0.25 1\n", p[0], p[1], p[2], i as f64 / 8.0);
    }
    for (f, q) in QUADS.iter().enumerate() {
        off += &format!("4 {} {} {} {} {} 0 0\n", q[0], q[1], q[2], q[3], f * 40);
    }
    std::fs::write(src.join("cube.off"), &off).unwrap();
    let mesh = read(&src.join("cube.off"), Format::Off, &cx(&src))
        .unwrap()
        .remove(0);
    let plan = hand_plan(&mesh, &[0, 1, 2], 6, 4, 5);
    let copy_path = out.join("cube.off");
    round_trip(
        &src.join("cube.off"),
        Format::Off,
        &[Some(plan)],
        &copy_path,
    );
    let text = std::fs::read_to_string(&copy_path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "COFF");
    assert_eq!(lines[1], "9 9 0");
    assert_eq!(lines[2], "0 0 0 0 0.5 0.25 1");
    assert_eq!(lines[10], "1.125 1.25 -0.125 0.25 0.5 0.25 1", "{text}");
    assert_eq!(lines[11], "4 0 1 2 3 0 0 0");
    assert_eq!(*lines.last().unwrap(), "3 0 1 5 80 0 0");
}

fn stl_binary() -> Vec<u8> {
    let mut b = b"binary header kept by meshvet".to_vec();
    b.resize(80, b'.');
    b.extend_from_slice(&12u32.to_le_bytes());
    for (f, q) in QUADS.iter().enumerate() {
        for (k, tri) in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]].iter().enumerate() {
            b.extend_from_slice(&[0u8; 12]);
            for &v in tri {
                for x in CUBE[v as usize] {
                    b.extend_from_slice(&(x as f32).to_le_bytes());
                }
            }
            b.extend_from_slice(&(0x8000u16 | (2 * f + k) as u16).to_le_bytes());
        }
    }
    b
}

/// Writes `bytes` as `src/cube.stl`, repairs it by hand (three faces flipped, a 4-5 split) into
/// `out/cube.stl` and checks the copy is binary: `84 + 50 n` bytes, the source's header, each
/// facet's attribute word kept (`0x8000 | source face`, 0 for new faces). Returns the plan, the
/// source's mesh and the copy's bytes.
fn binary_stl_copy(src: &Path, out: &Path, bytes: &[u8]) -> (Plan, Mesh, Vec<u8>) {
    std::fs::write(src.join("cube.stl"), bytes).unwrap();
    let mesh = read(&src.join("cube.stl"), Format::Stl, &cx(src))
        .unwrap()
        .remove(0);
    let plan = hand_plan(&mesh, &[0, 1, 2], 6, 4, 5);
    let copy_path = out.join("cube.stl");
    round_trip(
        &src.join("cube.stl"),
        Format::Stl,
        &[Some(plan.clone())],
        &copy_path,
    );
    let copy = std::fs::read(&copy_path).unwrap();
    assert_eq!(copy.len(), 84 + 50 * 12);
    assert_eq!(copy[..80], bytes[..80]);
    for (i, t) in plan.triangles.iter().enumerate() {
        let at = 84 + 50 * i + 48;
        let attribute = u16::from_le_bytes([copy[at], copy[at + 1]]);
        assert_eq!(attribute, t.source.map_or(0, |s| 0x8000 | s as u16));
    }
    (plan, mesh, copy)
}

#[test]
fn binary_stl_keeps_header_and_attribute_bytes() {
    let (_dir, src, out) = dirs();
    let (plan, _, copy) = binary_stl_copy(&src, &out, &stl_binary());
    for i in 0..plan.triangles.len() {
        let facet = &copy[84 + 50 * i..84 + 50 * (i + 1)];
        // The facet normal follows the final winding.
        let f = |k: usize| f32::from_le_bytes(facet[4 * k..4 * k + 4].try_into().unwrap()) as f64;
        let p = |v: usize| [f(3 + 3 * v), f(4 + 3 * v), f(5 + 3 * v)];
        let (a, b, c) = (p(0), p(1), p(2));
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        assert!(n[0] * f(0) + n[1] * f(1) + n[2] * f(2) > 0.0);
    }
}

#[test]
fn ascii_stl_stays_ascii_with_its_name() {
    let (_dir, src, out) = dirs();
    let mut s = String::from("solid my part\n");
    for q in QUADS {
        s += "facet normal 0 0 0\nouter loop\n";
        for v in q {
            let p = CUBE[v as usize];
            s += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
        }
        s += "endloop\nendfacet\n";
    }
    s += "endsolid my part\n";
    std::fs::write(src.join("cube.stl"), &s).unwrap();
    let mesh = read(&src.join("cube.stl"), Format::Stl, &cx(&src))
        .unwrap()
        .remove(0);
    let plan = hand_plan(&mesh, &[0, 1, 2], 6, 4, 5);
    let copy_path = out.join("cube.stl");
    round_trip(
        &src.join("cube.stl"),
        Format::Stl,
        &[Some(plan)],
        &copy_path,
    );
    let text = std::fs::read_to_string(&copy_path).unwrap();
    assert!(text.starts_with("solid my part\n") && text.trim_end().ends_with("endsolid my part"));
    assert_eq!(text.matches("facet normal").count(), 12);
}

/// An ASCII STL of two `solid` blocks (CAD exports write one per body) keeps both, with their
/// names: each facet in the block of the face it comes from, a fill in its neighbour's block.
/// Block `box` holds quads 0..4 (faces 0..9), block `lid` quad 5 (faces 10, 11); the plan drops
/// face 11 and adds it back as a fill near face 0, so `box` gets 11 facets and `lid` 1.
#[test]
fn ascii_stl_keeps_its_solid_blocks_and_their_names() {
    let (_dir, src, out) = dirs();
    let mut s = String::new();
    for (name, quads) in [("box", 0..5), ("lid", 5..6)] {
        s += &format!("solid {name}\n");
        for q in &QUADS[quads] {
            s += "facet normal 0 0 0\nouter loop\n";
            for &v in q {
                let p = CUBE[v as usize];
                s += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
            }
            s += "endloop\nendfacet\n";
        }
        s += &format!("endsolid {name}\n");
    }
    std::fs::write(src.join("two.stl"), &s).unwrap();
    let mesh = read(&src.join("two.stl"), Format::Stl, &cx(&src))
        .unwrap()
        .remove(0);
    assert_eq!(mesh.triangles.len(), 12);
    let plan = hand_plan(&mesh, &[1], 2, 11, 0);
    let copy_path = out.join("two.stl");
    round_trip(&src.join("two.stl"), Format::Stl, &[Some(plan)], &copy_path);
    let text = std::fs::read_to_string(&copy_path).unwrap();
    let blocks: Vec<(String, usize)> = text
        .split("endsolid")
        .filter_map(|b| {
            let at = b.find("solid ")?;
            let name = b[at + 6..].lines().next().unwrap().to_owned();
            Some((name, b.matches("facet normal").count()))
        })
        .collect();
    assert_eq!(blocks, [("box".to_owned(), 11), ("lid".to_owned(), 1)]);
    assert!(text.trim_end().ends_with("endsolid lid"));
}

// ---- glTF -------------------------------------------------------------------------------------

/// A glTF asset: mesh 0 is a box whose five sides are primitive 0 (material 0) and whose top is
/// primitive 1 (material 1), with flat normals, tangents, UVs and 3-byte colours; mesh 1 a lone
/// triangle; nodes, a texture, an image file and extras around them.
fn gltf_asset() -> (Value, Vec<u8>) {
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut add = |bin: &mut Vec<u8>,
                   data: Vec<u8>,
                   count: usize,
                   component: u32,
                   type_: &str,
                   extra: Value| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len()}));
        bin.extend(data);
        let mut a = json!({"bufferView": views.len() - 1, "componentType": component, "count": count, "type": type_});
        for (k, v) in extra.as_object().unwrap() {
            a[k] = v.clone();
        }
        accessors.push(a);
        accessors.len() - 1
    };
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let mut primitives = Vec::new();
    for (range, material) in [(0..5usize, 0), (5..6, 1)] {
        let order = [0usize, 2, 3, 5, 4, 1];
        let (mut pos, mut nor, mut tan, mut uv, mut col, mut idx) =
            (vec![], vec![], vec![], vec![], vec![], vec![]);
        for (k, &f) in order[range.clone()].iter().enumerate() {
            for (c, &v) in QUADS[f].iter().enumerate() {
                pos.extend(CUBE[v as usize].map(|x| x as f32));
                nor.extend(NORMALS[f].map(|x| x as f32));
                tan.extend([1.0f32, 0.0, 0.0, 1.0]);
                uv.extend([(c == 1 || c == 2) as u8 as f32, (c >= 2) as u8 as f32]);
                col.extend([40 * f as u8, 255, 7]);
                let _ = c;
            }
            let b = 4 * k as u16;
            idx.extend([b, b + 1, b + 2, b, b + 2, b + 3]);
        }
        let n = pos.len() / 3;
        let lo = json!([0.0, 0.0, 0.0]);
        let hi = json!([1.0, 1.0, 1.0]);
        let p = add(
            &mut bin,
            f32s(&pos),
            n,
            5126,
            "VEC3",
            json!({"min": lo, "max": hi}),
        );
        let nn = add(&mut bin, f32s(&nor), n, 5126, "VEC3", json!({}));
        let t = add(&mut bin, f32s(&tan), n, 5126, "VEC4", json!({}));
        let u = add(&mut bin, f32s(&uv), n, 5126, "VEC2", json!({}));
        // 3-byte colours: a stride of 4 keeps each element aligned.
        let mut padded = Vec::new();
        for c in col.chunks(3) {
            padded.extend_from_slice(c);
            padded.push(0);
        }
        let cc = add(
            &mut bin,
            padded,
            n,
            5121,
            "VEC3",
            json!({"normalized": true}),
        );
        let i = add(
            &mut bin,
            idx.iter().flat_map(|x| x.to_le_bytes()).collect(),
            idx.len(),
            5123,
            "SCALAR",
            json!({}),
        );
        primitives.push(json!({
            "attributes": {"POSITION": p, "NORMAL": nn, "TANGENT": t, "TEXCOORD_0": u, "COLOR_0": cc},
            "indices": i, "material": material, "extras": {"part": material}
        }));
    }
    let tri = add(
        &mut bin,
        f32s(&[0.0, 0.0, 5.0, 1.0, 0.0, 5.0, 0.0, 1.0, 5.0]),
        3,
        5126,
        "VEC3",
        json!({"min": [0.0, 0.0, 5.0], "max": [1.0, 1.0, 5.0]}),
    );
    // The colour accessors' views have a stride.
    for p in &primitives {
        let c = p["attributes"]["COLOR_0"].as_u64().unwrap() as usize;
        let v = accessors[c]["bufferView"].as_u64().unwrap() as usize;
        views[v]["byteStride"] = json!(4);
    }
    let doc = json!({
        "asset": {"version": "2.0", "generator": "meshvet test", "extras": {"note": "keep me"}},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"mesh": 0, "name": "box", "extras": {"tag": 1}},
            {"mesh": 1, "translation": [2.0, 0.0, 0.0], "name": "tri"}
        ],
        "meshes": [
            {"name": "box", "primitives": primitives},
            {"name": "tri", "primitives": [{"attributes": {"POSITION": tri}}]}
        ],
        "materials": [
            {"name": "sides", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
            {"name": "top", "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 1.0, 1.0]}, "extras": {"x": [1, 2]}}
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729}],
        "images": [{"uri": "tex/wood.png"}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    (doc, bin)
}

fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

/// The JSON document of a `.gltf` or `.glb` file.
fn document(bytes: &[u8]) -> Value {
    if bytes.starts_with(b"glTF") {
        let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        serde_json::from_slice(&bytes[20..20 + len]).unwrap()
    } else {
        serde_json::from_slice(bytes).unwrap()
    }
}

/// Loads a written copy with the gltf crate (validation included) and checks, for every triangle
/// of every primitive, that its corners' normals agree with its winding and every vertex has UVs.
fn check_with_gltf_crate(path: &Path) {
    let bytes = std::fs::read(path).unwrap();
    let gltf = gltf::Gltf::from_slice(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let folder = path.parent().unwrap();
    let buffers: Vec<Vec<u8>> = gltf
        .buffers()
        .map(|b| match b.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().unwrap(),
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                use base64::Engine as _;
                base64::engine::general_purpose::STANDARD
                    .decode(uri.split(',').nth(1).unwrap())
                    .unwrap()
            }
            gltf::buffer::Source::Uri(uri) => std::fs::read(folder.join(uri)).unwrap(),
        })
        .collect();
    for mesh in gltf.meshes() {
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
            if let Some(uv) = reader.read_tex_coords(0) {
                assert_eq!(uv.into_f32().count(), positions.len());
            }
            let Some(normals) = reader.read_normals() else {
                continue;
            };
            let normals: Vec<[f32; 3]> = normals.collect();
            let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
            for t in indices.chunks(3) {
                let p = t
                    .iter()
                    .map(|&i| positions[i as usize].map(f64::from))
                    .collect::<Vec<_>>();
                let u = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
                let w = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
                let n = [
                    u[1] * w[2] - u[2] * w[1],
                    u[2] * w[0] - u[0] * w[2],
                    u[0] * w[1] - u[1] * w[0],
                ];
                for &i in t {
                    let s = normals[i as usize];
                    let d = n[0] * s[0] as f64 + n[1] * s[1] as f64 + n[2] * s[2] as f64;
                    assert!(
                        d >= 0.0,
                        "{}: a normal disagrees with its face",
                        path.display()
                    );
                }
            }
        }
    }
}

/// The hand plan on the box: the first side flipped whole, one triangle of the top dropped and
/// added back as a fill near a side (so it borrows the top's vertices into the sides' primitive),
/// a vertex copy; mesh 1 untouched.
fn gltf_plans(meshes: &[Mesh]) -> Vec<Option<Plan>> {
    let plan = hand_plan(&meshes[0], &[0, 1], 3, 10, 2);
    vec![Some(plan), None]
}

fn check_gltf_copy(source: &Path, copy: &Path) {
    check_with_gltf_crate(copy);
    let before = document(&std::fs::read(source).unwrap());
    let after = document(&std::fs::read(copy).unwrap());
    for key in [
        "asset",
        "nodes",
        "materials",
        "textures",
        "samplers",
        "scenes",
        "images",
        "scene",
    ] {
        assert_eq!(before[key], after[key], "{key} changed");
    }
    assert_eq!(before["meshes"][1], after["meshes"][1]);
    assert_eq!(before["meshes"][0]["name"], after["meshes"][0]["name"]);
    for p in 0..2 {
        let (b, a) = (
            &before["meshes"][0]["primitives"][p],
            &after["meshes"][0]["primitives"][p],
        );
        assert_eq!(b["material"], a["material"]);
        assert_eq!(b["extras"], a["extras"]);
        let names = |v: &Value| {
            v["attributes"]
                .as_object()
                .unwrap()
                .keys()
                .cloned()
                .collect::<Vec<_>>()
        };
        assert_eq!(names(b), names(a));
    }
    assert!(
        copy.parent().unwrap().join("tex/wood.png").is_file(),
        "the image is copied beside the copy"
    );
}

/// A glTF whose name leaves no room for its copy's `NAME.repaired.bin` beside it: the repair
/// fails saying the name is too long (it said the names were taken by other files).
#[test]
fn a_gltf_named_too_long_for_its_buffer_says_so() {
    let (_dir, src, out) = dirs();
    let (mut doc, bin) = gltf_asset();
    std::fs::write(src.join("box.bin"), &bin).unwrap();
    std::fs::write(src.join("tex/wood.png"), b"png").unwrap();
    doc["buffers"][0]["uri"] = json!("box.bin");
    let name = format!("{}.gltf", "b".repeat(245));
    std::fs::write(src.join(&name), serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    let meshes = read(&src.join(&name), Format::Gltf, &cx(&src)).unwrap();
    let plans = gltf_plans(&meshes);
    let e = write_repaired(
        &src.join(&name),
        Format::Gltf,
        &plans,
        &out.join("models").join(&name),
        &cx(&src),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("too long a name"), "{e}");
}

#[test]
fn gltf_keeps_the_document_and_every_attribute() {
    let (_dir, src, out) = dirs();
    let (mut doc, bin) = gltf_asset();
    std::fs::write(src.join("box.bin"), &bin).unwrap();
    std::fs::write(src.join("tex/wood.png"), b"png").unwrap();
    doc["buffers"][0]["uri"] = json!("box.bin");
    std::fs::write(
        src.join("box.gltf"),
        serde_json::to_vec_pretty(&doc).unwrap(),
    )
    .unwrap();
    let meshes = read(&src.join("box.gltf"), Format::Gltf, &cx(&src)).unwrap();
    let plans = gltf_plans(&meshes);
    let copy = out.join("models/box.gltf");
    round_trip(&src.join("box.gltf"), Format::Gltf, &plans, &copy);
    check_gltf_copy(&src.join("box.gltf"), &copy);
    assert!(out.join("models/box.bin").is_file() && out.join("models/box.repaired.bin").is_file());
}

#[test]
fn glb_appends_to_its_binary_chunk() {
    let (_dir, src, out) = dirs();
    let (doc, bin) = gltf_asset();
    std::fs::write(src.join("tex/wood.png"), b"png").unwrap();
    std::fs::write(src.join("box.glb"), glb(&doc, &bin)).unwrap();
    let meshes = read(&src.join("box.glb"), Format::Glb, &cx(&src)).unwrap();
    let plans = gltf_plans(&meshes);
    let copy = out.join("box.glb");
    round_trip(&src.join("box.glb"), Format::Glb, &plans, &copy);
    check_gltf_copy(&src.join("box.glb"), &copy);
    let after = document(&std::fs::read(&copy).unwrap());
    assert_eq!(after["buffers"].as_array().unwrap().len(), 1);
    // The source's bytes are still at the start of the chunk.
    let bytes = std::fs::read(&copy).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    assert_eq!(&bytes[28 + json_len..28 + json_len + bin.len()], &bin[..]);
}

#[test]
fn embedded_gltf_stays_embedded() {
    use base64::Engine as _;
    let (_dir, src, out) = dirs();
    let (mut doc, bin) = gltf_asset();
    std::fs::write(src.join("tex/wood.png"), b"png").unwrap();
    doc["buffers"][0]["uri"] = json!(format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    ));
    std::fs::write(src.join("box.gltf"), serde_json::to_vec(&doc).unwrap()).unwrap();
    let meshes = read(&src.join("box.gltf"), Format::Gltf, &cx(&src)).unwrap();
    let copy = out.join("box.gltf");
    round_trip(
        &src.join("box.gltf"),
        Format::Gltf,
        &gltf_plans(&meshes),
        &copy,
    );
    check_gltf_copy(&src.join("box.gltf"), &copy);
    let after = document(&std::fs::read(&copy).unwrap());
    assert!(after["buffers"]
        .as_array()
        .unwrap()
        .iter()
        .all(|b| b["uri"].as_str().unwrap().starts_with("data:")));
    assert_eq!(
        std::fs::read_dir(&out).unwrap().count(),
        2,
        "only the copy and its image"
    );
}

#[test]
fn writing_over_the_source_is_refused() {
    let (_dir, src, _out) = dirs();
    std::fs::write(src.join("cube.stl"), stl_binary()).unwrap();
    let mesh = read(&src.join("cube.stl"), Format::Stl, &cx(&src))
        .unwrap()
        .remove(0);
    let e = write_repaired(
        &src.join("cube.stl"),
        Format::Stl,
        &[Some(identity(&mesh))],
        &src.join("cube.stl"),
        &cx(&src),
    )
    .unwrap_err();
    assert!(e.0.contains("overwrite"), "{e}");
    assert_eq!(std::fs::read(src.join("cube.stl")).unwrap(), stl_binary());
}

// ---- real files ------------------------------------------------------------------------------

/// Flips every seventh triangle (and keeps everything else).
fn flip_some(mesh: &Mesh) -> Plan {
    let mut p = identity(mesh);
    for t in p.triangles.iter_mut().step_by(7) {
        flip(t);
    }
    p.done = vec![(Kind::OrientFaces, mesh.triangles.len().div_ceil(7), None)];
    p
}

/// Real files from `../shared/corpus` (skipped when it is absent): each readable file with
/// triangles, up to 4 MB, is written through an identity plan and a plan that flips some faces;
/// the copies read back with the planned triangles, glTF copies pass the gltf crate's validation
/// whenever the source does and keep every primitive's attributes and material.
#[test]
fn corpus_round_trips() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    if !corpus.is_dir() {
        eprintln!("no ../shared/corpus: skipped");
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let mut done: BTreeMap<&str, usize> = BTreeMap::new();
    for entry in walkdir::WalkDir::new(&corpus)
        .sort_by_file_name()
        .into_iter()
        .flatten()
    {
        let path = entry.path();
        let Some(format) = Format::of_path(path) else {
            continue;
        };
        if !entry.file_type().is_file() || entry.metadata().unwrap().len() > 4 << 20 {
            continue;
        }
        let c = cx(path.parent().unwrap());
        let Ok(meshes) = read(path, format, &c) else {
            continue;
        };
        if meshes.iter().all(|m| m.triangles.is_empty()) {
            continue;
        }
        for (k, plan) in [identity as fn(&Mesh) -> Plan, flip_some]
            .iter()
            .enumerate()
        {
            let plans: Vec<Option<Plan>> = meshes.iter().map(|m| Some(plan(m))).collect();
            let name = format!("{k}-{}", path.file_name().unwrap().to_string_lossy());
            let copy = out.path().join(format.name()).join(name);
            let written = write_repaired(path, format, &plans, &copy, &c);
            let written = match written {
                Err(e) if e.0.contains("cannot be written yet") => continue,
                written => written.unwrap_or_else(|e| panic!("{}: {e}", path.display())),
            };
            assert_eq!(written[0], copy);
            let again = read(&copy, format, &cx(copy.parent().unwrap()))
                .unwrap_or_else(|e| panic!("{}: copy unreadable: {e}", path.display()));
            assert_eq!(again.len(), meshes.len(), "{}", path.display());
            for ((mesh, plan), again) in meshes.iter().zip(&plans).zip(&again) {
                let expected = plan.as_ref().unwrap().apply(mesh);
                assert_eq!(shape(again), shape(&expected), "{}", path.display());
            }
            if matches!(format, Format::Gltf | Format::Glb) {
                let source = std::fs::read(path).unwrap();
                let bytes = std::fs::read(&copy).unwrap();
                if gltf::Gltf::from_slice(&source).is_ok() {
                    gltf::Gltf::from_slice(&bytes).unwrap_or_else(|e| {
                        panic!("{}: copy fails validation: {e}", path.display())
                    });
                }
                let (before, after) = (document(&source), document(&bytes));
                for key in [
                    "nodes",
                    "materials",
                    "textures",
                    "skins",
                    "animations",
                    "scenes",
                ] {
                    assert_eq!(before[key], after[key], "{}: {key}", path.display());
                }
                for (m, mesh) in before["meshes"].as_array().unwrap().iter().enumerate() {
                    for (p, prim) in mesh["primitives"].as_array().unwrap().iter().enumerate() {
                        let copy = &after["meshes"][m]["primitives"][p];
                        assert_eq!(prim["material"], copy["material"], "{}", path.display());
                        let names = |v: &Value| {
                            v["attributes"]
                                .as_object()
                                .map(|o| o.keys().cloned().collect::<Vec<_>>())
                        };
                        assert_eq!(names(prim), names(copy), "{}", path.display());
                    }
                }
            }
            *done.entry(format.name()).or_default() += 1;
        }
    }
    eprintln!("corpus round trips: {done:?}");
    assert!(done.contains_key("gltf") || done.contains_key("glb"));
}

// ---- the command line ---------------------------------------------------------------------

/// `scan --repair-dir`: an open textured box with a flipped side gets a closed, oriented copy
/// whose re-check passes; a clean cube gets no copy; the output folder inside the scanned tree is
/// not scanned; and scanning the copies with `--repair-dir` again writes nothing.
#[test]
fn scan_writes_repaired_copies_and_rechecks_them() {
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    std::fs::create_dir_all(tree.join("props")).unwrap();
    let mut obj = String::from("mtllib box.mtl\n");
    for p in CUBE {
        obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    obj += "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\ng box\nusemtl wood\n";
    for (f, q) in QUADS.iter().enumerate() {
        let q: Vec<u32> = if f == 2 {
            q.iter().rev().copied().collect()
        } else {
            q.to_vec()
        };
        if f == 1 {
            continue; // the top is open
        }
        obj += "f";
        for (k, v) in q.iter().enumerate() {
            obj += &format!(" {}/{}", v + 1, k + 1);
        }
        obj += "\n";
    }
    std::fs::write(tree.join("props/box.obj"), &obj).unwrap();
    std::fs::write(tree.join("props/box.mtl"), "newmtl wood\nKd 1 1 1\n").unwrap();
    std::fs::write(tree.join("clean.stl"), stl_binary()).unwrap();
    let before = hash_tree(&tree);

    let run = |args: &[&Path]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_meshvet"))
            .arg("scan")
            .args(args)
            .arg("--quiet")
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(
            out.status.code().is_some_and(|c| c <= 1),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let csv_rows = |path: &Path| -> Vec<BTreeMap<String, String>> {
        let mut reader = csv::Reader::from_path(path).unwrap();
        let header = reader.headers().unwrap().clone();
        reader
            .records()
            .map(|r| {
                header
                    .iter()
                    .zip(r.unwrap().iter())
                    .map(|(h, v)| (h.to_owned(), v.to_owned()))
                    .collect()
            })
            .collect()
    };

    let report = dir.path().join("r.csv");
    run(&[
        &tree,
        Path::new("--csv"),
        &report,
        Path::new("--repair-dir"),
        &tree.join("fixed"),
    ]);
    for (path, hash) in &before {
        assert_eq!(
            hash_tree(&tree).get(path),
            Some(hash),
            "{} changed",
            path.display()
        );
    }
    let rows = csv_rows(&report);
    assert_eq!(rows.len(), 2, "the output folder is not scanned: {rows:?}");
    let stl = &rows[0];
    assert_eq!(
        (stl["repaired_path"].as_str(), stl["status_after"].as_str()),
        ("", "")
    );
    let row = &rows[1];
    assert_eq!(row["path"], "props/box.obj");
    assert_eq!(
        row["repairs"], "orient-faces:2;fill-holes:1(2 faces)",
        "{row:?}"
    );
    assert_eq!(row["status_after"], "pass", "{row:?}");
    // Before: the hole and the flipped faces; after: nothing left to find.
    assert!(row["findings"].contains("hole:1"), "{row:?}");
    assert_eq!(row["findings_after"], "", "{row:?}");
    let copy = PathBuf::from(&row["repaired_path"]);
    let copy = if copy.is_absolute() {
        copy
    } else {
        dir.path().join(copy)
    };
    assert_eq!(copy, tree.join("fixed/props/box.obj"));
    let text = std::fs::read_to_string(&copy).unwrap();
    assert_eq!(lines_with(&text, "vt").len(), 4);
    assert_eq!(lines_with(&text, "usemtl"), ["usemtl wood"]);
    assert!(tree.join("fixed/props/box.mtl").is_file());
    let mesh = read(&copy, Format::Obj, &cx(copy.parent().unwrap()))
        .unwrap()
        .remove(0);
    let analysis = meshvet::analyse(&mesh, &Default::default());
    assert_eq!(
        (
            analysis.shells.len(),
            analysis.border_edges,
            analysis.inconsistent_edges
        ),
        (1, 0, 0)
    );
    assert!((analysis.shells[0].volume.unwrap() - 1.0).abs() < 1e-9);

    // Repairing the repaired copy changes nothing: no copy is written.
    let again = dir.path().join("again.csv");
    run(&[
        &tree.join("fixed"),
        Path::new("--csv"),
        &again,
        Path::new("--repair-dir"),
        &dir.path().join("twice"),
    ]);
    let rows = csv_rows(&again);
    assert!(
        rows.iter()
            .all(|r| r["repaired_path"].is_empty() && r["status"] == "pass"),
        "{rows:?}"
    );
    assert_eq!(
        std::fs::read_dir(dir.path().join("twice")).unwrap().count(),
        0
    );
}

// ---- PLY elements beyond vertex and face ----------------------------------------------------

/// The unit cube's six quads as PLY face lines, vertex numbers shifted by `shift`.
fn ply_cube_faces(shift: u32) -> String {
    QUADS
        .iter()
        .map(|q| {
            let v: Vec<String> = q.iter().map(|v| (v + shift).to_string()).collect();
            format!("4 {}\n", v.join(" "))
        })
        .collect()
}

/// Vertex 0 (9 9 9) is used by no face, so the repair drops it and every cube vertex moves down
/// by one. The `edge` element's `vertex1`/`vertex2` follow: edge 1-2 becomes 0-1, edge 7-8
/// becomes 6-7, and edge 0-4 names the dropped vertex, so it is left out (said in a note). The
/// `material` element's integer `id` may number anything: left out, said in a note. The
/// `camera` element has only floats: copied as it was.
#[test]
fn ply_edges_follow_the_renumbered_vertices_and_unknown_elements_are_left_out() {
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 9\nproperty float x\nproperty float y\nproperty float z\n\
         element face 6\nproperty list uchar int vertex_indices\n\
         element edge 3\nproperty int vertex1\nproperty int vertex2\nproperty uchar red\n\
         element material 1\nproperty int id\nproperty float shine\n\
         element camera 1\nproperty float view_px\nproperty float view_py\nend_header\n9 9 9\n",
    );
    for p in CUBE {
        ply += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    ply += &ply_cube_faces(1);
    ply += "1 2 255\n0 4 128\n7 8 64\n5 0.5\n1.5 2.5\n";
    let (written, text, again) = ply_repaired(ply.as_bytes(), "drop-unreferenced-vertices:1");
    let (header, body) = text.split_once("end_header\n").unwrap();
    assert!(header.contains("element vertex 8\n"), "{header}");
    assert!(header.contains("element edge 2\n"), "{header}");
    assert!(
        !header.contains("material") && !header.contains("property int id"),
        "{header}"
    );
    assert!(
        header.contains("element camera 1\nproperty float view_px\n"),
        "{header}"
    );
    let lines: Vec<&str> = body.lines().collect();
    assert_eq!(lines.len(), 8 + 6 + 2 + 1, "{body}");
    assert_eq!(lines[0], "0 0 0");
    assert_eq!(&lines[14..], ["0 1 255", "6 7 64", "1.5 2.5"], "{body}");
    assert_eq!(written.notes.len(), 2, "{:?}", written.notes);
    assert!(
        written.notes[0].contains("`edge`: 1 record left out"),
        "{:?}",
        written.notes
    );
    assert!(
        written.notes[1].contains("`material` left out"),
        "{:?}",
        written.notes
    );
    // The copy is the clean cube, and repairing it again changes nothing.
    assert_eq!(again.positions.len(), 8);
    assert!(!meshvet::repair::plan(&again, &Default::default()).changes());
}

/// Writes `bytes` as a PLY, checks that the repair plans `summary` and writes the copy: its notes,
/// its bytes as text (lossy for a binary body) and the copy read back.
fn ply_repaired(bytes: &[u8], summary: &str) -> (Written, String, Mesh) {
    let (_dir, src, out) = dirs();
    std::fs::write(src.join("m.ply"), bytes).unwrap();
    let mesh = read(&src.join("m.ply"), Format::Ply, &cx(&src))
        .unwrap()
        .remove(0);
    let plan = meshvet::repair::plan(&mesh, &Default::default());
    assert_eq!(plan.summary(), summary);
    let copy = out.join("m.ply");
    let written = write_copy(
        &src.join("m.ply"),
        Format::Ply,
        &[Some(plan)],
        &copy,
        &cx(&src),
        None,
    )
    .unwrap();
    let bytes = std::fs::read(&copy).unwrap();
    let again = read(&copy, Format::Ply, &cx(&out)).unwrap().remove(0);
    (written, String::from_utf8_lossy(&bytes).into_owned(), again)
}

/// Two closed tetrahedra on one vertex, `centre + size * c` for the corners `c` below, as a PLY in
/// `format` (`ascii`, `binary_little_endian`, `binary_big_endian`) with coordinates of `scalar`
/// type (`short` or `float`) and a `uchar red` property numbering the vertices from 200.
fn two_tetrahedra_ply(format: &str, scalar: &str, centre: f64, size: f64) -> Vec<u8> {
    let corners = [
        [0, 0, 0],
        [1, 0, 0],
        [0, 1, 0],
        [0, 0, 1],
        [-1, 0, 0],
        [0, -1, 0],
        [0, 0, -1],
    ];
    // Outward faces: the first tetrahedron, then its point reflection with every face reversed.
    let faces: [[i32; 3]; 8] = [
        [0, 2, 1],
        [0, 1, 3],
        [0, 3, 2],
        [1, 2, 3],
        [0, 4, 5],
        [0, 6, 4],
        [0, 5, 6],
        [4, 6, 5],
    ];
    let mut bytes = format!(
        "ply\nformat {format} 1.0\nelement vertex 7\nproperty {scalar} x\nproperty {scalar} y\n\
         property {scalar} z\nproperty uchar red\nelement face 8\n\
         property list uchar int vertex_indices\nend_header\n"
    )
    .into_bytes();
    let big = format == "binary_big_endian";
    let mut push = |le: &[u8]| {
        let mut b = le.to_vec();
        if big {
            b.reverse();
        }
        bytes.extend(b);
    };
    for (i, c) in corners.iter().enumerate() {
        let p = c.map(|x| centre + size * f64::from(x));
        if format == "ascii" {
            push(format!("{} {} {} {}\n", p[0], p[1], p[2], 200 + i).as_bytes());
            continue;
        }
        for x in p {
            match scalar {
                "short" => push(&(x as i16).to_le_bytes()),
                _ => push(&(x as f32).to_le_bytes()),
            }
        }
        push(&[200 + i as u8]);
    }
    for f in faces {
        if format == "ascii" {
            push(format!("3 {} {} {}\n", f[0], f[1], f[2]).as_bytes());
            continue;
        }
        push(&[3]);
        for v in f {
            push(&v.to_le_bytes());
        }
    }
    bytes
}

/// Two closed tetrahedra on one vertex (the origin), coordinates 0 and +-10, stored as PLY
/// `short`s: the repair splits the vertex, and its copy moves a hair into its fan, between
/// integers. An integer type cannot hold that place (cast, it falls back onto the origin and the
/// copy read back welds onto it, non-manifold again), so the copy declares the coordinates
/// `float`, which holds the planned place and every short exactly, and says so in a note. The
/// plan rounds a split copy's place to f32, so `float` is enough.
#[test]
fn a_split_in_a_ply_of_integer_coordinates_declares_them_float() {
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let bytes = two_tetrahedra_ply(format, "short", 0.0, 10.0);
        let (written, text, again) = ply_repaired(&bytes, "split-non-manifold-vertices:1");
        let header = text.split("end_header").next().unwrap();
        assert!(
            header.contains(
                "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
            ),
            "{format}: {header}"
        );
        assert!(
            written
                .notes
                .iter()
                .any(|n| n.contains("(`x` short -> float, `y` short -> float, `z` short -> float)")),
            "{format}: {:?}",
            written.notes
        );
        assert_eq!(again.positions.len(), 8, "{format}");
        // Every original vertex is where it was; the copy is off the origin.
        for p in [[0.0; 3], [10.0, 0.0, 0.0], [0.0, 0.0, -10.0]] {
            assert!(again.positions.contains(&p), "{format}: {p:?}");
        }
        let after = meshvet::analyse(&again, &Default::default());
        assert_eq!(after.nonmanifold_vertices, 0, "{format}");
        assert_eq!(after.shells.len(), 2, "{format}");
    }
}

/// The same two tetrahedra as `float`s, around (1e6, 1e6, 1e6) with edges of 1/16, one `f32`
/// step there: the plan keeps the split copy's exact place (rounded to `f32` it would fall back
/// onto its vertex). A binary file declares the coordinates `double` to hold it; an ASCII file
/// keeps `float`, whose text holds every digit (its values read back as written), so real ASCII
/// files of decimal `float`s (0.1 is no `f32`) keep their types.
#[test]
fn a_split_finer_than_float_steps_declares_binary_coordinates_double() {
    for format in ["binary_little_endian", "ascii"] {
        let ascii = format == "ascii";
        let bytes = two_tetrahedra_ply(format, "float", 1e6, 1.0 / 16.0);
        let (written, text, again) = ply_repaired(&bytes, "split-non-manifold-vertices:1");
        let kept = if ascii { "float" } else { "double" };
        assert!(
            text.contains(&format!(
                "property {kept} x\nproperty {kept} y\nproperty {kept} z\n"
            )),
            "{format}: {text}"
        );
        assert_eq!(
            written
                .notes
                .iter()
                .any(|n| n.contains("`x` float -> double")),
            !ascii,
            "{format}: {:?}",
            written.notes
        );
        assert_eq!(again.positions.len(), 8, "{format}");
        let after = meshvet::analyse(&again, &Default::default());
        assert_eq!(after.nonmanifold_vertices, 0, "{format}");
    }
}

/// An inside-out cube whose vertices all carry the normal (1, 1, 1) as `uchar`s: the repair turns
/// the cube outward and the normals pointing against their vertex's faces over, to -1, which a
/// `uchar` cannot hold (cast, it became 0), so the copy declares them `float`.
#[test]
fn a_normal_turned_negative_declares_an_unsigned_normal_float() {
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar nx\nproperty uchar ny\nproperty uchar nz\n\
         element face 6\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for p in CUBE {
        ply += &format!("{} {} {} 1 1 1\n", p[0], p[1], p[2]);
    }
    for q in QUADS {
        ply += &format!("4 {} {} {} {}\n", q[3], q[2], q[1], q[0]);
    }
    let (written, text, _) = ply_repaired(ply.as_bytes(), "flip-inside-out-shells:1(12 faces)");
    assert!(
        text.contains("property float nx\nproperty float ny\nproperty float nz\n"),
        "{text}"
    );
    assert!(
        written
            .notes
            .iter()
            .any(|n| n.contains("`nx` uchar -> float")),
        "{:?}",
        written.notes
    );
    // The corner at the origin: its faces now face (-1, -1, -1).
    assert!(text.contains("\n0 0 0 -1 -1 -1\n"), "{text}");
}

/// A repair that moves no vertex off the integers (a face turned over) keeps a PLY's integer
/// coordinate types. A regression guard: the copy's types change only where a value
/// needs it.
#[test]
fn a_ply_of_integer_coordinates_stays_integer_when_no_vertex_moves() {
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 8\nproperty int x\nproperty int y\nproperty int z\n\
         element face 6\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for p in CUBE {
        ply += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    // The cube with its first face turned over.
    let faces = ply_cube_faces(0);
    let mut lines: Vec<String> = faces.lines().map(str::to_owned).collect();
    let first: Vec<&str> = lines[0].split(' ').collect();
    lines[0] = format!("4 {} {} {} {}", first[4], first[3], first[2], first[1]);
    ply += &(lines.join("\n") + "\n");
    let (written, text, again) = ply_repaired(ply.as_bytes(), "orient-faces:2");
    assert!(
        text.contains("property int x\nproperty int y\nproperty int z\n"),
        "{text}"
    );
    assert!(written.notes.is_empty(), "{:?}", written.notes);
    let after = meshvet::analyse(&again, &Default::default());
    assert_eq!(after.inconsistent_edges, 0);
}

/// Header lines whose words are separated by runs of spaces and tabs still get their new counts
/// (the header text is also checked on its own in `formats::write::ply`'s unit test).
#[test]
fn ply_header_with_runs_of_spaces_and_tabs_gets_new_counts() {
    let (_dir, src, out) = dirs();
    let mut ply = String::from(
        "ply\nformat  ascii\t1.0\nelement   vertex\t9\nproperty float x\nproperty\tfloat y\n\
         property float   z\nelement\tface  6\nproperty list uchar int vertex_indices\nend_header\n9 9 9\n",
    );
    for p in CUBE {
        ply += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    ply += &ply_cube_faces(1);
    std::fs::write(src.join("cube.ply"), &ply).unwrap();
    let mesh = read(&src.join("cube.ply"), Format::Ply, &cx(&src))
        .unwrap()
        .remove(0);
    let plan = meshvet::repair::plan(&mesh, &Default::default());
    let copy = out.join("cube.ply");
    round_trip(&src.join("cube.ply"), Format::Ply, &[Some(plan)], &copy);
    let text = std::fs::read_to_string(&copy).unwrap();
    let header = text.split("end_header").next().unwrap();
    let counts: Vec<&str> = header
        .lines()
        .filter(|l| l.split_whitespace().next() == Some("element"))
        .collect();
    assert_eq!(counts.len(), 2, "{header}");
    assert_eq!(
        counts[0].split_whitespace().collect::<Vec<_>>(),
        ["element", "vertex", "8"]
    );
    assert_eq!(
        counts[1].split_whitespace().collect::<Vec<_>>(),
        ["element", "face", "6"]
    );
}

/// Per-corner `texcoord` lists (two values a corner, `[quad, corner]`) on every quad but quad 4,
/// which has an empty list. Triangle 8 (quad 4's first, vertices 0 4 7) is dropped and added back
/// as a fill near triangle 4 (quad 2: vertices 0 1 5 4): the fill's record is quad 2's, and its
/// corners come from quad 4, which has no values. Each corner then takes quad 2's values at the
/// same vertex (vertex 0: corner 0 -> `2 0`; vertex 4: corner 3 -> `2 3`), or zeros where quad 2
/// has none (vertex 7): the list says 6 values and holds 6, in every encoding.
#[test]
fn ply_fill_corner_from_a_face_without_the_list_keeps_the_record_aligned() {
    for encoding in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let (_dir, src, out) = dirs();
        let big = encoding == "binary_big_endian";
        let mut bytes = format!(
            "ply\nformat {encoding} 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n\
             element face 6\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\nend_header\n"
        )
        .into_bytes();
        let put = |b: &mut Vec<u8>, le: &[u8]| {
            if big {
                b.extend(le.iter().rev());
            } else {
                b.extend_from_slice(le);
            }
        };
        for p in CUBE {
            if encoding == "ascii" {
                bytes.extend(format!("{} {} {}\n", p[0], p[1], p[2]).bytes());
            } else {
                for x in p {
                    put(&mut bytes, &(x as f32).to_le_bytes());
                }
            }
        }
        for (f, q) in QUADS.iter().enumerate() {
            let uv: Vec<f32> = if f == 4 {
                Vec::new()
            } else {
                (0..4).flat_map(|k| [f as f32, k as f32]).collect()
            };
            if encoding == "ascii" {
                let uv: Vec<String> = uv.iter().map(|x| x.to_string()).collect();
                bytes.extend(
                    format!(
                        "4 {} {} {} {} {} {}\n",
                        q[0],
                        q[1],
                        q[2],
                        q[3],
                        uv.len(),
                        uv.join(" ")
                    )
                    .bytes(),
                );
            } else {
                bytes.push(4);
                for v in q {
                    put(&mut bytes, &(*v as i32).to_le_bytes());
                }
                bytes.push(uv.len() as u8);
                for x in uv {
                    put(&mut bytes, &x.to_le_bytes());
                }
            }
        }
        std::fs::write(src.join("cube.ply"), &bytes).unwrap();
        let mesh = read(&src.join("cube.ply"), Format::Ply, &cx(&src))
            .unwrap()
            .remove(0);
        assert_eq!(mesh.triangles[8], [0, 4, 7]);
        let mut plan = identity(&mesh);
        let mut fill = plan.triangles.remove(8);
        fill.source = None;
        fill.near = 4;
        plan.triangles.push(fill);
        plan.done = vec![(Kind::FillHoles, 1, None)];
        let copy = out.join("cube.ply");
        round_trip(&src.join("cube.ply"), Format::Ply, &[Some(plan)], &copy);
        let bytes = std::fs::read(&copy).unwrap();
        let at = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        if encoding == "ascii" {
            let body = String::from_utf8_lossy(&bytes[at..]).into_owned();
            let faces: Vec<&str> = body.lines().skip(8).collect();
            assert_eq!(faces.last(), Some(&"3 0 4 7 6 2 0 2 3 0 0"), "{body}");
            // Quad 4's other triangle keeps its own (empty) list.
            assert!(faces.contains(&"3 0 7 3 0"), "{body}");
        } else {
            // 8 vertices of 12 bytes, 5 whole quads (1 + 16 + 1 + 32 bytes), quad 4's other
            // triangle (1 + 12 + 1) and the fill (1 + 12 + 1 + 24): nothing more, nothing less.
            assert_eq!(bytes.len() - at, 8 * 12 + 5 * 50 + 14 + 38);
            let fill = &bytes[bytes.len() - 38..];
            let f = |k: usize| {
                let mut b: [u8; 4] = fill[14 + 4 * k..18 + 4 * k].try_into().unwrap();
                if big {
                    b.reverse();
                }
                f32::from_le_bytes(b)
            };
            assert_eq!(fill[13], 6);
            assert_eq!(
                (0..6).map(f).collect::<Vec<_>>(),
                [2.0, 0.0, 2.0, 3.0, 0.0, 0.0]
            );
        }
    }
}

// ---- failures inside the repair of one file ---------------------------------------------------

/// The crate of `sample_assets/props` (a textured unit cube in quads, with its .mtl and .png), one
/// quad stored backwards so it needs `orient-faces`, in `src/props`; returns the source entry,
/// the meshes and the scan rows of it (no repair yet).
fn damaged_crate(
    src: &Path,
    settings: &meshvet::config::Settings,
) -> (
    meshvet::walk::Source,
    Vec<Mesh>,
    Vec<meshvet::report::Outcome>,
) {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_assets/props");
    let text = std::fs::read_to_string(assets.join("crate.obj")).unwrap();
    let text = text.replace("f 1/1/3 2/2/3 6/3/3 5/4/3", "f 5/4/3 6/3/3 2/2/3 1/1/3");
    std::fs::create_dir_all(src.join("props")).unwrap();
    std::fs::write(src.join("props/crate.obj"), text).unwrap();
    for f in ["crate.mtl", "crate.png"] {
        std::fs::copy(assets.join(f), src.join("props").join(f)).unwrap();
    }
    let source = meshvet::walk::walk(&[src.to_path_buf()], &meshvet::walk::Filter::everything())
        .into_iter()
        .find(|s| s.display == "props/crate.obj")
        .unwrap();
    let outcomes = meshvet::scan::scan_file(&source, settings);
    let c = ReadContext {
        root: src.to_path_buf(),
        limits: settings.limits.clone(),
    };
    let meshes = read(&source.path, Format::Obj, &c).unwrap();
    assert_eq!(outcomes.len(), 1);
    assert!(!outcomes[0].findings.is_empty(), "{:?}", outcomes[0].row);
    (source, meshes, outcomes)
}

/// Every mesh judged as the scan judges it.
fn judged_meshes(
    meshes: &[Mesh],
    settings: &meshvet::config::Settings,
) -> Vec<meshvet::judge::Judged> {
    meshes
        .iter()
        .map(|m| meshvet::judge::judge(m, settings))
        .collect()
}

/// Every file under `dir` (none for a missing folder).
fn files_under(dir: &Path) -> Vec<PathBuf> {
    walkdir::WalkDir::new(dir)
        .into_iter()
        .flatten()
        .filter(|e| e.file_type().is_file())
        .map(|e| e.path().to_path_buf())
        .collect()
}

/// Runs `copies::repair_file` on the damaged crate with `planner` and returns the rows
/// before and after.
fn repair_crate_with(
    settings: &meshvet::config::Settings,
    planner: &dyn Fn(&Mesh, &meshvet::repair::Options) -> Plan,
) -> (
    tempfile::TempDir,
    meshvet::report::Row,
    meshvet::report::Row,
) {
    let (dir, src, out) = dirs();
    let (source, meshes, mut outcomes) = damaged_crate(&src, settings);
    let before = outcomes[0].row.clone();
    let hashes = hash_tree(&src);
    let c = ReadContext {
        root: src.clone(),
        limits: settings.limits.clone(),
    };
    let mut judged = judged_meshes(&meshes, settings);
    let repaired = meshvet::copies::repair_file(
        &out,
        &source.report_path,
        &source.path,
        Format::Obj,
        &c,
        &meshes,
        &mut judged,
        None,
        settings,
        &|m, o, _| planner(m, o),
    );
    assert_eq!(hashes, hash_tree(&src), "the source tree changed");
    assert_eq!(repaired.len(), 1);
    outcomes[0] = meshvet::scan::outcome(
        &source.display,
        Format::Obj,
        &meshes[0],
        judged.remove(0),
        &repaired[0],
        0.0,
    );
    assert_eq!(
        files_under(&out),
        Vec::<PathBuf>::new(),
        "nothing is left in the output folder"
    );
    // Not even the staging folder or the folders made for it (`out`, `out/props`).
    assert!(!out.exists(), "{} is left", out.display());
    let after = outcomes.remove(0).row;
    (dir, before, after)
}

/// The row as it was but for the message, which gets `note` appended.
fn assert_kept_with_note(before: &meshvet::report::Row, after: &meshvet::report::Row, note: &str) {
    let mut expected = before.clone();
    expected.message = format!("{}; {note}", before.message);
    let mut got = after.clone();
    got.millis = expected.millis;
    assert_eq!(got, expected);
}

/// A panic in the planner becomes a note on the mesh's row; the scan row is kept as it was (no
/// "internal error" row) and nothing is written.
#[test]
fn a_panicking_planner_costs_the_copy_not_the_scan_row() {
    let settings = meshvet::config::Settings::default();
    let (_dir, before, after) = repair_crate_with(&settings, &|_, _| panic!("planner boom"));
    assert_kept_with_note(
        &before,
        &after,
        "repair failed: the repair planner crashed (planner boom) - this mesh is not repaired, the \
         source is untouched",
    );
}

/// A plan naming a vertex the mesh does not have makes the OBJ writer index out of range: the
/// panic is caught in `copies`, the row is kept with a note, and the half-staged copy, its .mtl
/// and texture are removed.
#[test]
fn a_crashing_writer_costs_the_copy_not_the_scan_row() {
    let settings = meshvet::config::Settings::default();
    let planner = |m: &Mesh, o: &meshvet::repair::Options| {
        let mut p = meshvet::repair::plan(m, o);
        p.triangles[0].corners[0].vertex = 1_000_000;
        p
    };
    let (_dir, before, after) = repair_crate_with(&settings, &planner);
    assert!(
        after.message.contains("repair failed: internal error ("),
        "{}",
        after.message
    );
    assert!(after
        .message
        .ends_with(" - no copy written, the source is untouched"));
    assert_eq!(after.repaired_path, "");
    assert_eq!(after.findings, before.findings);
    assert_eq!(after.status, before.status);
}

/// A copy that is written but cannot be read back (here: the plan doubles every face, and the
/// copy's 24 triangles are over `limits.max_triangles = 12`, which the 12-triangle source is not)
/// is removed with its .mtl and texture: no file is left, `repaired_path` stays empty and the
/// message says why.
#[test]
fn a_copy_that_cannot_be_read_back_is_removed_with_its_side_files() {
    let mut settings = meshvet::config::Settings::default();
    settings.limits.max_triangles = 12;
    let planner = |m: &Mesh, o: &meshvet::repair::Options| {
        let mut p = meshvet::repair::plan(m, o);
        let twice = p.triangles.clone();
        p.triangles.extend(twice);
        p
    };
    let (_dir, before, after) = repair_crate_with(&settings, &planner);
    assert!(
        after
            .message
            .contains("repair failed: the copy cannot be read: "),
        "{}",
        after.message
    );
    assert!(after
        .message
        .ends_with(" - no copy written, the source is untouched"));
    assert_eq!(
        (after.repaired_path.as_str(), after.repairs.as_str()),
        ("", "")
    );
    assert_eq!(after.status, before.status);
}

/// The same crate with the real planner: the copy, its .mtl and texture are in place (and no
/// staging folder is left), and the row says what was done.
#[test]
fn the_real_planner_puts_the_copy_and_its_side_files_in_place() {
    let (_dir, src, out) = dirs();
    let settings = meshvet::config::Settings::default();
    let (source, meshes, _) = damaged_crate(&src, &settings);
    let c = cx(&src);
    let mut judged = judged_meshes(&meshes, &settings);
    let repaired = meshvet::copies::repair_file(
        &out,
        &source.report_path,
        &source.path,
        Format::Obj,
        &c,
        &meshes,
        &mut judged,
        None,
        &settings,
        &meshvet::repair::plan_with,
    );
    let outcome = meshvet::scan::outcome(
        &source.display,
        Format::Obj,
        &meshes[0],
        judged.remove(0),
        &repaired[0],
        0.0,
    );
    let row = &outcome.row;
    assert_eq!(row.repairs, "orient-faces:2", "{row:?}");
    assert_eq!(row.status_after, "pass");
    assert_eq!(
        PathBuf::from(&row.repaired_path),
        out.join("props/crate.obj")
    );
    let mut names: Vec<String> = std::fs::read_dir(out.join("props"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["crate.mtl", "crate.obj", "crate.png"]);
}

// ---- files beside the copies of one folder ----------------------------------------------------

/// A glTF of two tetrahedra on the axes, `scale` long, whose buffer is the file `uri`: mesh 0 and
/// mesh 1 (placed 3 along x by its node) both read the positions and indices of that buffer. The
/// document and the buffer's bytes (positions, then indices).
fn tetra_gltf(uri: &str, scale: f32) -> (Value, Vec<u8>) {
    let mut bin = Vec::new();
    for p in [
        [0.0, 0.0, 0.0],
        [scale, 0.0, 0.0],
        [0.0, scale, 0.0],
        [0.0, 0.0, scale],
    ] {
        for x in p {
            bin.extend_from_slice(&f32::to_le_bytes(x));
        }
    }
    for i in [0u16, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let primitive = json!({"attributes": {"POSITION": 0}, "indices": 1});
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [3, 0, 0]}],
        "meshes": [{"primitives": [primitive]}, {"primitives": [primitive]}],
        "buffers": [{"uri": uri, "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 24}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [scale, scale, scale]},
            {"bufferView": 1, "componentType": 5123, "count": 12, "type": "SCALAR"}
        ]
    });
    (doc, bin)
}

/// `models/a.gltf` names `../lod0/mesh.bin`, `models/b.gltf` `../lod1/mesh.bin` (as many bytes,
/// a tetrahedron 5 long instead of 1), `models/c.gltf` `../lod0/mesh.bin` again; each copy
/// rewrites mesh 0 (into a buffer of its own) and leaves mesh 1 reading the source's buffer. The
/// copies go to one folder: a's buffer is copied as `mesh.bin`; b's cannot be (a different
/// `mesh.bin` is there now), so it is `mesh-1.bin` and b's copy names that; c's holds the same
/// bytes as a's and shares `mesh.bin`. Each copy's mesh 1 is still its own source's tetrahedron.
#[test]
fn gltf_copies_in_one_folder_keep_their_own_buffers() {
    let (_dir, src, out) = dirs();
    for (name, lod, scale) in [("a", "lod0", 1.0), ("b", "lod1", 5.0), ("c", "lod0", 1.0)] {
        let (doc, bin) = tetra_gltf(&format!("../{lod}/mesh.bin"), scale);
        std::fs::create_dir_all(src.join("models")).unwrap();
        std::fs::create_dir_all(src.join(lod)).unwrap();
        std::fs::write(src.join(lod).join("mesh.bin"), &bin).unwrap();
        std::fs::write(
            src.join("models").join(format!("{name}.gltf")),
            serde_json::to_vec(&doc).unwrap(),
        )
        .unwrap();
    }
    let c = cx(&src);
    for name in ["a", "b", "c"] {
        let source = src.join("models").join(format!("{name}.gltf"));
        let meshes = read(&source, Format::Gltf, &c).unwrap();
        let plans = vec![Some(identity(&meshes[0])), None];
        let copy = out.join("models").join(format!("{name}.gltf"));
        write_repaired(&source, Format::Gltf, &plans, &copy, &c).unwrap();
    }
    let uri = |name: &str| {
        let copy = out.join("models").join(format!("{name}.gltf"));
        document(&std::fs::read(copy).unwrap())["buffers"][0]["uri"]
            .as_str()
            .unwrap()
            .to_owned()
    };
    assert_eq!(
        [uri("a"), uri("b"), uri("c")],
        ["mesh.bin", "mesh-1.bin", "mesh.bin"]
    );
    assert_eq!(
        std::fs::read(out.join("models/mesh.bin")).unwrap(),
        std::fs::read(src.join("lod0/mesh.bin")).unwrap()
    );
    assert_eq!(
        std::fs::read(out.join("models/mesh-1.bin")).unwrap(),
        std::fs::read(src.join("lod1/mesh.bin")).unwrap()
    );
    for (name, scale) in [("a", 1.0), ("b", 5.0), ("c", 1.0)] {
        let copy = out.join("models").join(format!("{name}.gltf"));
        let meshes = read(&copy, Format::Gltf, &cx(&out)).unwrap();
        let far = meshes[1].positions.iter().map(|p| p[1]).fold(0.0, f64::max);
        assert_eq!(far, scale, "{name}: mesh 1 reads its own source's buffer");
    }
}

/// A repair never moves a side file over a different file: the output folder already holds a
/// `props/crate.mtl` of other bytes (left by an earlier run, or another program's), so the
/// crate's copy brings its library as `crate-1.mtl` and names that; `crate.mtl` keeps its bytes.
#[test]
fn a_side_file_never_replaces_a_different_file() {
    let (_dir, src, out) = dirs();
    let settings = meshvet::config::Settings::default();
    let (source, meshes, _) = damaged_crate(&src, &settings);
    std::fs::create_dir_all(out.join("props")).unwrap();
    std::fs::write(out.join("props/crate.mtl"), "newmtl other\n").unwrap();
    let mut judged = judged_meshes(&meshes, &settings);
    let repaired = meshvet::copies::repair_file(
        &out,
        &source.report_path,
        &source.path,
        Format::Obj,
        &cx(&src),
        &meshes,
        &mut judged,
        None,
        &settings,
        &meshvet::repair::plan_with,
    );
    let copy = out.join("props/crate.obj");
    assert_eq!(repaired[0].notes, Vec::<String>::new());
    assert!(repaired[0].copy.is_some());
    assert_eq!(
        std::fs::read_to_string(out.join("props/crate.mtl")).unwrap(),
        "newmtl other\n"
    );
    assert_eq!(
        std::fs::read(out.join("props/crate-1.mtl")).unwrap(),
        std::fs::read(src.join("props/crate.mtl")).unwrap()
    );
    let text = std::fs::read_to_string(&copy).unwrap();
    assert_eq!(lines_with(&text, "mtllib"), ["mtllib crate-1.mtl"]);
}

/// Two OBJs repaired into one folder bring different libraries of one name from shared folders
/// (`models/a.obj` names `../red/common.mtl`, `models/b.obj` `../blue/common.mtl`, each naming
/// `../textures/paint.png` of its own), and a third names `../red/common.mtl` again. The first
/// copy's library is `common.mtl`; the second's cannot be (a different `common.mtl` is there), so
/// it is `common-1.mtl` and its texture `paint-1.png`, and the copy names them; the third shares
/// the first's. Each copy, read from the output folder alone, has its own source's colour.
#[test]
fn obj_copies_in_one_folder_keep_their_own_libraries() {
    let (_dir, src, out) = dirs();
    std::fs::create_dir_all(src.join("models")).unwrap();
    for (colour, kd) in [("red", "1 0 0"), ("blue", "0 0 1")] {
        std::fs::create_dir_all(src.join(colour).join("textures")).unwrap();
        std::fs::write(
            src.join(colour).join("common.mtl"),
            format!("newmtl paint\nKd {kd}\nmap_Kd textures/paint.png\n"),
        )
        .unwrap();
        std::fs::write(src.join(colour).join("textures/paint.png"), colour).unwrap();
    }
    let c = cx(&src);
    for (name, colour) in [("a", "red"), ("b", "blue"), ("c", "red")] {
        let source = src.join("models").join(format!("{name}.obj"));
        std::fs::write(
            &source,
            format!(
                "mtllib ../{colour}/common.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl paint\nf 1 2 3\n"
            ),
        )
        .unwrap();
        let meshes = read(&source, Format::Obj, &c).unwrap();
        let plans = [Some(identity(&meshes[0]))];
        let copy = out.join("models").join(format!("{name}.obj"));
        write_repaired(&source, Format::Obj, &plans, &copy, &c).unwrap();
    }
    let models = out.join("models");
    for (name, library, kd, texture, colour) in [
        ("a", "common.mtl", "1 0 0", "textures/paint.png", "red"),
        ("b", "common-1.mtl", "0 0 1", "textures/paint-1.png", "blue"),
        ("c", "common.mtl", "1 0 0", "textures/paint.png", "red"),
    ] {
        let text = std::fs::read_to_string(models.join(format!("{name}.obj"))).unwrap();
        assert_eq!(
            lines_with(&text, "mtllib"),
            [format!("mtllib {library}")],
            "{name}"
        );
        let mtl = std::fs::read_to_string(models.join(library)).unwrap();
        assert_eq!(
            mtl,
            format!("newmtl paint\nKd {kd}\nmap_Kd {texture}\n"),
            "{name}"
        );
        assert_eq!(
            std::fs::read_to_string(models.join(texture)).unwrap(),
            colour
        );
    }
    assert_eq!(files_under(&out).len(), 7, "{:?}", files_under(&out));
}

/// A binary STL with bytes after its last facet (a trailing newline; padding longer than a
/// facet) is read as binary, with a note, so its copy is binary too: the header and each facet's
/// attribute word kept, exactly `84 + 50 n` bytes; the padding is left out, said in a note.
#[test]
fn padded_binary_stl_copy_stays_binary() {
    for pad in [&b"\n"[..], &[0u8; 64][..]] {
        let (_dir, src, out) = dirs();
        let mut bytes = stl_binary();
        bytes.extend_from_slice(pad);
        let (plan, mesh, _) = binary_stl_copy(&src, &out, &bytes);
        assert!(mesh.notes[0].starts_with(&format!("{} byte(s) after the 12 triangles", pad.len())));
        let written = write_copy(
            &src.join("cube.stl"),
            Format::Stl,
            &[Some(plan)],
            &out.join("again.stl"),
            &cx(&src),
            None,
        )
        .unwrap();
        assert_eq!(
            written.notes,
            [format!(
                "the {} byte(s) after the source's binary facets (padding the reader ignored) are \
                 not in the copy",
                pad.len()
            )]
        );
    }
}

/// A PLY whose face lists hold `uchar` vertex numbers, with 256 vertices (0..255, all used): a
/// tetrahedron on the axes and a square pyramid below it share vertex 0, which is non-manifold,
/// and 62 more tetrahedra along x use the other 248. The repair gives vertex 0 a copy, the 257th
/// vertex, number 256, which a `uchar` cannot hold: the copy's list is `ushort` (said in a note),
/// and its faces name vertex 256, at vertex 0's place (moved a hair into its fan), in both
/// encodings.
#[test]
fn ply_index_lists_are_widened_when_the_repair_numbers_past_them() {
    let mut positions: Vec<[f64; 3]> = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [-1.0, -1.0, -1.0],
        [1.0, -1.0, -1.0],
        [1.0, 1.0, -1.0],
        [-1.0, 1.0, -1.0],
    ];
    // Outward: the tetrahedron, then the pyramid's base (seen from below) and sides.
    let tetra = |b: u32| {
        [
            [b, b + 2, b + 1],
            [b, b + 1, b + 3],
            [b + 1, b + 2, b + 3],
            [b, b + 3, b + 2],
        ]
    };
    let mut faces: Vec<Vec<u32>> = tetra(0).iter().map(|f| f.to_vec()).collect();
    faces.push(vec![4, 7, 6, 5]);
    faces.extend([[4, 5, 0], [5, 6, 0], [6, 7, 0], [7, 4, 0]].map(|f| f.to_vec()));
    for k in 0..62 {
        let b = positions.len() as u32;
        let x = 5.0 + 3.0 * k as f64;
        positions.extend([
            [x, 0.0, 0.0],
            [x + 1.0, 0.0, 0.0],
            [x, 1.0, 0.0],
            [x, 0.0, 1.0],
        ]);
        faces.extend(tetra(b).iter().map(|f| f.to_vec()));
    }
    assert_eq!(positions.len(), 256);
    for encoding in ["ascii", "binary_little_endian"] {
        let dir = tempfile::tempdir().unwrap();
        let (src, out) = (dir.path().join("src"), dir.path().join("out"));
        std::fs::create_dir_all(&src).unwrap();
        let mut bytes = format!(
            "ply\nformat {encoding} 1.0\nelement vertex 256\nproperty float x\nproperty float y\n\
             property float z\nelement face {}\nproperty list uchar uchar vertex_indices\nend_header\n",
            faces.len()
        )
        .into_bytes();
        if encoding == "ascii" {
            for p in &positions {
                bytes.extend(format!("{} {} {}\n", p[0], p[1], p[2]).bytes());
            }
            for f in &faces {
                let numbers: Vec<String> = f.iter().map(u32::to_string).collect();
                bytes.extend(format!("{} {}\n", f.len(), numbers.join(" ")).bytes());
            }
        } else {
            for p in &positions {
                for x in p {
                    bytes.extend((*x as f32).to_le_bytes());
                }
            }
            for f in &faces {
                bytes.push(f.len() as u8);
                bytes.extend(f.iter().map(|&v| v as u8));
            }
        }
        std::fs::write(src.join("parts.ply"), &bytes).unwrap();
        let settings = meshvet::config::Settings {
            repair_dir: Some(out.clone()),
            ..Default::default()
        };
        let source = meshvet::walk::walk(
            std::slice::from_ref(&src),
            &meshvet::walk::Filter::everything(),
        )
        .remove(0);
        let outcomes = meshvet::scan::scan_file(&source, &settings);
        let row = &outcomes[0].row;
        assert_eq!(row.findings, "non-manifold-vertex:1", "{encoding}: {row:?}");
        assert_eq!(row.repairs, "split-non-manifold-vertices:1", "{encoding}");
        assert_eq!(
            (row.status_after.as_str(), row.findings_after.as_str()),
            ("pass", ""),
            "{encoding}"
        );
        assert!(
            row.message.contains(
                "copy: the PLY face list `vertex_indices` is ushort in the copy instead of uchar: \
                 the repair numbers vertices up to 256, past what uchar holds"
            ),
            "{encoding}: {}",
            row.message
        );
        let copy_path = out.join("parts.ply");
        let copy = std::fs::read(&copy_path).unwrap();
        let text = String::from_utf8_lossy(&copy);
        assert!(
            text.contains("element vertex 257\n")
                && text.contains("property list uchar ushort vertex_indices\n"),
            "{encoding}: {text}"
        );
        let again = read(&copy_path, Format::Ply, &cx(&out)).unwrap().remove(0);
        assert_eq!(again.positions.len(), 257);
        // The 256 source vertices keep their places; the copy is vertex 0's, a hair away.
        assert_eq!(again.positions[..256], positions[..]);
        let moved = again.positions[256];
        assert!(moved.iter().all(|x| x.abs() < 0.01), "{moved:?}");
        let named: BTreeSet<u32> = again.triangles.iter().flatten().copied().collect();
        assert_eq!(
            named.len(),
            257,
            "{encoding}: every vertex, 256 too, is named"
        );
    }
}

/// One texture reached from two libraries of one source folder that land in different folders of
/// the copy: `mtllib sub/l1.mtl ../models/sub/l2.mtl` keeps `sub/l1.mtl` in place and brings the
/// second (named through `../`) beside the copy as `l2.mtl`. Both name `wood.png` beside
/// themselves, so the copy needs it twice: `sub/wood.png` for `l1.mtl` and `wood.png` for
/// `l2.mtl` (it was written once, and `l2.mtl` named a file that was not there).
#[test]
fn a_texture_two_libraries_name_is_beside_each_in_the_copy() {
    let (_dir, src, out) = dirs();
    std::fs::create_dir_all(src.join("models/sub")).unwrap();
    for (lib, material) in [("l1", "m"), ("l2", "n")] {
        std::fs::write(
            src.join(format!("models/sub/{lib}.mtl")),
            format!("newmtl {material}\nmap_Kd wood.png\n"),
        )
        .unwrap();
    }
    std::fs::write(src.join("models/sub/wood.png"), "wood").unwrap();
    let obj =
        "mtllib sub/l1.mtl ../models/sub/l2.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n";
    let source = src.join("models/a.obj");
    std::fs::write(&source, obj).unwrap();
    let c = cx(&src);
    let meshes = read(&source, Format::Obj, &c).unwrap();
    let copy = out.join("models/a.obj");
    write_repaired(
        &source,
        Format::Obj,
        &[Some(identity(&meshes[0]))],
        &copy,
        &c,
    )
    .unwrap();
    let text = std::fs::read_to_string(&copy).unwrap();
    assert_eq!(lines_with(&text, "mtllib"), ["mtllib sub/l1.mtl l2.mtl"]);
    let models = out.join("models");
    for (library, texture) in [("sub/l1.mtl", "sub/wood.png"), ("l2.mtl", "wood.png")] {
        let mtl = std::fs::read_to_string(models.join(library)).unwrap();
        assert!(mtl.ends_with("map_Kd wood.png\n"), "{library}: {mtl}");
        assert_eq!(
            std::fs::read_to_string(models.join(texture)).unwrap(),
            "wood",
            "{texture}"
        );
    }
}

/// The change check covers glTF too, where the meshes live in a buffer file beside the document:
/// the box's buffer is rewritten after the scan read it, its first position moved from the
/// origin to (0.5, 0, 0). The document is the same bytes, so only the buffer tells; the copy is
/// refused. So is a GLB whose binary chunk changed the same way. (This tests the check, which
/// was untested for these formats; that the writer compares the very bytes it copies, with no
/// second read between, is a window no test here can open.)
#[test]
fn a_gltf_whose_buffer_changed_after_the_scan_read_it_is_not_copied() {
    let moved = |bin: &[u8]| {
        let mut bin = bin.to_vec();
        bin[..4].copy_from_slice(&0.5f32.to_le_bytes());
        bin
    };
    let refuse = |source: &Path, format: Format, change: &dyn Fn()| {
        let root = source.parent().unwrap();
        let c = cx(root);
        let meshes = read(source, format, &c).unwrap();
        assert_eq!(meshes[0].positions[0], [0.0; 3]);
        let plans = gltf_plans(&meshes);
        change();
        let copy = root.join("out").join(source.file_name().unwrap());
        let scanned = ScanRead {
            meshes: &meshes,
            retained: None,
        };
        let refused = write_copy(source, format, &plans, &copy, &c, Some(scanned));
        assert_eq!(
            refused.map_err(|e| e.to_string()),
            Err("the file changed after the scan read it: scan it again to repair it".into()),
            "{format:?}"
        );
        assert!(!copy.exists(), "{format:?}");
    };

    let (_dir, src, _out) = dirs();
    let (mut doc, bin) = gltf_asset();
    std::fs::write(src.join("tex/wood.png"), b"png").unwrap();
    std::fs::write(src.join("box.bin"), &bin).unwrap();
    doc["buffers"][0]["uri"] = json!("box.bin");
    let gltf = src.join("box.gltf");
    std::fs::write(&gltf, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    refuse(&gltf, Format::Gltf, &|| {
        std::fs::write(src.join("box.bin"), moved(&bin)).unwrap()
    });

    let (doc, bin) = gltf_asset();
    let source = src.join("box.glb");
    std::fs::write(&source, glb(&doc, &bin)).unwrap();
    refuse(&source, Format::Glb, &|| {
        std::fs::write(&source, glb(&doc, &moved(&bin))).unwrap()
    });
}

/// The limit on the bytes a glTF's buffer files give holds for the scan's read and for what the
/// copy reads besides, each on its own, though the writer now reads both in one pass: mesh 0
/// takes its positions from `a.bin` and its normals from `b.bin`, mesh 1 its positions from
/// `c.bin`, 1,000 bytes each, under a limit of 2,000. The scan reads a + c (2,000), the copy of
/// mesh 0 a + b (2,000): each within it, so the copy is written (counted together, 3,000, it was
/// refused). With `b.bin` grown to 2,001 bytes the scan still reads it, and the copy is refused,
/// saying to raise the limit to repair it.
#[test]
fn the_buffer_limit_holds_for_the_scan_and_the_copy_each() {
    let (_dir, src, out) = dirs();
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let file = |mut data: Vec<u8>, size: usize| {
        data.resize(size, 0);
        data
    };
    let triangle = f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let normals = f32s(&[0.0, 0.0, 1.0].repeat(3));
    std::fs::write(src.join("a.bin"), file(triangle.clone(), 1000)).unwrap();
    std::fs::write(src.join("c.bin"), file(triangle, 1000)).unwrap();
    let accessor = |view: usize| {
        json!({"bufferView": view, "componentType": 5126, "count": 3, "type": "VEC3",
               "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0]})
    };
    let views: Vec<Value> = (0..3)
        .map(|b| json!({"buffer": b, "byteLength": 36}))
        .collect();
    let source = src.join("s.gltf");
    let c = ReadContext {
        root: src.clone(),
        limits: Limits {
            max_file_bytes: 2000,
            ..Limits::default()
        },
    };
    let copy_with_normals_of = |size: usize, name: &str| {
        std::fs::write(src.join("b.bin"), file(normals.clone(), size)).unwrap();
        let doc = json!({
            "asset": {"version": "2.0"},
            "buffers": [
                {"uri": "a.bin", "byteLength": 1000},
                {"uri": "b.bin", "byteLength": size},
                {"uri": "c.bin", "byteLength": 1000}
            ],
            "bufferViews": views,
            "accessors": [accessor(0), accessor(1), accessor(2)],
            "meshes": [
                {"name": "m0", "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}}]},
                {"name": "m1", "primitives": [{"attributes": {"POSITION": 2}}]}
            ],
            "nodes": [{"mesh": 0}, {"mesh": 1}],
            "scenes": [{"nodes": [0, 1]}],
            "scene": 0
        });
        std::fs::write(&source, serde_json::to_vec(&doc).unwrap()).unwrap();
        let meshes = read(&source, Format::Gltf, &c).unwrap();
        let plans = [Some(identity(&meshes[0])), None];
        write_repaired(&source, Format::Gltf, &plans, &out.join(name), &c)
            .map_err(|e| e.to_string())
    };
    copy_with_normals_of(1000, "s.gltf").unwrap();
    assert!(out.join("s.gltf").is_file());
    let e = copy_with_normals_of(2001, "t.gltf").unwrap_err();
    assert!(e.contains("besides the scan's add 2001 bytes"), "{e}");
    assert!(e.contains("config to repair it"), "{e}");
}
