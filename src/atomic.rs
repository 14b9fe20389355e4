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
            let (file, temporary) = create_temporary(path)?;
            (file, Some(temporary))
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

/// Opens one of meshvet's own files (a cache pack or lock, a repair folder's ledger) with
/// `options`, only if it is a regular file: a link at its name is not followed (it may lead
/// anywhere), a FIFO is not waited on, and what was opened is checked again (the name may have
/// been replaced since it was looked at). A missing file is created when `options` say so.
pub fn open_own(path: &Path, options: &mut std::fs::OpenOptions) -> io::Result<File> {
    let not_regular = || io::Error::other("not a regular file");
    if std::fs::symlink_metadata(path).is_ok_and(|m| !m.is_file()) {
        return Err(not_regular());
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK);
    }
    let file = options.open(path)?;
    if !file.metadata()?.is_file() {
        return Err(not_regular());
    }
    Ok(file)
}

/// The number of the next temporary name (see [`create_temporary`]).
static NEXT: AtomicU64 = AtomicU64::new(0);

/// The longest part of the target's name a temporary name repeats: the rest of the 255 bytes a
/// file name may have is left for the dot, the process id, the number and `.tmp`.
const NAME_IN_TEMPORARY: usize = 200;

/// Creates a new temporary file `dir/.name.PID.N.tmp` beside `path`, so the final rename stays on
/// one file system (`name` is the target's name, cut to its first [`NAME_IN_TEMPORARY`] bytes,
/// so that a target of any name the file system takes has one). `N` keeps temporary names
/// distinct between threads of one process (the cache writes from every worker). The file is
/// created only if nothing is at its name, not even a link: a link planted there would otherwise
/// be followed and the file it names overwritten, then renamed onto the target. A name that is
/// taken is passed over for the next `N`.
fn create_temporary(path: &Path) -> io::Result<(File, PathBuf)> {
    let name = path
        .file_name()
        .map_or_else(|| "report".into(), |n| n.to_string_lossy());
    let mut cut = name.len().min(NAME_IN_TEMPORARY);
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    let name = &name[..cut];
    let mut tries = 0;
    loop {
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let temporary = path.with_file_name(format!(".{name}.{}.{n}.tmp", std::process::id()));
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temporary)
        {
            Ok(file) => return Ok((file, temporary)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists && tries < 1000 => tries += 1,
            Err(e) => return Err(e),
        }
    }
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

    /// Links planted at the temporary names a run would take (the process id and the numbers
    /// are easy to guess) are passed over: the file a link names keeps its bytes, and the target
    /// becomes a regular file, not a link.
    #[cfg(unix)]
    #[test]
    fn a_link_at_a_temporary_name_is_never_followed() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, "mine").unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let next = NEXT.load(Ordering::Relaxed);
        for n in next..next + 64 {
            let link = out.join(format!(".r.csv.{}.{n}.tmp", std::process::id()));
            std::os::unix::fs::symlink(&victim, link).unwrap();
        }
        let target = out.join("r.csv");
        let mut file = AtomicFile::create(&target).unwrap();
        file.write_all(b"path\n").unwrap();
        file.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "mine");
        assert!(std::fs::symlink_metadata(&target).unwrap().is_file());
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "path\n");
    }

    /// A target whose name is as long as a file name may be gets a temporary name that fits.
    #[test]
    fn a_target_of_the_longest_name_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join(format!("{}.csv", "r".repeat(251)));
        let mut file = AtomicFile::create(&target).unwrap();
        file.write_all(b"path\n").unwrap();
        file.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "path\n");
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
