//! Shared by every target: write the input to a file of the right extension in a per-process folder,
//! read it through `meshvet::formats::read`, then weld and analyse every mesh. No `catch_unwind`: a
//! panic anywhere is a finding.

use std::path::PathBuf;
use std::sync::OnceLock;

use meshvet::formats::{read, Format, Limits, ReadContext};
use meshvet::topology::Options;

/// Small enough that a hostile header count is refused long before libFuzzer's 256 MB malloc limit.
fn context(root: PathBuf) -> ReadContext {
    ReadContext {
        root,
        limits: Limits {
            max_file_bytes: 16 << 20,
            max_triangles: 1_000_000,
        },
    }
}

/// The per-process folder (in RAM when /dev/shm exists), created once; it is the glTF root.
fn folder() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let shm = PathBuf::from("/dev/shm");
        let base = if shm.is_dir() {
            shm
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("meshvet-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create the fuzz folder");
        dir
    })
}

pub fn run(format: Format, data: &[u8]) {
    let dir = folder();
    let path = dir.join(format!("input.{}", format.name()));
    std::fs::write(&path, data).expect("write the fuzz input");
    let cx = context(dir.clone());
    if let Ok(meshes) = read(&path, format, &cx) {
        for mesh in &meshes {
            let n = mesh.positions.len();
            assert!(
                mesh.triangles.iter().flatten().all(|&i| (i as usize) < n),
                "reader returned a triangle index out of range"
            );
            // Exact weld (inside analyse) and a tolerance weld (the spatial-hash path).
            meshvet::analyse(mesh, &Options::default());
            meshvet::weld::weld(&mesh.positions, 1e-3);
        }
    }
}
