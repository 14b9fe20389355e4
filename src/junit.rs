//! The JUnit XML report (`--junit FILE`), so CI dashboards show assets like tests: one
//! `<testsuite name="meshvet">`, one `<testcase>` per mesh (name `path` or `path#mesh`, classname the
//! mesh's folder, time its `millis`).
//!
//! - `pass` and `warn` meshes pass; warnings are listed in the case's `system-out`.
//! - A `fail` mesh has a `<failure>`: its message names every error-severity finding
//!   (`rule: message; ...`), its type every error rule (`non-manifold-edge,non-manifold-vertex`,
//!   in the findings' order), and its text one line per error finding.
//!   JUnit tools count a test case as failed once, and quick-junit writes one failure element per
//!   case, so several error findings share that one element, a line each.
//! - An `error` row (the file could not be read) is an `<error>` with the row's message.
//! - An `empty` mesh (no triangles) is `<skipped>`: there was nothing to test.
//!
//! Names and messages are written with the characters XML 1.0 cannot hold (control characters
//! but tab and line end, U+FFFE, U+FFFF) and those a reader would change (a line end or tab in
//! an attribute reads back as a space) as `\x1b`-style escapes, as the terminal shows them: a
//! name holding one gives a well-formed report and a case named apart from every other.
//!
//! Cases are kept in memory until [`JunitReport::finish`] (a few hundred bytes per mesh).

use std::io;
use std::time::Duration;

use quick_junit::{NonSuccessKind, Report, TestCase, TestCaseStatus, TestSuite};

use crate::report::Outcome;
use crate::report::{Output, Target};
use crate::rules::{Severity, Status};

/// A JUnit report being gathered; [`JunitReport::finish`] writes it (a file atomically).
pub struct JunitReport {
    out: Output,
    suite: TestSuite,
}

impl JunitReport {
    /// Opens the target now, so a bad path fails before the scan; the report is written into it
    /// when finished.
    pub fn create(target: &Target) -> io::Result<JunitReport> {
        Ok(JunitReport {
            out: Output::create(target)?,
            suite: TestSuite::new("meshvet"),
        })
    }

    pub fn write(&mut self, outcome: &Outcome) -> io::Result<()> {
        self.suite.add_test_case(case(outcome));
        Ok(())
    }

    /// Writes the report and puts it in place; `time` is the scan's wall time.
    pub fn finish(self, time: Duration) -> io::Result<()> {
        self.into_output(time)?.finish()
    }

    /// Writes the report into its output, for the caller to put in place.
    pub fn into_output(mut self, time: Duration) -> io::Result<Output> {
        self.suite.set_time(time);
        let mut report = Report::new("meshvet");
        report.set_time(time);
        report.add_test_suite(self.suite);
        report.serialize(&mut self.out).map_err(io::Error::other)?;
        Ok(self.out)
    }
}

/// The test case of one mesh (see the module docs).
pub fn case(outcome: &Outcome) -> TestCase {
    let row = &outcome.row;
    let name = if row.mesh.is_empty() {
        row.path.clone()
    } else {
        format!("{}#{}", row.path, row.mesh)
    };
    let line = |f: &crate::rules::Finding| escaped(&format!("{}: {}", f.rule, f.message));
    let of = |severity: Severity| -> Vec<String> {
        outcome
            .findings
            .iter()
            .filter(|f| f.severity == severity)
            .map(line)
            .collect()
    };
    let status = match row.status.unwrap_or(Status::Error) {
        Status::Pass | Status::Warn => TestCaseStatus::success(),
        Status::Fail => {
            let errors = of(Severity::Error);
            let mut status = TestCaseStatus::non_success(NonSuccessKind::Failure);
            status.set_message(errors.join("; "));
            status.set_type(outcome.error_rules().join(","));
            status.set_description(errors.join("\n"));
            status
        }
        Status::Error => {
            let mut status = TestCaseStatus::non_success(NonSuccessKind::Error);
            status.set_message(escaped(&row.message));
            status.set_type("unreadable");
            status
        }
        Status::Empty => {
            let mut status = TestCaseStatus::skipped();
            status.set_message(escaped(&row.message));
            status
        }
    };
    let mut case = TestCase::new(escaped(&name), status);
    let folder = row.path.rsplit_once('/').map_or(".", |(folder, _)| folder);
    case.set_classname(escaped(folder));
    if let Some(millis) = row.millis.filter(|m| m.is_finite() && *m >= 0.0) {
        case.set_time(Duration::from_secs_f64(millis / 1e3));
    }
    let warnings = of(Severity::Warning);
    if !warnings.is_empty() {
        case.set_system_out(format!("warnings:\n{}", warnings.join("\n")));
    }
    case
}

/// `text` with the characters XML 1.0 cannot hold, and line ends and tabs (an attribute's value
/// turns them into spaces), written as `\x0a`-style escapes (see the module docs).
fn escaped(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '\u{fffe}' | '\u{ffff}' => out.push_str(&format!("\\u{{{:04x}}}", u32::from(c))),
            c if c.is_control() => out.push_str(&format!("\\x{:02x}", u32::from(c))),
            c => out.push(c),
        }
    }
    out
}
