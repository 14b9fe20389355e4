//! Judgement after the facts: the rule table that turns an [`Analysis`] (and the few facts a reader
//! records on a [`Mesh`]) into findings with severities, and the `status` of a report row (SPEC 9).
//!
//! A rule is an enum variant; its name, summary and default severity come from one `match` each. The
//! names are part of the interface (configs and reports use them): never rename one casually.

use std::fmt;

use serde::Deserialize;

use crate::mesh::Mesh;
use crate::topology::Analysis;

/// How much a finding matters to the user (from the config, else the rule's default).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// Not reported at all.
    Off,
    Warning,
    Error,
}

impl Severity {
    pub fn name(self) -> &'static str {
        match self {
            Severity::Off => "off",
            Severity::Warning => "warning",
            Severity::Error => "error",
        }
    }

    /// The severity with this name.
    pub fn from_name(name: &str) -> Option<Severity> {
        [Severity::Off, Severity::Warning, Severity::Error]
            .into_iter()
            .find(|s| s.name() == name)
    }
}

impl fmt::Display for Severity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Every check meshvet reports. The order of [`Rule::ALL`] is the order findings of equal severity are
/// listed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Rule {
    InvalidVertex,
    DegenerateFace,
    ZeroAreaFace,
    DuplicateFace,
    UnreferencedVertex,
    NonManifoldEdge,
    NonManifoldVertex,
    Hole,
    InconsistentWinding,
    NonOrientable,
    InsideOutShell,
    Cavity,
    MirroredInstance,
}

impl Rule {
    pub const ALL: [Rule; 13] = [
        Rule::InvalidVertex,
        Rule::DegenerateFace,
        Rule::ZeroAreaFace,
        Rule::DuplicateFace,
        Rule::UnreferencedVertex,
        Rule::NonManifoldEdge,
        Rule::NonManifoldVertex,
        Rule::Hole,
        Rule::InconsistentWinding,
        Rule::NonOrientable,
        Rule::InsideOutShell,
        Rule::Cavity,
        Rule::MirroredInstance,
    ];

    /// The stable kebab-case name used in configs and reports.
    pub fn name(self) -> &'static str {
        match self {
            Rule::InvalidVertex => "invalid-vertex",
            Rule::DegenerateFace => "degenerate-face",
            Rule::ZeroAreaFace => "zero-area-face",
            Rule::DuplicateFace => "duplicate-face",
            Rule::UnreferencedVertex => "unreferenced-vertex",
            Rule::NonManifoldEdge => "non-manifold-edge",
            Rule::NonManifoldVertex => "non-manifold-vertex",
            Rule::Hole => "hole",
            Rule::InconsistentWinding => "inconsistent-winding",
            Rule::NonOrientable => "non-orientable",
            Rule::InsideOutShell => "inside-out-shell",
            Rule::Cavity => "cavity",
            Rule::MirroredInstance => "mirrored-instance",
        }
    }

    /// One line saying what the rule finds.
    pub fn summary(self) -> &'static str {
        match self {
            Rule::InvalidVertex => "a vertex has a NaN or infinite coordinate; its faces are left out",
            Rule::DegenerateFace => "a face has two corners on the same welded vertex",
            Rule::ZeroAreaFace => "a face has three distinct vertices but (almost) no area",
            Rule::DuplicateFace => "a face repeats the three vertices of an earlier face",
            Rule::UnreferencedVertex => "a vertex is used by no face",
            Rule::NonManifoldEdge => "an edge is shared by three or more faces",
            Rule::NonManifoldVertex => "the faces around a vertex do not form one fan",
            Rule::Hole => "a loop of border edges: the surface is open there",
            Rule::InconsistentWinding => {
                "two neighbouring faces wind their shared edge the same way (some faces are flipped)"
            }
            Rule::NonOrientable => {
                "a component cannot be wound consistently at all (Moebius strip, Klein bottle)"
            }
            Rule::InsideOutShell => "a closed shell faces the wrong way: a solid facing in or a cavity facing out",
            Rule::Cavity => "a closed shell lies inside another one: a void inside the material",
            Rule::MirroredInstance => {
                "a glTF node instances the mesh with a mirroring transform, so its winding flips on screen"
            }
        }
    }

    /// The severity a rule has when no config says otherwise.
    pub fn default_severity(self) -> Severity {
        match self {
            Rule::InvalidVertex => Severity::Error,
            Rule::DegenerateFace => Severity::Warning,
            Rule::ZeroAreaFace => Severity::Warning,
            Rule::DuplicateFace => Severity::Warning,
            Rule::UnreferencedVertex => Severity::Warning,
            Rule::NonManifoldEdge => Severity::Error,
            Rule::NonManifoldVertex => Severity::Error,
            Rule::Hole => Severity::Warning,
            Rule::InconsistentWinding => Severity::Error,
            Rule::NonOrientable => Severity::Error,
            Rule::InsideOutShell => Severity::Error,
            Rule::Cavity => Severity::Off,
            Rule::MirroredInstance => Severity::Warning,
        }
    }

    /// The rule with this name.
    pub fn from_name(name: &str) -> Option<Rule> {
        Rule::ALL.into_iter().find(|r| r.name() == name)
    }

    /// How many times the rule is broken in a mesh (0: not broken).
    pub fn count(self, analysis: &Analysis, mesh: &MeshFacts) -> usize {
        let a = analysis;
        match self {
            Rule::InvalidVertex => a.invalid_vertices,
            Rule::DegenerateFace => a.degenerate_faces,
            Rule::ZeroAreaFace => a.zero_area_faces,
            Rule::DuplicateFace => a.duplicate_faces,
            Rule::UnreferencedVertex => a.unreferenced_vertices,
            Rule::NonManifoldEdge => a.nonmanifold_edges,
            Rule::NonManifoldVertex => a.nonmanifold_vertices,
            Rule::Hole => a.holes(),
            // Inconsistent edges are inherent to a non-orientable component (non-orientable reports
            // those); this rule fires when some component could be wound consistently but is not.
            Rule::InconsistentWinding => {
                let fixable = a.components.iter().any(|c| c.orientable && !c.oriented);
                if fixable {
                    a.inconsistent_edges
                } else {
                    0
                }
            }
            Rule::NonOrientable => a.components.iter().filter(|c| !c.orientable).count(),
            Rule::InsideOutShell => a.inside_out_shells(),
            Rule::Cavity => a.cavities(),
            Rule::MirroredInstance => mesh.mirrored_instances as usize,
        }
    }

    /// The finding in words, e.g. `3 non-manifold edges`.
    pub fn describe(self, count: usize) -> String {
        let (one, many) = match self {
            Rule::InvalidVertex => (
                "vertex with a NaN or infinite coordinate",
                "vertices with NaN or infinite coordinates",
            ),
            Rule::DegenerateFace => ("degenerate face", "degenerate faces"),
            Rule::ZeroAreaFace => ("zero-area face", "zero-area faces"),
            Rule::DuplicateFace => ("duplicate face", "duplicate faces"),
            Rule::UnreferencedVertex => ("unreferenced vertex", "unreferenced vertices"),
            Rule::NonManifoldEdge => ("non-manifold edge", "non-manifold edges"),
            Rule::NonManifoldVertex => ("non-manifold vertex", "non-manifold vertices"),
            Rule::Hole => ("hole", "holes"),
            Rule::InconsistentWinding => {
                ("inconsistently wound edge", "inconsistently wound edges")
            }
            Rule::NonOrientable => ("non-orientable component", "non-orientable components"),
            Rule::InsideOutShell => ("inside-out shell", "inside-out shells"),
            Rule::Cavity => ("cavity", "cavities"),
            Rule::MirroredInstance => ("mirrored instance", "mirrored instances"),
        };
        format!("{count} {}", if count == 1 { one } else { many })
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What the rules need to know about a mesh besides its analysis.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MeshFacts {
    pub mirrored_instances: u32,
}

impl MeshFacts {
    pub fn of(mesh: &Mesh) -> MeshFacts {
        MeshFacts {
            mirrored_instances: mesh.mirrored_instances,
        }
    }
}

/// The severity of every rule: the defaults, overridden by the config.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Severities([Severity; Rule::ALL.len()]);

impl Default for Severities {
    fn default() -> Severities {
        Severities(Rule::ALL.map(Rule::default_severity))
    }
}

impl Severities {
    pub fn get(&self, rule: Rule) -> Severity {
        self.0[rule as usize]
    }

    pub fn set(&mut self, rule: Rule, severity: Severity) {
        self.0[rule as usize] = severity;
    }
}

/// One rule broken in one mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    pub rule: Rule,
    pub severity: Severity,
    pub count: usize,
    /// The count in words (`3 non-manifold edges`).
    pub message: String,
}

/// The findings of every rule that is broken and not `off`, worst first (errors, then warnings; rules
/// of equal severity in [`Rule::ALL`] order).
pub fn check(analysis: &Analysis, mesh: &MeshFacts, severities: &Severities) -> Vec<Finding> {
    let mut findings: Vec<Finding> = Rule::ALL
        .into_iter()
        .filter(|&rule| severities.get(rule) != Severity::Off)
        .filter_map(|rule| {
            let count = rule.count(analysis, mesh);
            (count > 0).then(|| Finding {
                rule,
                severity: severities.get(rule),
                count,
                message: rule.describe(count),
            })
        })
        .collect();
    findings.sort_by_key(|f| std::cmp::Reverse(f.severity));
    findings
}

/// The verdict of one report row (SPEC 9).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Status {
    Pass,
    Warn,
    Fail,
    /// The file could not be read (or its reader panicked).
    Error,
    /// The file or mesh holds no triangles.
    Empty,
}

impl Status {
    /// The status of a mesh that was read and holds triangles.
    pub fn of(findings: &[Finding]) -> Status {
        match findings.iter().map(|f| f.severity).max() {
            Some(Severity::Error) => Status::Fail,
            Some(Severity::Warning) => Status::Warn,
            _ => Status::Pass,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Status::Pass => "pass",
            Status::Warn => "warn",
            Status::Fail => "fail",
            Status::Error => "error",
            Status::Empty => "empty",
        }
    }

    /// The status with this name (as a report writes it).
    pub fn from_name(name: &str) -> Option<Status> {
        [
            Status::Pass,
            Status::Warn,
            Status::Fail,
            Status::Error,
            Status::Empty,
        ]
        .into_iter()
        .find(|s| s.name() == name)
    }

    /// Whether the row makes the scan exit with code 1.
    pub fn is_failure(self) -> bool {
        matches!(self, Status::Fail | Status::Error)
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::Component;

    #[test]
    fn names_are_unique_kebab_case_and_round_trip() {
        for rule in Rule::ALL {
            let name = rule.name();
            assert!(
                name.chars().all(|c| c.is_ascii_lowercase() || c == '-'),
                "{name}"
            );
            assert_eq!(Rule::from_name(name), Some(rule));
            assert_eq!(
                Rule::ALL[rule as usize],
                rule,
                "ALL is in declaration order"
            );
        }
    }

    #[test]
    fn findings_are_worst_first_and_skip_off_rules() {
        let analysis = Analysis {
            degenerate_faces: 2,
            nonmanifold_edges: 1,
            components: vec![Component {
                holes: 1,
                orientable: true,
                oriented: true,
                ..Component::default()
            }],
            ..Analysis::default()
        };
        let mut severities = Severities::default();
        severities.set(Rule::Hole, Severity::Off);
        let findings = check(&analysis, &MeshFacts::default(), &severities);
        let got: Vec<_> = findings.iter().map(|f| (f.rule, f.count)).collect();
        assert_eq!(got, [(Rule::NonManifoldEdge, 1), (Rule::DegenerateFace, 2)]);
        assert_eq!(findings[1].message, "2 degenerate faces");
        assert_eq!(Status::of(&findings), Status::Fail);
        assert_eq!(Status::of(&findings[1..]), Status::Warn);
        assert_eq!(Status::of(&[]), Status::Pass);
    }

    #[test]
    fn winding_is_judged_only_where_it_can_be_fixed() {
        let mobius = Component {
            orientable: false,
            oriented: false,
            ..Component::default()
        };
        let mut analysis = Analysis {
            inconsistent_edges: 4,
            components: vec![mobius.clone()],
            ..Analysis::default()
        };
        let facts = MeshFacts::default();
        assert_eq!(Rule::InconsistentWinding.count(&analysis, &facts), 0);
        assert_eq!(Rule::NonOrientable.count(&analysis, &facts), 1);
        analysis.components.push(Component {
            orientable: true,
            oriented: false,
            ..Component::default()
        });
        assert_eq!(Rule::InconsistentWinding.count(&analysis, &facts), 4);
    }
}
