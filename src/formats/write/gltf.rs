//! Repaired glTF / GLB. The document is edited as plain JSON (`serde_json::Value`), so every part
//! the repair does not touch (nodes, materials, textures, images, animations, skins, extras,
//! unknown extensions, other meshes and primitives) is written back as it was. Each triangle
//! primitive of a repaired mesh gets new accessors for every attribute it has (POSITION, NORMAL,
//! TANGENT, TEXCOORD_n, COLOR_n, JOINTS_n, WEIGHTS_n, custom ones and morph targets: a vertex copy
//! duplicates its vertex's values), new indices (mode TRIANGLES) and keeps its material. A hole
//! fill goes to its neighbour's primitive; a vertex it borrows from another primitive is copied
//! with the attributes both primitives have (others zero). Normals that disagree with a flipped
//! face are negated, with their tangent's w. A fill's corner whose vertex's normal is far from the
//! fill's own normal takes a copy of the vertex with the fill's normal (its tangent turned into
//! the fill's plane).
//!
//! New data goes into one new buffer: appended to the BIN chunk of a GLB, or a `.bin` beside a
//! `.gltf` copy (a `data:` URI when the source embeds all its buffers). External buffers and
//! images the copy refers to are copied next to it, so the copy opens where it is written, under
//! names claimed in the copy's final folder ([`super::names`]): a file of the same name but other
//! bytes there, or brought by another copy, makes it `name-1.ext`.
//! Old accessors stay in the document unused.

use std::borrow::Cow;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use gltf::json;
use gltf::json::accessor::{ComponentType, GenericComponentType, Type};
use gltf::json::mesh::Mode;
use gltf::json::validation::Checked;
use gltf::json::Value;
use rustc_hash::FxHashMap;
use serde_json::json;

use super::names::Claims;
use super::{fill_normals, normal_sums, write_atomic, Job, NormalCopies, WriteError, Written};
use crate::formats::gltf::accessor::{component_name, type_name, Data};
use crate::formats::gltf::buffers::{self, Location};
use crate::formats::gltf::container;
use crate::formats::ReadContext;
use crate::geometry::dot;
use crate::mesh::Mesh;
use crate::repair::Plan;

/// Writes the copy and, beside it, the buffers and images it names.
pub fn write(job: Job<'_>) -> Result<Written, WriteError> {
    let (source, plans, out, cx, claims) = (job.source, job.plans, job.out, job.cx, job.claims);
    let scanned = job.read.as_ref().map(|r| r.meshes);
    let side = crate::caught(|| write_unguarded(source, plans, out, cx, claims, scanned))
        .unwrap_or_else(|panic| {
            Err(WriteError::new(format!(
                "the glTF writer crashed on this file ({panic}): please report it"
            )))
        })?;
    Ok(job.written(side, Vec::new()))
}

fn bad(what: impl Into<String>) -> WriteError {
    WriteError::new(what)
}

fn write_unguarded(
    source: &Path,
    plans: &[Option<Plan>],
    out: &Path,
    cx: &ReadContext,
    claims: &Claims,
    scanned: Option<&[Mesh]>,
) -> Result<Vec<PathBuf>, WriteError> {
    let bytes = crate::formats::read_bytes(source, &cx.limits)?;
    let container = container::split(&bytes)?;
    let model = container::parse_model(container.json)?;
    if plans.len() != model.meshes.len() {
        return Err(bad(format!(
            "the file has {} meshes but {} plans were given",
            model.meshes.len(),
            plans.len()
        )));
    }
    let mut doc: Value = serde_json::from_slice(container.json)
        .map_err(|e| bad(format!("invalid glTF JSON: {e}")))?;
    let has_uris = model.buffers.iter().any(|b| b.uri.is_some())
        || doc["images"]
            .as_array()
            .is_some_and(|a| a.iter().any(|i| i.get("uri").is_some()));
    let location = if has_uris {
        Some(Location::new(source, &cx.root)?)
    } else {
        None
    };

    // Every buffer the repaired meshes read, their files each read once (as the reader does).
    let mut needed = BTreeSet::new();
    for (m, plan) in plans.iter().enumerate() {
        if plan.is_none() {
            continue;
        }
        for primitive in &model.meshes[m].primitives {
            let targets = primitive.targets.iter().flatten().flat_map(|t| {
                [t.positions, t.normals, t.tangents]
                    .into_iter()
                    .flatten()
                    .map(|i| i.value())
            });
            let accessors = primitive
                .attributes
                .values()
                .map(|i| i.value())
                .chain(primitive.indices.map(|i| i.value()))
                .chain(targets);
            for a in accessors {
                let accessor = model
                    .accessors
                    .get(a)
                    .ok_or_else(|| bad(format!("accessor {a} is missing")))?;
                for view in crate::formats::gltf::accessor::views_of(accessor) {
                    let view = model
                        .buffer_views
                        .get(view)
                        .ok_or_else(|| bad(format!("buffer view {view} is missing")))?;
                    needed.insert(view.buffer.value());
                }
            }
        }
    }
    // The meshes and every buffer the copy reads, from the bytes above and one read of each
    // buffer file: what is compared with the scan's meshes is what is copied.
    let (meshes, files) = crate::formats::gltf::read_from(&bytes, source, cx, &needed)?;
    super::unchanged(scanned, &meshes)?;
    let mut loaded: Vec<Option<Cow<'_, [u8]>>> = vec![None; model.buffers.len()];
    for &b in &needed {
        if let Some(buffer) = model.buffers.get(b) {
            loaded[b] = Some(buffers::load(
                b,
                buffer,
                container.bin,
                container.is_glb,
                &files,
            )?);
        }
    }
    let data = Data {
        root: &model,
        buffer_bytes: files.bytes_behind(&loaded),
        buffers: loaded,
        limits: &cx.limits,
    };

    // Where new data goes: buffer `target`, from byte `base`.
    let glb = container.is_glb;
    let mut bin: Vec<u8> = container.bin.map(<[u8]>::to_vec).unwrap_or_default();
    let (target, base) = if glb {
        let first_is_bin = doc["buffers"]
            .get(0)
            .is_some_and(|b| b.get("uri").is_none());
        if !first_is_bin {
            // The BIN chunk must be buffer 0: shift every buffer reference by one.
            if let Some(views) = doc.get_mut("bufferViews").and_then(Value::as_array_mut) {
                for view in views {
                    if let Some(b) = view["buffer"].as_u64() {
                        view["buffer"] = json!(b + 1);
                    }
                }
            }
            let buffers = doc["buffers"].as_array().cloned().unwrap_or_default();
            let mut shifted = vec![json!({"byteLength": 0})];
            shifted.extend(buffers);
            doc["buffers"] = Value::Array(shifted);
            bin.clear();
        }
        let declared = doc["buffers"][0]["byteLength"].as_u64().unwrap_or(0) as usize;
        (0usize, align4(declared.max(bin.len())))
    } else {
        (model.buffers.len(), 0)
    };
    let mut writer = NewData {
        bytes: Vec::new(),
        base,
        target,
        views: Vec::new(),
        accessors: Vec::new(),
        first_view: doc["bufferViews"].as_array().map_or(0, Vec::len),
        first_accessor: doc["accessors"].as_array().map_or(0, Vec::len),
    };
    for (m, plan) in plans.iter().enumerate() {
        let Some(plan) = plan else { continue };
        rewrite_mesh(&mut doc, &model, &data, &meshes[m], m, plan, &mut writer)?;
    }

    // Append the new views and accessors, then the buffer.
    let NewData {
        bytes: new,
        views,
        accessors,
        ..
    } = writer;
    extend(&mut doc, "bufferViews", views);
    extend(&mut doc, "accessors", accessors);
    let mut written = Vec::new();
    if let Some(location) = &location {
        written.extend(copy_external(&mut doc, location, out, claims, &files)?);
    }
    if glb {
        if !new.is_empty() {
            bin.resize(base, 0);
            bin.extend_from_slice(&new);
            doc["buffers"][0]["byteLength"] = json!(bin.len());
        }
    } else if !new.is_empty() {
        let embedded = model.buffers.iter().all(|b| {
            b.uri
                .as_deref()
                .is_some_and(|u| u.get(..5).is_some_and(|s| s.eq_ignore_ascii_case("data:")))
        });
        let uri = if embedded {
            format!(
                "data:application/octet-stream;base64,{}",
                base64::engine::general_purpose::STANDARD.encode(&new)
            )
        } else {
            let stem = out
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let wanted = format!("{stem}.repaired.bin");
            let name = claims
                .side(Path::new(&wanted), &new, true)
                .map_err(|_| claims.no_free_name(&wanted))?;
            let path = out.with_file_name(&name);
            write_atomic(&path, &new)?;
            written.push(path);
            encode_uri(&name.to_string_lossy())
        };
        extend(
            &mut doc,
            "buffers",
            vec![json!({"byteLength": new.len(), "uri": uri})],
        );
    }
    if doc["buffers"].as_array().is_some_and(Vec::is_empty) {
        doc.as_object_mut().map(|o| o.remove("buffers"));
    }

    let json_bytes =
        serde_json::to_vec(&doc).map_err(|e| bad(format!("cannot write the JSON: {e}")))?;
    let file = if glb {
        glb_bytes(&json_bytes, &bin)
    } else {
        json_bytes
    };
    write_atomic(out, &file)?;
    Ok(written)
}

fn extend(doc: &mut Value, key: &str, items: Vec<Value>) {
    if items.is_empty() {
        return;
    }
    match doc.get_mut(key).and_then(Value::as_array_mut) {
        Some(a) => a.extend(items),
        None => doc[key] = Value::Array(items),
    }
}

fn align4(n: usize) -> usize {
    n.div_ceil(4) * 4
}

/// The GLB container: header, JSON chunk (space padded), BIN chunk (zero padded) if any.
fn glb_bytes(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let json_len = align4(json.len());
    let bin_len = align4(bin.len());
    let total = 12 + 8 + json_len + if bin.is_empty() { 0 } else { 8 + bin_len };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    out.extend_from_slice(json);
    out.resize(20 + json_len, b' ');
    if !bin.is_empty() {
        out.extend_from_slice(&(bin_len as u32).to_le_bytes());
        out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
        out.extend_from_slice(bin);
        out.resize(total, 0);
    }
    out
}

/// New buffer views and accessors, and the bytes they point into.
struct NewData {
    bytes: Vec<u8>,
    /// Offset of `bytes` in buffer `target`.
    base: usize,
    target: usize,
    views: Vec<Value>,
    accessors: Vec<Value>,
    first_view: usize,
    first_accessor: usize,
}

impl NewData {
    /// Adds the values of vertex attribute `name` (`count` elements laid out as `v` says) as a view
    /// and accessor, with bounds where glTF requires them (POSITION) or the source had them;
    /// returns the accessor index.
    fn attribute(&mut self, name: &str, bytes: &[u8], v: &ValuesInfo, count: usize) -> usize {
        let b = (name == "POSITION" || v.has_bounds).then(|| bounds(bytes, v.size, v.component));
        self.accessor(
            bytes,
            v.size,
            count,
            component_code(v.component),
            type_name(v.type_),
            v.normalized,
            true,
            b,
        )
    }

    /// Adds `data` (elements of `size` bytes, `count` of them) as a view and accessor; returns the
    /// accessor index. Vertex attributes (`vertex`) get 4-byte aligned elements.
    #[allow(clippy::too_many_arguments)]
    fn accessor(
        &mut self,
        data: &[u8],
        size: usize,
        count: usize,
        component: u32,
        type_: &str,
        normalized: bool,
        vertex: bool,
        bounds: Option<(Value, Value)>,
    ) -> usize {
        let stride = if vertex { align4(size) } else { size };
        let start = align4(self.bytes.len());
        self.bytes.resize(start, 0);
        for i in 0..count {
            self.bytes
                .extend_from_slice(&data[i * size..(i + 1) * size]);
            self.bytes.resize(start + (i + 1) * stride, 0);
        }
        let mut view = json!({
            "buffer": self.target,
            "byteOffset": self.base + start,
            "byteLength": stride * count,
            "target": if vertex { 34962 } else { 34963 },
        });
        if vertex && stride != size {
            view["byteStride"] = json!(stride);
        }
        self.views.push(view);
        let mut accessor = json!({
            "bufferView": self.first_view + self.views.len() - 1,
            "componentType": component,
            "count": count,
            "type": type_,
        });
        if normalized {
            accessor["normalized"] = json!(true);
        }
        if let Some((min, max)) = bounds {
            accessor["min"] = min;
            accessor["max"] = max;
        }
        self.accessors.push(accessor);
        self.first_accessor + self.accessors.len() - 1
    }
}

/// One triangle primitive as the reader numbered it.
struct Part {
    primitive: usize,
    first_vertex: usize,
    vertices: usize,
    first_triangle: usize,
    triangles: usize,
}

/// The attribute values of one accessor, packed.
struct Values {
    bytes: Vec<u8>,
    size: usize,
    component: ComponentType,
    type_: Type,
    normalized: bool,
    has_bounds: bool,
}

fn values(
    data: &Data<'_>,
    model: &container::Model,
    index: usize,
    what: &str,
) -> Result<Values, WriteError> {
    let accessor = model
        .accessors
        .get(index)
        .ok_or_else(|| bad(format!("{what}: accessor {index} is missing")))?;
    let (Checked::Valid(type_), Checked::Valid(GenericComponentType(component))) =
        (accessor.type_, accessor.component_type)
    else {
        return Err(bad(format!("{what}: accessor {index} has an invalid type")));
    };
    let dims = match type_ {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 => 4,
        _ => return Err(bad(format!("{what}: matrix attributes are not supported"))),
    };
    let size = dims * component.size();
    let bytes = data.raw(accessor, size, what)?;
    Ok(Values {
        bytes,
        size,
        component,
        type_,
        normalized: accessor.normalized,
        has_bounds: accessor.min.is_some() || accessor.max.is_some(),
    })
}

fn component_code(c: ComponentType) -> u32 {
    match c {
        ComponentType::I8 => 5120,
        ComponentType::U8 => 5121,
        ComponentType::I16 => 5122,
        ComponentType::U16 => 5123,
        ComponentType::U32 => 5125,
        ComponentType::F32 => 5126,
    }
}

fn decode(c: ComponentType, b: &[u8]) -> f64 {
    match c {
        ComponentType::I8 => b[0] as i8 as f64,
        ComponentType::U8 => b[0] as f64,
        ComponentType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
        ComponentType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
        ComponentType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        ComponentType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
    }
}

/// Per-component min and max of packed elements, as JSON numbers of the component's kind.
fn bounds(bytes: &[u8], size: usize, component: ComponentType) -> (Value, Value) {
    let k = component.size();
    let dims = size / k;
    let mut lo = vec![f64::INFINITY; dims];
    let mut hi = vec![f64::NEG_INFINITY; dims];
    for element in bytes.chunks_exact(size) {
        for d in 0..dims {
            let x = decode(component, &element[d * k..(d + 1) * k]);
            if x.is_finite() {
                lo[d] = lo[d].min(x);
                hi[d] = hi[d].max(x);
            }
        }
    }
    let number = |x: f64| -> Value {
        if component == ComponentType::F32 {
            json!(x)
        } else {
            json!(x as i64)
        }
    };
    (
        Value::Array(lo.into_iter().map(number).collect()),
        Value::Array(hi.into_iter().map(number).collect()),
    )
}

/// Rewrites the triangle primitives of mesh `m` as `plan` says.
#[allow(clippy::too_many_arguments)]
fn rewrite_mesh(
    doc: &mut Value,
    model: &container::Model,
    data: &Data<'_>,
    mesh: &Mesh,
    m: usize,
    plan: &Plan,
    writer: &mut NewData,
) -> Result<(), WriteError> {
    let what = format!("mesh #{m}");
    // The reader's numbering: triangle primitives with positions, in order.
    let mut parts = Vec::new();
    let (mut vertices, mut triangles) = (0usize, 0usize);
    for (p, primitive) in model.meshes[m].primitives.iter().enumerate() {
        let mode = match primitive.mode {
            Checked::Valid(mode @ (Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)) => {
                mode
            }
            _ => continue,
        };
        let Some(position) = primitive.attributes.iter().find_map(|(s, a)| {
            matches!(s, Checked::Valid(json::mesh::Semantic::Positions)).then(|| a.value())
        }) else {
            continue;
        };
        let count = model
            .accessors
            .get(position)
            .map_or(0, |a| a.count.0 as usize);
        let n = match primitive.indices {
            Some(i) => model
                .accessors
                .get(i.value())
                .map_or(0, |a| a.count.0 as usize),
            None => count,
        };
        let t = if mode == Mode::Triangles {
            n / 3
        } else {
            n.saturating_sub(2)
        };
        parts.push(Part {
            primitive: p,
            first_vertex: vertices,
            vertices: count,
            first_triangle: triangles,
            triangles: t,
        });
        vertices += count;
        triangles += t;
    }
    if vertices != mesh.positions.len() || triangles != mesh.triangles.len() {
        return Err(bad(format!("{what}: the primitives do not add up to what the reader read (internal error: please report this file)")));
    }
    let origin = |v: u32| super::original(plan, mesh, v) as usize;
    let part_of_triangle =
        |t: u32| parts.partition_point(|p| p.first_triangle + p.triangles <= t as usize);

    let mut referenced_anywhere = vec![false; plan.used_vertices.len()];
    let mut faces_of: Vec<Vec<usize>> = vec![Vec::new(); parts.len()];
    for (i, t) in plan.triangles.iter().enumerate() {
        faces_of[part_of_triangle(t.near)].push(i);
        for c in &t.corners {
            referenced_anywhere[c.vertex as usize] = true;
        }
    }
    let sums = normal_sums(plan, mesh, |c| Some(c.vertex));
    let holes = fill_normals(plan, mesh);

    let mut empty = Vec::new();
    for (k, part) in parts.iter().enumerate() {
        let faces = &faces_of[k];
        if faces.is_empty() {
            empty.push(part.primitive);
            continue;
        }
        // Output vertices: this primitive's own (referenced here, or kept unreferenced), then
        // copies and borrowed vertices in plan order.
        let mut local: FxHashMap<u32, u32> = FxHashMap::default();
        let mut order: Vec<u32> = Vec::new();
        let mut here = vec![false; plan.used_vertices.len()];
        for &i in faces {
            for c in &plan.triangles[i].corners {
                here[c.vertex as usize] = true;
            }
        }
        for v in part.first_vertex..part.first_vertex + part.vertices {
            if here[v] || (plan.used_vertices[v] && !referenced_anywhere[v]) {
                local.insert(v as u32, order.len() as u32);
                order.push(v as u32);
            }
        }
        // New vertices first, then input vertices of other primitives (fills borrow them).
        let n = mesh.positions.len();
        let others = (n..here.len()).chain(0..n);
        for v in others.filter(|&v| here[v]) {
            if let std::collections::hash_map::Entry::Vacant(e) = local.entry(v as u32) {
                e.insert(order.len() as u32);
                order.push(v as u32);
            }
        }

        let pwhat = format!("{what} primitive {}", part.primitive);
        // Attribute names as the file writes them (custom `_NAME`s included).
        let names: Vec<(String, usize)> = doc["meshes"][m]["primitives"][part.primitive]
            ["attributes"]
            .as_object()
            .map(|o| {
                o.iter()
                    .filter_map(|(k, v)| Some((k.clone(), v.as_u64()? as usize)))
                    .collect()
            })
            .unwrap_or_default();
        let mut cache: FxHashMap<usize, Values> = FxHashMap::default();
        // A fill's corner whose vertex's normal is far from the fill's own normal gets a copy of
        // its vertex with the fill's normal (glTF's attributes are per vertex), one per vertex and
        // direction: `own_normals` are the copies' places in `order` with their normals, and
        // `fill_corner` sends a fill's corner (plan triangle and corner) to its copy.
        let mut own_normals: Vec<(usize, [f64; 3])> = Vec::new();
        let mut fill_corner: FxHashMap<(usize, usize), u32> = FxHashMap::default();
        // Attribute `name` (at `accessor` here) of the vertices of `order`.
        let gather_attribute =
            |cache: &mut FxHashMap<usize, Values>, accessor: usize, order: &[u32], name: &str| {
                gather(
                    data,
                    model,
                    cache,
                    accessor,
                    order,
                    k,
                    &parts,
                    &origin,
                    &pwhat,
                    |model, p| attribute_of(model, m, p, name),
                )
            };
        if let Some((_, accessor)) = names.iter().find(|(name, _)| name == "NORMAL") {
            let (bytes, v) = gather_attribute(&mut cache, *accessor, &order, "NORMAL")?;
            if v.component == ComponentType::F32 && v.type_ == Type::Vec3 {
                let stored = |vertex: u32| {
                    let at = local[&vertex] as usize;
                    [0, 1, 2].map(|d| decode(ComponentType::F32, &bytes[12 * at + 4 * d..]))
                };
                let copies = NormalCopies::new(plan, &holes, faces.iter().copied(), &sums, stored);
                let first = order.len();
                for &(vertex, n) in &copies.copies {
                    own_normals.push((order.len(), n));
                    order.push(vertex);
                }
                for (&corner, &place) in &copies.corners {
                    fill_corner.insert(corner, (first + place) as u32);
                }
            }
        }
        let mut negated = vec![false; order.len()];
        let mut attributes = serde_json::Map::new();
        // NORMAL before TANGENT: the tangent's w follows the normal.
        let mut sorted = names.clone();
        sorted.sort_by_key(|(name, _)| match name.as_str() {
            "NORMAL" => 0,
            "TANGENT" => 1,
            _ => 2,
        });
        for (name, accessor) in &sorted {
            let gathered = gather_attribute(&mut cache, *accessor, &order, name)?;
            let (mut bytes, v) = gathered;
            if name == "POSITION" {
                if v.component != ComponentType::F32 || v.type_ != Type::Vec3 {
                    return Err(bad(format!(
                        "{pwhat}: POSITION is {} {}, and a repaired copy is written with float \
                         positions only (quantized positions, KHR_mesh_quantization, are not \
                         decoded): {}",
                        component_name(v.component),
                        type_name(v.type_),
                        crate::formats::gltf::DEQUANTIZE
                    )));
                }
                for (i, &vertex) in order.iter().enumerate() {
                    let p = plan.position(mesh, vertex);
                    for d in 0..3 {
                        bytes[12 * i + 4 * d..12 * i + 4 * d + 4]
                            .copy_from_slice(&(p[d] as f32).to_le_bytes());
                    }
                }
            }
            if name == "NORMAL" && v.component == ComponentType::F32 && v.type_ == Type::Vec3 {
                for (i, vertex) in order.iter().enumerate() {
                    let Some(sum) = sums.get(vertex) else {
                        continue;
                    };
                    let n = [0, 1, 2].map(|d| decode(ComponentType::F32, &bytes[12 * i + 4 * d..]));
                    if dot(n, *sum) < 0.0 {
                        negated[i] = true;
                        for d in 0..3 {
                            bytes[12 * i + 4 * d..12 * i + 4 * d + 4]
                                .copy_from_slice(&(-n[d] as f32).to_le_bytes());
                        }
                    }
                }
            }
            if name == "NORMAL" && v.component == ComponentType::F32 && v.type_ == Type::Vec3 {
                for &(i, n) in &own_normals {
                    for d in 0..3 {
                        bytes[12 * i + 4 * d..12 * i + 4 * d + 4]
                            .copy_from_slice(&(n[d] as f32).to_le_bytes());
                    }
                }
            }
            if name == "TANGENT" && v.component == ComponentType::F32 && v.type_ == Type::Vec4 {
                for (i, _) in negated.iter().enumerate().filter(|(_, &n)| n) {
                    let w = decode(ComponentType::F32, &bytes[16 * i + 12..]);
                    bytes[16 * i + 12..16 * i + 16].copy_from_slice(&(-w as f32).to_le_bytes());
                }
                // A copy's tangent turned into the plane of its new normal, its handedness (w)
                // as its vertex's is written.
                for &(i, n) in &own_normals {
                    let t = [0, 1, 2].map(|d| decode(ComponentType::F32, &bytes[16 * i + 4 * d..]));
                    for d in 0..3 {
                        bytes[16 * i + 4 * d..16 * i + 4 * d + 4]
                            .copy_from_slice(&(tangent_across(t, n)[d] as f32).to_le_bytes());
                    }
                }
            }
            let index = writer.attribute(name, &bytes, &v, order.len());
            attributes.insert(name.clone(), json!(index));
        }

        // Morph targets: each target's attributes gathered the same way.
        let mut targets = Vec::new();
        if let Some(list) = doc["meshes"][m]["primitives"][part.primitive]["targets"]
            .as_array()
            .cloned()
        {
            for (ti, target) in list.iter().enumerate() {
                let mut out = serde_json::Map::new();
                for (name, accessor) in target.as_object().into_iter().flatten() {
                    let Some(accessor) = accessor.as_u64() else {
                        continue;
                    };
                    let (mut bytes, v) = gather(
                        data,
                        model,
                        &mut cache,
                        accessor as usize,
                        &order,
                        k,
                        &parts,
                        &origin,
                        &pwhat,
                        |model, p| target_of(model, m, p, ti, name),
                    )?;
                    if name == "NORMAL"
                        && v.component == ComponentType::F32
                        && v.type_ == Type::Vec3
                    {
                        for (i, _) in negated.iter().enumerate().filter(|(_, &n)| n) {
                            for d in 0..3 {
                                let x = decode(ComponentType::F32, &bytes[12 * i + 4 * d..]);
                                bytes[12 * i + 4 * d..12 * i + 4 * d + 4]
                                    .copy_from_slice(&(-x as f32).to_le_bytes());
                            }
                        }
                    }
                    // A copy with a fill's own normal does not bend with its vertex's morphs.
                    if (name == "NORMAL" || name == "TANGENT")
                        && v.component == ComponentType::F32
                        && v.type_ == Type::Vec3
                    {
                        for &(i, _) in &own_normals {
                            bytes[12 * i..12 * i + 12].fill(0);
                        }
                    }
                    let index = writer.attribute(name, &bytes, &v, order.len());
                    out.insert(name.clone(), json!(index));
                }
                targets.push(Value::Object(out));
            }
        }

        // Indices.
        let wide = order.len() >= 65535;
        let mut index_bytes = Vec::with_capacity(faces.len() * 3 * if wide { 4 } else { 2 });
        for &i in faces {
            for (j, c) in plan.triangles[i].corners.iter().enumerate() {
                let v = fill_corner
                    .get(&(i, j))
                    .copied()
                    .unwrap_or_else(|| local[&c.vertex]);
                if wide {
                    index_bytes.extend_from_slice(&v.to_le_bytes());
                } else {
                    index_bytes.extend_from_slice(&(v as u16).to_le_bytes());
                }
            }
        }
        let (size, code) = if wide { (4, 5125) } else { (2, 5123) };
        let indices = writer.accessor(
            &index_bytes,
            size,
            faces.len() * 3,
            code,
            "SCALAR",
            false,
            false,
            None,
        );

        // In the file's own order.
        let attributes: serde_json::Map<String, Value> = names
            .iter()
            .filter_map(|(name, _)| Some((name.clone(), attributes.get(name)?.clone())))
            .collect();
        let p = &mut doc["meshes"][m]["primitives"][part.primitive];
        p["attributes"] = Value::Object(attributes);
        p["indices"] = json!(indices);
        if let Some(o) = p.as_object_mut() {
            o.remove("mode");
        }
        if !targets.is_empty() {
            p["targets"] = Value::Array(targets);
        }
    }
    if !empty.is_empty() {
        let primitives = doc["meshes"][m]["primitives"]
            .as_array_mut()
            .ok_or_else(|| bad("no primitives"))?;
        let kept: Vec<Value> = primitives
            .iter()
            .enumerate()
            .filter(|(p, _)| !empty.contains(p))
            .map(|(_, v)| v.clone())
            .collect();
        if kept.is_empty() {
            return Err(bad(format!("{what}: the repair leaves no triangles")));
        }
        *primitives = kept;
    }
    Ok(())
}

/// Tangent `t` turned into the plane across unit normal `n` (its part along `n` removed), unit
/// length; a tangent along `n` (or none) is replaced by a unit vector across `n`.
fn tangent_across(t: [f64; 3], n: [f64; 3]) -> [f64; 3] {
    let along = dot(t, n);
    let across = [0, 1, 2].map(|d| t[d] - along * n[d]);
    let length = dot(across, across).sqrt();
    if length > 1e-6 && length.is_finite() {
        return across.map(|x| x / length);
    }
    // n times the axis it is least along.
    let least = (0..3).fold(0, |m, d| if n[d].abs() < n[m].abs() { d } else { m });
    let mut axis = [0.0; 3];
    axis[least] = 1.0;
    let u = crate::geometry::cross(n, axis);
    let length = dot(u, u).sqrt();
    u.map(|x| x / length)
}

/// The accessor of attribute `name` of primitive `p` of mesh `m`.
fn attribute_of(model: &container::Model, m: usize, p: usize, name: &str) -> Option<usize> {
    model.meshes[m].primitives[p]
        .attributes
        .iter()
        .find(|(s, _)| semantic_name(s).as_deref() == Some(name))
        .map(|(_, a)| a.value())
}

fn target_of(model: &container::Model, m: usize, p: usize, t: usize, name: &str) -> Option<usize> {
    let target = model.meshes[m].primitives[p].targets.as_ref()?.get(t)?;
    match name {
        "POSITION" => target.positions,
        "NORMAL" => target.normals,
        "TANGENT" => target.tangents,
        _ => None,
    }
    .map(|a| a.value())
}

fn semantic_name(s: &Checked<json::mesh::Semantic>) -> Option<String> {
    match s {
        Checked::Valid(s) => Some(s.to_string()),
        Checked::Invalid => None,
    }
}

/// The values of one attribute for the output vertices `order`: a vertex of this primitive (part
/// `own`) takes its own, a vertex of another primitive that primitive's value of the same
/// attribute (same type), zeros when it has none. `origin` is the input vertex a vertex copies.
#[allow(clippy::too_many_arguments)]
fn gather(
    data: &Data<'_>,
    model: &container::Model,
    cache: &mut FxHashMap<usize, Values>,
    accessor: usize,
    order: &[u32],
    own: usize,
    parts: &[Part],
    origin: &dyn Fn(u32) -> usize,
    what: &str,
    lookup: impl Fn(&container::Model, usize) -> Option<usize>,
) -> Result<(Vec<u8>, ValuesInfo), WriteError> {
    if let std::collections::hash_map::Entry::Vacant(e) = cache.entry(accessor) {
        e.insert(values(data, model, accessor, what)?);
    }
    let mine = &cache[&accessor];
    let info = ValuesInfo {
        size: mine.size,
        component: mine.component,
        type_: mine.type_,
        normalized: mine.normalized,
        has_bounds: mine.has_bounds,
    };
    let mut out = Vec::with_capacity(order.len() * info.size);
    let mut others: FxHashMap<usize, Option<usize>> = FxHashMap::default();
    for &v in order {
        let original = origin(v);
        let k = parts.partition_point(|p| p.first_vertex + p.vertices <= original);
        let local = original - parts[k].first_vertex;
        let source = if k == own {
            Some(accessor)
        } else {
            *others
                .entry(k)
                .or_insert_with(|| lookup(model, parts[k].primitive))
        };
        let mut pushed = false;
        if let Some(a) = source {
            if let std::collections::hash_map::Entry::Vacant(e) = cache.entry(a) {
                e.insert(values(data, model, a, what)?);
            }
            let other = &cache[&a];
            if other.size == info.size
                && other.component == info.component
                && other.type_ == info.type_
            {
                if let Some(bytes) = other.bytes.get(local * info.size..(local + 1) * info.size) {
                    out.extend_from_slice(bytes);
                    pushed = true;
                }
            }
        }
        if !pushed {
            out.resize(out.len() + info.size, 0);
        }
    }
    Ok((out, info))
}

struct ValuesInfo {
    size: usize,
    component: ComponentType,
    type_: Type,
    normalized: bool,
    has_bounds: bool,
}

/// Copies the external buffers and images the document refers to (relative files inside the
/// scanned tree) next to the copy, and points their URIs there. A file down from the source's
/// folder keeps its place and URI when that place is free for its bytes in the copy's final folder;
/// any other goes beside the copy under its file name, or the first free numbered name
/// (`mesh-1.bin`) when another file has that name there or another copy made meanwhile brings
/// one ([`Claims::side`]).
fn copy_external(
    doc: &mut Value,
    location: &Location,
    out: &Path,
    claims: &Claims,
    files: &buffers::Files,
) -> Result<Vec<PathBuf>, WriteError> {
    let folder = out.parent().unwrap_or(Path::new(""));
    let mut written = Vec::new();
    // Per source file named: its URI in the copy (`None`: as it was).
    let mut named: FxHashMap<PathBuf, Option<String>> = FxHashMap::default();
    // Places written (two files of the same bytes share a name).
    let mut placed: rustc_hash::FxHashSet<PathBuf> = Default::default();
    for key in ["buffers", "images"] {
        let Some(items) = doc.get_mut(key).and_then(Value::as_array_mut) else {
            continue;
        };
        for item in items {
            let Some(uri) = item.get("uri").and_then(Value::as_str) else {
                continue;
            };
            if uri
                .get(..5)
                .is_some_and(|s| s.eq_ignore_ascii_case("data:"))
            {
                continue;
            }
            // Outside the tree or missing: the uri stays as it was (the source has the same problem).
            let Ok(real) = buffers::resolve(uri, location) else {
                continue;
            };
            if let Some(new) = named.get(&real) {
                if let Some(new) = new {
                    item["uri"] = json!(new);
                }
                continue;
            }
            // A path down from the source's folder keeps its place (and its URI); one that climbs
            // (`../buffers/x.bin`) is copied beside the copy under its file name.
            let below = buffers::check(uri, location)
                .ok()
                .and_then(|p| p.strip_prefix(&location.folder).ok().map(Path::to_path_buf))
                .filter(|_| !uri.contains(".."));
            let bytes = super::read_side(&real)?;
            // A buffer file read for the meshes compared with the scan's must still begin with
            // what was read: the copy's other meshes keep reading it.
            if files
                .read_of(&real)
                .is_some_and(|read| !bytes.starts_with(read))
            {
                return Err(super::changed());
            }
            if let Some(rel) = below {
                if claims.side(&rel, &bytes, false).is_ok() {
                    let to = folder.join(&rel);
                    if placed.insert(to.clone()) {
                        super::put_beside(&real, &bytes, &to)?;
                        written.push(to);
                    }
                    named.insert(real, None);
                    continue;
                }
            }
            let file = real
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let name = claims
                .side(Path::new(&file), &bytes, true)
                .map_err(|_| claims.no_free_name(&file))?;
            let to = folder.join(&name);
            if placed.insert(to.clone()) {
                super::put_beside(&real, &bytes, &to)?;
                written.push(to);
            }
            let uri = encode_uri(&name.to_string_lossy());
            item["uri"] = json!(uri);
            named.insert(real, Some(uri));
        }
    }
    Ok(written)
}

/// A file name as a URI reference (RFC 3986 unreserved characters kept, the rest escaped).
fn encode_uri(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    for b in name.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}
