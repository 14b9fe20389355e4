//! The incremental cache for nightly scans (`--cache DIR`): one entry per scanned file, reused when
//! nothing that could change its rows has changed.
//!
//! **Key.** blake3 over: the cache format, meshvet's version, a hash of the effective settings (every
//! setting that can change a row: severities, weld tolerance, limits; not `jobs` or the
//! include/exclude globs, which only choose files), the file's report path, and the bytes of the
//! file and of everything its rows depend on: for `.obj`, every `mtllib` it names; for `.gltf` and
//! `.glb`, every external `buffers[].uri` and `images[].uri`. Dependencies are found by the readers'
//! own rule ([`crate::formats::contain`]): one that is missing, or that the reader would refuse
//! (absolute, a URI scheme, outside the scanned tree before or after symbolic links, not a regular
//! file), is hashed as `unavailable` and never looked at, so nothing outside the tree is read, and
//! it becoming available later changes the key.
//!
//! **Entry.** `DIR/xx/<hash of the file's identity>` (absolute path, scanned root and report path),
//! so a changed file overwrites its one entry instead of piling up new ones. It holds a header
//! line, a blake3 checksum of the rest, the key, the content hash, the file's dependencies with the
//! stamps of the file and each dependency, and the payload: the rows as CSV cells (which read back
//! exactly, see [`crate::report::Row`]), the findings and the shells. An entry is used only when
//! the header and the checksum match, every part decodes and the key matches; anything else
//! (truncated, corrupt, written by another version or for other settings) is a miss and is
//! rewritten. Entries are written atomically, so a crash leaves the old entry or the new one.
//!
//! **Stamps.** Hashing every byte of an unchanged tree costs more than it must, so, like git's
//! index, an entry records each file's stamp: size, modification and change times (ns), inode and
//! device. When every stamp is unchanged and its change time is at least 2 s older than the entry
//! (a file changed in the same clock tick could change again without a new stamp), the stored
//! content hash is used without reading the file. The change time cannot be set by tools (`touch`,
//! `tar` and `rsync -t` set only the modification time), so new bytes always mean a new stamp.
//! Otherwise the content is hashed as above, and an unchanged hash refreshes the stamps.
//!
//! **Hit.** The stored outcomes with `millis` replaced by the time the lookup took (hashing and
//! decoding); every other cell is what a fresh scan writes. Error rows are never stored: a file
//! that could not be read is read again next time. Outcomes with [`crate::scan::Detail`] (pictures
//! for the HTML report) are not cached; callers that need details bypass the cache.

use std::cell::OnceCell;
use std::io::{self, Read};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::atomic::AtomicFile;
use crate::config::Settings;
use crate::formats::contain::Location;
use crate::formats::Format;
use crate::report::{Row, ShellRow};
use crate::rules::{Finding, Rule, Severity, Status};
use crate::scan::Outcome;
use crate::topology::Role;
use crate::walk::Source;

/// First line of every entry; bump the number when the payload changes shape.
const HEADER: &str = "meshvet-cache 2";

/// An open cache folder.
pub struct Cache {
    dir: PathBuf,
    /// The current folder when the cache was opened: relative paths are made absolute against it
    /// (`std::path::absolute` asks the system for it, twice per file).
    cwd: Option<PathBuf>,
    /// blake3 of the format, the version and the row-changing settings.
    settings: blake3::Hash,
    max_file_bytes: u64,
    hits: AtomicUsize,
    misses: AtomicUsize,
    unread: AtomicUsize,
    write_errors: AtomicUsize,
}

/// How the cache did in one run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Stats {
    pub hits: usize,
    pub misses: usize,
    /// Hits answered from the file's stamps, without reading it.
    pub unread: usize,
    /// Entries that could not be written (the scan went on).
    pub write_errors: usize,
}

impl Cache {
    /// Opens (creating if needed) the cache folder `dir` for scans with `settings`.
    pub fn open(dir: &Path, settings: &Settings) -> io::Result<Cache> {
        std::fs::create_dir_all(dir)?;
        Ok(Cache {
            dir: dir.to_owned(),
            cwd: std::env::current_dir().ok(),
            settings: settings_hash(settings),
            max_file_bytes: settings.limits.max_file_bytes,
            hits: AtomicUsize::new(0),
            misses: AtomicUsize::new(0),
            unread: AtomicUsize::new(0),
            write_errors: AtomicUsize::new(0),
        })
    }

    pub fn stats(&self) -> Stats {
        Stats {
            hits: self.hits.load(Ordering::Relaxed),
            misses: self.misses.load(Ordering::Relaxed),
            unread: self.unread.load(Ordering::Relaxed),
            write_errors: self.write_errors.load(Ordering::Relaxed),
        }
    }

    /// The outcomes of `source`: from its entry when the entry is valid for the file as it is now,
    /// else from `fresh` (then stored). Never fails: cache trouble only costs time. A panic in the
    /// lookup falls back to `fresh`, and one while storing keeps the fresh outcomes, so the cache
    /// can never lose a result.
    pub fn outcomes(&self, source: &Source, fresh: impl FnOnce() -> Vec<Outcome>) -> Vec<Outcome> {
        let start = Instant::now();
        if source.error.is_some() || source.format.is_none() {
            return fresh();
        }
        let miss = match catch_unwind(AssertUnwindSafe(|| self.lookup(source, start))) {
            Ok(Lookup::Hit(outcomes)) => return outcomes,
            Ok(Lookup::Miss(miss)) => miss,
            Ok(Lookup::Uncacheable) | Err(_) => return fresh(),
        };
        self.misses.fetch_add(1, Ordering::Relaxed);
        let outcomes = fresh();
        let storable = outcomes
            .iter()
            .all(|o| o.row.status != Some(Status::Error) && o.detail.is_none());
        if storable {
            let written = catch_unwind(AssertUnwindSafe(|| {
                encode(&outcomes).and_then(|payload| {
                    write_entry(&miss.path, &miss.key, &miss.content, &miss.meta, &payload)
                })
            }));
            if !matches!(written, Ok(Ok(()))) {
                self.write_errors.fetch_add(1, Ordering::Relaxed);
            }
        }
        outcomes
    }

    /// The cached outcomes of `source` if its entry is valid, else what storing fresh ones needs.
    fn lookup(&self, source: &Source, start: Instant) -> Lookup {
        let hit = |outcomes: Vec<Outcome>| {
            self.hits.fetch_add(1, Ordering::Relaxed);
            let millis = (start.elapsed().as_secs_f64() * 1e6).round() / 1e3;
            Lookup::Hit(
                outcomes
                    .into_iter()
                    .map(|mut o| {
                        o.row.millis = Some(millis);
                        o
                    })
                    .collect(),
            )
        };
        let Some(format) = source.format else {
            return Lookup::Uncacheable;
        };
        let path = self.entry_path(source);
        let entry = read_entry(&path);
        let deps = Dependencies {
            format,
            source,
            location: OnceCell::new(),
        };
        // Fast path: the file and its dependencies carry the stamps they had when the entry was
        // written, long enough before it that a later change must have changed a stamp; the
        // content hash is then the stored one (and the key must still match these settings).
        if let Some(e) = &entry {
            let unchanged = stamps(&source.path, &deps, &e.meta.dependencies)
                .is_some_and(|now| now == e.meta.stamps && settled(&now, e.meta.written));
            if unchanged && self.key(source, &e.content) == e.key {
                if let Some(outcomes) = decode(&e.payload) {
                    self.unread.fetch_add(1, Ordering::Relaxed);
                    return hit(outcomes);
                }
            }
        }
        // Content path: hash the file and its dependencies.
        let Some((content, dependencies, stamps)) = self.content(source, &deps) else {
            return Lookup::Uncacheable;
        };
        let key = self.key(source, &content);
        let meta = Meta {
            written: now_secs(),
            dependencies,
            stamps: stamps.unwrap_or_default(),
        };
        if let Some(e) = entry.filter(|e| e.key == key) {
            if let Some(outcomes) = decode(&e.payload) {
                // Same content under new stamps (touched, copied, or too recent last time):
                // record them so the next run takes the fast path.
                let _ = write_entry(&path, &key, &content, &meta, &e.payload);
                return hit(outcomes);
            }
        }
        Lookup::Miss(Miss {
            path,
            key,
            content,
            meta,
        })
    }

    /// blake3 of the file's bytes and its dependencies' (see the module docs), the dependencies'
    /// names and the stamps taken before reading; `None` when the file cannot be cached (not a
    /// regular file, unreadable, over the size limit: the fresh scan says why).
    fn content(
        &self,
        source: &Source,
        deps: &Dependencies<'_>,
    ) -> Option<(blake3::Hash, Vec<String>, Option<Vec<String>>)> {
        let meta = std::fs::metadata(&source.path).ok()?;
        if !meta.is_file() || meta.len() > self.max_file_bytes {
            return None;
        }
        let before = stamps(&source.path, deps, &[]);
        let bytes = std::fs::read(&source.path).ok()?;
        let dependencies = dependencies(deps.format, &bytes);
        // Stamps of the dependencies too; the file's own was taken before reading it.
        let stamps = before.and_then(|mut own| {
            own.extend(
                stamps(&source.path, deps, &dependencies)?
                    .into_iter()
                    .skip(1),
            );
            Some(own)
        });
        let mut hasher = blake3::Hasher::new();
        field(&mut hasher, &bytes);
        for dependency in &dependencies {
            field(&mut hasher, dependency.as_bytes());
            match deps.resolve(dependency) {
                Some(path) => hash_file(&mut hasher, &path, self.max_file_bytes),
                None => field(&mut hasher, b"unavailable"),
            }
        }
        Some((hasher.finalize(), dependencies, stamps))
    }

    /// The entry key: the settings (with format and version), the report path and the content.
    fn key(&self, source: &Source, content: &blake3::Hash) -> blake3::Hash {
        let mut hasher = blake3::Hasher::new();
        hasher.update(self.settings.as_bytes());
        field(&mut hasher, source.display.as_bytes());
        hasher.update(content.as_bytes());
        hasher.finalize()
    }

    /// Where the entry of `source` lives.
    fn entry_path(&self, source: &Source) -> PathBuf {
        let absolute = |p: &Path| {
            let joined = match &self.cwd {
                Some(cwd) if p.is_relative() => cwd.join(p),
                _ => p.to_owned(),
            };
            std::path::absolute(&joined).unwrap_or(joined)
        };
        let mut hasher = blake3::Hasher::new();
        field(
            &mut hasher,
            absolute(&source.path).as_os_str().as_encoded_bytes(),
        );
        field(
            &mut hasher,
            absolute(&source.root).as_os_str().as_encoded_bytes(),
        );
        field(&mut hasher, source.display.as_bytes());
        let name = hasher.finalize().to_hex();
        self.dir.join(&name[..2]).join(&name[2..])
    }
}

/// Adds a length-prefixed field, so fields cannot run into each other.
fn field(hasher: &mut blake3::Hasher, bytes: &[u8]) {
    hasher.update(&(bytes.len() as u64).to_le_bytes());
    hasher.update(bytes);
}

/// What a lookup found.
enum Lookup {
    Hit(Vec<Outcome>),
    Miss(Miss),
    /// Not a file the cache can take (the fresh scan says why).
    Uncacheable,
}

/// What storing the fresh outcomes of a miss needs.
struct Miss {
    path: PathBuf,
    key: blake3::Hash,
    content: blake3::Hash,
    meta: Meta,
}

/// How a file's dependencies are found: by the reader's own rule for its format
/// ([`crate::formats::dependency`]), so the cache never looks at a file the reader would refuse.
struct Dependencies<'a> {
    format: Format,
    source: &'a Source,
    /// Where the file's dependencies may be, resolved on first use (most files have none, and
    /// resolving the tree costs a `readlink` per path component): `None` when the tree cannot be
    /// resolved, and then every dependency is unavailable, as it is to the reader.
    location: OnceCell<Option<Location>>,
}

impl Dependencies<'_> {
    /// The real path of dependency `name`, if the reader would read it.
    fn resolve(&self, name: &str) -> Option<PathBuf> {
        let location = self
            .location
            .get_or_init(|| Location::new(&self.source.path, &self.source.root).ok());
        crate::formats::dependency(self.format, name, location.as_ref()?)
    }
}

/// Hashes a dependency's bytes, or what it is when it cannot be read as a regular file.
fn hash_file(hasher: &mut blake3::Hasher, path: &Path, limit: u64) {
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
fn settings_hash(settings: &Settings) -> blake3::Hash {
    let relevant = Settings {
        jobs: 0,
        include: Vec::new(),
        exclude: Vec::new(),
        ..settings.clone()
    };
    let mut hasher = blake3::Hasher::new();
    field(&mut hasher, HEADER.as_bytes());
    field(&mut hasher, env!("CARGO_PKG_VERSION").as_bytes());
    field(&mut hasher, format!("{relevant:?}").as_bytes());
    hasher.finalize()
}

/// The relative paths a file's rows depend on, as the file names them (deduplicated, in order).
fn dependencies(format: Format, bytes: &[u8]) -> Vec<String> {
    let mut found = match format {
        Format::Obj => mtllibs(bytes),
        Format::Gltf | Format::Glb => gltf_uris(bytes),
        _ => Vec::new(),
    };
    let mut seen = std::collections::HashSet::new();
    found.retain(|d| seen.insert(d.clone()));
    found
}

/// The names after `mtllib`: the whole rest of the line and each word of it (the reader accepts a
/// name with spaces and several names).
fn mtllibs(bytes: &[u8]) -> Vec<String> {
    let mut names = Vec::new();
    let mut take = |line: &[u8]| {
        let Some(rest) = line.trim_ascii_start().strip_prefix(b"mtllib") else {
            return;
        };
        if !rest.first().is_some_and(u8::is_ascii_whitespace) {
            return;
        }
        let rest = String::from_utf8_lossy(rest);
        let rest = rest.trim();
        names.push(rest.to_owned());
        names.extend(rest.split_ascii_whitespace().map(str::to_owned));
    };
    match std::str::from_utf8(bytes) {
        // The common case: a fast substring search, then only the lines that mention `mtllib`.
        Ok(text) => {
            for (at, _) in text.match_indices("mtllib") {
                let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
                let end = text[at..].find('\n').map_or(text.len(), |i| at + i);
                if text[start..at].trim_ascii().is_empty() {
                    take(&text.as_bytes()[start..end]);
                }
            }
        }
        Err(_) => bytes.split(|&b| b == b'\n').for_each(take),
    }
    names
}

/// The external `buffers[].uri` and `images[].uri` of a glTF or GLB file (as written: the reader's
/// rule decodes them), or none when its JSON cannot be found or parsed (the reader will then report
/// the file).
fn gltf_uris(bytes: &[u8]) -> Vec<String> {
    let json = if bytes.starts_with(b"glTF") {
        // GLB: 12-byte header, then the JSON chunk (length, type, data).
        let Some(length) = bytes.get(12..16) else {
            return Vec::new();
        };
        let length = u32::from_le_bytes(length.try_into().expect("4 bytes")) as usize;
        match bytes.get(20..20usize.saturating_add(length)) {
            Some(json) => json,
            None => return Vec::new(),
        }
    } else {
        bytes
    };
    let Ok(value) = serde_json::from_slice::<serde_json::Value>(json) else {
        return Vec::new();
    };
    let mut uris = Vec::new();
    for list in ["buffers", "images"] {
        for item in value[list].as_array().into_iter().flatten() {
            if let Some(uri) = item["uri"].as_str() {
                if !uri
                    .get(..5)
                    .is_some_and(|s| s.eq_ignore_ascii_case("data:"))
                {
                    uris.push(uri.to_owned());
                }
            }
        }
    }
    uris
}

/// `(faces, holes, genus, volume as text, depth, role, inside_out)`.
type StoredShell = (usize, usize, Option<i64>, String, usize, String, bool);

/// One outcome as stored.
#[derive(Serialize, Deserialize)]
struct Stored {
    /// The row's CSV cells.
    row: Vec<String>,
    /// `(rule, severity, count, message)`.
    findings: Vec<(String, String, usize, String)>,
    /// `(faces, holes, genus, volume as text, depth, role, inside_out)`: the volume as Rust's
    /// shortest round-trip text, so even an infinite one comes back exactly.
    shells: Vec<StoredShell>,
}

fn encode(outcomes: &[Outcome]) -> io::Result<Vec<u8>> {
    let mut stored = Vec::with_capacity(outcomes.len());
    for o in outcomes {
        let mut writer = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Vec::new());
        writer.serialize(&o.row).map_err(io::Error::other)?;
        let line = writer.into_inner().map_err(|e| e.into_error())?;
        let cells = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(line.as_slice())
            .records()
            .next()
            .ok_or_else(|| io::Error::other("a row wrote no CSV record"))?
            .map_err(io::Error::other)?;
        stored.push(Stored {
            row: cells.iter().map(str::to_owned).collect(),
            findings: o
                .findings
                .iter()
                .map(|f| {
                    (
                        f.rule.name().to_owned(),
                        f.severity.name().to_owned(),
                        f.count,
                        f.message.clone(),
                    )
                })
                .collect(),
            shells: o
                .shells
                .iter()
                .map(|s| {
                    (
                        s.faces,
                        s.holes,
                        s.genus,
                        s.volume.map_or_else(String::new, |v| v.to_string()),
                        s.depth,
                        crate::json::role_name(s.role).to_owned(),
                        s.inside_out,
                    )
                })
                .collect(),
        });
    }
    serde_json::to_vec(&stored).map_err(io::Error::other)
}

fn decode(payload: &[u8]) -> Option<Vec<Outcome>> {
    let stored: Vec<Stored> = serde_json::from_slice(payload).ok()?;
    let mut outcomes = Vec::with_capacity(stored.len());
    for s in stored {
        // Cells as the CSV reader would give them (no reader to build per row: that is slow).
        let row: Row = csv::StringRecord::from(s.row).deserialize(None).ok()?;
        let findings = s
            .findings
            .into_iter()
            .map(|(rule, severity, count, message)| {
                Some(Finding {
                    rule: Rule::from_name(&rule)?,
                    severity: Severity::from_name(&severity)?,
                    count,
                    message,
                })
            })
            .collect::<Option<Vec<_>>>()?;
        let shells = s
            .shells
            .into_iter()
            .map(|(faces, holes, genus, volume, depth, role, inside_out)| {
                Some(ShellRow {
                    faces,
                    holes,
                    genus,
                    volume: if volume.is_empty() {
                        None
                    } else {
                        Some(volume.parse().ok()?)
                    },
                    depth,
                    role: match role.as_str() {
                        "solid" => Role::Solid,
                        "cavity" => Role::Cavity,
                        _ => return None,
                    },
                    inside_out,
                })
            })
            .collect::<Option<Vec<_>>>()?;
        outcomes.push(Outcome {
            row,
            findings,
            shells,
            detail: None,
        });
    }
    (!outcomes.is_empty()).then_some(outcomes)
}

/// What an entry records besides the key and the outcomes.
#[derive(Serialize, Deserialize)]
struct Meta {
    /// When the entry was written (Unix seconds).
    written: u64,
    /// The dependencies the file named (relative to its folder).
    dependencies: Vec<String>,
    /// Stamps of the file, then of each dependency (see [`stamp`]); empty where stamps are not
    /// available (then every run hashes the content).
    stamps: Vec<String>,
}

/// A whole entry: checked header and checksum, parsed parts.
struct Entry {
    key: blake3::Hash,
    content: blake3::Hash,
    meta: Meta,
    payload: Vec<u8>,
}

/// The entry at `path` if it is whole: the header, then a checksum of the rest, then key, content
/// hash, meta and payload. Anything else (missing, truncated, corrupt, foreign) is `None`.
fn read_entry(path: &Path) -> Option<Entry> {
    // Plain reads into a buffer that fits most entries: no size query, one read and the one that
    // sees the end (a warm re-scan does this for every file, so syscalls count).
    let mut file = std::fs::File::open(path).ok()?;
    let mut bytes = vec![0u8; 16 << 10];
    let mut len = 0;
    loop {
        if len == bytes.len() {
            bytes.resize(2 * len, 0);
        }
        match file.read(&mut bytes[len..]) {
            Ok(0) => break,
            Ok(n) => len += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(_) => return None,
        }
    }
    bytes.truncate(len);
    let mut parts = bytes.splitn(3, |&b| b == b'\n');
    let (header, sum, body) = (parts.next()?, parts.next()?, parts.next()?);
    if header != HEADER.as_bytes() || sum != blake3::hash(body).to_hex().as_bytes() {
        return None;
    }
    let mut parts = body.splitn(4, |&b| b == b'\n');
    let hash = |hex: &[u8]| blake3::Hash::from_hex(hex).ok();
    Some(Entry {
        key: hash(parts.next()?)?,
        content: hash(parts.next()?)?,
        meta: serde_json::from_slice(parts.next()?).ok()?,
        payload: parts.next()?.to_vec(),
    })
}

fn write_entry(
    path: &Path,
    key: &blake3::Hash,
    content: &blake3::Hash,
    meta: &Meta,
    payload: &[u8],
) -> io::Result<()> {
    let mut body = Vec::with_capacity(payload.len() + 300);
    body.extend_from_slice(key.to_hex().as_bytes());
    body.push(b'\n');
    body.extend_from_slice(content.to_hex().as_bytes());
    body.push(b'\n');
    serde_json::to_writer(&mut body, meta)?;
    body.push(b'\n');
    body.extend_from_slice(payload);
    let mut bytes = Vec::with_capacity(body.len() + 100);
    bytes.extend_from_slice(HEADER.as_bytes());
    bytes.push(b'\n');
    bytes.extend_from_slice(blake3::hash(&body).to_hex().as_bytes());
    bytes.push(b'\n');
    bytes.extend_from_slice(&body);
    if let Some(folder) = path.parent() {
        std::fs::create_dir_all(folder)?;
    }
    AtomicFile::write_all(path, &bytes)
}

fn now_secs() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

/// Stamps of `file` and of each dependency (where the reader's rule resolves it): size,
/// modification and change times to the nanosecond, inode and device, or `missing`; a dependency
/// the reader would not read (outside the tree, not a regular file, not there) is `unavailable`
/// and is never looked at. The change time cannot be set by any tool (`touch -d`, `tar`,
/// `rsync -t` set only the modification time), so new content under an old modification time
/// still changes the stamp. `None` where the platform has no such stamps.
fn stamps(file: &Path, deps: &Dependencies<'_>, dependencies: &[String]) -> Option<Vec<String>> {
    let mut stamps = vec![stamp(file)?];
    for d in dependencies {
        stamps.push(match deps.resolve(d) {
            Some(path) => stamp(&path)?,
            None => "unavailable".to_owned(),
        });
    }
    Some(stamps)
}

#[cfg(unix)]
fn stamp(path: &Path) -> Option<String> {
    use std::os::unix::fs::MetadataExt;
    Some(match std::fs::metadata(path) {
        Ok(m) => format!(
            "{} {}.{} {}.{} {} {}",
            m.len(),
            m.mtime(),
            m.mtime_nsec(),
            m.ctime(),
            m.ctime_nsec(),
            m.ino(),
            m.dev()
        ),
        Err(e) => format!("missing {:?}", e.kind()),
    })
}

#[cfg(not(unix))]
fn stamp(_: &Path) -> Option<String> {
    None
}

/// Whether every stamp's change time is at least 2 s before `written`: a file changed in the same
/// clock tick as its stamp was taken could change again without changing the stamp (git's "racy
/// clean" problem), so such an entry is checked by content.
fn settled(stamps: &[String], written: u64) -> bool {
    stamps.iter().all(|s| {
        let ctime = s.split(' ').nth(2).and_then(|t| t.split('.').next());
        match ctime.and_then(|t| t.parse::<i64>().ok()) {
            Some(ctime) => ctime.saturating_add(2) <= written as i64,
            // `missing` or `unavailable`: nothing that could change silently.
            None => !s.starts_with(char::is_numeric),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::scan_file;
    use crate::walk::{walk, Filter};

    const OPEN: &str = "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

    fn setup() -> (tempfile::TempDir, Cache, Source) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("tree")).unwrap();
        std::fs::write(dir.path().join("tree/m.obj"), OPEN).unwrap();
        let cache = Cache::open(&dir.path().join("cache"), &Settings::default()).unwrap();
        let source = walk(&[dir.path().join("tree")], &Filter::everything()).remove(0);
        (dir, cache, source)
    }

    fn without_millis(mut outcomes: Vec<Outcome>) -> Vec<Outcome> {
        for o in &mut outcomes {
            o.row.millis = None;
        }
        outcomes
    }

    #[test]
    fn a_hit_equals_a_fresh_scan_except_millis() {
        let (_dir, cache, source) = setup();
        let settings = Settings::default();
        let fresh = cache.outcomes(&source, || scan_file(&source, &settings));
        let again = cache.outcomes(&source, || panic!("must come from the cache"));
        assert_eq!(cache.stats().hits, 1);
        assert_eq!(without_millis(fresh), without_millis(again));
    }

    #[test]
    fn a_changed_file_or_dependency_is_a_miss() {
        let (dir, cache, source) = setup();
        let settings = Settings::default();
        cache.outcomes(&source, || scan_file(&source, &settings));
        // The MTL appears: the key changes.
        std::fs::write(dir.path().join("tree/a.mtl"), "newmtl x\n").unwrap();
        let rows = cache.outcomes(&source, || scan_file(&source, &settings));
        assert_eq!(cache.stats().misses, 2);
        assert!(
            !rows[0].row.message.contains("not found"),
            "{}",
            rows[0].row.message
        );
        std::fs::write(dir.path().join("tree/m.obj"), format!("{OPEN}f 1 3 2\n")).unwrap();
        cache.outcomes(&source, || scan_file(&source, &settings));
        assert_eq!(cache.stats().misses, 3);
        // Other settings: another key.
        let mut strict = Settings::default();
        strict.severities.set(Rule::DuplicateFace, Severity::Error);
        let other = Cache::open(&dir.path().join("cache"), &strict).unwrap();
        let rows = other.outcomes(&source, || scan_file(&source, &strict));
        assert_eq!(other.stats().misses, 1);
        assert_eq!(rows[0].row.status, Some(Status::Fail));
    }

    #[test]
    fn corrupt_truncated_or_foreign_entries_are_recomputed() {
        let (_dir, cache, source) = setup();
        let settings = Settings::default();
        let fresh = without_millis(cache.outcomes(&source, || scan_file(&source, &settings)));
        let entry = cache.entry_path(&source);
        let good = std::fs::read(&entry).unwrap();
        let flip_last = {
            let mut b = good.clone();
            *b.last_mut().unwrap() ^= 1;
            b
        };
        let foreign = String::from_utf8(good.clone())
            .unwrap()
            .replacen(HEADER, "meshvet-cache 0", 1)
            .into_bytes();
        for bad in [
            flip_last,
            good[..good.len() / 2].to_vec(),
            foreign,
            Vec::new(),
        ] {
            std::fs::write(&entry, &bad).unwrap();
            let misses = cache.stats().misses;
            let got = cache.outcomes(&source, || scan_file(&source, &settings));
            assert_eq!(cache.stats().misses, misses + 1, "not trusted");
            assert_eq!(without_millis(got), fresh);
            let again = cache.outcomes(&source, || panic!("the entry was rewritten"));
            assert_eq!(without_millis(again), fresh);
        }
    }

    /// Pretends the entry of `source` was written `seconds` later than it was.
    fn age(cache: &Cache, source: &Source, seconds: u64) {
        let path = cache.entry_path(source);
        let mut e = read_entry(&path).unwrap();
        e.meta.written += seconds;
        write_entry(&path, &e.key, &e.content, &e.meta, &e.payload).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn settled_stamps_skip_reading_and_any_change_is_still_seen() {
        let (dir, cache, source) = setup();
        let settings = Settings::default();
        let fresh = without_millis(cache.outcomes(&source, || scan_file(&source, &settings)));
        // Just written: too recent to trust the stamps, so the content is hashed.
        cache.outcomes(&source, || panic!("unchanged"));
        assert_eq!(cache.stats().unread, 0);
        age(&cache, &source, 10);
        let got = cache.outcomes(&source, || panic!("unchanged"));
        assert_eq!(cache.stats().unread, 1, "answered from the stamps");
        assert_eq!(without_millis(got), fresh);

        // Same size, modification time put back: the change time still differs.
        let file = dir.path().join("tree/m.obj");
        let mtime = std::fs::metadata(&file).unwrap().modified().unwrap();
        std::fs::write(&file, OPEN.replace("f 1 2 3", "f 1 3 2")).unwrap();
        std::fs::File::options()
            .write(true)
            .open(&file)
            .unwrap()
            .set_modified(mtime)
            .unwrap();
        let misses = cache.stats().misses;
        let got = cache.outcomes(&source, || scan_file(&source, &settings));
        assert_eq!(cache.stats().misses, misses + 1);
        assert_eq!(
            without_millis(got),
            without_millis(scan_file(&source, &settings))
        );
        // A dependency appearing changes its stamp from `missing`.
        age(&cache, &source, 10);
        std::fs::write(dir.path().join("tree/a.mtl"), "newmtl x\n").unwrap();
        let misses = cache.stats().misses;
        cache.outcomes(&source, || scan_file(&source, &settings));
        assert_eq!(cache.stats().misses, misses + 1);
    }

    /// A file in the tree that names `dependency`, which `place` puts outside the tree (or links
    /// to from inside); the outside file then changes. The cache must not have looked at it: the
    /// second lookup is a hit (before, its bytes were in the key, so it was a miss).
    fn outside_dependency_is_never_read(name: &str, text: &str, place: impl Fn(&Path)) {
        let dir = tempfile::tempdir().unwrap();
        let tree = dir.path().join("tree");
        std::fs::create_dir(&tree).unwrap();
        std::fs::write(tree.join(name), text).unwrap();
        std::fs::write(dir.path().join("outside.bin"), "secret").unwrap();
        place(dir.path());
        let cache = Cache::open(&dir.path().join("cache"), &Settings::default()).unwrap();
        let source = walk(&[tree], &Filter::everything()).remove(0);
        let settings = Settings::default();
        cache.outcomes(&source, || scan_file(&source, &settings));
        std::fs::write(dir.path().join("outside.bin"), "changed secret").unwrap();
        cache.outcomes(&source, || scan_file(&source, &settings));
        assert_eq!(cache.stats().hits, 1, "{name}: the outside file was read");
    }

    /// A glTF whose rows do not depend on its image (error rows are never stored, so the name
    /// is an image: the reader ignores it, the cache hashes it).
    const GLTF: &str = r#"{"asset":{"version":"2.0"},"images":[{"uri":"URI"}],
        "meshes":[{"primitives":[{"attributes":{}}]}]}"#;

    #[test]
    fn dependencies_outside_the_tree_are_never_read() {
        outside_dependency_is_never_read(
            "m.obj",
            &format!("mtllib ../outside.bin\n{OPEN}"),
            |_| {},
        );
        outside_dependency_is_never_read("m.gltf", &GLTF.replace("URI", "../outside.bin"), |_| {});
        outside_dependency_is_never_read(
            "m.gltf",
            &GLTF.replace("URI", "..%2Foutside.bin"),
            |_| {},
        );
        #[cfg(unix)]
        {
            let link = |dir: &Path| {
                std::os::unix::fs::symlink(dir.join("outside.bin"), dir.join("tree/link.bin"))
                    .unwrap()
            };
            outside_dependency_is_never_read("m.obj", &format!("mtllib link.bin\n{OPEN}"), link);
            outside_dependency_is_never_read("m.gltf", &GLTF.replace("URI", "link.bin"), link);
        }
    }

    #[test]
    fn a_dependency_inside_the_tree_is_still_hashed() {
        let (dir, cache, source) = setup();
        let settings = Settings::default();
        std::fs::write(dir.path().join("tree/a.mtl"), "newmtl x\n").unwrap();
        cache.outcomes(&source, || scan_file(&source, &settings));
        std::fs::write(dir.path().join("tree/a.mtl"), "newmtl y\n").unwrap();
        cache.outcomes(&source, || scan_file(&source, &settings));
        assert_eq!(cache.stats().misses, 2);
    }

    #[test]
    fn dependencies_are_found_in_obj_gltf_and_glb() {
        assert_eq!(
            dependencies(Format::Obj, b"v 0 0 0\n  mtllib a b.mtl\nmtllibx c\n"),
            ["a b.mtl", "a", "b.mtl"]
        );
        let gltf = br#"{"buffers":[{"uri":"../buffers/x%20y.bin"},{"uri":"data:,"}],"images":[{"uri":"t.png"}]}"#;
        assert_eq!(
            dependencies(Format::Gltf, gltf),
            ["../buffers/x%20y.bin", "t.png"]
        );
        let mut glb = b"glTF\x02\0\0\0\0\0\0\0".to_vec();
        glb.extend_from_slice(&(gltf.len() as u32).to_le_bytes());
        glb.extend_from_slice(b"JSON");
        glb.extend_from_slice(gltf);
        assert_eq!(dependencies(Format::Glb, &glb).len(), 2);
    }
}
