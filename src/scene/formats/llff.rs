//! LLFF: `poses_bounds.npy` beside an `images/` folder.

use crate::error::{Error, Result};
use crate::scene::Scene;
use std::path::Path;

/// Read an LLFF scene folder.
pub fn read(dir: &Path) -> Result<Scene> {
    Err(Error::format(dir, "LLFF reading is not built yet"))
}
