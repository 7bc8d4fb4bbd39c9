//! What a training run is told (`TrainConfig`) and what each step reports (`StepStats`).

use crate::field::march::RenderOptions;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrainConfig {
    pub seed: u64,
    /// Rays per step.
    pub batch: usize,
    /// The batch is drawn in runs of this many neighbouring pixels of a row
    /// ([`RaySet::draw_runs`]; 1: every ray drawn on its own, the default; 0: [`AUTO_RAY_RUN`]
    /// while the grid's parameters outgrow the cache, else 1).
    ///
    /// [`RaySet::draw_runs`]: crate::field::rays::RaySet::draw_runs
    pub ray_run: usize,
    /// Most steps; the learning rates decay over this many.
    pub steps: usize,
    pub lr_density: f32,
    pub lr_color: f32,
    /// Learning rate of a colour network's weights ([`crate::field::colour_net`]).
    pub lr_net: f32,
    /// Learning rates fall to this fraction at `steps` (exponentially).
    pub lr_final: f32,
    /// `lr_final` for an object field coloured by a network (seen from many views: lego). Its
    /// sparse Adam touches a vertex only when a drawn ray crosses it: at lego 800^2 a surface
    /// vertex about once in 200 steps, so each touch is a step of about the learning rate and
    /// a steep decay leaves the late touches too small to finish the fine detail. Final
    /// fraction 0.03 / 0.1 / 0.3: lego 800^2 in 300 s 31.94 / 32.27 / 32.56 dB, 200^2 in 60 s
    /// 32.56 / 32.94 / 32.94, but 200^2 in 300 s (~22 passes over its pixels) 34.06 / 34.14 /
    /// 33.71: a long run still wants the decay (examples/results/field.md, "Learning rates that
    /// decay less"). That was before a network field ended on the mean of its last parameters
    /// ([`TrainConfig::average_from_network`]): the mean takes out the scatter a larger late
    /// step leaves, so 0.3 now pays where 0.1 was chosen: lego 800^2 in 20 min 34.71 and 34.69
    /// dB against 34.51-34.65 in six runs at 0.1 (the mean 0.27 dB over the same run's last
    /// parameters, against 0.06; "The mean with a shallower decay"). The demo objects and fox
    /// (SH colour, fewer views) keep `lr_final`.
    pub lr_final_network: f32,
    pub beta1: f32,
    pub beta2: f32,
    /// Total-variation weights (density, colour), applied to the voxels a batch touches, as
    /// DVGO's (`total_variation_add_grad`: the same weights mean the same pull; 0: off).
    pub tv_density: f32,
    pub tv_color: f32,
    /// TV on every this many steps, at this many times its weight (the same pull in
    /// expectation): the pass over every touched vertex's neighbours cost half a run's steps
    /// on fern, and the steps between keep the optimiser's pass fused with the scatter (1:
    /// every step, as DVGO).
    pub tv_every: usize,
    /// TV stops once this fraction of the schedule has passed (1: the whole run, as DVGO's
    /// `tv_before`).
    pub tv_until: f32,
    /// Weight of the squared alpha error (the colour loss on a random background already
    /// supervises alpha; this sharpens the silhouette).
    pub alpha_weight: f32,
    /// Weight of the squared error of the expected depth of the opaque part of a ray
    /// (sum w t / sum w) against depth targets (lambda_d),
    /// the error measured in finest voxels so the weight does not depend on the scene's units
    /// (in metres, a 1 cm error squared is 1e-4: weight 0.1 left the demo's depth unchanged),
    /// and how many rays with a depth target are added to each batch.
    pub depth_weight: f32,
    pub depth_batch: usize,
    /// Past about this many finest voxels a depth error pulls less the larger it is (Cauchy's
    /// c^2 ln(1 + (e/c)^2), the square below): a stereo target far off, as on a wall with no
    /// texture, is then outvoted by the photos, while one near the surface still holds it
    /// (0: the plain square).
    pub depth_robust_voxels: f32,
    /// Rays drawn a step from [`RaySet::focus`] when it holds any.
    ///
    /// [`RaySet::focus`]: crate::field::rays::RaySet::focus
    pub focus_batch: usize,
    /// Weight of the distortion loss ([`distortion`], distances in finest voxels) per ray.
    ///
    /// [`distortion`]: crate::field::march::distortion
    pub distortion_weight: f32,
    /// Weight of the sparsity loss per ray (the sum of its kept samples' alphas,
    /// [`RayGrad::alpha_each`]): of two ways to explain a view, the one with less matter seen.
    /// Off by default: it takes the membrane out of the demo mug's cup (`objnerf demo` at 1e-3:
    /// mesh Chamfer 1.66 -> 1.26%, held out 33.60 -> 33.34 dB) but costs the other demo objects
    /// up to 0.7 dB held out (examples/results/field.md, "The mug's membrane" and "The sphere
    /// and box meshes hollow again").
    ///
    /// [`RayGrad::alpha_each`]: crate::field::march::RayGrad::alpha_each
    pub sparsity_weight: f32,
    /// Weight of the free-space loss ([`free_space`]) on rays with a depth target: what lies
    /// between a camera and a point it sees is empty (DS-NeRF's depth prior, as a bound). It
    /// clears the floaters and the faint matter in front of surfaces that colour alone leaves.
    ///
    /// [`free_space`]: crate::field::march::free_space
    pub free_space_weight: f32,
    /// How far in front of the target (finest voxels) space is taken as free: the targets are
    /// triangulated points, a voxel or two off.
    pub free_space_margin: f32,
    /// Coarse-to-fine: (fraction of `steps`, grid scale per axis), scales rising to 1.
    pub stages: Vec<(f32, f32)>,
    /// The schedule instead of `stages` when the memory budget makes the first (dense) stage
    /// coarser than `stages` asks, if it starts coarser: with two stages the finest was held
    /// to twice the first's resolution, far from what the budget's bricks allow (lego 800^2
    /// in 20 min: finest voxel 2.3 px, 32.96 dB; with this, 1.6 px and 33.72 dB).
    pub stages_when_capped: Vec<(f32, f32)>,
    /// Re-derive the occupancy grid every this many steps...
    pub prune_every: usize,
    /// ... once this fraction of the schedule has passed (a scene field starts transparent, and
    /// its surfaces need a while to rise above the pruning threshold).
    pub prune_after: f32,
    /// Before the grid grows, render every training ray and keep only the cells where some ray
    /// puts at least this much weight (T alpha): free space and what no view sees are dropped,
    /// so the finer grid only holds surfaces (0: off; scene fields, whose air density falls
    /// too slowly for density pruning).
    pub carve_weight: f32,
    /// Cells whose densest corner is less opaque than this over one step are pruned (at least
    /// the render's `alpha_thresh`, below which samples are skipped anyway).
    pub prune_alpha: f32,
    /// Polyak averaging ([`Trainer::take_average`]): from this fraction of the schedule on,
    /// every `average_every` steps the grid's values and the network's weights are folded into
    /// a running mean, which the run ends with (1 or more: off). The mean holds a copy of the
    /// grid's values (4 bytes a value more while it runs). Off for SH fields, whose rates decay
    /// to `lr_final`.
    ///
    /// [`Trainer::take_average`]: super::Trainer::take_average
    pub average_from: f32,
    /// `average_from` for a field coloured by a network, whose rates decay only to
    /// `lr_final_network`, so its late values scatter by a step of about that rate around where
    /// their gradients balance (examples/results/field.md, "The mean of the last parameters").
    pub average_from_network: f32,
    pub average_every: usize,
    /// The view direction a training ray's colour is computed for is the ray's, turned by a
    /// random angle of about this many radians (0: off): a prior on how fast the colour may
    /// change with direction between the training views. Off: 2 degrees scored lego 800^2 in
    /// 20 min at 34.54 dB, within the default's runs (examples/results/field.md, "A second
    /// hidden layer by default; the view direction jittered").
    pub view_jitter: f32,
    /// Learning rate of the per-view appearance correction ([`super::appearance`]: gains and
    /// offsets per colour channel, learnt for each training view and left out when rendering;
    /// 0: off).
    pub appearance_lr: f32,
    /// Weight of the pull of each view's correction to the identity (squared, per parameter).
    pub appearance_pull: f32,
    pub render: RenderOptions,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            seed: 0,
            batch: 2048,
            ray_run: 1,
            steps: 20_000,
            // Twice the rates of before, decaying to 0.03 of them (was 0.1): lego 200^2 60 s
            // 30.86 -> 31.32 dB; demo objects' held-out PSNR over seeds 0-3 not lower (mug /
            // sphere / box / torus +0.12 / +0.27 / +0.01 / +0.29 dB); their meshes no worse now
            // that the inside is filled; fox +0.06 dB. (0.2, 0.2) trains lego faster still but
            // costs the demo sphere 0.2 dB (examples/results/field.md, "learning rates").
            lr_density: 0.2,
            lr_color: 0.1,
            // DVGO uses 1e-3 for its network (8192-ray batches); here, lego 200^2, 3000 steps,
            // 12 features x 64 hidden: 1e-3 30.35 dB, 1e-2 31.08, 3e-2 31.18.
            lr_net: 0.03,
            lr_final: 0.03,
            lr_final_network: 0.3,
            beta1: 0.9,
            beta2: 0.99,
            tv_density: 0.0,
            tv_color: 0.0,
            tv_every: 1,
            tv_until: 1.0,
            alpha_weight: 0.1,
            depth_weight: 0.001,
            depth_batch: 1024,
            depth_robust_voxels: 0.0,
            focus_batch: 256,
            distortion_weight: 0.0,
            sparsity_weight: 0.0,
            // Measured on `objnerf demo` (sparse depth from the object's points; held-out PSNR,
            // mesh Chamfer, training seconds) without -> with it: mug 33.60 -> 33.93 dB, 1.66 ->
            // 1.54%, 24 -> 13 s; sphere 35.83 -> 36.30; box 33.48 -> 34.73; torus 36.40 -> 36.38
            // (examples/results/field.md, "Free space in front of the sparse points").
            free_space_weight: 1.0,
            free_space_margin: 3.0,
            stages: vec![(0.0, 0.5), (0.3, 1.0)],
            stages_when_capped: vec![(0.0, 0.35), (0.15, 0.6), (0.4, 1.0)],
            prune_every: 100,
            prune_after: 0.0,
            carve_weight: 0.0,
            // The faint shell in front of surfaces (cells under 1% opaque a step) goes: lego
            // 200^2 in 60 s 30.99 -> 32.34 dB (2.5x the steps; at 0: 1.14 M occupied cells,
            // 80% of samples weigh under 3e-3), 300 s 33.16 -> 33.40; demo objects and fox
            // within 0.02 dB at 3000 steps, in 0.6-0.7x the time (examples/results/field.md,
            // "Pruning the faint shell"). Scene fields used it already.
            prune_alpha: 0.01,
            average_from: 1.0,
            average_from_network: 0.8,
            average_every: 500,
            view_jitter: 0.0,
            appearance_lr: 0.0,
            appearance_pull: 1e-4,
            // Training samples every voxel; rendering and evaluation every half voxel. Measured
            // on lego 200^2 in 90 s: step 1.0 with 2048-ray batches gave 31.2 dB against 28.3 dB
            // at step 0.5 (same batch), since each step costs about half as much.
            render: RenderOptions {
                step: 1.0,
                ..RenderOptions::default()
            },
        }
    }
}

/// Runs of neighbouring rays make steps cheaper where the grid's parameters are larger than the
/// cache, but a batch of alike rays teaches less a step: lego 200^2 and 400^2 took 25-58% more
/// steps in the same time for the same test PSNR; fox's head at 3000 steps took 54 instead of
/// 89 s but scored 20.61 against 20.79 dB; the demo mug's removal at 6000 steps 24.25 / 19.64 dB
/// (full frame / inside the mug) against 24.54 / 20.08. The ring's scene field reached its
/// plateau sooner (24.46 dB in 117 s instead of 153). So runs are an option, off by default
/// (examples/results/field.md).
pub const AUTO_RAY_RUN: usize = 8;
pub(super) const AUTO_RAY_RUN_BYTES: usize = 8 << 20;

/// What one step reports.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct StepStats {
    pub step: usize,
    pub loss: f32,
    /// PSNR of the batch's colours (on their random backgrounds).
    pub psnr: f32,
    pub samples_per_ray: f32,
    /// Seconds since the run began, and rays per second over them (set by
    /// [`crate::field::session::run`]; 0 from a lone `Trainer::train_step`).
    pub seconds: f64,
    pub rays_per_second: f64,
}

impl StepStats {
    /// The step as a progress detail.
    pub fn detail(&self) -> crate::util::Detail<'static> {
        crate::util::Detail::Training {
            loss: self.loss,
            psnr: self.psnr,
            rays_per_second: self.rays_per_second,
        }
    }
}
