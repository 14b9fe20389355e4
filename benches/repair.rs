//! Repair benchmark (issue 4): the 1M-triangle torus of the engine benchmark with 1% of its faces
//! flipped and 50 small holes punched (each a vertex's six faces removed). Prints, single-threaded,
//! the analysis time next to the repair-planning time (from scratch, and from the analysis's weld
//! and table as a repairing scan plans), and for the mesh as an OBJ file and as a binary STL the
//! scan time (read + analyse) next to the repair time: what a repairing scan of the file costs
//! beyond the scan (its read keeps what the writer needs, then analyse, plan, write the copy).
//!
//!     cargo bench --bench repair

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use meshvet::formats::write::{write_copy, ScanRead};
use meshvet::formats::{read, read_retaining, Format, ReadContext};

use meshvet::repair::{plan, plan_with, Options};
use meshvet::topology::analyse_keeping;
use meshvet::{analyse, Mesh};

#[path = "../tests/shapes/mod.rs"]
#[allow(dead_code)]
mod shapes;

mod common;
use common::best;

/// The torus with every 100th face flipped and the faces around 50 spread-out vertices removed.
fn damaged(n: usize, m: usize) -> Mesh {
    let mut mesh = shapes::torus(n, m, None);
    let holes: Vec<u32> = (0..50)
        .map(|i| ((i * n / 50) * m + (i * 7) % m) as u32)
        .collect();
    mesh.triangles
        .retain(|t| !t.iter().any(|v| holes.contains(v)));
    for (i, t) in mesh.triangles.iter_mut().enumerate() {
        if i % 100 == 0 {
            t.swap(1, 2);
        }
    }
    let mut rng = shapes::XorShift::new(0x5eed);
    rng.shuffle(&mut mesh.triangles);
    mesh
}

fn main() {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global()
        .ok();
    let mesh = damaged(1000, 500);
    let (scan, a) = best(3, || analyse(&mesh, &Default::default()));
    assert_eq!(a.holes(), 50);
    let (repair, p) = best(3, || plan(&mesh, &Options::default()));
    let (_, kept) = analyse_keeping(&mesh, &Default::default());
    let start = Instant::now();
    let same = plan_with(&mesh, &Options::default(), Some(kept));
    let reused = start.elapsed().as_secs_f64();
    assert_eq!(
        same, p,
        "the plan does not depend on where its table came from"
    );
    let after = analyse(&p.apply(&mesh), &Default::default());
    assert_eq!(
        (after.holes(), after.inconsistent_edges, after.genus()),
        (0, 0, Some(1))
    );
    println!(
        "torus 1M, 1% flipped, 50 holes: {} triangles",
        mesh.triangles.len()
    );
    println!("  analysis        {:7.1} ms", scan * 1e3);
    println!(
        "  repair plan     {:7.1} ms  ({:.2}x the analysis)",
        repair * 1e3,
        repair / scan
    );
    println!(
        "  repair plan from the analysis's weld and table {:7.1} ms",
        reused * 1e3
    );
    println!("  repairs: {}", p.summary());

    let dir = tempfile::tempdir().expect("temporary folder");
    let cx = ReadContext {
        root: dir.path().to_path_buf(),
        limits: Default::default(),
    };
    for (name, format) in [("torus.obj", Format::Obj), ("torus.stl", Format::Stl)] {
        let source = dir.path().join(name);
        write_file(&source, format, &mesh);
        let copy = dir.path().join(format!("repaired-{name}"));
        let (scan, _) = best(3, || {
            let m = read(&source, format, &cx).expect("readable").remove(0);
            analyse(&m, &Default::default())
        });
        // The same file in a repairing scan (`scan --repair-dir`): the read keeps what the writer
        // needs, the analysis keeps its weld and table, the plan starts from them and the copy
        // is written. What it costs beyond the scan is the repair.
        let (repairing, _) = best(3, || {
            let (mut meshes, retained) = read_retaining(&source, format, &cx).expect("readable");
            let m = meshes.remove(0);
            let (_, built) = analyse_keeping(&m, &Default::default());
            let p = plan_with(&m, &Options::default(), Some(built));
            let read = ScanRead {
                meshes: std::slice::from_ref(&m),
                retained,
            };
            write_copy(&source, format, &[Some(p)], &copy, &cx, Some(read)).expect("written")
        });
        let repair = repairing - scan;
        println!(
            "  {name}: scan (read + analyse) {:.0} ms; repairing scan {:.0} ms, so repair (plan + write) {:.0} ms = {:.2}x the scan",
            scan * 1e3,
            repairing * 1e3,
            repair * 1e3,
            repair / scan
        );
    }
}

fn write_file(path: &Path, format: Format, mesh: &Mesh) {
    let mut bytes = Vec::new();
    match format {
        Format::Obj => {
            let mut s = String::new();
            for p in &mesh.positions {
                writeln!(s, "v {} {} {}", p[0] as f32, p[1] as f32, p[2] as f32).unwrap();
            }
            for t in &mesh.triangles {
                writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
            }
            bytes = s.into_bytes();
        }
        _ => {
            bytes.extend([0u8; 80]);
            bytes.extend((mesh.triangles.len() as u32).to_le_bytes());
            for t in &mesh.triangles {
                bytes.extend([0u8; 12]);
                for &v in t {
                    for x in mesh.positions[v as usize] {
                        bytes.extend((x as f32).to_le_bytes());
                    }
                }
                bytes.extend([0u8; 2]);
            }
        }
    }
    std::fs::write(path, bytes).expect("written");
}
