//! One object of the demo scene trained from its true masks and scored on held-out views against
//! the exact truth: colour where the object is visible, depth against the true depth images. The
//! field tests and benchmarks use it.

use crate::error::{Error, Result};
use crate::field::eval::evaluate;
use crate::field::holdout::{depth_error, split, DepthError, HoldOut};
use crate::field::session::{prepare, RunSummary, SetupConfig, SetupReport, StopRule};
use crate::field::{load_views, MaskSource, RenderOptions, TrainConfig, View};
use crate::supervision::add_depth_targets;
use crate::supervision::depth::add_dense_depth;
use crate::supervision::DepthMode;
use serde::Serialize;
use std::path::Path;

/// How to train and score one object of the demo scene ([`demo_object`]).
#[derive(Clone, Debug)]
pub struct DemoRun {
    pub downscale: u32,
    /// Hold out every this many views ([`HoldOut::Every`]).
    pub every: usize,
    pub depth: DepthMode,
    pub setup: SetupConfig,
    pub train: TrainConfig,
    pub stop: StopRule,
    /// Held-out views where less than this fraction of the object is visible are not scored on
    /// colour: the field renders the whole object, the truth shows what the occluder leaves.
    pub min_visible: f64,
    /// Rays a held-out pixel is the mean of, per axis ([`RenderOptions::pixel_samples`]).
    pub pixel_samples: u32,
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
            pixel_samples: 1,
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
    add_depth_targets(&mut views, &scene, run.depth, run.downscale)?;
    let (train, _) = split(views, HoldOut::Every(run.every.max(2)));
    let (_, test) = split(scoring, HoldOut::Every(run.every.max(2)));
    let points = crate::field::bounds::points_in_masks(&scene, &train, run.downscale);
    let (mut trainer, rays, setup) = prepare(&train, &points, &run.setup, run.train.clone(), None)?;
    let summary = crate::field::session::run(&mut trainer, &train, &rays, &run.stop, |_| {});
    let opt = RenderOptions {
        pixel_samples: run.pixel_samples,
        ..RenderOptions::default()
    };
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
