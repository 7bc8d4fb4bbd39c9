//! Opening and decoding the raster files of a scene, with errors that name the file.

use crate::error::{Error, Result};
use image::DynamicImage;
use std::path::Path;

/// A file opened for decoding, with an error naming it.
pub(super) fn open(path: &Path) -> Result<std::io::BufReader<std::fs::File>> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    Ok(std::io::BufReader::new(f))
}

/// An image decoded from `r`, its format from `path`'s extension (as `image::open` does), or
/// from its first bytes when the extension names none. `path` names the file in errors.
pub(super) fn decode_image<R: std::io::BufRead + std::io::Seek>(
    path: &Path,
    r: R,
) -> Result<DynamicImage> {
    let mut reader = image::ImageReader::new(r);
    match image::ImageFormat::from_path(path) {
        Ok(f) => reader.set_format(f),
        Err(_) => {
            reader = reader
                .with_guessed_format()
                .map_err(|e| Error::io(path, e))?
        }
    }
    reader.decode().map_err(|e| Error::image(path, e))
}
