//! Putting training together: views + masks → box (visual hull) → grid size (pixel footprint,
//! memory budget) → carved occupancy → rays pruned to the box → a [`Trainer`] run until the step
//! count, a time budget or a PSNR plateau.

use super::bounds::{fit_budget, object_box, pixel_footprint, visual_hull};
use super::colour_net::{MAX_HIDDEN, MAX_INPUTS};
use super::model::{Field, FieldConfig, MAX_CHANNELS};
use super::rays::RaySet;
use super::train::{stage_dims, StepStats, TrainConfig, Trainer};
use super::view::View;
use crate::error::Result;
use crate::space::layout::SpaceSetup;
use crate::space::Space;
use glam::Vec3;
use serde::Serialize;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct SetupConfig {
    pub sh_degree: u32,
    /// Colour from this many feature channels through a network of `net_hidden` units
    /// ([`super::colour_net`]; the direction enters as its SH basis to `sh_degree`); 0: SH
    /// coefficients on the grid.
    pub net_features: usize,
    pub net_hidden: usize,
    /// The SH degree of the view direction a colour network takes (0-3; `sh_degree` is SH
    /// colour's). Lego 200^2 in 300 s, degree 1 / 2 / 3: 33.31 / 33.52 / 33.55 dB; 800^2 in 20
    /// min 33.42 -> 33.56 (1 -> 3); shorter runs lose a little to the fewer steps (400^2 300 s
    /// 32.84 -> 32.75). Its worst test views miss the base plate's gloss seen from above
    /// (examples/results/field.md, "The network's view input").
    pub net_sh_degree: u32,
    /// A colour network also takes the view direction reflected about the density's normal, to
    /// the same SH degree ([`super::colour_net::reflect`]). Off: lego 800^2 in 20 min scored
    /// 34.39 dB with it, within three default runs' 34.35-34.58, in 11% fewer steps
    /// (examples/results/field.md, "Two inputs for the view-dependent colour").
    pub net_reflect: bool,
    /// Units of a colour network's second hidden layer (0: one layer; DVGO's has two). Lego
    /// 800^2 in 20 min with 32: 34.53 dB before the mean of the last parameters (default runs
    /// 34.35-34.58), then 34.59, 34.65, 34.51 and 34.61 with it (one layer: 34.42-34.52 over four
    /// runs), the near views gaining most, in ~9% fewer steps (examples/results/field.md,
    /// "Two inputs for the view-dependent colour" and "A second hidden layer by default").
    pub net_hidden2: usize,
    /// Views of fewer pixels than this keep one hidden layer (`net_hidden2` is not taken).
    /// The second layer multiplies the network's work a coloured sample by ~4, which is hidden
    /// where the finest grid is large and each step waits on its memory (lego 800^2: 9% fewer
    /// steps) but not on a grid that small views make small: lego 200^2 in 60 s took 8 745
    /// steps against 15 170 and scored 32.99 dB against 33.37 (examples/results/field.md, "A
    /// second hidden layer by default").
    pub net_hidden2_min_view_pixels: usize,
    /// An object field trained on fewer views than this takes SH colour whatever
    /// `net_features` says: the network's view dependence needs many views to hold between
    /// them. Lego (100 views) gains 0.5-0.6 dB held out at 400^2 and 800^2 from it; the demo
    /// sphere (30 views) loses 0.9 dB and fox's head (42) 0.24 (examples/results/field.md,
    /// "Colour by view count"). Scene fields take `scene_net_features`.
    pub net_min_views: usize,
    /// A scene field's colour network features (Some(0): SH colour; None: the space's default,
    /// [`scene_net_default`]), one hidden layer of `scene_net_hidden`, the view direction to
    /// `net_sh_degree`.
    pub scene_net_features: Option<usize>,
    /// A scene field's colour network's hidden units (one layer), DVGO's LLFF width. 64
    /// against the object field's 32 on the LLFF captures in 600 s: fern / flower / horns
    /// 24.05 / 25.79 / 25.76 -> 24.15 / 25.91 / 25.82 dB held out, at 13-23% fewer rays a second
    /// (examples/results/scene_field.md, twenty-second session, "A wider colour network").
    pub scene_net_hidden: usize,
    /// An object field trained on fewer views keeps its schedule when the memory budget
    /// coarsens the first stage ([`TrainConfig::stages_when_capped`] is not taken): a finer
    /// finest grid holds between many views but overfits few. Lego (100 views) 800^2 in 20
    /// min 32.96 -> 33.72 dB with it; fox's head (42 views) 21.55 -> 21.49 dB and 347 -> 584
    /// MiB (examples/results/field.md, "A coarser start where the budget binds").
    pub fine_min_views: usize,
    /// Voxels per pixel footprint at the median viewing distance.
    pub voxels_per_pixel: f32,
    /// The training a run affords, in passes over its training pixels, from which a field
    /// with a colour network is sized as the large model: `large_net` (features, hidden
    /// units) at `large_voxels_per_pixel`. More parameters fit better only when there are the
    /// steps to fit them: lego 200^2 in 300 s (~22 passes) 33.65 dB with the usual model,
    /// 34.05 with the large one; in 60 s (~4.5 passes) the usual 32.40, the large network alone
    /// 31.96 (examples/results/field.md, "A larger model for a longer run").
    pub large_model_passes: f64,
    /// The large model's network: features, hidden units and second-layer units (measured
    /// with one layer; the second was measured on the usual model only).
    pub large_net: (usize, usize, usize),
    pub large_voxels_per_pixel: f32,
    /// Bytes for the grid and its optimiser state.
    pub memory_budget: usize,
    /// The share of `memory_budget` the first (dense) stage may take. The finest stage has 8x
    /// its cells at half its voxel and keeps only the occupied bricks, so it needs the rest:
    /// a first stage that took the whole budget left the finest no room to grow (lego 800^2:
    /// every step at the finest grid the budget allowed, 44 k steps in 20 min).
    pub first_stage_share: f32,
    /// Box padding, as a fraction of its size per side.
    pub pad: f32,
    pub alpha_init: f32,
}

impl SetupConfig {
    /// Training memory per grid vertex ([`super::train::bytes_per_vertex`]).
    pub fn bytes_per_vertex(&self) -> usize {
        super::train::bytes_per_vertex(self.channels())
    }

    /// Whether the colour settings can be built: a clear error, not a panic, for user input.
    pub fn check(&self) -> Result<()> {
        if self.sh_degree > 2 || self.net_sh_degree > 3 {
            return Err(crate::error::Error::invalid(format!(
                "SH colour goes up to degree 2 and a colour network's view input up to 3 (asked for {} and {})",
                self.sh_degree, self.net_sh_degree
            )));
        }
        // The view direction's basis, and the reflected direction's as well when asked for.
        let bases = if self.net_reflect { 2 } else { 1 };
        let direction_inputs = bases * super::sh::sh_coeffs(self.net_sh_degree);
        let most = (MAX_INPUTS - direction_inputs).min(MAX_CHANNELS - 1);
        let nets = [
            (self.net_features, self.net_hidden),
            (self.scene_net_features.unwrap_or(0), self.scene_net_hidden),
        ];
        for (features, hidden) in nets {
            if features > most || (features > 0 && hidden == 0) {
                return Err(crate::error::Error::invalid(format!(
                    "a colour network takes 1 to {most} features and 1 to {MAX_HIDDEN} hidden units at SH degree {} (asked for {} and {})",
                    self.net_sh_degree, features, hidden
                )));
            }
        }
        let widest = self
            .net_hidden
            .max(self.net_hidden2)
            .max(self.scene_net_hidden);
        if widest > MAX_HIDDEN {
            return Err(crate::error::Error::invalid(format!(
                "a colour network takes at most {MAX_HIDDEN} hidden units a layer (asked for {widest})"
            )));
        }
        Ok(())
    }

    /// These settings for an object trained on `views` views of `pixels` pixels in all for
    /// `steps` steps of `batch` rays or `time_budget` seconds, whichever ends first (SH colour
    /// under `net_min_views`; the large model where the run affords
    /// [`SetupConfig::large_model_passes`]), and what colours it, for its report.
    pub fn for_views(
        &self,
        views: usize,
        pixels: usize,
        steps: usize,
        batch: usize,
        time_budget: Option<f64>,
    ) -> (SetupConfig, String) {
        let mut s = self.clone();
        if self.net_features > 0 && views < self.net_min_views {
            s.net_features = 0;
            let why = format!(
                "{} ({views} views, fewer than the {} a colour network needs)",
                s.colour(),
                self.net_min_views
            );
            return (s, why);
        }
        let mut why = format!("{views} views");
        if s.net_features > 0 {
            // The field's one SH degree is the network's view input from here on.
            s.sh_degree = s.net_sh_degree;
            let passes = passes(pixels, steps, batch, time_budget);
            if passes >= self.large_model_passes {
                (s.net_features, s.net_hidden, s.net_hidden2) = self.large_net;
                s.voxels_per_pixel = self.large_voxels_per_pixel;
                why += &format!(
                    "; the large model: ~{passes:.0} passes over the pixels, at least {}",
                    self.large_model_passes
                );
            } else if s.net_hidden2 > 0 && pixels / views.max(1) < self.net_hidden2_min_view_pixels
            {
                s.net_hidden2 = 0;
                why += &format!(
                    "; one hidden layer: views of fewer than {} pixels",
                    self.net_hidden2_min_view_pixels
                );
            }
        }
        let why = format!("{} ({why})", s.colour());
        (s, why)
    }

    /// What colours the field.
    fn colour(&self) -> String {
        match self.net_features {
            0 => format!("SH degree {}", self.sh_degree),
            f => format!(
                "network: {f} features, {} hidden units{}, view direction{} to SH degree {}",
                self.net_hidden,
                match self.net_hidden2 {
                    0 => String::new(),
                    h => format!(" then {h}"),
                },
                if self.net_reflect {
                    " and its reflection"
                } else {
                    ""
                },
                self.net_sh_degree
            ),
        }
    }

    /// Grid channels per vertex: density and the colour's.
    pub fn channels(&self) -> usize {
        match self.net_features {
            0 => 1 + 3 * super::sh::sh_coeffs(self.sh_degree),
            f => 1 + f,
        }
    }
}

/// Passes over `pixels` that `steps` steps of `batch` rays make, or fewer if the time budget
/// ends first (at [`NOMINAL_RAYS_PER_SECOND`]).
fn passes(pixels: usize, steps: usize, batch: usize, time_budget: Option<f64>) -> f64 {
    let mut rays = steps as f64 * batch as f64;
    if let Some(secs) = time_budget {
        rays = rays.min(secs * NOMINAL_RAYS_PER_SECOND);
    }
    rays / pixels.max(1) as f64
}

impl Default for SetupConfig {
    fn default() -> Self {
        SetupConfig {
            sh_degree: 1,
            net_features: 8,
            net_hidden: 32,
            net_sh_degree: 3,
            net_reflect: false,
            net_hidden2: 32,
            net_hidden2_min_view_pixels: 100_000,
            net_min_views: 80,
            scene_net_features: None,
            scene_net_hidden: 64,
            fine_min_views: 80,
            voxels_per_pixel: 1.0,
            large_model_passes: 15.0,
            large_net: (12, 64, 0),
            large_voxels_per_pixel: 1.3,
            memory_budget: 1 << 30,
            first_stage_share: 0.25,
            pad: 0.02,
            alpha_init: 0.01,
        }
    }
}

/// Training rays a second that a time budget is taken to buy when sizing the model
/// ([`SetupConfig::large_model_passes`]): lego 200^2 with the usual model on the 2-core machine
/// the defaults were measured on (47 786 steps of 2048 rays in 300 s). A constant, not a
/// measurement: a faster machine takes the large model later than it could, a slower one
/// sooner.
pub const NOMINAL_RAYS_PER_SECOND: f64 = 3.0e5;

/// What the setup chose, for the log and the benchmark JSON.
#[derive(Clone, Debug, Serialize)]
pub struct SetupReport {
    /// Where the grid lives; its box and voxel are in this space's coordinates.
    pub space: Space,
    pub box_min: [f32; 3],
    pub box_max: [f32; 3],
    pub voxel: f32,
    pub final_dims: [usize; 3],
    pub final_vertices: usize,
    pub why: String,
    pub rays_total: usize,
    pub rays_kept: usize,
    pub pruned_fraction: f64,
    pub hull_cells: usize,
    pub first_stage_cells: usize,
}

/// Build the trainer for an object's `views`: the box from its sparse `points` cut to the
/// masks' visual hull ([`object_box`]), occupancy carved by the hull, rays that miss the box
/// pruned. The model is sized for a run of `cfg.steps` steps or `time_budget` seconds.
pub fn prepare(
    views: &[View],
    points: &[Vec3],
    setup: &SetupConfig,
    mut cfg: TrainConfig,
    time_budget: Option<f64>,
) -> Result<(Trainer, RaySet, SetupReport)> {
    setup.check()?;
    let pixels = views.iter().map(|v| v.rgba.len()).sum();
    let (setup, colour) = setup.for_views(views.len(), pixels, cfg.steps, cfg.batch, time_budget);
    let setup = &setup;
    let (lo, hi, box_why) = object_box(views, points, setup.pad)?;
    let (footprint, why) = pixel_footprint(views, lo, hi);
    let mut why = format!("{box_why}; {why}; colour: {colour}");
    if setup.net_features > 0 {
        cfg.lr_final = cfg.lr_final_network;
        cfg.average_from = cfg.average_from_network;
        why += &format!(
            "; learning rates decay to {} of their start (a network field)",
            cfg.lr_final
        );
        if cfg.average_from < 1.0 {
            why += &format!(
                ", and it ends on the mean of its parameters from {:.0}% of the run on",
                cfg.average_from * 100.0
            );
        }
    }
    let few_views = (views.len() < setup.fine_min_views).then(|| {
        format!(
            "{} views, fewer than the {} a finer finest grid needs",
            views.len(),
            setup.fine_min_views
        )
    });
    let plan = GridPlan::new(lo, hi, footprint, why, setup, &mut cfg, few_views);
    let mut field = plan.field(setup, Space::Box, &cfg);
    let dims0 = field.grid.dims;
    let cells = [dims0[0] - 1, dims0[1] - 1, dims0[2] - 1];
    let keep = visual_hull(views, lo, field.box_max, cells);
    for (c, &k) in keep.iter().enumerate() {
        if !k {
            let plane = cells[0] * cells[1];
            field.set_occupied([c % cells[0], (c / cells[0]) % cells[1], c / plane], false);
        }
    }
    field.release_free_bricks();
    let hull_cells = keep.iter().filter(|&&k| k).count();
    let rays = RaySet::build(views, &field);
    let report = plan.report(&field, &rays, hull_cells);
    Ok((plan.trainer(field, setup, cfg), rays, report))
}

/// A scene field's colour network features when none are asked for: 9 for a forward capture
/// (NDC), SH colour in the other spaces. On the LLFF captures the network fits and holds out
/// better at about the same rays a second: fern 23.04 -> 23.45 dB held out in 300 s, horns
/// 24.50 -> 25.10 in 600 s, fern / flower 22.66 -> 23.13 / 24.08 -> 24.89 at 3000 steps.
/// On the demo ring (box) it gained 0.5 dB but at 0.8x the rays a second, and removal and
/// the unbounded captures were not measured with it (examples/results/scene_field.md, "A
/// colour network and shorter rays on forward captures").
pub fn scene_net_default(space: &Space) -> usize {
    match space {
        Space::Ndc(_) => 9,
        _ => 0,
    }
}

/// Build the trainer for a scene field in `space` (box in space coordinates, the pixel
/// footprint there): every cell occupied until pruned, rays that carry no loss (alpha 0: a
/// removed object's pixels) left out.
pub fn prepare_scene(
    views: &[View],
    space: &SpaceSetup,
    setup: &SetupConfig,
    mut cfg: TrainConfig,
    seeds: &[(Vec3, [u8; 3])],
) -> Result<(Trainer, RaySet, SetupReport)> {
    setup.check()?;
    let net = setup
        .scene_net_features
        .unwrap_or_else(|| scene_net_default(&space.space));
    let setup = &SetupConfig {
        net_features: net,
        // The network's view input is the field's SH degree; one hidden layer.
        sh_degree: if net > 0 {
            setup.net_sh_degree
        } else {
            setup.sh_degree
        },
        net_hidden: setup.scene_net_hidden,
        net_hidden2: 0,
        ..setup.clone()
    };
    let why = format!(
        "{}; one pixel covers {:.5} space units",
        space.why, space.pixel_footprint
    );
    let plan = GridPlan::new(
        space.box_min,
        space.box_max,
        space.pixel_footprint,
        why,
        setup,
        &mut cfg,
        None,
    );
    let mut field = plan.field(setup, space.space.clone(), &cfg);
    clear_near_cameras(&mut field, views, space.near_clip);
    field.release_free_bricks();
    field.seed_surfaces(seeds);
    let rays = RaySet::build(views, &field);
    if rays.rays.is_empty() {
        return Err(crate::error::Error::invalid(
            "no pixel is left to train the scene field on (every view is covered by removed objects)",
        ));
    }
    let report = plan.report(&field, &rays, field.num_cells());
    Ok((plan.trainer(field, setup, cfg), rays, report))
}

/// Free the cells within `radius` (world units) of any view's camera, where nothing of the scene
/// stands (see [`SpaceSetup::near_clip`]). Box and contracted spaces (cameras lie in the
/// contraction's linear inner ball); an NDC grid starts in front of the cameras anyway.
fn clear_near_cameras(field: &mut Field, views: &[View], radius: f32) {
    let scale = match &field.space {
        Space::Box => 1.0,
        Space::Unbounded { radius: r, .. } => 1.0 / r,
        Space::Ndc(_) => return,
    };
    let r = radius * scale / field.voxel;
    if r <= 0.0 {
        return;
    }
    let cells = field.grid.dims.map(|d| d - 1);
    for v in views {
        let g = field.to_grid(v.center());
        let lo = [0, 1, 2].map(|a| (g[a] - r - 1.0).floor().max(0.0) as usize);
        let hi = [0, 1, 2].map(|a| ((g[a] + r + 1.0).ceil().max(0.0) as usize).min(cells[a]));
        for z in lo[2]..hi[2] {
            for y in lo[1]..hi[1] {
                for x in lo[0]..hi[0] {
                    let c = glam::Vec3::new(x as f32, y as f32, z as f32) + 0.5;
                    if (c - g).length() <= r {
                        field.set_occupied([x, y, z], false);
                    }
                }
            }
        }
    }
}

/// A grid over a box: its finest dims (cells a multiple of 4 so coarse stages nest exactly) and
/// the box trimmed to them.
struct GridPlan {
    lo: Vec3,
    hi: Vec3,
    voxel: f32,
    final_dims: [usize; 3],
    why: String,
}

impl GridPlan {
    /// The finest voxel: `footprint / voxels_per_pixel`, made coarser only when the first stage
    /// (dense, at the schedule's first scale) would not fit its share of the memory budget
    /// ([`SetupConfig::first_stage_share`]). Then, if [`TrainConfig::stages_when_capped`]
    /// starts coarser, the schedule becomes that one, so the finest stage is not held to the
    /// first's resolution times the usual ratio; unless `keep_schedule` gives a reason not to
    /// (the report then says it). The finest stage
    /// is sparse: when it starts, the trainer fits its resolution to the budget by the bricks
    /// the occupied cells need ([`Trainer::budget`]).
    fn new(
        lo: Vec3,
        hi: Vec3,
        footprint: f32,
        why: String,
        setup: &SetupConfig,
        cfg: &mut TrainConfig,
        keep_schedule: Option<String>,
    ) -> Self {
        let bytes_per_vertex = setup.bytes_per_vertex();
        let first_scale = |st: &[(f32, f32)]| st.first().map(|s| s.1).unwrap_or(1.0).min(1.0);
        let target = footprint / setup.voxels_per_pixel;
        let share =
            (setup.memory_budget as f64 * setup.first_stage_share.clamp(0.01, 1.0) as f64) as usize;
        let mut coarse = first_scale(&cfg.stages);
        let (fit, _) = fit_budget(
            hi - lo,
            target / coarse,
            String::new(),
            bytes_per_vertex,
            share,
        );
        let capped = fit > target / coarse;
        let mut why = format!(
            "{why}; {} voxel(s) per pixel -> voxel {target:.5}",
            setup.voxels_per_pixel
        );
        if capped && first_scale(&cfg.stages_when_capped) < coarse {
            if let Some(reason) = keep_schedule {
                why += &format!("; the schedule stays as asked ({reason})");
            } else {
                cfg.stages = cfg.stages_when_capped.clone();
                coarse = first_scale(&cfg.stages);
                let stages: Vec<String> = cfg
                    .stages
                    .iter()
                    .map(|(at, s)| format!("{s} from {at}"))
                    .collect();
                why += &format!(
                    "; the first stage does not fit its share of the memory at that resolution, so the schedule is {}",
                    stages.join(", ")
                );
            }
        }
        why += &format!(
            "; the first stage at {coarse} of that resolution is dense, within {} of the memory",
            setup.first_stage_share
        );
        let (coarse_voxel, mut why) =
            fit_budget(hi - lo, target / coarse, why, bytes_per_vertex, share);
        let voxel = coarse_voxel * coarse;
        let e = hi - lo;
        let final_dims = [e.x, e.y, e.z].map(|l| ((l / voxel).ceil() as usize).div_ceil(4) * 4 + 1);
        let vertices: usize = final_dims.iter().product();
        why += &format!(
            "; box {:.3} x {:.3} x {:.3} -> at most {} x {} x {} vertices ({:.1} M if dense); the finest stage keeps the bricks it needs within the {} MiB budget",
            e.x,
            e.y,
            e.z,
            final_dims[0],
            final_dims[1],
            final_dims[2],
            vertices as f64 / 1e6,
            setup.memory_budget >> 20
        );
        let hi = lo
            + Vec3::new(
                (final_dims[0] - 1) as f32,
                (final_dims[1] - 1) as f32,
                (final_dims[2] - 1) as f32,
            ) * voxel;
        GridPlan {
            lo,
            hi,
            voxel,
            final_dims,
            why,
        }
    }

    fn trainer(&self, field: Field, setup: &SetupConfig, cfg: TrainConfig) -> Trainer {
        let mut t = Trainer::new(field, self.final_dims, cfg);
        t.budget = Some(setup.memory_budget);
        t
    }

    /// The field at the first coarse-to-fine stage.
    fn field(&self, setup: &SetupConfig, space: Space, cfg: &TrainConfig) -> Field {
        let first_scale = cfg.stages.first().map(|s| s.1).unwrap_or(1.0);
        let net = setup.net_features > 0;
        // A network's grid holds [density, features]: built at SH degree 0 first, not with SH
        // colour's channels (49 at the network's degree 3) only to replace them.
        let mut f = Field::new(
            FieldConfig {
                sh_degree: if net { 0 } else { setup.sh_degree },
                alpha_init: setup.alpha_init,
                base_voxel: self.voxel,
            },
            self.lo,
            self.hi,
            stage_dims(self.final_dims, first_scale),
        );
        if net {
            f.config.sh_degree = setup.sh_degree;
            f = f.with_colour_net(
                setup.net_features,
                [setup.net_hidden, setup.net_hidden2],
                setup.net_reflect,
                cfg.seed,
            );
        }
        f.space = space;
        f
    }

    fn report(&self, field: &Field, rays: &RaySet, hull_cells: usize) -> SetupReport {
        SetupReport {
            space: field.space.clone(),
            box_min: self.lo.to_array(),
            box_max: field.box_max.to_array(),
            voxel: self.voxel,
            final_dims: self.final_dims,
            final_vertices: self.final_dims.iter().product(),
            why: self.why.clone(),
            rays_total: rays.total,
            rays_kept: rays.rays.len(),
            pruned_fraction: rays.pruned_fraction(),
            hull_cells,
            first_stage_cells: field.num_cells(),
        }
    }
}

/// When to stop.
#[derive(Clone, Debug)]
pub struct StopRule {
    /// Seconds of training (the schedule follows the time spent when it is further along than
    /// the steps).
    pub time_budget: Option<f64>,
    /// Stop when the batch PSNR (averaged over `window` steps) rose by less than this many dB
    /// over the last window, once the grid is at its finest.
    pub plateau_db: Option<f32>,
    pub window: usize,
    /// End this run (one phase of a longer schedule) at this step or after this many seconds
    /// of the budget, without changing the schedule.
    pub until_step: Option<usize>,
    pub until_seconds: Option<f64>,
    /// Seconds of the budget spent by earlier phases.
    pub seconds_before: f64,
    /// End on the last parameters even where the run kept their mean
    /// ([`TrainConfig::average_from`](super::train::TrainConfig::average_from)); a benchmark
    /// that scores both takes the mean itself ([`Trainer::take_average`]).
    pub keep_last: bool,
}

impl StopRule {
    /// The rule of `objnerf train`: the budget, or a plateau at the finest grid.
    pub fn for_budget(time_budget: Option<f64>) -> StopRule {
        StopRule {
            time_budget,
            ..Default::default()
        }
    }
}

impl Default for StopRule {
    fn default() -> Self {
        StopRule {
            time_budget: None,
            plateau_db: Some(0.01),
            window: 500,
            until_step: None,
            until_seconds: None,
            seconds_before: 0.0,
            keep_last: false,
        }
    }
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct RunSummary {
    pub steps: usize,
    pub seconds: f64,
    pub rays_per_second: f64,
    /// Samples a ray kept, the mean over the run's steps.
    pub samples_per_ray: f64,
    /// Where the seconds went.
    pub phases: PhaseSeconds,
    pub final_psnr: f32,
    pub stopped_by: String,
    /// Snapshots of the parameters whose mean the run ended on (0: it ended on the last ones).
    pub averaged: u32,
}

/// Where a run's seconds went, by the trainer's clocks ([`Trainer::phase_secs`]). The rest of
/// [`RunSummary::seconds`] is growing the grid between stages and the loop around the steps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PhaseSeconds {
    /// Rays marched forward and back, with the steps of the network and of the views'
    /// colour corrections.
    pub rays: f64,
    /// The gradient scattered into the grid, with Adam on its touched vertices when TV is off.
    pub scatter: f64,
    /// TV and Adam, when TV is on.
    pub tv: f64,
    /// Pruning the occupancy and the running mean of the parameters.
    pub upkeep: f64,
}

impl PhaseSeconds {
    /// The seconds between two readings of [`Trainer::phase_secs`].
    fn between(before: [f64; 4], after: [f64; 4]) -> PhaseSeconds {
        let d = |i: usize| after[i] - before[i];
        PhaseSeconds {
            rays: d(0),
            scatter: d(1),
            tv: d(2),
            upkeep: d(3),
        }
    }

    /// Both runs' seconds, part by part.
    pub fn plus(self, o: PhaseSeconds) -> PhaseSeconds {
        PhaseSeconds {
            rays: self.rays + o.rays,
            scatter: self.scatter + o.scatter,
            tv: self.tv + o.tv,
            upkeep: self.upkeep + o.upkeep,
        }
    }
}

/// Train until `trainer.cfg.steps`, the time budget or a plateau; `progress` sees every step
/// (with its time and rate filled in).
pub fn run(
    trainer: &mut Trainer,
    views: &[View],
    rays: &RaySet,
    stop: &StopRule,
    mut progress: impl FnMut(&StepStats),
) -> RunSummary {
    let start = Instant::now();
    let first_step = trainer.step;
    let phases_before = trainer.phase_secs;
    let mut samples_per_ray_sum = 0.0f64;
    let mut stopped_by = "steps".to_string();
    let mut window_sum = 0.0f64;
    let mut last_window: Option<f64> = None;
    let mut last = StepStats::default();
    let w = stop.window.max(1);
    let last_step = stop.until_step.unwrap_or(usize::MAX).min(trainer.cfg.steps);
    let spent = || stop.seconds_before + start.elapsed().as_secs_f64();
    while trainer.step < last_step {
        if let Some(b) = stop.time_budget {
            trainer.time_frac = (spent() / b.max(1e-9)) as f32;
        }
        last = trainer.train_step(views, rays);
        let secs = start.elapsed().as_secs_f64();
        last.seconds = secs;
        last.rays_per_second =
            ((trainer.step - first_step) * trainer.cfg.batch) as f64 / secs.max(1e-9);
        progress(&last);
        samples_per_ray_sum += last.samples_per_ray as f64;
        window_sum += last.psnr as f64;
        if trainer.step % w == 0 {
            let mean = window_sum / w as f64;
            window_sum = 0.0;
            let at_finest = trainer.field.grid.dims == trainer.final_dims;
            if let (Some(db), Some(prev)) = (stop.plateau_db, last_window) {
                if at_finest && mean - prev < db as f64 {
                    stopped_by = "plateau".into();
                    break;
                }
            }
            last_window = at_finest.then_some(mean);
        }
        if stop.time_budget.is_some_and(|b| spent() >= b) {
            stopped_by = "time budget".into();
            break;
        }
        if stop.until_seconds.is_some_and(|b| spent() >= b) {
            stopped_by = "phase time".into();
            break;
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    // A phase of a longer schedule goes on from its last parameters; the end of the schedule
    // takes their mean where one was kept.
    let phase_end =
        stopped_by == "phase time" || (stopped_by == "steps" && trainer.step < trainer.cfg.steps);
    let averaged = if phase_end || stop.keep_last {
        0
    } else {
        trainer.take_average()
    };
    RunSummary {
        steps: trainer.step,
        seconds,
        rays_per_second: ((trainer.step - first_step) * trainer.cfg.batch) as f64
            / seconds.max(1e-9),
        samples_per_ray: samples_per_ray_sum / (trainer.step - first_step).max(1) as f64,
        phases: PhaseSeconds::between(phases_before, trainer.phase_secs),
        final_psnr: last.psnr,
        stopped_by,
        averaged,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lego 200^2: 100 views of 200 x 200 pixels.
    const PIXELS: usize = 100 * 200 * 200;

    #[test]
    fn a_long_run_on_many_views_takes_the_large_model() {
        let setup = SetupConfig::default();
        let uncapped = crate::fit::UNCAPPED_STEPS;
        // 300 s: ~22 passes; 60 s: ~4.5.
        let (long, why) = setup.for_views(100, PIXELS, uncapped, 2048, Some(300.0));
        assert_eq!((long.net_features, long.net_hidden), (12, 64), "{why}");
        assert_eq!(long.voxels_per_pixel, 1.3);
        assert!(why.contains("large model"), "{why}");
        assert_eq!(long.net_hidden2, 0);
        assert!(!why.contains("one hidden layer"), "{why}");
        let (short, why) = setup.for_views(100, PIXELS, uncapped, 2048, Some(60.0));
        assert_eq!((short.net_features, short.net_hidden), (8, 32));
        assert_eq!(short.voxels_per_pixel, 1.0);
        // Views of 200 x 200 pixels keep one layer; 800 x 800 take the second.
        assert_eq!(short.net_hidden2, 0, "{why}");
        assert!(why.contains("one hidden layer"), "{why}");
        let (large_views, why) = setup.for_views(100, 16 * PIXELS, uncapped, 2048, Some(1200.0));
        assert_eq!(
            (
                large_views.net_features,
                large_views.net_hidden,
                large_views.net_hidden2
            ),
            (8, 32, 32),
            "{why}"
        );
        // A step count caps the passes whatever the budget (20 000 steps: ~10 passes).
        let (capped, _) = setup.for_views(100, PIXELS, 20_000, 2048, Some(300.0));
        assert_eq!(capped.net_features, 8);
        // Without a budget the steps alone decide.
        let (steps, _) = SetupConfig::default().for_views(100, PIXELS, 40_000, 2048, None);
        assert_eq!(steps.net_hidden, 64);
        // Few views keep SH colour and their grid whatever the budget.
        let (few, _) = setup.for_views(30, PIXELS, uncapped, 2048, Some(3000.0));
        assert_eq!((few.net_features, few.voxels_per_pixel), (0, 1.0));
        // 'inf': never.
        let never = SetupConfig {
            large_model_passes: f64::INFINITY,
            ..SetupConfig::default()
        };
        assert_eq!(
            never
                .for_views(100, PIXELS, uncapped, 2048, Some(3000.0))
                .0
                .net_hidden,
            32
        );
    }

    #[test]
    fn a_scene_network_is_checked_with_its_own_width() {
        let scene = |features, hidden| SetupConfig {
            scene_net_features: Some(features),
            scene_net_hidden: hidden,
            ..SetupConfig::default()
        };
        assert!(scene(9, 64).check().is_ok());
        assert!(scene(0, 0).check().is_ok(), "SH colour needs no width");
        assert!(scene(9, 0).check().is_err());
        let wide = scene(9, MAX_HIDDEN + 1).check().unwrap_err().to_string();
        assert!(wide.contains(&format!("{}", MAX_HIDDEN + 1)), "{wide}");
    }
}
