//! Files that appear whole or not at all: every report (CSV, JSON Lines, JUnit, HTML, merged CSV),
//! every repaired copy and the cache's compacted pack are written to a temporary file beside their
//! target, synced to the disk and renamed over it when complete. A crash, a full disk, a power cut
//! or an error half-way leaves the previous file untouched or the whole new one, and no temporary
//! file behind (dropping an uncommitted [`AtomicFile`] removes it).
//!
//! A target that is not a regular file or a folder (`/dev/null`, `/dev/stdout`, a named pipe, a
//! socket) is written in place instead: a rename would put a regular file where the device or
//! pipe was (for root, `--csv /dev/null` would replace the system's `/dev/null`), and such a
//! target has no old contents to keep.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A file being written under a temporary name; [`AtomicFile::commit`] puts it in place.
pub struct AtomicFile {
    writer: Option<BufWriter<File>>,
    /// `None`: the target is a device, a pipe or a socket, written in place.
    temporary: Option<PathBuf>,
    path: PathBuf,
    /// [`AtomicFile::prepare`] flushed everything to the disk.
    synced: bool,
}

impl AtomicFile {
    /// Starts writing `path` (its folder must exist; a folder at `path` is refused now, not when
    /// the finished file would be renamed over it).
    pub fn create(path: &Path) -> io::Result<AtomicFile> {
        let meta = std::fs::metadata(path);
        if meta.as_ref().is_ok_and(|m| m.is_dir()) {
            return Err(io::Error::new(
                io::ErrorKind::IsADirectory,
                "it is a folder, not a file",
            ));
        }
        let special = meta.is_ok_and(|m| !m.is_file());
        let (file, temporary) = if special {
            (std::fs::OpenOptions::new().write(true).open(path)?, None)
        } else {
            let temporary = temporary_name(path);
            (File::create(&temporary)?, Some(temporary))
        };
        Ok(AtomicFile {
            writer: Some(BufWriter::new(file)),
            temporary,
            path: path.to_owned(),
            synced: false,
        })
    }

    /// Flushes the data to the disk, so that [`AtomicFile::commit`] has only the rename left:
    /// files put in place together ([`crate::report::Output::prepare`]) are all written before
    /// any of them replaces its target.
    pub fn prepare(&mut self) -> io::Result<()> {
        let in_place = self.temporary.is_none();
        let writer = self.writer()?;
        writer.flush()?;
        if !in_place {
            writer.get_ref().sync_all()?;
        }
        self.synced = true;
        Ok(())
    }

    /// Flushes the data to the disk (unless [`AtomicFile::prepare`] did) and renames the
    /// temporary file over the target, so even a power cut leaves the old file or the whole new
    /// one (a device or a pipe: flushes into it).
    pub fn commit(mut self) -> io::Result<()> {
        let writer = self.writer.take().expect("commit is called once");
        let file = writer.into_inner().map_err(|e| e.into_error())?;
        let Some(temporary) = &self.temporary else {
            return Ok(());
        };
        if !self.synced {
            file.sync_all()?;
        }
        drop(file);
        std::fs::rename(temporary, &self.path)
        // On error, `drop` removes the temporary file.
    }

    fn writer(&mut self) -> io::Result<&mut BufWriter<File>> {
        self.writer
            .as_mut()
            .ok_or_else(|| io::Error::other("the file is already committed"))
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer()?.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer()?.flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        self.writer = None;
        // After a successful rename the temporary name no longer exists; the error is ignored.
        if let Some(temporary) = &self.temporary {
            let _ = std::fs::remove_file(temporary);
        }
    }
}

/// `dir/.name.PID.N.tmp` beside `path`, so the final rename stays on one file system. `N` keeps
/// temporary names distinct between threads of one process (the cache writes from every worker).
fn temporary_name(path: &Path) -> PathBuf {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map_or_else(|| "report".into(), |n| n.to_string_lossy());
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}.{}.{n}.tmp", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder holding `r.txt` = "old", and an atomic file over it with `text` written.
    fn over_old(text: &[u8]) -> (tempfile::TempDir, PathBuf, AtomicFile) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.txt");
        std::fs::write(&path, "old").unwrap();
        let mut file = AtomicFile::create(&path).unwrap();
        file.write_all(text).unwrap();
        (dir, path, file)
    }

    #[test]
    fn committed_files_replace_the_old_one_and_leave_no_temporary() {
        let (dir, path, file) = over_old(b"new");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old", "not yet");
        file.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// A named pipe stays a pipe and gets the bytes (as `/dev/null` or `/dev/stdout` would: a
    /// rename put a regular file in their place, for root even over the system's `/dev/null`).
    #[cfg(unix)]
    #[test]
    fn a_pipe_is_written_in_place_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let pipe = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&pipe).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("no mkfifo here: skipped");
            return;
        }
        let reader = {
            let pipe = pipe.clone();
            std::thread::spawn(move || std::fs::read(pipe))
        };
        let mut file = AtomicFile::create(&pipe).unwrap();
        file.write_all(b"path,faces\n").unwrap();
        file.commit().unwrap();
        assert!(std::fs::metadata(&pipe).unwrap().file_type().is_fifo());
        assert_eq!(reader.join().unwrap().unwrap(), b"path,faces\n");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// A folder named as the target is refused when the file is started, before a scan's work,
    /// and stays as it was.
    #[test]
    fn a_folder_is_refused_at_once() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("reports");
        std::fs::create_dir(&folder).unwrap();
        let e = AtomicFile::create(&folder)
            .err()
            .expect("a folder is refused");
        assert_eq!(e.kind(), io::ErrorKind::IsADirectory);
        assert!(folder.is_dir());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// Prepared, the file is on the disk under its temporary name and the target unchanged; the
    /// commit then only renames.
    #[test]
    fn prepared_files_replace_the_target_only_when_committed() {
        let (dir, path, mut file) = over_old(b"new");
        file.prepare().unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        let temporary = file.temporary.clone().unwrap();
        assert_eq!(std::fs::read_to_string(&temporary).unwrap(), "new");
        file.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn dropped_files_leave_the_old_one() {
        let (dir, path, file) = over_old(b"half");
        drop(file);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
