//! The workflows of issue 5 through the binary on temporary trees: the pre-commit hook as pre-commit
//! runs it, the JSON Lines and JUnit reports as CI tools read them, the cache, the baseline and
//! sharded scans joined by `merge`.

use std::path::Path;
use std::process::{Command, Stdio};

use tempfile::TempDir;

/// A closed tetrahedron wound outward: passes every rule.
const TETRA: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
/// The same tetrahedron wound inward: one inside-out shell (an error).
const INSIDE_OUT: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 4 2\nf 1 3 4\nf 2 4 3\n";
/// A single triangle: one hole (a warning).
const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
/// Two triangles sharing an edge with a third: one non-manifold edge (error), holes (warning).
const FIN: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n";

fn tree(files: &[(&str, &str)]) -> TempDir {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in files {
        write(dir.path(), name, text.as_bytes());
    }
    dir
}

fn write(root: &Path, name: &str, bytes: &[u8]) {
    let path = root.join(name);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
}

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

/// Runs `program ARGS` in `cwd` as a hook runner does: arguments only, standard input closed,
/// output captured (no terminal anywhere).
///
/// A program this test process has just copied can be busy for a moment: another test's thread
/// that forks while the copy's file is open for writing holds it open in its child until that
/// child execs (`ETXTBSY`). That is retried.
fn run(program: &str, cwd: &Path, args: &[&str]) -> Run {
    let mut tries = 0;
    let out = loop {
        let out = Command::new(program)
            .args(args)
            .current_dir(cwd)
            .stdin(Stdio::null())
            .output();
        match out {
            Err(e) if e.kind() == std::io::ErrorKind::ExecutableFileBusy && tries < 100 => {
                tries += 1;
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            out => break out.unwrap(),
        }
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    Run {
        code: out
            .status
            .code()
            .unwrap_or_else(|| panic!("{program} {args:?} ended with {}: {stderr}", out.status)),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: stderr.into_owned(),
    }
}

fn meshvet(cwd: &Path, args: &[&str]) -> Run {
    run(env!("CARGO_BIN_EXE_meshvet"), cwd, args)
}

/// Header and rows of a CSV with `millis` blanked.
fn without_millis(csv: &str) -> Vec<Vec<String>> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(csv.as_bytes());
    let mut records: Vec<Vec<String>> = reader
        .records()
        .map(|r| r.unwrap().iter().map(str::to_owned).collect())
        .collect();
    let millis = records[0].iter().position(|c| c == "millis").unwrap();
    for r in &mut records[1..] {
        r[millis].clear();
    }
    records
}

fn read(root: &Path, name: &str) -> String {
    std::fs::read_to_string(root.join(name)).unwrap()
}

/// The hook's `entry` from `.pre-commit-hooks.yaml`, split into words.
fn hook_entry() -> Vec<String> {
    let hooks = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join(".pre-commit-hooks.yaml"),
    )
    .unwrap();
    let entry = hooks
        .lines()
        .find_map(|l| l.trim().strip_prefix("entry:"))
        .expect("the hook has an entry");
    entry.split_whitespace().map(str::to_owned).collect()
}

#[test]
fn the_pre_commit_hook_prints_one_line_per_finding_worst_first() {
    let dir = tree(&[
        ("meshvet.toml", "exclude = [\"**/wip/**\"]\n"),
        ("models/ok.obj", TETRA),
        ("models/open.obj", TRIANGLE),
        ("models/fin.obj", FIN),
        ("models/flipped.OBJ", INSIDE_OUT),
        ("models/wip/broken.obj", INSIDE_OUT),
    ]);
    let entry = hook_entry();
    assert_eq!(entry[0], "meshvet");
    let mut args: Vec<&str> = entry[1..].iter().map(String::as_str).collect();
    // pre-commit appends the staged files that match `files`, relative to the repository root.
    args.extend([
        "models/ok.obj",
        "models/open.obj",
        "models/fin.obj",
        "models/flipped.OBJ",
        "models/wip/broken.obj",
    ]);
    let hook = run(env!("CARGO_BIN_EXE_meshvet"), dir.path(), &args);
    assert_eq!(hook.code, 1, "{}", hook.stderr);
    assert_eq!(
        hook.stdout,
        "\
models/fin.obj: error non-manifold-edge: an edge is shared by three or more faces (1)
models/fin.obj: error non-manifold-vertex: the faces around a vertex do not form one fan (2)
models/flipped.OBJ: error inside-out-shell: a closed shell faces the wrong way: a solid facing in or a cavity facing out (1)
models/fin.obj: warning hole: a loop of border edges: the surface is open there (1)
models/open.obj: warning hole: a loop of border edges: the surface is open there (1)
",
        "the excluded wip/broken.obj is skipped although named"
    );
    assert_eq!(hook.stderr, "");

    // Only warnings: exit 0, the warnings still listed.
    let mut ok_args: Vec<&str> = entry[1..].iter().map(String::as_str).collect();
    ok_args.extend(["models/ok.obj", "models/open.obj", "models/wip/broken.obj"]);
    let hook = run(env!("CARGO_BIN_EXE_meshvet"), dir.path(), &ok_args);
    assert_eq!(hook.code, 0);
    assert_eq!(
        hook.stdout,
        "models/open.obj: warning hole: a loop of border edges: the surface is open there (1)\n"
    );
    // Nothing wrong: no output at all.
    let mut clean: Vec<&str> = entry[1..].iter().map(String::as_str).collect();
    clean.push("models/ok.obj");
    let hook = run(env!("CARGO_BIN_EXE_meshvet"), dir.path(), &clean);
    assert_eq!(
        (hook.code, hook.stdout.as_str(), hook.stderr.as_str()),
        (0, "", "")
    );

    // An unreadable file is one error line, under its path as named.
    write(
        dir.path(),
        "models/cut.stl",
        &[0xde, 0xad, 0xbe, 0xef, 0, 1, 2],
    );
    let mut cut: Vec<&str> = entry[1..].iter().map(String::as_str).collect();
    cut.push("models/cut.stl");
    let hook = run(env!("CARGO_BIN_EXE_meshvet"), dir.path(), &cut);
    assert_eq!(hook.code, 1);
    assert!(
        hook.stdout.starts_with("models/cut.stl: error: "),
        "{}",
        hook.stdout
    );
    assert_eq!(hook.stdout.lines().count(), 1);
}

#[test]
fn the_hook_file_matches_the_mesh_extensions_in_any_case() {
    let hooks = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join(".pre-commit-hooks.yaml"),
    )
    .unwrap();
    // Every extension meshvet reads, from its own list, so a new format cannot be left out.
    let extensions: Vec<String> = meshvet::formats::Format::extension_list()
        .split(' ')
        .map(|x| x.trim_start_matches('.').to_owned())
        .collect();
    let files = format!("files: (?i)\\.({})$", extensions.join("|"));
    for key in [
        "id: meshvet",
        "language: rust",
        "require_serial: true",
        &files,
    ] {
        assert!(hooks.contains(key), "{key} in {hooks}");
    }
}

fn scan_tree() -> TempDir {
    let dir = tree(&[
        ("a/ok.obj", TETRA),
        ("a/open.obj", TRIANGLE),
        ("b/fin.obj", FIN),
        ("b/flipped.obj", INSIDE_OUT),
        ("c/empty.obj", ""),
    ]);
    write(
        dir.path(),
        "c/garbage.stl",
        &[0xde, 0xad, 0xbe, 0xef, 0, 1, 2],
    );
    dir
}

#[test]
fn json_lines_carry_every_csv_column_findings_and_shells() {
    let dir = scan_tree();
    let run = meshvet(
        dir.path(),
        &[
            "scan",
            "--csv",
            "r.csv",
            "--json",
            "r.jsonl",
            "--repair-dir",
            "fixed",
        ],
    );
    assert_eq!(run.code, 1, "{}", run.stderr);
    let csv = read(dir.path(), "r.csv");
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header: Vec<String> = reader
        .headers()
        .unwrap()
        .iter()
        .map(str::to_owned)
        .collect();
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    let json = read(dir.path(), "r.jsonl");
    let objects: Vec<serde_json::Value> = json
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    assert_eq!(objects.len(), rows.len());
    for (object, row) in objects.iter().zip(&rows) {
        let keys: Vec<&String> = object.as_object().unwrap().keys().collect();
        assert_eq!(
            keys,
            header.iter().collect::<Vec<_>>(),
            "every column, in order"
        );
        for (name, cell) in header.iter().zip(row.iter()) {
            let value = &object[name.as_str()];
            match name.as_str() {
                "findings" | "findings_after" => {
                    let rules: Vec<String> = value
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|f| format!("{}:{}", f["rule"].as_str().unwrap(), f["count"]))
                        .collect();
                    assert_eq!(rules.join(";"), cell, "the CSV cell spelt out");
                }
                "repairs" => {
                    let done: Vec<String> = value
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|r| match r["faces"].as_u64() {
                            Some(f) => format!(
                                "{}:{}({f} faces)",
                                r["repair"].as_str().unwrap(),
                                r["count"]
                            ),
                            None => format!("{}:{}", r["repair"].as_str().unwrap(), r["count"]),
                        })
                        .collect();
                    assert_eq!(done.join(";"), cell, "the CSV cell spelt out");
                }
                "shells" => {
                    let count = value.as_array().unwrap().len();
                    assert!(
                        cell.is_empty() || cell == count.to_string(),
                        "{cell} vs {value}"
                    );
                }
                "millis" => assert!(value.is_number()),
                _ if cell.is_empty() => {
                    assert!(value.is_null() || value == "", "{name}: {value}")
                }
                _ => match value {
                    serde_json::Value::String(s) => assert_eq!(s, cell, "{name}"),
                    serde_json::Value::Bool(b) => assert_eq!(b.to_string(), cell, "{name}"),
                    serde_json::Value::Number(n) => {
                        let parsed: f64 = cell.parse().unwrap();
                        assert_eq!(n.as_f64().unwrap(), parsed, "{name}")
                    }
                    other => panic!("{name}: {other}"),
                },
            }
        }
    }
    let flipped = objects
        .iter()
        .find(|o| o["path"] == "b/flipped.obj")
        .unwrap();
    assert_eq!(flipped["status"], "fail");
    assert_eq!(
        flipped["findings"][0],
        serde_json::json!({"rule": "inside-out-shell", "severity": "error", "count": 1,
            "message": "1 inside-out shell"})
    );
    let shell = &flipped["shells"][0];
    assert_eq!(
        (
            &shell["faces"],
            &shell["holes"],
            &shell["genus"],
            &shell["depth"]
        ),
        (&4.into(), &0.into(), &0.into(), &0.into())
    );
    assert_eq!(
        (&shell["role"], &shell["inside_out"]),
        (&"solid".into(), &true.into())
    );
    assert!((shell["volume"].as_f64().unwrap() + 1.0 / 6.0).abs() < 1e-12);
    // Its copy: the one shell turned (4 faces), and nothing left to find.
    assert_eq!(
        flipped["repairs"],
        serde_json::json!([{"repair": "flip-inside-out-shells", "count": 1, "faces": 4}])
    );
    assert_eq!(flipped["findings_after"], serde_json::json!([]));
    let garbage = objects
        .iter()
        .find(|o| o["path"] == "c/garbage.stl")
        .unwrap();
    assert_eq!(garbage["status"], "error");
    assert_eq!(garbage["faces"], serde_json::Value::Null);
}

/// Names holding characters XML 1.0 cannot hold (U+FFFE, U+FFFF, control characters) broke the
/// whole JUnit report, and those it can but an attribute changes (a line end, a tab) or the
/// writer dropped (an escape sequence) made cases of different files share a name. Each is now
/// written as a `\x1b`-style escape, as the terminal shows it.
#[cfg(unix)]
#[test]
fn junit_names_stay_well_formed_and_apart() {
    let names = [
        "ab",
        "a\rb",
        "a\tb",
        "a\nb",
        "\u{fffe}",
        "\u{ffff}",
        "c\x1b[31m",
    ];
    let files: Vec<(String, &str)> = names.iter().map(|n| (format!("{n}.obj"), TETRA)).collect();
    let files: Vec<(&str, &str)> = files.iter().map(|(n, t)| (n.as_str(), *t)).collect();
    let dir = tree(&files);
    let run = meshvet(dir.path(), &["scan", ".", "--junit", "j.xml", "-q"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    let xml = read(dir.path(), "j.xml");
    let doc = roxmltree::Document::parse(&xml).expect("a well-formed report");
    let mut cases: Vec<&str> = doc
        .descendants()
        .filter(|n| n.has_tag_name("testcase"))
        .map(|n| n.attribute("name").unwrap())
        .collect();
    cases.sort_unstable();
    let mut expected = [
        "ab.obj",
        "a\\x0db.obj",
        "a\\x09b.obj",
        "a\\x0ab.obj",
        "\\u{fffe}.obj",
        "\\u{ffff}.obj",
        "c\\x1b[31m.obj",
    ];
    expected.sort_unstable();
    assert_eq!(cases, expected);
}

#[test]
fn junit_has_one_suite_a_case_per_mesh_and_the_right_counts() {
    let dir = scan_tree();
    let run = meshvet(dir.path(), &["scan", "--junit", "out/junit.xml"]);
    assert_eq!(run.code, 2, "the folder does not exist: {}", run.stderr);
    assert!(run.stderr.contains("out/junit.xml"), "{}", run.stderr);
    std::fs::create_dir(dir.path().join("out")).unwrap();
    let run = meshvet(dir.path(), &["scan", "--junit", "out/junit.xml"]);
    assert_eq!(run.code, 1, "{}", run.stderr);
    let xml = read(dir.path(), "out/junit.xml");
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let suites: Vec<_> = doc
        .descendants()
        .filter(|n| n.has_tag_name("testsuite"))
        .collect();
    assert_eq!(suites.len(), 1);
    let suite = suites[0];
    let attr = |name: &str| suite.attribute(name).unwrap().parse::<usize>().unwrap();
    let cases: Vec<_> = suite
        .children()
        .filter(|n| n.has_tag_name("testcase"))
        .collect();
    assert_eq!(cases.len(), 6);
    assert_eq!(attr("tests"), 6);
    assert_eq!(attr("failures"), 2, "fin and flipped");
    assert_eq!(attr("errors"), 1, "garbage");
    assert_eq!(attr("skipped"), 1, "empty");
    let case = |name: &str| {
        *cases
            .iter()
            .find(|c| c.attribute("name") == Some(name))
            .unwrap()
    };
    let failure = case("b/fin.obj")
        .children()
        .find(|n| n.has_tag_name("failure"))
        .unwrap();
    assert_eq!(
        failure.attribute("type"),
        Some("non-manifold-edge,non-manifold-vertex"),
        "every error rule"
    );
    assert_eq!(
        failure.text().unwrap().lines().collect::<Vec<_>>(),
        [
            "non-manifold-edge: 1 non-manifold edge",
            "non-manifold-vertex: 2 non-manifold vertices"
        ],
        "a line per error-severity finding"
    );
    assert_eq!(
        case("a/ok.obj")
            .children()
            .filter(|n| n.is_element())
            .count(),
        0
    );
    assert!(case("c/garbage.stl")
        .children()
        .any(|n| n.has_tag_name("error")));
    let names: Vec<_> = std::fs::read_dir(dir.path().join("out")).unwrap().collect();
    assert_eq!(names.len(), 1, "no temporary file left");
}

/// The files in `dir` whose names start as the cache's packs do.
fn cache_packs(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut packs: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("pack-")
        })
        .collect();
    packs.sort();
    packs
}

#[test]
fn the_cache_gives_the_same_csv_and_survives_corrupt_entries() {
    let dir = scan_tree();
    write(
        dir.path(),
        "a/textured.obj",
        format!("mtllib t.mtl\n{TETRA}").as_bytes(),
    );
    let args = ["scan", "--cache", "cache", "--csv", "-", "a", "b", "c"];
    let cold = meshvet(dir.path(), &args);
    assert!(
        cold.stderr.contains("0 files reused, 7 read"),
        "{}",
        cold.stderr
    );
    let warm = meshvet(dir.path(), &args);
    // Error rows are never stored: garbage.stl is read again.
    assert!(
        warm.stderr.contains("6 files reused, 1 read"),
        "{}",
        warm.stderr
    );
    assert_eq!(without_millis(&warm.stdout), without_millis(&cold.stdout));
    assert_eq!(warm.code, cold.code);

    // Damage every record (one byte of its header line) and leave a torn record at the end of a
    // pack: each entry is recomputed, the report is unchanged. (The warm run refreshed the stamps
    // of files changed so recently, in a second pack.)
    let marker = [0xF5, b'm', b'v', b'3'];
    let mut records = 0;
    let mut size = 0;
    for pack in cache_packs(&dir.path().join("cache")) {
        let mut bytes = std::fs::read(&pack).unwrap();
        let starts: Vec<usize> = (0..bytes.len() - 4)
            .filter(|&i| bytes[i..i + 4] == marker)
            .collect();
        for &at in &starts {
            assert_eq!(&bytes[at + 20..at + 33], b"meshvet-cache");
            bytes[at + 25] ^= 1;
        }
        records += starts.len();
        bytes.extend_from_slice(&marker);
        bytes.extend_from_slice(&[7; 30]);
        size += bytes.len();
        std::fs::write(&pack, &bytes).unwrap();
    }
    assert_eq!(records, 12);
    let damaged = meshvet(dir.path(), &args);
    assert!(
        damaged.stderr.contains("0 files reused, 7 read"),
        "{}",
        damaged.stderr
    );
    assert_eq!(
        without_millis(&damaged.stdout),
        without_millis(&cold.stdout)
    );
    // That run had the folder to itself and found damage: one clean pack is left.
    let packs = cache_packs(&dir.path().join("cache"));
    assert_eq!(packs.len(), 1);
    assert!(std::fs::read(&packs[0]).unwrap().len() < size);
    let again = meshvet(dir.path(), &args);
    assert!(
        again.stderr.contains("6 files reused, 1 read"),
        "{}",
        again.stderr
    );

    // A changed file and a new dependency are read again; the rest still comes from the cache.
    write(dir.path(), "a/open.obj", TETRA.as_bytes());
    write(dir.path(), "a/t.mtl", b"newmtl red\n");
    let changed = meshvet(dir.path(), &args);
    assert!(
        changed.stderr.contains("4 files reused, 3 read"),
        "{}",
        changed.stderr
    );
    let fresh = meshvet(dir.path(), &["scan", "--csv", "-", "a", "b", "c"]);
    assert_eq!(
        without_millis(&changed.stdout),
        without_millis(&fresh.stdout)
    );
}

/// Shards on one machine share a cache folder: each run writes a pack of its own while the others
/// read theirs, none removes a pack another has open, and a later whole scan reuses every entry.
/// A rebuilt meshvet of the same version (a copy of the executable with another modification
/// time stands in for it) reads every file again instead of reusing the rows the build before it
/// judged; the same build reuses them.
#[test]
fn a_rebuilt_meshvet_does_not_reuse_the_rows_of_the_build_before() {
    let dir = scan_tree();
    let exe = dir.path().join("meshvet-build");
    std::fs::copy(env!("CARGO_BIN_EXE_meshvet"), &exe).unwrap();
    let exe = exe.to_str().unwrap();
    let args = ["scan", "--cache", "cache", "--csv", "-", "a", "b", "c"];
    let said = |run: &Run, text: &str| {
        assert!(run.stderr.contains(text), "{text}: {}", run.stderr);
    };
    // Error rows are never stored: garbage.stl is read every time.
    said(&run(exe, dir.path(), &args), "0 files reused, 6 read");
    said(&run(exe, dir.path(), &args), "5 files reused, 1 read");
    let later = std::time::SystemTime::now() + std::time::Duration::from_secs(3600);
    let file = std::fs::File::options().write(true).open(exe).unwrap();
    file.set_modified(later).unwrap();
    drop(file);
    said(&run(exe, dir.path(), &args), "0 files reused, 6 read");
    said(&run(exe, dir.path(), &args), "5 files reused, 1 read");
}

#[test]
fn shards_running_at_once_share_one_cache() {
    let dir = tree(&[]);
    for i in 0..60 {
        let text = [TETRA, INSIDE_OUT, TRIANGLE, FIN][i % 4];
        write(
            dir.path(),
            &format!("lib/d{}/m{i:02}.obj", i % 5),
            text.as_bytes(),
        );
    }
    let whole = meshvet(dir.path(), &["scan", "lib", "--csv", "whole.csv"]);
    // Twice: the second round's shards find the first round's packs (and may compact them).
    for round in 0..2 {
        let handles: Vec<_> = (1..=3)
            .map(|k| {
                Command::new(env!("CARGO_BIN_EXE_meshvet"))
                    .args(["scan", "lib", "--cache", "cache", "--shard"])
                    .arg(format!("{k}/3"))
                    .arg("--csv")
                    .arg(format!("shard{k}.csv"))
                    .current_dir(dir.path())
                    .stdin(Stdio::null())
                    .stdout(Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        for handle in handles {
            let out = handle.wait_with_output().unwrap();
            assert!(out.status.code().unwrap() <= 1, "round {round}");
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(!stdout.contains("not all saved"), "{stdout}");
        }
    }
    let all = meshvet(
        dir.path(),
        &["scan", "lib", "--cache", "cache", "--csv", "cached.csv"],
    );
    assert!(
        all.stdout.contains("60 files reused, 0 read"),
        "{}",
        all.stdout
    );
    assert_eq!(
        without_millis(&read(dir.path(), "cached.csv")),
        without_millis(&read(dir.path(), "whole.csv"))
    );
    assert_eq!(whole.code, all.code);
}

/// Runs `meshvet ARGS` in `cwd`, killing it after a minute: `None` when it had to be killed.
fn meshvet_or_hang(cwd: &Path, args: &[&str]) -> Option<Run> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_meshvet"))
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(60) {
            child.kill().unwrap();
            child.wait().unwrap();
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    Some(Run {
        code: out.status.code().expect("exits normally"),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    })
}

/// `--cache .` on the scanned folder itself, which holds the user's files named `pack-...` (one a
/// mesh the scan reads, one named exactly as the cache names its packs) and a FIFO named like a
/// pack: every run finishes and reports the mesh, and the user's files stay as they were, also
/// when a damaged pack of the cache's own makes a run merge its packs.
#[test]
fn the_cache_never_removes_or_waits_on_files_it_did_not_write() {
    let theirs = [
        ("pack-hole.obj", TRIANGLE),
        ("pack-list.txt", "my notes\n"),
        (
            "pack-00000000000000000001-1-0",
            "my notes, named like a pack\n",
        ),
    ];
    let dir = tree(&theirs);
    #[cfg(unix)]
    let fifo = {
        let fifo = dir.path().join("pack-00000000000000000002-1-0");
        assert!(Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success());
        fifo
    };
    let args = ["scan", ".", "--cache", ".", "--csv", "-"];
    for round in 0..3 {
        let run = meshvet_or_hang(dir.path(), &args)
            .unwrap_or_else(|| panic!("round {round}: the scan hangs"));
        assert_eq!(run.code, 0, "round {round}: {}", run.stderr);
        let rows = without_millis(&run.stdout);
        assert_eq!(rows.len(), 2, "round {round}: {rows:?}");
        assert_eq!(
            (rows[1][0].as_str(), rows[1][3].as_str()),
            ("pack-hole.obj", "warn")
        );
        for (name, text) in theirs {
            assert_eq!(read(dir.path(), name), text, "round {round}");
        }
        #[cfg(unix)]
        {
            use std::os::unix::fs::FileTypeExt;
            let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
            assert!(kind.is_fifo(), "round {round}");
        }
        // Damage the cache's own packs: the next run merges them.
        for pack in cache_packs(dir.path()) {
            let name = pack.file_name().unwrap().to_string_lossy().into_owned();
            if name.len() > 25 && !theirs.iter().any(|(n, _)| *n == name) && pack.is_file() {
                let mut bytes = std::fs::read(&pack).unwrap();
                bytes.extend_from_slice(b"torn");
                std::fs::write(&pack, bytes).unwrap();
            }
        }
    }
}

#[test]
fn the_baseline_names_regressions_and_can_alone_decide_the_exit_code() {
    let dir = tree(&[
        ("m/fin.obj", FIN),
        ("m/ok.obj", TETRA),
        ("m/open.obj", TRIANGLE),
    ]);
    let old = meshvet(dir.path(), &["scan", "m", "--csv", "old.csv"]);
    assert_eq!(old.code, 1, "fin.obj already fails");
    let same = meshvet(
        dir.path(),
        &["scan", "m", "--baseline", "old.csv", "--fail-on-regression"],
    );
    assert_eq!(
        same.code, 0,
        "a failure the baseline had is no regression: {}",
        same.stdout
    );
    assert!(
        same.stdout
            .contains("since old.csv: 0 got worse, 0 got better"),
        "{}",
        same.stdout
    );

    write(dir.path(), "m/open.obj", INSIDE_OUT.as_bytes());
    write(dir.path(), "m/new.obj", INSIDE_OUT.as_bytes());
    write(dir.path(), "m/fin.obj", TETRA.as_bytes());
    let worse = meshvet(
        dir.path(),
        &["scan", "m", "--baseline", "old.csv", "--fail-on-regression"],
    );
    assert_eq!(worse.code, 1);
    let tail: Vec<&str> = worse
        .stdout
        .lines()
        .skip_while(|l| !l.starts_with("since"))
        .collect();
    assert_eq!(
        tail,
        [
            "since old.csv: 2 got worse, 1 got better",
            "worse: new.obj: newly failing: inside-out-shell (new -> fail)",
            "worse: open.obj: newly failing: inside-out-shell (warn -> fail)",
        ]
    );
    // Without the flag the ordinary rule decides; the regressions are still reported.
    let plain = meshvet(dir.path(), &["scan", "m", "--baseline", "old.csv", "-q"]);
    assert_eq!(plain.code, 1);
    assert!(plain.stdout.contains("worse: open.obj"), "{}", plain.stdout);

    // A CSV with another column set is a clear usage error.
    write(
        dir.path(),
        "other.csv",
        b"path,mesh,status\nm/ok.obj,,pass\n",
    );
    let other = meshvet(dir.path(), &["scan", "m", "--baseline", "other.csv"]);
    assert_eq!(other.code, 2);
    assert!(other.stderr.contains("other columns"), "{}", other.stderr);
    let flag_alone = meshvet(dir.path(), &["scan", "m", "--fail-on-regression"]);
    assert_eq!(flag_alone.code, 2, "--fail-on-regression needs --baseline");
}

/// A glTF with two meshes named `Part`, one failing (a flipped face) and one passing, compared
/// with its own baseline: nothing got worse or better (each mesh has a row of its own name; they
/// used to share `Part`, and the passing row was compared with the failing one's). A baseline
/// with two rows of one path and mesh (an older meshvet's) is refused with what to do.
#[test]
fn meshes_of_one_name_are_compared_with_their_own_baseline_rows() {
    // Two tetrahedra in one buffer: mesh 0's second face turned.
    let mut bin = Vec::new();
    for p in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]] {
        bin.extend(p.iter().flat_map(|x| x.to_le_bytes()));
    }
    for faces in [
        [0u16, 2, 1, 0, 3, 1, 1, 2, 3, 0, 3, 2],
        [0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2],
    ] {
        bin.extend(faces.iter().flat_map(|i| i.to_le_bytes()));
    }
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": bin.len(), "uri": "parts.bin"}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 24},
            {"buffer": 0, "byteOffset": 72, "byteLength": 24}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5123, "count": 12, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5123, "count": 12, "type": "SCALAR"}
        ],
        "meshes": [
            {"name": "Part", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
            {"name": "Part", "primitives": [{"attributes": {"POSITION": 0}, "indices": 2}]}
        ],
        "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [3, 0, 0]}],
        "scenes": [{"nodes": [0, 1]}]
    });
    let dir = tree(&[("m/parts.gltf", &doc.to_string())]);
    write(dir.path(), "m/parts.bin", &bin);
    let old = meshvet(dir.path(), &["scan", "m", "--csv", "old.csv"]);
    assert_eq!(old.code, 1, "mesh 0 fails: {}", old.stdout);
    let csv = std::fs::read_to_string(dir.path().join("old.csv")).unwrap();
    let rows: Vec<(&str, &str)> = csv
        .lines()
        .skip(1)
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            (cells[1], cells[3])
        })
        .collect();
    assert_eq!(rows, [("Part (#0)", "fail"), ("Part (#1)", "pass")]);
    let same = meshvet(
        dir.path(),
        &["scan", "m", "--baseline", "old.csv", "--fail-on-regression"],
    );
    assert_eq!(same.code, 0, "{}", same.stdout);
    assert!(
        same.stdout
            .contains("since old.csv: 0 got worse, 0 got better"),
        "{}",
        same.stdout
    );
    // An older meshvet's rows: both named `Part`.
    write(
        dir.path(),
        "older.csv",
        csv.replace("Part (#0)", "Part")
            .replace("Part (#1)", "Part")
            .as_bytes(),
    );
    let older = meshvet(dir.path(), &["scan", "m", "--baseline", "older.csv"]);
    assert_eq!(older.code, 2, "{}", older.stdout);
    assert!(
        older.stderr.contains("has two rows for parts.gltf#Part")
            && older.stderr.contains("scan again to make a new baseline"),
        "{}",
        older.stderr
    );
}

#[test]
fn three_shards_merged_equal_the_unsharded_scan() {
    let dir = tree(&[]);
    for i in 0..40 {
        let text = [TETRA, INSIDE_OUT, TRIANGLE, FIN][i % 4];
        write(
            dir.path(),
            &format!("lib/d{}/m{i:02}.obj", i % 5),
            text.as_bytes(),
        );
    }
    write(dir.path(), "lib/d1/garbage.stl", b"\x00\x01 not an STL");
    let whole = meshvet(dir.path(), &["scan", "lib", "--csv", "whole.csv"]);
    let mut sizes = Vec::new();
    for k in 1..=3 {
        let shard = format!("{k}/3");
        let out = format!("shard{k}.csv");
        let run = meshvet(
            dir.path(),
            &["scan", "lib", "--shard", &shard, "--csv", &out],
        );
        assert!(run.code <= 1, "{}", run.stderr);
        sizes.push(read(dir.path(), &out).lines().count() - 1);
    }
    assert_eq!(sizes.iter().sum::<usize>(), 41);
    assert!(sizes.iter().all(|&n| n > 0), "{sizes:?}");
    let merge = meshvet(
        dir.path(),
        &[
            "merge",
            "shard3.csv",
            "shard1.csv",
            "shard2.csv",
            "--csv",
            "all.csv",
        ],
    );
    assert_eq!(merge.code, 0, "{}", merge.stderr);
    assert_eq!(
        without_millis(&read(dir.path(), "all.csv")),
        without_millis(&read(dir.path(), "whole.csv"))
    );
    assert_eq!(whole.code, 1);

    let overlap = meshvet(
        dir.path(),
        &["merge", "shard1.csv", "shard1.csv", "--csv", "bad.csv"],
    );
    assert_eq!(overlap.code, 2);
    assert!(
        overlap.stderr.contains("both hold shard 1/2") && overlap.stderr.contains("given twice"),
        "{}",
        overlap.stderr
    );
    // A shard's report missing: two of the three, read as shards of 2, mix shards.
    let missing = meshvet(
        dir.path(),
        &["merge", "shard1.csv", "shard2.csv", "--csv", "bad.csv"],
    );
    assert_eq!(missing.code, 2);
    assert!(
        missing.stderr.contains("is a shard's report missing"),
        "{}",
        missing.stderr
    );
    assert!(!dir.path().join("bad.csv").exists());
    write(dir.path(), "other.csv", b"path,mesh,status\nz.obj,,pass\n");
    let mismatch = meshvet(
        dir.path(),
        &["merge", "shard1.csv", "other.csv", "--csv", "-"],
    );
    assert_eq!(mismatch.code, 2);
    assert!(
        mismatch
            .stderr
            .contains("has other columns than this meshvet's CSV"),
        "{}",
        mismatch.stderr
    );
    let bad_shard = meshvet(dir.path(), &["scan", "lib", "--shard", "4/3"]);
    assert_eq!(bad_shard.code, 2);
}

/// A cached row would skip writing the repaired copy, so with `--repair-dir` the cache is not
/// consulted: a copy deleted after the first run is written again by the second.
#[test]
fn repair_runs_do_not_answer_from_the_cache() {
    let dir = tree(&[("in/fin.obj", FIN)]);
    let args = [
        "scan",
        "in",
        "--cache",
        "cache",
        "--repair-dir",
        "out",
        "--csv",
        "r.csv",
    ];
    let first = meshvet(dir.path(), &args);
    let copy = dir.path().join("out/fin.obj");
    assert!(copy.is_file(), "{}", first.stderr);
    std::fs::remove_file(&copy).unwrap();
    let second = meshvet(dir.path(), &args);
    assert!(
        copy.is_file(),
        "the copy was not written again: {}",
        second.stderr
    );
    assert_eq!(second.code, first.code);
    assert!(
        second.stdout.contains("cache cache: not used"),
        "the summary says the cache was left alone: {}",
        second.stdout
    );
    assert!(
        !dir.path().join("cache").exists(),
        "an unused cache folder is not even created"
    );
}

/// A tetrahedron 1e300 long: its area and volume overflow `f64` (1e600), so they are not defined:
/// empty cells in the CSV and `null` in the JSON, as SPEC 9 says of undefined numbers, never
/// `NaN` or `inf`. Its bounding box is finite and is written (in digits: cells never use an
/// exponent).
#[test]
fn numbers_that_overflow_are_empty_cells() {
    let huge =
        "v 0 0 0\nv 1e300 0 0\nv 0 1e300 0\nv 0 0 1e300\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    let dir = tree(&[("huge.obj", huge)]);
    let run = meshvet(
        dir.path(),
        &[
            "scan", "huge.obj", "--csv", "r.csv", "--json", "r.jsonl", "-q",
        ],
    );
    assert!(run.code <= 1, "{}", run.stderr);
    let mut reader = csv::Reader::from_path(dir.path().join("r.csv")).unwrap();
    let header = reader.headers().unwrap().clone();
    let row = reader.records().next().unwrap().unwrap();
    let cell = |name: &str| row[header.iter().position(|h| h == name).unwrap()].to_owned();
    assert_eq!(
        (cell("volume"), cell("area")),
        (String::new(), String::new())
    );
    assert_eq!(cell("bbox_max_x").parse::<f64>(), Ok(1e300));
    let json = std::fs::read_to_string(dir.path().join("r.jsonl")).unwrap();
    assert!(!json.contains("NaN") && !json.contains("inf"), "{json}");
}
