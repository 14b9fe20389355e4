//! glTF 2.0 / GLB reader: one [`Mesh`] per glTF `mesh`, all its triangle primitives together, in
//! the mesh's local space, counted once however many nodes instance it (SPEC section 2).
//!
//! The gltf crate panics on several malformed inputs, all in its validation pass and its `Reader`
//! (CRATES.md 5.1-5.3). So this reader uses only the crate's JSON types: it deserializes the
//! members geometry needs itself (`container::Model`, after turning away glTF 1.0 and extensions
//! it cannot decode), never builds a `gltf::Document`, resolves buffers itself (`buffers`), and
//! reads accessors from bytes it has checked (`accessor`). Every index, type, stride and byte range is checked before use; a panic that
//! slips through anyway is caught and reported as a read error for this file.

pub(super) mod accessor;
pub(super) mod buffers;
pub(super) mod container;
mod nodes;

use std::collections::BTreeSet;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use gltf::json;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use super::{ReadContext, ReadError};
use crate::mesh::Mesh;
use accessor::Data;

/// Reads every mesh of a `.gltf` or `.glb` file (either is recognised by its content).
pub fn read(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    guard(|| read_unguarded(path, cx))
}

/// Runs `f`, turning a panic (a check this reader lacks) into a read error for this file.
fn guard<T>(f: impl FnOnce() -> Result<T, ReadError>) -> Result<T, ReadError> {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|panic| {
        let detail = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".to_string());
        Err(ReadError::new(format!(
            "the glTF reader crashed on this file ({detail}): the file is malformed in a way meshvet does not yet describe; please report it"
        )))
    })
}

fn read_unguarded(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    let bytes = std::fs::read(path)?;
    let container = container::split(&bytes)?;
    let root = container::parse_model(container.json)?;
    if root.meshes.is_empty() {
        return Ok(Vec::new());
    }
    let mirrored = nodes::mirrored_instances(&root)?;

    // Load only the buffers the meshes read: a missing texture-only .bin is not our concern.
    let mut needed = BTreeSet::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let Some((position, indices)) = triangle_accessors(primitive) else {
                continue;
            };
            for index in std::iter::once(position).chain(indices) {
                let what = primitive_name(mesh, m, p);
                let accessor = accessor::get(&root, index, &what)?;
                for view in accessor::views_of(accessor) {
                    let view = root.buffer_views.get(view).ok_or_else(|| {
                        ReadError::new(format!(
                            "{what} refers to buffer view {view}, but the file has {} buffer views",
                            root.buffer_views.len()
                        ))
                    })?;
                    needed.insert(view.buffer.value());
                }
            }
        }
    }
    let mut loaded = Vec::with_capacity(root.buffers.len());
    let location = if container.is_glb && root.buffers.iter().all(|b| b.uri.is_none()) {
        None // a self-contained GLB needs no file system lookups
    } else {
        Some(buffers::Location::new(path, &cx.root)?)
    };
    for (index, buffer) in root.buffers.iter().enumerate() {
        if needed.contains(&index) {
            let bytes = buffers::load(
                index,
                buffer,
                container.bin,
                container.is_glb,
                location.as_ref(),
                &cx.limits,
            )?;
            loaded.push(Some(bytes));
        } else {
            // A URI no mesh reads is still refused if it points outside the tree (checked
            // lexically, nothing is touched); a missing file there is not our concern.
            if let (Some(uri), Some(location)) = (&buffer.uri, &location) {
                if !uri
                    .get(..5)
                    .is_some_and(|s| s.eq_ignore_ascii_case("data:"))
                {
                    buffers::check(uri, location)?;
                }
            }
            loaded.push(None);
        }
    }
    let data = Data {
        root: &root,
        buffers: loaded,
        limits: &cx.limits,
    };

    let mut scratch = Vec::new();
    root.meshes
        .iter()
        .enumerate()
        .map(|(m, mesh)| {
            let mut out = read_mesh(&data, mesh, m, &mut scratch)?;
            out.mirrored_instances = mirrored[m];
            Ok(out)
        })
        .collect()
}

/// The POSITION accessor and indices accessor of a triangle primitive; `None` for other modes
/// (and invalid modes, reported when the mesh is read) or a primitive without positions.
fn triangle_accessors(primitive: &json::mesh::Primitive) -> Option<(usize, Option<usize>)> {
    match primitive.mode {
        Checked::Valid(Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) => {}
        _ => return None,
    }
    let position = position_accessor(primitive)?;
    Some((position, primitive.indices.map(|i| i.value())))
}

fn position_accessor(primitive: &json::mesh::Primitive) -> Option<usize> {
    primitive
        .attributes
        .iter()
        .find_map(|(semantic, accessor)| {
            matches!(semantic, Checked::Valid(Semantic::Positions)).then(|| accessor.value())
        })
}

fn mesh_name(mesh: &json::Mesh, index: usize) -> String {
    mesh.name.clone().unwrap_or_else(|| format!("#{index}"))
}

fn primitive_name(mesh: &json::Mesh, m: usize, p: usize) -> String {
    match &mesh.name {
        Some(name) => format!("mesh \"{name}\" (#{m}) primitive {p}"),
        None => format!("mesh #{m} primitive {p}"),
    }
}

/// Reads one glTF mesh: each triangle primitive's vertices appended, its indices offset.
fn read_mesh(
    data: &Data<'_>,
    mesh: &json::Mesh,
    m: usize,
    indices: &mut Vec<u32>,
) -> Result<Mesh, ReadError> {
    let limits = data.limits;
    let mut out = Mesh {
        name: Some(mesh_name(mesh, m)),
        ..Mesh::default()
    };
    let mut skipped: [usize; 4] = [0; 4]; // POINTS, LINES, LINE_LOOP, LINE_STRIP
    let mut without_positions = 0usize;
    for (p, primitive) in mesh.primitives.iter().enumerate() {
        let what = primitive_name(mesh, m, p);
        let mode = match primitive.mode {
            Checked::Valid(mode) => mode,
            Checked::Invalid => {
                return Err(ReadError::new(format!(
                    "{what} has an invalid mode (glTF modes are 0 to 6)"
                )))
            }
        };
        match mode {
            Mode::Points => skipped[0] += 1,
            Mode::Lines => skipped[1] += 1,
            Mode::LineLoop => skipped[2] += 1,
            Mode::LineStrip => skipped[3] += 1,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => {}
        }
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            continue;
        }
        let Some(position) = position_accessor(primitive) else {
            without_positions += 1;
            continue;
        };

        let position = accessor::get(data.root, position, &what)?;
        if position.count.0 > limits.max_triangles {
            return Err(over_limit(
                &what,
                "vertices",
                position.count.0,
                limits.max_triangles,
            ));
        }
        let base = out.positions.len();
        data.append_positions(position, &mut out.positions, &what)?;
        let vertices = out.positions.len() - base;
        if u32::try_from(out.positions.len()).is_err()
            || out.positions.len() as u64 > limits.max_triangles
        {
            return Err(over_limit(
                &mesh_name(mesh, m),
                "vertices",
                out.positions.len() as u64,
                limits.max_triangles,
            ));
        }

        let corners = match primitive.indices {
            Some(i) => {
                let accessor = accessor::get(data.root, i.value(), &what)?;
                data.read_indices(accessor, indices, &what)?;
                if let Some((k, &bad)) = indices
                    .iter()
                    .enumerate()
                    .find(|(_, &v)| v as usize >= vertices)
                {
                    return Err(ReadError::new(format!(
                        "{what}: index {bad} (at position {k}) is out of range: the primitive has {vertices} vertices"
                    )));
                }
                Some(indices.as_slice())
            }
            None => None,
        };
        let n = corners.map_or(vertices, <[u32]>::len);
        let triangles = match mode {
            Mode::Triangles => n / 3,
            _ => n.saturating_sub(2),
        };
        let total = out.triangles.len() as u64 + triangles as u64;
        if total > limits.max_triangles {
            return Err(over_limit(
                &mesh_name(mesh, m),
                "triangles",
                total,
                limits.max_triangles,
            ));
        }
        if mode == Mode::Triangles && n % 3 != 0 {
            out.notes.push(format!(
                "primitive {p}: {} vertex references after the last whole triangle were ignored",
                n % 3
            ));
        }
        let base = base as u32; // fits: out.positions.len() fits in u32 (checked above)
        let corner = |k: usize| base + corners.map_or(k as u32, |c| c[k]);
        out.triangles.reserve(triangles);
        match mode {
            Mode::Triangles => out.triangles.extend(
                (0..triangles).map(|t| [corner(3 * t), corner(3 * t + 1), corner(3 * t + 2)]),
            ),
            // glTF 2.0 3.7.2.1: strip triangle i is (i, i+1+i%2, i+2-i%2), fan triangle i is (i+1, i+2, 0).
            Mode::TriangleStrip => out.triangles.extend(
                (0..triangles).map(|i| [corner(i), corner(i + 1 + i % 2), corner(i + 2 - i % 2)]),
            ),
            _ => out
                .triangles
                .extend((0..triangles).map(|i| [corner(i + 1), corner(i + 2), corner(0)])),
        }
    }

    let names = ["POINTS", "LINES", "LINE_LOOP", "LINE_STRIP"];
    let skipped: Vec<String> = skipped
        .iter()
        .zip(names)
        .filter(|(&n, _)| n > 0)
        .map(|(n, name)| format!("{n} {name}"))
        .collect();
    if !skipped.is_empty() {
        out.notes.push(format!(
            "skipped primitives that are not triangles: {}",
            skipped.join(", ")
        ));
    }
    if without_positions > 0 {
        out.notes.push(format!(
            "skipped {without_positions} primitive(s) with no POSITION attribute"
        ));
    }
    Ok(out)
}

fn over_limit(what: &str, unit: &str, count: u64, limit: u64) -> ReadError {
    ReadError::new(format!(
        "{what} has {count} {unit}, over the limit of {limit}: raise limits.max_triangles in the config to read it"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_a_read_error() {
        let err = guard::<()>(|| panic!("boom {}", 7)).unwrap_err();
        assert!(
            err.0.contains("crashed") && err.0.contains("boom 7"),
            "{err}"
        );
        assert_eq!(guard(|| Ok(3)), Ok(3));
    }
}
