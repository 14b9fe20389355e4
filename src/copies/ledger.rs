//! The repair folder's ledger: which copies meshvet put there, so a copy replaces only a file
//! meshvet wrote and nobody has changed since.
//!
//! A repair folder mirrors the scanned tree, so a copy's place may hold anything: last night's
//! copy (to be replaced), but also a file of the user's (a folder inside the scanned tree that
//! happens to hold models, another asset library named by mistake). Before it, every copy was
//! renamed over whatever was at its place. Now the folder keeps a file `.meshvet-copies`, one line
//! per copy put in place: the blake3 hash of its bytes and its path under the folder (both in hex,
//! so any name's bytes fit). A copy may replace a file only when the ledger's latest line for that
//! place has the file's hash. Lines are appended as copies are put in place (one write each, so
//! two scans writing into one folder do not tear each other's lines, and a killed scan has listed
//! what it put in place); a ledger of more than twice as many lines as places is rewritten with
//! one line per place when first read. A ledger that is missing, unreadable, a link or damaged
//! lists nothing or less: a copy then fails with a note rather than replace an unlisted file.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use rustc_hash::FxHashMap;

use crate::atomic::AtomicFile;

/// The ledger's name in the repair folder.
pub const LEDGER: &str = ".meshvet-copies";

/// The first line of a ledger.
const HEADER: &str = "meshvet-copies 1";

/// The ledger of one repair folder: the hash of the latest copy at each place (by its path's
/// bytes under the folder).
#[derive(Default)]
struct Book {
    places: FxHashMap<Vec<u8>, blake3::Hash>,
}

/// The ledgers read in this process, by repair folder (as the scan names it).
static BOOKS: Mutex<Option<FxHashMap<PathBuf, Book>>> = Mutex::new(None);

fn books() -> MutexGuard<'static, Option<FxHashMap<PathBuf, Book>>> {
    // Nothing panics while the lock is held; a poisoned map is still consistent.
    BOOKS.lock().unwrap_or_else(|e| e.into_inner())
}

/// The bytes of `place`'s path under `folder`; `None` when it is not under it.
fn key(folder: &Path, place: &Path) -> Option<Vec<u8>> {
    let relative = place.strip_prefix(folder).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        Some(relative.as_os_str().as_bytes().to_vec())
    }
    #[cfg(not(unix))]
    Some(relative.to_string_lossy().into_owned().into_bytes())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(text: &str) -> Option<Vec<u8>> {
    if !text.len().is_multiple_of(2) {
        return None;
    }
    (0..text.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(text.get(i..i + 2)?, 16).ok())
        .collect()
}

fn line(place: &[u8], digest: &blake3::Hash) -> String {
    format!("{} {}\n", digest.to_hex(), hex(place))
}

/// Opens the ledger for appending without following a link at its name (a link there could lead
/// anywhere); `None` when that fails.
fn open_for_append(path: &Path) -> Option<std::fs::File> {
    let mut options = std::fs::OpenOptions::new();
    options.append(true).create(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK);
    }
    let file = options.open(path).ok()?;
    file.metadata().ok()?.is_file().then_some(file)
}

/// Reads the ledger of `folder` (see the module docs); rewrites it with one line per place when
/// more than half of its lines are superseded.
fn read(folder: &Path) -> Book {
    let path = folder.join(LEDGER);
    let mut book = Book::default();
    let is_file = std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file());
    let Some(text) = is_file
        .then(|| std::fs::read_to_string(&path).ok())
        .flatten()
    else {
        return book;
    };
    let mut lines = text.lines();
    if lines.next() != Some(HEADER) {
        return book;
    }
    let mut count = 0usize;
    for l in lines {
        let Some((digest, place)) = l.split_once(' ') else {
            continue;
        };
        let (Ok(digest), Some(place)) = (blake3::Hash::from_hex(digest), unhex(place)) else {
            continue;
        };
        count += 1;
        book.places.insert(place, digest);
    }
    if count > 2 * book.places.len() + 64 {
        let mut places: Vec<_> = book.places.iter().collect();
        places.sort_by(|a, b| a.0.cmp(b.0));
        let mut text = format!("{HEADER}\n");
        for (place, digest) in places {
            text.push_str(&line(place, digest));
        }
        // Lost to a scan appending at this moment, a line only costs that copy's next
        // replacement (refused, with a note): the ledger never lists a file it should not.
        let _ = AtomicFile::create(&path).and_then(|mut f| {
            f.write_all(text.as_bytes())?;
            f.commit()
        });
    }
    book
}

/// Whether the ledger of `folder` lists `place` (whatever it holds now).
pub fn lists(folder: &Path, place: &Path) -> bool {
    let Some(key) = key(folder, place) else {
        return false;
    };
    let mut books = books();
    let books = books.get_or_insert_with(FxHashMap::default);
    let book = books
        .entry(folder.to_path_buf())
        .or_insert_with(|| read(folder));
    book.places.contains_key(&key)
}

/// `Ok` when a copy may be put at `place` in the repair folder `folder`: nothing is there, or
/// the copy meshvet put there last, unchanged. Else what is in the way and what to do.
pub fn may_replace(folder: &Path, place: &Path) -> Result<(), String> {
    let meta = match std::fs::symlink_metadata(place) {
        Ok(meta) => meta,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(format!("cannot look at {}: {e}", place.display())),
    };
    let advice = "move it away, or repair into another folder";
    if !meta.is_file() {
        return Err(format!(
            "{} is already there and is not a file meshvet wrote - {advice}",
            place.display()
        ));
    }
    let listed = key(folder, place).and_then(|key| {
        let mut books = books();
        let books = books.get_or_insert_with(FxHashMap::default);
        let book = books
            .entry(folder.to_path_buf())
            .or_insert_with(|| read(folder));
        book.places.get(&key).copied()
    });
    let Some(listed) = listed else {
        return Err(format!(
            "{} is already there and meshvet did not write it (it is not in the folder's {LEDGER}) \
             - {advice}",
            place.display()
        ));
    };
    let mut hasher = blake3::Hasher::new();
    let now = crate::formats::open_regular(place)
        .and_then(|f| hasher.update_reader(f).map(|h| h.finalize()))
        .map_err(|e| format!("cannot read {}: {e}", place.display()))?;
    if now != listed {
        return Err(format!(
            "{} was written by meshvet but has changed since - {advice}",
            place.display()
        ));
    }
    Ok(())
}

/// Lists the copy of hash `digest` now at `place` in the ledger of `folder`. A ledger that cannot
/// be written costs that copy's next replacement only (refused, with a note).
pub fn record(folder: &Path, place: &Path, digest: blake3::Hash) {
    let Some(key) = key(folder, place) else {
        return;
    };
    let mut books = books();
    let books = books.get_or_insert_with(FxHashMap::default);
    let book = books
        .entry(folder.to_path_buf())
        .or_insert_with(|| read(folder));
    let path = folder.join(LEDGER);
    if let Some(mut file) = open_for_append(&path) {
        let mut text = String::new();
        if file.metadata().is_ok_and(|m| m.len() == 0) {
            text.push_str(HEADER);
            text.push('\n');
        }
        text.push_str(&line(&key, &digest));
        if file.write_all(text.as_bytes()).is_ok() {
            book.places.insert(key, digest);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A copy listed with its hash may be replaced; one changed since, or never listed, or not a
    /// file, may not. The ledger read again (another scan) says the same.
    #[test]
    fn only_listed_unchanged_copies_may_be_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("fixed");
        std::fs::create_dir_all(folder.join("props")).unwrap();
        let copy = folder.join("props/crate.obj");
        assert!(may_replace(&folder, &copy).is_ok(), "nothing there");
        std::fs::write(&copy, "v 0 0 0\n").unwrap();
        let refused = may_replace(&folder, &copy).unwrap_err();
        assert!(refused.contains("meshvet did not write it"), "{refused}");
        record(&folder, &copy, blake3::hash(b"v 0 0 0\n"));
        assert!(may_replace(&folder, &copy).is_ok());
        assert!(lists(&folder, &copy));

        // Another process reads the ledger from the disk.
        books().as_mut().unwrap().remove(&folder);
        assert!(may_replace(&folder, &copy).is_ok());
        std::fs::write(&copy, "v 1 0 0\n").unwrap();
        let changed = may_replace(&folder, &copy).unwrap_err();
        assert!(changed.contains("has changed since"), "{changed}");
        let other = folder.join("props/barrel.obj");
        std::fs::create_dir(&other).unwrap();
        assert!(may_replace(&folder, &other).is_err(), "a folder");
    }

    /// A ledger with many superseded lines is rewritten with the latest per place when read; a
    /// damaged line is passed over, and a ledger without its header lists nothing.
    #[test]
    fn a_long_ledger_is_compacted_and_damage_lists_less() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().to_path_buf();
        let mut text = format!("{HEADER}\n");
        for i in 0..200u32 {
            text.push_str(&line(b"a.obj", &blake3::hash(&i.to_le_bytes())));
        }
        text.push_str("not a line\nzz 6162\n");
        std::fs::write(folder.join(LEDGER), &text).unwrap();
        std::fs::write(folder.join("a.obj"), 199u32.to_le_bytes()).unwrap();
        assert!(may_replace(&folder, &folder.join("a.obj")).is_ok());
        let after = std::fs::read_to_string(folder.join(LEDGER)).unwrap();
        assert_eq!(after.lines().count(), 2, "{after}");

        let other = tempfile::tempdir().unwrap();
        std::fs::write(
            other.path().join(LEDGER),
            line(b"a.obj", &blake3::hash(b"x")),
        )
        .unwrap();
        std::fs::write(other.path().join("a.obj"), "x").unwrap();
        assert!(may_replace(other.path(), &other.path().join("a.obj")).is_err());
    }

    /// A link at the ledger's name is neither followed when reading nor written through.
    #[cfg(unix)]
    #[test]
    fn a_link_at_the_ledgers_name_is_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("fixed");
        std::fs::create_dir(&folder).unwrap();
        let elsewhere = dir.path().join("notes.txt");
        std::fs::write(&elsewhere, format!("{HEADER}\n")).unwrap();
        std::os::unix::fs::symlink(&elsewhere, folder.join(LEDGER)).unwrap();
        record(&folder, &folder.join("a.obj"), blake3::hash(b"x"));
        assert_eq!(
            std::fs::read_to_string(&elsewhere).unwrap(),
            format!("{HEADER}\n")
        );
        assert!(!lists(&folder, &folder.join("a.obj")));
    }
}
