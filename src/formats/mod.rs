//! Format readers. One module per format (a folder for the formats of several files); each turns bytes into [`Mesh`]es or a [`ReadError`] whose
//! message says what is wrong and what to do. No reader panics on bad input, none sizes an allocation
//! from an unchecked header count, only regular files are read (a FIFO or device would block), and
//! no file a model names is read outside the scanned tree ([`contain`]).

use std::fmt;
use std::path::{Path, PathBuf};

use crate::mesh::Mesh;

pub(crate) mod contain;
mod gltf;
pub(crate) mod obj;
pub(crate) mod off;
pub(crate) mod ply;
pub(crate) mod polygon;
mod stl;
pub(crate) mod threemf;
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
    /// 3D Manufacturing Format (a ZIP package of XML model parts).
    ThreeMf,
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
            "3mf" => Format::ThreeMf,
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
            Format::ThreeMf => "3mf",
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
    check_file(path, &cx.limits)?;
    match format {
        Format::Obj => obj::read(path, cx),
        Format::Gltf | Format::Glb => gltf::read(path, cx),
        Format::Stl => stl::read(path, cx),
        Format::Ply => ply::read(path, cx),
        Format::Off => off::read(path, cx),
        Format::ThreeMf => threemf::read(path, cx),
    }
}

/// What a reader kept of a file for the writer of its repaired copy, so that the copy is written
/// without reading and parsing the file a second time ([`read_retaining`]).
#[derive(Debug)]
pub struct Retained(RetainedKind);

#[derive(Debug)]
enum RetainedKind {
    Obj(Box<obj::Detail>),
}

/// [`read`], also keeping what the writer of a repaired copy needs where reading it again would
/// cost a second parse of the file (OBJ: texture coordinates, normals, polygons and groups; the
/// other writers read what they need again, which costs little next to their parse). The meshes
/// are those [`read`] returns.
pub fn read_retaining(
    path: &Path,
    format: Format,
    cx: &ReadContext,
) -> Result<(Vec<Mesh>, Option<Retained>), ReadError> {
    match format {
        Format::Obj => {
            check_file(path, &cx.limits)?;
            let (meshes, detail) = obj::read_retaining(path, cx)?;
            Ok((meshes, Some(Retained(RetainedKind::Obj(detail)))))
        }
        _ => Ok((read(path, format, cx)?, None)),
    }
}

impl Retained {
    /// The OBJ detail, when this was kept of an OBJ file.
    pub(crate) fn obj(self) -> Option<Box<obj::Detail>> {
        match self.0 {
            RetainedKind::Obj(detail) => Some(detail),
        }
    }
}

/// The real path of `name`, a file a model of `format` names (an OBJ `mtllib`, a glTF buffer or
/// image URI), if the reader's own rule lets it be read ([`contain`]: inside the tree before and
/// after symbolic links, a regular file); `None` otherwise. Opens nothing. For the cache, which
/// hashes what the readers read and must never look anywhere else.
pub(crate) fn dependency(
    format: Format,
    name: &str,
    location: &contain::Location,
) -> Option<PathBuf> {
    match format {
        Format::Obj => obj::library(name, location).ok(),
        Format::Gltf | Format::Glb => gltf::buffers::resolve(name, location).ok(),
        // A 3MF package is one file: its parts are inside it.
        Format::Stl | Format::Ply | Format::Off | Format::ThreeMf => None,
    }
}

/// What a path that is not a regular file is (`a FIFO`, `a folder`, ...), or `None` for a regular
/// file. Reading a FIFO or a device blocks (or never ends), so only regular files are read.
pub fn not_regular(meta: &std::fs::Metadata) -> Option<&'static str> {
    let kind = meta.file_type();
    if kind.is_file() {
        return None;
    }
    if kind.is_dir() {
        return Some("a folder");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if kind.is_socket() {
            return Some("a socket");
        }
        if kind.is_char_device() || kind.is_block_device() {
            return Some("a device");
        }
    }
    Some("not a file")
}

/// The message for a path that is not a regular file.
pub fn not_regular_message(kind: &str) -> String {
    format!(
        "not a regular file ({kind}): meshvet reads only regular files - name the mesh file itself"
    )
}

/// Refuses, before anything is opened, a path that is not a regular file or is over the size
/// limit. (Symbolic links are followed: a link to a regular file is read.)
pub(crate) fn check_file(path: &Path, limits: &Limits) -> Result<u64, ReadError> {
    let meta = std::fs::metadata(path)?;
    if let Some(kind) = not_regular(&meta) {
        return Err(ReadError::new(not_regular_message(kind)));
    }
    let size = meta.len();
    if size > limits.max_file_bytes {
        return Err(ReadError::new(format!(
            "file is {size} bytes, over the limit of {} bytes: raise limits.max_file_bytes in the config to scan it",
            limits.max_file_bytes
        )));
    }
    Ok(size)
}
