//! meshvet against the reference libraries on the shared corpus (`../shared/corpus`).
//!
//! `reference_consensus.csv` holds, per file, the values trimesh, PyMeshLab, libigl and Open3D agree
//! on. A value is a reference here only when its `*_support` is `k/k` with `k >= 2` (every library
//! that reported it agrees, and at least two did). For every such (file, column) this test reads the
//! file with meshvet's readers, analyses it with the default options and asserts that meshvet gives
//! the same value, unless
//!
//! * the file is one meshvet refuses on purpose (an error row, see [`REFUSED`]), or
//! * the conventions differ for the whole file (a glTF scene that is not one mesh placed once: the
//!   libraries flatten the scene, SPEC 2 analyses each glTF mesh once in its own space), or
//! * the (file, column) is in [`EXCLUDED`], each with a [`Reason`] naming the definitional difference
//!   (README of the corpus, SPEC) and a check, run here, that the explanation holds for that file.
//!
//! For a glTF mesh placed once, the libraries measure it after its node's world transform, so its
//! volume is compared times that transform's determinant (counts do not depend on it).
//!
//! An exclusion that no longer differs fails the test too: the list must stay exact.
//! Without the corpus (a user's clone) the test prints one line and passes.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

use meshvet::formats::{self, Format, Limits, ReadContext};
use meshvet::{analyse, Analysis, Mesh, Options};

/// Files larger than this are left out to keep the test quick (the corpus has none today).
const MAX_FILE_BYTES: u64 = 50 << 20;

// ---------------------------------------------------------------------------------------------
// Columns

/// The reference columns compared, in the CSV's order. `n_components_vertex` and
/// `n_manifold_patches` have no meshvet counterpart and are not compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Column {
    Vertices,
    Triangles,
    Edges,
    BoundaryEdges,
    NonmanifoldEdges,
    NonmanifoldVertices,
    Components,
    BoundaryLoops,
    Closed,
    WindingConsistent,
    Euler,
    Genus,
    Volume,
}

use Column::*;

const COLUMNS: [Column; 13] = [
    Vertices,
    Triangles,
    Edges,
    BoundaryEdges,
    NonmanifoldEdges,
    NonmanifoldVertices,
    Components,
    BoundaryLoops,
    Closed,
    WindingConsistent,
    Euler,
    Genus,
    Volume,
];

impl Column {
    fn name(self) -> &'static str {
        match self {
            Vertices => "n_vertices",
            Triangles => "n_triangles",
            Edges => "n_edges",
            BoundaryEdges => "n_boundary_edges",
            NonmanifoldEdges => "n_nonmanifold_edges",
            NonmanifoldVertices => "n_nonmanifold_vertices",
            Components => "n_components",
            BoundaryLoops => "n_boundary_loops",
            Closed => "closed",
            WindingConsistent => "winding_consistent",
            Euler => "euler",
            Genus => "genus",
            Volume => "volume",
        }
    }

    /// meshvet's value for this column, as text comparable with the CSV (`None`: undefined).
    ///
    /// `volume_scale` is the determinant of the world transform that places a glTF mesh (1 for
    /// other formats): the libraries measure the placed mesh, meshvet the mesh in its own space.
    fn ours(self, a: &Analysis, volume_scale: f64) -> Option<Value> {
        let n = |x: usize| Some(Value::Int(x as i64));
        match self {
            // The libraries merge equal positions and count only the vertices some face refers
            // to (point clouds give 0; trimesh/bunny.ply: 8171 welded, 8146 referenced, all four
            // libraries say 8146).
            Vertices => n(a.welded_vertices - a.unreferenced_vertices),
            Triangles => n(a.faces),
            Edges => n(a.edges),
            BoundaryEdges => n(a.border_edges),
            NonmanifoldEdges => n(a.nonmanifold_edges),
            NonmanifoldVertices => n(a.nonmanifold_vertices),
            Components => n(a.components.len()),
            BoundaryLoops => n(a.holes()),
            // Watertight: there are faces and every edge has valence 2.
            Closed => Some(Value::Bool(
                !a.components.is_empty() && a.components.iter().all(|c| c.closed),
            )),
            WindingConsistent => Some(Value::Bool(a.oriented())),
            Euler => Some(Value::Int(a.euler)),
            Genus => a.genus().map(Value::Int),
            Volume => a.volume().map(|v| Value::Float(v * volume_scale)),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Value {
    Int(i64),
    Bool(bool),
    Float(f64),
}

impl std::fmt::Display for Value {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Value::Int(x) => write!(f, "{x}"),
            Value::Bool(x) => write!(f, "{x}"),
            Value::Float(x) => write!(f, "{x}"),
        }
    }
}

/// Whether meshvet's value is the reference's. Volumes in the CSV carry five significant digits
/// (Python's `%.5g`), so ours must round to the reference: within half a unit of its fifth digit
/// (plus 1e-9 relative for summation order).
fn agrees(ours: Option<Value>, reference: &str) -> bool {
    match ours {
        None => false,
        Some(Value::Int(x)) => reference.parse::<i64>() == Ok(x),
        Some(Value::Bool(x)) => reference.eq_ignore_ascii_case(if x { "true" } else { "false" }),
        Some(Value::Float(x)) => {
            let Ok(r) = reference.parse::<f64>() else {
                return false;
            };
            if r == 0.0 {
                return x.abs() < 1e-12;
            }
            let half_unit = 0.5 * 10f64.powi(r.abs().log10().floor() as i32 - 4);
            (x - r).abs() <= half_unit + 1e-9 * r.abs()
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Files meshvet refuses

/// Files meshvet gives an error row for (SPEC 2: "a file that cannot be read gives a row with status
/// `error`"), where the libraries load what they can or find nothing. Their reference values are not
/// comparable; the test checks that meshvet does refuse each one.
const REFUSED: &[(&str, &str)] = &[
    (
        "tinyobjloader/invalid-relative-vertex-index.obj",
        "relative face index before the first vertex: the libraries drop the face",
    ),
    (
        "tinyobjloader/invalid-relative-texture-index.obj",
        "face index 1 with no vertices in the file: the libraries drop the face",
    ),
    (
        "tinyobjloader/issue-140-zero-face-idx.obj",
        "face index 0 (OBJ indices start at 1): the libraries drop or wrap it",
    ),
    (
        "assimp/invalid/malformed.obj",
        "face index 0 (OBJ indices start at 1)",
    ),
    (
        "assimp/OBJ/box_UTF16BE.obj",
        "UTF-16 text: OBJ is ASCII or UTF-8",
    ),
    (
        "assimp/OFF/invalid.off",
        "face uses vertex 20 of a 3-vertex file: the libraries drop the face",
    ),
    (
        "assimp/invalid/OutOfMemory.off",
        "header declares 353535235358 vertices in a 288-byte file",
    ),
    (
        "assimp/invalid/crash-30d6d0f7c529b3b66b4131700b7a4580cd7082df.ply",
        "no `end_header` line",
    ),
    (
        "assimp/nonbsd/ant-half.ply",
        "truncated after 259 of 912 declared faces: the libraries keep the 259",
    ),
    (
        "assimp/PLY/issue623.ply",
        "`vertex_indices` declared on the vertex element and missing from its lines",
    ),
    (
        "assimp/PLY/payload_JVN42386607.ply",
        "`format ascii` without a version: an exploit payload, not a PLY",
    ),
    (
        "draco/glb/Box_Draco.glb",
        "Draco-compressed (extensionsRequired): meshvet cannot decode it",
    ),
    (
        "assimp/glTF2/draco/2CylinderEngine.gltf",
        "Draco-compressed (extensionsRequired): meshvet cannot decode it",
    ),
    (
        "assimp/glTF2/IndexOutOfRange/IndexOutOfRange.gltf",
        "index 255 into a 24-vertex primitive",
    ),
    (
        "assimp/glTF2/IndexOutOfRange/AllIndicesOutOfRange.gltf",
        "every index out of range",
    ),
    (
        "assimp/glTF2/wrongTypes/badArray.gltf",
        "`primitives` is an object, not an array: invalid glTF",
    ),
    (
        "assimp/glTF2/MissingBin/BoxTextured.gltf",
        "the buffer file is missing",
    ),
    (
        "assimp/glTF2/sceneWrongType.gltf",
        "the buffer file is missing",
    ),
    (
        "assimp/glTF1/TwoBoxes/TwoBoxes.gltf",
        "glTF 1.0 is not supported",
    ),
];

// ---------------------------------------------------------------------------------------------
// Definitional differences

/// Why meshvet and the libraries differ on a (file, column), by definition (or, for the last two,
/// because the reference cannot be trusted for that file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Reason {
    /// Corpus README: the libraries do not count the endpoints of non-manifold edges as
    /// non-manifold vertices; SPEC 6 (seed 003) does, since their star is not edge-manifold.
    NonManifoldEdgeEndpoints,
    /// Corpus README: the libraries keep degenerate faces (two corners on one welded vertex) and
    /// count their vertices and edges; SPEC 4 leaves them out of the table.
    DegenerateFaces,
    /// SPEC 3: triangles using a vertex with a NaN or infinite coordinate are left out of the
    /// analysis; the libraries keep them.
    InvalidVertices,
    /// SPEC 4 splits a concave polygon by ear clipping; the libraries fan-split every polygon from
    /// its first corner, which for a concave polygon makes overlapping triangles (and here
    /// non-manifold edges).
    PolygonFan,
    /// Not definitional: the reference is wrong for this file. Its PLY header lines end with a
    /// bare CR (old Mac style); the libraries that loaded it read no elements.
    BareCrPlyHeader,
}

impl Reason {
    fn why(self) -> &'static str {
        match self {
            Reason::NonManifoldEdgeEndpoints => {
                "non-manifold edge endpoints: SPEC counts them as non-manifold vertices, the libraries do not"
            }
            Reason::DegenerateFaces => {
                "degenerate faces: the libraries count their vertices and edges; SPEC leaves them out"
            }
            Reason::InvalidVertices => {
                "NaN/inf vertices: SPEC leaves out the faces using them; the libraries keep them"
            }
            Reason::PolygonFan => {
                "concave polygons: SPEC ear-clips them; the libraries fan-split (overlaps, nm edges)"
            }
            Reason::BareCrPlyHeader => {
                "reference wrong: PLY header with bare-CR line ends, the libraries read nothing"
            }
        }
    }

    /// Checks that the explanation holds for this file; `Err` says why it does not.
    fn holds(self, cx: &FileCx, column: Column) -> Result<(), String> {
        let a = &cx.analysis;
        let reference = cx.reference(column);
        match self {
            Reason::NonManifoldEdgeEndpoints => {
                // Exactly the endpoints make the difference.
                let endpoints = nonmanifold_edge_endpoints(&cx.mesh);
                let r: usize = reference.parse().map_err(|_| "bad reference")?;
                if a.nonmanifold_vertices == r + endpoints {
                    Ok(())
                } else {
                    Err(format!(
                        "the file's non-manifold edges have {endpoints} endpoints, and {} != {r} + {endpoints}",
                        a.nonmanifold_vertices
                    ))
                }
            }
            Reason::DegenerateFaces => {
                if a.degenerate_faces == 0 {
                    return Err("the file has no degenerate faces".into());
                }
                if column == Euler {
                    let chi = euler_keeping_degenerate_faces(&cx.mesh);
                    if reference.parse() != Ok(chi) {
                        return Err(format!(
                            "V - E + F with the degenerate faces kept is {chi}, not the reference"
                        ));
                    }
                }
                Ok(())
            }
            Reason::InvalidVertices => {
                if a.invalid_faces == 0 {
                    return Err("no face uses an invalid vertex".into());
                }
                Ok(())
            }
            Reason::PolygonFan => {
                // Fan-split the polygons as the libraries do; meshvet's own analysis of that
                // split must then give the reference value.
                let fan = obj_fan_split(&cx.path)?;
                let value = column.ours(&analyse(&fan, &Options::default()), 1.0);
                if agrees(value, reference) {
                    Ok(())
                } else {
                    Err(format!(
                        "the fan split gives {value:?}, not the reference either"
                    ))
                }
            }
            Reason::BareCrPlyHeader => {
                let bytes = std::fs::read(&cx.path).map_err(|e| e.to_string())?;
                let end = bytes
                    .windows(10)
                    .position(|w| w == b"end_header")
                    .ok_or("no end_header")?;
                let bare_cr = bytes[..end].contains(&b'\r') && !bytes[..end].contains(&b'\n');
                if bare_cr && a.faces > 0 && cx.reference(Triangles) == "0" {
                    Ok(())
                } else {
                    Err("the header does not use bare CR line ends, or nobody reads faces".into())
                }
            }
        }
    }
}

/// (file, column) pairs that differ by definition, each with its reason (checked per file).
#[rustfmt::skip]
const EXCLUDED: &[(&str, Column, Reason)] = &[
    // Non-manifold vertices at the endpoints of non-manifold edges.
    ("draco/non_manifold_wrap.obj", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("libigl_tests/degenerated.obj", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("trimesh/two_objects.obj", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("trimesh/joined_tetrahedra.obj", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("trimesh/shared.STL", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("gltf_samples/DamagedHelmet/glTF/DamagedHelmet.gltf", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("trimesh/not_convex.obj", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("pymeshfix/planar_mesh.ply", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("assimp/STL/3DSMaxExport.STL", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("common3d/beetle.obj", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("manifold/test_models/Offset1.obj", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("trimesh/bunny.ply", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("trimesh/cycloidal.ply", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("pymeshfix/StanfordBunny.ply", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    ("gltf_samples/BrainStem/glTF-Binary/BrainStem.glb", NonmanifoldVertices, Reason::NonManifoldEdgeEndpoints),
    // One face, all three corners at one position: the libraries count V = 1, E = 1, F = 1.
    ("draco/degenerate_mesh.obj", Euler, Reason::DegenerateFaces),
    // One face on three NaN/inf vertices: SPEC analyses nothing.
    ("draco/inf_nan.obj", Euler, Reason::InvalidVertices),
    // Concave polygons (walls with holes, joined by `\` continuation lines; bent quads).
    ("trimesh/wallhole.obj", Closed, Reason::PolygonFan),
    ("common3d/beast.obj", Closed, Reason::PolygonFan),
    // Reference wrong (bare-CR header): the libraries saw an empty file.
    ("draco/Box.ply", Vertices, Reason::BareCrPlyHeader),
    ("draco/Box.ply", Triangles, Reason::BareCrPlyHeader),
    ("draco/Box.ply", Edges, Reason::BareCrPlyHeader),
    ("draco/Box.ply", Closed, Reason::BareCrPlyHeader),
];

// ---------------------------------------------------------------------------------------------
// Independent recomputations for the reasons' checks

/// Exact weld (SPEC 3, -0.0 == 0.0), written independently of `meshvet::weld`; `None` for a vertex
/// with a NaN or infinite coordinate.
fn weld_exactly(positions: &[[f64; 3]]) -> Vec<Option<u32>> {
    let mut ids: HashMap<[u64; 3], u32> = HashMap::new();
    positions
        .iter()
        .map(|p| {
            p.iter().all(|x| x.is_finite()).then(|| {
                let next = ids.len() as u32;
                *ids.entry(p.map(|x| (x + 0.0).to_bits())).or_insert(next)
            })
        })
        .collect()
}

/// Distinct welded vertices at the ends of edges bounding three or more table faces.
fn nonmanifold_edge_endpoints(mesh: &Mesh) -> usize {
    let map = weld_exactly(&mesh.positions);
    let mut valence: HashMap<(u32, u32), usize> = HashMap::new();
    for t in &mesh.triangles {
        let Some(w) = t
            .iter()
            .map(|&i| map[i as usize])
            .collect::<Option<Vec<u32>>>()
        else {
            continue;
        };
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (w[k], w[(k + 1) % 3]);
            *valence.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let ends: HashSet<u32> = valence
        .iter()
        .filter(|(_, &n)| n >= 3)
        .flat_map(|(&(a, b), _)| [a, b])
        .collect();
    ends.len()
}

/// V - E + F with every valid face kept, degenerate ones too (their edges as unordered pairs,
/// a pair of one vertex included), as the libraries count.
fn euler_keeping_degenerate_faces(mesh: &Mesh) -> i64 {
    let map = weld_exactly(&mesh.positions);
    let (mut vertices, mut edges, mut faces) = (HashSet::new(), HashSet::new(), 0i64);
    for t in &mesh.triangles {
        let Some(w) = t
            .iter()
            .map(|&i| map[i as usize])
            .collect::<Option<Vec<u32>>>()
        else {
            continue;
        };
        faces += 1;
        for k in 0..3 {
            let (a, b) = (w[k], w[(k + 1) % 3]);
            vertices.insert(a);
            edges.insert((a.min(b), a.max(b)));
        }
    }
    vertices.len() as i64 - edges.len() as i64 + faces
}

/// A minimal OBJ reading (`v` and `f` statements, `\` continuation lines, negative indices) that
/// splits every polygon as a fan from its first corner, the way the libraries do.
fn obj_fan_split(path: &Path) -> Result<Mesh, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let text = text.replace("\\\r\n", " ").replace("\\\n", " ");
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let p: Vec<f64> = words.take(3).map(|w| w.parse().unwrap()).collect();
                positions.push([p[0], p[1], p[2]]);
            }
            Some("f") => {
                let n = positions.len() as i64;
                let corners: Vec<u32> = words
                    .map(|w| {
                        let i: i64 = w.split('/').next().unwrap().parse().unwrap();
                        (if i < 0 { n + i } else { i - 1 }) as u32
                    })
                    .collect();
                for k in 1..corners.len().saturating_sub(1) {
                    triangles.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok(Mesh::new(positions, triangles))
}

// ---------------------------------------------------------------------------------------------
// Per-file context

/// One corpus file as meshvet sees it, for the comparisons and the reasons' checks.
struct FileCx {
    path: PathBuf,
    mesh: Mesh,
    analysis: Analysis,
    /// The reference row: CSV header -> cell.
    reference: HashMap<String, String>,
}

impl FileCx {
    fn reference(&self, column: Column) -> &str {
        &self.reference[column.name()]
    }
}

/// `Some(k)` when `support` is `k/k` with `k >= 2`.
fn unanimous(support: &str) -> Option<u32> {
    let (k, of) = support.split_once('/')?;
    let k: u32 = k.parse().ok()?;
    (k >= 2 && of.parse() == Ok(k)).then_some(k)
}

// ---------------------------------------------------------------------------------------------
// glTF scenes

/// For a glTF/GLB file whose scene places exactly one mesh exactly once, and meshvet read exactly that
/// mesh: the determinant of the placing node's world transform (the libraries flatten the scene
/// with node transforms, so their volume is ours times it). `None` when the scene conventions
/// differ (several meshes, or a mesh placed several times or never): SPEC 2 analyses each glTF mesh
/// once in its own space, the libraries the flattened scene.
fn gltf_single_placement(path: &Path) -> Option<f64> {
    use gltf::json::Value as J;
    let bytes = std::fs::read(path).ok()?;
    let json = if bytes.starts_with(b"glTF") {
        let len = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?) as usize;
        bytes.get(20..20 + len)?.to_vec()
    } else {
        bytes
    };
    let doc: J = gltf::json::deserialize::from_slice(&json).ok()?;
    if doc["meshes"].as_array()?.len() != 1 {
        return None;
    }
    let nodes = doc["nodes"].as_array()?;
    let indices = |v: &J| -> Vec<usize> {
        v.as_array()
            .into_iter()
            .flatten()
            .filter_map(J::as_u64)
            .map(|i| i as usize)
            .collect()
    };
    let local_det = |n: &J| -> f64 {
        if let Some(m) = n["matrix"].as_array() {
            let m: Vec<f64> = m.iter().filter_map(J::as_f64).collect();
            if m.len() != 16 {
                return f64::NAN; // malformed: a NaN volume fails visibly
            }
            // column-major 4x4; the upper 3x3 is m[0..3], m[4..7], m[8..11]
            return m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2])
                + m[8] * (m[1] * m[6] - m[5] * m[2]);
        }
        n["scale"]
            .as_array()
            .map_or(1.0, |s| s.iter().filter_map(J::as_f64).product())
    };
    // trimesh flattens the default scene (`scene`, else the first).
    let scenes = doc["scenes"].as_array()?;
    let scene = doc["scene"].as_u64().unwrap_or(0) as usize;
    let mut stack: Vec<(usize, f64)> = indices(&scenes.get(scene)?["nodes"])
        .into_iter()
        .map(|n| (n, 1.0))
        .collect();
    let mut seen = HashSet::new();
    let mut placements = Vec::new();
    while let Some((n, parent)) = stack.pop() {
        if !seen.insert(n) {
            continue;
        }
        let node = nodes.get(n)?;
        let det = parent * local_det(node);
        if node["mesh"].as_u64().is_some() {
            placements.push(det);
        }
        stack.extend(indices(&node["children"]).into_iter().map(|c| (c, det)));
    }
    match placements[..] {
        [det] => Some(det),
        _ => None,
    }
}

// ---------------------------------------------------------------------------------------------
// The test

#[derive(Default)]
struct Tally {
    compared: usize,
    agree: usize,
    excluded: BTreeMap<Reason, usize>,
    refused: usize,
    scene: usize,
}

#[test]
fn meshvet_agrees_with_the_reference_libraries() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    let csv_path = root.join("reference_consensus.csv");
    if !csv_path.is_file() {
        println!("skip: no reference corpus at {}", root.display());
        return;
    }
    let started = std::time::Instant::now();
    let cx = ReadContext {
        root: root.clone(),
        limits: Limits::default(),
    };
    let refused: HashMap<&str, &str> = REFUSED.iter().copied().collect();
    let mut excluded: HashMap<(&str, Column), Reason> = HashMap::new();
    for &(file, column, reason) in EXCLUDED {
        assert!(
            excluded.insert((file, column), reason).is_none(),
            "{file} {} excluded twice",
            column.name()
        );
    }
    let mut used_exclusions = HashSet::new();

    let mut reader = csv::Reader::from_path(&csv_path).unwrap();
    let headers = reader.headers().unwrap().clone();
    let mut tally: BTreeMap<Column, Tally> =
        COLUMNS.iter().map(|&c| (c, Tally::default())).collect();
    let mut failures = Vec::new();
    let (mut files, mut too_big) = (0, 0);

    for record in reader.records() {
        let record = record.unwrap();
        let row: HashMap<String, String> = headers
            .iter()
            .zip(record.iter())
            .map(|(h, v)| (h.to_string(), v.to_string()))
            .collect();
        let file = row["file"].clone();
        let references: Vec<Column> = COLUMNS
            .iter()
            .copied()
            .filter(|c| unanimous(&row[&format!("{}_support", c.name())]).is_some())
            .collect();
        let path = root.join(&file);
        files += 1;
        if std::fs::metadata(&path).unwrap().len() > MAX_FILE_BYTES {
            too_big += 1;
            continue;
        }
        let format = Format::of_path(&path).unwrap();
        let meshes = match formats::read(&path, format, &cx) {
            Err(e) => {
                if refused.contains_key(file.as_str()) {
                    for c in &references {
                        tally.get_mut(c).unwrap().refused += 1;
                    }
                } else {
                    failures.push(format!("{file}: meshvet cannot read it: {e}"));
                }
                continue;
            }
            Ok(meshes) => {
                if refused.contains_key(file.as_str()) {
                    failures.push(format!(
                        "{file}: listed in REFUSED ({}) but meshvet reads it",
                        refused[file.as_str()]
                    ));
                }
                meshes
            }
        };
        let mut volume_scale = 1.0;
        let mesh = match (format, meshes.len()) {
            (_, 0) => Mesh::default(), // nothing to analyse, as for the libraries
            (Format::Gltf | Format::Glb, 1) => match gltf_single_placement(&path) {
                Some(det) => {
                    volume_scale = det.abs();
                    meshes.into_iter().next().unwrap()
                }
                None => {
                    for c in &references {
                        tally.get_mut(c).unwrap().scene += 1;
                    }
                    continue;
                }
            },
            (Format::Gltf | Format::Glb, _) => {
                for c in &references {
                    tally.get_mut(c).unwrap().scene += 1;
                }
                continue;
            }
            (_, 1) => meshes.into_iter().next().unwrap(),
            (_, n) => panic!("{file}: {n} meshes from a single-mesh format"),
        };
        let analysis = analyse(&mesh, &Options::default());
        let file_cx = FileCx {
            path,
            mesh,
            analysis,
            reference: row,
        };
        for &column in &references {
            let t = tally.get_mut(&column).unwrap();
            t.compared += 1;
            let ours = column.ours(&file_cx.analysis, volume_scale);
            let reference = file_cx.reference(column);
            let same = agrees(ours, reference);
            let shown = ours.map_or("undefined".to_string(), |v| v.to_string());
            match excluded.get(&(file.as_str(), column)) {
                None if same => t.agree += 1,
                None => failures.push(format!(
                    "{file} {}: meshvet {shown}, references {reference}",
                    column.name()
                )),
                Some(&reason) => {
                    used_exclusions.insert((file.clone(), column));
                    if same {
                        failures.push(format!(
                            "{file} {}: excluded ({}) but agrees now ({shown}): remove the exclusion",
                            column.name(),
                            reason.why()
                        ));
                        t.agree += 1;
                    } else if let Err(e) = reason.holds(&file_cx, column) {
                        failures.push(format!(
                            "{file} {}: meshvet {shown}, references {reference}; excluded as \"{}\", but {e}",
                            column.name(),
                            reason.why()
                        ));
                    } else {
                        *t.excluded.entry(reason).or_default() += 1;
                    }
                }
            }
        }
    }
    for &(file, column, _) in EXCLUDED {
        if !used_exclusions.contains(&(file.to_string(), column)) {
            failures.push(format!(
                "{file} {}: excluded, but not compared (no k/k reference, or the file was skipped)",
                column.name()
            ));
        }
    }

    // Summary
    println!(
        "\nmeshvet vs reference libraries: {files} files ({too_big} over {} MB skipped), {:.1?}",
        MAX_FILE_BYTES >> 20,
        started.elapsed()
    );
    println!(
        "{:<24} {:>8} {:>6} {:>9} {:>8} {:>6}",
        "column", "compared", "agree", "excluded", "refused", "scene"
    );
    for (column, t) in &tally {
        println!(
            "{:<24} {:>8} {:>6} {:>9} {:>8} {:>6}",
            column.name(),
            t.compared,
            t.agree,
            t.excluded.values().sum::<usize>(),
            t.refused,
            t.scene
        );
    }
    let mut by_reason: BTreeMap<Reason, usize> = BTreeMap::new();
    for t in tally.values() {
        for (&r, &n) in &t.excluded {
            *by_reason.entry(r).or_default() += n;
        }
    }
    println!("excluded by reason:");
    for (reason, n) in &by_reason {
        println!("  {n:>3}  {}", reason.why());
    }
    println!("(refused: meshvet gives an error row; scene: glTF scene not one mesh placed once)");
    assert!(
        failures.is_empty(),
        "{} disagreements with the reference libraries:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
