//! The config: a TOML schema ([`Config`], every key optional), its discovery (`--config FILE`, else
//! the nearest `meshvet.toml` upward from the current folder, else built-in defaults) and the one merge
//! path that turns defaults + file + command-line flags into resolved [`Settings`].
//!
//! Command-line flags are parsed into the same [`Config`] type as a file, so a flag and a key can
//! never disagree about what they mean. Unknown keys and unknown rule names are errors that say where
//! (file, line) and suggest the closest known name.

use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::formats::Limits;
use crate::rules::{Rule, Severities, Severity};
use crate::topology::{Options, Search};

/// The documented default config: every key with its built-in default and what it does (a test
/// holds it to [`Settings::default`]). `meshvet config --default` prints it.
pub const DEFAULT_TOML: &str = include_str!("../configs/default.toml");

/// The file name looked for upward from the current folder.
pub const FILE_NAME: &str = "meshvet.toml";

/// One layer of configuration, as a TOML file or the command line states it. `None`: not stated.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Rule name -> severity. Names are checked against [`Rule::ALL`] after parsing so an unknown one
    /// can be reported with its line and a suggestion.
    pub rules: Option<BTreeMap<Spanned<String>, Severity>>,
    /// Weld distance; `0` welds only exactly equal positions.
    pub weld_tolerance: Option<f64>,
    /// Globs a file's path must match one of (empty: every file).
    pub include: Option<Vec<String>>,
    /// Globs that leave a file (or a whole folder) out of the scan.
    pub exclude: Option<Vec<String>>,
    pub limits: Option<LimitsConfig>,
    /// Worker threads; `0`: one per core.
    pub jobs: Option<usize>,
    pub repair: Option<RepairConfig>,
    pub intersections: Option<IntersectionsConfig>,
}

/// The `[intersections]` table: the search for [faces that meet](crate::definitions#intersections).
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IntersectionsConfig {
    /// Look for faces that meet at all (`false`: the counts are empty and the two rules silent).
    pub check: Option<bool>,
    /// How many pairs of faces that meet are kept per mesh for the QA page's picture (the counts
    /// stay exact).
    pub kept_pairs: Option<usize>,
    /// How many pairs of faces with overlapping boxes the search looks at per face before it
    /// stops ([`Search::pair_budget`]).
    pub pair_budget: Option<u64>,
}

/// The `[repair]` table: which [repairs](crate::definitions#repairs) `--repair-dir` runs.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RepairConfig {
    pub drop_degenerate_faces: Option<bool>,
    pub drop_duplicate_faces: Option<bool>,
    pub split_nonmanifold: Option<bool>,
    pub orient_faces: Option<bool>,
    pub flip_inside_out: Option<bool>,
    pub fill_holes: Option<bool>,
    pub max_hole_edges: Option<usize>,
    pub drop_unreferenced_vertices: Option<bool>,
}

/// The `[limits]` table.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsConfig {
    pub max_file_bytes: Option<u64>,
    pub max_triangles: Option<u64>,
}

/// Everything a scan needs to know, resolved.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    pub severities: Severities,
    pub weld_tolerance: f64,
    pub include: Vec<String>,
    pub exclude: Vec<String>,
    pub limits: Limits,
    /// Worker threads; `0`: one per core.
    pub jobs: usize,
    /// The repairs `--repair-dir` runs (its weld tolerance follows `weld_tolerance`).
    pub repair: crate::repair::Options,
    /// Where repaired copies go (`--repair-dir`; not a config key). `None`: no repair.
    pub repair_dir: Option<PathBuf>,
    /// The search for faces that meet; `None`: switched off.
    pub intersections: Option<Search>,
}

impl Default for Settings {
    fn default() -> Settings {
        Settings {
            severities: Severities::default(),
            weld_tolerance: 0.0,
            include: Vec::new(),
            exclude: Vec::new(),
            limits: Limits::default(),
            jobs: 0,
            repair: crate::repair::Options::default(),
            repair_dir: None,
            intersections: Some(Search::default()),
        }
    }
}

impl Settings {
    /// These settings with a config layer on top: every key the layer states replaces the value
    /// below it; rule severities are replaced one rule at a time.
    pub fn merge(mut self, layer: &Config) -> Settings {
        if let Some(rules) = &layer.rules {
            for (name, &severity) in rules {
                // Names were checked when the layer was parsed; an unknown one cannot get here.
                if let Some(rule) = Rule::from_name(name.get_ref()) {
                    self.severities.set(rule, severity);
                }
            }
        }
        if let Some(t) = layer.weld_tolerance {
            self.weld_tolerance = t;
        }
        if let Some(globs) = &layer.include {
            self.include = globs.clone();
        }
        if let Some(globs) = &layer.exclude {
            self.exclude = globs.clone();
        }
        if let Some(limits) = &layer.limits {
            if let Some(n) = limits.max_file_bytes {
                self.limits.max_file_bytes = n;
            }
            if let Some(n) = limits.max_triangles {
                self.limits.max_triangles = n;
            }
        }
        if let Some(jobs) = layer.jobs {
            self.jobs = jobs;
        }
        if let Some(x) = &layer.intersections {
            let before = self.intersections.unwrap_or_default();
            let check = x.check.unwrap_or(self.intersections.is_some());
            self.intersections = check.then_some(Search {
                kept_pairs: x.kept_pairs.unwrap_or(before.kept_pairs),
                pair_budget: x.pair_budget.unwrap_or(before.pair_budget),
                ..before
            });
        }
        if let Some(r) = &layer.repair {
            let o = &mut self.repair;
            for (value, slot) in [
                (r.drop_degenerate_faces, &mut o.drop_degenerate_faces),
                (r.drop_duplicate_faces, &mut o.drop_duplicate_faces),
                (r.split_nonmanifold, &mut o.split_nonmanifold),
                (r.orient_faces, &mut o.orient_faces),
                (r.flip_inside_out, &mut o.flip_inside_out),
                (r.fill_holes, &mut o.fill_holes),
                (
                    r.drop_unreferenced_vertices,
                    &mut o.drop_unreferenced_vertices,
                ),
            ] {
                if let Some(v) = value {
                    *slot = v;
                }
            }
            if let Some(n) = r.max_hole_edges {
                o.max_hole_edges = n;
            }
        }
        self
    }

    /// The repair options these settings ask for (welding as the analysis does). A repair runs
    /// only while a rule it answers is on: a rule set to `off` says that defect is fine for these
    /// assets (`hole = "off"` in `configs/realtime.toml`: open meshes are meant), so a copy made
    /// for another finding keeps it (its holes stay open).
    pub fn repair_options(&self) -> crate::repair::Options {
        let on = |rule: Rule| self.severities.get(rule) != Severity::Off;
        let r = &self.repair;
        crate::repair::Options {
            drop_invalid_faces: r.drop_invalid_faces
                && r.drop_degenerate_faces
                && on(Rule::InvalidVertex),
            drop_degenerate_faces: r.drop_degenerate_faces && on(Rule::DegenerateFace),
            // A duplicate face makes its edges non-manifold: dropping it is that edge's repair too.
            drop_duplicate_faces: r.drop_duplicate_faces
                && (on(Rule::DuplicateFace) || on(Rule::NonManifoldEdge)),
            split_nonmanifold: r.split_nonmanifold
                && (on(Rule::NonManifoldEdge) || on(Rule::NonManifoldVertex)),
            orient_faces: r.orient_faces && on(Rule::InconsistentWinding),
            flip_inside_out: r.flip_inside_out && on(Rule::InsideOutShell),
            fill_holes: r.fill_holes && on(Rule::Hole),
            max_hole_edges: r.max_hole_edges,
            drop_unreferenced_vertices: r.drop_unreferenced_vertices
                && on(Rule::UnreferencedVertex),
            weld_tolerance: self.weld_tolerance,
            // The format's, set where the copy is planned.
            single_precision: false,
        }
    }

    /// The analysis options these settings ask for.
    pub fn options(&self) -> Options {
        Options {
            weld_tolerance: self.weld_tolerance,
            intersections: self.intersections,
        }
    }
}

/// A config that cannot be used. The message names the file and line and says what to do.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    pub path: PathBuf,
    /// 1-based line and column, when known.
    pub position: Option<(usize, usize)>,
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some((line, column)) = self.position {
            write!(f, ":{line}:{column}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for ConfigError {}

impl Config {
    /// Parses and checks a config file's text. `path` is only used in error messages.
    pub fn parse(text: &str, path: &Path) -> Result<Config, ConfigError> {
        let error = |span: Option<Range<usize>>, message: String| ConfigError {
            path: path.to_owned(),
            position: span.map(|s| position(text, s.start)),
            message,
        };
        let config: Config = toml::from_str(text).map_err(|e| {
            let message = e
                .message()
                .trim_end()
                .replace("unknown field", "unknown key");
            let explained = match e.span().and_then(|s| key_at(text, s.start)) {
                Some(key) => explain_value(&message, &key),
                None => message.clone(),
            };
            let message = match suggest_for_unknown_field(&message) {
                Some(known) => format!("{explained}; did you mean `{known}`?"),
                None => explained,
            };
            error(e.span(), message)
        })?;
        if let Some(tolerance) = config.weld_tolerance {
            if !(tolerance >= 0.0 && tolerance.is_finite()) {
                return Err(error(
                    None,
                    format!("weld_tolerance must be a finite number >= 0, not {tolerance}"),
                ));
            }
        }
        if config
            .intersections
            .as_ref()
            .is_some_and(|x| x.pair_budget == Some(0))
        {
            // The search spends its budget in batches, so a budget of 0 would never stop it.
            return Err(error(
                None,
                "`[intersections] pair_budget` must be at least 1 (pairs looked at per face); to \
                 skip the search, set `check = false`"
                    .into(),
            ));
        }
        for name in config.rules.iter().flat_map(|rules| rules.keys()) {
            if Rule::from_name(name.get_ref()).is_none() {
                let names = Rule::ALL.map(Rule::name);
                let hint = match closest(name.get_ref(), &names) {
                    Some(known) => format!("did you mean `{known}`?"),
                    None => format!("known rules: {}", names.join(", ")),
                };
                return Err(error(
                    Some(name.span()),
                    format!("unknown rule `{}` in [rules]: {hint}", name.get_ref()),
                ));
            }
        }
        Ok(config)
    }

    /// Reads and parses a config file.
    pub fn read(path: &Path) -> Result<Config, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
            path: path.to_owned(),
            position: None,
            message: format!("cannot read the config: {e}"),
        })?;
        Config::parse(&text, path)
    }
}

/// The nearest `meshvet.toml` in `start` or a folder above it.
pub fn discover(start: &Path) -> Option<PathBuf> {
    start
        .ancestors()
        .map(|dir| dir.join(FILE_NAME))
        .find(|candidate| candidate.is_file())
}

/// The settings for a run: built-in defaults, then the config file (`explicit`, else the one
/// [`discover`] finds from `cwd`), then the command-line layer. Returns the config file used, if any.
pub fn resolve(
    explicit: Option<&Path>,
    cwd: &Path,
    command_line: &Config,
) -> Result<(Settings, Option<PathBuf>), ConfigError> {
    let file = match explicit {
        Some(path) => Some(path.to_owned()),
        None => discover(cwd),
    };
    let mut settings = Settings::default();
    if let Some(path) = &file {
        settings = settings.merge(&Config::read(path)?);
    }
    Ok((settings.merge(command_line), file))
}

/// 1-based line and column of a byte offset.
fn position(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// The key whose value starts at byte `offset` (`hole`, or `[rules] hole` inside a table), read
/// from the text: the part of the line before its `=`.
fn key_at(text: &str, offset: usize) -> Option<String> {
    let before = text.get(..offset)?;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let (key, _) = text[line_start..].split_once('=')?;
    let key = key.trim().trim_matches('"');
    if key.is_empty() || key.contains(['[', '#']) {
        return None;
    }
    let table = before[..line_start]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .map(|l| format!("{} ", l.split('#').next().unwrap_or(l).trim()));
    Some(format!("{}{key}", table.unwrap_or_default()))
}

/// serde's message about a value of `key` in words a config's author can act on: the allowed
/// values and the closest one for a misspelt word, the type wanted for a value of another type.
fn explain_value(message: &str, key: &str) -> String {
    if let Some(rest) = message.strip_prefix("unknown variant `") {
        if let Some((value, expected)) = rest.split_once('`') {
            let known: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
            let hint = match closest(value, &known) {
                Some(k) => format!("; did you mean `{k}`?"),
                None => String::new(),
            };
            return format!(
                "`{key}` cannot be \"{value}\": it takes {}{hint}",
                known
                    .iter()
                    .map(|k| format!("\"{k}\""))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    if let Some(rest) = message.strip_prefix("invalid type: ") {
        if let Some((found, wanted)) = rest.split_once(", expected ") {
            let wanted = match wanted.trim() {
                "usize" | "u64" | "u32" => "a whole number (0 or more)",
                "f64" | "f32" => "a number",
                "a boolean" | "bool" => "true or false",
                "a sequence" => "a list (`[\"...\", ...]`)",
                "a string" => "text in quotes",
                other => other,
            };
            return format!("`{key}` must be {wanted}, not {found}");
        }
    }
    format!("`{key}`: {message}")
}

/// For serde's "unknown field `x`, expected one of `a`, `b`" message (with "key" for "field"): the closest expected name.
fn suggest_for_unknown_field(message: &str) -> Option<String> {
    let rest = message.strip_prefix("unknown key `")?;
    let (field, expected) = rest.split_once('`')?;
    let known: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
    closest(field, &known).map(str::to_owned)
}

/// The known name closest to `name` by edit distance, if it is close enough to be a typo (for
/// the command line's flags, as for config keys and rule names).
pub fn suggest<'a>(name: &str, known: &[&'a str]) -> Option<&'a str> {
    closest(name, known)
}

/// The known name closest to `name` by edit distance, if it is close enough to be a typo, ignoring
/// case (`HOLE`): within a third of its length (at least 2), or a short form or plural of it
/// (`warn` for `warning`, `cavities` for `cavity`: the names share all but the known name's last
/// letter, and four letters at least).
fn closest<'a>(name: &str, known: &[&'a str]) -> Option<&'a str> {
    let name = name.to_lowercase();
    let close = |k: &str, d: usize| {
        let shared = name
            .chars()
            .zip(k.chars())
            .take_while(|(a, b)| a == b)
            .count();
        let short = name.chars().count().min(k.chars().count());
        d <= 2.max(k.len() / 3) || (shared >= 4 && shared + 1 >= short)
    };
    known
        .iter()
        .map(|k| (edit_distance(&name, k), *k))
        .filter(|&(d, k)| close(k, d))
        .min()
        .map(|(_, k)| k)
}

/// Levenshtein distance over chars.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (diagonal + usize::from(ca != cb))
                .min(above + 1)
                .min(row[j] + 1);
            diagonal = above;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Config, ConfigError> {
        Config::parse(text, Path::new("meshvet.toml"))
    }

    #[test]
    fn edit_distance_counts_single_edits() {
        assert_eq!(edit_distance("hole", "hole"), 0);
        assert_eq!(edit_distance("holes", "hole"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
    }

    #[test]
    fn unknown_rule_names_its_line_and_the_closest_rule() {
        let err =
            parse("weld_tolerance = 0.0\n[rules]\nnon-manifold-edges = \"warning\"\n").unwrap_err();
        assert_eq!(err.position, Some((3, 1)));
        assert!(
            err.message.contains("did you mean `non-manifold-edge`?"),
            "{}",
            err.message
        );
        assert!(err
            .to_string()
            .starts_with("meshvet.toml:3:1: unknown rule"));
    }

    #[test]
    fn unknown_key_suggests_the_closest_key() {
        let err = parse("\n\nweld_tolerence = 0.1\n").unwrap_err();
        assert_eq!(err.position.map(|p| p.0), Some(3));
        assert!(
            err.message.contains("did you mean `weld_tolerance`?"),
            "{}",
            err.message
        );
        let err = parse("[limits]\nmax_triangle = 5\n").unwrap_err();
        assert!(
            err.message.contains("did you mean `max_triangles`?"),
            "{}",
            err.message
        );
        // The key is named with its table, suggestion or not.
        let err = parse("[repair]\nfill = true\n").unwrap_err();
        assert!(
            err.message
                .starts_with("`[repair] fill`: unknown key `fill`")
                && err.message.ends_with("did you mean `fill_holes`?"),
            "{}",
            err.message
        );
    }

    /// A repair runs while a rule it answers is on: filling holes only while `hole` is; dropping
    /// duplicate faces while `duplicate-face` or `non-manifold-edge` is (a duplicate makes its
    /// edges non-manifold, and dropping it is their repair: splitting them instead cut one copy
    /// loose and left a hole).
    #[test]
    fn repairs_follow_the_rules_they_answer() {
        let with = |text: &str| {
            Settings::default()
                .merge(&parse(text).unwrap())
                .repair_options()
        };
        assert!(with("").fill_holes && with("").drop_duplicate_faces);
        assert!(!with("[rules]\nhole = \"off\"\n").fill_holes);
        assert!(with("[rules]\nduplicate-face = \"off\"\n").drop_duplicate_faces);
        let both = with("[rules]\nduplicate-face = \"off\"\nnon-manifold-edge = \"off\"\n");
        assert!(!both.drop_duplicate_faces);
        assert!(both.split_nonmanifold, "non-manifold-vertex is still on");
    }

    /// A pair budget of 0 would stop nothing (the search spends it in batches): refused, saying
    /// how to skip the search.
    #[test]
    fn a_pair_budget_of_zero_is_refused() {
        let err = parse("[intersections]\npair_budget = 0\n").unwrap_err();
        assert!(err.message.contains("at least 1"), "{}", err.message);
        assert!(err.message.contains("check = false"), "{}", err.message);
        assert!(parse("[intersections]\npair_budget = 1\n").is_ok());
    }

    /// Short forms, plurals and capitals are typos too: each gets the name meant.
    #[test]
    fn short_forms_plurals_and_capitals_get_a_suggestion() {
        for (text, meant) in [
            ("[rules]\nhole = \"warn\"\n", "warning"),
            ("[rules]\nhole = \"Error\"\n", "error"),
            ("[rules]\ncavities = \"error\"\n", "cavity"),
            ("[rules]\nHOLE = \"error\"\n", "hole"),
            (
                "[rules]\nself-intersections = \"error\"\n",
                "self-intersection",
            ),
        ] {
            let err = parse(text).unwrap_err();
            assert!(
                err.message.contains(&format!("did you mean `{meant}`?")),
                "{text}: {}",
                err.message
            );
        }
        // Not everything is close: no suggestion for a word unlike any name.
        let err = parse("[rules]\nhole = \"maybe\"\n").unwrap_err();
        assert!(!err.message.contains("did you mean"), "{}", err.message);
    }

    #[test]
    fn bad_severity_is_an_error() {
        let err = parse("[rules]\nhole = \"fatal\"\n").unwrap_err();
        assert_eq!(err.position.map(|p| p.0), Some(2));
    }

    /// `[intersections] check = false` switches the search off; `kept_pairs` alone keeps it on.
    #[test]
    fn the_intersection_search_can_be_switched_off_or_capped() {
        let off = Settings::default().merge(&parse("[intersections]\ncheck = false\n").unwrap());
        assert_eq!(off.intersections, None);
        assert_eq!(off.options().intersections, None);
        let capped =
            Settings::default().merge(&parse("[intersections]\nkept_pairs = 5\n").unwrap());
        assert_eq!(capped.intersections.map(|s| s.kept_pairs), Some(5));
        assert_eq!(
            Settings::default().intersections.map(|s| s.kept_pairs),
            Some(100)
        );
        // A later layer that sets one key keeps what an earlier one set of the other.
        let budget = capped.merge(
            &parse(
                "[intersections]
pair_budget = 7
",
            )
            .unwrap(),
        );
        assert_eq!(
            budget.intersections.map(|s| (s.kept_pairs, s.pair_budget)),
            Some((5, 7))
        );
    }

    /// A misspelt value names its key, the values it takes and the closest one; a value of the
    /// wrong type names its key and the type wanted.
    #[test]
    fn bad_values_name_their_key_and_what_it_takes() {
        let err = parse("[rules]\nhole = \"erorr\"\n").unwrap_err();
        assert_eq!(
            err.message,
            "`[rules] hole` cannot be \"erorr\": it takes \"off\", \"warning\", \"error\"; did you \
             mean `error`?"
        );
        let err = parse("weld_tolerance = 0.0\njobs = \"two\"\n").unwrap_err();
        assert_eq!(err.position.map(|p| p.0), Some(2));
        assert_eq!(
            err.message,
            "`jobs` must be a whole number (0 or more), not string \"two\""
        );
        let err = parse("[repair]\nfill_holes = 1\n").unwrap_err();
        assert_eq!(
            err.message,
            "`[repair] fill_holes` must be true or false, not integer `1`"
        );
    }

    #[test]
    fn layers_override_in_order() {
        let file =
            parse("jobs = 3\nexclude = [\"**/tmp/**\"]\n[rules]\nhole = \"error\"\n").unwrap();
        let flags = Config {
            jobs: Some(1),
            ..Config::default()
        };
        let settings = Settings::default().merge(&file).merge(&flags);
        assert_eq!(settings.jobs, 1);
        assert_eq!(settings.exclude, ["**/tmp/**"]);
        assert_eq!(settings.severities.get(Rule::Hole), Severity::Error);
        assert_eq!(settings.severities.get(Rule::Cavity), Severity::Off);
    }

    fn shipped(name: &str) -> Settings {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("configs")
            .join(name);
        let config = Config::read(&path).unwrap_or_else(|e| panic!("{e}"));
        Settings::default().merge(&config)
    }

    #[test]
    fn default_toml_states_every_key_with_its_built_in_default() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/default.toml");
        let config = Config::read(&path).unwrap_or_else(|e| panic!("{e}"));
        // Start from settings that differ from the defaults everywhere: only a file that states
        // every key, with the default value, turns them back into the defaults.
        let mut different = Settings {
            weld_tolerance: 1.0,
            include: vec!["x".into()],
            exclude: vec!["y".into()],
            limits: Limits {
                max_file_bytes: 1,
                max_triangles: 1,
            },
            jobs: 7,
            repair: crate::repair::Options {
                // No key of its own: the file cannot set it.
                drop_invalid_faces: true,
                drop_degenerate_faces: false,
                drop_duplicate_faces: false,
                split_nonmanifold: false,
                orient_faces: false,
                flip_inside_out: false,
                fill_holes: false,
                max_hole_edges: 3,
                drop_unreferenced_vertices: false,
                weld_tolerance: 0.0,
                single_precision: false,
            },
            intersections: Some(Search {
                kept_pairs: 1,
                first_only: false,
                pair_budget: 2,
            }),
            ..Settings::default()
        };
        for rule in Rule::ALL {
            let other = match rule.default_severity() {
                Severity::Off => Severity::Error,
                _ => Severity::Off,
            };
            different.severities.set(rule, other);
        }
        assert_eq!(different.merge(&config), Settings::default());
    }

    #[test]
    fn print_and_realtime_configs_say_what_they_promise() {
        let print = shipped("print.toml");
        for rule in [
            Rule::Hole,
            Rule::NonManifoldEdge,
            Rule::NonManifoldVertex,
            Rule::InconsistentWinding,
            Rule::NonOrientable,
            Rule::InsideOutShell,
        ] {
            assert_eq!(print.severities.get(rule), Severity::Error, "{rule}");
        }
        assert_eq!(print.severities.get(Rule::Cavity), Severity::Warning);

        let realtime = shipped("realtime.toml");
        assert_eq!(realtime.severities.get(Rule::Hole), Severity::Off);
        assert_eq!(
            realtime.severities.get(Rule::NonManifoldEdge),
            Severity::Warning
        );
        assert_eq!(
            realtime.severities.get(Rule::NonManifoldVertex),
            Severity::Warning
        );
        assert_eq!(
            realtime.severities.get(Rule::DuplicateFace),
            Severity::Warning
        );
        assert_eq!(
            realtime.severities.get(Rule::InsideOutShell),
            Severity::Error
        );
    }

    #[test]
    fn discovery_finds_the_nearest_file_upward() {
        let dir = tempfile::tempdir().unwrap();
        let deep = dir.path().join("a/b");
        std::fs::create_dir_all(&deep).unwrap();
        assert_eq!(discover(&deep).filter(|p| p.starts_with(dir.path())), None);
        std::fs::write(dir.path().join("a").join(FILE_NAME), "").unwrap();
        assert_eq!(discover(&deep), Some(dir.path().join("a").join(FILE_NAME)));
    }
}
