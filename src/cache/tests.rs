use super::entry::{body, decode, encode, Entry, Meta, HEADER};
use super::pack::{
    frame, frame_check, list, load, record, Id, Index, Slot, FRAME, MAGIC, MAX_PACKS,
};
use super::*;
use crate::report::Row;
use crate::rules::{Rule, Severity, Status};
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

/// The packs of `DIR/cache` (not the files there only named like packs).
fn packs(dir: &Path) -> Vec<PathBuf> {
    load(&dir.join("cache"))
        .unwrap()
        .2
        .names
        .iter()
        .map(|n| dir.join("cache").join(n))
        .collect()
}

/// The regular files of `DIR/cache` named as packs are, one still empty in its writer's buffer
/// included.
fn pack_files(dir: &Path) -> Vec<PathBuf> {
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

/// A file replaced while it is scanned (after the cache hashed it, before the reader read it),
/// then put back: the outcomes of the other bytes are not stored under the first bytes' key
/// (before, the next run hit them: an open triangle reported as the tetrahedron).
#[cfg(unix)]
#[test]
fn a_file_changed_during_its_scan_is_not_stored() {
    let (dir, source) = setup();
    let path = source.path.clone();
    let settings = Settings::default();
    let cache = open(dir.path());
    let during = cache.outcomes(&source, || {
        let other = dir.path().join("other.obj");
        std::fs::write(&other, TETRA).unwrap();
        std::fs::rename(&other, &path).unwrap();
        scan_file(&source, &settings)
    });
    assert_eq!(
        during[0].row.faces,
        Some(4),
        "the scan read the tetrahedron"
    );
    cache.finish().unwrap();
    std::fs::write(&path, OPEN).unwrap();
    let (stats, outcomes) = run(dir.path(), std::slice::from_ref(&source));
    assert_eq!((stats.hits, stats.misses), (0, 1));
    assert_eq!(outcomes, fresh(std::slice::from_ref(&source)));
    assert_eq!(outcomes[0][0].row.faces, Some(1));
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

/// Each role a shell can have comes back from an entry as it went in (a role the decoder did not
/// know would make the entry unreadable, and the scan would redo the file every time).
#[test]
fn every_shell_role_comes_back() {
    use crate::report::ShellRow;
    use crate::topology::Role;
    let shells: Vec<ShellRow> = [Role::Solid, Role::Cavity, Role::Neither]
        .into_iter()
        .enumerate()
        .map(|(depth, role)| ShellRow {
            faces: 4,
            depth,
            role,
            ..ShellRow::default()
        })
        .collect();
    let outcome = Outcome {
        shells: shells.clone(),
        ..Outcome::default()
    };
    let decoded = decode(&encode(&[outcome]).unwrap()).unwrap().remove(0);
    assert_eq!(decoded.shells, shells);
}

/// The cells decode as they read back from a CSV file: every field distinct, so a column read
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
        self_intersections: Some(26),
        intersecting_components: Some(27),
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
        writer.write_record(row.cells()).unwrap();
        let line = writer.into_inner().unwrap();
        let record = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(line.as_slice())
            .records()
            .next()
            .unwrap()
            .unwrap();
        assert_eq!(Row::from_cells(record.iter()), Ok(decoded));
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
    let good = record(7, &body(&hash, &hash, &meta, b"payload")).unwrap();
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
    // Enough packs that compaction is due (none compacts while `blocker` is open), and the user's
    // files named like packs, which are none.
    let blocker = open(dir.path());
    for i in 0..=MAX_PACKS {
        run(dir.path(), &sources[i..=i]);
        std::fs::write(
            dir.path().join("cache").join(format!("pack-{i}")),
            b"not a pack",
        )
        .unwrap();
    }
    drop(blocker);
    let before = pack_files(dir.path());
    assert_eq!(before.len(), MAX_PACKS + 1);
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
    let after_a = pack_files(dir.path());
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
    for i in 0..=MAX_PACKS {
        let theirs = dir.path().join("cache").join(format!("pack-{i}"));
        assert_eq!(std::fs::read(theirs).unwrap(), b"not a pack");
    }
}

#[test]
fn format_2_entries_are_removed_by_compaction_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let sources = tree(dir.path(), 1);
    let entry = format!("{:062x}", 7);
    std::fs::create_dir_all(cache.join("ab")).unwrap();
    std::fs::write(cache.join("ab").join(&entry), "meshvet-cache 2\n").unwrap();
    std::fs::write(
        cache.join("ab").join(format!(".{entry}.12.0.tmp")),
        "meshvet-cache 2\nha",
    )
    .unwrap();
    std::fs::create_dir_all(cache.join("cd")).unwrap();
    std::fs::write(cache.join("cd").join("notes.txt"), "mine").unwrap();
    std::fs::write(cache.join("cd").join(&entry), "mine, named like an entry").unwrap();
    std::fs::write(cache.join("notes.txt"), "mine").unwrap();
    // A compaction's temporary file, torn after its first marker; and the user's.
    let temporary = ".pack-00000000000000000001-2-3.4.0.tmp";
    std::fs::write(cache.join(temporary), b"\xF5mv3half").unwrap();
    std::fs::write(cache.join(".pack-1-2-3.1.0.tmp"), "mine").unwrap();
    std::fs::write(cache.join(".pack-00000000000000000001-2-3.5.0.tmp"), "mine").unwrap();
    let (stats, _) = run(dir.path(), &sources);
    assert_eq!(stats.misses, 1, "format 2's entry is not read");
    assert!(!cache.join("ab").exists());
    assert!(!cache.join(temporary).exists());
    assert!(cache.join(".pack-1-2-3.1.0.tmp").exists());
    assert!(cache
        .join(".pack-00000000000000000001-2-3.5.0.tmp")
        .exists());
    assert!(cache.join("cd/notes.txt").exists());
    assert!(cache.join("cd").join(&entry).exists());
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
    outside_dependency_is_never_read("m.obj", &format!("mtllib ../outside.bin\n{OPEN}"), |_| {});
    outside_dependency_is_never_read("m.gltf", &GLTF.replace("URI", "../outside.bin"), |_| {});
    outside_dependency_is_never_read("m.gltf", &GLTF.replace("URI", "..%2Foutside.bin"), |_| {});
    #[cfg(unix)]
    {
        let link = |dir: &Path| {
            std::os::unix::fs::symlink(dir.join("outside.bin"), dir.join("tree/link.bin")).unwrap()
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

/// A folder used as the cache that also holds the user's files, some named like packs
/// (`pack-...`) or a compaction's temporary files: however often the cache compacts, they stay
/// as they were. Only a regular file named exactly as the cache names its packs, and in which a
/// record of the cache is found, is a pack.
#[test]
fn files_in_the_cache_folder_that_are_not_its_packs_are_never_removed() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    std::fs::create_dir_all(&cache).unwrap();
    let theirs: [(&str, &[u8]); 7] = [
        ("pack-hole.obj", OPEN.as_bytes()),
        ("pack-list.txt", b"my notes\n"),
        ("pack-", b"x"),
        // The exact name of a pack, but no record in it: nothing the cache wrote.
        (
            "pack-00000000000000000001-1-0",
            b"my notes, named like a pack\n",
        ),
        ("pack-00000000000000000002-1-0", b""),
        // A marker but no frame further on: not at the start, so not the cache's either.
        ("pack-00000000000000000003-1-0", b"notes \xF5mv3 and more"),
        (
            ".pack-00000000000000000004-1-0.1.0.tmp",
            b"half of my notes",
        ),
    ];
    for (name, bytes) in theirs {
        std::fs::write(cache.join(name), bytes).unwrap();
    }
    let sources = tree(dir.path(), MAX_PACKS + 1);
    // One pack per run, so the last run compacts; then a damaged pack, so the next one does.
    for i in 0..=MAX_PACKS {
        run(dir.path(), &sources[i..=i]);
    }
    assert_eq!(packs(dir.path()).len(), 1, "the last run merged its packs");
    let pack = packs(dir.path()).remove(0);
    let mut bytes = std::fs::read(&pack).unwrap();
    bytes.extend_from_slice(b"torn");
    std::fs::write(&pack, bytes).unwrap();
    let (stats, rows) = run(dir.path(), &sources);
    assert_eq!(stats.hits, MAX_PACKS + 1);
    assert_eq!(rows, fresh(&sources));
    assert!(!pack.exists(), "the damaged pack was merged away");
    for (name, bytes) in theirs {
        assert_eq!(std::fs::read(cache.join(name)).unwrap(), bytes, "{name}");
    }
    // They count as no pack: not damage, not towards the packs that make a merge due.
    let (packs, _, found) = load(&cache).unwrap();
    assert_eq!((packs.len(), found.damaged), (1, false));
    assert_eq!(found.foreign.len(), 3, "{:?}", found.foreign);
}

/// A pack the cache wrote, torn in its first record, is still the cache's (it begins with the
/// marker): it is merged away like any damaged pack.
#[test]
fn a_pack_torn_in_its_first_record_is_still_removed() {
    let dir = tempfile::tempdir().unwrap();
    let sources = tree(dir.path(), 1);
    run(dir.path(), &sources);
    let pack = packs(dir.path()).remove(0);
    let bytes = std::fs::read(&pack).unwrap();
    std::fs::write(&pack, &bytes[..FRAME - 1]).unwrap();
    let (_, _, found) = load(&dir.path().join("cache")).unwrap();
    assert_eq!(found.names.len(), 1);
    assert!(found.damaged);
    let (stats, _) = run(dir.path(), &sources);
    assert_eq!(stats.misses, 1);
    assert!(!pack.exists());
    assert_eq!(packs(dir.path()).len(), 1);
}

/// A FIFO named like a pack (or a compaction's temporary file) would block the open for ever, and
/// a link named like one may lead anywhere: neither is opened, read through or removed.
#[cfg(unix)]
#[test]
fn a_fifo_or_link_named_like_a_pack_is_neither_opened_nor_removed() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let sources = tree(dir.path(), MAX_PACKS + 1);
    // A real pack, moved out of the folder and linked to from it.
    run(dir.path(), &sources[..1]);
    let pack = packs(dir.path()).remove(0);
    let outside = dir.path().join("outside-pack");
    std::fs::rename(&pack, &outside).unwrap();
    std::os::unix::fs::symlink(&outside, &pack).unwrap();
    let kept = std::fs::read(&outside).unwrap();
    let fifos = [
        "pack-00000000000000000001-1-0",
        ".pack-00000000000000000001-1-0.1.0.tmp",
    ];
    for name in fifos {
        let status = std::process::Command::new("mkfifo")
            .arg(cache.join(name))
            .status()
            .unwrap();
        assert!(status.success());
    }
    let (done, wait) = std::sync::mpsc::channel();
    let (root, all) = (dir.path().to_owned(), sources.clone());
    std::thread::spawn(move || {
        let first = run(&root, &all[..1]);
        // One pack per run, so the last run compacts.
        for i in 1..=MAX_PACKS {
            run(&root, &all[i..=i]);
        }
        let _ = done.send(first);
    });
    let (stats, rows) = wait
        .recv_timeout(std::time::Duration::from_secs(60))
        .expect("the runs hang on the FIFO");
    assert_eq!((stats.hits, stats.misses), (0, 1), "the link was not read");
    assert_eq!(rows, fresh(&sources[..1]));
    assert_eq!(packs(dir.path()).len(), 1, "the last run merged its packs");
    let link = std::fs::symlink_metadata(&pack).unwrap();
    assert!(link.file_type().is_symlink());
    assert_eq!(std::fs::read(&outside).unwrap(), kept);
    for name in fifos {
        use std::os::unix::fs::FileTypeExt;
        let meta = std::fs::symlink_metadata(cache.join(name)).unwrap();
        assert!(meta.file_type().is_fifo(), "{name}");
    }
}

/// A link named `lock` in the cache folder is not followed: nothing is created or locked where it
/// leads, and the cache still works (without a lock it never compacts).
#[cfg(unix)]
#[test]
fn a_link_named_lock_is_not_followed() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    std::fs::create_dir_all(&cache).unwrap();
    let outside = dir.path().join("outside-lock");
    std::os::unix::fs::symlink(&outside, cache.join("lock")).unwrap();
    let sources = tree(dir.path(), 1);
    run(dir.path(), &sources);
    let (stats, rows) = run(dir.path(), &sources);
    assert_eq!(stats.hits, 1);
    assert_eq!(rows, fresh(&sources));
    assert!(!outside.exists(), "the link was followed");
}
