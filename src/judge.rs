//! The one path from a mesh to a verdict: analyse it, let the rules turn the facts into findings,
//! and give the status a report row shows. The scan judges every mesh it reads with [`judge`], and
//! the repair stage judges every copy it writes with the same function, so a copy is held to
//! exactly the standard its source was.

use crate::config::Settings;
use crate::mesh::Mesh;
use crate::rules::{self, Finding, MeshFacts, Status};
use crate::topology::{analyse_keeping, Analysis, Built};

/// A mesh judged: the facts, the findings (worst first), the status, and the weld and Corner Table
/// the analysis built (for a picture or a repair of the same mesh; set it to `None` when neither
/// follows, so a file of many meshes does not hold every table).
#[derive(Debug)]
pub struct Judged {
    pub analysis: Analysis,
    pub findings: Vec<Finding>,
    /// `empty` for a mesh without triangles, else `pass`, `warn` or `fail` by the worst finding.
    pub status: Status,
    pub built: Option<Built>,
}

/// Judges one mesh under `settings` (its weld tolerance and rule severities).
pub fn judge(mesh: &Mesh, settings: &Settings) -> Judged {
    let (analysis, built) = analyse_keeping(mesh, &settings.options());
    let (status, findings) = if mesh.triangles.is_empty() {
        (Status::Empty, Vec::new())
    } else {
        let findings = rules::check(&analysis, &MeshFacts::of(mesh), &settings.severities);
        (Status::of(&findings), findings)
    };
    Judged {
        analysis,
        findings,
        status,
        built: Some(built),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rules::{Rule, Severity};

    /// A lone triangle: 3 border edges forming 1 hole, a warning by default; with `hole` set to
    /// `error` it fails, and a mesh with no triangles is empty whatever the rules say.
    #[test]
    fn status_follows_the_worst_finding() {
        let mesh = Mesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2]],
        );
        let mut settings = Settings::default();
        let judged = judge(&mesh, &settings);
        assert_eq!(judged.status, Status::Warn);
        assert_eq!(judged.findings[0].rule, Rule::Hole);
        assert_eq!(judged.analysis.border_edges, 3);
        settings.severities.set(Rule::Hole, Severity::Error);
        assert_eq!(judge(&mesh, &settings).status, Status::Fail);
        let empty = Mesh::new(vec![[0.0; 3]], Vec::new());
        assert_eq!(judge(&empty, &settings).status, Status::Empty);
    }
}
