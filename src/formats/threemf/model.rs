//! One model part of a 3MF package, read as a stream of XML events (no document tree, so a part
//! of hundreds of megabytes costs only its meshes): the `<model>` and its unit and required
//! extensions, the `<resources>` (objects with a `<mesh>` or `<components>`; materials,
//! colours, textures, slices and other extension resources are read past), and the `<build>`.
//!
//! Refused, each with a message: a root element that is not a 3MF `<model>`, a required extension
//! meshvet does not read, a unit or object type the specification does not have, more than one
//! `<resources>` or `<build>` (or none), an object without an id or with the id of another, a
//! vertex without a coordinate or with one that is not a number, a triangle index that is not a
//! whole number or names a vertex the mesh does not have, a transform that is not twelve finite
//! numbers, and a reference to another part that lies outside the package. Vertex coordinates
//! that are numbers but not finite (`INF`, `NaN`) are kept: the analysis counts them as invalid
//! vertices, as it does for every format. Elements the reader does not know are read past (their
//! tags still checked); inside `<vertices>` and `<triangles>` they are counted in a note, and what
//! else a `<mesh>` holds (a beam lattice, triangle sets) is named in one.
//!
//! Also here: the two small parts of the package that are XML too, relationships (`.rels`) and
//! the secure-content keystore.

use std::io::BufRead;
use std::ops::Range;

use quick_xml::events::{BytesStart, Event};
use rustc_hash::FxHashMap;

use super::super::{Limits, ReadError};
use super::package;
use super::xml::{Step, Xml};

/// The 3MF core namespace.
pub const CORE: &[u8] = b"http://schemas.microsoft.com/3dmanufacturing/core/2015/02";
/// The production extension (`p:path`, `p:UUID`).
pub const PRODUCTION: &[u8] = b"http://schemas.microsoft.com/3dmanufacturing/production/2015/06";

/// Extensions a file may require that leave the meaning of its `<mesh>` elements as the core
/// specification says: materials and properties, production, beam lattices (and their balls),
/// slices, secure content (an encrypted part is refused when it is read) and triangle sets.
const READ_PAST: [&[u8]; 7] = [
    b"http://schemas.microsoft.com/3dmanufacturing/material/2015/02",
    PRODUCTION,
    b"http://schemas.microsoft.com/3dmanufacturing/beamlattice/2017/02",
    b"http://schemas.microsoft.com/3dmanufacturing/beamlattice/balls/2020/07",
    b"http://schemas.microsoft.com/3dmanufacturing/slice/2015/07",
    b"http://schemas.microsoft.com/3dmanufacturing/securecontent/2019/04",
    b"http://schemas.microsoft.com/3dmanufacturing/trianglesets/2021/07",
];

/// No per-triangle property (`pid`, `p1`..`p3`).
pub const NONE: u32 = u32::MAX;

/// The `unit` of a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    Micron,
    Millimeter,
    Centimeter,
    Inch,
    Foot,
    Meter,
}

impl Unit {
    const ALL: [Unit; 6] = [
        Unit::Micron,
        Unit::Millimeter,
        Unit::Centimeter,
        Unit::Inch,
        Unit::Foot,
        Unit::Meter,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Unit::Micron => "micron",
            Unit::Millimeter => "millimeter",
            Unit::Centimeter => "centimeter",
            Unit::Inch => "inch",
            Unit::Foot => "foot",
            Unit::Meter => "meter",
        }
    }
}

/// An object's `type`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Model,
    SolidSupport,
    Support,
    Surface,
    /// Not printable: skipped, and an error when the build or a component names it.
    Other,
}

impl Kind {
    const ALL: [Kind; 5] = [
        Kind::Model,
        Kind::SolidSupport,
        Kind::Support,
        Kind::Surface,
        Kind::Other,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Kind::Model => "model",
            Kind::SolidSupport => "solidsupport",
            Kind::Support => "support",
            Kind::Surface => "surface",
            Kind::Other => "other",
        }
    }
}

/// The sign of a placement's determinant: mirrored, flat (zero) or neither.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sign {
    Positive,
    Negative,
    Zero,
}

/// A build item or a component: an object and how it is placed.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    pub object: u32,
    /// The part named by `p:path` (a key); `None`: the part that holds the reference.
    pub path: Option<String>,
    pub sign: Sign,
}

/// Where a mesh's elements lie in the inflated part, for the writer of a repaired copy.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Spans {
    pub mesh: Range<u64>,
    pub vertices: Option<Range<u64>>,
    pub triangles: Option<Range<u64>>,
}

/// The `<mesh>` of an object.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshData {
    pub positions: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// `pid`, `p1`, `p2`, `p3` of every triangle ([`NONE`] where absent); only when kept.
    pub properties: Vec<[u32; 4]>,
    /// The other attributes of the triangles that have any (a slicer's paint, such as
    /// `slic3rpe:mmu_segmentation` or `paint_color`, namespace declarations, ...), as the file
    /// writes them: each ` name="value"` with its prefix, its quotes and its value's references
    /// as they are, so that a writer can put them back verbatim. Per such triangle, its index and
    /// the end of its text in [`MeshData::other_text`] (its text starts where the one before ends);
    /// only when kept.
    pub others: Vec<(u32, usize)>,
    pub other_text: String,
    pub spans: Spans,
    /// What else the `<mesh>` holds, in words (`beam lattice`, `triangle sets`, `<x>`), each kind
    /// once with how many elements of it there are, at most [`EXTRA_KINDS`] kinds: a note per
    /// element made a 2 KB file give a report row of 240,000 notes.
    pub extras: Vec<(String, u64)>,
    /// Elements of kinds past the first [`EXTRA_KINDS`].
    pub other_extras: u64,
    /// Elements inside `<vertices>` or `<triangles>` that the core specification does not have.
    pub unknown: u64,
}

/// The kinds of elements a `<mesh>` holds besides its vertices and triangles that are named in
/// notes; those past them are counted together.
pub const EXTRA_KINDS: usize = 8;

impl MeshData {
    /// The other attributes of triangle `t` (see [`MeshData::others`]), `""` when it has none.
    pub fn other_attributes(&self, t: u32) -> &str {
        match self.others.binary_search_by_key(&t, |&(k, _)| k) {
            Ok(i) => {
                let start = if i == 0 { 0 } else { self.others[i - 1].1 };
                self.other_text.get(start..self.others[i].1).unwrap_or("")
            }
            Err(_) => "",
        }
    }

    /// Adds ` name="value"` to the other attributes of the triangle being read (`value` as
    /// written, references not expanded; in single quotes when it holds a double one).
    fn other_attribute(&mut self, name: &[u8], value: &[u8]) {
        let quote = if value.contains(&b'"') { b'\'' } else { b'"' };
        let text = &mut self.other_text;
        text.push(' ');
        text.push_str(&String::from_utf8_lossy(name));
        text.push('=');
        text.push(char::from(quote));
        text.push_str(&String::from_utf8_lossy(value));
        text.push(char::from(quote));
    }

    /// Ends the other attributes of the triangle about to be pushed (its text began at `start`).
    fn close_others(&mut self, start: usize) {
        if self.other_text.len() > start {
            let t = u32::try_from(self.triangles.len()).unwrap_or(u32::MAX);
            self.others.push((t, self.other_text.len()));
        }
    }

    /// Counts an element of kind `extra` (see [`MeshData::extras`]).
    fn add_extra(&mut self, extra: String) {
        if let Some(kind) = self.extras.iter_mut().find(|(e, _)| *e == extra) {
            kind.1 += 1;
        } else if self.extras.len() < EXTRA_KINDS {
            self.extras.push((extra, 1));
        } else {
            self.other_extras += 1;
        }
    }

    /// Adds a triangle (and its properties, when kept), counting it against the file's limit.
    fn push_triangle(
        &mut self,
        t: [u32; 3],
        properties: [u32; 4],
        totals: &mut Totals,
        settings: &Settings,
        part: &str,
    ) -> Result<(), ReadError> {
        totals.triangles += 1;
        if totals.triangles > settings.limits.max_triangles {
            return Err(over_limit(part, "triangles", settings.limits));
        }
        self.triangles.push(t);
        if settings.keep {
            self.properties.push(properties);
        }
        Ok(())
    }
}

/// What an object is made of.
#[derive(Debug, Clone, PartialEq)]
pub enum Content {
    Mesh(Box<MeshData>),
    Components(Vec<Reference>),
    /// Neither (its shape comes from an extension meshvet does not read).
    Nothing,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    pub id: u32,
    pub name: Option<String>,
    pub kind: Kind,
    pub content: Content,
}

/// One model part.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    pub unit: Unit,
    /// In document order.
    pub objects: Vec<Object>,
    /// Object id -> index in `objects`.
    pub ids: FxHashMap<u32, usize>,
    /// The build items (only the root part's are used).
    pub items: Vec<Reference>,
}

/// What the parts of one package have read so far, held to `limits.max_triangles`.
#[derive(Debug, Default)]
pub struct Totals {
    pub vertices: u64,
    pub triangles: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Node {
    Model,
    Resources,
    Build,
    Object,
    Mesh,
    Vertices,
    Triangles,
    Components,
}

/// What the reading of a part needs besides its bytes.
pub struct Settings<'a> {
    /// The part's key.
    pub key: &'a str,
    /// The part's name as the package spells it (`/3D/3dmodel.model`), for messages.
    pub name: &'a str,
    /// Whether this is the root model part (its build is used and required).
    pub root: bool,
    /// Keep per-triangle properties (for the writer).
    pub keep: bool,
    pub limits: &'a Limits,
}

/// An object being read.
struct Open {
    id: u32,
    name: Option<String>,
    kind: Kind,
    content: Content,
}

/// Reads one model part.
pub fn parse<R: BufRead>(
    source: R,
    settings: &Settings<'_>,
    totals: &mut Totals,
) -> Result<Model, ReadError> {
    let part = settings.name.to_owned();
    let mut xml = Xml::new(source, &part);
    let mut buf = Vec::with_capacity(1 << 10);
    let mut stack: Vec<Node> = Vec::with_capacity(8);
    let mut model = Model {
        unit: Unit::Millimeter,
        objects: Vec::new(),
        ids: FxHashMap::default(),
        items: Vec::new(),
    };
    let (mut resources, mut build) = (0u32, 0u32);
    let mut open: Option<Open> = None;
    let mut mesh: Option<Box<MeshData>> = None;
    let mut components: Vec<Reference> = Vec::new();
    // Whether the last event was a tag (so the source is between markup, see `Xml::empty_run`).
    let mut after_tag = false;
    loop {
        if after_tag {
            match (stack.last(), mesh.as_mut()) {
                (Some(Node::Vertices), Some(m)) => {
                    xml.empty_run(b"vertex", CORE, |attributes| {
                        let Some(p) = plain_vertex(attributes) else {
                            return Ok(false);
                        };
                        totals.vertices += 1;
                        if totals.vertices > settings.limits.max_triangles {
                            return Err(over_limit(&part, "vertices", settings.limits));
                        }
                        m.positions.push(p);
                        Ok(true)
                    })?;
                }
                (Some(Node::Triangles), Some(m)) => {
                    xml.empty_run(b"triangle", CORE, |attributes| {
                        let Some((t, properties)) = plain_triangle(attributes, settings.keep)
                        else {
                            return Ok(false);
                        };
                        if settings.keep {
                            let start = m.other_text.len();
                            for &(name, value) in attributes {
                                if !core_triangle_attribute(name) {
                                    m.other_attribute(name, value);
                                }
                            }
                            m.close_others(start);
                        }
                        m.push_triangle(t, properties, totals, settings, &part)?;
                        Ok(true)
                    })?;
                }
                _ => {}
            }
        }
        let (step, event) = xml.next(&mut buf)?;
        after_tag = matches!(step, Step::Start | Step::Empty | Step::End);
        let e = match (&step, &event) {
            (Step::Start | Step::Empty, Event::Start(e) | Event::Empty(e)) => e,
            (Step::End, _) => {
                let at = xml.position();
                match stack.pop() {
                    Some(Node::Vertices) => {
                        if let Some(m) = mesh.as_mut() {
                            m.spans.vertices =
                                Some(m.spans.vertices.take().unwrap_or_default().start..at);
                        }
                    }
                    Some(Node::Triangles) => {
                        if let Some(m) = mesh.as_mut() {
                            m.spans.triangles =
                                Some(m.spans.triangles.take().unwrap_or_default().start..at);
                        }
                    }
                    Some(Node::Mesh) => {
                        let mut m = mesh.take().expect("a mesh is open inside <mesh>");
                        m.spans.mesh.end = at;
                        let o = open.as_mut().expect("a mesh is inside an object");
                        check_indices(&m, o.id, &part)?;
                        o.content = Content::Mesh(m);
                    }
                    Some(Node::Components) => {
                        let o = open.as_mut().expect("components are inside an object");
                        o.content = Content::Components(std::mem::take(&mut components));
                    }
                    Some(Node::Object) => {
                        let o = open.take().expect("an object is open");
                        add_object(&mut model, o, &part)?;
                    }
                    _ => {}
                }
                continue;
            }
            (Step::Eof, _) => break,
            _ => continue,
        };
        let start = step == Step::Start;
        let core = xml.namespace(e) == Some(CORE);
        let local = e.local_name().into_inner();
        let parent = stack.last().copied();
        // The hot paths first: a million-triangle part is almost all vertices and triangles.
        if core && parent == Some(Node::Vertices) && local == b"vertex" {
            let m = mesh.as_mut().expect("vertices are inside a mesh");
            let p = vertex(e, &xml, m.positions.len())?;
            totals.vertices += 1;
            if totals.vertices > settings.limits.max_triangles {
                return Err(over_limit(&part, "vertices", settings.limits));
            }
            m.positions.push(p);
            if start {
                xml.skip(&mut buf)?;
            }
            continue;
        }
        if core && parent == Some(Node::Triangles) && local == b"triangle" {
            let m = mesh.as_mut().expect("triangles are inside a mesh");
            let (t, properties) = triangle(e, &xml, m.triangles.len(), settings.keep)?;
            if settings.keep {
                let start = m.other_text.len();
                xml.each_raw_attribute(e, |name, value| {
                    if !core_triangle_attribute(name) {
                        m.other_attribute(name, value);
                    }
                });
                m.close_others(start);
            }
            m.push_triangle(t, properties, totals, settings, &part)?;
            if start {
                xml.skip(&mut buf)?;
            }
            continue;
        }
        let node = match (parent, core, local) {
            (None, true, b"model") => {
                read_model(e, &xml, &mut model)?;
                Some(Node::Model)
            }
            (None, _, _) => {
                return Err(xml.error(&format!(
                    "has the root element <{}>, not the <model> of the 3MF core namespace: it is not a 3MF model",
                    String::from_utf8_lossy(e.name().as_ref())
                )))
            }
            (Some(Node::Model), true, b"resources") => {
                resources += 1;
                Some(Node::Resources)
            }
            (Some(Node::Model), true, b"build") => {
                build += 1;
                Some(Node::Build)
            }
            (Some(Node::Resources), true, b"object") => {
                open = Some(read_object(e, &xml)?);
                Some(Node::Object)
            }
            (Some(Node::Object), true, b"mesh" | b"components") => {
                let o = open.as_ref().expect("an object is open");
                if o.content != Content::Nothing {
                    return Err(xml.error(&format!(
                        "gives object {} more than one <mesh> or <components> (an object is one or the other)",
                        o.id
                    )));
                }
                if local == b"mesh" {
                    mesh = Some(Box::new(MeshData {
                        spans: Spans {
                            mesh: xml.start..xml.start,
                            ..Spans::default()
                        },
                        ..MeshData::default()
                    }));
                    Some(Node::Mesh)
                } else {
                    Some(Node::Components)
                }
            }
            (Some(Node::Mesh), true, b"vertices" | b"triangles") => {
                let m = mesh.as_mut().expect("a mesh is open");
                let seen = if local == b"vertices" {
                    &m.spans.vertices
                } else {
                    &m.spans.triangles
                };
                if seen.is_some() {
                    return Err(xml.error(&format!(
                        "gives a mesh more than one <{}> (a mesh has one of each): the file is damaged - re-export it",
                        String::from_utf8_lossy(local)
                    )));
                }
                let span = Some(xml.start..xml.position());
                if local == b"vertices" {
                    m.spans.vertices = span;
                    Some(Node::Vertices)
                } else {
                    m.spans.triangles = span;
                    Some(Node::Triangles)
                }
            }
            (Some(Node::Components), true, b"component") => {
                components.push(reference(e, &xml, settings.key, "a component")?);
                None
            }
            (Some(Node::Build), true, b"item") => {
                model.items.push(reference(e, &xml, settings.key, "a build item")?);
                None
            }
            (Some(Node::Mesh), _, _) => {
                let m = mesh.as_mut().expect("a mesh is open");
                let ns = xml.namespace(e);
                m.add_extra(extra_name(ns, local));
                None
            }
            (Some(Node::Vertices | Node::Triangles), true, _) => {
                mesh.as_mut().expect("a mesh is open").unknown += 1;
                None
            }
            _ => {
                // Materials, metadata, extension resources and attributes: read past.
                None
            }
        };
        match (node, start) {
            (Some(node), true) => stack.push(node),
            (Some(node), false) => {
                // An empty structural element: `<mesh/>`, `<build/>`, `<object .../>`, ...
                match node {
                    Node::Object => {
                        let o = open.take().expect("an object is open");
                        add_object(&mut model, o, &part)?;
                    }
                    Node::Mesh => {
                        let mut m = mesh.take().expect("a mesh is open");
                        m.spans.mesh.end = xml.position();
                        open.as_mut().expect("an object is open").content = Content::Mesh(m);
                    }
                    Node::Components => {
                        open.as_mut().expect("an object is open").content =
                            Content::Components(Vec::new());
                    }
                    _ => {}
                }
            }
            (None, true) => xml.skip(&mut buf)?,
            (None, false) => {}
        }
    }
    if resources != 1 {
        return Err(xml.error(&match resources {
            0 => "has no <resources> (a 3MF model needs one): the file is damaged - re-export it".to_owned(),
            n => format!("has {n} <resources> elements (a 3MF model has one): the file is damaged - re-export it"),
        }));
    }
    if build > 1 || (settings.root && build == 0) {
        return Err(xml.error(&match build {
            0 => "has no <build> (a 3MF model needs one to say what is printed): the file is damaged - re-export it".to_owned(),
            n => format!("has {n} <build> elements (a 3MF model has one): the file is damaged - re-export it"),
        }));
    }
    Ok(model)
}

fn over_limit(part: &str, what: &str, limits: &Limits) -> ReadError {
    ReadError::new(format!(
        "part {part} brings the meshes of this file to more than {} {what}: raise limits.max_triangles in the config to read it",
        limits.max_triangles
    ))
}

fn add_object(model: &mut Model, o: Open, part: &str) -> Result<(), ReadError> {
    if model.ids.insert(o.id, model.objects.len()).is_some() {
        return Err(ReadError::new(format!(
            "part {part} defines object {} twice (object ids are unique in a part): the file is damaged - re-export it",
            o.id
        )));
    }
    model.objects.push(Object {
        id: o.id,
        name: o.name,
        kind: o.kind,
        content: o.content,
    });
    Ok(())
}

/// Every triangle index names a vertex of the mesh.
fn check_indices(m: &MeshData, id: u32, part: &str) -> Result<(), ReadError> {
    let n = m.positions.len();
    let bad = m
        .triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&v| v as usize >= n));
    if let Some((t, corners)) = bad {
        let v = corners
            .iter()
            .find(|&&v| v as usize >= n)
            .copied()
            .unwrap_or(0);
        return Err(ReadError::new(format!(
            "part {part}: triangle {t} of object {id} names vertex {v}, but the mesh has {n} vertices (indices count from 0): the file is damaged - re-export it"
        )));
    }
    Ok(())
}

fn read_model<R: BufRead>(
    e: &BytesStart,
    xml: &Xml<R>,
    model: &mut Model,
) -> Result<(), ReadError> {
    let part = xml.part.as_str();
    let mut required: Vec<Vec<u8>> = Vec::new();
    xml.each_attribute(e, |ns, local, value| {
        if ns.is_some() {
            return Ok(());
        }
        match local {
            b"unit" => {
                model.unit = Unit::ALL
                    .into_iter()
                    .find(|u| u.name().as_bytes() == value)
                    .ok_or_else(|| {
                        ReadError::new(format!(
                            "part {part} has the unit `{}`, which 3MF does not have (micron, millimeter, centimeter, inch, foot or meter): fix or re-export the file",
                            String::from_utf8_lossy(value)
                        ))
                    })?;
            }
            b"requiredextensions" => required.extend(
                value
                    .split(u8::is_ascii_whitespace)
                    .filter(|p| !p.is_empty())
                    .map(<[u8]>::to_vec),
            ),
            _ => {}
        }
        Ok(())
    })?;
    for prefix in required {
        let text = String::from_utf8_lossy(&prefix);
        match xml.prefix(&prefix) {
            Some(ns) => {
                if ns != CORE && !READ_PAST.contains(&ns) {
                    return Err(ReadError::new(format!(
                        "part {part} requires the 3MF extension {} (prefix `{text}`), which meshvet does not read: the meshes it describes may not be what the file means - check it with a tool that supports the extension",
                        String::from_utf8_lossy(ns)
                    )));
                }
            }
            _ => {
                return Err(ReadError::new(format!(
                    "part {part} requires the extension prefix `{text}`, which it does not declare (XML that is not namespace-well-formed): the file is damaged - re-export it"
                )))
            }
        }
    }
    Ok(())
}

fn read_object<R: BufRead>(e: &BytesStart, xml: &Xml<R>) -> Result<Open, ReadError> {
    let part = xml.part.as_str();
    let mut id = None;
    let mut name = None;
    let mut kind = Kind::Model;
    xml.each_attribute(e, |ns, local, value| {
        if ns.is_some() {
            return Ok(());
        }
        match local {
            b"id" => id = Some(whole(value, part, "an object", "id")?),
            b"name" => name = Some(String::from_utf8_lossy(value).into_owned()),
            b"type" => {
                kind = Kind::ALL
                    .into_iter()
                    .find(|k| k.name().as_bytes() == value)
                    .ok_or_else(|| {
                        ReadError::new(format!(
                            "part {part} has an object of type `{}`, which 3MF does not have (model, solidsupport, support, surface or other): fix or re-export the file",
                            String::from_utf8_lossy(value)
                        ))
                    })?
            }
            _ => {}
        }
        Ok(())
    })?;
    let id = required(id, part, "an object", "id")?;
    Ok(Open {
        id,
        name,
        kind,
        content: Content::Nothing,
    })
}

/// A build item or component: `objectid`, `transform`, `p:path`.
fn reference<R: BufRead>(
    e: &BytesStart,
    xml: &Xml<R>,
    key: &str,
    what: &str,
) -> Result<Reference, ReadError> {
    let part = xml.part.as_str();
    let mut object = None;
    let mut path = None;
    let mut sign = Sign::Positive;
    xml.each_attribute(e, |ns, local, value| {
        match (ns, local) {
            (None, b"objectid") => object = Some(whole(value, part, what, "objectid")?),
            (None, b"transform") => {
                sign = transform_sign(value).map_err(|why| {
                    ReadError::new(format!(
                        "part {part} has {what} whose transform `{}` {why}: a 3MF transform is twelve finite numbers - fix or re-export the file",
                        String::from_utf8_lossy(value)
                    ))
                })?
            }
            (Some(PRODUCTION), b"path") => {
                let target = String::from_utf8_lossy(value);
                path = Some(package::resolve(&target, key).map_err(|why| {
                    ReadError::new(format!("part {part} has {what} whose p:path {why}"))
                })?);
            }
            _ => {}
        }
        Ok(())
    })?;
    let object = required(object, part, what, "objectid")?;
    Ok(Reference { object, path, sign })
}

/// The index in attribute `name` of `what` (`an object`, `a build item`, ...), or why it is none.
fn whole(value: &[u8], part: &str, what: &str, name: &str) -> Result<u32, ReadError> {
    index(value).ok_or_else(|| {
        ReadError::new(format!(
            "part {part} has {what} whose {name} `{}` is not a whole number: the file is damaged - re-export it",
            String::from_utf8_lossy(value)
        ))
    })
}

/// Attribute `name` of `what`, which 3MF requires.
fn required<T>(value: Option<T>, part: &str, what: &str, name: &str) -> Result<T, ReadError> {
    value.ok_or_else(|| {
        ReadError::new(format!(
            "part {part} has {what} without an {name}: the file is damaged - re-export it"
        ))
    })
}

/// The sign of the determinant of a transform's 3x3 part (`m00 m01 m02 m10 m11 m12 m20 m21 m22`,
/// then the translation), or why the text is not a transform.
pub fn transform_sign(text: &[u8]) -> Result<Sign, String> {
    let mut m = [0.0f64; 12];
    let mut n = 0;
    for word in text
        .split(u8::is_ascii_whitespace)
        .filter(|w| !w.is_empty())
    {
        if n == 12 {
            return Err("has more than twelve numbers".into());
        }
        let x = number(word).ok_or_else(|| {
            format!(
                "holds `{}`, which is not a number",
                String::from_utf8_lossy(word)
            )
        })?;
        if !x.is_finite() {
            return Err(format!(
                "holds `{}`, which is not finite",
                String::from_utf8_lossy(word)
            ));
        }
        m[n] = x;
        n += 1;
    }
    if n < 12 {
        return Err(format!("has {n} numbers"));
    }
    let det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6])
        + m[2] * (m[3] * m[7] - m[4] * m[6]);
    Ok(if det > 0.0 {
        Sign::Positive
    } else if det < 0.0 {
        Sign::Negative
    } else {
        Sign::Zero // flat, or so large it overflows: not mirrored
    })
}

/// A number as 3MF writes them (ASCII, optional sign, exponent), read to the same value as
/// `str::parse::<f64>` gives; surrounding whitespace is allowed. `NaN` and `INF` read as such.
pub fn number(text: &[u8]) -> Option<f64> {
    fast_float2::parse::<f64, _>(text.trim_ascii()).ok()
}

/// A non-negative whole number that fits in `u32` (an optional `+`, decimal digits).
pub fn index(text: &[u8]) -> Option<u32> {
    let text = text.trim_ascii();
    let digits = text.strip_prefix(b"+").unwrap_or(text);
    if digits.is_empty() {
        return None;
    }
    let mut n: u32 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        n = n.checked_mul(10)?.checked_add(u32::from(d - b'0'))?;
    }
    Some(n)
}

/// A vertex from the plain attributes of a tag, if they hold three numbers.
fn plain_vertex(attributes: &[(&[u8], &[u8])]) -> Option<[f64; 3]> {
    let mut p = [0.0f64; 3];
    let mut got = 0u8;
    for &(name, value) in attributes {
        let axis = match name {
            b"x" => 0,
            b"y" => 1,
            b"z" => 2,
            _ => continue,
        };
        p[axis] = number(value)?;
        got |= 1 << axis;
    }
    (got == 0b111).then_some(p)
}

/// Whether an attribute of a `<triangle>` (its name as written) is one the reader takes apart:
/// `v1`..`v3`, `pid`, `p1`..`p3` (no prefix: the core namespace's).
fn core_triangle_attribute(name: &[u8]) -> bool {
    matches!(name, b"v1" | b"v2" | b"v3" | b"pid" | b"p1" | b"p2" | b"p3")
}

/// A triangle (and its properties when `keep`) from the plain attributes of a tag, if its indices
/// are whole numbers.
fn plain_triangle(attributes: &[(&[u8], &[u8])], keep: bool) -> Option<([u32; 3], [u32; 4])> {
    let mut v = [0u32; 3];
    let mut properties = [NONE; 4];
    let mut got = 0u8;
    for &(name, value) in attributes {
        match name {
            b"v1" | b"v2" | b"v3" => {
                let k = usize::from(name[1] - b'1');
                v[k] = index(value)?;
                got |= 1 << k;
            }
            b"pid" | b"p1" | b"p2" | b"p3" => {
                let k = if name == b"pid" {
                    0
                } else {
                    usize::from(name[1] - b'0')
                };
                // Checked also when not kept: a scan refuses what the repair's reading refuses.
                let n = index(value)?;
                if keep {
                    properties[k] = n;
                }
            }
            _ => {}
        }
    }
    (got == 0b111).then_some((v, properties))
}

fn vertex<R: BufRead>(e: &BytesStart, xml: &Xml<R>, k: usize) -> Result<[f64; 3], ReadError> {
    let part = xml.part.as_str();
    let mut p = [0.0f64; 3];
    let mut got = 0u8;
    xml.each_attribute(e, |ns, local, value| {
        let axis = match (ns, local) {
            (None, b"x") => 0,
            (None, b"y") => 1,
            (None, b"z") => 2,
            _ => return Ok(()),
        };
        p[axis] = number(value).ok_or_else(|| {
            ReadError::new(format!(
                "part {part}: vertex {k} has the coordinate `{}`, which is not a number: fix or re-export the file",
                String::from_utf8_lossy(value)
            ))
        })?;
        got |= 1 << axis;
        Ok(())
    })?;
    if got != 0b111 {
        let missing = ["x", "y", "z"]
            .iter()
            .enumerate()
            .find(|(i, _)| got & (1 << i) == 0)
            .map_or("x", |(_, n)| *n);
        return Err(ReadError::new(format!(
            "part {part}: vertex {k} has no {missing} coordinate: the file is damaged - re-export it"
        )));
    }
    Ok(p)
}

fn triangle<R: BufRead>(
    e: &BytesStart,
    xml: &Xml<R>,
    t: usize,
    keep: bool,
) -> Result<([u32; 3], [u32; 4]), ReadError> {
    let part = xml.part.as_str();
    let mut v = [0u32; 3];
    let mut properties = [NONE; 4];
    let mut got = 0u8;
    xml.each_attribute(e, |ns, local, value| {
        let (slot, is_vertex) = match (ns, local) {
            (None, b"v1") => (0, true),
            (None, b"v2") => (1, true),
            (None, b"v3") => (2, true),
            (None, b"pid") => (0, false),
            (None, b"p1") => (1, false),
            (None, b"p2") => (2, false),
            (None, b"p3") => (3, false),
            _ => return Ok(()),
        };
        let n = index(value).ok_or_else(|| {
            ReadError::new(format!(
                "part {part}: triangle {t} has `{}` where a vertex or property index (a whole number) belongs: fix or re-export the file",
                String::from_utf8_lossy(value)
            ))
        })?;
        // Property indices are checked also when not kept: a scan refuses what the repair's
        // reading refuses.
        if is_vertex {
            v[slot] = n;
            got |= 1 << slot;
        } else if keep {
            properties[slot] = n;
        }
        Ok(())
    })?;
    if got != 0b111 {
        return Err(ReadError::new(format!(
            "part {part}: triangle {t} lacks one of v1, v2, v3: the file is damaged - re-export it"
        )));
    }
    Ok((v, properties))
}

/// Words for an element inside `<mesh>` that is not its vertices or triangles.
fn extra_name(ns: Option<&[u8]>, local: &[u8]) -> String {
    let ns = ns.unwrap_or_default();
    let contains = |s: &[u8]| ns.windows(s.len()).any(|w| w == s);
    if contains(b"/beamlattice/") {
        "a beam lattice".into()
    } else if contains(b"/trianglesets/") {
        "triangle sets".into()
    } else {
        format!("<{}>", String::from_utf8_lossy(local))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The settings of the root model part `/3D/3dmodel.model`, properties kept.
    fn root_part(limits: &Limits) -> Settings<'_> {
        Settings {
            key: "3d/3dmodel.model",
            name: "/3D/3dmodel.model",
            root: true,
            keep: true,
            limits,
        }
    }

    fn read(text: &str) -> Result<Model, ReadError> {
        let limits = Limits::default();
        parse(text.as_bytes(), &root_part(&limits), &mut Totals::default())
    }

    const HEAD: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<model unit="inch" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02" xmlns:p="http://schemas.microsoft.com/3dmanufacturing/production/2015/06">"#;

    /// A triangle with properties, a second object of components, an item with a mirroring
    /// transform (det of diag(-1, 1, 1) is -1).
    #[test]
    fn a_model_part_reads_to_objects_and_items() {
        let text = format!(
            r#"{HEAD}<resources>
<object id="1" name="tri" type="support"><mesh><vertices>
<vertex x="0" y="0" z="0"/><vertex x="1" y="0" z="0"></vertex><vertex x="0" y="1.5e0" z="-0"/>
</vertices><triangles><triangle v1="0" v2="1" v3="2" pid="4" p1="1" p2="2" p3="3"/></triangles></mesh></object>
<object id="2"><components><component objectid="1" transform="-1 0 0 0 1 0 0 0 1 5 5 5"/><component objectid="7" p:path="/3D/other.model"/></components></object>
</resources><build><item objectid="2"/><item objectid="1" transform="1 0 0 0 1 0 0 0 0 0 0 0"/></build></model>"#
        );
        let model = read(&text).unwrap();
        assert_eq!(model.unit, Unit::Inch);
        assert_eq!(model.objects.len(), 2);
        let Content::Mesh(m) = &model.objects[0].content else {
            panic!("{:?}", model.objects[0]);
        };
        assert_eq!(m.positions, [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.5, -0.0]]);
        assert_eq!(m.triangles, [[0, 1, 2]]);
        assert_eq!(m.properties, [[4, 1, 2, 3]]);
        assert_eq!(model.objects[0].kind, Kind::Support);
        assert_eq!(model.objects[0].name.as_deref(), Some("tri"));
        let spans = &m.spans;
        assert!(text[spans.mesh.start as usize..spans.mesh.end as usize].starts_with("<mesh>"));
        assert!(text[spans.mesh.start as usize..spans.mesh.end as usize].ends_with("</mesh>"));
        let v = spans.vertices.clone().unwrap();
        assert!(text[v.start as usize..v.end as usize].starts_with("<vertices>"));
        assert!(text[v.start as usize..v.end as usize].ends_with("</vertices>"));
        let t = spans.triangles.clone().unwrap();
        assert!(text[t.start as usize..t.end as usize].ends_with("</triangles>"));
        assert_eq!(
            model.objects[1].content,
            Content::Components(vec![
                Reference {
                    object: 1,
                    path: None,
                    sign: Sign::Negative
                },
                Reference {
                    object: 7,
                    path: Some("3d/other.model".into()),
                    sign: Sign::Positive
                }
            ])
        );
        assert_eq!(model.items[0].sign, Sign::Positive);
        assert_eq!(model.items[1].sign, Sign::Zero);
    }

    /// The run of plain tags read past the XML reader gives what the XML reader gives: the same
    /// mesh written plainly (`x="1"`, taken by the run) and with spaces around `=` (which only the
    /// XML reader takes), over 20,000 vertices, so that tags also straddle the 64 KiB buffer
    /// boundaries of a real read.
    #[test]
    fn plain_runs_read_as_the_xml_reader_reads() {
        let mut plain = String::new();
        let mut spaced = String::new();
        let n = 20_000u32;
        for k in 0..n {
            let (x, y, z) = (
                f64::from(k) * 0.1,
                -f64::from(k) / 3.0,
                1e-3 * f64::from(k % 7),
            );
            plain.push_str(&format!("<vertex x=\"{x}\" y='{y}' z=\"{z}\"/>\n"));
            spaced.push_str(&format!("<vertex x = \"{x}\" y='{y}' z=\"{z}\" />\n"));
        }
        let mut plain_t = String::new();
        let mut spaced_t = String::new();
        for k in 0..n - 2 {
            let (a, b, c) = (k, k + 1, k + 2);
            let mut p = if k % 3 == 0 {
                format!(" pid=\"2\" p1=\"{a}\"")
            } else {
                String::new()
            };
            if k % 5 == 0 {
                p.push_str(&format!(" paint_color='{k}C'"));
            }
            plain_t.push_str(&format!(
                "\t<triangle v1=\"{a}\" v2=\"{b}\" v3=\"{c}\"{p}/>\r\n"
            ));
            spaced_t.push_str(&format!(
                "\t<triangle v1=\"{a}\" v2 =\"{b}\" v3=\"{c}\"{p}/>\r\n"
            ));
        }
        let doc = |v: &str, t: &str| {
            format!("{HEAD}<resources><object id=\"1\"><mesh><vertices>{v}</vertices><triangles>{t}</triangles></mesh></object></resources><build><item objectid=\"1\"/></build></model>")
        };
        let limits = Limits::default();
        let settings = root_part(&limits);
        let parse_buffered = |text: &str| {
            let source = std::io::BufReader::with_capacity(1 << 16, text.as_bytes());
            parse(source, &settings, &mut Totals::default()).unwrap()
        };
        let a = parse_buffered(&doc(&plain, &plain_t));
        let b = parse_buffered(&doc(&spaced, &spaced_t));
        let (Content::Mesh(a), Content::Mesh(b)) = (&a.objects[0].content, &b.objects[0].content)
        else {
            panic!("no meshes");
        };
        assert_eq!(a.positions.len(), n as usize);
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.triangles, b.triangles);
        assert_eq!(a.properties, b.properties);
        assert_eq!(a.properties[3], [2, 3, NONE, NONE]);
        assert_eq!((&a.others, &a.other_text), (&b.others, &b.other_text));
        assert_eq!(a.others.len(), (n as usize - 2).div_ceil(5));
        assert_eq!(a.other_attributes(5), " paint_color=\"5C\"");
        assert_eq!(a.other_attributes(6), "");
        // The spans still point at the elements after a run.
        let text = doc(&plain, &plain_t);
        let t = a.spans.triangles.clone().unwrap();
        assert!(text[t.start as usize..t.end as usize].starts_with("<triangles>"));
        assert!(text[t.start as usize..t.end as usize].ends_with("</triangles>"));
        // Tags a run leaves to the XML reader are still checked by it.
        for (tag, words) in [
            ("<vertex x=\"1\" x=\"2\" y=\"0\" z=\"0\"/>", "twice"),
            ("<vertex x=\"1\" y=\"2\"/>", "no z coordinate"),
            ("<vertex x=\"a\" y=\"2\" z=\"3\"/>", "not a number"),
            ("<vertex x=\"1\"y=\"2\" z=\"3\"/>", "apart"),
            ("<vertex q:x=\"1\" y=\"2\" z=\"3\"/>", "prefix `q:`"),
        ] {
            let e = read(&doc(&format!("{plain}{tag}"), &plain_t)).unwrap_err();
            assert!(e.0.contains(words), "{tag}: {e}");
        }
        let inf = read(&doc(
            &format!("{plain}<vertex x=\"1e999\" y=\"0\" z=\"0\"></vertex>"),
            &plain_t,
        ))
        .unwrap();
        let Content::Mesh(m) = &inf.objects[0].content else {
            panic!()
        };
        assert!(m.positions[n as usize][0].is_infinite());
    }

    #[test]
    fn numbers_read_as_the_standard_parser_reads_them() {
        let texts = [
            "0",
            "-0",
            "+1",
            "1.",
            ".5",
            "1e5",
            "1E-5",
            "-1.25e+3",
            "0.1",
            "3.141592653589793",
            "1e308",
            "1e309",
            "2.2250738585072014e-308",
            "4.9e-324",
            "1e-400",
            "  7 ",
            "123456789012345678901234567890",
            "0.30000000000000004",
            "inf",
            "-INF",
            "NaN",
            "infinity",
        ];
        for text in texts {
            let ours = number(text.as_bytes());
            let std = text.trim().parse::<f64>().ok();
            assert_eq!(ours.map(f64::to_bits), std.map(f64::to_bits), "{text}");
        }
        for bad in ["", "1,5", "1 2", "x", "1e", "--1", "0x10"] {
            assert_eq!(number(bad.as_bytes()), None, "{bad}");
        }
    }

    proptest::proptest! {
        /// Any f64, written by Rust's shortest round-trip formatting or with an exponent, reads
        /// back to the same bits through `number` as through `str::parse`.
        #[test]
        fn any_number_reads_back_like_str_parse(bits in proptest::prelude::any::<u64>()) {
            let x = f64::from_bits(bits);
            for text in [format!("{x}"), format!("{x:e}"), format!("{x:.3}"), format!("{x:.17e}")] {
                let ours = number(text.as_bytes()).map(f64::to_bits);
                let std = text.parse::<f64>().ok().map(f64::to_bits);
                if x.is_nan() {
                    proptest::prop_assert!(ours.is_some_and(|b| f64::from_bits(b).is_nan()));
                } else {
                    proptest::prop_assert_eq!(ours, std, "{}", text);
                }
            }
        }
    }

    #[test]
    fn indices_are_whole_numbers_that_fit() {
        assert_eq!(index(b"0"), Some(0));
        assert_eq!(index(b"+12"), Some(12));
        assert_eq!(index(b"4294967295"), Some(u32::MAX));
        for bad in [&b""[..], b"-1", b"4294967296", b"1.0", b"1e3", b"+"] {
            assert_eq!(index(bad), None, "{:?}", String::from_utf8_lossy(bad));
        }
    }

    /// det of the 3x3 part: identity 1, a mirror in x -1, a flat scale 0.
    #[test]
    fn transform_signs() {
        assert_eq!(
            transform_sign(b"1 0 0 0 1 0 0 0 1 0 0 0"),
            Ok(Sign::Positive)
        );
        assert_eq!(
            transform_sign(b"-1 0 0 0 1 0 0 0 1 0 0 0"),
            Ok(Sign::Negative)
        );
        assert_eq!(
            transform_sign(b"0 1 0 1 0 0 0 0 1 9 9 9"),
            Ok(Sign::Negative)
        );
        assert_eq!(transform_sign(b"1 0 0 0 1 0 0 0 0 0 0 0"), Ok(Sign::Zero));
        assert!(transform_sign(b"1 0 0 0 1 0 0 0 1 0 0").is_err());
        assert!(transform_sign(b"1 0 0 0 1 0 0 0 1 0 0 0 0").is_err());
        assert!(transform_sign(b"1 0 0 0 1 0 0 0 1 NaN 0 0").is_err());
        assert!(transform_sign(b"1 0 0 0 1 0 0 0 1 inf 0 0").is_err());
        assert!(transform_sign(b"1,0 0 0 0 1 0 0 0 1 0 0 0").is_err());
    }
}
