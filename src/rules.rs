//! Judgement after the facts: the rule table that turns an [`Analysis`] (and the few facts a reader
//! records on a [`Mesh`]) into findings with severities, and the `status` of a report row
//! ([definitions](crate::definitions#report)).
//!
//! A rule is an enum variant. Everything said about it (name, summary, why it matters, how it is
//! repaired, default severity, the finding in words) is its [`Doc`], one `match` arm each; what
//! it counts is [`Rule::count`]. The names are part of the interface (configs and reports use
//! them): never rename one casually.

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
    SelfIntersection,
    IntersectingComponents,
}

impl Rule {
    pub const ALL: [Rule; 15] = [
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
        Rule::SelfIntersection,
        Rule::IntersectingComponents,
    ];

    /// Everything meshvet says about the rule.
    pub fn doc(self) -> &'static Doc {
        match self {
            Rule::InvalidVertex => &Doc {
                name: "invalid-vertex",
                summary: "a vertex has a NaN or infinite coordinate; its faces are left out",
                meaning: "A coordinate that is not a number breaks every renderer, exporter and bounding box that touches it; the faces using the vertex cannot be drawn or measured.",
                repair: "Repair drops the faces that use such vertices. The intended position is lost, so fix the exporter or the source file.",
                default: Severity::Error,
                one: "vertex with a NaN or infinite coordinate",
                many: "vertices with NaN or infinite coordinates",
            },
            Rule::DegenerateFace => &Doc {
                name: "degenerate-face",
                summary: "a face has two corners on the same welded vertex",
                meaning: "A face whose corners collapse onto an edge or a point has no area and no normal; it upsets normal and tangent generation.",
                repair: "Repair drops degenerate faces; nothing visible changes.",
                default: Severity::Warning,
                one: "degenerate face",
                many: "degenerate faces",
            },
            Rule::ZeroAreaFace => &Doc {
                name: "zero-area-face",
                summary: "a face has three distinct vertices but (almost) no area",
                meaning: "A sliver face has almost no area: its normal is unstable, it shades badly and it trips booleans and slicers.",
                repair: "Not repaired automatically; collapse the short edge or decimate in a modelling tool.",
                default: Severity::Warning,
                one: "zero-area face",
                many: "zero-area faces",
            },
            Rule::DuplicateFace => &Doc {
                name: "duplicate-face",
                summary: "a face repeats the three vertices of an earlier face",
                meaning: "The same triangle twice flickers (z-fighting) and makes its edges non-manifold.",
                repair: "Repair drops the extra copies and keeps the first.",
                default: Severity::Warning,
                one: "duplicate face",
                many: "duplicate faces",
            },
            Rule::UnreferencedVertex => &Doc {
                name: "unreferenced-vertex",
                summary: "a vertex is used by no face",
                meaning: "Stray vertices waste memory and inflate vertex counts and bounding boxes.",
                repair: "Repair drops vertices no face uses.",
                default: Severity::Warning,
                one: "unreferenced vertex",
                many: "unreferenced vertices",
            },
            Rule::NonManifoldEdge => &Doc {
                name: "non-manifold-edge",
                summary: "an edge is shared by three or more faces",
                meaning: "An edge shared by three or more faces has no clear inside and outside; slicers, booleans, UV unwrapping and light-map bakers fail on it.",
                repair: "Repair splits the edge so each fan of faces gets its own copy; often the cause is duplicated or interpenetrating geometry an artist should remove.",
                default: Severity::Error,
                one: "non-manifold edge",
                many: "non-manifold edges",
            },
            Rule::NonManifoldVertex => &Doc {
                name: "non-manifold-vertex",
                summary: "the faces around a vertex do not form one fan",
                meaning: "Fans of faces touching at a single vertex (a bowtie) break smoothing, half-edge tools and UV unwrapping.",
                repair: "Repair gives each fan its own copy of the vertex.",
                default: Severity::Error,
                one: "non-manifold vertex",
                many: "non-manifold vertices",
            },
            Rule::Hole => &Doc {
                name: "hole",
                summary: "a loop of border edges: the surface is open there",
                meaning: "An open surface has no inside: it cannot be printed, has no volume for physics, and shows gaps from behind.",
                repair: "Repair fills holes up to the configured size; larger openings need an artist (they may be intended).",
                default: Severity::Warning,
                one: "hole",
                many: "holes",
            },
            Rule::InconsistentWinding => &Doc {
                name: "inconsistent-winding",
                summary: "two neighbouring faces wind their shared edge the same way (some faces are flipped); counts the edges of components that can be wound consistently (a non-orientable one's are its own rule's)",
                meaning: "Neighbouring faces disagree about which side is out, so back-face culling hides some of them and lighting flips.",
                repair: "Repair re-orients each component consistently, flipping the faces that disagree with the majority.",
                default: Severity::Error,
                one: "inconsistently wound edge",
                many: "inconsistently wound edges",
            },
            Rule::NonOrientable => &Doc {
                name: "non-orientable",
                summary: "a component cannot be wound consistently at all (Moebius strip, Klein bottle)",
                meaning: "A one-sided surface (Moebius strip, Klein bottle) can never be wound consistently, so it cannot bound a solid.",
                repair: "Not repairable automatically: the surface has to be rebuilt.",
                default: Severity::Error,
                one: "non-orientable component",
                many: "non-orientable components",
            },
            Rule::InsideOutShell => &Doc {
                name: "inside-out-shell",
                summary: "a closed shell faces the wrong way: a solid facing in or a cavity facing out",
                meaning: "A closed shell facing the wrong way renders inside out and has a negative volume, which breaks printing and physics.",
                repair: "Repair flips every face of the shell.",
                default: Severity::Error,
                one: "inside-out shell",
                many: "inside-out shells",
            },
            Rule::Cavity => &Doc {
                name: "cavity",
                summary: "a closed shell lies inside another one: a void inside the material",
                meaning: "A shell inside another encloses a void: right for a hollow print, surprising for a mass estimate or a game asset.",
                repair: "Not a defect to repair; delete the inner shell if the void is not wanted.",
                default: Severity::Off,
                one: "cavity",
                many: "cavities",
            },
            Rule::MirroredInstance => &Doc {
                name: "mirrored-instance",
                summary: "a glTF node or 3MF placement uses the mesh with a mirroring transform, so its winding flips",
                meaning: "A placement with a mirroring (negative-determinant) transform flips the mesh's winding on screen or on the print bed unless the engine or slicer compensates.",
                repair: "Apply the mirroring to the geometry when exporting, or check that the engine handles negative scale.",
                default: Severity::Warning,
                one: "mirrored instance",
                many: "mirrored instances",
            },
            Rule::SelfIntersection => &Doc {
                name: "self-intersection",
                summary: "two faces of one connected part cross, touch or overlap, other than along an edge or at a vertex they share",
                meaning: "A surface that passes through itself has no well-defined inside: slicers print or skip the overlap unpredictably, booleans and remeshing fail, and a volume or mass estimate is wrong.",
                repair: "Not repaired automatically: move or remesh the crossing faces in a modelling tool (or run a remesher).",
                default: Severity::Warning,
                one: "pair of faces that meet within a part",
                many: "pairs of faces that meet within a part",
            },
            Rule::IntersectingComponents => &Doc {
                name: "intersecting-components",
                summary: "two separate parts of the mesh cross or touch each other",
                meaning: "Separate parts that overlap (a button sunk into a body, two boxes pushed together) print as one only if the slicer unions them; their volume counts the overlap twice, and nesting cannot say whether one is inside the other.",
                repair: "Not repaired automatically: union the parts (a boolean) or move them apart; harmless for many game assets.",
                default: Severity::Warning,
                one: "pair of parts that meet",
                many: "pairs of parts that meet",
            },
        }
    }

    /// The stable kebab-case name used in configs and reports.
    pub fn name(self) -> &'static str {
        self.doc().name
    }

    /// One line saying what the rule finds.
    pub fn summary(self) -> &'static str {
        self.doc().summary
    }

    /// The severity a rule has when no config says otherwise.
    pub fn default_severity(self) -> Severity {
        self.doc().default
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
            // those); this rule counts those of the components that could be wound consistently.
            Rule::InconsistentWinding => a
                .components
                .iter()
                .filter(|c| c.orientable)
                .map(|c| c.inconsistent_edges)
                .sum(),
            Rule::NonOrientable => a.components.iter().filter(|c| !c.orientable).count(),
            Rule::InsideOutShell => a.inside_out_shells(),
            Rule::Cavity => a.cavities(),
            Rule::MirroredInstance => mesh.mirrored_instances as usize,
            Rule::SelfIntersection => a.self_intersections().unwrap_or(0),
            Rule::IntersectingComponents => a.intersecting_components().unwrap_or(0),
        }
    }

    /// The finding in words, e.g. `3 non-manifold edges`.
    pub fn describe(self, count: usize) -> String {
        let doc = self.doc();
        format!("{count} {}", if count == 1 { doc.one } else { doc.many })
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What meshvet says about one rule, in one place: the config, the reports, the QA page's detail
/// view and `--format lines` all read it from here, and a test holds the README's rule table to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Doc {
    /// The stable kebab-case name used in configs and reports.
    pub name: &'static str,
    /// One line saying what the rule finds.
    pub summary: &'static str,
    /// Why it matters downstream.
    pub meaning: &'static str,
    /// What a repaired copy does about it (or why it does nothing).
    pub repair: &'static str,
    /// The severity when no config says otherwise.
    pub default: Severity,
    /// A finding in words, for one and for several: `non-manifold edge`, `non-manifold edges`.
    pub one: &'static str,
    pub many: &'static str,
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
                message: match (rule, &analysis.intersections) {
                    // How much of the surface is involved, beside the number of pairs.
                    (Rule::SelfIntersection | Rule::IntersectingComponents, Some(i)) => format!(
                        "{} ({} faces meet others)",
                        rule.describe(count),
                        i.involved_faces_in(rule == Rule::SelfIntersection)
                    ),
                    _ => rule.describe(count),
                },
            })
        })
        .collect();
    findings.sort_by_key(|f| std::cmp::Reverse(f.severity));
    findings
}

/// The verdict of one report row ([definitions](crate::definitions#report)).
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

    /// The README's rule table is the rules' docs, row for row, so it cannot drift from them.
    #[test]
    fn the_readme_table_is_the_docs() {
        let readme = include_str!("../README.md");
        let rows: Vec<&str> = readme
            .lines()
            .skip_while(|l| *l != "## Rules")
            .skip_while(|l| !l.starts_with("| rule |"))
            .skip(2)
            .take_while(|l| l.starts_with('|'))
            .collect();
        let expected: Vec<String> = Rule::ALL
            .iter()
            .map(|r| {
                let d = r.doc();
                format!(
                    "| `{}` | {} | {} | {} |",
                    d.name, d.default, d.summary, d.repair
                )
            })
            .collect();
        assert_eq!(rows, expected);
    }

    #[test]
    fn findings_are_worst_first_and_skip_off_rules() {
        let analysis = Analysis {
            degenerate_faces: 2,
            nonmanifold_edges: 1,
            components: vec![Component::with_holes(1)],
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
            inconsistent_edges: 4,
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
        analysis.inconsistent_edges = 7;
        analysis.components.push(Component {
            orientable: true,
            oriented: false,
            inconsistent_edges: 3,
            ..Component::default()
        });
        // Only the orientable component's edges: the strip's are inherent to it.
        assert_eq!(Rule::InconsistentWinding.count(&analysis, &facts), 3);
    }
}
