//! Outputs are written to a temporary name beside their destination and renamed into place,
//! so a failed or interrupted run never leaves a half-written file behind.

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Write `path` atomically: `fill` writes into a temporary file in the same directory, which is
/// then renamed over `path`. The parent directory is created if needed.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let mut tmp = temp_file_beside(path)?;
    {
        let mut w = std::io::BufWriter::new(tmp.as_file_mut());
        fill(&mut w).map_err(|e| Error::io(path, e))?;
        w.flush().map_err(|e| Error::io(path, e))?;
    }
    tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
    Ok(())
}

/// A temporary file in `path`'s directory (created if needed), to be filled and then persisted
/// over `path`: the rename is atomic because both are on the same filesystem.
pub fn temp_file_beside(path: &Path) -> Result<tempfile::NamedTempFile> {
    let dir = parent_dir(path);
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    tempfile::Builder::new()
        .prefix(".objnerf-")
        .suffix(".tmp")
        .tempfile_in(&dir)
        .map_err(|e| Error::io(&dir, e))
}

/// Write bytes atomically.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}

/// Save an image atomically; the format follows the extension of `path`.
pub fn save_image_atomic(path: &Path, img: &image::DynamicImage) -> Result<()> {
    let format = image::ImageFormat::from_path(path).map_err(|e| Error::image(path, e))?;
    let mut buf = std::io::Cursor::new(Vec::new());
    img.write_to(&mut buf, format)
        .map_err(|e| Error::image(path, e))?;
    write_bytes_atomic(path, buf.get_ref())
}

/// Temporary files are created 0600; installed models are meant to be shared (0644).
pub fn make_readable(path: &Path) -> Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o644))
            .map_err(|e| Error::io(path, e))?;
    }
    Ok(())
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A directory output built under a temporary name and renamed into place by [`AtomicDir::commit`].
/// Dropped without commit, the temporary directory is removed. While it lives it holds a lock
/// beside the destination ([`DirLock`]), so two runs into one folder cannot interleave: the
/// second is refused. A run that was killed leaves its temporary folder behind; the next run
/// into the same destination removes it.
pub struct AtomicDir {
    tmp: Option<tempfile::TempDir>,
    dest: PathBuf,
    _lock: DirLock,
}

impl AtomicDir {
    /// Start building `dest`. Fails if `dest` exists and is not an empty directory, unless
    /// `overwrite` is set, in which case it is replaced on commit; fails if another run is
    /// writing `dest`.
    pub fn new(dest: &Path, overwrite: bool) -> Result<Self> {
        if dest.exists() && !overwrite {
            let empty = std::fs::read_dir(dest)
                .map(|mut d| d.next().is_none())
                .unwrap_or(false);
            if !empty {
                return Err(Error::invalid(format!(
                    "{}: output directory exists and is not empty (pass --overwrite to replace it)",
                    dest.display()
                )));
            }
        }
        let parent = parent_dir(dest);
        std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        let lock = DirLock::acquire(dest)?;
        let prefix = partial_prefix(dest);
        remove_stale(&parent, &prefix);
        let tmp = tempfile::Builder::new()
            .prefix(&prefix)
            .tempdir_in(&parent)
            .map_err(|e| Error::io(&parent, e))?;
        Ok(AtomicDir {
            tmp: Some(tmp),
            dest: dest.to_path_buf(),
            _lock: lock,
        })
    }

    /// Where to write the contents until commit.
    pub fn path(&self) -> &Path {
        self.tmp
            .as_ref()
            .expect("AtomicDir used after commit")
            .path()
    }

    /// The final location.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Move the finished directory into place. An existing destination is first renamed aside
    /// (then deleted), so at no moment is there a half-deleted or half-written one: a kill
    /// leaves the old output, no output, or the new one.
    pub fn commit(mut self) -> Result<PathBuf> {
        let tmp = self.tmp.take().expect("AtomicDir committed twice").keep();
        let old = if self.dest.exists() {
            let aside = tmp.with_file_name(format!(
                "{}old",
                tmp.file_name().unwrap_or_default().to_string_lossy()
            ));
            std::fs::rename(&self.dest, &aside).map_err(|e| Error::io(&self.dest, e))?;
            Some(aside)
        } else {
            None
        };
        std::fs::rename(&tmp, &self.dest).map_err(|e| Error::io(&self.dest, e))?;
        if let Some(old) = old {
            std::fs::remove_dir_all(&old).map_err(|e| Error::io(&old, e))?;
        }
        Ok(self.dest.clone())
    }
}

/// The name temporary folders for `dest` start with: hidden, beside it, and recognisably its.
fn partial_prefix(dest: &Path) -> String {
    let name = dest
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    format!(".{name}.objnerf-partial-")
}

/// Remove what killed runs into the same destination left in `parent` (called with the lock
/// held, so nothing else is writing them). Failures are ignored: a leftover costs only space.
fn remove_stale(parent: &Path, prefix: &str) {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for e in entries.flatten() {
        if e.file_name().to_string_lossy().starts_with(prefix) {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

/// An exclusive lock on a destination: the file `.<name>.objnerf-lock` beside it, locked with
/// flock(2), the operating system's advisory lock (released by the kernel if the process dies, so a
/// killed run never blocks the next) and removed when dropped.
pub struct DirLock {
    /// Open for as long as the lock is held: closing it releases the lock.
    _file: std::fs::File,
    path: PathBuf,
}

impl DirLock {
    pub fn acquire(dest: &Path) -> Result<DirLock> {
        let name = dest
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let path = parent_dir(dest).join(format!(".{name}.objnerf-lock"));
        loop {
            let mut file = std::fs::OpenOptions::new()
                .create(true)
                .truncate(false)
                .read(true)
                .write(true)
                .open(&path)
                .map_err(|e| Error::io(&path, e))?;
            match try_lock(&file) {
                Ok(true) => {}
                Ok(false) => {
                    let mut holder = String::new();
                    let _ = std::io::Read::read_to_string(&mut file, &mut holder);
                    let holder = holder.trim();
                    return Err(Error::invalid(format!(
                        "{}: another objnerf run{} is writing this folder: wait for it to finish or choose another output (lock: {})",
                        dest.display(),
                        if holder.is_empty() {
                            String::new()
                        } else {
                            format!(" (pid {holder})")
                        },
                        path.display()
                    )));
                }
                Err(e) => return Err(Error::io(&path, e)),
            }
            // The previous holder removes the file before unlocking: if it did so between our
            // open and our lock, we hold a lock on a file nobody else can see; try again.
            if same_file(&file, &path) {
                let _ = file.set_len(0);
                let _ = write!(file, "{}", std::process::id());
                return Ok(DirLock { _file: file, path });
            }
        }
    }
}

/// flock(2) the whole file, exclusive, without waiting: Ok(false) when another holds it.
fn try_lock(file: &std::fs::File) -> std::io::Result<bool> {
    use std::os::unix::io::AsRawFd;
    // SAFETY: flock only reads the descriptor, which `file` keeps open for the call.
    if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    match e.raw_os_error() {
        Some(libc::EWOULDBLOCK) => Ok(false),
        _ => Err(e),
    }
}

fn same_file(file: &std::fs::File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.ino() == b.ino() && a.dev() == b.dev(),
        _ => false,
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        // Remove first, unlock second: closing the file (when `self.file` drops, right after)
        // releases the lock.
        let _ = std::fs::remove_file(&self.path);
    }
}
