//! The worlds a camera path's matrices can be in (the dataset's, nerfstudio's viewer's), the name
//! a file states for its world, and nerfstudio's `dataparser_transforms.json` that maps one to the
//! other.

use crate::error::{Error, Result};
use crate::scene::formats::json::read_json_file;
use crate::util::write_atomic;
use glam::{DMat3, DMat4, DVec3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which world a path's matrices are in.
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // one per file read or written: a box would only add noise
pub enum PathFrame {
    /// The dataset's own world (its transforms.json's, our scene's).
    Data,
    /// The world of nerfstudio's viewer and `ns-render`: the dataparser's output.
    Viewer(DataparserTransform),
}

/// The key of a camera_path.json that names its world: [`FrameName::as_str`].
pub const FRAME_KEY: &str = "objnerf_frame";

/// A world's name, as [`FRAME_KEY`] holds it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameName {
    Data,
    Viewer,
}

impl FrameName {
    pub fn as_str(self) -> &'static str {
        match self {
            FrameName::Data => "data",
            FrameName::Viewer => "viewer",
        }
    }

    /// The world a file states, None when it states none.
    pub(super) fn stated(
        v: Option<&serde_json::Value>,
    ) -> std::result::Result<Option<Self>, String> {
        match v.map(|v| (v, v.as_str())) {
            None => Ok(None),
            Some((_, Some("data"))) => Ok(Some(FrameName::Data)),
            Some((_, Some("viewer"))) => Ok(Some(FrameName::Viewer)),
            Some((v, _)) => Err(format!(
                "{FRAME_KEY} is {v}, a frame objnerf does not know (\"data\": the dataset's world, \"viewer\": nerfstudio's)"
            )),
        }
    }
}

impl PathFrame {
    pub fn name(&self) -> FrameName {
        match self {
            PathFrame::Data => FrameName::Data,
            PathFrame::Viewer(_) => FrameName::Viewer,
        }
    }
}

/// nerfstudio's `dataparser_transforms.json` (written into every training run's folder), plus the
/// dataset's `applied_transform`: nerfstudio's `transform` starts from the coordinates before that
/// was applied, our scene is in those after it.
#[derive(Clone, Debug, PartialEq)]
pub struct DataparserTransform {
    /// 3x4 row-major, rigid.
    pub transform: [[f64; 4]; 3],
    pub scale: f64,
    pub applied_transform: Option<[[f64; 4]; 3]>,
}

/// Tolerance on "a rotation times a scale" for the world transforms nerfstudio writes (float32).
const SIMILARITY_TOL: f64 = 1e-5;

/// A 3x4 row-major transform as a 4x4 matrix, checked to be a similarity (s R, t) with s > 0.
fn similarity(m: &[[f64; 4]; 3], what: &str) -> std::result::Result<DMat4, String> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err(format!("{what} has a non-finite entry"));
    }
    let col = |j: usize| DVec3::new(m[0][j], m[1][j], m[2][j]);
    let lin = DMat3::from_cols(col(0), col(1), col(2));
    let s = lin.determinant().cbrt();
    let rot = lin * (1.0 / s);
    let err = (rot.transpose() * rot - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |a, v| a.max(v.abs()));
    if !(s > 0.0 && err < SIMILARITY_TOL) {
        return Err(format!(
            "{what} is not a rotation with a uniform scale (det = {:.6}, |R^T R - I| = {err:.2e})",
            lin.determinant()
        ));
    }
    Ok(DMat4::from_cols(
        col(0).extend(0.0),
        col(1).extend(0.0),
        col(2).extend(0.0),
        col(3).extend(1.0),
    ))
}

#[derive(Serialize, Deserialize)]
struct DataparserFile {
    transform: Vec<Vec<f64>>,
    scale: f64,
}

impl DataparserTransform {
    /// Read `dataparser_transforms.json`; `applied_transform` is the dataset's (its scene's).
    pub fn read(path: &Path, applied_transform: Option<[[f64; 4]; 3]>) -> Result<Self> {
        let file: DataparserFile = read_json_file(path)?;
        let bad = |m: String| Error::format(path, m);
        if file.transform.len() < 3 || file.transform.iter().take(3).any(|r| r.len() != 4) {
            return Err(bad("'transform' must be 3x4 (or 4x4)".into()));
        }
        let transform = [0, 1, 2].map(|r| {
            let row = &file.transform[r];
            [row[0], row[1], row[2], row[3]]
        });
        let t = DataparserTransform {
            transform,
            scale: file.scale,
            applied_transform,
        };
        t.data_to_viewer().map_err(bad)?;
        Ok(t)
    }

    /// Write it as nerfstudio does (`applied_transform` belongs to the dataset, not this file).
    pub fn write(&self, path: &Path) -> Result<()> {
        let file = DataparserFile {
            transform: self.transform.iter().map(|r| r.to_vec()).collect(),
            scale: self.scale,
        };
        let json = serde_json::to_string_pretty(&file).map_err(|e| Error::json(path, e))?;
        write_atomic(path, |w| w.write_all(json.as_bytes()))
    }

    /// The map from the data world to the viewer's: `scale * T * applied^-1`, a similarity.
    pub fn data_to_viewer(&self) -> std::result::Result<DMat4, String> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(format!("scale is {}, not a positive number", self.scale));
        }
        let t = similarity(&self.transform, "transform")?;
        let undo_applied = match &self.applied_transform {
            Some(a) => similarity(a, "the dataset's applied_transform")?.inverse(),
            None => DMat4::IDENTITY,
        };
        Ok(DMat4::from_scale(DVec3::splat(self.scale)) * t * undo_applied)
    }
}
