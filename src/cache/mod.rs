//! The incremental cache for nightly scans (`--cache DIR`): one entry per scanned file, reused when
//! nothing that could change its rows has changed. By job: the key's parts (`key`), pack files and
//! their index (`pack`), an entry's body and codec (`entry`), file stamps (`stamp`); this module
//! opens, looks up, appends and compacts.
//!
//! **Key.** blake3 over: the cache format, meshvet's version and build (the executable's size and
//! modification time, so a rebuild never reuses rows), the report's columns, a hash of the
//! effective settings (every setting that can change a row: severities, weld tolerance, limits; not
//! `jobs` or the include/exclude globs, which only choose files), the file's report path, and the
//! bytes of the file and of everything its rows depend on: for `.obj`, every `mtllib` it names; for
//! `.gltf` and `.glb`, every external `buffers[].uri` and `images[].uri`. Dependencies are found by
//! the readers' own rule (`formats::contain`): one that is missing, or that the reader
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
//! **Other files.** The folder may hold files that are not the cache's, and meshvet never removes
//! a file it did not write. A pack is a regular file named exactly as the cache names them
//! (`pack-`, 20 digits, `-<pid>-<n>`: a user's `pack-hole.obj` is none) that begins with the record
//! marker or holds a frame that checks (a file of a pack's name without either holds nothing of
//! the cache's: it is neither counted nor removed). The type is checked without following a link
//! before a pack is opened, and again on what was opened: a link named like a pack may lead
//! anywhere, and opening a FIFO would wait for ever. A compaction's temporary file and format 2's
//! entries are removed only when so named, regular, and begun as the cache began them.
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
//! run holds the folder; then, when the folder has more than 8 packs (`MAX_PACKS`), damaged bytes or
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
//! that could not be read is read again next time. Outcomes with [`crate::report::Detail`] (pictures
//! for the HTML report) are not cached; callers that need details bypass the cache.

use std::cell::OnceCell;
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
use crate::report::Outcome;
use crate::rules::Status;
use crate::walk::Source;

mod entry;
mod key;
mod pack;
mod stamp;
#[cfg(test)]
mod tests;

use entry::{body, decode, encode, now_secs, Entry, Meta};
use key::{field, hash_file, settings_hash};
use pack::{
    copy_live, frame, list, load, pack_name, record, remove_if_there, remove_leftovers, Found, Id,
    Index, Pack, AHEAD, FRAME, MAX_PACKS,
};
use stamp::{put_stamps, settled, stamps, Stamp};

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
        // A link named `lock` is not followed (it may lead anywhere: the open would create or
        // lock a file outside the folder), nor a FIFO waited on; without a lock the cache still
        // works, it only never compacts.
        let lock = crate::atomic::open_own(
            &dir.join("lock"),
            File::options()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false),
        )
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
        // The fresh scan read the file again: if it changed after the hash was taken, the
        // outcomes may be of other bytes than the key's, and stored under it they would be hit
        // once the file holds the hashed bytes again.
        let storable = outcomes
            .iter()
            .all(|o| o.row.status != Some(Status::Error) && o.detail.is_none())
            && self.unchanged_since(source, &miss.meta);
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

    /// Whether the file and its dependencies still carry the stamps `meta` took before their
    /// content was hashed. Where no stamps are taken (not on unix) it cannot tell, and says yes.
    fn unchanged_since(&self, source: &Source, meta: &Meta) -> bool {
        if meta.stamps.is_empty() {
            return true;
        }
        let Some(format) = source.format else {
            return false;
        };
        let deps = Dependencies {
            format,
            source,
            location: OnceCell::new(),
        };
        stamps(&source.path, &deps, &meta.dependencies).is_some_and(|now| {
            let mut bytes = Vec::with_capacity(64 * now.len());
            put_stamps(&mut bytes, &now);
            bytes == meta.stamps
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
        let bytes = key::read_at_most(&source.path, self.max_file_bytes).ok()?;
        let dependencies = crate::formats::side_file_names(deps.format, &bytes);
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
        let record = record(*id, &body(key, content, meta, payload))?;
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
        // The packs it read, its own, and the files named like packs that are none.
        let mut known = self.found.names.clone();
        known.extend(own.name.clone());
        known.extend(self.found.foreign.iter().cloned());
        known.sort();
        if listing.names == known && !self.found.damaged && !own.failed && !listing.leftovers {
            // Nothing but this run changed the folder since it was opened: count from memory.
            let records = self.found.records + own.records;
            let live = (self.index.len() + own.records).saturating_sub(*self.superseded.get_mut());
            let packs = self.found.names.len() + usize::from(own.name.is_some());
            if packs <= MAX_PACKS && records - live.min(records) <= live {
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
                copy_live(
                    &packs,
                    &index.slots,
                    |body| Entry::verified(body).is_some(),
                    &mut out,
                )?;
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
