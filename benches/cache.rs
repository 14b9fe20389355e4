//! Cache benchmark (issue 5): a generated tree of 5,000 small files (OBJ and binary STL tori of
//! 200 to 3,000 triangles), scanned without a cache, then with `--cache` cold (empty folder) and
//! warm (the tree unchanged). Each run is a whole scan as the binary does it: open the cache (which
//! reads its packs), walk, scan on 2 threads, every row serialized to CSV (in memory), finish the
//! cache (write out its pack).
//!
//!     cargo bench --bench cache

use std::fmt::Write as _;
use std::fs;
use std::path::Path;
use std::time::Instant;

use meshvet::cache::{Cache, Stats};
use meshvet::config::Settings;
use meshvet::report::Row;
use meshvet::scan;
use meshvet::walk::{walk, Filter, Source};
use meshvet::Mesh;

#[path = "../tests/shapes/mod.rs"]
#[allow(dead_code)]
mod shapes;

const FILES: usize = 5000;

fn main() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let tree = dir.path().join("library");
    let bytes = write_tree(&tree);
    println!("tree: {FILES} small files, {:.1} MB", bytes as f64 / 1e6);
    let settings = Settings {
        jobs: 2,
        ..Settings::default()
    };

    let (plain, plain_csv, _) = run(&tree, &settings, None);
    println!("  no cache:       {plain:.2} s");
    let cache_dir = dir.path().join("cache");
    let (cold, cold_csv, stats) = run(&tree, &settings, Some(&cache_dir));
    println!("  cache, cold:    {cold:.2} s  ({stats:?})");
    println!(
        "  cache folder:   {:.1} MB",
        folder_bytes(&cache_dir) as f64 / 1e6
    );
    let mut warm = f64::INFINITY;
    let mut warm_csv = String::new();
    let mut stats = Default::default();
    for _ in 0..3 {
        let (seconds, csv, run_stats) = run(&tree, &settings, Some(&cache_dir));
        stats = run_stats;
        assert_eq!(stats.misses, 0, "every file comes from the cache");
        warm = warm.min(seconds);
        warm_csv = csv;
    }
    println!("  cache, warm:    {warm:.3} s (best of 3; {stats:?})");
    println!(
        "  warm re-scan is {:.1}x faster than the cold scan ({:.1}x than no cache)",
        cold / warm,
        plain / warm
    );
    assert_eq!(
        plain_csv, cold_csv,
        "the cache changes no row (millis aside)"
    );
    assert_eq!(
        cold_csv, warm_csv,
        "a cached row equals a fresh one (millis aside)"
    );
}

/// One whole scan, opening and finishing the cache in `cache` if given; returns its wall time, the
/// CSV without `millis` and the cache's figures.
fn run(tree: &Path, settings: &Settings, cache: Option<&Path>) -> (f64, String, Stats) {
    let start = Instant::now();
    let cache = cache.map(|dir| Cache::open(dir, settings).unwrap());
    let sources = walk(&[tree.to_owned()], &Filter::everything());
    let per_file = |source: &Source| {
        let fresh = || scan::scan_file(source, settings);
        match &cache {
            Some(cache) => cache.outcomes(source, fresh),
            None => fresh(),
        }
    };
    let mut csv = csv::Writer::from_writer(Vec::new());
    scan::scan_each(&sources, settings.jobs, &per_file, &|_| {}, |outcome| {
        let row = Row {
            millis: None,
            ..outcome.row
        };
        csv.write_record(row.cells()).map_err(std::io::Error::other)
    })
    .unwrap();
    let stats = cache.map_or_else(Stats::default, |c| c.finish().unwrap());
    let seconds = start.elapsed().as_secs_f64();
    let csv = String::from_utf8(csv.into_inner().unwrap()).unwrap();
    (seconds, csv, stats)
}

fn folder_bytes(dir: &Path) -> u64 {
    fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().metadata().unwrap().len())
        .sum()
}

fn write_tree(root: &Path) -> u64 {
    let mut bytes = 0;
    for i in 0..FILES {
        let folder = root.join(format!("set{:02}", i / 100));
        fs::create_dir_all(&folder).unwrap();
        let mesh = shapes::torus(10 + (i * 7) % 40, 10 + i % 20, Some(i as u64 + 1));
        let path = if i % 2 == 0 {
            let path = folder.join(format!("m{i}.obj"));
            fs::write(&path, obj(&mesh)).unwrap();
            path
        } else {
            let path = folder.join(format!("m{i}.stl"));
            fs::write(&path, stl(&mesh)).unwrap();
            path
        };
        bytes += fs::metadata(path).unwrap().len();
    }
    bytes
}

fn obj(mesh: &Mesh) -> String {
    let mut s = String::with_capacity(mesh.triangles.len() * 40);
    for p in &mesh.positions {
        writeln!(s, "v {} {} {}", p[0] as f32, p[1] as f32, p[2] as f32).unwrap();
    }
    for t in &mesh.triangles {
        writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    s
}

fn stl(mesh: &Mesh) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend((mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        b.extend([0u8; 12]);
        for i in t {
            for x in mesh.positions[*i as usize] {
                b.extend((x as f32).to_le_bytes());
            }
        }
        b.extend([0u8; 2]);
    }
    b
}
