//! The JSON Lines report (`--json FILE`): one object per mesh, in report order, for tools that would
//! rather not parse CSV.
//!
//! Each object has every CSV column under its CSV name, in CSV order, typed: counts and floats are
//! JSON numbers, booleans are `true`/`false`, an undefined number or boolean (an empty CSV cell) is
//! `null`, and text columns stay text (`mesh`, `repaired_path`, ... are `""` when empty). Four keys
//! carry more than their CSV cells: `findings` and `findings_after` are arrays of
//! `{rule, severity, count, message}` (worst first, the CSV's `rule:count;...` cells spelt out),
//! `repairs` an array of `{repair, count, faces}` (`faces`: the faces a `fill-holes` or
//! `flip-inside-out-shells` added or turned, else `null`), and `shells` the per-shell table
//! `{faces, holes, genus, volume, depth, role: "solid"|"cavity"|"neither", inside_out, pinched, meets}` (the
//! CSV's count is its length, less the pinched solids; `meets`: the shells, by index in the table,
//! whose faces meet this one's). A float that is not finite (an overflowing volume) is `null`, as JSON has no infinity.

use std::io::{self, Write};

use serde_json::Value;

use crate::report::Outcome;
use crate::report::{Cell, Output, RepairDone, ShellRow, Target};
use crate::rules::Finding;
use crate::topology::Role;

/// A JSON Lines report being written; [`JsonReport::finish`] puts a file in place atomically.
pub struct JsonReport {
    out: Output,
}

impl JsonReport {
    pub fn create(target: &Target) -> io::Result<JsonReport> {
        Ok(JsonReport {
            out: Output::create(target)?,
        })
    }

    pub fn write(&mut self, outcome: &Outcome) -> io::Result<()> {
        serde_json::to_writer(&mut self.out, &record(outcome))?;
        self.out.write_all(b"\n")
    }

    pub fn finish(self) -> io::Result<()> {
        self.out.finish()
    }

    /// The output, for the caller to put in place.
    pub fn into_output(self) -> Output {
        self.out
    }
}

/// The JSON object of one mesh (see the module docs).
pub fn record(outcome: &Outcome) -> Value {
    let mut object = outcome.row.json();
    for (key, list) in [
        ("findings", outcome.findings.iter().map(finding).collect()),
        ("repairs", outcome.repairs.iter().map(repair).collect()),
        (
            "findings_after",
            outcome.findings_after.iter().map(finding).collect(),
        ),
        ("shells", outcome.shells.iter().map(shell).collect()),
    ] {
        object.insert(key.to_owned(), Value::Array(list));
    }
    Value::Object(object)
}

fn finding(f: &Finding) -> Value {
    serde_json::json!({
        "rule": f.rule.name(),
        "severity": f.severity.name(),
        "count": f.count,
        "message": f.message,
    })
}

fn repair(r: &RepairDone) -> Value {
    serde_json::json!({"repair": r.repair, "count": r.count, "faces": r.faces})
}

fn shell(s: &ShellRow) -> Value {
    serde_json::json!({
        "faces": s.faces,
        "holes": s.holes,
        "genus": s.genus,
        "volume": s.volume.json(),
        "depth": s.depth,
        "role": role_name(s.role),
        "inside_out": s.inside_out,
        "pinched": s.pinched,
        "meets": s.meets,
    })
}

/// `solid`, `cavity` or `neither`, as the reports write a shell's role.
pub fn role_name(role: Role) -> &'static str {
    match role {
        Role::Solid => "solid",
        Role::Cavity => "cavity",
        Role::Neither => "neither",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::{Row, COLUMNS};
    use crate::rules::{Rule, Severity, Status};

    #[test]
    fn every_column_is_a_key_with_a_typed_value() {
        let outcome = Outcome {
            row: Row {
                path: "a.obj".into(),
                status: Some(Status::Fail),
                faces: Some(4),
                orientable: Some(true),
                volume: Some(-0.5),
                millis: Some(1.25),
                findings: "inside-out-shell:1".into(),
                ..Row::default()
            },
            findings: vec![Finding {
                rule: Rule::InsideOutShell,
                severity: Severity::Error,
                count: 1,
                message: "1 inside-out shell".into(),
            }],
            shells: vec![ShellRow {
                faces: 4,
                genus: Some(0),
                volume: Some(-0.5),
                role: Role::Solid,
                inside_out: true,
                ..ShellRow::default()
            }],
            repairs: vec![RepairDone {
                repair: "fill-holes",
                count: 1,
                faces: Some(6),
            }],
            ..Outcome::default()
        };
        let value = record(&outcome);
        let keys: Vec<&str> = value
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        assert_eq!(keys, COLUMNS, "the CSV columns in order");
        assert_eq!(value["status"], "fail");
        assert_eq!(value["faces"], 4);
        assert_eq!(value["edges"], Value::Null);
        assert_eq!(value["orientable"], true);
        assert_eq!(value["volume"], -0.5);
        assert_eq!(value["bbox_min_x"], Value::Null);
        assert_eq!(value["millis"], 1.25);
        assert_eq!(
            value["findings"],
            serde_json::json!([{"rule": "inside-out-shell", "severity": "error", "count": 1,
                "message": "1 inside-out shell"}])
        );
        assert_eq!(
            value["repairs"],
            serde_json::json!([{"repair": "fill-holes", "count": 1, "faces": 6}])
        );
        assert_eq!(value["findings_after"], serde_json::json!([]));
        assert_eq!(
            value["shells"],
            serde_json::json!([{"faces": 4, "holes": 0, "genus": 0, "volume": -0.5, "depth": 0,
                "role": "solid", "inside_out": true, "pinched": false, "meets": []}])
        );
    }
}
