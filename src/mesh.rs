//! The in-memory asset handed from a format reader to the analysis: positions, triangles and what the
//! reader noticed on the way. Attributes needed by repair (UVs, normals, materials) arrive with the
//! repair work; the topology only ever needs positions and triangles.

/// One [mesh](crate::definitions#meshes): a whole OBJ/STL/PLY/OFF file, or one glTF `mesh`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// The glTF mesh name (or `#INDEX`); `None` for single-mesh formats.
    pub name: Option<String>,
    /// Input vertex positions, unwelded, as the file stores them (glTF: in the mesh's local space).
    pub positions: Vec<[f64; 3]>,
    /// Triangles after polygon splitting; every index is `< positions.len()` (readers check this).
    pub triangles: Vec<[u32; 3]>,
    /// Things the reader left out or noticed that a user should hear about (skipped lines or points,
    /// a missing `.mtl`, non-UTF-8 bytes, ...). Not errors.
    pub notes: Vec<String>,
    /// glTF: how many nodes instance this mesh with a mirroring (negative-determinant) transform.
    pub mirrored_instances: u32,
}

impl Mesh {
    /// A mesh from positions and triangles (tests and generated meshes).
    pub fn new(positions: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Mesh {
        Mesh {
            positions,
            triangles,
            ..Mesh::default()
        }
    }
}
