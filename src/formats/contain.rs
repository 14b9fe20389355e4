//! The one containment rule for every file a model names besides itself (glTF buffers and images,
//! OBJ material libraries), used by the readers and by the cache when it hashes dependencies, so
//! nothing outside the scanned tree is ever opened, read or even looked at.
//!
//! A name is first checked lexically, without touching the disk ([`join`]): not absolute, no NUL,
//! `..` applied to the canonical folder of the model, and the result must stay inside the canonical
//! tree (shared `../textures/` folders inside the tree are fine). Then [`resolve`] follows symbolic
//! links and checks the real path again: inside the tree, and a regular file (a FIFO or device would
//! block a read).

use std::path::{Component, Path, PathBuf};

use super::ReadError;

/// Where relative names are looked up and how far they may go.
#[derive(Debug, Clone)]
pub struct Location {
    /// The canonical folder of the model file.
    pub folder: PathBuf,
    /// The canonical scanned tree: every file a model names must resolve inside it.
    pub tree: PathBuf,
    /// The tree as it was given (for messages: `.` is the current folder).
    pub given: PathBuf,
}

impl Location {
    /// The folder of `path` and the tree `root` (a file root means its own folder), both canonical.
    pub fn new(path: &Path, root: &Path) -> Result<Location, ReadError> {
        let canonical = |p: &Path| {
            p.canonicalize().map_err(|e| {
                ReadError::new(format!("cannot resolve the folder {}: {e}", p.display()))
            })
        };
        let file = canonical(path)?;
        let folder = file.parent().map(Path::to_path_buf).unwrap_or(file);
        let mut tree = canonical(root)?;
        if tree.is_file() {
            tree.pop();
        }
        Ok(Location {
            folder,
            tree,
            given: root.to_path_buf(),
        })
    }

    /// The tree in words, for a refusal: `the current folder`, or `the folder `assets``, and how
    /// to widen it.
    pub fn tree_name(&self) -> String {
        let tree = if self.given == Path::new(".") || self.given.as_os_str().is_empty() {
            "the current folder".to_owned()
        } else {
            format!("the folder `{}`", self.given.display())
        };
        format!("{tree} (a wider one can be given with --root DIR)")
    }
}

/// Why a name is refused before anything is looked up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    Absolute,
    ClimbsOut,
    Nul,
}

impl Refusal {
    pub fn describe(self) -> &'static str {
        match self {
            Refusal::Absolute => "it is an absolute path",
            Refusal::ClimbsOut => "it climbs out of the scanned tree",
            Refusal::Nul => "it contains a NUL byte",
        }
    }
}

/// The path `relative` names from the model's folder, checked lexically (no disk access): not
/// absolute, no NUL, and inside the tree once `..` is applied. Use [`resolve`] before opening it.
pub fn join(relative: &str, location: &Location) -> Result<PathBuf, Refusal> {
    if relative.contains('\0') {
        return Err(Refusal::Nul);
    }
    let path = Path::new(relative);
    let drive = relative.len() >= 2 && relative.as_bytes()[1] == b':';
    if relative.starts_with('/') || relative.starts_with('\\') || drive || path.is_absolute() {
        return Err(Refusal::Absolute);
    }
    // `..` is applied to the canonical folder without touching the disk.
    let mut joined = location.folder.clone();
    for component in path.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir => {
                if !joined.pop() {
                    return Err(Refusal::ClimbsOut);
                }
            }
            Component::Normal(part) => joined.push(part),
            Component::RootDir | Component::Prefix(_) => return Err(Refusal::Absolute),
        }
    }
    if !joined.starts_with(&location.tree) {
        return Err(Refusal::ClimbsOut);
    }
    Ok(joined)
}

/// Why a lexically fine path cannot be opened.
#[derive(Debug)]
pub enum Unresolved {
    /// It does not exist (or a folder on the way does not).
    Missing,
    /// It cannot be looked at (permissions, a loop of links, ...).
    Io(std::io::Error),
    /// Through a symbolic link it lands outside the tree.
    Outside,
    /// It is a folder, FIFO, socket or device.
    NotAFile(PathBuf),
}

/// The real file behind `joined` (from [`join`]): symbolic links followed, still inside the tree,
/// and a regular file. Looks at the disk, opens nothing.
pub fn resolve(joined: &Path, location: &Location) -> Result<PathBuf, Unresolved> {
    let real = joined.canonicalize().map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Unresolved::Missing,
        _ => Unresolved::Io(e),
    })?;
    if !real.starts_with(&location.tree) {
        return Err(Unresolved::Outside);
    }
    match std::fs::metadata(&real) {
        Ok(m) if m.is_file() => Ok(real),
        Ok(_) => Err(Unresolved::NotAFile(real)),
        Err(e) => Err(Unresolved::Io(e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lexical_rule() {
        let location = Location {
            folder: PathBuf::from("/tree/models"),
            tree: PathBuf::from("/tree"),
            given: PathBuf::from("/tree"),
        };
        assert_eq!(
            join("../shared/a.bin", &location),
            Ok(PathBuf::from("/tree/shared/a.bin"))
        );
        assert_eq!(
            join("./sub/../a.mtl", &location),
            Ok(PathBuf::from("/tree/models/a.mtl"))
        );
        assert_eq!(join("../../etc/x", &location), Err(Refusal::ClimbsOut));
        assert_eq!(join("/etc/passwd", &location), Err(Refusal::Absolute));
        assert_eq!(join("\\\\server\\x", &location), Err(Refusal::Absolute));
        assert_eq!(join("C:/x.bin", &location), Err(Refusal::Absolute));
        assert_eq!(join("a\0b", &location), Err(Refusal::Nul));
    }
}
