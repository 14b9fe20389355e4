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
const EXTRA_COLUMNS: &str =
    "invalid_faces,mirrored_instances,findings,status_after,findings_after,\
self_intersections,intersecting_components";

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
    // A quick scan says its milliseconds rather than "0.0 s".
    assert!(run.stdout.trim_end().ends_with(" ms"), "{}", run.stdout);
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

    // Scanning the folder by an absolute path changes nothing; a named file is reported as written.
    let abs = meshvet(
        Path::new("/"),
        &["scan", "--csv", "-", tree.path().to_str().unwrap()],
    );
    assert_eq!(without_millis(&abs.stdout), without_millis(&run.stdout));
    let one = meshvet(tree.path(), &["scan", "--csv", "-", "a/b/c.OBJ"]);
    assert_eq!(rows(&one.stdout)[0][0], "a/b/c.OBJ");
    let dotted = meshvet(tree.path(), &["scan", "--csv", "-", "./a/b/c.OBJ"]);
    assert_eq!(rows(&dotted.stdout)[0][0], "a/b/c.OBJ");
}

/// Two files of one name in two folders, each named alone as a pre-commit hook names them: each
/// line says which one it is.
#[test]
fn a_named_file_is_printed_as_written() {
    let tree = Tree::new(&[("a/part.obj", INSIDE_OUT), ("b/part.obj", TRIANGLE)]);
    let a = meshvet(tree.path(), &["scan", "--format", "lines", "a/part.obj"]);
    assert!(
        a.stdout.starts_with("a/part.obj: error inside-out-shell"),
        "{}",
        a.stdout
    );
    let b = meshvet(tree.path(), &["scan", "--format", "lines", "b/part.obj"]);
    assert!(
        b.stdout.starts_with("b/part.obj: warning hole"),
        "{}",
        b.stdout
    );
    let summary = meshvet(tree.path(), &["scan", "a/part.obj"]);
    assert!(
        summary.stdout.contains("\na/part.obj: error"),
        "{}",
        summary.stdout
    );
}

/// The bundled barrel's buffer sits in a sibling folder (`props/barrel.gltf` ->
/// `../buffers/barrel.bin`), as in the asset repositories a pre-commit hook runs in: named from the
/// top of the tree (where the hook runs) it passes. Named from inside `props/`, the current folder
/// is the tree and the buffer is outside it: refused, and the message names the tree and the way
/// out (`--root`), which then lets it pass. A root that does not hold the file is a usage error.
#[test]
fn a_named_gltf_may_use_buffers_in_the_tree_it_is_named_from() {
    let tree = Tree::new(&[]);
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_assets");
    for f in ["props/barrel.gltf", "buffers/barrel.bin"] {
        tree.write(f, &std::fs::read(assets.join(f)).unwrap());
    }
    let hook = meshvet(
        tree.path(),
        &["scan", "--format", "lines", "props/barrel.gltf"],
    );
    assert_eq!(
        (hook.code, hook.stdout.as_str()),
        (0, ""),
        "{}",
        hook.stderr
    );

    let props = tree.path().join("props");
    let inside = meshvet(&props, &["scan", "--format", "lines", "barrel.gltf"]);
    assert_eq!(inside.code, 1);
    assert!(
        inside.stdout.contains("refused")
            && inside.stdout.contains("the current folder")
            && inside.stdout.contains("--root"),
        "{}",
        inside.stdout
    );
    let rooted = meshvet(
        &props,
        &["scan", "--format", "lines", "--root", "..", "barrel.gltf"],
    );
    assert_eq!(
        (rooted.code, rooted.stdout.as_str()),
        (0, ""),
        "{}",
        rooted.stderr
    );
    let narrow = meshvet(
        tree.path(),
        &["scan", "--root", "buffers", "props/barrel.gltf"],
    );
    assert_eq!(narrow.code, 2);
    assert!(
        narrow.stderr.contains("not inside --root buffers"),
        "{}",
        narrow.stderr
    );
}

/// A buffer reached through a symbolic link out of the tree stays refused for a named file too.
#[cfg(unix)]
#[test]
fn a_named_gltf_cannot_reach_out_through_a_link() {
    let outside = Tree::new(&[]);
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_assets");
    outside.write(
        "barrel.bin",
        &std::fs::read(assets.join("buffers/barrel.bin")).unwrap(),
    );
    let tree = Tree::new(&[]);
    tree.write(
        "props/barrel.gltf",
        &std::fs::read(assets.join("props/barrel.gltf")).unwrap(),
    );
    std::fs::create_dir_all(tree.path().join("buffers")).unwrap();
    std::os::unix::fs::symlink(
        outside.path().join("barrel.bin"),
        tree.path().join("buffers/barrel.bin"),
    )
    .unwrap();
    let run = meshvet(
        tree.path(),
        &["scan", "--format", "lines", "props/barrel.gltf"],
    );
    assert_eq!(run.code, 1);
    assert!(
        run.stdout.contains("through a symbolic link"),
        "{}",
        run.stdout
    );
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

/// A report named like a scanned file (by another path to it, too) would replace the source:
/// refused with exit 2 before anything is written, the source byte for byte as it was. Two
/// reports naming one file are refused too; a report over last run's report is not.
#[test]
fn a_report_never_replaces_a_scanned_file() {
    let tree = Tree::new(&[("m/a.obj", TETRA), ("m/b.obj", TRIANGLE)]);
    for (flag, path) in [
        ("--csv", "m/a.obj"),
        ("--json", "m/../m/b.obj"),
        ("--junit", "m/a.obj"),
        ("--html", "m/b.obj"),
    ] {
        let run = meshvet(tree.path(), &["scan", "m", flag, path, "-q"]);
        assert_eq!(run.code, 2, "{flag} {path}: {}", run.stderr);
        assert!(
            run.stderr.contains(flag) && run.stderr.contains("reads"),
            "{flag} {path}: {}",
            run.stderr
        );
    }
    let read = |name: &str| std::fs::read_to_string(tree.path().join(name)).unwrap();
    assert_eq!(read("m/a.obj"), TETRA);
    assert_eq!(read("m/b.obj"), TRIANGLE);

    let run = meshvet(
        tree.path(),
        &["scan", "m", "--csv", "r.csv", "--json", "./r.csv", "-q"],
    );
    assert_eq!(run.code, 2, "{}", run.stderr);
    std::fs::write(tree.path().join("r.csv"), "last run").unwrap();
    let run = meshvet(tree.path(), &["scan", "m", "--csv", "r.csv", "-q"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert_eq!(rows(&read("r.csv")).len(), 2);
}

/// A link named on the command line reads the file it points to, whatever either is called:
/// a report over that file is refused too (before, only a source of the report's own file name
/// was compared, and `--csv ../assets/real_mesh.obj` replaced the mesh behind `link.obj`).
#[cfg(unix)]
#[test]
fn a_report_never_replaces_the_file_behind_a_named_link() {
    let tree = Tree::new(&[("assets/real_mesh.obj", TETRA), ("work/keep.txt", "")]);
    std::os::unix::fs::symlink("../assets/real_mesh.obj", tree.path().join("work/link.obj"))
        .unwrap();
    let run = meshvet(
        &tree.path().join("work"),
        &["scan", "link.obj", "--csv", "../assets/real_mesh.obj", "-q"],
    );
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr.contains("is a file this scan reads (link.obj)"),
        "{}",
        run.stderr
    );
    let mesh = std::fs::read_to_string(tree.path().join("assets/real_mesh.obj")).unwrap();
    assert_eq!(mesh, TETRA);
}

/// A report named by a link writes the file the link leads to and keeps the link: the rename
/// went over the link's own name, so a regular file took its place (run as root with standard
/// output sent to a file, `--csv /dev/stdout` replaced the system's `/dev/stdout`). A name for
/// standard output itself writes into it, the summary going to standard error as with `-`; a
/// link that leads nowhere is refused.
#[cfg(target_os = "linux")]
#[test]
fn a_report_named_by_a_link_writes_through_it() {
    use std::os::unix::fs::symlink;
    let tree = Tree::new(&[("m/a.obj", TETRA), ("s.csv", "")]);
    let dir = tree.path();
    let is_link = |name: &str| {
        std::fs::symlink_metadata(dir.join(name))
            .unwrap()
            .is_symlink()
    };
    symlink("real.csv", dir.join("link.csv")).unwrap();
    let run = meshvet(dir, &["scan", "m", "--csv", "link.csv", "-q"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(is_link("link.csv"));
    let real = std::fs::read_to_string(dir.join("real.csv")).unwrap();
    assert_eq!(rows(&real).len(), 1, "{real}");

    symlink("/proc/self/fd/1", dir.join("stdout-link")).unwrap();
    let bin = env!("CARGO_BIN_EXE_meshvet");
    for (k, args) in [
        ["scan", "m", "--csv", "stdout-link"].as_slice(),
        &["scan", "m", "--csv", "/dev/stdout"],
        &["merge", "real.csv", "--csv", "stdout-link"],
    ]
    .into_iter()
    .enumerate()
    {
        let sent = dir.join(format!("sent{k}.csv"));
        let out = Command::new(bin)
            .args(args)
            .current_dir(dir)
            .stdout(std::fs::File::create(&sent).unwrap())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {stderr}");
        assert!(is_link("stdout-link"), "{args:?}");
        let text = std::fs::read_to_string(&sent).unwrap();
        assert_eq!(rows(&text).len(), 1, "{args:?}: {text}");
        if args[0] == "scan" {
            assert!(stderr.contains("1 mesh: 1 pass"), "{args:?}: {stderr}");
        }
    }

    symlink("gone/r.csv", dir.join("dangling.csv")).unwrap();
    let run = meshvet(dir, &["scan", "m", "--csv", "dangling.csv", "-q"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(run.stderr.contains("link"), "{}", run.stderr);
    assert!(is_link("dangling.csv"));
}

/// Nor a file a model reads beside it (its material library, a texture) or the config in use:
/// inside a scanned tree a report may replace only an earlier meshvet report (not another tool's
/// table that has a `path` column) or an empty file, and nowhere the config. Each refusal exits 2
/// before anything is written.
#[test]
fn a_report_never_replaces_a_file_a_model_or_the_scan_reads() {
    let tree = Tree::new(&[
        ("m/a.obj", &format!("mtllib a.mtl\nusemtl red\n{TETRA}")),
        ("m/a.mtl", "newmtl red\nKd 1 0 0\nmap_Kd red.png\n"),
        ("m/red.png", "not really a picture"),
        ("m/empty.csv", ""),
        ("m/sizes.csv", "path,bytes\na.obj,120\n"),
        ("m/sizes.jsonl", "{\"path\":\"a.obj\",\"bytes\":120}\n"),
        ("meshvet.toml", "[rules]\nhole = \"off\"\n"),
        ("other.toml", "[rules]\nhole = \"off\"\n"),
    ]);
    let read = |name: &str| std::fs::read_to_string(tree.path().join(name)).unwrap();
    for args in [
        &["--csv", "m/a.mtl"][..],
        &["--json", "m/red.png"],
        &["--junit", "meshvet.toml"],
        &["--html", "other.toml", "--config", "other.toml"],
        // Another tool's tables with a `path` column are no meshvet reports.
        &["--csv", "m/sizes.csv"],
        &["--json", "m/sizes.jsonl"],
    ] {
        let run = meshvet(tree.path(), &[&["scan", "m", "-q"], args].concat());
        assert_eq!(run.code, 2, "{args:?}: {}", run.stderr);
        assert!(
            run.stderr.contains(args[0]) && run.stderr.contains("would replace it"),
            "{args:?}: {}",
            run.stderr
        );
    }
    assert!(read("m/a.mtl").starts_with("newmtl red"));
    assert_eq!(read("m/red.png"), "not really a picture");
    assert_eq!(read("meshvet.toml"), read("other.toml"));
    assert_eq!(read("m/sizes.csv"), "path,bytes\na.obj,120\n");

    // Reports of an earlier run, and an empty file, may be replaced, as each kind of report.
    let reports = [
        "--csv",
        "m/r.csv",
        "--json",
        "m/r.jsonl",
        "--junit",
        "m/r.xml",
        "--html",
        "m/r.html",
    ];
    for round in 0..2 {
        let run = meshvet(tree.path(), &[&["scan", "m", "-q"], &reports[..]].concat());
        assert_eq!(run.code, 0, "round {round}: {}", run.stderr);
    }
    let run = meshvet(tree.path(), &["scan", "m", "-q", "--csv", "m/empty.csv"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert_eq!(rows(&read("m/empty.csv")).len(), 1);
}

/// A report path that cannot be written (a missing folder, a folder itself) is refused before
/// the scan, and no report of the run replaces its target: the reports are put in place together
/// once all of them are written. `/dev/full` takes the bytes in place and fails them as a full
/// disk would: the CSV beside it stays the earlier one.
#[test]
fn reports_are_put_in_place_together_or_not_at_all() {
    let tree = Tree::new(&[("m/a.obj", TETRA), ("r.csv", "path,earlier\n")]);
    std::fs::create_dir(tree.path().join("folder")).unwrap();
    let read = |name: &str| std::fs::read_to_string(tree.path().join(name)).unwrap();
    let mut cases = vec![
        (["--html", "missing/r.html"], "missing/r.html"),
        (["--json", "folder"], "a folder"),
    ];
    if Path::new("/dev/full").exists() {
        cases.push((["--json", "/dev/full"], "/dev/full"));
    }
    for (args, said) in cases {
        let run = meshvet(
            tree.path(),
            &[&["scan", "m", "-q", "--csv", "r.csv"], &args[..]].concat(),
        );
        assert_eq!(run.code, 2, "{args:?}: {}", run.stderr);
        assert!(run.stderr.contains(said), "{args:?}: {}", run.stderr);
        assert_eq!(read("r.csv"), "path,earlier\n", "{args:?}");
    }
    assert!(tree.path().join("folder").is_dir());
    let left: Vec<_> = std::fs::read_dir(tree.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 3, "no temporary file left: {left:?}");
}

/// A file name holding an escape sequence, a line feed or a right-to-left override reaches the
/// terminal escaped: no raw control character recolours it, no override reverses the rest of the
/// line, and each finding stays one line for a hook to read.
#[cfg(unix)]
#[test]
fn control_characters_in_names_are_escaped_on_the_terminal() {
    let tree = Tree::new(&[
        ("m/red\u{1b}[31m.obj", INSIDE_OUT),
        ("m/two\nlines.obj", INSIDE_OUT),
        ("m/evil\u{202e}jbo.obj", INSIDE_OUT),
    ]);
    for format in [&[][..], &["--format", "lines"]] {
        let run = meshvet(tree.path(), &[&["scan", "m"], format].concat());
        assert_eq!(run.code, 1, "{}", run.stderr);
        assert!(!run.stdout.contains('\u{1b}'), "{:?}", run.stdout);
        assert!(
            run.stdout.contains("red\\x1b[31m.obj: error"),
            "{:?}",
            run.stdout
        );
        assert!(
            run.stdout.contains("two\\x0alines.obj: error"),
            "{:?}",
            run.stdout
        );
        // A right-to-left override would show the rest of the line reversed.
        assert!(!run.stdout.contains('\u{202e}'), "{:?}", run.stdout);
        assert!(
            run.stdout.contains("evil\\u{202e}jbo.obj: error"),
            "{:?}",
            run.stdout
        );
    }
    // And in a refusal, which names the file.
    let run = meshvet(tree.path(), &["scan", "m", "--csv", "m/red\u{1b}[31m.obj"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(!run.stderr.contains('\u{1b}'), "{:?}", run.stderr);
    assert!(run.stderr.contains("red\\x1b[31m.obj"), "{:?}", run.stderr);
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

/// A glob naming a folder (`vendor`) keeps out a file named below it, as the walk of `.` does
/// (before, only the file's name and whole path were matched, and the hook reported
/// `vendor/deep/bad.obj`).
#[test]
fn an_excluded_folder_keeps_out_files_named_below_it() {
    let tree = Tree::new(&[
        ("meshvet.toml", "exclude = [\"vendor\"]\n"),
        ("vendor/deep/bad.obj", INSIDE_OUT),
        ("src/ok.obj", TETRA),
    ]);
    let walked = meshvet(tree.path(), &["scan", "--csv", "-"]);
    assert_eq!(rows(&walked.stdout).len(), 1, "{}", walked.stdout);
    for named in [
        "vendor/deep/bad.obj",
        "./vendor/deep/bad.obj",
        "vendor/deep",
    ] {
        let run = meshvet(
            tree.path(),
            &["scan", "src/ok.obj", named, "--format", "lines"],
        );
        assert_eq!(run.code, 0, "{named}: {}", run.stdout);
        assert!(!run.stdout.contains("bad.obj"), "{named}: {}", run.stdout);
    }
}

/// Folders above the scanned tree are not matched: a project kept under a folder `build` is
/// scanned whole with `exclude = ["**/build"]`, its files named by absolute path too (a first
/// version of the fix above matched every folder of the path as written and left them out).
#[test]
fn folders_above_the_tree_are_not_excluded() {
    let tree = Tree::new(&[
        ("build/proj/meshvet.toml", "exclude = [\"**/build\"]\n"),
        ("build/proj/models/bad.obj", INSIDE_OUT),
    ]);
    let project = tree.path().join("build/proj");
    let absolute = project.join("models/bad.obj");
    for args in [
        vec!["scan", "--csv", "-"],
        vec!["scan", "models/bad.obj", "--csv", "-"],
        vec!["scan", absolute.to_str().unwrap(), "--csv", "-"],
        vec!["scan", "models", "--csv", "-"],
    ] {
        let run = meshvet(&project, &args);
        assert_eq!(rows(&run.stdout).len(), 1, "{args:?}: {}", run.stdout);
    }
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
            status("odd-\\xFF.obj").0,
            "pass",
            "a non-UTF-8 name still gets a row, the byte shown as \\xFF"
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

/// A file whose search would take long stops at the config's budget and says so in its row;
/// the file beside it is not cut short. 400 separate long triangles in parallel planes (none
/// meet) whose boxes all overlap make 79,800 pairs to look at; `pair_budget = 1` allows a small
/// mesh 65,536.
#[test]
fn a_search_past_its_budget_says_its_counts_are_lower_bounds() {
    let mut slivers = String::new();
    for i in 0..400 {
        let (d, y) = (f64::from(i) / 1024.0, f64::from(i) / 1_048_576.0);
        slivers += &format!(
            "v 0 {y} {d}\nv 1 {y} {}\nv 0.5 {} {}\nf -3 -2 -1\n",
            1.0 + d,
            y + 1.0 / 64.0,
            0.5 + d
        );
    }
    let tree = Tree::new(&[
        ("slivers.obj", &slivers),
        ("good.obj", TETRA),
        ("budget.toml", "[intersections]\npair_budget = 1\n"),
    ]);
    let note = "raise `[intersections] pair_budget`";
    let message = |rows: &[Vec<String>], path: &str| {
        let row = rows.iter().find(|r| r[0] == path).unwrap();
        row[column("message")].clone()
    };
    let run = meshvet(
        tree.path(),
        &["scan", "--csv", "-", "--config", "budget.toml"],
    );
    let cut = rows(&run.stdout);
    assert!(message(&cut, "slivers.obj").contains(note), "{cut:?}");
    assert!(!message(&cut, "good.obj").contains(note));
    let run = meshvet(tree.path(), &["scan", "--csv", "-"]);
    let full = rows(&run.stdout);
    assert!(!message(&full, "slivers.obj").contains(note), "{full:?}");
    assert_eq!(message(&full, "slivers.obj"), "400 holes");
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

/// One scan holding a good file in every format next to more hostile ones: each hostile file gets
/// its own row saying why, the good ones keep their hand-counted numbers (a tetrahedron: 4 faces, 6
/// edges, 1 shell), and a glTF buffer outside the scanned tree is never read.
#[test]
fn every_format_reads_and_hostile_files_each_get_a_row() {
    const TRI_TETRA: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    const FACES: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
    let outside = tempfile::tempdir().unwrap();
    let tree = Tree::new(&[("ok/tetra.obj", TETRA)]);
    // OFF, PLY (ASCII and binary), STL (ASCII and binary), glTF (data URI and .bin) and GLB of the
    // same tetrahedron.
    let mut off = String::from("OFF\n4 4 0\n");
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         element face 4\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for p in TRI_TETRA {
        off += &format!("{} {} {}\n", p[0], p[1], p[2]);
        ply += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    let mut ascii = String::from("solid t\n");
    let mut binary = vec![0u8; 80];
    binary.extend(4u32.to_le_bytes());
    for f in FACES {
        off += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
        ply += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
        ascii += "facet normal 0 0 0\nouter loop\n";
        binary.extend([0u8; 12]);
        for i in f {
            let p = TRI_TETRA[i as usize];
            ascii += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
            binary.extend(p.iter().flat_map(|x| x.to_le_bytes()));
        }
        ascii += "endloop\nendfacet\n";
        binary.extend([0u8; 2]);
    }
    ascii += "endsolid t\n";
    tree.write("ok/tetra.off", off.as_bytes());
    tree.write("ok/tetra.ply", ply.as_bytes());
    tree.write("ok/tetra_ascii.stl", ascii.as_bytes());
    tree.write("ok/tetra_binary.stl", &binary);
    let mut bin: Vec<u8> = TRI_TETRA
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    bin.extend(
        FACES
            .iter()
            .flatten()
            .flat_map(|i| (*i as u16).to_le_bytes()),
    );
    let gltf = |uri: &str, extra: &str| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},{extra}"meshes":[{{"name":"tetra","primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
"buffers":[{{"uri":"{uri}","byteLength":72}}],
"bufferViews":[{{"buffer":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":24}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3"}},{{"bufferView":1,"componentType":5123,"count":12,"type":"SCALAR"}}]}}"#
        )
    };
    use base64::Engine as _;
    let data_uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    tree.write("ok/tetra.gltf", gltf(&data_uri, "").as_bytes());
    // The same buffer as a .bin beside the .gltf, and as a GLB's BIN chunk (no uri).
    tree.write("ok/tetra_bin.bin", &bin);
    tree.write("ok/tetra_bin.gltf", gltf("tetra_bin.bin", "").as_bytes());
    let mut json = gltf("", "").replace(r#""uri":"","#, "").into_bytes();
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut chunk = bin.clone();
    chunk.resize(chunk.len().next_multiple_of(4), 0);
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(((12 + 8 + json.len() + 8 + chunk.len()) as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    glb.extend((chunk.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&chunk);
    tree.write("ok/tetra.glb", &glb);
    // Binary little-endian PLY: float positions, uchar-counted int index lists.
    let mut ply_le = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n\
property float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
        .to_vec();
    ply_le.extend(TRI_TETRA.iter().flatten().flat_map(|x| x.to_le_bytes()));
    for f in FACES {
        ply_le.push(3);
        ply_le.extend(f.iter().flat_map(|&i| (i as i32).to_le_bytes()));
    }
    tree.write("ok/tetra_le.ply", &ply_le);
    // Hostile ones.
    let mut truncated = binary.clone();
    truncated.truncate(84 + 50 + 20);
    tree.write("bad/truncated.stl", &truncated);
    tree.write(
        "bad/png.stl",
        b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR\0\0\0\x01\0\0\0\x01\x08\x02\0\0\0",
    );
    std::fs::write(outside.path().join("secret.bin"), &bin).unwrap();
    let climb = format!("{}/secret.bin", relative_up(tree.path(), outside.path()));
    tree.write("bad/climbs_out.gltf", gltf(&climb, "").as_bytes());
    let draco = r#""extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"],"#;
    tree.write("bad/draco.gltf", gltf(&data_uri, draco).as_bytes());
    tree.write("bad/nan.obj", format!("v nan 0 0\n{TETRA}").as_bytes());

    let run = meshvet(tree.path(), &["scan", "--csv", "-"]);
    assert_eq!(run.code, 1);
    let rows = rows(&run.stdout);
    let row = |path: &str| {
        rows.iter()
            .find(|r| r[0] == path)
            .unwrap_or_else(|| panic!("no row for {path}: {rows:?}"))
            .clone()
    };
    for path in [
        "ok/tetra.obj",
        "ok/tetra.off",
        "ok/tetra.ply",
        "ok/tetra_ascii.stl",
        "ok/tetra_binary.stl",
        "ok/tetra.gltf",
        "ok/tetra_bin.gltf",
        "ok/tetra.glb",
        "ok/tetra_le.ply",
    ] {
        let r = row(path);
        assert_eq!(r[column("status")], "pass", "{path}: {r:?}");
        assert_eq!(
            [
                &r[column("faces")],
                &r[column("edges")],
                &r[column("shells")]
            ],
            ["4", "6", "1"],
            "{path}"
        );
    }
    let error = |path: &str, words: &str| {
        let r = row(path);
        assert_eq!(r[column("status")], "error", "{path}: {r:?}");
        assert!(
            r[column("message")].contains(words),
            "{path}: {}",
            r[column("message")]
        );
    };
    error("bad/truncated.stl", "truncated");
    error("bad/png.stl", "not an STL file");
    error("bad/climbs_out.gltf", "secret.bin");
    error("bad/draco.gltf", "KHR_draco_mesh_compression");
    // NaN coordinates are a finding, not an unreadable file.
    let nan = row("bad/nan.obj");
    assert_eq!(nan[column("status")], "fail");
    assert_eq!(nan[column("invalid_vertices")], "1");
    assert_eq!(nan[column("faces")], "4");
}

/// `../../..` from `from` up to the filesystem root, then down to `to` (both absolute).
fn relative_up(from: &Path, to: &Path) -> String {
    let ups = from.components().count() - 1;
    let mut s = "../".repeat(ups);
    s.push_str(to.strip_prefix("/").unwrap().to_str().unwrap());
    s
}

/// The bowtie fixture (two triangles touching at a vertex): the repair splits the vertex, but each
/// triangle's hole could only be filled by repeating the face, so both holes stay: the row shows
/// the findings before and after and says what was not repairable.
#[test]
fn a_partial_repair_reports_what_is_left() {
    let tree = Tree::new(&[]);
    let fixture =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_assets/rules/non-manifold-vertex.obj");
    tree.write("bowtie.obj", &std::fs::read(fixture).unwrap());
    let run = meshvet(
        tree.path(),
        &["scan", ".", "--repair-dir", "fixed", "--csv", "-"],
    );
    let rows = rows(&run.stdout);
    let row = rows.iter().find(|r| r[0] == "bowtie.obj").expect("a row");
    assert_eq!(row[column("findings")], "non-manifold-vertex:1;hole:2");
    assert_eq!(row[column("repairs")], "split-non-manifold-vertices:1");
    assert_eq!(row[column("status_after")], "warn");
    assert_eq!(row[column("findings_after")], "hole:2");
    assert!(
        row[column("message")].contains("not repairable: 2 holes left open"),
        "{row:?}"
    );
}

/// A repair folder inside the scanned tree holds last night's copies: they are not scanned as
/// sources, and a copy replaces only the copy meshvet put there, unchanged. A file of the user's
/// at a copy's place stays (the copy fails, with a note), and mesh files there that meshvet did
/// not write are said not to be scanned (before, the user's file was silently replaced and left
/// out of the report). A repair folder that holds the scanned folder would hide every source:
/// refused.
#[test]
fn the_repair_folder_is_never_scanned_and_never_holds_the_sources() {
    let tree = Tree::new(&[
        ("in/inside_out.obj", INSIDE_OUT),
        ("in/fixed/inside_out.obj", TETRA),
        ("in/fixed/stale.obj", TRIANGLE),
    ]);
    let args = ["scan", "in", "--repair-dir", "in/fixed", "--csv", "-"];
    let run = meshvet(tree.path(), &args);
    let paths: Vec<String> = rows(&run.stdout)
        .into_iter()
        .map(|r| r[0].clone())
        .collect();
    assert_eq!(paths, ["inside_out.obj"], "{}", run.stderr);
    let row = &rows(&run.stdout)[0];
    assert_eq!(row[column("repairs")], "", "{row:?}");
    assert!(
        row[column("message")].contains("is not in the repair folder's list of the copies"),
        "{row:?}"
    );
    let read = |name: &str| std::fs::read_to_string(tree.path().join(name)).unwrap();
    assert_eq!(
        read("in/fixed/inside_out.obj"),
        TETRA,
        "the user's file stays"
    );
    assert!(
        run.stderr
            .contains("not scanned: 2 mesh file(s) inside the repair folder in/fixed"),
        "{}",
        run.stderr
    );

    // Into an empty place the copy goes; the next run replaces it, and only it.
    std::fs::remove_file(tree.path().join("in/fixed/inside_out.obj")).unwrap();
    for _ in 0..2 {
        let run = meshvet(tree.path(), &args);
        let row = &rows(&run.stdout)[0];
        assert_eq!(
            row[column("repairs")],
            "flip-inside-out-shells:1(4 faces)",
            "one shell of the tetrahedron's four faces: {row:?}"
        );
        assert_eq!(row[column("status_after")], "pass", "{row:?}");
        assert!(
            run.stderr.contains("not scanned: 1 mesh file(s)"),
            "stale.obj only: {}",
            run.stderr
        );
    }
    // A copy changed by hand since is not replaced either.
    std::fs::write(tree.path().join("in/fixed/inside_out.obj"), TETRA).unwrap();
    let run = meshvet(tree.path(), &args);
    let row = &rows(&run.stdout)[0];
    assert!(
        row[column("message")].contains("has changed since"),
        "{row:?}"
    );
    assert_eq!(read("in/fixed/inside_out.obj"), TETRA);

    // A list that cannot be written (a folder in its place) is said in the row of the copy it
    // could not list; that copy is then refused by the next run, and says why.
    std::fs::remove_file(tree.path().join("in/fixed/inside_out.obj")).unwrap();
    std::fs::remove_file(tree.path().join("in/fixed/.meshvet-copies")).unwrap();
    std::fs::create_dir(tree.path().join("in/fixed/.meshvet-copies")).unwrap();
    let run = meshvet(tree.path(), &args);
    let row = &rows(&run.stdout)[0];
    assert_eq!(row[column("status_after")], "pass", "{row:?}");
    assert!(
        row[column("message")].contains("the next repair will not replace it"),
        "{row:?}"
    );

    let refused = meshvet(tree.path(), &["scan", "in", "--repair-dir", "."]);
    assert_eq!(refused.code, 2, "{}", refused.stderr);
    // A repair folder above the scanned folder holds it too.
    let nested = meshvet(tree.path(), &["scan", "in/fixed", "--repair-dir", "in"]);
    assert_eq!(nested.code, 2, "{}", nested.stderr);
    assert!(
        refused.stderr.contains("choose a repair folder outside it"),
        "{}",
        refused.stderr
    );
}

/// Two scans repairing one tree into one folder at the same time (shards, parallel CI jobs) do
/// not refuse each other's copies, and the next run replaces every copy (before, each scan read
/// the list of copies once, and refused copies the other had put in place since).
#[test]
fn two_scans_into_one_repair_folder_keep_each_others_copies() {
    let tree = Tree::new(&[]);
    for i in 0..40 {
        tree.write(format!("in/d{i}/inside_out.obj"), INSIDE_OUT.as_bytes());
    }
    let spawn = |csv: &str| {
        Command::new(env!("CARGO_BIN_EXE_meshvet"))
            .args(["scan", "in", "--repair-dir", "fixed", "-q", "--csv", csv])
            .current_dir(tree.path())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap()
    };
    for round in 0..2 {
        let (mut a, mut b) = (spawn("a.csv"), spawn("b.csv"));
        a.wait().unwrap();
        b.wait().unwrap();
        for csv in ["a.csv", "b.csv"] {
            let text = std::fs::read_to_string(tree.path().join(csv)).unwrap();
            let failed: Vec<Vec<String>> = rows(&text)
                .into_iter()
                .filter(|r| r[column("message")].contains("repair failed"))
                .collect();
            assert!(failed.is_empty(), "round {round}, {csv}: {failed:?}");
        }
    }
}

/// With `--shard`, each shard counts only its own files in the note on the repair folder: the
/// shards' counts add up to the folder's files (each shard said the whole tree's count).
#[test]
fn each_shard_counts_its_own_files_in_the_repair_folder() {
    let tree = Tree::new(&[("in/a.obj", TETRA)]);
    for i in 0..12 {
        tree.write(format!("in/fixed/theirs{i}.obj"), TETRA.as_bytes());
    }
    let mut total = 0;
    for shard in ["1/2", "2/2"] {
        let run = meshvet(
            tree.path(),
            &["scan", "in", "--repair-dir", "in/fixed", "--shard", shard],
        );
        total += run
            .stderr
            .split("not scanned: ")
            .nth(1)
            .and_then(|rest| rest.split(' ').next())
            .map_or(0, |n| n.parse::<usize>().unwrap());
    }
    assert_eq!(total, 12);
}

/// A repair folder named by an existing file is refused with what to do, before anything is
/// scanned or written (before: "cannot create the repair folder ref.csv: File exists").
#[test]
fn a_file_named_as_the_repair_folder_is_refused_with_advice() {
    let tree = Tree::new(&[("in/inside_out.obj", INSIDE_OUT), ("ref.csv", "mine")]);
    let run = meshvet(tree.path(), &["scan", "in", "--repair-dir", "ref.csv"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr
            .contains("ref.csv is a file, not a folder - name a folder"),
        "{}",
        run.stderr
    );
    assert_eq!(
        std::fs::read_to_string(tree.path().join("ref.csv")).unwrap(),
        "mine"
    );
}

/// The README's scan: every sample asset outside `rules/` (whose fixtures `tests/rules.rs` checks)
/// gives what it was made to show. Clean ones in every format pass; the others carry the defect
/// they were built with: an open shield under a mirrored node, a bracket placed twice by an
/// assembly, once mirrored, a hollow block whose void faces out, a print plate's box without its
/// top (one hole), two boxes sharing an edge, an open vase (top and bottom) and an open wall patch.
#[test]
fn the_sample_assets_show_what_they_were_made_to_show() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let run = meshvet(root, &["scan", "sample_assets", "--csv", "-"]);
    assert_eq!(
        run.code, 1,
        "the samples hold failing meshes: {}",
        run.stderr
    );
    let got: Vec<[String; 4]> = rows(&run.stdout)
        .into_iter()
        .filter(|r| !r[0].starts_with("rules/"))
        .map(|r| {
            [
                r[0].clone(),
                r[1].clone(),
                r[column("status")].clone(),
                r[column("findings")].clone(),
            ]
        })
        .collect();
    let expected = [
        ["characters/knight_props.glb", "ring", "pass", ""],
        [
            "characters/knight_props.glb",
            "shield",
            "warn",
            "hole:1;mirrored-instance:1",
        ],
        [
            "print/bracket_pair.3mf",
            "bracket",
            "warn",
            "mirrored-instance:1",
        ],
        ["print/hex_bolt_head.off", "", "pass", ""],
        ["print/hollow_block.obj", "", "fail", "inside-out-shell:1"],
        ["print/plate.3mf", "cube", "pass", ""],
        ["print/plate.3mf", "open_box", "warn", "hole:1"],
        ["print/plate.3mf", "wedge", "pass", ""],
        ["print/ring_bracket.stl", "", "pass", ""],
        [
            "print/twin_boxes.stl",
            "",
            "fail",
            "non-manifold-edge:1;non-manifold-vertex:2",
        ],
        ["props/barrel.gltf", "barrel", "pass", ""],
        ["props/crate.obj", "", "pass", ""],
        ["scans/pebble.ply", "", "pass", ""],
        ["scans/vase.off", "", "warn", "hole:2"],
        ["scans/wall_patch.ply", "", "warn", "hole:1"],
    ];
    assert_eq!(got, expected.map(|r| r.map(str::to_owned)));
}

/// `-` is standard output for every report flag, `--html` included (no file named `-`); two
/// reports there at once, or a report there beside `--format lines`, would mix: refused (exit 2).
#[test]
fn a_dash_is_standard_output_for_every_report_and_only_one_may_use_it() {
    let tree = Tree::new(&[("a.obj", TETRA)]);
    let page = meshvet(tree.path(), &["scan", "--html", "-"]);
    assert_eq!(page.code, 0, "{}", page.stderr);
    assert!(
        page.stdout.starts_with("<!DOCTYPE html>"),
        "{}",
        &page.stdout[..80]
    );
    assert!(page.stdout.trim_end().ends_with("</html>"));
    assert!(
        page.stderr.contains("1 mesh: 1 pass"),
        "the summary moves to stderr"
    );
    assert!(!tree.path().join("-").exists());

    let two = meshvet(tree.path(), &["scan", "--csv", "-", "--html", "-"]);
    assert_eq!(two.code, 2);
    assert!(
        two.stderr
            .contains("--csv and --html write to standard output"),
        "{}",
        two.stderr
    );
    assert_eq!(two.stdout, "");
    let lines = meshvet(tree.path(), &["scan", "--format", "lines", "--json", "-"]);
    assert_eq!(lines.code, 2);
    assert!(
        lines
            .stderr
            .contains("--format lines prints its lines on standard output"),
        "{}",
        lines.stderr
    );
    let to_file = meshvet(
        tree.path(),
        &["scan", "--format", "lines", "--json", "r.jsonl"],
    );
    assert_eq!(to_file.code, 0, "{}", to_file.stderr);
}

/// `--jobs 100000` on three files is capped (it ran for minutes at a load of ~700 before) and
/// gives the rows one thread gives.
#[test]
fn a_huge_jobs_count_is_capped_and_changes_no_row() {
    let tree = Tree::new(&[("a.obj", TETRA), ("b.obj", INSIDE_OUT), ("c.obj", TRIANGLE)]);
    let one = meshvet(tree.path(), &["scan", "--csv", "-", "--jobs", "1"]);
    let many = meshvet(tree.path(), &["scan", "--csv", "-", "--jobs", "100000"]);
    assert_eq!(many.code, 1);
    assert_eq!(without_millis(&many.stdout), without_millis(&one.stdout));
    let help = meshvet(tree.path(), &["scan", "--help"]);
    assert!(
        help.stdout.contains("Capped at 4 per core"),
        "{}",
        help.stdout
    );
}

/// A misspelt flag gets the flag it was meant to be, though `scan` takes paths too.
#[test]
fn a_misspelt_flag_gets_a_suggestion() {
    let tree = Tree::new(&[("a.obj", TETRA)]);
    let run = meshvet(tree.path(), &["scan", "--cvs", "out.csv"]);
    assert_eq!(run.code, 2);
    assert!(
        run.stderr
            .contains("tip: a similar argument exists: '--csv'"),
        "{}",
        run.stderr
    );
    assert!(
        !run.stderr.contains("to pass '--cvs' as a value"),
        "{}",
        run.stderr
    );
}

/// A misspelt value in a config names its key, what it takes and the closest value; a missing
/// config points to `meshvet config --default`, which prints the documented defaults.
#[test]
fn config_mistakes_say_how_to_fix_them() {
    let tree = Tree::new(&[
        ("a.obj", TETRA),
        ("meshvet.toml", "[rules]\nhole = \"erorr\"\n"),
    ]);
    let typo = meshvet(tree.path(), &["scan"]);
    assert_eq!(typo.code, 2);
    assert!(typo.stderr.contains("meshvet.toml:2:8"), "{}", typo.stderr);
    assert!(
        typo.stderr.contains("did you mean `error`?"),
        "{}",
        typo.stderr
    );
    let missing = meshvet(tree.path(), &["scan", "--config", "nope.toml"]);
    assert_eq!(missing.code, 2);
    assert!(
        missing.stderr.contains("`meshvet config --default`"),
        "{}",
        missing.stderr
    );
    let defaults = meshvet(tree.path(), &["config", "--default"]);
    assert_eq!(defaults.code, 0);
    let documented =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/default.toml"))
            .unwrap();
    assert_eq!(defaults.stdout, documented);
    let which = meshvet(tree.path(), &["config"]);
    assert!(
        which.stdout.trim_end().ends_with("meshvet.toml"),
        "{}",
        which.stdout
    );
}

/// The two overlapping cubes of the rule fixture: 0 pairs within a part, 1 pair of parts, and the
/// message says the volume counts their overlap twice; with `[intersections] check = false` both
/// cells are empty and the rule is silent.
#[test]
fn faces_that_meet_have_columns_and_can_be_switched_off() {
    let fixture = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("sample_assets/rules/intersecting-components.obj"),
    )
    .unwrap();
    let tree = Tree::new(&[]);
    tree.write("boxes.obj", &fixture);
    let header: Vec<&str> = SPEC_COLUMNS
        .split(',')
        .chain(EXTRA_COLUMNS.split(','))
        .collect();
    let cell = |csv: &str, name: &str| {
        let i = header.iter().position(|c| *c == name).unwrap();
        rows(csv)[0][i].clone()
    };
    let on = meshvet(tree.path(), &["scan", "--csv", "-"]);
    assert_eq!(cell(&on.stdout, "self_intersections"), "0");
    assert_eq!(cell(&on.stdout, "intersecting_components"), "1");
    assert_eq!(cell(&on.stdout, "findings"), "intersecting-components:1");
    assert!(
        cell(&on.stdout, "message").contains("volume counts the space where shells overlap twice"),
        "{}",
        on.stdout
    );
    tree.write("meshvet.toml", b"[intersections]\ncheck = false\n");
    let off = meshvet(tree.path(), &["scan", "--csv", "-"]);
    assert_eq!(cell(&off.stdout, "self_intersections"), "");
    assert_eq!(cell(&off.stdout, "intersecting_components"), "");
    assert_eq!(cell(&off.stdout, "findings"), "");
}

/// Two files whose names differ only in a byte that is not UTF-8, and a third named with U+FFFD
/// where they have that byte: three rows, the bytes shown as `\xHH`; sharded, each file lands in
/// exactly one shard and the merge equals the whole scan; repaired, each copy gets the real name
/// of its source.
#[cfg(unix)]
#[test]
fn names_that_are_not_utf8_are_three_rows_in_one_shard_each_and_copied_by_their_names() {
    use std::os::unix::ffi::OsStrExt;
    let tree = Tree::new(&[]);
    let name = |b: &[u8]| PathBuf::from(std::ffi::OsStr::from_bytes(b));
    tree.write(name(b"in/bad\xff.obj"), INSIDE_OUT.as_bytes());
    tree.write(name(b"in/bad\xfe.obj"), INSIDE_OUT.as_bytes());
    tree.write("in/bad\u{fffd}.obj", TETRA.as_bytes());
    let run = meshvet(tree.path(), &["scan", "in", "--csv", "whole.csv"]);
    let whole = std::fs::read_to_string(tree.path().join("whole.csv")).unwrap();
    let got: Vec<(String, String)> = rows(&whole)
        .into_iter()
        .map(|r| (r[0].clone(), r[column("status")].clone()))
        .collect();
    let want = [
        ("bad\\xFE.obj", "fail"),
        ("bad\\xFF.obj", "fail"),
        ("bad\u{fffd}.obj", "pass"),
    ];
    let want: Vec<(String, String)> = want
        .iter()
        .map(|(p, s)| (p.to_string(), s.to_string()))
        .collect();
    assert_eq!(got, want, "{}", run.stderr);

    for k in 1..=3 {
        let shard = format!("{k}/3");
        let csv = format!("shard{k}.csv");
        let run = meshvet(
            tree.path(),
            &["scan", "in", "--shard", &shard, "--csv", &csv],
        );
        assert!(run.code <= 1, "{}", run.stderr);
    }
    let merged = meshvet(
        tree.path(),
        &[
            "merge",
            "shard1.csv",
            "shard2.csv",
            "shard3.csv",
            "--csv",
            "merged.csv",
        ],
    );
    assert_eq!(merged.code, 0, "a path in two shards: {}", merged.stderr);
    let merged = std::fs::read_to_string(tree.path().join("merged.csv")).unwrap();
    assert_eq!(without_millis(&merged), without_millis(&whole));

    let run = meshvet(
        tree.path(),
        &["scan", "in", "--repair-dir", "fixed", "--csv", "-"],
    );
    let copies: Vec<String> = rows(&run.stdout)
        .into_iter()
        .map(|r| r[column("repaired_path")].clone())
        .collect();
    assert_eq!(copies, ["fixed/bad\\xFE.obj", "fixed/bad\\xFF.obj", ""]);
    let mut written: Vec<Vec<u8>> = std::fs::read_dir(tree.path().join("fixed"))
        .unwrap()
        .map(|e| e.unwrap().file_name().as_bytes().to_vec())
        .collect();
    written.sort();
    assert_eq!(
        written,
        [
            b".meshvet-copies".to_vec(),
            b"bad\xfe.obj".to_vec(),
            b"bad\xff.obj".to_vec()
        ],
        "the two copies, and the list of the copies meshvet wrote"
    );
}

/// The same file given twice, as part of a folder and by another spelling (absolute, through
/// `..`): one row, under the spelling reached first.
#[test]
fn a_file_given_twice_by_two_spellings_is_one_row() {
    let tree = Tree::new(&[("models/a.obj", TETRA), ("models/b.obj", TRIANGLE)]);
    let absolute = tree.path().join("models/a.obj");
    let run = meshvet(
        tree.path(),
        &[
            "scan",
            "--csv",
            "-",
            "models",
            absolute.to_str().unwrap(),
            "models/../models/b.obj",
        ],
    );
    let paths: Vec<String> = rows(&run.stdout)
        .into_iter()
        .map(|r| r[0].clone())
        .collect();
    assert_eq!(paths, ["models/a.obj", "models/b.obj"], "{}", run.stderr);
    assert!(run.stderr.contains("2 meshes"), "{}", run.stderr);
}

/// A folder given that cannot be read is an error row named as the folder was given (not an
/// empty path), whose message says what to do. Run as another user when run as root (for root
/// every folder can be read).
#[cfg(unix)]
#[test]
fn an_unreadable_folder_given_is_a_row_named_by_it() {
    use std::os::unix::fs::PermissionsExt;
    let tree = Tree::new(&[("tree/a.obj", TETRA)]);
    let as_root = unsafe { libc::geteuid() } == 0;
    let mut command = if as_root {
        let found = Command::new("setpriv").arg("--version").output();
        if !found.is_ok_and(|o| o.status.success()) {
            eprintln!("run as root without setpriv: skipped");
            return;
        }
        let nobody = Some(65534);
        std::os::unix::fs::chown(tree.path().join("tree"), nobody, nobody).unwrap();
        let open = std::fs::Permissions::from_mode(0o755);
        std::fs::set_permissions(tree.path(), open).unwrap();
        let mut command = Command::new("setpriv");
        command.args(["--reuid=65534", "--regid=65534", "--clear-groups"]);
        command.arg(env!("CARGO_BIN_EXE_meshvet"));
        command
    } else {
        Command::new(env!("CARGO_BIN_EXE_meshvet"))
    };
    let closed = std::fs::Permissions::from_mode(0o000);
    std::fs::set_permissions(tree.path().join("tree"), closed).unwrap();
    let out = command
        .args(["scan", "./tree/", "--csv", "-"])
        .current_dir(tree.path())
        .output()
        .unwrap();
    let open = std::fs::Permissions::from_mode(0o755);
    std::fs::set_permissions(tree.path().join("tree"), open).unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    let rows = rows(&stdout);
    assert_eq!(rows.len(), 1, "{stdout}");
    assert_eq!(rows[0][0], "tree", "{stdout}");
    assert_eq!(rows[0][column("status")], "error");
    assert!(
        rows[0][column("message")].contains("check its permissions"),
        "{stdout}"
    );
}
