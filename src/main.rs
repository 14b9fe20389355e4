//! The `meshvet` process: parses the command line, resolves the config, drives the scan with a
//! progress bar, writes the CSV, prints the summary and decides the exit code
//! ([definitions](meshvet::definitions#exit-codes)).
//! Everything else lives in the library, which never prints.

mod cli;
mod outputs;

use std::io::{IsTerminal, Write};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Instant, SystemTime};

use clap::{CommandFactory, FromArgMatches};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use cli::{Cli, Command, Format};
use meshvet::baseline::Baseline;
use meshvet::cache::Cache;
use meshvet::config;
use meshvet::html::{self, HtmlReport};
use meshvet::report::Outcome;
use meshvet::rules::{Severity, Status};
use meshvet::scan;
use meshvet::shard;
use meshvet::walk::{self, Source};

/// Large blocks on huge pages: far fewer page faults for a big mesh's arrays.
#[global_allocator]
static ALLOCATOR: meshvet::pages::HugePages = meshvet::pages::HugePages;

/// The command was wrong (bad flag, config or path).
const USAGE: u8 = 2;

fn main() -> ExitCode {
    meshvet::pages::keep_freed_memory();
    // The formats come from the library's registry, so `--help` lists what this build reads.
    let formats = format!(
        "Reads {} (any case).",
        meshvet::formats::Format::extension_list()
    );
    let command = Cli::command().mut_subcommand("scan", |scan| scan.after_help(formats));
    let matches = command
        .clone()
        .try_get_matches()
        .unwrap_or_else(|e| exit_with_suggestion(&command, e));
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    match cli.command {
        Command::Scan(args) => match run_scan(&args) {
            Ok(code) => code,
            Err(message) => {
                // Line by line: a message may have lines of its own (what to do next).
                let lines: Vec<_> = message.lines().map(outputs::printable).collect();
                eprintln!("meshvet: {}", lines.join("\n"));
                ExitCode::from(USAGE)
            }
        },
        Command::Config(args) => {
            if args.default {
                print!("{}", config::DEFAULT_TOML);
                return ExitCode::SUCCESS;
            }
            let found = std::env::current_dir()
                .ok()
                .and_then(|cwd| config::discover(&cwd));
            match found {
                Some(path) => println!("{}", path.display()),
                None => println!(
                    "no {} here or above: a scan uses the built-in defaults (meshvet config --default prints them)",
                    config::FILE_NAME
                ),
            }
            ExitCode::SUCCESS
        }
        Command::Merge(args) => {
            let target = cli::target(&args.csv);
            match shard::merge(&args.reports, &target) {
                Ok(_) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("meshvet merge: {e}");
                    ExitCode::from(USAGE)
                }
            }
        }
    }
}

/// Exits with clap's error, adding the closest flag when an unknown `--flag` is a typo of one
/// (clap suggests only where no positional value could be meant, and `scan` takes paths).
fn exit_with_suggestion(command: &clap::Command, e: clap::Error) -> ! {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    let typed = match (e.kind(), e.get(ContextKind::InvalidArg)) {
        (ErrorKind::UnknownArgument, Some(ContextValue::String(arg))) => arg.clone(),
        _ => e.exit(),
    };
    let Some(typo) = typed.strip_prefix("--") else {
        e.exit()
    };
    let typo = typo.split('=').next().unwrap_or(typo);
    // The flags of the subcommand named on the command line, else the top level's.
    let words: Vec<String> = std::env::args().skip(1).collect();
    let sub = command
        .get_subcommands()
        .find(|c| words.iter().any(|w| w == c.get_name()))
        .unwrap_or(command);
    let longs: Vec<&str> = sub.get_arguments().filter_map(|a| a.get_long()).collect();
    match config::suggest(typo, &longs) {
        Some(known) => {
            // Clap's own tip (`-- --cvs` to pass it as a path) is not what a typo needs.
            let text = e.render().to_string();
            let mut lines: Vec<String> = text
                .lines()
                .filter(|l| !l.trim_start().starts_with("tip: to pass"))
                .map(str::to_owned)
                .collect();
            let at = lines.iter().position(|l| l.is_empty()).unwrap_or(1);
            lines.insert(
                at + 1,
                format!("  tip: a similar argument exists: '--{known}'"),
            );
            eprintln!("{}", lines.join("\n"));
            std::process::exit(USAGE.into())
        }
        None => e.exit(),
    }
}

/// Panics inside the scan threads are caught and reported as `error` rows; keep their text off the
/// terminal. Panics anywhere else are real crashes and print as usual.
fn install_quiet_panic_hook() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let name = std::thread::current().name().map(str::to_owned);
        if !name.is_some_and(|n| n.starts_with(scan::THREAD_NAME)) {
            default(info);
        }
    }));
}

/// Tallies rows by status and keeps one line per failing mesh.
#[derive(Default)]
struct Summary {
    rows: usize,
    pass: usize,
    warn: usize,
    fail: usize,
    error: usize,
    empty: usize,
    failures: Vec<String>,
}

impl Summary {
    fn add(&mut self, outcome: &Outcome) {
        let row = &outcome.row;
        self.rows += 1;
        let status = row.status.unwrap_or(Status::Error);
        *match status {
            Status::Pass => &mut self.pass,
            Status::Warn => &mut self.warn,
            Status::Fail => &mut self.fail,
            Status::Error => &mut self.error,
            Status::Empty => &mut self.empty,
        } += 1;
        if !status.is_failure() {
            return;
        }
        let mut line = row.path.clone();
        if !row.mesh.is_empty() {
            line = format!("{line}#{}", row.mesh);
        }
        if status == Status::Error {
            line = format!("{line}: error: {}", row.message);
        } else {
            const SHOWN: usize = 3;
            let mut worst: Vec<String> = outcome
                .findings
                .iter()
                .filter(|f| f.severity == Severity::Error)
                .map(|f| format!("error {}: {}", f.rule, f.message))
                .collect();
            if worst.is_empty() {
                // A failure always has an error finding; should one ever not, still say something.
                worst.push(format!("{status:?}").to_lowercase());
            }
            line = format!("{line}: {}", worst[..worst.len().min(SHOWN)].join("; "));
            if worst.len() > SHOWN {
                line = format!("{line} (+{} more)", worst.len() - SHOWN);
            }
        }
        self.failures.push(line);
    }

    fn line(&self, seconds: f64) -> String {
        let meshes = if self.rows == 1 { "mesh" } else { "meshes" };
        let mut line = format!(
            "{} {meshes}: {} pass, {} warn, {} fail, {} error",
            self.rows, self.pass, self.warn, self.fail, self.error
        );
        if self.empty > 0 {
            line = format!("{line}, {} empty", self.empty);
        }
        if seconds < 1.0 {
            format!("{line} in {:.0} ms", seconds * 1e3)
        } else {
            format!("{line} in {seconds:.1} s")
        }
    }
}

fn run_scan(args: &cli::Scan) -> Result<ExitCode, String> {
    let started = Instant::now();
    install_quiet_panic_hook();
    let cwd =
        std::env::current_dir().map_err(|e| format!("cannot tell the current folder: {e}"))?;
    let (mut settings, config_file) =
        config::resolve(args.config.as_deref(), &cwd, &args.config_layer()).map_err(|e| {
            format!(
                "bad config: {e}\nfix the config: `meshvet config --default` prints every key and \
                 rule with its default and what it does"
            )
        })?;
    let config_name = config_file.as_ref().map_or_else(
        || "built-in defaults".to_owned(),
        |p| p.display().to_string(),
    );
    let filter = walk::Filter::new(&settings.include, &settings.exclude).map_err(|e| {
        let from = config_file
            .as_ref()
            .map_or_else(|| "the config".to_owned(), |p| p.display().to_string());
        format!("bad include/exclude in {from}: {e}")
    })?;
    for path in &args.paths {
        if std::fs::symlink_metadata(path).is_err() {
            return Err(format!(
                "no such file or folder: {} - check the path",
                path.display()
            ));
        }
    }

    // A repair folder that holds a scanned path would hide every source: refused before anything
    // is created or walked. (A folder that does not exist yet holds nothing.)
    if let Some(dir) = &args.repair_dir {
        if let Ok(real) = dir.canonicalize() {
            if let Some(inside) = args
                .paths
                .iter()
                .find(|p| p.canonicalize().is_ok_and(|p| p.starts_with(&real)))
            {
                return Err(format!(
                    "the repair folder {} holds the scanned path {}: copies would be scanned as \
                     sources - choose a repair folder outside it",
                    dir.display(),
                    inside.display()
                ));
            }
        }
    }
    if let Some(root) = &args.root {
        let real = root
            .canonicalize()
            .ok()
            .filter(|r| r.is_dir())
            .ok_or_else(|| format!("--root {}: no such folder - check the path", root.display()))?;
        if let Some(outside) = args
            .paths
            .iter()
            .find(|p| !p.canonicalize().is_ok_and(|p| p.starts_with(&real)))
        {
            return Err(format!(
                "{} is not inside --root {}: name a root that holds every scanned path",
                outside.display(),
                root.display()
            ));
        }
    }
    let mut sources = walk::walk_within(&args.paths, &filter, args.root.as_deref());
    outputs::refuse_reports_over_inputs(args, &sources, config_file.as_deref())?;
    if let Some(dir) = &args.repair_dir {
        if std::fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
            return Err(format!(
                "the repair folder {} is a file, not a folder - name a folder (it is created if \
                 it does not exist)",
                dir.display()
            ));
        }
        std::fs::create_dir_all(dir).map_err(|e| {
            format!(
                "cannot create the repair folder {}: {e} - check the path and that its parent \
                 can be written",
                dir.display()
            )
        })?;
        // Copies written in an earlier run are not scanned as sources, nor anything else in the
        // repair folder (its copies would be copied into it again); files meshvet did not put
        // there are counted, so that leaving them out is said.
        let real = dir
            .canonicalize()
            .map_err(|e| format!("{}: {e}", dir.display()))?;
        let mut not_copies = 0usize;
        sources.retain(|s| {
            let Some(inside) = s.path.canonicalize().ok().filter(|p| p.starts_with(&real)) else {
                return true;
            };
            // Each shard counts its own.
            let in_shard = args.shard.as_ref().is_none_or(|k| k.contains(&s.display));
            if in_shard && !meshvet::copies::ledger::lists(&real, &inside) {
                not_copies += 1;
            }
            false
        });
        if not_copies > 0 && !args.quiet {
            eprintln!(
                "meshvet: not scanned: {not_copies} mesh file(s) inside the repair folder {} that \
                 meshvet did not write - move them out of the repair folder to scan them",
                dir.display()
            );
        }
        settings.repair_dir = Some(dir.clone());
    }
    if let Some(shard) = &args.shard {
        sources.retain(|s| shard.contains(&s.display));
    }
    let mut baseline = args.baseline.as_deref().map(Baseline::read).transpose()?;
    // Pictures for the HTML report are not cached, and a cached row would skip writing the
    // repaired copy: with --html or --repair-dir every file is read and the cache is left alone.
    let cache_unused = args.cache.is_some() && (args.html.is_some() || args.repair_dir.is_some());
    let cache = match &args.cache {
        Some(dir) if !cache_unused => Some(Cache::open(dir, &settings).map_err(|e| {
            format!(
                "cannot use the cache folder {}: {e} - check that it can be created and written",
                dir.display()
            )
        })?),
        _ => None,
    };
    let mut reports = outputs::Reports::create(args)?;
    let reports_on_stdout = reports.uses_stdout(args);
    let lines_format = args.format == Format::Lines;

    let bar = if args.quiet || lines_format || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        ProgressBar::with_draw_target(Some(sources.len() as u64), ProgressDrawTarget::stderr())
            .with_style(
                ProgressStyle::with_template("{bar:30} {pos}/{len} files  {msg}  ETA {eta}")
                    .expect("the template is valid"),
            )
    };
    let meshes = AtomicUsize::new(0);
    let progress = |rows: usize| {
        let done = meshes.fetch_add(rows, Ordering::Relaxed) + rows;
        let seconds = started.elapsed().as_secs_f64().max(1e-3);
        bar.set_message(format!("{:.0} meshes/s", done as f64 / seconds));
        bar.inc(1);
    };

    let mut summary = Summary::default();
    let mut html = args.html.as_ref().map(|_| HtmlReport::new());
    let extras = scan::Extras {
        details: html.is_some(),
    };
    let per_file = |source: &Source| {
        let fresh = || scan::scan_file_with(source, &settings, extras);
        match &cache {
            Some(cache) => cache.outcomes(source, fresh),
            None => fresh(),
        }
    };
    let mut finding_lines = Vec::new();
    let written = scan::scan_each(&sources, settings.jobs, &per_file, &progress, |outcome| {
        summary.add(&outcome);
        let written = reports.write(&outcome);
        if let Some(b) = &mut baseline {
            b.compare(&outcome);
        }
        if lines_format {
            finding_lines.extend(outputs::finding_lines(&outcome));
        }
        if let Some(h) = &mut html {
            h.add(outcome);
        }
        written
    });
    bar.finish_and_clear();
    // Written out (and compacted) before anything can fail: the entries are this run's work.
    let cache = cache.map(|cache| {
        let stats = cache.stats();
        (stats, cache.finish().err())
    });
    written.map_err(|e| e.to_string())?;
    let mut page = None;
    if let Some(report) = &mut html {
        if let (Some(b), Some(name)) = (&baseline, &args.baseline) {
            report.set_baseline(html::Baseline {
                name: name.display().to_string(),
                worse: b.worse.clone(),
                better: b.better.clone(),
            });
        }
        let meta = html::Meta {
            roots: args.paths.iter().map(|p| p.display().to_string()).collect(),
            config: config_name,
            version: env!("CARGO_PKG_VERSION").to_owned(),
            started: SystemTime::now() - started.elapsed(),
            seconds: started.elapsed().as_secs_f64(),
            files: sources.len(),
        };
        page = Some(report.render(&meta));
    }
    reports.finish(started.elapsed(), page)?;

    // The summary goes to standard output unless a report does.
    let mut out: Box<dyn Write> = if reports_on_stdout {
        Box::new(std::io::stderr())
    } else {
        Box::new(std::io::stdout())
    };
    let mut lines = Vec::new();
    if lines_format {
        // Errors first, each severity in report order (the sort is stable).
        finding_lines.sort_by_key(|(severity, _)| std::cmp::Reverse(*severity));
        lines.extend(finding_lines.into_iter().map(|(_, line)| line));
    } else {
        if sources.is_empty() && !args.quiet {
            eprintln!(
                "meshvet: no mesh files found ({})",
                meshvet::formats::Format::extension_list()
            );
        }
        if !args.quiet {
            lines.push(summary.line(started.elapsed().as_secs_f64()));
            if let (Some((stats, unsaved)), Some(dir)) = (&cache, &args.cache) {
                let mut line = format!(
                    "cache {}: {} files reused, {} read",
                    dir.display(),
                    stats.hits,
                    stats.misses
                );
                if stats.write_errors > 0 {
                    line = format!(
                        "{line} ({} entries could not be written)",
                        stats.write_errors
                    );
                }
                if let Some(e) = unsaved {
                    line = format!("{line} (not all saved: {e})");
                }
                lines.push(line);
            }
            if let (true, Some(dir)) = (cache_unused, &args.cache) {
                lines.push(format!(
                    "cache {}: not used: --html and --repair-dir read every file",
                    dir.display()
                ));
            }
        }
        lines.extend(summary.failures.iter().cloned());
    }
    if let (Some(b), Some(name)) = (&baseline, &args.baseline) {
        if !lines_format || !b.worse.is_empty() {
            lines.push(format!(
                "since {}: {} got worse, {} got better",
                name.display(),
                b.worse.len(),
                b.better.len()
            ));
        }
        lines.extend(b.worse.iter().map(|c| format!("worse: {}", c.line())));
    }
    for line in lines {
        // A closed pipe (`| head`) is not worth a panic.
        if writeln!(out, "{}", outputs::printable(&line)).is_err() {
            break;
        }
    }
    let failed = match (&baseline, args.fail_on_regression) {
        (Some(b), true) => !b.worse.is_empty(),
        _ => summary.fail + summary.error > 0,
    };
    Ok(if failed {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
