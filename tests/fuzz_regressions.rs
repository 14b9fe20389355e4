//! Inputs from the fuzz targets in `fuzz/`, fed through the same path as the targets: write the bytes
//! to a file of the format's extension, `formats::read` it, then analyse and tolerance-weld every
//! mesh. Each case asserts that nothing panics and that the read gives the expected `Ok`/`Err`.
//!
//! A crash found by `cargo fuzz` is minimised (`cargo fuzz tmin`) and added below as a byte-string
//! literal. The committed seeds in `fuzz/seeds/` are checked too: they must stay valid meshes, or the
//! fuzzer starts from inputs that never reach the geometry code.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use meshvet::formats::{read, Format, Limits, ReadContext};
use meshvet::topology::Options;

/// Reads `bytes` as `format` like a fuzz target does (same limits); returns the triangle count of
/// every mesh, or the read error.
fn fuzz_path(format: Format, bytes: &[u8]) -> Result<Vec<usize>, String> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("input.{}", format.name()));
    std::fs::write(&path, bytes).unwrap();
    let cx = ReadContext {
        root: dir.path().to_path_buf(),
        limits: Limits {
            max_file_bytes: 16 << 20,
            max_triangles: 1_000_000,
        },
    };
    let outcome = catch_unwind(AssertUnwindSafe(|| {
        let meshes = read(&path, format, &cx).map_err(|e| e.0)?;
        let mut triangles = Vec::new();
        for mesh in &meshes {
            let n = mesh.positions.len();
            assert!(
                mesh.triangles.iter().flatten().all(|&i| (i as usize) < n),
                "reader returned a triangle index out of range"
            );
            let analysis = meshvet::analyse(mesh, &Options::default());
            assert_eq!(analysis.faces, mesh.triangles.len());
            meshvet::weld::weld(&mesh.positions, 1e-3);
            triangles.push(mesh.triangles.len());
        }
        Ok(triangles)
    }));
    assert!(outcome.is_ok(), "{format} input panicked");
    outcome.unwrap()
}

#[test]
fn fuzz_seeds_are_valid_meshes() {
    let seeds = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds");
    let targets = [
        ("obj", Format::Obj),
        ("stl", Format::Stl),
        ("ply", Format::Ply),
        ("off", Format::Off),
        ("gltf", Format::Gltf),
        ("glb", Format::Glb),
    ];
    for (folder, format) in targets {
        let mut seen = 0;
        for entry in std::fs::read_dir(seeds.join(folder)).unwrap() {
            let path = entry.unwrap().path();
            let bytes = std::fs::read(&path).unwrap();
            let triangles = fuzz_path(format, &bytes)
                .unwrap_or_else(|e| panic!("seed {} does not read: {e}", path.display()));
            assert!(
                triangles.iter().sum::<usize>() > 0,
                "seed {} has no triangles",
                path.display()
            );
            seen += 1;
        }
        assert!(seen >= 1, "no seeds for the {folder} target");
    }
}

#[test]
fn empty_and_garbage_inputs_do_not_panic() {
    for format in [
        Format::Obj,
        Format::Stl,
        Format::Ply,
        Format::Off,
        Format::Gltf,
        Format::Glb,
    ] {
        let _ = fuzz_path(format, b"");
        let _ = fuzz_path(format, b"\xff\xfe\x00garbage\n\x00\x00");
    }
}

/// [`fuzz_path`] on another thread, failing if it takes more than `seconds` (a hang is a finding
/// too, and must fail the test rather than stall the suite).
fn fuzz_path_within(seconds: u64, format: Format, bytes: Vec<u8>) -> Result<Vec<usize>, String> {
    let (send, receive) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = send.send(fuzz_path(format, &bytes));
    });
    receive
        .recv_timeout(std::time::Duration::from_secs(seconds))
        .unwrap_or_else(|_| panic!("{format} input did not finish within {seconds} s"))
}

#[test]
fn audit_hang_and_expansion_inputs() {
    // A binary PLY element with no properties and 2^64 - 1 entries: each entry is 0 bytes, so the
    // size check passed and the skip loop never ended.
    let ply =
        b"ply\nformat binary_little_endian 1.0\nelement junk 18446744073709551615\nend_header\n";
    assert_eq!(fuzz_path_within(20, Format::Ply, ply.to_vec()), Ok(vec![0]));
    // An accessor with no buffer view and 900,000 elements (within these limits) in a 200-byte
    // glTF: with the default limits, 10^8 of them gave 2.4 GB of zeros.
    let gltf = br#"{"asset":{"version":"2.0"},"accessors":[{"componentType":5126,"type":"VEC3","count":900000}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]}"#;
    let e = fuzz_path_within(20, Format::Gltf, gltf.to_vec()).unwrap_err();
    assert!(e.contains("far more than this file's"), "{e}");
    // Binary STL padded after its declared facets: read, not refused.
    let mut stl = vec![0u8; 80];
    stl.extend(1u32.to_le_bytes());
    stl.extend([0u8; 12]);
    stl.extend(
        [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
            .map(f32::to_le_bytes)
            .concat(),
    );
    stl.extend([0u8; 2 + 7]);
    assert_eq!(fuzz_path_within(20, Format::Stl, stl), Ok(vec![1]));
}
