//! Repaired PLY: same encoding (ASCII, binary little or big endian), same header (comments and
//! `obj_info` kept, element counts updated), every vertex and face property kept. A vertex copy
//! duplicates its vertex's properties at the new position; a face keeps its own properties, a
//! hole fill takes its neighbour's; per-corner face lists (`texcoord` with 2 values a corner)
//! follow their corners (a fill's corner taken from a face without such a list gets the values of
//! its own face's corner at the same vertex, else zeros, so every record keeps its length). Normals
//! (`nx ny nz`) that disagree with a flipped face are negated; a fill's corner whose vertex's
//! normal is far from the fill's own takes a copy of the vertex with the fill's normal. A face
//! index list whose item type cannot hold the copy's largest vertex number (a `uchar` list once a
//! split, or a fill's own normal, numbers a vertex copy 256) is declared with the smallest wider
//! type of its kind, with a note; numbers are never wrapped or cut. Likewise a vertex property
//! whose type cannot hold a value the copy writes is declared `float` (or `double` where `float`
//! cannot hold it either), with a note: integer coordinates (`short x`) where a split vertex's copy
//! lies between integers (cast back, it would fall onto its vertex and weld onto it again when
//! read), `float` coordinates where a split in a fan finer than `float`'s steps keeps its exact
//! place, an integer normal given a fill's normal or turned negative.
//!
//! Other elements: one that names vertices by a recognised property (integer scalars `vertex`,
//! `vertex1`, `vertex2`, ..., `vertex_index`, `vertex_id`; integer lists `vertex_indices`,
//! `vertex_index`, `vertex_list`, as in the standard `edge` element) has those indices renumbered
//! like the vertices, and a record naming a dropped or missing vertex is left out. One with no
//! integer property at all cannot number anything and is copied unchanged. Any other (integers of
//! unknown meaning, which may number vertices or faces the repair renumbered) is left out of the
//! copy, and so is an element without properties; each of these is said in a note.

use std::fmt::Write as _;
use std::path::Path;

use ply_rs_bw::ply::{ElementDef, Encoding, PropertyType, ScalarType};

use rustc_hash::FxHashMap;

use super::{
    fill_normals, normal_sums, polygon_corner, renumber, write_atomic, Item, Job, NormalCopies,
    Polygons, WriteError, Written,
};
use crate::formats::ply::{header, next_line, scalar, scalar_size};
use crate::mesh::Mesh;
use crate::repair::Plan;

/// The records of one element: record `i` is `values[starts[i]..starts[i + 1]]`, a list stored as
/// its length then its items. Every PLY number fits an f64 exactly.
struct Element {
    def: ElementDef,
    starts: Vec<usize>,
    values: Vec<f64>,
}

impl Element {
    fn record(&self, i: usize) -> &[f64] {
        &self.values[self.starts[i]..self.starts[i + 1]]
    }

    /// Every record, in order.
    fn records(&self) -> impl Iterator<Item = &[f64]> {
        self.starts.windows(2).map(|w| &self.values[w[0]..w[1]])
    }
}

/// Writes the copy, with notes on what it could not keep (elements left out, records dropped).
pub fn write(job: Job<'_>) -> Result<Written, WriteError> {
    // Read once, as the reader reads it (its limits), and parsed as it parses.
    let bytes = crate::formats::read_bytes(job.source, &job.cx.limits)?;
    let mesh = crate::formats::ply::parse(&bytes, job.cx)?;
    job.unchanged(std::slice::from_ref(&mesh))?;
    let notes = copy(&bytes, &mesh, job.single()?, job.out)?;
    Ok(job.written(Vec::new(), notes))
}

/// The copy of the source `bytes`, read as `mesh`.
fn copy(bytes: &[u8], mesh: &Mesh, plan: &Plan, out: &Path) -> Result<Vec<String>, WriteError> {
    let (text, header, start) = header(bytes)?;
    if header.elements.contains_key("tristrips") {
        return Err(WriteError::new(
            "PLY triangle strips (`tristrips`) cannot be written yet: convert the file to faces",
        ));
    }
    let elements = parse_body(&bytes[start..], &header)?;
    let face_element = elements.iter().find(|e| e.def.name == "face");
    let index_key = face_element.and_then(|e| {
        ["vertex_indices", "vertex_index"]
            .into_iter()
            .find(|k| e.def.properties.contains_key(*k))
    });
    let index_slot = |e: &Element| {
        e.def
            .properties
            .keys()
            .position(|k| Some(k.as_str()) == index_key)
    };

    // Face polygons, as the reader split them.
    let polygons = match face_element {
        Some(e) => {
            let slot = index_slot(e).unwrap_or(0);
            Polygons::new(e.def.count, |i, out| list_into(e, i, slot, out), mesh)?
        }
        None => Polygons::new(0, |_, _| {}, mesh)?,
    };
    let items = polygons.items(plan, mesh);
    let (index, kept) = renumber(plan);
    let mut notes = Vec::new();
    let sums = normal_sums(plan, mesh, |c| Some(c.vertex));
    let copies = normal_copies(&elements, plan, mesh, &sums);

    // The face element as the copy declares it: its index list's item type widened when the
    // copy's vertex numbers do not fit it (a split's copies numbered past 255 in a `uchar` list).
    // Every vertex of a polygon written whole is a corner of one of its triangles, so the largest
    // number the faces name is the largest among the plan's triangles.
    let mut face_def = face_element.map(|e| e.def.clone());
    let mut widened = None;
    if let (Some(def), Some(key)) = (face_def.as_mut(), index_key) {
        if let Some(p) = def.properties.get_mut(key) {
            if let PropertyType::List(_, item) = &mut p.data_type {
                let top = plan
                    .triangles
                    .iter()
                    .flat_map(|t| &t.corners)
                    .map(|c| index[c.vertex as usize])
                    .max()
                    .unwrap_or(0)
                    .max((kept + copies.copies.len()).saturating_sub(1) as u32);
                if let Some(wide) = wider(item, top) {
                    notes.push(format!(
                        "the PLY face list `{key}` is {} in the copy instead of {}: the repair \
                         numbers vertices up to {top}, past what {} holds",
                        type_name(&wide),
                        type_name(item),
                        type_name(item)
                    ));
                    widened = Some((key, wide.clone()));
                    *item = wide;
                }
            }
        }
    }

    // The vertex records the copy writes, then the vertex element as the copy declares it: a
    // scalar property whose type cannot hold a value written (integer coordinates where a split's
    // copy moved a hair into its fan; an integer normal given a fill's normal or turned over)
    // declared `float`, or `double` where `float` cannot hold it either.
    let vertex_element = elements.iter().find(|e| e.def.name == "vertex");
    let vertex_records = vertex_element.map(|e| vertex_records(e, plan, mesh, &sums, &copies));
    let mut vertex_def = vertex_element.map(|e| e.def.clone());
    // The properties retyped: name, old type, new type.
    let mut retyped = Vec::new();
    if let (Some(def), Some(e), Some(records)) =
        (vertex_def.as_mut(), vertex_element, &vertex_records)
    {
        for (slot, (name, p)) in def.properties.iter_mut().enumerate() {
            let PropertyType::Scalar(t) = &mut p.data_type else {
                continue;
            };
            let values = || records.records().map(|r| r[scalar_at(e, r, slot)]);
            if values().all(|v| holds(t, v, header.encoding)) {
                continue;
            }
            let wide = if values().all(|v| holds(&ScalarType::Float, v, header.encoding)) {
                ScalarType::Float
            } else {
                ScalarType::Double
            };
            retyped.push((name.clone(), type_name(t), wide.clone()));
            *t = wide;
        }
    }
    if !retyped.is_empty() {
        let each: Vec<String> = retyped
            .iter()
            .map(|(name, was, wide)| format!("`{name}` {was} -> {}", type_name(wide)))
            .collect();
        notes.push(format!(
            "PLY vertex propert{} declared wider in the copy ({}): the copy writes values the \
                 source's types cannot hold, such as a split vertex's copy between integer \
                 positions or a fill's normal",
            if each.len() == 1 { "y" } else { "ies" },
            each.join(", ")
        ));
    }

    let mut body = Body::new(header.encoding);
    // Each element's new count; `None`: left out of the copy.
    let mut counts: Vec<(String, Option<usize>)> = Vec::new();
    for e in &elements {
        if e.def.properties.is_empty() {
            if e.def.count > 0 {
                notes.push(format!(
                    "PLY element `{}` has no properties (no data): left out of the copy",
                    e.def.name
                ));
            }
            counts.push((e.def.name.clone(), None));
            continue;
        }
        match e.def.name.as_str() {
            "vertex" => {
                let def = vertex_def.as_ref().unwrap_or(&e.def);
                for record in vertex_records.iter().flat_map(Element::records) {
                    body.record(def, record);
                }
                counts.push((e.def.name.clone(), Some(kept + copies.copies.len())));
            }
            "face" => {
                let def = face_def.as_ref().unwrap_or(&e.def);
                let slot = index_slot(e).unwrap_or(0);
                for item in &items {
                    // (polygon whose properties are used, its corners in output order, vertices)
                    let (face, corners, vertices): (usize, Vec<usize>, Vec<u32>) = match *item {
                        Item::Polygon { face, reversed } => {
                            let poly = list(e, face, slot);
                            let n = poly.len();
                            let corners: Vec<usize> =
                                (0..n).map(|k| polygon_corner(n, k, reversed)).collect();
                            let vertices = corners.iter().map(|&k| poly[k]).collect();
                            (face, corners, vertices)
                        }
                        Item::Triangle(i) => {
                            let t = &plan.triangles[i];
                            let face = polygons.of(t);
                            let corners = t
                                .corners
                                .iter()
                                .map(|c| polygons.corner(c.from).1)
                                .collect();
                            let vertices = t.corners.iter().map(|c| c.vertex).collect();
                            (face, corners, vertices)
                        }
                    };
                    let origins: Vec<u32> = vertices
                        .iter()
                        .map(|&v| super::original(plan, mesh, v))
                        .collect();
                    // The copy's vertex numbers: a fill's corner may take a vertex copy.
                    let numbers: Vec<u32> = vertices
                        .iter()
                        .enumerate()
                        .map(|(j, &v)| {
                            let copy = match *item {
                                Item::Triangle(i) => copies
                                    .corners
                                    .get(&(i, j))
                                    .map(|&place| (kept + place) as u32),
                                Item::Polygon { .. } => None,
                            };
                            copy.unwrap_or(index[v as usize])
                        })
                        .collect();
                    let record = face_record(
                        e, face, slot, &corners, &numbers, &origins, item, plan, &polygons,
                    );
                    body.record(def, &record);
                }
                counts.push((e.def.name.clone(), Some(items.len())));
            }
            _ => match vertex_references(e) {
                References::None => {
                    for i in 0..e.def.count {
                        body.record(&e.def, e.record(i));
                    }
                    counts.push((e.def.name.clone(), Some(e.def.count)));
                }
                References::Known(slots) => {
                    let mut kept = 0;
                    'records: for i in 0..e.def.count {
                        let mut record = e.record(i).to_vec();
                        for &(slot, is_list) in &slots {
                            let at = scalar_at(e, &record, slot);
                            let range = if is_list {
                                at + 1..at + 1 + record[at] as usize
                            } else {
                                at..at + 1
                            };
                            for value in &mut record[range] {
                                match renumbered(*value, mesh.positions.len(), &index) {
                                    Some(new) => *value = new as f64,
                                    None => continue 'records,
                                }
                            }
                        }
                        body.record(&e.def, &record);
                        kept += 1;
                    }
                    if kept < e.def.count {
                        let n = e.def.count - kept;
                        notes.push(format!(
                            "PLY element `{}`: {n} record{} left out (they name a vertex the \
                             repair dropped or that does not exist)",
                            e.def.name,
                            if n == 1 { "" } else { "s" }
                        ));
                    }
                    counts.push((e.def.name.clone(), Some(kept)));
                }
                References::Unknown => {
                    notes.push(format!(
                        "PLY element `{}` left out of the copy: its integer properties may number \
                         vertices or faces, which the repair renumbered",
                        e.def.name
                    ));
                    counts.push((e.def.name.clone(), None));
                }
            },
        }
    }

    let mut header_text = rewrite_counts(&text, &counts);
    if let Some((key, wide)) = &widened {
        header_text = retype(&header_text, "face", key, wide);
    }
    for (name, _, wide) in &retyped {
        header_text = retype(&header_text, "vertex", name, wide);
    }
    let mut out_bytes = header_text.into_bytes();
    out_bytes.extend_from_slice(&body.bytes);
    write_atomic(out, &out_bytes)?;
    Ok(notes)
}

/// The vertex copies fills' corners take for their hole's normal ([`NormalCopies`]; a PLY vertex
/// has one normal), numbered after the kept vertices; none without `nx ny nz`.
fn normal_copies(
    elements: &[Element],
    plan: &Plan,
    mesh: &Mesh,
    sums: &FxHashMap<u32, [f64; 3]>,
) -> NormalCopies {
    let none = NormalCopies {
        copies: Vec::new(),
        corners: FxHashMap::default(),
    };
    let Some(e) = elements.iter().find(|e| e.def.name == "vertex") else {
        return none;
    };
    let keys = e.def.properties.keys();
    let Some(slots) = ["nx", "ny", "nz"]
        .map(|k| keys.clone().position(|p| p == k))
        .into_iter()
        .collect::<Option<Vec<usize>>>()
    else {
        return none;
    };
    let stored = |vertex: u32| {
        let record = e.record(super::original(plan, mesh, vertex) as usize);
        [0, 1, 2].map(|k| record[scalar_at(e, record, slots[k])])
    };
    let holes = fill_normals(plan, mesh);
    NormalCopies::new(plan, &holes, 0..plan.triangles.len(), sums, stored)
}

/// How an element other than `vertex` and `face` refers to vertices.
enum References {
    /// No integer property: it cannot number anything.
    None,
    /// These property slots (and whether each is a list) hold vertex indices.
    Known(Vec<(usize, bool)>),
    /// Integer properties of unknown meaning.
    Unknown,
}

fn vertex_references(e: &Element) -> References {
    let integer = |t: &ScalarType| !matches!(t, ScalarType::Float | ScalarType::Double);
    let mut known = Vec::new();
    let mut integers = false;
    for (slot, (name, p)) in e.def.properties.iter().enumerate() {
        let name = name.to_ascii_lowercase();
        match &p.data_type {
            PropertyType::Scalar(t) if integer(t) => {
                integers = true;
                let numbered = name
                    .strip_prefix("vertex")
                    .is_some_and(|rest| rest.bytes().all(|b| b.is_ascii_digit()));
                if numbered || name == "vertex_index" || name == "vertex_id" {
                    known.push((slot, false));
                }
            }
            PropertyType::List(_, t) if integer(t) => {
                integers = true;
                if matches!(
                    name.as_str(),
                    "vertex_indices" | "vertex_index" | "vertex_list"
                ) {
                    known.push((slot, true));
                }
            }
            _ => {}
        }
    }
    match (known.is_empty(), integers) {
        (false, _) => References::Known(known),
        (true, false) => References::None,
        (true, true) => References::Unknown,
    }
}

/// The new number of input vertex `value` (`None`: not a vertex of the input, or dropped).
fn renumbered(value: f64, inputs: usize, index: &[u32]) -> Option<u32> {
    if !(value >= 0.0 && value < inputs as f64 && value.fract() == 0.0) {
        return None;
    }
    index
        .get(value as usize)
        .copied()
        .filter(|&n| n != u32::MAX)
}

/// A face record: the properties of source face `face` with the index list replaced by
/// `vertices` (renumbered) and per-corner lists reordered by `corners`. `origins` are the input
/// vertices the output corners carry (for a fill corner whose source face has no such list).
#[allow(clippy::too_many_arguments)]
fn face_record(
    e: &Element,
    face: usize,
    slot: usize,
    corners: &[usize],
    numbers: &[u32],
    origins: &[u32],
    item: &Item,
    plan: &Plan,
    polygons: &Polygons,
) -> Vec<f64> {
    let source = e.record(face);
    let own_vertices = list(e, face, slot);
    let n_source = own_vertices.len();
    let mut out = Vec::with_capacity(source.len());
    let mut at = 0;
    for (k, (name, p)) in e.def.properties.iter().enumerate() {
        match p.data_type {
            PropertyType::Scalar(_) => {
                out.push(source[at]);
                at += 1;
            }
            PropertyType::List(..) => {
                let len = source[at] as usize;
                let items = &source[at + 1..at + 1 + len];
                at += 1 + len;
                if k == slot {
                    out.push(numbers.len() as f64);
                    out.extend(numbers.iter().map(|&v| f64::from(v)));
                } else if n_source > 0 && len > 0 && len.is_multiple_of(n_source) {
                    // Per-corner values: each output corner takes its own corner's values (a
                    // fill's corner, those of the neighbour face it came from). Exactly `stride`
                    // values go out per corner, so the record keeps the length it states.
                    let stride = len / n_source;
                    let own = |c: usize| &items[stride * c..stride * (c + 1)];
                    out.push((stride * corners.len()) as f64);
                    for (j, &c) in corners.iter().enumerate() {
                        let from = match item {
                            Item::Triangle(i) => {
                                Some(polygons.corner(plan.triangles[*i].corners[j].from))
                            }
                            Item::Polygon { .. } => None,
                        };
                        match from {
                            Some((f, k)) if f != face => {
                                let other = per_corner(e, f, k, slot);
                                match other.get(name.as_str()).filter(|v| v.len() == stride) {
                                    Some(values) => out.extend_from_slice(values),
                                    // That face has no such list: this face's corner at the same
                                    // vertex, or zeros when it has none there.
                                    None => {
                                        match own_vertices.iter().position(|&v| v == origins[j]) {
                                            Some(c) => out.extend_from_slice(own(c)),
                                            None => out.extend(std::iter::repeat_n(0.0, stride)),
                                        }
                                    }
                                }
                            }
                            _ => out.extend_from_slice(own(c)),
                        }
                    }
                } else {
                    out.push(len as f64);
                    out.extend_from_slice(items);
                }
            }
        }
    }
    out
}

/// The per-corner list values of corner `k` of face `f`, by property name.
fn per_corner(
    e: &Element,
    f: usize,
    k: usize,
    slot: usize,
) -> std::collections::HashMap<&str, Vec<f64>> {
    let source = e.record(f);
    let n = list(e, f, slot).len();
    let mut out = std::collections::HashMap::new();
    let mut at = 0;
    for (j, (name, p)) in e.def.properties.iter().enumerate() {
        match p.data_type {
            PropertyType::Scalar(_) => at += 1,
            PropertyType::List(..) => {
                let len = source[at] as usize;
                if j != slot && n > 0 && len > 0 && len.is_multiple_of(n) {
                    let stride = len / n;
                    out.insert(
                        name.as_str(),
                        source[at + 1 + stride * k..at + 1 + stride * (k + 1)].to_vec(),
                    );
                }
                at += 1 + len;
            }
        }
    }
    out
}

/// The integer list in property slot `slot` of record `i`.
fn list(e: &Element, i: usize, slot: usize) -> Vec<u32> {
    let mut out = Vec::new();
    list_into(e, i, slot, &mut out);
    out
}

/// Appends the vertex indices of face `i` (its list in property `slot`) to `out`.
fn list_into(e: &Element, i: usize, slot: usize, out: &mut Vec<u32>) {
    let r = e.record(i);
    let mut at = 0;
    for (k, (_, p)) in e.def.properties.iter().enumerate() {
        let width = match p.data_type {
            PropertyType::Scalar(_) => 1,
            PropertyType::List(..) => 1 + r[at] as usize,
        };
        if k == slot {
            out.extend(r[at + 1..at + width].iter().map(|&x| x as u32));
            return;
        }
        at += width;
    }
}

/// The index in `record` of the value of scalar property slot `slot`.
fn scalar_at(e: &Element, record: &[f64], slot: usize) -> usize {
    let mut at = 0;
    for (_, p) in e.def.properties.iter().take(slot) {
        at += match p.data_type {
            PropertyType::Scalar(_) => 1,
            PropertyType::List(..) => 1 + record[at] as usize,
        };
    }
    at
}

/// The header text with each element's count replaced, and the elements counted `None` (with
/// their property lines) left out. Words may be separated by any run of whitespace.
fn rewrite_counts(header: &str, counts: &[(String, Option<usize>)]) -> String {
    let mut out = String::with_capacity(header.len() + 16);
    let mut skipping = false;
    for line in header.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        if words.first() == Some(&"element") {
            skipping = false;
            if words.len() == 3 {
                if let Some((_, n)) = counts.iter().find(|(name, _)| name == words[1]) {
                    match n {
                        Some(n) => {
                            let _ = writeln!(out, "element {} {n}", words[1]);
                        }
                        None => skipping = true,
                    }
                    continue;
                }
            }
        } else if words.first() == Some(&"end_header") {
            skipping = false;
        } else if skipping && words.first() == Some(&"property") {
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// The smallest integer type of the same kind as `item` (signed or not) that holds `top`, when
/// `item` does not; `None` when it does (or is a float type).
fn wider(item: &ScalarType, top: u32) -> Option<ScalarType> {
    let top = u64::from(top);
    let max = |t: &ScalarType| match t {
        ScalarType::Char => 127,
        ScalarType::UChar => 255,
        ScalarType::Short => 32_767,
        ScalarType::UShort => 65_535,
        ScalarType::Int => 2_147_483_647,
        ScalarType::UInt | ScalarType::Float | ScalarType::Double => u64::MAX,
    };
    if top <= max(item) {
        return None;
    }
    let ladder: &[ScalarType] = match item {
        ScalarType::Char | ScalarType::Short | ScalarType::Int => {
            &[ScalarType::Short, ScalarType::Int, ScalarType::UInt]
        }
        _ => &[ScalarType::UShort, ScalarType::UInt],
    };
    ladder.iter().find(|t| top <= max(t)).cloned()
}

/// The copy's vertex records (as an element of `e`'s properties): each used vertex's record at
/// its planned place, its normal turned to agree with its faces where they turned over, then the
/// copies of vertices that fills' corners take with the fills' own normals.
fn vertex_records(
    e: &Element,
    plan: &Plan,
    mesh: &Mesh,
    sums: &FxHashMap<u32, [f64; 3]>,
    copies: &NormalCopies,
) -> Element {
    let slot_of = |key: &str| e.def.properties.keys().position(|k| k == key);
    let xyz = ["x", "y", "z"].map(slot_of);
    let normal = ["nx", "ny", "nz"].map(slot_of);
    let mut out = Element {
        def: e.def.clone(),
        starts: vec![0],
        values: Vec::new(),
    };
    let mut push = |from: u32, p: [f64; 3], normal_of: &dyn Fn(&mut [f64])| {
        let start = out.values.len();
        out.values.extend_from_slice(e.record(from as usize));
        let record = &mut out.values[start..];
        for (k, slot) in xyz.iter().enumerate() {
            if let Some(s) = slot {
                record[scalar_at(e, record, *s)] = p[k];
            }
        }
        normal_of(record);
        out.starts.push(out.values.len());
    };
    let normal_at = |record: &[f64]| match normal {
        [Some(a), Some(b), Some(c)] => Some([a, b, c].map(|s| scalar_at(e, record, s))),
        _ => None,
    };
    for (v, &used) in plan.used_vertices.iter().enumerate() {
        if !used {
            continue;
        }
        let v = v as u32;
        push(
            super::original(plan, mesh, v),
            plan.position(mesh, v),
            &|record| {
                if let (Some(sum), Some(at)) = (sums.get(&v), normal_at(record)) {
                    if crate::geometry::dot(at.map(|i| record[i]), *sum) < 0.0 {
                        for i in at {
                            record[i] = -record[i];
                        }
                    }
                }
            },
        );
    }
    for &(v, n) in &copies.copies {
        push(
            super::original(plan, mesh, v),
            plan.position(mesh, v),
            &|record| {
                for (k, slot) in normal.iter().enumerate() {
                    if let Some(s) = slot {
                        record[scalar_at(e, record, *s)] = n[k];
                    }
                }
            },
        );
    }
    out
}

/// Whether a property of type `t` holds `v` exactly in a file of this `encoding`: an integer type a
/// whole number in its range; `float` in a binary file a value that round trips through `f32`,
/// and in an ASCII file any value (the text holds every digit of it, and it reads back as
/// written: the reader parses `float` text to `f64` as it does `double`).
fn holds(t: &ScalarType, v: f64, encoding: Encoding) -> bool {
    let whole = |lo: f64, hi: f64| v.fract() == 0.0 && (lo..=hi).contains(&v);
    match t {
        ScalarType::Char => whole(-128.0, 127.0),
        ScalarType::UChar => whole(0.0, 255.0),
        ScalarType::Short => whole(-32_768.0, 32_767.0),
        ScalarType::UShort => whole(0.0, 65_535.0),
        ScalarType::Int => whole(-2_147_483_648.0, 2_147_483_647.0),
        ScalarType::UInt => whole(0.0, 4_294_967_295.0),
        // NaN holds as NaN; a finite value must round trip.
        ScalarType::Float => encoding == Encoding::Ascii || v.is_nan() || f64::from(v as f32) == v,
        ScalarType::Double => true,
    }
}

/// A scalar type's name in a PLY header.
fn type_name(t: &ScalarType) -> &'static str {
    match t {
        ScalarType::Char => "char",
        ScalarType::UChar => "uchar",
        ScalarType::Short => "short",
        ScalarType::UShort => "ushort",
        ScalarType::Int => "int",
        ScalarType::UInt => "uint",
        ScalarType::Float => "float",
        ScalarType::Double => "double",
    }
}

/// The header text with property `property` of element `element` declared with type `t`: a
/// scalar's type, or a list's item type (its count type kept).
fn retype(header: &str, element: &str, property: &str, t: &ScalarType) -> String {
    let mut out = String::with_capacity(header.len() + 8);
    let mut current = "";
    for line in header.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let here = |name: &str| current == element && name == property;
        match words.as_slice() {
            ["element", name, ..] => current = name,
            ["property", "list", count, _, name] if here(name) => {
                let _ = writeln!(out, "property list {count} {} {name}", type_name(t));
                continue;
            }
            ["property", _, name] if here(name) => {
                let _ = writeln!(out, "property {} {name}", type_name(t));
                continue;
            }
            _ => {}
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

fn parse_body(body: &[u8], header: &ply_rs_bw::ply::Header) -> Result<Vec<Element>, WriteError> {
    let mut elements = Vec::new();
    let mut reader = Reader {
        rest: body,
        encoding: header.encoding,
    };
    for def in header.elements.values() {
        let mut e = Element {
            def: def.clone(),
            starts: vec![0],
            values: Vec::new(),
        };
        // An element without properties holds no bytes (however large its count): nothing to read.
        let count = if def.properties.is_empty() {
            0
        } else {
            def.count
        };
        for i in 0..count {
            reader.record(def, &mut e.values).ok_or_else(|| {
                WriteError::new(format!("PLY {} {i} could not be read again", def.name))
            })?;
            e.starts.push(e.values.len());
        }
        elements.push(e);
    }
    Ok(elements)
}

struct Reader<'a> {
    rest: &'a [u8],
    encoding: Encoding,
}

impl Reader<'_> {
    fn record(&mut self, def: &ElementDef, out: &mut Vec<f64>) -> Option<()> {
        if self.encoding == Encoding::Ascii {
            let line = next_line(&mut self.rest, &mut 0)?;
            let text = std::str::from_utf8(line).ok()?;
            let mut tokens = text.split_ascii_whitespace();
            for p in def.properties.values() {
                match p.data_type {
                    PropertyType::Scalar(_) => out.push(tokens.next()?.parse().unwrap_or(f64::NAN)),
                    PropertyType::List(..) => {
                        let n: usize = tokens.next()?.parse().ok()?;
                        out.push(n as f64);
                        for _ in 0..n {
                            out.push(tokens.next()?.parse().unwrap_or(f64::NAN));
                        }
                    }
                }
            }
            return Some(());
        }
        let big = self.encoding == Encoding::BinaryBigEndian;
        for p in def.properties.values() {
            match &p.data_type {
                PropertyType::Scalar(t) => out.push(self.scalar(t, big)?),
                PropertyType::List(count, item) => {
                    let n = self.scalar(count, big)?;
                    out.push(n);
                    for _ in 0..n as usize {
                        out.push(self.scalar(item, big)?);
                    }
                }
            }
        }
        Some(())
    }

    fn scalar(&mut self, t: &ScalarType, big: bool) -> Option<f64> {
        let b = self.rest.get(..scalar_size(t))?;
        self.rest = &self.rest[b.len()..];
        Some(scalar(b, t, big))
    }
}

/// The payload being written.
struct Body {
    encoding: Encoding,
    bytes: Vec<u8>,
}

impl Body {
    fn new(encoding: Encoding) -> Body {
        Body {
            encoding,
            bytes: Vec::new(),
        }
    }

    fn record(&mut self, def: &ElementDef, values: &[f64]) {
        let mut at = 0;
        let mut first = true;
        for p in def.properties.values() {
            match &p.data_type {
                PropertyType::Scalar(t) => {
                    self.value(t, values[at], &mut first);
                    at += 1;
                }
                PropertyType::List(count, item) => {
                    let n = values[at] as usize;
                    self.value(count, n as f64, &mut first);
                    for &v in &values[at + 1..at + 1 + n] {
                        self.value(item, v, &mut first);
                    }
                    at += 1 + n;
                }
            }
        }
        if self.encoding == Encoding::Ascii {
            self.bytes.push(b'\n');
        }
    }

    fn value(&mut self, t: &ScalarType, v: f64, first: &mut bool) {
        match self.encoding {
            Encoding::Ascii => {
                if !*first {
                    self.bytes.push(b' ');
                }
                *first = false;
                let text = match t {
                    ScalarType::Float | ScalarType::Double => super::number(v),
                    _ => format!("{}", v as i64),
                };
                self.bytes.extend_from_slice(text.as_bytes());
            }
            Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
                let mut b: Vec<u8> = match t {
                    ScalarType::Char => vec![v as i8 as u8],
                    ScalarType::UChar => vec![v as u8],
                    ScalarType::Short => (v as i16).to_le_bytes().to_vec(),
                    ScalarType::UShort => (v as u16).to_le_bytes().to_vec(),
                    ScalarType::Int => (v as i32).to_le_bytes().to_vec(),
                    ScalarType::UInt => (v as u32).to_le_bytes().to_vec(),
                    ScalarType::Float => (v as f32).to_le_bytes().to_vec(),
                    ScalarType::Double => v.to_le_bytes().to_vec(),
                };
                if self.encoding == Encoding::BinaryBigEndian {
                    b.reverse();
                }
                self.bytes.extend_from_slice(&b);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::rewrite_counts;

    /// Element lines with runs of spaces or tabs get their new count; a dropped element goes with
    /// its property lines, and the lines around it stay.
    #[test]
    fn counts_are_rewritten_whatever_the_spacing() {
        let header = "ply\nformat ascii 1.0\nelement  vertex\t9\nproperty float x\n\
                      element\tedge   3\nproperty int vertex1\nproperty int vertex2\n\
                      element face 6\nproperty list uchar int vertex_indices\nend_header\n";
        let counts = [
            ("vertex".to_owned(), Some(8)),
            ("edge".to_owned(), None),
            ("face".to_owned(), Some(7)),
        ];
        assert_eq!(
            rewrite_counts(header, &counts),
            "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\n\
             element face 7\nproperty list uchar int vertex_indices\nend_header\n"
        );
    }
}
