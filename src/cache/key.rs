//! The cache key's parts: length-prefixed fields, the bytes of a file the rows depend on (or what
//! it is when it cannot be read), and a hash of every setting that can change a row.

use std::path::Path;

use super::entry::HEADER;
use crate::config::Settings;

/// Adds a length-prefixed field, so fields cannot run into each other.
pub(super) fn field(hasher: &mut blake3::Hasher, bytes: &[u8]) {
    hasher.update(&(bytes.len() as u64).to_le_bytes());
    hasher.update(bytes);
}

/// The bytes of the regular file at `path` (a FIFO or device put there since its path was looked
/// at is refused, not waited on), at most `limit` of them: a file that grew past it is an error.
pub(super) fn read_at_most(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    crate::formats::read_within(crate::formats::open_regular(path)?, 0, limit).map_err(|e| match e
        .kind()
    {
        std::io::ErrorKind::FileTooLarge => std::io::Error::other("over the size limit"),
        _ => e,
    })
}

/// Hashes a dependency's bytes, or what it is when it cannot be read as a regular file.
pub(super) fn hash_file(hasher: &mut blake3::Hasher, path: &Path, limit: u64) {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() && m.len() <= limit => match read_at_most(path, limit) {
            Ok(bytes) => {
                hasher.update(b"file");
                field(hasher, &bytes);
            }
            Err(e) => field(hasher, format!("unreadable {:?}", e.kind()).as_bytes()),
        },
        Ok(m) if m.is_file() => field(hasher, format!("large {}", m.len()).as_bytes()),
        Ok(_) => field(hasher, b"not a file"),
        Err(e) => field(hasher, format!("missing {:?}", e.kind()).as_bytes()),
    }
}

/// The settings that can change a row, hashed with the cache format and meshvet's version. The
/// `Debug` form covers every field, so a setting added later is in the key without anyone
/// remembering to add it.
pub(super) fn settings_hash(settings: &Settings) -> blake3::Hash {
    let relevant = Settings {
        jobs: 0,
        include: Vec::new(),
        exclude: Vec::new(),
        ..settings.clone()
    };
    let mut hasher = blake3::Hasher::new();
    field(&mut hasher, HEADER);
    field(&mut hasher, env!("CARGO_PKG_VERSION").as_bytes());
    // The build too: a binary rebuilt from changed code keeps the version but may judge meshes
    // otherwise, and must not reuse the rows of the one before.
    field(&mut hasher, build_identity().as_bytes());
    // The columns, so a build whose rows have other cells never decodes this one's.
    field(&mut hasher, crate::report::COLUMNS.join(",").as_bytes());
    field(&mut hasher, format!("{relevant:?}").as_bytes());
    hasher.finalize()
}

/// What tells this build of meshvet from another of the same version: the size and modification
/// time of the running executable (a rebuild or a reinstall changes them, so its first scan reads
/// every file again). Where the executable cannot be found, an identity of this process alone,
/// so that no entry is reused across runs rather than one reused wrongly.
fn build_identity() -> &'static str {
    static IDENTITY: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    IDENTITY.get_or_init(|| {
        std::env::current_exe()
            .ok()
            .and_then(|exe| file_identity(&exe))
            .unwrap_or_else(|| {
                let now = std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos());
                format!("process {} {now}", std::process::id())
            })
    })
}

/// The size and modification time of the file at `path` (links followed).
fn file_identity(path: &Path) -> Option<String> {
    let meta = std::fs::metadata(path).ok()?;
    let modified = meta
        .modified()
        .ok()?
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?;
    Some(format!("{} {}", meta.len(), modified.as_nanos()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rebuilt executable (another size, or another modification time) has another identity,
    /// the same file the same one.
    #[test]
    fn a_rebuilt_executable_has_another_identity() {
        let dir = tempfile::tempdir().unwrap();
        let exe = dir.path().join("meshvet");
        std::fs::write(&exe, b"build one").unwrap();
        let first = file_identity(&exe).unwrap();
        assert_eq!(file_identity(&exe).unwrap(), first);
        std::fs::write(&exe, b"build two, longer").unwrap();
        let second = file_identity(&exe).unwrap();
        assert_ne!(second, first);
        let file = std::fs::File::options().write(true).open(&exe).unwrap();
        let later = std::time::SystemTime::now() + std::time::Duration::from_secs(3600);
        file.set_modified(later).unwrap();
        assert_ne!(file_identity(&exe).unwrap(), second);
        assert_eq!(build_identity(), build_identity());
        assert!(file_identity(&dir.path().join("missing")).is_none());
    }
}
