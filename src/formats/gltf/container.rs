//! The outside of a glTF asset: the GLB container (header, JSON chunk, BIN chunk), the version
//! check that turns glTF 1.0 away with a clear message, and the `extensionsRequired` gate. Nothing
//! here trusts a length it has not checked against the bytes it has.

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
        let advice = match ext.as_str() {
            "KHR_draco_mesh_compression" => {
                "which meshvet cannot decode: export without Draco compression"
            }
            "EXT_meshopt_compression" | "KHR_meshopt_compression" => {
                "which meshvet cannot decode: export without meshopt compression"
            }
            "KHR_mesh_quantization" => {
                "which meshvet cannot decode: export with float positions (no mesh quantization)"
            }
            _ => "which meshvet does not support: export without it",
        };
        return Err(ReadError::new(format!(
            "requires extension {ext}, {advice}"
        )));
    }
    json::deserialize::from_slice(json).map_err(invalid)
}

fn v1() -> ReadError {
    ReadError::new("glTF 1.0 is not supported; convert to glTF 2.0")
}
