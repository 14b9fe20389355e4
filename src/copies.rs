//! Repaired copies of one scanned file (`scan --repair-dir DIR`, SPEC 10): for each mesh with a
//! finding, plan the repair; when a plan changes anything, write the file's copy under DIR (the
//! scanned tree mirrored, the input's format), read the copy back, analyse it, and fill the rows'
//! `repaired_path`, `repairs` and `status_after`. A failure becomes a note in the rows' message;
//! the scan goes on.

use std::path::{Component, Path, PathBuf};

use crate::config::Settings;
use crate::formats::{self, write, Format, ReadContext};
use crate::mesh::Mesh;
use crate::repair::{self, Plan};
use crate::rules::{self, MeshFacts, Status};
use crate::scan::Outcome;
use crate::topology::analyse;

/// Where the copy of the file reported as `display` goes under `dir`: the report path with
/// anything that would climb out (`..`, a root) left out.
pub fn copy_path(dir: &Path, display: &str) -> PathBuf {
    let mut out = dir.to_path_buf();
    for c in Path::new(display).components() {
        if let Component::Normal(part) = c {
            out.push(part);
        }
    }
    out
}

/// Repairs the meshes of one file (`outcomes[i]` is the row of `meshes[i]`).
#[allow(clippy::too_many_arguments)]
pub fn repair_file(
    dir: &Path,
    display: &str,
    source: &Path,
    format: Format,
    context: &ReadContext,
    meshes: &[Mesh],
    outcomes: &mut [Outcome],
    settings: &Settings,
) {
    let options = settings.repair_options();
    let plans: Vec<Option<Plan>> = meshes
        .iter()
        .zip(outcomes.iter())
        .map(|(mesh, outcome)| {
            if outcome.findings.is_empty() || mesh.triangles.is_empty() {
                return None;
            }
            let plan = repair::plan(mesh, &options);
            (plan.changes() || !plan.not_repairable.is_empty()).then_some(plan)
        })
        .collect();
    for (plan, outcome) in plans.iter().zip(outcomes.iter_mut()) {
        if let Some(plan) = plan {
            if !plan.not_repairable.is_empty() {
                note(
                    outcome,
                    &format!("not repairable: {}", plan.not_repairable.join(", ")),
                );
            }
        }
    }
    // Only plans that change something are written; a mesh that needs nothing stays as it is.
    let plans: Vec<Option<Plan>> = plans.into_iter().map(|p| p.filter(Plan::changes)).collect();
    if plans.iter().all(Option::is_none) {
        return;
    }
    let out = copy_path(dir, display);
    let failed = |outcomes: &mut [Outcome], plans: &[Option<Plan>], why: String| {
        for (plan, outcome) in plans.iter().zip(outcomes.iter_mut()) {
            if plan.is_some() {
                note(outcome, &format!("repair failed: {why}"));
            }
        }
    };
    if let Err(e) = write::write_repaired(source, format, &plans, &out, context) {
        return failed(outcomes, &plans, e.to_string());
    }
    // Read the copy back and judge it as the scan judges a file.
    let copy_context = ReadContext {
        root: dir.to_path_buf(),
        limits: context.limits.clone(),
    };
    let again = match formats::read(&out, format, &copy_context) {
        Ok(again) if again.len() == meshes.len() => again,
        Ok(_) => {
            return failed(
                outcomes,
                &plans,
                "the copy has a different number of meshes".into(),
            )
        }
        Err(e) => return failed(outcomes, &plans, format!("the copy cannot be read: {e}")),
    };
    let analysis_options = settings.options();
    let repaired_path = out.to_string_lossy().replace('\\', "/");
    for ((plan, outcome), mesh) in plans.iter().zip(outcomes.iter_mut()).zip(&again) {
        let Some(plan) = plan else { continue };
        let analysis = analyse(mesh, &analysis_options);
        let findings = rules::check(&analysis, &MeshFacts::of(mesh), &settings.severities);
        let status = if mesh.triangles.is_empty() {
            Status::Empty
        } else {
            Status::of(&findings)
        };
        outcome.row.repaired_path = repaired_path.clone();
        outcome.row.repairs = plan.summary();
        outcome.row.status_after = status.to_string();
        outcome.row.findings_after = crate::report::findings_cell(&findings);
    }
}

fn note(outcome: &mut Outcome, text: &str) {
    if !outcome.row.message.is_empty() {
        outcome.row.message.push_str("; ");
    }
    outcome.row.message.push_str(text);
}
