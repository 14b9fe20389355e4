//! Repaired OBJ: every `v` that stays (copies of split vertices appended, dropped ones left out and
//! the rest renumbered), every `vt` and `vn` (plus negated copies of normals that disagree with a
//! flipped face), then the faces in order with `o`/`g`/`s`/`usemtl` re-emitted where they change.
//! A polygon that survives whole is written as the polygon (reversed when flipped); otherwise its
//! surviving triangles are. Hole fills follow the faces of their neighbour's group and material.
//! `mtllib` is kept, and the libraries and the textures they name are copied next to the copy
//! (only files inside the source's folder). Comments, points and lines are not kept.

use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use super::{
    normal_sums, polygon_corner, push_int, push_number, renumber, write_atomic, Item, Job,
    Polygons, WriteError, Written,
};
use crate::formats::obj::{read_full, Detail, State};
use crate::formats::{contain, text, ReadContext};
use crate::mesh::Mesh;
use crate::repair::Plan;

/// Writes the copy and, beside it, its material libraries and textures.
pub fn write(mut job: Job<'_>) -> Result<Written, WriteError> {
    let kept = match job.retained.take() {
        Some((mesh, retained)) => retained.take::<Detail>().map(|detail| (mesh, detail)),
        None => None,
    };
    let side = copy(job.source, job.single()?, job.out, job.cx, kept)?;
    Ok(job.written(side, Vec::new()))
}

/// `kept`: the mesh and detail the scan's read kept of `source`; without them the source is read
/// again.
fn copy(
    source: &Path,
    plan: &Plan,
    out: &Path,
    cx: &ReadContext,
    kept: Option<(&Mesh, Box<Detail>)>,
) -> Result<Vec<PathBuf>, WriteError> {
    let read;
    let (mesh, detail): (&Mesh, &Detail) = match &kept {
        Some((mesh, detail)) => (mesh, detail),
        None => {
            read = read_full(source, cx)?;
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
            (detail.normals.len() + extra_normals.len() - 1) as u32
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
    let mut corner_text = |faces: &mut String, v: u32, vt: Option<u32>, vn: Option<u32>| {
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
                push_int(faces, u64::from(flip_normal(v, n)) + 1);
            }
            (Some(t), Some(n)) => {
                faces.push('/');
                push_int(faces, u64::from(t) + 1);
                faces.push('/');
                push_int(faces, u64::from(flip_normal(v, n)) + 1);
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
                    corner_text(&mut faces, v, vt, vn);
                }
            }
            Item::Triangle(i) => {
                for c in &plan.triangles[i].corners {
                    let (vt, vn) = corner_of(c.from);
                    corner_text(&mut faces, c.vertex, vt, vn);
                }
            }
        }
        faces.push('\n');
    }

    let mut text = String::with_capacity(faces.len() + 40 * plan.used_vertices.len());
    text.push_str("# repaired by meshvet");
    if plan.changes() {
        let _ = write!(text, ": {}", plan.summary());
    }
    text.push('\n');
    for lib in &detail.mtllibs {
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
    for vn in detail.normals.iter().chain(&extra_normals) {
        let _ = writeln!(text, "vn {vn}");
    }
    text.push_str(&faces);
    write_atomic(out, text.as_bytes())?;

    copy_materials(source, out, &detail.mtllibs, &cx.root)
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

/// Copies each material library, and the texture files it names, next to the copy (same relative
/// names), when they are files inside the source's folder, each once however often it is named.
/// What is read follows the readers' containment rule ([`contain`]): a library or texture that is
/// a link to a file outside the scanned tree `root` is not read, so not copied either.
fn copy_materials(
    source: &Path,
    out: &Path,
    mtllibs: &[String],
    root: &Path,
) -> Result<Vec<PathBuf>, WriteError> {
    let to = out.parent().unwrap_or(Path::new(""));
    let Ok(location) = contain::Location::new(source, root) else {
        return Ok(Vec::new()); // the source's read could not resolve it either
    };
    // The real file behind `rel` (inside the source's folder), if it may be read.
    let real = |rel: &Path| {
        let joined = contain::join(&rel.to_string_lossy(), &location).ok()?;
        contain::resolve(&joined, &location).ok()
    };
    let mut done = HashSet::new();
    let mut written = Vec::new();
    for lib in mtllibs {
        let names: Vec<&str> = if inside(lib).and_then(|rel| real(&rel)).is_some() {
            vec![lib.as_str()]
        } else {
            lib.split_ascii_whitespace().collect()
        };
        for name in names {
            let Some(rel) = inside(name) else { continue };
            if !done.insert(rel.clone()) {
                continue;
            }
            // A missing .mtl was a note when scanned; the copy is as good as the source.
            let Some(bytes) = real(&rel).and_then(|path| std::fs::read(path).ok()) else {
                continue;
            };
            write_atomic(&to.join(&rel), &bytes)?;
            written.push(to.join(&rel));
            let mtl_folder = rel.parent().map(Path::to_path_buf).unwrap_or_default();
            for texture in textures(&bytes) {
                let Some(t) = inside(&texture) else { continue };
                let rel = mtl_folder.join(t);
                // Only inside the source's folder, after `..` in the library's own folder.
                let Some(rel) = inside(&rel.to_string_lossy()) else {
                    continue;
                };
                if !done.insert(rel.clone()) {
                    continue;
                }
                if let Some(path) = real(&rel) {
                    super::copy_beside(&path, &to.join(&rel))?;
                    written.push(to.join(&rel));
                }
            }
        }
    }
    Ok(written)
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

/// The texture file names of an MTL (`map_*`, `bump`, `disp`, `decal`, `refl`), option flags
/// skipped: the last word is the file name (names with spaces are rare). Lines end as the OBJ
/// reader ends them (a bare CR too, [`text::lf_line_ends`]).
fn textures(mtl: &[u8]) -> Vec<String> {
    let mtl = text::lf_line_ends(mtl);
    let mtl = String::from_utf8_lossy(&mtl);
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    for line in mtl.lines() {
        let mut words = line.split_ascii_whitespace();
        let Some(key) = words.next() else { continue };
        let key = key.to_ascii_lowercase();
        if key.starts_with("map_")
            || matches!(key.as_str(), "bump" | "disp" | "decal" | "refl" | "norm")
        {
            if let Some(last) = words.last() {
                if seen.insert(last) {
                    out.push(last.to_string());
                }
            }
        }
    }
    out
}
