//! Stamps: what a file looked like (size, times, inode, device), so an unchanged file can be
//! trusted without reading it, and when a stamp is too fresh to trust.

use std::path::Path;

use super::entry::{put_str, put_u64};
use super::Dependencies;

/// What a file looked like, to tell without reading it whether it may have changed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum Stamp {
    /// Size, modification and change times (seconds, nanoseconds), inode and device.
    File {
        len: u64,
        modified: (i64, i64),
        changed: (i64, i64),
        inode: u64,
        device: u64,
    },
    /// It could not be looked at (the error's kind).
    Missing(String),
    /// A dependency the reader would not read; never looked at.
    Unavailable,
}

pub(super) fn put_stamps(out: &mut Vec<u8>, stamps: &[Stamp]) {
    for stamp in stamps {
        match stamp {
            Stamp::File {
                len,
                modified,
                changed,
                inode,
                device,
            } => {
                out.push(b'f');
                for n in [
                    *len,
                    modified.0 as u64,
                    modified.1 as u64,
                    changed.0 as u64,
                    changed.1 as u64,
                    *inode,
                    *device,
                ] {
                    put_u64(out, n);
                }
            }
            Stamp::Missing(kind) => {
                out.push(b'm');
                put_str(out, kind);
            }
            Stamp::Unavailable => out.push(b'u'),
        }
    }
}

/// Stamps of `file` and of each dependency (where the reader's rule resolves it); a dependency the
/// reader would not read (outside the tree, not a regular file, not there) is `Unavailable` and is
/// never looked at. The change time cannot be set by any tool (`touch -d`, `tar`, `rsync -t` set
/// only the modification time), so new content under an old modification time still changes the
/// stamp. `None` where the platform has no such stamps.
pub(super) fn stamps(
    file: &Path,
    deps: &Dependencies<'_>,
    dependencies: &[String],
) -> Option<Vec<Stamp>> {
    let mut stamps = Vec::with_capacity(1 + dependencies.len());
    stamps.push(stamp(file)?);
    for d in dependencies {
        stamps.push(match deps.resolve(d) {
            Some(path) => stamp(&path)?,
            None => Stamp::Unavailable,
        });
    }
    Some(stamps)
}

#[cfg(unix)]
pub(super) fn stamp(path: &Path) -> Option<Stamp> {
    use std::os::unix::fs::MetadataExt;
    Some(match std::fs::metadata(path) {
        Ok(m) => Stamp::File {
            len: m.len(),
            modified: (m.mtime(), m.mtime_nsec()),
            changed: (m.ctime(), m.ctime_nsec()),
            inode: m.ino(),
            device: m.dev(),
        },
        Err(e) => Stamp::Missing(format!("{:?}", e.kind())),
    })
}

#[cfg(not(unix))]
pub(super) fn stamp(_: &Path) -> Option<Stamp> {
    None
}

/// Whether every stamp's change time is at least 2 s before `written`: a file changed in the same
/// clock tick as its stamp was taken could change again without changing the stamp (git's "racy
/// clean" problem), so such an entry is checked by content.
pub(super) fn settled(stamps: &[Stamp], written: u64) -> bool {
    stamps.iter().all(|s| match s {
        Stamp::File { changed, .. } => changed.0.saturating_add(2) <= written as i64,
        // Missing or unavailable: nothing that could change silently.
        Stamp::Missing(_) | Stamp::Unavailable => true,
    })
}
