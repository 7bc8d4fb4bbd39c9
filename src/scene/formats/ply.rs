//! PLY point clouds (positions and colours), read and written.

use crate::error::{Error, Result};
use glam::DVec3;
use std::path::Path;

/// Write points with colours as a binary little-endian PLY.
pub fn write_points(path: &Path, points: &[(DVec3, [u8; 3])]) -> Result<()> {
    crate::util::write_atomic(path, |w| {
        writeln!(
            w,
            "ply\nformat binary_little_endian 1.0\nelement vertex {}",
            points.len()
        )?;
        writeln!(w, "property float x\nproperty float y\nproperty float z")?;
        writeln!(
            w,
            "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header"
        )?;
        for (p, c) in points {
            for v in p.to_array() {
                w.write_all(&(v as f32).to_le_bytes())?;
            }
            w.write_all(c)?;
        }
        Ok(())
    })
}

/// Read the vertices (x, y, z and, if present, red, green, blue) of a PLY file.
pub fn read_points(path: &Path) -> Result<Vec<(DVec3, [u8; 3])>> {
    Err(Error::format(path, "PLY reading is not built yet"))
}
