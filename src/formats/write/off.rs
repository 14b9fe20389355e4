//! Repaired OFF: the same header keyword (`COFF`, `NOFF`, `STOFF`, ...), every vertex's extra
//! values (normals, colours, texture coordinates) kept and duplicated for copies, every face's
//! colour kept (a hole fill takes its neighbour's). With `N` in the keyword, vertex normals that
//! disagree with a flipped face are negated. Comments are not kept.

use std::fmt::Write as _;
use std::path::Path;

use super::{
    normal_sums, number, polygon_corner, renumber, write_atomic, Item, Job, Polygons, WriteError,
    Written,
};
use crate::formats::off::{read_full, Detail};
use crate::mesh::Mesh;
use crate::repair::Plan;

/// Writes the copy.
pub fn write(job: Job<'_>) -> Result<Written, WriteError> {
    let (mesh, detail) = read_full(job.source, job.cx)?;
    job.unchanged(std::slice::from_ref(&mesh))?;
    copy(&mesh, &detail, job.single()?, job.out)?;
    Ok(job.written(Vec::new(), Vec::new()))
}

fn copy(mesh: &Mesh, detail: &Detail, plan: &Plan, out: &Path) -> Result<(), WriteError> {
    let polygons = Polygons::new(
        detail.faces.len(),
        |f, out| out.extend_from_slice(&detail.faces[f]),
        mesh,
    )?;
    let items = polygons.items(plan, mesh);
    let (index, kept) = renumber(plan);
    // `[ST][C][N][4]OFF`: normals come right after x y z (after w in 4OFF, which is rare).
    let prefix = detail.keyword.to_ascii_uppercase();
    let prefix = &prefix[..prefix.find("OFF").unwrap_or(0)];
    let has_normals = prefix.contains('N') && !prefix.contains('4');
    let sums = if has_normals {
        normal_sums(plan, mesh, |c| Some(c.vertex))
    } else {
        Default::default()
    };

    let mut text = String::new();
    let _ = writeln!(
        text,
        "{}",
        detail.keyword.get(..prefix.len() + 3).unwrap_or("OFF")
    );
    let _ = writeln!(text, "{kept} {} 0", items.len());
    for (v, &used) in plan.used_vertices.iter().enumerate() {
        if !used {
            continue;
        }
        let p = plan.position(mesh, v as u32);
        let from = super::original(plan, mesh, v as u32) as usize;
        let _ = write!(text, "{} {} {}", number(p[0]), number(p[1]), number(p[2]));
        let extra = detail.vertex_extra.get(from).map_or("", String::as_str);
        let mut words: Vec<String> = extra.split_ascii_whitespace().map(str::to_owned).collect();
        if let Some(sum) = sums.get(&(v as u32)) {
            let n: Option<Vec<f64>> = words.iter().take(3).map(|w| w.parse().ok()).collect();
            if let Some(n) = n.filter(|n| n.len() == 3) {
                if crate::geometry::dot([n[0], n[1], n[2]], *sum) < 0.0 {
                    for (w, x) in words.iter_mut().zip(n) {
                        *w = number(-x);
                    }
                }
            }
        }
        for w in &words {
            let _ = write!(text, " {w}");
        }
        text.push('\n');
    }
    for item in &items {
        let (vertices, face): (Vec<u32>, usize) = match *item {
            Item::Polygon { face, reversed } => {
                let poly = &detail.faces[face];
                let n = poly.len();
                (
                    (0..n)
                        .map(|k| poly[polygon_corner(n, k, reversed)])
                        .collect(),
                    face,
                )
            }
            Item::Triangle(i) => {
                let t = &plan.triangles[i];
                (t.corners.iter().map(|c| c.vertex).collect(), polygons.of(t))
            }
        };
        let _ = write!(text, "{}", vertices.len());
        for v in vertices {
            let _ = write!(text, " {}", index[v as usize]);
        }
        match detail.face_extra.get(face) {
            Some(extra) if !extra.is_empty() => {
                let _ = writeln!(text, " {extra}");
            }
            _ => text.push('\n'),
        }
    }
    write_atomic(out, text.as_bytes())
}
