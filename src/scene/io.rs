//! Reading the per-view rasters a scene refers to: colour images, masks and depth maps.

use crate::error::{Error, Result};
use std::path::Path;

/// A depth map in metres; 0 (or non-finite) means unknown.
#[derive(Clone, Debug)]
pub struct DepthMap {
    pub width: u32,
    pub height: u32,
    pub metres: Vec<f32>,
}

/// Read a depth image: a 16-bit PNG storing depth * `scale` (millimetres: scale = 1000, 0 =
/// unknown), or an EXR storing metres in its first channel.
pub fn read_depth(path: &Path, scale: f64) -> Result<DepthMap> {
    let _ = scale;
    Err(Error::format(path, "depth reading is not built yet"))
}

/// Read a colour image as 8-bit RGB.
pub fn read_rgb(path: &Path) -> Result<image::RgbImage> {
    let img = image::open(path).map_err(|e| Error::image(path, e))?;
    Ok(img.to_rgb8())
}
