//! `--baseline OLD.csv`: what got worse (and better) since a previous scan's CSV, so a nightly job
//! can page someone only for regressions.
//!
//! Meshes are matched by `(path, mesh)`. A mesh **got worse** (a regression) when now it:
//! - is `error` (the file cannot be read) and was not `error`, or is new;
//! - is `fail` and was not `fail` (it was `pass`, `warn`, `empty`, `error`), or is new;
//! - is `fail` and was `fail`, but has an error-severity finding whose rule the old row's `findings`
//!   cell does not list (a new kind of defect; a higher count of a known one is not a regression).
//!
//! A mesh **got better** when it was `fail` or `error` and now is neither. The old CSV must have
//! exactly this meshvet's columns: a report from another column set is refused with an error
//! rather than compared wrongly.

use std::collections::{BTreeSet, HashMap};
use std::path::Path;

use crate::report::Outcome;
use crate::report::{Row, COLUMNS};
use crate::rules::Status;

/// One mesh whose result changed since the baseline.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Change {
    pub path: String,
    pub mesh: String,
    /// Status in the baseline; empty when the mesh is new.
    pub before: String,
    /// Status now.
    pub after: String,
    /// What changed, in words (`newly failing: inside-out-shell`, `new error findings: hole`).
    pub what: String,
}

impl Change {
    /// `path[#mesh]: what (before -> after)`.
    pub fn line(&self) -> String {
        let name = if self.mesh.is_empty() {
            self.path.clone()
        } else {
            format!("{}#{}", self.path, self.mesh)
        };
        let before = if self.before.is_empty() {
            "new"
        } else {
            &self.before
        };
        format!("{name}: {} ({before} -> {})", self.what, self.after)
    }
}

/// What a mesh was in the baseline.
#[derive(Debug, Clone)]
struct Before {
    status: Option<Status>,
    /// Rule names in the old `findings` cell.
    rules: BTreeSet<String>,
}

/// A previous scan to compare with, and the comparison so far.
#[derive(Debug, Default)]
pub struct Baseline {
    before: HashMap<(String, String), Before>,
    pub worse: Vec<Change>,
    pub better: Vec<Change>,
}

impl Baseline {
    /// Reads a CSV written by this meshvet (`--csv`). The error says what is wrong with it.
    pub fn read(path: &Path) -> Result<Baseline, String> {
        let name = path.display();
        let mut reader = csv::Reader::from_path(path)
            .map_err(|e| format!("cannot read the baseline {name}: {e}"))?;
        let header = reader
            .headers()
            .map_err(|e| format!("cannot read the baseline {name}: {e}"))?
            .clone();
        if header.iter().ne(COLUMNS.iter().copied()) {
            return Err(format!(
                "the baseline {name} has other columns than this meshvet's CSV (written by \
                 another version, or not a meshvet report): scan again to make a new baseline \
                 (expected {} columns `{}...`, found {} `{}...`)",
                COLUMNS.len(),
                COLUMNS[..3].join(","),
                header.len(),
                header.iter().take(3).collect::<Vec<_>>().join(",")
            ));
        }
        let mut before = HashMap::new();
        for (i, record) in reader.records().enumerate() {
            let row = record
                .map_err(|e| e.to_string())
                .and_then(|r| Row::from_cells(r.iter()))
                .map_err(|e| {
                    format!(
                        "the baseline {name} is not a meshvet CSV at row {}: {e}",
                        i + 2
                    )
                })?;
            let rules = row
                .findings
                .split(';')
                .filter_map(|f| f.split(':').next())
                .filter(|r| !r.is_empty())
                .map(str::to_owned)
                .collect();
            let key = (row.path, row.mesh);
            if before.contains_key(&key) {
                return Err(format!(
                    "the baseline {name} has two rows for {}{}{} (an older meshvet gave two \
                     meshes of one name in a file the same row name; now each has its own): scan \
                     again to make a new baseline",
                    key.0,
                    if key.1.is_empty() { "" } else { "#" },
                    key.1
                ));
            }
            before.insert(
                key,
                Before {
                    status: row.status,
                    rules,
                },
            );
        }
        Ok(Baseline {
            before,
            ..Baseline::default()
        })
    }

    /// Meshes in the baseline.
    pub fn len(&self) -> usize {
        self.before.len()
    }

    pub fn is_empty(&self) -> bool {
        self.before.is_empty()
    }

    /// Compares one mesh of the current scan (in report order).
    pub fn compare(&mut self, outcome: &Outcome) {
        let row = &outcome.row;
        let now = row.status.unwrap_or(Status::Error);
        let old = self.before.get(&(row.path.clone(), row.mesh.clone()));
        let was = old.and_then(|b| b.status);
        let change = |what: String| Change {
            path: row.path.clone(),
            mesh: row.mesh.clone(),
            before: was.map_or_else(String::new, |s| s.name().to_owned()),
            after: now.name().to_owned(),
            what,
        };
        let error_rules = outcome.error_rules();
        match now {
            Status::Error if was != Some(Status::Error) => {
                self.worse
                    .push(change(format!("newly unreadable: {}", row.message)));
            }
            Status::Fail if was != Some(Status::Fail) => {
                self.worse
                    .push(change(format!("newly failing: {}", error_rules.join(", "))));
            }
            Status::Fail => {
                let known = old.map(|b| &b.rules);
                let new: Vec<&str> = error_rules
                    .iter()
                    .copied()
                    .filter(|r| !known.is_some_and(|k| k.contains(*r)))
                    .collect();
                if !new.is_empty() {
                    self.worse
                        .push(change(format!("new error findings: {}", new.join(", "))));
                }
            }
            _ => {
                if was.is_some_and(Status::is_failure) && !now.is_failure() {
                    self.better.push(change("no longer failing".to_owned()));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rules::{Finding, Rule};

    fn outcome(path: &str, status: Status, rules: &[Rule]) -> Outcome {
        let findings: Vec<Finding> = rules
            .iter()
            .map(|&rule| Finding {
                rule,
                severity: rule.default_severity(),
                count: 1,
                message: rule.describe(1),
            })
            .collect();
        Outcome {
            row: Row {
                path: path.into(),
                status: Some(status),
                findings: crate::report::findings_cell(&findings),
                message: if status == Status::Error {
                    "truncated".into()
                } else {
                    String::new()
                },
                ..Row::default()
            },
            findings,
            ..Outcome::default()
        }
    }

    fn baseline_of(outcomes: &[Outcome]) -> Baseline {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.csv");
        let mut report =
            crate::report::CsvReport::create(&crate::report::Target::File(path.clone())).unwrap();
        for o in outcomes {
            report.write(&o.row).unwrap();
        }
        report.finish().unwrap();
        Baseline::read(&path).unwrap()
    }

    #[test]
    fn regressions_are_new_failures_new_error_rules_and_new_errors() {
        let mut baseline = baseline_of(&[
            outcome("fixed.obj", Status::Fail, &[Rule::NonManifoldEdge]),
            outcome("same.obj", Status::Fail, &[Rule::NonManifoldEdge]),
            outcome("worse.obj", Status::Fail, &[Rule::NonManifoldEdge]),
            outcome("broke.obj", Status::Warn, &[Rule::Hole]),
            outcome("unreadable.obj", Status::Pass, &[]),
            outcome("still-unreadable.obj", Status::Error, &[]),
        ]);
        for o in [
            outcome(
                "broke.obj",
                Status::Fail,
                &[Rule::InsideOutShell, Rule::Hole],
            ),
            outcome("fixed.obj", Status::Warn, &[Rule::Hole]),
            outcome("new.obj", Status::Fail, &[Rule::NonManifoldVertex]),
            outcome("new-ok.obj", Status::Pass, &[]),
            outcome(
                "same.obj",
                Status::Fail,
                &[Rule::NonManifoldEdge, Rule::Hole],
            ),
            outcome("still-unreadable.obj", Status::Error, &[]),
            outcome("unreadable.obj", Status::Error, &[]),
            outcome(
                "worse.obj",
                Status::Fail,
                &[Rule::NonManifoldEdge, Rule::InsideOutShell],
            ),
        ] {
            baseline.compare(&o);
        }
        let worse: Vec<String> = baseline.worse.iter().map(Change::line).collect();
        assert_eq!(
            worse,
            [
                "broke.obj: newly failing: inside-out-shell (warn -> fail)",
                "new.obj: newly failing: non-manifold-vertex (new -> fail)",
                "unreadable.obj: newly unreadable: truncated (pass -> error)",
                "worse.obj: new error findings: inside-out-shell (fail -> fail)",
            ]
        );
        let better: Vec<String> = baseline.better.iter().map(Change::line).collect();
        assert_eq!(better, ["fixed.obj: no longer failing (fail -> warn)"]);
    }

    #[test]
    fn a_csv_with_other_columns_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.csv");
        std::fs::write(&path, "path,mesh,status\na.obj,,pass\n").unwrap();
        let err = Baseline::read(&path).unwrap_err();
        assert!(err.contains("other columns"), "{err}");
    }
}
