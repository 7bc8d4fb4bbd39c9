//! The model file (`.objf`): a versioned JSON header followed by raw little-endian arrays.
//!
//! Layout:
//! ```text
//! 8 bytes   magic "OBJNFLD\n"
//! u64 LE    header length H
//! H bytes   header, UTF-8 JSON (see `Header`): format version, field layout (box, voxel, dims,
//!           channels, SH degree, activations), the object's world transform, the training
//!           settings and step, and the list of arrays that follow (name, dtype, length, SHA-256)
//! arrays    in the header's order, each `length` values of its dtype, little-endian:
//!           "grid"      f32, dims[0]*dims[1]*dims[2]*channels, x-fastest, channels per vertex
//!                       [raw density, SH red (K), SH green (K), SH blue (K)]
//!           "occupancy" u64, one bit per cell, x-fastest
//!           "adam_m", "adam_v" f32 (optional; present for resuming training)
//! ```
//! Every array is checked against its length and hash, and the file must end where the last
//! array ends, so a truncated or corrupted file is an error that says what is wrong.

use super::model::{sh_coeffs, Field, FieldConfig};
use super::train::TrainConfig;
use crate::error::{Error, Result};
use glam::Vec3;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::Path;

pub const MAGIC: &[u8; 8] = b"OBJNFLD\n";
pub const VERSION: u32 = 1;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ArrayInfo {
    pub name: String,
    pub dtype: String,
    pub len: u64,
    pub sha256: String,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Header {
    pub format: String,
    pub version: u32,
    pub config: FieldConfig,
    pub box_min: [f32; 3],
    pub box_max: [f32; 3],
    pub voxel: f32,
    pub dims: [usize; 3],
    pub channels: usize,
    /// Dims of the finest coarse-to-fine stage (training resumes towards it).
    pub final_dims: [usize; 3],
    /// Object-to-world transform (row-major 4x4): where the object sits in its scene.
    pub world_transform: [[f64; 4]; 4],
    pub train: Option<TrainConfig>,
    pub step: usize,
    pub adam_t: u32,
    /// Free-form notes from training (setup report, timings).
    #[serde(default)]
    pub notes: serde_json::Value,
    pub arrays: Vec<ArrayInfo>,
}

/// Everything a model file holds.
#[derive(Clone, Debug)]
pub struct Model {
    pub field: Field,
    pub final_dims: [usize; 3],
    pub world_transform: [[f64; 4]; 4],
    pub train: Option<TrainConfig>,
    pub step: usize,
    /// Adam m, v and step count, if saved.
    pub adam: Option<(Vec<f32>, Vec<f32>, u32)>,
    pub notes: serde_json::Value,
}

pub const IDENTITY: [[f64; 4]; 4] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn u64_bytes(v: &[u64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn hex(d: &[u8]) -> String {
    d.iter().map(|b| format!("{b:02x}")).collect()
}

pub fn save(path: &Path, m: &Model) -> Result<()> {
    let f = &m.field;
    let mut blobs: Vec<(&str, &str, u64, Vec<u8>)> = vec![
        (
            "grid",
            "f32",
            f.grid.data.len() as u64,
            f32_bytes(&f.grid.data),
        ),
        (
            "occupancy",
            "u64",
            f.occupancy.len() as u64,
            u64_bytes(&f.occupancy),
        ),
    ];
    if let Some((am, av, _)) = &m.adam {
        blobs.push(("adam_m", "f32", am.len() as u64, f32_bytes(am)));
        blobs.push(("adam_v", "f32", av.len() as u64, f32_bytes(av)));
    }
    let header = Header {
        format: "objnerf-field".into(),
        version: VERSION,
        config: f.config.clone(),
        box_min: f.box_min.to_array(),
        box_max: f.box_max.to_array(),
        voxel: f.voxel,
        dims: f.grid.dims,
        channels: f.grid.channels,
        final_dims: m.final_dims,
        world_transform: m.world_transform,
        train: m.train.clone(),
        step: m.step,
        adam_t: m.adam.as_ref().map(|a| a.2).unwrap_or(0),
        notes: m.notes.clone(),
        arrays: blobs
            .iter()
            .map(|(n, t, l, b)| ArrayInfo {
                name: n.to_string(),
                dtype: t.to_string(),
                len: *l,
                sha256: hex(&Sha256::digest(b)),
            })
            .collect(),
    };
    let json = serde_json::to_vec_pretty(&header)
        .map_err(|e| Error::invalid(format!("cannot serialise the model header: {e}")))?;
    crate::util::write_atomic(path, |w| {
        w.write_all(MAGIC)?;
        w.write_all(&(json.len() as u64).to_le_bytes())?;
        w.write_all(&json)?;
        for (_, _, _, b) in &blobs {
            w.write_all(b)?;
        }
        Ok(())
    })
}

pub fn load(path: &Path) -> Result<Model> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(path, &bytes)
}

/// Parse a model file's bytes (`path` names it in errors).
pub fn parse(path: &Path, bytes: &[u8]) -> Result<Model> {
    let bad = |msg: String| Error::format(path, msg);
    if bytes.len() < 16 || &bytes[..8] != MAGIC {
        return Err(bad(
            "not an objnerf field model (bad magic; expected a file written by `objnerf train`)"
                .into(),
        ));
    }
    let hlen = u64::from_le_bytes(bytes[8..16].try_into().expect("8 bytes")) as usize;
    let hend = 16usize
        .checked_add(hlen)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| {
            bad(format!(
                "truncated: the header says it is {hlen} bytes but the file has {} after the magic",
                bytes.len() - 16
            ))
        })?;
    let h: Header = serde_json::from_slice(&bytes[16..hend])
        .map_err(|e| bad(format!("corrupt header: {e}")))?;
    if h.format != "objnerf-field" {
        return Err(bad(format!(
            "header format is '{}', not objnerf-field",
            h.format
        )));
    }
    if h.version > VERSION {
        return Err(bad(format!(
            "model format version {} is newer than this objnerf reads ({VERSION})",
            h.version
        )));
    }
    if h.config.sh_degree > 2 || h.channels != 1 + 3 * sh_coeffs(h.config.sh_degree) {
        return Err(bad(format!(
            "inconsistent header: {} channels for SH degree {}",
            h.channels, h.config.sh_degree
        )));
    }
    if h.dims.iter().any(|&d| d < 2) || h.voxel.is_nan() || h.voxel <= 0.0 {
        return Err(bad(format!(
            "inconsistent header: dims {:?}, voxel {}",
            h.dims, h.voxel
        )));
    }
    let nv: usize = h.dims.iter().product();
    let ncells: usize = h.dims.iter().map(|d| d - 1).product();
    let mut pos = hend;
    let mut arrays: std::collections::HashMap<String, &[u8]> = Default::default();
    for a in &h.arrays {
        let size = match a.dtype.as_str() {
            "f32" => 4,
            "u64" => 8,
            t => return Err(bad(format!("array '{}' has unknown dtype '{t}'", a.name))),
        };
        let n = (a.len as usize)
            .checked_mul(size)
            .filter(|&n| pos + n <= bytes.len())
            .ok_or_else(|| {
                bad(format!(
                    "truncated: array '{}' needs {} bytes but only {} remain",
                    a.name,
                    a.len.saturating_mul(size as u64),
                    bytes.len() - pos
                ))
            })?;
        let data = &bytes[pos..pos + n];
        if hex(&Sha256::digest(data)) != a.sha256 {
            return Err(bad(format!(
                "corrupt: array '{}' fails its SHA-256 check",
                a.name
            )));
        }
        arrays.insert(a.name.clone(), data);
        pos += n;
    }
    if pos != bytes.len() {
        return Err(bad(format!(
            "{} unexpected bytes after the last array",
            bytes.len() - pos
        )));
    }
    let f32s = |name: &str, want: usize| -> Result<Option<Vec<f32>>> {
        let Some(b) = arrays.get(name) else {
            return Ok(None);
        };
        if b.len() != want * 4 {
            return Err(bad(format!(
                "array '{name}' holds {} values, the dims need {want}",
                b.len() / 4
            )));
        }
        Ok(Some(
            b.chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect(),
        ))
    };
    let grid = f32s("grid", nv * h.channels)?.ok_or_else(|| bad("no 'grid' array".into()))?;
    let occ_b = arrays
        .get("occupancy")
        .ok_or_else(|| bad("no 'occupancy' array".into()))?;
    if occ_b.len() != ncells.div_ceil(64) * 8 {
        return Err(bad("array 'occupancy' does not match the dims".into()));
    }
    let occupancy: Vec<u64> = occ_b
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect();
    let adam = match (
        f32s("adam_m", nv * h.channels)?,
        f32s("adam_v", nv * h.channels)?,
    ) {
        (Some(m), Some(v)) => Some((m, v, h.adam_t)),
        _ => None,
    };
    let mut field = Field::new(
        h.config.clone(),
        Vec3::from_array(h.box_min),
        Vec3::from_array(h.box_max),
        h.dims,
    );
    field.voxel = h.voxel;
    field.grid.data = grid;
    field.occupancy = occupancy;
    field.rebuild_blocks();
    Ok(Model {
        field,
        final_dims: h.final_dims,
        world_transform: h.world_transform,
        train: h.train,
        step: h.step,
        adam,
        notes: h.notes,
    })
}
