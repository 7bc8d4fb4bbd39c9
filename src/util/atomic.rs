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
/// Dropped without commit, the temporary directory is removed.
pub struct AtomicDir {
    tmp: Option<tempfile::TempDir>,
    dest: PathBuf,
}

impl AtomicDir {
    /// Start building `dest`. Fails if `dest` exists and is not an empty directory, unless
    /// `overwrite` is set, in which case it is replaced on commit.
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
        let tmp = tempfile::Builder::new()
            .prefix(".objnerf-")
            .tempdir_in(&parent)
            .map_err(|e| Error::io(&parent, e))?;
        Ok(AtomicDir {
            tmp: Some(tmp),
            dest: dest.to_path_buf(),
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

    /// Move the finished directory into place.
    pub fn commit(mut self) -> Result<PathBuf> {
        let tmp = self.tmp.take().expect("AtomicDir committed twice").keep();
        if self.dest.exists() {
            std::fs::remove_dir_all(&self.dest).map_err(|e| Error::io(&self.dest, e))?;
        }
        std::fs::rename(&tmp, &self.dest).map_err(|e| Error::io(&self.dest, e))?;
        Ok(self.dest.clone())
    }
}
