//! The one path from a mesh to a verdict: analyse it, let the rules turn the facts into findings,
//! and give the status a report row shows. The scan judges every mesh it reads with [`judge`] (or
//! [`judge_releasing`], the same verdict with the mesh's arrays freed early, when no repair
//! follows), and the repair stage judges every copy it writes with [`judge`], so a copy is held to
//! exactly the standard its source was.

use crate::config::Settings;
use crate::mesh::Mesh;
use crate::rules::{self, Finding, MeshFacts, Status};
use crate::topology::{analyse_keeping, analyse_releasing, Analysis, Built};

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
    verdict(
        analysis,
        built,
        mesh.triangles.is_empty(),
        &MeshFacts::of(mesh),
        settings,
    )
}

/// [`judge`], freeing the mesh's positions and faces (left empty) once the analysis no longer
/// needs them ([`analyse_releasing`]): for a scan that keeps only the mesh's name and notes for
/// its row.
pub fn judge_releasing(mesh: &mut Mesh, settings: &Settings) -> Judged {
    let (empty, facts) = (mesh.triangles.is_empty(), MeshFacts::of(mesh));
    let (analysis, built) = analyse_releasing(mesh, &settings.options());
    verdict(analysis, built, empty, &facts, settings)
}

/// The findings and status of an analysis (`empty`: the mesh has no triangles).
fn verdict(
    analysis: Analysis,
    built: Built,
    empty: bool,
    facts: &MeshFacts,
    settings: &Settings,
) -> Judged {
    let (status, findings) = if empty {
        (Status::Empty, Vec::new())
    } else {
        let findings = rules::check(&analysis, facts, &settings.severities);
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

    /// Judging while freeing the mesh gives the same verdict as judging it, and leaves the mesh
    /// without its positions and faces (their memory given back), its name and notes kept. Two
    /// crossing tetrahedra, one of them missing a face: a hole, faces that meet, two components.
    #[test]
    fn judging_while_freeing_the_mesh_judges_the_same() {
        let mut positions = vec![
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 2.0],
        ];
        positions.extend(positions.clone().iter().map(|p| p.map(|x| x + 0.5)));
        let tetrahedron = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        let mut triangles: Vec<[u32; 3]> = tetrahedron.to_vec();
        triangles.extend(tetrahedron[..3].iter().map(|t| t.map(|v| v + 4)));
        let mut mesh = Mesh::new(positions, triangles);
        mesh.name = Some("pair".to_owned());
        mesh.notes.push("a note".to_owned());
        let settings = Settings::default();
        let kept = judge(&mesh, &settings);
        let mut freed_mesh = mesh.clone();
        let freed = judge_releasing(&mut freed_mesh, &settings);
        assert_eq!(freed.analysis, kept.analysis);
        assert_eq!(freed.findings, kept.findings);
        assert_eq!(freed.status, kept.status);
        assert_eq!(kept.status, Status::Warn);
        assert_eq!(kept.analysis.faces, 7);
        assert_eq!(kept.analysis.intersecting_components(), Some(1));
        assert_eq!(freed_mesh.positions.capacity(), 0);
        assert_eq!(freed_mesh.triangles.capacity(), 0);
        assert_eq!(freed_mesh.name, mesh.name);
        assert_eq!(freed_mesh.notes, mesh.notes);
        // A mesh without faces stays empty after its faces are freed.
        let mut empty = Mesh::new(vec![[0.0; 3]], Vec::new());
        assert_eq!(judge_releasing(&mut empty, &settings).status, Status::Empty);
    }
}
