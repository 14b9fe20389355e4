//! Reader benchmark: MB/s of each reader on one thread, on large generated files of the same mesh
//! (a closed grid torus of 1,000,000 triangles and 500,000 vertices) written as OBJ, ASCII PLY,
//! OFF, ASCII STL, binary STL and binary PLY. Each file is read several times through
//! `meshvet::formats::read` (file bytes from the page cache, so the figure is the parser's); the
//! lowest, median and highest rates are printed, since a loaded machine makes single runs noisy,
//! both by wall time and by the thread's CPU time (which other processes disturb less).
//!
//!     cargo bench --bench read              # every format
//!     cargo bench --bench read -- obj stl   # the formats whose label contains a word

use std::fmt::Write as _;
use std::fs;
use std::path::Path;
use std::time::Instant;

use meshvet::formats::{self, Format, ReadContext};
use meshvet::Mesh;

#[path = "../tests/shapes/mod.rs"]
#[allow(dead_code)]
mod shapes;

/// The allocator the `meshvet` program runs with (large blocks on huge pages), so that the figures
/// are the reader's as a scan runs it: with 4 KiB pages, faulting in the fresh output arrays costs
/// more than decoding a binary file (binary STL: about 1,000 MB/s with the system allocator's
/// small pages, 3,000 with huge ones).
#[global_allocator]
static ALLOCATOR: meshvet::pages::HugePages = meshvet::pages::HugePages;

/// Reads of each file; the first warms the page cache and is not counted.
const RUNS: usize = 7;

/// One file to read: its label, its format, and how it is written.
struct Case {
    label: &'static str,
    file: &'static str,
    format: Format,
    write: fn(&Mesh) -> Vec<u8>,
}

const CASES: [Case; 6] = [
    Case {
        label: "obj",
        file: "torus.obj",
        format: Format::Obj,
        write: obj,
    },
    Case {
        label: "ply-ascii",
        file: "torus_ascii.ply",
        format: Format::Ply,
        write: ply_ascii,
    },
    Case {
        label: "off",
        file: "torus.off",
        format: Format::Off,
        write: off,
    },
    Case {
        label: "stl-ascii",
        file: "torus_ascii.stl",
        format: Format::Stl,
        write: stl_ascii,
    },
    Case {
        label: "stl-binary",
        file: "torus.stl",
        format: Format::Stl,
        write: stl_binary,
    },
    Case {
        label: "ply-binary",
        file: "torus.ply",
        format: Format::Ply,
        write: ply_binary,
    },
];

fn main() {
    // What the program does at its start (src/main.rs).
    meshvet::pages::keep_freed_memory();
    let words: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let dir = tempfile::tempdir().expect("temporary folder");
    // 1000 x 500 grid torus: 2 * 1000 * 500 = 1,000,000 triangles on 500,000 vertices.
    let torus = shapes::torus(1000, 500, None);
    let cx = ReadContext {
        root: dir.path().to_path_buf(),
        limits: Default::default(),
    };
    println!(
        "one thread, {} reads of each file after one warm-up (MB = 10^6 bytes)",
        RUNS - 1
    );
    for case in &CASES {
        if !words.is_empty() && !words.iter().any(|w| case.label.contains(w.as_str())) {
            continue;
        }
        let path = dir.path().join(case.file);
        let bytes = (case.write)(&torus);
        fs::write(&path, &bytes).expect("write the file");
        let mb = bytes.len() as f64 / 1e6;
        drop(bytes);
        let (mut wall, mut cpu) = (Vec::new(), Vec::new());
        for run in 0..RUNS {
            let (seconds, cpu_seconds, meshes) = timed(|| read(&path, case.format, &cx));
            assert_eq!(meshes[0].triangles.len(), 1_000_000, "{}", case.label);
            if run > 0 {
                wall.push(mb / seconds);
                cpu.push(mb / cpu_seconds);
            }
        }
        println!(
            "{:<11} {mb:>6.1} MB  wall {}  cpu {}",
            case.label,
            range(&mut wall),
            range(&mut cpu)
        );
        let _ = fs::remove_file(&path);
    }
}

fn read(path: &Path, format: Format, cx: &ReadContext) -> Vec<Mesh> {
    formats::read(path, format, cx).expect("the generated file reads")
}

/// `lowest .. highest MB/s (median m)`.
fn range(rates: &mut [f64]) -> String {
    rates.sort_by(f64::total_cmp);
    format!(
        "{:>5.0} .. {:>5.0} MB/s (median {:>5.0})",
        rates[0],
        rates[rates.len() - 1],
        rates[rates.len() / 2]
    )
}

/// Wall seconds, CPU seconds of this thread, and the result of `f`.
fn timed<T>(f: impl FnOnce() -> T) -> (f64, f64, T) {
    let (start, cpu) = (Instant::now(), thread_cpu_seconds());
    let out = f();
    (
        start.elapsed().as_secs_f64(),
        thread_cpu_seconds() - cpu,
        out,
    )
}

/// CPU time this thread has used, in seconds.
fn thread_cpu_seconds() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid timespec for the call to fill in.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
}

/// A coordinate as an exporter writes it: the shortest text of the f32 value (up to 9 digits).
fn coordinate(x: f64) -> f32 {
    x as f32
}

fn obj(mesh: &Mesh) -> Vec<u8> {
    let mut s = String::with_capacity(mesh.triangles.len() * 48);
    s.push_str("# torus\no torus\n");
    for p in &mesh.positions {
        let [x, y, z] = p.map(coordinate);
        writeln!(s, "v {x} {y} {z}").unwrap();
    }
    for t in &mesh.triangles {
        writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    s.into_bytes()
}

fn off(mesh: &Mesh) -> Vec<u8> {
    let header = format!("OFF\n{} {} 0\n", mesh.positions.len(), mesh.triangles.len());
    points_and_faces(header, mesh)
}

/// `header`, then a line `x y z` per vertex and `3 a b c` per face (OFF and ASCII PLY alike).
fn points_and_faces(mut s: String, mesh: &Mesh) -> Vec<u8> {
    for p in &mesh.positions {
        let [x, y, z] = p.map(coordinate);
        writeln!(s, "{x} {y} {z}").unwrap();
    }
    for t in &mesh.triangles {
        writeln!(s, "3 {} {} {}", t[0], t[1], t[2]).unwrap();
    }
    s.into_bytes()
}

fn ply_header(mesh: &Mesh, format: &str) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment torus\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )
}

fn ply_ascii(mesh: &Mesh) -> Vec<u8> {
    points_and_faces(ply_header(mesh, "ascii"), mesh)
}

fn ply_binary(mesh: &Mesh) -> Vec<u8> {
    let mut b = ply_header(mesh, "binary_little_endian").into_bytes();
    for p in &mesh.positions {
        for x in p.map(coordinate) {
            b.extend(x.to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        b.push(3);
        for i in t {
            b.extend((*i as i32).to_le_bytes());
        }
    }
    b
}

fn corners(mesh: &Mesh, t: &[u32; 3]) -> [[f32; 3]; 3] {
    t.map(|i| mesh.positions[i as usize].map(coordinate))
}

fn stl_ascii(mesh: &Mesh) -> Vec<u8> {
    let mut s = String::from("solid torus\n");
    for t in &mesh.triangles {
        s.push_str("  facet normal 0 0 0\n    outer loop\n");
        for [x, y, z] in corners(mesh, t) {
            writeln!(s, "      vertex {x:e} {y:e} {z:e}").unwrap();
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid torus\n");
    s.into_bytes()
}

fn stl_binary(mesh: &Mesh) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend((mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        b.extend([0u8; 12]);
        for x in corners(mesh, t).iter().flatten() {
            b.extend(x.to_le_bytes());
        }
        b.extend([0u8; 2]);
    }
    b
}
