//! The per-file pipeline, run on many files in parallel: read -> judge (analyse, rules) -> repair
//! (when asked) -> report rows.
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
use crate::copies::{self, Repaired};
use crate::formats::{self, Format, ReadContext};
use crate::judge::{judge, judge_releasing, Judged};
use crate::mesh::Mesh;
use crate::picture;
use crate::report::{Detail, Outcome, RepairDone, Row, ShellRow};
use crate::rules::Status;
use crate::topology::places;
use crate::walk::Source;

/// Files per chunk for each worker thread. Rows are small, so a chunk costs little memory; a large
/// chunk keeps threads busy when one file in it is slow (the chunk ends when its slowest file does).
const CHUNK_PER_THREAD: usize = 256;

/// Prefix of the scan threads' names: a panic hook can recognise panics that will be caught.
pub const THREAD_NAME: &str = "meshvet-scan";

/// What to compute beyond the report rows. The default (nothing) is what a plain scan pays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Extras {
    /// Fill [`Outcome::detail`]: the per-shell table and a picture (for the HTML report).
    pub details: bool,
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
        .num_threads(pool_size(jobs, sources.len(), cores()))
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

/// The cores this process may use.
fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

/// Threads for a scan of `files` files asked to use `jobs` (0: one per core): never more than
/// [`MAX_THREADS_PER_CORE`] per core (more only wait for each other: 100,000 threads on three
/// files ran for minutes), and never more than there are files, but for one thread per core,
/// which a big mesh uses inside its own analysis.
pub fn pool_size(jobs: usize, files: usize, cores: usize) -> usize {
    let cores = cores.max(1);
    let asked = if jobs == 0 { cores } else { jobs };
    asked
        .min(MAX_THREADS_PER_CORE * cores)
        .min(files.max(cores))
}

/// The most threads per core [`pool_size`] gives (threads waiting on slow disks can help a
/// little beyond one per core).
pub const MAX_THREADS_PER_CORE: usize = 4;

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
            ..Outcome::default()
        }]
    };
    if let Some(message) = &source.error {
        return error(message, start);
    }
    let Some(format) = source.format else {
        return error(
            &format!(
                "not a mesh file: meshvet reads {} - rename it if it is one",
                Format::extension_list()
            ),
            start,
        );
    };
    match caught(|| read_and_judge(source, format, settings, extras)) {
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

/// Reads one file and judges its meshes; with a repair folder, repairs them too. Only here are
/// rows assembled.
fn read_and_judge(
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
    let (mut meshes, retained) = if repairing {
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
            ..Outcome::default()
        }]);
    }
    let mut judged = Vec::with_capacity(meshes.len());
    let mut details = Vec::with_capacity(meshes.len());
    let mut took = Vec::with_capacity(meshes.len());
    for mesh in &mut meshes {
        let start = Instant::now();
        let has_faces = !mesh.triangles.is_empty();
        // Only the repair stage reads a mesh's positions and faces again: without it they are
        // freed before the search, where a big mesh's analysis needs the most memory.
        let mut verdict = if repairing {
            judge(mesh, settings)
        } else {
            judge_releasing(mesh, settings)
        };
        // A drawing that panics costs the picture, never the row.
        let detail = (extras.details && has_faces).then(|| {
            let picture = verdict.built.as_ref().and_then(|built| {
                caught(|| picture::draw(&places(built, &verdict.analysis)))
                    .ok()
                    .flatten()
            });
            Box::new(Detail {
                shells: verdict.analysis.shells.clone(),
                picture,
            })
        });
        // Only a mesh the repair stage will plan keeps its table.
        if !repairing || verdict.findings.is_empty() {
            verdict.built = None;
        }
        took.push(read_millis + millis(start));
        judged.push(verdict);
        details.push(detail);
    }
    let repaired = match &settings.repair_dir {
        Some(dir) => copies::repair_file(
            dir,
            &source.report_path,
            &source.path,
            format,
            &context,
            &meshes,
            &mut judged,
            retained,
            settings,
            &crate::repair::plan_with,
        ),
        None => vec![Repaired::default(); meshes.len()],
    };
    let outcomes = meshes
        .iter()
        .zip(judged)
        .zip(details)
        .zip(repaired)
        .zip(took)
        .map(|((((mesh, judged), detail), repaired), millis)| {
            let mut outcome = outcome(&source.display, format, mesh, judged, &repaired, millis);
            outcome.detail = detail;
            outcome
        })
        .collect();
    Ok(outcomes)
}

/// The report of one mesh of the file reported as `display`: what judging it found and, after a
/// repair, what the repair stage did (`Repaired::default()` when there was none); `millis` is the
/// time it took.
pub fn outcome(
    display: &str,
    format: Format,
    mesh: &Mesh,
    judged: Judged,
    repaired: &Repaired,
    millis: f64,
) -> Outcome {
    let mut notes = Vec::with_capacity(mesh.notes.len() + repaired.notes.len() + 1);
    if judged.status == Status::Empty {
        notes.push("no triangles".to_owned());
    }
    notes.extend(mesh.notes.iter().cloned());
    let overlapping = judged.analysis.overlapping_shells();
    if overlapping > 0 {
        notes.push(format!(
            "volume counts the space where shells overlap twice ({overlapping} pair{} of shells meet)",
            if overlapping == 1 { "" } else { "s" }
        ));
    }
    if judged
        .analysis
        .intersections
        .as_ref()
        .is_some_and(|i| i.stopped)
    {
        notes.push(
            "the search for faces that meet stopped at its budget (a pile of overlapping faces or \
             parts): its counts are lower bounds; raise `[intersections] pair_budget` to finish it"
                .to_owned(),
        );
    }
    notes.extend(repaired.notes.iter().cloned());
    let mut row = Row::analysed(
        display,
        mesh.name.as_deref(),
        format,
        judged.status,
        &judged.analysis,
        &judged.findings,
        &notes,
        mesh.mirrored_instances,
        millis,
    );
    let mut outcome = Outcome::default();
    if let Some(copy) = &repaired.copy {
        row.repaired_path = copy.path.clone();
        row.repairs = copy.repairs.clone();
        row.status_after = copy.status.to_string();
        row.findings_after = crate::report::findings_cell(&copy.findings);
        outcome.repairs = copy
            .done
            .iter()
            .map(|&(repair, count, faces)| RepairDone {
                repair,
                count,
                faces,
            })
            .collect();
        outcome.findings_after = copy.findings.clone();
    }
    Outcome {
        row,
        shells: ShellRow::of(&judged.analysis),
        findings: judged.findings,
        ..outcome
    }
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

    /// Asked for 100,000 threads on 3 files with 2 cores: 3 (the files); on 50 files: 8 (4 per
    /// core); one file still gets a thread per core; 0 is one per core, capped the same way.
    #[test]
    fn the_pool_is_capped_at_what_can_help() {
        assert_eq!(pool_size(100_000, 3, 2), 3);
        assert_eq!(pool_size(100_000, 50, 2), 8);
        assert_eq!(pool_size(100_000, 1, 2), 2);
        assert_eq!(pool_size(0, 1000, 2), 2);
        assert_eq!(pool_size(3, 1000, 2), 3);
        assert_eq!(pool_size(1, 1000, 16), 1);
        assert_eq!(pool_size(0, 0, 0), 1);
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
