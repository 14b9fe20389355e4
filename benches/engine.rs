//! Topology engine benchmark (issue 2): a closed grid torus of ~1M and ~5M triangles with shuffled
//! face order, single-threaded. Prints triangles/s for welding, the O-table build and the full
//! topology analysis (no search for faces that meet) and the full default analysis, with the peak
//! heap each allocates beyond the input mesh, per triangle; then the
//! stages of the analysis (the weld, the weld of the same mesh as a triangle soup, the build of the
//! Corner Table from the mesh, and the walks after it), and for the shuffled 5M torus the analysis on
//! a pool of two threads beside one (the same analysis, checked).
//!
//!     cargo bench --bench engine            # 1M and 5M
//!     cargo bench --bench engine -- 1       # 1M only

use std::alloc::{GlobalAlloc, Layout};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use meshvet::pages::HugePages;
use meshvet::topology::build;
use meshvet::{analyse, weld::weld, CornerTable, Mesh, Options};

#[path = "../tests/shapes/mod.rs"]
#[allow(dead_code)]
mod shapes;

mod common;
use common::best;

/// The program's allocator (large blocks on huge pages, [`HugePages`]), counting live heap bytes
/// and their peak. Every call is passed on as it is (`realloc` and `alloc_zeroed` too, which the
/// trait's defaults would turn into a copy or a second zeroing the program does not pay).
struct Counting;
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

impl Counting {
    fn grew(p: *mut u8, size: usize) {
        if !p.is_null() {
            let live = LIVE.fetch_add(size, Relaxed) + size;
            PEAK.fetch_max(live, Relaxed);
        }
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { HugePages.alloc(layout) };
        Self::grew(p, layout.size());
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { HugePages.alloc_zeroed(layout) };
        Self::grew(p, layout.size());
        p
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let q = unsafe { HugePages.realloc(ptr, layout, new_size) };
        if !q.is_null() {
            LIVE.fetch_sub(layout.size(), Relaxed);
            Self::grew(q, new_size);
        }
        q
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { HugePages.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Relaxed);
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn bench(label: &str, mesh: &Mesh) {
    let tris = mesh.triangles.len() as f64;
    let mrate = |s: f64| tris / s / 1e6;

    let (t_weld, welded) = best(3, || weld(&mesh.positions, 0.0));
    let table_input: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| welded.map[i as usize]))
        .collect();
    let (t_table, _) = best(3, || {
        CornerTable::build(&table_input, welded.positions.len())
    });
    drop(table_input);

    // The topology alone (weld, table, walks, shells, nesting), then the scan's default analysis,
    // which adds the search for faces that meet (its own figures: `cargo bench --bench intersect`).
    let topology = Options {
        intersections: None,
        ..Options::default()
    };
    let options = Options::default();
    let heap = |options: &Options| {
        let base = LIVE.load(Relaxed);
        PEAK.store(base, Relaxed);
        let (t, analysis) = best(3, || analyse(mesh, options));
        (t, analysis, PEAK.load(Relaxed) - base)
    };
    let (t_topo, analysis, extra_topo) = heap(&topology);
    let (t_all, _, extra) = heap(&options);

    assert_eq!(analysis.genus(), Some(1), "a torus has genus 1");
    assert_eq!(analysis.border_edges, 0);
    println!(
        "{label}: {} triangles, {} vertices",
        mesh.triangles.len(),
        mesh.positions.len()
    );
    println!(
        "  weld          {:7.1} ms  {:6.1} M triangles/s",
        t_weld * 1e3,
        mrate(t_weld)
    );
    println!(
        "  O table       {:7.1} ms  {:6.1} M triangles/s",
        t_table * 1e3,
        mrate(t_table)
    );
    println!(
        "  topology      {:7.1} ms  {:6.1} M triangles/s  (weld + table + walks + shells; \
         peak heap beyond the input {:.1} bytes/triangle)",
        t_topo * 1e3,
        mrate(t_topo),
        extra_topo as f64 / tris
    );
    println!(
        "  full analysis {:7.1} ms  {:6.1} M triangles/s  (with faces that meet; \
         peak heap beyond the input {:.1} bytes/triangle)",
        t_all * 1e3,
        mrate(t_all),
        extra as f64 / tris
    );

    // Stages: the build (weld, faces sorted and left out, table) and what the walks add.
    let soup = shapes::soup(mesh);
    let (t_soup, _) = best(3, || weld(&soup.positions, 0.0));
    drop(soup);
    let (t_build, _) = best(3, || build(mesh, &topology));
    println!(
        "  stages: weld as a soup {:.1} ms ({} positions); build (weld + faces + table) {:.1} ms; \
         walks and shells (topology - build) {:.1} ms",
        t_soup * 1e3,
        3 * mesh.triangles.len(),
        t_build * 1e3,
        (t_topo - t_build) * 1e3
    );
}

/// The analysis of one big mesh on a pool of one thread and on a pool of two: the weld, the sorts
/// and the pairing of the table spread over the pool (same analysis, checked). One and two threads
/// alternate, four rounds, best of each, so that a slow spell of the machine touches both. Both run
/// on pool threads, as a scan does: on the main thread, the one-thread rounds drew on glibc's main
/// arena, which keeps what they free, while a pool's threads get arenas of their own whose emptied
/// heaps go back to the kernel and come back as fresh pages (on the 5M torus, full analysis, six
/// runs with the one-thread rounds on the main thread gave 1.13-1.37x, seven on pools 1.76-2.01x).
fn bench_threads(label: &str, mesh: &Mesh, options: &Options) {
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool of one thread");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a pool of two threads");
    let (mut one, mut two, mut b1, mut b2) =
        (f64::INFINITY, f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut ratios = Vec::new();
    for _ in 0..4 {
        let (t1, a1) = best(1, || single.install(|| analyse(mesh, options)));
        let (t2, a2) = best(1, || pool.install(|| analyse(mesh, options)));
        assert_eq!(a1, a2, "two threads give the one-thread analysis");
        ratios.push(t1 / t2);
        (one, two) = (one.min(t1), two.min(t2));
        b1 = b1.min(best(1, || single.install(|| build(mesh, options))).0);
        b2 = b2.min(best(1, || pool.install(|| build(mesh, options))).0);
    }
    ratios.sort_by(f64::total_cmp);
    println!(
        "{label}: analysis 1 thread {:.1} ms, 2 threads {:.1} ms: {:.2}x (round by round \
         {:.2}-{:.2}x; build {:.1} -> {:.1} ms: {:.2}x)",
        one * 1e3,
        two * 1e3,
        one / two,
        ratios[0],
        ratios[ratios.len() - 1],
        b1 * 1e3,
        b2 * 1e3,
        b1 / b2
    );
}

/// 10,000 unit cubes ("bolts") on a 100 x 100 grid, disjoint or all inside one box: nesting must
/// prune by bounding boxes before any point-in-solid test.
fn bench_bolts() {
    let bolts: Vec<Mesh> = (0..10_000)
        .map(|i| {
            let (x, y) = ((i % 100) as f64 * 2.0, (i / 100) as f64 * 2.0);
            shapes::cuboid([x, y, 0.0], [x + 1.0, y + 1.0, 1.0])
        })
        .collect();
    let disjoint = shapes::merge(&bolts);
    let mut boxed = bolts;
    boxed.push(shapes::cuboid([-1.0, -1.0, -1.0], [201.0, 201.0, 2.0]));
    let boxed = shapes::merge(&boxed);
    let options = Options::default();
    for (label, mesh, cavities) in [
        ("disjoint", &disjoint, 0),
        ("inside one box", &boxed, 10_000),
    ] {
        let (t, a) = best(3, || analyse(mesh, &options));
        assert_eq!(a.shells.len(), mesh.triangles.len() / 12);
        assert_eq!(a.cavities(), cavities);
        println!(
            "10,000 cube shells, {label}: full analysis with nesting {:.1} ms",
            t * 1e3
        );
    }
}

fn main() {
    // What the program does at its start (src/main.rs).
    meshvet::pages::keep_freed_memory();
    let only: Option<usize> = std::env::args().skip(1).find_map(|a| a.parse().ok());
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global()
        .ok();
    bench_bolts();
    for (millions, n, m) in [(1, 1000, 500), (5, 2500, 1000)] {
        if only.is_some_and(|o| o != millions) {
            continue;
        }
        let mesh = shapes::torus(n, m, Some(0x5eed));
        bench(&format!("torus {millions}M, shuffled faces"), &mesh);
        if millions == 5 {
            let topology = Options {
                intersections: None,
                ..Options::default()
            };
            bench_threads("torus 5M, shuffled faces, topology", &mesh, &topology);
            bench_threads(
                "torus 5M, shuffled faces, with faces that meet",
                &mesh,
                &Options::default(),
            );
        }
        drop(mesh);
        let mesh = shapes::torus(n, m, None);
        bench(&format!("torus {millions}M, faces in grid order"), &mesh);
    }
}
