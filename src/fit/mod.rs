//! Training an object's field on a scene, as one call: views and masks in, a trained
//! [`Trainer`] and a report out. `objnerf train` and `objnerf extract` both use it; saving the
//! model ([`crate::field::io::save`]) is the caller's choice.

pub mod object_checks;
pub mod scene_checks;

use crate::error::{Error, Result};
use crate::field::bounds::points_in_masks;
use crate::field::io::Model;
use crate::field::rays::RaySet;
use crate::field::session::{
    prepare, prepare_scene, run, RunSummary, SetupConfig, SetupReport, StopRule,
};
use crate::field::train::{StepStats, TrainConfig, Trainer, ViewAppearance};
use crate::field::view::{load_views, MaskSource, View};
use crate::field::RenderOptions;
use crate::fit::scene_checks::{check_scene_fit, measure_scene_fit, SceneFitCheck};
use crate::scene::Scene;
use crate::space::layout::{choose_space, SpaceChoice};
use crate::supervision::edge::add_edge_bands;
use crate::supervision::{add_depth_targets, loss_mask, DepthMode};
use crate::util::warnings::Warning;
use image::GrayImage;
use serde::Serialize;
use std::sync::Arc;

/// How to train a field on a scene.
#[derive(Clone, Debug)]
pub struct FitOptions {
    /// Train on images downscaled by this factor (box filter).
    pub downscale: u32,
    /// Stop after this many seconds of training (None: the steps or a plateau).
    pub time_budget: Option<f64>,
    pub depth: DepthMode,
    pub seed: u64,
    /// Most optimisation steps (the learning-rate schedule spans them).
    pub steps: usize,
    /// Train for the whole `time_budget`: no step cap (the schedule follows the time instead
    /// of `steps`) and no plateau stop. No effect without a budget.
    pub whole_budget: bool,
    pub setup: SetupConfig,
    /// Views left out of training (e.g. the ones segmentation found obstructed, or held out).
    pub exclude_views: Vec<String>,
    /// Pixels either side of a segmented mask's edge whose colour target is the photo over the
    /// background behind the object ([`crate::supervision::edge`]; 0: masks taken as exact). Images' own
    /// alpha is always exact.
    pub mask_band: u32,
    /// Learning rate of each training view's colour correction (gains and offsets, learnt and
    /// left out when rendering: [`crate::field::train::Appearance`]; 0: off).
    pub appearance_lr: f32,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            downscale: 1,
            time_budget: None,
            depth: DepthMode::None,
            seed: 0,
            steps: TrainConfig::default().steps,
            whole_budget: false,
            setup: SetupConfig::default(),
            exclude_views: vec![],
            mask_band: 2,
            appearance_lr: TrainConfig::default().appearance_lr,
        }
    }
}

/// Steps the schedule spans when a run trains for its whole budget: more than any budget
/// reaches, so the schedule follows the time.
pub const UNCAPPED_STEPS: usize = 100_000_000;

impl FitOptions {
    fn trains_whole_budget(&self) -> bool {
        self.whole_budget && self.time_budget.is_some()
    }

    /// The steps the schedule spans ([`FitOptions::whole_budget`]: uncapped).
    pub fn schedule_steps(&self) -> usize {
        if self.trains_whole_budget() {
            UNCAPPED_STEPS
        } else {
            self.steps
        }
    }

    /// When training stops: the budget, the steps, or (unless it trains for the whole budget)
    /// a plateau.
    pub fn stop_rule(&self) -> StopRule {
        let mut stop = StopRule::for_budget(self.time_budget);
        if self.trains_whole_budget() {
            stop.plateau_db = None;
        }
        stop
    }
}

/// What training did.
#[derive(Clone, Debug, Serialize)]
pub struct TrainReport {
    /// How the box and grid were chosen (None when resuming a model).
    pub setup: Option<SetupReport>,
    pub run: RunSummary,
    pub vertices: usize,
    pub dims: [usize; 3],
    pub memory_bytes: usize,
    pub occupied_cells: usize,
    pub depth_targets: usize,
    /// The finest stage's grid: resolution, bricks, bytes per brick and why (None when training
    /// ended before it).
    pub finest: Option<crate::field::train::FinestStage>,
    /// A scene field's fit to its own training views ([`SceneFit::check_fit`]; None for an
    /// object field, whose checks hold views back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene_fit: Option<SceneFitCheck>,
    /// The scene fit's self-checks that tripped.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
    /// Each training view's learnt colour correction (empty: none learnt).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub appearance: Vec<ViewAppearance>,
}

/// The corrections `trainer` learnt for `views` (none: empty).
fn appearance_report(trainer: &Trainer, views: &[View]) -> Vec<ViewAppearance> {
    let names: Vec<String> = views.iter().map(|v| v.name.clone()).collect();
    trainer
        .appearance
        .as_ref()
        .map_or(Vec::new(), |a| a.report(&names))
}

/// A trained field with its optimiser state, and the report.
pub struct Fitted {
    pub trainer: Trainer,
    pub report: TrainReport,
}

/// Train a field on `scene`'s views with `masks` (or continue `resume`); `progress` sees every
/// step.
pub fn fit_object(
    scene: &Scene,
    masks: &MaskSource,
    opts: &FitOptions,
    resume: Option<Model>,
    progress: &mut dyn FnMut(&StepStats),
) -> Result<Fitted> {
    if opts.downscale == 0 {
        return Err(Error::invalid("--downscale must be at least 1"));
    }
    let mut views = load_views(scene, masks, opts.downscale)?;
    let depth_targets = depth_and_training_views(&mut views, scene, opts)?;
    if masks.is_segmented() {
        add_edge_bands(&mut views, scene, opts.downscale, opts.mask_band)?;
    }
    let cfg = TrainConfig {
        seed: opts.seed,
        steps: opts.schedule_steps(),
        appearance_lr: opts.appearance_lr,
        // Measured where the targets are the sparse points alone (examples/results/field.md,
        // "Free space in front of the sparse points"). With the demo's exact dense depth, which
        // places every surface already, it cost the edit test's objects 0.1-0.4 dB inside.
        free_space_weight: match opts.depth {
            DepthMode::Sparse => TrainConfig::default().free_space_weight,
            _ => 0.0,
        },
        ..Default::default()
    };
    let (mut trainer, rays, setup) = match resume {
        None => {
            let points = points_in_masks(scene, &views, opts.downscale);
            let (t, r, s) = prepare(&views, &points, &opts.setup, cfg, opts.time_budget)?;
            (t, r, Some(s))
        }
        Some(m) => {
            let t = Trainer::from_model(m, cfg);
            let rays = RaySet::build(&views, &t.field);
            (t, rays, None)
        }
    };
    let stop = opts.stop_rule();
    let summary = run(&mut trainer, &views, &rays, &stop, progress);
    let report = TrainReport {
        setup,
        run: summary,
        vertices: trainer.field.grid.num_vertices(),
        dims: trainer.field.grid.dims,
        memory_bytes: trainer.memory_bytes(),
        occupied_cells: trainer.field.occupied_cells(),
        depth_targets,
        finest: trainer.finest.clone(),
        scene_fit: None,
        warnings: Vec::new(),
        appearance: appearance_report(&trainer, &views),
    };
    Ok(Fitted { trainer, report })
}

/// Add the depth targets `opts` asks for to `views`, then keep only the views it trains on;
/// returns how many targets there are.
fn depth_and_training_views(
    views: &mut Vec<View>,
    scene: &Scene,
    opts: &FitOptions,
) -> Result<usize> {
    let targets = add_depth_targets(views, scene, opts.depth, opts.downscale)?;
    views.retain(|v| !opts.exclude_views.contains(&v.name));
    if views.is_empty() {
        return Err(Error::invalid(format!(
            "{}: no views left to train on",
            scene.source.display()
        )));
    }
    Ok(targets)
}

/// How to train a scene field: the whole scene, or the scene without some objects (their
/// pixels, dilated, carry no loss; other views fill in what they hid).
#[derive(Clone, Debug)]
pub struct SceneFitOptions {
    /// Which space the grid lives in ([`SpaceChoice::Auto`]: from the capture's layout).
    pub space: SpaceChoice,
    pub fit: FitOptions,
    /// Masks of the objects to remove, one per scene image (None: nothing to remove there).
    pub removed: Option<Arc<Vec<Option<GrayImage>>>>,
    /// Grow the removed masks by this many pixels (full resolution): SAM's tight edges would
    /// otherwise leave a rim of the object in the background. Every pixel grown is one more no
    /// view may see (on the demo ring the torus's never-seen share of its true mask + 4 px is
    /// 31% at 1 px, 40% at 2, 50% at 4). SAM's masks grown by 1 px miss 4 of the torus's
    /// 51 265 true pixels (36 views) and 958 of the mug's 54 785 (2 px: 2 and 183; 3 px: none).
    /// Removing both, inside their true masks (+4 px), mug / torus: at 6 000 steps 24.22 /
    /// 19.68 dB at 4 px, 24.96 / 20.27 at 3, 24.70 / 21.22 at 2, 24.33 / 21.61 at 1; at the
    /// removal test's 20 000 steps 25.43 / 21.56 at 2 px, 25.27 / 22.08 at 1 (full frame 28.84,
    /// 28.65), no rim of the mug in the held-out crops.
    pub dilate_px: u32,
    /// Sparse points not to seed surfaces from (indices into the scene's points): the removed
    /// objects' own.
    pub exclude_points: std::collections::HashSet<usize>,
    /// The trainer's settings for a scene field ([`scene_train_config`]); its seed and steps
    /// are `fit`'s.
    pub train: TrainConfig,
    /// A forward-facing capture's own settings (NDC space).
    pub forward: ForwardSettings,
    /// The grid's learning rates (density and colour) are `train`'s times this where the
    /// training views carry depth targets (a forward capture's: [`ForwardSettings`]). Depth
    /// holds the geometry while the faster density carves the fog, so rays end sooner: twice
    /// the rates, 300 s, the demo ring held out +0.90 dB, fox at 3 000 steps +0.40, at 1.3-2x
    /// the rays a second; removal and the user's path over their lines. Where nothing holds
    /// it the air carves before the photos agree where the surfaces are: the forward demo with
    /// no depth held out 17.69 dB at twice the rates against 20.24
    /// (examples/results/scene_field.md, "Twice the grid's rates fail a field with no depth").
    pub rate_scale_with_depth: f32,
}

/// A forward-facing capture's settings, where they differ from a ring's or a room's. Its
/// cameras stand a few centimetres apart, so colour alone tells a near surface from a far one
/// only weakly, and what pulls a ray's weight anywhere wins.
///
/// The distortion loss did: measured in world length it pulled every ray onto the near plane
/// (fern held out 14.6-15.4 dB, whatever the depth weight up to 1e-4), and even measured in
/// space (as it now is) at the ring's weight it still does (forward demo without depth, 3000
/// steps: 16.40 dB at 1e-3, 25.18 at 1e-4, 27.48 off). Off, the photos alone find the geometry:
/// at 3000 steps without depth fern / flower / horns held out 23.10 / 23.36 / 23.48 dB, where
/// the stereo depth settings below, made to hold the field up against that pull, gave at most
/// 20.86. With the loss off they still pay on some captures and cost on others (22.66 / 24.08
/// / 22.79 dB), at 1.5-2x the rays a second (their surfaces end rays sooner)
/// (examples/results/scene_field.md, "The near-plane screen was the distortion loss").
#[derive(Clone, Debug)]
pub struct ForwardSettings {
    pub distortion_weight: f32,
    /// Stereo depth weighed as a ring's, the free-space loss in front of the same targets, and
    /// surfaces started at the targets as well as at the sparse points. 50x (0.05) held the
    /// field against the distortion loss's pull; with that loss off, lighter scores higher on
    /// every LLFF capture in 600 s: 0.01 (fern / flower / horns 23.64 / 25.58 / 24.85 -> 23.92
    /// / 25.69 / 25.23 dB held out, twentieth session), then 0.003 (23.88 / 25.71 / 25.31 ->
    /// 23.99 / 25.74 / 25.55, with 27 / 20 / 3% more rays a second: the wrong parts of
    /// stereo's targets hold less fog), then 0.001 (24.05 / 25.79 / 25.76, twenty-second),
    /// examples/results/scene_field.md, "the forward depth weight" (twentieth to
    /// twenty-second sessions). With the Cauchy penalty below, 0.0003: 24.54 / 26.03 / 26.80
    /// (SSIM 0.804 / 0.862 / 0.891) -> 24.74 / 26.28 / 27.29 (0.804 / 0.867 / 0.898) held out
    /// in 600 s (each pair measured the same day; scene_field.md, "A depth loss that gives way"
    /// and "The lighter forward depth weight kept").
    pub depth_weight: f32,
    /// [`TrainConfig::depth_robust_voxels`] for a forward capture: 3 (the free-space loss's
    /// margin, "a voxel or two off"), so a stereo target far off is outvoted by the photos.
    /// At 600 s, fern / flower / horns held out 24.15 / 25.91 / 25.82 dB (SSIM 0.789 / 0.855 /
    /// 0.872) -> 24.54 / 25.99 / 26.80 (0.804 / 0.859 / 0.891), with fewer samples a ray; the
    /// lighter square (0.0003) gave 24.27 / 25.94 / 26.17, none at all 24.24 / 26.36 / 27.31
    /// but fern's SSIM 0.749 and its fronds ghosted (examples/results/scene_field.md, "A depth
    /// loss that gives way", twenty-third session).
    pub depth_robust_voxels: f32,
    pub free_space_weight: f32,
    pub seed_from_depth: bool,
    /// [`SceneFitOptions::rate_scale_with_depth`] for a forward capture: 1, the object
    /// field's rates. Twice them paid in 300 s on a slower machine (fern / flower / horns
    /// +0.21 / +0.13 / +0.35 dB) but cost flower 0.44 dB in the 600 s (25.66 -> 25.22
    /// held out; examples/results/scene_field.md, "Twice the rates where depth holds the
    /// geometry").
    pub rate_scale_with_depth: f32,
    /// Total variation (density, colour, period: [`TrainConfig::tv_density`],
    /// [`TrainConfig::tv_color`], [`TrainConfig::tv_every`]): 1e-5 and 1e-5 on every 8th step at
    /// 8x; DVGO's LLFF weights (1e-5 and 1e-6) at first, the colour's raised below. The gap on
    /// these captures is between the views (fern's fit to its training views 3 dB over held out),
    /// and TV fills in between them; on every step it cost half the steps (fern 24.62 / 0.806 in
    /// 6 912 steps against 24.74 / 0.804 in 13 168); on every 8th, held out in 600 s fern / flower
    /// / horns 24.71 / 26.28 / 27.32 dB (SSIM 0.804 / 0.867 / 0.899) -> 24.92 / 26.37 / 27.47
    /// (0.810 / 0.867 / 0.903), each pair the same day, at 0.6-0.75x the rays a second (it keeps
    /// more air: 8-11 samples a ray against 5-8) (examples/results/scene_field.md, "TV on every 8th
    /// step"). The colour's weight then raised to the density's, 1e-5: held out in 600 s 24.92 /
    /// 26.53 / 27.44 dB (SSIM 0.810 / 0.873 / 0.902) -> 25.02 / 26.75 / 27.61 (0.816 / 0.878 /
    /// 0.905), each pair the same hour, with 1.05-1.07x the steps (scene_field.md, "Colour TV ten
    /// times DVGO's").
    pub tv: (f32, f32, usize),
    /// [`TrainConfig::tv_until`] for a forward capture: TV for the first half of the schedule
    /// (the two coarser stages), none in the finest: the steps its pass took there (half its
    /// 55-67 s of 600) outweighed its pull. Held out in 600 s, fern / flower / horns 24.92 /
    /// 26.44 / 27.29 dB (SSIM 0.808 / 0.870 / 0.897) -> 24.94 / 26.55 / 27.47 (0.811 / 0.873 /
    /// 0.902), 1.10-1.18x the steps, each pair the same hour (examples/results/scene_field.md,
    /// "TV for the first half").
    pub tv_until: f32,
}

impl Default for ForwardSettings {
    fn default() -> Self {
        ForwardSettings {
            distortion_weight: 0.0,
            depth_weight: 0.0003,
            depth_robust_voxels: 3.0,
            free_space_weight: 1.0,
            seed_from_depth: true,
            rate_scale_with_depth: 1.0,
            tv: (1e-5, 1e-5, 8),
            tv_until: 0.5,
        }
    }
}

/// The trainer's settings for a scene field, where they differ from an object's.
pub fn scene_train_config() -> TrainConfig {
    TrainConfig {
        // Empty space pruned after a tenth of the schedule, cells carved below this weight
        // before the grid grows, three coarse-to-fine stages.
        prune_after: 0.1,
        carve_weight: 1e-3,
        stages: vec![(0.0, 0.25), (0.25, 0.5), (0.5, 1.0)],
        // The distortion loss gathers each ray's weight into one interval, against floaters:
        // demo ring, 3000 steps, 27.08 dB held out without it, 27.57 with it (a forward
        // capture's is off: [`ForwardSettings`]).
        distortion_weight: 0.001,
        // Air starts at alpha_init and its density falls slowly; pruning what is not yet 1%
        // opaque per step (the trainer's default, as object fields prune) keeps the grid near
        // the surfaces (demo at 160x120, 2000 steps: the same held-out PSNR, 24.3 against 24.0
        // dB, in 60 instead of 113 CPU-s).
        // (A forward capture's own settings are [`ForwardSettings`]'.)
        free_space_weight: 0.0,
        // A ray ends once less than 1e-3 of it gets through: what lies behind changes its
        // pixel by under a quarter of an 8-bit level (renders still march to 1e-4). Flower in
        // 300 s (colour network, LLFF hold-out): 47 k -> 63 k rays/s, 18.7 -> 12.7 samples a
        // ray, held out 25.37 -> 25.44 dB (examples/results/scene_field.md, "Rays that end
        // sooner").
        render: RenderOptions {
            term_thresh: 1e-3,
            ..TrainConfig::default().render
        },
        ..TrainConfig::default()
    }
}

impl Default for SceneFitOptions {
    fn default() -> Self {
        SceneFitOptions {
            space: SpaceChoice::Auto,
            // The sparse points' depths keep a scene's surfaces where they are: without them
            // the demo scene's held-out views fell from 23.7 to 17.8 dB at 160x120 (see
            // docs/decisions.md). Spread over the surfaces between the points they give the
            // colour rays a geometry to agree on: demo ring at 320x240, 3000 steps, 19.7 ->
            // 23.6 dB held out; forward demo 27.1 -> 29.2 dB; fox unchanged (26.8 / 26.7 dB;
            // examples/results/scene_field.md). Plane-sweep stereo between neighbouring photos
            // gives far more of it (ring, 3000 steps: 23.9 -> 26.2 dB, as much as the truth's
            // dense depth).
            fit: FitOptions {
                depth: DepthMode::Stereo,
                ..FitOptions::default()
            },
            removed: None,
            dilate_px: 1,
            exclude_points: Default::default(),
            train: scene_train_config(),
            forward: ForwardSettings::default(),
            rate_scale_with_depth: 2.0,
        }
    }
}

/// Where the training views' depth targets put a surface, with the pixel's colour: a scene
/// field's surfaces start wherever stereo (or depth images) found one, not only at the sparse
/// points (a capture with poses alone, LLFF's, has none).
fn depth_seeds(views: &[View]) -> Vec<(glam::Vec3, [u8; 3])> {
    let mut seeds = Vec::new();
    for v in views {
        let Some(depth) = &v.depth else { continue };
        for (i, &t) in depth.iter().enumerate() {
            if t > 0.0 {
                let (o, d) = v.ray(i as u32);
                let p = v.rgba[i];
                seeds.push((o + d * t, [p[0], p[1], p[2]]));
            }
        }
    }
    seeds
}

/// Training views a whole-scene field is checked on after training ([`SceneFit::check_fit`]).
pub const SCENE_FIT_VIEWS: usize = 8;

/// A scene field being trained, with its views and rays, for callers that train in phases
/// (removal: train, find the hole, fill it, train on).
pub struct SceneFit {
    pub trainer: Trainer,
    /// The training views (removed objects' pixels marked in each `loss_mask`).
    pub views: Vec<View>,
    pub rays: RaySet,
    /// The space chosen from the capture, and why.
    space_choice: String,
    setup: SetupReport,
    depth_targets: usize,
    runs: Vec<RunSummary>,
    fit_check: Option<SceneFitCheck>,
    warnings: Vec<Warning>,
}

impl SceneFit {
    /// Load the views, choose the space, seed the grid from the sparse points.
    pub fn new(scene: &Scene, opts: &SceneFitOptions) -> Result<SceneFit> {
        let fit = &opts.fit;
        if fit.downscale == 0 {
            return Err(Error::invalid("--downscale must be at least 1"));
        }
        let space = choose_space(scene, opts.space, fit.downscale)?;
        let mut views = load_views(scene, &MaskSource::Opaque, fit.downscale)?;
        if let Some(removed) = &opts.removed {
            for (v, m) in views.iter_mut().zip(removed.iter()) {
                if let Some(m) = m {
                    v.loss_mask = Some(loss_mask(
                        m,
                        opts.dilate_px,
                        fit.downscale,
                        v.width,
                        v.height,
                    ));
                }
            }
        }
        // Depth targets where the loss applies (a removed object's points give none).
        let depth_targets = depth_and_training_views(&mut views, scene, fit)?;
        let mut cfg = TrainConfig {
            seed: fit.seed,
            steps: fit.schedule_steps(),
            appearance_lr: fit.appearance_lr,
            ..opts.train.clone()
        };
        let forward = matches!(space.space, crate::space::Space::Ndc(_));
        if forward {
            cfg.distortion_weight = opts.forward.distortion_weight;
            cfg.depth_weight = opts.forward.depth_weight;
            cfg.depth_robust_voxels = opts.forward.depth_robust_voxels;
            cfg.free_space_weight = opts.forward.free_space_weight;
            (cfg.tv_density, cfg.tv_color, cfg.tv_every) = opts.forward.tv;
            cfg.tv_until = opts.forward.tv_until;
        }
        if depth_targets > 0 && cfg.depth_weight > 0.0 {
            let scale = if forward {
                opts.forward.rate_scale_with_depth
            } else {
                opts.rate_scale_with_depth
            };
            cfg.lr_density *= scale;
            cfg.lr_color *= scale;
        }
        let mut seeds: Vec<(glam::Vec3, [u8; 3])> = scene
            .points
            .iter()
            .enumerate()
            .filter(|(i, _)| !opts.exclude_points.contains(i))
            .map(|(_, p)| (p.xyz.as_vec3(), p.rgb))
            .collect();
        if forward && opts.forward.seed_from_depth {
            seeds.extend(depth_seeds(&views));
        }
        let (trainer, rays, setup) = prepare_scene(&views, &space, &fit.setup, cfg, &seeds)?;
        Ok(SceneFit {
            trainer,
            views,
            rays,
            space_choice: format!("{} ({})", space.space.name(), space.why),
            setup,
            depth_targets,
            runs: Vec::new(),
            fit_check: None,
            warnings: Vec::new(),
        })
    }

    /// The space the field lives in, as chosen from the capture's layout, and why.
    pub fn space_choice(&self) -> &str {
        &self.space_choice
    }

    /// Train until `stop` says so.
    pub fn train(&mut self, stop: &StopRule, progress: &mut dyn FnMut(&StepStats)) -> RunSummary {
        let summary = run(&mut self.trainer, &self.views, &self.rays, stop, progress);
        self.runs.push(summary.clone());
        summary
    }

    /// Seconds trained so far, over every phase.
    pub fn seconds(&self) -> f64 {
        self.runs.iter().map(|r| r.seconds).sum()
    }

    /// Check the field on up to `max_views` of its training views, spread over the capture, and
    /// keep the result and its warnings for the report.
    pub fn check_fit(&mut self, max_views: usize) -> &[Warning] {
        let n = self.views.len();
        let step = n.div_ceil(max_views.max(1)).max(1);
        let views: Vec<View> = self.views.iter().step_by(step).cloned().collect();
        let renders = crate::field::eval::render_all(
            &self.trainer.field,
            &crate::field::march::RenderOptions::default(),
            &views,
        );
        let c = measure_scene_fit(&views, &renders);
        self.warnings = check_scene_fit(&c);
        self.fit_check = Some(c);
        &self.warnings
    }

    /// Rebuild the training rays after the views' loss masks or depth targets changed.
    pub fn rebuild_rays(&mut self) {
        self.rays = RaySet::build(&self.views, &self.trainer.field);
    }

    /// The trained field and its report (the phases' runs summed).
    pub fn finish(self) -> Fitted {
        let last = self.runs.last().cloned().unwrap_or_default();
        // Rates over every phase, each phase weighed by the rays it trained.
        let rays: Vec<f64> = self
            .runs
            .iter()
            .map(|r| r.rays_per_second * r.seconds)
            .collect();
        let total_rays: f64 = rays.iter().sum();
        let seconds: f64 = self.runs.iter().map(|r| r.seconds).sum();
        let summary = RunSummary {
            seconds,
            rays_per_second: total_rays / seconds.max(1e-9),
            samples_per_ray: (self.runs.iter().zip(&rays))
                .map(|(r, n)| r.samples_per_ray * n)
                .sum::<f64>()
                / total_rays.max(1e-9),
            phases: (self.runs.iter()).fold(Default::default(), |a, r| a.plus(r.phases)),
            ..last
        };
        let t = self.trainer;
        let appearance = appearance_report(&t, &self.views);
        let report = TrainReport {
            setup: Some(self.setup),
            run: summary,
            vertices: t.field.grid.num_vertices(),
            dims: t.field.grid.dims,
            memory_bytes: t.memory_bytes(),
            occupied_cells: t.field.occupied_cells(),
            depth_targets: self.depth_targets,
            finest: t.finest.clone(),
            scene_fit: self.fit_check,
            warnings: self.warnings,
            appearance,
        };
        Fitted { trainer: t, report }
    }
}

/// What a model file holds: one object's field, or a field of the scene (whole, or with objects
/// removed).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FieldKind {
    Object,
    Scene,
}

/// The notes a model file keeps about its training: what it is, where it came from (scene,
/// downscale, the world's up direction, for meshing without the scene) and what happened.
pub fn model_notes(
    kind: FieldKind,
    scene: &Scene,
    opts: &FitOptions,
    report: &TrainReport,
) -> serde_json::Value {
    let (up, up_why) = scene.up();
    // Where the training cameras stood: a mesh's colour is the field's seen from them.
    let view_centres: Vec<[f64; 3]> = scene
        .images
        .iter()
        .filter(|v| !opts.exclude_views.contains(&v.name))
        .map(|v| v.pose.center().to_array())
        .collect();
    serde_json::json!({
        "kind": kind,
        "downscale": opts.downscale,
        "setup": report.setup,
        "run": report.run,
        "scene": scene.source,
        "up": up.to_array(),
        "up_why": up_why,
        "depth": opts.depth,
        "depth_targets": report.depth_targets,
        "appearance": report.appearance,
        "view_centres": view_centres,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_whole_budget_lifts_the_step_cap_and_the_plateau_stop() {
        let capped = FitOptions {
            time_budget: Some(60.0),
            ..Default::default()
        };
        assert_eq!(capped.schedule_steps(), capped.steps);
        assert!(capped.stop_rule().plateau_db.is_some());
        let whole = FitOptions {
            whole_budget: true,
            ..capped.clone()
        };
        assert!(whole.schedule_steps() > 1000 * whole.steps);
        assert!(whole.stop_rule().plateau_db.is_none());
        assert_eq!(whole.stop_rule().time_budget, Some(60.0));
        // Without a budget there is nothing to fill: the steps and the plateau stop as before.
        let no_budget = FitOptions {
            time_budget: None,
            ..whole
        };
        assert_eq!(no_budget.schedule_steps(), no_budget.steps);
        assert!(no_budget.stop_rule().plateau_db.is_some());
    }
}
