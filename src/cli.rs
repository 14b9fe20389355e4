//! The command line (clap derive). Flags that mean the same as a config key become a
//! [`Config`] layer, so they go through the one merge path in `config.rs`.

use std::path::PathBuf;

use clap::{Parser, Subcommand};

use meshvet::config::Config;
use meshvet::report::Target;
use meshvet::shard::Shard;

#[derive(Debug, Parser)]
#[command(
    name = "meshvet",
    version,
    about = "Vets 3D mesh files in bulk: topology checks and a CSV report"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

// Parsed once per run: the size difference between the variants costs nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Scan mesh files and report their topology.
    ///
    /// Exit code 0: no error-severity findings; 1: a mesh failed or a file could not be read;
    /// 2: the command or the config is wrong.
    Scan(Scan),

    /// Join the CSV reports of `scan --shard K/N` runs into one, sorted by path then mesh.
    ///
    /// Give the reports of all N shards of one scan: each report's rows must belong to one shard
    /// of N (the number of reports given), no two reports to the same shard or path. Exit code 0:
    /// merged; 2: a report is missing, malformed, of another version, or overlapping.
    Merge(Merge),

    /// Show which config a scan here would use, or print the documented default config.
    ///
    /// `meshvet config --default > meshvet.toml` starts a config of your own: every key with its
    /// default and what it does.
    Config(ConfigArgs),
}

#[derive(Debug, clap::Args)]
pub struct ConfigArgs {
    /// Print the default config, every key stated and explained.
    #[arg(long)]
    pub default: bool,
}

#[derive(Debug, clap::Args)]
pub struct Merge {
    /// The shard reports, all N (CSV files written by `meshvet scan --shard K/N --csv`).
    #[arg(required = true, value_name = "REPORT")]
    pub reports: Vec<PathBuf>,

    /// Write the merged CSV to FILE (`-`: standard output).
    #[arg(long, value_name = "FILE", required = true)]
    pub csv: PathBuf,
}

/// What `scan` prints on standard output (reports go to their own files).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Format {
    /// A summary line, then one line per failing mesh.
    #[default]
    Summary,
    /// One line per finding, `path[#mesh]: severity rule: what the rule finds (count)`, errors
    /// first, nothing else: for pre-commit hooks and editors.
    Lines,
}

#[derive(Debug, clap::Args)]
pub struct Scan {
    /// Folders (walked recursively) and files to scan. With several, report paths start with the
    /// PATH as written.
    #[arg(default_value = ".")]
    pub paths: Vec<PathBuf>,

    /// Write the CSV report to FILE (`-`: standard output).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,

    /// Also write a self-contained HTML QA report to FILE: summary charts, a sortable table of every
    /// mesh and a detail view with a picture of each.
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,

    /// The tree that files a model names (glTF buffers and images, OBJ material libraries) must
    /// stay inside. Default: each folder PATH itself; for a file PATH, the current folder when the
    /// file is inside it, else the file's own folder. Every PATH must lie inside DIR.
    #[arg(long, value_name = "DIR")]
    pub root: Option<PathBuf>,

    /// Use this config instead of the nearest meshvet.toml upward from the current folder.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,

    /// Worker threads (default: one per core). Capped at 4 per core, and at the number of files
    /// when that is more than the cores: more threads only wait for each other.
    #[arg(long, short = 'j', value_name = "N")]
    pub jobs: Option<usize>,

    /// No progress bar and no summary line; print only failing meshes.
    #[arg(long, short = 'q')]
    pub quiet: bool,

    /// What to print: `summary`, or `lines` (one line per finding, for pre-commit hooks).
    #[arg(long, value_enum, default_value_t = Format::Summary)]
    pub format: Format,

    /// Also write JSON Lines to FILE (`-`: standard output): one object per mesh with every CSV
    /// column, the findings and the per-shell table.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,

    /// Also write a JUnit XML report to FILE (`-`: standard output): a test case per mesh.
    #[arg(long, value_name = "FILE")]
    pub junit: Option<PathBuf>,

    /// Reuse the rows of files that have not changed since a scan with the same cache folder
    /// (keyed by content, meshvet version and settings).
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,

    /// Compare with a previous scan's CSV and report the meshes that got worse.
    #[arg(long, value_name = "OLD.csv")]
    pub baseline: Option<PathBuf>,

    /// Exit 1 only when a mesh got worse than in the baseline (failures it already had do not
    /// count).
    #[arg(long, requires = "baseline")]
    pub fail_on_regression: bool,

    /// Write a repaired copy of every file with a repairable defect under DIR, mirroring the
    /// scanned tree, in the input's format (the `[repair]` config says which repairs run). The
    /// report's `repaired_path`, `repairs` and `status_after` columns say what was done. Sources
    /// are never changed; DIR is left out of the scan.
    #[arg(long, value_name = "DIR")]
    pub repair_dir: Option<PathBuf>,

    /// Scan only shard K of N (1 <= K <= N): the files whose path hashes to it. Join the shards'
    /// CSVs with `meshvet merge`.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
}

impl Scan {
    /// The flags that are also config keys, as a config layer.
    pub fn config_layer(&self) -> Config {
        Config {
            jobs: self.jobs,
            ..Config::default()
        }
    }
}

/// A report path: `-` is standard output, and so is a path to the file standard output already
/// is (`/dev/stdout`, `/proc/self/fd/1`, or the file the shell sent it to): written into that
/// open file, with the summary on standard error, not renamed over the name.
pub fn target(path: &std::path::Path) -> Target {
    if path.as_os_str() == "-" || is_standard_output(path) {
        Target::Stdout
    } else {
        Target::File(path.to_owned())
    }
}

/// Whether `path` (its links followed) is the file standard output writes to.
fn is_standard_output(path: &std::path::Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::fd::AsFd;
        use std::os::unix::fs::MetadataExt;
        let Ok(out) = std::io::stdout().as_fd().try_clone_to_owned() else {
            return false;
        };
        match (std::fs::File::from(out).metadata(), std::fs::metadata(path)) {
            (Ok(a), Ok(b)) => (a.dev(), a.ino()) == (b.dev(), b.ino()),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        false
    }
}
