//! The incremental cache for nightly scans (`--cache DIR`): one entry per scanned file, reused when
//! nothing that could change its rows has changed.
//!
//! **Key.** blake3 over: the cache format, meshvet's version, the report's columns, a hash of the
//! effective settings (every setting that can change a row: severities, weld tolerance, limits; not
//! `jobs` or the include/exclude globs, which only choose files), the file's report path, and the
//! bytes of the file and of everything its rows depend on: for `.obj`, every `mtllib` it names; for
//! `.gltf` and `.glb`, every external `buffers[].uri` and `images[].uri`. Dependencies are found by
//! the readers' own rule ([`crate::formats::contain`]): one that is missing, or that the reader
//! would refuse (absolute, a URI scheme, outside the scanned tree before or after symbolic links,
//! not a regular file), is hashed as `unavailable` and never looked at, so nothing outside the tree
//! is read, and it becoming available later changes the key.
//!
//! **Packs.** Entries are records in pack files, `DIR/pack-<unix ns>-<pid>-<n>`, each written by
//! one run and only ever appended to. A record is a frame (a marker, a 64-bit hash of the file's
//! identity - its path and scanned root, with the current folder when relative, and its report
//! path -, the body's length, and a check of those two) followed by the entry's body. Opening the
//! cache reads every pack once, in name order, and keeps only an index: for each identity, where
//! its latest record is (about 25 bytes a file, no payload). A hit reads its record with a
//! positioned read, which also reads ahead: files are looked up in the order the last run wrote
//! them, so one read serves the next records too. A frame that does not check (a torn tail after a
//! crash, bit rot, an edit) is skipped to the next marker, so damage costs the records it touches,
//! not the rest of the pack. A run appends its misses and refreshed stamps to a pack of its own,
//! created on its first write (a warm run writes nothing); they are seen by later runs, not by the
//! run itself. The one-file-per-entry folders of format 2 (`DIR/xx/...`) are ignored, and removed
//! by the next compaction.
//!
//! **Entry.** A record's body holds a header line, a blake3 checksum of the rest, the key, the
//! content hash, when it was written, the file's dependencies with the stamps of the file and each
//! dependency, and the payload: the rows as CSV cells (which read back exactly, see
//! [`crate::report::Row`]), the findings and the shells. An entry is used only when its frame
//! names the file, the header and the checksum match, every part decodes and the key matches;
//! anything else (truncated, corrupt, written by another version or for other settings) is a miss
//! and is written again.
//!
//! **Sharing and compaction.** Several runs may use one folder at once (shards): each holds a
//! shared lock on `DIR/lock` while open, and never changes a pack it did not write. A run that
//! finishes ([`Cache::finish`]) lets go of its lock and takes the exclusive one only if no other
//! run holds the folder; then, when the folder has more than [`MAX_PACKS`] packs, damaged bytes or
//! more superseded records than live ones, it copies the live records that verify into one new
//! pack (written under a temporary name, synced, renamed) and only then removes the old packs. So
//! no pack is removed while another run reads or writes it, and a crash at any point leaves packs
//! whose records are verified before use: a crash may cost entries, never give a wrong row. On a
//! file system without locks the cache works but never compacts.
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

use std::cell::{OnceCell, RefCell};
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

use crate::atomic::AtomicFile;
use crate::config::Settings;
use crate::formats::contain::Location;
use crate::formats::Format;
use crate::report::{Row, ShellRow};
use crate::rules::{Finding, Rule, Severity, Status};
use crate::scan::Outcome;
use crate::topology::Role;
use crate::walk::Source;

/// First line of every entry's body; bump the number when the body changes shape.
const HEADER: &[u8] = b"meshvet-cache 4\n";
/// Starts every record. 0xF5 never occurs in UTF-8, so a search for the next record after damage
/// rarely stops inside a body (and a false stop fails the frame's check).
const MAGIC: [u8; 4] = [0xF5, b'm', b'v', b'3'];
/// A record's frame: marker, identity, body length, check of the two.
const FRAME: usize = 4 + 8 + 4 + 4;
/// A finishing run that has the folder to itself merges more packs than this into one.
pub const MAX_PACKS: usize = 8;
/// Packs are read in pieces of this size when opened or compacted.
const WINDOW: usize = 1 << 20;
/// No body is this long (a file has a few rows); a frame that says so is damaged.
const MAX_BODY: usize = 1 << 28;
/// Index positions: the pack's number above, the offset in it below.
const OFFSET_BITS: u32 = 40;

/// A hash of a file's identity (see [`Cache::identity`]).
type Id = u64;

/// An open cache folder.
pub struct Cache {
    /// Tells this cache's read-ahead from another's.
    serial: u64,
    dir: PathBuf,
    /// The current folder when the cache was opened: relative paths are identified with it.
    cwd: Vec<u8>,
    /// blake3 of the format, the version and the row-changing settings.
    settings: blake3::Hash,
    max_file_bytes: u64,
    /// `DIR/lock`, held shared while open; `None` where the file system has no locks.
    lock: Option<File>,
    /// The packs read when opening, by number.
    packs: Vec<Pack>,
    /// The latest record of each identity.
    index: Index,
    /// What opening found, so finishing can tell whether compaction is due without reading again.
    found: Found,
    own: Mutex<Own>,
    /// Records this run appended for identities the index already had.
    superseded: AtomicUsize,
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

/// Where a record is: 24 bytes per indexed file.
#[derive(Clone, Copy)]
struct Slot {
    id: Id,
    /// Pack number and offset (see [`OFFSET_BITS`]); a later record has a larger one.
    at: u64,
    /// The whole record's length, frame included.
    len: u32,
}

/// The slots sorted by identity, and where each run of leading identity bits starts (identities
/// are hashes, so spread evenly): a lookup looks at about two slots, and the table costs at most
/// 2 bytes a slot.
struct Index {
    slots: Vec<Slot>,
    /// `starts[b]`: the first slot whose identity's top `bits` bits are at least `b`; then the end.
    starts: Vec<u32>,
    bits: u32,
}

impl Index {
    /// `slots` sorted by identity, each identity once.
    fn new(mut slots: Vec<Slot>) -> Index {
        slots.shrink_to_fit();
        let bits = (slots.len() / 2).max(1).ilog2().min(24);
        let mut starts = vec![0u32; (1 << bits) + 1];
        for slot in &slots {
            starts[Index::bucket(slot.id, bits) + 1] += 1;
        }
        for b in 1..starts.len() {
            starts[b] += starts[b - 1];
        }
        Index {
            slots,
            starts,
            bits,
        }
    }

    fn bucket(id: Id, bits: u32) -> usize {
        id.checked_shr(64 - bits).unwrap_or(0) as usize
    }

    fn get(&self, id: Id) -> Option<Slot> {
        let b = Index::bucket(id, self.bits);
        let (from, to) = (self.starts[b] as usize, self.starts[b + 1] as usize);
        self.slots[from..to].iter().find(|s| s.id == id).copied()
    }

    fn len(&self) -> usize {
        self.slots.len()
    }

    fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }
}

impl Slot {
    fn pack(self) -> usize {
        (self.at >> OFFSET_BITS) as usize
    }

    fn offset(self) -> u64 {
        self.at & ((1 << OFFSET_BITS) - 1)
    }
}

/// What listing and reading the packs found.
struct Found {
    /// The packs read, by number.
    names: Vec<String>,
    /// Records in them, superseded ones included.
    records: usize,
    /// Bytes that are no record (a torn tail, damage), or a pack that could not be read.
    damaged: bool,
    /// The largest time in a pack name: new packs are named later even if the clock went back.
    newest: u64,
}

/// This run's own pack, created on its first write.
#[derive(Default)]
struct Own {
    writer: Option<BufWriter<File>>,
    name: Option<String>,
    records: usize,
    /// A write failed part-way: the end of the pack is unknown, so nothing more is appended.
    failed: bool,
}

impl Cache {
    /// Opens (creating if needed) the cache folder `dir` for scans with `settings`: takes the
    /// shared lock (waiting while another run compacts) and reads every pack's frames.
    pub fn open(dir: &Path, settings: &Settings) -> io::Result<Cache> {
        std::fs::create_dir_all(dir)?;
        let lock = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(dir.join("lock"))
            .ok()
            .filter(|lock| lock.lock_shared().is_ok());
        let (packs, index, found) = load(dir)?;
        static SERIAL: AtomicU64 = AtomicU64::new(0);
        Ok(Cache {
            serial: SERIAL.fetch_add(1, Ordering::Relaxed),
            dir: dir.to_owned(),
            cwd: std::env::current_dir()
                .map(|d| d.into_os_string().into_encoded_bytes())
                .unwrap_or_default(),
            settings: settings_hash(settings),
            max_file_bytes: settings.limits.max_file_bytes,
            lock,
            packs,
            index,
            found,
            own: Mutex::new(Own::default()),
            superseded: AtomicUsize::new(0),
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

    /// Ends the run: writes out this run's pack, then compacts the folder if it is due and no
    /// other run has it open (see the module docs). Dropping the cache instead only writes the
    /// pack out. An error costs entries, never a result: the scan's rows are already out.
    pub fn finish(mut self) -> io::Result<Stats> {
        let stats = self.stats();
        let written = self.close_own();
        let compacted = self.compact();
        written.and(compacted).map(|()| stats)
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
                    self.append(&miss.id, &miss.key, &miss.content, &miss.meta, &payload)
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
        let id = self.identity(source);
        let record = self.record(&id);
        let entry = record.as_deref().and_then(|r| Entry::parse(&r[FRAME..]));
        let deps = Dependencies {
            format,
            source,
            location: OnceCell::new(),
        };
        // Fast path: the file and its dependencies carry the stamps they had when the entry was
        // written, long enough before it that a later change must have changed a stamp; the
        // content hash is then the stored one (and the key must still match these settings).
        if let Some(e) = &entry {
            let unchanged = stamps(&source.path, &deps, &e.dependencies).is_some_and(|now| {
                settled(&now, e.written) && {
                    let mut bytes = Vec::with_capacity(64 * now.len());
                    put_stamps(&mut bytes, &now);
                    bytes == e.stamps
                }
            });
            if unchanged && self.key(source, &e.content) == e.key {
                if let Some(outcomes) = decode(e.payload) {
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
        let mut meta = Meta {
            written: now_secs(),
            dependencies,
            stamps: Vec::new(),
        };
        put_stamps(&mut meta.stamps, stamps.as_deref().unwrap_or_default());
        if let Some(e) = entry.filter(|e| e.key == key) {
            if let Some(outcomes) = decode(e.payload) {
                // Same content under new stamps (touched, copied, or too recent last time):
                // record them so the next run takes the fast path.
                if self.append(&id, &key, &content, &meta, e.payload).is_err() {
                    self.write_errors.fetch_add(1, Ordering::Relaxed);
                }
                return hit(outcomes);
            }
        }
        Lookup::Miss(Miss {
            id,
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
    ) -> Option<(blake3::Hash, Vec<String>, Option<Vec<Stamp>>)> {
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

    /// Which file `source` is: its path and root (relative ones with the current folder, so the
    /// same relative path under two roots or two folders is two files) and its report path. The
    /// identity only says which record to look at, the key and the stamps decide whether it is
    /// reused: two spellings of one file, or two files whose identities collide, cost misses,
    /// never a wrong row. So a fast 64-bit hash does (blake3 cost more than the rest of a hit's
    /// hashing).
    fn identity(&self, source: &Source) -> Id {
        use std::hash::Hasher;
        let mut hasher = rustc_hash::FxHasher::default();
        for path in [source.path.as_path(), &source.root] {
            hasher.write(if path.is_relative() { &self.cwd } else { &[] });
            hasher.write(path.as_os_str().as_encoded_bytes());
        }
        hasher.write(source.display.as_bytes());
        hasher.finish()
    }

    /// The indexed record of `id`, if it can be read and its frame names `id`.
    fn record(&self, id: &Id) -> Option<Vec<u8>> {
        let slot = self.index.get(*id)?;
        let pack = self.packs.get(slot.pack())?;
        let record = AHEAD.with_borrow_mut(|ahead| ahead.read(self.serial, slot, pack).ok())??;
        let (framed, len) = frame(&record)?;
        (framed == *id && FRAME + len == record.len()).then_some(record)
    }

    /// Appends an entry for `id` to this run's pack (creating it on the first write).
    fn append(
        &self,
        id: &Id,
        key: &blake3::Hash,
        content: &blake3::Hash,
        meta: &Meta,
        payload: &[u8],
    ) -> io::Result<()> {
        let record = record(id, key, content, meta, payload)?;
        let mut own = self
            .own
            .lock()
            .map_err(|_| io::Error::other("a write to the cache panicked"))?;
        if own.failed {
            return Err(io::Error::other("an earlier write to the cache failed"));
        }
        if own.writer.is_none() {
            let name = pack_name(self.found.newest);
            let file = File::options()
                .write(true)
                .create_new(true)
                .open(self.dir.join(&name))?;
            own.writer = Some(BufWriter::with_capacity(256 << 10, file));
            own.name = Some(name);
        }
        let writer = own.writer.as_mut().expect("created above");
        if let Err(e) = writer.write_all(&record) {
            own.failed = true;
            return Err(e);
        }
        own.records += 1;
        drop(own);
        if self.index.get(*id).is_some() {
            self.superseded.fetch_add(1, Ordering::Relaxed);
        }
        Ok(())
    }

    /// Writes out and closes this run's pack.
    fn close_own(&mut self) -> io::Result<()> {
        let own = self.own.get_mut().unwrap_or_else(PoisonError::into_inner);
        match own.writer.take() {
            Some(writer) if !own.failed => writer.into_inner().map(drop).map_err(|e| {
                own.failed = true;
                e.into_error()
            }),
            _ => Ok(()),
        }
    }

    /// Compacts the folder if that is due and no other run has it open (see the module docs).
    fn compact(&mut self) -> io::Result<()> {
        let Some(lock) = self.lock.take() else {
            return Ok(());
        };
        // Leave the shared lock, then take the exclusive one only if no other run holds a lock:
        // a run that opens meanwhile waits for us, one that opened before keeps us out. Any
        // trouble with the locks only means no compaction this time.
        if lock.unlock().is_err() || lock.try_lock().is_err() {
            return Ok(());
        }
        let listing = list(&self.dir)?;
        let own = self.own.get_mut().unwrap_or_else(PoisonError::into_inner);
        let mut known = self.found.names.clone();
        known.extend(own.name.clone());
        known.sort();
        if listing.names == known && !self.found.damaged && !own.failed && !listing.leftovers {
            // Nothing but this run changed the folder since it was opened: count from memory.
            let records = self.found.records + own.records;
            let live = (self.index.len() + own.records).saturating_sub(*self.superseded.get_mut());
            if known.len() <= MAX_PACKS && records - live.min(records) <= live {
                return Ok(());
            }
        }
        self.packs.clear();
        let (packs, index, found) = load(&self.dir)?;
        let dead = found.records - index.len();
        if found.damaged || found.names.len() > MAX_PACKS || dead > index.len() {
            if !index.is_empty() {
                let name = pack_name(found.newest);
                let mut out = AtomicFile::create(&self.dir.join(&name))?;
                copy_live(&packs, &index.slots, &mut out)?;
                out.commit()?;
            }
            drop(packs);
            for old in &found.names {
                remove_if_there(&self.dir.join(old))?;
            }
        }
        if listing.leftovers {
            remove_leftovers(&self.dir);
        }
        Ok(())
        // The exclusive lock goes with `lock`.
    }
}

impl Drop for Cache {
    fn drop(&mut self) {
        let _ = self.close_own();
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
    id: Id,
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
    field(&mut hasher, HEADER);
    field(&mut hasher, env!("CARGO_PKG_VERSION").as_bytes());
    // The columns, so a build whose rows have other cells never decodes this one's.
    field(&mut hasher, crate::report::COLUMNS.join(",").as_bytes());
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

/// A pack open for positioned reads.
struct Pack {
    #[cfg(unix)]
    file: File,
    /// Without positioned reads, a seek and a read that must not interleave with another thread's.
    #[cfg(not(unix))]
    file: Mutex<File>,
    /// Its length when opened: what is beyond (a run still appending) is not looked at.
    len: u64,
}

impl Pack {
    fn open(path: &Path) -> io::Result<Pack> {
        let file = File::open(path)?;
        let meta = file.metadata()?;
        if !meta.is_file() {
            return Err(io::Error::other("not a pack"));
        }
        let len = meta.len();
        #[cfg(not(unix))]
        let file = Mutex::new(file);
        Ok(Pack { file, len })
    }

    /// Fills `buf` from `offset` as far as the pack goes; returns how much it read.
    fn read_at(&self, buf: &mut [u8], offset: u64) -> io::Result<usize> {
        let end = self.len.saturating_sub(offset).min(buf.len() as u64) as usize;
        let buf = &mut buf[..end];
        #[cfg(unix)]
        {
            use std::os::unix::fs::FileExt;
            self.file.read_exact_at(buf, offset)?;
        }
        #[cfg(not(unix))]
        {
            use std::io::{Read, Seek, SeekFrom};
            let mut file = self.file.lock().unwrap_or_else(PoisonError::into_inner);
            file.seek(SeekFrom::Start(offset))?;
            file.read_exact(buf)?;
        }
        Ok(end)
    }
}

thread_local! {
    /// Each scanning thread's read-ahead.
    static AHEAD: RefCell<ReadAhead> = RefCell::new(ReadAhead::default());
}

/// The bytes after the record a thread read last. Files are looked up in the order of the
/// previous run, which wrote their records in that order, so the next record a thread needs is
/// usually a little further on: one read then serves many hits. The read grows while that pays
/// and shrinks when it does not (random order costs at most a little more than the record).
#[derive(Default)]
struct ReadAhead {
    /// Which cache and pack `buf` is from.
    cache: u64,
    pack: usize,
    start: u64,
    buf: Vec<u8>,
    filled: usize,
    /// How much to read past a record, and how many records the current read served.
    ahead: usize,
    served: usize,
}

impl ReadAhead {
    const LEAST: usize = 1 << 10;
    const MOST: usize = 64 << 10;

    /// The record at `slot` (`None`: past the end of the pack).
    fn read(&mut self, cache: u64, slot: Slot, pack: &Pack) -> io::Result<Option<Vec<u8>>> {
        let (at, len) = (slot.offset(), slot.len as usize);
        let held = self.cache == cache
            && self.pack == slot.pack()
            && at >= self.start
            && at + len as u64 <= self.start + self.filled as u64;
        if held {
            self.served += 1;
        } else {
            self.ahead = match self.served {
                _ if self.ahead == 0 => 16 << 10,
                0 | 1 => (self.ahead / 2).max(Self::LEAST),
                _ => (self.ahead * 2).min(Self::MOST),
            };
            let want = len + self.ahead;
            if self.buf.len() < want {
                self.buf.resize(want, 0);
            }
            (self.cache, self.pack, self.start, self.served) = (cache, slot.pack(), at, 1);
            self.filled = 0;
            self.filled = pack.read_at(&mut self.buf[..want], at)?;
        }
        let from = (at - self.start) as usize;
        let record = self.buf[..self.filled]
            .get(from..from + len)
            .map(<[u8]>::to_vec);
        if self.buf.len() > 4 * Self::MOST {
            // A rare huge record: do not keep its buffer for the thread's life.
            *self = ReadAhead::default();
        }
        Ok(record)
    }
}

/// A piece of a pack read in one go, for reading a pack from end to end.
struct Window<'a> {
    pack: &'a Pack,
    buf: Vec<u8>,
    start: u64,
    filled: usize,
}

impl<'a> Window<'a> {
    fn new(pack: &'a Pack) -> Window<'a> {
        Window {
            pack,
            buf: Vec::new(),
            start: 0,
            filled: 0,
        }
    }

    /// The `n` bytes at `at`, fewer at the end of the pack.
    fn get(&mut self, at: u64, n: usize) -> io::Result<&[u8]> {
        let end = self.start + self.filled as u64;
        let covered =
            at >= self.start && at <= end && (at + n as u64 <= end || end == self.pack.len);
        if !covered {
            if self.buf.len() < n.max(WINDOW) {
                self.buf.resize(n.max(WINDOW), 0);
            }
            self.start = at;
            self.filled = 0;
            self.filled = self.pack.read_at(&mut self.buf, at)?;
        }
        let from = (at - self.start) as usize;
        Ok(&self.buf[from..self.filled.min(from + n)])
    }

    /// Where the next marker at or after `at` is.
    fn find(&mut self, mut at: u64) -> io::Result<Option<u64>> {
        while at + MAGIC.len() as u64 <= self.pack.len {
            let bytes = self.get(at, WINDOW)?;
            if let Some(i) = bytes.windows(MAGIC.len()).position(|w| w == MAGIC) {
                return Ok(Some(at + i as u64));
            }
            if bytes.len() < MAGIC.len() {
                break;
            }
            at += (bytes.len() + 1 - MAGIC.len()) as u64;
        }
        Ok(None)
    }
}

/// The packs in `dir` (sorted by name, so by age) and whether leftovers need removing.
struct Listing {
    names: Vec<String>,
    leftovers: bool,
}

fn list(dir: &Path) -> io::Result<Listing> {
    let mut listing = Listing {
        names: Vec::new(),
        leftovers: false,
    };
    for entry in std::fs::read_dir(dir)? {
        let Ok(entry) = entry else { continue };
        let Ok(name) = entry.file_name().into_string() else {
            continue;
        };
        if name.starts_with("pack-") {
            listing.names.push(name);
        } else if is_temporary_pack(&name) || is_old_folder(&name) {
            listing.leftovers = true;
        }
    }
    listing.names.sort();
    Ok(listing)
}

/// Opens and reads every pack in `dir`: the packs, the index of their latest records and what was
/// found. A pack that cannot be opened is left out (and so never removed by compaction).
fn load(dir: &Path) -> io::Result<(Vec<Pack>, Index, Found)> {
    let listing = list(dir)?;
    let mut found = Found {
        names: Vec::new(),
        records: 0,
        damaged: false,
        newest: 0,
    };
    let mut packs = Vec::new();
    let mut slots = Vec::new();
    for name in listing.names {
        let time = name.split('-').nth(1).and_then(|t| t.parse::<u64>().ok());
        found.newest = found.newest.max(time.unwrap_or(0));
        let Ok(pack) = Pack::open(&dir.join(&name)) else {
            continue;
        };
        if packs.len() >= 1 << (64 - OFFSET_BITS) {
            break;
        }
        match index_pack(&pack, packs.len(), &mut slots) {
            Ok((records, damaged)) => {
                found.records += records;
                found.damaged |= damaged;
            }
            // What was indexed before the error stays; the rest of the pack is lost.
            Err(_) => found.damaged = true,
        }
        packs.push(pack);
        found.names.push(name);
    }
    // Latest record first within each identity, then keep only it.
    slots.sort_unstable_by(|a, b| a.id.cmp(&b.id).then(b.at.cmp(&a.at)));
    slots.dedup_by_key(|s| s.id);
    Ok((packs, Index::new(slots), found))
}

/// Adds the records of pack number `number` to `slots`; returns how many it has and whether it has
/// bytes that are no record. Bodies are not verified here, only when used.
fn index_pack(pack: &Pack, number: usize, slots: &mut Vec<Slot>) -> io::Result<(usize, bool)> {
    let mut window = Window::new(pack);
    let (mut records, mut damaged) = (0, false);
    let mut at = 0;
    while at < pack.len {
        let bytes = window.get(at, FRAME)?;
        if let Some((id, len)) = frame(bytes) {
            let end = at + (FRAME + len) as u64;
            if end <= pack.len && end < 1 << OFFSET_BITS {
                slots.push(Slot {
                    id,
                    at: ((number as u64) << OFFSET_BITS) | at,
                    len: (FRAME + len) as u32,
                });
                records += 1;
                at = end;
                continue;
            }
        }
        // Damage or a torn tail: go on from the next marker.
        damaged = true;
        match window.find(at + 1)? {
            Some(next) => at = next,
            None => break,
        }
    }
    Ok((records, damaged))
}

/// The identity and body length in a frame, if it is one.
fn frame(bytes: &[u8]) -> Option<(Id, usize)> {
    if bytes.len() < FRAME || bytes[..4] != MAGIC {
        return None;
    }
    let id = Id::from_le_bytes(bytes[4..12].try_into().ok()?);
    let len = u32::from_le_bytes(bytes[12..16].try_into().ok()?) as usize;
    let check = u32::from_le_bytes(bytes[16..20].try_into().ok()?);
    (check == frame_check(&bytes[4..16]) && len <= MAX_BODY).then_some((id, len))
}

/// FNV-1a of the identity and length: catches a damaged length or a false marker cheaply (the
/// body has its own checksum).
fn frame_check(bytes: &[u8]) -> u32 {
    bytes.iter().fold(0x811c_9dc5, |h, &b| {
        (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
    })
}

/// `pack-<ns>-<pid>-<n>`, at least one nanosecond later than `newest` (so it sorts after every
/// pack seen even if the clock went back; if another run's clock is behind, a record may be
/// superseded by an older one, which costs a miss, never a wrong row).
fn pack_name(newest: u64) -> String {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    format!(
        "pack-{:020}-{}-{}",
        now.max(newest + 1),
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    )
}

/// Copies the indexed records that verify, in the order they were written.
fn copy_live(packs: &[Pack], index: &[Slot], out: &mut impl Write) -> io::Result<()> {
    let mut slots = index.to_vec();
    slots.sort_unstable_by_key(|s| s.at);
    let mut window: Option<(usize, Window<'_>)> = None;
    for slot in slots {
        if window.as_ref().is_none_or(|(pack, _)| *pack != slot.pack()) {
            window = Some((slot.pack(), Window::new(&packs[slot.pack()])));
        }
        let (_, window) = window.as_mut().expect("set above");
        let record = window.get(slot.offset(), slot.len as usize)?;
        if record.len() == slot.len as usize && Entry::verified(&record[FRAME..]).is_some() {
            out.write_all(record)?;
        }
    }
    Ok(())
}

fn remove_if_there(path: &Path) -> io::Result<()> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
        _ => Ok(()),
    }
}

/// A compaction's temporary file ([`AtomicFile`] names it `.pack-....tmp`).
fn is_temporary_pack(name: &str) -> bool {
    name.starts_with(".pack-") && name.ends_with(".tmp")
}

fn is_hex(name: &str, len: usize) -> bool {
    name.len() == len && name.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

/// A folder of format 2's entries: two hex digits.
fn is_old_folder(name: &str) -> bool {
    is_hex(name, 2)
}

/// Removes compactions' temporary files (only a crash leaves one: compaction holds the folder
/// alone) and format 2's entries: in each two-hex-digit folder, the files named as it named
/// entries (62 hex digits) and their temporary files, then the folder if that emptied it.
/// Anything else is left alone, in case the folder is not only the cache's.
fn remove_leftovers(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if is_temporary_pack(&name) {
            let _ = std::fs::remove_file(entry.path());
        } else if is_old_folder(&name) && entry.file_type().is_ok_and(|t| t.is_dir()) {
            for file in std::fs::read_dir(entry.path())
                .into_iter()
                .flatten()
                .flatten()
            {
                let name = file.file_name();
                let name = name.to_string_lossy();
                let temporary = name
                    .strip_prefix('.')
                    .filter(|n| n.ends_with(".tmp"))
                    .and_then(|n| n.get(..62));
                if is_hex(&name, 62) || temporary.is_some_and(|n| is_hex(n, 62)) {
                    let _ = std::fs::remove_file(file.path());
                }
            }
            let _ = std::fs::remove_dir(entry.path());
        }
    }
}

/// A whole record: frame, then the body (header, checksum of the rest, the rest).
fn record(
    id: &Id,
    key: &blake3::Hash,
    content: &blake3::Hash,
    meta: &Meta,
    payload: &[u8],
) -> io::Result<Vec<u8>> {
    let mut rest = Vec::with_capacity(payload.len() + 200);
    rest.extend_from_slice(key.as_bytes());
    rest.extend_from_slice(content.as_bytes());
    put_u64(&mut rest, meta.written);
    put_len(&mut rest, meta.dependencies.len());
    for d in &meta.dependencies {
        put_str(&mut rest, d);
    }
    put_len(&mut rest, meta.stamps.len());
    rest.extend_from_slice(&meta.stamps);
    rest.extend_from_slice(payload);
    let len = HEADER.len() + 32 + rest.len();
    if len > MAX_BODY {
        return Err(io::Error::other("the entry is too large for the cache"));
    }
    let mut out = Vec::with_capacity(FRAME + len);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&id.to_le_bytes());
    out.extend_from_slice(&(len as u32).to_le_bytes());
    let check = frame_check(&out[4..16]);
    out.extend_from_slice(&check.to_le_bytes());
    out.extend_from_slice(HEADER);
    out.extend_from_slice(blake3::hash(&rest).as_bytes());
    out.extend_from_slice(&rest);
    Ok(out)
}

/// A body whose header and checksum match, parsed (the payload is decoded only when used).
struct Entry<'a> {
    key: blake3::Hash,
    content: blake3::Hash,
    written: u64,
    dependencies: Vec<String>,
    /// Encoded as [`put_stamps`] writes them, compared as bytes.
    stamps: &'a [u8],
    payload: &'a [u8],
}

impl<'a> Entry<'a> {
    /// What follows the header and checksum, if they match.
    fn verified(body: &'a [u8]) -> Option<&'a [u8]> {
        let (sum, rest) = body.strip_prefix(HEADER)?.split_at_checked(32)?;
        (blake3::hash(rest).as_bytes()[..] == *sum).then_some(rest)
    }

    fn parse(body: &'a [u8]) -> Option<Entry<'a>> {
        let mut r = Reader(Entry::verified(body)?);
        let key = blake3::Hash::from_bytes(r.array()?);
        let content = blake3::Hash::from_bytes(r.array()?);
        let written = r.u64()?;
        let dependencies = (0..r.len()?)
            .map(|_| r.str().map(str::to_owned))
            .collect::<Option<Vec<_>>>()?;
        let len = r.len()?;
        let stamps = r.take(len)?;
        Some(Entry {
            key,
            content,
            written,
            dependencies,
            stamps,
            payload: r.0,
        })
    }
}

/// What an entry records besides the key and the outcomes.
struct Meta {
    /// When the entry was written (Unix seconds).
    written: u64,
    /// The dependencies the file named (relative to its folder).
    dependencies: Vec<String>,
    /// Stamps of the file, then of each dependency, as [`put_stamps`] writes them; empty where
    /// stamps are not available (then every run hashes the content).
    stamps: Vec<u8>,
}

fn put_u64(out: &mut Vec<u8>, n: u64) {
    out.extend_from_slice(&n.to_le_bytes());
}

fn put_len(out: &mut Vec<u8>, n: usize) {
    out.extend_from_slice(&(n as u32).to_le_bytes());
}

/// 7 bits a byte, low first; a set top bit means more follow (a cell's length: mostly one byte).
fn put_varint(out: &mut Vec<u8>, mut n: usize) {
    while n >= 0x80 {
        out.push(n as u8 | 0x80);
        n >>= 7;
    }
    out.push(n as u8);
}

fn put_str(out: &mut Vec<u8>, s: &str) {
    put_len(out, s.len());
    out.extend_from_slice(s.as_bytes());
}

/// Reads what the `put_` functions wrote; every read is checked against the end.
struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let (taken, rest) = self.0.split_at_checked(n)?;
        self.0 = rest;
        Some(taken)
    }

    fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        self.take(N)?.try_into().ok()
    }

    fn u8(&mut self) -> Option<u8> {
        Some(self.array::<1>()?[0])
    }

    fn u64(&mut self) -> Option<u64> {
        self.array().map(u64::from_le_bytes)
    }

    fn usize(&mut self) -> Option<usize> {
        self.u64()?.try_into().ok()
    }

    fn len(&mut self) -> Option<usize> {
        self.array().map(|b| u32::from_le_bytes(b) as usize)
    }

    fn varint(&mut self) -> Option<usize> {
        let mut n = 0usize;
        for shift in (0..35).step_by(7) {
            let byte = self.u8()?;
            n |= usize::from(byte & 0x7f) << shift;
            if byte < 0x80 {
                return Some(n);
            }
        }
        None
    }

    fn str(&mut self) -> Option<&'a str> {
        let n = self.len()?;
        std::str::from_utf8(self.take(n)?).ok()
    }
}

/// The payload: for each outcome, the row's CSV cells, the findings `(rule, severity, count,
/// message)` and the shells, volumes as their bits (so even an infinite one comes back exactly).
fn encode(outcomes: &[Outcome]) -> io::Result<Vec<u8>> {
    let mut out = Vec::with_capacity(1024);
    put_len(&mut out, outcomes.len());
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
        put_len(&mut out, cells.len());
        put_len(&mut out, cells.as_byte_record().as_slice().len());
        for cell in &cells {
            put_varint(&mut out, cell.len());
        }
        out.extend_from_slice(cells.as_byte_record().as_slice());
        put_len(&mut out, o.findings.len());
        for f in &o.findings {
            put_str(&mut out, f.rule.name());
            put_str(&mut out, f.severity.name());
            put_u64(&mut out, f.count as u64);
            put_str(&mut out, &f.message);
        }
        put_len(&mut out, o.shells.len());
        for s in &o.shells {
            put_u64(&mut out, s.faces as u64);
            put_u64(&mut out, s.holes as u64);
            out.push(u8::from(s.genus.is_some()));
            put_u64(&mut out, s.genus.unwrap_or(0) as u64);
            out.push(u8::from(s.volume.is_some()));
            put_u64(&mut out, s.volume.unwrap_or(0.0).to_bits());
            put_u64(&mut out, s.depth as u64);
            out.push(match s.role {
                Role::Solid => b's',
                Role::Cavity => b'c',
            });
            out.push(u8::from(s.inside_out));
        }
    }
    Ok(out)
}

fn decode(payload: &[u8]) -> Option<Vec<Outcome>> {
    let mut r = Reader(payload);
    let count = r.len()?;
    let mut outcomes = Vec::with_capacity(count.min(64));
    for _ in 0..count {
        let count = r.len()?;
        let size = r.len()?;
        let mut lens = Reader(r.0);
        for _ in 0..count {
            lens.varint()?;
        }
        let lens = Reader(r.take(r.0.len() - lens.0.len())?);
        let mut cells = Cells {
            text: std::str::from_utf8(r.take(size)?).ok()?,
            lens,
            left: count,
            start: 0,
        };
        let row = cells.row()?;
        let findings = (0..r.len()?)
            .map(|_| {
                Some(Finding {
                    rule: Rule::from_name(r.str()?)?,
                    severity: Severity::from_name(r.str()?)?,
                    count: r.usize()?,
                    message: r.str()?.to_owned(),
                })
            })
            .collect::<Option<Vec<_>>>()?;
        let shells = (0..r.len()?)
            .map(|_| {
                let faces = r.usize()?;
                let holes = r.usize()?;
                let genus = (r.u8()? == 1, r.u64()? as i64);
                let volume = (r.u8()? == 1, f64::from_bits(r.u64()?));
                Some(ShellRow {
                    faces,
                    holes,
                    genus: genus.0.then_some(genus.1),
                    volume: volume.0.then_some(volume.1),
                    depth: r.usize()?,
                    role: match r.u8()? {
                        b's' => Role::Solid,
                        b'c' => Role::Cavity,
                        _ => return None,
                    },
                    inside_out: r.u8()? == 1,
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
    (r.0.is_empty() && !outcomes.is_empty()).then_some(outcomes)
}

/// A row's CSV cells, read in column order: one block of text and each cell's length.
struct Cells<'a> {
    text: &'a str,
    /// Each cell's length, as [`put_varint`] writes it.
    lens: Reader<'a>,
    left: usize,
    start: usize,
}

impl<'a> Cells<'a> {
    fn next(&mut self) -> Option<&'a str> {
        self.left = self.left.checked_sub(1)?;
        let end = self.start.checked_add(self.lens.varint()?)?;
        let cell = self.text.get(self.start..end)?;
        self.start = end;
        Some(cell)
    }

    fn text(&mut self) -> Option<String> {
        self.next().map(str::to_owned)
    }

    /// An empty cell is `None`, like the CSV reader's; the rest parse as the reader parses them
    /// (a number's text, `true`/`false`).
    fn value<T: std::str::FromStr>(&mut self) -> Option<Option<T>> {
        match self.next()? {
            "" => Some(None),
            cell => cell.parse().ok().map(Some),
        }
    }

    fn status(&mut self) -> Option<Option<Status>> {
        match self.next()? {
            "" => Some(None),
            cell => Status::from_name(cell).map(Some),
        }
    }

    /// The row these cells are, as `csv`'s deserializer reads it (a test compares the two), without
    /// its per-field dispatch: this is most of a hit's decoding. Every field is named, so a
    /// changed [`Row`] does not compile until this follows; the cells must all be used.
    fn row(&mut self) -> Option<Row> {
        let row = Row {
            path: self.text()?,
            mesh: self.text()?,
            format: self.text()?,
            status: self.status()?,
            message: self.text()?,
            vertices: self.value()?,
            welded_vertices: self.value()?,
            faces: self.value()?,
            degenerate_faces: self.value()?,
            zero_area_faces: self.value()?,
            duplicate_faces: self.value()?,
            invalid_vertices: self.value()?,
            unreferenced_vertices: self.value()?,
            edges: self.value()?,
            border_edges: self.value()?,
            nonmanifold_edges: self.value()?,
            nonmanifold_vertices: self.value()?,
            inconsistent_edges: self.value()?,
            components: self.value()?,
            shells: self.value()?,
            holes: self.value()?,
            orientable: self.value()?,
            oriented: self.value()?,
            inside_out_shells: self.value()?,
            cavities: self.value()?,
            solids: self.value()?,
            euler: self.value()?,
            genus: self.value()?,
            volume: self.value()?,
            area: self.value()?,
            bbox_min_x: self.value()?,
            bbox_min_y: self.value()?,
            bbox_min_z: self.value()?,
            bbox_max_x: self.value()?,
            bbox_max_y: self.value()?,
            bbox_max_z: self.value()?,
            repaired_path: self.text()?,
            repairs: self.text()?,
            millis: self.value()?,
            invalid_faces: self.value()?,
            mirrored_instances: self.value()?,
            findings: self.text()?,
            status_after: self.text()?,
            findings_after: self.text()?,
        };
        (self.left == 0 && self.start == self.text.len()).then_some(row)
    }
}

fn now_secs() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

/// What a file looked like, to tell without reading it whether it may have changed.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Stamp {
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

fn put_stamps(out: &mut Vec<u8>, stamps: &[Stamp]) {
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
fn stamps(file: &Path, deps: &Dependencies<'_>, dependencies: &[String]) -> Option<Vec<Stamp>> {
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
fn stamp(path: &Path) -> Option<Stamp> {
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
fn stamp(_: &Path) -> Option<Stamp> {
    None
}

/// Whether every stamp's change time is at least 2 s before `written`: a file changed in the same
/// clock tick as its stamp was taken could change again without changing the stamp (git's "racy
/// clean" problem), so such an entry is checked by content.
fn settled(stamps: &[Stamp], written: u64) -> bool {
    stamps.iter().all(|s| match s {
        Stamp::File { changed, .. } => changed.0.saturating_add(2) <= written as i64,
        // Missing or unavailable: nothing that could change silently.
        Stamp::Missing(_) | Stamp::Unavailable => true,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::scan_file;
    use crate::walk::{walk, Filter};

    const OPEN: &str = "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    /// A closed tetrahedron, so a mesh with shells and no finding.
    const TETRA: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

    /// A folder with `tree/m.obj` (an open triangle naming `a.mtl`) and room for `cache/`.
    fn setup() -> (tempfile::TempDir, Source) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("tree")).unwrap();
        std::fs::write(dir.path().join("tree/m.obj"), OPEN).unwrap();
        let source = walk(&[dir.path().join("tree")], &Filter::everything()).remove(0);
        (dir, source)
    }

    fn open(dir: &Path) -> Cache {
        Cache::open(&dir.join("cache"), &Settings::default()).unwrap()
    }

    /// Looks every source up, scanning the misses.
    fn look(cache: &Cache, sources: &[Source]) -> Vec<Vec<Outcome>> {
        let settings = Settings::default();
        sources
            .iter()
            .map(|s| without_millis(cache.outcomes(s, || scan_file(s, &settings))))
            .collect()
    }

    /// One whole run: open, look every source up, finish.
    fn run(dir: &Path, sources: &[Source]) -> (Stats, Vec<Vec<Outcome>>) {
        let cache = open(dir);
        let outcomes = look(&cache, sources);
        (cache.finish().unwrap(), outcomes)
    }

    fn fresh(sources: &[Source]) -> Vec<Vec<Outcome>> {
        let settings = Settings::default();
        sources
            .iter()
            .map(|s| without_millis(scan_file(s, &settings)))
            .collect()
    }

    fn without_millis(mut outcomes: Vec<Outcome>) -> Vec<Outcome> {
        for o in &mut outcomes {
            o.row.millis = None;
        }
        outcomes
    }

    fn packs(dir: &Path) -> Vec<PathBuf> {
        list(&dir.join("cache"))
            .unwrap()
            .names
            .iter()
            .map(|n| dir.join("cache").join(n))
            .collect()
    }

    /// Every record in the packs, latest last.
    fn records(dir: &Path) -> Vec<Vec<u8>> {
        let (packs, index, _) = load(&dir.join("cache")).unwrap();
        let mut slots = index.slots;
        slots.sort_by_key(|s| s.at);
        slots
            .iter()
            .map(|s| {
                let mut record = vec![0; s.len as usize];
                packs[s.pack()].read_at(&mut record, s.offset()).unwrap();
                record
            })
            .collect()
    }

    /// `count` files `tree/m<i>.obj`, each a tetrahedron moved by `i`.
    fn tree(dir: &Path, count: usize) -> Vec<Source> {
        let tree = dir.join("tree");
        std::fs::create_dir_all(&tree).unwrap();
        for i in 0..count {
            let text = TETRA.replace("v 0 0 0", &format!("v 0 0 -{i}"));
            std::fs::write(tree.join(format!("m{i}.obj")), text).unwrap();
        }
        walk(&[tree], &Filter::everything())
    }

    #[test]
    fn a_hit_equals_a_fresh_scan_except_millis() {
        let (dir, source) = setup();
        let sources = [source];
        let (stats, cold) = run(dir.path(), &sources);
        assert_eq!((stats.hits, stats.misses), (0, 1));
        assert_eq!(cold, fresh(&sources));
        let cache = open(dir.path());
        let again = cache.outcomes(&sources[0], || panic!("must come from the cache"));
        assert_eq!(cache.stats().hits, 1);
        assert_eq!(without_millis(again), cold[0]);
        assert!(!cold[0][0].findings.is_empty(), "findings are stored too");
    }

    #[test]
    fn shells_and_every_cell_come_back_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let sources = tree(dir.path(), 1);
        let (_, cold) = run(dir.path(), &sources);
        assert_eq!(cold[0][0].shells.len(), 1);
        let (stats, warm) = run(dir.path(), &sources);
        assert_eq!(stats.hits, 1);
        assert_eq!(warm, cold);
    }

    /// The cells decode as the CSV reader reads them: every field distinct, so a column read
    /// into the wrong field shows.
    #[test]
    fn cells_decode_as_the_csv_reader_reads_them() {
        let row = Row {
            path: "a, \"b\"\nc/é.obj".into(),
            mesh: "m".into(),
            format: "obj".into(),
            status: Some(Status::Warn),
            // Long enough that its length takes two bytes.
            message: "1 hole; ".repeat(45),
            vertices: Some(1),
            welded_vertices: Some(2),
            faces: Some(3),
            degenerate_faces: Some(4),
            zero_area_faces: Some(5),
            duplicate_faces: Some(6),
            invalid_vertices: Some(7),
            unreferenced_vertices: Some(8),
            edges: Some(9),
            border_edges: Some(10),
            nonmanifold_edges: Some(11),
            nonmanifold_vertices: Some(12),
            inconsistent_edges: Some(13),
            components: Some(14),
            shells: Some(15),
            holes: Some(16),
            orientable: Some(true),
            oriented: Some(false),
            inside_out_shells: Some(17),
            cavities: Some(18),
            solids: Some(19),
            euler: Some(-20),
            genus: Some(21),
            volume: Some(0.1 + 0.2),
            area: Some(f64::INFINITY),
            bbox_min_x: Some(-1e-300),
            bbox_min_y: Some(1e300),
            bbox_min_z: Some(-0.0),
            bbox_max_x: Some(22.5),
            bbox_max_y: Some(f64::MIN_POSITIVE),
            bbox_max_z: Some(f64::MAX),
            repaired_path: "out/x.obj".into(),
            repairs: "welded".into(),
            millis: Some(23.25),
            invalid_faces: Some(24),
            mirrored_instances: Some(25),
            findings: "hole:1".into(),
            status_after: "pass".into(),
            findings_after: "x".into(),
        };
        for row in [row, Row::default()] {
            let outcome = Outcome {
                row: row.clone(),
                ..Outcome::default()
            };
            let payload = encode(&[outcome]).unwrap();
            let decoded = decode(&payload).unwrap().remove(0).row;
            assert_eq!(decoded, row);
            let mut writer = csv::WriterBuilder::new()
                .has_headers(false)
                .from_writer(Vec::new());
            writer.serialize(&row).unwrap();
            let line = writer.into_inner().unwrap();
            let record = csv::ReaderBuilder::new()
                .has_headers(false)
                .from_reader(line.as_slice())
                .records()
                .next()
                .unwrap()
                .unwrap();
            assert_eq!(record.deserialize::<Row>(None).unwrap(), decoded);
            // Cut short or too long: not a row.
            assert!(decode(&payload[..payload.len() - 1]).is_none());
            let mut longer = payload.clone();
            longer.push(0);
            assert!(decode(&longer).is_none());
        }
    }

    #[test]
    fn a_run_sees_the_entries_of_earlier_runs_not_its_own() {
        let dir = tempfile::tempdir().unwrap();
        let sources = tree(dir.path(), 3);
        let cache = open(dir.path());
        look(&cache, &sources[..1]);
        look(&cache, &sources[..1]);
        assert_eq!(
            cache.stats().misses,
            2,
            "its own entries wait for the next run"
        );
        drop(cache);
        // Dropped without finishing: the pack was still written out.
        let (stats, _) = run(dir.path(), &sources[1..2]);
        assert_eq!(stats.misses, 1);
        let (stats, warm) = run(dir.path(), &sources);
        assert_eq!((stats.hits, stats.misses), (2, 1));
        assert_eq!(warm, fresh(&sources));
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!(stats.hits, 3);
    }

    #[test]
    fn a_warm_run_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let sources = tree(dir.path(), 2);
        run(dir.path(), &sources);
        let before = packs(dir.path());
        // Entries just written are too recent for their stamps; the content confirms them and
        // the refreshed stamps are written once.
        run(dir.path(), &sources);
        let settled = packs(dir.path());
        assert_eq!(settled.len(), before.len() + 1);
        age(dir.path(), &sources, 10);
        let aged = packs(dir.path());
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!(stats.unread, 2);
        assert_eq!(
            packs(dir.path()),
            aged,
            "nothing written, nothing compacted"
        );
    }

    #[test]
    fn a_changed_file_or_dependency_is_a_miss() {
        let (dir, source) = setup();
        let sources = [source];
        run(dir.path(), &sources);
        // The MTL appears: the key changes.
        std::fs::write(dir.path().join("tree/a.mtl"), "newmtl x\n").unwrap();
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.misses, 1);
        assert!(
            !rows[0][0].row.message.contains("not found"),
            "{}",
            rows[0][0].row.message
        );
        std::fs::write(dir.path().join("tree/m.obj"), format!("{OPEN}f 1 3 2\n")).unwrap();
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.misses, 1);
        assert_eq!(rows, fresh(&sources));
        // Other settings: another key.
        let mut strict = Settings::default();
        strict.severities.set(Rule::DuplicateFace, Severity::Error);
        let other = Cache::open(&dir.path().join("cache"), &strict).unwrap();
        let rows = other.outcomes(&sources[0], || scan_file(&sources[0], &strict));
        assert_eq!(other.stats().misses, 1);
        assert_eq!(rows[0].row.status, Some(Status::Fail));
    }

    /// Rewrites the pack of a one-file cache with `damage` applied, then checks the next run does
    /// not trust what is left, gives fresh rows, and writes an entry the run after reuses.
    fn damaged_pack_is_recomputed(damage: impl Fn(&mut Vec<u8>)) {
        let (dir, source) = setup();
        let sources = [source];
        let (_, cold) = run(dir.path(), &sources);
        let pack = packs(dir.path()).remove(0);
        let mut bytes = std::fs::read(&pack).unwrap();
        damage(&mut bytes);
        std::fs::write(&pack, &bytes).unwrap();
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!((stats.hits, stats.misses), (0, 1), "not trusted");
        assert_eq!(rows, cold);
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.hits, 1, "written again");
        assert_eq!(rows, cold);
    }

    #[test]
    fn a_damaged_record_is_recomputed() {
        // A flipped byte in the payload, the checksum, the frame's length or its marker.
        for at in [1, 33, 13, 0] {
            damaged_pack_is_recomputed(|b| {
                let at = if at == 1 { b.len() - 1 } else { at };
                b[at] ^= 0x10;
            });
        }
        // A cell that still decodes, to something else: only the checksum tells.
        damaged_pack_is_recomputed(|b| {
            let at = b.windows(5).rposition(|w| w == b"m.obj").unwrap();
            b[at] = b'n';
        });
        // Cut mid-record, or nothing left.
        damaged_pack_is_recomputed(|b| b.truncate(b.len() / 2));
        damaged_pack_is_recomputed(|b| b.truncate(FRAME - 1));
        damaged_pack_is_recomputed(Vec::clear);
        // Written by another version: the same bytes under another header.
        damaged_pack_is_recomputed(|b| {
            let at = FRAME + HEADER.len() - 2;
            assert_eq!(&b[FRAME..at], b"meshvet-cache ");
            b[at] = b'0';
        });
        // Another identity: the record is some other file's.
        damaged_pack_is_recomputed(|b| {
            b[4] ^= 1;
            let check = frame_check(&b[4..16]);
            b[16..20].copy_from_slice(&check.to_le_bytes());
        });
    }

    #[test]
    fn the_index_finds_every_identity_and_no_other() {
        for n in [0, 1, 2, 3, 5, 64, 1000, 4097] {
            // Spread like hashes, plus the extremes.
            let mut ids: Vec<Id> = (0..n as u64)
                .map(|i| i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (i << 7))
                .collect();
            if n > 2 {
                ids[0] = 0;
                ids[1] = Id::MAX;
            }
            ids.sort_unstable();
            ids.dedup();
            let slots = ids
                .iter()
                .map(|&id| Slot {
                    id,
                    at: id / 3,
                    len: 1,
                })
                .collect();
            let index = Index::new(slots);
            assert_eq!(index.len(), ids.len());
            for &id in &ids {
                assert_eq!(index.get(id).map(|s| s.at), Some(id / 3), "{n}: {id}");
                if !ids.contains(&id.wrapping_add(1)) {
                    assert!(index.get(id.wrapping_add(1)).is_none());
                }
            }
        }
    }

    #[test]
    fn a_frame_checks_its_identity_and_length() {
        let meta = Meta {
            written: 1,
            dependencies: vec!["a.mtl".into()],
            stamps: Vec::new(),
        };
        let hash = blake3::hash(b"k");
        let good = record(&7, &hash, &hash, &meta, b"payload").unwrap();
        assert_eq!(frame(&good), Some((7, good.len() - FRAME)));
        for at in [4, 11, 12, 15, 16, 19] {
            let mut bad = good.clone();
            bad[at] ^= 1;
            assert_eq!(frame(&bad), None, "byte {at}");
        }
        assert_eq!(frame(&good[..FRAME - 1]), None);
        let e = Entry::parse(&good[FRAME..]).unwrap();
        assert_eq!(
            (e.written, e.dependencies, e.payload),
            (1, meta.dependencies, &b"payload"[..])
        );
    }

    #[test]
    fn damage_costs_only_the_records_it_touches() {
        let dir = tempfile::tempdir().unwrap();
        let sources = tree(dir.path(), 3);
        run(dir.path(), &sources);
        let pack = packs(dir.path()).remove(0);
        let good = std::fs::read(&pack).unwrap();
        let records = records(dir.path());
        assert_eq!(records.len(), 3);
        assert_eq!(good.len(), records.iter().map(Vec::len).sum::<usize>());
        // The first record's length is broken: the other two are still found.
        let mut bytes = good.clone();
        bytes[13] ^= 0x40;
        // Garbage at the end, as a torn append would leave.
        bytes.extend_from_slice(&MAGIC);
        bytes.extend_from_slice(b"torn");
        std::fs::write(&pack, &bytes).unwrap();
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!((stats.hits, stats.misses), (2, 1));
        assert_eq!(rows, fresh(&sources));
        // That run found damage, so it compacted: one clean pack, and later runs append to
        // packs of their own.
        assert_eq!(packs(dir.path()).len(), 1);
        let (_, _, found) = load(&dir.path().join("cache")).unwrap();
        assert!(!found.damaged);
        assert_eq!(found.records, 3);
        std::fs::write(dir.path().join("tree/m0.obj"), TETRA).unwrap();
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!((stats.hits, stats.misses), (2, 1));
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.hits, 3);
        assert_eq!(rows, fresh(&sources));
    }

    #[test]
    fn a_torn_tail_is_ignored_and_later_runs_still_append() {
        let dir = tempfile::tempdir().unwrap();
        let sources = tree(dir.path(), 2);
        run(dir.path(), &sources);
        let pack = packs(dir.path()).remove(0);
        let bytes = std::fs::read(&pack).unwrap();
        // A crash half-way through writing the second record.
        let first = records(dir.path())[0].len();
        std::fs::write(&pack, &bytes[..first + 30]).unwrap();
        let (_, index, found) = load(&dir.path().join("cache")).unwrap();
        assert!(found.damaged);
        assert_eq!(
            (found.records, index.len()),
            (1, 1),
            "the torn record is not indexed"
        );
        // Without the exclusive lock nothing compacts: the torn pack stays as it is.
        let blocker = open(dir.path());
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!((stats.hits, stats.misses), (1, 1));
        assert_eq!(std::fs::read(&pack).unwrap().len(), first + 30);
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.hits, 2);
        assert_eq!(rows, fresh(&sources));
        // Alone, a run compacts the torn pack away.
        drop(blocker);
        run(dir.path(), &sources);
        assert_eq!(packs(dir.path()).len(), 1);
        assert!(!packs(dir.path()).contains(&pack));
        let (_, _, found) = load(&dir.path().join("cache")).unwrap();
        assert!(!found.damaged);
    }

    /// Pretends every entry of `sources` was written `seconds` later than it was (a run of its
    /// own appends copies with that time).
    fn age(dir: &Path, sources: &[Source], seconds: u64) {
        let cache = open(dir);
        for source in sources {
            let id = cache.identity(source);
            let record = cache.record(&id).unwrap();
            let e = Entry::parse(&record[FRAME..]).unwrap();
            let meta = Meta {
                written: e.written + seconds,
                dependencies: e.dependencies.clone(),
                stamps: e.stamps.to_vec(),
            };
            cache
                .append(&id, &e.key, &e.content, &meta, e.payload)
                .unwrap();
        }
        cache.finish().unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn settled_stamps_skip_reading_and_any_change_is_still_seen() {
        let (dir, source) = setup();
        let sources = [source];
        let (_, cold) = run(dir.path(), &sources);
        // Just written: too recent to trust the stamps, so the content is hashed.
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!((stats.hits, stats.unread), (1, 0));
        age(dir.path(), &sources, 10);
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.unread, 1, "answered from the stamps");
        assert_eq!(rows, cold);
        // Settled stamps under other settings: the key still decides.
        let mut strict = Settings::default();
        strict.severities.set(Rule::Hole, Severity::Error);
        let other = Cache::open(&dir.path().join("cache"), &strict).unwrap();
        let rows = other.outcomes(&sources[0], || scan_file(&sources[0], &strict));
        assert_eq!((other.stats().hits, other.stats().misses), (0, 1));
        assert_eq!(rows[0].row.status, Some(Status::Fail));
        drop(other);
        age(dir.path(), &sources, 10);

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
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.misses, 1);
        assert_eq!(rows, fresh(&sources));
        // A dependency appearing changes its stamp from `missing`.
        age(dir.path(), &sources, 10);
        std::fs::write(dir.path().join("tree/a.mtl"), "newmtl x\n").unwrap();
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!(stats.misses, 1);
    }

    #[test]
    fn compaction_keeps_one_pack_of_the_live_entries() {
        let dir = tempfile::tempdir().unwrap();
        let sources = tree(dir.path(), 3);
        let (_, cold) = run(dir.path(), &sources);
        // Every file changes, then one more: 4 superseded records, 3 live.
        for (i, source) in sources.iter().enumerate() {
            std::fs::write(
                &source.path,
                TETRA.replace("v 1 0 0", &format!("v {} 0 0", i + 2)),
            )
            .unwrap();
        }
        run(dir.path(), &sources);
        assert_eq!(packs(dir.path()).len(), 2, "3 superseded, 3 live: not yet");
        std::fs::write(&sources[0].path, TETRA).unwrap();
        let (stats, changed) = run(dir.path(), &sources);
        assert_eq!(stats.misses, 1);
        assert_eq!(changed, fresh(&sources));
        assert_ne!(changed, cold);
        let packs = packs(dir.path());
        assert_eq!(packs.len(), 1);
        let (_, index, found) = load(&dir.path().join("cache")).unwrap();
        assert_eq!((found.records, index.len()), (3, 3));
        // Nothing else is left behind.
        let mut names: Vec<_> = std::fs::read_dir(dir.path().join("cache"))
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(names.len(), 2, "{names:?}");
        assert_eq!(names[0], "lock");
        let (stats, warm) = run(dir.path(), &sources);
        assert_eq!(stats.hits, 3);
        assert_eq!(warm, changed);
    }

    #[test]
    fn too_many_packs_are_merged() {
        let dir = tempfile::tempdir().unwrap();
        let sources = tree(dir.path(), MAX_PACKS + 1);
        for i in 0..=MAX_PACKS {
            run(dir.path(), &sources[i..=i]);
        }
        assert_eq!(packs(dir.path()).len(), 1, "the last run merged them");
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.hits, MAX_PACKS + 1);
        assert_eq!(rows, fresh(&sources));
    }

    #[test]
    fn a_second_open_cache_is_neither_lost_nor_removed() {
        let dir = tempfile::tempdir().unwrap();
        let sources = tree(dir.path(), MAX_PACKS + 4);
        // Enough packs that compaction is due.
        for i in 0..=MAX_PACKS {
            run(dir.path(), &sources[i..=i]);
            std::fs::write(
                dir.path().join("cache").join(format!("pack-{i}")),
                b"not a pack: damage",
            )
            .unwrap();
        }
        let before = packs(dir.path());
        let a = open(dir.path());
        let b = open(dir.path());
        let shared = MAX_PACKS + 1;
        assert_eq!(
            look(&a, &sources[shared..shared + 1]),
            fresh(&sources[shared..shared + 1])
        );
        assert_eq!(look(&b, &sources[shared + 1..shared + 2]).len(), 1);
        // `b` is open: `a` may not compact, so every pack is still there, `b`'s own too.
        a.finish().unwrap();
        let after_a = packs(dir.path());
        assert_eq!(after_a.len(), before.len() + 2);
        assert!(before.iter().all(|p| after_a.contains(p)));
        // `b` still reads what it opened.
        let hits = b.stats().hits;
        assert_eq!(look(&b, &sources[..shared]), fresh(&sources[..shared]));
        assert_eq!(b.stats().hits, hits + shared);
        look(&b, &sources[shared + 2..]);
        // Now alone: `b` compacts, keeping what `a` wrote.
        b.finish().unwrap();
        assert_eq!(packs(dir.path()).len(), 1);
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.hits, sources.len());
        assert_eq!(rows, fresh(&sources));
    }

    #[test]
    fn format_2_entries_are_removed_by_compaction_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let cache = dir.path().join("cache");
        let sources = tree(dir.path(), 1);
        let entry = format!("{:062x}", 7);
        std::fs::create_dir_all(cache.join("ab")).unwrap();
        std::fs::write(cache.join("ab").join(&entry), "meshvet-cache 2\n").unwrap();
        std::fs::write(cache.join("ab").join(format!(".{entry}.12.0.tmp")), "").unwrap();
        std::fs::create_dir_all(cache.join("cd")).unwrap();
        std::fs::write(cache.join("cd").join("notes.txt"), "mine").unwrap();
        std::fs::write(cache.join("notes.txt"), "mine").unwrap();
        std::fs::write(cache.join(".pack-1-2-3.1.0.tmp"), "half").unwrap();
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!(stats.misses, 1, "format 2's entry is not read");
        assert!(!cache.join("ab").exists());
        assert!(!cache.join(".pack-1-2-3.1.0.tmp").exists());
        assert!(cache.join("cd/notes.txt").exists());
        assert!(cache.join("notes.txt").exists());
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!(stats.hits, 1);
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
        let sources = walk(&[tree], &Filter::everything());
        run(dir.path(), &sources);
        std::fs::write(dir.path().join("outside.bin"), "changed secret").unwrap();
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!(stats.hits, 1, "{name}: the outside file was read");
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
        let (dir, source) = setup();
        let sources = [source];
        std::fs::write(dir.path().join("tree/a.mtl"), "newmtl x\n").unwrap();
        run(dir.path(), &sources);
        std::fs::write(dir.path().join("tree/a.mtl"), "newmtl y\n").unwrap();
        let (stats, _) = run(dir.path(), &sources);
        assert_eq!(stats.misses, 1);
    }

    #[test]
    fn the_same_relative_path_under_two_roots_is_two_files() {
        let dir = tempfile::tempdir().unwrap();
        for root in ["one", "two"] {
            std::fs::create_dir(dir.path().join(root)).unwrap();
        }
        std::fs::write(dir.path().join("one/m.obj"), TETRA).unwrap();
        std::fs::write(dir.path().join("two/m.obj"), OPEN).unwrap();
        let mut one = walk(&[dir.path().join("one")], &Filter::everything());
        let mut two = walk(&[dir.path().join("two")], &Filter::everything());
        assert_eq!(one[0].display, two[0].display);
        let cache = open(dir.path());
        assert_ne!(cache.identity(&one[0]), cache.identity(&two[0]));
        drop(cache);
        let sources = [one.remove(0), two.remove(0)];
        run(dir.path(), &sources);
        let (stats, rows) = run(dir.path(), &sources);
        assert_eq!(stats.hits, 2);
        assert_eq!(rows, fresh(&sources));
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

    /// A 3MF package is one file: its parts live inside it, so its key is its bytes alone, even
    /// when a part's text looks like a file another format would name.
    #[test]
    fn a_3mf_package_has_no_dependencies() {
        let text =
            b"PK\x03\x04 mtllib a.mtl\n{\"buffers\":[{\"uri\":\"b.bin\"}]} p:path=\"/3D/x.model\"";
        assert!(dependencies(Format::ThreeMf, text).is_empty());
        // A file the name could mean is there (an OBJ would depend on it); a 3MF does not.
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.mtl"), "newmtl a\n").unwrap();
        std::fs::write(dir.path().join("m.3mf"), text).unwrap();
        let location = Location::new(&dir.path().join("m.3mf"), dir.path()).unwrap();
        assert!(crate::formats::dependency(Format::Obj, "a.mtl", &location).is_some());
        assert_eq!(
            crate::formats::dependency(Format::ThreeMf, "a.mtl", &location),
            None
        );
    }
}
