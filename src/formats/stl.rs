//! STL reader (ASCII and binary), our own rather than stl_io (whose detection is fragile, which
//! reads only the first `solid` and welds -0.0 apart from 0.0).
//!
//! Detection: a file is binary exactly when its size is `84 + 50 n` for the triangle count `n` in its
//! header, even when it starts with `solid` (many exporters write that into the binary header).
//! Otherwise a file starting with `solid` (and holding text) is parsed as ASCII. Anything else is
//! binary: a file longer than `84 + 50 n` is read as its `n` declared facets with a note about the
//! bytes after them (exporters pad files), and a shorter one is truncated, reported with the
//! declared and actual counts; another format's signature or UTF-16 text is named instead
//! ([`super::text`]). Every facet contributes its own positions, exactly as stored (the analysis
//! welds); ASCII loops with more than three vertices are split by [`super::polygon`]. A binary
//! file of exactly the declared size is read from disk in chunks and decoded as fixed 50-byte
//! records, never held whole.

use std::io::{Read as _, Seek as _};
use std::path::Path;

use super::text::{self, Binary};
use super::{ReadContext, ReadError};
use crate::geometry::polygon::{self, SplitTally};
use crate::mesh::Mesh;

pub fn read(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    let (mut file, size) = super::open_file(path, &cx.limits)?;
    // A binary file of exactly the size its header declares (the common case) is read in chunks,
    // never held whole; anything else is read whole and judged by `parse`.
    let mut header = [0u8; HEADER];
    if size >= HEADER as u64 && file.read_exact(&mut header).is_ok() {
        let n = declared(&header);
        if HEADER as u64 + FACET as u64 * n == size {
            return read_binary(&mut file, n, cx).map(|m| vec![m]);
        }
        // A file that cannot be ASCII is judged by its header and size alone: a padded file's
        // facets are read in chunks as an exact one's are, and a wrong size is refused without
        // reading the rest (a 2 GB file of zeros was read whole to be refused).
        if !could_be_ascii(&header) {
            if let Layout::Binary { facets, extra } = layout_of(&header, size)? {
                let mut mesh = read_binary(&mut file, facets, cx)?;
                mesh.notes.push(padding_note(facets, extra));
                return Ok(vec![mesh]);
            }
        }
    }
    file.rewind()?;
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes)?;
    parse(&bytes, cx).map(|m| vec![m])
}

/// The triangle count of a binary header.
fn declared(header: &[u8; HEADER]) -> u64 {
    u32::from_le_bytes([header[80], header[81], header[82], header[83]]) as u64
}

/// Size of the binary header plus the triangle count.
const HEADER: usize = 84;
/// Size of one binary facet: normal, three vertices (12 f32) and the attribute word.
const FACET: usize = 50;

fn parse(bytes: &[u8], cx: &ReadContext) -> Result<Mesh, ReadError> {
    match layout(bytes)? {
        Layout::Empty => {
            let mut mesh = Mesh::default();
            mesh.notes.push("the file is empty".into());
            Ok(mesh)
        }
        Layout::Ascii => parse_ascii(bytes, cx),
        Layout::Binary { facets, extra: 0 } => parse_binary(bytes, facets, cx),
        // Longer than the declared facets: exporters pad binary files (to a block size, with a
        // trailing newline, ...). The declared facets are all there; the rest is ignored, noted.
        Layout::Binary { facets: n, extra } => {
            let end = bytes.len() - extra;
            let mut mesh = parse_binary(&bytes[..end], n, cx)?;
            mesh.notes.push(padding_note(n, extra));
            Ok(mesh)
        }
    }
}

/// The note on `extra` bytes ignored after the `n` facets a binary header declares.
fn padding_note(n: u64, extra: usize) -> String {
    let more = extra / FACET;
    let hint = if more > 0 {
        format!(
            " (room for {more} more facet(s): if the model looks incomplete, the header's \
             triangle count is wrong - re-export the file)"
        )
    } else {
        String::new()
    };
    format!("{extra} byte(s) after the {n} triangles the binary header declares were ignored{hint}")
}

/// Whether a file whose first bytes are `header` may be ASCII STL: after any blanks, what follows
/// is `solid` or, cut off by the header's end, the start of it (or nothing).
fn could_be_ascii(header: &[u8]) -> bool {
    let rest = after_blanks(header);
    let k = rest.len().min(5);
    rest[..k].eq_ignore_ascii_case(&b"solid"[..k])
}

/// How [`parse`] reads a file's bytes; the writer of repaired copies decides by the same rule, so
/// a copy is written as its source was read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Layout {
    Empty,
    Ascii,
    /// `facets` binary facets after the header, then `extra` bytes that are ignored (padding).
    Binary {
        facets: u64,
        extra: usize,
    },
}

/// How `bytes` are read, or why they cannot be: the detection the module comment describes.
pub(crate) fn layout(bytes: &[u8]) -> Result<Layout, ReadError> {
    layout_of(bytes, bytes.len() as u64)
}

/// [`layout`] of a file of `size` bytes that starts with `bytes`: the whole file, or its first
/// bytes when they show it cannot be ASCII ([`could_be_ascii`]), as the rest is then only
/// counted.
fn layout_of(bytes: &[u8], size: u64) -> Result<Layout, ReadError> {
    if size == 0 {
        return Ok(Layout::Empty);
    }
    let declared = bytes.first_chunk::<HEADER>().map(declared);
    if let Some(n) = declared {
        if HEADER as u64 + FACET as u64 * n == size {
            return Ok(Layout::Binary {
                facets: n,
                extra: 0,
            });
        }
    }
    // Binary data after a `solid` header (a binary file of the wrong size) is not ASCII STL.
    if starts_with_solid(bytes) && Binary::of(bytes).is_none() {
        return Ok(Layout::Ascii);
    }
    // Binary data is binary STL, but not an image, an archive or another mesh format. A UTF-16
    // byte order mark (two bytes a binary header may start with) is said only of a file that is
    // no binary STL either.
    let other = Binary::known(bytes);
    if let Some(other @ Binary::Known(_)) = other {
        return Err(other.error("STL"));
    }
    match declared {
        _ if other == Some(Binary::Utf16)
            && declared.is_none_or(|n| HEADER as u64 + FACET as u64 * n > size) =>
        {
            Err(Binary::Utf16.error("STL"))
        }
        None => Err(ReadError::new(format!(
            "not an STL file: {size} bytes, too short for a binary STL (at least 84 bytes) and it \
             does not start with `solid` - re-export the file"
        ))),
        // No facets declared but room for some: a streaming exporter never filled the count in.
        // Reading none would make a full file an `empty` row; guessing the count is not ours.
        Some(0) if size >= (HEADER + FACET) as u64 => Err(ReadError::new(format!(
            "binary STL header declares 0 triangles, but the file has room for {} facets after \
             it - the exporter did not fill in the triangle count: re-export the file",
            (size - HEADER as u64) / FACET as u64
        ))),
        Some(n) if HEADER as u64 + FACET as u64 * n < size => {
            let end = HEADER as u64 + FACET as u64 * n;
            Ok(Layout::Binary {
                facets: n,
                // At most the file's size, which the read limit keeps within memory.
                extra: usize::try_from(size - end).unwrap_or(usize::MAX),
            })
        }
        Some(n) => {
            let held = (size - HEADER as u64) / FACET as u64;
            Err(ReadError::new(format!(
                "truncated binary STL: header declares {n} triangles ({} bytes), file holds {held} \
                 ({} bytes) - re-export the file",
                HEADER as u64 + FACET as u64 * n,
                size
            )))
        }
    }
}

fn starts_with_solid(bytes: &[u8]) -> bool {
    after_blanks(bytes)
        .get(..5)
        .is_some_and(|s| s.eq_ignore_ascii_case(b"solid"))
}

/// `bytes` from their first byte that is not ASCII whitespace.
fn after_blanks(bytes: &[u8]) -> &[u8] {
    let start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    &bytes[start..]
}

fn check_limit(triangles: u64, cx: &ReadContext) -> Result<(), ReadError> {
    if triangles > cx.limits.max_triangles {
        return Err(ReadError::new(format!(
            "the file has {triangles} triangles, over the limit of {}: raise limits.max_triangles \
             in the config to scan it",
            cx.limits.max_triangles
        )));
    }
    Ok(())
}

/// The `n` facets after the header of a binary file in memory.
fn parse_binary(bytes: &[u8], n: u64, cx: &ReadContext) -> Result<Mesh, ReadError> {
    let n = checked(n, cx)?;
    let mut positions = Vec::with_capacity(3 * n);
    corners(&bytes[HEADER..HEADER + FACET * n], &mut positions);
    Ok(binary_mesh(positions, n))
}

/// Facets read from a file per call: about 64 KB, in cache while they are decoded.
const CHUNK: usize = 1310;

/// The `n` facets of a binary file of at least `84 + 50 n` bytes, read from `file` (past the
/// header) a chunk at a time.
fn read_binary(file: &mut std::fs::File, n: u64, cx: &ReadContext) -> Result<Mesh, ReadError> {
    let n = checked(n, cx)?;
    let mut positions = Vec::with_capacity(3 * n);
    let mut chunk = vec![0u8; FACET * CHUNK.min(n)];
    let mut left = n;
    while left > 0 {
        let k = left.min(CHUNK);
        file.read_exact(&mut chunk[..FACET * k]).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                ReadError::new(
                    "the binary STL became shorter while it was read (another program is \
                     writing it?) - scan it again when it is complete",
                )
            } else {
                ReadError::from(e)
            }
        })?;
        corners(&chunk[..FACET * k], &mut positions);
        left -= k;
    }
    Ok(binary_mesh(positions, n))
}

/// `n` as a count of facets to read, within the limits and indexable.
fn checked(n: u64, cx: &ReadContext) -> Result<usize, ReadError> {
    check_limit(n, cx)?;
    if 3 * n > u32::MAX as u64 {
        return Err(ReadError::new(format!(
            "binary STL with {n} triangles: more vertices than meshvet can index"
        )));
    }
    // The file size is 84 + 50 n (or more), so n facets are really there: allocations sized by n
    // are backed by data.
    Ok(n as usize)
}

/// Appends the three corners of every 50-byte facet of `facets`, exactly as stored. The facet
/// normal (its first 12 bytes) is skipped: the analysis derives orientation from the winding.
fn corners(facets: &[u8], positions: &mut Vec<[f64; 3]>) {
    let (facets, _) = facets.as_chunks::<FACET>();
    for f in facets {
        let c = |k: usize| f32::from_le_bytes([f[k], f[k + 1], f[k + 2], f[k + 3]]) as f64;
        positions.extend_from_slice(&[
            [c(12), c(16), c(20)],
            [c(24), c(28), c(32)],
            [c(36), c(40), c(44)],
        ]);
    }
}

/// The mesh of `n` facets whose corners are `positions`, in order.
fn binary_mesh(positions: Vec<[f64; 3]>, n: usize) -> Mesh {
    let triangles = (0..n as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
    let mut mesh = Mesh::new(positions, triangles);
    if n == 0 {
        mesh.notes.push("binary STL with 0 triangles".into());
    }
    mesh
}

fn word(token: &[u8]) -> String {
    String::from_utf8_lossy(&token[..token.len().min(40)]).into_owned()
}

fn parse_ascii(bytes: &[u8], cx: &ReadContext) -> Result<Mesh, ReadError> {
    ascii_solids(bytes, cx).map(|(mesh, _)| mesh)
}

/// The file's bytes read as [`read`] reads them, with an ASCII file's `solid` blocks (none for a
/// binary file): what the repaired copy needs, from one parse.
pub(crate) fn parse_with_solids(
    bytes: &[u8],
    cx: &ReadContext,
) -> Result<(Mesh, Vec<Solid>), ReadError> {
    match layout(bytes)? {
        Layout::Ascii => ascii_solids(bytes, cx),
        _ => Ok((parse(bytes, cx)?, Vec::new())),
    }
}

/// A `solid` block of an ASCII STL: the first of the mesh's faces read after it, and its name
/// (the rest of its line, trimmed).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Solid {
    pub first_face: u32,
    pub name: String,
}

/// An ASCII STL read as one mesh, with its `solid` blocks in order (the repaired copy keeps them).
fn ascii_solids(bytes: &[u8], cx: &ReadContext) -> Result<(Mesh, Vec<Solid>), ReadError> {
    let bytes = text::lf_line_ends(bytes);
    let mut tokens = text::Tokens::<false>::new(&bytes, 1);
    let mut mesh = Mesh::default();
    let mut tally = SplitTally::default();
    let mut solids = Vec::new();
    let mut in_loop = false;
    let mut loop_start = 0usize;
    let mut loop_line = 0u64;
    let mut poly: Vec<u32> = Vec::new();
    let err = |line: u64, what: String| {
        Err(ReadError::new(format!(
            "ASCII STL line {line}: {what} - fix or re-export the file"
        )))
    };
    while let Some((tok, line)) = tokens.next() {
        // (Keywords are nearly always written in lower case.)
        let key = match tok {
            b"vertex" | b"facet" | b"normal" | b"outer" | b"loop" | b"endloop" | b"endfacet" => tok,
            _ => keyword(tok),
        };
        match key {
            b"solid" => {
                solids.push(Solid {
                    first_face: mesh.triangles.len() as u32,
                    name: String::from_utf8_lossy(tokens.rest_of_line()).into_owned(),
                });
            }
            b"endsolid" => tokens.skip_line(),
            b"facet" | b"normal" | b"endfacet" => {}
            b"outer" => {}
            b"loop" => {
                if in_loop {
                    return err(
                        line,
                        "`outer loop` inside another loop (missing `endloop`)".into(),
                    );
                }
                in_loop = true;
                loop_start = mesh.positions.len();
                loop_line = line;
            }
            b"vertex" => {
                if !in_loop {
                    return err(line, "`vertex` outside `outer loop ... endloop`".into());
                }
                let mut p = [0.0f64; 3];
                for c in &mut p {
                    let Some((x, l)) = tokens.number(text::leading_f64) else {
                        return err(line, "the file ends inside a vertex".into());
                    };
                    *c = x.map_err(|num| {
                        ReadError::new(format!(
                            "ASCII STL line {l}: `{}` is not a number - fix or re-export the file",
                            word(num)
                        ))
                    })?;
                }
                mesh.positions.push(p);
            }
            b"endloop" => {
                if !in_loop {
                    return err(line, "`endloop` without `outer loop`".into());
                }
                in_loop = false;
                let end = mesh.positions.len();
                if end > u32::MAX as usize {
                    return err(line, "more than 4 billion vertices".into());
                }
                poly.clear();
                poly.extend(loop_start as u32..end as u32);
                let split = polygon::triangulate(&poly, &mesh.positions, &mut mesh.triangles);
                tally.add(split, loop_line);
                check_limit(mesh.triangles.len() as u64, cx)?;
            }
            _ => {
                // Facet normals and vertex numbers were consumed above; anything else is not STL.
                if text::parse_f64(tok).is_some() {
                    continue; // the three numbers after `facet normal`
                }
                return err(line, format!("unexpected `{}`", word(tok)));
            }
        }
    }
    if in_loop {
        return err(
            tokens.line,
            "the file ends inside `outer loop` (truncated)".into(),
        );
    }
    if solids.len() > 1 {
        mesh.notes
            .push(format!("{} `solid` blocks read as one mesh", solids.len()));
    }
    tally.notes("line", &mut mesh.notes);
    Ok((mesh, solids))
}

/// The token lower-cased when it is an STL keyword (no allocation); numbers and anything else are
/// returned unchanged.
fn keyword(tok: &[u8]) -> &[u8] {
    const WORDS: [&[u8]; 9] = [
        b"solid",
        b"endsolid",
        b"facet",
        b"normal",
        b"endfacet",
        b"outer",
        b"loop",
        b"vertex",
        b"endloop",
    ];
    // Most tokens are numbers, and most numbers are shorter or longer than any keyword.
    if !(4..=8).contains(&tok.len()) {
        return tok;
    }
    WORDS
        .iter()
        .find(|w| w.eq_ignore_ascii_case(tok))
        .copied()
        .unwrap_or(tok)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cx() -> ReadContext {
        ReadContext::for_tests()
    }

    fn binary(tris: &[[[f32; 3]; 3]], header: &[u8]) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b[..header.len()].copy_from_slice(header);
        b.extend((tris.len() as u32).to_le_bytes());
        for t in tris {
            b.extend([0u8; 12]);
            for v in t {
                for c in v {
                    b.extend(c.to_le_bytes());
                }
            }
            b.extend([0u8; 2]);
        }
        b
    }

    const TRI: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

    #[test]
    fn binary_even_when_it_starts_with_solid() {
        let b = binary(&[TRI, TRI], b"solid but binary");
        let m = parse(&b, &cx()).unwrap();
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.triangles, vec![[0, 1, 2], [3, 4, 5]]);
        assert_eq!(m.positions[4], [1.0, 0.0, 0.0]);
    }

    #[test]
    fn truncated_binary_names_both_counts() {
        let mut b = binary(&[TRI, TRI, TRI], b"");
        b.truncate(84 + 50 * 2 + 7);
        let e = parse(&b, &cx()).unwrap_err().0;
        assert!(
            e.contains("declares 3 triangles") && e.contains("holds 2"),
            "{e}"
        );
    }

    #[test]
    fn ascii_multi_solid_with_odd_case_and_a_quad() {
        let s = b"solid a\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   \
                  vertex 0 1 0\n  endloop\n endfacet\nendsolid a\nSOLID b\nFACET NORMAL 0 0 1 OUTER \
                  LOOP VERTEX 0 0 1 VERTEX 1 0 1 VERTEX 1 1 1 VERTEX 0 1 1 ENDLOOP ENDFACET\nendsolid\n";
        let m = parse(s, &cx()).unwrap();
        assert_eq!(m.positions.len(), 7);
        assert_eq!(m.triangles.len(), 3);
        assert!(m.notes.iter().any(|n| n.contains("2 `solid` blocks")));
    }

    #[test]
    fn ascii_nan_is_kept_and_errors_have_lines() {
        let s = b"solid x\nfacet normal 0 0 0\nouter loop\nvertex nan 0 0\nvertex 1 0 0\nvertex 0 1 0\n\
                  endloop\nendfacet\nendsolid\n";
        let m = parse(s, &cx()).unwrap();
        assert!(m.positions[0][0].is_nan());
        let bad = b"solid x\nfacet normal 0 0 0\nouter loop\nvertex 1 zz 0\n";
        let e = parse(bad, &cx()).unwrap_err().0;
        assert!(e.contains("line 4") && e.contains("zz"), "{e}");
        let e = parse(
            b"solid x\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\n",
            &cx(),
        )
        .unwrap_err()
        .0;
        assert!(e.contains("truncated"), "{e}");
    }

    #[test]
    fn garbage_and_empty() {
        assert!(parse(b"", &cx()).unwrap().triangles.is_empty());
        assert!(parse(b"hello", &cx()).unwrap_err().0.contains("not an STL"));
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        png.resize(500, 7);
        assert!(parse(&png, &cx())
            .unwrap_err()
            .0
            .contains("looks like a PNG image, not an STL file"));
    }

    /// UTF-16 text is named; a binary header that happens to start with the same two bytes
    /// (`FF FE`) is still binary: 2 facets and 3 bytes of padding, read with a note.
    #[test]
    fn utf16_text_is_named_but_a_binary_header_may_start_like_it() {
        let text: Vec<u8> = "solid x\nendsolid x\n"
            .encode_utf16()
            .flat_map(u16::to_le_bytes)
            .collect();
        let mut utf16 = vec![0xFF, 0xFE];
        utf16.extend(&text);
        let e = parse(&utf16, &cx()).unwrap_err().0;
        assert!(e.contains("UTF-16"), "{e}");
        let mut b = binary(&[TRI, TRI], b"\xff\xfe binary");
        b.extend(b"\n\n\n");
        let m = parse(&b, &cx()).unwrap();
        assert_eq!(m.triangles.len(), 2);
        assert!(
            m.notes[0].contains("3 byte(s) after the 2 triangles"),
            "{:?}",
            m.notes
        );
    }

    #[test]
    fn limit_is_respected() {
        let mut c = cx();
        c.limits.max_triangles = 1;
        let e = parse(&binary(&[TRI, TRI], b""), &c).unwrap_err().0;
        assert!(e.contains("max_triangles"), "{e}");
    }
}
