//! Repaired 3MF. The copy is the source package with only the `<vertices>` and `<triangles>` of the
//! repaired objects rewritten: every other entry of the ZIP (thumbnails, `Metadata/`, slicer
//! configurations, textures, other model parts) is copied as its stored bytes, in the same order and
//! with the same names, and inside a rewritten model part every byte outside those two elements
//! (the XML declaration, materials, other objects, the build, the `<mesh>` tag itself) is kept.
//!
//! A triangle keeps its properties: its `pid`, and the `p1`..`p3` of its corners follow the corners,
//! so a flipped triangle swaps `p2` and `p3` along with `v2` and `v3` (a triangle with `p1` alone
//! keeps `p1` alone). Its other attributes (a slicer's paint such as `slic3rpe:mmu_segmentation`
//! or `paint_color`, anything else) are written back as the source writes them, prefixes and all;
//! the start tags of `<vertices>` and `<triangles>` keep their attributes too, so every prefix
//! stays declared. Slicer paint is relative to the corner order: on a flipped triangle it is
//! re-encoded for the new order ([`crate::formats::threemf::paint`]), and a paint string that is
//! not of that encoding is left out, with a note that says how many triangles lost paint. A
//! triangle that fills a hole takes the `pid` and `p1` of the triangle beside it (its `near`
//! triangle), or none, and no other attribute. A vertex the repair adds (one copy per extra fan
//! of a split vertex) is written like the others: 3MF vertices carry nothing but their position.
//!
//! PrusaSlicer's `Metadata/Slic3r_PE_model.config` gives each volume of an object a range of its
//! triangles (`firstid`..`lastid`); it is kept as it is, so when a repair drops or adds triangles
//! of an object the ranges no longer fit it, and a note says so.
//!
//! A mesh whose other children number its vertices or triangles (a beam lattice, triangle sets) is
//! not rewritten: the repair renumbers both, and those references would point elsewhere.

use std::io::{Cursor, Write as _};
use std::path::Path;

use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipWriter};

use super::{push_int, push_number, renumber, write_atomic, Job, WriteError, Written};
use crate::formats::threemf::model::{Content, MeshData, NONE};
use crate::formats::threemf::package::{self, Package};
use crate::formats::threemf::paint;
use crate::formats::threemf::read_full;
use crate::formats::ReadContext;
use crate::mesh::Mesh;
use crate::repair::Plan;

/// Writes the copy: the package with the repaired meshes' `<mesh>` text replaced, every other
/// byte of every part kept.
pub fn write(job: Job<'_>) -> Result<Written, WriteError> {
    let (source, plans, out, cx) = (job.source, job.plans, job.out, job.cx);
    let scanned = job.read.as_ref().map(|r| r.meshes);
    let notes = crate::caught(|| write_unguarded(source, plans, out, cx, scanned)).unwrap_or_else(
        |panic| {
            Err(WriteError::new(format!(
                "the 3MF writer crashed on this file ({panic}): please report it"
            )))
        },
    )?;
    Ok(job.written(Vec::new(), notes))
}

/// PrusaSlicer's per-object configuration, with each volume's range of triangles.
const SLIC3R_MODEL_CONFIG: &str = "Metadata/Slic3r_PE_model.config";

/// One mesh to rewrite: its two byte ranges in its part and their new text.
struct Splice {
    at: std::ops::Range<u64>,
    text: String,
}

/// Writes the copy; returns the notes on what it could not keep.
fn write_unguarded(
    source: &Path,
    plans: &[Option<Plan>],
    out: &Path,
    cx: &ReadContext,
    scanned: Option<&[Mesh]>,
) -> Result<Vec<String>, WriteError> {
    let read = read_full(source, cx)?;
    super::unchanged(scanned, &read.meshes)?;
    if plans.len() != read.meshes.len() {
        return Err(WriteError::new(format!(
            "the file has {} meshes but {} plans were given",
            read.meshes.len(),
            plans.len()
        )));
    }
    let mut package = Package::open(source, &cx.limits)?;
    let ranges = package.has(&package::key(SLIC3R_MODEL_CONFIG));
    let mut notes = Vec::new();
    // Per part: its new bytes.
    let mut rewritten: Vec<(String, Vec<u8>)> = Vec::new();
    for (p, (key, model)) in read.parts.iter().enumerate() {
        let mut splices: Vec<Splice> = Vec::new();
        for (m, plan) in plans.iter().enumerate() {
            let Some(plan) = plan else { continue };
            let (part, o) = read.sources[m];
            if part != p {
                continue;
            }
            let object = &model.objects[o];
            let Content::Mesh(data) = &object.content else {
                continue;
            };
            let what = || format!("object {} of {}", object.id, read.names[p]);
            if let Some((extra, _)) = data.extras.first() {
                return Err(WriteError::new(format!(
                    "{} also holds {extra}, which numbers the mesh's vertices or triangles; a repair renumbers them, so a mesh with one cannot be written yet",
                    what()
                )));
            }
            let (Some(vertices), Some(triangles)) =
                (data.spans.vertices.clone(), data.spans.triangles.clone())
            else {
                return Err(WriteError::new(format!(
                    "{} has no <vertices> or no <triangles> element to rewrite",
                    what()
                )));
            };
            let (vertex_text, triangle_text, lost) = mesh_text(plan, &read.meshes[m], data);
            if lost.triangles > 0 {
                notes.push(format!(
                    "{}: {} flipped triangle(s) lost their slicer paint ({}): a repair that flips a triangle reorders its corners, and this paint could not be re-encoded for the new order (it is not the encoding PrusaSlicer writes, or past meshvet's limits of 64 levels and 262,144 codes) - repaint them in the slicer",
                    what(),
                    lost.triangles,
                    lost.names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
                ));
            }
            if lost.nul > 0 {
                notes.push(format!(
                    "{}: {} attribute(s) of its triangles hold a NUL character, which XML does not allow: they were left out",
                    what(),
                    lost.nul
                ));
            }
            // The ranges count the source's triangles in order: they fit only while every
            // triangle is kept in its place and none is added.
            let in_place = plan.triangles.len() == data.triangles.len()
                && plan
                    .triangles
                    .iter()
                    .enumerate()
                    .all(|(i, t)| t.source == Some(i as u32));
            if ranges && !in_place {
                let kept = plan.triangles.iter().filter(|t| t.source.is_some()).count();
                notes.push(format!(
                    "{}: {SLIC3R_MODEL_CONFIG} is kept as it was, but its volumes' triangle ranges (firstid/lastid) number the source's {} triangles, and the repair dropped {} and added {}: PrusaSlicer may refuse the copy (\"Found invalid triangle id\") or give the object's parts the wrong triangles - check its parts when opening the copy in PrusaSlicer",
                    what(),
                    data.triangles.len(),
                    data.triangles.len().saturating_sub(kept),
                    plan.triangles.len() - kept
                ));
            }
            splices.push(Splice {
                at: vertices,
                text: vertex_text,
            });
            splices.push(Splice {
                at: triangles,
                text: triangle_text,
            });
        }
        if splices.is_empty() {
            continue;
        }
        let bytes = package
            .read(key)?
            .ok_or_else(|| WriteError::new(format!("part {} is gone", read.names[p])))?;
        rewritten.push((key.clone(), splice(&bytes, splices, &read.names[p])?));
    }

    let keys: Vec<(usize, Vec<u8>)> = rewritten
        .into_iter()
        .map(|(key, bytes)| {
            package
                .index(&key)
                .map(|i| (i, bytes))
                .ok_or_else(|| WriteError::new(format!("part /{key} has no ZIP entry")))
        })
        .collect::<Result<_, _>>()?;
    let mut archive = package.into_archive();
    let mut zip = ZipWriter::new(Cursor::new(Vec::new()));
    let bad = |e: zip::result::ZipError| {
        WriteError::new(format!("cannot write the repaired package: {e}"))
    };
    for i in 0..archive.len() {
        if let Some((_, bytes)) = keys.iter().find(|(k, _)| *k == i) {
            let entry = archive.by_index_raw(i).map_err(bad)?;
            let name = String::from_utf8_lossy(entry.name_raw()).into_owned();
            let method = match entry.compression() {
                CompressionMethod::Stored => CompressionMethod::Stored,
                _ => CompressionMethod::Deflated,
            };
            let mut options = SimpleFileOptions::default()
                .compression_method(method)
                .large_file(bytes.len() as u64 >= u32::MAX as u64);
            if let Some(time) = entry.last_modified() {
                options = options.last_modified_time(time);
            }
            drop(entry);
            zip.start_file(name, options).map_err(bad)?;
            zip.write_all(bytes)?;
        } else {
            let entry = archive.by_index_raw(i).map_err(bad)?;
            zip.raw_copy_file(entry).map_err(bad)?;
        }
    }
    let comment = archive.comment().to_vec();
    if !comment.is_empty() {
        zip.set_raw_comment(comment.into_boxed_slice())
            .map_err(bad)?;
    }
    let bytes = zip.finish().map_err(bad)?.into_inner();
    write_atomic(out, &bytes)?;
    Ok(notes)
}

/// The part `bytes` with every splice's range replaced by its text (ranges sorted, checked to be
/// elements of the part and not to overlap).
fn splice(bytes: &[u8], mut splices: Vec<Splice>, part: &str) -> Result<Vec<u8>, WriteError> {
    splices.sort_by_key(|s| s.at.start);
    let mut out =
        Vec::with_capacity(bytes.len() + splices.iter().map(|s| s.text.len()).sum::<usize>());
    let mut done = 0usize;
    for s in &splices {
        let (start, end) = (s.at.start as usize, s.at.end as usize);
        let fits = start >= done
            && start < end
            && end <= bytes.len()
            && bytes[start] == b'<'
            && bytes[end - 1] == b'>';
        if !fits {
            return Err(WriteError::new(format!(
                "the mesh elements of {part} are not where they were read (internal error: please report this file)"
            )));
        }
        out.extend_from_slice(&bytes[done..start]);
        // The element's own qualified name, attributes and indentation are kept for what
        // replaces it.
        out.extend_from_slice(&restyle(&s.text, &bytes[..end], start));
        done = end;
    }
    out.extend_from_slice(&bytes[done..]);
    Ok(out)
}

/// `text` (written with [`mesh_text`]'s markers: NUL `P` for the element's prefix, NUL `A` for the
/// attributes of its start tag, NUL `I` for a new line at the element's indentation and NUL `D`
/// one level deeper) for the element at `start` of `bytes` (which end with the element).
fn restyle(text: &str, bytes: &[u8], start: usize) -> Vec<u8> {
    let name_end = bytes[start + 1..]
        .iter()
        .position(|b| b.is_ascii_whitespace() || matches!(b, b'>' | b'/'))
        .map_or(bytes.len(), |n| start + 1 + n);
    let name = &bytes[start + 1..name_end];
    let prefix = match name.iter().rposition(|&b| b == b':') {
        Some(colon) => &name[..=colon],
        None => &[][..],
    };
    let line = bytes[..start]
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |n| n + 1);
    let indent: Vec<u8> = bytes[line..start]
        .iter()
        .take_while(|b| matches!(b, b' ' | b'\t'))
        .copied()
        .collect();
    let mut deeper = indent.clone();
    deeper.extend_from_slice(if indent.contains(&b'\t') {
        b"\t"
    } else {
        b"  "
    });
    let attributes = start_tag_attributes(bytes, name_end);
    let mut out = Vec::with_capacity(text.len() + text.len() / 4);
    let mut rest = text.as_bytes();
    while let Some(i) = rest.iter().position(|&b| b == 0) {
        out.extend_from_slice(&rest[..i]);
        match rest.get(i + 1) {
            Some(b'P') => out.extend_from_slice(prefix),
            Some(b'A') => out.extend_from_slice(attributes),
            Some(b'I') => {
                out.push(b'\n');
                out.extend_from_slice(&indent);
            }
            Some(b'D') => {
                out.push(b'\n');
                out.extend_from_slice(&deeper);
            }
            _ => {}
        }
        rest = &rest[(i + 2).min(rest.len())..];
    }
    out.extend_from_slice(rest);
    out
}

/// The attributes of the start tag whose name ends at `name_end` of `bytes`: everything up to its
/// `>` (or `/>`), which is the first one outside quotes (a value may hold a `>`).
fn start_tag_attributes(bytes: &[u8], name_end: usize) -> &[u8] {
    let mut quote = None;
    let rest = bytes.get(name_end..).unwrap_or_default();
    for (i, &b) in rest.iter().enumerate() {
        match (quote, b) {
            (None, b'"' | b'\'') => quote = Some(b),
            (Some(q), _) if b == q => quote = None,
            (None, b'>') => {
                let attributes = &rest[..i];
                return attributes.strip_suffix(b"/").unwrap_or(attributes);
            }
            _ => {}
        }
    }
    &[]
}

/// Triangles whose slicer paint could not be carried: how many, and the attributes' names; and
/// how many attributes hold a NUL character (which XML does not allow, and which would read as
/// one of [`restyle`]'s markers).
#[derive(Default)]
struct Lost {
    triangles: usize,
    names: std::collections::BTreeSet<String>,
    nul: usize,
}

/// The attributes in `text` (` name="value"` each, as [`MeshData::other_attributes`] gives them):
/// (name, value without quotes, the whole attribute with its leading space).
fn attributes(text: &str) -> impl Iterator<Item = (&str, &str, &str)> {
    let mut rest = text;
    std::iter::from_fn(move || {
        let start = rest.find(|c: char| !c.is_ascii_whitespace())?;
        let eq = start + rest[start..].find('=')?;
        let quote = rest[eq + 1..].chars().next()?;
        let close = eq + 2 + rest[eq + 2..].find(quote)?;
        let (name, value, whole) = (&rest[start..eq], &rest[eq + 2..close], &rest[..=close]);
        rest = &rest[close + 1..];
        Some((name, value, whole))
    })
}

/// The new `<vertices>` and `<triangles>` of a repaired mesh, in [`restyle`]'s markers: NUL `P`
/// for the prefix, NUL `A` for the start tag's attributes, NUL `I` for a line at the element's
/// indentation, NUL `D` one level deeper; and the paint that could not be carried.
fn mesh_text(plan: &Plan, mesh: &Mesh, data: &MeshData) -> (String, String, Lost) {
    let (index, count) = renumber(plan);
    let index = &index;
    let mut v = String::with_capacity(48 * count + 32);
    v.push_str("<\0Pvertices\0A>");
    for (i, &used) in plan.used_vertices.iter().enumerate() {
        if !used {
            continue;
        }
        let p = plan.position(mesh, i as u32);
        v.push_str("\0D<\0Pvertex x=\"");
        push_number(&mut v, p[0]);
        v.push_str("\" y=\"");
        push_number(&mut v, p[1]);
        v.push_str("\" z=\"");
        push_number(&mut v, p[2]);
        v.push_str("\"/>");
    }
    v.push_str("\0I</\0Pvertices>");

    let mut t = String::with_capacity(48 * plan.triangles.len() + 32);
    t.push_str("<\0Ptriangles\0A>");
    let mut lost = Lost::default();
    let property = |s: usize| data.properties.get(s).copied().unwrap_or([NONE; 4]);
    for triangle in &plan.triangles {
        t.push_str("\0D<\0Ptriangle");
        for (k, c) in triangle.corners.iter().enumerate() {
            t.push_str([" v1=\"", "\" v2=\"", "\" v3=\""][k]);
            push_int(&mut t, index[c.vertex as usize]);
        }
        t.push('"');
        let (pid, corners) = match triangle.source {
            Some(s) => {
                let [pid, p1, p2, p3] = property(s as usize);
                // A triangle with p1 alone has one property for all its corners.
                let alone = p2 == NONE && p3 == NONE;
                let corner = |c: u32| -> u32 {
                    if c / 3 != s || alone {
                        return p1;
                    }
                    match [p1, p2, p3][(c % 3) as usize] {
                        NONE => p1,
                        p => p,
                    }
                };
                let q = triangle.corners.map(|c| corner(c.from));
                (pid, if alone { [q[0], NONE, NONE] } else { q })
            }
            None => {
                let [pid, p1, _, _] = property(triangle.near as usize);
                (pid, [p1, NONE, NONE])
            }
        };
        if pid != NONE {
            t.push_str(" pid=\"");
            push_int(&mut t, pid);
            t.push('"');
        }
        for (k, p) in corners.into_iter().enumerate() {
            if p != NONE {
                t.push_str([" p1=\"", " p2=\"", " p3=\""][k]);
                push_int(&mut t, p);
                t.push('"');
            }
        }
        if let Some(s) = triangle.source {
            others(&mut t, triangle, data.other_attributes(s), &mut lost);
        }
        t.push_str("/>");
    }
    t.push_str("\0I</\0Ptriangles>");
    (v, t, lost)
}

/// Appends to `t` the other attributes `text` of the source of the kept `triangle`: as they are,
/// but slicer paint re-encoded for the triangle's new corner order when the repair changed it
/// (counted in `lost` when it cannot be).
fn others(t: &mut String, triangle: &crate::repair::Triangle, text: &str, lost: &mut Lost) {
    if text.is_empty() {
        return;
    }
    let order = triangle.corners.map(|c| (c.from % 3) as u8);
    if order == [0, 1, 2] && !text.contains('\0') {
        t.push_str(text);
        return;
    }
    let mut dropped = false;
    for (name, value, whole) in attributes(text) {
        if whole.contains('\0') {
            lost.nul += 1;
            continue;
        }
        if order == [0, 1, 2] || !paint::is_paint(name) {
            t.push_str(whole);
            continue;
        }
        match paint::reorder(value, order) {
            Some(value) => {
                t.push(' ');
                t.push_str(name);
                t.push_str("=\"");
                t.push_str(&value);
                t.push('"');
            }
            None => {
                dropped = true;
                lost.names.insert(name.to_owned());
            }
        }
    }
    lost.triangles += usize::from(dropped);
}
