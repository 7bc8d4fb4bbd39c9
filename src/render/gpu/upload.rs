//! The composite's fields as the shader reads them (`march.wgsl`): every field's brick values,
//! fill and network weights in one `f32` buffer, its brick index, occupancy and live-brick bits
//! in one `u32` buffer, and per layer a record of scalars (the `Layer` struct of the shader,
//! written word by word in its order) that says where its parts lie and how to march it.

use super::super::composite::{Composite, Layer};
use crate::error::{Error, Result};
use crate::field::march::NET_MIN_WEIGHT;
use crate::field::RenderOptions;
use crate::space::Space;
use glam::Vec3;

/// The most layers one pass draws (the shader's per-layer state is a fixed array).
pub const MAX_LAYERS: usize = 16;

/// Words of one `Layer` record.
pub const LAYER_WORDS: usize = 56;

/// The fields' data, uploaded once per composite.
pub struct Packed {
    pub vals: Vec<f32>,
    pub words: Vec<u32>,
    /// Per layer: the record without the camera (its first 3 words are the camera centre in
    /// the layer's frame, filled per frame by [`layer_records`]).
    pub records: Vec<[u32; LAYER_WORDS]>,
}

/// Why a composite cannot be drawn by the GPU renderer, if it cannot.
pub fn unsupported(c: &Composite) -> Option<String> {
    if c.layers.len() > MAX_LAYERS {
        return Some(format!(
            "{} fields in one frame; the GPU renderer draws at most {MAX_LAYERS}",
            c.layers.len()
        ));
    }
    c.layers.iter().find_map(|l| match l.field.space {
        Space::Box => None,
        ref s => Some(format!(
            "a field in {} space; the GPU renderer draws box fields only",
            s.name()
        )),
    })
}

/// Pack every layer of `c`.
pub fn pack(c: &Composite) -> Result<Packed> {
    if let Some(why) = unsupported(c) {
        return Err(Error::invalid(why));
    }
    let mut p = Packed {
        vals: Vec::new(),
        words: Vec::new(),
        records: Vec::new(),
    };
    for l in &c.layers {
        let rec = pack_layer(&mut p, l, &c.render);
        p.records.push(rec);
    }
    Ok(p)
}

/// 64-bit words as pairs of 32-bit words, low half first (bit i stays bit i).
fn push_u64s(words: &mut Vec<u32>, src: &[u64]) -> u32 {
    let off = words.len() as u32;
    for w in src {
        words.push(*w as u32);
        words.push((*w >> 32) as u32);
    }
    off
}

fn pack_layer(p: &mut Packed, l: &Layer, opt: &RenderOptions) -> [u32; LAYER_WORDS] {
    let f = l.field;
    let g = &f.grid;
    let data_off = p.vals.len() as u32;
    p.vals.extend_from_slice(&g.data);
    let fill_off = p.vals.len() as u32;
    p.vals.extend_from_slice(g.fill());
    let net_off = p.vals.len() as u32;
    if let Some(net) = &f.net {
        p.vals.extend_from_slice(&net.weights);
    }
    let index_off = p.words.len() as u32;
    p.words.extend_from_slice(g.brick_index());
    let occ_off = push_u64s(&mut p.words, f.occupancy_words());
    let (bricks, blocks, block_dims) = f.live_bricks().words();
    let live_off = push_u64s(&mut p.words, bricks);
    let block_off = push_u64s(&mut p.words, blocks);
    // As Marcher::new and Marcher::line compute them.
    let delta = opt.step * f.voxel / f.config.base_voxel;
    let shift = f.shift();
    let raw_min = f.raw_for_alpha(opt.alpha_thresh, delta) + f.shift() - 1e-3;
    let step_w = opt.step * f.voxel;
    let (to_world, scaled) = if l.scale != 1.0 {
        (1.0 / l.scale, 1)
    } else {
        (1.0, 0)
    };
    let (recolour, rc) = match &l.recolour {
        None => (0u32, [0.0f32; 3]),
        Some(r) => match r.parts() {
            (Some([a, b]), strength, _) => (1, [a, b, strength]),
            (None, _, [c, s]) => (2, [c, s, 0.0]),
        },
    };
    let (is_net, features, dir_terms, refl_terms, hidden, hidden2) = match &f.net {
        Some(n) => (
            1,
            n.features,
            n.dir_terms,
            n.refl_terms,
            n.hidden,
            n.hidden2,
        ),
        None => (0, 0, 0, 0, 0, 0),
    };
    let r = l.rot.to_cols_array();
    let fw = |v: f32| v.to_bits();
    let uw = |v: usize| v as u32;
    let words: Vec<u32> = [
        // The camera centre: per frame.
        vec![0, 0, 0],
        r.iter().map(|v| fw(*v)).collect(),
        vec![fw(to_world), scaled],
        [f.box_min, f.box_max]
            .iter()
            .flat_map(|v| v.to_array())
            .map(fw)
            .collect(),
        [
            f.voxel,
            step_w,
            delta,
            shift,
            raw_min,
            NET_MIN_WEIGHT * opt.step,
        ]
        .map(fw)
        .to_vec(),
        vec![uw(g.dims[0]), uw(g.dims[1]), uw(g.dims[2]), uw(g.channels)],
        g.brick_dims.map(uw).to_vec(),
        block_dims.map(uw).to_vec(),
        vec![
            data_off, fill_off, index_off, occ_off, live_off, block_off, net_off,
        ],
        vec![
            f.config.sh_degree,
            uw(f.sh_k()),
            is_net,
            uw(features),
            uw(dir_terms),
            uw(refl_terms),
            uw(hidden),
            uw(hidden2),
        ],
        vec![l.index as u32, recolour, fw(rc[0]), fw(rc[1]), fw(rc[2])],
    ]
    .concat();
    let mut rec = [0u32; LAYER_WORDS];
    rec.copy_from_slice(&words);
    rec
}

/// The records with the camera centre `o` (world) carried into each layer's frame, as
/// `composite::render_ray` carries it.
pub fn layer_records(c: &Composite, packed: &Packed, o: Vec3) -> Vec<u32> {
    let mut out = Vec::with_capacity(packed.records.len() * LAYER_WORDS);
    for (l, rec) in c.layers.iter().zip(&packed.records) {
        let ol = l.scale * (l.rot * o) + l.shift;
        let mut r = *rec;
        r[..3].copy_from_slice(&ol.to_array().map(f32::to_bits));
        out.extend_from_slice(&r);
    }
    out
}
