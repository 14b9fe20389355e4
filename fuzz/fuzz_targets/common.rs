//! Shared by every target: write the input to a file of the right extension in a per-process folder,
//! read it through `meshvet::formats::read`, then weld and analyse every mesh, then repair it as
//! `scan --repair-dir` does (plan, write the copy). No `catch_unwind`: a panic anywhere is a finding.

use std::path::PathBuf;
use std::sync::OnceLock;

use meshvet::formats::write::{write_copy, ScanRead};
use meshvet::formats::{read, read_retaining, Format, Limits, ReadContext};
use meshvet::topology::{analyse_keeping, Options};

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

/// The per-process folder, once made.
static DIR: OnceLock<PathBuf> = OnceLock::new();

/// Removes the per-process folder when the fuzzer ends by `exit` (its time or run limit), so runs
/// leave no folders behind in RAM; a crash keeps it, with the input that crashed.
extern "C" fn remove_folder() {
    if let Some(dir) = DIR.get() {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// The per-process folder (in RAM when /dev/shm exists), created once; it is the glTF root.
fn folder() -> &'static PathBuf {
    DIR.get_or_init(|| {
        let shm = PathBuf::from("/dev/shm");
        let base = if shm.is_dir() {
            shm
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("meshvet-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create the fuzz folder");
        // SAFETY: `atexit` only records the handler, which touches nothing but the folder.
        unsafe { libc::atexit(remove_folder) };
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
        repair(format, &path, &meshes, &cx);
    }
}

/// What `scan --repair-dir` does with the file: a read that keeps the writer's detail (the same
/// meshes), plans from the analysis's table (the same plan as from scratch), and the copy.
fn repair(format: Format, path: &std::path::Path, meshes: &[meshvet::Mesh], cx: &ReadContext) {
    let (again, retained) = read_retaining(path, format, cx).expect("read_retaining reads what read reads");
    // Compared as text: a NaN coordinate is not equal to itself.
    assert_eq!(format!("{again:?}"), format!("{meshes:?}"), "read_retaining returned other meshes");
    let options = meshvet::repair::Options::default();
    let plans: Vec<_> = meshes
        .iter()
        .map(|mesh| {
            let (_, built) = analyse_keeping(mesh, &Options::default());
            let plan = meshvet::repair::plan_with(mesh, &options, Some(built));
            let fresh = meshvet::repair::plan(mesh, &options);
            assert_eq!(format!("{plan:?}"), format!("{fresh:?}"), "the plan depends on its table's origin");
            Some(plan).filter(|p| p.changes())
        })
        .collect();
    if plans.iter().any(Option::is_some) {
        let out = folder().join("copy").join(path.file_name().expect("a file name"));
        let read = ScanRead { meshes, retained };
        // A copy that cannot be written is an error row, not a finding; a panic is.
        let _ = write_copy(path, format, &plans, &out, cx, Some(read));
    }
}
