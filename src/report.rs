//! The CSV report ([definitions](crate::definitions#report)): one flat [`Row`] per mesh whose field
//! order is the column order, and a writer that puts the file in place atomically (a temporary file
//! in the same folder, renamed when complete) or streams to standard output.
//!
//! Cells: booleans `true`/`false`; a number that is undefined (genus of a non-manifold mesh, every
//! count of a file that could not be read) is an empty cell; floats print in Rust's `Display` form,
//! the shortest digits that read back exactly, never an exponent (`0.5`, `1`, `0.0000001`). After
//! the topology columns come `invalid_faces`, `mirrored_instances` and `findings`
//! (`rule:count;rule:count`, worst first, `off` rules left out).
//! `millis` is the time to read the file plus the time to analyse this mesh, to the microsecond; it is
//! the only cell that differs between two scans of the same tree.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use crate::atomic::AtomicFile;
use crate::formats::Format;
use crate::rules::{Finding, Status};
use crate::topology::{Analysis, Role, Shell};

/// The report's columns, in order: each field's name and type, listed once. The [`Row`] struct,
/// [`COLUMNS`], the CSV cells ([`Row::cells`], [`Row::from_cells`]) and the JSON object
/// ([`Row::json`]) are all made from this list, and how a cell is written, read back and typed in
/// JSON follows its field's type ([`Cell`]), so a new column is one line here.
macro_rules! columns {
    ($($(#[$doc:meta])* $name:ident: $ty:ty,)*) => {
        /// One line of the CSV report. Field order is column order. A row reads back from its
        /// cells exactly (floats print in a form that reads back to the same number), which the
        /// cache, `--baseline` and `merge` rely on.
        #[derive(Debug, Clone, PartialEq, Default)]
        pub struct Row {
            $($(#[$doc])* pub $name: $ty,)*
        }

        /// The column names in order (the header the writer emits).
        pub const COLUMNS: &[&str] = &[$(stringify!($name)),*];

        /// Per column, whether its cells are free text ([`Cell::TEXT`]): a mesh named `1.50`
        /// stays a name wherever cells are typed by what they look like.
        pub const TEXT_COLUMNS: &[bool] = &[$(<$ty as Cell>::TEXT),*];

        impl Row {
            /// The cells in column order, as the CSV writes them.
            pub fn cells(&self) -> Vec<String> {
                vec![$(self.$name.cell()),*]
            }

            /// The row these cells are (in column order, as [`Row::cells`] writes them). The error
            /// names the column whose cell does not read as its type.
            pub fn from_cells<'a>(cells: impl IntoIterator<Item = &'a str>) -> Result<Row, String> {
                let mut cells = cells.into_iter();
                let row = Row {
                    $($name: {
                        let cell = cells
                            .next()
                            .ok_or_else(|| format!("no `{}` column", stringify!($name)))?;
                        Cell::parse(cell).ok_or_else(|| {
                            format!("`{cell}` is not a valid `{}` cell", stringify!($name))
                        })?
                    },)*
                };
                match cells.next() {
                    None => Ok(row),
                    Some(_) => Err(format!("more than {} cells", COLUMNS.len())),
                }
            }

            /// The row as a JSON object: every column under its name, in column order, typed.
            pub fn json(&self) -> serde_json::Map<String, serde_json::Value> {
                let mut object = serde_json::Map::new();
                $(object.insert(stringify!($name).to_owned(), self.$name.json());)*
                object
            }
        }
    };
}

columns! {
    path: String,
    mesh: String,
    format: String,
    status: Option<Status>,
    message: String,
    vertices: Option<usize>,
    welded_vertices: Option<usize>,
    faces: Option<usize>,
    degenerate_faces: Option<usize>,
    zero_area_faces: Option<usize>,
    duplicate_faces: Option<usize>,
    invalid_vertices: Option<usize>,
    unreferenced_vertices: Option<usize>,
    edges: Option<usize>,
    border_edges: Option<usize>,
    nonmanifold_edges: Option<usize>,
    nonmanifold_vertices: Option<usize>,
    inconsistent_edges: Option<usize>,
    components: Option<usize>,
    shells: Option<usize>,
    holes: Option<usize>,
    orientable: Option<bool>,
    oriented: Option<bool>,
    inside_out_shells: Option<usize>,
    cavities: Option<usize>,
    solids: Option<usize>,
    euler: Option<i64>,
    genus: Option<i64>,
    volume: Option<f64>,
    area: Option<f64>,
    bbox_min_x: Option<f64>,
    bbox_min_y: Option<f64>,
    bbox_min_z: Option<f64>,
    bbox_max_x: Option<f64>,
    bbox_max_y: Option<f64>,
    bbox_max_z: Option<f64>,
    repaired_path: String,
    repairs: String,
    millis: Option<f64>,
    invalid_faces: Option<usize>,
    mirrored_instances: Option<u32>,
    findings: String,
    /// The status of the repaired copy when scanned again (empty: no copy written).
    status_after: String,
    /// The repaired copy's findings, `rule:count;...` like `findings` (empty: none, or no copy).
    findings_after: String,
    /// Pairs of faces of one component that meet (empty: the search is switched off).
    self_intersections: Option<usize>,
    /// Pairs of components with faces that meet (empty: the search is switched off).
    intersecting_components: Option<usize>,
}

/// How a column's type is written in a CSV cell, read back from one and typed in JSON. Undefined
/// values (`None`) are empty cells and JSON `null`.
pub trait Cell: Sized {
    /// Whether the cell is free text (a path, a name, a message), never a number, whatever it
    /// looks like.
    const TEXT: bool = false;
    /// The cell's text.
    fn cell(&self) -> String;
    /// The value a cell's text stands for; `None` when it does not read as this type.
    fn parse(cell: &str) -> Option<Self>;
    fn json(&self) -> serde_json::Value;
}

impl Cell for String {
    const TEXT: bool = true;

    fn cell(&self) -> String {
        self.clone()
    }

    fn parse(cell: &str) -> Option<String> {
        Some(cell.to_owned())
    }

    fn json(&self) -> serde_json::Value {
        serde_json::Value::String(self.clone())
    }
}

/// Counts, integers and booleans: their `Display` text, JSON numbers and booleans.
macro_rules! plain_cell {
    ($($ty:ty),*) => {$(
        impl Cell for Option<$ty> {
            fn cell(&self) -> String {
                self.map_or_else(String::new, |v| v.to_string())
            }

            fn parse(cell: &str) -> Option<Option<$ty>> {
                if cell.is_empty() {
                    Some(None)
                } else {
                    cell.parse().ok().map(Some)
                }
            }

            fn json(&self) -> serde_json::Value {
                serde_json::json!(self)
            }
        }
    )*};
}

plain_cell!(usize, u32, i64, bool);

/// Floats: Rust's `Display` text (the shortest digits that read back to the same number, never an
/// exponent: `0.5`, `1`, `0.0000001`); in JSON a number, or `null` when not finite (JSON has no
/// infinity).
impl Cell for Option<f64> {
    fn cell(&self) -> String {
        self.map_or_else(String::new, |v| v.to_string())
    }

    fn parse(cell: &str) -> Option<Option<f64>> {
        if cell.is_empty() {
            Some(None)
        } else {
            cell.parse().ok().map(Some)
        }
    }

    fn json(&self) -> serde_json::Value {
        self.and_then(serde_json::Number::from_f64)
            .map_or(serde_json::Value::Null, serde_json::Value::Number)
    }
}

/// A status: its name.
impl Cell for Option<Status> {
    fn cell(&self) -> String {
        self.map_or("", Status::name).to_owned()
    }

    fn parse(cell: &str) -> Option<Option<Status>> {
        if cell.is_empty() {
            Some(None)
        } else {
            Status::from_name(cell).map(Some)
        }
    }

    fn json(&self) -> serde_json::Value {
        self.map_or(serde_json::Value::Null, |s| s.name().into())
    }
}

/// One closed [shell](crate::definitions#components) of a mesh, for the JSON report and the cache; the CSV only counts
/// shells.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ShellRow {
    pub faces: usize,
    /// Boundary loops of the shell's component (0: a shell is closed).
    pub holes: usize,
    pub genus: Option<i64>,
    /// Signed volume in the stored winding's majority; `None` when not orientable.
    pub volume: Option<f64>,
    /// How many other shells contain this one.
    pub depth: usize,
    pub role: Role,
    pub inside_out: bool,
    /// A pinched solid, not a shell ([`Shell::pinched`]).
    pub pinched: bool,
    /// The other shells of the table (their indices in it) whose faces meet this one's.
    pub meets: Vec<usize>,
}

impl ShellRow {
    /// The shells of an analysis, in component order.
    pub fn of(analysis: &Analysis) -> Vec<ShellRow> {
        analysis
            .shells
            .iter()
            .map(|shell| ShellRow {
                faces: shell.faces,
                holes: analysis
                    .components
                    .get(shell.component)
                    .map_or(0, |c| c.holes),
                genus: shell.genus,
                volume: shell.volume.filter(|v| v.is_finite()),
                depth: shell.depth,
                role: shell.role,
                inside_out: shell.inside_out,
                pinched: shell.pinched,
                meets: shell.meets.clone(),
            })
            .collect()
    }
}

impl Row {
    /// A row for a file that could not be read: every number empty, the message says why.
    pub fn error(path: &str, format: Option<Format>, message: &str, millis: f64) -> Row {
        Row {
            path: path.to_owned(),
            format: format.map_or_else(String::new, |f| f.name().to_owned()),
            status: Some(Status::Error),
            message: message.to_owned(),
            millis: Some(to_microseconds(millis)),
            ..Row::default()
        }
    }

    /// A row for a mesh that was read and analysed.
    #[allow(clippy::too_many_arguments)]
    pub fn analysed(
        path: &str,
        mesh: Option<&str>,
        format: Format,
        status: Status,
        analysis: &Analysis,
        findings: &[Finding],
        notes: &[String],
        mirrored_instances: u32,
        millis: f64,
    ) -> Row {
        let a = analysis;
        let bbox = |i: usize, k: usize| a.bbox.map(|b| b[i][k]);
        let message: Vec<&str> = findings
            .iter()
            .map(|f| f.message.as_str())
            .chain(notes.iter().map(String::as_str))
            .collect();
        let defined = a.faces > 0;
        Row {
            path: path.to_owned(),
            mesh: mesh.unwrap_or_default().to_owned(),
            format: format.name().to_owned(),
            status: Some(status),
            message: message.join("; "),
            vertices: Some(a.vertices),
            welded_vertices: Some(a.welded_vertices),
            faces: Some(a.faces),
            degenerate_faces: Some(a.degenerate_faces),
            zero_area_faces: Some(a.zero_area_faces),
            duplicate_faces: Some(a.duplicate_faces),
            invalid_vertices: Some(a.invalid_vertices),
            unreferenced_vertices: Some(a.unreferenced_vertices),
            edges: Some(a.edges),
            border_edges: Some(a.border_edges),
            nonmanifold_edges: Some(a.nonmanifold_edges),
            nonmanifold_vertices: Some(a.nonmanifold_vertices),
            inconsistent_edges: Some(a.inconsistent_edges),
            components: Some(a.components.len()),
            shells: Some(a.shell_count()),
            holes: Some(a.holes()),
            orientable: defined.then(|| a.orientable()),
            oriented: defined.then(|| a.oriented()),
            inside_out_shells: Some(a.inside_out_shells()),
            cavities: Some(a.cavities()),
            solids: Some(a.solids()),
            euler: Some(a.euler),
            genus: a.genus(),
            // Past about 1e154 a coordinate's square overflows: a number that is not finite is
            // not defined, an empty cell as SPEC 9 says (not `NaN` or `inf`).
            volume: a.volume().filter(|v| v.is_finite()),
            area: Some(a.area).filter(|x| x.is_finite()),
            bbox_min_x: bbox(0, 0),
            bbox_min_y: bbox(0, 1),
            bbox_min_z: bbox(0, 2),
            bbox_max_x: bbox(1, 0),
            bbox_max_y: bbox(1, 1),
            bbox_max_z: bbox(1, 2),
            repaired_path: String::new(),
            repairs: String::new(),
            millis: Some(to_microseconds(millis)),
            invalid_faces: Some(a.invalid_faces),
            mirrored_instances: Some(mirrored_instances),
            findings: findings_cell(findings),
            status_after: String::new(),
            findings_after: String::new(),
            self_intersections: a.self_intersections(),
            intersecting_components: a.intersecting_components(),
        }
    }
}

/// Milliseconds rounded to the microsecond, so that a sum of two times prints `0.021`, not
/// `0.020999999999999998`.
pub fn to_microseconds(millis: f64) -> f64 {
    (millis * 1e3).round() / 1e3
}

/// `rule:count;rule:count` in the findings' order.
pub fn findings_cell(findings: &[Finding]) -> String {
    findings
        .iter()
        .map(|f| format!("{}:{}", f.rule, f.count))
        .collect::<Vec<_>>()
        .join(";")
}

/// One mesh as every report sees it: its row, the findings behind it (for the summary, the JSON and
/// JUnit reports), its shells and what a detailed report shows.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Outcome {
    pub row: Row,
    pub findings: Vec<Finding>,
    /// The mesh's closed shells (for the JSON report and the cache; a few small structs per mesh,
    /// so always kept). Empty for error and empty rows.
    pub shells: Vec<ShellRow>,
    /// What a detailed report shows beyond the row; only when the scan was asked for details and
    /// the mesh has triangles.
    pub detail: Option<Box<Detail>>,
    /// The repairs a repaired copy had (the `repairs` cell spelt out), and what judging the copy
    /// found (the `findings_after` cell spelt out). Empty without a copy; never cached (a
    /// repairing scan reads every file).
    pub repairs: Vec<RepairDone>,
    pub findings_after: Vec<Finding>,
}

/// One repair of a copy: its stable name, how many it did, and the faces it added or turned
/// where the repair says (`fill-holes`, `flip-inside-out-shells`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RepairDone {
    pub repair: &'static str,
    pub count: usize,
    pub faces: Option<usize>,
}

impl Outcome {
    /// The names of the rules with an error-severity finding, worst first.
    pub fn error_rules(&self) -> Vec<&'static str> {
        self.findings
            .iter()
            .filter(|f| f.severity == crate::rules::Severity::Error)
            .map(|f| f.rule.name())
            .collect()
    }
}

/// The per-shell table and the drawing of one mesh, made while it is in memory.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Detail {
    pub shells: Vec<Shell>,
    /// An SVG drawing with the problem places marked (see `picture.rs`); `None` when drawing
    /// failed or there was nothing to draw.
    pub picture: Option<String>,
}

/// Where the CSV goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Target {
    Stdout,
    File(PathBuf),
}

/// The file a report path names: links are followed to the name they lead to (which need not
/// exist yet), so the report replaces that file and the links stay (renaming over a link's own
/// name would put a regular file in its place).
fn through_links(path: &Path) -> io::Result<PathBuf> {
    let mut path = path.to_owned();
    // As many links as the system follows in one path.
    for _ in 0..40 {
        if !std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_symlink()) {
            return Ok(path);
        }
        let to = std::fs::read_link(&path)?;
        path = path
            .parent()
            .map_or_else(|| to.clone(), |folder| folder.join(&to));
    }
    Err(io::Error::other(
        "it is a link in a loop of links: name the file itself",
    ))
}

/// An open report destination: standard output, or a file put in place atomically by
/// [`Output::finish`] (see [`crate::atomic`]). Dropped unfinished, a file target is left untouched.
pub enum Output {
    Stdout(io::BufWriter<io::Stdout>),
    File(AtomicFile),
}

impl Output {
    pub fn create(target: &Target) -> io::Result<Output> {
        Ok(match target {
            Target::Stdout => Output::Stdout(io::BufWriter::new(io::stdout())),
            Target::File(path) => {
                let real = through_links(path)?;
                Output::File(AtomicFile::create(&real).map_err(|e| {
                    if real == *path {
                        e
                    } else {
                        let to = real.display();
                        io::Error::new(e.kind(), format!("{e} (it is a link to {to})"))
                    }
                })?)
            }
        })
    }

    /// Flushes everything written (for a file, to the disk), so that [`Output::finish`] has only
    /// the rename left.
    pub fn prepare(&mut self) -> io::Result<()> {
        match self {
            Output::Stdout(out) => out.flush(),
            Output::File(file) => file.prepare(),
        }
    }

    /// Flushes and, for a file, renames it into place.
    pub fn finish(self) -> io::Result<()> {
        match self {
            Output::Stdout(mut out) => out.flush(),
            Output::File(file) => file.commit(),
        }
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Output::Stdout(out) => out.write(buf),
            Output::File(file) => file.write(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Output::Stdout(out) => out.flush(),
            Output::File(file) => file.flush(),
        }
    }
}

/// A CSV report being written. [`CsvReport::finish`] puts a file target in place; dropping the
/// report unfinished removes its temporary file and leaves any earlier report untouched.
pub struct CsvReport {
    writer: Option<csv::Writer<Output>>,
}

impl CsvReport {
    /// Starts a report and writes the header.
    pub fn create(target: &Target) -> io::Result<CsvReport> {
        let mut report = CsvReport {
            writer: Some(
                csv::WriterBuilder::new()
                    .has_headers(false)
                    .from_writer(Output::create(target)?),
            ),
        };
        report.writer()?.write_record(COLUMNS)?;
        Ok(report)
    }

    fn writer(&mut self) -> io::Result<&mut csv::Writer<Output>> {
        self.writer
            .as_mut()
            .ok_or_else(|| io::Error::other("the report is already finished"))
    }

    pub fn write(&mut self, row: &Row) -> io::Result<()> {
        self.writer()?
            .write_record(row.cells())
            .map_err(io::Error::other)
    }

    /// Flushes the rows and, for a file, renames the temporary file over the target.
    pub fn finish(self) -> io::Result<()> {
        self.into_output()?.finish()
    }

    /// Flushes the rows into the output, for the caller to put in place.
    pub fn into_output(mut self) -> io::Result<Output> {
        let writer = self.writer.take().expect("the output is taken once");
        writer.into_inner().map_err(|e| e.into_error())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rules::{Rule, Severity};
    use crate::topology::Component;

    fn csv_of(rows: &[Row]) -> String {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        let mut report = CsvReport::create(&Target::File(path.clone())).unwrap();
        for row in rows {
            report.write(row).unwrap();
        }
        report.finish().unwrap();
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "the temporary file is gone");
        std::fs::read_to_string(path).unwrap()
    }

    /// Read and analysis times add up to float noise (0.009 + 0.012 is 0.020999999999999998): the
    /// cell is rounded to the microsecond.
    #[test]
    fn millis_are_written_to_the_microsecond() {
        let row = Row::analysed(
            "a.obj",
            None,
            Format::Obj,
            Status::Pass,
            &Analysis::default(),
            &[],
            &[],
            0,
            0.009 + 0.012,
        );
        assert_eq!(
            row.cells()[COLUMNS.iter().position(|c| *c == "millis").unwrap()],
            "0.021"
        );
        assert_eq!(Row::error("b.obj", None, "", 1.0 / 3.0).millis, Some(0.333));
    }

    /// Every cell reads back as what it was written from, and a cell of the wrong type is an
    /// error that names its column.
    #[test]
    fn cells_read_back_exactly() {
        let row = Row {
            path: "a,b \"c\".obj".into(),
            status: Some(Status::Warn),
            faces: Some(12),
            euler: Some(-2),
            orientable: Some(false),
            volume: Some(0.1 + 0.2),
            bbox_min_x: Some(-1e-300),
            area: Some(1e300),
            ..Row::default()
        };
        let cells = row.cells();
        assert_eq!(cells.len(), COLUMNS.len());
        assert_eq!(Row::from_cells(cells.iter().map(String::as_str)), Ok(row));
        let mut bad = Row::default().cells();
        bad[7] = "seven".into();
        let error = Row::from_cells(bad.iter().map(String::as_str)).unwrap_err();
        assert_eq!(error, "`seven` is not a valid `faces` cell");
        assert!(Row::from_cells(["a"]).is_err());
    }

    #[test]
    fn cells_follow_the_spec() {
        let analysis = Analysis {
            vertices: 4,
            faces: 4,
            area: 2.5,
            bbox: Some([[0.0, -0.5, 0.0], [1.0, 1e-7, 3.0]]),
            components: vec![Component::with_holes(2)],
            ..Analysis::default()
        };
        let findings = [Finding {
            rule: Rule::Hole,
            severity: Severity::Warning,
            count: 2,
            message: "2 holes".into(),
        }];
        let row = Row::analysed(
            "a/b.obj",
            None,
            Format::Obj,
            Status::Warn,
            &analysis,
            &findings,
            &["missing b.mtl".into()],
            0,
            1.5,
        );
        let text = csv_of(&[
            row,
            Row::error("c.stl", Some(Format::Stl), "truncated", 0.25),
        ]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], COLUMNS.join(","));
        assert_eq!(
            lines[1],
            "a/b.obj,,obj,warn,2 holes; missing b.mtl,4,0,4,0,0,0,0,0,0,0,0,0,0,1,0,2,true,true,0,0,0,0,,,2.5,0,-0.5,0,1,0.0000001,3,,,1.5,0,0,hole:2,,,,"
        );
        assert_eq!(
            lines[2],
            format!("c.stl,,stl,error,truncated{}0.25,,,,,,,", ",".repeat(34))
        );
    }

    #[test]
    fn an_unfinished_report_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        std::fs::write(&path, "old").unwrap();
        let report = CsvReport::create(&Target::File(path.clone())).unwrap();
        drop(report);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
