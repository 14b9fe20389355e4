//! Repaired OBJ: every `v` that stays (copies of split vertices appended, dropped ones left out and
//! the rest renumbered), every `vt` and `vn` (plus the fills' own normals where the ones they
//! take from the border are far from them, and negated copies of normals that disagree with a
//! flipped face), then the faces in order with `o`/`g`/`s`/`usemtl` re-emitted where they change.
//! A polygon that survives whole is written as the polygon (reversed when flipped); otherwise its
//! surviving triangles are. Hole fills follow the faces of their neighbour's group and material.
//! `mtllib` is kept, and the libraries and the textures they name are copied next to the copy: a
//! file inside the source's folder keeps its place; one reached through `../` (a shared
//! `../materials/` or `../textures/` folder of the scanned tree) is copied beside the file that
//! names it, under its file name. Every such name is claimed for the file's bytes in the copy's
//! final folder ([`Claims::side`]): when a different file has it there, or another copy made in
//! the same scan brings a different file under it, the first free numbered name in that folder
//! is taken (`common-1.mtl`), and the name in the copy's `mtllib` or the copied library's
//! `map_*` line is rewritten to it. Nothing outside the scanned tree is read ([`contain`]); what
//! cannot be copied (outside the tree, missing, not a file) keeps its name, and a note says so.
//! Comments, points and lines are not kept.

use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use rustc_hash::FxHashMap;

use super::names::Claims;
use super::{
    borrowed_normal_fits, normal_sums, polygon_corner, push_int, push_number, renumber,
    write_atomic, Item, Job, Polygons, WriteError, Written,
};
use crate::formats::contain::{self, Location, Unresolved};
use crate::formats::obj::{library, library_names, read_full, Detail, NotRead, State};
use crate::formats::text;
use crate::formats::{Kept, Retained};
use crate::mesh::Mesh;

/// Writes the copy and, beside it, its material libraries and textures.
pub fn write(mut job: Job<'_>) -> Result<Written, WriteError> {
    let kept = match job.read.as_mut() {
        Some(read) => match (read.meshes, read.retained.take()) {
            ([mesh], Some(Retained(Kept::Obj(detail)))) => Some((mesh, detail)),
            _ => None,
        },
        None => None,
    };
    let (side, notes) = copy(&job, kept)?;
    Ok(job.written(side, notes))
}

/// `kept`: the mesh and detail the scan's read kept of `source`; without them the source is read
/// again. Returns the side files written and the notes on what could not be copied.
fn copy(
    job: &Job<'_>,
    kept: Option<(&Mesh, Box<Detail>)>,
) -> Result<(Vec<PathBuf>, Vec<String>), WriteError> {
    let (source, plan, out, cx) = (job.source, job.single()?, job.out, job.cx);
    let read;
    let (mesh, detail): (&Mesh, &Detail) = match &kept {
        Some((mesh, detail)) => (mesh, detail),
        None => {
            read = read_full(source, cx)?;
            job.unchanged(std::slice::from_ref(&read.0))?;
            (&read.0, &read.1)
        }
    };
    let polygons = Polygons::new(
        detail.faces.len(),
        |f, out| out.extend(detail.corners(f).iter().map(|c| c.v)),
        mesh,
    )?;
    let items = polygons.items(plan, mesh);
    let (index, _) = renumber(plan);

    // The (v, vt, vn) of input corner `c`.
    let corner_of = |c: u32| -> (Option<u32>, Option<u32>) {
        let (f, k) = polygons.corner(c);
        let (_, vt, vn) = detail.corners(f)[k].parts();
        (vt, vn)
    };

    // Normals a flipped face's corners disagree with get a negated copy.
    let sums = normal_sums(plan, mesh, |c| corner_of(c.from).1.map(|vn| (c.vertex, vn)));
    // The normal a corner's `vn` is written as: negated where it disagrees with a flipped face.
    let written = |vertex: u32, vn: u32| -> Option<[f64; 3]> {
        let n = parse3(&detail.normals[vn as usize])?;
        let negated = sums
            .get(&(vertex, vn))
            .is_some_and(|sum| crate::geometry::dot(n, *sum) < 0.0);
        Some(if negated { n.map(|x| -x) } else { n })
    };
    // A fill's corner whose borrowed normal is far from the fill's own normal gets the fill's:
    // the file's own `vn` of exactly that value, else one new `vn` per direction after the file's
    // own (plan triangle and corner -> `vn`).
    let mut fill_normals: Vec<[f64; 3]> = Vec::new();
    let mut fill_vn: FxHashMap<(usize, usize), u32> = FxHashMap::default();
    let mut by_direction: FxHashMap<[u64; 3], u32> = FxHashMap::default();
    if plan.triangles.iter().any(|t| t.source.is_none()) {
        for (i, text) in detail.normals.iter().enumerate().rev() {
            if let Some(n) = parse3(text) {
                by_direction.insert(n.map(|x| (x + 0.0).to_bits()), i as u32);
            }
        }
    }
    let holes = super::fill_normals(plan, mesh);
    for (i, t) in plan.triangles.iter().enumerate() {
        let Some(own) = holes[i] else {
            continue;
        };
        for (k, c) in t.corners.iter().enumerate() {
            let Some(vn) = corner_of(c.from).1 else {
                continue;
            };
            if written(c.vertex, vn).is_some_and(|b| borrowed_normal_fits(b, own)) {
                continue;
            }
            let index = *by_direction
                .entry(own.map(f64::to_bits))
                .or_insert_with(|| {
                    fill_normals.push(own);
                    (detail.normals.len() + fill_normals.len() - 1) as u32
                });
            fill_vn.insert((i, k), index);
        }
    }
    let first_extra = detail.normals.len() + fill_normals.len();

    let mut extra_normals: Vec<String> = Vec::new();
    let mut negated: rustc_hash::FxHashMap<u32, u32> = Default::default();
    let mut flip_normal = |vertex: u32, vn: u32| -> u32 {
        let Some(sum) = sums.get(&(vertex, vn)) else {
            return vn;
        };
        let Some(n) = parse3(&detail.normals[vn as usize]) else {
            return vn;
        };
        if crate::geometry::dot(n, *sum) >= 0.0 {
            return vn;
        }
        *negated.entry(vn).or_insert_with(|| {
            extra_normals.push(format!(
                "{} {} {}",
                super::number(-n[0]),
                super::number(-n[1]),
                super::number(-n[2])
            ));
            (first_extra + extra_normals.len() - 1) as u32
        })
    };

    // Faces first (they decide the extra normals), in groups: fills after their neighbour's block.
    let block_of_face: Vec<u32> = detail.faces.iter().map(|f| f.state).collect();
    let mut ordered: Vec<(u32, usize, Item)> = items
        .iter()
        .enumerate()
        .map(|(k, &item)| {
            let block = match item {
                Item::Polygon { face, .. } => block_of_face[face],
                Item::Triangle(i) => block_of_face[polygons.of(&plan.triangles[i])],
            };
            let fill = matches!(item, Item::Triangle(i) if plan.triangles[i].source.is_none());
            // Blocks are runs in file order: kept faces stay in order, fills go to the end of
            // their neighbour's run.
            (block, if fill { usize::MAX } else { k }, item)
        })
        .collect();
    // Usually in order already (one block, fills last): checking is cheaper than sorting.
    if !ordered.is_sorted_by_key(|&(block, k, _)| (block, k)) {
        ordered.sort_by_key(|&(block, k, _)| (block, k));
    }

    let mut faces = String::with_capacity(16 * ordered.len());
    let mut state = State::default();
    // Indices as 1-based text (itoa: `write!` costs several times more over a million faces).
    // `vn` is the source's normal (negated here where it disagrees with a flipped face) or, with
    // `fill`, the index of a fill's own normal.
    let mut corner_text = |faces: &mut String, v: u32, vt: Option<u32>, vn: Option<u32>, fill| {
        let mut normal = |n: u32| if fill { n } else { flip_normal(v, n) };
        faces.push(' ');
        push_int(faces, u64::from(index[v as usize]) + 1);
        match (vt, vn) {
            (None, None) => {}
            (Some(t), None) => {
                faces.push('/');
                push_int(faces, u64::from(t) + 1);
            }
            (None, Some(n)) => {
                faces.push_str("//");
                push_int(faces, u64::from(normal(n)) + 1);
            }
            (Some(t), Some(n)) => {
                faces.push('/');
                push_int(faces, u64::from(t) + 1);
                faces.push('/');
                push_int(faces, u64::from(normal(n)) + 1);
            }
        }
    };
    let mut current_block = None;
    for &(block, _, item) in &ordered {
        if current_block != Some(block) {
            switch_state(&mut faces, &mut state, &detail.states[block as usize]);
            current_block = Some(block);
        }
        faces.push('f');
        match item {
            Item::Polygon { face, reversed } => {
                let corners = detail.corners(face);
                let n = corners.len();
                for k in 0..n {
                    let (v, vt, vn) = corners[polygon_corner(n, k, reversed)].parts();
                    corner_text(&mut faces, v, vt, vn, false);
                }
            }
            Item::Triangle(i) => {
                for (k, c) in plan.triangles[i].corners.iter().enumerate() {
                    let (vt, vn) = corner_of(c.from);
                    match fill_vn.get(&(i, k)) {
                        Some(&own) => corner_text(&mut faces, c.vertex, vt, Some(own), true),
                        None => corner_text(&mut faces, c.vertex, vt, vn, false),
                    }
                }
            }
        }
        faces.push('\n');
    }

    // The libraries and textures first: a library copied under a new name is named so.
    let sides = copy_materials(source, out, &detail.mtllibs, &cx.root, job.claims)?;
    let mut text = String::with_capacity(faces.len() + 40 * plan.used_vertices.len());
    text.push_str("# repaired by meshvet");
    if plan.changes() {
        let _ = write!(text, ": {}", plan.summary());
    }
    text.push('\n');
    for lib in &sides.mtllibs {
        let _ = writeln!(text, "mtllib {lib}");
    }
    for (v, &used) in plan.used_vertices.iter().enumerate() {
        if !used {
            continue;
        }
        let p = plan.position(mesh, v as u32);
        let from = super::original(plan, mesh, v as u32) as usize;
        text.push('v');
        for x in p {
            text.push(' ');
            push_number(&mut text, x);
        }
        match detail.vertex_extra.get(from) {
            Some(extra) if !extra.is_empty() => {
                let _ = writeln!(text, " {extra}");
            }
            _ => text.push('\n'),
        }
    }
    for vt in &detail.texcoords {
        let _ = writeln!(text, "vt {vt}");
    }
    for vn in &detail.normals {
        let _ = writeln!(text, "vn {vn}");
    }
    for n in &fill_normals {
        text.push_str("vn");
        for x in n {
            text.push(' ');
            push_number(&mut text, *x);
        }
        text.push('\n');
    }
    for vn in &extra_normals {
        let _ = writeln!(text, "vn {vn}");
    }
    text.push_str(&faces);
    write_atomic(out, text.as_bytes())?;
    let mut notes = sides.notes;
    if sides.more_notes > 0 {
        notes.push(format!(
            "{} more material libraries or textures were not copied",
            sides.more_notes
        ));
    }
    Ok((sides.written, notes))
}

fn parse3(text: &str) -> Option<[f64; 3]> {
    let mut w = text.split_ascii_whitespace().map(|w| w.parse::<f64>().ok());
    Some([w.next()??, w.next()??, w.next()??])
}

/// Emits the statements that change `state` into `wanted`.
fn switch_state(out: &mut String, state: &mut State, wanted: &State) {
    let mut emit =
        |keyword: &str, have: &mut Option<String>, want: &Option<String>, reset: &str| {
            if have != want {
                match want {
                    Some(v) => {
                        let _ = writeln!(out, "{keyword} {v}");
                    }
                    None if !reset.is_empty() => {
                        let _ = writeln!(out, "{keyword} {reset}");
                    }
                    None => {
                        let _ = writeln!(out, "{keyword}");
                    }
                }
                *have = want.clone();
            }
        };
    emit("o", &mut state.object, &wanted.object, "");
    emit("g", &mut state.group, &wanted.group, "");
    emit("usemtl", &mut state.material, &wanted.material, "");
    emit("s", &mut state.smoothing, &wanted.smoothing, "off");
}

/// At most this many notes on files not copied; the rest are counted in one.
const SIDE_NOTES: usize = 20;

/// The material libraries and textures of one copy, as they are copied.
struct Sides {
    /// The copy's `mtllib` arguments, in the source's order (names rewritten where needed).
    mtllibs: Vec<String>,
    /// The files written beside the copy.
    written: Vec<PathBuf>,
    notes: Vec<String>,
    more_notes: usize,
}

/// What copying the side files of one copy needs as it goes.
struct Copier<'a> {
    /// The copy's folder (its staging folder).
    to: &'a Path,
    location: &'a Location,
    /// The names claimed in the copy's final folder, which every place is relative to.
    claims: &'a Claims,
    /// Places written already (two files of the same bytes share a place).
    placed: HashSet<PathBuf>,
    /// Names looked up already, per folder they are named from in the source and the folder of
    /// the library naming them in the copy (a texture two libraries name from one source folder
    /// needs a place relative to each): their new names (`None`: not copied, the name stays).
    named: FxHashMap<(PathBuf, PathBuf, String), Option<String>>,
    sides: Sides,
}

impl Copier<'_> {
    fn note(&mut self, note: String) {
        if self.sides.notes.len() < SIDE_NOTES {
            self.sides.notes.push(note);
        } else {
            self.sides.more_notes += 1;
        }
    }

    /// Claims a place for `bytes` at `wanted` (relative to the copy's folder), or the first free
    /// numbered name in the same folder (`wood-1.png`) when another file has it: in the final
    /// folder, or claimed by any copy being made, this one included ([`Claims::side`]).
    fn claim(&self, wanted: &Path, bytes: &[u8]) -> Result<PathBuf, WriteError> {
        self.claims.side(wanted, bytes, true).map_err(|_| {
            let file = wanted.file_name().unwrap_or_default().to_string_lossy();
            self.claims.no_free_name(&file)
        })
    }

    /// Writes `bytes`, read from `real`, at `place` (relative to the copy's folder) once, and
    /// lists it at `slot` of the files written (a library before the textures it names).
    fn write(
        &mut self,
        slot: usize,
        place: &Path,
        real: &Path,
        bytes: &[u8],
    ) -> Result<(), WriteError> {
        if !self.placed.insert(place.to_path_buf()) {
            return Ok(());
        }
        let to = self.to.join(place);
        super::put_beside(real, bytes, &to)?;
        let slot = slot.min(self.sides.written.len());
        self.sides.written.insert(slot, to);
        Ok(())
    }
}

/// The file name of `real` as a name beside the copy: whitespace, `:` and `\` made `_`, so that
/// `mtllib` and `map_*` read it back as one relative name.
fn plain_name(real: &Path) -> PathBuf {
    let file: String = real
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
        .chars()
        .map(|c| {
            if c.is_whitespace() || c == ':' || c == '\\' {
                '_'
            } else {
                c
            }
        })
        .collect();
    PathBuf::from(file)
}

/// `name` as written (`\` read as `/`) with its last part made the file name of `place`: the
/// name of a file numbered in its own folder.
fn renamed_file(name: &str, place: &Path) -> String {
    let file = place.file_name().unwrap_or_default();
    Path::new(&name.replace('\\', "/"))
        .with_file_name(file)
        .to_string_lossy()
        .into_owned()
}

/// Why a file the copy names is not copied, in words.
fn why_not(not: &NotRead) -> String {
    match not {
        NotRead::Refused => "its path is absolute or leaves the scanned tree".into(),
        NotRead::Unresolved(Unresolved::Missing) => "there is no such file".into(),
        NotRead::Unresolved(Unresolved::Outside) => {
            "it resolves, through a symbolic link, outside the scanned tree".into()
        }
        NotRead::Unresolved(Unresolved::NotAFile(_)) => "it is not a regular file".into(),
        NotRead::Unresolved(Unresolved::Io(e)) => format!("it cannot be looked at ({e})"),
    }
}

/// Copies each material library, and the texture files it names, beside the copy (see the module
/// documentation), each once however often it is named. What is read follows the readers'
/// containment rule ([`contain`]): a library or texture outside the scanned tree `root`, also
/// through a link, is not read, so not copied either.
fn copy_materials(
    source: &Path,
    out: &Path,
    mtllibs: &[String],
    root: &Path,
    claims: &Claims,
) -> Result<Sides, WriteError> {
    let to = out.parent().unwrap_or(Path::new(""));
    let mut sides = Sides {
        mtllibs: mtllibs.to_vec(),
        written: Vec::new(),
        notes: Vec::new(),
        more_notes: 0,
    };
    if mtllibs.is_empty() {
        return Ok(sides);
    }
    let location = match contain::Location::new(source, root) {
        Ok(location) => location,
        Err(e) => {
            sides.notes.push(format!(
                "the material libraries are not copied: {e}; the copy names them as the source does"
            ));
            return Ok(sides);
        }
    };
    let mut copier = Copier {
        to,
        location: &location,
        claims,
        placed: HashSet::new(),
        named: FxHashMap::default(),
        sides,
    };
    let mut lines = Vec::with_capacity(mtllibs.len());
    for lib in mtllibs {
        let names = library_names(lib, &location);
        let mut line = Vec::with_capacity(names.len());
        for name in &names {
            let new = library_copy(&mut copier, name)?;
            line.push(new.unwrap_or_else(|| (*name).to_owned()));
        }
        lines.push(if names.len() == 1 && line[0] == names[0] {
            lib.clone()
        } else {
            line.join(" ")
        });
    }
    copier.sides.mtllibs = lines;
    Ok(copier.sides)
}

/// Copies the library the copy's `mtllib` names `name` (and its textures); its name in the copy,
/// `None` when not copied.
fn library_copy(copier: &mut Copier<'_>, name: &str) -> Result<Option<String>, WriteError> {
    let key = (PathBuf::new(), PathBuf::new(), name.to_owned());
    if let Some(done) = copier.named.get(&key) {
        return Ok(done.clone());
    }
    let location = copier.location;
    let not_copied = |copier: &mut Copier<'_>, why: String| {
        copier.note(format!(
            "material library `{name}` is not copied: {why}; the copy names it as the source does"
        ));
        copier.named.insert(key.clone(), None);
        Ok(None)
    };
    // `\\` separates folders in names written on Windows.
    let real = match library(&name.replace('\\', "/"), location) {
        Ok(real) => real,
        Err(not) => return not_copied(copier, why_not(&not)),
    };
    let bytes = match crate::formats::read_regular(&real) {
        Ok(bytes) => bytes,
        Err(e) => return not_copied(copier, format!("it cannot be read ({e})")),
    };
    // Below the source's folder: the same place. Through `../`: beside the copy. Either way the
    // folder is decided here (only the file name may be numbered), so the textures, named from
    // the library's folder, are placed first: a renamed texture changes the library's bytes,
    // which are claimed once final.
    let kept = inside(name);
    let wanted = kept.clone().unwrap_or_else(|| plain_name(&real));
    let base = wanted.parent().map(Path::to_path_buf).unwrap_or_default();
    // Textures are named from the library's folder: in the source, the folder of the name as
    // written (before links); in the copy, the folder of its place.
    let joined = contain::join(&name.replace('\\', "/"), location).unwrap_or_else(|_| real.clone());
    let from = joined.parent().map(Path::to_path_buf).unwrap_or_default();
    let slot = copier.sides.written.len();
    let mut renamed: FxHashMap<String, String> = FxHashMap::default();
    for texture in textures(&bytes) {
        let moved = kept.is_none();
        if let Some(new) = texture_copy(copier, name, &texture, &from, &base, moved)? {
            if new != texture {
                renamed.insert(texture, new);
            }
        }
    }
    let bytes = if renamed.is_empty() {
        bytes
    } else {
        rename_textures(&bytes, &renamed)
    };
    let place = copier.claim(&wanted, &bytes)?;
    let new = match kept {
        Some(_) if place == wanted => name.to_owned(),
        Some(_) => renamed_file(name, &place),
        None => place.to_string_lossy().into_owned(),
    };
    copier.named.insert(key, Some(new.clone()));
    copier.write(slot, &place, &real, &bytes)?;
    Ok(Some(new))
}

/// Copies the texture a library (named `library` in the OBJ) names `name`, looked up from `from`
/// (the library's folder in the source tree) and copied relative to `base` (the library's folder
/// in the copy, relative to the copy's folder). `moved`: the library is not at its source place
/// relative to the copy. Returns the texture's name in the copied library, `None` when not copied.
fn texture_copy(
    copier: &mut Copier<'_>,
    library: &str,
    name: &str,
    from: &Path,
    base: &Path,
    moved: bool,
) -> Result<Option<String>, WriteError> {
    let key = (from.to_path_buf(), base.to_path_buf(), name.to_owned());
    if let Some(done) = copier.named.get(&key) {
        return Ok(done.clone());
    }
    let not_copied = |copier: &mut Copier<'_>, why: String| {
        copier.note(format!(
            "texture `{name}` (named in `{library}`) is not copied: {why}; the copied library names it as the source does"
        ));
        copier.named.insert(key.clone(), None);
        Ok(None)
    };
    let location = Location {
        folder: from.to_path_buf(),
        ..copier.location.clone()
    };
    let found = if name.contains(':') {
        Err(NotRead::Refused)
    } else {
        contain::join(&name.replace('\\', "/"), &location)
            .map_err(|_| NotRead::Refused)
            .and_then(|joined| contain::resolve(&joined, &location).map_err(NotRead::Unresolved))
    };
    let real = match found {
        Ok(real) => real,
        Err(not) => return not_copied(copier, why_not(&not)),
    };
    let bytes = match crate::formats::read_regular(&real) {
        Ok(bytes) => bytes,
        Err(e) => return not_copied(copier, format!("it cannot be read ({e})")),
    };
    // The same relative name works when the texture keeps its place relative to the library: it
    // lies below the library's folder, or the library kept its place and the texture is inside
    // the source's folder. Otherwise it goes beside the library under its file name.
    let keep = if moved {
        inside(name).map(|rel| base.join(rel))
    } else {
        inside(&base.join(name).to_string_lossy())
    };
    let wanted = keep.clone().unwrap_or_else(|| base.join(plain_name(&real)));
    let place = copier.claim(&wanted, &bytes)?;
    let new = match keep {
        Some(_) if place == wanted => name.to_owned(),
        Some(_) => renamed_file(name, &place),
        None => place
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned(),
    };
    copier.named.insert(key, Some(new.clone()));
    let slot = copier.sides.written.len();
    copier.write(slot, &place, &real, &bytes)?;
    Ok(Some(new))
}

/// A relative path that stays inside its folder, normalised; `None` otherwise.
fn inside(name: &str) -> Option<PathBuf> {
    let name = name.replace('\\', "/");
    let mut out = PathBuf::new();
    for c in Path::new(&name).components() {
        match c {
            Component::Normal(part) => out.push(part),
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    return None;
                }
            }
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    (!out.as_os_str().is_empty() && !name.contains(':')).then_some(out)
}

/// An MTL with the texture names of its `map_*` (and `bump`, ...) lines replaced as `renamed`
/// says (the line's last word, as [`textures`] reads it); every other byte kept, line ends too.
fn rename_textures(mtl: &[u8], renamed: &FxHashMap<String, String>) -> Vec<u8> {
    let mut out = Vec::with_capacity(mtl.len() + 64);
    let mut rest = mtl;
    while !rest.is_empty() {
        let end = rest
            .iter()
            .position(|&b| b == b'\n' || b == b'\r')
            .unwrap_or(rest.len());
        let line = &rest[..end];
        match std::str::from_utf8(line)
            .ok()
            .and_then(|l| texture_of(l).map(|t| (l, t)))
        {
            Some((l, (at, t))) if renamed.contains_key(t) => {
                out.extend_from_slice(&l.as_bytes()[..at]);
                out.extend_from_slice(renamed[t].as_bytes());
                out.extend_from_slice(&l.as_bytes()[at + t.len()..]);
            }
            _ => out.extend_from_slice(line),
        }
        let ends = match rest.get(end..end + 2) {
            Some(b"\r\n") => 2,
            _ => usize::from(end < rest.len()),
        };
        out.extend_from_slice(&rest[end..end + ends]);
        rest = &rest[end + ends..];
    }
    out
}

/// The texture file name of an MTL line (`map_*`, `bump`, `disp`, `decal`, `refl`, `norm`: its
/// last word, option flags before it) and where it starts in the line.
fn texture_of(line: &str) -> Option<(usize, &str)> {
    let mut words = line.split_ascii_whitespace();
    let key = words.next()?.to_ascii_lowercase();
    if !(key.starts_with("map_")
        || matches!(key.as_str(), "bump" | "disp" | "decal" | "refl" | "norm"))
    {
        return None;
    }
    let last = words.last()?;
    let at = line.rfind(last)?;
    Some((at, last))
}

/// The texture file names of an MTL (`map_*`, `bump`, `disp`, `decal`, `refl`), option flags
/// skipped: the last word is the file name (names with spaces are rare). Lines end as the OBJ
/// reader ends them (a bare CR too, [`text::lf_line_ends`]).
fn textures(mtl: &[u8]) -> Vec<String> {
    let mtl = text::lf_line_ends(mtl);
    let mtl = String::from_utf8_lossy(&mtl);
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    for line in mtl.lines() {
        if let Some((_, last)) = texture_of(line) {
            if seen.insert(last) {
                out.push(last.to_string());
            }
        }
    }
    out
}
