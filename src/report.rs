//! The CSV report (SPEC 9): one flat [`Row`] per mesh whose field order is the column order, and a
//! writer that puts the file in place atomically (a temporary file in the same folder, renamed when
//! complete) or streams to standard output.
//!
//! Cells: booleans `true`/`false`; a number that is undefined (genus of a non-manifold mesh, every
//! count of a file that could not be read) is an empty cell; floats print as Rust's shortest
//! round-trip form (`0.5`, `1`, `1e-7`). After SPEC's columns come `invalid_faces`,
//! `mirrored_instances` and `findings` (`rule:count;rule:count`, worst first, `off` rules left out).
//! `millis` is the time to read the file plus the time to analyse this mesh, to the microsecond; it is
//! the only cell that differs between two scans of the same tree.

use std::io::{self, Write};
use std::path::PathBuf;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::atomic::AtomicFile;
use crate::formats::Format;
use crate::rules::{Finding, Status};
use crate::topology::{Analysis, Role, Shell};

/// The column names in order (the header the writer emits).
pub const COLUMNS: [&str; 44] = [
    "path",
    "mesh",
    "format",
    "status",
    "message",
    "vertices",
    "welded_vertices",
    "faces",
    "degenerate_faces",
    "zero_area_faces",
    "duplicate_faces",
    "invalid_vertices",
    "unreferenced_vertices",
    "edges",
    "border_edges",
    "nonmanifold_edges",
    "nonmanifold_vertices",
    "inconsistent_edges",
    "components",
    "shells",
    "holes",
    "orientable",
    "oriented",
    "inside_out_shells",
    "cavities",
    "solids",
    "euler",
    "genus",
    "volume",
    "area",
    "bbox_min_x",
    "bbox_min_y",
    "bbox_min_z",
    "bbox_max_x",
    "bbox_max_y",
    "bbox_max_z",
    "repaired_path",
    "repairs",
    "millis",
    "invalid_faces",
    "mirrored_instances",
    "findings",
    "status_after",
    "findings_after",
];

/// One line of the CSV report. Field order is column order (checked against [`COLUMNS`] by a test).
/// A row reads back from its CSV cells exactly (floats print in shortest round-trip form), which
/// the cache, `--baseline` and `merge` rely on.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Row {
    pub path: String,
    pub mesh: String,
    pub format: String,
    #[serde(with = "status_cell")]
    pub status: Option<Status>,
    pub message: String,
    pub vertices: Option<usize>,
    pub welded_vertices: Option<usize>,
    pub faces: Option<usize>,
    pub degenerate_faces: Option<usize>,
    pub zero_area_faces: Option<usize>,
    pub duplicate_faces: Option<usize>,
    pub invalid_vertices: Option<usize>,
    pub unreferenced_vertices: Option<usize>,
    pub edges: Option<usize>,
    pub border_edges: Option<usize>,
    pub nonmanifold_edges: Option<usize>,
    pub nonmanifold_vertices: Option<usize>,
    pub inconsistent_edges: Option<usize>,
    pub components: Option<usize>,
    pub shells: Option<usize>,
    pub holes: Option<usize>,
    pub orientable: Option<bool>,
    pub oriented: Option<bool>,
    pub inside_out_shells: Option<usize>,
    pub cavities: Option<usize>,
    pub solids: Option<usize>,
    pub euler: Option<i64>,
    pub genus: Option<i64>,
    #[serde(with = "float_cell")]
    pub volume: Option<f64>,
    #[serde(with = "float_cell")]
    pub area: Option<f64>,
    #[serde(with = "float_cell")]
    pub bbox_min_x: Option<f64>,
    #[serde(with = "float_cell")]
    pub bbox_min_y: Option<f64>,
    #[serde(with = "float_cell")]
    pub bbox_min_z: Option<f64>,
    #[serde(with = "float_cell")]
    pub bbox_max_x: Option<f64>,
    #[serde(with = "float_cell")]
    pub bbox_max_y: Option<f64>,
    #[serde(with = "float_cell")]
    pub bbox_max_z: Option<f64>,
    pub repaired_path: String,
    pub repairs: String,
    #[serde(with = "float_cell")]
    pub millis: Option<f64>,
    pub invalid_faces: Option<usize>,
    pub mirrored_instances: Option<u32>,
    pub findings: String,
    /// The status of the repaired copy when scanned again (empty: no copy written).
    pub status_after: String,
    /// The repaired copy's findings, `rule:count;...` like `findings` (empty: none, or no copy).
    pub findings_after: String,
}

mod float_cell {
    use super::*;

    pub fn serialize<S: Serializer>(value: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        match value {
            Some(v) => s.serialize_str(&v.to_string()),
            None => s.serialize_str(""),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
        let cell = String::deserialize(d)?;
        if cell.is_empty() {
            return Ok(None);
        }
        cell.parse()
            .map(Some)
            .map_err(|_| serde::de::Error::custom(format!("`{cell}` is not a number")))
    }
}

mod status_cell {
    use super::*;

    pub fn serialize<S: Serializer>(value: &Option<Status>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(value.map_or("", Status::name))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Status>, D::Error> {
        let cell = String::deserialize(d)?;
        if cell.is_empty() {
            return Ok(None);
        }
        Status::from_name(&cell)
            .map(Some)
            .ok_or_else(|| serde::de::Error::custom(format!("unknown status `{cell}`")))
    }
}

/// One closed shell of a mesh (SPEC 7, 8), for the JSON report and the cache; the CSV only counts
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
                volume: shell.volume,
                depth: shell.depth,
                role: shell.role,
                inside_out: shell.inside_out,
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
            millis: Some(millis),
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
            shells: Some(a.shells.len()),
            holes: Some(a.holes()),
            orientable: defined.then(|| a.orientable()),
            oriented: defined.then(|| a.oriented()),
            inside_out_shells: Some(a.inside_out_shells()),
            cavities: Some(a.cavities()),
            solids: Some(a.solids()),
            euler: Some(a.euler),
            genus: a.genus(),
            volume: a.volume(),
            area: Some(a.area),
            bbox_min_x: bbox(0, 0),
            bbox_min_y: bbox(0, 1),
            bbox_min_z: bbox(0, 2),
            bbox_max_x: bbox(1, 0),
            bbox_max_y: bbox(1, 1),
            bbox_max_z: bbox(1, 2),
            repaired_path: String::new(),
            repairs: String::new(),
            millis: Some(millis),
            invalid_faces: Some(a.invalid_faces),
            mirrored_instances: Some(mirrored_instances),
            findings: findings_cell(findings),
            status_after: String::new(),
            findings_after: String::new(),
        }
    }
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
            Target::File(path) => Output::File(AtomicFile::create(path)?),
        })
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
        self.writer()?.serialize(row).map_err(io::Error::other)
    }

    /// Flushes the rows and, for a file, renames the temporary file over the target.
    pub fn finish(mut self) -> io::Result<()> {
        let writer = self.writer.take().expect("finish is called once");
        writer.into_inner().map_err(|e| e.into_error())?.finish()
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

    #[test]
    fn row_fields_are_the_columns_in_order() {
        let text = {
            let mut w = csv::Writer::from_writer(Vec::new());
            w.serialize(Row::default()).unwrap();
            String::from_utf8(w.into_inner().unwrap()).unwrap()
        };
        assert_eq!(text.lines().next().unwrap(), COLUMNS.join(","));
    }

    #[test]
    fn cells_follow_the_spec() {
        let analysis = Analysis {
            vertices: 4,
            faces: 4,
            area: 2.5,
            bbox: Some([[0.0, -0.5, 0.0], [1.0, 1e-7, 3.0]]),
            components: vec![Component {
                holes: 2,
                orientable: true,
                oriented: true,
                ..Component::default()
            }],
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
            "a/b.obj,,obj,warn,2 holes; missing b.mtl,4,0,4,0,0,0,0,0,0,0,0,0,0,1,0,2,true,true,0,0,0,0,,,2.5,0,-0.5,0,1,0.0000001,3,,,1.5,0,0,hole:2,,"
        );
        assert_eq!(
            lines[2],
            format!("c.stl,,stl,error,truncated{}0.25,,,,,", ",".repeat(34))
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
