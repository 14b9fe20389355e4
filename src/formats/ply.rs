//! PLY reader (ASCII, binary little and big endian) on `ply-rs-bw` with our own `PropertyAccess`
//! structs (its `DefaultElement` is a map per vertex: CRATES.md 5.8).
//!
//! The header is parsed by the crate; before any payload is read, every element count is checked
//! against the bytes left in the file (a header claiming 4 billion vertices in a 1 KB file fails at
//! once, without allocating). The payload is then read one element at a time, so faces go straight
//! into triangles (split by [`super::polygon`]) and other elements are skipped without being kept.
//! Vertex `x y z` may have any numeric type; face indices come from `vertex_indices` or
//! `vertex_index` lists of any integer type and are range-checked here.

use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    BeginList, ElementDef, Encoding, Property, PropertyAccess, PropertyAccessResult, PropertyType,
    ScalarType,
};

use super::polygon::{self, SplitTally};
use super::{ReadContext, ReadError};
use crate::mesh::Mesh;

pub fn read(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    let bytes = std::fs::read(path)?;
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

/// Any element we do not use: read (to move past it) and dropped.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

fn scalar_size(t: &ScalarType) -> u64 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The fewest payload bytes one element can take: binary, the scalars and list counts (empty
/// lists); ASCII, one character and one separator per property.
fn min_element_bytes(def: &ElementDef, encoding: Encoding) -> u64 {
    if encoding == Encoding::Ascii {
        return (2 * def.properties.len() as u64).max(1);
    }
    def.properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) => scalar_size(t),
            PropertyType::List(count, _) => scalar_size(count),
        })
        .sum()
}

fn parse(bytes: &[u8], cx: &ReadContext) -> Result<Mesh, ReadError> {
    if bytes.is_empty() {
        let mut mesh = Mesh::default();
        mesh.notes.push("the file is empty".into());
        return Ok(mesh);
    }
    if !(bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r")) {
        return Err(ReadError::new(
            "not a PLY file: it does not start with the line `ply` - check that the file really \
             is a PLY (a renamed or corrupted file?)",
        ));
    }
    let mut reader = Reader::new(bytes);
    let header = Parser::<Skip>::new()
        .read_header(&mut reader)
        .map_err(|e| {
            ReadError::new(format!(
                "invalid PLY header: {} - fix the header or re-export the file",
                flat(&e.to_string())
            ))
        })?;
    let body: &[u8] = reader.get_ref();
    let header_lines = bytes[..bytes.len() - body.len()]
        .iter()
        .filter(|&&b| b == b'\n')
        .count() as u64;

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

    let mut mesh = Mesh::default();
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
    let vertices_read_before_faces = header
        .elements
        .get_index_of("vertex")
        .zip(header.elements.get_index_of("face"))
        .is_none_or(|(v, f)| v < f);
    for def in header.elements.values() {
        match def.name.as_str() {
            "vertex" => {
                for i in 0..def.count {
                    let v: Vertex = body.element(def, i)?;
                    mesh.positions.push(v.0);
                }
            }
            "face" => {
                for i in 0..def.count {
                    let f: Face = body.element(def, i)?;
                    poly.clear();
                    for index in f
                        .signed
                        .iter()
                        .map(|&k| k as i64)
                        .chain(f.unsigned.iter().map(|&k| k as i64))
                    {
                        if index < 0 || index as usize >= n_vertices {
                            return Err(ReadError::new(format!(
                                "PLY face {i}{}: vertex index {index} is out of range (the file \
                                 has {n_vertices} vertices) - the file is broken, re-export it",
                                body.at()
                            )));
                        }
                        poly.push(index as u32);
                    }
                    if vertices_read_before_faces {
                        let split =
                            polygon::triangulate(&poly, &mesh.positions, &mut mesh.triangles);
                        tally.add(split, i as u64);
                    } else {
                        faces.push((i as u64, poly.clone()));
                    }
                    if mesh.triangles.len() as u64 > cx.limits.max_triangles {
                        return Err(ReadError::new(format!(
                            "the file has more than {} triangles, over the limit: raise \
                             limits.max_triangles in the config to scan it",
                            cx.limits.max_triangles
                        )));
                    }
                }
            }
            _ => {
                for i in 0..def.count {
                    let _: Skip = body.element(def, i)?;
                }
                if def.count > 0 {
                    mesh.notes.push(format!(
                        "PLY element `{}` ({} entries) skipped",
                        def.name, def.count
                    ));
                }
            }
        }
    }
    for (i, poly) in &faces {
        let split = polygon::triangulate(poly, &mesh.positions, &mut mesh.triangles);
        tally.add(split, *i);
    }
    tally.notes("face (0-based)", &mut mesh.notes);
    Ok(mesh)
}

/// Error text from ply-rs on one line.
fn flat(s: &str) -> String {
    let s = s.split_whitespace().collect::<Vec<_>>().join(" ");
    s.chars().take(300).collect()
}

/// The payload still to read, and (ASCII) the line number of the last line read.
struct Body<'a> {
    encoding: Encoding,
    rest: &'a [u8],
    line: u64,
}

impl Body<'_> {
    fn at(&self) -> String {
        if self.encoding == Encoding::Ascii {
            format!(" (line {})", self.line)
        } else {
            String::new()
        }
    }

    fn element<E: PropertyAccess>(&mut self, def: &ElementDef, i: usize) -> Result<E, ReadError> {
        let parser = Parser::<E>::new();
        let result = match self.encoding {
            Encoding::Ascii => {
                // One element per line; blank lines are tolerated.
                let line = loop {
                    if self.rest.is_empty() {
                        return Err(ReadError::new(format!(
                            "truncated PLY: the file ends after {i} of the {} `{}` elements its \
                             header declares - re-export the file",
                            def.count, def.name
                        )));
                    }
                    let end = self
                        .rest
                        .iter()
                        .position(|&b| b == b'\n')
                        .unwrap_or(self.rest.len());
                    let line = &self.rest[..end];
                    self.rest = self.rest.get(end + 1..).unwrap_or(&[]);
                    self.line += 1;
                    if !line.trim_ascii().is_empty() {
                        break line;
                    }
                };
                let text = std::str::from_utf8(line).map_err(|_| {
                    ReadError::new(format!(
                        "PLY line {}: not text in an ASCII PLY - the file is corrupted",
                        self.line
                    ))
                })?;
                parser.read_ascii_element(text, def)
            }
            Encoding::BinaryLittleEndian => parser.read_little_endian_element(&mut self.rest, def),
            Encoding::BinaryBigEndian => parser.read_big_endian_element(&mut self.rest, def),
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
    use crate::formats::Limits;

    fn cx() -> ReadContext {
        ReadContext {
            root: ".".into(),
            limits: Limits::default(),
        }
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
