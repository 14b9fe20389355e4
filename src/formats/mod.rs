//! Format readers. One module per format (a folder for the formats of several files); each turns bytes into [`Mesh`]es or a [`ReadError`] whose
//! message says what is wrong and what to do. No reader panics on bad input, none sizes an allocation
//! from an unchecked header count, only regular files are read (a FIFO or device would block), and
//! no file a model names is read outside the scanned tree (`contain`).

use std::fmt;
use std::path::{Path, PathBuf};

use crate::mesh::Mesh;

pub(crate) mod contain;
mod gltf;
pub(crate) mod obj;
pub(crate) mod off;
pub(crate) mod ply;
mod stl;
mod text;
pub(crate) mod threemf;
pub mod write;

/// The file formats meshvet reads. Everything else meshvet knows of a format is its line of
/// `FORMATS`.
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

/// One format: how it is named, found, read and written, and which other files its files name.
pub(crate) struct Entry {
    pub format: Format,
    /// The report's `format` column.
    pub name: &'static str,
    /// File name extensions, lower case, without the dot (matched in any case).
    pub extensions: &'static [&'static str],
    /// Reads every mesh of a file (opened with [`open_file`]).
    pub read: Reader,
    /// A read that also keeps what the writer of a repaired copy needs, where reading the file
    /// again would cost a second parse; `None`: the writer reads the source itself.
    pub read_retaining: Option<RetainingReader>,
    /// Writes a repaired copy ([`write::Job`]).
    pub write: fn(write::Job<'_>) -> Result<write::Written, write::WriteError>,
    /// The other files a file of this format names (`None`: it names none).
    pub side_files: Option<SideFiles>,
    /// Its copies store positions as 32-bit floats (STL, glTF; an ASCII STL is taken as binary):
    /// a split vertex's copy must clear their rounding ([`crate::repair::Options::single_precision`]).
    pub single_precision: bool,
}

type Reader = fn(&Path, &ReadContext) -> Result<Vec<Mesh>, ReadError>;
type RetainingReader = fn(&Path, &ReadContext) -> Result<(Vec<Mesh>, Retained), ReadError>;

/// How a format's files name other files: the cache hashes those files too, found by the reader's
/// own rule so that it never looks anywhere the reader would not.
pub(crate) struct SideFiles {
    /// The names a file's bytes hold, as written (the cache dedups them).
    pub names: fn(&[u8]) -> Vec<String>,
    /// The real path of a name, if the reader would read it ([`contain`]).
    pub resolve: fn(&str, &contain::Location) -> Option<PathBuf>,
}

/// Every format, in [`Format`] order. Adding a format is a variant above, a reader and a writer
/// module, and one line here.
pub(crate) const FORMATS: [Entry; 7] = [
    Entry {
        format: Format::Obj,
        name: "obj",
        extensions: &["obj"],
        read: obj::read,
        read_retaining: Some(obj::read_retaining),
        write: write::obj::write,
        side_files: Some(obj::SIDE_FILES),
        single_precision: false,
    },
    Entry {
        format: Format::Gltf,
        name: "gltf",
        extensions: &["gltf"],
        read: gltf::read,
        read_retaining: None,
        write: write::gltf::write,
        side_files: Some(gltf::SIDE_FILES),
        single_precision: true,
    },
    Entry {
        format: Format::Glb,
        name: "glb",
        extensions: &["glb"],
        read: gltf::read,
        read_retaining: None,
        write: write::gltf::write,
        side_files: Some(gltf::SIDE_FILES),
        single_precision: true,
    },
    Entry {
        format: Format::Stl,
        name: "stl",
        extensions: &["stl"],
        read: stl::read,
        read_retaining: None,
        write: write::stl::write,
        side_files: None,
        single_precision: true,
    },
    Entry {
        format: Format::Ply,
        name: "ply",
        extensions: &["ply"],
        read: ply::read,
        read_retaining: None,
        write: write::ply::write,
        side_files: None,
        single_precision: false,
    },
    Entry {
        format: Format::Off,
        name: "off",
        extensions: &["off"],
        read: off::read,
        read_retaining: None,
        write: write::off::write,
        side_files: None,
        single_precision: false,
    },
    Entry {
        format: Format::ThreeMf,
        name: "3mf",
        extensions: &["3mf"],
        read: threemf::read,
        read_retaining: None,
        write: write::threemf::write,
        // A package is one file: its parts are inside it.
        side_files: None,
        single_precision: false,
    },
];

impl Format {
    /// Every format, in declaration order.
    pub const ALL: [Format; FORMATS.len()] = {
        let mut all = [Format::Obj; FORMATS.len()];
        let mut i = 0;
        while i < FORMATS.len() {
            all[i] = FORMATS[i].format;
            i += 1;
        }
        all
    };

    pub(crate) fn entry(self) -> &'static Entry {
        &FORMATS[self as usize]
    }

    /// The format of a path, from its extension (case-insensitive).
    pub fn of_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?;
        FORMATS
            .iter()
            .find(|e| e.extensions.iter().any(|x| x.eq_ignore_ascii_case(ext)))
            .map(|e| e.format)
    }

    /// The lower-case name used in the report's `format` column.
    pub fn name(self) -> &'static str {
        self.entry().name
    }

    /// Every extension meshvet reads, as a user would type them: `.obj .gltf .glb ...`.
    pub fn extension_list() -> String {
        let all: Vec<String> = FORMATS
            .iter()
            .flat_map(|e| e.extensions)
            .map(|x| format!(".{x}"))
            .collect();
        all.join(" ")
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

#[cfg(test)]
impl ReadContext {
    /// The current folder as the tree, default limits: for the readers' unit tests.
    pub(crate) fn for_tests() -> ReadContext {
        ReadContext {
            root: ".".into(),
            limits: Limits::default(),
        }
    }
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
    (format.entry().read)(path, cx).map(fitted)
}

/// Gives the meshes of one file distinct names: each mesh whose name another shares gets
/// ` (TAG)` appended, `tag(i)` being unique per mesh (glTF: `#index`; 3MF: `#id`). Report rows
/// are matched by path and mesh (a baseline, the page's links), so no two may share both. Repeated
/// while names still meet (a mesh may be named `Part (#1)` already): two names tagged in one round
/// end in different tags, so each round after the first tags a name that was never tagged, and
/// the rounds end.
pub(crate) fn distinct_names(meshes: &mut [Mesh], tag: impl Fn(usize) -> String) {
    for _ in 0..=meshes.len() {
        let mut uses: std::collections::HashMap<String, usize> = Default::default();
        for mesh in meshes.iter() {
            *uses
                .entry(mesh.name.clone().unwrap_or_default())
                .or_default() += 1;
        }
        if uses.len() == meshes.len() {
            return;
        }
        for (i, mesh) in meshes.iter_mut().enumerate() {
            let name = mesh.name.clone().unwrap_or_default();
            if uses[&name] > 1 {
                mesh.name = Some(format!("{name} ({})", tag(i)));
            }
        }
    }
}

/// The meshes with their arrays cut to their size. A reader that pushes as it parses, or reserves
/// what a header declares (up to a cap) and then grows, leaves up to twice a mesh's memory
/// allocated, and a scan holds the mesh through its whole analysis (a 5M-face binary PLY: 80 MB
/// too many). Shrinking a large block returns its tail pages without copying it.
fn fitted(mut meshes: Vec<Mesh>) -> Vec<Mesh> {
    for mesh in &mut meshes {
        mesh.positions.shrink_to_fit();
        mesh.triangles.shrink_to_fit();
    }
    meshes
}

/// What a reader kept of a file for the writer of its repaired copy, so that the copy is written
/// without reading and parsing the file a second time ([`read_retaining`]). Opaque outside the
/// crate; inside, one variant per format that keeps something, holding the reader's own type,
/// so that what a writer takes out is what the reader put in, checked when compiling (a
/// type-erased box once let the OBJ writer ask for the wrong type and silently parse the file
/// again). A writer handed no variant of its own format reads the file again, as without one.
#[derive(Debug)]
pub struct Retained(pub(crate) Kept);

/// What each format keeps ([`Retained`]).
#[derive(Debug)]
pub(crate) enum Kept {
    /// OBJ: texture coordinates, normals, polygons and groups.
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
    match format.entry().read_retaining {
        Some(read_retaining) => {
            let (meshes, kept) = read_retaining(path, cx)?;
            Ok((fitted(meshes), Some(kept)))
        }
        None => Ok((read(path, format, cx)?, None)),
    }
}

/// The names of the other files a file of `format` names (an OBJ's `mtllib`s, a glTF's buffer and
/// image URIs), deduplicated, in order, as written: for the cache, which hashes them.
pub(crate) fn side_file_names(format: Format, bytes: &[u8]) -> Vec<String> {
    let Some(side) = &format.entry().side_files else {
        return Vec::new();
    };
    let mut names = (side.names)(bytes);
    let mut seen = std::collections::HashSet::new();
    names.retain(|d| seen.insert(d.clone()));
    names
}

/// The real path of `name`, a file a model of `format` names, if the reader's own rule lets it be
/// read ([`contain`]: inside the tree before and after symbolic links, a regular file); `None`
/// otherwise. Opens nothing. For the cache, which hashes what the readers read and must never look
/// anywhere else.
pub(crate) fn dependency(
    format: Format,
    name: &str,
    location: &contain::Location,
) -> Option<PathBuf> {
    (format.entry().side_files.as_ref()?.resolve)(name, location)
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

/// Opens `path` for reading without waiting: on unix the open itself does not wait for a
/// FIFO's writer. What was opened is then checked by the callers.
fn open_unblocked(path: &Path) -> std::io::Result<std::fs::File> {
    let mut options = std::fs::File::options();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    options.open(path)
}

/// Opens `path` for reading if what is opened is a regular file: checked on the opened file
/// itself, so a file replaced by a FIFO or a device after its path was looked at is refused, not
/// waited on.
pub fn open_regular(path: &Path) -> std::io::Result<std::fs::File> {
    let file = open_unblocked(path)?;
    match not_regular(&file.metadata()?) {
        None => Ok(file),
        Some(kind) => Err(std::io::Error::other(not_regular_message(kind))),
    }
}

/// The bytes of the regular file at `path` ([`open_regular`]).
pub fn read_regular(path: &Path) -> std::io::Result<Vec<u8>> {
    use std::io::Read as _;
    let mut file = open_regular(path)?;
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Opens a mesh file for a reader: refuses what is opened unless it is a regular file (a FIFO or
/// a device would block or never end; a link to a regular file is read) within the size limit,
/// checked on the opened file itself, so a file replaced after the walk looked at its path is
/// refused, not waited on or read past the limit. Returns the file and its size.
pub(crate) fn open_file(path: &Path, limits: &Limits) -> Result<(std::fs::File, u64), ReadError> {
    let file = open_unblocked(path)?;
    let meta = file.metadata()?;
    if let Some(kind) = not_regular(&meta) {
        return Err(ReadError::new(not_regular_message(kind)));
    }
    let size = meta.len();
    if size > limits.max_file_bytes {
        return Err(over_limit(size, limits));
    }
    Ok((file, size))
}

/// The bytes of the file at `path` ([`open_file`]); never more than the size limit, even from a
/// file that grows while it is read.
pub(crate) fn read_bytes(path: &Path, limits: &Limits) -> Result<Vec<u8>, ReadError> {
    let (file, size) = open_file(path, limits)?;
    read_within(file, size, limits.max_file_bytes).map_err(|e| match e.kind() {
        std::io::ErrorKind::FileTooLarge => over_limit(limits.max_file_bytes + 1, limits),
        _ => e.into(),
    })
}

/// Reads `file` to its end (`size`: its size when opened), at most `limit` bytes: a file that
/// has grown past the limit meanwhile is an error of kind `FileTooLarge`, after `limit + 1`
/// bytes.
pub(crate) fn read_within(file: std::fs::File, size: u64, limit: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read as _;
    let mut bytes = Vec::with_capacity(size.min(limit) as usize);
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(std::io::ErrorKind::FileTooLarge.into());
    }
    Ok(bytes)
}

fn over_limit(size: u64, limits: &Limits) -> ReadError {
    ReadError::new(format!(
        "file is {size} bytes, over the limit of {} bytes: raise limits.max_file_bytes in the config to scan it",
        limits.max_file_bytes
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file replaced by a FIFO after the walk looked at its path: every reader refuses
    /// what it opened instead of waiting for a writer that never comes (before, the scan hung
    /// there for good). Each reader is called directly, as after the swap.
    #[cfg(unix)]
    #[test]
    fn every_reader_refuses_a_fifo_it_opens_instead_of_waiting() {
        let dir = tempfile::tempdir().unwrap();
        for entry in FORMATS {
            let fifo = dir.path().join(format!("m.{}", entry.extensions[0]));
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if !made.is_ok_and(|s| s.success()) {
                eprintln!("no mkfifo here: skipped");
                return;
            }
            let (send, receive) = std::sync::mpsc::channel();
            let read = entry.read;
            std::thread::spawn(move || {
                let cx = ReadContext {
                    root: fifo.parent().unwrap().to_path_buf(),
                    limits: Limits::default(),
                };
                let _ = send.send(read(&fifo, &cx).map(|_| ()));
            });
            let result = receive
                .recv_timeout(std::time::Duration::from_secs(10))
                .unwrap_or_else(|_| panic!("the {} reader waits on a FIFO", entry.name));
            let e = result.expect_err("a FIFO is no mesh file");
            assert!(e.to_string().contains("FIFO"), "{}: {e}", entry.name);
        }
        // Nor does a writer copying a side file (a glTF's buffer or image) that became a FIFO.
        let fifo = dir.path().join(format!("m.{}", FORMATS[0].extensions[0]));
        let (send, receive) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = send.send(write::read_side(&fifo).map(|_| ()));
        });
        let result = receive
            .recv_timeout(std::time::Duration::from_secs(10))
            .expect("the writer waits on a FIFO");
        let e = result.expect_err("a FIFO is no side file");
        assert!(e.to_string().contains("FIFO"), "{e}");
    }

    #[test]
    fn the_registry_is_in_format_order() {
        for (i, entry) in FORMATS.iter().enumerate() {
            assert_eq!(entry.format as usize, i, "{}", entry.name);
            assert_eq!(
                Format::of_path(Path::new(&format!(
                    "a.{}",
                    entry.extensions[0].to_uppercase()
                ))),
                Some(entry.format)
            );
        }
        assert_eq!(
            Format::extension_list(),
            ".obj .gltf .glb .stl .ply .off .3mf"
        );
        assert_eq!(Format::of_path(Path::new("a.txt")), None);
    }

    #[test]
    fn side_files_are_found_in_obj_gltf_and_glb() {
        assert_eq!(
            side_file_names(Format::Obj, b"v 0 0 0\n  mtllib a b.mtl\nmtllibx c\n"),
            ["a b.mtl", "a", "b.mtl"]
        );
        let gltf = br#"{"buffers":[{"uri":"../buffers/x%20y.bin"},{"uri":"data:,"}],"images":[{"uri":"t.png"}]}"#;
        assert_eq!(
            side_file_names(Format::Gltf, gltf),
            ["../buffers/x%20y.bin", "t.png"]
        );
        let mut glb = b"glTF\x02\0\0\0\0\0\0\0".to_vec();
        glb.extend_from_slice(&(gltf.len() as u32).to_le_bytes());
        glb.extend_from_slice(b"JSON");
        glb.extend_from_slice(gltf);
        assert_eq!(side_file_names(Format::Glb, &glb).len(), 2);
    }

    /// A mesh comes out of [`read`] and [`read_retaining`] with no room to spare in its arrays
    /// (which a scan holds through the whole analysis): an OBJ strip of 3,000 triangles on 3,002
    /// vertices, which its reader reserves for from the file size (a line of 64 bytes) and then
    /// grows by doubling as it pushes.
    #[test]
    fn read_meshes_have_no_spare_room() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("strip.obj");
        let mut text = String::new();
        for i in 0..3002 {
            text += &format!("v {} {} 0\n", i / 2, i % 2);
        }
        for i in 1..=3000 {
            text += &format!("f {} {} {}\n", i, i + 1, i + 2);
        }
        std::fs::write(&path, text).unwrap();
        let cx = ReadContext {
            root: dir.path().into(),
            limits: Limits::default(),
        };
        let (retained, _) = read_retaining(&path, Format::Obj, &cx).unwrap();
        for meshes in [read(&path, Format::Obj, &cx).unwrap(), retained] {
            let mesh = &meshes[0];
            assert_eq!(mesh.triangles.len(), 3000);
            assert_eq!(mesh.positions.len(), 3002);
            assert_eq!(mesh.triangles.capacity(), 3000);
            assert_eq!(mesh.positions.capacity(), 3002);
        }
    }

    /// A 3MF package is one file: its parts live inside it, so its cache key is its bytes alone,
    /// even when a part's text looks like a file another format would name.
    #[test]
    fn a_3mf_package_names_no_side_files() {
        let text =
            b"PK\x03\x04 mtllib a.mtl\n{\"buffers\":[{\"uri\":\"b.bin\"}]} p:path=\"/3D/x.model\"";
        assert!(side_file_names(Format::ThreeMf, text).is_empty());
        // A file the name could mean is there (an OBJ would depend on it); a 3MF does not.
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.mtl"), "newmtl a\n").unwrap();
        std::fs::write(dir.path().join("m.3mf"), text).unwrap();
        let location = contain::Location::new(&dir.path().join("m.3mf"), dir.path()).unwrap();
        assert!(dependency(Format::Obj, "a.mtl", &location).is_some());
        assert_eq!(dependency(Format::ThreeMf, "a.mtl", &location), None);
    }
}
