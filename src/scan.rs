//! The per-file pipeline, run on many files in parallel: read -> analyse -> rules -> report rows.
//!
//! One file is the unit of parallel work. Files go through a rayon pool of `settings.jobs` threads in
//! chunks, so however large the tree only one chunk's rows are in memory; each chunk's rows are handed
//! to the caller in order before the next chunk starts. Rows come out sorted by path then mesh (the
//! walk sorts files; rows of one file are sorted by mesh), so the report is the same with any number of
//! threads except for `millis`.
//!
//! Every file gets at least one row: a read error gives one `error` row, a file without triangles an
//! `empty` row, and a panic in a reader or in the analysis is caught and becomes an `error` row. The
//! scan never prints; progress is reported through a callback.

use std::time::Instant;

use rayon::prelude::*;

use crate::caught;
use crate::config::Settings;
use crate::formats::{self, Format, ReadContext};
use crate::picture;
use crate::report::{Row, ShellRow};
use crate::rules::{self, Finding, MeshFacts, Status};
use crate::topology::{analyse, analyse_keeping, places, Built, Shell};
use crate::walk::Source;

/// Files per chunk for each worker thread. Rows are small, so a chunk costs little memory; a large
/// chunk keeps threads busy when one file in it is slow (the chunk ends when its slowest file does).
const CHUNK_PER_THREAD: usize = 256;

/// Prefix of the scan threads' names: a panic hook can recognise panics that will be caught.
pub const THREAD_NAME: &str = "meshvet-scan";

/// One report row and the findings behind it (for the summary).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Outcome {
    pub row: Row,
    pub findings: Vec<Finding>,
    /// The mesh's closed shells (for the JSON report and the cache; a few small structs per mesh,
    /// so always kept). Empty for error and empty rows.
    pub shells: Vec<ShellRow>,
    /// What a detailed report shows beyond the row; only when [`Extras::details`] asked for it and
    /// the mesh has triangles.
    pub detail: Option<Box<Detail>>,
}

/// What to compute beyond the report rows. The default (nothing) is what a plain scan pays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Extras {
    /// Fill [`Outcome::detail`]: the per-shell table and a picture (for the HTML report).
    pub details: bool,
}

/// The per-shell table and the drawing of one mesh, made while it is in memory.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Detail {
    pub shells: Vec<Shell>,
    /// An SVG drawing with the problem places marked (see `picture.rs`); `None` when drawing
    /// failed or there was nothing to draw.
    pub picture: Option<String>,
}

/// Scans `sources` on a pool of `settings.jobs` threads (0: one per core). `progress` is called from
/// the worker threads once per file with the number of rows it gave; `emit` receives every outcome, in
/// report order. Stops at the first error `emit` returns.
pub fn scan<E>(
    sources: &[Source],
    settings: &Settings,
    progress: &(dyn Fn(usize) + Sync),
    emit: impl FnMut(Outcome) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<std::io::Error>,
{
    scan_with(sources, settings, Extras::default(), progress, emit)
}

/// [`scan`], computing `extras` too.
pub fn scan_with<E>(
    sources: &[Source],
    settings: &Settings,
    extras: Extras,
    progress: &(dyn Fn(usize) + Sync),
    emit: impl FnMut(Outcome) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<std::io::Error>,
{
    let per_file = |source: &Source| scan_file_with(source, settings, extras);
    scan_each(sources, settings.jobs, &per_file, progress, emit)
}

/// The parallel engine under [`scan_with`]: runs `per_file` on every source on a pool of `jobs`
/// threads (0: one per core) and hands the outcomes to `emit` in report order. A caller that can
/// answer some files without reading them (the cache) passes its own `per_file`.
pub fn scan_each<E>(
    sources: &[Source],
    jobs: usize,
    per_file: &(dyn Fn(&Source) -> Vec<Outcome> + Sync),
    progress: &(dyn Fn(usize) + Sync),
    mut emit: impl FnMut(Outcome) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<std::io::Error>,
{
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .thread_name(|i| format!("{THREAD_NAME}-{i}"))
        .build()
        .map_err(|e| std::io::Error::other(format!("cannot start the worker threads: {e}")))?;
    let chunk = CHUNK_PER_THREAD * pool.current_num_threads();
    for files in sources.chunks(chunk) {
        let outcomes: Vec<Vec<Outcome>> = pool.install(|| {
            files
                .par_iter()
                .map(|source| {
                    // `scan_file` catches its own panics; this backstop covers whatever else a
                    // caller's `per_file` does (a cache lookup), so one file never ends the scan.
                    let outcomes = caught(|| per_file(source)).unwrap_or_else(|panic| {
                        vec![Outcome {
                            row: Row::error(
                                &source.display,
                                source.format,
                                &format!("internal error: {panic} - please report this file"),
                                0.0,
                            ),
                            ..Outcome::default()
                        }]
                    });
                    progress(outcomes.len());
                    outcomes
                })
                .collect()
        });
        for outcome in outcomes.into_iter().flatten() {
            emit(outcome)?;
        }
    }
    Ok(())
}

/// Reads and judges one file: its rows, sorted by mesh. Never panics (a panic inside is caught).
pub fn scan_file(source: &Source, settings: &Settings) -> Vec<Outcome> {
    scan_file_with(source, settings, Extras::default())
}

/// [`scan_file`], computing `extras` too.
pub fn scan_file_with(source: &Source, settings: &Settings, extras: Extras) -> Vec<Outcome> {
    let start = Instant::now();
    let error = |message: &str, start: Instant| {
        vec![Outcome {
            row: Row::error(&source.display, source.format, message, millis(start)),
            findings: Vec::new(),
            shells: Vec::new(),
            detail: None,
        }]
    };
    if let Some(message) = &source.error {
        return error(message, start);
    }
    let Some(format) = source.format else {
        return error(
            "not a mesh file: meshvet reads .obj .gltf .glb .stl .ply .off .3mf - rename it if it is one",
            start,
        );
    };
    match caught(|| judge(source, format, settings, extras)) {
        Ok(Ok(mut outcomes)) => {
            outcomes.sort_by(|a, b| a.row.mesh.cmp(&b.row.mesh));
            outcomes
        }
        Ok(Err(message)) => error(&message, start),
        Err(panic) => error(
            &format!("internal error while reading: {panic} - please report this file"),
            start,
        ),
    }
}

fn judge(
    source: &Source,
    format: Format,
    settings: &Settings,
    extras: Extras,
) -> Result<Vec<Outcome>, String> {
    let start = Instant::now();
    let context = ReadContext {
        root: source.root.to_path_buf(),
        limits: settings.limits.clone(),
    };
    // A repairing scan keeps what the writer of a copy needs, so the file is read once.
    let repairing = settings.repair_dir.is_some();
    let (meshes, retained) = if repairing {
        formats::read_retaining(&source.path, format, &context).map_err(|e| e.to_string())?
    } else {
        let meshes = formats::read(&source.path, format, &context).map_err(|e| e.to_string())?;
        (meshes, None)
    };
    let read_millis = millis(start);
    if meshes.is_empty() {
        let mut row = Row::error(&source.display, Some(format), "", read_millis);
        row.status = Some(Status::Empty);
        row.message = "the file holds no meshes".to_owned();
        return Ok(vec![Outcome {
            row,
            findings: Vec::new(),
            shells: Vec::new(),
            detail: None,
        }]);
    }
    let options = settings.options();
    // ... and the weld and table of each mesh it will repair, for the repair planner.
    let mut built: Vec<Option<Built>> = Vec::new();
    let outcomes = meshes
        .iter()
        .map(|mesh| {
            let start = Instant::now();
            let (analysis, kept) = if repairing {
                let (analysis, kept) = analyse_keeping(mesh, &options);
                (analysis, Some(kept))
            } else {
                (analyse(mesh, &options), None)
            };
            let (status, findings) = if mesh.triangles.is_empty() {
                (Status::Empty, Vec::new())
            } else {
                let findings = rules::check(&analysis, &MeshFacts::of(mesh), &settings.severities);
                (Status::of(&findings), findings)
            };
            // A mesh without findings is not repaired: its table goes now.
            built.push(kept.filter(|_| !findings.is_empty()));
            let mut notes = mesh.notes.clone();
            if status == Status::Empty {
                notes.insert(0, "no triangles".to_owned());
            }
            let row = Row::analysed(
                &source.display,
                mesh.name.as_deref(),
                format,
                status,
                &analysis,
                &findings,
                &notes,
                mesh.mirrored_instances,
                read_millis + millis(start),
            );
            // A drawing that panics costs the picture, never the row.
            let detail = (extras.details && !mesh.triangles.is_empty()).then(|| {
                Box::new(Detail {
                    shells: analysis.shells.clone(),
                    picture: caught(|| picture::draw(&places(mesh, &options, &analysis)))
                        .ok()
                        .flatten(),
                })
            });
            Outcome {
                row,
                findings,
                shells: ShellRow::of(&analysis),
                detail,
            }
        })
        .collect::<Vec<Outcome>>();
    let mut outcomes = outcomes;
    if let Some(dir) = &settings.repair_dir {
        crate::copies::repair_file(
            dir,
            &source.display,
            &source.path,
            format,
            &context,
            &meshes,
            crate::copies::Kept { built, retained },
            &mut outcomes,
            settings,
            &crate::repair::plan_with,
        );
    }
    Ok(outcomes)
}

/// Milliseconds since `start`, to the microsecond.
fn millis(start: Instant) -> f64 {
    (start.elapsed().as_secs_f64() * 1e6).round() / 1e3
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::walk::{walk, Filter};
    use std::sync::atomic::{AtomicUsize, Ordering};

    #[test]
    fn a_panic_becomes_its_message() {
        let n = 3;
        assert_eq!(
            caught(|| panic!("index {n} out of range")),
            Err::<(), _>("index 3 out of range".into())
        );
        assert_eq!(caught(|| panic!("static")), Err::<(), _>("static".into()));
        assert_eq!(caught(|| 7), Ok(7));
    }

    #[test]
    fn every_file_reports_progress_and_rows_come_sorted() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_assets/rules");
        let sources = walk(&[root], &Filter::everything());
        let settings = Settings {
            jobs: 2,
            ..Settings::default()
        };
        let files = AtomicUsize::new(0);
        let rows = AtomicUsize::new(0);
        let progress = |n: usize| {
            files.fetch_add(1, Ordering::Relaxed);
            rows.fetch_add(n, Ordering::Relaxed);
        };
        let mut paths = Vec::new();
        scan(&sources, &settings, &progress, |o| {
            paths.push((o.row.path, o.row.mesh));
            Ok::<(), std::io::Error>(())
        })
        .unwrap();
        assert_eq!(files.into_inner(), sources.len());
        assert_eq!(rows.into_inner(), paths.len());
        assert!(paths.windows(2).all(|w| w[0] <= w[1]), "{paths:?}");
    }
}
