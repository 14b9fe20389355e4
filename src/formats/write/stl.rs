//! Repaired STL: binary stays binary (the 80-byte header kept, each surviving facet's attribute
//! word kept, 0 for hole fills), ASCII stays ASCII with its `solid` blocks and their names (a
//! facet in the block of the face it comes from, a fill in its neighbour's); which one a file
//! is, the reader decides ([`crate::formats::stl::layout`]: a padded binary file is binary, its
//! padding left out of the copy with a note). Facet normals are
//! recomputed from the final winding. STL stores no shared vertices, so copies and dropped
//! vertices need nothing.

use std::fmt::Write as _;
use std::path::Path;

use super::{write_atomic, Job, WriteError, Written};
use crate::formats::stl::{layout, parse_with_solids, Layout, Solid};
use crate::geometry::{dot, normal};
use crate::mesh::Mesh;
use crate::repair::Plan;

/// Writes the copy, with a note when the source's padding after its binary facets is left out.
pub fn write(job: Job<'_>) -> Result<Written, WriteError> {
    // Read as the reader reads it (its limits), as the PLY and glTF writers do.
    let bytes = crate::formats::read_bytes(job.source, &job.cx.limits)?;
    let (mesh, solids) = parse_with_solids(&bytes, job.cx)?;
    job.unchanged(std::slice::from_ref(&mesh))?;
    let notes = copy(&bytes, &mesh, &solids, job.single()?, job.out)?;
    Ok(job.written(Vec::new(), notes))
}

/// A facet of the copy: its normal, corners, attribute word and the input face whose block it
/// goes in.
type Facet = ([f32; 3], [[f64; 3]; 3], u16, u32);

/// The copy of the source `bytes`, read as `mesh` with these `solid` blocks (ASCII).
fn copy(
    bytes: &[u8],
    mesh: &Mesh,
    solids: &[Solid],
    plan: &Plan,
    out: &Path,
) -> Result<Vec<String>, WriteError> {
    // Binary exactly when the reader read it as binary (padded files too).
    let (binary, extra) = match layout(bytes)? {
        Layout::Binary { extra, .. } => (true, extra),
        Layout::Ascii | Layout::Empty => (false, 0),
    };
    let facets: Vec<Facet> = plan
        .triangles
        .iter()
        .map(|t| {
            // Binary stores f32: the normal is taken from the positions as they will be stored.
            let p = t.corners.map(|c| plan.position(mesh, c.vertex));
            let wide = if binary {
                p.map(|q| q.map(|x| x as f32 as f64))
            } else {
                p
            };
            let n = normal(wide[0], wide[1], wide[2]);
            let len = dot(n, n).sqrt();
            let n = if len > 0.0 && len.is_finite() {
                n.map(|x| (x / len) as f32)
            } else {
                [0.0; 3]
            };
            let attribute = match t.source {
                Some(s) if binary => {
                    let at = 84 + 50 * s as usize + 48;
                    u16::from_le_bytes([bytes[at], bytes[at + 1]])
                }
                _ => 0,
            };
            (n, p, attribute, t.near)
        })
        .collect();
    let data = if binary {
        let mut b = Vec::with_capacity(84 + 50 * facets.len());
        b.extend_from_slice(&bytes[..80]);
        b.extend_from_slice(&(facets.len() as u32).to_le_bytes());
        for (n, p, attribute, _) in &facets {
            let stored = p.iter().flatten().map(|&x| x as f32);
            for x in n.iter().copied().chain(stored) {
                b.extend_from_slice(&x.to_le_bytes());
            }
            b.extend_from_slice(&attribute.to_le_bytes());
        }
        b
    } else {
        let unnamed = [Solid {
            first_face: 0,
            name: String::new(),
        }];
        let solids = if solids.is_empty() {
            &unnamed[..]
        } else {
            solids
        };
        // The facets in block order, each block's in plan order.
        let block = |face: u32| solids.partition_point(|b| b.first_face <= face).max(1) - 1;
        let mut order: Vec<(usize, usize)> =
            (0..facets.len()).map(|i| (block(facets[i].3), i)).collect();
        order.sort_unstable();
        let mut next = order.iter().peekable();
        let mut s = String::with_capacity(250 * facets.len());
        for (k, Solid { name, .. }) in solids.iter().enumerate() {
            let _ = writeln!(s, "solid {name}");
            while let Some((_, i)) = next.next_if(|(b, _)| *b == k) {
                let (n, p, _, _) = &facets[*i];
                let _ = writeln!(s, "  facet normal {} {} {}", n[0], n[1], n[2]);
                s.push_str("    outer loop\n");
                for q in p {
                    let _ = writeln!(s, "      vertex {} {} {}", q[0], q[1], q[2]);
                }
                s.push_str("    endloop\n  endfacet\n");
            }
            let _ = writeln!(s, "endsolid {name}");
        }
        s.into_bytes()
    };
    write_atomic(out, &data)?;
    let mut notes = Vec::new();
    if extra > 0 {
        notes.push(format!(
            "the {extra} byte(s) after the source's binary facets (padding the reader ignored) are \
             not in the copy"
        ));
    }
    Ok(notes)
}
