//! The sorted list of files a scan reads. Folders are walked recursively (symlinks are not followed,
//! so a link loop cannot trap the walk); a file named on the command line is taken alone. Only the
//! mesh extensions count in folders (`.obj .gltf .glb .stl .ply .off .3mf`, any case); a file named
//! explicitly is always listed, so a wrong extension becomes an `error` row rather than silence, and
//! so does a named path that is not a regular file (a FIFO or device: reading it would block). In
//! folders only regular files are listed.
//!
//! Report paths: with one PATH, a file's path is relative to that PATH (a folder, or the folder of a
//! file) with `/` separators. With several PATHs each file's path is the PATH as written (without a
//! leading `./`) joined with that relative path, so rows from different PATHs stay distinct; the list
//! is sorted by report path and a file reached twice is listed once. Names that are not UTF-8 are kept
//! and reported lossily (U+FFFD for the bad bytes).
//!
//! Include and exclude globs match the relative path or the report path, for walked and named files
//! alike; `*` also crosses `/`. An excluded folder is not descended into.

use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use globset::{Glob, GlobSet, GlobSetBuilder};

use crate::copies::STAGE_PREFIX;
use crate::formats::Format;

/// One file to scan, or one walk error to report.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    /// Where to read the file.
    pub path: PathBuf,
    /// The path in the report (see the module docs).
    pub display: String,
    /// The tree glTF buffers must stay inside: the folder given, or the folder of a file given.
    /// Shared by every file of a walked folder (a million-file tree holds one copy).
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
    let prefixed = paths.len() > 1;
    let mut sources = Vec::new();
    for given in paths {
        let prefix = if prefixed {
            normalise(given)
        } else {
            PathBuf::new()
        };
        if given.is_dir() {
            walk_folder(given, &prefix, filter, &mut sources);
        } else {
            let name = given
                .file_name()
                .map(PathBuf::from)
                .unwrap_or_else(|| given.clone());
            let display = if prefixed {
                prefix.clone()
            } else {
                name.clone()
            };
            if !filter.admits(&[&name, &normalise(given)]) {
                continue;
            }
            let root: Arc<Path> = match given.parent() {
                Some(p) if !p.as_os_str().is_empty() => p.into(),
                _ => Path::new(".").into(),
            };
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
                root,
                error,
            });
        }
    }
    sources.sort_by(|a, b| a.display.cmp(&b.display));
    sources.dedup_by(|a, b| a.display == b.display);
    sources
}

fn walk_folder(root: &Path, prefix: &Path, filter: &Filter, sources: &mut Vec<Source>) {
    let shared_root: Arc<Path> = root.into();
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
                sources.push(Source {
                    path: e.path().to_owned(),
                    display: slashed(&display),
                    root: shared_root.clone(),
                    format: Some(format),
                    error: None,
                });
            }
            Err(e) => {
                // A folder or file the walk could not look at still gets a row.
                let path = e.path().unwrap_or(root).to_owned();
                let display = prefix.join(relative(&path));
                let why = e
                    .io_error()
                    .map_or_else(|| e.to_string(), |io| io.to_string());
                sources.push(Source {
                    format: Format::of_path(&path),
                    display: slashed(&display),
                    path,
                    root: shared_root.clone(),
                    error: Some(format!(
                        "cannot read this entry while walking the tree: {why} - check its permissions"
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

/// A path as the report writes it: components joined by `/`, lossy for non-UTF-8 names.
pub fn slashed(path: &Path) -> String {
    let mut out = String::new();
    for c in path.components() {
        match c {
            Component::RootDir => out.push('/'),
            Component::CurDir => continue,
            _ => {
                if !out.is_empty() && !out.ends_with('/') {
                    out.push('/');
                }
                out.push_str(&c.as_os_str().to_string_lossy());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;

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
        assert_eq!(displays(&named), ["c.obj"]);
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

    #[cfg(unix)]
    #[test]
    fn non_utf8_names_are_listed_lossily() {
        use std::os::unix::ffi::OsStrExt;
        let dir = tempfile::tempdir().unwrap();
        let name = std::ffi::OsStr::from_bytes(b"bad\xff.obj");
        fs::write(dir.path().join(name), "").unwrap();
        let got = walk(&[dir.path().to_owned()], &Filter::everything());
        assert_eq!(displays(&got), ["bad\u{fffd}.obj"]);
    }
}
