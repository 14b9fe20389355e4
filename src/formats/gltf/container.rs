//! The outside of a glTF asset: the GLB container (header, JSON chunk, BIN chunk), the version
//! check that turns glTF 1.0 away with a clear message, the `extensionsRequired` gate, and the
//! extensions on primitives, buffer views and nodes that change the geometry (compression that
//! may be used without being required, GPU instancing). Nothing
//! here trusts a length it has not checked against the bytes it has.

use std::collections::{BTreeMap, BTreeSet};

use gltf::json;
use serde::Deserialize;

use super::super::ReadError;

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// The two parts of an asset: its JSON and, for GLB, the binary chunk that buffer 0 refers to.
pub struct Container<'a> {
    pub json: &'a [u8],
    pub bin: Option<&'a [u8]>,
    pub is_glb: bool,
}

/// Splits a file into JSON and BIN, whatever its extension says: GLB is recognised by its magic,
/// anything starting with `{` (after whitespace or a BOM) is JSON.
pub fn split(bytes: &[u8]) -> Result<Container<'_>, ReadError> {
    if bytes.starts_with(GLB_MAGIC) {
        return split_glb(bytes);
    }
    let json = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    match json.iter().find(|b| !b.is_ascii_whitespace()) {
        Some(b'{') => Ok(Container {
            json,
            bin: None,
            is_glb: false,
        }),
        _ => Err(ReadError::new(
            "not a glTF file: it is neither a GLB container (no 'glTF' magic) nor JSON",
        )),
    }
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let end = at.checked_add(4)?;
    let word = bytes.get(at..end)?;
    Some(u32::from_le_bytes([word[0], word[1], word[2], word[3]]))
}

fn split_glb(bytes: &[u8]) -> Result<Container<'_>, ReadError> {
    let truncated = |what: String| {
        ReadError::new(format!(
            "truncated GLB: {what}; the file is cut short, export or download it again"
        ))
    };
    if bytes.len() < 12 {
        return Err(truncated(format!(
            "{} bytes, less than the 12-byte header",
            bytes.len()
        )));
    }
    let version = u32_at(bytes, 4).unwrap_or(0);
    if version == 1 {
        return Err(ReadError::new(
            "binary glTF 1.0 is not supported; convert to glTF 2.0",
        ));
    }
    if version != 2 {
        return Err(ReadError::new(format!(
            "GLB container version {version} is not supported (meshvet reads glTF 2.0)"
        )));
    }
    let declared = u32_at(bytes, 8).unwrap_or(0) as usize;
    if declared > bytes.len() {
        return Err(truncated(format!(
            "the header declares {declared} bytes but the file has {}",
            bytes.len()
        )));
    }
    let bytes = &bytes[..declared];
    let mut json = None;
    let mut bin = None;
    let mut at = 12usize;
    let mut chunk = 0usize;
    while at < bytes.len() {
        let (Some(len), Some(kind)) = (u32_at(bytes, at), u32_at(bytes, at + 4)) else {
            return Err(truncated(format!("chunk {chunk} has an incomplete header")));
        };
        let start = at + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&end| end <= bytes.len())
            .ok_or_else(|| {
                truncated(format!(
                    "chunk {chunk} declares {len} bytes but only {} remain",
                    bytes.len().saturating_sub(start)
                ))
            })?;
        let data = &bytes[start..end];
        match (chunk, kind) {
            // Some writers pad the JSON chunk with NULs instead of spaces.
            (0, CHUNK_JSON) => {
                let trimmed = data.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
                json = Some(&data[..trimmed]);
            }
            (0, _) => {
                return Err(ReadError::new(
                    "invalid GLB: the first chunk is not the JSON chunk",
                ))
            }
            (1, CHUNK_BIN) => bin = Some(data),
            _ => {} // unknown chunks are skipped, as the spec asks
        }
        at = end;
        chunk += 1;
    }
    let json = json.ok_or_else(|| ReadError::new("invalid GLB: it has no JSON chunk"))?;
    Ok(Container {
        json,
        bin,
        is_glb: true,
    })
}

/// Just enough of the JSON to decide whether the rest is worth deserializing.
#[derive(Deserialize)]
struct Preamble {
    asset: Option<PreambleAsset>,
    #[serde(default, rename = "extensionsRequired")]
    extensions_required: Vec<String>,
    meshes: Option<json::Value>,
}

#[derive(Deserialize)]
struct PreambleAsset {
    version: Option<String>,
}

/// Required extensions that change nothing about geometry, so meshvet can ignore them.
fn is_harmless(extension: &str) -> bool {
    extension.starts_with("KHR_materials_")
        || matches!(
            extension,
            "KHR_texture_transform"
                | "KHR_texture_basisu"
                | "EXT_texture_webp"
                | "EXT_texture_avif"
                | "KHR_lights_punctual"
                | "KHR_xmp_json_ld"
                | "EXT_mesh_gpu_instancing"
        )
}

/// The parts of a glTF document that geometry depends on, in the gltf crate's JSON types. Other
/// members (materials, textures, animations, ...) are skipped unread, so a broken texture
/// reference does not stop a topology check. A scene without `nodes` (allowed by the spec, refused
/// by the crate's `Scene`) is an empty scene.
#[derive(Deserialize)]
pub struct Model {
    #[serde(default)]
    pub accessors: Vec<json::Accessor>,
    #[serde(default)]
    pub buffers: Vec<json::Buffer>,
    #[serde(default, rename = "bufferViews")]
    pub buffer_views: Vec<json::buffer::View>,
    #[serde(default)]
    pub meshes: Vec<json::Mesh>,
    #[serde(default)]
    pub nodes: Vec<json::Node>,
    #[serde(default)]
    pub scenes: Vec<Scene>,
    /// Size of the JSON the model was read from: with the loaded buffers, the real data an
    /// accessor without a buffer view may be expanded against (see `accessor`).
    #[serde(skip)]
    pub json_bytes: u64,
    /// The extensions geometry depends on, which the crate's JSON types drop.
    #[serde(skip)]
    pub extensions: Extensions,
}

/// The extensions on primitives, buffer views, buffers and nodes that change what geometry a file
/// holds: compressed data meshvet cannot decode, and per-instance transforms.
#[derive(Debug, Default)]
pub struct Extensions {
    /// `(mesh, primitive)` pairs with `KHR_draco_mesh_compression`.
    pub draco: BTreeSet<(usize, usize)>,
    /// Buffer views with `EXT_meshopt_compression` or `KHR_meshopt_compression`, and which.
    pub meshopt_views: BTreeMap<usize, &'static str>,
    /// Buffers marked as a meshopt `fallback`: placeholders with no real data.
    pub fallback_buffers: BTreeSet<usize>,
    /// Nodes with `EXT_mesh_gpu_instancing`.
    pub instancing: BTreeMap<usize, Instancing>,
}

/// The attributes of one node's `EXT_mesh_gpu_instancing`, as accessor indices.
#[derive(Debug, Default, Clone)]
pub struct Instancing {
    /// Every attribute accessor (all have the instance count).
    pub attributes: Vec<u64>,
    pub scale: Option<u64>,
}

const MESHOPT: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

/// Just the `extensions` objects of the members [`Extensions`] reads.
#[derive(Deserialize, Default)]
#[serde(default)]
struct RawExtensions {
    meshes: Vec<RawMesh>,
    #[serde(rename = "bufferViews")]
    buffer_views: Vec<RawItem>,
    buffers: Vec<RawItem>,
    nodes: Vec<RawItem>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct RawMesh {
    primitives: Vec<RawItem>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct RawItem {
    extensions: Option<json::Value>,
}

impl RawItem {
    fn get(&self, name: &str) -> Option<&json::Value> {
        self.extensions.as_ref()?.get(name)
    }
}

impl Extensions {
    /// Reads the extensions leniently: a shape this does not expect means "no extension" (the
    /// model itself, deserialized already, is what refuses malformed JSON).
    fn of(json: &[u8]) -> Extensions {
        let raw: RawExtensions = json::deserialize::from_slice(json).unwrap_or_default();
        let mut out = Extensions::default();
        for (m, mesh) in raw.meshes.iter().enumerate() {
            for (p, primitive) in mesh.primitives.iter().enumerate() {
                if primitive.get("KHR_draco_mesh_compression").is_some() {
                    out.draco.insert((m, p));
                }
            }
        }
        for (v, view) in raw.buffer_views.iter().enumerate() {
            if let Some(name) = MESHOPT.iter().find(|e| view.get(e).is_some()) {
                out.meshopt_views.insert(v, name);
            }
        }
        for (b, buffer) in raw.buffers.iter().enumerate() {
            let fallback = MESHOPT.iter().any(|e| {
                buffer
                    .get(e)
                    .and_then(|x| x.get("fallback"))
                    .and_then(json::Value::as_bool)
                    == Some(true)
            });
            if fallback {
                out.fallback_buffers.insert(b);
            }
        }
        for (n, node) in raw.nodes.iter().enumerate() {
            let Some(attributes) = node
                .get("EXT_mesh_gpu_instancing")
                .and_then(|x| x.get("attributes"))
                .and_then(json::Value::as_object)
            else {
                continue;
            };
            let mut instancing = Instancing::default();
            for (name, accessor) in attributes {
                if let Some(a) = accessor.as_u64() {
                    instancing.attributes.push(a);
                    if name == "SCALE" {
                        instancing.scale = Some(a);
                    }
                }
            }
            out.instancing.insert(n, instancing);
        }
        out
    }
}

#[derive(Deserialize)]
pub struct Scene {
    #[serde(default)]
    pub nodes: Vec<json::Index<json::Node>>,
}

/// Checks the version and required extensions, then deserializes the JSON into [`Model`]
/// (deserialization only: the crate's validation pass is where it panics, so we never run it).
pub fn parse_model(json: &[u8]) -> Result<Model, ReadError> {
    let invalid = |e: json::Error| ReadError::new(format!("invalid glTF JSON: {e}"));
    let preamble: Preamble = json::deserialize::from_slice(json).map_err(invalid)?;
    let version = preamble.asset.and_then(|a| a.version);
    let looks_v1 = matches!(preamble.meshes, Some(json::Value::Object(_)));
    match version.as_deref() {
        Some(v) if v == "1" || v.starts_with("1.") => return Err(v1()),
        None if looks_v1 => return Err(v1()),
        None => {
            return Err(ReadError::new(
                "invalid glTF: asset.version is missing (meshvet reads glTF 2.0)",
            ))
        }
        Some(v) if !(v == "2" || v.starts_with("2.")) => {
            return Err(ReadError::new(format!(
                "glTF version {v} is not supported (meshvet reads glTF 2.0)"
            )))
        }
        Some(_) if looks_v1 => return Err(v1()),
        Some(_) => {}
    }
    if let Some(ext) = preamble
        .extensions_required
        .iter()
        .find(|e| !is_harmless(e))
    {
        let dequantize;
        let advice = match ext.as_str() {
            "KHR_draco_mesh_compression" => {
                "which meshvet cannot decode: export without Draco compression"
            }
            "EXT_meshopt_compression" | "KHR_meshopt_compression" => {
                "which meshvet cannot decode: export without meshopt compression"
            }
            "KHR_mesh_quantization" => {
                dequantize = format!("which meshvet cannot decode: {}", super::DEQUANTIZE);
                &dequantize
            }
            _ => "which meshvet does not support: export without it",
        };
        return Err(ReadError::new(format!(
            "requires extension {ext}, {advice}"
        )));
    }
    let mut model: Model = json::deserialize::from_slice(json).map_err(invalid)?;
    model.json_bytes = json.len() as u64;
    model.extensions = Extensions::of(json);
    Ok(model)
}

fn v1() -> ReadError {
    ReadError::new("glTF 1.0 is not supported; convert to glTF 2.0")
}
