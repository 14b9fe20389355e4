//! Writers of repaired copies ([definitions](crate::definitions#repairs)): each applies a [`Plan`] to the source file and writes the
//! result in the source's format, keeping every attribute the file carries.
//!
//! A writer re-reads the source with its reader's "full" read (the readers are deterministic, so
//! the plan's input vertices and corners line up with what the full read returns), unless the
//! scan's read kept what it needs ([`super::read_retaining`]: OBJ, whose second parse cost more
//! than the rest of the copy), then writes
//! the copy to a temporary file in the output folder and renames it: a crash leaves no half-written
//! copy, and the source is never opened for writing. Helpers shared by the polygon formats live
//! here: which source polygons survive whole, vertex renumbering and the normal checks: a normal
//! that disagrees with a flipped face is negated, and a hole fill's corner whose normal (taken
//! from the border corner it sits on) is more than 60 degrees from its hole's normal
//! (`fill_normals`) gets that normal (`borrowed_normal_fits`; OBJ as the file's `vn` of that
//! value or a new one, glTF and PLY, whose normals are per vertex, with a copy of the vertex).

pub(super) mod gltf;
pub mod names;
pub(super) mod obj;
pub(super) mod off;
pub(super) mod ply;
pub(super) mod stl;
pub(super) mod threemf;

use std::io::Write as _;
use std::path::{Path, PathBuf};

use rustc_hash::FxHashMap;

use super::{Format, ReadContext, ReadError};
use crate::atomic::AtomicFile;
use crate::geometry::polygon;
use crate::mesh::Mesh;
use crate::repair::Plan;
use names::Claims;

/// Why a repaired copy could not be written. The message is for a person.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct WriteError(pub String);

impl WriteError {
    pub fn new(msg: impl Into<String>) -> WriteError {
        WriteError(msg.into())
    }
}

impl From<ReadError> for WriteError {
    fn from(e: ReadError) -> WriteError {
        WriteError(format!("cannot re-read the source: {}", e.0))
    }
}

impl From<std::io::Error> for WriteError {
    fn from(e: std::io::Error) -> WriteError {
        WriteError(format!("cannot write the repaired copy: {e}"))
    }
}

/// What writing a copy did: every file written (the copy first), and notes for the row's message
/// about what the copy could not keep (a PLY element whose vertex references are unknown).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Written {
    pub files: Vec<PathBuf>,
    pub notes: Vec<String>,
}

/// What a scan read of a source whose copy it writes: the meshes its plans were made for, and what
/// its read kept for the writer ([`super::read_retaining`]; the writer then does not read the
/// source again). A writer that does read it again refuses the copy when that read's positions or
/// triangles differ: the file's geometry changed after the scan read it, and the plans are not for
/// what it holds now (a change to its other data, normals or materials, is copied as it is now).
pub struct ScanRead<'a> {
    pub meshes: &'a [Mesh],
    pub retained: Option<super::Retained>,
}

/// One repaired copy to write: the source file, one plan per mesh its reader returns (`None`: that
/// mesh is left as it is), where the copy goes, the reader's context, what the scan read of the
/// source (when a scan did), and the names claimed in the folder the
/// copy finally goes to (a writer that brings a file beside the copy names it through
/// [`Claims::side`], so that no other copy in that folder takes the name for other bytes).
pub struct Job<'a> {
    pub source: &'a Path,
    pub format: Format,
    pub plans: &'a [Option<Plan>],
    pub out: &'a Path,
    pub cx: &'a ReadContext,
    pub read: Option<ScanRead<'a>>,
    pub claims: &'a Claims,
}

impl Job<'_> {
    /// The plan of a one-mesh format's only mesh.
    pub(crate) fn single(&self) -> Result<&Plan, WriteError> {
        match self.plans {
            [Some(plan)] => Ok(plan),
            _ => Err(WriteError::new(format!(
                "a {} file is one mesh: expected one plan, got {}",
                self.format,
                self.plans.len()
            ))),
        }
    }

    /// Refuses the copy when the source, read again as `again`, is not what the scan read.
    pub(crate) fn unchanged(&self, again: &[Mesh]) -> Result<(), WriteError> {
        unchanged(self.read.as_ref().map(|r| r.meshes), again)
    }

    /// What a writer wrote: the copy, the `side` files beside it, and `notes`.
    pub(crate) fn written(&self, side: Vec<PathBuf>, notes: Vec<String>) -> Written {
        let mut files = vec![self.out.to_path_buf()];
        files.extend(side);
        Written { files, notes }
    }
}

/// Writes the repaired copy of `source` to `out`: `plans` has one entry per mesh the reader
/// returns (`None`: that mesh is left as it is). Files the copy needs beside it (an OBJ's `.mtl`
/// and textures, a glTF's buffers and images) are written next to it. Returns every file written,
/// the copy first.
pub fn write_repaired(
    source: &Path,
    format: Format,
    plans: &[Option<Plan>],
    out: &Path,
    cx: &ReadContext,
) -> Result<Vec<PathBuf>, WriteError> {
    write_copy(source, format, plans, out, cx, None).map(|w| w.files)
}

/// [`write_repaired`], with the writer's notes. Every file it writes is `out` or lies in `out`'s
/// folder or below it. `read` is what a scan read of the source, which the plans were made for
/// ([`ScanRead`]).
pub fn write_copy(
    source: &Path,
    format: Format,
    plans: &[Option<Plan>],
    out: &Path,
    cx: &ReadContext,
    read: Option<ScanRead<'_>>,
) -> Result<Written, WriteError> {
    let folder = out.parent().unwrap_or(Path::new(""));
    let claims = Claims::new(folder);
    write_claimed(source, format, plans, out, cx, read, &claims)
}

/// Refuses a copy whose source, read again as `again`, is not the `scanned` meshes.
pub(crate) fn unchanged(scanned: Option<&[Mesh]>, again: &[Mesh]) -> Result<(), WriteError> {
    let same = |a: &Mesh, b: &Mesh| {
        a.triangles == b.triangles
            && a.positions.len() == b.positions.len()
            && a.positions
                .iter()
                .zip(&b.positions)
                .all(|(p, q)| p.map(f64::to_bits) == q.map(f64::to_bits))
    };
    match scanned {
        Some(scanned)
            if scanned.len() != again.len()
                || scanned.iter().zip(again).any(|(a, b)| !same(a, b)) =>
        {
            Err(changed())
        }
        _ => Ok(()),
    }
}

/// The refusal of a copy whose source changed after the scan read it.
pub(crate) fn changed() -> WriteError {
    WriteError::new("the file changed after the scan read it: scan it again to repair it")
}

/// [`write_copy`] into a staging folder that stands for the folder the copy finally goes to:
/// `claims` (made for that folder) names the files the copy brings beside it there, and holds
/// those names until it is dropped, after the files are moved into place.
pub fn write_claimed(
    source: &Path,
    format: Format,
    plans: &[Option<Plan>],
    out: &Path,
    cx: &ReadContext,
    read: Option<ScanRead<'_>>,
    claims: &Claims,
) -> Result<Written, WriteError> {
    refuse_own_source(source, out)?;
    let size = std::fs::metadata(source)?.len();
    if size > cx.limits.max_file_bytes {
        return Err(WriteError::new(format!(
            "file is {size} bytes, over the limit of {} bytes",
            cx.limits.max_file_bytes
        )));
    }
    (format.entry().write)(Job {
        source,
        format,
        plans,
        out,
        cx,
        read,
        claims,
    })
}

/// Refuses a copy whose place `out` is its `source` itself (a scan's copy goes to its final place
/// only after it is written elsewhere, so the scan asks before staging it, and so does each write).
pub fn refuse_own_source(source: &Path, out: &Path) -> Result<(), WriteError> {
    match (source.canonicalize(), out.canonicalize()) {
        (Ok(a), Ok(b)) if a == b => Err(WriteError::new(
            "the repaired copy would overwrite its source: choose an output folder outside the scanned files",
        )),
        _ => Ok(()),
    }
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, creating
/// the folder when needed.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let folder = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(folder)?;
    let written = AtomicFile::create(path).and_then(|mut file| {
        file.write_all(bytes)?;
        file.commit()
    });
    written.map_err(|e| WriteError(format!("cannot write {}: {e}", path.display())))
}

/// The bytes of `from`, a file the source refers to.
pub(crate) fn read_side(from: &Path) -> Result<Vec<u8>, WriteError> {
    super::read_regular(from)
        .map_err(|e| WriteError(format!("cannot read {}: {e}", from.display())))
}

/// Writes `bytes`, read from `from`, to `to` atomically, unless `to` is `from` itself.
pub(crate) fn put_beside(from: &Path, bytes: &[u8], to: &Path) -> Result<(), WriteError> {
    if let (Ok(a), Ok(b)) = (from.canonicalize(), to.canonicalize()) {
        if a == b {
            return Ok(());
        }
    }
    write_atomic(to, bytes)
}

/// New numbers of the kept vertices (input, then new, as [`Plan::apply`] numbers them);
/// `u32::MAX` for dropped ones.
pub(crate) fn renumber(plan: &Plan) -> (Vec<u32>, usize) {
    let mut index = vec![u32::MAX; plan.used_vertices.len()];
    let mut next = 0u32;
    for (i, &used) in plan.used_vertices.iter().enumerate() {
        if used {
            index[i] = next;
            next += 1;
        }
    }
    (index, next as usize)
}

/// The input vertex a plan vertex carries the attributes of (itself, or what a new vertex copies).
pub(crate) fn original(plan: &Plan, mesh: &Mesh, vertex: u32) -> u32 {
    match (vertex as usize).checked_sub(mesh.positions.len()) {
        Some(i) => plan.new_vertices[i].copy_of,
        None => vertex,
    }
}

/// One item of a repaired polygon file, in output order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Item {
    /// A source polygon written back whole (`reversed`: every triangle of it was flipped).
    Polygon { face: usize, reversed: bool },
    /// A plan triangle written as a triangle.
    Triangle(usize),
}

/// The source polygons of a file: polygon `f` became `triangles[first[f]..first[f] + count[f]]`.
pub(crate) struct Polygons {
    pub first: Vec<u32>,
    pub count: Vec<u32>,
    /// The polygon of every input triangle.
    pub of_triangle: Vec<u32>,
    /// The polygon corner (0-based position in its polygon) of every input triangle's corners.
    pub local: Vec<[u32; 3]>,
    /// Whether each polygon was split as a fan from its first corner (so its reverse, read again,
    /// splits into the same triangles reversed).
    pub fan: Vec<bool>,
}

impl Polygons {
    /// `face(f, out)` puts the vertices of polygon `f` (of `count`) in `out`; they were split in
    /// order, `n - 2` triangles each (none under 3), by the same code that splits them here.
    pub fn new(
        count: usize,
        mut face: impl FnMut(usize, &mut Vec<u32>),
        mesh: &Mesh,
    ) -> Result<Polygons, WriteError> {
        let mut p = Polygons {
            first: Vec::new(),
            count: Vec::new(),
            of_triangle: Vec::with_capacity(mesh.triangles.len()),
            local: Vec::with_capacity(mesh.triangles.len()),
            fan: Vec::new(),
        };
        let mut local = Vec::new();
        let mut poly = Vec::new();
        for f in 0..count {
            poly.clear();
            face(f, &mut poly);
            let first = p.of_triangle.len();
            local.clear();
            local_triangles(&poly, &mesh.positions, &mut local);
            let fan = local
                .iter()
                .enumerate()
                .all(|(i, t)| *t == [0, i as u32 + 1, i as u32 + 2]);
            for (i, t) in local.iter().enumerate() {
                let expected = t.map(|k| poly[k as usize]);
                if mesh.triangles.get(first + i) != Some(&expected) {
                    return Err(WriteError::new(format!(
                        "the source's polygon {f} did not split as it did when scanned (internal error: please report this file)"
                    )));
                }
            }
            p.of_triangle
                .extend(std::iter::repeat_n(f as u32, local.len()));
            p.local.extend_from_slice(&local);
            p.first.push(first as u32);
            p.count.push(local.len() as u32);
            p.fan.push(fan);
        }
        if p.of_triangle.len() != mesh.triangles.len() {
            return Err(WriteError::new(
                "the source's polygons do not add up to its triangles (internal error: please report this file)",
            ));
        }
        Ok(p)
    }

    /// The output items: polygons whose triangles all survive with their own vertices (all flipped
    /// or none) are written whole, at their first triangle; everything else as triangles.
    pub fn items(&self, plan: &Plan, mesh: &Mesh) -> Vec<Item> {
        // Per polygon: surviving unchanged triangles, how many of them flipped.
        let mut whole = vec![(0u32, 0u32); self.first.len()];
        for t in &plan.triangles {
            let Some(source) = t.source else { continue };
            let unchanged = t.corners.iter().all(|c| {
                c.from / 3 == source
                    && mesh
                        .triangles
                        .get(source as usize)
                        .map(|s| s[(c.from % 3) as usize])
                        == Some(c.vertex)
            });
            if unchanged {
                let f = self.of_triangle[source as usize] as usize;
                whole[f].0 += 1;
                whole[f].1 += u32::from(t.flipped);
            }
        }
        let is_whole = |f: usize| {
            let (kept, flipped) = whole[f];
            kept == self.count[f] && (flipped == 0 || (flipped == kept && self.fan[f]))
        };
        let mut done = vec![false; self.first.len()];
        let mut items = Vec::with_capacity(plan.triangles.len());
        for (i, t) in plan.triangles.iter().enumerate() {
            if let Some(source) = t.source {
                let f = self.of_triangle[source as usize] as usize;
                if self.count[f] > 1 && is_whole(f) {
                    if !done[f] {
                        done[f] = true;
                        items.push(Item::Polygon {
                            face: f,
                            reversed: whole[f].1 > 0,
                        });
                    }
                    continue;
                }
            }
            items.push(Item::Triangle(i));
        }
        items
    }

    /// Polygon and polygon corner of input corner `c` (`3 * triangle + k`).
    pub fn corner(&self, c: u32) -> (usize, usize) {
        let t = (c / 3) as usize;
        (
            self.of_triangle[t] as usize,
            self.local[t][(c % 3) as usize] as usize,
        )
    }

    /// The polygon whose attributes (material, group, face properties) plan triangle `t` takes.
    pub fn of(&self, t: &crate::repair::Triangle) -> usize {
        self.of_triangle[t.near as usize] as usize
    }
}

/// The triangles `polygon::triangulate` makes of `poly`, as corner numbers of the polygon.
pub(crate) fn local_triangles(poly: &[u32], positions: &[[f64; 3]], out: &mut Vec<[u32; 3]>) {
    let n = poly.len() as u32;
    if n == 3 {
        // What `triangulate` does with a triangle, without its two allocations.
        out.push([0, 1, 2]);
        return;
    }
    let corners: Vec<u32> = (0..n).collect();
    // An index out of range makes the reader's split a fan; an empty list does the same here.
    let points: Option<Vec<[f64; 3]>> = poly
        .iter()
        .map(|&v| positions.get(v as usize).copied())
        .collect();
    polygon::triangulate(&corners, points.as_deref().unwrap_or(&[]), out);
}

/// The corner of polygon item `face` at position `k` of the output (reversed polygons start at
/// the same corner and run backwards, so a fan stays a fan).
pub(crate) fn polygon_corner(n: usize, k: usize, reversed: bool) -> usize {
    if reversed {
        (n - k) % n
    } else {
        k
    }
}

/// The normal (cross product, length twice the area) of a plan triangle at final positions.
pub(crate) fn triangle_normal(plan: &Plan, mesh: &Mesh, t: &crate::repair::Triangle) -> [f64; 3] {
    let [a, b, c] = t.corners.map(|c| plan.position(mesh, c.vertex));
    crate::geometry::normal(a, b, c)
}

/// Per plan triangle, the unit normal of the hole its fill closes: one normal per hole (its fill
/// triangles joined edge to edge), the sum of their normals (cross products, so weighted by area:
/// for a flat hole exactly the plane's direction, the same for every triangle of it), in the fills'
/// winding. `None` for a kept face, and for a fill whose hole's normal has no direction or length
/// in `f64` (zero-area fills, or coordinates so large the cross products overflow).
pub(crate) fn fill_normals(plan: &Plan, mesh: &Mesh) -> Vec<Option<[f64; 3]>> {
    let fills: Vec<usize> = (0..plan.triangles.len())
        .filter(|&i| plan.triangles[i].source.is_none())
        .collect();
    let mut out = vec![None; plan.triangles.len()];
    if fills.is_empty() {
        return out;
    }
    // The holes: fills joined by the edges they share (fills of different holes share none).
    let mut parent: Vec<u32> = (0..fills.len() as u32).collect();
    let mut by_edge: FxHashMap<[u32; 2], u32> = FxHashMap::default();
    for (k, &i) in fills.iter().enumerate() {
        let v = plan.triangles[i].corners.map(|c| c.vertex);
        for j in 0..3 {
            let (a, b) = (v[j], v[(j + 1) % 3]);
            let other = *by_edge.entry([a.min(b), a.max(b)]).or_insert(k as u32);
            crate::topology::sets::union(&mut parent, other, k as u32);
        }
    }
    let mut sums: FxHashMap<u32, [f64; 3]> = FxHashMap::default();
    for (k, &i) in fills.iter().enumerate() {
        let n = triangle_normal(plan, mesh, &plan.triangles[i]);
        let sum = sums
            .entry(crate::topology::sets::find(&mut parent, k as u32))
            .or_insert([0.0; 3]);
        for d in 0..3 {
            sum[d] += n[d];
        }
    }
    for (k, &i) in fills.iter().enumerate() {
        let hole = crate::topology::sets::find(&mut parent, k as u32);
        out[i] = unit(sums[&hole]);
    }
    out
}

/// The vertex copies that fills' corners take, in a format whose normals are per vertex (glTF,
/// PLY): a fill's corner whose vertex's normal as the copy writes it (`stored(v)`, negated where
/// `sums` says it disagrees with a flipped face, [`normal_sums`]) is more than 60 degrees from its
/// hole's normal (`holes`, [`fill_normals`]) takes a copy of its vertex with the hole's normal,
/// one copy per vertex and direction. Only the plan triangles `triangles` are looked at.
pub(crate) struct NormalCopies {
    /// Each copy's plan vertex and normal, in the order the copies are to be numbered.
    pub(crate) copies: Vec<(u32, [f64; 3])>,
    /// A fill's corner (plan triangle and corner) -> its copy's place in `copies`.
    pub(crate) corners: FxHashMap<(usize, usize), usize>,
}

impl NormalCopies {
    pub(crate) fn new(
        plan: &Plan,
        holes: &[Option<[f64; 3]>],
        triangles: impl IntoIterator<Item = usize>,
        sums: &FxHashMap<u32, [f64; 3]>,
        stored: impl Fn(u32) -> [f64; 3],
    ) -> NormalCopies {
        let mut out = NormalCopies {
            copies: Vec::new(),
            corners: FxHashMap::default(),
        };
        let mut places: FxHashMap<(u32, [u64; 3]), usize> = FxHashMap::default();
        for i in triangles {
            let Some(own) = holes[i] else {
                continue;
            };
            for (j, c) in plan.triangles[i].corners.iter().enumerate() {
                let mut n = stored(c.vertex);
                if sums
                    .get(&c.vertex)
                    .is_some_and(|sum| crate::geometry::dot(n, *sum) < 0.0)
                {
                    n = n.map(|x| -x);
                }
                if borrowed_normal_fits(n, own) {
                    continue;
                }
                let copies = &mut out.copies;
                let place = *places
                    .entry((c.vertex, own.map(f64::to_bits)))
                    .or_insert_with(|| {
                        copies.push((c.vertex, own));
                        copies.len() - 1
                    });
                out.corners.insert((i, j), place);
            }
        }
        out
    }
}

/// `v` scaled to length 1; `None` when it has no direction (zero, or not finite).
fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    // Divided by its largest component first, so that squaring neither overflows nor underflows.
    let largest = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if !(largest > 0.0 && largest.is_finite()) {
        return None;
    }
    let w = v.map(|x| x / largest);
    let length = crate::geometry::dot(w, w).sqrt();
    // `+ 0.0` turns -0 into 0, so that one direction is written one way.
    Some(w.map(|x| x / length + 0.0))
}

/// Whether a normal that a fill's corner takes from the border corner at its vertex may stay
/// there: it is within 60 degrees of the unit normal `face` of the fill's hole ([`fill_normals`]).
/// A hole in a smooth surface keeps the surface's shading across it; a lid across a crease (a
/// box's missing top, whose border corners hold the walls' normals, at 90 degrees to the lid)
/// gets the hole's normal instead, as does a corner whose normal has no direction.
pub(crate) fn borrowed_normal_fits(borrowed: [f64; 3], face: [f64; 3]) -> bool {
    unit(borrowed).is_some_and(|b| crate::geometry::dot(b, face) >= 0.5)
}

/// Area-weighted normals of the final faces around every vertex a flipped triangle uses, keyed
/// by `key(corner)` (the plan vertex for per-vertex normals; vertex and normal index for OBJ's
/// per-corner normals). A stored normal whose dot product with its sum is negative disagrees
/// with the new winding and is negated; vertices no flipped triangle touches are left alone.
pub(crate) fn normal_sums<K: std::hash::Hash + Eq + Copy>(
    plan: &Plan,
    mesh: &Mesh,
    key: impl Fn(&crate::repair::Corner) -> Option<K>,
) -> FxHashMap<K, [f64; 3]> {
    let mut sums: FxHashMap<K, [f64; 3]> = FxHashMap::default();
    for t in plan.triangles.iter().filter(|t| t.flipped) {
        for c in &t.corners {
            if let Some(k) = key(c) {
                sums.insert(k, [0.0; 3]);
            }
        }
    }
    if sums.is_empty() {
        return sums;
    }
    for t in &plan.triangles {
        let normal = triangle_normal(plan, mesh, t);
        for c in &t.corners {
            if let Some(sum) = key(c).and_then(|k| sums.get_mut(&k)) {
                for i in 0..3 {
                    sum[i] += normal[i];
                }
            }
        }
    }
    sums
}

/// A number as the shortest text that reads back as the same value (`1` for 1.0).
pub(crate) fn number(x: f64) -> String {
    let mut s = String::new();
    push_number(&mut s, x);
    s
}

/// Appends [`number`]`(x)`: the shortest round-trip digits (ryu, several times faster than
/// `format!`, which matters for a million vertices), written without a trailing `.0`, so `1` for
/// 1.0, `0.1` for 0.1 and `1e-7` for 1e-7. NaN and infinities as Rust writes them.
pub(crate) fn push_number(out: &mut String, x: f64) {
    let mut buffer = ryu::Buffer::new();
    let text = buffer.format(x);
    out.push_str(text.strip_suffix(".0").unwrap_or(text));
}

/// Appends the decimal text of `n`.
pub(crate) fn push_int(out: &mut String, n: impl itoa::Integer) {
    out.push_str(itoa::Buffer::new().format(n));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Number text reads back as the very same value, with no `.0` on whole numbers, for values
    /// where the shortest text uses an exponent too.
    #[test]
    fn numbers_read_back_exactly() {
        let values = [
            0.0,
            -0.0,
            1.0,
            -2.0,
            0.1,
            1.0 / 3.0,
            f64::from(0.1f32),
            1e-7,
            1.5e-300,
            1e16,
            123456789.0,
            f64::MAX,
            f64::MIN_POSITIVE,
        ];
        for x in values {
            let text = number(x);
            let back: f64 = text.parse().unwrap();
            assert_eq!(back.to_bits(), x.to_bits(), "{x} wrote {text}");
            assert!(!text.ends_with(".0"), "{text}");
        }
        assert_eq!(number(1.0), "1");
        assert_eq!(number(-0.5), "-0.5");
        assert_eq!(number(f64::NAN), "NaN");
        assert_eq!(number(f64::NEG_INFINITY), "-inf");
        let mut s = String::new();
        push_int(&mut s, 4_294_967_296u64);
        assert_eq!(s, "4294967296");
    }
}
