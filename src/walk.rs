//! The sorted list of files a scan reads. Folders are walked recursively (symlinks are not followed,
//! so a link loop cannot trap the walk); a file named on the command line is taken alone. Only the
//! mesh extensions count in folders (those of [`Format`], any case); a file named
//! explicitly is always listed, so a wrong extension becomes an `error` row rather than silence, and
//! so does a named path that is not a regular file (a FIFO or device: reading it would block). In
//! folders only regular files are listed.
//!
//! Report paths: with one folder PATH, a file's path is relative to it, with `/` separators; a file
//! named on the command line is reported as written (without a leading `./`). With several PATHs
//! each file's path is the PATH as written (without a leading `./`) joined with that relative path,
//! so rows from different PATHs stay distinct; the list is sorted by report path. A file reached
//! twice (a folder and a file in it, or one file spelt two ways: `a/b.obj`, `/abs/a/b.obj`,
//! `a/../a/b.obj`, a link named on the command line) is listed once, under the spelling reached
//! first; it is told by its real path (the walked folder's canonical path joined with the path
//! below it, a named file's canonical path), so two hard links to one file are two names, both
//! listed. A folder PATH that cannot be read is listed as an error entry under PATH as written.
//!
//! Names that are not UTF-8 are kept (the file is read by its real name, and a repaired copy gets
//! that name) and shown in the report path with each byte that is not UTF-8 as `\xHH` (two
//! upper-case hex digits): `bad\xFF.obj`. So that no two names show alike, a backslash in a name
//! is doubled when the next character shown is `x` or another backslash: a file really named
//! `bad\xFF.obj` shows as `bad\\xFF.obj`. Every other name shows as it is.
//!
//! Include and exclude globs match the relative path or the report path, for walked and named files
//! alike; `*` also crosses `/`. An excluded folder is not descended into, and a file or folder
//! named on the command line inside one (below the current folder, or `--root`) is left out too;
//! folders above the scanned tree are never matched.

use std::collections::HashSet;
use std::ffi::OsStr;
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use globset::{Glob, GlobSet, GlobSetBuilder};

use crate::formats::Format;

/// The prefix of the staging folders a repair writes its copies in before they are checked
/// (`.meshvet-stage-PID-N`, next to the copy's place). Only a killed run leaves one behind; the
/// walk never descends into one.
pub const STAGE_PREFIX: &str = ".meshvet-stage-";

/// One file to scan, or one walk error to report.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    /// Where to read the file.
    pub path: PathBuf,
    /// The path in the report (see the module docs): [`Source::report_path`] as text.
    pub display: String,
    /// The path in the report with the real bytes of every name (a repaired copy is named from
    /// it, not from `display`, which escapes the bytes that are not UTF-8).
    pub report_path: PathBuf,
    /// The tree every file a model names (glTF buffers and images, OBJ material libraries) must
    /// stay inside: `--root`, else the folder given, or for a file given alone the current folder
    /// (when the file is inside it) or its own folder. Shared by every file of a walked folder (a
    /// million-file tree holds one copy).
    pub root: Arc<Path>,
    /// `None`: not a mesh extension (only for files named explicitly).
    pub format: Option<Format>,
    /// Why this entry could not be listed (permission denied, vanished while walking, ...).
    pub error: Option<String>,
}

/// The include and exclude globs of the settings.
#[derive(Debug, Clone)]
pub struct Filter {
    include: Option<GlobSet>,
    exclude: GlobSet,
}

impl Filter {
    /// Compiles the globs; an error names the bad pattern.
    pub fn new(include: &[String], exclude: &[String]) -> Result<Filter, String> {
        let build = |patterns: &[String]| -> Result<GlobSet, String> {
            let mut set = GlobSetBuilder::new();
            for p in patterns {
                set.add(Glob::new(p).map_err(|e| format!("bad glob `{p}`: {e}"))?);
            }
            set.build().map_err(|e| e.to_string())
        };
        Ok(Filter {
            include: if include.is_empty() {
                None
            } else {
                Some(build(include)?)
            },
            exclude: build(exclude)?,
        })
    }

    /// A filter that admits every file.
    pub fn everything() -> Filter {
        Filter {
            include: None,
            exclude: GlobSet::empty(),
        }
    }

    fn excludes(&self, names: &[&Path]) -> bool {
        names.iter().any(|n| self.exclude.is_match(n))
    }

    fn admits(&self, names: &[&Path]) -> bool {
        let included = match &self.include {
            Some(set) => names.iter().any(|n| set.is_match(n)),
            None => true,
        };
        included && !self.excludes(names)
    }
}

/// The sorted, de-duplicated files under `paths` that the filter admits. Paths that do not exist give
/// an error entry (callers that want to refuse them should check first).
pub fn walk(paths: &[PathBuf], filter: &Filter) -> Vec<Source> {
    walk_within(paths, filter, None)
}

/// [`walk`], with `root` as the tree every file a model names must stay inside (`--root`). Without
/// one, a walked folder is its own tree, and a file named alone has the current folder as its tree
/// when it lies inside it (the tree a user works in: `props/barrel.gltf` may use
/// `buffers/barrel.bin`), else its own folder.
pub fn walk_within(paths: &[PathBuf], filter: &Filter, root: Option<&Path>) -> Vec<Source> {
    let prefixed = paths.len() > 1;
    let given_root: Option<Arc<Path>> = root.map(Into::into);
    let current: Arc<Path> = Path::new(".").into();
    let current_real = Path::new(".").canonicalize().ok();
    let given_root_real = given_root.as_deref().map(real);
    let mut sources = Vec::new();
    // The real paths listed so far: only several PATHs can reach one file twice.
    let mut seen = Seen {
        paths: prefixed.then(HashSet::new),
    };
    for given in paths {
        let prefix = if prefixed {
            normalise(given)
        } else {
            PathBuf::new()
        };
        if given.is_dir() {
            // Inside the current folder (or `--root`), a folder named in a folder the exclude
            // globs name is left out as the walk of `.` leaves it out.
            let around = given_root_real.as_deref().or(current_real.as_deref());
            if in_excluded_folder(filter, given, around) {
                continue;
            }
            let tree = given_root.clone().unwrap_or_else(|| given.as_path().into());
            let folder = Folder {
                root: given,
                real: real(given),
                prefix: &prefix,
                tree: &tree,
            };
            walk_folder(&folder, filter, &mut seen, &mut sources);
        } else {
            let name = given
                .file_name()
                .map(PathBuf::from)
                .unwrap_or_else(|| given.clone());
            // The path as written (less `./`), so `a/part.obj` and `b/part.obj` stay apart.
            let display = normalise(given);
            let folder = match given.parent() {
                Some(p) if !p.as_os_str().is_empty() => p,
                _ => Path::new("."),
            };
            let inside_current = match (&current_real, folder.canonicalize()) {
                (Some(cwd), Ok(real)) => real.starts_with(cwd),
                _ => false,
            };
            let root = match &given_root {
                Some(r) => r.clone(),
                None if inside_current => current.clone(),
                None => folder.into(),
            };
            // A folder the exclude globs name is left out with every file in it, as the walk
            // leaves it out (`vendor` keeps `vendor/deep/part.obj` out), counting the folders of
            // the file's tree only.
            // The tree's real path: known already but for a file's own folder.
            let tree_real = match (&given_root_real, inside_current) {
                (Some(r), _) => Some(r.clone()),
                (None, true) => current_real.clone(),
                (None, false) => Some(real(&root)),
            };
            if in_excluded_folder(filter, folder, tree_real.as_deref())
                || !filter.admits(&[&name, &display])
            {
                continue;
            }
            if !seen.first(|| real(given)) {
                continue;
            }
            // Only regular files are read: a FIFO or a device named here would block the scan.
            let error = match std::fs::metadata(given) {
                Ok(meta) => {
                    crate::formats::not_regular(&meta).map(crate::formats::not_regular_message)
                }
                Err(e) => Some(format!("cannot open the file: {e}")),
            };
            sources.push(Source {
                format: Format::of_path(given),
                path: given.clone(),
                display: slashed(&display),
                report_path: display,
                root,
                error,
            });
        }
    }
    // Report paths are distinct (one per real path, and names shown injectively): the sort alone
    // orders the list.
    sources.sort_by(|a, b| a.display.cmp(&b.display));
    sources
}

/// Whether `folder` is, or lies in, a folder the exclude globs name, by its path below `tree` (a
/// real path): the folders above the tree are not the user's to exclude (`**/build` must not
/// leave out a project kept under `/tmp/build`). `false` for a folder outside the tree or that
/// cannot be resolved.
fn in_excluded_folder(filter: &Filter, folder: &Path, tree: Option<&Path>) -> bool {
    let (Some(tree), Ok(folder)) = (tree, folder.canonicalize()) else {
        return false;
    };
    let Ok(inside) = folder.strip_prefix(tree) else {
        return false;
    };
    inside
        .ancestors()
        .any(|f| !f.as_os_str().is_empty() && filter.excludes(&[f]))
}

/// The real paths of the files listed so far, when a file can be reached twice.
struct Seen {
    paths: Option<HashSet<PathBuf>>,
}

impl Seen {
    /// Whether the file whose real path `real` gives is reached for the first time (always, when
    /// no file can be reached twice: then `real` is not called).
    fn first(&mut self, real: impl FnOnce() -> PathBuf) -> bool {
        self.paths.as_mut().is_none_or(|paths| paths.insert(real()))
    }
}

/// The canonical path of `path`; for one that cannot be resolved (missing, unreadable), its
/// absolute path as written, less `.` components.
fn real(path: &Path) -> PathBuf {
    path.canonicalize().unwrap_or_else(|_| {
        let path = normalise(path);
        std::path::absolute(&path).unwrap_or(path)
    })
}

/// A folder PATH being walked.
struct Folder<'a> {
    /// As written.
    root: &'a Path,
    /// Its real path ([`real`]): a file below it is `real` joined with its path below `root`, as
    /// the walk follows no link.
    real: PathBuf,
    /// What report paths start with (the folder as written, with several PATHs).
    prefix: &'a Path,
    /// The tree every file a model names must stay inside.
    tree: &'a Arc<Path>,
}

fn walk_folder(folder: &Folder<'_>, filter: &Filter, seen: &mut Seen, sources: &mut Vec<Source>) {
    let (root, prefix) = (folder.root, folder.prefix);
    let shared_root = folder.tree.clone();
    let relative = |p: &Path| p.strip_prefix(root).unwrap_or(p).to_owned();
    let walker = walkdir::WalkDir::new(root)
        .follow_links(false)
        .sort_by_file_name()
        .into_iter()
        .filter_entry(|e| {
            if e.depth() == 0 || !e.file_type().is_dir() {
                return true;
            }
            // A repair's staging folder (left behind only by a killed run) holds no sources.
            if e.file_name().to_string_lossy().starts_with(STAGE_PREFIX) {
                return false;
            }
            let rel = relative(e.path());
            !filter.excludes(&[&rel, &prefix.join(&rel)])
        });
    for entry in walker {
        match entry {
            Ok(e) => {
                if !e.file_type().is_file() {
                    continue;
                }
                let Some(format) = Format::of_path(e.path()) else {
                    continue;
                };
                let rel = relative(e.path());
                let display = prefix.join(&rel);
                if !filter.admits(&[&rel, &display]) {
                    continue;
                }
                if !seen.first(|| folder.real.join(&rel)) {
                    continue;
                }
                sources.push(Source {
                    path: e.path().to_owned(),
                    display: slashed(&display),
                    report_path: display,
                    root: shared_root.clone(),
                    format: Some(format),
                    error: None,
                });
            }
            Err(e) => {
                // A folder or file the walk could not look at still gets a row.
                let path = e.path().unwrap_or(root).to_owned();
                let rel = relative(&path);
                if !seen.first(|| folder.real.join(&rel)) {
                    continue;
                }
                let mut report_path = prefix.join(&rel);
                let mut display = slashed(&report_path);
                if display.is_empty() {
                    // The folder given itself (one PATH): named as written, never an empty path.
                    report_path = root.to_owned();
                    display = Some(slashed(root))
                        .filter(|d| !d.is_empty())
                        .unwrap_or_else(|| ".".into());
                }
                // What to do follows from why: only a refused read is about permissions.
                let (why, todo) = match e.io_error() {
                    Some(io) if io.kind() == std::io::ErrorKind::PermissionDenied => {
                        (io.to_string(), "check its permissions")
                    }
                    Some(io) if io.kind() == std::io::ErrorKind::NotFound => (
                        io.to_string(),
                        "it was removed or renamed during the scan; scan again",
                    ),
                    Some(io) => (io.to_string(), "check that the entry can be listed"),
                    None => (e.to_string(), "check that the entry can be listed"),
                };
                sources.push(Source {
                    format: Format::of_path(&path),
                    display,
                    report_path,
                    path,
                    root: shared_root.clone(),
                    error: Some(format!(
                        "cannot read this entry while walking the tree: {why} - {todo}"
                    )),
                });
            }
        }
    }
}

/// `path` without `.` components (so `./models/` becomes `models`).
fn normalise(path: &Path) -> PathBuf {
    path.components()
        .filter(|c| !matches!(c, Component::CurDir))
        .collect()
}

/// A path as the report writes it: components joined by `/`, without `.` components, names shown
/// as the module docs say (each byte that is not UTF-8 as `\xHH`).
pub fn slashed(path: &Path) -> String {
    shown(path, false)
}

/// `path` joined by `/` with its names shown as in a report path (see the module docs), keeping
/// `.` components when `keep_dots` (a repaired copy's path under the repair folder as given).
pub fn shown(path: &Path, keep_dots: bool) -> String {
    let mut out = String::new();
    for c in path.components() {
        match c {
            Component::RootDir => out.push('/'),
            Component::CurDir if !keep_dots => continue,
            _ => {
                if !out.is_empty() && !out.ends_with('/') {
                    out.push('/');
                }
                push_name(&mut out, c.as_os_str());
            }
        }
    }
    out
}

/// Appends `name` as a report shows it: UTF-8 as it is, each other byte as `\xHH`, and a
/// backslash doubled when the next character shown is `x` or a backslash (so `\x` in the
/// output always starts an escaped byte, and no two names show alike).
fn push_name(out: &mut String, name: &OsStr) {
    let bytes = name.as_encoded_bytes();
    if let Ok(text) = std::str::from_utf8(bytes) {
        if !text.contains('\\') {
            out.push_str(text);
            return;
        }
    }
    // What the name shows as, piece by piece: a character, or a byte that is not UTF-8.
    enum Piece {
        Char(char),
        Byte(u8),
    }
    let pieces: Vec<Piece> = bytes
        .utf8_chunks()
        .flat_map(|chunk| {
            let chars = chunk.valid().chars().map(Piece::Char);
            chars.chain(chunk.invalid().iter().map(|&b| Piece::Byte(b)))
        })
        .collect();
    for (i, piece) in pieces.iter().enumerate() {
        match piece {
            Piece::Char('\\') => {
                let escaped = matches!(
                    pieces.get(i + 1),
                    Some(Piece::Char('\\' | 'x') | Piece::Byte(_))
                );
                out.push_str(if escaped { "\\\\" } else { "\\" });
            }
            Piece::Char(c) => out.push(*c),
            Piece::Byte(b) => out.push_str(&format!("\\x{b:02X}")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;

    /// An entry too deep for a path to reach (over 4,096 bytes here) gets its own error row, and
    /// its advice is not about permissions (before, every walk error said "check its
    /// permissions").
    #[cfg(target_os = "linux")]
    #[test]
    fn an_entry_whose_path_is_too_long_is_not_called_a_permissions_problem() {
        let dir = tempfile::tempdir().unwrap();
        let levels = 24;
        let mut short = dir.path().join("t");
        for _ in 0..levels {
            short.push("d");
        }
        fs::create_dir_all(&short).unwrap();
        fs::write(short.join("m.obj"), "").unwrap();
        // Each level renamed to a long name, deepest first, so every rename's path stays short.
        let long = "d".repeat(200);
        for depth in (1..=levels).rev() {
            let mut parent = dir.path().join("t");
            for _ in 1..depth {
                parent.push("d");
            }
            fs::rename(parent.join("d"), parent.join(&long)).unwrap();
        }
        let sources = walk(&[dir.path().join("t")], &Filter::everything());
        let errors: Vec<&str> = sources.iter().filter_map(|s| s.error.as_deref()).collect();
        assert!(!errors.is_empty(), "{sources:?}");
        assert!(
            errors
                .iter()
                .all(|e| e.contains("check that the entry can be listed")
                    && !e.contains("permissions")),
            "{errors:?}"
        );
    }

    fn tree(files: &[&str]) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        for f in files {
            let p = dir.path().join(f);
            fs::create_dir_all(p.parent().unwrap()).unwrap();
            fs::write(p, "").unwrap();
        }
        dir
    }

    fn displays(sources: &[Source]) -> Vec<&str> {
        sources.iter().map(|s| s.display.as_str()).collect()
    }

    #[test]
    fn walks_sorted_mesh_files_case_insensitively() {
        let dir = tree(&[
            "b.OBJ",
            "a/c.stl",
            "a.glb",
            "notes.txt",
            "a/d.Ply",
            "z/e.off",
            "z/.meshvet-stage-41-0/e.off",
        ]);
        let got = walk(&[dir.path().to_owned()], &Filter::everything());
        assert_eq!(
            displays(&got),
            ["a.glb", "a/c.stl", "a/d.Ply", "b.OBJ", "z/e.off"],
            "a killed repair's staging folder is not walked"
        );
        assert!(got
            .iter()
            .all(|s| *s.root == *dir.path() && s.error.is_none()));
    }

    #[test]
    fn globs_apply_to_walked_and_named_files() {
        let dir = tree(&["keep/a.obj", "tmp/b.obj", "c.obj", "c.stl"]);
        let filter = Filter::new(&["*.obj".into()], &["tmp".into()]).unwrap();
        let got = walk(&[dir.path().to_owned()], &filter);
        assert_eq!(displays(&got), ["c.obj", "keep/a.obj"]);
        let named = walk(&[dir.path().join("c.stl")], &filter);
        assert!(named.is_empty());
        let named = walk(&[dir.path().join("c.obj")], &filter);
        // As written; outside the current folder, so its own folder is its tree.
        assert_eq!(displays(&named), [slashed(&dir.path().join("c.obj"))]);
        assert_eq!(&*named[0].root, dir.path());
    }

    #[test]
    fn several_paths_are_prefixed_and_deduplicated() {
        let dir = tree(&["x/a.obj", "y/a.obj"]);
        let cwd_relative = |p: &str| dir.path().join(p);
        let got = walk(
            &[
                cwd_relative("y"),
                cwd_relative("x"),
                cwd_relative("x/a.obj"),
            ],
            &Filter::everything(),
        );
        let base = slashed(dir.path());
        assert_eq!(
            displays(&got),
            [format!("{base}/x/a.obj"), format!("{base}/y/a.obj")]
        );
    }

    #[test]
    fn slashed_joins_with_forward_slashes() {
        assert_eq!(slashed(Path::new("./a/b/c.obj")), "a/b/c.obj");
        assert_eq!(slashed(Path::new("/abs/c.obj")), "/abs/c.obj");
    }

    #[cfg(unix)]
    #[test]
    fn a_named_fifo_is_an_error_entry_and_a_walked_one_is_skipped() {
        let dir = tree(&["a.stl"]);
        let fifo = dir.path().join("pipe.stl");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        let named = walk(&[fifo], &Filter::everything());
        let error = named[0].error.as_deref().unwrap_or("");
        assert!(error.contains("not a regular file (a FIFO"), "{error}");
        let walked = walk(&[dir.path().to_owned()], &Filter::everything());
        assert_eq!(displays(&walked), ["a.stl"]);
    }

    /// Two names that differ only in bytes that are not UTF-8, a name with U+FFFD where they
    /// have those bytes, and names that hold what an escaped byte looks like: five files, five
    /// report paths, each file read and copied by its real name.
    #[cfg(unix)]
    #[test]
    fn names_that_are_not_utf8_are_shown_distinctly_and_kept_whole() {
        use std::os::unix::ffi::OsStrExt;
        let names: [(&[u8], &str); 5] = [
            (b"bad\xff.obj", "bad\\xFF.obj"),
            (b"bad\xfe.obj", "bad\\xFE.obj"),
            ("bad\u{fffd}.obj".as_bytes(), "bad\u{fffd}.obj"),
            // A backslash, `x`, `F`, `F`: the backslash is doubled.
            (b"bad\\xFF.obj", "bad\\\\xFF.obj"),
            // A backslash, then the byte 0xFF.
            (b"bad\\\xff.obj", "bad\\\\\\xFF.obj"),
        ];
        let dir = tempfile::tempdir().unwrap();
        for (name, _) in names {
            fs::write(dir.path().join(OsStr::from_bytes(name)), name).unwrap();
        }
        let got = walk(&[dir.path().to_owned()], &Filter::everything());
        let mut want: Vec<&str> = names.iter().map(|(_, shown)| *shown).collect();
        want.sort();
        assert_eq!(displays(&got), want);
        for source in &got {
            let (name, _) = names.iter().find(|(_, s)| *s == source.display).unwrap();
            assert_eq!(source.report_path.as_os_str().as_bytes(), *name);
            assert_eq!(fs::read(&source.path).unwrap(), *name);
        }
        // A backslash before anything else, and at the end, shows as it is.
        assert_eq!(slashed(Path::new("a\\b/c\\")), "a\\b/c\\");
        assert_eq!(slashed(Path::new("a\\\\b")), "a\\\\\\b");
    }

    /// One file named through a folder given, by another spelling, through `..` and through a
    /// link: listed once, under the spelling reached first. A hard link is another name, listed.
    #[cfg(unix)]
    #[test]
    fn a_file_reached_twice_is_listed_once_under_its_first_spelling() {
        let dir = tree(&["x/a.obj", "x/b.obj", "y/c.obj"]);
        fs::hard_link(dir.path().join("x/a.obj"), dir.path().join("x/hard.obj")).unwrap();
        std::os::unix::fs::symlink(dir.path().join("x/a.obj"), dir.path().join("link.obj"))
            .unwrap();
        let base = slashed(dir.path());
        let given = |p: &str| dir.path().join(p);
        let got = walk(
            &[
                given("y/../x/a.obj"),
                given("x"),
                given("link.obj"),
                given("x/./b.obj"),
                given("y"),
            ],
            &Filter::everything(),
        );
        assert_eq!(
            displays(&got),
            [
                format!("{base}/x/b.obj"),
                format!("{base}/x/hard.obj"),
                format!("{base}/y/../x/a.obj"),
                format!("{base}/y/c.obj"),
            ]
        );
        let got = walk(
            &[given("x"), given("y/../x/a.obj"), given("x/a.obj")],
            &Filter::everything(),
        );
        assert_eq!(
            displays(&got),
            [
                format!("{base}/x/a.obj"),
                format!("{base}/x/b.obj"),
                format!("{base}/x/hard.obj"),
            ]
        );
        // A path that does not exist, named twice: one error entry.
        let got = walk(
            &[given("gone.obj"), given("./gone.obj")],
            &Filter::everything(),
        );
        assert_eq!(displays(&got), [format!("{base}/gone.obj")]);
    }
}
