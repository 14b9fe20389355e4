//! OBJ (+MTL) reader: our own line parser for the geometry, tobj only for the material library.
//!
//! tobj drops unreferenced vertices, renumbers them by first use, splits by `usemtl` and cannot
//! name a line; a validator needs the file's own vertex list. So `v` lines become
//! `Mesh::positions` in file order, as stored (NaN kept), and `f` lines become triangles indexing
//! them (1-based, negative = relative, polygons split by [`crate::geometry::polygon`]). One file is
//! one mesh whatever its `o`/`g`/`usemtl`. `vt`/`vn`/`o`/`g`/`s`/`usemtl` play no part in the
//! topology; a repairing scan keeps them (with each face's polygon and corners) for the writer of
//! the repaired copy ([`read_retaining`]); points and lines are counted into notes.
//!
//! `mtllib` files are read with tobj under `catch_unwind` (it panics on short colour lines), only
//! when they are regular files inside the scanned tree (after symbolic links too,
//! [`super::contain`]) and within `limits.max_file_bytes`; each distinct library is read once
//! however many lines name it, and any MTL trouble is a note (the first [`MTL_NOTES`], then one
//! for the rest), never an error. Binary content is refused ([`super::text`]). The common
//! `v x y z` and `f a b c` lines are read in one pass over their bytes; anything else in them sends
//! the line to the word-by-word reader, which owns every message.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

use super::contain::{self, Location, Unresolved};
use super::text::{self, Binary};
use super::{Kept, Limits, ReadContext, ReadError, Retained, SideFiles};
use crate::geometry::polygon::{self, SplitTally};
use crate::mesh::Mesh;

pub fn read(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    read_with(path, cx, None).map(|(meshes, _)| meshes)
}

/// [`read`], also keeping the [`Detail`] the writer of a repaired copy needs (the scan of a
/// repairing run: one read of the file instead of two).
pub(crate) fn read_retaining(
    path: &Path,
    cx: &ReadContext,
) -> Result<(Vec<Mesh>, Retained), ReadError> {
    let (meshes, detail) = read_with(path, cx, Some(Box::default()))?;
    Ok((meshes, Retained(Kept::Obj(detail.unwrap_or_default()))))
}

/// The material libraries an OBJ file names, found as the reader finds them.
pub(crate) const SIDE_FILES: SideFiles = SideFiles {
    names: mtllib_names,
    resolve: |name, location| library(name, location).ok(),
};

/// The names after `mtllib`: the whole rest of the line and each word of it (the reader accepts a
/// name with spaces and several names).
fn mtllib_names(bytes: &[u8]) -> Vec<String> {
    let bytes = &*text::lf_line_ends(bytes);
    let mut names = Vec::new();
    let mut take = |line: &[u8]| {
        let Some(rest) = line.trim_ascii_start().strip_prefix(b"mtllib") else {
            return;
        };
        if !rest.first().is_some_and(u8::is_ascii_whitespace) {
            return;
        }
        let rest = String::from_utf8_lossy(rest);
        let rest = rest.trim();
        names.push(rest.to_owned());
        names.extend(rest.split_ascii_whitespace().map(str::to_owned));
    };
    match std::str::from_utf8(bytes) {
        // The common case: a fast substring search, then only the lines that mention `mtllib`.
        Ok(text) => {
            for (at, _) in text.match_indices("mtllib") {
                let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
                let end = text[at..].find('\n').map_or(text.len(), |i| at + i);
                if text[start..at].trim_ascii().is_empty() {
                    take(&text.as_bytes()[start..end]);
                }
            }
        }
        Err(_) => bytes.split(|&b| b == b'\n').for_each(take),
    }
    names
}

fn read_with(
    path: &Path,
    cx: &ReadContext,
    detail: Option<Box<Detail>>,
) -> Result<(Vec<Mesh>, Option<Box<Detail>>), ReadError> {
    let bytes = super::read_bytes(path, &cx.limits)?;
    let mut parsed = parse_with(&bytes, cx, detail)?;
    if let Some(detail) = parsed.detail.as_mut() {
        detail.mtllibs = parsed
            .mtllibs
            .iter()
            .map(|(name, _)| name.clone())
            .collect();
    }
    let detail = parsed.detail;
    let mut mesh = parsed.mesh;
    if parsed.mtllibs.is_empty() {
        return Ok((vec![mesh], detail));
    }
    let location = match Location::new(path, &cx.root) {
        Ok(location) => location,
        Err(e) => {
            mesh.notes.push(format!(
                "material libraries not read ({e}); materials do not affect the checks"
            ));
            return Ok((vec![mesh], detail));
        }
    };
    // Each distinct name is looked up once and each file read and parsed once, however many
    // lines name it (or spell its path differently): a library named on every one of 20,000
    // lines was read and parsed 20,000 times (53 s for a 260 KB OBJ), and noted as often.
    let mut lines_seen = HashSet::new();
    let mut names_seen = HashSet::new();
    let mut files_read = HashSet::new();
    let (mut noted, mut more) = (0, (0u64, 0u64));
    for (name, line) in &parsed.mtllibs {
        if !lines_seen.insert(name.as_str()) {
            continue;
        }
        for name in library_names(name, &location) {
            if !names_seen.insert(name) {
                continue;
            }
            if let Some(note) = check_mtl(&location, name, *line, &cx.limits, &mut files_read) {
                if noted < MTL_NOTES {
                    noted += 1;
                    mesh.notes.push(note);
                } else {
                    count(&mut more, *line);
                }
            }
        }
    }
    if more.0 > 0 {
        mesh.notes.push(format!(
            "{} more material libraries were not read or have problems (the first named on \
             line {}); materials do not affect the checks",
            more.0, more.1
        ));
    }
    Ok((vec![mesh], detail))
}

/// How many notes the material libraries of one file may give before the rest are summed up in
/// one (a file naming 200,000 missing libraries made a 28 MB message).
const MTL_NOTES: usize = 20;

/// The files an `mtllib` line names: `mtllib a.mtl b.mtl` names several, but a single name with
/// spaces is common too (it wins when such a file exists).
pub(crate) fn library_names<'a>(name: &'a str, location: &Location) -> Vec<&'a str> {
    if name.contains(char::is_whitespace) && library(name, location).is_err() {
        name.split_ascii_whitespace().collect()
    } else {
        vec![name]
    }
}

/// Why a material library is not read.
#[derive(Debug)]
pub(crate) enum NotRead {
    /// Absolute, with a drive or scheme, or climbing out of the scanned tree: never looked at.
    Refused,
    Unresolved(Unresolved),
}

/// The real path of material library `name`, by the rule every external file obeys
/// ([`contain`]): relative, inside the scanned tree before and after symbolic links, and a regular
/// file. Opens nothing. The cache hashes dependencies through this too.
pub(crate) fn library(name: &str, location: &Location) -> Result<PathBuf, NotRead> {
    if name.contains(':') {
        return Err(NotRead::Refused);
    }
    let joined = contain::join(name, location).map_err(|_| NotRead::Refused)?;
    contain::resolve(&joined, location).map_err(NotRead::Unresolved)
}

/// The geometry of a file and the `mtllib` names it asks for (with their lines).
#[derive(Debug)]
struct Parsed {
    mesh: Mesh,
    mtllibs: Vec<(String, u64)>,
    detail: Option<Box<Detail>>,
}

/// Counts of skipped statements: keyword -> (lines, first line).
type Skipped = BTreeMap<String, (u64, u64)>;

/// Parses OBJ bytes. Errors name the line.
#[cfg(test)]
fn parse(bytes: &[u8], cx: &ReadContext) -> Result<Parsed, ReadError> {
    parse_with(bytes, cx, None)
}

/// What a repaired copy needs beyond the geometry (a "full" read, [`read_full`]): texture
/// coordinates, normals, each polygon's corners and the triangles it became, and the
/// `o`/`g`/`s`/`usemtl` state each polygon was read in. The scan never pays for this.
#[derive(Debug, Default)]
pub(crate) struct Detail {
    /// Text after `x y z` on each `v` line (`w`, vertex colours), trimmed; usually empty.
    pub vertex_extra: Vec<String>,
    /// Text after `vt` on each `vt` line.
    pub texcoords: Vec<String>,
    /// Text after `vn` on each `vn` line.
    pub normals: Vec<String>,
    pub faces: Vec<Face>,
    /// The corners of every face, face after face (one array: a million faces are not a million
    /// allocations).
    pub corners: Vec<FaceCorner>,
    /// `o`, `g`, `s`, `usemtl` as they were for each face ([`Face::state`]).
    pub states: Vec<State>,
    /// `mtllib` arguments, in file order.
    pub mtllibs: Vec<String>,
}

/// One `f` line: its corners are `Detail::corners[first..first + len]`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Face {
    pub first: u32,
    pub len: u32,
    /// Index into [`Detail::states`].
    pub state: u32,
}

/// v, vt and vn of a face corner, 0-based; a `vt`/`vn` that is absent or out of range is
/// [`FaceCorner::NONE`] (12 bytes a corner: a million faces' corners are 36 MB, not 60).
#[derive(Debug, Clone, Copy)]
pub(crate) struct FaceCorner {
    pub v: u32,
    vt: u32,
    vn: u32,
}

impl FaceCorner {
    const NONE: u32 = u32::MAX;

    fn new(v: u32, vt: Option<u32>, vn: Option<u32>) -> FaceCorner {
        FaceCorner {
            v,
            vt: vt.unwrap_or(Self::NONE),
            vn: vn.unwrap_or(Self::NONE),
        }
    }

    /// `(v, vt, vn)`, with `None` for an absent `vt` or `vn`.
    pub fn parts(self) -> (u32, Option<u32>, Option<u32>) {
        let some = |i: u32| (i != Self::NONE).then_some(i);
        (self.v, some(self.vt), some(self.vn))
    }
}

impl Detail {
    /// The corners of face `f`.
    pub fn corners(&self, f: usize) -> &[FaceCorner] {
        let face = self.faces[f];
        &self.corners[face.first as usize..(face.first + face.len) as usize]
    }
}

/// The grouping statements in force (the text after the keyword).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct State {
    pub object: Option<String>,
    pub group: Option<String>,
    pub smoothing: Option<String>,
    pub material: Option<String>,
}

/// Reads the file's one mesh with the [`Detail`] a writer needs (no `.mtl` is looked at).
pub(crate) fn read_full(path: &Path, cx: &ReadContext) -> Result<(Mesh, Detail), ReadError> {
    let bytes = super::read_bytes(path, &cx.limits)?;
    let parsed = parse_with(&bytes, cx, Some(Box::default()))?;
    let mut detail = parsed.detail.unwrap_or_default();
    detail.mtllibs = parsed.mtllibs.into_iter().map(|(name, _)| name).collect();
    Ok((parsed.mesh, *detail))
}

fn parse_with(
    bytes: &[u8],
    cx: &ReadContext,
    detail: Option<Box<Detail>>,
) -> Result<Parsed, ReadError> {
    let quick = detail.is_none();
    parse_lines(bytes, cx, detail, quick)
}

/// Reads the statements of the file. With `quick`, the common `v x y z` and `f a b c` lines are
/// read in one pass that finds the line's end too ([`Parser::quick_line`]); any other line, or
/// one of those it does not take as it is, is cut at its line feed and read by
/// [`Parser::statement`]. The two ways give the same mesh, notes and errors (a test reads random
/// files both ways).
fn parse_lines(
    bytes: &[u8],
    cx: &ReadContext,
    detail: Option<Box<Detail>>,
    quick: bool,
) -> Result<Parsed, ReadError> {
    let mut notes = Vec::new();
    let bytes = text::lf_line_ends(bytes);
    let text = decode(&bytes, &mut notes)?;
    let mut p = Parser {
        cx,
        mesh: Mesh::default(),
        tally: SplitTally::default(),
        poly: Vec::new(),
        deferred: Vec::new(),
        points: (0, 0),
        lines: (0, 0),
        skipped: Skipped::new(),
        mtllibs: Vec::new(),
        max_index: (0, 0),
        odd_numbers: (0, 0),
        malformed: (0, 0),
        detail,
        state: State::default(),
    };
    // Rough preallocation from the file size (a vertex line is at least ~8 bytes); capped so a
    // large file of comments does not reserve much.
    p.mesh.positions.reserve((text.len() / 64).min(1 << 20));
    p.mesh.triangles.reserve((text.len() / 64).min(1 << 20));

    let mut joined = String::new();
    let mut joined_line = 0u64;
    let (bytes, mut start, mut line_no) = (text.as_bytes(), 0, 0u64);
    // Every line, the last one too (empty after a final line feed).
    while start <= bytes.len() {
        line_no += 1;
        if quick && joined.is_empty() {
            if let Some(len) = p.quick_line(&bytes[start..], line_no)? {
                start += len;
                continue;
            }
        }
        let end = memchr::memchr(b'\n', &bytes[start..]).map_or(bytes.len(), |k| start + k);
        // Cut at line feeds: always character boundaries.
        let raw = text.get(start..end).unwrap_or_default();
        let line = raw.strip_suffix('\r').unwrap_or(raw);
        // `\` at the end of a line continues the statement on the next line.
        if let Some(head) = continued(line) {
            if joined.is_empty() {
                joined_line = line_no;
            }
            joined.push_str(head);
            joined.push(' ');
        } else if !joined.is_empty() {
            joined.push_str(line);
            let statement = std::mem::take(&mut joined);
            p.statement(&statement, joined_line)?;
        } else {
            p.statement(line, line_no)?;
        }
        start = end + 1;
    }
    if !joined.is_empty() {
        let statement = std::mem::take(&mut joined);
        p.statement(&statement, joined_line)?;
    }
    p.finish(notes)
}

/// UTF-8 text of the file: BOM stripped, non-UTF-8 bytes replaced (with a note); UTF-16 and binary
/// content refused ([`Binary`]).
fn decode<'a>(bytes: &'a [u8], notes: &mut Vec<String>) -> Result<Cow<'a, str>, ReadError> {
    if let Some(binary) = Binary::of(bytes) {
        return Err(binary.error("OBJ"));
    }
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    match std::str::from_utf8(bytes) {
        Ok(s) => Ok(Cow::Borrowed(s)),
        Err(e) => {
            let line = bytes[..e.valid_up_to()]
                .iter()
                .filter(|&&b| b == b'\n')
                .count()
                + 1;
            notes.push(format!(
                "the file is not valid UTF-8 (first bad byte on line {line}); the bad bytes were \
                 replaced, which only matters for names"
            ));
            Ok(Cow::Owned(String::from_utf8_lossy(bytes).into_owned()))
        }
    }
}

struct Parser<'c> {
    cx: &'c ReadContext,
    mesh: Mesh,
    tally: SplitTally,
    /// Vertex indices of the face being read (reused: no allocation per line).
    poly: Vec<u32>,
    /// Faces that reference vertices defined later in the file: (first triangle slot, line,
    /// indices). Split at the end, into the n-2 slots reserved in order.
    deferred: Vec<(usize, u64, Vec<u32>)>,
    /// (count, first line) of `p` and `l` statements.
    points: (u64, u64),
    lines: (u64, u64),
    skipped: Skipped,
    mtllibs: Vec<(String, u64)>,
    /// Largest 1-based positive face index and its line, checked against the final vertex count.
    max_index: (u64, u64),
    /// (count, first line) of coordinates written in C's `1.#IND`/`1.#QNAN` style, read as NaN.
    odd_numbers: (u64, u64),
    /// (count, first line) of malformed numbers read by their leading part.
    malformed: (u64, u64),
    /// Kept only for a full read.
    detail: Option<Box<Detail>>,
    state: State,
}

fn line_err(line: u64, what: impl std::fmt::Display) -> ReadError {
    ReadError::new(format!("OBJ line {line}: {what}"))
}

impl Parser<'_> {
    /// Full read: keeps a `vt`/`vn` line or a change of grouping state.
    fn keep(&mut self, keyword: &str, line: &str) {
        let Some(detail) = self.detail.as_mut() else {
            return;
        };
        let rest = line.trim_start()[keyword.len()..].trim().to_owned();
        let value = (!rest.is_empty()).then_some(rest.clone());
        match keyword {
            "vt" => detail.texcoords.push(rest),
            "vn" => detail.normals.push(rest),
            "o" => self.state.object = value,
            "g" => self.state.group = value,
            "s" => self.state.smoothing = value,
            _ => self.state.material = value,
        }
    }

    /// Full read: the face just read, with its `vt`/`vn` indices and grouping state.
    fn keep_face<'a>(&mut self, words: impl Iterator<Item = &'a [u8]>) {
        let Some(detail) = self.detail.as_mut() else {
            return;
        };
        if detail.states.last() != Some(&self.state) {
            detail.states.push(self.state.clone());
        }
        let resolve = |word: Option<&[u8]>, n: usize| -> Option<u32> {
            let i = text::parse_i64(word?)?;
            let i = if i < 0 { n as i64 + i } else { i - 1 };
            (0..n as i64).contains(&i).then_some(i as u32)
        };
        let (nt, nn) = (detail.texcoords.len(), detail.normals.len());
        let first = detail.corners.len();
        detail.corners.extend(words.zip(&self.poly).map(|(w, &v)| {
            // Most files have `v` or `v/vt/vn` words; a plain `v` has nothing more to read.
            let Some(slash) = w.iter().position(|&b| b == b'/') else {
                return FaceCorner::new(v, None, None);
            };
            let mut parts = w[slash + 1..].split(|&b| b == b'/');
            let vt = resolve(parts.next(), nt);
            let vn = resolve(parts.next(), nn);
            FaceCorner::new(v, vt, vn)
        }));
        detail.faces.push(Face {
            first: first as u32,
            len: (detail.corners.len() - first) as u32,
            state: (detail.states.len() - 1) as u32,
        });
    }

    /// Reads one statement, `line`.
    fn statement(&mut self, line: &str, line_no: u64) -> Result<(), ReadError> {
        let mut words = statement_words(line.as_bytes());
        let Some(keyword) = words.next() else {
            return Ok(());
        };
        match keyword {
            b"v" => self.vertex(words, line_no),
            b"f" | b"fo" => {
                self.face(words.clone(), line_no)?;
                self.keep_face(words);
                Ok(())
            }
            b"vt" | b"vn" | b"o" | b"g" | b"s" | b"usemtl" if self.detail.is_some() => {
                let keyword = std::str::from_utf8(keyword).unwrap_or_default();
                self.keep(keyword, strip_comment(line));
                Ok(())
            }
            b"vt" | b"vn" | b"vp" | b"o" | b"g" | b"s" | b"usemtl" => Ok(()),
            b"mtllib" => {
                let rest = strip_comment(line).trim_start()["mtllib".len()..].trim();
                if !rest.is_empty() {
                    self.mtllibs.push((rest.to_owned(), line_no));
                }
                Ok(())
            }
            b"p" => {
                count(&mut self.points, line_no);
                Ok(())
            }
            b"l" => {
                count(&mut self.lines, line_no);
                Ok(())
            }
            other => {
                let other = String::from_utf8_lossy(other);
                if self.skipped.len() < 32 || self.skipped.contains_key(other.as_ref()) {
                    let name: String = other.chars().take(24).collect();
                    let e = self.skipped.entry(name).or_insert((0, line_no));
                    e.0 += 1;
                } else {
                    let e = self.skipped.entry("...".into()).or_insert((0, line_no));
                    e.0 += 1;
                }
                Ok(())
            }
        }
    }

    fn vertex<'a>(
        &mut self,
        mut words: impl Iterator<Item = &'a [u8]>,
        line_no: u64,
    ) -> Result<(), ReadError> {
        let mut p = [0.0f64; 3];
        for (axis, c) in p.iter_mut().enumerate() {
            let Some(w) = words.next() else {
                return Err(line_err(
                    line_no,
                    format!(
                        "vertex has {axis} coordinate(s), needs x y z - fix the line or re-export"
                    ),
                ));
            };
            *c = match text::parse_f64(w) {
                Some(x) => x,
                None if [&b"#IND"[..], b"#QNAN", b"#INF"]
                    .iter()
                    .any(|odd| memchr::memmem::find(w, odd).is_some()) =>
                {
                    count(&mut self.odd_numbers, line_no);
                    f64::NAN
                }
                // `3.1+e2`: read like C's strtod (the leading number) and noted, as other
                // readers do; a word with no leading number is an error.
                None => match leading_number(w) {
                    Some(x) => {
                        count(&mut self.malformed, line_no);
                        x
                    }
                    None => {
                        return Err(line_err(
                            line_no,
                            format!("`{}` is not a number - fix the line or re-export", short(w)),
                        ))
                    }
                },
            };
        }
        self.push_vertex(p)?;
        if let Some(detail) = self.detail.as_mut() {
            let extra: Vec<Cow<str>> = words.map(String::from_utf8_lossy).collect();
            detail.vertex_extra.push(extra.join(" "));
        }
        Ok(())
    }

    fn face<'a>(
        &mut self,
        words: impl Iterator<Item = &'a [u8]>,
        line_no: u64,
    ) -> Result<(), ReadError> {
        self.poly.clear();
        let mut forward = false;
        for w in words {
            let v = w
                .iter()
                .position(|&b| b == b'/')
                .map_or(w, |slash| &w[..slash]);
            let i = text::parse_i64(v).ok_or_else(|| {
                line_err(
                    line_no,
                    format!(
                        "face corner `{}` does not start with a vertex index - fix the line or re-export",
                        short(w)
                    ),
                )
            })?;
            self.corner(i, &mut forward, line_no)?;
        }
        self.split_face(forward, line_no)
    }

    /// Reads the line at the start of `rest` (the rest of the file) when it is a `v` or `f`
    /// statement that [`Parser::vertex_line`] or [`Parser::face_line`] takes, and returns its
    /// length with its line feed; `None`, having kept nothing, for any other line.
    #[inline]
    fn quick_line(&mut self, rest: &[u8], line_no: u64) -> Result<Option<usize>, ReadError> {
        match rest {
            [b'v', b' ' | b'\t', ..] => self.vertex_line(rest),
            [b'f', b' ' | b'\t', ..] => self.face_line(rest, line_no),
            _ => Ok(None),
        }
    }

    /// [`Parser::face`] for the common line `f a b c ...` whose corners are `i`, `i/...` words,
    /// ending at its line feed (or the file's end): reads it in one pass over the bytes. Returns
    /// `None` at anything else (a comment, a word that is not a corner); the line is then read
    /// again by `face`, which says what is wrong. Errors of the indices themselves are the same
    /// either way.
    #[inline]
    fn face_line(&mut self, rest: &[u8], line_no: u64) -> Result<Option<usize>, ReadError> {
        // Most faces are triangles of vertices read already: pushed as they are (which is what
        // `corner` and `split_face` would do with them; such indices can never be the file's
        // largest out-of-range one that `corner` tracks).
        let known = (self.mesh.positions.len() as i64).min(u32::MAX as i64);
        let (mut t, mut at) = ([0u32; 3], 2);
        let three = t.iter_mut().all(|k| match corner_word(rest, &mut at) {
            Word::Index(i) if (1..=known).contains(&i) => {
                *k = (i - 1) as u32;
                true
            }
            _ => false,
        });
        if three && matches!(corner_word(rest, &mut at), Word::End) {
            self.mesh.triangles.push(t);
            if self.mesh.triangles.len() as u64 > self.cx.limits.max_triangles {
                return Err(over_limit("triangles", self.cx));
            }
            return Ok(Some(at));
        }
        self.poly.clear();
        let (mut forward, mut at) = (false, 2);
        loop {
            match corner_word(rest, &mut at) {
                Word::Index(i) => self.corner(i, &mut forward, line_no)?,
                Word::End => break,
                Word::Other => return Ok(None),
            }
        }
        self.split_face(forward, line_no)?;
        Ok(Some(at))
    }

    /// Adds corner `i` (as written: 1-based, or negative for relative) to the face being read.
    #[inline(always)]
    fn corner(&mut self, i: i64, forward: &mut bool, line_no: u64) -> Result<(), ReadError> {
        let n = self.mesh.positions.len() as i64;
        let index = match i {
            0 => {
                return Err(line_err(
                    line_no,
                    "face index 0: OBJ indices start at 1 - the exporter is broken, re-export",
                ))
            }
            i if i < 0 => {
                let abs = n + i;
                if abs < 0 {
                    return Err(line_err(
                        line_no,
                        format!(
                            "relative face index {i} points before the first vertex (only {n} \
                             vertices so far) - fix the face or re-export"
                        ),
                    ));
                }
                abs as u64
            }
            i => {
                let i = i as u64;
                if i > self.max_index.0 {
                    self.max_index = (i, line_no);
                }
                if i > n as u64 {
                    *forward = true;
                }
                i - 1
            }
        };
        if index >= u32::MAX as u64 {
            return Err(line_err(line_no, format!("face index {i} is out of range")));
        }
        self.poly.push(index as u32);
        Ok(())
    }

    /// Splits the face read into `self.poly` into triangles (later, when it names vertices not
    /// read yet).
    #[inline]
    fn split_face(&mut self, forward: bool, line_no: u64) -> Result<(), ReadError> {
        let before = self.mesh.triangles.len();
        if let [a, b, c] = self.poly[..] {
            // What `triangulate` does with a triangle, known or not (the tally ignores it).
            self.mesh.triangles.push([a, b, c]);
        } else if forward && self.poly.len() > 3 {
            // Positions not known yet: reserve the n-2 slots, split at the end.
            self.deferred.push((before, line_no, self.poly.clone()));
            self.mesh
                .triangles
                .extend(std::iter::repeat_n([0; 3], self.poly.len() - 2));
        } else if forward {
            let split = polygon::triangulate(&self.poly, &[], &mut self.mesh.triangles);
            self.tally.add(split, line_no);
        } else {
            let split =
                polygon::triangulate(&self.poly, &self.mesh.positions, &mut self.mesh.triangles);
            self.tally.add(split, line_no);
        }
        if self.mesh.triangles.len() as u64 > self.cx.limits.max_triangles {
            return Err(over_limit("triangles", self.cx));
        }
        Ok(())
    }

    /// [`Parser::vertex`] for the common line `v x y z ...`: when its first three words are
    /// numbers, reads them in one pass, goes to the line's end and returns the line's length;
    /// `None`, having kept nothing, at anything else, or when the line continues on the next
    /// one (`vertex` then reads the words again and says what is wrong).
    #[inline]
    fn vertex_line(&mut self, rest: &[u8]) -> Result<Option<usize>, ReadError> {
        let Some((p, at)) = text::leading_numbers(rest, 2, text::blank, text::leading_f64) else {
            return Ok(None);
        };
        let len = match &rest[at..] {
            [] => at,
            [b'\n', ..] => at + 1,
            [b'\r', b'\n', ..] => at + 2,
            // More words (`w`, colours, a comment): to the line feed, unless a `\` at the end
            // continues the statement.
            tail => {
                let end = memchr::memchr(b'\n', tail).map_or(rest.len(), |k| at + k);
                let line = std::str::from_utf8(&rest[..end]).ok();
                if line.is_none_or(|line| continued(line).is_some()) {
                    return Ok(None);
                }
                (end + 1).min(rest.len())
            }
        };
        self.push_vertex(p)?;
        Ok(Some(len))
    }

    fn push_vertex(&mut self, p: [f64; 3]) -> Result<(), ReadError> {
        if self.mesh.positions.len() as u64 >= self.cx.limits.max_triangles {
            return Err(over_limit("vertices", self.cx));
        }
        self.mesh.positions.push(p);
        Ok(())
    }

    fn finish(mut self, mut notes: Vec<String>) -> Result<Parsed, ReadError> {
        let n = self.mesh.positions.len() as u64;
        let (max, line) = self.max_index;
        if max > n {
            return Err(line_err(
                line,
                format!(
                    "face index {max} is out of range: the file has only {n} vertices - the file is \
                     truncated or broken, re-export it"
                ),
            ));
        }
        if let Some(&(_, first, _)) = self.deferred.first() {
            notes.push(format!(
                "faces reference vertices defined later in the file (first at line {first}); read \
                 anyway"
            ));
        }
        let mut scratch = Vec::new();
        for (slot, line, poly) in std::mem::take(&mut self.deferred) {
            scratch.clear();
            let split = polygon::triangulate(&poly, &self.mesh.positions, &mut scratch);
            self.tally.add(split, line);
            // Always n - 2 triangles, the number of slots reserved.
            if let Some(dst) = self.mesh.triangles.get_mut(slot..slot + scratch.len()) {
                dst.copy_from_slice(&scratch);
            }
        }
        self.tally.notes("line", &mut notes);
        if self.points.0 > 0 {
            notes.push(format!(
                "{} point statement(s) (`p`) skipped (first at line {})",
                self.points.0, self.points.1
            ));
        }
        if self.lines.0 > 0 {
            notes.push(format!(
                "{} line statement(s) (`l`) skipped (first at line {})",
                self.lines.0, self.lines.1
            ));
        }
        if self.odd_numbers.0 > 0 {
            notes.push(format!(
                "{} coordinate(s) written as `1.#IND`/`1.#QNAN` (a C library's NaN) read as NaN \
                 (first at line {})",
                self.odd_numbers.0, self.odd_numbers.1
            ));
        }
        if self.malformed.0 > 0 {
            notes.push(format!(
                "{} malformed number(s) read by their leading digits, e.g. `3.1+e2` as 3.1 (first \
                 at line {}); check the exporter",
                self.malformed.0, self.malformed.1
            ));
        }
        for (keyword, (times, first)) in &self.skipped {
            notes.push(format!(
                "{times} line(s) with unknown keyword `{keyword}` skipped (first at line {first})"
            ));
        }
        self.mesh.notes = notes;
        Ok(Parsed {
            mesh: self.mesh,
            mtllibs: self.mtllibs,
            detail: self.detail,
        })
    }
}

/// A word of an `f` line as [`Parser::face_line`] reads it.
enum Word {
    /// `i` or `i/...`: the vertex index `i` as written.
    Index(i64),
    /// The line's end: past its line feed, or the file's end.
    End,
    /// A comment, or a word that is not a corner (or one that may continue the statement on the
    /// next line): the line is read as a statement instead.
    Other,
}

/// The word of an `f` line at `at` in `rest` (the rest of the file), and `at` moved past it.
#[inline(always)]
fn corner_word(rest: &[u8], at: &mut usize) -> Word {
    while rest.get(*at).copied().is_some_and(text::blank) {
        *at += 1;
    }
    match rest.get(*at) {
        None => return Word::End,
        Some(b'\n') => {
            *at += 1;
            return Word::End;
        }
        Some(b'#') => return Word::Other,
        Some(_) => {}
    }
    // (A number ends at a blank or a line feed, so within the line.)
    let Some((i, end)) = text::leading_i64(&rest[*at..]) else {
        return Word::Other;
    };
    *at += end;
    match rest.get(*at) {
        None => {}
        Some(b) if b.is_ascii_whitespace() => {}
        Some(b'/') => {
            while let Some(&b) = rest.get(*at).filter(|b| !b.is_ascii_whitespace()) {
                // (A `\` may end the line: the statement goes on on the next one.)
                if b == b'\\' {
                    return Word::Other;
                }
                *at += 1;
            }
        }
        Some(_) => return Word::Other,
    }
    Word::Index(i)
}

/// The longest leading part of `w` that is a number (like C's `strtod`), if any.
fn leading_number(w: &[u8]) -> Option<f64> {
    let w = std::str::from_utf8(w).ok()?;
    if w.len() > 64 {
        return None;
    }
    (1..w.len())
        .rev()
        .filter(|&k| w.is_char_boundary(k))
        .find_map(|k| w[..k].parse::<f64>().ok())
}

/// The line up to a `#` that starts a word (a `#` inside a word is part of it: `1.#IND`).
fn strip_comment(line: &str) -> &str {
    let b = line.as_bytes();
    let mut from = 0;
    while let Some(i) = line[from..].find('#') {
        let at = from + i;
        if at == 0 || b[at - 1].is_ascii_whitespace() {
            return &line[..at];
        }
        from = at + 1;
    }
    line
}

fn count(c: &mut (u64, u64), line: u64) {
    if c.0 == 0 {
        c.1 = line;
    }
    c.0 += 1;
}

fn short(w: &[u8]) -> String {
    String::from_utf8_lossy(w).chars().take(40).collect()
}

/// The words of a statement: the line's words up to one that starts with `#` (a comment; a `#`
/// inside a word is part of it: `1.#IND`).
fn statement_words(line: &[u8]) -> impl Iterator<Item = &[u8]> + Clone {
    text::words(line).take_while(|w| w[0] != b'#')
}

/// The line without its final `\` when it ends with one (trailing whitespace aside): the statement
/// continues on the next line. As `line.trim_end().strip_suffix('\\')`, without decoding
/// characters unless the line ends with a non-ASCII one.
fn continued(line: &str) -> Option<&str> {
    let b = line.as_bytes();
    let mut n = b.len();
    while n > 0 && matches!(b[n - 1], b'\t'..=b'\r' | b' ') {
        n -= 1;
    }
    match n.checked_sub(1).map(|last| b[last]) {
        Some(b'\\') => line.get(..n - 1),
        Some(c) if c >= 0x80 => line.trim_end().strip_suffix('\\'),
        _ => None,
    }
}

fn over_limit(what: &str, cx: &ReadContext) -> ReadError {
    ReadError::new(format!(
        "the file has more than {} {what}, over the limit: raise limits.max_triangles in the \
         config to scan it",
        cx.limits.max_triangles
    ))
}

/// Reads the material library `name` (from `mtllib` on `line`). Returns a note when it is missing,
/// refused (outside the scanned tree, through a link too; not a regular file; over
/// `limits.max_file_bytes`) or unreadable; `None` when it reads fine or is a file in `read` (read
/// already, under another name: its note, if any, was given then), which it joins.
fn check_mtl(
    location: &Location,
    name: &str,
    line: u64,
    limits: &Limits,
    read: &mut HashSet<PathBuf>,
) -> Option<String> {
    let not_read = |why: String| {
        Some(format!(
            "material library `{name}` (line {line}) not read: {why}; materials do not affect the \
             checks"
        ))
    };
    let path = match library(name, location) {
        Ok(path) => path,
        Err(NotRead::Refused) => {
            return not_read("its path is absolute or leaves the scanned folder".into())
        }
        Err(NotRead::Unresolved(Unresolved::Missing)) => {
            return Some(format!(
                "material library `{name}` (line {line}) not found next to the OBJ; materials do \
                 not affect the checks, but ship the .mtl with the model"
            ))
        }
        Err(NotRead::Unresolved(Unresolved::Outside)) => {
            return not_read(
                "it resolves, through a symbolic link, outside the scanned folder".into(),
            )
        }
        Err(NotRead::Unresolved(Unresolved::NotAFile(_))) => {
            return not_read("it is not a regular file".into())
        }
        Err(NotRead::Unresolved(Unresolved::Io(e))) => {
            return Some(format!(
                "material library `{name}` (line {line}) could not be read: {e}"
            ))
        }
    };
    if !read.insert(path.clone()) {
        return None;
    }
    // At most the size limit is read, even if the file grows meanwhile.
    let limit = limits.max_file_bytes;
    match super::open_regular(&path).and_then(|f| super::read_within(f, 0, limit)) {
        Err(e) if e.kind() == std::io::ErrorKind::FileTooLarge => not_read(format!(
            "it is over the limit of {limit} bytes (limits.max_file_bytes)"
        )),
        Ok(bytes) => check_mtl_bytes(name, &bytes),
        Err(e) => Some(format!(
            "material library `{name}` (line {line}) could not be read: {e}"
        )),
    }
}

/// Parses MTL bytes with tobj; trouble (including a tobj panic) becomes a note.
fn check_mtl_bytes(name: &str, bytes: &[u8]) -> Option<String> {
    // tobj panics on colour lines with fewer than 3 numbers; find them first so
    // the note can name the line, and never hand them to tobj.
    let text = String::from_utf8_lossy(bytes);
    for (k, l) in text.lines().enumerate() {
        let mut w = l.split_ascii_whitespace();
        if let Some(key @ ("Ka" | "Kd" | "Ks" | "Ke" | "Tf")) = w.next() {
            let n = w.take_while(|t| !t.starts_with('#')).count();
            let spectral = l.contains("spectral") || l.contains("xyz");
            if n < 3 && !spectral {
                return Some(format!(
                    "material library `{name}` line {}: colour `{key}` has {n} value(s), needs 3; \
                     materials were not read (they do not affect the checks)",
                    k + 1
                ));
            }
        }
    }
    let mut reader = std::io::BufReader::new(bytes);
    match crate::caught(|| tobj::load_mtl_buf(&mut reader)) {
        Ok(Ok(_)) => None,
        Ok(Err(e)) => Some(format!(
            "material library `{name}` could not be parsed ({e}); materials do not affect the checks"
        )),
        Err(_) => Some(format!(
            "material library `{name}` crashed the MTL parser; materials were not read (they do \
             not affect the checks)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::Limits;

    fn cx() -> ReadContext {
        ReadContext::for_tests()
    }

    fn mesh(s: &str) -> Mesh {
        parse(s.as_bytes(), &cx()).unwrap().mesh
    }

    fn err(s: &[u8]) -> String {
        parse(s, &cx()).unwrap_err().0
    }

    #[test]
    fn all_corner_forms_and_relative_indices() {
        let m = mesh(
            "# quad and triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
             f 1 2/1 3//1 4/1/1\nf -4 -3 -1\n",
        );
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 3]]);
        assert!(m.notes.is_empty(), "{:?}", m.notes);
    }

    #[test]
    fn unreferenced_vertices_and_file_order_are_kept() {
        let m = mesh("v 9 9 9\no a\nv 0 0 0\nv 1 0 0\ng b\nusemtl m\nv 0 1 0\nf 4 3 2\n");
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.positions[0], [9.0, 9.0, 9.0]);
        assert_eq!(m.triangles, vec![[3, 2, 1]]);
    }

    #[test]
    fn continuation_comments_bom_and_crlf() {
        let m = mesh("\u{feff}v 0 0 0 # origin\r\nv 1 \\\r\n 0 0\r\nv 0 1 0\r\nf 1 2 \\\n 3\r\n");
        assert_eq!(m.positions[1], [1.0, 0.0, 0.0]);
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn nan_kept_points_lines_and_unknown_noted() {
        let m =
            mesh("v nan 0 0\nv 1 0 0\nv 1.#IND 1 0\np 1\nl 1 2\nl 2 3\ncurv 0 1 1 2\nf 1 2 3\n");
        assert!(m.positions[0][0].is_nan() && m.positions[2][0].is_nan());
        assert_eq!(m.triangles.len(), 1);
        let notes = m.notes.join("\n");
        assert!(notes.contains("1 point statement"), "{notes}");
        assert!(notes.contains("2 line statement"), "{notes}");
        assert!(notes.contains("`curv`"), "{notes}");
        assert!(notes.contains("1.#IND"), "{notes}");
    }

    #[test]
    fn bad_indices_name_the_line() {
        assert!(err(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n").contains("line 4: face index 0"));
        let e = err(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
        assert!(e.contains("line 4") && e.contains("only 3 vertices"), "{e}");
        let e = err(b"v 0 0 0\nf -1 -2 -3\n");
        assert!(e.contains("line 2") && e.contains("relative"), "{e}");
        let e = err(b"v 0 0 0\nv 1 x 0\n");
        assert!(e.contains("line 2") && e.contains("`x`"), "{e}");
        assert!(err(b"v 1 2\n").contains("needs x y z"));
        assert!(err(b"f a b c\n").contains("line 1"));
    }

    #[test]
    fn forward_references_are_resolved_in_order() {
        let m = mesh("f 1 2 3 4\nf 1 2 3\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n");
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2]]);
        assert!(m.notes.iter().any(|n| n.contains("defined later")));
    }

    #[test]
    fn encodings() {
        assert!(err(b"\xff\xfev\x000\x00").contains("UTF-16"));
        assert!(err(b"\x89PNG\r\n\x1a\n\0\0\0").contains("looks like a PNG image"));
        assert!(err(b"v 0 0 0\n\0").contains("binary data (a zero byte at offset 8)"));
        let m = parse(b"o caf\xe9\nv 0 0 0\n", &cx()).unwrap().mesh;
        assert_eq!(m.positions.len(), 1);
        assert!(m.notes[0].contains("not valid UTF-8"), "{:?}", m.notes);
    }

    /// The byte-level line helpers agree with the `str` operations they stand for: the words of
    /// the comment-stripped line, and `trim_end().strip_suffix('\\')` (Unicode whitespace too).
    #[test]
    fn statement_words_and_continuations_match_their_definitions() {
        for line in [
            "v 1 2 3",
            "v 1 2 3 # c",
            "v 1.#IND 2#x 3",
            "#v 1",
            " # v",
            "f 1 2 3#4 5",
            "",
            "f 1 \\",
            "f 1 \\ \t",
            "f 1 \\\u{a0}",
            "f 1 \\\u{3000} \u{a0}",
            "f 1\u{a0}",
            "f \\x",
            "\\",
            " \\ ",
            "caf\u{e9}\\",
            "f 1 \\\x0b",
        ] {
            let ours: Vec<&[u8]> = statement_words(line.as_bytes()).collect();
            let std: Vec<&[u8]> = strip_comment(line)
                .split_ascii_whitespace()
                .map(str::as_bytes)
                .collect();
            assert_eq!(ours, std, "`{line}`");
            assert_eq!(
                continued(line),
                line.trim_end().strip_suffix('\\'),
                "`{line}`"
            );
        }
    }

    /// Random files of `v`/`f` lines (and a few others) with odd words, blanks, comments,
    /// continuations and line ends give the same mesh, notes and errors read with the one-pass
    /// `v`/`f` readers as read statement by statement.
    #[test]
    fn quick_lines_read_as_statements() {
        const WORDS: [&str; 24] = [
            "1",
            "2",
            "3",
            "-1",
            "-3",
            "0",
            "+2",
            "4/1",
            "2//3",
            "1/2/3",
            "-1/1",
            "1.5",
            "2e1",
            "nan",
            "1.#IND",
            "#",
            "#x",
            "\\",
            "x",
            "\x0b",
            "\u{e9}",
            "9999999999",
            "3#",
            "1/",
        ];
        const GAPS: [&str; 5] = [" ", "\t", "\x0c", "  ", "\r"];
        const ENDS: [&str; 6] = ["\n", "\n", "\r\n", " \\\n", "\\\n", " \n"];
        const STARTS: [&str; 8] = ["v", "v", "v", "f", "f", "f ", "vt", "# c"];
        let mut random = crate::geometry::xorshift(0x2545_f491_4f6c_dd1d);
        let mut pick = |n: usize| (random() % n as u64) as usize;
        let cx = cx();
        let (mut quick_read, mut errors) = (0, 0);
        for _ in 0..6_000 {
            let mut file = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
            for _ in 0..pick(8) {
                file.push_str(STARTS[pick(STARTS.len())]);
                file.push_str(GAPS[pick(2)]);
                for k in 0..pick(6) {
                    if k > 0 {
                        file.push_str(GAPS[pick(GAPS.len())]);
                    }
                    // Plain small numbers most of the time, so that many lines are taken.
                    match pick(12) {
                        0 => file.push_str(WORDS[pick(WORDS.len())]),
                        _ => file.push_str(&(1 + pick(3)).to_string()),
                    }
                }
                file.push_str(ENDS[pick(ENDS.len())]);
            }
            if pick(2) == 0 {
                file.pop();
            }
            let quick = parse_lines(file.as_bytes(), &cx, None, true);
            let slow = parse_lines(file.as_bytes(), &cx, None, false);
            match (quick, slow) {
                (Ok(q), Ok(s)) => {
                    let bits = |m: &Mesh| -> Vec<[u64; 3]> {
                        m.positions.iter().map(|p| p.map(f64::to_bits)).collect()
                    };
                    assert_eq!(bits(&q.mesh), bits(&s.mesh), "{file:?}");
                    assert_eq!(q.mesh.triangles, s.mesh.triangles, "{file:?}");
                    assert_eq!(q.mesh.notes, s.mesh.notes, "{file:?}");
                    quick_read += usize::from(!q.mesh.triangles.is_empty());
                }
                (Err(q), Err(s)) => {
                    assert_eq!(q.0, s.0, "{file:?}");
                    errors += 1;
                }
                (q, s) => panic!("{file:?}: {:?} against {:?}", q.err(), s.err()),
            }
        }
        // Both outcomes are common, so both ways were compared.
        assert!(quick_read > 500 && errors > 500, "{quick_read} {errors}");
    }

    #[test]
    fn limits() {
        let mut c = cx();
        c.limits.max_triangles = 1;
        let e = parse(b"v 0 0 0\nv 1 0 0\nv 0 1 0\n", &c).unwrap_err().0;
        assert!(e.contains("max_triangles"), "{e}");
    }

    #[test]
    fn mtl_problems_are_notes() {
        let n = check_mtl_bytes("a.mtl", b"newmtl m\nKd 1 0\n").unwrap();
        assert!(n.contains("line 2") && n.contains("Kd"), "{n}");
        assert_eq!(check_mtl_bytes("a.mtl", b"newmtl m\nKd 1 0 0\n"), None);
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("m.obj"), "").unwrap();
        let location = Location::new(&dir.path().join("m.obj"), dir.path()).unwrap();
        let limits = Limits::default();
        let n = check_mtl(&location, "../x.mtl", 3, &limits, &mut HashSet::new()).unwrap();
        assert!(n.contains("leaves the scanned folder"), "{n}");
        let n = check_mtl(&location, "/etc/x.mtl", 3, &limits, &mut HashSet::new()).unwrap();
        assert!(n.contains("absolute"), "{n}");
        assert!(check_mtl(
            &location,
            "sub/../nope.mtl",
            3,
            &limits,
            &mut HashSet::new()
        )
        .unwrap()
        .contains("not found"));
    }
}
