//! Scan benchmark (issue 3): a generated tree of 2,000 small files in every format, plus one
//! 2M-triangle OBJ and one 2M-triangle binary STL.
//!
//! Prints files/s and MB/s end to end with 1 and 2 threads (and the speed-up), parse-only vs full scan
//! time for the large files, and the peak resident memory of each phase.
//!
//!     cargo bench --bench scan

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use meshvet::config::Settings;
use meshvet::formats::{self, Format, ReadContext};
use meshvet::scan;
use meshvet::walk::{walk, Filter};
use meshvet::Mesh;

#[path = "../tests/shapes/mod.rs"]
#[allow(dead_code)]
mod shapes;

mod common;
use common::best;

fn main() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let small = dir.path().join("library");
    let bytes = write_small_tree(&small, 2000);
    println!("tree: 2000 small files, {:.1} MB", bytes as f64 / 1e6);

    let mut rates = Vec::new();
    for jobs in [1, 2] {
        reset_peak_rss();
        let (seconds, rows) = scan_tree(&small, jobs);
        rates.push(2000.0 / seconds);
        println!(
            "  {jobs} thread(s): {seconds:.2} s, {rows} rows, {:.0} files/s, {:.1} MB/s, peak RSS {} MB",
            2000.0 / seconds,
            bytes as f64 / 1e6 / seconds,
            peak_rss_mb()
        );
    }
    println!("  speed-up 1 -> 2 threads: {:.2}x", rates[1] / rates[0]);

    let big = dir.path().join("big");
    fs::create_dir_all(&big).unwrap();
    // A 1000 x 1000 grid torus: 2,000,000 triangles.
    let torus = shapes::torus(1000, 1000, None);
    let obj = big.join("torus.obj");
    let stl = big.join("torus.stl");
    write_obj(&obj, &torus);
    write_stl(&stl, &torus);
    drop(torus);
    for (path, format) in [(obj, Format::Obj), (stl, Format::Stl)] {
        let size = fs::metadata(&path).unwrap().len() as f64 / 1e6;
        let cx = ReadContext {
            root: big.clone(),
            limits: Default::default(),
        };
        reset_peak_rss();
        let (parse, _) = best(3, || formats::read(&path, format, &cx).expect("readable"));
        let parse_rss = peak_rss_mb();
        reset_peak_rss();
        let (full, rows) = best(3, || scan_tree(&path, 1));
        println!(
            "{}: {size:.0} MB; parse only {:.0} ms ({:.0} MB/s, peak RSS {parse_rss} MB); full scan {:.0} ms \
             ({:.0} MB/s, peak RSS {} MB, {} rows); scan / parse = {:.2}",
            path.file_name().unwrap().to_string_lossy(),
            parse * 1e3,
            size / parse,
            full * 1e3,
            size / full,
            peak_rss_mb(),
            rows.1,
            full / parse
        );
    }
}

/// Walks and scans `path` with `jobs` threads, the way the command line does: (seconds, rows).
fn scan_tree(path: &Path, jobs: usize) -> (f64, usize) {
    let settings = Settings {
        jobs,
        ..Settings::default()
    };
    let start = Instant::now();
    let sources = walk(&[path.to_path_buf()], &Filter::everything());
    let mut rows = 0;
    scan::scan::<std::io::Error>(&sources, &settings, &|_| {}, |_| {
        rows += 1;
        Ok(())
    })
    .expect("scan");
    (start.elapsed().as_secs_f64(), rows)
}

/// 2,000 small meshes (tori of 200 to 5,000 triangles) in all six formats, 100 per folder.
fn write_small_tree(root: &Path, count: usize) -> u64 {
    let mut bytes = 0;
    for i in 0..count {
        let folder = root.join(format!("set{:02}", i / 100));
        fs::create_dir_all(&folder).unwrap();
        let n = 10 + (i * 7) % 40;
        let mesh = shapes::torus(n, 10 + i % 20, Some(i as u64 + 1));
        let path: PathBuf = match i % 6 {
            0 => write_obj(&folder.join(format!("m{i}.obj")), &mesh),
            1 => write_stl(&folder.join(format!("m{i}.stl")), &mesh),
            2 => write_ply(&folder.join(format!("m{i}.ply")), &mesh),
            3 => write_off(&folder.join(format!("m{i}.off")), &mesh),
            4 => write_glb(&folder.join(format!("m{i}.glb")), &mesh),
            _ => write_ascii_stl(&folder.join(format!("m{i}_ascii.stl")), &mesh),
        };
        bytes += fs::metadata(path).unwrap().len();
    }
    bytes
}

fn write_obj(path: &Path, mesh: &Mesh) -> PathBuf {
    let mut s = String::with_capacity(mesh.triangles.len() * 40);
    for p in &mesh.positions {
        writeln!(s, "v {} {} {}", p[0] as f32, p[1] as f32, p[2] as f32).unwrap();
    }
    for t in &mesh.triangles {
        writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    fs::write(path, s).unwrap();
    path.to_path_buf()
}

fn write_off(path: &Path, mesh: &Mesh) -> PathBuf {
    let mut s = format!("OFF\n{} {} 0\n", mesh.positions.len(), mesh.triangles.len());
    for p in &mesh.positions {
        writeln!(s, "{} {} {}", p[0] as f32, p[1] as f32, p[2] as f32).unwrap();
    }
    for t in &mesh.triangles {
        writeln!(s, "3 {} {} {}", t[0], t[1], t[2]).unwrap();
    }
    fs::write(path, s).unwrap();
    path.to_path_buf()
}

fn corners(mesh: &Mesh, t: &[u32; 3]) -> [[f32; 3]; 3] {
    t.map(|i| mesh.positions[i as usize].map(|x| x as f32))
}

fn write_stl(path: &Path, mesh: &Mesh) -> PathBuf {
    let mut b = vec![0u8; 80];
    b.extend((mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        b.extend([0u8; 12]);
        for p in corners(mesh, t) {
            for x in p {
                b.extend(x.to_le_bytes());
            }
        }
        b.extend([0u8; 2]);
    }
    fs::write(path, b).unwrap();
    path.to_path_buf()
}

fn write_ascii_stl(path: &Path, mesh: &Mesh) -> PathBuf {
    let mut s = String::from("solid bench\n");
    for t in &mesh.triangles {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for p in corners(mesh, t) {
            writeln!(s, "vertex {} {} {}", p[0], p[1], p[2]).unwrap();
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid bench\n");
    fs::write(path, s).unwrap();
    path.to_path_buf()
}

fn write_ply(path: &Path, mesh: &Mesh) -> PathBuf {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )
    .into_bytes();
    for p in &mesh.positions {
        for x in p {
            b.extend((*x as f32).to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        b.push(3);
        for i in t {
            b.extend(i.to_le_bytes());
        }
    }
    fs::write(path, b).unwrap();
    path.to_path_buf()
}

fn write_glb(path: &Path, mesh: &Mesh) -> PathBuf {
    let mut bin = Vec::new();
    for p in &mesh.positions {
        for x in p {
            bin.extend((*x as f32).to_le_bytes());
        }
    }
    let positions_len = bin.len();
    for t in &mesh.triangles {
        for i in t {
            bin.extend(i.to_le_bytes());
        }
    }
    let (lo, hi) = mesh
        .positions
        .iter()
        .fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
            (
                [0, 1, 2].map(|k| lo[k].min(p[k])),
                [0, 1, 2].map(|k| hi[k].max(p[k])),
            )
        });
    let mut json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
"buffers":[{{"byteLength":{}}}],
"bufferViews":[{{"buffer":0,"byteLength":{positions_len}}},{{"buffer":0,"byteOffset":{positions_len},"byteLength":{}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":[{},{},{}],"max":[{},{},{}]}},
{{"bufferView":1,"componentType":5125,"count":{},"type":"SCALAR"}}]}}"#,
        bin.len(),
        bin.len() - positions_len,
        mesh.positions.len(),
        lo[0] as f32,
        lo[1] as f32,
        lo[2] as f32,
        hi[0] as f32,
        hi[1] as f32,
        hi[2] as f32,
        3 * mesh.triangles.len()
    )
    .into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut b = Vec::with_capacity(total);
    b.extend(b"glTF");
    b.extend(2u32.to_le_bytes());
    b.extend((total as u32).to_le_bytes());
    b.extend((json.len() as u32).to_le_bytes());
    b.extend(b"JSON");
    b.extend(&json);
    b.extend((bin.len() as u32).to_le_bytes());
    b.extend(b"BIN\0");
    b.extend(&bin);
    fs::write(path, b).unwrap();
    path.to_path_buf()
}

/// Resets the kernel's peak-RSS mark of this process (Linux: `5` into clear_refs).
fn reset_peak_rss() {
    let _ = fs::write("/proc/self/clear_refs", "5");
}

/// Peak resident set size since the last reset, in MB (0 where /proc is missing).
fn peak_rss_mb() -> u64 {
    let status = fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        .map_or(0, |kb| kb / 1024)
}
