//! PLY reader (ASCII, binary little and big endian): the header parsed by `ply-rs-bw`, the payload
//! read here.
//!
//! Before any payload is read, every element count is checked against the bytes left in the file
//! (a header claiming 4 billion vertices in a 1 KB file fails at once, without allocating). Each
//! property's role (a vertex coordinate, a face's index list, or nothing) is worked out once per
//! element. Binary vertices made only of scalars are decoded as fixed records in one pass, and
//! binary faces of one index list with scalars around it (`list uchar int vertex_indices` is the
//! common case) record by record without a per-face allocation, triangles straight into the mesh;
//! any other layout, and the record where a bulk read stops (short, a negative length, an index
//! out of range), goes through ply-rs's generic element reader with our own `PropertyAccess`
//! structs (its `DefaultElement` is a map per vertex), which says exactly what is wrong. ASCII
//! lines are split here (ply-rs's grammar rejects `nan` and `inf`), numbers parsed from bytes.
//! Faces become triangles (polygons split by [`super::polygon`]); other elements are skipped
//! without being kept. Vertex `x y z` may have any numeric type; face indices come from
//! `vertex_indices` or `vertex_index` lists of any integer type and are range-checked here.

use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    BeginList, ElementDef, Encoding, Property, PropertyAccess, PropertyAccessResult, PropertyType,
    ScalarType,
};

use super::text::{self, Binary};
use super::{ReadContext, ReadError};
use crate::geometry::polygon::{self, SplitTally};
use crate::mesh::Mesh;

pub fn read(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    let bytes = super::read_bytes(path, &cx.limits)?;
    parse(&bytes, cx).map(|m| vec![m])
}

/// The coordinates of one vertex (other properties are ignored).
struct Vertex([f64; 3]);

impl Vertex {
    fn set(&mut self, key: &str, value: f64) -> PropertyAccessResult {
        let axis = match key {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return PropertyAccessResult::Ignored,
        };
        self.0[axis] = value;
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex([0.0; 3])
    }
    fn set_float(&mut self, key: &str, value: f32) -> PropertyAccessResult {
        self.set(key, value as f64)
    }
    fn set_double(&mut self, key: &str, value: f64) -> PropertyAccessResult {
        self.set(key, value)
    }
    fn set_property(&mut self, key: &str, property: Property) -> PropertyAccessResult {
        let value = match property {
            Property::Char(v) => v as f64,
            Property::UChar(v) => v as f64,
            Property::Short(v) => v as f64,
            Property::UShort(v) => v as f64,
            Property::Int(v) => v as f64,
            Property::UInt(v) => v as f64,
            Property::Float(v) => v as f64,
            Property::Double(v) => v,
            _ => return PropertyAccessResult::Ignored,
        };
        self.set(key, value)
    }
}

/// The vertex indices of one face, from whichever integer list type the file uses.
#[derive(Default)]
struct Face {
    signed: Vec<i32>,
    unsigned: Vec<u32>,
}

fn is_index_list(key: &str) -> bool {
    key == "vertex_indices" || key == "vertex_index"
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }
    fn begin_list_int(&mut self, key: &str, _len: usize) -> BeginList<'_, i32> {
        if is_index_list(key) {
            BeginList::Fill(&mut self.signed)
        } else {
            BeginList::UseSetter
        }
    }
    fn begin_list_uint(&mut self, key: &str, _len: usize) -> BeginList<'_, u32> {
        if is_index_list(key) {
            BeginList::Fill(&mut self.unsigned)
        } else {
            BeginList::UseSetter
        }
    }
    fn set_property(&mut self, key: &str, property: Property) -> PropertyAccessResult {
        if !is_index_list(key) {
            return PropertyAccessResult::Ignored;
        }
        self.signed = match property {
            Property::ListChar(v) => v.into_iter().map(i32::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i32::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i32::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i32::from).collect(),
            _ => return PropertyAccessResult::UnsupportedType,
        };
        PropertyAccessResult::Set
    }
}

/// Appends the triangles of one triangle strip (`-1` restarts the strip; every other triangle is
/// wound the other way round, so all keep the strip's orientation). Windows that repeat a vertex
/// index are the strip's stitching, not faces: they are left out and counted. An index that is
/// neither `-1` nor a vertex is returned as the error.
fn add_strip(
    strip: impl Iterator<Item = i64>,
    n_vertices: usize,
    out: &mut Vec<[u32; 3]>,
) -> Result<usize, i64> {
    let mut stitches = 0;
    let mut run: Vec<u32> = Vec::new();
    let mut flush = |run: &mut Vec<u32>, out: &mut Vec<[u32; 3]>| {
        for (k, w) in run.windows(3).enumerate() {
            let t = if k % 2 == 0 {
                [w[0], w[1], w[2]]
            } else {
                [w[1], w[0], w[2]]
            };
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                stitches += 1;
            } else {
                out.push(t);
            }
        }
        run.clear();
    };
    for index in strip {
        match index {
            -1 => flush(&mut run, out),
            i if i >= 0 && (i as usize) < n_vertices => run.push(i as u32),
            i => return Err(i),
        }
    }
    flush(&mut run, out);
    Ok(stitches)
}

/// Any element we do not use: read (to move past it) and dropped.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// The fewest payload bytes one element can take: binary, the scalars and list counts (empty
/// lists); ASCII, one character and one separator per property. An element with no properties
/// takes no bytes in either encoding: it is skipped without reading (see [`parse`]), so its count,
/// which no byte of the file backs, never drives a loop.
fn min_element_bytes(def: &ElementDef, encoding: Encoding) -> u64 {
    if def.properties.is_empty() {
        return 0;
    }
    if encoding == Encoding::Ascii {
        return 2 * def.properties.len() as u64;
    }
    def.properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) => scalar_size(t) as u64,
            PropertyType::List(count, _) => scalar_size(count) as u64,
        })
        .sum()
}

/// The mesh of a PLY file's `bytes` (what [`read`] returns, for a writer that has the bytes).
pub(crate) fn parse(bytes: &[u8], cx: &ReadContext) -> Result<Mesh, ReadError> {
    if bytes.is_empty() {
        let mut mesh = Mesh::default();
        mesh.notes.push("the file is empty".into());
        return Ok(mesh);
    }
    if !(bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r")) {
        // Binary PLY exists: only another format's signature says more than the line below.
        if let Some(other) = Binary::known(bytes) {
            return Err(other.error("PLY"));
        }
        return Err(ReadError::new(
            "not a PLY file: it does not start with the line `ply` - check that the file really \
             is a PLY (a renamed or corrupted file?)",
        ));
    }
    let mut mesh = Mesh::default();
    let (header_text, body_start, header_lines) = split_header(bytes, &mut mesh.notes)?;
    let mut reader = Reader::new(header_text.as_bytes());
    let header = Parser::<Skip>::new()
        .read_header(&mut reader)
        .map_err(|e| {
            ReadError::new(format!(
                "invalid PLY header: {} - fix the header or re-export the file",
                flat(&e.to_string())
            ))
        })?;
    let body = &bytes[body_start..];

    // Check every declared count against what the file can hold before reading anything.
    let mut need = 0u128;
    for def in header.elements.values() {
        need += def.count as u128 * min_element_bytes(def, header.encoding) as u128;
    }
    let have = body.len() as u128;
    // The last ASCII line may lack its line break.
    let slack = u128::from(header.encoding == Encoding::Ascii);
    if need > have + slack {
        let counts: Vec<String> = header
            .elements
            .values()
            .map(|d| format!("{} {}", d.count, d.name))
            .collect();
        return Err(ReadError::new(format!(
            "truncated PLY: the header declares {} (at least {need} bytes of data), but the file \
             holds only {have} bytes after the header - re-export the file",
            counts.join(", ")
        )));
    }

    let vertex_def = header.elements.get("vertex");
    let n_vertices = vertex_def.map_or(0, |d| d.count);
    let n_faces = header.elements.get("face").map_or(0, |d| d.count);
    for (n, what) in [(n_vertices, "vertices"), (n_faces, "faces")] {
        if n as u64 > cx.limits.max_triangles {
            return Err(ReadError::new(format!(
                "the PLY header declares {n} {what}, over the limit of {}: raise \
                 limits.max_triangles in the config to scan it",
                cx.limits.max_triangles
            )));
        }
    }
    if n_vertices > u32::MAX as usize - 1 {
        return Err(ReadError::new(format!(
            "the PLY header declares {n_vertices} vertices, more than meshvet can index"
        )));
    }
    if let Some(def) = vertex_def {
        if !["x", "y", "z"].iter().all(|k| {
            matches!(
                def.properties.get(*k).map(|p| &p.data_type),
                Some(PropertyType::Scalar(_))
            )
        }) {
            return Err(ReadError::new(
                "the PLY `vertex` element has no scalar `x`, `y` and `z` properties - this is not \
                 a mesh meshvet can check",
            ));
        }
    }
    if let Some(def) = header.elements.get("face") {
        let list = ["vertex_indices", "vertex_index"]
            .iter()
            .find_map(|k| def.properties.get(*k));
        match list.map(|p| &p.data_type) {
            Some(PropertyType::List(_, t))
                if !matches!(t, ScalarType::Float | ScalarType::Double) => {}
            _ => {
                return Err(ReadError::new(
                    "the PLY `face` element has no integer list `vertex_indices` (or \
                     `vertex_index`) - re-export the file with faces as index lists",
                ))
            }
        }
    }

    // Backed by the size check above (every vertex takes at least a few bytes of the file).
    mesh.positions.reserve_exact(n_vertices);
    mesh.triangles.reserve(n_faces.min(1 << 22));
    let mut faces: Vec<(u64, Vec<u32>)> = Vec::new();
    let mut tally = SplitTally::default();
    let mut body = Body {
        encoding: header.encoding,
        rest: body,
        line: header_lines,
    };
    let mut poly = Vec::new();
    let mut indices = Vec::new();
    let mut stitches = 0;
    let vertices_read_before_faces = header
        .elements
        .get_index_of("vertex")
        .zip(header.elements.get_index_of("face"))
        .is_none_or(|(v, f)| v < f);
    for def in header.elements.values() {
        match def.name.as_str() {
            "vertex" => body.vertices(def, &mut mesh.positions)?,
            "face" => {
                let roles = roles(def);
                let fixed = FixedFace::of(def).filter(|_| body.encoding != Encoding::Ascii);
                let quick = QuickAscii::of(def, &roles, &[Role::Indices])
                    .filter(|_| body.encoding == Encoding::Ascii && vertices_read_before_faces);
                let mut i = 0;
                while i < def.count {
                    // Triangles (most faces) go straight into the mesh, as `triangulate` would
                    // put them (and the tally ignores triangles): binary records in bulk, ASCII
                    // lines the quick reader takes. Any other face, or one with an index out of
                    // range, is read below.
                    let (limit, left, out) =
                        (cx.limits.max_triangles, def.count - i, &mut mesh.triangles);
                    i += match (quick, &fixed) {
                        (Some(q), _) => body.triangles(q, left, n_vertices, limit, out),
                        (None, Some(f)) if vertices_read_before_faces => {
                            f.triangles(&mut body, left, n_vertices, limit, out)
                        }
                        _ => 0,
                    };
                    if mesh.triangles.len() as u64 > limit {
                        return Err(over_limit(cx));
                    }
                    if i == def.count {
                        break;
                    }
                    body.indices(def, &roles, fixed.as_ref(), i, &mut indices)?;
                    poly.clear();
                    for &index in &indices {
                        if index < 0 || index as usize >= n_vertices {
                            return Err(ReadError::new(format!(
                                "PLY face {i}{}: vertex index {index} is out of range (the file \
                                 has {n_vertices} vertices) - the file is broken, re-export it",
                                body.at()
                            )));
                        }
                        poly.push(index as u32);
                    }
                    if !vertices_read_before_faces {
                        faces.push((i as u64, poly.clone()));
                    } else if let [a, b, c] = poly[..] {
                        mesh.triangles.push([a, b, c]);
                    } else {
                        let split =
                            polygon::triangulate(&poly, &mesh.positions, &mut mesh.triangles);
                        tally.add(split, i as u64);
                    }
                    if mesh.triangles.len() as u64 > cx.limits.max_triangles {
                        return Err(over_limit(cx));
                    }
                    i += 1;
                }
            }
            "tristrips" if def.properties.keys().any(|k| is_index_list(k)) => {
                let roles = roles(def);
                for i in 0..def.count {
                    body.indices(def, &roles, None, i, &mut indices)?;
                    stitches += add_strip(indices.iter().copied(), n_vertices, &mut mesh.triangles)
                        .map_err(|index| {
                            ReadError::new(format!(
                                "PLY tristrips {i}{}: vertex index {index} is out of range (the \
                                 file has {n_vertices} vertices) - the file is broken, re-export it",
                                body.at()
                            ))
                        })?;
                    if mesh.triangles.len() as u64 > cx.limits.max_triangles {
                        return Err(over_limit(cx));
                    }
                }
            }
            // No properties: every entry is empty, in ASCII (blank lines are skipped anyway) as
            // in binary. Skipped in O(1): a loop over a count of 2^64 empty records never ends.
            _ if def.properties.is_empty() => {
                if def.count > 0 {
                    mesh.notes.push(format!(
                        "PLY element `{}` declares {} entries but no properties: it holds no \
                         data and was skipped",
                        def.name, def.count
                    ));
                }
            }
            _ => {
                body.skip(def)?;
                if def.count > 0 {
                    let entries = if def.count == 1 { "entry" } else { "entries" };
                    mesh.notes.push(format!(
                        "PLY element `{}` ({} {entries}) skipped",
                        def.name, def.count
                    ));
                }
            }
        }
    }
    if stitches > 0 {
        mesh.notes.push(format!(
            "{stitches} triangles of PLY tristrips repeat a vertex (strip stitching) and were left out"
        ));
    }
    for (i, poly) in &faces {
        let split = polygon::triangulate(poly, &mesh.positions, &mut mesh.triangles);
        tally.add(split, *i);
    }
    tally.notes("face (0-based)", &mut mesh.notes);
    if body.encoding != Encoding::Ascii && !body.rest.is_empty() {
        mesh.notes.push(format!(
            "{} bytes after the last element declared in the header were ignored",
            body.rest.len()
        ));
    }
    Ok(mesh)
}

/// The header of a PLY file for a writer: its cleaned text (one statement a line, comments kept),
/// the parsed definitions and the offset of the payload.
pub(crate) fn header(bytes: &[u8]) -> Result<(String, ply_rs_bw::ply::Header, usize), ReadError> {
    let mut notes = Vec::new();
    let (text, body_start, _) = split_header(bytes, &mut notes)?;
    let header = Parser::<Skip>::new()
        .read_header(&mut Reader::new(text.as_bytes()))
        .map_err(|e| ReadError::new(format!("invalid PLY header: {}", flat(&e.to_string()))))?;
    Ok((text, header, body_start))
}

fn over_limit(cx: &ReadContext) -> ReadError {
    ReadError::new(format!(
        "the file has more than {} triangles, over the limit: raise limits.max_triangles in the \
         config to scan it",
        cx.limits.max_triangles
    ))
}

/// What the reader takes from a property of an element.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    /// Coordinate 0, 1 or 2 of a vertex (scalar `x`, `y`, `z` of the `vertex` element).
    Axis(usize),
    /// A face's or strip's vertex indices (`vertex_indices` or `vertex_index`).
    Indices,
    /// Read past.
    Other,
}

/// The role of each property of `def`, in order: axes in `vertex`, index lists in `face` and
/// `tristrips`, nothing elsewhere.
fn roles(def: &ElementDef) -> Vec<Role> {
    def.properties
        .iter()
        .map(|(key, p)| match (def.name.as_str(), &p.data_type) {
            ("vertex", PropertyType::Scalar(_)) => match key.as_str() {
                "x" => Role::Axis(0),
                "y" => Role::Axis(1),
                "z" => Role::Axis(2),
                _ => Role::Other,
            },
            ("face" | "tristrips", PropertyType::List(..)) if is_index_list(key) => Role::Indices,
            _ => Role::Other,
        })
        .collect()
}

/// One ASCII element line, property by property (tokens beyond the declared ones are ignored):
/// coordinates into `xyz`, index list items appended to `indices`. ply-rs's ASCII grammar rejects
/// `nan` and `inf`, which a validator must read (and report), so ASCII lines are split here.
/// Only the numbers the reader takes are parsed: any token fills another scalar or list item.
fn ascii_record(
    line: &[u8],
    def: &ElementDef,
    roles: &[Role],
    xyz: &mut [f64; 3],
    indices: &mut Vec<i64>,
) -> Result<(), String> {
    let mut tokens = text::Tokens::<false>::new(line, 0);
    for ((key, p), &role) in def.properties.iter().zip(roles) {
        let missing = || format!("the line ends before property `{key}`");
        match (&p.data_type, role) {
            (PropertyType::Scalar(_), Role::Axis(axis)) => {
                let (x, _) = tokens.number(text::leading_f64).ok_or_else(missing)?;
                xyz[axis] = x.map_err(|token| {
                    format!("`{}` is not a number (property `{key}`)", cut(token))
                })?;
            }
            (PropertyType::Scalar(_), _) => {
                tokens.next().ok_or_else(missing)?;
            }
            (PropertyType::List(..), _) => {
                let (n, _) = tokens.number(text::leading_u64).ok_or_else(missing)?;
                let n = match n.map(usize::try_from) {
                    Ok(Ok(n)) => n,
                    Ok(Err(_)) => return Err(format!("list `{key}` is too long")),
                    Err(token) => {
                        return Err(format!(
                            "`{}` is not a list length (property `{key}`)",
                            cut(token)
                        ))
                    }
                };
                for k in 0..n {
                    let declared =
                        || format!("list `{key}` declares {n} items but the line has {k}");
                    if role == Role::Indices {
                        let (i, _) = tokens.number(text::leading_i64).ok_or_else(declared)?;
                        indices.push(i.map_err(|item| {
                            format!("`{}` is not an integer (list `{key}`)", cut(item))
                        })?);
                    } else {
                        tokens.next().ok_or_else(declared)?;
                    }
                }
            }
        }
    }
    Ok(())
}

/// The size in bytes of a binary scalar.
pub(crate) fn scalar_size(t: &ScalarType) -> usize {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The binary scalar of type `t` at the start of `b` (at least its size long), as an f64 (exact
/// for every PLY type).
#[inline]
pub(crate) fn scalar(b: &[u8], t: &ScalarType, big: bool) -> f64 {
    let mut a = [0u8; 8];
    let n = scalar_size(t);
    a[..n].copy_from_slice(&b[..n]);
    if big {
        a[..n].reverse();
    }
    match t {
        ScalarType::Char => a[0] as i8 as f64,
        ScalarType::UChar => a[0] as f64,
        ScalarType::Short => i16::from_le_bytes([a[0], a[1]]) as f64,
        ScalarType::UShort => u16::from_le_bytes([a[0], a[1]]) as f64,
        ScalarType::Int => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        ScalarType::UInt => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        ScalarType::Float => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        ScalarType::Double => f64::from_le_bytes(a),
    }
}

/// The binary integer of type `t` at the start of `b` (at least its size long); a float type
/// (never a list's length or an index list's type here) is cut to an integer.
#[inline(always)]
fn integer(b: &[u8], t: &ScalarType, big: bool) -> i64 {
    let two = || [b[0], b[1]];
    let four = || [b[0], b[1], b[2], b[3]];
    match (t, big) {
        (ScalarType::Char, _) => b[0] as i8 as i64,
        (ScalarType::UChar, _) => b[0] as i64,
        (ScalarType::Short, false) => i16::from_le_bytes(two()) as i64,
        (ScalarType::Short, true) => i16::from_be_bytes(two()) as i64,
        (ScalarType::UShort, false) => u16::from_le_bytes(two()) as i64,
        (ScalarType::UShort, true) => u16::from_be_bytes(two()) as i64,
        (ScalarType::Int, false) => i32::from_le_bytes(four()) as i64,
        (ScalarType::Int, true) => i32::from_be_bytes(four()) as i64,
        (ScalarType::UInt, false) => u32::from_le_bytes(four()) as i64,
        (ScalarType::UInt, true) => u32::from_be_bytes(four()) as i64,
        (ScalarType::Float | ScalarType::Double, _) => scalar(b, t, big) as i64,
    }
}

/// A binary element of scalars only: every record has the same size.
struct FixedRecord {
    size: usize,
    /// Offset and type of `x`, `y`, `z` (vertices only).
    axes: Option<[(usize, ScalarType); 3]>,
}

impl FixedRecord {
    fn of(def: &ElementDef) -> Option<FixedRecord> {
        let mut size = 0;
        let mut axes: [Option<(usize, ScalarType)>; 3] = [None, None, None];
        for (p, role) in def.properties.values().zip(roles(def)) {
            let PropertyType::Scalar(t) = &p.data_type else {
                return None;
            };
            if let Role::Axis(axis) = role {
                axes[axis] = Some((size, t.clone()));
            }
            size += scalar_size(t);
        }
        let axes = match axes {
            [Some(x), Some(y), Some(z)] => Some([x, y, z]),
            _ => None,
        };
        Some(FixedRecord { size, axes })
    }
}

/// A binary face element of one index list with an integer length and any scalars around it
/// (`list uchar int vertex_indices` is the common case): its records are read here in bulk.
#[derive(Debug)]
struct FixedFace {
    /// Bytes of the scalars before and after the list.
    before: usize,
    after: usize,
    count: ScalarType,
    item: ScalarType,
}

impl FixedFace {
    fn of(def: &ElementDef) -> Option<FixedFace> {
        let (mut before, mut after, mut list) = (0, 0, None);
        for (key, p) in &def.properties {
            match &p.data_type {
                PropertyType::Scalar(t) if list.is_none() => before += scalar_size(t),
                PropertyType::Scalar(t) => after += scalar_size(t),
                PropertyType::List(count, item)
                    if list.is_none()
                        && is_index_list(key)
                        && !matches!(count, ScalarType::Float | ScalarType::Double) =>
                {
                    list = Some((count.clone(), item.clone()));
                }
                PropertyType::List(..) => return None,
            }
        }
        let (count, item) = list?;
        Some(FixedFace {
            before,
            after,
            count,
            item,
        })
    }

    /// The three indices of the record at the start of `rest` when it is a triangle, and the
    /// bytes after it; `None` for a short record or another length ([`FixedFace::read`] then).
    #[inline]
    fn triangle<'a>(&self, rest: &'a [u8], big: bool) -> Option<([i64; 3], &'a [u8])> {
        let size = scalar_size(&self.item);
        let items = self.before + scalar_size(&self.count);
        let end = items + 3 * size + self.after;
        let record = rest.get(..end)?;
        if integer(&record[self.before..], &self.count, big) != 3 {
            return None;
        }
        let b = &record[items..];
        let t = [0, size, 2 * size].map(|at| integer(&b[at..], &self.item, big));
        Some((t, &rest[end..]))
    }

    /// Reads up to `count` faces from `body` straight into `out` while they are triangles whose
    /// indices are below `n_vertices`, stopping too once `out` holds more than `limit`
    /// triangles; returns how many it read.
    fn triangles(
        &self,
        body: &mut Body<'_>,
        count: usize,
        n_vertices: usize,
        limit: u64,
        out: &mut Vec<[u32; 3]>,
    ) -> usize {
        let big = body.big();
        if let (false, ScalarType::Char | ScalarType::UChar, ScalarType::Int | ScalarType::UInt) =
            (big, &self.count, &self.item)
        {
            return self.little_triangles(body, count, n_vertices, limit, out);
        }
        let mut read = 0;
        while read < count && out.len() as u64 <= limit {
            let Some((t, rest)) = self.triangle(body.rest, big) else {
                break;
            };
            if t.iter().any(|&k| k < 0 || k as usize >= n_vertices) {
                break;
            }
            out.push(t.map(|k| k as u32));
            body.rest = rest;
            read += 1;
        }
        read
    }

    /// [`FixedFace::triangles`] for the layout nearly every exporter writes, a one-byte length
    /// and 4-byte little-endian indices (`list uchar int`), decoded without asking the types for
    /// each number.
    fn little_triangles(
        &self,
        body: &mut Body<'_>,
        count: usize,
        n_vertices: usize,
        limit: u64,
        out: &mut Vec<[u32; 3]>,
    ) -> usize {
        let (at, size) = (self.before, self.before + 13 + self.after);
        // Reads while `out` holds at most `limit` triangles, as the general loop does.
        let room = limit.saturating_add(1).saturating_sub(out.len() as u64);
        let room = usize::try_from(room).unwrap_or(usize::MAX);
        let records = body.rest.chunks_exact(size).take(count.min(room));
        out.reserve_exact(records.len());
        // An `int` index below 0 reads as a `u32` of 2^31 or more: outside this bound.
        let bound = match self.item {
            ScalarType::Int => n_vertices.min(1 << 31),
            _ => n_vertices,
        };
        let before = out.len();
        out.extend(records.map_while(|r| {
            let i = |k: usize| u32::from_le_bytes([r[k], r[k + 1], r[k + 2], r[k + 3]]);
            let t = [i(at + 1), i(at + 5), i(at + 9)];
            (r[at] == 3 && t.iter().all(|&k| (k as usize) < bound)).then_some(t)
        }));
        let read = out.len() - before;
        body.rest = &body.rest[read * size..];
        read
    }

    /// The indices of the record at the start of `rest` and the bytes after it; `None` when the
    /// record is short or its length negative (the generic reader then says what is wrong).
    #[inline]
    fn read<'a>(&self, rest: &'a [u8], big: bool, indices: &mut Vec<i64>) -> Option<&'a [u8]> {
        let count_size = scalar_size(&self.count);
        let head = rest.get(self.before..self.before + count_size)?;
        let n = integer(head, &self.count, big);
        if n < 0 {
            return None;
        }
        let item_size = scalar_size(&self.item);
        let items_at = self.before + count_size;
        let end = (n as usize)
            .checked_mul(item_size)?
            .checked_add(items_at + self.after)?;
        let record = rest.get(..end)?;
        let items = &record[items_at..end - self.after];
        indices.extend(
            items
                .chunks_exact(item_size)
                .map(|b| integer(b, &self.item, big)),
        );
        Some(&rest[end..])
    }
}

/// An ASCII element whose lines the quick reader takes: its first properties are the ones read
/// (`x y z` scalars of a vertex, or a face's index list), then only scalars (`more` of them).
/// Other layouts are read line by line by [`ascii_record`].
#[derive(Clone, Copy)]
struct QuickAscii {
    more: usize,
}

impl QuickAscii {
    fn of(def: &ElementDef, roles: &[Role], lead: &[Role]) -> Option<QuickAscii> {
        let rest_scalars = (def.properties.values().skip(lead.len()))
            .all(|p| matches!(p.data_type, PropertyType::Scalar(_)));
        (roles.starts_with(lead) && rest_scalars).then(|| QuickAscii {
            more: roles.len() - lead.len(),
        })
    }

    /// The `N` numbers that start the line at the start of `rest`, read by `leading`, and the
    /// length of the line with its line end; `None`, having read nothing, for a line this does not
    /// take as it is (blank, short, a token that is not a number, a byte that is not ASCII):
    /// [`ascii_record`] then reads it and says what is wrong. What it takes, it reads as
    /// [`next_line`] and [`ascii_record`] would: tokens between blanks, extra tokens ignored.
    #[inline]
    fn numbers<T: Copy + Default, const N: usize>(
        self,
        rest: &[u8],
        leading: impl Fn(&[u8]) -> Option<(T, usize)>,
    ) -> Option<([T; N], usize)> {
        // ASCII whitespace that is not a line end (`is_ascii_whitespace` without `\n`, `\r`).
        let blank = |b: u8| matches!(b, b' ' | b'\t' | 0x0c);
        let (out, mut at) = text::leading_numbers(rest, 0, blank, leading)?;
        // The other scalars' tokens (at least `more`) and anything after them, to the line end.
        let mut tokens = 0;
        let mut in_token = false;
        let end = loop {
            match rest.get(at) {
                None => break at,
                Some(b'\n') => break at + 1,
                Some(b'\r') => break at + 1 + usize::from(rest.get(at + 1) == Some(&b'\n')),
                Some(&b) if b >= 0x80 => return None,
                Some(&b) => {
                    let starts = !blank(b) && !in_token;
                    tokens += usize::from(starts);
                    in_token = !blank(b);
                }
            }
            at += 1;
        };
        (tokens >= self.more).then_some((out, end))
    }
}

fn cut(token: &[u8]) -> String {
    String::from_utf8_lossy(token).chars().take(40).collect()
}

/// The header as clean `\n`-separated lines for ply-rs, the offset of the payload and the number
/// of header lines. Real files end lines with `\r\n` or a bare `\r` (old Mac exporters), indent
/// header lines, or carry comment text without `comment`: such lines are cleaned or skipped
/// (with a note) rather than failing the file.
fn split_header(bytes: &[u8], notes: &mut Vec<String>) -> Result<(String, usize, u64), ReadError> {
    const KEYWORDS: [&str; 7] = [
        "ply",
        "format",
        "comment",
        "obj_info",
        "element",
        "property",
        "end_header",
    ];
    // The line ending style of the file, from its first line: it decides where `end_header`'s
    // line (and so the binary payload) ends.
    // Only a file whose lines end with a bare `\r` can have `end_header\r` followed by a payload
    // starting with `\n`; elsewhere `end_header\r\n` is one line end (seen after `\n` lines).
    let crlf = !bytes.starts_with(b"ply\r") || bytes.starts_with(b"ply\r\n");
    let mut header = String::new();
    let mut pos = 0;
    let mut line_no = 0u64;
    let mut skipped = 0u64;
    while pos < bytes.len() {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n' || b == b'\r')
            .map_or(bytes.len(), |k| pos + k);
        let next = if crlf && bytes.get(end) == Some(&b'\r') && bytes.get(end + 1) == Some(&b'\n') {
            end + 2
        } else {
            end + 1
        };
        line_no += 1;
        let line = String::from_utf8_lossy(&bytes[pos..end]);
        let line = line.trim();
        pos = next.min(bytes.len());
        let first = line.split_ascii_whitespace().next().unwrap_or("");
        if first == "end_header" {
            header.push_str("end_header\n");
            return Ok((header, pos, line_no));
        }
        if line.is_empty() {
            continue;
        }
        if !KEYWORDS.contains(&first) {
            skipped += 1;
            if skipped == 1 {
                notes.push(format!(
                    "PLY header line {line_no} is not a header statement (`{}`); skipped",
                    cut(line.as_bytes())
                ));
            }
            continue;
        }
        // One space between words: ply-rs's grammar rejects tabs and runs of spaces.
        for (k, word) in line.split_ascii_whitespace().enumerate() {
            if k > 0 {
                header.push(' ');
            }
            header.push_str(word);
        }
        header.push('\n');
        if header.len() > 1 << 20 {
            break;
        }
    }
    Err(ReadError::new(
        "invalid PLY header: no `end_header` line (or a header over 1 MB) - the file is truncated \
         or not a PLY",
    ))
}

/// Error text from ply-rs on one line.
fn flat(s: &str) -> String {
    let s = s.split_whitespace().collect::<Vec<_>>().join(" ");
    s.chars().take(300).collect()
}

/// The next non-blank line of an ASCII PLY payload, moving `rest` past it; `line` counts the
/// lines taken, blank ones too. A line ends at `\n`, `\r` or `\r\n` (files from old Macs end
/// lines with a bare `\r`).
pub(crate) fn next_line<'a>(rest: &mut &'a [u8], line: &mut u64) -> Option<&'a [u8]> {
    while !rest.is_empty() {
        let end = memchr::memchr2(b'\n', b'\r', rest).unwrap_or(rest.len());
        let found = &rest[..end];
        let crlf = rest.get(end..end + 2) == Some(b"\r\n");
        *rest = rest.get(end + 1 + usize::from(crlf)..).unwrap_or(&[]);
        *line += 1;
        if !found.trim_ascii().is_empty() {
            return Some(found);
        }
    }
    None
}

/// The payload still to read, and (ASCII) the line number of the last line read.
struct Body<'a> {
    encoding: Encoding,
    rest: &'a [u8],
    line: u64,
}

impl<'a> Body<'a> {
    fn at(&self) -> String {
        if self.encoding == Encoding::Ascii {
            format!(" (line {})", self.line)
        } else {
            String::new()
        }
    }

    fn big(&self) -> bool {
        self.encoding == Encoding::BinaryBigEndian
    }

    /// Appends the positions of every vertex of `def` to `out`.
    fn vertices(&mut self, def: &ElementDef, out: &mut Vec<[f64; 3]>) -> Result<(), ReadError> {
        if self.encoding == Encoding::Ascii {
            let roles = roles(def);
            let axes = [Role::Axis(0), Role::Axis(1), Role::Axis(2)];
            let quick = QuickAscii::of(def, &roles, &axes);
            let mut indices = Vec::new();
            let plain = quick.is_some_and(|q| q.more == 0);
            for i in 0..def.count {
                // The plainest lines first (`x y z` and a line feed, single spaces), then the
                // other lines the quick reader takes, then the general reader.
                let line = (plain.then(|| text::plain_line(self.rest, text::leading_decimal)))
                    .flatten()
                    .or_else(|| quick.and_then(|q| q.numbers(self.rest, text::leading_f64)));
                if let Some((xyz, n)) = line {
                    self.rest = &self.rest[n..];
                    self.line += 1;
                    out.push(xyz);
                    continue;
                }
                let mut xyz = [0.0; 3];
                self.ascii(def, i, &roles, &mut xyz, &mut indices)?;
                out.push(xyz);
            }
            return Ok(());
        }
        let mut first = 0;
        if let Some(FixedRecord {
            size,
            axes: Some(axes),
        }) = FixedRecord::of(def)
        {
            // Whole records in one pass; a short tail is left to the generic reader's error.
            let whole = (self.rest.len() / size.max(1)).min(def.count);
            let (block, rest) = self.rest.split_at(whole * size);
            let big = self.big();
            match axes {
                [(0, ScalarType::Float), (4, ScalarType::Float), (8, ScalarType::Float)]
                    if !big =>
                {
                    out.extend(block.chunks_exact(size).map(|r| {
                        let f = |k: usize| {
                            f32::from_le_bytes([r[k], r[k + 1], r[k + 2], r[k + 3]]) as f64
                        };
                        [f(0), f(4), f(8)]
                    }))
                }
                _ => out.extend(
                    block
                        .chunks_exact(size)
                        .map(|r| axes.each_ref().map(|(at, t)| scalar(&r[*at..], t, big))),
                ),
            }
            self.rest = rest;
            first = whole;
        }
        for i in first..def.count {
            let v: Vertex = self.element(def, i)?;
            out.push(v.0);
        }
        Ok(())
    }

    /// The vertex indices of element `i` of a face or strip element, into `indices` (cleared
    /// first); `roles` are the element's [`roles`], `fixed` its bulk layout if it has one.
    fn indices(
        &mut self,
        def: &ElementDef,
        roles: &[Role],
        fixed: Option<&FixedFace>,
        i: usize,
        indices: &mut Vec<i64>,
    ) -> Result<(), ReadError> {
        indices.clear();
        if self.encoding == Encoding::Ascii {
            return self.ascii(def, i, roles, &mut [0.0; 3], indices);
        }
        if let Some(rest) = fixed.and_then(|f| f.read(self.rest, self.big(), indices)) {
            self.rest = rest;
            return Ok(());
        }
        indices.clear();
        let f: Face = self.element(def, i)?;
        let signed = f.signed.iter().map(|&k| k as i64);
        indices.extend(signed.chain(f.unsigned.iter().map(|&k| k as i64)));
        Ok(())
    }

    /// [`FixedFace::triangles`] for ASCII lines: reads up to `count` face lines that
    /// [`QuickAscii`] takes straight into `out` while they are triangles whose indices are below
    /// `n_vertices`, stopping too once `out` holds more than `limit` triangles; returns how many
    /// it read.
    fn triangles(
        &mut self,
        quick: QuickAscii,
        count: usize,
        n_vertices: usize,
        limit: u64,
        out: &mut Vec<[u32; 3]>,
    ) -> usize {
        let mut read = 0;
        let plain = quick.more == 0;
        while read < count && out.len() as u64 <= limit {
            // `3 a b c` and a line feed, single spaces (most lines), read without the quick
            // reader's scans; other lines by the quick reader.
            let line = (plain.then(|| text::plain_line(self.rest, text::leading_i64)))
                .flatten()
                .or_else(|| quick.numbers(self.rest, text::leading_i64));
            let Some(([n, a, b, c], len)) = line else {
                break;
            };
            let t = [a, b, c];
            if n != 3 || t.iter().any(|&k| k < 0 || k as usize >= n_vertices) {
                break;
            }
            out.push(t.map(|k| k as u32));
            self.rest = &self.rest[len..];
            self.line += 1;
            read += 1;
        }
        read
    }

    /// Reads past every record of `def`.
    fn skip(&mut self, def: &ElementDef) -> Result<(), ReadError> {
        if self.encoding == Encoding::Ascii {
            let roles = roles(def);
            let mut indices = Vec::new();
            for i in 0..def.count {
                self.ascii(def, i, &roles, &mut [0.0; 3], &mut indices)?;
            }
            return Ok(());
        }
        let mut first = 0;
        if let Some(fixed) = FixedRecord::of(def) {
            let whole = (self.rest.len() / fixed.size.max(1)).min(def.count);
            self.rest = &self.rest[whole * fixed.size..];
            first = whole;
        }
        for i in first..def.count {
            let _: Skip = self.element(def, i)?;
        }
        Ok(())
    }

    /// ASCII element `i` of `def` (its line, read by [`ascii_record`]).
    fn ascii(
        &mut self,
        def: &ElementDef,
        i: usize,
        roles: &[Role],
        xyz: &mut [f64; 3],
        indices: &mut Vec<i64>,
    ) -> Result<(), ReadError> {
        let Some(line) = next_line(&mut self.rest, &mut self.line) else {
            return Err(ReadError::new(format!(
                "truncated PLY: the file ends after {i} of the {} `{}` elements its header \
                 declares - re-export the file",
                def.count, def.name
            )));
        };
        if !line.is_ascii() && std::str::from_utf8(line).is_err() {
            return Err(ReadError::new(format!(
                "PLY line {}: not text in an ASCII PLY - the file is corrupted",
                self.line
            )));
        }
        ascii_record(line, def, roles, xyz, indices).map_err(|what| {
            ReadError::new(format!(
                "PLY {} {i} (line {}): {what} - fix or re-export the file",
                def.name, self.line
            ))
        })
    }

    /// Binary element `i` of `def` through ply-rs's generic reader: for layouts not read in bulk,
    /// and for the exact error where a bulk read stops (a short record, a negative length).
    fn element<E: PropertyAccess>(&mut self, def: &ElementDef, i: usize) -> Result<E, ReadError> {
        let parser = Parser::<E>::new();
        let result = match self.encoding {
            Encoding::BinaryBigEndian => parser.read_big_endian_element(&mut self.rest, def),
            _ => parser.read_little_endian_element(&mut self.rest, def),
        };
        result.map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                ReadError::new(format!(
                    "truncated PLY: the file ends inside `{}` element {i} (the header declares \
                     {}) - re-export the file",
                    def.name, def.count
                ))
            } else {
                ReadError::new(format!(
                    "PLY {} {i}{}: {} - fix or re-export the file",
                    def.name,
                    self.at(),
                    flat(&e.to_string())
                ))
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cx() -> ReadContext {
        ReadContext::for_tests()
    }

    /// An element the reader does not use is named in a note with its count, in the singular
    /// for one entry.
    #[test]
    fn skipped_elements_are_noted_with_their_count() {
        for (count, said) in [(1, "(1 entry)"), (2, "(2 entries)")] {
            let text = format!(
                "ply\nformat ascii 1.0\nelement material {count}\nproperty uchar r\n\
                 element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                 element face 1\nproperty list uchar int vertex_indices\nend_header\n\
                 {}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                "7\n".repeat(count)
            );
            let mesh = parse(text.as_bytes(), &cx()).expect("a triangle");
            assert_eq!(mesh.triangles.len(), 1);
            let note = format!("PLY element `material` {said} skipped");
            assert!(mesh.notes.contains(&note), "{:?}", mesh.notes);
        }
    }

    /// Strip 0 1 2 3 | 4 5 6 6 7 (-1 restarts): triangles 012, 213 (second window reversed), 456;
    /// 566 and 667 repeat vertex 6 (stitching), left out.
    #[test]
    fn tristrips_alternate_winding_and_drop_stitches() {
        let mut out = Vec::new();
        let strip = [0, 1, 2, 3, -1, 4, 5, 6, 6, 7].into_iter();
        assert_eq!(add_strip(strip, 8, &mut out), Ok(2));
        assert_eq!(out, vec![[0, 1, 2], [2, 1, 3], [4, 5, 6]]);
        assert_eq!(add_strip([0, 1, 9].into_iter(), 8, &mut out), Err(9));
        assert_eq!(add_strip([0, -2].into_iter(), 8, &mut out), Err(-2));
    }

    /// The quick reader of ASCII lines reads what the line-by-line reader reads, wherever it
    /// takes a line: the same line end, the same numbers. Random lines of numbers, odd tokens,
    /// blanks and line ends, for vertices and faces with 0-2 more scalars after what is read.
    #[test]
    fn quick_ascii_lines_read_as_the_line_reader() {
        const TOKENS: [&str; 16] = [
            "1",
            "-2.5",
            "3",
            "+4",
            "nan",
            "1e5",
            "0x1",
            "-0",
            "é",
            "1.0e",
            "2,5",
            "-",
            "7",
            "\x0b",
            "99999999999999999999",
            "inf",
        ];
        const GAPS: [&str; 5] = [" ", "\t", "\x0c", "  ", " \t"];
        const ENDS: [&str; 4] = ["\n", "\r\n", "\r", ""];
        let mut random = crate::geometry::xorshift(0x9e37_79b9_7f4a_7c15);
        let mut pick = |n: usize| (random() % n as u64) as usize;
        let mut taken = [0; 2];
        for more in 0..3 {
            let extra: String = (0..more).map(|k| format!("property int e{k}\n")).collect();
            let text = format!(
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                 property float z\n{extra}element face 1\n\
                 property list uchar int vertex_indices\n{extra}end_header\n"
            );
            let (_, header, _) = header(text.as_bytes()).unwrap();
            for (e, def) in header.elements.values().enumerate() {
                let roles = roles(def);
                let lead = [
                    [Role::Axis(0), Role::Axis(1), Role::Axis(2)].as_slice(),
                    &[Role::Indices],
                ];
                let quick = QuickAscii::of(def, &roles, lead[e]).expect("a quick layout");
                for _ in 0..20_000 {
                    let mut line = String::new();
                    if pick(4) == 0 {
                        line.push_str(GAPS[pick(GAPS.len())]);
                    }
                    for k in 0..pick(8) {
                        if k > 0 || pick(3) == 0 {
                            line.push_str(GAPS[pick(GAPS.len())]);
                        }
                        // Plain small numbers most of the time, so that many lines are taken.
                        match pick(3) {
                            // A face's list length is 3 for half of the lines.
                            _ if k == 0 && e == 1 && pick(2) == 0 => line.push('3'),
                            0 => line.push_str(TOKENS[pick(TOKENS.len())]),
                            _ => line.push_str(&pick(5).to_string()),
                        }
                    }
                    line.push_str(ENDS[pick(ENDS.len())]);
                    line.push_str("8 9 1\n");
                    let bytes = line.as_bytes();
                    let (mut xyz, mut indices) = ([0.0; 3], Vec::new());
                    let (mut rest, mut line_no) = (bytes, 0);
                    let by_line = next_line(&mut rest, &mut line_no)
                        .filter(|_| line_no == 1)
                        .filter(|l| l.is_ascii() || std::str::from_utf8(l).is_ok())
                        .and_then(|l| ascii_record(l, def, &roles, &mut xyz, &mut indices).ok())
                        .map(|()| bytes.len() - rest.len());
                    let (len, numbers) = if e == 0 {
                        let Some((q, len)) = quick.numbers::<f64, 3>(bytes, text::leading_f64)
                        else {
                            continue;
                        };
                        (len, q.map(f64::to_bits).to_vec())
                    } else {
                        let Some((q, len)) = quick.numbers::<i64, 4>(bytes, text::leading_i64)
                        else {
                            continue;
                        };
                        if q[0] != 3 {
                            continue;
                        }
                        (len, q[1..].iter().map(|&i| i as u64).collect())
                    };
                    taken[e] += 1;
                    let line = line.escape_debug();
                    assert_eq!(by_line, Some(len), "`{line}`");
                    let expected: Vec<u64> = if e == 0 {
                        xyz.map(f64::to_bits).to_vec()
                    } else {
                        indices.iter().map(|&i| i as u64).collect()
                    };
                    assert_eq!(numbers, expected, "`{line}`");
                }
            }
        }
        assert!(taken.iter().all(|&n| n > 3_000), "lines taken: {taken:?}");
    }

    /// The plainest lines' reader ([`text::plain_line`]) reads what the line-by-line reader
    /// reads, wherever it takes a line, and takes the plain lines of a real file's body. Random
    /// lines, mostly single spaces and line feeds, with odd tokens, blanks and line ends mixed in.
    #[test]
    fn plain_lines_read_as_the_line_reader() {
        const TOKENS: [&str; 14] = [
            "-2.5",
            "+4",
            "nan",
            "1e5",
            "1.",
            ".5",
            "-0",
            "1.0e",
            "1E-3",
            "2,5",
            "-",
            "inf",
            "99999999999999999999",
            "0.1234567890123456789",
        ];
        const GAPS: [&str; 3] = ["\t", "  ", " \x0c"];
        const ENDS: [&str; 4] = ["\r\n", " \n", "\r", "\t\n"];
        let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
            property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let (_, header, _) = header(text.as_bytes()).unwrap();
        let mut random = crate::geometry::xorshift(0x2545_f491_4f6c_dd1d);
        let mut pick = |n: usize| (random() % n as u64) as usize;
        let mut taken = [0; 2];
        for (e, def) in header.elements.values().enumerate() {
            let roles = roles(def);
            for _ in 0..20_000 {
                let mut line = String::new();
                // Mostly the numbers read (3 of a vertex, 4 of a face), single spaces and `\n`.
                let count = if pick(5) == 0 { 2 + pick(4) } else { 3 + e };
                for k in 0..count {
                    match pick(10) {
                        0 => line.push_str(GAPS[pick(GAPS.len())]),
                        _ if k > 0 => line.push(' '),
                        _ => {}
                    }
                    match pick(6) {
                        _ if k == 0 && e == 1 => line.push_str(["3", "3", "3", "4"][pick(4)]),
                        0 => line.push_str(TOKENS[pick(TOKENS.len())]),
                        1 if e == 0 => line.push_str(&format!("{:e}", pick(1 << 40) as f64 / 7e3)),
                        2 if e == 0 => line.push_str(&format!("-{}.{:03}", pick(1000), pick(1000))),
                        _ => line.push_str(&pick(100_000).to_string()),
                    }
                }
                line.push_str(if pick(8) == 0 {
                    ENDS[pick(ENDS.len())]
                } else {
                    "\n"
                });
                line.push_str("8 9 1\n");
                let bytes = line.as_bytes();
                let (mut xyz, mut indices) = ([0.0; 3], Vec::new());
                let (mut rest, mut line_no) = (bytes, 0);
                let by_line = next_line(&mut rest, &mut line_no)
                    .and_then(|l| ascii_record(l, def, &roles, &mut xyz, &mut indices).ok())
                    .map(|()| bytes.len() - rest.len());
                let (len, numbers, expected) = if e == 0 {
                    let Some((q, len)) = text::plain_line::<f64, 3>(bytes, text::leading_decimal)
                    else {
                        continue;
                    };
                    (
                        len,
                        q.map(f64::to_bits).to_vec(),
                        xyz.map(f64::to_bits).to_vec(),
                    )
                } else {
                    let Some((q, len)) = text::plain_line::<i64, 4>(bytes, text::leading_i64)
                    else {
                        continue;
                    };
                    if q[0] != 3 {
                        continue;
                    }
                    let expected = indices.iter().map(|&i| i as u64).collect();
                    (len, q[1..].iter().map(|&i| i as u64).collect(), expected)
                };
                taken[e] += 1;
                let line = line.escape_debug();
                assert_eq!(by_line, Some(len), "`{line}`");
                assert_eq!(numbers, expected, "`{line}`");
            }
        }
        assert!(taken.iter().all(|&n| n > 3_000), "lines taken: {taken:?}");
    }

    const SQUARE: &str = "ply\nformat ascii 1.0\ncomment unit square\nelement vertex 4\n\
        property float x\nproperty float y\nproperty float z\nproperty uchar red\n\
        element face 2\nproperty list uchar int vertex_indices\nproperty int flags\n\
        end_header\n0 0 0 255\n1 0 0 255\n1 1 0 255\n0 1 0 255\n4 0 1 2 3 7\n3 0 1 3 0\n";

    #[test]
    fn ascii_quad_and_triangle() {
        let m = parse(SQUARE.as_bytes(), &cx()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 3]]);
    }

    fn binary(big: bool) -> Vec<u8> {
        let fmt = if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut b = format!(
            "ply\nformat {fmt} 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
             property double z\nelement edge 1\nproperty int a\nelement face 1\n\
             property list uchar ushort vertex_index\nend_header\n"
        )
        .into_bytes();
        for v in [[0.0f64, 0.0, 0.0], [1.0, 0.0, 0.0], [f64::NAN, 1.0, 0.0]] {
            for c in v {
                b.extend(if big {
                    c.to_be_bytes()
                } else {
                    c.to_le_bytes()
                });
            }
        }
        b.extend([0u8; 4]);
        b.push(3);
        for i in [0u16, 1, 2] {
            b.extend(if big {
                i.to_be_bytes()
            } else {
                i.to_le_bytes()
            });
        }
        b
    }

    #[test]
    fn binary_both_endians_keep_nan() {
        for big in [false, true] {
            let m = parse(&binary(big), &cx()).unwrap();
            assert_eq!(m.triangles, vec![[0, 1, 2]]);
            assert_eq!(m.positions[1], [1.0, 0.0, 0.0]);
            assert!(m.positions[2][0].is_nan());
            assert!(m.notes.iter().any(|n| n.contains("`edge`")));
        }
    }

    /// A binary file in the layouts read in bulk, with scalars around the axes and the list:
    /// vertices `float x, uchar flag, float y, float z` (a unit square, 0 1 2 3 counter-clockwise)
    /// and faces `uchar a, list <count> int vertex_indices, short b`. Faces: `faces`, each a list
    /// of indices; `count` is the list's length type (`uchar` or `char`).
    fn bulk(count: &str, faces: &[&[i32]]) -> Vec<u8> {
        let mut b = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n\
             property uchar flag\nproperty float y\nproperty float z\nelement face {}\n\
             property uchar a\nproperty list {count} int vertex_indices\nproperty short b\n\
             end_header\n",
            faces.len()
        )
        .into_bytes();
        for [x, y] in [[0.0f32, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]] {
            b.extend(x.to_le_bytes());
            b.push(7);
            b.extend(y.to_le_bytes());
            b.extend(0f32.to_le_bytes());
        }
        for face in faces {
            b.push(9);
            b.push(face.len() as u8);
            for i in *face {
                b.extend(i.to_le_bytes());
            }
            b.extend((-2i16).to_le_bytes());
        }
        b
    }

    /// Triangle, square, triangle: 1 + 2 + 1 triangles, the square split as a fan (convex); the
    /// bulk reader stops at the square and takes up again after it. An index out of range, a
    /// record cut short and a negative length are the generic reader's errors, naming the face.
    #[test]
    fn binary_bulk_layouts_read_every_face_and_keep_the_errors() {
        let m = parse(
            &bulk("uchar", &[&[0, 1, 2], &[0, 1, 2, 3], &[1, 2, 3]]),
            &cx(),
        )
        .unwrap();
        assert_eq!(m.positions[2], [1.0, 1.0, 0.0]);
        assert_eq!(
            m.triangles,
            vec![[0, 1, 2], [0, 1, 2], [0, 2, 3], [1, 2, 3]]
        );
        let e = parse(&bulk("uchar", &[&[0, 1, 2], &[1, 2, 9]]), &cx())
            .unwrap_err()
            .0;
        assert!(
            e.starts_with("PLY face 1: vertex index 9 is out of range"),
            "{e}"
        );
        let b = bulk("uchar", &[&[0, 1, 2], &[1, 2, 3]]);
        let e = parse(&b[..b.len() - 3], &cx()).unwrap_err().0;
        assert!(e.contains("ends inside `face` element 1"), "{e}");
        let mut b = bulk("char", &[&[0, 1, 2], &[1, 2, 3]]);
        let second = b.len() - (1 + 1 + 12 + 2) + 1;
        b[second] = 0xFF; // a length of -1
        let e = parse(&b, &cx()).unwrap_err().0;
        assert!(
            e.contains("PLY face 1: List length cannot be negative"),
            "{e}"
        );
    }

    /// The bulk reader of `list uchar int` stops where the general reader would: at a negative
    /// index (a `u32` of 2^32 - 1 when read as one), and once the triangles pass the limit.
    #[test]
    fn bulk_triangles_stop_at_negative_indices_and_at_the_limit() {
        let e = parse(&bulk("uchar", &[&[0, 1, 2], &[1, -1, 3]]), &cx())
            .unwrap_err()
            .0;
        assert!(
            e.starts_with("PLY face 1: vertex index -1 is out of range"),
            "{e}"
        );
        // A square (two triangles), then three triangles: five triangles from four faces.
        let five = bulk(
            "uchar",
            &[&[0, 1, 2, 3], &[0, 1, 2], &[1, 2, 3], &[0, 2, 3]],
        );
        let mut cx = cx();
        cx.limits.max_triangles = 5;
        assert_eq!(parse(&five, &cx).unwrap().triangles.len(), 5);
        cx.limits.max_triangles = 4;
        let e = parse(&five, &cx).unwrap_err().0;
        assert!(e.contains("more than 4 triangles"), "{e}");
    }

    #[test]
    fn huge_header_count_fails_fast() {
        let s = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
                  property float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0";
        let e = parse(s, &cx()).unwrap_err().0;
        assert!(
            e.contains("4000000000 vertex") && e.contains("truncated"),
            "{e}"
        );
    }

    #[test]
    fn truncated_and_bad_indices() {
        let b = binary(false);
        let e = parse(&b[..b.len() - 3], &cx()).unwrap_err().0;
        assert!(e.contains("truncated"), "{e}");
        let bad = SQUARE.replace("3 0 1 3 0", "3 0 1 9 0");
        let e = parse(bad.as_bytes(), &cx()).unwrap_err().0;
        assert!(
            e.contains("face 1") && e.contains("line 18") && e.contains("9"),
            "{e}"
        );
        let neg = SQUARE.replace("3 0 1 3 0", "3 0 -1 3 0");
        assert!(parse(neg.as_bytes(), &cx()).unwrap_err().0.contains("-1"));
    }

    #[test]
    fn not_ply_and_empty() {
        assert!(parse(b"\x89PNG\r\n", &cx())
            .unwrap_err()
            .0
            .contains("not a PLY"));
        assert!(parse(b"", &cx()).unwrap().triangles.is_empty());
        let e = parse(b"ply\nformat ascii 1.0\nelement vertex 1\nbogus\n", &cx())
            .unwrap_err()
            .0;
        assert!(e.contains("invalid PLY header"), "{e}");
    }
}
