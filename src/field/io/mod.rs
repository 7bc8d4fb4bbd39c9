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
//!           "bricks"    u64 per allocated brick: its position x | y << 21 | z << 42, in
//!                       (z, y, x) order (bricks of 4^3 vertices, `field::grid`)
//!           "grid"      f32, bricks * 64 vertices * channels: per brick the 64 vertices' raw
//!                       densities (x-fastest), then each vertex's other channels [SH red (K),
//!                       SH green (K), SH blue (K)] or features in turn (version 5; versions 3
//!                       and 4 kept every channel of a vertex together, and load converted)
//!           "occupancy" u64 per brick, one bit per cell whose base vertex is in the brick
//!           "colour_net" f32, the colour network's weights (version 4, when the header's
//!                       `colour_net` gives its shape; the grid's channels are then [raw
//!                       density, features]): W1 (inputs x hidden), b1, W2 (3 x hidden), b2
//!           "adam_m", "adam_v" f32 like "grid" (optional; present for resuming training)
//! Versions 1 and 2 stored a dense grid (x-fastest over dims) and one occupancy bit per cell.
//! ```
//! Every array is checked against its length and hash, and the file must end where the last
//! array ends, so a truncated or corrupted file is an error that says what is wrong.

use super::colour_net::{ColourNet, MAX_HIDDEN, MAX_INPUTS};
use super::grid::{from_interleaved, put_vertex, Grid, BRICK_VERTICES};
use super::model::{Field, FieldConfig};
use super::sh::sh_coeffs;
use super::train::{TrainConfig, Trainer};
use crate::error::{Error, Result};
use crate::space::Space;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::path::Path;

mod arrays;
pub use arrays::ArrayInfo;
use arrays::{read_arrays, Arrays, Blob};

pub const MAGIC: &[u8; 8] = b"OBJNFLD\n";
/// 5: a brick's densities apart from its other channels (`field::grid`'s layout).
/// 4: an optional colour network (the header's `colour_net`, its weights in "colour_net").
/// 3: sparse bricks ("bricks": the allocated bricks' positions; "grid", "occupancy" and the
/// optimiser state per brick). 2: a dense grid with the field's [`Space`] in the header. 1: a
/// dense box-space grid. Versions 1 and 2 still load (as a grid with every brick allocated).
pub const VERSION: u32 = 5;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Header {
    pub format: String,
    pub version: u32,
    pub config: FieldConfig,
    /// Where the grid lives (absent in version 1: a box in world coordinates).
    #[serde(default)]
    pub space: Space,
    pub box_min: [f32; 3],
    pub box_max: [f32; 3],
    pub voxel: f32,
    pub dims: [usize; 3],
    pub channels: usize,
    /// The colour network's shape (version 4; absent: SH colour), its weights in the
    /// "colour_net" array.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour_net: Option<NetShape>,
    /// Dims of the finest coarse-to-fine stage (training resumes towards it).
    pub final_dims: [usize; 3],
    /// Object-to-world transform (row-major 4x4): where the object sits in its scene.
    pub world_transform: [[f64; 4]; 4],
    pub train: Option<TrainConfig>,
    pub step: usize,
    pub adam_t: u32,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub net_adam_t: u32,
    /// Free-form notes from training (setup report, timings).
    #[serde(default)]
    pub notes: serde_json::Value,
    pub arrays: Vec<ArrayInfo>,
}

fn is_zero<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

/// A colour network's shape ([`ColourNet`]).
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct NetShape {
    pub features: usize,
    pub dir_terms: usize,
    /// Terms of the reflected direction's basis; 0 (and absent, in files before it): none.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub refl_terms: usize,
    pub hidden: usize,
    /// Units of the second hidden layer; 0 (and absent, in files before it): none.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub hidden2: usize,
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
    /// The colour network's Adam m, v and step count, if it has one and they were saved.
    pub net_adam: Option<(Vec<f32>, Vec<f32>, u32)>,
    pub notes: serde_json::Value,
}

pub const IDENTITY: [[f64; 4]; 4] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// What a model file is written from, borrowed: training writes its trainer's grid and
/// optimiser state without copying them (for fox's 1 GiB grid a copy doubled the peak memory).
pub struct ModelParts<'a> {
    pub field: &'a Field,
    pub final_dims: [usize; 3],
    pub world_transform: [[f64; 4]; 4],
    pub train: Option<&'a TrainConfig>,
    pub step: usize,
    pub adam: Option<(Moments<'a>, Moments<'a>, u32)>,
    pub net_adam: Option<(&'a [f32], &'a [f32], u32)>,
    pub notes: serde_json::Value,
}

/// Adam's m or v as the trainer keeps them (bfloat16) or as a loaded model holds them (f32);
/// the file stores f32 either way.
#[derive(Clone, Copy)]
pub enum Moments<'a> {
    F32(&'a [f32]),
    Bf16(&'a [u16]),
}

impl<'a> Moments<'a> {
    fn blob(self) -> Blob<'a> {
        match self {
            Moments::F32(v) => Blob::F32(v),
            Moments::Bf16(v) => Blob::F32FromBf16(v),
        }
    }
}

impl Model {
    pub fn parts(&self) -> ModelParts<'_> {
        ModelParts {
            field: &self.field,
            final_dims: self.final_dims,
            world_transform: self.world_transform,
            train: self.train.as_ref(),
            step: self.step,
            adam: self
                .adam
                .as_ref()
                .map(|(m, v, t)| (Moments::F32(m), Moments::F32(v), *t)),
            net_adam: self.net_adam.as_ref().map(|(m, v, t)| (&m[..], &v[..], *t)),
            notes: self.notes.clone(),
        }
    }
}

impl Model {
    /// The downscale the model was trained at (1 if it does not say).
    pub fn downscale(&self) -> u32 {
        self.notes
            .get("downscale")
            .and_then(|v| v.as_u64())
            .map(|v| v.max(1) as u32)
            .unwrap_or(1)
    }

    /// Whether this is a field of a scene (notes `"kind": "scene"`) rather than of one object.
    pub fn is_scene_field(&self) -> bool {
        self.notes.get("kind").and_then(|k| k.as_str()) == Some("scene")
    }

    /// The capture's up direction recorded at training ([`crate::Scene::up`]), if any.
    pub fn up(&self) -> Option<glam::DVec3> {
        let v = self.notes.get("up")?.as_array()?;
        let xyz: Vec<f64> = v.iter().filter_map(|x| x.as_f64()).collect();
        (xyz.len() == 3).then(|| glam::DVec3::new(xyz[0], xyz[1], xyz[2]))
    }
}

impl Trainer {
    /// Continue from a saved model: its grid, step and (if saved) optimiser state. The saved
    /// training settings win over `cfg` except for the step count, so a resumed run follows the
    /// same schedule.
    pub fn from_model(m: Model, cfg: TrainConfig) -> Trainer {
        let mut c = m.train.clone().unwrap_or(cfg.clone());
        c.steps = c.steps.max(cfg.steps);
        let mut t = Trainer::new(m.field, m.final_dims, c);
        t.step = m.step;
        if let Some((am, av, at)) = m.adam {
            t.set_adam_state(am, av, at);
        }
        if let Some((nm, nv, nt)) = m.net_adam {
            t.set_net_adam_state(nm, nv, nt);
        }
        t
    }

    /// What a model file holds for this trainer (with optimiser state, so it can resume),
    /// borrowed: saving copies nothing.
    pub fn parts(&self, world: [[f64; 4]; 4], notes: serde_json::Value) -> ModelParts<'_> {
        ModelParts {
            field: &self.field,
            final_dims: self.final_dims,
            world_transform: world,
            train: Some(&self.cfg),
            step: self.step,
            adam: Some({
                let (m, v, t) = self.adam_state();
                (Moments::Bf16(m), Moments::Bf16(v), t)
            }),
            net_adam: self.net_adam_state(),
            notes,
        }
    }
}

pub fn save(path: &Path, m: &ModelParts) -> Result<()> {
    let f = m.field;
    let bricks: Vec<u64> = f.grid.brick_list().iter().map(|&b| pack_brick(b)).collect();
    let mut blobs: Vec<(&str, Blob)> = vec![
        ("bricks", Blob::U64(&bricks)),
        ("grid", Blob::F32(&f.grid.data)),
        ("occupancy", Blob::U64(&f.occupancy)),
    ];
    if let Some(net) = &f.net {
        blobs.push(("colour_net", Blob::F32(&net.weights)));
    }
    if let Some((am, av, _)) = m.adam {
        blobs.push(("adam_m", am.blob()));
        blobs.push(("adam_v", av.blob()));
    }
    if let Some((nm, nv, _)) = m.net_adam {
        blobs.push(("adam_net_m", Blob::F32(nm)));
        blobs.push(("adam_net_v", Blob::F32(nv)));
    }
    let header = Header {
        format: "objnerf-field".into(),
        version: VERSION,
        config: f.config.clone(),
        space: f.space.clone(),
        box_min: f.box_min.to_array(),
        box_max: f.box_max.to_array(),
        voxel: f.voxel,
        dims: f.grid.dims,
        channels: f.grid.channels,
        colour_net: f.net.as_ref().map(|n| NetShape {
            features: n.features,
            dir_terms: n.dir_terms,
            refl_terms: n.refl_terms,
            hidden: n.hidden,
            hidden2: n.hidden2,
        }),
        final_dims: m.final_dims,
        world_transform: m.world_transform,
        train: m.train.cloned(),
        step: m.step,
        adam_t: m.adam.map(|a| a.2).unwrap_or(0),
        net_adam_t: m.net_adam.map(|a| a.2).unwrap_or(0),
        notes: m.notes.clone(),
        arrays: blobs
            .iter()
            .map(|(n, b)| ArrayInfo {
                name: n.to_string(),
                dtype: b.dtype().to_string(),
                len: b.len() as u64,
                sha256: b.sha256(),
            })
            .collect(),
    };
    let json = serde_json::to_vec_pretty(&header)
        .map_err(|e| Error::invalid(format!("cannot serialise the model header: {e}")))?;
    crate::util::write_atomic(path, |w| {
        w.write_all(MAGIC)?;
        w.write_all(&(json.len() as u64).to_le_bytes())?;
        w.write_all(&json)?;
        for (_, b) in &blobs {
            b.for_each_chunk(|c| w.write_all(c))?;
        }
        Ok(())
    })
}

/// Load a model with its optimiser state (to resume training).
pub fn load(path: &Path) -> Result<Model> {
    read(path, true)
}

/// Load a model without its optimiser state (two thirds of the file): for rendering, meshing
/// and evaluation. The arrays it skips are not checked.
pub fn load_field(path: &Path) -> Result<Model> {
    read(path, false)
}

/// Read a model file as a stream: the arrays go straight into their typed vectors, so the
/// file's bytes are never held whole.
fn read(path: &Path, with_adam: bool) -> Result<Model> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let total = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let r = std::io::BufReader::with_capacity(1 << 20, file);
    read_from(path, r, total, with_adam)
}

/// A model from a stream of `total` bytes, as [`load`] (`with_adam`) or [`load_field`] read it
/// from a file; `path` names the file in errors.
pub fn read_from<R: std::io::Read + std::io::Seek>(
    path: &Path,
    mut r: R,
    total: u64,
    with_adam: bool,
) -> Result<Model> {
    let (h, start) = read_header(path, &mut r, total)?;
    let mut arrays = read_arrays(path, &mut r, &h.arrays, start, total, with_adam)?;
    let bad = |msg: String| Error::format(path, msg);
    let (field, adam) = if h.version >= 3 {
        bricked_field(&h, &mut arrays, with_adam).map_err(bad)?
    } else {
        dense_field(&h, &mut arrays).map_err(bad)?
    };
    let net_len = field.net.as_ref().map_or(0, |n| n.weights.len());
    let net_adam = match (
        arrays.f32s.remove("adam_net_m"),
        arrays.f32s.remove("adam_net_v"),
    ) {
        (Some(m), Some(v)) if m.len() == net_len && v.len() == net_len => {
            Some((m, v, h.net_adam_t))
        }
        (None, None) => None,
        _ => {
            return Err(bad(
                "the colour network's optimiser state does not match it".into(),
            ))
        }
    };
    Ok(Model {
        field,
        final_dims: h.final_dims,
        world_transform: h.world_transform,
        train: h.train,
        step: h.step,
        adam: adam.map(|(m, v)| (m, v, h.adam_t)),
        net_adam,
        notes: h.notes,
    })
}

/// A brick position packed into one u64 (21 bits per axis).
fn pack_brick(b: [u32; 3]) -> u64 {
    b[0] as u64 | (b[1] as u64) << 21 | (b[2] as u64) << 42
}

fn unpack_brick(v: u64) -> [u32; 3] {
    [0, 21, 42].map(|s| ((v >> s) & 0x1f_ffff) as u32)
}

/// The optimiser's m and v, as saved.
type AdamArrays = Option<(Vec<f32>, Vec<f32>)>;

/// A version 3 to 5 file's field: bricks, their values and occupancy words.
fn bricked_field(
    h: &Header,
    arrays: &mut Arrays,
    with_adam: bool,
) -> std::result::Result<(Field, AdamArrays), String> {
    let bricks: Vec<[u32; 3]> = arrays
        .u64s
        .remove("bricks")
        .ok_or("no 'bricks' array")?
        .into_iter()
        .map(unpack_brick)
        .collect();
    let values = bricks.len() * BRICK_VERTICES * h.channels;
    let mut f32s = |name: &str| -> std::result::Result<Option<Vec<f32>>, String> {
        match arrays.f32s.remove(name) {
            Some(v) if v.len() != values => Err(format!(
                "array '{name}' holds {} values, {} bricks need {values}",
                v.len(),
                bricks.len()
            )),
            v => Ok(v),
        }
    };
    let mut data = f32s("grid")?.ok_or("no 'grid' array")?;
    let mut adam = match (f32s("adam_m")?, f32s("adam_v")?) {
        (Some(m), Some(v)) if with_adam => Some((m, v)),
        _ => None,
    };
    if h.version < 5 {
        from_interleaved(&mut data, h.channels);
        if let Some((m, v)) = adam.as_mut() {
            from_interleaved(m, h.channels);
            from_interleaved(v, h.channels);
        }
    }
    let occupancy = arrays
        .u64s
        .remove("occupancy")
        .ok_or("no 'occupancy' array")?;
    if occupancy.len() != bricks.len() {
        return Err("array 'occupancy' does not match the bricks".into());
    }
    let mut field = empty_field(h);
    let fill = vec![0.0; h.channels];
    field.grid = Grid::from_parts(h.dims, h.channels, &fill, bricks, data)?;
    field.set_occupancy_words(occupancy);
    if let Some(n) = h.colour_net {
        let weights = arrays
            .f32s
            .remove("colour_net")
            .ok_or("no 'colour_net' array for the header's colour network")?;
        let inputs = n.features + n.dir_terms + n.refl_terms;
        let want = ColourNet::weight_count(inputs, n.hidden, n.hidden2);
        if weights.len() != want {
            return Err(format!(
                "array 'colour_net' holds {} values, the network {n:?} needs {want}",
                weights.len()
            ));
        }
        field.net = Some(ColourNet {
            features: n.features,
            dir_terms: n.dir_terms,
            refl_terms: n.refl_terms,
            hidden: n.hidden,
            hidden2: n.hidden2,
            weights,
        });
    }
    Ok((field, adam))
}

/// A version 1 or 2 file's field: a dense grid and one occupancy bit per cell, loaded with every
/// brick allocated (its optimiser state, laid out densely, is not carried over).
fn dense_field(
    h: &Header,
    arrays: &mut Arrays,
) -> std::result::Result<(Field, AdamArrays), String> {
    let nv: usize = h.dims.iter().product();
    let ncells: usize = h.dims.iter().map(|d| d - 1).product();
    let dense = arrays.f32s.remove("grid").ok_or("no 'grid' array")?;
    if dense.len() != nv * h.channels {
        return Err(format!(
            "array 'grid' holds {} values, the dims need {}",
            dense.len(),
            nv * h.channels
        ));
    }
    let bits = arrays
        .u64s
        .remove("occupancy")
        .ok_or("no 'occupancy' array")?;
    if bits.len() != ncells.div_ceil(64) {
        return Err("array 'occupancy' does not match the dims".into());
    }
    let mut field = empty_field(h);
    field.grid = Grid::new(h.dims, h.channels, &vec![0.0; h.channels]);
    let [nx, ny, nz] = h.dims;
    let ch = h.channels;
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let v = field.grid.vertex_slot(x, y, z) as usize;
                let src = (x + nx * (y + ny * z)) * ch;
                put_vertex(&mut field.grid.data, v, &dense[src..src + ch]);
            }
        }
    }
    field.fill_occupancy(false);
    for z in 0..nz - 1 {
        for y in 0..ny - 1 {
            for x in 0..nx - 1 {
                let c = x + (nx - 1) * (y + (ny - 1) * z);
                if bits[c >> 6] >> (c & 63) & 1 == 1 {
                    field.set_occupied([x, y, z], true);
                }
            }
        }
    }
    Ok((field, None))
}

/// The header's field with no brick allocated (its grid and occupancy are filled in after).
fn empty_field(h: &Header) -> Field {
    Field {
        config: h.config.clone(),
        space: h.space.clone(),
        box_min: Vec3::from_array(h.box_min),
        box_max: Vec3::from_array(h.box_max),
        voxel: h.voxel,
        grid: Grid::with_bricks(h.dims, h.channels, &vec![0.0; h.channels], |_| false),
        occupancy: Vec::new(),
        live: Default::default(),
        net: None,
    }
}

/// The magic, the header length and the header, checked for consistency; returns the header
/// and the offset where the arrays start.
fn read_header(path: &Path, r: &mut impl std::io::Read, total: u64) -> Result<(Header, u64)> {
    let bad = |msg: String| Error::format(path, msg);
    let mut start = [0u8; 16];
    if total < 16 || r.read_exact(&mut start).is_err() || &start[..8] != MAGIC {
        return Err(bad(
            "not an objnerf field model (bad magic; expected a file written by `objnerf train`)"
                .into(),
        ));
    }
    let hlen = u64::from_le_bytes(start[8..16].try_into().expect("8 bytes"));
    if hlen > total - 16 {
        return Err(bad(format!(
            "truncated: the header says it is {hlen} bytes but the file has {} after the magic",
            total - 16
        )));
    }
    let mut hbytes = vec![0u8; hlen as usize];
    r.read_exact(&mut hbytes).map_err(|e| Error::io(path, e))?;
    let h: Header =
        serde_json::from_slice(&hbytes).map_err(|e| bad(format!("corrupt header: {e}")))?;
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
    let colour_channels = match h.colour_net {
        Some(n) => n.features,
        None => 3 * sh_coeffs(h.config.sh_degree),
    };
    // SH colour stops at degree 2; a network's view input goes to 3.
    let most_degree = if h.colour_net.is_some() { 3 } else { 2 };
    if h.config.sh_degree > most_degree || h.channels != 1 + colour_channels {
        return Err(bad(format!(
            "inconsistent header: {} channels for SH degree {} and colour network {:?}",
            h.channels, h.config.sh_degree, h.colour_net
        )));
    }
    if let Some(n) = h.colour_net {
        if n.dir_terms != sh_coeffs(h.config.sh_degree)
            || (n.refl_terms != 0 && n.refl_terms != n.dir_terms)
            || n.features + n.dir_terms + n.refl_terms > MAX_INPUTS
            || n.hidden == 0
            || n.hidden > MAX_HIDDEN
            || n.hidden2 > MAX_HIDDEN
        {
            return Err(bad(format!(
                "inconsistent header: colour network {n:?} for SH degree {}",
                h.config.sh_degree
            )));
        }
    }
    // The brick index is dense over the box: bound the box so a corrupt header cannot ask for
    // an absurd allocation (2^32 vertices: a 1600^3 grid).
    let box_vertices = h
        .dims
        .iter()
        .try_fold(1u64, |a, &d| a.checked_mul(d as u64));
    if h.dims.iter().any(|&d| d < 2)
        || box_vertices.is_none_or(|n| n > 1 << 32)
        || !h.voxel.is_finite()
        || h.voxel <= 0.0
    {
        return Err(bad(format!(
            "inconsistent header: dims {:?}, voxel {}",
            h.dims, h.voxel
        )));
    }
    if (0..3).any(|i| !(h.box_min[i].is_finite() && h.box_max[i].is_finite()))
        || (0..3).any(|i| h.box_max[i] <= h.box_min[i])
    {
        return Err(bad(format!(
            "inconsistent header: box {:?} to {:?} is not a finite, non-empty box",
            h.box_min, h.box_max
        )));
    }
    Ok((h, 16 + hlen))
}
