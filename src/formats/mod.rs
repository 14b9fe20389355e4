//! Format readers. One module per format; each turns bytes into [`Mesh`]es or a [`ReadError`] whose
//! message says what is wrong and what to do. No reader panics on bad input, none sizes an allocation
//! from an unchecked header count, and the glTF reader never reads outside the scanned tree.

use std::fmt;
use std::path::{Path, PathBuf};

use crate::mesh::Mesh;

mod gltf;
pub(crate) mod obj;
pub(crate) mod off;
pub(crate) mod ply;
pub(crate) mod polygon;
mod stl;
pub mod write;

/// The file formats meshvet reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Format {
    Obj,
    Gltf,
    Glb,
    Stl,
    Ply,
    Off,
}

impl Format {
    /// The format of a path, from its extension (case-insensitive).
    pub fn of_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "obj" => Format::Obj,
            "gltf" => Format::Gltf,
            "glb" => Format::Glb,
            "stl" => Format::Stl,
            "ply" => Format::Ply,
            "off" => Format::Off,
            _ => return None,
        })
    }

    /// The lower-case name used in the report's `format` column.
    pub fn name(self) -> &'static str {
        match self {
            Format::Obj => "obj",
            Format::Gltf => "gltf",
            Format::Glb => "glb",
            Format::Stl => "stl",
            Format::Ply => "ply",
            Format::Off => "off",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Limits that keep a hostile or huge file from exhausting memory.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// Files larger than this are refused before reading.
    pub max_file_bytes: u64,
    /// Meshes with more triangles (or vertices) than this are refused.
    pub max_triangles: u64,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            max_file_bytes: 2 << 30,
            max_triangles: 100_000_000,
        }
    }
}

/// Where a reader may look besides the file itself.
#[derive(Debug, Clone)]
pub struct ReadContext {
    /// The scanned tree: glTF buffer URIs must resolve inside it.
    pub root: PathBuf,
    pub limits: Limits,
}

/// Why a file could not be read. The message is for a person: what is wrong and what to do.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ReadError(pub String);

impl ReadError {
    pub fn new(msg: impl Into<String>) -> ReadError {
        ReadError(msg.into())
    }
}

impl From<std::io::Error> for ReadError {
    fn from(e: std::io::Error) -> ReadError {
        ReadError(format!("cannot read the file: {e}"))
    }
}

/// Reads every mesh of a file. A file with no triangles gives meshes with no triangles (or none at all),
/// not an error.
pub fn read(path: &Path, format: Format, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    let size = std::fs::metadata(path)?.len();
    if size > cx.limits.max_file_bytes {
        return Err(ReadError::new(format!(
            "file is {size} bytes, over the limit of {} bytes: raise limits.max_file_bytes in the config to scan it",
            cx.limits.max_file_bytes
        )));
    }
    match format {
        Format::Obj => obj::read(path, cx),
        Format::Gltf | Format::Glb => gltf::read(path, cx),
        Format::Stl => stl::read(path, cx),
        Format::Ply => ply::read(path, cx),
        Format::Off => off::read(path, cx),
    }
}
