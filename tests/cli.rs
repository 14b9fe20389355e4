//! The `meshvet` binary on temporary trees: exit codes, the exact CSV header, sorted `/` paths,
//! determinism across thread counts, config errors, and hostile files next to good ones.

use std::path::{Path, PathBuf};
use std::process::Command;

use tempfile::TempDir;

/// SPEC 9's columns, in order, then the extra columns meshvet adds after them.
const SPEC_COLUMNS: &str = "path,mesh,format,status,message,vertices,welded_vertices,faces,\
degenerate_faces,zero_area_faces,duplicate_faces,invalid_vertices,unreferenced_vertices,edges,\
border_edges,nonmanifold_edges,nonmanifold_vertices,inconsistent_edges,components,shells,holes,\
orientable,oriented,inside_out_shells,cavities,solids,euler,genus,volume,area,bbox_min_x,\
bbox_min_y,bbox_min_z,bbox_max_x,bbox_max_y,bbox_max_z,repaired_path,repairs,millis";
const EXTRA_COLUMNS: &str = "invalid_faces,mirrored_instances,findings,status_after";

/// A closed tetrahedron wound outward: passes every rule.
const TETRA: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
/// The same tetrahedron wound inward: one inside-out shell (an error).
const INSIDE_OUT: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 4 2\nf 1 3 4\nf 2 4 3\n";
/// A single triangle: one hole (a warning).
const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

struct Tree {
    dir: TempDir,
}

impl Tree {
    fn new(files: &[(&str, &str)]) -> Tree {
        let tree = Tree {
            dir: tempfile::tempdir().unwrap(),
        };
        for (name, text) in files {
            tree.write(name, text.as_bytes());
        }
        tree
    }

    fn write(&self, name: impl AsRef<Path>, bytes: &[u8]) {
        let path = self.path().join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, bytes).unwrap();
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }
}

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

/// Runs `meshvet ARGS` in `cwd`.
fn meshvet(cwd: &Path, args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_meshvet"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap();
    Run {
        code: out
            .status
            .code()
            .expect("meshvet exits normally, not by a signal"),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// The CSV rows (without the header), each as its cells.
fn rows(csv: &str) -> Vec<Vec<String>> {
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    reader
        .records()
        .map(|r| r.unwrap().iter().map(str::to_owned).collect())
        .collect()
}

fn column(name: &str) -> usize {
    SPEC_COLUMNS
        .split(',')
        .chain(EXTRA_COLUMNS.split(','))
        .position(|c| c == name)
        .unwrap()
}

/// The CSV's header and rows with the `millis` cell blanked, for comparing runs.
fn without_millis(csv: &str) -> Vec<Vec<String>> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(csv.as_bytes());
    reader
        .records()
        .enumerate()
        .map(|(i, r)| {
            let mut cells: Vec<String> = r.unwrap().iter().map(str::to_owned).collect();
            if i > 0 {
                cells[column("millis")].clear();
            }
            cells
        })
        .collect()
}

#[test]
fn clean_tree_exits_0_with_a_summary() {
    let tree = Tree::new(&[("a.obj", TETRA)]);
    let run = meshvet(tree.path(), &["scan"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(
        run.stdout
            .starts_with("1 mesh: 1 pass, 0 warn, 0 fail, 0 error in "),
        "{}",
        run.stdout
    );
    assert_eq!(
        run.stdout.lines().count(),
        1,
        "without --csv only the summary"
    );
}

#[test]
fn warnings_exit_0_and_failures_exit_1_naming_the_worst_findings() {
    let tree = Tree::new(&[("open.obj", TRIANGLE)]);
    let run = meshvet(tree.path(), &["scan"]);
    assert_eq!(run.code, 0, "a warning is not a failure");

    tree.write("models/bad.obj", INSIDE_OUT.as_bytes());
    let run = meshvet(tree.path(), &["scan"]);
    assert_eq!(run.code, 1);
    let lines: Vec<&str> = run.stdout.lines().collect();
    assert!(
        lines[0].starts_with("2 meshes: 0 pass, 1 warn, 1 fail, 0 error in "),
        "{}",
        run.stdout
    );
    assert_eq!(
        lines[1..],
        ["models/bad.obj: error inside-out-shell: 1 inside-out shell"]
    );

    let quiet = meshvet(tree.path(), &["scan", "--quiet"]);
    assert_eq!(quiet.code, 1);
    assert_eq!(
        quiet.stdout,
        "models/bad.obj: error inside-out-shell: 1 inside-out shell\n"
    );
    assert_eq!(quiet.stderr, "");
}

#[test]
fn csv_header_is_the_spec_columns_then_the_extras() {
    let tree = Tree::new(&[("a.obj", TETRA)]);
    let run = meshvet(tree.path(), &["scan", "--csv", "-"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    let header = run.stdout.lines().next().unwrap();
    assert_eq!(header, format!("{SPEC_COLUMNS},{EXTRA_COLUMNS}"));
    // With the CSV on standard output, the summary moves to standard error.
    assert!(run.stderr.contains("1 mesh: 1 pass"), "{}", run.stderr);
}

#[test]
fn a_good_mesh_row_carries_its_numbers() {
    let tree = Tree::new(&[("a.obj", TETRA)]);
    let run = meshvet(tree.path(), &["scan", "--csv", "-"]);
    let rows = rows(&run.stdout);
    assert_eq!(rows.len(), 1);
    let cell = |name: &str| rows[0][column(name)].as_str();
    assert_eq!(
        [
            cell("path"),
            cell("mesh"),
            cell("format"),
            cell("status"),
            cell("message")
        ],
        ["a.obj", "", "obj", "pass", ""]
    );
    assert_eq!(
        [
            cell("vertices"),
            cell("welded_vertices"),
            cell("faces"),
            cell("edges")
        ],
        ["4", "4", "4", "6"]
    );
    assert_eq!(
        [
            cell("border_edges"),
            cell("holes"),
            cell("components"),
            cell("shells")
        ],
        ["0", "0", "1", "1"]
    );
    assert_eq!(
        [
            cell("orientable"),
            cell("oriented"),
            cell("euler"),
            cell("genus")
        ],
        ["true", "true", "2", "0"]
    );
    assert_eq!(
        [cell("solids"), cell("cavities"), cell("inside_out_shells")],
        ["1", "0", "0"]
    );
    let volume: f64 = cell("volume").parse().unwrap();
    assert!((volume - 1.0 / 6.0).abs() < 1e-12, "{volume}");
    assert_eq!(
        [
            cell("bbox_min_x"),
            cell("bbox_max_z"),
            cell("repaired_path"),
            cell("findings")
        ],
        ["0", "1", "", ""]
    );
}

#[test]
fn rows_are_sorted_with_relative_slash_paths() {
    let tree = Tree::new(&[
        ("b.obj", TETRA),
        ("a/z.obj", TETRA),
        ("a.obj", TETRA),
        ("a/b/c.OBJ", TETRA),
        ("readme.txt", "not a mesh"),
    ]);
    let run = meshvet(tree.path(), &["scan", "--csv", "-"]);
    let paths: Vec<String> = rows(&run.stdout)
        .into_iter()
        .map(|r| r[0].clone())
        .collect();
    assert_eq!(paths, ["a.obj", "a/b/c.OBJ", "a/z.obj", "b.obj"]);

    // Scanning the folder by an absolute path changes nothing; a named file is relative to its folder.
    let abs = meshvet(
        Path::new("/"),
        &["scan", "--csv", "-", tree.path().to_str().unwrap()],
    );
    assert_eq!(without_millis(&abs.stdout), without_millis(&run.stdout));
    let one = meshvet(tree.path(), &["scan", "--csv", "-", "a/b/c.OBJ"]);
    assert_eq!(rows(&one.stdout)[0][0], "c.OBJ");
}

#[test]
fn several_paths_keep_the_path_as_written_as_a_prefix() {
    let tree = Tree::new(&[("x/a.obj", TETRA), ("y/a.obj", TETRA), ("y/b.obj", TETRA)]);
    let run = meshvet(tree.path(), &["scan", "--csv", "-", "./y", "x", "y/b.obj"]);
    let paths: Vec<String> = rows(&run.stdout)
        .into_iter()
        .map(|r| r[0].clone())
        .collect();
    assert_eq!(paths, ["x/a.obj", "y/a.obj", "y/b.obj"]);
}

#[test]
fn one_and_two_threads_give_the_same_csv_except_millis() {
    let tree = Tree::new(&[]);
    for i in 0..60 {
        let text = [TETRA, INSIDE_OUT, TRIANGLE][i % 3];
        tree.write(format!("d{}/m{i:02}.obj", i % 7), text.as_bytes());
    }
    tree.write("d1/garbage.stl", b"\x00\x01 definitely not an STL");
    let one = meshvet(tree.path(), &["scan", "--csv", "-", "--jobs", "1"]);
    let two = meshvet(tree.path(), &["scan", "--csv", "-", "--jobs", "2"]);
    assert_eq!(one.code, 1);
    assert_eq!(rows(&one.stdout).len(), 61);
    assert_eq!(without_millis(&one.stdout), without_millis(&two.stdout));
}

#[test]
fn csv_file_is_written_whole_and_the_summary_still_printed() {
    let tree = Tree::new(&[("m/a.obj", TETRA)]);
    let run = meshvet(tree.path(), &["scan", "m", "--csv", "out/report.csv"]);
    assert!(
        run.code == 2 && run.stderr.contains("out/report.csv"),
        "missing folder: {}",
        run.stderr
    );

    std::fs::create_dir(tree.path().join("out")).unwrap();
    let run = meshvet(tree.path(), &["scan", "m", "--csv", "out/report.csv"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(run.stdout.starts_with("1 mesh: 1 pass"));
    let written = std::fs::read_to_string(tree.path().join("out/report.csv")).unwrap();
    assert_eq!(rows(&written).len(), 1);
    let names: Vec<PathBuf> = std::fs::read_dir(tree.path().join("out"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(names.len(), 1, "no temporary file left: {names:?}");
}

#[test]
fn bad_commands_exit_2() {
    let tree = Tree::new(&[("a.obj", TETRA)]);
    assert_eq!(meshvet(tree.path(), &["scan", "--jobs", "many"]).code, 2);
    assert_eq!(meshvet(tree.path(), &["scan", "--no-such-flag"]).code, 2);
    let missing = meshvet(tree.path(), &["scan", "nowhere"]);
    assert_eq!(missing.code, 2);
    assert!(missing.stderr.contains("nowhere"), "{}", missing.stderr);
    let missing_config = meshvet(tree.path(), &["scan", "--config", "none.toml"]);
    assert_eq!(missing_config.code, 2);
    assert!(
        missing_config.stderr.contains("none.toml"),
        "{}",
        missing_config.stderr
    );
}

#[test]
fn a_typo_in_a_rule_name_exits_2_with_a_suggestion() {
    let tree = Tree::new(&[
        ("a.obj", TETRA),
        (
            "meshvet.toml",
            "# rules\n[rules]\nnon-manifold-edges = \"warning\"\n",
        ),
    ]);
    let run = meshvet(tree.path(), &["scan"]);
    assert_eq!(run.code, 2);
    assert!(
        run.stderr.contains("did you mean `non-manifold-edge`"),
        "{}",
        run.stderr
    );
    assert!(
        run.stderr.contains("meshvet.toml:3:"),
        "names the file and line: {}",
        run.stderr
    );
    assert_eq!(run.stdout, "");
}

#[test]
fn an_unknown_key_exits_2_with_a_suggestion() {
    let tree = Tree::new(&[
        ("a.obj", TETRA),
        ("cfg/strict.toml", "weld_tolerence = 0.5\n"),
    ]);
    let run = meshvet(tree.path(), &["scan", "--config", "cfg/strict.toml"]);
    assert_eq!(run.code, 2);
    assert!(run.stderr.contains("cfg/strict.toml:1:"), "{}", run.stderr);
    assert!(
        run.stderr.contains("did you mean `weld_tolerance`"),
        "{}",
        run.stderr
    );
}

#[test]
fn the_nearest_config_upward_is_used() {
    let tree = Tree::new(&[
        ("meshvet.toml", "[rules]\nhole = \"error\"\n"),
        ("models/open.obj", TRIANGLE),
    ]);
    let run = meshvet(&tree.path().join("models"), &["scan"]);
    assert_eq!(
        run.code, 1,
        "hole is an error in the discovered config: {}",
        run.stdout
    );
    // --config wins over discovery.
    tree.write("lenient.toml", b"[rules]\nhole = \"off\"\n");
    let run = meshvet(
        &tree.path().join("models"),
        &["scan", "--config", "../lenient.toml"],
    );
    assert_eq!(run.code, 0);
    assert!(run.stdout.starts_with("1 mesh: 1 pass"), "{}", run.stdout);
}

#[test]
fn excludes_apply_to_named_files_too() {
    let tree = Tree::new(&[
        ("meshvet.toml", "exclude = [\"**/wip/**\"]\n"),
        ("wip/bad.obj", INSIDE_OUT),
        ("ok.obj", TETRA),
    ]);
    let run = meshvet(tree.path(), &["scan", "--csv", "-"]);
    assert_eq!(run.code, 0);
    assert_eq!(rows(&run.stdout).len(), 1);
    let run = meshvet(
        tree.path(),
        &["scan", "--csv", "-", "wip/bad.obj", "ok.obj"],
    );
    assert_eq!(run.code, 0, "the excluded file is skipped even when named");
    let paths: Vec<String> = rows(&run.stdout)
        .into_iter()
        .map(|r| r[0].clone())
        .collect();
    assert_eq!(paths, ["ok.obj"]);
}

#[test]
fn hostile_files_get_rows_and_the_good_file_is_still_reported() {
    let tree = Tree::new(&[("good.obj", TETRA), ("empty.obj", "")]);
    tree.write(
        "garbage.stl",
        &[0xde, 0xad, 0xbe, 0xef, 0x00, 0xff, 0x13, 0x37, 0x42],
    );
    tree.write("big-count.stl", &{
        // A binary STL header that declares 4 billion triangles in a 90-byte file.
        let mut b = vec![0u8; 80];
        b.extend_from_slice(&u32::MAX.to_le_bytes());
        b.extend_from_slice(&[0u8; 6]);
        b
    });
    tree.write("bad-index.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    tree.write("not-json.gltf", b"{ this is not json");
    #[cfg(unix)]
    let odd_name = {
        use std::os::unix::ffi::OsStrExt;
        let name = std::ffi::OsStr::from_bytes(b"odd-\xff.obj");
        tree.write(name, TETRA.as_bytes());
        true
    };
    #[cfg(not(unix))]
    let odd_name = false;

    let run = meshvet(tree.path(), &["scan", "--csv", "-"]);
    assert_eq!(run.code, 1, "unreadable files make the scan fail");
    let rows = rows(&run.stdout);
    let status = |path: &str| {
        let row = rows
            .iter()
            .find(|r| r[0] == path)
            .unwrap_or_else(|| panic!("no row for {path}: {rows:?}"));
        (
            row[column("status")].clone(),
            row[column("message")].clone(),
        )
    };
    for path in [
        "garbage.stl",
        "big-count.stl",
        "bad-index.obj",
        "not-json.gltf",
    ] {
        let (status, message) = status(path);
        assert_eq!(status, "error", "{path}");
        assert!(!message.is_empty(), "{path} says why");
    }
    assert_eq!(status("empty.obj").0, "empty");
    if odd_name {
        assert_eq!(
            status("odd-\u{fffd}.obj").0,
            "pass",
            "a non-UTF-8 name still gets a row"
        );
    }
    let good = rows.iter().find(|r| r[0] == "good.obj").unwrap();
    assert_eq!(good[column("status")], "pass");
    assert_eq!(good[column("faces")], "4");
    assert_eq!(good[column("shells")], "1");
    // Every error row leaves the numbers empty.
    let error_row = rows.iter().find(|r| r[0] == "garbage.stl").unwrap();
    assert_eq!(error_row[column("faces")], "");
    assert_eq!(error_row[column("orientable")], "");

    // The summary names each unreadable file.
    let run = meshvet(tree.path(), &["scan"]);
    assert!(
        run.stdout.contains("garbage.stl: error: "),
        "{}",
        run.stdout
    );
}

#[test]
fn a_named_file_with_another_extension_is_an_error_row_not_silence() {
    let tree = Tree::new(&[("notes.txt", "hello")]);
    let run = meshvet(tree.path(), &["scan", "--csv", "-", "notes.txt"]);
    assert_eq!(run.code, 1);
    let rows = rows(&run.stdout);
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0][column("status")], "error");
    assert!(rows[0][column("message")].contains("not a mesh file"));
}
