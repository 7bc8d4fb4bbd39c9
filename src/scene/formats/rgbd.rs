//! RGB-D captures in the Redwood/Open3D layout: `camera_*.json` intrinsics, `trajectory.log`
//! camera-to-world poses, `rgbd.match` pairing depth and colour images.

use crate::error::{Error, Result};
use crate::scene::Scene;
use std::path::Path;

/// Read a Redwood RGB-D folder.
pub fn read_redwood(dir: &Path) -> Result<Scene> {
    Err(Error::format(dir, "RGB-D reading is not built yet"))
}
