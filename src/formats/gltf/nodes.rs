//! The node hierarchy, walked only to count mirrored instances: nodes whose world transform
//! (parent x child, from the scene roots down) has a negative determinant, which turns the mesh's
//! winding inside out where it is placed, and `EXT_mesh_gpu_instancing` instances whose SCALE
//! mirrors them (or un-mirrors a mirrored node). The walk is iterative and visits each node once, so a
//! cyclic or shared hierarchy (invalid, but found in the wild) neither loops nor explodes.

use std::collections::BTreeMap;

use glam::{DMat4, DQuat, DVec3};
use gltf::json;

use super::container::Model;

use super::super::ReadError;

/// The instances an `EXT_mesh_gpu_instancing` node draws, by the sign of the product of their
/// SCALE components (a rotation never mirrors, a translation has no say). Zero-scale instances are
/// in neither count: they are flat, not mirrored.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InstanceSigns {
    pub positive: u32,
    pub negative: u32,
}

/// For each mesh, how many instances place it with a mirroring transform: nodes whose world
/// transform has a negative determinant and, for a node with GPU instancing (`instances`), each
/// instance whose transform (world x instance) does. Roots are the nodes of every scene; a file
/// with no scenes uses every node that is nobody's child.
pub fn mirrored_instances(
    root: &Model,
    instances: &BTreeMap<usize, InstanceSigns>,
) -> Result<Vec<u32>, ReadError> {
    let nodes = &root.nodes;
    let check = |index: usize, who: &dyn Fn() -> String| {
        if index < nodes.len() {
            Ok(index)
        } else {
            Err(ReadError::new(format!(
                "{} refers to node {index}, but the file has {} nodes",
                who(),
                nodes.len()
            )))
        }
    };
    let mut roots = Vec::new();
    if root.scenes.is_empty() {
        let mut has_parent = vec![false; nodes.len()];
        for (n, node) in nodes.iter().enumerate() {
            for child in node.children.iter().flatten() {
                has_parent[check(child.value(), &|| format!("node {n}"))?] = true;
            }
        }
        roots.extend((0..nodes.len()).filter(|&n| !has_parent[n]));
    } else {
        for (s, scene) in root.scenes.iter().enumerate() {
            for node in &scene.nodes {
                roots.push(check(node.value(), &|| format!("scene {s}"))?);
            }
        }
    }

    let mut counts = vec![0u32; root.meshes.len()];
    let mut visited = vec![false; nodes.len()];
    let mut stack: Vec<(usize, DMat4)> =
        roots.iter().rev().map(|&n| (n, DMat4::IDENTITY)).collect();
    while let Some((n, parent)) = stack.pop() {
        if std::mem::replace(&mut visited[n], true) {
            continue;
        }
        let node = &nodes[n];
        let world = parent * local_transform(node);
        if let Some(mesh) = node.mesh {
            let count = counts.get_mut(mesh.value()).ok_or_else(|| {
                ReadError::new(format!(
                    "node {n} refers to mesh {}, but the file has {} meshes",
                    mesh.value(),
                    root.meshes.len()
                ))
            })?;
            let det = world.determinant();
            let mirrored = match instances.get(&n) {
                // The node draws only its instances, each at world x instance.
                Some(signs) if det > 0.0 => signs.negative,
                Some(signs) if det < 0.0 => signs.positive,
                Some(_) => 0,
                None => u32::from(det < 0.0),
            };
            *count = count.saturating_add(mirrored);
        }
        for child in node.children.iter().flatten() {
            let c = check(child.value(), &|| format!("node {n}"))?;
            if !visited[c] {
                stack.push((c, world));
            }
        }
    }
    Ok(counts)
}

/// A node's local transform: its matrix, or translation x rotation x scale.
fn local_transform(node: &json::Node) -> DMat4 {
    if let Some(m) = node.matrix {
        return DMat4::from_cols_array(&m.map(f64::from));
    }
    let v = |a: [f32; 3]| DVec3::new(a[0].into(), a[1].into(), a[2].into());
    let translation = node.translation.map_or(DVec3::ZERO, v);
    let scale = node.scale.map_or(DVec3::ONE, v);
    let rotation = node.rotation.map_or(DQuat::IDENTITY, |q| {
        let q = DQuat::from_xyzw(q.0[0].into(), q.0[1].into(), q.0[2].into(), q.0[3].into());
        // A rotation that is not a unit quaternion is repaired for the sign test; a zero or
        // non-finite one is treated as no rotation.
        let length = q.length();
        if length.is_finite() && length > 0.0 {
            q / length
        } else {
            DQuat::IDENTITY
        }
    });
    DMat4::from_scale_rotation_translation(scale, rotation, translation)
}
