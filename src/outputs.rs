//! The scan's report files (CSV, JSON Lines, JUnit), opened before the scan so a bad path fails
//! at once, fed every outcome in report order and put in place together at the end; and the
//! one-line-per-finding output of `--format lines` (pre-commit hooks).

use std::collections::HashSet;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use meshvet::json::JsonReport;
use meshvet::junit::JunitReport;
use meshvet::report::Outcome;
use meshvet::report::{CsvReport, Output, Target};
use meshvet::rules::{Severity, Status};

use crate::cli::{self, Scan};
use meshvet::walk::Source;

/// The report files a scan writes.
pub struct Reports {
    csv: Option<(Target, CsvReport)>,
    json: Option<(Target, JsonReport)>,
    junit: Option<(Target, JunitReport)>,
    /// The HTML page's output, opened with the others; the page is written at the end.
    html: Option<(Target, Output)>,
}

impl Reports {
    /// Opens every report the flags ask for. At most one report may go to standard output, and
    /// none when `--format lines` prints its lines there.
    pub fn create(args: &Scan) -> Result<Reports, String> {
        let flags = ["--csv", "--json", "--junit", "--html"];
        let on_stdout: Vec<&str> = [&args.csv, &args.json, &args.junit, &args.html]
            .iter()
            .zip(flags)
            .filter(|(p, _)| p.as_deref().map(cli::target) == Some(Target::Stdout))
            .map(|(_, flag)| flag)
            .collect();
        if on_stdout.len() > 1 {
            return Err(format!(
                "{} write to standard output (`-`): only one report can; send the others to files",
                on_stdout.join(" and ")
            ));
        }
        if let (Some(flag), cli::Format::Lines) = (on_stdout.first(), args.format) {
            return Err(format!(
                "--format lines prints its lines on standard output, so {flag} - cannot write there \
                 too: give {flag} a file"
            ));
        }
        let [csv, json, junit, html] =
            [&args.csv, &args.json, &args.junit, &args.html].map(|p| p.as_deref().map(cli::target));
        fn open<R>(
            target: Option<Target>,
            create: impl Fn(&Target) -> io::Result<R>,
        ) -> Result<Option<(Target, R)>, String> {
            target
                .map(|t| {
                    create(&t)
                        .map(|r| (t.clone(), r))
                        .map_err(|e| cannot_write(&t, &e))
                })
                .transpose()
        }
        Ok(Reports {
            csv: open(csv, CsvReport::create)?,
            json: open(json, JsonReport::create)?,
            junit: open(junit, JunitReport::create)?,
            html: open(html, Output::create)?,
        })
    }

    /// Whether a report goes to standard output (then the summary goes to standard error).
    pub fn uses_stdout(&self, args: &Scan) -> bool {
        let csv = self.csv.as_ref().map(|(t, _)| t);
        let json = self.json.as_ref().map(|(t, _)| t);
        let junit = self.junit.as_ref().map(|(t, _)| t);
        let html = args.html.as_deref().map(cli::target);
        [csv, json, junit, html.as_ref()].contains(&Some(&Target::Stdout))
    }

    /// Adds one outcome to every report. The error names the report.
    pub fn write(&mut self, outcome: &Outcome) -> io::Result<()> {
        fn named(t: &Target) -> impl Fn(io::Error) -> io::Error + '_ {
            move |e| io::Error::other(cannot_write(t, &e))
        }
        if let Some((t, r)) = &mut self.csv {
            r.write(&outcome.row).map_err(named(t))?;
        }
        if let Some((t, r)) = &mut self.json {
            r.write(outcome).map_err(named(t))?;
        }
        if let Some((t, r)) = &mut self.junit {
            r.write(outcome).map_err(named(t))?;
        }
        Ok(())
    }

    /// Puts every report in place together: each is written out and flushed to the disk first,
    /// and only when all of them are does any replace its target (a full disk or a failing write
    /// leaves every earlier report as it was). `time` is the scan's wall time (for JUnit); `page`
    /// the HTML page, when `--html` asked for one.
    pub fn finish(self, time: Duration, page: Option<String>) -> Result<(), String> {
        let mut ready: Vec<(Target, io::Result<Output>)> = Vec::new();
        if let Some((t, r)) = self.csv {
            ready.push((t, r.into_output()));
        }
        if let Some((t, r)) = self.json {
            ready.push((t, Ok(r.into_output())));
        }
        if let Some((t, r)) = self.junit {
            ready.push((t, r.into_output(time)));
        }
        if let Some((t, mut out)) = self.html {
            let written = out.write_all(page.unwrap_or_default().as_bytes());
            ready.push((t, written.map(|()| out)));
        }
        let mut outputs = Vec::with_capacity(ready.len());
        for (t, out) in ready {
            let out = out.and_then(|mut out| out.prepare().map(|()| out));
            outputs.push((out.map_err(|e| cannot_write(&t, &e))?, t));
        }
        for (out, t) in outputs {
            out.finish().map_err(|e| cannot_write(&t, &e))?;
        }
        Ok(())
    }
}

/// Refuses, before anything is written, a report that would be put in place of a file the scan
/// reads, or in place of another report. Sources are never written: `--csv models/part.obj`
/// would replace the mesh with the CSV, `--csv buffers/part.bin` the buffer a glTF reads, and
/// `--junit meshvet.toml` the config. A report may replace
/// - a file outside every scanned tree (the scan reads none there) but the config in use
///   (`config`) and the cache's own files;
/// - inside a scanned tree, only a file that is a meshvet report already (or empty), since any
///   other file there may be a buffer, material library or texture a model names.
///
/// Each report is compared by its real path with the sources of the same file name and with the
/// paths named on the command line (a link there may have any name), so a scan of a million
/// files costs nothing more; the trees are looked at only for a report that exists.
pub fn refuse_reports_over_inputs(
    args: &Scan,
    sources: &[Source],
    config: Option<&Path>,
) -> Result<(), String> {
    let flags = [
        ("--csv", &args.csv),
        ("--json", &args.json),
        ("--junit", &args.junit),
        ("--html", &args.html),
    ];
    let config = config.and_then(|c| c.canonicalize().ok());
    let cache = args.cache.as_deref().and_then(|c| c.canonicalize().ok());
    let mut trees: Option<Vec<PathBuf>> = None;
    let mut seen: Vec<(&str, PathBuf)> = Vec::new();
    for (flag, path) in flags {
        let Some(path) = path.as_deref().filter(|p| cli::target(p) != Target::Stdout) else {
            continue;
        };
        let Some(real) = real_path(path) else {
            continue;
        };
        if let Some((other, _)) = seen.iter().find(|(_, p)| *p == real) {
            return Err(format!(
                "{other} and {flag} name the same file {}: give each report its own file",
                path.display()
            ));
        }
        // A walked file is never a link, so its real name is its own; a path named on the
        // command line may be a link of any name.
        let name = real.file_name();
        let read = sources
            .iter()
            .find(|s| s.path.file_name() == name && s.path.canonicalize().is_ok_and(|p| p == real))
            .map(|s| s.display.clone())
            .or_else(|| {
                args.paths
                    .iter()
                    .find(|p| p.canonicalize().is_ok_and(|p| p == real))
                    .map(|p| p.display().to_string())
            });
        if let Some(source) = read {
            return Err(format!(
                "{flag} {} is a file this scan reads ({source}): the report would replace it - \
                 write the report outside the scanned files or under another name",
                path.display(),
            ));
        }
        if config.as_ref() == Some(&real) {
            return Err(format!(
                "{flag} {} is the config this scan reads: the report would replace it - write \
                 the report under another name",
                path.display()
            ));
        }
        if cache.as_deref().is_some_and(|c| real.parent() == Some(c)) {
            return Err(format!(
                "{flag} {} is in the cache folder, which holds meshvet's own files - write the \
                 report elsewhere",
                path.display()
            ));
        }
        if real.is_file() {
            let trees = trees.get_or_insert_with(|| scanned_trees(sources));
            if trees.iter().any(|t| real.starts_with(t)) && !is_report(&real) {
                return Err(format!(
                    "{flag} {} is a file inside the scanned tree that is not a meshvet report (a \
                     model may read it as a buffer, material or texture): the report would \
                     replace it - write the report elsewhere, or remove the file first if it is \
                     not needed",
                    path.display()
                ));
            }
        }
        seen.push((flag, real));
    }
    Ok(())
}

/// The real paths of the trees the sources' models may read files from (each source's
/// [`Source::root`]), each once.
fn scanned_trees(sources: &[Source]) -> Vec<PathBuf> {
    let roots: HashSet<&Path> = sources.iter().map(|s| &*s.root).collect();
    let mut trees: Vec<PathBuf> = roots
        .into_iter()
        .filter_map(|r| r.canonicalize().ok())
        .collect();
    trees.sort();
    trees.dedup();
    trees
}

/// Whether the file at `path` is empty or begins as one of meshvet's reports does (CSV, JSON
/// Lines, JUnit, HTML page): a file a report may replace inside a scanned tree.
fn is_report(path: &Path) -> bool {
    let mut head = Vec::new();
    let read =
        meshvet::formats::open_regular(path).and_then(|f| f.take(4096).read_to_end(&mut head));
    if read.is_err() {
        return false;
    }
    let text = head.strip_prefix("\u{feff}".as_bytes()).unwrap_or(&head);
    let holds = |needle: &[u8]| text.windows(needle.len()).any(|w| w == needle);
    text.is_empty()
        // The first columns every meshvet CSV and JSON Lines report has begun with (SPEC 9): a
        // table another tool wrote with a `path` column is not replaced.
        || text.starts_with(b"path,mesh,format,status,message,")
        || (text.starts_with(b"{\"path\":")
            && holds(b"\"mesh\":")
            && holds(b"\"format\":")
            && holds(b"\"status\":"))
        || (text.starts_with(b"<?xml") && holds(b"<testsuites name=\"meshvet\""))
        || (text.starts_with(b"<!DOCTYPE html>") && holds(b"<title>meshvet QA report"))
}

/// The real path of `path`, or of its folder joined with its name when it does not exist yet;
/// `None` when neither can be told (the report's own error then comes when it is opened).
fn real_path(path: &Path) -> Option<PathBuf> {
    path.canonicalize().ok().or_else(|| {
        let folder = path.parent().filter(|p| !p.as_os_str().is_empty());
        let folder = folder.unwrap_or(Path::new("."));
        Some(folder.canonicalize().ok()?.join(path.file_name()?))
    })
}

pub fn cannot_write(target: &Target, e: &io::Error) -> String {
    match target {
        Target::Stdout => format!("cannot write the report to standard output: {e}"),
        Target::File(p) if e.kind() == io::ErrorKind::IsADirectory => format!(
            "cannot write the report {}: {e} - name a file for it",
            p.display()
        ),
        Target::File(p) => format!(
            "cannot write the report {}: {e} - check that its folder exists and is writable",
            p.display()
        ),
    }
}

/// `line` as the terminal shows it: control characters (a file or mesh name may hold an escape
/// sequence that recolours or rewrites the terminal, or a line feed that splits one finding's
/// line in two for a hook reading them) written as `\x1b`-style escapes, and the directional
/// formatting characters ([`is_bidi`]) as `\u{202e}`-style ones. The CSV and JSON reports keep
/// names as they are (each in its own quoting); JUnit escapes what XML cannot hold
/// ([`crate::junit`]).
pub fn printable(line: &str) -> std::borrow::Cow<'_, str> {
    if !line.chars().any(|c| c.is_control() || is_bidi(c)) {
        return line.into();
    }
    let mut out = String::with_capacity(line.len() + 8);
    for c in line.chars() {
        if c.is_control() {
            out.push_str(&format!("\\x{:02x}", u32::from(c)));
        } else if is_bidi(c) {
            out.push_str(&format!("\\u{{{:04x}}}", u32::from(c)));
        } else {
            out.push(c);
        }
    }
    out.into()
}

/// Unicode's directional formatting characters (marks, embeddings, overrides, isolates): in a
/// name they reorder what the terminal shows after them (`part\u{202e}lts.exe` shows as
/// `partexe.stl`), so they are written as `\u{202e}`-style escapes too.
fn is_bidi(c: char) -> bool {
    matches!(c, '\u{061c}' | '\u{200e}' | '\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
}

/// The `--format lines` lines of one mesh with their severity (for sorting, errors first):
/// `path[#mesh]: severity rule: what the rule finds (count)` per finding, or
/// `path: error: message` for a file that could not be read. Pass and empty meshes give none.
pub fn finding_lines(outcome: &Outcome) -> Vec<(Severity, String)> {
    let row = &outcome.row;
    let name = if row.mesh.is_empty() {
        row.path.clone()
    } else {
        format!("{}#{}", row.path, row.mesh)
    };
    if row.status.unwrap_or(Status::Error) == Status::Error {
        return vec![(Severity::Error, format!("{name}: error: {}", row.message))];
    }
    outcome
        .findings
        .iter()
        .map(|f| {
            (
                f.severity,
                format!(
                    "{name}: {} {}: {} ({})",
                    f.severity,
                    f.rule,
                    f.rule.summary(),
                    f.count
                ),
            )
        })
        .collect()
}
