//! OFF reader (ASCII; binary OFF is refused with a message).
//!
//! Header: a keyword `[ST][C][N][4]OFF` (texture coordinates, colour, normal and homogeneous
//! variants; the extra per-vertex values are skipped), then `vertices faces edges`, on the same line
//! or the next. `#` starts a comment anywhere. Each vertex is a line whose first three numbers are
//! x y z (the rest of the line, whatever the variant, is ignored); each face is a line
//! `n i0 ... i(n-1) [colour]`. Counts are checked against the file size before anything is
//! allocated, indices are range-checked, and polygons are split by [`super::polygon`]. Binary
//! content that is not `OFF BINARY` is refused with what it looks like ([`super::text`]).

use std::path::Path;

use super::text::{self, Binary};
use super::{ReadContext, ReadError};
use crate::geometry::polygon::{self, SplitTally};
use crate::mesh::Mesh;

pub fn read(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    let bytes = super::read_bytes(path, &cx.limits)?;
    parse(&bytes, cx).map(|m| vec![m])
}

/// Non-empty, comment-free lines with their 1-based numbers.
struct Lines<'a> {
    rest: &'a [u8],
    line: u64,
}

impl<'a> Lines<'a> {
    fn next(&mut self) -> Option<(&'a [u8], u64)> {
        while !self.rest.is_empty() {
            let end = self
                .rest
                .iter()
                .position(|&b| b == b'\n')
                .unwrap_or(self.rest.len());
            let mut line = &self.rest[..end];
            self.rest = self.rest.get(end + 1..).unwrap_or(&[]);
            self.line += 1;
            if let Some(hash) = line.iter().position(|&b| b == b'#') {
                line = &line[..hash];
            }
            let line = line.trim_ascii();
            if !line.is_empty() {
                return Some((line, self.line));
            }
        }
        None
    }
}

/// The first 40 bytes of a word, for a message.
fn shown(w: &[u8]) -> String {
    String::from_utf8_lossy(&w[..w.len().min(40)]).into_owned()
}

fn over_limit(cx: &ReadContext) -> ReadError {
    ReadError::new(format!(
        "the file has more than {} triangles, over the limit: raise limits.max_triangles in the \
         config to scan it",
        cx.limits.max_triangles
    ))
}

fn line_err(line: u64, what: impl std::fmt::Display) -> ReadError {
    ReadError::new(format!("OFF line {line}: {what}"))
}

fn parse(bytes: &[u8], cx: &ReadContext) -> Result<Mesh, ReadError> {
    parse_with(bytes, cx, None)
}

/// What a writer needs beyond the geometry: the header keyword, the values after each vertex's
/// `x y z` (normals, colours, texture coordinates) and after each face's indices (its colour).
#[derive(Debug, Default)]
pub(crate) struct Detail {
    pub keyword: String,
    pub vertex_extra: Vec<String>,
    pub faces: Vec<Vec<u32>>,
    pub face_extra: Vec<String>,
}

/// Reads the file's one mesh with the [`Detail`] a writer needs.
pub(crate) fn read_full(path: &Path, cx: &ReadContext) -> Result<(Mesh, Detail), ReadError> {
    let bytes = super::read_bytes(path, &cx.limits)?;
    let mut detail = Detail::default();
    let mesh = parse_with(&bytes, cx, Some(&mut detail))?;
    Ok((mesh, detail))
}

fn parse_with(
    bytes: &[u8],
    cx: &ReadContext,
    detail: Option<&mut Detail>,
) -> Result<Mesh, ReadError> {
    let quick = detail.is_none();
    parse_lines(bytes, cx, detail, quick)
}

/// Reads the file. With `quick`, a vertex line of exactly `x y z` and a face line of exactly
/// `3 a b c` (indices in range) are read whole by [`text::Tokens::line`]; everything else, and
/// every line without `quick`, as tokens. The two ways give the same mesh, notes and errors (a
/// test reads random files both ways).
fn parse_lines(
    bytes: &[u8],
    cx: &ReadContext,
    mut detail: Option<&mut Detail>,
    quick: bool,
) -> Result<Mesh, ReadError> {
    let mut mesh = Mesh::default();
    let bytes = text::lf_line_ends(bytes);
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
    let mut lines = Lines {
        rest: bytes,
        line: 0,
    };
    // Binary content is an error only where the text is not OFF: `OFF BINARY` has its own message.
    let binary = Binary::of(bytes);
    let Some((first, first_no)) = lines.next() else {
        if let Some(binary) = binary {
            return Err(binary.error("OFF"));
        }
        mesh.notes.push("the file is empty".into());
        return Ok(mesh);
    };
    let mut head = text::words(first);
    let keyword = head.next().unwrap_or_default();
    if let Some(d) = detail.as_deref_mut() {
        d.keyword = String::from_utf8_lossy(keyword).into_owned();
    }
    // `[ST][C][N][4][n]OFF`, possibly glued to the first count (`OFF8 6 12` is seen in the wild).
    let at = keyword
        .windows(3)
        .position(|w| w.eq_ignore_ascii_case(b"OFF"));
    let glued = at.map(|k| &keyword[k + 3..]);
    let Some((prefix, glued)) = at
        .zip(glued)
        .filter(|(_, g)| g.iter().all(u8::is_ascii_digit))
        .map(|(k, g)| (&keyword[..k], g))
    else {
        if let Some(binary) = binary {
            return Err(binary.error("OFF"));
        }
        let what = if first.iter().any(|&b| !(0x09..0x80).contains(&b)) {
            "binary data".to_string()
        } else {
            format!("`{}`", shown(keyword))
        };
        return Err(ReadError::new(format!(
            "not an OFF file: it starts with {what} instead of `OFF` - check that the file really \
             is an OFF (a renamed or corrupted file?)"
        )));
    };
    // `nOFF` (lower-case n right before OFF) means vertices of any dimension; `NOFF` means
    // normals, which are just extra numbers on the vertex line.
    if prefix.ends_with(b"n") {
        return Err(line_err(
            first_no,
            "nOFF (vertices of any dimension) is not supported - convert the file to 3D OFF",
        ));
    }
    if prefix.contains(&b'4') {
        mesh.notes
            .push("4OFF: the homogeneous w coordinate was ignored".into());
    }
    // Counts: on the keyword line after it, or on the next line.
    let mut counts: Vec<&[u8]> = Some(glued)
        .filter(|g| !g.is_empty())
        .into_iter()
        .chain(head)
        .collect();
    if counts
        .first()
        .is_some_and(|w| w.eq_ignore_ascii_case(b"BINARY"))
    {
        return Err(ReadError::new(
            "binary OFF is not supported - convert the file to ASCII OFF, PLY or STL",
        ));
    }
    let mut counts_no = first_no;
    if counts.is_empty() {
        let Some((l, no)) = lines.next() else {
            mesh.notes
                .push("OFF header without counts: no vertices or faces".into());
            return Ok(mesh);
        };
        counts = text::words(l).collect();
        counts_no = no;
    }
    let count = |k: usize, what: &str| -> Result<u64, ReadError> {
        let w = counts.get(k).ok_or_else(|| {
            line_err(
                counts_no,
                format!("the header has no {what} count - it needs `vertices faces edges`"),
            )
        })?;
        text::parse_u64(w).ok_or_else(|| {
            line_err(
                counts_no,
                format!("{what} count `{}` is not a whole number", shown(w)),
            )
        })
    };
    let n_vertices = count(0, "vertex")?;
    let n_faces = count(1, "face")?;
    // The edge count is optional and unused.

    // Each vertex line takes at least 6 bytes ("0 0 0\n"), each face at least 2 ("0\n").
    let have = lines.rest.len() as u128;
    let need = n_vertices as u128 * 6 + n_faces as u128 * 2;
    if need > have + 1 {
        return Err(ReadError::new(format!(
            "truncated OFF: the header declares {n_vertices} vertices and {n_faces} faces (at least \
             {need} bytes), but only {have} bytes follow it - re-export the file"
        )));
    }
    for (n, what) in [(n_vertices, "vertices"), (n_faces, "faces")] {
        if n > cx.limits.max_triangles {
            return Err(ReadError::new(format!(
                "the OFF header declares {n} {what}, over the limit of {}: raise \
                 limits.max_triangles in the config to scan it",
                cx.limits.max_triangles
            )));
        }
    }
    if n_vertices >= u32::MAX as u64 {
        return Err(ReadError::new(format!(
            "the OFF header declares {n_vertices} vertices, more than meshvet can index"
        )));
    }
    // Backed by the size check: at least 6 bytes per vertex are in the file.
    mesh.positions.reserve_exact(n_vertices as usize);
    mesh.triangles.reserve(n_faces as usize);

    // The body is read as tokens that may cross lines (some writers wrap long faces); what
    // is left on a line after a vertex's x y z or a face's indices (normals, colours, texture
    // coordinates) is skipped.
    let mut body = text::Tokens::<true>::new(lines.rest, lines.line + 1);
    let truncated = |k: u64, n: u64, what: &str| {
        ReadError::new(format!(
            "truncated OFF: the file ends after {k} of {n} {what} - re-export it"
        ))
    };
    for k in 0..n_vertices {
        if let Some((p, len)) = quick.then(|| body.line(text::leading_f64)).flatten() {
            body.pass(len);
            mesh.positions.push(p);
            continue;
        }
        let mut p = [0.0f64; 3];
        for c in &mut p {
            let (x, no) = body
                .number(text::leading_f64)
                .ok_or_else(|| truncated(k, n_vertices, "vertices"))?;
            *c = x.map_err(|word| {
                line_err(no, format!("vertex {k}: `{}` is not a number", shown(word)))
            })?;
        }
        match detail.as_deref_mut() {
            Some(d) => d
                .vertex_extra
                .push(String::from_utf8_lossy(body.rest_of_line()).into_owned()),
            None => body.skip_line(),
        }
        mesh.positions.push(p);
    }

    let mut tally = SplitTally::default();
    let mut poly = Vec::new();
    for k in 0..n_faces {
        if let Some(([3, a, b, c], len)) = quick.then(|| body.line(text::leading_i64)).flatten() {
            let t = [a, b, c];
            if t.iter().all(|&i| (0..n_vertices as i64).contains(&i)) {
                body.pass(len);
                // What `triangulate` does with a triangle (and the tally ignores it).
                mesh.triangles.push(t.map(|i| i as u32));
                if mesh.triangles.len() as u64 > cx.limits.max_triangles {
                    return Err(over_limit(cx));
                }
                continue;
            }
        }
        let (n, no) = body
            .number(text::leading_u64)
            .ok_or_else(|| truncated(k, n_faces, "faces"))?;
        let count = |first: &[u8]| {
            line_err(
                no,
                format!("face {k}: `{}` is not a vertex count", shown(first)),
            )
        };
        let n = match n {
            Ok(n) => usize::try_from(n).map_err(|_| count(&[]))?,
            Err(first) => return Err(count(first)),
        };
        poly.clear();
        for _ in 0..n {
            let (i, no) = body
                .number(text::leading_i64)
                .ok_or_else(|| truncated(k, n_faces, "faces"))?;
            let i = i.map_err(|word| {
                line_err(
                    no,
                    format!("face {k}: `{}` is not a vertex index", shown(word)),
                )
            })?;
            if i < 0 || i as u64 >= n_vertices {
                return Err(line_err(
                    no,
                    format!(
                        "face {k}: vertex index {i} is out of range (the file has {n_vertices} \
                         vertices; OFF indices start at 0) - the file is broken, re-export it"
                    ),
                ));
            }
            poly.push(i as u32);
        }
        // Anything after the indices is the face colour.
        match detail.as_deref_mut() {
            Some(d) => {
                d.face_extra
                    .push(String::from_utf8_lossy(body.rest_of_line()).into_owned());
                d.faces.push(poly.clone());
            }
            None => body.skip_line(),
        }
        let split = polygon::triangulate(&poly, &mesh.positions, &mut mesh.triangles);
        tally.add(split, no);
        if mesh.triangles.len() as u64 > cx.limits.max_triangles {
            return Err(over_limit(cx));
        }
    }
    tally.notes("line", &mut mesh.notes);
    if let Some((_, no)) = body.next() {
        mesh.notes.push(format!(
            "data after the {n_faces} declared faces was ignored (from line {no})"
        ));
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cx() -> ReadContext {
        ReadContext::for_tests()
    }

    fn ok(s: &str) -> Mesh {
        parse(s.as_bytes(), &cx()).unwrap()
    }

    /// Random files of vertex and face lines with odd words, extra numbers, comments, blank and
    /// wrapped lines, and line ends give the same mesh, notes and errors read with whole lines
    /// where they are plain as read token by token.
    #[test]
    fn quick_lines_read_as_tokens() {
        const WORDS: [&str; 14] = [
            "-1", "0", "1.5", "nan", "#c", "x", "4", "+2", "1e400", "3#", "\u{e9}", "\x0b", "9", "",
        ];
        const GAPS: [&str; 5] = [" ", "\t", "\x0c", "  ", "\r"];
        const ENDS: [&str; 5] = ["\n", "\n", "\r\n", " \n", "\n\n"];
        let mut random = crate::geometry::xorshift(0x6a09_e667_f3bc_c908);
        let mut pick = |n: usize| (random() % n as u64) as usize;
        let cx = cx();
        let (mut read, mut errors) = (0, 0);
        for _ in 0..6_000 {
            let (nv, nf) = (3 + pick(3), pick(5));
            let mut file = format!("OFF\n{nv} {nf} 0\n");
            for k in 0..nv + nf {
                let face = k >= nv;
                let mut words: Vec<String> = if face {
                    let n = if pick(8) == 0 { 4 } else { 3 };
                    std::iter::once(n.to_string())
                        .chain((0..n).map(|_| pick(nv).to_string()))
                        .collect()
                } else {
                    (0..3)
                        .map(|_| format!("{}.{}", pick(3), pick(10)))
                        .collect()
                };
                match pick(10) {
                    0 => words.push(WORDS[pick(WORDS.len())].to_string()),
                    1 => {
                        let at = pick(words.len());
                        words[at] = WORDS[pick(WORDS.len())].to_string();
                    }
                    _ => {}
                }
                if pick(4) == 0 {
                    file.push_str(GAPS[pick(GAPS.len())]);
                }
                for (i, w) in words.iter().enumerate() {
                    if i > 0 {
                        // Now and then a line wrapped inside a vertex or a face.
                        file.push_str(if pick(30) == 0 {
                            "\n"
                        } else {
                            GAPS[pick(GAPS.len())]
                        });
                    }
                    file.push_str(w);
                }
                file.push_str(ENDS[pick(ENDS.len())]);
            }
            if pick(2) == 0 {
                file.pop();
            }
            let quick = parse_lines(file.as_bytes(), &cx, None, true);
            let tokens = parse_lines(file.as_bytes(), &cx, None, false);
            match (quick, tokens) {
                (Ok(q), Ok(t)) => {
                    let bits = |m: &Mesh| -> Vec<[u64; 3]> {
                        m.positions.iter().map(|p| p.map(f64::to_bits)).collect()
                    };
                    assert_eq!(bits(&q), bits(&t), "{file:?}");
                    assert_eq!(q.triangles, t.triangles, "{file:?}");
                    assert_eq!(q.notes, t.notes, "{file:?}");
                    read += usize::from(!q.triangles.is_empty());
                }
                (Err(q), Err(t)) => {
                    assert_eq!(q.0, t.0, "{file:?}");
                    errors += 1;
                }
                (q, t) => panic!("{file:?}: {:?} against {:?}", q.err(), t.err()),
            }
        }
        // Both outcomes are common, so both ways were compared.
        assert!(read > 500 && errors > 500, "{read} {errors}");
    }

    fn err(s: &str) -> String {
        parse(s.as_bytes(), &cx()).unwrap_err().0
    }

    #[test]
    fn plain_and_variants() {
        let m =
            ok("OFF\n# square\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 255 0 0\n3 0 1 3\n");
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 3]]);
        let m = ok("COFF 3 1 0\n0 0 0 1 0 0 1\n1 0 0 1 0 0 1\n0 1 0 1 0 0 1\n3 0 1 2\n");
        assert_eq!((m.positions.len(), m.triangles.len()), (3, 1));
        let m = ok("NOFF\n3 1 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1 # n\n\n3 2 1 0\n");
        assert_eq!(m.triangles, vec![[2, 1, 0]]);
        let m = ok(
            "STCNOFF\n3 1 0\n0 0 0 0 0 1 0 0 0 0 1 1\n1 0 0 0 0 1 0 0 0 0 1 1\n\
                    0 1 0 0 0 1 0 0 0 0 1 1\n3 0 1 2\n",
        );
        assert_eq!(m.triangles.len(), 1);
    }

    #[test]
    fn nan_kept_and_errors_named() {
        let m = ok("OFF\n3 1 0\nnan 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
        assert!(m.positions[0][0].is_nan());
        let e = err("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
        assert!(e.contains("line 6") && e.contains("index 3"), "{e}");
        let e = err("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n");
        assert!(e.contains("-1"), "{e}");
        let e = err("OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n");
        assert!(e.contains("line 4") && e.contains("`x`"), "{e}");
        assert!(err("OFF BINARY\n").contains("binary OFF"));
        assert!(err("PLY\n").contains("not an OFF"));
        assert!(err("\u{89}PNG\n").contains("not an OFF"));
    }

    #[test]
    fn counts_checked_before_allocating() {
        let e = err("OFF\n4000000000 1 0\n0 0 0\n");
        assert!(
            e.contains("truncated OFF") && e.contains("4000000000"),
            "{e}"
        );
        let e = err("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
        assert!(e.contains("1 of 2 faces"), "{e}");
        assert!(ok("").triangles.is_empty());
        assert!(ok("# nothing\n").triangles.is_empty());
    }
}
