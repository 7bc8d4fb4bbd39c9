//! nerfstudio `transforms.json` (and the NeRF-synthetic form), read and written.

use crate::error::{Error, Result};
use crate::scene::Scene;
use std::path::Path;

/// Read a nerfstudio or NeRF-synthetic transforms JSON file.
pub fn read(path: &Path) -> Result<Scene> {
    Err(Error::format(
        path,
        "transforms.json reading is not built yet",
    ))
}

/// Write `scene` as a nerfstudio transforms.json at `path` (image paths relative to its folder).
pub fn write(_scene: &Scene, path: &Path) -> Result<()> {
    Err(Error::format(
        path,
        "transforms.json writing is not built yet",
    ))
}
