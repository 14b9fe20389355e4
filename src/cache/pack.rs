//! Pack files: append-only files of framed records, each written by one run; the in-memory index
//! of where each identity's latest record is; reading records back with read-ahead; finding the
//! next record after damage; listing, naming, compacting and clearing the folder.

use std::cell::RefCell;
use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Starts every record. 0xF5 never occurs in UTF-8, so a search for the next record after damage
/// rarely stops inside a body (and a false stop fails the frame's check).
pub(super) const MAGIC: [u8; 4] = [0xF5, b'm', b'v', b'3'];
/// A record's frame: marker, identity, body length, check of the two.
pub(super) const FRAME: usize = 4 + 8 + 4 + 4;
/// A finishing run that has the folder to itself merges more packs than this into one.
pub(super) const MAX_PACKS: usize = 8;
/// Packs are read in pieces of this size when opened or compacted.
pub(super) const WINDOW: usize = 1 << 20;
/// No body is this long (a file has a few rows); a frame that says so is damaged.
pub(super) const MAX_BODY: usize = 1 << 28;
/// Index positions: the pack's number above, the offset in it below.
pub(super) const OFFSET_BITS: u32 = 40;

/// A hash of a file's identity (see [`Cache::identity`]).
pub(super) type Id = u64;

/// Where a record is: 24 bytes per indexed file.
#[derive(Clone, Copy)]
pub(super) struct Slot {
    pub(super) id: Id,
    /// Pack number and offset (see [`OFFSET_BITS`]); a later record has a larger one.
    pub(super) at: u64,
    /// The whole record's length, frame included.
    pub(super) len: u32,
}

/// The slots sorted by identity, and where each run of leading identity bits starts (identities
/// are hashes, so spread evenly): a lookup looks at about two slots, and the table costs at most
/// 2 bytes a slot.
pub(super) struct Index {
    pub(super) slots: Vec<Slot>,
    /// `starts[b]`: the first slot whose identity's top `bits` bits are at least `b`; then the end.
    pub(super) starts: Vec<u32>,
    pub(super) bits: u32,
}

impl Index {
    /// `slots` sorted by identity, each identity once.
    pub(super) fn new(mut slots: Vec<Slot>) -> Index {
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

    pub(super) fn bucket(id: Id, bits: u32) -> usize {
        id.checked_shr(64 - bits).unwrap_or(0) as usize
    }

    pub(super) fn get(&self, id: Id) -> Option<Slot> {
        let b = Index::bucket(id, self.bits);
        let (from, to) = (self.starts[b] as usize, self.starts[b + 1] as usize);
        self.slots[from..to].iter().find(|s| s.id == id).copied()
    }

    pub(super) fn len(&self) -> usize {
        self.slots.len()
    }

    pub(super) fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }
}

impl Slot {
    pub(super) fn pack(self) -> usize {
        (self.at >> OFFSET_BITS) as usize
    }

    pub(super) fn offset(self) -> u64 {
        self.at & ((1 << OFFSET_BITS) - 1)
    }
}

/// What listing and reading the packs found.
pub(super) struct Found {
    /// The packs read, by number.
    pub(super) names: Vec<String>,
    /// Files named like a pack that are none: no record of the cache is in them, or they could
    /// not be opened. They are never counted, used or removed.
    pub(super) foreign: Vec<String>,
    /// Records in them, superseded ones included.
    pub(super) records: usize,
    /// Bytes that are no record (a torn tail, damage), or a pack that could not be read.
    pub(super) damaged: bool,
    /// The largest time in a pack name: new packs are named later even if the clock went back.
    pub(super) newest: u64,
}

/// A pack open for positioned reads.
pub(super) struct Pack {
    #[cfg(unix)]
    pub(super) file: File,
    /// Without positioned reads, a seek and a read that must not interleave with another thread's.
    #[cfg(not(unix))]
    pub(super) file: Mutex<File>,
    /// Its length when opened: what is beyond (a run still appending) is not looked at.
    pub(super) len: u64,
}

impl Pack {
    /// Opens the regular file at `path` for reading. Anything else is refused unopened: a FIFO
    /// would block the open (and every scan with it), a device or a link could be anything. The
    /// type is checked without following a link before opening, and again on what was opened (the
    /// name may have been replaced in between; on unix the open itself neither follows a link nor
    /// waits for a FIFO's writer).
    pub(super) fn open(path: &Path) -> io::Result<Pack> {
        let file = crate::atomic::open_own(path, File::options().read(true))?;
        let len = file.metadata()?.len();
        #[cfg(not(unix))]
        let file = Mutex::new(file);
        Ok(Pack { file, len })
    }

    /// Fills `buf` from `offset` as far as the pack goes; returns how much it read.
    pub(super) fn read_at(&self, buf: &mut [u8], offset: u64) -> io::Result<usize> {
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
    pub(super) static AHEAD: RefCell<ReadAhead> = RefCell::new(ReadAhead::default());
}

/// The bytes after the record a thread read last. Files are looked up in the order of the
/// previous run, which wrote their records in that order, so the next record a thread needs is
/// usually a little further on: one read then serves many hits. The read grows while that pays
/// and shrinks when it does not (random order costs at most a little more than the record).
#[derive(Default)]
pub(super) struct ReadAhead {
    /// Which cache and pack `buf` is from.
    pub(super) cache: u64,
    pub(super) pack: usize,
    pub(super) start: u64,
    pub(super) buf: Vec<u8>,
    pub(super) filled: usize,
    /// How much to read past a record, and how many records the current read served.
    pub(super) ahead: usize,
    pub(super) served: usize,
}

impl ReadAhead {
    pub(super) const LEAST: usize = 1 << 10;
    pub(super) const MOST: usize = 64 << 10;

    /// The record at `slot` (`None`: past the end of the pack).
    pub(super) fn read(
        &mut self,
        cache: u64,
        slot: Slot,
        pack: &Pack,
    ) -> io::Result<Option<Vec<u8>>> {
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
pub(super) struct Window<'a> {
    pub(super) pack: &'a Pack,
    pub(super) buf: Vec<u8>,
    pub(super) start: u64,
    pub(super) filled: usize,
}

impl<'a> Window<'a> {
    pub(super) fn new(pack: &'a Pack) -> Window<'a> {
        Window {
            pack,
            buf: Vec::new(),
            start: 0,
            filled: 0,
        }
    }

    /// The `n` bytes at `at`, fewer at the end of the pack.
    pub(super) fn get(&mut self, at: u64, n: usize) -> io::Result<&[u8]> {
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
    pub(super) fn find(&mut self, mut at: u64) -> io::Result<Option<u64>> {
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
pub(super) struct Listing {
    pub(super) names: Vec<String>,
    pub(super) leftovers: bool,
}

/// The regular files in `dir` named as the cache names its packs ([`is_pack_name`]), and whether
/// it has leftovers ([`remove_leftovers`]). Nothing else is a pack, whatever its name starts with:
/// a user's `pack-notes.txt` in the folder is not the cache's.
pub(super) fn list(dir: &Path) -> io::Result<Listing> {
    let mut listing = Listing {
        names: Vec::new(),
        leftovers: false,
    };
    for entry in std::fs::read_dir(dir)? {
        let Ok(entry) = entry else { continue };
        let Ok(name) = entry.file_name().into_string() else {
            continue;
        };
        // The entry's own type: a link is not followed, a FIFO or a device is no pack.
        let Ok(kind) = entry.file_type() else {
            continue;
        };
        if is_pack_name(&name) {
            if kind.is_file() {
                listing.names.push(name);
            }
        } else if !listing.leftovers && !old_entries(&entry).is_empty() {
            listing.leftovers = true;
        }
    }
    listing.names.sort();
    Ok(listing)
}

/// Opens and reads every pack in `dir`: the packs, the index of their latest records and what was
/// found. A file named like a pack that cannot be opened, or in which no record is found (see
/// [`Indexed::ours`]), is no pack: it is left out, so never removed by compaction.
pub(super) fn load(dir: &Path) -> io::Result<(Vec<Pack>, Index, Found)> {
    let listing = list(dir)?;
    let mut found = Found {
        names: Vec::new(),
        foreign: Vec::new(),
        records: 0,
        damaged: false,
        newest: 0,
    };
    let mut packs = Vec::new();
    let mut slots = Vec::new();
    for name in listing.names {
        let Ok(pack) = Pack::open(&dir.join(&name)) else {
            found.foreign.push(name);
            continue;
        };
        if packs.len() >= 1 << (64 - OFFSET_BITS) {
            break;
        }
        let before = slots.len();
        let indexed = index_pack(&pack, packs.len(), &mut slots);
        // What was indexed before a read error stays; the rest of the pack is lost.
        let indexed = indexed.unwrap_or(Indexed {
            records: slots.len() - before,
            damaged: true,
            ours: slots.len() > before,
        });
        if !indexed.ours {
            found.foreign.push(name);
            continue;
        }
        let time = name.split('-').nth(1).and_then(|t| t.parse::<u64>().ok());
        found.newest = found.newest.max(time.unwrap_or(0));
        found.records += indexed.records;
        found.damaged |= indexed.damaged;
        packs.push(pack);
        found.names.push(name);
    }
    // Latest record first within each identity, then keep only it.
    slots.sort_unstable_by(|a, b| a.id.cmp(&b.id).then(b.at.cmp(&a.at)));
    slots.dedup_by_key(|s| s.id);
    Ok((packs, Index::new(slots), found))
}

/// What reading one pack's frames found.
pub(super) struct Indexed {
    /// Whole records.
    pub(super) records: usize,
    /// Bytes that are no record.
    pub(super) damaged: bool,
    /// Whether the cache wrote the file: it begins with the record marker (every pack the cache
    /// writes does, even one torn in its first record) or holds a frame that checks somewhere. A
    /// file without either holds nothing of the cache's, whatever its name: it is never used
    /// and never removed.
    pub(super) ours: bool,
}

/// Adds the records of pack number `number` to `slots`; returns what it found. Bodies are not
/// verified here, only when used.
pub(super) fn index_pack(pack: &Pack, number: usize, slots: &mut Vec<Slot>) -> io::Result<Indexed> {
    let mut window = Window::new(pack);
    let (mut records, mut damaged) = (0, false);
    let mut ours = window.get(0, MAGIC.len())? == MAGIC;
    let mut at = 0;
    while at < pack.len {
        let bytes = window.get(at, FRAME)?;
        if let Some((id, len)) = frame(bytes) {
            ours = true;
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
    Ok(Indexed {
        records,
        damaged,
        ours,
    })
}

/// The identity and body length in a frame, if it is one.
pub(super) fn frame(bytes: &[u8]) -> Option<(Id, usize)> {
    if bytes.len() < FRAME || bytes[..4] != MAGIC {
        return None;
    }
    let id = Id::from_le_bytes(bytes[4..12].try_into().ok()?);
    let len = u32::from_le_bytes(bytes[12..16].try_into().ok()?) as usize;
    let check = u32::from_le_bytes(bytes[16..20].try_into().ok()?);
    (check == frame_check(&bytes[4..16]) && len <= MAX_BODY).then_some((id, len))
}

/// A whole record: the frame (marker, identity, body length, check of the two), then `body`.
pub(super) fn record(id: Id, body: &[u8]) -> std::io::Result<Vec<u8>> {
    if body.len() > MAX_BODY {
        return Err(std::io::Error::other(
            "the entry is too large for the cache",
        ));
    }
    let mut out = Vec::with_capacity(FRAME + body.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&id.to_le_bytes());
    out.extend_from_slice(&(body.len() as u32).to_le_bytes());
    let check = frame_check(&out[4..16]);
    out.extend_from_slice(&check.to_le_bytes());
    out.extend_from_slice(body);
    Ok(out)
}

/// FNV-1a of the identity and length: catches a damaged length or a false marker cheaply (the
/// body has its own checksum).
pub(super) fn frame_check(bytes: &[u8]) -> u32 {
    bytes.iter().fold(0x811c_9dc5, |h, &b| {
        (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
    })
}

/// Whether `name` is one [`pack_name`] gives: `pack-`, 20 digits, `-`, digits, `-`, digits.
pub(super) fn is_pack_name(name: &str) -> bool {
    let digits = |part: Option<&str>| {
        part.is_some_and(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()))
    };
    let Some(rest) = name.strip_prefix("pack-") else {
        return false;
    };
    let mut parts = rest.split('-');
    let time = parts.next();
    time.is_some_and(|t| t.len() == 20)
        && digits(time)
        && digits(parts.next())
        && digits(parts.next())
        && parts.next().is_none()
}

/// `pack-<ns>-<pid>-<n>`, at least one nanosecond later than `newest` (so it sorts after every
/// pack seen even if the clock went back; if another run's clock is behind, a record may be
/// superseded by an older one, which costs a miss, never a wrong row).
pub(super) fn pack_name(newest: u64) -> String {
    pub(super) static NEXT: AtomicU64 = AtomicU64::new(0);
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    format!(
        "pack-{:020}-{}-{}",
        now.max(newest.saturating_add(1)),
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    )
}

/// Copies the indexed records whose body `verifies`, in the order they were written.
pub(super) fn copy_live(
    packs: &[Pack],
    index: &[Slot],
    verifies: impl Fn(&[u8]) -> bool,
    out: &mut impl Write,
) -> io::Result<()> {
    let mut slots = index.to_vec();
    slots.sort_unstable_by_key(|s| s.at);
    let mut window: Option<(usize, Window<'_>)> = None;
    for slot in slots {
        if window.as_ref().is_none_or(|(pack, _)| *pack != slot.pack()) {
            window = Some((slot.pack(), Window::new(&packs[slot.pack()])));
        }
        let (_, window) = window.as_mut().expect("set above");
        let record = window.get(slot.offset(), slot.len as usize)?;
        if record.len() == slot.len as usize && verifies(&record[FRAME..]) {
            out.write_all(record)?;
        }
    }
    Ok(())
}

pub(super) fn remove_if_there(path: &Path) -> io::Result<()> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
        _ => Ok(()),
    }
}

/// A compaction's temporary file: [`AtomicFile`] names it `.NAME.PID.N.tmp` after the pack
/// `NAME` it becomes.
pub(super) fn is_temporary_pack(name: &str) -> bool {
    is_temporary_of(name, is_pack_name)
}

/// Whether `name` is `.NAME.PID.N.tmp` (an [`AtomicFile`]'s temporary name) with `is_target(NAME)`.
fn is_temporary_of(name: &str, is_target: impl Fn(&str) -> bool) -> bool {
    let digits = |p: &str| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit());
    let Some(inner) = name.strip_prefix('.').and_then(|n| n.strip_suffix(".tmp")) else {
        return false;
    };
    let mut parts = inner.rsplitn(3, '.');
    let (n, pid, target) = (parts.next(), parts.next(), parts.next());
    n.is_some_and(digits) && pid.is_some_and(digits) && target.is_some_and(is_target)
}

pub(super) fn is_hex(name: &str, len: usize) -> bool {
    name.len() == len && name.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

/// A folder of format 2's entries: two hex digits.
pub(super) fn is_old_folder(name: &str) -> bool {
    is_hex(name, 2)
}

/// Whether the regular file at `path` is a pack the cache wrote (see [`Indexed::ours`]).
fn holds_records(path: &Path) -> bool {
    Pack::open(path)
        .and_then(|pack| index_pack(&pack, 0, &mut Vec::new()))
        .is_ok_and(|indexed| indexed.ours)
}

/// Whether the regular file at `path` begins as the entries of formats 1 and 2 began.
fn is_old_entry(path: &Path) -> bool {
    const OLD_HEADER: &[u8] = b"meshvet-cache ";
    let Ok(pack) = Pack::open(path) else {
        return false;
    };
    let mut start = [0; OLD_HEADER.len()];
    pack.read_at(&mut start, 0).is_ok_and(|n| n == start.len()) && start == OLD_HEADER
}

/// What [`remove_leftovers`] removes for the folder entry `entry`: a compaction's temporary
/// file (only a crash leaves one: compaction holds the folder alone), or in a folder of format 2
/// (two hex digits) the files named as it named entries (62 hex digits) and their temporary files.
/// Only a regular file whose name is exactly one the cache gives and whose bytes show the cache
/// wrote it (a pack's record marker, an old entry's header) is one: anything else is left alone,
/// in case the folder is not only the cache's.
fn old_entries(entry: &std::fs::DirEntry) -> Vec<PathBuf> {
    let is_file = |entry: &std::fs::DirEntry| entry.file_type().is_ok_and(|t| t.is_file());
    let name = entry.file_name();
    let Some(name) = name.to_str() else {
        return Vec::new();
    };
    if is_temporary_pack(name) {
        return if is_file(entry) && holds_records(&entry.path()) {
            vec![entry.path()]
        } else {
            Vec::new()
        };
    }
    if !is_old_folder(name) || !entry.file_type().is_ok_and(|t| t.is_dir()) {
        return Vec::new();
    }
    std::fs::read_dir(entry.path())
        .into_iter()
        .flatten()
        .flatten()
        .filter(|file| {
            let name = file.file_name();
            let named = name
                .to_str()
                .is_some_and(|n| is_hex(n, 62) || is_temporary_of(n, |n| is_hex(n, 62)));
            named && is_file(file) && is_old_entry(&file.path())
        })
        .map(|file| file.path())
        .collect()
}

/// Removes the leftovers in `dir` (see [`old_entries`]), then each format 2 folder they emptied.
pub(super) fn remove_leftovers(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let files = old_entries(&entry);
        for file in &files {
            let _ = std::fs::remove_file(file);
        }
        if !files.is_empty() && entry.file_type().is_ok_and(|t| t.is_dir()) {
            let _ = std::fs::remove_dir(entry.path());
        }
    }
}
