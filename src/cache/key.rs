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

/// Hashes a dependency's bytes, or what it is when it cannot be read as a regular file.
pub(super) fn hash_file(hasher: &mut blake3::Hasher, path: &Path, limit: u64) {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() && m.len() <= limit => match std::fs::read(path) {
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
    // The columns, so a build whose rows have other cells never decodes this one's.
    field(&mut hasher, crate::report::COLUMNS.join(",").as_bytes());
    field(&mut hasher, format!("{relevant:?}").as_bytes());
    hasher.finalize()
}
