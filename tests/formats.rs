//! The OBJ, STL, PLY and OFF readers through `meshvet::formats::read`, on files written to a
//! temporary folder: each format's happy path with hand-counted positions and triangles, hostile
//! inputs (empty, truncated, absurd header counts, NaN, indices out of range, binary garbage,
//! another format under the extension) and the real-world corpus in `../shared/corpus`.

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use meshvet::formats::{read, Format, Limits, ReadContext, ReadError};
use meshvet::Mesh;

/// Writes `bytes` to `name` in a fresh temporary folder and reads it as that name's format.
fn load(name: &str, bytes: &[u8]) -> Result<Mesh, ReadError> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    load_path(&path, dir.path())
}

fn load_path(path: &Path, root: &Path) -> Result<Mesh, ReadError> {
    let cx = ReadContext {
        root: root.to_path_buf(),
        limits: Limits::default(),
    };
    let format = Format::of_path(path).expect("a mesh extension");
    let mut meshes = read(path, format, &cx)?;
    assert_eq!(meshes.len(), 1, "one mesh per file for {}", path.display());
    let mesh = meshes.pop().unwrap();
    assert!(mesh.name.is_none());
    let n = mesh.positions.len() as u32;
    assert!(
        mesh.triangles.iter().flatten().all(|&i| i < n),
        "index out of range"
    );
    Ok(mesh)
}

fn ok(name: &str, bytes: &[u8]) -> Mesh {
    load(name, bytes).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn err(name: &str, bytes: &[u8]) -> String {
    match load(name, bytes) {
        Ok(m) => panic!("{name} should not load, got {m:?}"),
        Err(e) => e.0,
    }
}

fn binary_stl(tris: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut b = b"solid binary header written by an exporter that says solid".to_vec();
    b.resize(80, b' ');
    b.extend((tris.len() as u32).to_le_bytes());
    for t in tris {
        b.extend([0u8; 12]);
        for c in t.iter().flatten() {
            b.extend(c.to_le_bytes());
        }
        b.extend([0u8; 2]);
    }
    b
}

/// A unit cube as 8 vertices and 6 quads (OBJ numbering, 1-based): V=8, F=12 triangles.
const CUBE_OBJ: &str = "\
mtllib cube.mtl
o cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
v 5 5 5
vt 0 0
vn 0 0 -1
usemtl red
f 1/1/1 4/1/1 3/1/1 2/1/1
f 5 6 7 8
g sides
f 1//1 2//1 6//1 5//1
f 2 3 7 6
f 3 4 8 7
f -9 -5 -2 -6
";

#[test]
fn obj_cube_keeps_the_unreferenced_vertex() {
    let m = ok("cube.obj", CUBE_OBJ.as_bytes());
    // 9 `v` lines, one of them unreferenced; 6 quads -> 12 triangles.
    assert_eq!(m.positions.len(), 9);
    assert_eq!(m.positions[8], [5.0, 5.0, 5.0]);
    assert_eq!(m.triangles.len(), 12);
    // The last face is relative: with 9 vertices, -9 -5 -2 -6 are vertices 1 5 8 4 (0-based
    // 0 4 7 3), a convex square split as a fan.
    assert_eq!(m.triangles[10..], [[0, 4, 7], [0, 7, 3]]);
    // The .mtl is missing: a note, not an error.
    assert!(m
        .notes
        .iter()
        .any(|n| n.contains("cube.mtl") && n.contains("not found")));
}

#[test]
fn obj_mtl_that_crashes_tobj_is_a_note() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 1 0\n").unwrap();
    let obj = dir.path().join("m.obj");
    std::fs::write(
        &obj,
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n",
    )
    .unwrap();
    let m = load_path(&obj, dir.path()).unwrap();
    assert_eq!(m.triangles.len(), 1);
    let note = m.notes.join("\n");
    assert!(note.contains("m.mtl") && note.contains("Kd"), "{note}");
    // A good .mtl gives no note; one outside the folder is not read.
    std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
    assert!(load_path(&obj, dir.path()).unwrap().notes.is_empty());
    std::fs::write(&obj, "mtllib ../m.mtl\nv 0 0 0\n").unwrap();
    let m = load_path(&obj, dir.path()).unwrap();
    assert!(
        m.notes[0].contains("leaves the scanned folder"),
        "{:?}",
        m.notes
    );
}

#[test]
fn obj_hostile() {
    assert!(ok("e.obj", b"").triangles.is_empty());
    let e = err("z.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    assert!(e.contains("line 4") && e.contains("start at 1"), "{e}");
    let e = err("r.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 30\n");
    assert!(e.contains("line 5") && e.contains("30"), "{e}");
    let m = ok("n.obj", b"v nan inf -inf\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert!(m.positions[0][0].is_nan() && m.positions[0][1] == f64::INFINITY);
    assert!(err("u.obj", b"\xff\xfev\x00 \x001\x00").contains("UTF-16"));
    let garbage: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    let _ = load("g.obj", &garbage); // error or notes, never a panic
    let png = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR";
    assert!(err("p.obj", png).contains("looks like a PNG image"));
    let m = ok("pl.obj", b"v 0 0 0\nv 1 0 0\np 1 2\nl 1 2\n");
    assert!(
        m.triangles.is_empty() && m.notes.len() == 2,
        "{:?}",
        m.notes
    );
}

#[test]
fn stl_binary_and_ascii() {
    let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, -0.0]];
    let m = ok("b.stl", &binary_stl(&[t, t, t]));
    assert_eq!((m.positions.len(), m.triangles.len()), (9, 3));
    assert_eq!(m.triangles[2], [6, 7, 8]);
    let ascii =
        "solid one\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n\
                 endloop\nendfacet\nendsolid one\nsolid two\n  facet normal 0 0 1\n    outer loop\n\
                 vertex 0 0 1\nvertex 1 0 1\nvertex 1 1 1\nvertex 0.5 1.5 1\nvertex 0 1 1\n\
                 endloop\n  endfacet\nendsolid two\n";
    let m = ok("a.stl", ascii.as_bytes());
    // A triangle and a pentagon: 3 + 5 positions, 1 + 3 triangles.
    assert_eq!((m.positions.len(), m.triangles.len()), (8, 4));
}

#[test]
fn stl_hostile() {
    assert!(ok("e.stl", b"").triangles.is_empty());
    let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mut b = binary_stl(&vec![t; 40]);
    b.truncate(84 + 50 * 37 + 11);
    let e = err("t.stl", &b);
    assert!(
        e.contains("declares 40 triangles") && e.contains("holds 37"),
        "{e}"
    );
    // A header claiming 4 billion triangles in a small file.
    let mut b = binary_stl(&[t]);
    b[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(err("h.stl", &b).contains("declares 4294967295"));
    let nan = [[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert!(ok("n.stl", &binary_stl(&[nan])).positions[0][0].is_nan());
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.resize(300, 0);
    assert!(err("png.stl", &png).contains("not an STL"));
    assert!(err(
        "s.stl",
        b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
    )
    .contains("line"));
}

const PLY_HEAD: &str =
    "ply\nformat ascii 1.0\nelement vertex 5\nproperty double x\nproperty double y\n\
    property double z\nelement face 2\nproperty list uchar uint vertex_indices\nend_header\n";

#[test]
fn ply_ascii_and_binary() {
    // A pentagon and a triangle: 3 + 1 triangles.
    let s = format!("{PLY_HEAD}0 0 0\n2 0 0\n2 2 0\n1 1 0\n0 2 0\n5 0 1 2 3 4\n3 0 1 3\n");
    let m = ok("a.ply", s.as_bytes());
    assert_eq!((m.positions.len(), m.triangles.len()), (5, 4));
    // The pentagon is concave at (1,1): ear clipping, noted.
    assert!(
        m.notes.iter().any(|n| n.contains("ear clipping")),
        "{:?}",
        m.notes
    );

    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_index\n\
        end_header\n"
        .to_vec();
    for c in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        b.extend(c.to_le_bytes());
    }
    b.push(3);
    for i in [0i32, 1, 2] {
        b.extend(i.to_le_bytes());
    }
    let m = ok("b.ply", &b);
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    b.truncate(b.len() - 2);
    assert!(err("t.ply", &b).contains("truncated"));
}

#[test]
fn ply_hostile() {
    assert!(ok("e.ply", b"").triangles.is_empty());
    let huge = "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\n\
        property float y\nproperty float z\nend_header\n0 0 0\n";
    let e = err("h.ply", huge.as_bytes());
    assert!(e.contains("4000000000") && e.contains("truncated"), "{e}");
    let s = format!("{PLY_HEAD}0 0 0\n2 0 0\n2 2 0\nnan 1 0\n0 2 0\n3 0 1 2\n3 0 1 5\n");
    let e = err("r.ply", s.as_bytes());
    assert!(e.contains("face 1") && e.contains("vertex index 5"), "{e}");
    let s = format!("{PLY_HEAD}0 0 0\n2 0 0\n2 2 0\nnan 1 0\n0 2 0\n3 0 1 2\n3 0 1 3\n");
    assert!(ok("n.ply", s.as_bytes()).positions[3][0].is_nan());
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.resize(300, 7);
    assert!(err("png.ply", &png).contains("not a PLY"));
    let garbage: Vec<u8> = b"ply\n"
        .iter()
        .copied()
        .chain((0..2000u32).map(|i| (i.wrapping_mul(40503) >> 7) as u8))
        .collect();
    let _ = load("g.ply", &garbage);
}

#[test]
fn off_happy_and_hostile() {
    // Header counts on the OFF line, comments, a quad with a colour: 4 positions, 2 + 1 triangles.
    let m = ok(
        "q.off",
        b"OFF 4 2 0 # counts here\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 0.5 0.5 0.5\n3 0 2 3\n",
    );
    assert_eq!((m.positions.len(), m.triangles.len()), (4, 3));
    assert!(ok("e.off", b"").triangles.is_empty());
    let e = err("h.off", b"OFF\n4000000000 4000000000 0\n0 0 0\n");
    assert!(e.contains("truncated") && e.contains("4000000000"), "{e}");
    let e = err("r.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
    assert!(e.contains("line 6") && e.contains("7"), "{e}");
    assert!(ok("n.off", b"OFF\n3 1 0\nnan 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").positions[0][0].is_nan());
    assert!(err("t.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n").contains("truncated"));
    assert!(err("png.off", b"\x89PNG\r\n\x1a\n\0\0").contains("not an OFF"));
}

/// `n` bytes of compressed-looking data without a zero byte (zeros turned into ones): about one in
/// nine is a control character, about half are not UTF-8.
fn noise(n: usize) -> Vec<u8> {
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 24) as u8
        })
        .map(|b| b.max(1))
        .collect()
}

/// A PNG renamed to each text format (its signature, then bytes with no zero among them): an
/// error naming the PNG, never an `empty` row; the same for other signatures, and binary data
/// of no known format is binary data (by its control characters).
#[test]
fn binary_content_named_as_a_text_format_is_an_error_that_says_what_it_looks_like() {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(noise(3000));
    for (name, what) in [
        ("a.obj", "an OBJ"),
        ("a.off", "an OFF"),
        ("a.ply", "a PLY"),
        ("a.stl", "an STL"),
    ] {
        let e = err(name, &png);
        assert!(
            e.contains(&format!("this looks like a PNG image, not {what} file")),
            "{name}: {e}"
        );
    }
    let mut zip = b"PK\x03\x04".to_vec();
    zip.extend(noise(500));
    assert!(err("z.obj", &zip).contains("looks like a ZIP archive"));
    let mut pdf = b"%PDF-1.7\n".to_vec();
    pdf.extend(noise(500));
    assert!(err("d.stl", &pdf).contains("looks like a PDF document, not an STL file"));
    assert!(err("g.off", b"glTF\x02\x00\x00\x00").contains("binary glTF"));
    let e = err("n.obj", &noise(3000));
    assert!(
        e.contains("not a text OBJ file: binary data (control characters"),
        "{e}"
    );
    let e = err("n.off", &noise(3000));
    assert!(e.contains("not a text OFF file: binary data"), "{e}");
    assert!(err("u.off", b"\xff\xfeO\0F\0F\0").contains("UTF-16"));
}

/// What is still text: Latin-1 names (a note), and an OBJ after a short binary preamble (a web
/// archive holding the text: 20 control characters in its first 8 KiB, zeros only after them),
/// whose 200 squares are read as 400 triangles.
#[test]
fn latin1_names_and_a_short_binary_preamble_stay_text() {
    let m = ok(
        "l.obj",
        b"# export\xe9 par Mod\xe8le\no caf\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    assert_eq!(m.triangles.len(), 1);
    assert!(m.notes.iter().any(|n| n.contains("not valid UTF-8")));
    let mut archive =
        b"bplist00\xd1\x01\x02_\x10\x0fWebMainResource\xd5\x03\x04\x05\x06\x07\x08\x09\
        \x0a\x0b\x0c_\x10\x0fWebResource\x0e\x11\x12\x13\x14\x15<html><pre>\n"
            .to_vec();
    let square = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";
    archive.extend(square.repeat(200).as_bytes());
    archive.extend(b"</pre></html>\x00\x00\x01");
    let m = ok("w.obj", &archive);
    assert_eq!(m.triangles.len(), 400);
}

/// Awkward coordinates read by every text reader to the very `f64` the standard parser gives
/// (a NaN for a NaN): 17+ significant digits, ties, subnormals, just past the largest double,
/// overflow and underflow, signed zeros, `.5`, `5.`, `+3` and the infinity and NaN spellings.
#[test]
fn awkward_numbers_read_as_the_standard_parser_reads_them() {
    // Nine vertices: three STL facets.
    const NUMBERS: [&str; 27] = [
        "0.1",
        "-0",
        "+3",
        ".5",
        "5.",
        "-.5e-3",
        "1e400",
        "-1e400",
        "1e-400",
        "4.9e-324",
        "2.2250738585072011e-308",
        "1.7976931348623158e308",
        "1.7976931348623159e308",
        "3.14159265358979323846264338327950288",
        "9007199254740993",
        "0.30000000000000004",
        "123456789012345678901234567890e-20",
        "inf",
        "-Infinity",
        "+INF",
        "nan",
        "-NaN",
        "NAN",
        "1E+2",
        "-0.0",
        "1e-5",
        "000.000001",
    ];
    let triples: Vec<[&str; 3]> = NUMBERS.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
    let n = triples.len();
    let mut obj = String::new();
    let mut off = format!("OFF\n{n} 1 0\n");
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {n}\nproperty double x\nproperty double y\n\
         property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    );
    let mut stl = String::from("solid s\n");
    for (k, [x, y, z]) in triples.iter().enumerate() {
        obj.push_str(&format!("v {x} {y}\t{z}\n"));
        off.push_str(&format!("{x} {y} {z} # comment\n"));
        ply.push_str(&format!("{x} {y} {z}\n"));
        if k % 3 == 0 {
            stl.push_str("facet normal 0 0 0\nouter loop\n");
        }
        stl.push_str(&format!("vertex {x} {y} {z}\n"));
        if k % 3 == 2 {
            stl.push_str("endloop\nendfacet\n");
        }
    }
    obj.push_str("f 1 2 3\n");
    off.push_str("3 0 1 2\n");
    ply.push_str("3 0 1 2\n");
    stl.push_str("endsolid s\n");
    let expected: Vec<[f64; 3]> = triples
        .iter()
        .map(|t| t.map(|x| x.parse::<f64>().unwrap()))
        .collect();
    let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    for (name, text) in [
        ("a.obj", obj),
        ("a.off", off),
        ("a.ply", ply),
        ("a.stl", stl),
    ] {
        let m = ok(name, text.as_bytes());
        assert!(m.notes.is_empty(), "{name}: {:?}", m.notes);
        assert_eq!(m.positions.len(), n, "{name}");
        for (got, want) in m.positions.iter().zip(&expected) {
            assert!(
                (0..3).all(|k| same(got[k], want[k])),
                "{name}: {got:?} vs {want:?}"
            );
        }
    }
}

/// Every mesh file of the shared corpus loads without a panic, and where the reference libraries
/// agree unanimously (k/k, k >= 2) on the triangle count, ours is the same.
#[test]
fn corpus() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    if !root.is_dir() {
        println!("skip: no corpus at {}", root.display());
        return;
    }
    // Files where the references count differently by definition (reason given).
    let excluded: BTreeMap<&str, &str> = BTreeMap::from([
        (
            "assimp/OFF/invalid.off",
            "face 1 uses vertex index 20 in a 3-vertex file: an index out of range is an error \
             row for us, the libraries drop the face",
        ),
        (
            "tinyobjloader/invalid-relative-vertex-index.obj",
            "relative index before the first vertex: an error row for us, the libraries drop \
             the face",
        ),
        (
            "tinyobjloader/invalid-relative-texture-index.obj",
            "face index 1 with no vertices in the file: an error row for us, the libraries drop \
             the face",
        ),
        (
            "assimp/nonbsd/ant-half.ply",
            "truncated: the data ends after 259 of the 912 faces the header declares; a \
             truncated file is an error row for us, the libraries keep the 259 faces",
        ),
        (
            "assimp/PLY/issue623.ply",
            "the header puts `vertex_indices` on the vertex element (no face element) and the \
             vertex lines lack it: an error row for us, the libraries read the vertices only",
        ),
        (
            "draco/Box.ply",
            "header lines end with a bare CR (old Mac style): we read the 8 faces (4 quads, \
             4 triangles = 12, consuming the 800-byte payload exactly); the libraries find none",
        ),
    ]);

    let mut reference = BTreeMap::new();
    let mut csv = csv::Reader::from_path(root.join("reference_consensus.csv")).unwrap();
    let headers = csv.headers().unwrap().clone();
    let col = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let (file, tris, support) = (col("file"), col("n_triangles"), col("n_triangles_support"));
    for row in csv.records() {
        let row = row.unwrap();
        let Some((k, of)) = row[support].split_once('/') else {
            continue;
        };
        if k == of && k.parse::<u32>().unwrap_or(0) >= 2 {
            if let Ok(n) = row[tris].parse::<usize>() {
                reference.insert(row[file].to_string(), n);
            }
        }
    }

    let mut files = Vec::new();
    for entry in walkdir::WalkDir::new(&root).sort_by_file_name() {
        let entry = entry.unwrap();
        let ext = entry
            .path()
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if matches!(ext.as_deref(), Some("obj" | "stl" | "ply" | "off")) {
            files.push(entry.into_path());
        }
    }
    let (mut loaded, mut errors, mut matched, mut panics, mut mismatches) =
        (0, 0, 0, vec![], vec![]);
    for path in &files {
        let rel = path
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let result = catch_unwind(AssertUnwindSafe(|| load_path(path, &root)));
        let mesh = match result {
            Err(_) => {
                panics.push(rel);
                continue;
            }
            Ok(Err(e)) => {
                errors += 1;
                println!("error  {rel}: {e}");
                None
            }
            Ok(Ok(m)) => {
                loaded += 1;
                Some(m)
            }
        };
        let Some(&expected) = reference.get(&rel) else {
            continue;
        };
        let got = mesh.as_ref().map(|m| m.triangles.len());
        if got == Some(expected) {
            matched += 1;
        } else if let Some(reason) = excluded.get(rel.as_str()) {
            println!("excluded {rel}: ours {got:?}, references {expected}: {reason}");
        } else {
            mismatches.push(format!("{rel}: ours {got:?}, references {expected}"));
        }
    }
    println!(
        "corpus: {} files, {loaded} loaded, {errors} errors, {} with a k/k reference count: {matched} \
         matched, {} excluded, {} mismatched",
        files.len(),
        files.iter().filter(|p| reference.contains_key(&p.strip_prefix(&root).unwrap().to_string_lossy().replace('\\', "/"))).count(),
        excluded.len(),
        mismatches.len()
    );
    assert!(panics.is_empty(), "panics: {panics:#?}");
    assert!(
        mismatches.is_empty(),
        "triangle counts differ: {mismatches:#?}"
    );
}

// ---------------------------------------------------------------------------------------------
// Audit regressions: hangs, blocking reads, reads outside the tree, refused padding

/// Runs `f` on another thread and fails the test if it takes longer than `seconds` (a hang must
/// fail the test, not stall the suite forever).
fn within<T: Send + 'static>(seconds: u64, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (send, receive) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = send.send(f());
    });
    receive
        .recv_timeout(std::time::Duration::from_secs(seconds))
        .unwrap_or_else(|_| panic!("did not finish within {seconds} s"))
}

fn load_owned(name: &'static str, bytes: Vec<u8>) -> Result<Mesh, ReadError> {
    load(name, &bytes)
}

/// A PLY with one triangle and an element `junk` with 2^64 - 1 entries and no properties.
fn ply_with_empty_element(format: &str) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat {format} 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nelement junk 18446744073709551615\nelement face 1\n\
         property list uchar int vertex_indices\nend_header\n"
    )
    .into_bytes();
    if format == "ascii" {
        b.extend(b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    } else {
        for c in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            b.extend(c.to_le_bytes());
        }
        b.push(3);
        for i in [0i32, 1, 2] {
            b.extend(i.to_le_bytes());
        }
    }
    b
}

#[test]
fn ply_element_without_properties_and_a_huge_count_does_not_hang() {
    for format in ["binary_little_endian", "ascii"] {
        let bytes = ply_with_empty_element(format);
        let m = within(20, move || load_owned("junk.ply", bytes))
            .unwrap_or_else(|e| panic!("{format}: {e}"));
        assert_eq!(m.triangles, vec![[0, 1, 2]], "{format}");
        assert!(
            m.notes
                .iter()
                .any(|n| n.contains("`junk`") && n.contains("no properties")),
            "{format}: {:?}",
            m.notes
        );
    }
}

/// An ASCII STL whose `solid` starts anywhere from byte 0 to byte 90 (after spaces or line ends)
/// is read as ASCII: one triangle. With 80 to 83 blanks first, `solid` runs past the 84 bytes of
/// a binary header, which then read as a count of 1.7 billion triangles, and the file was
/// refused as a truncated binary STL.
#[test]
fn ascii_stl_after_many_blanks_stays_ascii() {
    let body = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n\
                vertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
    for blanks in 0..=90 {
        for blank in [" ", "\n"] {
            let text = format!("{}{body}", blank.repeat(blanks));
            let m = ok("a.stl", text.as_bytes());
            assert_eq!(m.triangles.len(), 1, "{blanks} x {blank:?}");
        }
    }
}

/// The peak resident memory of this process so far (`VmHWM`), in bytes.
#[cfg(target_os = "linux")]
fn peak_resident() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    let kb: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    kb << 10
}

/// A binary STL whose header cannot start an ASCII file (no `solid`) is judged by its header and
/// its size alone: a 1.9 GB file (sparse, so it takes no disk) whose header declares 0 triangles
/// is refused as an unfilled count, with room for (1.9e9 - 84) / 50 = 37,999,998 facets, and one
/// declaring 2 triangles before the same padding is read with its note, both without holding the
/// file: the process's peak resident memory grows by far less than the file. Both were read
/// whole to be judged, 1.9 GB each.
#[cfg(target_os = "linux")]
#[test]
fn a_huge_binary_stl_is_judged_without_reading_it_whole() {
    const SIZE: u64 = 1_900_000_000;
    let dir = tempfile::tempdir().unwrap();
    let t = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let write = |name: &str, triangles: u32| {
        let path = dir.path().join(name);
        let mut bytes = vec![b'x'; 80];
        bytes.extend(triangles.to_le_bytes());
        for _ in 0..triangles {
            bytes.extend([0u8; 12]);
            bytes.extend(t.iter().flatten().flat_map(|x| x.to_le_bytes()));
            bytes.extend([0u8; 2]);
        }
        std::fs::write(&path, bytes).unwrap();
        std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .unwrap()
            .set_len(SIZE)
            .unwrap();
        path
    };
    let (unfilled, padded) = (write("unfilled.stl", 0), write("padded.stl", 2));
    let before = peak_resident();
    let e = load_path(&unfilled, dir.path()).unwrap_err().0;
    assert!(
        e.contains("declares 0 triangles, but the file has room for 37999998 facets"),
        "{e}"
    );
    let m = load_path(&padded, dir.path()).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    let extra = SIZE - 84 - 100;
    assert!(
        m.notes
            .join("\n")
            .contains(&format!("{extra} byte(s) after the 2 triangles")),
        "{:?}",
        m.notes
    );
    let grown = peak_resident() - before;
    assert!(grown < 500 << 20, "peak memory grew by {grown} bytes");
}

#[test]
fn stl_binary_with_trailing_bytes_is_read_with_a_note() {
    let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    // Padded by 3 bytes, and by two facets' worth: the declared 2 triangles are read.
    for extra in [3usize, 100] {
        let mut b = binary_stl(&[t, t]);
        b.extend(vec![0u8; extra]);
        let m = ok("p.stl", &b);
        assert_eq!(m.triangles, vec![[0, 1, 2], [3, 4, 5]]);
        assert_eq!(m.positions[1], [1.0, 0.0, 0.0]);
        let note = m.notes.join("\n");
        assert!(
            note.contains(&format!("{extra} byte(s) after the 2 triangles")),
            "{note}"
        );
        assert_eq!(
            note.contains("room for 2 more facet"),
            extra == 100,
            "{note}"
        );
    }
    // The header starts with `solid` (binary_stl writes that) and the data is binary: still
    // binary, not misread as ASCII, padded or not.
    let mut b = binary_stl(&[t]);
    assert!(b.starts_with(b"solid"));
    b.push(b'\n');
    assert_eq!(ok("s.stl", &b).triangles.len(), 1);
    // A count of 0 over real facets is an unfilled header, not an empty model: an error.
    let mut b = binary_stl(&[t, t]);
    b[80..84].copy_from_slice(&0u32.to_le_bytes());
    assert!(
        err("unfilled.stl", &b).contains("declares 0 triangles, but the file has room for 2"),
        "{}",
        err("unfilled.stl", &b)
    );
    // Shorter than declared stays an error.
    let mut b = binary_stl(&[t, t]);
    b.truncate(b.len() - 1);
    assert!(err("short.stl", &b).contains("truncated binary STL"));
}

#[test]
fn huge_concave_polygon_is_split_quickly() {
    // An outward spiral turning a little more than 120 degrees per corner: no corner is a proper
    // ear and every ear test runs to the end. The old clipper took O(n^3) on it (minutes at 4096
    // vertices); now it is over the ear-clipping limit and split as a fan, with a note.
    let n = 4096;
    let mut obj = String::new();
    for i in 0..n {
        let (a, r) = (i as f64 * 2.1, 1.001f64.powi(i));
        obj.push_str(&format!("v {} {} 0\n", r * a.cos(), r * a.sin()));
    }
    obj.push('f');
    for i in 1..=n {
        obj.push_str(&format!(" {i}"));
    }
    obj.push('\n');
    let m = within(20, move || load_owned("spiral.obj", obj.into_bytes())).unwrap();
    assert_eq!(m.triangles.len(), n as usize - 2);
    assert!(
        m.notes
            .iter()
            .any(|n| n.contains("more than 1024 vertices")),
        "{:?}",
        m.notes
    );
}

#[cfg(unix)]
fn mkfifo(path: &Path) {
    let status = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .expect("mkfifo runs");
    assert!(status.success());
}

#[cfg(unix)]
#[test]
fn a_fifo_is_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.stl");
    mkfifo(&fifo);
    let root = dir.path().to_path_buf();
    let e = within(20, move || load_path(&fifo, &root)).unwrap_err().0;
    assert!(
        e.contains("not a regular file") && e.contains("FIFO"),
        "{e}"
    );
}

#[cfg(unix)]
#[test]
fn mtl_is_read_only_when_it_is_a_regular_file_inside_the_tree() {
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    std::fs::create_dir(&tree).unwrap();
    // Outside the tree: a library that would give a note naming its bad colour line if read.
    std::fs::write(dir.path().join("secret.mtl"), "newmtl x\nKd 1 0\n").unwrap();
    std::os::unix::fs::symlink(dir.path().join("secret.mtl"), tree.join("link.mtl")).unwrap();
    mkfifo(&tree.join("pipe.mtl"));
    std::fs::write(tree.join("plain.mtl"), "newmtl x\nKd 1 0\n").unwrap();
    let obj = tree.join("m.obj");
    std::fs::write(
        &obj,
        "mtllib link.mtl\nmtllib pipe.mtl\nmtllib plain.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let cx = ReadContext {
        root: tree.clone(),
        limits: Limits::default(),
    };
    let notes = within(20, move || {
        meshvet::formats::read(&obj, Format::Obj, &cx).map(|mut m| m.pop().unwrap().notes)
    })
    .unwrap()
    .join("\n");
    assert!(
        notes.contains(
            "`link.mtl` (line 1) not read: it resolves, through a symbolic link, outside"
        ),
        "{notes}"
    );
    assert!(
        !notes.contains("`link.mtl` line"),
        "the outside file was read: {notes}"
    );
    assert!(
        notes.contains("`pipe.mtl` (line 2) not read: it is not a regular file"),
        "{notes}"
    );
    // A regular file inside the tree is read (and its bad colour line named).
    assert!(notes.contains("`plain.mtl` line 2: colour `Kd`"), "{notes}");
}

#[test]
fn mtl_over_the_size_limit_is_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("m.obj");
    let geometry = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    std::fs::write(&obj, format!("mtllib m.mtl\n{geometry}")).unwrap();
    let big = format!("newmtl x\nKd 1 0\n{}", "# padding\n".repeat(20));
    std::fs::write(dir.path().join("m.mtl"), &big).unwrap();
    let limit = (geometry.len() + 20) as u64;
    assert!((big.len() as u64) > limit);
    let cx = ReadContext {
        root: dir.path().to_path_buf(),
        limits: Limits {
            max_file_bytes: limit,
            ..Limits::default()
        },
    };
    let notes = read(&obj, Format::Obj, &cx).unwrap().pop().unwrap().notes;
    let notes = notes.join("\n");
    assert!(
        notes.contains("`m.mtl` (line 1) not read: it is over the limit"),
        "{notes}"
    );
}

/// A library named on 50,000 lines is looked up, read and parsed once, and its note given once;
/// so is a missing one. Distinct libraries past the first few that give notes are summed up in
/// one note, not one each: a file of 200,000 `mtllib` lines made a 27 MB message.
#[test]
fn each_material_library_is_read_once_and_noted_once() {
    let dir = tempfile::tempdir().unwrap();
    let mut mtl: String = (0..200)
        .map(|i| format!("newmtl m{i}\nKd 1 0 0\n"))
        .collect();
    mtl.push_str("newmtl bad\nKd 1 0\n");
    std::fs::write(dir.path().join("a.mtl"), &mtl).unwrap();
    let mut obj = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    for _ in 0..50_000 {
        obj.push_str("mtllib a.mtl\nmtllib gone.mtl\nmtllib ./a.mtl\n");
    }
    for i in 0..1000 {
        obj.push_str(&format!("mtllib gone{i}.mtl\n"));
    }
    let path = dir.path().join("m.obj");
    std::fs::write(&path, obj).unwrap();
    let root = dir.path().to_path_buf();
    let m = within(20, move || load_path(&path, &root)).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    let count = |s: &str| m.notes.iter().filter(|n| n.contains(s)).count();
    // `./a.mtl` is the same file: read once, noted once.
    assert_eq!(
        count("colour `Kd` has 2 value(s)"),
        1,
        "{:?}",
        &m.notes[..5]
    );
    assert_eq!(count("`a.mtl` line 402"), 1);
    assert_eq!(count("`gone.mtl` (line 6) not found"), 1);
    assert!(m.notes.len() <= 21, "{}", m.notes.len());
    let last = m.notes.last().unwrap();
    assert!(
        last.contains("982 more material libraries") && last.contains("line 150023"),
        "{last}"
    );
}

/// The cap on library notes counts library notes only: after the reader's own notes (points,
/// lines, an unknown keyword), twenty missing libraries are each named, with no summing-up note.
#[test]
fn the_cap_on_library_notes_counts_only_library_notes() {
    let dir = tempfile::tempdir().unwrap();
    let mut obj = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\np 1\nl 1 2\nzz 1\n");
    for i in 0..20 {
        obj.push_str(&format!("mtllib gone{i}.mtl\n"));
    }
    let path = dir.path().join("m.obj");
    std::fs::write(&path, obj).unwrap();
    let m = load_path(&path, dir.path()).unwrap();
    let missing = m.notes.iter().filter(|n| n.contains("not found")).count();
    assert!(m.notes.len() > 20, "{:?}", m.notes);
    assert_eq!(missing, 20, "{:?}", m.notes);
    assert!(
        !m.notes
            .iter()
            .any(|n| n.contains("more material libraries")),
        "{:?}",
        m.notes
    );
}

/// The unit-axes tetrahedron (4 faces, closed, volume 1/6) written with LF, CRLF and bare-CR
/// (classic Mac OS) line ends reads the same in OBJ, ASCII STL and OFF: a bare-CR file came out
/// `empty` (OBJ, STL) or "truncated" (OFF). A stray CR inside a line of an LF file stays a blank.
#[test]
fn lf_crlf_and_bare_cr_line_ends_read_the_same() {
    let p = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]];
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let obj: Vec<String> = p
        .iter()
        .map(|q| format!("v {} {} {}", q[0], q[1], q[2]))
        .chain(
            faces
                .iter()
                .map(|f| format!("f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1)),
        )
        .collect();
    let mut stl = vec!["solid tet".to_string()];
    for f in faces {
        stl.extend(["facet normal 0 0 0".into(), "outer loop".into()]);
        stl.extend(f.map(|i| format!("vertex {} {} {}", p[i][0], p[i][1], p[i][2])));
        stl.extend(["endloop".into(), "endfacet".into()]);
    }
    stl.push("endsolid tet".into());
    let off: Vec<String> = ["OFF".to_string(), "4 4 6".into()]
        .into_iter()
        .chain(p.iter().map(|q| format!("{} {} {}", q[0], q[1], q[2])))
        .chain(
            faces
                .iter()
                .map(|f| format!("3 {} {} {}", f[0], f[1], f[2])),
        )
        .collect();
    for (name, lines) in [("t.obj", &obj), ("t.stl", &stl), ("t.off", &off)] {
        let mut seen = Vec::new();
        for end in ["\n", "\r\n", "\r"] {
            let text = lines.join(end) + end;
            let mesh = ok(name, text.as_bytes());
            assert!(mesh.notes.is_empty(), "{name} {end:?}: {:?}", mesh.notes);
            let a = meshvet::analyse(&mesh, &meshvet::Options::default());
            assert_eq!(a.faces, 4, "{name} {end:?}");
            assert_eq!(a.shells.len(), 1, "{name} {end:?}");
            assert!(a.components[0].closed, "{name} {end:?}");
            let volume = a.shells[0].volume.unwrap();
            assert!(
                (volume - 1.0 / 6.0).abs() < 1e-12,
                "{name} {end:?}: {volume}"
            );
            seen.push(format!("{a:?}"));
        }
        assert!(seen.iter().all(|s| *s == seen[0]), "{name}: {seen:#?}");
    }
    // A stray CR inside a line of an LF file is a blank, not a line end.
    let stray = obj.join("\n").replacen("v 1 0 0", "v 1\r0 0", 1) + "\n";
    assert_eq!(ok("s.obj", stray.as_bytes()).triangles.len(), 4);
    let stray = off.join("\n").replacen("4 4 6", "4\r4 6", 1) + "\n";
    assert_eq!(ok("s.off", stray.as_bytes()).triangles.len(), 4);
}
