//! Training on some views of a scene and scoring the others: the split, and the depth error of a
//! field against true depth (the demo scene's truth, or any depth images).

use super::model::Field;
use super::view::View;
use crate::field::march::{forward, RenderOptions};
use rayon::prelude::*;
use serde::Serialize;

/// Whether view `i` is held out when every `every`-th view is (0: none): views every/2,
/// every/2 + every, ... (the first view, where a demo click is, stays in training; `every` = 6
/// holds out 6 of the demo scene's 36 views, spread around the ring).
pub fn is_held_out(i: usize, every: usize) -> bool {
    every > 0 && i % every == every / 2
}

/// Split views into (train, held out) by [`is_held_out`] (`every` at least 2).
pub fn split_every(views: Vec<View>, every: usize) -> (Vec<View>, Vec<View>) {
    let every = every.max(2);
    let (mut train, mut test) = (Vec::new(), Vec::new());
    for (i, v) in views.into_iter().enumerate() {
        if is_held_out(i, every) {
            test.push(v);
        } else {
            train.push(v);
        }
    }
    (train, test)
}

/// Depth error of a field over the pixels that have a true depth (views' `depth`: distance along
/// the unit ray, set inside the object's mask only), in z-depth (the convention of depth images).
#[derive(Clone, Debug, Default, Serialize)]
pub struct DepthError {
    /// Median |rendered - true| z-depth, world units.
    pub median: f64,
    /// Mean signed error (rendered - true): > 0 means the surface is rendered too far.
    pub mean_signed: f64,
    /// 90th percentile of the absolute error.
    pub p90: f64,
    /// Median |error| of the depth where the opacity along the ray first reaches one half (the
    /// median termination depth), for comparison.
    pub median_half: f64,
    /// Pixels scored.
    pub pixels: usize,
    /// Pixels where the field's opacity is below 0.5 although the object is there (scored with
    /// their normalised expected depth all the same).
    pub transparent: usize,
}

/// Render the depth of every pixel with a true depth and compare. The rendered depth is the
/// expected termination distance normalised by the opacity (sum w t / sum w), converted to z-depth.
pub fn depth_error(f: &Field, opt: &RenderOptions, views: &[View]) -> DepthError {
    let per: Vec<(Vec<(f64, f64)>, usize)> = views
        .par_iter()
        .filter_map(|v| v.depth.as_ref().map(|d| (v, d)))
        .map(|(v, truth)| {
            let mut scratch = Vec::new();
            let mut errs = Vec::new();
            let mut transparent = 0;
            for (i, &dt) in truth.iter().enumerate() {
                if dt <= 0.0 {
                    continue;
                }
                let (o, d) = v.ray(i as u32);
                let r = forward(f, opt, o, d, 0.5, [1.0; 3], &mut scratch);
                if r.alpha < 0.5 {
                    transparent += 1;
                }
                let dr = if r.alpha > 1e-3 {
                    r.depth / r.alpha
                } else {
                    0.0
                };
                let half = scratch
                    .iter()
                    .find(|s| 1.0 - s.trans * (1.0 - s.alpha) >= 0.5)
                    .map_or(0.0, |s| s.t);
                let k = v.ray_scale(i as u32);
                errs.push((((dr - dt) / k) as f64, ((half - dt) / k) as f64));
            }
            (errs, transparent)
        })
        .collect();
    let transparent = per.iter().map(|p| p.1).sum();
    let both: Vec<(f64, f64)> = per.into_iter().flat_map(|p| p.0).collect();
    let signed: Vec<f64> = both.iter().map(|e| e.0).collect();
    let mut half: Vec<f64> = both.iter().map(|e| e.1.abs()).collect();
    half.sort_by(|a, b| a.total_cmp(b));
    if signed.is_empty() {
        return DepthError::default();
    }
    let mut abs: Vec<f64> = signed.iter().map(|e| e.abs()).collect();
    abs.sort_by(|a, b| a.total_cmp(b));
    let q = |p: f64| abs[((abs.len() - 1) as f64 * p).round() as usize];
    DepthError {
        median: q(0.5),
        mean_signed: signed.iter().sum::<f64>() / signed.len() as f64,
        p90: q(0.9),
        median_half: half.get(half.len() / 2).copied().unwrap_or(0.0),
        pixels: abs.len(),
        transparent,
    }
}

/// The names of every `every`-th view of `scene` (views every/2, every/2 + every, ...; 0:
/// none), to hold out of training.
pub fn held_out_views(scene: &crate::scene::Scene, every: usize) -> Vec<String> {
    scene
        .images
        .iter()
        .enumerate()
        .filter(|(i, _)| is_held_out(*i, every))
        .map(|(_, im)| im.name.clone())
        .collect()
}
