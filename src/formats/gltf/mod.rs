//! glTF 2.0 / GLB reader.

use std::path::Path;

use super::{ReadContext, ReadError};
use crate::mesh::Mesh;

pub fn read(path: &Path, cx: &ReadContext) -> Result<Vec<Mesh>, ReadError> {
    let _ = (path, cx);
    Err(ReadError::new("not supported yet"))
}
