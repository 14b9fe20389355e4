//! Repair benchmark (issue 4): the 1M-triangle torus of the engine benchmark with 1% of its faces
//! flipped and 50 small holes punched (each a vertex's six faces removed). Prints the analysis time
//! next to the repair-planning time, single-threaded.
//!
//!     cargo bench --bench repair

use std::time::Instant;

use meshvet::repair::{plan, Options};
use meshvet::{analyse, Mesh};

#[path = "../tests/shapes/mod.rs"]
#[allow(dead_code)]
mod shapes;

fn best<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..runs {
        let start = Instant::now();
        out = Some(f());
        best = best.min(start.elapsed().as_secs_f64());
    }
    (best, out.expect("one run"))
}

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
    println!("  repairs: {}", p.summary());
}
