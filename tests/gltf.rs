//! The glTF / GLB reader on small files built by hand in temporary folders: buffers from data URIs,
//! external files and GLB chunks; the tree policy for buffer URIs; primitive modes; instancing and
//! mirroring; every gltf-crate panic CRATES.md lists, as a regression test that must give an
//! error; and the shared corpus, read without a panic and checked against reference triangle
//! counts where the libraries agree.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use base64::Engine as _;
use meshvet::formats::{read, Format, Limits, ReadContext, ReadError};
use meshvet::mesh::Mesh;

// ---------------------------------------------------------------------------------------------
// Harness

fn cx(root: &Path) -> ReadContext {
    ReadContext {
        root: root.to_path_buf(),
        limits: Limits::default(),
    }
}

/// Reads `path` with `root` as the scanned tree; a panic fails the test with the file named.
fn read_in(path: &Path, root: &Path) -> Result<Vec<Mesh>, ReadError> {
    let format = Format::of_path(path).expect("a .gltf or .glb path");
    catch_unwind(AssertUnwindSafe(|| read(path, format, &cx(root))))
        .unwrap_or_else(|_| panic!("reader panicked on {}", path.display()))
}

/// Writes `name` (which may hold folders) under `dir` and returns its path.
fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Writes a file and reads it with its own folder as the tree.
fn read_file(name: &str, bytes: impl AsRef<[u8]>) -> Result<Vec<Mesh>, ReadError> {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), name, bytes);
    read_in(&path, dir.path())
}

fn read_ok(name: &str, bytes: impl AsRef<[u8]>) -> Vec<Mesh> {
    read_file(name, bytes).unwrap_or_else(|e| panic!("expected {name} to read, got: {e}"))
}

/// The error of a file that must not read; it must come from a check, not from a caught panic.
fn read_err(name: &str, bytes: impl AsRef<[u8]>) -> String {
    match read_file(name, bytes) {
        Ok(meshes) => panic!("expected an error, read {meshes:?}"),
        Err(e) => {
            assert!(
                !e.0.contains("crashed"),
                "error came from a caught panic: {e}"
            );
            e.0
        }
    }
}

fn f32s(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn u16s(values: &[u16]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn data_uri(bytes: &[u8]) -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// A glTF 2.0 document from top-level `"key": value` members.
fn doc(members: &[(&str, String)]) -> String {
    let mut json = String::from(r#"{"asset":{"version":"2.0"}"#);
    for (key, value) in members {
        json.push_str(&format!(r#","{key}":{value}"#));
    }
    json.push('}');
    json
}

/// One buffer, one view per `(offset, length)` and one accessor per
/// `(view, componentType, type, count)`, plus meshes, nodes and scenes as given.
struct Asset {
    uri: Option<String>,
    buffer_len: usize,
    views: Vec<String>,
    accessors: Vec<String>,
    meshes: String,
    extra: Vec<(&'static str, String)>,
}

impl Asset {
    fn new(uri: Option<String>, buffer_len: usize, meshes: &str) -> Asset {
        Asset {
            uri,
            buffer_len,
            views: Vec::new(),
            accessors: Vec::new(),
            meshes: meshes.to_string(),
            extra: Vec::new(),
        }
    }
    fn view(mut self, offset: usize, length: usize) -> Asset {
        self.views.push(format!(
            r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{length}}}"#
        ));
        self
    }
    fn accessor(mut self, view: usize, component: u32, kind: &str, count: usize) -> Asset {
        self.accessors.push(format!(
            r#"{{"bufferView":{view},"componentType":{component},"type":"{kind}","count":{count}}}"#
        ));
        self
    }
    fn with(mut self, key: &'static str, value: &str) -> Asset {
        self.extra.push((key, value.to_string()));
        self
    }
    fn json(&self) -> String {
        let buffer = match &self.uri {
            Some(uri) => format!(r#"[{{"uri":"{uri}","byteLength":{}}}]"#, self.buffer_len),
            None => format!(r#"[{{"byteLength":{}}}]"#, self.buffer_len),
        };
        let mut members = vec![
            ("buffers", buffer),
            ("bufferViews", format!("[{}]", self.views.join(","))),
            ("accessors", format!("[{}]", self.accessors.join(","))),
            ("meshes", self.meshes.clone()),
        ];
        members.extend(self.extra.iter().cloned());
        doc(&members)
    }
}

const FLOAT: u32 = 5126;
const USHORT: u32 = 5123;

/// The unit quad: 4 positions (48 bytes) then 6 u16 indices (12 bytes), two triangles.
fn quad_bin() -> Vec<u8> {
    let mut bin = f32s(&[0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.]);
    bin.extend(u16s(&[0, 1, 2, 0, 2, 3]));
    bin
}

/// The quad as an asset whose only buffer has `uri` (`None`: the GLB chunk).
fn quad(uri: Option<String>) -> Asset {
    Asset::new(
        uri,
        60,
        r#"[{"name":"quad","primitives":[{"attributes":{"POSITION":0},"indices":1}]}]"#,
    )
    .view(0, 48)
    .view(48, 12)
    .accessor(0, FLOAT, "VEC3", 4)
    .accessor(1, USHORT, "SCALAR", 6)
}

/// A GLB container: header, JSON chunk (space padded), BIN chunk (zero padded).
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&bin);
    out
}

fn assert_quad(meshes: &[Mesh]) {
    assert_eq!(meshes.len(), 1);
    let quad = &meshes[0];
    assert_eq!(quad.name.as_deref(), Some("quad"));
    assert_eq!(quad.positions.len(), 4);
    assert_eq!(quad.positions[2], [1.0, 1.0, 0.0]);
    assert_eq!(quad.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert!(quad.notes.is_empty(), "{:?}", quad.notes);
}

/// A single triangle without indices, positions in a data URI; `meshes` and more as given.
fn triangle_with(meshes: &str, extra: &[(&'static str, &str)]) -> String {
    let bin = f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]);
    let mut asset = Asset::new(Some(data_uri(&bin)), 36, meshes)
        .view(0, 36)
        .accessor(0, FLOAT, "VEC3", 3);
    for (key, value) in extra {
        asset = asset.with(key, value);
    }
    asset.json()
}

fn triangle() -> String {
    triangle_with(r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#, &[])
}

// ---------------------------------------------------------------------------------------------
// Buffers

#[test]
fn triangle_from_a_data_uri() {
    let meshes = read_ok("tri.gltf", triangle());
    assert_eq!(meshes.len(), 1);
    assert_eq!(meshes[0].name.as_deref(), Some("#0"));
    assert_eq!(
        meshes[0].positions,
        vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]
    );
    assert_eq!(meshes[0].triangles, vec![[0, 1, 2]]);
    assert_eq!(meshes[0].mirrored_instances, 0);
}

/// Rows are matched by path and mesh, so meshes of one file never share a name: two named `Part`
/// become `Part (#0)` and `Part (#1)`; one named `#2` and the unnamed mesh 2 (`#2`) become
/// `#2 (#1)` and `#2 (#2)`; a name no other mesh has is left alone.
#[test]
fn meshes_sharing_a_name_get_their_index() {
    let primitive = r#"{"primitives":[{"attributes":{"POSITION":0}}]}"#;
    let named = |name: &str| {
        format!(r#"{{"name":"{name}","primitives":[{{"attributes":{{"POSITION":0}}}}]}}"#)
    };
    let meshes = format!(
        "[{},{},{},{},{}]",
        named("Part"),
        named("#2"),
        primitive,
        named("Part"),
        named("Lid")
    );
    let read = read_ok("parts.gltf", triangle_with(&meshes, &[]));
    let names: Vec<&str> = read.iter().map(|m| m.name.as_deref().unwrap()).collect();
    assert_eq!(
        names,
        ["Part (#0)", "#2 (#1)", "#2 (#2)", "Part (#3)", "Lid"]
    );
    // Names that the tags meet again, ten deep (`X`, `X`, `X (#1)`, `X (#1) (#1)`, ...): every
    // round of tags ends with all names distinct.
    let mut chain = vec![named("X")];
    let mut name = "X".to_owned();
    for _ in 0..10 {
        chain.push(named(&name));
        name += " (#1)";
    }
    let read = read_ok(
        "chain.gltf",
        triangle_with(&format!("[{}]", chain.join(",")), &[]),
    );
    let mut names: Vec<&str> = read.iter().map(|m| m.name.as_deref().unwrap()).collect();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), 11, "{names:?}");
}

#[test]
fn indexed_quad_from_an_external_bin() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "quad.bin", quad_bin());
    let path = write(
        dir.path(),
        "quad.gltf",
        quad(Some("quad.bin".into())).json(),
    );
    assert_quad(&read_in(&path, dir.path()).unwrap());
}

#[test]
fn percent_encoded_buffer_uri() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "my quad.bin", quad_bin());
    let path = write(
        dir.path(),
        "quad.gltf",
        quad(Some("my%20quad.bin".into())).json(),
    );
    assert_quad(&read_in(&path, dir.path()).unwrap());
}

#[test]
fn glb_built_by_hand() {
    let bytes = glb(&quad(None).json(), &quad_bin());
    assert_quad(&read_ok("quad.glb", &bytes));
    // Content decides, not the extension: the same bytes named .gltf read the same.
    assert_quad(&read_ok("quad.gltf", &bytes));
}

#[test]
fn shared_buffer_folder_inside_the_tree_is_allowed() {
    let tree = tempfile::tempdir().unwrap();
    write(tree.path(), "buffers/quad.bin", quad_bin());
    let path = write(
        tree.path(),
        "models/quad.gltf",
        quad(Some("../buffers/quad.bin".into())).json(),
    );
    assert_quad(&read_in(&path, tree.path()).unwrap());
}

#[test]
fn buffer_climbing_out_of_the_tree_is_refused_and_not_read() {
    let top = tempfile::tempdir().unwrap();
    // A valid buffer outside the tree: reading it would succeed, so an error proves it was refused.
    write(top.path(), "outside/quad.bin", quad_bin());
    let tree = top.path().join("tree");
    let uri = "../../outside/quad.bin";
    let path = write(&tree, "models/quad.gltf", quad(Some(uri.into())).json());
    let err = read_in(&path, &tree).unwrap_err().0;
    assert!(err.contains("refused"), "{err}");
    assert!(err.contains(uri), "{err}");
    assert!(err.contains("climbs out"), "{err}");
    // The same file with the wider tree reads: the refusal is the tree policy, nothing else.
    assert_quad(&read_in(&path, top.path()).unwrap());
}

#[test]
fn climbing_out_and_back_in_is_judged_on_the_resolved_path() {
    let top = tempfile::tempdir().unwrap();
    write(top.path(), "tree/buffers/quad.bin", quad_bin());
    let tree = top.path().join("tree");
    let path = write(
        &tree,
        "models/quad.gltf",
        quad(Some("../../tree/buffers/quad.bin".into())).json(),
    );
    assert_quad(&read_in(&path, &tree).unwrap());
}

#[test]
fn absolute_and_scheme_uris_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bin = write(dir.path(), "quad.bin", quad_bin());
    let absolute = bin
        .canonicalize()
        .unwrap()
        .to_str()
        .unwrap()
        .replace('\\', "/");
    for uri in [
        absolute.clone(),
        format!("file://{absolute}"),
        "http://example.com/quad.bin".to_string(),
        "https://example.com/quad.bin".to_string(),
        "ftp:quad.bin".to_string(),
    ] {
        let path = write(dir.path(), "quad.gltf", quad(Some(uri.clone())).json());
        let err = read_in(&path, dir.path()).unwrap_err().0;
        assert!(
            err.contains("refused") && err.contains(&uri),
            "{uri}: {err}"
        );
    }
}

#[cfg(unix)]
#[test]
fn symbolic_link_out_of_the_tree_is_refused() {
    let top = tempfile::tempdir().unwrap();
    let outside = write(top.path(), "outside/quad.bin", quad_bin());
    let tree = top.path().join("tree");
    std::fs::create_dir_all(&tree).unwrap();
    std::os::unix::fs::symlink(&outside, tree.join("quad.bin")).unwrap();
    let path = write(&tree, "quad.gltf", quad(Some("quad.bin".into())).json());
    let err = read_in(&path, &tree).unwrap_err().0;
    assert!(err.contains("symbolic link"), "{err}");
}

#[test]
fn missing_buffer_file_is_a_clear_error() {
    let err = read_err("quad.gltf", quad(Some("gone.bin".into())).json());
    assert!(
        err.contains("gone.bin") && err.contains("not found"),
        "{err}"
    );
}

#[test]
fn buffer_shorter_than_its_byte_length_is_an_error() {
    let bin = quad_bin();
    let err = read_err("quad.gltf", quad(Some(data_uri(&bin[..50]))).json());
    assert!(err.contains("byteLength 60"), "{err}");
}

/// `n` buffers that all name `file` with `byte_length`, and one mesh per buffer whose triangle is
/// the first 36 bytes of the file.
fn buffers_sharing(file: &str, byte_length: usize, n: usize) -> String {
    let each = |f: &dyn Fn(usize) -> String| (0..n).map(f).collect::<Vec<_>>().join(",");
    doc(&[
        (
            "buffers",
            format!(
                "[{}]",
                each(&|_| format!(r#"{{"uri":"{file}","byteLength":{byte_length}}}"#))
            ),
        ),
        (
            "bufferViews",
            format!(
                "[{}]",
                each(&|i| format!(r#"{{"buffer":{i},"byteLength":36}}"#))
            ),
        ),
        (
            "accessors",
            format!(
                "[{}]",
                each(&|i| format!(
                    r#"{{"bufferView":{i},"componentType":{FLOAT},"type":"VEC3","count":3}}"#
                ))
            ),
        ),
        (
            "meshes",
            format!(
                "[{}]",
                each(&|i| format!(r#"{{"primitives":[{{"attributes":{{"POSITION":{i}}}}}]}}"#))
            ),
        ),
    ])
}

/// A file whose first 36 bytes are the triangle (0,0,0) (1,0,0) (0,1,0), then zeros to `len`.
fn triangle_file(len: usize) -> Vec<u8> {
    let mut bytes = f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]);
    bytes.resize(len, 0);
    bytes
}

/// 100 buffers naming one file read it once, and only the bytes they use: the file is twice the
/// size limit (it is never read whole) and 100 copies of what the buffers use would be 60 times
/// it, yet the asset reads, every mesh its triangle.
#[test]
fn buffers_sharing_a_file_read_it_once_and_only_what_they_use() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "big.bin", triangle_file(2_000_000));
    let path = write(
        dir.path(),
        "many.gltf",
        buffers_sharing("big.bin", 600_000, 100),
    );
    let mut context = cx(dir.path());
    context.limits.max_file_bytes = 1_000_000;
    let meshes = read(&path, Format::Gltf, &context).unwrap();
    assert_eq!(meshes.len(), 100);
    for mesh in &meshes {
        assert_eq!(
            mesh.positions,
            vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]
        );
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    }
    // The file is shorter than a buffer that names it: an error, though it is shared.
    let path = write(
        dir.path(),
        "short.gltf",
        buffers_sharing("big.bin", 2_000_001, 2),
    );
    let err = read(&path, Format::Gltf, &cx(dir.path())).unwrap_err().0;
    assert!(
        err.contains("holds 2000000 bytes") && err.contains("byteLength 2000001"),
        "{err}"
    );
}

/// The files the buffers of one glTF read count together against the size limit of one file:
/// two files each under it but over it together are an error naming the limit and what to do.
#[test]
fn buffer_files_over_the_size_limit_together_are_an_error() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "a.bin", triangle_file(600_000));
    write(dir.path(), "b.bin", triangle_file(600_000));
    let json =
        buffers_sharing("a.bin", 600_000, 2).replacen(r#"{"uri":"a.bin""#, r#"{"uri":"b.bin""#, 1);
    let path = write(dir.path(), "two.gltf", json);
    let mut context = cx(dir.path());
    context.limits.max_file_bytes = 1_000_000;
    let err = read(&path, Format::Gltf, &context).unwrap_err().0;
    assert!(
        err.contains("1200000 bytes")
            && err.contains("over the limit of 1000000")
            && err.contains("raise limits.max_file_bytes"),
        "{err}"
    );
    context.limits.max_file_bytes = 1_200_000;
    assert_eq!(read(&path, Format::Gltf, &context).unwrap().len(), 2);
}

#[test]
fn glb_without_bin_chunk_is_an_error() {
    let mut bytes = glb(&quad(None).json(), &[]);
    bytes.truncate(bytes.len() - 8); // drop the empty BIN chunk header
    let total = bytes.len() as u32;
    bytes[8..12].copy_from_slice(&total.to_le_bytes());
    let err = read_err("quad.glb", &bytes);
    assert!(err.contains("binary chunk"), "{err}");
}

#[test]
fn sparse_accessor_values_replace_the_base() {
    // Base positions: the triangle; sparse: vertex 1 moves to (5, 0, 0).
    let mut bin = f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]);
    bin.extend(u16s(&[1, 0])); // one sparse index, padded to 4 bytes
    bin.extend(f32s(&[5., 0., 0.]));
    let json = Asset::new(
        Some(data_uri(&bin)),
        bin.len(),
        r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
    )
    .view(0, 36)
    .view(36, 2)
    .view(40, 12)
    .json()
    .replace(
        r#""accessors":[]"#,
        r#""accessors":[{"bufferView":0,"componentType":5126,"type":"VEC3","count":3,
            "sparse":{"count":1,"indices":{"bufferView":1,"componentType":5123},
                      "values":{"bufferView":2}}}]"#,
    );
    let meshes = read_ok("sparse.gltf", json);
    assert_eq!(
        meshes[0].positions,
        vec![[0., 0., 0.], [5., 0., 0.], [0., 1., 0.]]
    );
}

// ---------------------------------------------------------------------------------------------
// Meshes, primitives, modes

#[test]
fn strip_and_fan_become_triangles() {
    // Five vertices; a strip of 5 gives 3 triangles, a fan of 5 gives 3 (glTF 2.0 3.7.2.1):
    // strip i -> (i, i+1+i%2, i+2-i%2): (0,1,2) (1,3,2) (2,3,4)
    // fan i   -> (i+1, i+2, 0):         (1,2,0) (2,3,0) (3,4,0), offset by the strip's 5 vertices.
    let bin = f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0., 0., 2., 0.]);
    let json = Asset::new(
        Some(data_uri(&bin)),
        60,
        r#"[{"primitives":[{"attributes":{"POSITION":0},"mode":5},
                           {"attributes":{"POSITION":0},"mode":6}]}]"#,
    )
    .view(0, 60)
    .accessor(0, FLOAT, "VEC3", 5)
    .json();
    let meshes = read_ok("modes.gltf", json);
    assert_eq!(meshes.len(), 1);
    assert_eq!(meshes[0].positions.len(), 10);
    assert_eq!(
        meshes[0].triangles,
        vec![
            [0, 1, 2],
            [1, 3, 2],
            [2, 3, 4],
            [6, 7, 5],
            [7, 8, 5],
            [8, 9, 5]
        ]
    );
}

#[test]
fn indexed_strip_uses_the_indices() {
    // Strip over indices [3, 2, 1, 0]: (3,2,1) and (2,0,1).
    let mut bin = f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.]);
    bin.extend(u16s(&[3, 2, 1, 0]));
    let json = Asset::new(
        Some(data_uri(&bin)),
        56,
        r#"[{"primitives":[{"attributes":{"POSITION":0},"indices":1,"mode":5}]}]"#,
    )
    .view(0, 48)
    .view(48, 8)
    .accessor(0, FLOAT, "VEC3", 4)
    .accessor(1, USHORT, "SCALAR", 4)
    .json();
    assert_eq!(
        read_ok("strip.gltf", json)[0].triangles,
        vec![[3, 2, 1], [2, 0, 1]]
    );
}

#[test]
fn points_and_lines_are_skipped_with_a_note() {
    let json = triangle_with(
        r#"[{"name":"dots","primitives":[{"attributes":{"POSITION":0},"mode":0},
                                          {"attributes":{"POSITION":0},"mode":1}]}]"#,
        &[],
    );
    let meshes = read_ok("dots.gltf", json);
    assert_eq!(meshes.len(), 1);
    assert_eq!(meshes[0].name.as_deref(), Some("dots"));
    assert!(meshes[0].triangles.is_empty());
    assert!(meshes[0].positions.is_empty());
    let notes = meshes[0].notes.join("; ");
    assert!(
        notes.contains("1 POINTS") && notes.contains("1 LINES"),
        "{notes}"
    );
}

#[test]
fn unnamed_meshes_are_numbered() {
    let json = triangle_with(
        r#"[{"primitives":[{"attributes":{"POSITION":0}}]},
            {"name":"named","primitives":[{"attributes":{"POSITION":0}}]},
            {"primitives":[]}]"#,
        &[],
    );
    let meshes = read_ok("names.gltf", json);
    let names: Vec<_> = meshes.iter().map(|m| m.name.clone().unwrap()).collect();
    assert_eq!(names, ["#0", "named", "#2"]);
    assert!(meshes[2].triangles.is_empty());
}

#[test]
fn no_meshes_reads_as_empty() {
    assert!(read_ok("empty.gltf", doc(&[])).is_empty());
    assert!(read_ok(
        "nodes.gltf",
        doc(&[
            ("nodes", "[{}]".into()),
            ("scenes", r#"[{"nodes":[0]}]"#.into())
        ])
    )
    .is_empty());
}

#[test]
fn a_mesh_instanced_by_two_nodes_is_read_once() {
    let json = triangle_with(
        r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
        &[
            ("nodes", r#"[{"mesh":0},{"mesh":0,"translation":[5,0,0]}]"#),
            ("scenes", r#"[{"nodes":[0,1]}]"#),
        ],
    );
    let meshes = read_ok("twice.gltf", json);
    assert_eq!(meshes.len(), 1);
    assert_eq!(meshes[0].triangles.len(), 1);
    assert_eq!(meshes[0].mirrored_instances, 0);
}

#[test]
fn mirrored_instances_follow_world_transforms() {
    // Node 0: scale (-1,1,1), mirrored. Node 1 (scale -1 on y) has child 2 (scale -1 on z): the
    // child's world determinant is (+1), not mirrored, but node 1 itself has no mesh. Node 3: a
    // matrix with det -1 (x and y swapped). Node 4: rotation only. So 2 mirrored instances.
    let json = triangle_with(
        r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
        &[
            (
                "nodes",
                r#"[{"mesh":0,"scale":[-1,1,1]},
                    {"scale":[1,-1,1],"children":[2]},
                    {"mesh":0,"scale":[1,1,-1]},
                    {"mesh":0,"matrix":[0,1,0,0, 1,0,0,0, 0,0,1,0, 0,0,0,1]},
                    {"mesh":0,"rotation":[0,0,0.7071068,0.7071068]}]"#,
            ),
            ("scenes", r#"[{"nodes":[0,1,3,4]}]"#),
        ],
    );
    assert_eq!(read_ok("mirror.gltf", json)[0].mirrored_instances, 2);
}

#[test]
fn mirrored_child_of_a_plain_parent_counts() {
    let json = triangle_with(
        r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
        &[
            (
                "nodes",
                r#"[{"children":[1],"translation":[1,2,3]},{"mesh":0,"scale":[-1,1,1]}]"#,
            ),
            ("scenes", r#"[{"nodes":[0]}]"#),
        ],
    );
    assert_eq!(read_ok("child.gltf", json)[0].mirrored_instances, 1);
}

#[test]
fn cyclic_node_hierarchy_terminates() {
    let json = triangle_with(
        r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
        &[
            (
                "nodes",
                r#"[{"children":[1]},{"children":[0],"mesh":0,"scale":[-1,1,1]}]"#,
            ),
            ("scenes", r#"[{"nodes":[0]}]"#),
        ],
    );
    assert_eq!(read_ok("cycle.gltf", json)[0].mirrored_instances, 1);
}

#[test]
fn triangle_limit_is_respected() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "tri.gltf", triangle());
    let mut context = cx(dir.path());
    context.limits.max_triangles = 2; // 3 vertices: over the vertex limit
    let err = read(&path, Format::Gltf, &context).unwrap_err().0;
    assert!(err.contains("limits.max_triangles"), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Bad input: errors, never panics

#[test]
fn draco_required_is_named() {
    let json = triangle_with(
        r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
        &[
            ("extensionsUsed", r#"["KHR_draco_mesh_compression"]"#),
            ("extensionsRequired", r#"["KHR_draco_mesh_compression"]"#),
        ],
    );
    let err = read_err("draco.gltf", json);
    assert!(
        err.contains("requires extension KHR_draco_mesh_compression, which meshvet cannot decode: export without Draco compression"),
        "{err}"
    );
}

#[test]
fn other_required_extensions_are_named_and_harmless_ones_pass() {
    for ext in [
        "EXT_meshopt_compression",
        "KHR_mesh_quantization",
        "VENDOR_unknown",
    ] {
        let json = triangle_with(
            r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
            &[("extensionsRequired", &format!(r#"["{ext}"]"#))],
        );
        let err = read_err("ext.gltf", json);
        assert!(err.contains(&format!("requires extension {ext}")), "{err}");
    }
    let json = triangle_with(
        r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
        &[("extensionsRequired", r#"["KHR_texture_transform"]"#)],
    );
    assert_eq!(read_ok("ext.gltf", json)[0].triangles.len(), 1);
}

#[test]
fn gltf_1_is_refused_clearly() {
    let v1 = r#"{"asset":{"version":"1.0"},"meshes":{"m":{"primitives":[]}}}"#;
    assert!(read_err("v1.gltf", v1).contains("glTF 1.0 is not supported; convert to glTF 2.0"));
    let no_asset = r#"{"accessors":{},"meshes":{"m":{"primitives":[]}}}"#;
    assert!(read_err("v1.gltf", no_asset).contains("glTF 1.0 is not supported"));
    let mut binary_v1 = glb("{}", &[]);
    binary_v1[4] = 1;
    assert!(read_err("v1.glb", binary_v1).contains("glTF 1.0"));
}

#[test]
fn missing_position_min_max_is_tolerated() {
    // Assets here never carry min/max; the gltf crate's validation would reject them.
    assert_eq!(read_ok("tri.gltf", triangle())[0].triangles.len(), 1);
}

/// CRATES.md 5.1: gltf-json mesh.rs:151 panics inside validation on a POSITION accessor index out
/// of range.
#[test]
fn regression_position_accessor_index_out_of_range() {
    let json = triangle_with(r#"[{"primitives":[{"attributes":{"POSITION":7}}]}]"#, &[]);
    let err = read_err("pos.gltf", json);
    assert!(
        err.contains("mesh #0 primitive 0") && err.contains("accessor 7"),
        "{err}"
    );
}

/// CRATES.md 5.1: gltf mesh/mod.rs:396 `unreachable!` on FLOAT indices.
#[test]
fn regression_float_indices() {
    let mut bin = f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]);
    bin.extend(f32s(&[0., 1., 2.]));
    let json = Asset::new(
        Some(data_uri(&bin)),
        48,
        r#"[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}]"#,
    )
    .view(0, 36)
    .view(36, 12)
    .accessor(0, FLOAT, "VEC3", 3)
    .accessor(1, FLOAT, "SCALAR", 3)
    .json();
    let err = read_err("floatidx.gltf", json);
    assert!(err.contains("FLOAT SCALAR"), "{err}");
}

/// CRATES.md 5.1: gltf accessor/util.rs:266 panics on byteStride smaller than the element.
#[test]
fn regression_byte_stride_smaller_than_element() {
    let json = triangle().replace(r#""byteLength":36}"#, r#""byteLength":36,"byteStride":4}"#);
    assert!(json.contains("byteStride"));
    let err = read_err("stride.gltf", json);
    assert!(err.contains("byteStride 4"), "{err}");
}

/// CRATES.md 5.1: gltf import.rs:50 panics on `%FF` in a URI.
#[test]
fn regression_percent_ff_in_uri() {
    let err = read_err("ff.gltf", quad(Some("quad%FF.bin".into())).json());
    assert!(err.contains("quad%FF.bin"), "{err}");
}

/// CRATES.md 5.3: `Option::unwrap` in `Primitive::indices` (and `get`) with validation off, on an
/// indices accessor index out of range.
#[test]
fn regression_indices_accessor_index_out_of_range() {
    let json = quad(Some(data_uri(&quad_bin())))
        .json()
        .replace(r#""indices":1"#, r#""indices":9"#);
    let err = read_err("idx.gltf", json);
    assert!(
        err.contains("mesh \"quad\" (#0) primitive 0") && err.contains("accessor 9"),
        "{err}"
    );
}

#[test]
fn regression_views_and_buffers_out_of_range() {
    let bad_view = quad(Some(data_uri(&quad_bin())))
        .json()
        .replace(r#"{"bufferView":1,"#, r#"{"bufferView":5,"#);
    assert!(read_err("v.gltf", bad_view).contains("buffer view 5"));
    let bad_buffer = quad(Some(data_uri(&quad_bin()))).json().replace(
        r#"{"buffer":0,"byteOffset":48"#,
        r#"{"buffer":3,"byteOffset":48"#,
    );
    assert!(read_err("b.gltf", bad_buffer).contains("buffer 3"));
    let past_end = quad(Some(data_uri(&quad_bin()))).json().replace(
        r#""byteOffset":48,"byteLength":12"#,
        r#""byteOffset":48,"byteLength":4000"#,
    );
    assert!(read_err("e.gltf", past_end).contains("runs past the end"));
    let huge_count = quad(Some(data_uri(&quad_bin())))
        .json()
        .replace(r#""count":6"#, r#""count":18446744073709551615"#);
    assert!(read_err("c.gltf", huge_count).contains("do not fit"));
    let invalid_mode = quad(Some(data_uri(&quad_bin())))
        .json()
        .replace(r#""indices":1"#, r#""indices":1,"mode":9"#);
    assert!(read_err("m.gltf", invalid_mode).contains("invalid mode"));
    let bad_node = triangle_with(
        r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
        &[("nodes", r#"[{"mesh":4}]"#)],
    );
    assert!(read_err("n.gltf", bad_node).contains("mesh 4"));
}

/// Integer positions are quantized (KHR_mesh_quantization), which meshvet neither reads nor
/// repairs: the error says what the file holds and what to do with it, whether the extension is
/// declared required or not.
#[test]
fn quantized_positions_are_refused() {
    let json = triangle().replace(r#""componentType":5126"#, r#""componentType":5123"#);
    let err = read_err("q.gltf", json.clone());
    let advice = "re-export it with float positions (no mesh quantization: gltfpack -noq), or \
                  dequantize it (gltf-transform dequantize) and scan that file";
    assert!(
        err.contains("UNSIGNED_SHORT VEC3") && err.contains("KHR_mesh_quantization"),
        "{err}"
    );
    assert!(err.ends_with(advice), "{err}");
    let required = json.replacen(
        '{',
        r#"{"extensionsRequired":["KHR_mesh_quantization"],"#,
        1,
    );
    let err = read_err("q.gltf", required);
    assert_eq!(
        err,
        format!("requires extension KHR_mesh_quantization, which meshvet cannot decode: {advice}")
    );
}

#[test]
fn out_of_range_index_names_mesh_and_primitive() {
    let mut bin = quad_bin();
    bin[48 + 10..].copy_from_slice(&9u16.to_le_bytes());
    let err = read_err("oor.gltf", quad(Some(data_uri(&bin))).json());
    assert!(
        err.contains("mesh \"quad\" (#0) primitive 0") && err.contains("index 9"),
        "{err}"
    );
}

#[test]
fn every_truncation_of_a_glb_is_an_error() {
    let bytes = glb(&quad(None).json(), &quad_bin());
    for len in 0..bytes.len() {
        let result = read_file("cut.glb", &bytes[..len]);
        match result {
            Err(e) => assert!(!e.0.contains("crashed"), "cut at {len}: {e}"),
            Ok(m) => panic!("cut at {len} of {} read as {m:?}", bytes.len()),
        }
    }
}

#[test]
fn binary_garbage_named_glb_is_an_error() {
    let garbage: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    let err = read_err("garbage.glb", &garbage);
    assert!(err.contains("not a glTF file"), "{err}");
    // GLB magic followed by garbage.
    let mut magic = b"glTF".to_vec();
    magic.extend(&garbage);
    read_err("garbage.glb", &magic);
    // JSON that is not glTF.
    assert!(read_err("x.gltf", "{\"asset\":").contains("invalid glTF JSON"));
    assert!(read_err("x.gltf", "").contains("not a glTF file"));
}

#[test]
fn every_single_byte_corruption_of_a_glb_is_handled() {
    // Flip each byte of the header, chunk headers and the first JSON bytes: never a panic.
    let bytes = glb(&quad(None).json(), &quad_bin());
    for at in (0..bytes.len()).step_by(3) {
        let mut bad = bytes.clone();
        bad[at] ^= 0xA5;
        let _ = read_file("flip.glb", &bad);
    }
}

// ---------------------------------------------------------------------------------------------
// The shared corpus

fn corpus() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    dir.is_dir().then_some(dir)
}

fn corpus_gltf_files(corpus: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = walkdir::WalkDir::new(corpus)
        .into_iter()
        .filter_map(Result::ok)
        .map(|e| e.into_path())
        .filter(|p| matches!(Format::of_path(p), Some(Format::Gltf | Format::Glb)))
        .collect();
    files.sort();
    files
}

#[test]
fn corpus_reads_without_panic() {
    let Some(corpus) = corpus() else {
        println!("skip: ../shared/corpus not found");
        return;
    };
    let (mut ok, mut errors) = (0, Vec::new());
    for path in corpus_gltf_files(&corpus) {
        let rel = path.strip_prefix(&corpus).unwrap().display().to_string();
        match read_in(&path, &corpus) {
            Ok(_) => ok += 1,
            Err(e) => {
                assert!(!e.0.contains("crashed"), "{rel}: caught panic: {e}");
                errors.push(format!("{rel}: {e}"));
            }
        }
    }
    println!("corpus glTF/GLB: {ok} read, {} errors", errors.len());
    for e in &errors {
        println!("  {e}");
    }
    assert!(ok > 50, "only {ok} corpus files read");
}

/// Corpus files left out of the reference comparison, with the reason.
const REFERENCE_EXCLUDED: &[(&str, &str)] = &[
    (
        "draco/glb/Box_Draco.glb",
        "Draco-compressed (extensionsRequired): meshvet refuses it by design",
    ),
    (
        "assimp/glTF2/draco/2CylinderEngine.gltf",
        "Draco-compressed (extensionsRequired): meshvet refuses it by design",
    ),
    (
        "assimp/glTF2/wrongTypes/badArray.gltf",
        "invalid glTF (`primitives` is an object): the libraries loaded nothing and said 0, meshvet gives an error row",
    ),
];

/// Corpus files whose meshes are instanced by several nodes. The reference libraries flatten the
/// scene and count each instance; SPEC counts each glTF mesh once. For these the reference must
/// equal meshvet's per-mesh counts weighted by the number of instancing nodes (checked
/// independently below from the JSON), and must differ from the plain sum.
const INSTANCED: &[&str] = &[
    "gltf_samples/SimpleMeshes/glTF/SimpleMeshes.gltf",
    "gltf_samples/CesiumMilkTruck/glTF/CesiumMilkTruck.gltf",
    "trimesh/TestScene.gltf",
    "gltf_samples/ReciprocatingSaw/glTF-Binary/ReciprocatingSaw.glb",
];

/// How many scene nodes instance each mesh, read from the file's JSON with the gltf crate's
/// untyped `Value` (an independent walk: scenes, then children, each node once).
fn instances_per_mesh(path: &Path) -> Vec<usize> {
    use gltf::json::Value;
    let bytes = std::fs::read(path).unwrap();
    let json = if bytes.starts_with(b"glTF") {
        let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        bytes[20..20 + len].to_vec()
    } else {
        bytes
    };
    let doc: Value = gltf::json::deserialize::from_slice(&json).unwrap();
    let list = |v: &Value| -> Vec<usize> {
        v.as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|i| i.as_u64())
                    .map(|i| i as usize)
                    .collect()
            })
            .unwrap_or_default()
    };
    let nodes = doc["nodes"].as_array().cloned().unwrap_or_default();
    let mut counts = vec![0; doc["meshes"].as_array().map_or(0, Vec::len)];
    let mut seen = vec![false; nodes.len()];
    let mut stack: Vec<usize> = doc["scenes"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|s| list(&s["nodes"]))
        .collect();
    while let Some(n) = stack.pop() {
        if std::mem::replace(&mut seen[n], true) {
            continue;
        }
        if let Some(m) = nodes[n]["mesh"].as_u64() {
            counts[m as usize] += 1;
        }
        stack.extend(list(&nodes[n]["children"]));
    }
    counts
}

#[test]
fn corpus_triangle_counts_match_the_references() {
    let Some(corpus) = corpus() else {
        println!("skip: ../shared/corpus not found");
        return;
    };
    let mut reader = csv::Reader::from_path(corpus.join("reference_consensus.csv")).unwrap();
    let headers = reader.headers().unwrap().clone();
    let column = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let (file, n, support) = (
        column("file"),
        column("n_triangles"),
        column("n_triangles_support"),
    );
    let (mut compared, mut mismatches) = (0, Vec::new());
    for record in reader.records() {
        let record = record.unwrap();
        let rel = &record[file];
        let path = corpus.join(rel);
        if !matches!(Format::of_path(&path), Some(Format::Gltf | Format::Glb)) {
            continue;
        }
        let agreed = record[support]
            .split_once('/')
            .is_some_and(|(k, of)| k == of && k.parse::<u32>().is_ok_and(|k| k >= 2));
        if !agreed || REFERENCE_EXCLUDED.iter().any(|(f, _)| *f == rel) {
            continue;
        }
        let expected: usize = record[n].parse().unwrap();
        compared += 1;
        let meshes = match read_in(&path, &corpus) {
            Ok(meshes) => meshes,
            Err(e) => {
                mismatches.push(format!("{rel}: reference {expected}, meshvet error: {e}"));
                continue;
            }
        };
        let once: usize = meshes.iter().map(|m| m.triangles.len()).sum();
        if INSTANCED.contains(&rel) {
            let instances = instances_per_mesh(&path);
            let per_node: usize = meshes
                .iter()
                .zip(&instances)
                .map(|(m, k)| m.triangles.len() * k)
                .sum();
            if per_node != expected || once == expected {
                mismatches.push(format!(
                    "{rel} (instanced): reference {expected}, meshvet {once} once, {per_node} per node"
                ));
            }
        } else if once != expected {
            mismatches.push(format!("{rel}: reference {expected}, meshvet {once}"));
        }
    }
    println!("compared {compared} corpus glTF files with reference triangle counts");
    assert!(compared >= 60, "only {compared} files compared");
    assert!(mismatches.is_empty(), "{}", mismatches.join("\n"));
}

// ---------------------------------------------------------------------------------------------
// Audit regressions: expansion without data, per-file totals, compression used without being
// required, GPU instancing

#[test]
fn accessor_without_buffer_view_cannot_expand_past_the_input() {
    // 100 million zero positions (2.4 GB decoded) declared in a file of a few hundred bytes.
    let json = doc(&[
        (
            "accessors",
            r#"[{"componentType":5126,"type":"VEC3","count":100000000}]"#.into(),
        ),
        (
            "meshes",
            r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#.into(),
        ),
    ]);
    assert!(json.len() < 300);
    let err = read_err("zeros.gltf", &json);
    assert!(
        err.contains("accessor without a buffer view declares 100000000 elements")
            && err.contains("far more than this file's"),
        "{err}"
    );
    // A few zero positions are fine (a degenerate but honest file).
    let json = json.replace("100000000", "3");
    let meshes = read_ok("few.gltf", &json);
    assert_eq!(meshes[0].positions, vec![[0.0; 3]; 3]);
    assert_eq!(meshes[0].triangles.len(), 1);
}

#[test]
fn many_primitives_reusing_one_accessor_are_bounded_per_file() {
    // One 3-vertex accessor in a GLB, read by 1000 primitives over 10 meshes.
    let primitive = r#"{"attributes":{"POSITION":0}}"#;
    let primitives = vec![primitive; 100].join(",");
    let meshes = format!(
        "[{}]",
        vec![format!(r#"{{"primitives":[{primitives}]}}"#); 10].join(",")
    );
    let bin = f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]);
    let json = Asset::new(None, 36, &meshes)
        .view(0, 36)
        .accessor(0, FLOAT, "VEC3", 3)
        .json();
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "reuse.glb", glb(&json, &bin));
    let mut context = cx(dir.path());
    // Each mesh alone (300 vertices, 100 triangles) is within 2000; the file (3000) is not.
    context.limits.max_triangles = 2000;
    let err = read(&path, Format::Glb, &context).unwrap_err().0;
    assert!(
        err.contains("in all, over the limit of 2000 per file") && err.contains("vertices"),
        "{err}"
    );
    context.limits.max_triangles = 3000;
    let meshes = read(&path, Format::Glb, &context).unwrap();
    assert_eq!(meshes.len(), 10);
    assert!(meshes.iter().all(|m| m.triangles.len() == 100));
}

#[test]
fn draco_on_a_primitive_without_being_required_is_named() {
    // The Draco primitive's POSITION accessor has no buffer view: without the extension it would
    // read as zeros.
    let json = doc(&[
        ("extensionsUsed", r#"["KHR_draco_mesh_compression"]"#.into()),
        (
            "accessors",
            r#"[{"componentType":5126,"type":"VEC3","count":3}]"#.into(),
        ),
        (
            "meshes",
            r#"[{"name":"d","primitives":[{"attributes":{"POSITION":0},
                "extensions":{"KHR_draco_mesh_compression":{"bufferView":0,"attributes":{"POSITION":0}}}}]}]"#
                .into(),
        ),
    ]);
    let err = read_err("draco.gltf", json);
    assert!(
        err.contains("mesh \"d\" (#0) primitive 0 is compressed with KHR_draco_mesh_compression, which meshvet cannot decode"),
        "{err}"
    );
    // With the uncompressed fallback the extension allows, the fallback is read, with a note.
    let json = triangle_with(
        r#"[{"primitives":[{"attributes":{"POSITION":0},
            "extensions":{"KHR_draco_mesh_compression":{"bufferView":0,"attributes":{"POSITION":0}}}}]}]"#,
        &[("extensionsUsed", r#"["KHR_draco_mesh_compression"]"#)],
    );
    let meshes = read_ok("fallback.gltf", json);
    assert_eq!(meshes[0].positions[1], [1.0, 0.0, 0.0]);
    assert!(
        meshes[0]
            .notes
            .iter()
            .any(|n| n.contains("uncompressed fallback")),
        "{:?}",
        meshes[0].notes
    );
}

#[test]
fn meshopt_buffer_view_without_being_required_is_named() {
    let meshopt = r#"{"buffer":0,"byteOffset":0,"byteLength":36,
        "extensions":{"EXT_meshopt_compression":{"buffer":1,"byteLength":20,"byteStride":12,"count":3,"mode":"ATTRIBUTES"}}}"#;
    // Buffer 1 is the compressed data; buffer 0, which the view reads, is a fallback placeholder.
    let json = doc(&[
        ("extensionsUsed", r#"["EXT_meshopt_compression"]"#.into()),
        (
            "buffers",
            format!(
                r#"[{{"byteLength":36,"extensions":{{"EXT_meshopt_compression":{{"fallback":true}}}}}},
                    {{"uri":"{}","byteLength":20}}]"#,
                data_uri(&[0; 20])
            ),
        ),
        ("bufferViews", format!("[{meshopt}]")),
        (
            "accessors",
            r#"[{"bufferView":0,"componentType":5126,"type":"VEC3","count":3}]"#.into(),
        ),
        (
            "meshes",
            r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#.into(),
        ),
    ]);
    let err = read_err("meshopt.gltf", json);
    assert!(
        err.contains("reads buffer view 0, compressed with EXT_meshopt_compression, which meshvet cannot decode"),
        "{err}"
    );
    // A view whose own buffer holds real (fallback) data is read, with a note.
    let json = triangle().replace(
        r#""bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36}]"#,
        &format!("\"bufferViews\":[{meshopt}]"),
    );
    assert!(json.contains("EXT_meshopt_compression"));
    let meshes = read_ok("fallback.gltf", json);
    assert_eq!(meshes[0].triangles.len(), 1);
    assert!(
        meshes[0]
            .notes
            .iter()
            .any(|n| n.contains("EXT_meshopt_compression")),
        "{:?}",
        meshes[0].notes
    );
}

#[test]
fn gpu_instances_with_a_negative_scale_product_are_mirrored() {
    // Positions (36 bytes) then the SCALE of five instances: (1,1,1), (-1,1,1), (-1,-1,1),
    // (1,1,-2), (2,2,2): two of them mirror the mesh, three do not.
    let mut bin = f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]);
    bin.extend(f32s(&[
        1., 1., 1., -1., 1., 1., -1., -1., 1., 1., 1., -2., 2., 2., 2.,
    ]));
    let asset = |node_scale: &str, attributes: &str| {
        let nodes = format!(
            r#"[{{"mesh":0{node_scale},"extensions":{{"EXT_mesh_gpu_instancing":{{"attributes":{attributes}}}}}}}]"#
        );
        Asset::new(
            Some(data_uri(&bin)),
            bin.len(),
            r#"[{"primitives":[{"attributes":{"POSITION":0}}]}]"#,
        )
        .view(0, 36)
        .view(36, 60)
        .accessor(0, FLOAT, "VEC3", 3)
        .accessor(1, FLOAT, "VEC3", 5)
        .with("extensionsUsed", r#"["EXT_mesh_gpu_instancing"]"#)
        .with("nodes", &nodes)
        .json()
    };
    let meshes = read_ok("instanced.gltf", asset("", r#"{"SCALE":1}"#));
    assert_eq!(meshes[0].mirrored_instances, 2);
    // A mirrored node flips every instance: the other three are mirrored now.
    let flip = r#","scale":[1,1,-1]"#;
    let meshes = read_ok("flipped.gltf", asset(flip, r#"{"SCALE":1}"#));
    assert_eq!(meshes[0].mirrored_instances, 3);
    // Without SCALE every instance has the node's orientation.
    let meshes = read_ok("moved.gltf", asset(flip, r#"{"TRANSLATION":1}"#));
    assert_eq!(meshes[0].mirrored_instances, 5);
    // An unreadable SCALE is a note, and the instances count as unscaled.
    let meshes = read_ok("broken.gltf", asset(flip, r#"{"TRANSLATION":1,"SCALE":7}"#));
    assert_eq!(meshes[0].mirrored_instances, 5);
    assert!(
        meshes[0]
            .notes
            .iter()
            .any(|n| n.contains("SCALE could not be read")),
        "{:?}",
        meshes[0].notes
    );
}
