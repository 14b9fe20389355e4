//! 3MF reader (3D Manufacturing Format, core specification 1.x, with the production extension's
//! parts): one [`Mesh`] per mesh object the build uses, directly or through components, in the
//! object's own coordinates.
//!
//! A `.3mf` file is a ZIP package ([`package`]). Its `_rels/.rels` names the root model part;
//! model parts are streamed XML ([`model`], with the rules of [`xml`]); production `p:path`
//! references load further model parts of the same package. The build and the components are
//! walked by [`assembly`], which counts each mesh's placements and how many of them mirror it.
//!
//! A mesh is named by its object's `name`, else `#id` (`/3D/part.model#id` in a part other than the
//! root), with ` (#id)` added when two meshes share a name. Its notes say the model's unit and how
//! many placements use it (`unit millimeter`, `2 placements`), its type when it is not `model`,
//! and what it carries that is not checked (a beam lattice, unknown elements: one note per kind,
//! with its count). Meshes come in document order: the root part's objects first, then the other
//! parts' in the order they were first named. Objects of type `other` are not printable and give
//! no mesh.
//!
//! Refused with a message (besides what the modules above refuse): no or more than one root model
//! relationship, a model part that is missing or encrypted (listed in a secure-content keystore,
//! or a ZIP entry with a password), a build item or component naming an object the part does not
//! define or one of type `other`, an object the build reaches that has neither a mesh nor
//! components. Everything a file declares is held to the limits: inflated bytes to
//! `limits.max_file_bytes`, vertices and triangles of all its parts to `limits.max_triangles`.

pub(crate) mod assembly;
pub(crate) mod model;
pub(crate) mod package;
pub(crate) mod paint;
mod xml;

use std::io::BufReader;
use std::path::Path;

use rustc_hash::FxHashMap;

use super::{ReadContext, ReadError};
use crate::mesh::Mesh;
use model::{Content, Kind, Model, Reference, Sign, Totals};
use package::{Package, MODEL_RELATIONSHIP};

/// The relationship type of a secure-content keystore.
const KEYSTORE: &str = "http://schemas.microsoft.com/3dmanufacturing/2019/04/keystore";

/// Reads the meshes of a `.3mf` file.
pub fn read(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    guard(|| read_package(path, cx, false).map(|p| p.meshes))
}

/// Everything a read found, for the writer of a repaired copy: the meshes, where each came from,
/// and the model parts (with per-triangle properties and the byte spans of each mesh).
pub(crate) struct Read {
    pub meshes: Vec<Mesh>,
    /// Per mesh: index into `parts` and into that part's objects.
    pub sources: Vec<(usize, usize)>,
    /// Every model part read, as (key, model).
    pub parts: Vec<(String, Model)>,
    /// The name of each part as the package spells it (`/3D/3dmodel.model`).
    pub names: Vec<String>,
}

/// [`read`], keeping what the writer needs.
pub(crate) fn read_full(path: &Path, cx: &ReadContext) -> Result<Read, ReadError> {
    guard(|| read_package(path, cx, true))
}

/// Runs `f`, turning a panic (a check this reader lacks) into a read error for this file.
fn guard<T>(f: impl FnOnce() -> Result<T, ReadError>) -> Result<T, ReadError> {
    crate::caught(f).unwrap_or_else(|detail| {
        Err(ReadError::new(format!(
            "the 3MF reader crashed on this file ({detail}): the file is malformed in a way meshvet does not yet describe; please report it"
        )))
    })
}

/// The model parts of a package, loaded as the references need them.
struct Parts<'a> {
    package: Package,
    cx: &'a ReadContext,
    keep: bool,
    parts: Vec<(String, Model)>,
    names: Vec<String>,
    index: FxHashMap<String, usize>,
    encrypted: Vec<String>,
    totals: Totals,
}

impl Parts<'_> {
    /// The index of part `key`, read now if it is new.
    fn load(&mut self, key: &str, root: bool, named_by: &str) -> Result<usize, ReadError> {
        if let Some(&i) = self.index.get(key) {
            return Ok(i);
        }
        if self.encrypted.iter().any(|k| k == key) {
            return Err(package::encrypted(&self.package.name(key)));
        }
        // What the part's own relationships name must lie inside the package too.
        self.package.relationships(&Package::rels_of(key), key)?;
        let name = self.package.name(key);
        let settings = model::Settings {
            key,
            name: &name,
            root,
            keep: self.keep,
            limits: &self.cx.limits,
        };
        let reader = self.package.open_part(key)?.ok_or_else(|| {
            ReadError::new(format!(
                "{named_by} names the model part /{key}, which the package does not have: the file is incomplete - re-export it"
            ))
        })?;
        let model = model::parse(
            BufReader::with_capacity(1 << 16, xml::Utf8::new(reader, &name)),
            &settings,
            &mut self.totals,
        )?;
        self.index.insert(key.to_owned(), self.parts.len());
        self.parts.push((key.to_owned(), model));
        self.names.push(name);
        Ok(self.parts.len() - 1)
    }
}

fn read_package(path: &Path, cx: &ReadContext, keep: bool) -> Result<Read, ReadError> {
    let mut package = Package::open(path, &cx.limits)?;
    if !package.has("_rels/.rels") {
        return Err(ReadError::new(
            "not a 3MF package: the ZIP has no _rels/.rels, so no root model part is named - re-export the file as 3MF",
        ));
    }
    let relationships = package.relationships("_rels/.rels", "")?;
    let roots: Vec<&str> = relationships
        .iter()
        .filter(|r| r.kind == MODEL_RELATIONSHIP)
        .map(|r| r.target.as_str())
        .collect();
    let root = match roots.as_slice() {
        [] => {
            return Err(ReadError::new(
                "not a 3MF package: _rels/.rels names no root model part (no relationship of the 3D model type) - re-export the file as 3MF",
            ))
        }
        [one] => one.to_string(),
        many => {
            return Err(ReadError::new(format!(
                "_rels/.rels names {} root model parts ({}); a 3MF package has exactly one, so which one is printed is unclear - re-export the file",
                many.len(),
                many.iter().map(|k| package.name(k)).collect::<Vec<_>>().join(", ")
            )))
        }
    };
    let mut encrypted = Vec::new();
    for keystore in relationships.iter().filter(|r| r.kind == KEYSTORE) {
        encrypted.extend(package.keystore(&keystore.target)?);
    }
    let mut parts = Parts {
        package,
        cx,
        keep,
        parts: Vec::new(),
        names: Vec::new(),
        index: FxHashMap::default(),
        encrypted,
        totals: Totals::default(),
    };
    parts.load(&root, true, "_rels/.rels")?;
    // Every part a reference names, until none is new.
    let mut next = 0;
    while next < parts.parts.len() {
        let model = &parts.parts[next].1;
        let from = format!("part {}", parts.names[next]);
        // Only the root part's build is printed; the others' items are not followed.
        let items = if next == 0 {
            model.items.as_slice()
        } else {
            &[]
        };
        let named: Vec<String> = items
            .iter()
            .chain(model.objects.iter().flat_map(|o| match &o.content {
                Content::Components(c) => c.as_slice(),
                _ => &[],
            }))
            .filter_map(|r| r.path.clone())
            .collect();
        for key in named {
            parts.load(&key, false, &from)?;
        }
        next += 1;
    }
    let Parts {
        parts: models,
        names,
        index,
        ..
    } = parts;
    assemble(models, names, &index, keep)
}

/// Node numbers: part `p`'s object `o` is `first[p] + o`.
/// The meshes the build reaches, taken out of `models` unless `keep` (then copied, and the models
/// keep them for the writer).
fn assemble(
    mut models: Vec<(String, Model)>,
    names: Vec<String>,
    index: &FxHashMap<String, usize>,
    keep: bool,
) -> Result<Read, ReadError> {
    let mut first = Vec::with_capacity(models.len());
    let mut nodes: Vec<(usize, usize)> = Vec::new();
    for (p, (_, model)) in models.iter().enumerate() {
        first.push(nodes.len());
        nodes.extend((0..model.objects.len()).map(|o| (p, o)));
    }
    let label = |p: usize, o: usize| -> String {
        let object = &models[p].1.objects[o];
        let id = if p == 0 {
            format!("object {}", object.id)
        } else {
            format!("object {} of {}", object.id, names[p])
        };
        match &object.name {
            Some(name) => format!("{id} (\"{name}\")"),
            None => id,
        }
    };
    // A reference from part `p` as a node.
    let resolve = |p: usize,
                   r: &Reference,
                   who: &dyn Fn() -> String|
     -> Result<(usize, Sign), ReadError> {
        let target = match &r.path {
            Some(key) => *index.get(key).ok_or_else(|| {
                ReadError::new(format!(
                    "{} names the part /{key}, which was not read",
                    who()
                ))
            })?,
            None => p,
        };
        let model = &models[target].1;
        let o = *model.ids.get(&r.object).ok_or_else(|| {
            ReadError::new(format!(
                "{} names object {}, which part {} does not define: the file is damaged - re-export it",
                who(),
                r.object,
                names[target]
            ))
        })?;
        if model.objects[o].kind == Kind::Other {
            return Err(ReadError::new(format!(
                "{} names {}, whose type is `other` (not a printable object): fix the file so that only printable objects are placed",
                who(),
                label(target, o)
            )));
        }
        Ok((first[target] + o, r.sign))
    };
    let mut children = vec![Vec::new(); nodes.len()];
    for (n, &(p, o)) in nodes.iter().enumerate() {
        if let Content::Components(list) = &models[p].1.objects[o].content {
            for (c, r) in list.iter().enumerate() {
                let who = || format!("component {c} of {}", label(p, o));
                children[n].push(resolve(p, r, &who)?);
            }
        }
    }
    let items: Vec<(usize, Sign)> = models[0]
        .1
        .items
        .iter()
        .enumerate()
        .map(|(i, r)| resolve(0, r, &|| format!("build item {i}")))
        .collect::<Result<_, _>>()?;
    let name = |n: usize| {
        let (p, o) = nodes[n];
        label(p, o)
    };
    let placements = assembly::place(&children, &items, &name)?;

    let unit = models[0].1.unit;
    let mut meshes = Vec::new();
    let mut sources = Vec::new();
    for (n, &(p, o)) in nodes.iter().enumerate() {
        let placed = placements[n];
        if placed.total() == 0 {
            continue;
        }
        let object = &models[p].1.objects[o];
        let data = match &object.content {
            Content::Mesh(data) => data,
            Content::Components(_) => continue,
            Content::Nothing => {
                return Err(ReadError::new(format!(
                    "the build places {}, which has neither a <mesh> nor <components> (its shape comes from an extension meshvet does not read?): check it with a tool that supports the extension",
                    label(p, o)
                )))
            }
        };
        let mut notes = vec![
            format!("unit {}", unit.name()),
            match placed.total() {
                1 => "1 placement".to_owned(),
                // Counts stop at the largest number they hold (components that fan out on many
                // levels multiply): past it, say so rather than print it as exact.
                u64::MAX => format!("more than {} placements", u64::MAX - 1),
                k => format!("{k} placements"),
            },
        ];
        if placed.negative >= u64::from(u32::MAX) {
            notes.push(format!(
                "more than {} mirrored placements (`mirrored_instances` holds {}, its largest value)",
                u32::MAX - 1,
                u32::MAX
            ));
        }
        if object.kind != Kind::Model {
            notes.push(format!("type {}", object.kind.name()));
        }
        for (extra, count) in &data.extras {
            notes.push(match count {
                1 => format!("{extra} in the mesh is not checked"),
                n => format!("{extra} in the mesh is not checked ({n} elements)"),
            });
        }
        if data.other_extras > 0 {
            notes.push(format!(
                "{} more element(s) of other kinds in the mesh are not checked",
                data.other_extras
            ));
        }
        if data.unknown > 0 {
            notes.push(format!(
                "{} element(s) in <vertices> or <triangles> that 3MF does not define were read past",
                data.unknown
            ));
        }
        meshes.push(Mesh {
            name: Some(match &object.name {
                Some(name) => name.clone(),
                None if p == 0 => format!("#{}", object.id),
                None => format!("{}#{}", names[p], object.id),
            }),
            notes,
            mirrored_instances: u32::try_from(placed.negative).unwrap_or(u32::MAX),
            ..Mesh::default()
        });
        sources.push((p, o));
    }
    for (mesh, &(p, o)) in meshes.iter_mut().zip(&sources) {
        let Content::Mesh(data) = &mut models[p].1.objects[o].content else {
            continue;
        };
        if keep {
            mesh.positions = data.positions.clone();
            mesh.triangles = data.triangles.clone();
        } else {
            mesh.positions = std::mem::take(&mut data.positions);
            mesh.triangles = std::mem::take(&mut data.triangles);
        }
    }
    // Names that two meshes share get their object's id.
    super::distinct_names(&mut meshes, |i| {
        let (p, o) = sources[i];
        let id = models[p].1.objects[o].id;
        if p == 0 {
            format!("#{id}")
        } else {
            format!("{}#{id}", names[p])
        }
    });
    Ok(Read {
        meshes,
        sources,
        parts: models,
        names,
    })
}
