//! HTML report benchmark: a tree of 10,000 small OBJ meshes (cubes: whole, open, with a fin, inside
//! out) in 25 top-level folders. Prints the scan time without and with the details the page needs
//! (shell table and picture), the time to render and write the page, and its size; then a page of
//! 100,000 rows, opened in headless Chromium with `#selftest` when it is installed, for the time to
//! load, sort and filter it. Last, the pictures of a few big meshes (tori of 80,000 to 180,000
//! faces: whole, inside out, hollow; and 5,000 separate cubes): the time to find their places and
//! draw them, and the bytes each picture adds to a page.
//!
//!     cargo bench --bench html
//!     cargo bench --bench html -- pictures     # the big pictures only

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;
use std::time::{Instant, SystemTime};

use meshvet::config::Settings;
use meshvet::html::{HtmlReport, Meta};
use meshvet::report::Row;
use meshvet::report::{Outcome, Target};
use meshvet::rules::{Finding, Rule, Severity, Status};
use meshvet::scan::{self, Extras};
use meshvet::topology::analyse_keeping;
use meshvet::topology::places;
use meshvet::walk::{walk, Filter};
use meshvet::{picture, Mesh, Options};

#[path = "../tests/shapes/mod.rs"]
#[allow(dead_code)]
mod shapes;

const FILES: usize = 10_000;

/// A unit cube's OBJ text, broken according to `kind`.
fn cube(kind: usize, shift: f64) -> String {
    let mut obj = String::new();
    for i in 0..8 {
        let _ = writeln!(
            obj,
            "v {} {} {}",
            (i & 1) as f64 + shift,
            (i >> 1 & 1) as f64,
            (i >> 2 & 1) as f64
        );
    }
    let mut faces = vec![
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ];
    match kind {
        1 => {
            faces.pop(); // a hole
        }
        2 => faces.push([1, 2, 4, 3]), // the bottom twice: non-manifold edges
        3 => faces.iter_mut().for_each(|f| f.reverse()), // inside out
        _ => {}
    }
    for f in faces {
        let _ = writeln!(obj, "f {} {} {} {}", f[0], f[1], f[2], f[3]);
    }
    obj
}

fn tree(dir: &Path) {
    for i in 0..FILES {
        let folder = dir.join(format!("folder{:02}", i % 25));
        std::fs::create_dir_all(&folder).unwrap();
        let kind = [0, 0, 0, 1, 1, 2, 3][i % 7];
        std::fs::write(
            folder.join(format!("mesh{i:05}.obj")),
            cube(kind, i as f64 * 0.001),
        )
        .unwrap();
    }
}

fn meta(files: usize) -> Meta {
    Meta {
        roots: vec!["bench".into()],
        config: "built-in defaults".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        started: SystemTime::now(),
        seconds: 0.0,
        files,
    }
}

fn chromium() -> Option<std::path::PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("chromium"))
        .find(|p| p.is_file())
}

fn main() {
    if std::env::args().skip(1).any(|a| a == "pictures") {
        big_pictures();
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    tree(dir.path());
    let sources = walk(&[dir.path().to_owned()], &Filter::everything());
    let settings = Settings::default();
    let progress = |_: usize| {};

    let start = Instant::now();
    let mut rows = 0;
    scan::scan(&sources, &settings, &progress, |_| {
        rows += 1;
        Ok::<(), std::io::Error>(())
    })
    .unwrap();
    let plain = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let mut page = HtmlReport::new();
    let extras = Extras { details: true };
    scan::scan_with(&sources, &settings, extras, &progress, |o| {
        page.add(o);
        Ok::<(), std::io::Error>(())
    })
    .unwrap();
    let detailed = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let out = dir.path().join("report.html");
    page.write(&Target::File(out.clone()), &meta(sources.len()))
        .unwrap();
    let written = start.elapsed().as_secs_f64();
    let bytes = std::fs::metadata(&out).unwrap().len();
    println!(
        "{rows} meshes: scan {plain:.2} s; scan with details {detailed:.2} s (+{:.2} s); page rendered and written in {written:.3} s; {:.1} MB ({} pictures left out)",
        detailed - plain,
        bytes as f64 / 1e6,
        page.pictures_left_out()
    );
    println!(
        "time beyond the scan: {:.2} s",
        (detailed - plain).max(0.0) + written
    );

    // 100,000 rows: the page's table must stay responsive.
    let mut big = HtmlReport::new();
    let open_cube = {
        let text = cube(1, 0.0);
        let obj = dir.path().join("one.obj");
        std::fs::write(&obj, text).unwrap();
        let source = &walk(&[obj], &Filter::everything())[0];
        scan::scan_file_with(source, &settings, extras)
            .remove(0)
            .detail
    };
    let start = Instant::now();
    for i in 0..100_000usize {
        let status = [Status::Pass, Status::Warn, Status::Fail][i % 3];
        let findings = match status {
            Status::Warn => vec![finding(Rule::Hole, Severity::Warning, 1 + i % 4)],
            Status::Fail => vec![finding(Rule::NonManifoldEdge, Severity::Error, 1 + i % 9)],
            _ => Vec::new(),
        };
        big.add(Outcome {
            row: Row {
                path: format!("folder{:02}/sub{}/mesh{i:06}.obj", i % 40, i % 7),
                format: "obj".into(),
                status: Some(status),
                faces: Some(12 + i % 1000),
                vertices: Some(8 + i % 500),
                border_edges: Some(i % 5),
                millis: Some((i % 97) as f64 * 0.013),
                findings: meshvet::report::findings_cell(&findings),
                ..Row::default()
            },
            findings,
            // A picture on every 50th row, as a scan gives the failing ones.
            detail: if i % 50 == 0 { open_cube.clone() } else { None },
            ..Outcome::default()
        });
    }
    let added = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let out = dir.path().join("big.html");
    big.write(&Target::File(out.clone()), &meta(100_000))
        .unwrap();
    let written = start.elapsed().as_secs_f64();
    let bytes = std::fs::metadata(&out).unwrap().len();
    println!(
        "100,000 rows: collected in {added:.2} s, page written in {written:.2} s, {:.1} MB",
        bytes as f64 / 1e6
    );
    let Some(browser) = chromium() else {
        println!("chromium not installed: no browser timings");
        return;
    };
    let start = Instant::now();
    let dump = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
        ])
        .arg(format!(
            "--user-data-dir={}",
            dir.path().join("profile").display()
        ))
        .arg("--dump-dom")
        .arg(format!("file://{}#selftest", out.display()))
        .output()
        .unwrap();
    let dom = String::from_utf8_lossy(&dump.stdout);
    let verdict = dom
        .split("<div id=\"selftest\"")
        .nth(1)
        .and_then(|s| s.split("</div>").next())
        .unwrap_or("(no self-test result)");
    println!(
        "chromium, 100,000 rows (whole run {:.1} s): {verdict}",
        start.elapsed().as_secs_f64()
    );
    big_pictures();
}

/// The torus with its tube shrunk by `factor` toward the tube's core circle (radius 2 in z = 0).
fn shrunk_tube(mesh: &Mesh, factor: f64) -> Mesh {
    let positions = mesh
        .positions
        .iter()
        .map(|p| {
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            let core = [p[0] * shapes::TORUS_R / r, p[1] * shapes::TORUS_R / r, 0.0];
            [0, 1, 2].map(|k| core[k] + factor * (p[k] - core[k]))
        })
        .collect();
    Mesh::new(positions, mesh.triangles.clone())
}

/// Pictures of big meshes: places and drawing time (fastest and slowest of five runs) and size.
fn big_pictures() {
    let torus = shapes::torus(200, 200, Some(7));
    let hollow = shapes::merge(&[
        shapes::torus(300, 150, Some(7)),
        shapes::flipped(&shrunk_tube(&shapes::torus(300, 150, Some(8)), 0.5)),
    ]);
    let cubes: Vec<Mesh> = (0..5000)
        .map(|i| {
            let mut c = shapes::cube();
            for p in &mut c.positions {
                p[0] += 2.0 * (i % 100) as f64;
                p[1] += 2.0 * (i / 100) as f64;
            }
            c
        })
        .collect();
    let meshes = [
        ("torus", torus.clone()),
        ("inside-out torus", shapes::flipped(&torus)),
        ("hollow torus", hollow),
        ("5,000 cubes", shapes::merge(&cubes)),
    ];
    let options = Options::default();
    for (name, mesh) in &meshes {
        let (analysis, built) = analyse_keeping(mesh, &options);
        let mut times = Vec::new();
        let mut bytes = 0;
        for _ in 0..5 {
            let start = Instant::now();
            let svg = picture::draw(&places(&built, &analysis)).expect("a picture");
            times.push(start.elapsed().as_secs_f64());
            bytes = svg.len();
        }
        times.sort_by(f64::total_cmp);
        println!(
            "picture of {name} ({} faces): {:.1}-{:.1} ms, {:.1} KB",
            mesh.triangles.len(),
            1e3 * times[0],
            1e3 * times[4],
            bytes as f64 / 1e3
        );
    }
}

fn finding(rule: Rule, severity: Severity, count: usize) -> Finding {
    Finding {
        rule,
        severity,
        count,
        message: rule.describe(count),
    }
}
