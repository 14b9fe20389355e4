//! 3MF benchmark: one 1,000,000-triangle mesh (a 1000 x 500 grid torus) as a deflated 3MF package
//! and as a binary STL, read and analysed the way a scan does (walk, read, weld, Corner Table,
//! topology, rules, row), one thread. The target: the 3MF within 1.5x the STL's time.
//!
//! Prints the best of five runs of each, parse-only times, file sizes and the ratio.
//!
//!     cargo bench --bench threemf

use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::Path;

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
    let torus = shapes::torus(1000, 500, None);
    assert_eq!(torus.triangles.len(), 1_000_000);
    let threemf = dir.path().join("torus.3mf");
    let stl = dir.path().join("torus.stl");
    write_3mf(&threemf, &torus);
    write_stl(&stl, &torus);
    drop(torus);

    let mut scans = Vec::new();
    for (path, format) in [(&stl, Format::Stl), (&threemf, Format::ThreeMf)] {
        let size = fs::metadata(path).unwrap().len() as f64 / 1e6;
        let cx = ReadContext {
            root: dir.path().to_path_buf(),
            limits: Default::default(),
        };
        let (parse, meshes) = best(5, || formats::read(path, format, &cx).expect("readable"));
        assert_eq!(meshes[0].triangles.len(), 1_000_000);
        let (full, rows) = best(5, || scan_tree(path));
        assert_eq!(rows, 1);
        println!(
            "{}: {size:.1} MB; parse {:.0} ms; read + analyse (scan, 1 thread) {:.0} ms",
            path.file_name().unwrap().to_string_lossy(),
            parse * 1e3,
            full * 1e3
        );
        scans.push(full);
    }
    let ratio = scans[1] / scans[0];
    println!(
        "3mf / stl = {ratio:.2} (target <= 1.5: {})",
        if ratio <= 1.5 { "met" } else { "missed" }
    );
}

/// Walks and scans `path` with one thread: the number of rows.
fn scan_tree(path: &Path) -> usize {
    let settings = Settings {
        jobs: 1,
        ..Settings::default()
    };
    let sources = walk(&[path.to_path_buf()], &Filter::everything());
    let mut rows = 0;
    scan::scan::<std::io::Error>(&sources, &settings, &|_| {}, |_| {
        rows += 1;
        Ok(())
    })
    .expect("scan");
    rows
}

/// A 3MF package as slicers write it: coordinates as f32 text, one vertex or triangle a line,
/// deflated.
fn write_3mf(path: &Path, mesh: &Mesh) {
    let mut s = String::with_capacity(mesh.triangles.len() * 60);
    s.push_str(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<model unit=\"millimeter\" xml:lang=\"en-US\" \
         xmlns=\"http://schemas.microsoft.com/3dmanufacturing/core/2015/02\">\n <resources>\n  \
         <object id=\"1\" name=\"torus\" type=\"model\">\n   <mesh>\n    <vertices>\n",
    );
    for p in &mesh.positions {
        writeln!(
            s,
            "     <vertex x=\"{}\" y=\"{}\" z=\"{}\"/>",
            p[0] as f32, p[1] as f32, p[2] as f32
        )
        .unwrap();
    }
    s.push_str("    </vertices>\n    <triangles>\n");
    for t in &mesh.triangles {
        writeln!(
            s,
            "     <triangle v1=\"{}\" v2=\"{}\" v3=\"{}\"/>",
            t[0], t[1], t[2]
        )
        .unwrap();
    }
    s.push_str(
        "    </triangles>\n   </mesh>\n  </object>\n </resources>\n <build>\n  <item objectid=\"1\"/>\n </build>\n</model>\n",
    );
    let rels = "<?xml version=\"1.0\" encoding=\"UTF-8\"?><Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\"><Relationship Target=\"/3D/3dmodel.model\" Id=\"rel0\" Type=\"http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel\"/></Relationships>";
    let mut zip = zip::ZipWriter::new(fs::File::create(path).unwrap());
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .large_file(false);
    zip.start_file("_rels/.rels", options).unwrap();
    zip.write_all(rels.as_bytes()).unwrap();
    zip.start_file("3D/3dmodel.model", options).unwrap();
    zip.write_all(s.as_bytes()).unwrap();
    zip.finish().unwrap();
}

fn write_stl(path: &Path, mesh: &Mesh) {
    let mut b = vec![0u8; 80];
    b.extend((mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        b.extend([0u8; 12]);
        for &i in t {
            for x in mesh.positions[i as usize] {
                b.extend((x as f32).to_le_bytes());
            }
        }
        b.extend([0u8; 2]);
    }
    fs::write(path, b).unwrap();
}
