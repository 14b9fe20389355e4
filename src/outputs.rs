//! The scan's report files (CSV, JSON Lines, JUnit), opened before the scan so a bad path fails
//! at once, fed every outcome in report order and put in place together at the end; and the
//! one-line-per-finding output of `--format lines` (pre-commit hooks).

use std::io;
use std::time::Duration;

use meshvet::json::JsonReport;
use meshvet::junit::JunitReport;
use meshvet::report::Outcome;
use meshvet::report::{CsvReport, Target};
use meshvet::rules::{Severity, Status};

use crate::cli::{self, Scan};
use meshvet::walk::Source;

/// The report files a scan writes.
pub struct Reports {
    csv: Option<(Target, CsvReport)>,
    json: Option<(Target, JsonReport)>,
    junit: Option<(Target, JunitReport)>,
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
        let [csv, json, junit] =
            [&args.csv, &args.json, &args.junit].map(|p| p.as_deref().map(cli::target));
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

    /// Puts every report in place; `time` is the scan's wall time (for JUnit).
    pub fn finish(self, time: Duration) -> Result<(), String> {
        if let Some((t, r)) = self.csv {
            r.finish().map_err(|e| cannot_write(&t, &e))?;
        }
        if let Some((t, r)) = self.json {
            r.finish().map_err(|e| cannot_write(&t, &e))?;
        }
        if let Some((t, r)) = self.junit {
            r.finish(time).map_err(|e| cannot_write(&t, &e))?;
        }
        Ok(())
    }
}

/// Refuses, before anything is written, a report that would be put in place of a file the scan
/// reads (`--csv models/part.obj` would replace the mesh with the CSV: sources are never
/// written) or in place of another report. Each report is compared by its real path with the
/// sources of the same file name, so a scan of a million files costs nothing more.
pub fn refuse_reports_over_sources(args: &Scan, sources: &[Source]) -> Result<(), String> {
    let flags = [
        ("--csv", &args.csv),
        ("--json", &args.json),
        ("--junit", &args.junit),
        ("--html", &args.html),
    ];
    let mut seen: Vec<(&str, std::path::PathBuf)> = Vec::new();
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
        let name = real.file_name();
        if let Some(source) = sources
            .iter()
            .find(|s| s.path.file_name() == name && s.path.canonicalize().is_ok_and(|p| p == real))
        {
            return Err(format!(
                "{flag} {} is a file this scan reads ({}): the report would replace it - \
                 write the report outside the scanned files or under another name",
                path.display(),
                source.display
            ));
        }
        seen.push((flag, real));
    }
    Ok(())
}

/// The real path of `path`, or of its folder joined with its name when it does not exist yet;
/// `None` when neither can be told (the report's own error then comes when it is opened).
fn real_path(path: &std::path::Path) -> Option<std::path::PathBuf> {
    path.canonicalize().ok().or_else(|| {
        let folder = path.parent().filter(|p| !p.as_os_str().is_empty());
        let folder = folder.unwrap_or(std::path::Path::new("."));
        Some(folder.canonicalize().ok()?.join(path.file_name()?))
    })
}

pub fn cannot_write(target: &Target, e: &io::Error) -> String {
    match target {
        Target::Stdout => format!("cannot write the report to standard output: {e}"),
        Target::File(p) => format!(
            "cannot write the report {}: {e} - check that its folder exists and is writable",
            p.display()
        ),
    }
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
