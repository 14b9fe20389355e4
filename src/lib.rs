//! meshvet vets triangle meshes in bulk: it reads OBJ, glTF/GLB, STL, PLY, OFF and 3MF files, builds a
//! Corner Table for each mesh and reports its topology (holes, non-manifold edges and vertices,
//! orientation, shells, cavities, genus). The library never prints; the binary owns the terminal.

pub mod atomic;
pub mod baseline;
pub mod cache;
pub mod config;
pub mod copies;
pub mod corner_table;
#[doc = include_str!("definitions.md")]
pub mod definitions {}
pub mod formats;
pub mod geometry;
pub mod html;
pub mod json;
pub mod judge;
pub mod junit;
pub mod mesh;
pub mod pages;
pub mod picture;
pub mod repair;
pub mod report;
pub mod rules;
pub mod scan;
pub mod shard;
pub mod topology;
pub mod walk;
pub mod weld;

pub use corner_table::CornerTable;
pub use mesh::Mesh;
pub use topology::{analyse, Analysis, Component, Options, Role, Shell};

/// Runs `work`, turning a panic into its message: the one way meshvet keeps a panic in one file's
/// reader, analysis or repair from ending a scan (the caller makes it that file's row or note).
pub(crate) fn caught<T>(work: impl FnOnce() -> T) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)).map_err(|panic| {
        panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic without a message".to_owned())
    })
}
