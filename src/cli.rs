//! The command line (clap derive). Flags that mean the same as a config key become a
//! [`Config`] layer, so they go through the one merge path in `config.rs`.

use std::path::PathBuf;

use clap::{Parser, Subcommand};

use meshvet::config::Config;
use meshvet::report::Target;

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

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Scan mesh files (.obj .gltf .glb .stl .ply .off) and report their topology.
    ///
    /// Exit code 0: no error-severity findings; 1: a mesh failed or a file could not be read;
    /// 2: the command or the config is wrong.
    Scan(Scan),
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

    /// Use this config instead of the nearest meshvet.toml upward from the current folder.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,

    /// Worker threads (default: one per core).
    #[arg(long, short = 'j', value_name = "N")]
    pub jobs: Option<usize>,

    /// No progress bar and no summary line; print only failing meshes.
    #[arg(long, short = 'q')]
    pub quiet: bool,

    /// Write a repaired copy of every file with a repairable defect under DIR, mirroring the
    /// scanned tree, in the input's format (the `[repair]` config says which repairs run). The
    /// report's `repaired_path`, `repairs` and `status_after` columns say what was done. Sources
    /// are never changed; DIR is left out of the scan.
    #[arg(long, value_name = "DIR")]
    pub repair_dir: Option<PathBuf>,
}

impl Scan {
    /// The flags that are also config keys, as a config layer.
    pub fn config_layer(&self) -> Config {
        Config {
            jobs: self.jobs,
            ..Config::default()
        }
    }

    /// Where the CSV goes, if anywhere.
    pub fn csv_target(&self) -> Option<Target> {
        self.csv.as_ref().map(|p| {
            if p.as_os_str() == "-" {
                Target::Stdout
            } else {
                Target::File(p.clone())
            }
        })
    }
}
