//! glTF 2.0 / GLB reader: one [`Mesh`] per glTF `mesh`, all its triangle primitives together, in
//! the mesh's local space, counted once however many nodes instance it
//! ([definitions](crate::definitions#meshes)).
//!
//! The gltf crate panics on several malformed inputs, all in its validation pass and its `Reader`
//! (the POSITION index check of its validation, float indices in its `Reader`, a byte stride shorter
//! than an element, a `%FF` in a URI: all seen in release builds). So this reader uses only the crate's JSON types: it deserializes the
//! members geometry needs itself (`container::Model`, after turning away glTF 1.0 and extensions
//! it cannot decode), never builds a `gltf::Document`, resolves buffers itself (`buffers`), and
//! reads accessors from bytes it has checked (`accessor`). Every index, type, stride and byte range is checked before use; a panic that
//! slips through anyway is caught and reported as a read error for this file.
//!
//! Nothing a small file declares can make it expand without bound: `limits.max_triangles` holds for
//! the vertices and triangles of all meshes of a file together (meshes and primitives may reuse one
//! accessor), and an accessor without a buffer view (all zeros but its sparse values) may stand for
//! at most `accessor::UNBACKED_PER_INPUT_BYTE` bytes per byte of JSON and loaded buffers, per accessor
//! and per file. Compression meshvet cannot decode is refused by name even when it is only used,
//! not required (`check_compression`).

pub(super) mod accessor;
pub(super) mod buffers;
pub(super) mod container;
mod nodes;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use gltf::json;
use gltf::json::accessor::{ComponentType, GenericComponentType, Type};
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use super::{ReadContext, ReadError, SideFiles};
use crate::mesh::Mesh;
use accessor::Data;

/// What to do with a glTF whose positions are quantized (KHR_mesh_quantization): meshvet reads,
/// checks and repairs only float positions.
pub(crate) const DEQUANTIZE: &str = "re-export it with float positions (no mesh quantization: \
     gltfpack -noq), or dequantize it (gltf-transform dequantize) and scan that file";

/// The buffers and images a glTF or GLB file names, found as the reader finds them.
pub(crate) const SIDE_FILES: SideFiles = SideFiles {
    names: uris,
    resolve: |name, location| buffers::resolve(name, location).ok(),
};

/// The external `buffers[].uri` and `images[].uri` of a glTF or GLB file (as written: the reader's
/// rule decodes them), or none when its JSON cannot be found or parsed (the reader will then report
/// the file).
fn uris(bytes: &[u8]) -> Vec<String> {
    let json = if bytes.starts_with(b"glTF") {
        // GLB: 12-byte header, then the JSON chunk (length, type, data).
        let Some(length) = bytes.get(12..16) else {
            return Vec::new();
        };
        let length = u32::from_le_bytes(length.try_into().expect("4 bytes")) as usize;
        match bytes.get(20..20usize.saturating_add(length)) {
            Some(json) => json,
            None => return Vec::new(),
        }
    } else {
        bytes
    };
    let Ok(value) = serde_json::from_slice::<serde_json::Value>(json) else {
        return Vec::new();
    };
    let mut uris = Vec::new();
    for list in ["buffers", "images"] {
        for item in value[list].as_array().into_iter().flatten() {
            if let Some(uri) = item["uri"].as_str() {
                if !uri
                    .get(..5)
                    .is_some_and(|s| s.eq_ignore_ascii_case("data:"))
                {
                    uris.push(uri.to_owned());
                }
            }
        }
    }
    uris
}

/// Reads every mesh of a `.gltf` or `.glb` file (either is recognised by its content).
pub fn read(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    guard(|| read_unguarded(path, cx))
}

/// Runs `f`, turning a panic (a check this reader lacks) into a read error for this file.
fn guard<T>(f: impl FnOnce() -> Result<T, ReadError>) -> Result<T, ReadError> {
    crate::caught(f).unwrap_or_else(|detail| {
        Err(ReadError::new(format!(
            "the glTF reader crashed on this file ({detail}): the file is malformed in a way meshvet does not yet describe; please report it"
        )))
    })
}

fn read_unguarded(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    let bytes = super::read_bytes(path, &cx.limits)?;
    Ok(read_from(&bytes, path, cx, &BTreeSet::new())?.0)
}

/// The meshes of the glTF whose bytes `bytes` were read from `path`, and the buffer files read
/// for them, which hold the buffers in `also` as well (all of whose trouble is an error). The
/// copy writer reads the file once through this: the meshes it checks against the scan's are
/// those of the very bytes and buffers it copies.
pub(crate) fn read_from(
    bytes: &[u8],
    path: &Path,
    cx: &ReadContext,
    also: &BTreeSet<usize>,
) -> Result<(Vec<Mesh>, buffers::Files), ReadError> {
    let container = container::split(bytes)?;
    let root = container::parse_model(container.json)?;
    if root.meshes.is_empty() {
        return Ok((Vec::new(), buffers::Files::default()));
    }
    let mut notes = vec![Vec::new(); root.meshes.len()];
    check_compression(&root, container.is_glb, &mut notes)?;

    // Load only the buffers the meshes read: a missing texture-only .bin is not our concern.
    let mut needed = BTreeSet::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let Some((position, indices)) = triangle_accessors(primitive) else {
                continue;
            };
            for index in std::iter::once(position).chain(indices) {
                let what = primitive_name(mesh, m, p);
                let accessor = accessor::get(&root, index, &what)?;
                for view in accessor::views_of(accessor) {
                    let view = root.buffer_views.get(view).ok_or_else(|| {
                        ReadError::new(format!(
                            "{what} refers to buffer view {view}, but the file has {} buffer views",
                            root.buffer_views.len()
                        ))
                    })?;
                    needed.insert(view.buffer.value());
                }
            }
        }
    }
    // GPU instancing SCALE data only refines the mirrored count: its buffers are loaded if they
    // can be, and a failure is a note.
    let mut optional = BTreeSet::new();
    for instancing in root.extensions.instancing.values() {
        let scale = instancing
            .scale
            .and_then(|a| root.accessors.get(a as usize));
        for view in scale.into_iter().flat_map(accessor::views_of) {
            if let Some(view) = root.buffer_views.get(view) {
                optional.insert(view.buffer.value());
            }
        }
    }
    let mut loaded = Vec::with_capacity(root.buffers.len());
    let location = if container.is_glb && root.buffers.iter().all(|b| b.uri.is_none()) {
        None // a self-contained GLB needs no file system lookups
    } else {
        Some(buffers::Location::new(path, &cx.root)?)
    };
    let files = buffers::Files::read(
        &root.buffers,
        &needed,
        also,
        &optional,
        location.as_ref(),
        &cx.limits,
    )?;
    for (index, buffer) in root.buffers.iter().enumerate() {
        let load = || buffers::load(index, buffer, container.bin, container.is_glb, &files);
        if needed.contains(&index) {
            loaded.push(Some(load()?));
        } else {
            // A URI no mesh reads is still refused if it points outside the tree (checked
            // lexically, nothing is touched); a missing file there is not our concern.
            if let (Some(uri), Some(location)) = (&buffer.uri, &location) {
                if !uri
                    .get(..5)
                    .is_some_and(|s| s.eq_ignore_ascii_case("data:"))
                {
                    buffers::check(uri, location)?;
                }
            }
            loaded.push(optional.contains(&index).then(load).and_then(Result::ok));
        }
    }
    let data = Data {
        root: &root,
        buffer_bytes: files.bytes_behind(&loaded),
        buffers: loaded,
        limits: &cx.limits,
    };
    let instances = instance_signs(&data, &mut notes);
    let mirrored = nodes::mirrored_instances(&root, &instances)?;

    let mut scratch = Vec::new();
    let mut totals = Totals::default();
    let mut meshes = root
        .meshes
        .iter()
        .zip(notes)
        .enumerate()
        .map(|(m, (mesh, notes))| {
            let mut out = read_mesh(&data, mesh, m, &mut scratch, &mut totals)?;
            out.mirrored_instances = mirrored[m];
            out.notes.splice(0..0, notes);
            Ok(out)
        })
        .collect::<Result<Vec<Mesh>, ReadError>>()?;
    // Two meshes named `Part` (or one named `#1` and the unnamed mesh 1) get their index.
    super::distinct_names(&mut meshes, |m| format!("#{m}"));
    Ok((meshes, files))
}

/// Refuses a triangle primitive whose data is compressed by an extension meshvet cannot decode
/// (`KHR_draco_mesh_compression` on the primitive, `EXT_meshopt_compression` or
/// `KHR_meshopt_compression` on a buffer view it reads), even when the file does not list the
/// extension as required: its accessors would read as zeros or as a placeholder buffer. When the
/// uncompressed fallback the extensions allow is there, it is read, with a note.
fn check_compression(
    root: &container::Model,
    is_glb: bool,
    notes: &mut [Vec<String>],
) -> Result<(), ReadError> {
    let extensions = &root.extensions;
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let Some((position, indices)) = triangle_accessors(primitive) else {
                continue;
            };
            let what = primitive_name(mesh, m, p);
            // Accessors that do not exist are reported when the buffers are chosen.
            let accessors: Vec<&json::Accessor> = std::iter::once(position)
                .chain(indices)
                .filter_map(|a| root.accessors.get(a))
                .collect();
            if extensions.draco.contains(&(m, p)) {
                if accessors.iter().any(|a| a.buffer_view.is_none()) {
                    return Err(ReadError::new(format!(
                        "{what} is compressed with KHR_draco_mesh_compression, which meshvet cannot decode: export without Draco compression"
                    )));
                }
                notes[m].push(format!(
                    "primitive {p} is also compressed with KHR_draco_mesh_compression; its uncompressed fallback data was read"
                ));
            }
            let views: BTreeSet<usize> = accessors
                .iter()
                .flat_map(|a| accessor::views_of(a))
                .collect();
            for view in views {
                let Some(name) = extensions.meshopt_views.get(&view) else {
                    continue;
                };
                let placeholder = root.buffer_views.get(view).is_none_or(|v| {
                    let b = v.buffer.value();
                    extensions.fallback_buffers.contains(&b)
                        || root
                            .buffers
                            .get(b)
                            .is_some_and(|buffer| buffer.uri.is_none() && !(is_glb && b == 0))
                });
                if placeholder {
                    return Err(ReadError::new(format!(
                        "{what} reads buffer view {view}, compressed with {name}, which meshvet cannot decode: export without meshopt compression"
                    )));
                }
                notes[m].push(format!(
                    "primitive {p} reads buffer view {view}, also compressed with {name}; its uncompressed fallback data was read"
                ));
            }
        }
    }
    Ok(())
}

/// For each node with `EXT_mesh_gpu_instancing`, its instances by the sign of their SCALE. A
/// SCALE that cannot be read leaves the node's instances unscaled, with a note on its mesh.
fn instance_signs(
    data: &Data<'_>,
    notes: &mut [Vec<String>],
) -> BTreeMap<usize, nodes::InstanceSigns> {
    let root = data.root;
    let mut out = BTreeMap::new();
    for (&n, instancing) in &root.extensions.instancing {
        let count = instancing
            .attributes
            .iter()
            .filter_map(|&a| root.accessors.get(a as usize))
            .map(|a| a.count.0)
            .max()
            .unwrap_or(0);
        let unscaled = nodes::InstanceSigns {
            positive: u32::try_from(count).unwrap_or(u32::MAX),
            negative: 0,
        };
        let signs = match instancing.scale {
            None => unscaled,
            Some(a) => scale_signs(data, a, n).unwrap_or_else(|e| {
                let mesh = root.nodes.get(n).and_then(|node| node.mesh);
                if let Some(list) = mesh.and_then(|mesh| notes.get_mut(mesh.value())) {
                    list.push(format!(
                        "node {n}: the EXT_mesh_gpu_instancing SCALE could not be read ({e}); its instances were counted as not mirrored by their scale"
                    ));
                }
                unscaled
            }),
        };
        out.insert(n, signs);
    }
    out
}

/// The signs of the SCALE products of one instancing node (FLOAT, or normalized BYTE or SHORT,
/// VEC3, as the extension allows).
fn scale_signs(data: &Data<'_>, index: u64, node: usize) -> Result<nodes::InstanceSigns, String> {
    let what = format!("node {node} instancing SCALE");
    let accessor = usize::try_from(index)
        .ok()
        .and_then(|i| data.root.accessors.get(i))
        .ok_or_else(|| format!("accessor {index} does not exist"))?;
    let component = match (accessor.type_, accessor.component_type) {
        (Checked::Valid(Type::Vec3), Checked::Valid(GenericComponentType(c)))
            if matches!(
                c,
                ComponentType::F32 | ComponentType::I8 | ComponentType::I16
            ) =>
        {
            c
        }
        _ => return Err("it is not a FLOAT, BYTE or SHORT VEC3 accessor".into()),
    };
    for view in accessor::views_of(accessor) {
        let buffer = data.root.buffer_views.get(view).map(|v| v.buffer.value());
        if !buffer.is_some_and(|b| matches!(data.buffers.get(b), Some(Some(_)))) {
            return Err(format!(
                "the buffer of buffer view {view} could not be loaded"
            ));
        }
    }
    let size = component.size();
    let raw = data
        .raw(accessor, 3 * size, &what)
        .map_err(|e| e.to_string())?;
    let sign = |b: &[u8]| -> i8 {
        let v = match component {
            ComponentType::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            ComponentType::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            _ => f64::from(b[0] as i8),
        };
        if v > 0.0 {
            1
        } else if v < 0.0 {
            -1
        } else {
            0 // zero or NaN: flat or broken, not mirrored
        }
    };
    let mut signs = nodes::InstanceSigns::default();
    for instance in raw.chunks_exact(3 * size) {
        let product: i8 = instance.chunks_exact(size).map(sign).product();
        match product {
            1 => signs.positive = signs.positive.saturating_add(1),
            -1 => signs.negative = signs.negative.saturating_add(1),
            _ => {}
        }
    }
    Ok(signs)
}

/// What the meshes of one file have decoded so far: the limits hold for the file as a whole, so
/// many meshes or primitives reusing one accessor cannot multiply a small file into N x the limit.
#[derive(Default)]
struct Totals {
    vertices: u64,
    triangles: u64,
    /// Bytes of zeros expanded from accessors without a buffer view.
    unbacked: u64,
}

/// The POSITION accessor and indices accessor of a triangle primitive; `None` for other modes
/// (and invalid modes, reported when the mesh is read) or a primitive without positions.
fn triangle_accessors(primitive: &json::mesh::Primitive) -> Option<(usize, Option<usize>)> {
    match primitive.mode {
        Checked::Valid(Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) => {}
        _ => return None,
    }
    let position = position_accessor(primitive)?;
    Some((position, primitive.indices.map(|i| i.value())))
}

fn position_accessor(primitive: &json::mesh::Primitive) -> Option<usize> {
    primitive
        .attributes
        .iter()
        .find_map(|(semantic, accessor)| {
            matches!(semantic, Checked::Valid(Semantic::Positions)).then(|| accessor.value())
        })
}

fn mesh_name(mesh: &json::Mesh, index: usize) -> String {
    mesh.name.clone().unwrap_or_else(|| format!("#{index}"))
}

fn primitive_name(mesh: &json::Mesh, m: usize, p: usize) -> String {
    match &mesh.name {
        Some(name) => format!("mesh \"{name}\" (#{m}) primitive {p}"),
        None => format!("mesh #{m} primitive {p}"),
    }
}

/// Reads one glTF mesh: each triangle primitive's vertices appended, its indices offset.
fn read_mesh(
    data: &Data<'_>,
    mesh: &json::Mesh,
    m: usize,
    indices: &mut Vec<u32>,
    totals: &mut Totals,
) -> Result<Mesh, ReadError> {
    let limits = data.limits;
    let mut out = Mesh {
        name: Some(mesh_name(mesh, m)),
        ..Mesh::default()
    };
    let mut skipped: [usize; 4] = [0; 4]; // POINTS, LINES, LINE_LOOP, LINE_STRIP
    let mut without_positions = 0usize;
    for (p, primitive) in mesh.primitives.iter().enumerate() {
        let what = primitive_name(mesh, m, p);
        let mode = match primitive.mode {
            Checked::Valid(mode) => mode,
            Checked::Invalid => {
                return Err(ReadError::new(format!(
                    "{what} has an invalid mode (glTF modes are 0 to 6)"
                )))
            }
        };
        match mode {
            Mode::Points => skipped[0] += 1,
            Mode::Lines => skipped[1] += 1,
            Mode::LineLoop => skipped[2] += 1,
            Mode::LineStrip => skipped[3] += 1,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => {}
        }
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            continue;
        }
        let Some(position) = position_accessor(primitive) else {
            without_positions += 1;
            continue;
        };

        let position = accessor::get(data.root, position, &what)?;
        if position.count.0 > limits.max_triangles {
            return Err(over_limit(
                &what,
                "vertices",
                position.count.0,
                limits.max_triangles,
            ));
        }
        let file_vertices = totals.vertices.saturating_add(position.count.0);
        if file_vertices > limits.max_triangles {
            return Err(over_file_limit(
                &what,
                "vertices",
                file_vertices,
                limits.max_triangles,
            ));
        }
        unbacked(data, position, 12, totals, &what)?;
        let base = out.positions.len();
        data.append_positions(position, &mut out.positions, &what)?;
        totals.vertices = file_vertices;
        let vertices = out.positions.len() - base;
        if u32::try_from(out.positions.len()).is_err()
            || out.positions.len() as u64 > limits.max_triangles
        {
            return Err(over_limit(
                &mesh_name(mesh, m),
                "vertices",
                out.positions.len() as u64,
                limits.max_triangles,
            ));
        }

        let corners = match primitive.indices {
            Some(i) => {
                let accessor = accessor::get(data.root, i.value(), &what)?;
                let size = match accessor.component_type {
                    Checked::Valid(GenericComponentType(c)) => c.size(),
                    Checked::Invalid => 4,
                };
                unbacked(data, accessor, size, totals, &what)?;
                data.read_indices(accessor, indices, &what)?;
                if let Some((k, &bad)) = indices
                    .iter()
                    .enumerate()
                    .find(|(_, &v)| v as usize >= vertices)
                {
                    return Err(ReadError::new(format!(
                        "{what}: index {bad} (at position {k}) is out of range: the primitive has {vertices} vertices"
                    )));
                }
                Some(indices.as_slice())
            }
            None => None,
        };
        let n = corners.map_or(vertices, <[u32]>::len);
        let triangles = match mode {
            Mode::Triangles => n / 3,
            _ => n.saturating_sub(2),
        };
        let total = out.triangles.len() as u64 + triangles as u64;
        if total > limits.max_triangles {
            return Err(over_limit(
                &mesh_name(mesh, m),
                "triangles",
                total,
                limits.max_triangles,
            ));
        }
        let file_triangles = totals.triangles.saturating_add(triangles as u64);
        if file_triangles > limits.max_triangles {
            return Err(over_file_limit(
                &what,
                "triangles",
                file_triangles,
                limits.max_triangles,
            ));
        }
        totals.triangles = file_triangles;
        if mode == Mode::Triangles && n % 3 != 0 {
            out.notes.push(format!(
                "primitive {p}: {} vertex references after the last whole triangle were ignored",
                n % 3
            ));
        }
        let base = base as u32; // fits: out.positions.len() fits in u32 (checked above)
        let corner = |k: usize| base + corners.map_or(k as u32, |c| c[k]);
        out.triangles.reserve(triangles);
        match mode {
            Mode::Triangles => out.triangles.extend(
                (0..triangles).map(|t| [corner(3 * t), corner(3 * t + 1), corner(3 * t + 2)]),
            ),
            // glTF 2.0 3.7.2.1: strip triangle i is (i, i+1+i%2, i+2-i%2), fan triangle i is (i+1, i+2, 0).
            Mode::TriangleStrip => out.triangles.extend(
                (0..triangles).map(|i| [corner(i), corner(i + 1 + i % 2), corner(i + 2 - i % 2)]),
            ),
            _ => out
                .triangles
                .extend((0..triangles).map(|i| [corner(i + 1), corner(i + 2), corner(0)])),
        }
    }

    let names = ["POINTS", "LINES", "LINE_LOOP", "LINE_STRIP"];
    let skipped: Vec<String> = skipped
        .iter()
        .zip(names)
        .filter(|(&n, _)| n > 0)
        .map(|(n, name)| format!("{n} {name}"))
        .collect();
    if !skipped.is_empty() {
        out.notes.push(format!(
            "skipped primitives that are not triangles: {}",
            skipped.join(", ")
        ));
    }
    if without_positions > 0 {
        out.notes.push(format!(
            "skipped {without_positions} primitive(s) with no POSITION attribute"
        ));
    }
    Ok(out)
}

fn over_file_limit(what: &str, unit: &str, count: u64, limit: u64) -> ReadError {
    ReadError::new(format!(
        "{what} brings the meshes of this file to {count} {unit} in all, over the limit of {limit} per file (a mesh or primitive that reuses an accessor counts it again): raise limits.max_triangles in the config to read it"
    ))
}

/// Adds an accessor without a buffer view to the file's expanded zeros, which together may not
/// exceed what the input can describe (the per-accessor rule of [`Data::check_unbacked`], for
/// the file as a whole).
fn unbacked(
    data: &Data<'_>,
    accessor: &json::Accessor,
    size: usize,
    totals: &mut Totals,
    what: &str,
) -> Result<(), ReadError> {
    if accessor.buffer_view.is_some() {
        return Ok(());
    }
    data.check_unbacked(accessor.count.0, size, what)?;
    let bytes = accessor.count.0.saturating_mul(size as u64);
    totals.unbacked = totals.unbacked.saturating_add(bytes);
    let input = data.input_bytes();
    if totals.unbacked > input.saturating_mul(accessor::UNBACKED_PER_INPUT_BYTE) {
        return Err(ReadError::new(format!(
            "{what}: the accessors without a buffer view of this file expand to {} bytes of zeros, far more than its {input} bytes of JSON and buffers can describe: their data is missing (compressed by an extension meshvet cannot decode?) - fix or re-export the file",
            totals.unbacked
        )));
    }
    Ok(())
}

fn over_limit(what: &str, unit: &str, count: u64, limit: u64) -> ReadError {
    ReadError::new(format!(
        "{what} has {count} {unit}, over the limit of {limit}: raise limits.max_triangles in the config to read it"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_a_read_error() {
        let err = guard::<()>(|| panic!("boom {}", 7)).unwrap_err();
        assert!(
            err.0.contains("crashed") && err.0.contains("boom 7"),
            "{err}"
        );
        assert_eq!(guard(|| Ok(3)), Ok(3));
    }
}
