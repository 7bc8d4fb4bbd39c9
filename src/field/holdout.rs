//! Training on some views of a scene and scoring the others: the split, and the depth error of a
//! field against true depth (the demo scene's truth, or any depth images).

use super::commands::DepthMode;
use super::depth::{add_dense_depth, add_sparse_depth};
use super::eval::evaluate;
use super::model::Field;
use super::rays::{load_views, MaskSource, View};
use super::render::{forward, RenderOptions};
use super::session::{prepare, RunSummary, SetupConfig, SetupReport, StopRule};
use super::train::TrainConfig;
use crate::error::{Error, Result};
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;

/// Split views into (train, held out): every `every`-th view, starting with the first, is held
/// out (`every` = 6 holds out 6 of the demo scene's 36 views, spread around the ring).
pub fn split_every(views: Vec<View>, every: usize) -> (Vec<View>, Vec<View>) {
    let every = every.max(2);
    let (mut train, mut test) = (Vec::new(), Vec::new());
    for (i, v) in views.into_iter().enumerate() {
        if i % every == 0 {
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

/// How to train and score one object of the demo scene ([`demo_object`]).
#[derive(Clone, Debug)]
pub struct DemoRun {
    pub downscale: u32,
    /// Hold out every this many views (see [`split_every`]).
    pub every: usize,
    pub depth: DepthMode,
    pub setup: SetupConfig,
    pub train: TrainConfig,
    pub stop: StopRule,
    /// Held-out views where less than this fraction of the object is visible are not scored on
    /// colour: the field renders the whole object, the truth shows what the occluder leaves.
    pub min_visible: f64,
}

impl Default for DemoRun {
    fn default() -> Self {
        DemoRun {
            downscale: 1,
            every: 6,
            depth: DepthMode::None,
            setup: SetupConfig::default(),
            train: TrainConfig::default(),
            stop: StopRule::default(),
            min_visible: 0.9,
        }
    }
}

/// What [`demo_object`] measured.
#[derive(Clone, Debug, Serialize)]
pub struct DemoReport {
    pub object: String,
    pub setup: SetupReport,
    pub run: RunSummary,
    pub memory_bytes: usize,
    /// PSNR and SSIM on the scored held-out views, composited on white.
    pub psnr: f64,
    pub ssim: f64,
    pub scored_views: Vec<String>,
    pub held_out_views: usize,
    /// Depth error on all held-out views, inside the object's true mask.
    pub depth: DepthError,
    /// Diagonal of the object's true bounding box, and the median depth error as a fraction of it.
    pub box_diagonal: f64,
    pub depth_error_fraction: f64,
}

/// Train one object of a demo scene (`objnerf demo-scene`) from its true masks on all views but
/// every `run.every`-th, then score the held-out ones: colour on white where the object is
/// visible, depth against the true depth images.
pub fn demo_object(scene_dir: &Path, object: &str, run: &DemoRun) -> Result<DemoReport> {
    let truth = crate::demo::read_truth(scene_dir)?;
    let obj = truth.iter().find(|o| o.name == object).ok_or_else(|| {
        Error::invalid(format!(
            "{}: the demo scene has no object '{object}'",
            scene_dir.display()
        ))
    })?;
    let scene = crate::Scene::load(&scene_dir.join("transforms.json"))?;
    let masks = MaskSource::Dir(scene_dir.join("truth/masks").join(object));
    let mut views = load_views(&scene, &masks, run.downscale)?;
    // Truth depth on every view for scoring; training gets the targets it was asked for.
    let mut scoring = views.clone();
    add_dense_depth(&mut scoring, &scene, run.downscale)?;
    match run.depth {
        DepthMode::None => 0,
        DepthMode::Dense => add_dense_depth(&mut views, &scene, run.downscale)?,
        DepthMode::Sparse => add_sparse_depth(&mut views, &scene, run.downscale)?,
    };
    let (train, _) = split_every(views, run.every);
    let (_, test) = split_every(scoring, run.every);
    let (mut trainer, rays, setup) = prepare(&train, &run.setup, run.train.clone())?;
    let summary = super::session::run(&mut trainer, &train, &rays, &run.stop, |_, _| {});
    let opt = RenderOptions::default();
    let visible = |v: &View| {
        let file = Path::new(&v.name).file_name().map(|f| f.to_string_lossy());
        file.and_then(|f| obj.visible.get(f.as_ref()).copied())
            .unwrap_or(1.0)
    };
    let scored: Vec<View> = test
        .iter()
        .filter(|v| visible(v) >= run.min_visible)
        .cloned()
        .collect();
    let ev = evaluate(&trainer.field, &opt, &scored);
    let depth = depth_error(&trainer.field, &opt, &test);
    let diag = (glam::DVec3::from(obj.bbox_max) - glam::DVec3::from(obj.bbox_min)).length();
    Ok(DemoReport {
        object: object.to_string(),
        memory_bytes: trainer.memory_bytes(),
        psnr: ev.psnr,
        ssim: ev.ssim,
        scored_views: scored.iter().map(|v| v.name.clone()).collect(),
        held_out_views: test.len(),
        depth_error_fraction: depth.median / diag,
        depth,
        box_diagonal: diag,
        setup,
        run: summary,
    })
}
