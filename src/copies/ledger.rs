//! The repair folder's ledger: which copies meshvet put there, so a copy replaces only a file
//! meshvet wrote and nobody has changed since.
//!
//! A repair folder mirrors the scanned tree, so a copy's place may hold anything: last night's
//! copy (to be replaced), but also a file of the user's (a folder inside the scanned tree that
//! happens to hold models, another asset library named by mistake). Before it, every copy was
//! renamed over whatever was at its place. Now the folder keeps a file `.meshvet-copies`: a header
//! line, then one line per copy put in place, the blake3 hash of its bytes and its path under the
//! folder (both in hex, so any name's bytes fit; folders joined by `/` on every system). A copy
//! may replace a file only when the ledger's latest line for that place has the file's hash.
//!
//! Several scans may write into one folder at once (shards, parallel CI jobs). Each line is
//! appended in one write, under a shared lock of the ledger, and begins with a line end, so a line
//! cut short by a killed scan never swallows the next. Before refusing a place it does not list,
//! a scan reads the ledger again (another scan may have put the copy there since). A ledger of
//! more than twice as many lines as places is rewritten with one line per place, under the
//! exclusive lock, from what the locked file holds; a scan appending meanwhile waits, then finds
//! the new ledger (unix; elsewhere it is never rewritten). A ledger that is missing, a link, not a
//! file or damaged lists nothing or less, and lines that are not what this module writes are
//! passed over one by one: a copy then fails with a note rather than replace an unlisted file.
//! A ledger that cannot be written is said in the row of the copy that could not be listed.

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use rustc_hash::FxHashMap;

use crate::atomic::{open_own, AtomicFile};

/// The ledger's name in the repair folder.
pub const LEDGER: &str = ".meshvet-copies";

/// The first line of a ledger.
const HEADER: &str = "meshvet-copies 1";

/// The most of a ledger that is read (about five million copies).
const MOST_READ: u64 = 1 << 30;

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

/// The book of `folder`, read from the disk the first time.
fn book_of<'a>(
    books: &'a mut MutexGuard<'static, Option<FxHashMap<PathBuf, Book>>>,
    folder: &Path,
) -> &'a mut Book {
    books
        .get_or_insert_with(FxHashMap::default)
        .entry(folder.to_path_buf())
        .or_insert_with(|| read(folder))
}

/// The bytes of `place`'s path under `folder`, its names joined by `/`; `None` when it is not
/// under it.
fn key(folder: &Path, place: &Path) -> Option<Vec<u8>> {
    let relative = place.strip_prefix(folder).ok()?;
    let mut key = Vec::new();
    for part in relative.components() {
        let Component::Normal(name) = part else {
            return None;
        };
        if !key.is_empty() {
            key.push(b'/');
        }
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStrExt;
            key.extend_from_slice(name.as_bytes());
        }
        #[cfg(not(unix))]
        key.extend_from_slice(name.to_string_lossy().as_bytes());
    }
    Some(key)
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

/// A ledger line, with the line end before it that keeps a torn line from joining it.
fn line(place: &[u8], digest: &blake3::Hash) -> String {
    format!("\n{} {}", digest.to_hex(), hex(place))
}

/// Opens the ledger at `path` ([`open_own`]: no link followed, no FIFO waited on), for appending
/// (created if missing) when `create`; `None` unless a regular file is opened.
fn open(path: &Path, create: bool) -> Option<File> {
    let mut options = File::options();
    options.read(true);
    if create {
        options.append(true).create(true);
    }
    open_own(path, &mut options).ok()
}

/// The places `bytes` (a ledger's content) lists, and how many lines it has for them; empty
/// unless it begins with the header.
fn parse(bytes: &[u8]) -> (FxHashMap<Vec<u8>, blake3::Hash>, usize) {
    let mut places = FxHashMap::default();
    let mut lines = bytes.split(|&b| b == b'\n');
    if lines.next() != Some(HEADER.as_bytes()) {
        return (places, 0);
    }
    let mut count = 0;
    for l in lines {
        let Some((digest, place)) = std::str::from_utf8(l).ok().and_then(|l| l.split_once(' '))
        else {
            continue;
        };
        let (Ok(digest), Some(place)) = (blake3::Hash::from_hex(digest), unhex(place)) else {
            continue;
        };
        count += 1;
        places.insert(place, digest);
    }
    (places, count)
}

/// Reads the whole of `file` (at most [`MOST_READ`] bytes) from its start.
fn content(file: &File) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut from = file;
    let _ = std::io::Seek::rewind(&mut from).and_then(|()| {
        from.take(MOST_READ).read_to_end(&mut bytes)?;
        Ok(())
    });
    bytes
}

/// Reads the ledger of `folder` (see the module docs); rewrites it with one line per place when
/// more than half of its lines are superseded.
fn read(folder: &Path) -> Book {
    let path = folder.join(LEDGER);
    let Some(file) = open(&path, false) else {
        return Book::default();
    };
    let (places, count) = parse(&content(&file));
    if count > 2 * places.len() + 64 {
        compact(&path, &file);
    }
    Book { places }
}

/// Rewrites the ledger `file` (open at `path`) with the latest line per place, under its exclusive
/// lock and from what it holds once locked; nothing when another scan holds the lock.
#[cfg(unix)]
fn compact(path: &Path, file: &File) {
    if file.try_lock().is_err() {
        return;
    }
    let (places, _) = parse(&content(file));
    let mut sorted: Vec<_> = places.iter().collect();
    sorted.sort_by(|a, b| a.0.cmp(b.0));
    let mut text = HEADER.to_owned();
    for (place, digest) in sorted {
        text.push_str(&line(place, digest));
    }
    // Appenders wait on the lock of this file, then find the new one at the path.
    let _ = AtomicFile::create(path).and_then(|mut f| {
        f.write_all(text.as_bytes())?;
        f.commit()
    });
    let _ = file.unlock();
}

#[cfg(not(unix))]
fn compact(_: &Path, _: &File) {}

/// Whether `file` is still the file at `path` (a compaction may have replaced it).
#[cfg(unix)]
fn still_at(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::symlink_metadata(path)) {
        (Ok(a), Ok(b)) => a.ino() == b.ino() && a.dev() == b.dev(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn still_at(_: &File, _: &Path) -> bool {
    true
}

/// Appends `text` to the ledger at `path` under its shared lock, to the file at `path` once the
/// lock is held (see [`compact`]), with the header first in a new ledger.
fn append(path: &Path, text: &str) -> Result<(), String> {
    let cannot = |why: &str| format!("{} cannot be written: {why}", path.display());
    for _ in 0..8 {
        let file = open(path, true).ok_or_else(|| cannot("it is not a regular file"))?;
        file.lock_shared().map_err(|e| cannot(&e.to_string()))?;
        if !still_at(&file, path) {
            continue;
        }
        let mut out = String::new();
        if file.metadata().is_ok_and(|m| m.len() == 0) {
            out.push_str(HEADER);
        }
        out.push_str(text);
        return (&file)
            .write_all(out.as_bytes())
            .map_err(|e| cannot(&e.to_string()));
    }
    Err(cannot("it keeps being replaced"))
}

/// The hash a ledger line gives the regular file at `path`.
pub fn digest(path: &Path) -> std::io::Result<blake3::Hash> {
    let mut hasher = blake3::Hasher::new();
    hasher.update_reader(crate::formats::open_regular(path)?)?;
    Ok(hasher.finalize())
}

/// Whether the ledger of `folder` lists `place` (whatever it holds now).
pub fn lists(folder: &Path, place: &Path) -> bool {
    let Some(key) = key(folder, place) else {
        return false;
    };
    book_of(&mut books(), folder).places.contains_key(&key)
}

/// `Ok` when a copy may be put at `place` in the repair folder `folder`: nothing is there
/// (`None`), or the copy meshvet put there last, unchanged (its hash). Else what is in the way
/// and what to do.
pub fn may_replace(folder: &Path, place: &Path) -> Result<Option<blake3::Hash>, String> {
    let meta = match std::fs::symlink_metadata(place) {
        Ok(meta) => meta,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("cannot look at {}: {e}", place.display())),
    };
    let advice = "move it away, or repair into another folder";
    if !meta.is_file() {
        return Err(format!(
            "{} is already there and is not a file meshvet wrote - {advice}",
            place.display()
        ));
    }
    let Some(key) = key(folder, place) else {
        return Err(format!(
            "{} is not inside the repair folder (internal error: please report this file)",
            place.display()
        ));
    };
    let now = digest(place).map_err(|e| format!("cannot read {}: {e}", place.display()))?;
    let mut books = books();
    let book = book_of(&mut books, folder);
    if book.places.get(&key) != Some(&now) {
        // Another scan may have put its copy there since this one read the ledger.
        book.places.extend(read(folder).places);
    }
    match book.places.get(&key) {
        Some(listed) if *listed == now => Ok(Some(now)),
        Some(_) => Err(format!(
            "{} is not the copy meshvet put there last (it has changed since) - {advice}",
            place.display()
        )),
        None => Err(format!(
            "{} is already there and is not in the repair folder's list of the copies meshvet \
             wrote ({LEDGER}) - {advice} (an earlier copy whose listing was lost can be removed)",
            place.display()
        )),
    }
}

/// Lists the copy of hash `digest` now at `place` in the ledger of `folder`; what went wrong when
/// the ledger cannot be written (that copy is then not replaced by the next scan).
pub fn record(folder: &Path, place: &Path, digest: blake3::Hash) -> Result<(), String> {
    let key = key(folder, place).ok_or_else(|| {
        format!(
            "{} is not inside the repair folder (internal error: please report this file)",
            place.display()
        )
    })?;
    let mut books = books();
    let book = book_of(&mut books, folder);
    book.places.insert(key.clone(), digest);
    append(&folder.join(LEDGER), &line(&key, &digest))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Forgets what this process read of `folder`'s ledger, as another process would not know it.
    fn forget(folder: &Path) {
        books().as_mut().map(|b| b.remove(folder));
    }

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
        assert!(
            refused.contains("is not in the repair folder's list"),
            "{refused}"
        );
        record(&folder, &copy, blake3::hash(b"v 0 0 0\n")).unwrap();
        assert!(may_replace(&folder, &copy).is_ok());
        assert!(lists(&folder, &copy));

        forget(&folder);
        assert!(may_replace(&folder, &copy).is_ok());
        std::fs::write(&copy, "v 1 0 0\n").unwrap();
        let changed = may_replace(&folder, &copy).unwrap_err();
        assert!(changed.contains("has changed since"), "{changed}");
        let other = folder.join("props/barrel.obj");
        std::fs::create_dir(&other).unwrap();
        assert!(may_replace(&folder, &other).is_err(), "a folder");
    }

    /// A copy another scan put in place and listed after this one read the ledger may be
    /// replaced: the ledger is read again before a place is refused (before, two scans into one
    /// folder refused each other's copies).
    #[test]
    fn a_copy_another_scan_listed_since_may_be_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().to_path_buf();
        let copy = folder.join("a.obj");
        assert!(
            !lists(&folder, &copy),
            "this scan has read the (empty) ledger"
        );
        std::fs::write(&copy, "theirs").unwrap();
        let line = line(&key(&folder, &copy).unwrap(), &blake3::hash(b"theirs"));
        std::fs::write(folder.join(LEDGER), format!("{HEADER}{line}")).unwrap();
        assert!(may_replace(&folder, &copy).is_ok());
    }

    /// A ledger with many superseded lines is rewritten with the latest per place when read; a
    /// damaged line (bytes that are not UTF-8, a line cut short) is passed over alone, and a
    /// ledger without its header lists nothing.
    #[test]
    fn a_long_ledger_is_compacted_and_damage_costs_its_own_lines_only() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().to_path_buf();
        let mut text = HEADER.as_bytes().to_vec();
        for i in 0..200u32 {
            text.extend(line(b"a.obj", &blake3::hash(&i.to_le_bytes())).bytes());
        }
        text.extend(b"\nnot a line\nzz\xff 6162\n6162");
        text.extend(line(b"b.obj", &blake3::hash(b"b")).bytes());
        std::fs::write(folder.join(LEDGER), &text).unwrap();
        std::fs::write(folder.join("a.obj"), 199u32.to_le_bytes()).unwrap();
        std::fs::write(folder.join("b.obj"), "b").unwrap();
        assert!(may_replace(&folder, &folder.join("a.obj")).is_ok());
        assert!(may_replace(&folder, &folder.join("b.obj")).is_ok());
        let after = std::fs::read_to_string(folder.join(LEDGER)).unwrap();
        assert_eq!(after.lines().count(), 3, "{after}");

        let other = tempfile::tempdir().unwrap();
        std::fs::write(
            other.path().join(LEDGER),
            line(b"a.obj", &blake3::hash(b"x")),
        )
        .unwrap();
        std::fs::write(other.path().join("a.obj"), "x").unwrap();
        assert!(may_replace(other.path(), &other.path().join("a.obj")).is_err());
    }

    /// A line appended while another scan rewrites the ledger lands in the rewritten ledger: the
    /// appender waits for the rewriter's lock, then finds the new file at the ledger's name
    /// (before, a line appended to the old file between its reading and the rename was lost, and
    /// its copy was refused every night after).
    #[cfg(unix)]
    #[test]
    fn a_line_appended_during_a_rewrite_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(LEDGER);
        let old = format!("{HEADER}{}", line(b"a.obj", &blake3::hash(b"a")));
        std::fs::write(&path, &old).unwrap();
        let rewriter = open(&path, false).unwrap();
        rewriter.lock().unwrap();
        let appender = {
            let path = path.clone();
            std::thread::spawn(move || append(&path, &line(b"b.obj", &blake3::hash(b"b"))))
        };
        std::thread::sleep(std::time::Duration::from_millis(200));
        let new = dir.path().join("new");
        std::fs::write(&new, &old).unwrap();
        std::fs::rename(&new, &path).unwrap();
        rewriter.unlock().unwrap();
        appender.join().unwrap().unwrap();
        let (places, _) = parse(&std::fs::read(&path).unwrap());
        assert_eq!(places.len(), 2, "{places:?}");
    }

    /// A link at the ledger's name is neither followed when reading nor written through, and a
    /// ledger that cannot be written is said.
    #[cfg(unix)]
    #[test]
    fn a_link_at_the_ledgers_name_is_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("fixed");
        std::fs::create_dir(&folder).unwrap();
        let elsewhere = dir.path().join("notes.txt");
        std::fs::write(&elsewhere, HEADER).unwrap();
        std::os::unix::fs::symlink(&elsewhere, folder.join(LEDGER)).unwrap();
        let e = record(&folder, &folder.join("a.obj"), blake3::hash(b"x")).unwrap_err();
        assert!(e.contains("cannot be written"), "{e}");
        assert_eq!(std::fs::read_to_string(&elsewhere).unwrap(), HEADER);
        forget(&folder);
        assert!(!lists(&folder, &folder.join("a.obj")));
    }

    /// Places are named the same on every system: folders joined by `/`.
    #[test]
    fn places_are_named_with_slashes() {
        let folder = Path::new("fixed");
        assert_eq!(
            key(folder, &folder.join("props").join("crate.obj")).unwrap(),
            b"props/crate.obj"
        );
    }
}
