//! The HTML QA report (`--html FILE`): one self-contained page (inline CSS, JS and SVG; no network)
//! that a QA lead opens from disk or from a CI run.
//!
//! The header and the summary (status counts, bar charts per rule, per format and per top-level
//! folder) are rendered here as static HTML with CSS bars, so they read even without JavaScript. The
//! table of every mesh and the detail view are drawn by the small script in `html_page.html` from a
//! JSON block: one array per row holding the CSV cells (same text as the CSV report) plus the findings
//! with severities, the shell table and a picture number. Pictures travel as one
//! `<script type="text/x-svg">` element each, read only when a detail view opens, so a big page
//! loads as fast as its JSON parses.
//!
//! Size budget: pictures are at most [`PICTURE_BUDGET`] bytes in all. When the budget is reached, a
//! picture of a `warn`/`fail` mesh evicts pictures of `pass` meshes; otherwise the new picture is left
//! out (the detail view says so). Shell tables are cut at [`MAX_SHELLS`] shells per mesh. With the
//! ~250 bytes of a row, a 10,000-mesh page stays under ~20 MB whatever the meshes.
//!
//! The page data is [`HtmlReport`]; [`HtmlReport::set_baseline`] takes a list of changes since an
//! earlier scan (got worse / got better), shown in their own section.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::{self, Write};
use std::time::{SystemTime, UNIX_EPOCH};

pub use crate::baseline::Change;
use crate::report::Outcome;
use crate::report::{Output, Row, Target, COLUMNS, TEXT_COLUMNS};
use crate::rules::{Rule, Severity, Status};
use crate::topology::{Role, Shell};

/// The most bytes of pictures one page carries.
pub const PICTURE_BUDGET: usize = 12_000_000;

/// The most shells listed per mesh in the detail view.
pub const MAX_SHELLS: usize = 100;

/// The most entries listed per side of the baseline comparison.
pub const MAX_CHANGES: usize = 1000;

/// The most folders in the per-folder chart (the ones with most problems).
const MAX_FOLDERS: usize = 40;

const PAGE: &str = include_str!("html_page.html");

/// The statuses in the order the page counts and colours them.
pub const STATUSES: [Status; 5] = [
    Status::Pass,
    Status::Warn,
    Status::Fail,
    Status::Error,
    Status::Empty,
];

/// What was scanned, for the header.
#[derive(Debug, Clone, PartialEq)]
pub struct Meta {
    /// The paths given on the command line, as written.
    pub roots: Vec<String>,
    /// The config file used, or a note that the built-in defaults were.
    pub config: String,
    pub version: String,
    /// When the scan started.
    pub started: SystemTime,
    /// How long the scan took.
    pub seconds: f64,
    /// Files scanned.
    pub files: usize,
}

/// The comparison with a baseline scan: what got worse and what got better.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Baseline {
    /// Which baseline (its file name).
    pub name: String,
    pub worse: Vec<Change>,
    pub better: Vec<Change>,
}

/// One mesh on the page.
#[derive(Debug, Clone, PartialEq)]
struct Entry {
    row: Row,
    findings: Vec<(Rule, Severity, usize)>,
    shells: Vec<Shell>,
    shell_count: usize,
    picture: Option<String>,
    /// A picture was drawn but left out (or evicted) to keep the page within its budget.
    picture_left_out: bool,
}

impl Entry {
    fn status(&self) -> Status {
        self.row.status.unwrap_or(Status::Error)
    }
}

/// The counts the summary shows.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Summary {
    pub meshes: usize,
    /// Distinct files among the rows.
    pub files: usize,
    /// Rows per status, in [`STATUSES`] order.
    pub statuses: [usize; 5],
    /// Meshes that break each rule (rules broken by none left out), most first; with the worst
    /// severity seen.
    pub rules: Vec<(Rule, Severity, usize)>,
    /// Rows per status for each format, by name.
    pub formats: Vec<(String, [usize; 5])>,
    /// Rows per status for each top-level folder, most problems (fail + error, then warn) first.
    pub folders: Vec<(String, [usize; 5])>,
}

/// The page being collected, one outcome at a time.
#[derive(Debug, Default)]
pub struct HtmlReport {
    entries: Vec<Entry>,
    picture_bytes: usize,
    /// Indices of entries with a `pass` status that hold a picture (evicted first).
    pass_pictures: Vec<usize>,
    pictures_left_out: usize,
    baseline: Option<Baseline>,
}

impl HtmlReport {
    pub fn new() -> HtmlReport {
        HtmlReport::default()
    }

    /// Adds one mesh (in report order).
    pub fn add(&mut self, outcome: Outcome) {
        let Outcome {
            row,
            findings,
            detail,
            ..
        } = outcome;
        let (shells, shell_count, picture) = match detail {
            Some(d) => {
                let count = d.shells.iter().filter(|s| !s.pinched).count();
                let mut shells = d.shells;
                shells.truncate(MAX_SHELLS);
                (shells, count, d.picture)
            }
            None => (Vec::new(), 0, None),
        };
        let mut entry = Entry {
            row,
            findings: findings
                .iter()
                .map(|f| (f.rule, f.severity, f.count))
                .collect(),
            shells,
            shell_count,
            picture: None,
            picture_left_out: false,
        };
        if let Some(svg) = picture {
            entry.picture = self.make_room(svg, entry.status());
            entry.picture_left_out = entry.picture.is_none();
        }
        if entry.picture.is_some() && entry.status() == Status::Pass {
            self.pass_pictures.push(self.entries.len());
        }
        self.entries.push(entry);
    }

    /// Keeps `svg` if the budget allows, evicting `pass` pictures for a worse mesh's.
    fn make_room(&mut self, svg: String, status: Status) -> Option<String> {
        if status != Status::Pass {
            while self.picture_bytes + svg.len() > PICTURE_BUDGET {
                let Some(i) = self.pass_pictures.pop() else {
                    break;
                };
                if let Some(old) = self.entries[i].picture.take() {
                    self.entries[i].picture_left_out = true;
                    self.picture_bytes -= old.len();
                    self.pictures_left_out += 1;
                }
            }
        }
        if self.picture_bytes + svg.len() > PICTURE_BUDGET {
            self.pictures_left_out += 1;
            return None;
        }
        self.picture_bytes += svg.len();
        Some(svg)
    }

    /// Shows a comparison with a baseline scan.
    pub fn set_baseline(&mut self, baseline: Baseline) {
        self.baseline = Some(baseline);
    }

    /// Meshes collected so far.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Pictures left out to stay within [`PICTURE_BUDGET`].
    pub fn pictures_left_out(&self) -> usize {
        self.pictures_left_out
    }

    /// The counts behind the summary section.
    pub fn summary(&self) -> Summary {
        let mut s = Summary {
            meshes: self.entries.len(),
            ..Summary::default()
        };
        let mut rules: BTreeMap<Rule, (Severity, usize)> = BTreeMap::new();
        let mut formats: BTreeMap<String, [usize; 5]> = BTreeMap::new();
        let mut folders: BTreeMap<String, [usize; 5]> = BTreeMap::new();
        let mut last_path: Option<&str> = None;
        for e in &self.entries {
            if last_path != Some(e.row.path.as_str()) {
                s.files += 1;
                last_path = Some(&e.row.path);
            }
            let k = status_index(e.status());
            s.statuses[k] += 1;
            for &(rule, severity, _) in &e.findings {
                let r = rules.entry(rule).or_insert((severity, 0));
                r.0 = r.0.max(severity);
                r.1 += 1;
            }
            let format = if e.row.format.is_empty() {
                "(none)".to_owned()
            } else {
                e.row.format.clone()
            };
            formats.entry(format).or_default()[k] += 1;
            folders.entry(top_folder(&e.row.path)).or_default()[k] += 1;
        }
        s.rules = rules.into_iter().map(|(r, (sev, n))| (r, sev, n)).collect();
        s.rules.sort_by(|a, b| b.2.cmp(&a.2).then(a.0.cmp(&b.0)));
        s.formats = formats.into_iter().collect();
        s.folders = folders.into_iter().collect();
        // Most failures first, then most warnings, then by name (the sort is stable).
        s.folders
            .sort_by_key(|(_, n)| std::cmp::Reverse((n[2] + n[3], n[1])));
        s
    }

    /// The whole page.
    pub fn render(&self, meta: &Meta) -> String {
        let summary = self.summary();
        let mut page =
            String::with_capacity(self.picture_bytes + 300 * self.entries.len() + 64_000);
        let mut rest = PAGE;
        while let Some(at) = rest.find("{{") {
            page.push_str(&rest[..at]);
            let end = rest[at..].find("}}").expect("placeholders are closed") + at;
            match &rest[at + 2..end] {
                "title" => page.push_str(&escape(&title(meta))),
                "picture_style" => page.push_str(crate::picture::STYLE),
                "header" => self.write_header(&mut page, meta, &summary),
                "summary" => self.write_summary(&mut page, &summary),
                "baseline" => self.write_baseline(&mut page),
                "data" => self.write_data(&mut page),
                "pictures" => self.write_pictures(&mut page),
                other => panic!("unknown placeholder {other}"),
            }
            rest = &rest[end + 2..];
        }
        page.push_str(rest);
        page
    }

    /// Renders the page and writes it to standard output or, atomically, to a file (a temporary
    /// file beside it, then a rename).
    pub fn write(&self, target: &Target, meta: &Meta) -> io::Result<()> {
        let mut out = Output::create(target)?;
        out.write_all(self.render(meta).as_bytes())?;
        out.finish()
    }

    fn write_header(&self, out: &mut String, meta: &Meta, summary: &Summary) {
        let mut formats: Vec<&str> = summary.formats.iter().map(|(f, _)| f.as_str()).collect();
        formats.retain(|f| *f != "(none)");
        let items = [
            ("scanned", meta.roots.join(", ")),
            (
                "files",
                format!("{} files, {} meshes", meta.files, summary.meshes),
            ),
            ("formats", formats.join(", ")),
            ("config", meta.config.clone()),
            ("meshvet", meta.version.clone()),
            ("date", date(meta.started)),
            ("duration", format!("{:.1} s", meta.seconds)),
        ];
        out.push_str("<dl class='meta'>");
        for (k, v) in items {
            let _ = write!(out, "<div><dt>{k}</dt><dd>{}</dd></div>", escape(&v));
        }
        out.push_str("</dl>");
    }

    fn write_summary(&self, out: &mut String, s: &Summary) {
        out.push_str("<div class='tiles'>");
        for (k, status) in STATUSES.iter().enumerate() {
            let _ = write!(
                out,
                "<button class='tile s-{0}' data-status='{0}'><b>{1}</b>{0}</button>",
                status.name(),
                s.statuses[k]
            );
        }
        out.push_str("</div><div class='charts'>");

        out.push_str("<figure><figcaption>Meshes per rule</figcaption>");
        if s.rules.is_empty() {
            out.push_str("<p class='none'>No rule was broken.</p>");
        }
        let most = s.rules.first().map_or(1, |r| r.2).max(1);
        for &(rule, severity, n) in &s.rules {
            let _ = write!(
                out,
                "<div class='bar' data-rule='{name}' title='{summary}'><span class='label'>{name}</span>\
                 <span class='track'><span class='fill v-{sev}' style='width:{w:.1}%'></span></span>\
                 <span class='n'>{n}</span></div>",
                name = rule.name(),
                summary = escape(rule.summary()),
                sev = severity.name(),
                w = 100.0 * n as f64 / most as f64,
            );
        }
        out.push_str("</figure>");

        stacked_chart(out, "Meshes per format", "format", &s.formats, usize::MAX);
        stacked_chart(
            out,
            "Meshes per top-level folder",
            "folder",
            &s.folders,
            MAX_FOLDERS,
        );
        out.push_str("</div>");
    }

    fn write_baseline(&self, out: &mut String) {
        let Some(b) = &self.baseline else {
            return;
        };
        let _ = write!(
            out,
            "<section id='baseline'><h2>Since the baseline <code>{}</code></h2>\
             <p><b class='worse'>{} got worse</b>, <b class='better'>{} got better</b>.</p>",
            escape(&b.name),
            b.worse.len(),
            b.better.len()
        );
        for (class, title, list) in [
            ("worse", "Got worse", &b.worse),
            ("better", "Got better", &b.better),
        ] {
            if list.is_empty() {
                continue;
            }
            let _ = write!(
                out,
                "<details open class='{class}'><summary>{title} ({})</summary><table><thead><tr>\
                 <th>path</th><th>mesh</th><th>before</th><th>now</th><th>what changed</th></tr></thead><tbody>",
                list.len()
            );
            for c in list.iter().take(MAX_CHANGES) {
                let _ = write!(
                    out,
                    "<tr><td class='path'>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    escape(&c.path),
                    escape(&c.mesh),
                    badge(&c.before),
                    badge(&c.after),
                    escape(&c.what)
                );
            }
            out.push_str("</tbody></table>");
            if list.len() > MAX_CHANGES {
                let _ = write!(out, "<p>... and {} more</p>", list.len() - MAX_CHANGES);
            }
            out.push_str("</details>");
        }
        out.push_str("</section>");
    }

    /// The JSON block: columns, rule texts and one array per row.
    fn write_data(&self, out: &mut String) {
        out.push_str("{\"columns\":[");
        for (i, c) in COLUMNS.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            json_string(out, c);
        }
        out.push_str("],\"rules\":[");
        for (i, rule) in Rule::ALL.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            let (matters, repair) = explain(*rule);
            out.push('[');
            for (j, text) in [rule.name(), rule.summary(), matters, repair]
                .iter()
                .enumerate()
            {
                if j > 0 {
                    out.push(',');
                }
                json_string(out, text);
            }
            out.push(']');
        }
        let _ = write!(
            out,
            "],\"picturesLeftOut\":{},\"pictureBudget\":{},\"rows\":[",
            self.pictures_left_out, PICTURE_BUDGET
        );
        // The cells exactly as the CSV report writes them.
        let mut picture = 0;
        for (i, e) in self.entries.iter().enumerate() {
            if i > 0 {
                out.push_str(",\n");
            }
            out.push('[');
            let record = e.row.cells();
            for (cell, text) in record.iter().zip(TEXT_COLUMNS) {
                if !text && is_json_number(cell) {
                    out.push_str(cell);
                } else {
                    json_string(out, cell);
                }
                out.push(',');
            }
            // Findings: [rule index, 2 error / 1 warning, count].
            out.push('[');
            for (j, &(rule, severity, count)) in e.findings.iter().enumerate() {
                if j > 0 {
                    out.push(',');
                }
                let sev = u8::from(severity == Severity::Error) + 1;
                let _ = write!(out, "[{},{sev},{count}]", rule as usize);
            }
            // Shells: [faces, vertices, genus, volume, depth, role (0 solid, 1 cavity, 2 neither),
            // inside-out, oriented].
            out.push_str("],[");
            for (j, s) in e.shells.iter().enumerate() {
                if j > 0 {
                    out.push(',');
                }
                let genus = s.genus.map_or("null".to_owned(), |g| g.to_string());
                let volume = s
                    .volume
                    .filter(|v| v.is_finite())
                    .map_or("null".to_owned(), |v| format!("{v:.6e}"));
                let _ = write!(
                    out,
                    "[{},{},{genus},{volume},{},{},{},{}]",
                    s.faces,
                    s.vertices,
                    s.depth,
                    match s.role {
                        Role::Solid => 0,
                        Role::Cavity => 1,
                        Role::Neither => 2,
                    },
                    u8::from(s.inside_out),
                    u8::from(s.oriented)
                );
            }
            // The picture's number; -1: none was drawn, -2: left out for the budget.
            let pic = if e.picture.is_some() {
                picture += 1;
                picture - 1
            } else if e.picture_left_out {
                -2
            } else {
                -1
            };
            let _ = write!(out, "],{},{pic}]", e.shell_count);
        }
        out.push_str("]}");
    }

    fn write_pictures(&self, out: &mut String) {
        for (i, svg) in self
            .entries
            .iter()
            .filter_map(|e| e.picture.as_ref())
            .enumerate()
        {
            // Our SVG never holds `</script`; the check keeps a future change from breaking the page.
            debug_assert!(!svg.contains("</script"));
            let _ = writeln!(out, "<script type='text/x-svg' id='pic{i}'>{svg}</script>");
        }
    }
}

/// Why a rule matters and how it is repaired, for the detail view.
pub fn explain(rule: Rule) -> (&'static str, &'static str) {
    let doc = rule.doc();
    (doc.meaning, doc.repair)
}

/// A bar chart with one bar per name, split by status; a click filters the table by `kind`
/// (`format` or `folder`) through the bar's `data-KIND` attribute.
fn stacked_chart(
    out: &mut String,
    caption: &str,
    kind: &str,
    bars: &[(String, [usize; 5])],
    max: usize,
) {
    let _ = write!(out, "<figure><figcaption>{caption}</figcaption>");
    let most = bars
        .iter()
        .map(|(_, n)| n.iter().sum::<usize>())
        .max()
        .unwrap_or(1)
        .max(1);
    for (name, counts) in bars.iter().take(max) {
        let total: usize = counts.iter().sum();
        let tip: Vec<String> = STATUSES
            .iter()
            .zip(counts)
            .filter(|(_, &n)| n > 0)
            .map(|(s, n)| format!("{n} {}", s.name()))
            .collect();
        let _ = write!(
            out,
            "<div class='bar' data-{kind}='{name}' title='{tip}'><span class='label'>{name}</span><span class='track'>",
            name = escape(name),
            tip = escape(&tip.join(", "))
        );
        for (status, &n) in STATUSES.iter().zip(counts) {
            if n > 0 {
                let _ = write!(
                    out,
                    "<span class='fill s-{}' style='width:{:.2}%'></span>",
                    status.name(),
                    100.0 * n as f64 / most as f64
                );
            }
        }
        let _ = write!(out, "</span><span class='n'>{total}</span></div>");
    }
    if bars.len() > max {
        let _ = write!(out, "<p class='none'>... and {} more</p>", bars.len() - max);
    }
    out.push_str("</figure>");
}

fn status_index(status: Status) -> usize {
    STATUSES
        .iter()
        .position(|&s| s == status)
        .expect("every status is listed")
}

/// The first folder of a report path, or `(top level)` for a file directly in the scanned folder.
fn top_folder(path: &str) -> String {
    match path.split_once('/') {
        Some((first, _)) if !first.is_empty() => first.to_owned(),
        _ => "(top level)".to_owned(),
    }
}

fn badge(status: &str) -> String {
    if status.is_empty() {
        "<span class='dim'>-</span>".to_owned()
    } else {
        format!("<span class='badge s-{0}'>{0}</span>", escape(status))
    }
}

fn title(meta: &Meta) -> String {
    format!("meshvet QA report: {}", meta.roots.join(", "))
}

/// `YYYY-MM-DD HH:MM UTC`.
fn date(time: SystemTime) -> String {
    let secs = time.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs()) as i64;
    let (days, rest) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02} UTC",
        rest / 3600,
        rest % 3600 / 60
    )
}

/// Text for HTML content and attribute values.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A JSON string safe inside a `<script>` element (`<`, `>` and `&` escaped).
fn json_string(out: &mut String, text: &str) {
    out.push('"');
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            '<' | '>' | '&' | '\u{2028}' | '\u{2029}' => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

/// Whether a CSV cell is a JSON number as it stands (RFC 8259: `-`, then `0` or digits not
/// starting with `0`, then `.` and digits, then `e` or `E`, a sign and digits, each part after the
/// first optional), so that it can be written bare.
fn is_json_number(cell: &str) -> bool {
    fn digits(b: &[u8]) -> usize {
        b.iter().take_while(|c| c.is_ascii_digit()).count()
    }
    let mut b = cell.as_bytes();
    b = b.strip_prefix(b"-").unwrap_or(b);
    let whole = digits(b);
    if whole == 0 || (whole > 1 && b[0] == b'0') {
        return false;
    }
    b = &b[whole..];
    if let Some(rest) = b.strip_prefix(b".") {
        let fraction = digits(rest);
        if fraction == 0 {
            return false;
        }
        b = &rest[fraction..];
    }
    if let Some(rest) = b.strip_prefix(b"e").or_else(|| b.strip_prefix(b"E")) {
        let rest = rest
            .strip_prefix(b"+")
            .or_else(|| rest.strip_prefix(b"-"))
            .unwrap_or(rest);
        let exponent = digits(rest);
        if exponent == 0 {
            return false;
        }
        b = &rest[exponent..];
    }
    // Past `f64` (1e999), JavaScript would read it as Infinity.
    b.is_empty() && cell.parse::<f64>().is_ok_and(f64::is_finite)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::Detail;
    use crate::rules::Finding;

    fn outcome(path: &str, status: Status, findings: &[(Rule, Severity, usize)]) -> Outcome {
        Outcome {
            row: Row {
                path: path.to_owned(),
                format: path.rsplit('.').next().unwrap().to_owned(),
                status: Some(status),
                faces: Some(12),
                ..Row::default()
            },
            findings: findings
                .iter()
                .map(|&(rule, severity, count)| Finding {
                    rule,
                    severity,
                    count,
                    message: rule.describe(count),
                })
                .collect(),
            ..Outcome::default()
        }
    }

    fn meta() -> Meta {
        Meta {
            roots: vec!["assets".into()],
            config: "built-in defaults".into(),
            version: "0.1.0".into(),
            started: UNIX_EPOCH + std::time::Duration::from_secs(1_763_790_000),
            seconds: 1.25,
            files: 4,
        }
    }

    fn sample() -> HtmlReport {
        let mut r = HtmlReport::new();
        let hole = (Rule::Hole, Severity::Warning, 2);
        let nm = (Rule::NonManifoldEdge, Severity::Error, 1);
        r.add(outcome("props/a.obj", Status::Pass, &[]));
        r.add(outcome("props/b.obj", Status::Warn, &[hole]));
        r.add(outcome("print/c.stl", Status::Fail, &[nm, hole]));
        r.add(outcome("d.glb", Status::Fail, &[nm]));
        r.add(outcome("d.glb", Status::Pass, &[]));
        r.add(outcome("e.ply", Status::Error, &[]));
        r
    }

    #[test]
    fn summary_counts_statuses_rules_formats_and_folders() {
        let s = sample().summary();
        assert_eq!(s.meshes, 6);
        assert_eq!(s.files, 5);
        assert_eq!(s.statuses, [2, 1, 2, 1, 0]);
        assert_eq!(
            s.rules,
            [
                (Rule::NonManifoldEdge, Severity::Error, 2),
                (Rule::Hole, Severity::Warning, 2)
            ]
        );
        let formats: Vec<_> = s.formats.iter().map(|(f, n)| (f.as_str(), *n)).collect();
        assert_eq!(
            formats,
            [
                ("glb", [1, 0, 1, 0, 0]),
                ("obj", [1, 1, 0, 0, 0]),
                ("ply", [0, 0, 0, 1, 0]),
                ("stl", [0, 0, 1, 0, 0])
            ]
        );
        let folders: Vec<_> = s.folders.iter().map(|(f, n)| (f.as_str(), *n)).collect();
        assert_eq!(
            folders,
            [
                ("(top level)", [1, 0, 1, 1, 0]),
                ("print", [0, 0, 1, 0, 0]),
                ("props", [1, 1, 0, 0, 0])
            ]
        );
    }

    #[test]
    fn the_page_has_the_summary_and_every_row_and_no_external_url() {
        let mut r = sample();
        r.set_baseline(Baseline {
            name: "old.csv".into(),
            worse: vec![Change {
                path: "print/c.stl".into(),
                before: "pass".into(),
                after: "fail".into(),
                what: "+1 non-manifold-edge".into(),
                ..Change::default()
            }],
            better: Vec::new(),
        });
        let page = r.render(&meta());
        assert!(page.starts_with("<!DOCTYPE html>"));
        assert!(page.contains("2025-11-22 05:40 UTC"), "the date");
        assert!(page.contains("<b>2</b>fail"));
        assert!(page.contains("data-rule='non-manifold-edge'"));
        assert!(page.contains("Since the baseline <code>old.csv</code>"));
        assert!(page.contains("+1 non-manifold-edge"));
        assert_eq!(page.matches("\n[\"").count() + 1, 6, "six rows");
        assert!(!page.contains("{{"), "every placeholder is filled");
        assert_no_external_url(&page);
    }

    pub fn assert_no_external_url(page: &str) {
        let lower = page.to_ascii_lowercase();
        for bad in [
            "http://",
            "https://",
            "src=\"//",
            "src='//",
            "href=\"//",
            "href='//",
            "url(",
            "@import",
        ] {
            assert!(!lower.contains(bad), "the page refers to {bad}");
        }
    }

    #[test]
    fn text_is_escaped_in_html_and_json() {
        let mut r = HtmlReport::new();
        let mut o = outcome("x/</script><b>.obj", Status::Error, &[]);
        o.row.message = "bad \"quote\" & \u{7}".into();
        r.add(o);
        let page = r.render(&meta());
        assert!(!page.contains("</script><b>"));
        assert!(page.contains("x/\\u003c/script\\u003e\\u003cb\\u003e.obj"));
        assert!(page.contains("bad \\\"quote\\\" \\u0026 \\u0007"));
    }

    #[test]
    fn numbers_are_bare_and_other_cells_strings() {
        for n in ["0", "12", "-3", "2.5", "1e-7", "-0.5", "1E+5", "-0", "0.01"] {
            assert!(is_json_number(n), "{n}");
        }
        let not = [
            "", "true", "inf", "NaN", "01", "1.", "-", "1e", "-01", "-.5", "1.e5", ".5", "+1",
            "1e+", "0x10", "1 ", "1e999",
        ];
        for s in not {
            assert!(!is_json_number(s), "{s}");
        }
    }

    /// Text cells stay strings whatever they look like: glTF meshes named `-01`, `-.5`, `1.e5`
    /// (not JSON numbers: written bare they broke the whole page's data) and `1.50` (a JSON
    /// number, read as 1.5), and a path `12`. The page's data block parses as JSON and gives the
    /// names back as written.
    #[test]
    fn names_that_look_like_numbers_stay_names() {
        let mut r = HtmlReport::new();
        for name in ["-01", "-.5", "1.e5", "1.50"] {
            let mut o = outcome("12", Status::Pass, &[]);
            o.row.mesh = name.to_owned();
            r.add(o);
        }
        let mut data = String::new();
        r.write_data(&mut data);
        let json = data
            .split_once('{')
            .map(|(_, rest)| format!("{{{rest}"))
            .unwrap();
        let json = json.trim_end().trim_end_matches(';');
        let value: serde_json::Value = serde_json::from_str(json).expect("the data is JSON");
        let rows = value["rows"].as_array().unwrap();
        let names: Vec<&str> = rows.iter().map(|r| r[1].as_str().unwrap()).collect();
        assert_eq!(names, ["-01", "-.5", "1.e5", "1.50"]);
        assert!(rows.iter().all(|r| r[0] == "12" && r[7] == 12));
    }

    #[test]
    fn pass_pictures_make_room_for_worse_ones() {
        let mut r = HtmlReport::new();
        let big = "x".repeat(PICTURE_BUDGET / 2 + 1);
        let with_picture = |status| {
            let mut o = outcome("a.obj", status, &[]);
            o.detail = Some(Box::new(Detail {
                shells: Vec::new(),
                picture: Some(big.clone()),
            }));
            o
        };
        r.add(with_picture(Status::Pass));
        r.add(with_picture(Status::Pass)); // over budget: left out
        assert_eq!(r.pictures_left_out(), 1);
        r.add(with_picture(Status::Fail)); // evicts the first pass picture
        assert_eq!(r.pictures_left_out(), 2);
        let kept: Vec<bool> = r.entries.iter().map(|e| e.picture.is_some()).collect();
        let left_out: Vec<bool> = r.entries.iter().map(|e| e.picture_left_out).collect();
        assert_eq!(
            left_out,
            [true, true, false],
            "each row knows its own picture was left out"
        );
        assert_eq!(kept, [false, false, true]);
        assert!(r.picture_bytes <= PICTURE_BUDGET);
    }

    #[test]
    fn dates_are_utc() {
        assert_eq!(date(UNIX_EPOCH), "1970-01-01 00:00 UTC");
        let leap = UNIX_EPOCH + std::time::Duration::from_secs(951_782_400 + 86_399);
        assert_eq!(date(leap), "2000-02-29 23:59 UTC");
    }

    #[test]
    fn the_page_writes_atomically() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.html");
        sample()
            .write(&Target::File(path.clone()), &meta())
            .unwrap();
        assert!(std::fs::read_to_string(&path).unwrap().contains("meshvet"));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
