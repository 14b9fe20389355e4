//! Names in the folder a repaired copy finally goes to, for the files it brings beside it (a glTF's
//! buffers and images, an OBJ's material libraries and textures).
//!
//! A scan makes copies in parallel, each in a staging folder of its own, and moves each into place
//! once it is checked ([`crate::copies`]). Two copies in one folder may each bring a different file
//! under one name (`models/a.gltf` names `../lod0/mesh.bin`, `models/b.gltf` names
//! `../lod1/mesh.bin`): whichever moved last would replace the other's, and the other copy would
//! silently read the wrong bytes. So every such name is claimed here first, under one lock for the
//! whole process. A name is given to some bytes when the final folder has no file of that name or
//! one with exactly these bytes, and no copy being made has claimed it for other bytes (a hash of
//! the bytes is compared; two claims of the same bytes share the name, so a library many copies
//! bring is there once). Otherwise a writer that can rename takes the first free of `stem-1.ext`,
//! `stem-2.ext`, ... ([`Claims::side`]). A claim lasts until its copy is in place or has failed.
//! A copy's own path is claimed too, so no side file takes it and no two copies are put at one
//! path in one run. A side file in place that a copy names is remembered: another copy's path never
//! replaces it, and a copy whose move fails removes only side files no other copy needs.
//!
//! The lock covers this process: another program writing into the folder at the same time is
//! caught when the files are moved, which never replaces a different file.

use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use rustc_hash::FxHashMap;

use super::WriteError;

/// The longest file name most file systems take, in bytes.
const MAX_NAME: usize = 255;

/// How many numbered names [`Claims::side`] tries.
const NUMBERED: u32 = 999;

/// What a claimed path holds.
struct Held {
    /// The hash of the bytes it is claimed for; `None` for a copy's own path, which is never
    /// shared.
    digest: Option<blake3::Hash>,
    /// Claims alive: copies being written or checked that put this file there.
    holders: usize,
    /// A side file that a copy in place names.
    in_use: bool,
}

/// Every path claimed in this process, by its final place.
static CLAIMED: Mutex<Option<FxHashMap<PathBuf, Held>>> = Mutex::new(None);

fn claimed() -> MutexGuard<'static, Option<FxHashMap<PathBuf, Held>>> {
    // Nothing panics while the lock is held; a poisoned map is still consistent.
    CLAIMED.lock().unwrap_or_else(|e| e.into_inner())
}

/// Why a side file cannot have a name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// The final folder has a different file (or a folder) of that name.
    OnDisk,
    /// Another copy being made claimed the name for other bytes, or it is a copy's own path.
    Claimed,
}

/// The names one copy has claimed in its final folder; dropping it ends the claims.
pub struct Claims {
    /// The folder the copy finally goes to: side-file names are relative to it.
    folder: PathBuf,
    /// Final paths claimed (side files; the copy's own path, if claimed, too).
    held: RefCell<Vec<PathBuf>>,
}

impl Claims {
    /// Claims for a copy whose final folder is `folder` (its staging folder stands for it).
    pub fn new(folder: &Path) -> Claims {
        Claims {
            folder: folder.to_path_buf(),
            held: RefCell::new(Vec::new()),
        }
    }

    /// The final folder.
    pub fn folder(&self) -> &Path {
        &self.folder
    }

    /// Claims `path`, the copy's own final place: refused when another copy being made claimed
    /// it, or a side file a copy names is there.
    pub fn copy(&self, path: &Path) -> Result<(), WriteError> {
        let mut map = claimed();
        let map = map.get_or_insert_with(FxHashMap::default);
        if let Some(held) = map.get(path) {
            if held.holders > 0 || held.in_use {
                return Err(WriteError::new(format!(
                    "{} is also the place of another file's repaired copy, or of a file such a \
                     copy brings, in this scan: repair these files into separate folders",
                    path.display()
                )));
            }
        }
        map.insert(
            path.to_path_buf(),
            Held {
                digest: None,
                holders: 1,
                in_use: false,
            },
        );
        self.held.borrow_mut().push(path.to_path_buf());
        Ok(())
    }

    /// A name for a side file holding `bytes` that the writer wants at `wanted` (relative to the
    /// final folder): `wanted` when it is free for these bytes, else, when `numbered`, the first
    /// free of `stem-1.ext`, `stem-2.ext`, ... in the same folder. The name returned is claimed
    /// until `self` is dropped.
    pub fn side(&self, wanted: &Path, bytes: &[u8], numbered: bool) -> Result<PathBuf, Refused> {
        let digest = blake3::hash(bytes);
        let exact = self.take(&self.folder.join(wanted), digest, bytes);
        if exact.is_ok() || !numbered {
            return exact.map(|()| wanted.to_path_buf());
        }
        let file = wanted
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let (stem, ext) = match file.rsplit_once('.') {
            Some((s, e)) if !s.is_empty() => (s.to_owned(), format!(".{e}")),
            _ => (file.clone(), String::new()),
        };
        // Bounded: a folder that cannot be looked into refuses every name.
        let mut why = exact;
        for n in 1..=NUMBERED {
            let name = wanted.with_file_name(format!("{stem}-{n}{ext}"));
            why = self.take(&self.folder.join(&name), digest, bytes);
            if why.is_ok() {
                return Ok(name);
            }
        }
        why.map(|()| wanted.to_path_buf())
    }

    /// The error of a side file `file` that [`Claims::side`] found no name for.
    pub fn no_free_name(&self, file: &str) -> WriteError {
        // A name (with room for `-N`) longer than file systems take is no name at all.
        if file.len() + 4 > MAX_NAME {
            return WriteError::new(format!(
                "{file} is too long a name for a file beside the copy (file systems take \
                 {MAX_NAME} bytes) - give the source a shorter name"
            ));
        }
        WriteError::new(format!(
            "no free name for {file} in {}: that name and its numbered variants are taken by \
             other files (or the folder cannot be read) - repair into an empty folder",
            self.folder.display()
        ))
    }

    /// Whether `path` (a final place) is claimed by these claims.
    pub fn holds(&self, path: &Path) -> bool {
        self.held.borrow().iter().any(|p| p == path)
    }

    /// Claims the final place `path` for `bytes`, exactly.
    pub fn exact(&self, path: &Path, bytes: &[u8]) -> Result<(), Refused> {
        self.take(path, blake3::hash(bytes), bytes)
    }

    fn take(&self, path: &Path, digest: blake3::Hash, bytes: &[u8]) -> Result<(), Refused> {
        let mut map = claimed();
        let map = map.get_or_insert_with(FxHashMap::default);
        match map.get(path) {
            // Claimed by copies being made: only for the same bytes (never a copy's own path).
            Some(held) if held.holders > 0 && held.digest != Some(digest) => {
                return Err(Refused::Claimed)
            }
            // Claimed by these claims for these bytes already (a file the document names twice).
            Some(_) if self.holds(path) => return Ok(()),
            _ => {}
        }
        // What is on disk: nothing, or these very bytes (checked under the lock, so no other copy
        // of this process is moving a file there meanwhile without having claimed it).
        let mut absent = false;
        match std::fs::symlink_metadata(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => absent = true,
            Ok(m) if m.is_file() && m.len() == bytes.len() as u64 => {
                if crate::formats::read_regular(path).ok().as_deref() != Some(bytes) {
                    return Err(Refused::OnDisk);
                }
            }
            _ => return Err(Refused::OnDisk),
        }
        let held = map.entry(path.to_path_buf()).or_insert(Held {
            digest: Some(digest),
            holders: 0,
            in_use: false,
        });
        held.digest = Some(digest);
        held.holders += 1;
        // Nothing there: no copy in place names it (it was removed since).
        held.in_use &= !absent;
        self.held.borrow_mut().push(path.to_path_buf());
        Ok(())
    }

    /// The copy is in place: the side files it claimed are named by it from now on.
    pub fn committed(&self) {
        let mut map = claimed();
        let map = map.get_or_insert_with(FxHashMap::default);
        for path in self.held.borrow().iter() {
            if let Some(held) = map.get_mut(path) {
                if held.digest.is_some() {
                    held.in_use = true;
                }
            }
        }
    }

    /// Removes the side file this copy moved to `path` again (its copy could not be put in
    /// place), unless another copy claims or names it too.
    pub fn undo(&self, path: &Path) {
        let map = claimed();
        let alone = map
            .as_ref()
            .and_then(|m| m.get(path))
            .is_none_or(|held| held.holders <= 1 && !held.in_use);
        if alone {
            let _ = std::fs::remove_file(path);
        }
    }
}

impl Drop for Claims {
    fn drop(&mut self) {
        let mut map = claimed();
        let Some(map) = map.as_mut() else { return };
        for path in self.held.get_mut().drain(..) {
            if let Some(held) = map.get_mut(&path) {
                held.holders = held.holders.saturating_sub(1);
                if held.holders == 0 && !held.in_use {
                    map.remove(&path);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Threads claiming one name for different bytes at the same moment each get a name of their
    /// own; those claiming it for the same bytes share it; a name held by a file of other bytes is
    /// never given; and names are free again once their claims end with nothing written.
    #[test]
    fn concurrent_claims_never_share_a_name_for_different_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("models");
        std::fs::create_dir_all(&folder).unwrap();
        std::fs::write(folder.join("old.bin"), b"left by an earlier run").unwrap();
        // Eight threads: contents 0..4, each twice.
        let barrier = std::sync::Barrier::new(8);
        let names: Vec<(u8, PathBuf, Claims)> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..8u8)
                .map(|i| {
                    let (barrier, folder) = (&barrier, &folder);
                    s.spawn(move || {
                        let claims = Claims::new(folder);
                        let bytes = [i % 4; 16];
                        barrier.wait();
                        let name = claims.side(Path::new("mesh.bin"), &bytes, true).unwrap();
                        (i % 4, name, claims)
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let mut by_content: FxHashMap<u8, PathBuf> = FxHashMap::default();
        for (content, name, _) in &names {
            let first = by_content.entry(*content).or_insert_with(|| name.clone());
            assert_eq!(first, name, "one content, one name");
        }
        let mut distinct: Vec<&PathBuf> = by_content.values().collect();
        distinct.sort();
        // Four contents: `mesh.bin` and three numbered names, in whatever order they came.
        assert_eq!(
            distinct,
            ["mesh-1.bin", "mesh-2.bin", "mesh-3.bin", "mesh.bin"]
                .map(Path::new)
                .iter()
                .collect::<Vec<_>>()
        );
        // A file on disk: other bytes do not get its name, its own bytes share it.
        let claims = Claims::new(&folder);
        assert_eq!(
            claims.side(Path::new("old.bin"), b"other", false),
            Err(Refused::OnDisk)
        );
        assert_eq!(
            claims.side(Path::new("old.bin"), b"other", true),
            Ok(PathBuf::from("old-1.bin"))
        );
        assert_eq!(
            claims.side(Path::new("old.bin"), b"left by an earlier run", false),
            Ok(PathBuf::from("old.bin"))
        );
        // Claimed now (nothing on disk yet): other bytes do not get it either.
        assert_eq!(
            Claims::new(&folder).side(Path::new("old-1.bin"), b"third", false),
            Err(Refused::Claimed)
        );
        // A copy's own path is no side file's, and not another copy's.
        claims.copy(&folder.join("a.gltf")).unwrap();
        assert_eq!(
            Claims::new(&folder).side(Path::new("a.gltf"), b"x", false),
            Err(Refused::Claimed)
        );
        assert!(Claims::new(&folder).copy(&folder.join("a.gltf")).is_err());
        drop(claims);
        drop(names);
        // Nothing was written: every name is free again.
        let claims = Claims::new(&folder);
        assert_eq!(
            claims.side(Path::new("mesh.bin"), b"new", true),
            Ok(PathBuf::from("mesh.bin"))
        );
        claims.copy(&folder.join("a.gltf")).unwrap();
    }

    /// A side file a copy in place names is not removed by another copy's undo; once it is gone
    /// from the folder and claimed again, the new claim's undo removes what it put there.
    #[test]
    fn undo_removes_only_side_files_no_copy_in_place_names() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lib.mtl");
        let first = Claims::new(dir.path());
        assert_eq!(
            first.side(Path::new("lib.mtl"), b"one", false),
            Ok(PathBuf::from("lib.mtl"))
        );
        std::fs::write(&path, b"one").unwrap();
        first.committed();
        drop(first);
        let second = Claims::new(dir.path());
        assert!(second.side(Path::new("lib.mtl"), b"one", false).is_ok());
        second.undo(&path);
        assert!(path.is_file(), "a copy in place names it");
        drop(second);
        std::fs::remove_file(&path).unwrap();
        let third = Claims::new(dir.path());
        assert!(third.side(Path::new("lib.mtl"), b"two", false).is_ok());
        std::fs::write(&path, b"two").unwrap();
        third.undo(&path);
        assert!(!path.exists(), "only this claim put it there");
    }
}
