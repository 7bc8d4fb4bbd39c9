//! The MobileSAM image encoder (TinyViT-5M at 1024 x 1024 with SAM's neck) as an ONNX graph:
//! input `image` 1x3x1024x1024 (normalised, padded), output `image_embeddings` 1x256x64x64.
//! Mirrors `mobile_sam/modeling/tiny_vit_sam.py` (mobilesam-mirror 1.0.0) layer by layer;
//! BatchNorms are folded into the convolutions before them, as the PyTorch exporter does.

use super::graph::{Attr, Conv, Dim, Graph};
use super::onnx_proto::{ModelProto, FLOAT};
use super::quant::linear_int8;
use super::torch::{StateDict, Tensor};
use crate::error::Result;

/// TinyViT-5M as MobileSAM configures it: channels, depths, heads and window sizes per stage.
const DIMS: [usize; 4] = [64, 128, 160, 320];
const DEPTHS: [usize; 4] = [2, 2, 6, 2];
const HEADS: [usize; 4] = [2, 4, 5, 10];
const WINDOWS: [usize; 4] = [7, 7, 14, 7];
/// Token grid side per stage (the last stage keeps 64: its patch merging has stride 1).
const RES: [usize; 4] = [256, 128, 64, 64];
const KEY_DIM: usize = 32;
const MLP_RATIO: usize = 4;
const MBCONV_EXPAND: usize = 4;
/// `nn.BatchNorm2d` and `nn.LayerNorm` defaults.
const BN_EPS: f32 = 1e-5;
/// The neck's convolutions: 1x1, and 3x3 keeping the size.
const PLAIN: Conv = Conv {
    stride: 1,
    pad: 0,
    groups: 1,
};
const SAME: Conv = Conv {
    stride: 1,
    pad: 1,
    groups: 1,
};
const LN_EPS: f32 = 1e-5;

/// Which encoder graph to write. The reference (all false) has the PyTorch exporter's operators
/// and is what `encoder.onnx` holds; the others trade exactness for speed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Variant {
    /// The attention and MLP Linear layers with int8 weights (one scale per output channel) and
    /// activations quantised per call ([`linear_int8`]).
    pub int8_linears: bool,
    /// Each attention's core (scores, bias, softmax, weighted sum over heads) as ONNX Runtime's
    /// `MultiHeadAttention`, with q, k and v from three Linear layers: no Split and no per-head
    /// Transposes between them.
    pub fused_attention: bool,
    /// The int8 Linear layers' weights stored as uint8 with zero point 128 ([`linear_int8`]).
    pub unsigned_weights: bool,
}

impl Variant {
    pub const FP32: Variant = Variant {
        int8_linears: false,
        fused_attention: false,
        unsigned_weights: false,
    };
    pub const INT8: Variant = Variant {
        int8_linears: true,
        fused_attention: true,
        unsigned_weights: true,
    };
}

pub fn build(sd: &StateDict) -> Result<ModelProto> {
    build_variant(sd, Variant::FP32)
}

pub fn build_variant(sd: &StateDict, variant: Variant) -> Result<ModelProto> {
    let mut g = Graph::new();
    let w = Weights {
        sd,
        prefix: "image_encoder.",
        variant,
    };
    let image = g.input("image", FLOAT, &[1, 3, 1024, 1024].map(Dim::Fixed));
    let out = g.scope("enc", |g| -> Result<String> {
        // Patch embedding: two stride-2 convolutions, 1024 -> 256.
        let x = g.scope("patch_embed", |g| -> Result<String> {
            let x = conv_bn(g, &w, &image, "patch_embed.seq.0", 3, DIMS[0] / 2, 3, 2, 1)?;
            let x = g.gelu(&x);
            conv_bn(
                g,
                &w,
                &x,
                "patch_embed.seq.2",
                DIMS[0] / 2,
                DIMS[0],
                3,
                2,
                1,
            )
        })?;
        // Stage 0: MBConv blocks on NCHW.
        let mut x = x;
        for i in 0..DEPTHS[0] {
            x = g.scope(&format!("layers.0/blocks.{i}"), |g| {
                mbconv(g, &w, &x, &format!("layers.0.blocks.{i}"), DIMS[0])
            })?;
        }
        x = g.scope("layers.0/downsample", |g| {
            patch_merging(g, &w, &x, "layers.0.downsample", None, DIMS[0], DIMS[1], 2)
        })?;
        // Stages 1-3: windowed attention blocks on (1, L, C) tokens.
        for s in 1..4 {
            for i in 0..DEPTHS[s] {
                let name = format!("layers.{s}.blocks.{i}");
                x = g.scope(&format!("layers.{s}/blocks.{i}"), |g| {
                    tiny_vit_block(g, &w, &x, &name, s)
                })?;
            }
            if s < 3 {
                let stride = if DIMS[s + 1] == 320 { 1 } else { 2 };
                x = g.scope(&format!("layers.{s}/downsample"), |g| {
                    let name = format!("layers.{s}.downsample");
                    patch_merging(g, &w, &x, &name, Some(RES[s]), DIMS[s], DIMS[s + 1], stride)
                })?;
            }
        }
        // Tokens back to NCHW, then SAM's neck.
        let x = g.reshape(&x, &[1, 64, 64, DIMS[3] as i64]);
        let x = g.transpose(&x, &[0, 3, 1, 2]);
        g.scope("neck", |g| -> Result<String> {
            let x = g.conv(
                &x,
                "neck.0",
                w.get("neck.0.weight", &[256, 320, 1, 1])?,
                None,
                PLAIN,
            );
            let x = layer_norm_2d(g, &w, &x, "neck.1", 256)?;
            let x = g.conv(
                &x,
                "neck.2",
                w.get("neck.2.weight", &[256, 256, 3, 3])?,
                None,
                SAME,
            );
            layer_norm_2d(g, &w, &x, "neck.3", 256)
        })
    })?;
    g.output(
        &out,
        "image_embeddings",
        FLOAT,
        &[1, 256, 64, 64].map(Dim::Fixed),
    );
    Ok(g.into_model(
        "mobile_sam_encoder",
        "MobileSAM image encoder (TinyViT-5M + neck), written by objnerf from mobile_sam.pt",
    ))
}

/// Checkpoint tensors under one module prefix.
pub(super) struct Weights<'a> {
    pub sd: &'a StateDict,
    pub prefix: &'a str,
    pub variant: Variant,
}

impl Weights<'_> {
    /// `nn.Linear` named `name` (weight `out x in`) in the variant's precision.
    fn linear(&self, g: &mut Graph, x: &str, name: &str, out: usize, inp: usize) -> Result<String> {
        let wt = self.get(&format!("{name}.weight"), &[out, inp])?;
        let b = self.vec(&format!("{name}.bias"), out)?;
        Ok(self.linear_of(g, x, name, wt, b))
    }
    fn linear_of(&self, g: &mut Graph, x: &str, name: &str, w: &Tensor, b: &Tensor) -> String {
        if self.variant.int8_linears {
            linear_int8(g, x, name, w, b, self.variant.unsigned_weights)
        } else {
            g.linear(x, name, w, b)
        }
    }

    pub fn get(&self, name: &str, shape: &[usize]) -> Result<&Tensor> {
        self.sd.get(&format!("{}{name}", self.prefix), shape)
    }
    pub fn vec(&self, name: &str, n: usize) -> Result<&Tensor> {
        self.get(name, &[n])
    }
}

/// `Conv2d_BN`: a bias-free convolution and a BatchNorm, folded into one convolution exactly as
/// `torch.onnx`'s eval peephole does (float32: s = gamma / sqrt(var + eps); w * s; beta - mean * s).
#[allow(clippy::too_many_arguments)]
fn conv_bn(
    g: &mut Graph,
    w: &Weights,
    x: &str,
    name: &str,
    cin_per_group: usize,
    cout: usize,
    k: usize,
    stride: i64,
    pad: i64,
) -> Result<String> {
    let conv = w.get(&format!("{name}.c.weight"), &[cout, cin_per_group, k, k])?;
    let gamma = w.vec(&format!("{name}.bn.weight"), cout)?;
    let beta = w.vec(&format!("{name}.bn.bias"), cout)?;
    let mean = w.vec(&format!("{name}.bn.running_mean"), cout)?;
    let var = w.vec(&format!("{name}.bn.running_var"), cout)?;
    let per = conv.len() / cout;
    let mut wd = conv.data.clone();
    let mut bd = vec![0f32; cout];
    for o in 0..cout {
        let s = gamma.data[o] / (var.data[o] + BN_EPS).sqrt();
        for v in &mut wd[o * per..(o + 1) * per] {
            *v *= s;
        }
        bd[o] = beta.data[o] - mean.data[o] * s;
    }
    let groups = if cin_per_group == 1 { cout as i64 } else { 1 };
    let fused = Tensor::new(conv.shape.clone(), wd);
    let bias = Tensor::new(vec![cout], bd);
    Ok(g.conv(
        x,
        name,
        &fused,
        Some(&bias),
        Conv {
            stride,
            pad,
            groups,
        },
    ))
}

fn layer_norm_2d(g: &mut Graph, w: &Weights, x: &str, name: &str, c: usize) -> Result<String> {
    let (wt, b) = (
        w.vec(&format!("{name}.weight"), c)?,
        w.vec(&format!("{name}.bias"), c)?,
    );
    Ok(g.layer_norm_2d(x, name, wt, b))
}

/// MBConv: 1x1 expand, 3x3 depthwise, 1x1 project, residual, GELU.
fn mbconv(g: &mut Graph, w: &Weights, x: &str, name: &str, c: usize) -> Result<String> {
    let h = c * MBCONV_EXPAND;
    let y = conv_bn(g, w, x, &format!("{name}.conv1"), c, h, 1, 1, 0)?;
    let y = g.gelu(&y);
    let y = conv_bn(g, w, &y, &format!("{name}.conv2"), 1, h, 3, 1, 1)?;
    let y = g.gelu(&y);
    let y = conv_bn(g, w, &y, &format!("{name}.conv3"), h, c, 1, 1, 0)?;
    let y = g.add(&y, x);
    Ok(g.gelu(&y))
}

/// PatchMerging: (tokens ->) NCHW, 1x1, depthwise 3x3 with `stride`, 1x1, then (1, L, C) tokens.
#[allow(clippy::too_many_arguments)]
fn patch_merging(
    g: &mut Graph,
    w: &Weights,
    x: &str,
    name: &str,
    tokens_side: Option<usize>,
    cin: usize,
    cout: usize,
    stride: i64,
) -> Result<String> {
    let x = match tokens_side {
        Some(s) => {
            let r = g.reshape(x, &[1, s as i64, s as i64, -1]);
            g.transpose(&r, &[0, 3, 1, 2])
        }
        None => x.to_string(),
    };
    let y = conv_bn(g, w, &x, &format!("{name}.conv1"), cin, cout, 1, 1, 0)?;
    let y = g.gelu(&y);
    let y = conv_bn(g, w, &y, &format!("{name}.conv2"), 1, cout, 3, stride, 1)?;
    let y = g.gelu(&y);
    let y = conv_bn(g, w, &y, &format!("{name}.conv3"), cout, cout, 1, 1, 0)?;
    let y = g.reshape(&y, &[1, cout as i64, -1]);
    Ok(g.transpose(&y, &[0, 2, 1]))
}

/// TinyViTBlock on (1, L, C): windowed attention (padded to whole windows), residual, depthwise
/// local convolution, MLP with residual.
fn tiny_vit_block(g: &mut Graph, w: &Weights, x: &str, name: &str, stage: usize) -> Result<String> {
    let (c, side, ws) = (DIMS[stage], RES[stage], WINDOWS[stage]);
    let pad = (ws - side % ws) % ws;
    let ps = side + pad;
    let nw = ps / ws;
    let (c_, side_, ws_, ps_, nw_) = (c as i64, side as i64, ws as i64, ps as i64, nw as i64);
    let l = side_ * side_;

    let t = g.reshape(x, &[1, side_, side_, c_]);
    let pads = g.i64s(&[0, 0, 0, 0, 0, pad as i64, pad as i64, 0]);
    let t = g.op("Pad", &[&t, &pads], vec![("mode", Attr::Str("constant"))]);
    let t = g.reshape(&t, &[1, nw_, ws_, nw_, ws_, c_]);
    let t = g.transpose(&t, &[0, 1, 3, 2, 4, 5]);
    let t = g.reshape(&t, &[nw_ * nw_, ws_ * ws_, c_]);
    let t = g.scope("attn", |g| {
        attention(g, w, &t, &format!("{name}.attn"), stage)
    })?;
    let t = g.reshape(&t, &[1, nw_, nw_, ws_, ws_, c_]);
    let t = g.transpose(&t, &[0, 1, 3, 2, 4, 5]);
    let t = g.reshape(&t, &[1, ps_, ps_, c_]);
    let t = slice(g, &t, 1, side_);
    let t = slice(g, &t, 2, side_);
    let t = g.reshape(&t, &[1, l, c_]);
    let x = g.add(x, &t);

    let t = g.transpose(&x, &[0, 2, 1]);
    let t = g.reshape(&t, &[1, c_, side_, side_]);
    let t = conv_bn(g, w, &t, &format!("{name}.local_conv"), 1, c, 3, 1, 1)?;
    let t = g.reshape(&t, &[1, c_, l]);
    let x = g.transpose(&t, &[0, 2, 1]);

    let m = g.scope("mlp", |g| -> Result<String> {
        let p = format!("{name}.mlp");
        let h = c * MLP_RATIO;
        let y = g.layer_norm(
            &x,
            &format!("{p}.norm"),
            w.vec(&format!("{p}.norm.weight"), c)?,
            w.vec(&format!("{p}.norm.bias"), c)?,
            LN_EPS,
        );
        let y = w.linear(g, &y, &format!("{p}.fc1"), h, c)?;
        let y = g.gelu(&y);
        w.linear(g, &y, &format!("{p}.fc2"), c, h)
    })?;
    Ok(g.add(&x, &m))
}

fn slice(g: &mut Graph, x: &str, axis: i64, end: i64) -> String {
    let (s, e, a, st) = (g.i64s(&[0]), g.i64s(&[end]), g.i64s(&[axis]), g.i64s(&[1]));
    g.op("Slice", &[x, &s, &e, &a, &st], vec![])
}

/// TinyViT attention on (windows, N, C): LayerNorm, qkv, per-head softmax(q k^T * scale + bias) v,
/// projection. The learned bias per relative offset is expanded to N x N here (the `ab` buffer).
fn attention(g: &mut Graph, w: &Weights, x: &str, name: &str, stage: usize) -> Result<String> {
    let (c, nh, ws) = (DIMS[stage], HEADS[stage], WINDOWS[stage]);
    let n = ws * ws;
    let side = RES[stage] + (ws - RES[stage] % ws) % ws;
    let windows = ((side / ws) * (side / ws)) as i64;
    let qkv_out = nh * 3 * KEY_DIM;
    let y = g.layer_norm(
        x,
        &format!("{name}.norm"),
        w.vec(&format!("{name}.norm.weight"), c)?,
        w.vec(&format!("{name}.norm.bias"), c)?,
        LN_EPS,
    );
    let bias = relative_bias(w, name, nh, ws)?;
    if w.variant.fused_attention {
        let o = fused_attention(g, w, &y, name, c, nh, bias)?;
        return w.linear(g, &o, &format!("{name}.proj"), c, nh * KEY_DIM);
    }
    let y = w.linear(g, &y, &format!("{name}.qkv"), qkv_out, c)?;
    let y = g.reshape(&y, &[windows, n as i64, nh as i64, -1]);
    let split = g.i64s(&[KEY_DIM as i64; 3]);
    let qkv = g.op_n("Split", &[&y, &split], 3, vec![("axis", Attr::Int(3))]);
    let q = g.transpose(&qkv[0], &[0, 2, 1, 3]);
    let v = g.transpose(&qkv[2], &[0, 2, 1, 3]);
    let k = g.transpose(&qkv[1], &[0, 2, 3, 1]);
    let a = g.matmul(&q, &k);
    let scale = g.scalar((KEY_DIM as f32).powf(-0.5));
    let a = g.mul(&a, &scale);
    let bias = g.weight(&format!("{name}.ab"), &bias);
    let a = g.add(&a, &bias);
    let a = g.op("Softmax", &[&a], vec![("axis", Attr::Int(-1))]);
    let o = g.matmul(&a, &v);
    let o = g.transpose(&o, &[0, 2, 1, 3]);
    let o = g.reshape(&o, &[windows, n as i64, (nh * KEY_DIM) as i64]);
    w.linear(g, &o, &format!("{name}.proj"), c, nh * KEY_DIM)
}

/// The attention's core as one `MultiHeadAttention` node on (windows, N, heads x 32) q, k and v,
/// each from its own Linear layer: TinyViT's qkv weight holds, head by head, 32 rows of q, 32 of
/// k and 32 of v, so its rows are regrouped here into three weights. The operator's default scale
/// is TinyViT's (32^-0.5); the relative bias (1, heads, N, N) broadcasts over the windows.
fn fused_attention(
    g: &mut Graph,
    w: &Weights,
    y: &str,
    name: &str,
    c: usize,
    nh: usize,
    bias: Tensor,
) -> Result<String> {
    let qkv_w = w.get(&format!("{name}.qkv.weight"), &[nh * 3 * KEY_DIM, c])?;
    let qkv_b = w.vec(&format!("{name}.qkv.bias"), nh * 3 * KEY_DIM)?;
    let mut parts = Vec::new();
    for (j, part) in ["q", "k", "v"].iter().enumerate() {
        let rows: Vec<usize> = (0..nh)
            .flat_map(|h| (0..KEY_DIM).map(move |r| h * 3 * KEY_DIM + j * KEY_DIM + r))
            .collect();
        let wd = rows
            .iter()
            .flat_map(|&r| qkv_w.data[r * c..(r + 1) * c].iter().copied())
            .collect();
        let bd = rows.iter().map(|&r| qkv_b.data[r]).collect();
        let (wt, b) = (
            Tensor::new(vec![rows.len(), c], wd),
            Tensor::new(vec![rows.len()], bd),
        );
        parts.push(w.linear_of(g, y, &format!("{name}.{part}"), &wt, &b));
    }
    let n = bias.shape[1];
    let bias = g.weight(&format!("{name}.ab"), &bias.reshape(&[1, nh, n, n]));
    Ok(g.op_ms(
        "MultiHeadAttention",
        &[&parts[0], &parts[1], &parts[2], "", "", &bias],
        vec![("num_heads", Attr::Int(nh as i64))],
    ))
}

/// `attention_biases[:, attention_bias_idxs]`: offsets (|dy|, |dx|) numbered in order of first
/// appearance over all point pairs of a window, as TinyViT's constructor numbers them.
fn relative_bias(w: &Weights, name: &str, nh: usize, ws: usize) -> Result<Tensor> {
    let n = ws * ws;
    let mut ids: Vec<Option<usize>> = vec![None; n];
    let mut count = 0;
    let mut idx = Vec::with_capacity(n * n);
    for p1 in 0..n {
        for p2 in 0..n {
            let (dy, dx) = ((p1 / ws).abs_diff(p2 / ws), (p1 % ws).abs_diff(p2 % ws));
            let slot = &mut ids[dy * ws + dx];
            let id = *slot.get_or_insert_with(|| {
                count += 1;
                count - 1
            });
            idx.push(id);
        }
    }
    let biases = w.get(&format!("{name}.attention_biases"), &[nh, count])?;
    let mut data = Vec::with_capacity(nh * n * n);
    for h in 0..nh {
        data.extend(idx.iter().map(|&i| biases.data[h * count + i]));
    }
    Ok(Tensor::new(vec![nh, n, n], data))
}
