//! SAM's prompt decoder as the standard SAM ONNX model (`SamOnnxModel` with
//! `return_single_mask=True`): prompt encoder (points with labels -1..3, optional mask input),
//! two-way transformer, mask and IoU heads, the multi-click mask choice, and the upscaling to
//! `orig_im_size`. Inputs and outputs are those of the reference export; batch 1, any number of
//! points.

use super::encoder::{Variant, Weights};
use super::graph::{Attr, Conv, Dim, Graph};
use super::onnx_proto::{ModelProto, FLOAT};
use super::torch::{StateDict, Tensor};
use crate::error::Result;

const C: usize = 256;
const GRID: usize = 64;
const LOW_RES: i64 = 256;
const IMG: f32 = 1024.0;
const HEADS: i64 = 8;
const MASK_TOKENS: usize = 4;
const MLP_DIM: usize = 2048;
const LN_EPS: f32 = 1e-5;

pub fn build(sd: &StateDict) -> Result<ModelProto> {
    let mut g = Graph::new();
    let pe_w = Weights {
        sd,
        prefix: "prompt_encoder.",
        variant: Variant::FP32,
    };
    let md = Weights {
        sd,
        prefix: "mask_decoder.",
        variant: Variant::FP32,
    };
    let n = Dim::Named("num_points");
    let emb = g.input(
        "image_embeddings",
        FLOAT,
        &[1, C as i64, GRID as i64, GRID as i64].map(Dim::Fixed),
    );
    let coords = g.input(
        "point_coords",
        FLOAT,
        &[Dim::Fixed(1), n.clone(), Dim::Fixed(2)],
    );
    let labels = g.input("point_labels", FLOAT, &[Dim::Fixed(1), n]);
    let mask_in = g.input(
        "mask_input",
        FLOAT,
        &[1, 1, LOW_RES, LOW_RES].map(Dim::Fixed),
    );
    let has_mask = g.input("has_mask_input", FLOAT, &[Dim::Fixed(1)]);
    let orig = g.input("orig_im_size", FLOAT, &[Dim::Fixed(2)]);

    let gauss = pe_w.get("pe_layer.positional_encoding_gaussian_matrix", &[2, C / 2])?;
    let gauss = g.weight("pe_layer.gaussian", gauss);

    // Sparse prompts: Fourier features of the points, then the label's learned embedding
    // (label -1 is padding: its features are replaced by `not_a_point_embed`).
    let sparse = g.scope("prompt", |g| -> Result<String> {
        let half = g.scalar(0.5);
        let size = g.scalar(IMG);
        let c = g.add(&coords, &half);
        let c = g.op("Div", &[&c, &size], vec![]);
        let pe = fourier(g, &c, &gauss);
        let axes = g.i64s(&[2]);
        let l = g.op("Unsqueeze", &[&labels, &axes], vec![]);
        let label_is = |g: &mut Graph, v: f32| {
            let k = g.scalar(v);
            g.op("Equal", &[&l, &k], vec![])
        };
        let to_f =
            |g: &mut Graph, b: &str| g.op("Cast", &[b], vec![("to", Attr::Int(FLOAT as i64))]);
        let pad = label_is(g, -1.0);
        let not_pad = g.op("Not", &[&pad], vec![]);
        let keep = to_f(g, &not_pad);
        let mut x = g.mul(&pe, &keep);
        let pad_f = to_f(g, &pad);
        let nap = g.weight(
            "not_a_point_embed",
            pe_w.get("not_a_point_embed.weight", &[1, C])?,
        );
        let t = g.mul(&nap, &pad_f);
        x = g.add(&x, &t);
        for i in 0..4 {
            let is = label_is(g, i as f32);
            let is = to_f(g, &is);
            let e = pe_w.get(&format!("point_embeddings.{i}.weight"), &[1, C])?;
            let e = g.weight(&format!("point_embeddings.{i}"), e);
            let t = g.mul(&e, &is);
            x = g.add(&x, &t);
        }
        Ok(x)
    })?;

    // Dense prompt: the downscaled mask input, or `no_mask_embed` when has_mask_input is 0.
    let dense = g.scope("mask_downscaling", |g| -> Result<String> {
        let p = "mask_downscaling";
        let conv = |g: &mut Graph, x: &str, i: usize, cin: usize, cout: usize, k: usize| {
            let w = pe_w.get(&format!("{p}.{i}.weight"), &[cout, cin, k, k])?;
            let b = pe_w.vec(&format!("{p}.{i}.bias"), cout)?;
            let spec = Conv {
                stride: k as i64,
                pad: 0,
                groups: 1,
            };
            Ok::<_, crate::Error>(g.conv(x, &format!("{p}.{i}"), w, Some(b), spec))
        };
        let ln = |g: &mut Graph, x: &str, i: usize, c: usize| {
            let w = pe_w.vec(&format!("{p}.{i}.weight"), c)?;
            let b = pe_w.vec(&format!("{p}.{i}.bias"), c)?;
            Ok::<_, crate::Error>(g.layer_norm_2d(x, &format!("{p}.{i}"), w, b))
        };
        let x = conv(g, &mask_in, 0, 1, 4, 2)?;
        let x = ln(g, &x, 1, 4)?;
        let x = g.gelu(&x);
        let x = conv(g, &x, 3, 4, 16, 2)?;
        let x = ln(g, &x, 4, 16)?;
        let x = g.gelu(&x);
        let x = conv(g, &x, 6, 16, C, 1)?;
        let with = g.mul(&has_mask, &x);
        let one = g.scalar(1.0);
        let without = g.op("Sub", &[&one, &has_mask], vec![]);
        let nm = pe_w
            .get("no_mask_embed.weight", &[1, C])?
            .reshape(&[1, C, 1, 1]);
        let nm = g.weight("no_mask_embed", &nm);
        let without = g.mul(&without, &nm);
        Ok(g.add(&with, &without))
    })?;

    // The image's positional encoding on the 64 x 64 grid (cell centres), as (1, 4096, 256).
    let image_pe = g.scope("pe_layer", |g| {
        let mut grid = Vec::with_capacity(GRID * GRID * 2);
        for y in 0..GRID {
            for x in 0..GRID {
                grid.push((x as f32 + 0.5) / GRID as f32);
                grid.push((y as f32 + 0.5) / GRID as f32);
            }
        }
        let grid = g.f32s(&[1, (GRID * GRID) as i64, 2], &grid);
        fourier(g, &grid, &gauss)
    });

    // Tokens: the IoU token, the mask tokens, then the prompts.
    let iou_tok = md.get("iou_token.weight", &[1, C])?;
    let mask_tok = md.get("mask_tokens.weight", &[MASK_TOKENS, C])?;
    let mut out_tokens = iou_tok.data.clone();
    out_tokens.extend_from_slice(&mask_tok.data);
    let out_tokens = g.weight(
        "output_tokens",
        &Tensor::new(vec![1, 1 + MASK_TOKENS, C], out_tokens),
    );
    let tokens = g.op(
        "Concat",
        &[&out_tokens, &sparse],
        vec![("axis", Attr::Int(1))],
    );
    let src = g.add(&emb, &dense);
    let src = g.reshape(&src, &[1, C as i64, -1]);
    let src = g.transpose(&src, &[0, 2, 1]);

    let (hs, keys) = g.scope("transformer", |g| {
        two_way_transformer(g, &md, &tokens, &src, &image_pe)
    })?;

    let (masks, iou) = g.scope("heads", |g| -> Result<(String, String)> {
        let iou_out = gather(g, &hs, 0);
        let (s, e, a) = (
            g.i64s(&[1]),
            g.i64s(&[1 + MASK_TOKENS as i64]),
            g.i64s(&[1]),
        );
        let mask_out = g.op("Slice", &[&hs, &s, &e, &a], vec![]);
        let x = g.transpose(&keys, &[0, 2, 1]);
        let x = g.reshape(&x, &[1, C as i64, GRID as i64, GRID as i64]);
        let x = conv_transpose(g, &md, &x, "output_upscaling.0", C, C / 4)?;
        let x = g.layer_norm_2d(
            &x,
            "output_upscaling.1",
            md.vec("output_upscaling.1.weight", C / 4)?,
            md.vec("output_upscaling.1.bias", C / 4)?,
        );
        let x = g.gelu(&x);
        let x = conv_transpose(g, &md, &x, "output_upscaling.3", C / 4, C / 8)?;
        let up = g.gelu(&x);
        let mut hyper = Vec::new();
        for i in 0..MASK_TOKENS {
            let t = gather(g, &mask_out, i as i64);
            let h = mlp(g, &md, &t, &format!("output_hypernetworks_mlps.{i}"), C / 8)?;
            let ax = g.i64s(&[1]);
            hyper.push(g.op("Unsqueeze", &[&h, &ax], vec![]));
        }
        let refs: Vec<&str> = hyper.iter().map(String::as_str).collect();
        let hyper = g.op("Concat", &refs, vec![("axis", Attr::Int(1))]);
        let up = g.reshape(&up, &[1, (C / 8) as i64, LOW_RES * LOW_RES]);
        let m = g.matmul(&hyper, &up);
        let m = g.reshape(&m, &[1, -1, LOW_RES, LOW_RES]);
        let iou = mlp(g, &md, &iou_out, "iou_prediction_head", MASK_TOKENS)?;
        Ok((m, iou))
    })?;

    // One mask: with one point (or a box alone) the best of masks 1-3 by predicted IoU, else
    // mask 0 (the reweighting trick of SamOnnxModel.select_masks).
    let (low_res, best_iou) = g.scope("select", |g| {
        let np = g.op(
            "Shape",
            &[&coords],
            vec![("start", Attr::Int(1)), ("end", Attr::Int(2))],
        );
        let np = g.op("Cast", &[&np], vec![("to", Attr::Int(FLOAT as i64))]);
        let k = g.scalar(2.5);
        let np = g.op("Sub", &[&np, &k], vec![]);
        let w = g.f32s(&[1, MASK_TOKENS as i64], &[1000.0, 0.0, 0.0, 0.0]);
        let bonus = g.mul(&np, &w);
        let score = g.add(&iou, &bonus);
        let best = g.op(
            "ArgMax",
            &[&score],
            vec![("axis", Attr::Int(1)), ("keepdims", Attr::Int(0))],
        );
        let ax1 = || vec![("axis", Attr::Int(1))];
        let low = g.op("Gather", &[&masks, &best], ax1());
        let s = g.op("Gather", &[&iou, &best], ax1());
        (low, s)
    });

    // Upscale: to 1024 x 1024, crop the resized image's extent, then to orig_im_size.
    let up = g.scope("postprocess", |g| {
        let sizes = g.i64s(&[1, 1, IMG as i64, IMG as i64]);
        let resize = |g: &mut Graph, x: &str, sizes: &str| {
            g.op(
                "Resize",
                &[x, "", "", sizes],
                vec![
                    ("coordinate_transformation_mode", Attr::Str("half_pixel")),
                    ("mode", Attr::Str("linear")),
                ],
            )
        };
        let x = resize(g, &low_res, &sizes);
        let longest = g.op("ReduceMax", &[&orig], vec![("keepdims", Attr::Int(0))]);
        let inv = g.op("Reciprocal", &[&longest], vec![]);
        let size = g.scalar(IMG);
        let scale = g.mul(&inv, &size);
        let s = g.mul(&scale, &orig);
        let half = g.scalar(0.5);
        let s = g.add(&s, &half);
        let s = g.op("Floor", &[&s], vec![]);
        let to_i = vec![("to", Attr::Int(super::onnx_proto::INT64 as i64))];
        let prepadded = g.op("Cast", &[&s], to_i);
        let (st, ax) = (g.i64s(&[0, 0]), g.i64s(&[2, 3]));
        let x = g.op("Slice", &[&x, &st, &prepadded, &ax], vec![]);
        let hw = g.op(
            "Cast",
            &[&orig],
            vec![("to", Attr::Int(super::onnx_proto::INT64 as i64))],
        );
        let one_one = g.i64s(&[1, 1]);
        let sizes = g.op("Concat", &[&one_one, &hw], vec![("axis", Attr::Int(0))]);
        resize(g, &x, &sizes)
    });

    g.output(
        &up,
        "masks",
        FLOAT,
        &[
            Dim::Fixed(1),
            Dim::Fixed(1),
            Dim::Named("orig_height"),
            Dim::Named("orig_width"),
        ],
    );
    g.output(
        &best_iou,
        "iou_predictions",
        FLOAT,
        &[Dim::Fixed(1), Dim::Fixed(1)],
    );
    g.output(
        &low_res,
        "low_res_masks",
        FLOAT,
        &[1, 1, LOW_RES, LOW_RES].map(Dim::Fixed),
    );
    Ok(g.into_model(
        "mobile_sam_decoder",
        "SAM prompt decoder (SamOnnxModel, single mask), written by objnerf from mobile_sam.pt",
    ))
}

/// `PositionEmbeddingRandom._pe_encoding` of coordinates in [0, 1]: sin and cos of
/// 2 pi (2c - 1) G.
fn fourier(g: &mut Graph, c: &str, gauss: &str) -> String {
    let (two, one) = (g.scalar(2.0), g.scalar(1.0));
    let x = g.mul(c, &two);
    let x = g.op("Sub", &[&x, &one], vec![]);
    let x = g.matmul(&x, gauss);
    let tau = g.scalar(std::f32::consts::TAU);
    let x = g.mul(&x, &tau);
    let s = g.op("Sin", &[&x], vec![]);
    let c = g.op("Cos", &[&x], vec![]);
    g.op("Concat", &[&s, &c], vec![("axis", Attr::Int(-1))])
}

/// Row `i` of axis 1 of a (1, n, C) tensor, as (1, C).
fn gather(g: &mut Graph, x: &str, i: i64) -> String {
    let idx = g.i64_scalar(i);
    g.op("Gather", &[x, &idx], vec![("axis", Attr::Int(1))])
}

fn conv_transpose(
    g: &mut Graph,
    md: &Weights,
    x: &str,
    name: &str,
    cin: usize,
    cout: usize,
) -> Result<String> {
    let w = g.weight(
        &format!("{name}.weight"),
        md.get(&format!("{name}.weight"), &[cin, cout, 2, 2])?,
    );
    let b = g.weight(
        &format!("{name}.bias"),
        md.vec(&format!("{name}.bias"), cout)?,
    );
    Ok(g.op(
        "ConvTranspose",
        &[x, &w, &b],
        vec![
            ("dilations", Attr::Ints(vec![1, 1])),
            ("group", Attr::Int(1)),
            ("kernel_shape", Attr::Ints(vec![2, 2])),
            ("pads", Attr::Ints(vec![0; 4])),
            ("strides", Attr::Ints(vec![2, 2])),
        ],
    ))
}

/// SAM's 3-layer `MLP` (ReLU between layers) on a (1, C) row.
fn mlp(g: &mut Graph, md: &Weights, x: &str, name: &str, out: usize) -> Result<String> {
    let mut x = x.to_string();
    for i in 0..3 {
        let o = if i == 2 { out } else { C };
        let w = md.get(&format!("{name}.layers.{i}.weight"), &[o, C])?;
        let b = md.vec(&format!("{name}.layers.{i}.bias"), o)?;
        x = g.gemm(&x, &format!("{name}.layers.{i}"), w, b);
        if i < 2 {
            x = g.relu(&x);
        }
    }
    Ok(x)
}

/// SAM's TwoWayTransformer (depth 2): returns the processed tokens and image keys.
fn two_way_transformer(
    g: &mut Graph,
    md: &Weights,
    tokens: &str,
    keys: &str,
    key_pe: &str,
) -> Result<(String, String)> {
    let mut q = tokens.to_string();
    let mut k = keys.to_string();
    for layer in 0..2 {
        let p = format!("transformer.layers.{layer}");
        (q, k) = g.scope(
            &format!("layers.{layer}"),
            |g| -> Result<(String, String)> {
                let norm = |g: &mut Graph, x: &str, n: &str| -> Result<String> {
                    let w = md.vec(&format!("{p}.{n}.weight"), C)?;
                    let b = md.vec(&format!("{p}.{n}.bias"), C)?;
                    Ok(g.layer_norm(x, &format!("{p}.{n}"), w, b, LN_EPS))
                };
                // Self-attention (the first layer has no positional encoding and no residual).
                let mut q = if layer == 0 {
                    attention(g, md, &format!("{p}.self_attn"), &q, &q, &q, C)?
                } else {
                    let qp = g.add(&q, tokens);
                    let a = attention(g, md, &format!("{p}.self_attn"), &qp, &qp, &q, C)?;
                    g.add(&q, &a)
                };
                q = norm(g, &q, "norm1")?;
                // Tokens attend to the image.
                let qp = g.add(&q, tokens);
                let kp = g.add(&k, key_pe);
                let a = attention(
                    g,
                    md,
                    &format!("{p}.cross_attn_token_to_image"),
                    &qp,
                    &kp,
                    &k,
                    C / 2,
                )?;
                q = g.add(&q, &a);
                q = norm(g, &q, "norm2")?;
                // MLP.
                let h = g.linear(
                    &q,
                    &format!("{p}.mlp.lin1"),
                    md.get(&format!("{p}.mlp.lin1.weight"), &[MLP_DIM, C])?,
                    md.vec(&format!("{p}.mlp.lin1.bias"), MLP_DIM)?,
                );
                let h = g.relu(&h);
                let h = g.linear(
                    &h,
                    &format!("{p}.mlp.lin2"),
                    md.get(&format!("{p}.mlp.lin2.weight"), &[C, MLP_DIM])?,
                    md.vec(&format!("{p}.mlp.lin2.bias"), C)?,
                );
                q = g.add(&q, &h);
                q = norm(g, &q, "norm3")?;
                // The image attends to the tokens.
                let qp = g.add(&q, tokens);
                let kp = g.add(&k, key_pe);
                let a = attention(
                    g,
                    md,
                    &format!("{p}.cross_attn_image_to_token"),
                    &kp,
                    &qp,
                    &q,
                    C / 2,
                )?;
                let k = g.add(&k, &a);
                let k = norm(g, &k, "norm4")?;
                Ok((q, k))
            },
        )?;
    }
    let qp = g.add(&q, tokens);
    let kp = g.add(&k, key_pe);
    let a = attention(
        g,
        md,
        "transformer.final_attn_token_to_image",
        &qp,
        &kp,
        &k,
        C / 2,
    )?;
    let q = g.add(&q, &a);
    let q = g.layer_norm(
        &q,
        "transformer.norm_final_attn",
        md.vec("transformer.norm_final_attn.weight", C)?,
        md.vec("transformer.norm_final_attn.bias", C)?,
        LN_EPS,
    );
    Ok((q, k))
}

/// SAM's multi-head `Attention` with the projections' width `internal` (256 or 128 when
/// downsampled), 8 heads.
fn attention(
    g: &mut Graph,
    md: &Weights,
    name: &str,
    q: &str,
    k: &str,
    v: &str,
    internal: usize,
) -> Result<String> {
    let short = name.rsplit('.').next().unwrap_or(name).to_string();
    g.scope(&short, |g| {
        let proj = |g: &mut Graph, x: &str, p: &str| -> Result<String> {
            Ok(g.linear(
                x,
                &format!("{name}.{p}"),
                md.get(&format!("{name}.{p}.weight"), &[internal, C])?,
                md.vec(&format!("{name}.{p}.bias"), internal)?,
            ))
        };
        let d = internal as i64 / HEADS;
        let heads = [1, -1, HEADS, d];
        let qh = proj(g, q, "q_proj")?;
        let qh = g.reshape(&qh, &heads);
        let qh = g.transpose(&qh, &[0, 2, 1, 3]);
        let kh = proj(g, k, "k_proj")?;
        let kh = g.reshape(&kh, &heads);
        let vh = proj(g, v, "v_proj")?;
        let vh = g.reshape(&vh, &heads);
        let vh = g.transpose(&vh, &[0, 2, 1, 3]);
        let kt = g.transpose(&kh, &[0, 2, 3, 1]);
        let a = g.matmul(&qh, &kt);
        let s = g.scalar((d as f32).sqrt());
        let a = g.op("Div", &[&a, &s], vec![]);
        let a = g.op("Softmax", &[&a], vec![("axis", Attr::Int(-1))]);
        let o = g.matmul(&a, &vh);
        let o = g.transpose(&o, &[0, 2, 1, 3]);
        let o = g.reshape(&o, &[1, -1, internal as i64]);
        Ok(g.linear(
            &o,
            &format!("{name}.out_proj"),
            md.get(&format!("{name}.out_proj.weight"), &[C, internal])?,
            md.vec(&format!("{name}.out_proj.bias"), C)?,
        ))
    })
}
