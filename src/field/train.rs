//! Training: random ray batches, colour + alpha loss on a random background, hand-written
//! backward, and a sparse per-voxel Adam step with total variation on the touched voxels.
//!
//! Determinism: a batch is cut into fixed chunks of rays whose randomness comes from the seed, the
//! step and the ray's position in the batch (not from the thread that runs it). Each chunk writes
//! its per-sample gradients as records; the grid is then split into z-slabs, one per task, and
//! every slab adds the records that touch it in chunk order. So each voxel's gradient is summed in
//! the same order whatever the thread count, and two runs with one seed give identical grids.

use super::colour_net::NetAdam;
use super::grid::{compact_buffer, Corners, Grid, BRICK, BRICK_VERTICES, NONE};
use super::model::Field;
use super::rays::RaySet;
use super::render::{backward, distortion, forward, RayGrad, RayOut, RenderOptions, Sample};
use super::view::{EdgePixel, View};
use crate::util::Rng;
use rayon::prelude::*;
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
    pub ray_run: usize,
    /// Most steps; the learning rates decay over this many.
    pub steps: usize,
    pub lr_density: f32,
    pub lr_color: f32,
    /// Learning rate of a colour network's weights ([`super::colour_net`]).
    pub lr_net: f32,
    /// Learning rates fall to this fraction at `steps` (exponentially).
    pub lr_final: f32,
    pub beta1: f32,
    pub beta2: f32,
    /// Total-variation weights (density, colour), applied to the voxels a batch touches.
    pub tv_density: f32,
    pub tv_color: f32,
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
    /// Rays drawn a step from [`RaySet::focus`] when it holds any.
    pub focus_batch: usize,
    /// Weight of the distortion loss ([`distortion`], distances in finest voxels) per ray.
    pub distortion_weight: f32,
    /// Weight of the sparsity loss per ray (the sum of its kept samples' alphas,
    /// [`RayGrad::alpha_each`]): of two ways to explain a view, the one with less matter seen.
    /// Off by default: at 3e-4 it takes the membrane out of the demo mug's cup (mesh Chamfer
    /// 1.72 -> 1.27%) but costs the demo objects 0.2-0.7 dB held out, and applied for the
    /// first half of training only the membrane grows back (examples/results/field.md).
    pub sparsity_weight: f32,
    /// Coarse-to-fine: (fraction of `steps`, grid scale per axis), scales rising to 1.
    pub stages: Vec<(f32, f32)>,
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
            beta1: 0.9,
            beta2: 0.99,
            tv_density: 0.0,
            tv_color: 0.0,
            alpha_weight: 0.1,
            depth_weight: 0.001,
            depth_batch: 1024,
            focus_batch: 256,
            distortion_weight: 0.0,
            sparsity_weight: 0.0,
            stages: vec![(0.0, 0.5), (0.3, 1.0)],
            prune_every: 100,
            prune_after: 0.0,
            carve_weight: 0.0,
            prune_alpha: 0.0,
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
const AUTO_RAY_RUN_BYTES: usize = 8 << 20;

/// What one step reports.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct StepStats {
    pub step: usize,
    pub loss: f32,
    /// PSNR of the batch's colours (on their random backgrounds).
    pub psnr: f32,
    pub samples_per_ray: f32,
    /// Seconds since the run began, and rays per second over them (set by
    /// [`super::session::run`]; 0 from a lone [`Trainer::train_step`]).
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

const CHUNK: usize = 256;

/// [`Trainer::carve_by_weight`] keeps the cells where a ray's accumulated opacity passes from
/// this to 1 minus this: a shell around the surfaces, not the fog in front of them.
const CARVE_BAND: f32 = 0.02;

/// Opacity a ray needs before its depth is supervised (its normalised depth means little before).
const MIN_DEPTH_ALPHA: f32 = 0.1;

/// How many listed vertices ahead [`AdamStep::apply`] prefetches.
const PREFETCH_AHEAD: usize = 8;

/// Ask for the cache line holding `buf[i]` (a hint: no effect on results; nothing off x86-64).
#[inline(always)]
fn prefetch(buf: &[f32], i: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(x) = buf.get(i) {
        // SAFETY: a prefetch hint reads nothing and cannot fault; the pointer is in bounds.
        unsafe {
            std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                (x as *const f32).cast(),
            )
        };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (buf, i);
}

/// One Adam step's constants (bias corrections and the decayed learning rates).
#[derive(Clone, Copy)]
struct AdamStep {
    b1: f32,
    b2: f32,
    c1: f32,
    c2: f32,
    lr: [f32; 2],
}

impl AdamStep {
    /// Update the listed vertices of one slab (slices start at vertex `v0`) and clear their
    /// gradients.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn apply(
        &self,
        p: &mut [f32],
        g: &mut [f32],
        m: &mut [f32],
        v: &mut [f32],
        list: &[u32],
        v0: usize,
        ch: usize,
    ) {
        // lr (m / c1) / (sqrt(v) / c2 + eps) = (lr c2 / c1) m / (sqrt(v) + eps c2): one division
        // per value, and the density channel (its own rate) split off so the colour channels
        // run as one branch-free loop the compiler vectorises.
        let rate = self.lr.map(|l| l * self.c2 / self.c1);
        let eps = 1e-8 * self.c2;
        for (k, &vtx) in list.iter().enumerate() {
            // The list ascends with irregular gaps, which the hardware prefetcher does not
            // follow: fetch the values a few vertices ahead.
            if let Some(&ahead) = list.get(k + PREFETCH_AHEAD) {
                let o = (ahead as usize - v0) * ch;
                for buf in [&*p, &*g, &*m, &*v] {
                    prefetch(buf, o);
                    prefetch(buf, o + ch - 1);
                }
            }
            let o = (vtx as usize - v0) * ch;
            let r = o..o + ch;
            let (p, g, m, v) = (
                &mut p[r.clone()],
                &mut g[r.clone()],
                &mut m[r.clone()],
                &mut v[r],
            );
            self.update(
                &mut p[..1],
                &mut g[..1],
                &mut m[..1],
                &mut v[..1],
                rate[0],
                eps,
            );
            self.update(
                &mut p[1..],
                &mut g[1..],
                &mut m[1..],
                &mut v[1..],
                rate[1],
                eps,
            );
        }
    }

    /// Adam on equal-length runs of values (parameters, gradients, moments); clears the
    /// gradients.
    #[inline(always)]
    fn update(
        &self,
        p: &mut [f32],
        g: &mut [f32],
        m: &mut [f32],
        v: &mut [f32],
        rate: f32,
        eps: f32,
    ) {
        let (b1, b2) = (self.b1, self.b2);
        for (((p, g), m), v) in p
            .iter_mut()
            .zip(g.iter_mut())
            .zip(m.iter_mut())
            .zip(v.iter_mut())
        {
            let gj = *g;
            *g = 0.0;
            *m = b1 * *m + (1.0 - b1) * gj;
            *v = b2 * *v + (1.0 - b2) * gj * gj;
            *p -= rate * *m / (v.sqrt() + eps);
        }
    }
}

/// Optimiser state and the buffers of one training run.
pub struct Trainer {
    pub field: Field,
    pub cfg: TrainConfig,
    /// Dims of the finest stage.
    pub final_dims: [usize; 3],
    pub step: usize,
    grad: Vec<f32>,
    m: Vec<f32>,
    v: Vec<f32>,
    /// Step (+1) at which a vertex was last touched, to list touched vertices without clearing.
    stamp: Vec<u32>,
    adam_t: u32,
    /// Per chunk, per z-slab: the gradient records of samples whose cell touches that slab.
    records: Vec<Vec<Vec<f32>>>,
    /// Per chunk: the colour network's weight gradient (summed in chunk order), and its Adam.
    net_grads: Vec<Vec<f32>>,
    net_adam: NetAdam,
    /// Fraction of a time budget used so far: the schedule follows whichever of step and time
    /// progress is further along, so a short budget still reaches the finest grid. Left at 0
    /// (no budget), training depends on the seed alone.
    pub time_frac: f32,
    /// Seconds spent in (forward + backward, gradient scatter, TV + Adam, occupancy pruning).
    pub phase_secs: [f64; 4],
    /// Bytes the grid and its optimiser state may take at the finest stage (None: as planned).
    pub budget: Option<usize>,
    /// How the finest stage's resolution was chosen, once it started.
    pub finest: Option<FinestStage>,
}

/// The finest stage's grid: chosen when it starts, from the bricks the occupied cells need.
#[derive(Clone, Debug, Serialize)]
pub struct FinestStage {
    pub dims: [usize; 3],
    /// Voxel length (space units).
    pub voxel: f32,
    pub bricks: usize,
    /// Grid and optimiser bytes per allocated brick.
    pub bytes_per_brick: usize,
    pub why: String,
}

/// `keep` (cells, x fastest, `cells` per axis) grown by one cell along each axis.
fn dilate_cells(keep: &[bool], cells: [usize; 3]) -> Vec<bool> {
    let mut out = keep.to_vec();
    let strides = [1, cells[0], cells[0] * cells[1]];
    for axis in 0..3 {
        let src = out.clone();
        let n = cells[axis];
        let s = strides[axis];
        for (i, k) in src.iter().enumerate() {
            if !*k {
                continue;
            }
            let c = (i / s) % n;
            if c > 0 {
                out[i - s] = true;
            }
            if c + 1 < n {
                out[i + s] = true;
            }
        }
    }
    out
}

/// Stage dims: (final - 1) * scale + 1 per axis (final - 1 is a multiple of 4, so 1/2 and 1/4
/// scales are exact and voxels stay cubic).
pub fn stage_dims(final_dims: [usize; 3], scale: f32) -> [usize; 3] {
    final_dims.map(|d| (((d - 1) as f32 * scale).round() as usize).max(1) + 1)
}

impl Trainer {
    /// Start from `field` (already at the first stage's dims, occupancy carved) aiming at
    /// `final_dims`.
    pub fn new(field: Field, final_dims: [usize; 3], cfg: TrainConfig) -> Trainer {
        let mut t = Trainer {
            field,
            cfg,
            final_dims,
            step: 0,
            grad: Vec::new(),
            m: Vec::new(),
            v: Vec::new(),
            stamp: Vec::new(),
            adam_t: 0,
            records: Vec::new(),
            net_grads: Vec::new(),
            net_adam: NetAdam::default(),
            time_frac: 0.0,
            phase_secs: [0.0; 4],
            budget: None,
            finest: None,
        };
        t.reset_state();
        t
    }

    fn reset_state(&mut self) {
        let n = self.field.grid.data.len();
        self.grad = vec![0.0; n];
        self.m = vec![0.0; n];
        self.v = vec![0.0; n];
        self.stamp = vec![0; self.field.grid.num_vertices()];
        self.adam_t = 0;
    }

    /// Follow the grid when it dropped bricks: the optimiser state of the kept slots moves with
    /// them (the gradient is all zero between steps).
    fn follow_compaction(&mut self, map: &[u32]) {
        let per = BRICK_VERTICES * self.field.grid.channels;
        compact_buffer(&mut self.m, map, per);
        compact_buffer(&mut self.v, map, per);
        self.grad.truncate(self.m.len());
        compact_buffer(&mut self.stamp, map, BRICK_VERTICES);
    }

    /// Occupy `cells` ([`Field::occupy`]); the optimiser starts afresh when bricks were added
    /// (the slots moved). Returns the cells that were free before.
    pub fn occupy(&mut self, cells: &[[usize; 3]]) -> Vec<[usize; 3]> {
        let len = self.field.grid.data.len();
        let opened = self.field.occupy(cells);
        if self.field.grid.data.len() != len {
            self.reset_state();
        }
        opened
    }

    /// Optimiser state (m, v, step count) for saving a resumable model.
    pub fn adam_state(&self) -> (&[f32], &[f32], u32) {
        (&self.m, &self.v, self.adam_t)
    }

    /// Restore optimiser state saved with [`Trainer::adam_state`].
    pub fn set_adam_state(&mut self, m: Vec<f32>, v: Vec<f32>, t: u32) {
        if m.len() == self.grad.len() && v.len() == self.grad.len() {
            self.m = m;
            self.v = v;
            self.adam_t = t;
        }
    }

    /// The colour network's optimiser state, if it has stepped.
    pub fn net_adam_state(&self) -> Option<(&[f32], &[f32], u32)> {
        self.net_adam.state()
    }

    /// Restore state saved with [`Trainer::net_adam_state`] (ignored if it does not fit).
    pub fn set_net_adam_state(&mut self, m: Vec<f32>, v: Vec<f32>, t: u32) {
        let n = self.field.net.as_ref().map_or(0, |n| n.weights.len());
        if m.len() == n && v.len() == n {
            self.net_adam = NetAdam::restore(m, v, t);
        }
    }

    /// Bytes of parameters and optimiser state.
    pub fn memory_bytes(&self) -> usize {
        self.field.param_bytes()
            + (self.grad.len() + self.m.len() + self.v.len()) * 4
            + self.stamp.len() * 4
    }

    /// The grid scale the schedule wants at `step`.
    /// Progress through the schedule in [0, 1].
    pub fn progress(&self) -> f32 {
        (self.step as f32 / self.cfg.steps.max(1) as f32)
            .max(self.time_frac)
            .min(1.0)
    }

    fn scale_at(&self) -> f32 {
        let frac = self.progress();
        let mut s = 1.0;
        for &(at, scale) in &self.cfg.stages {
            if frac >= at {
                s = scale;
            }
        }
        s
    }

    /// Grow the grid when the schedule says so; true if it grew.
    pub fn maybe_grow(&mut self, views: &[View], rays: &RaySet) -> bool {
        let mut want = stage_dims(self.final_dims, self.scale_at());
        if want[0] <= self.field.grid.dims[0] {
            return false;
        }
        if self.cfg.carve_weight > 0.0 {
            self.carve_by_weight(views, rays);
        }
        // Every growth fits the budget: a stage whose bricks would not fit is made coarser, and
        // then it is the finest (a grid that cannot grow at all stays as it is).
        let planned = want;
        want = self.fit_finest(want);
        if want != planned || planned == self.final_dims {
            self.final_dims = want;
        } else {
            self.finest = None;
        }
        if want[0] <= self.field.grid.dims[0] {
            self.final_dims = self.field.grid.dims;
            return false;
        }
        self.field.upsample(want);
        self.reset_state();
        self.prune();
        true
    }

    /// Keep only the cells where some training ray puts weight >= `cfg.carve_weight` (each
    /// ray rendered once, as training samples it); release the bricks the rest held.
    pub fn carve_by_weight(&mut self, views: &[View], rays: &RaySet) {
        let f = &self.field;
        let opt = self.cfg.render;
        let thr = self.cfg.carve_weight;
        let dims = f.grid.dims;
        let seen: Vec<Vec<u32>> = rays
            .rays
            .par_chunks(4096)
            .map(|chunk| {
                let mut samples = Vec::new();
                let mut keep = Vec::new();
                for &(vi, px) in chunk {
                    let (o, d) = views[vi as usize].ray(px);
                    forward(f, &opt, o, d, 0.5, [0.0; 3], &mut samples);
                    // The cells where the ray ends: weight >= thr, inside the band where its
                    // accumulated opacity passes from CARVE_BAND to 1 - CARVE_BAND (air in
                    // front, and what the surface hides, go).
                    keep.extend(
                        samples
                            .iter()
                            .filter(|s| {
                                let before = 1.0 - s.trans;
                                let after = 1.0 - s.trans * (1.0 - s.alpha);
                                s.trans * s.alpha >= thr
                                    && before <= 1.0 - CARVE_BAND
                                    && after >= CARVE_BAND
                            })
                            .map(|s| s.base),
                    );
                }
                keep.sort_unstable();
                keep.dedup();
                keep
            })
            .collect();
        let mut keep = vec![false; f.num_cells().max(1)];
        let cells = [dims[0] - 1, dims[1] - 1, dims[2] - 1];
        for b in seen.into_iter().flatten() {
            let [x, y, z] = f.grid.cell_of_base(b as usize);
            keep[x + cells[0] * (y + cells[1] * z)] = true;
        }
        // A view between the training views crosses a surface where no training ray quite did:
        // keep one cell around every kept cell, or it sees through pinholes.
        let keep = dilate_cells(&keep, cells);
        for c in self.field.occupied_cell_list() {
            if !keep[c[0] + cells[0] * (c[1] + cells[1] * c[2])] {
                self.field.set_occupied(c, false);
            }
        }
        if let Some(map) = self.field.release_free_bricks() {
            self.follow_compaction(&map);
        }
    }

    /// The finest grid the budget allows: `planned`, or coarser until the bricks its occupied
    /// cells need fit (never below the current grid).
    fn fit_finest(&mut self, planned: [usize; 3]) -> [usize; 3] {
        let per_brick = BRICK_VERTICES * (self.field.grid.channels * 16 + 4);
        let current = self.field.grid.dims;
        let mut dims = planned;
        let mut bricks = self.field.bricks_at(dims);
        let mut why = format!("planned {dims:?}: {bricks} bricks");
        if let Some(budget) = self.budget {
            while bricks * per_brick > budget && dims[0] > current[0] + 1 {
                dims = stage_dims(dims, 0.9).map(|d| d.max(2));
                if dims[0] <= current[0] {
                    dims = current;
                }
                bricks = self.field.bricks_at(dims);
            }
            why += &format!(
                "; {} MiB budget -> {dims:?} ({bricks} bricks, {} MiB)",
                budget >> 20,
                (bricks * per_brick) >> 20
            );
        }
        self.finest = Some(FinestStage {
            dims,
            voxel: self.field.voxel_for(dims),
            bricks,
            bytes_per_brick: per_brick,
            why,
        });
        dims
    }

    fn prune(&mut self) {
        let delta = self.cfg.render.step * self.field.voxel / self.field.config.base_voxel;
        self.field.prune_occupancy(
            delta,
            self.cfg.prune_alpha.max(self.cfg.render.alpha_thresh),
        );
        if let Some(map) = self.field.release_free_bricks() {
            self.follow_compaction(&map);
        }
    }

    /// One optimisation step on `batch` rays drawn from `rays`.
    pub fn train_step(&mut self, views: &[View], rays: &RaySet) -> StepStats {
        self.maybe_grow(views, rays);
        let cfg = self.cfg.clone();
        let step = self.step;
        let clock = std::time::Instant::now();
        let picks = draw_batch(&cfg, step, rays, self.field.param_bytes());
        let nchunks = picks.len().div_ceil(CHUNK);
        self.records.resize_with(nchunks, Vec::new);
        let slabs = self.slabs();
        let field = &self.field;
        let stride = field.grid.channels + 4;
        let ctx = StepContext {
            field,
            cfg: &cfg,
            views,
            step,
            inv_b: 1.0 / picks.len() as f32,
            plane: field.grid.dims[0] * field.grid.dims[1],
            nslabs: slabs.count(),
            layers_per_slab: slabs.layers_per_slab,
        };
        let net_len = field.net.as_ref().map_or(0, |n| n.weights.len());
        self.net_grads.resize_with(nchunks, Vec::new);
        let stats: Vec<(f64, f64, usize)> = self
            .records
            .par_iter_mut()
            .zip(self.net_grads.par_iter_mut())
            .zip(picks.par_chunks(CHUNK))
            .enumerate()
            .map(|(ci, ((rec, net_grad), chunk))| {
                net_grad.clear();
                net_grad.resize(net_len, 0.0);
                ctx.chunk_gradients(ci, chunk, rec, net_grad)
            })
            .collect();
        let (loss, mse, nsamp) = stats
            .iter()
            .fold((0.0, 0.0, 0), |a, s| (a.0 + s.0, a.1 + s.1, a.2 + s.2));
        if net_len > 0 {
            self.step_net(nchunks);
        }
        self.phase_secs[0] += clock.elapsed().as_secs_f64();
        self.apply_gradients(stride, &slabs);
        self.step += 1;
        if cfg.prune_every > 0
            && self.step % cfg.prune_every == 0
            && self.progress() >= cfg.prune_after
        {
            let c = std::time::Instant::now();
            self.prune();
            self.phase_secs[3] += c.elapsed().as_secs_f64();
        }
        let n = picks.len() as f64;
        StepStats {
            step: self.step,
            loss: (loss / n) as f32,
            psnr: (-10.0 * (mse / n).max(1e-12).log10()) as f32,
            samples_per_ray: nsamp as f32 / n as f32,
            ..Default::default()
        }
    }

    /// How the grid's z-layers are split for the scatter: (slab count, layers per slab). Depends
    /// on the thread count, which does not change the sums (see the module notes).
    /// The grid's z-slabs: ranges of brick layers, each a contiguous range of slots, about two
    /// per thread; each thread sums and applies the gradient of its own slab.
    fn slabs(&self) -> Slabs {
        let grid = &self.field.grid;
        let layers = grid.brick_dims[2];
        let want = (rayon::current_num_threads() * 2).clamp(1, layers);
        let layers_per_slab = layers.div_ceil(want);
        let starts = grid.layer_starts();
        let bounds = (0..=layers.div_ceil(layers_per_slab))
            .map(|i| starts[(i * layers_per_slab).min(layers)] * BRICK_VERTICES)
            .collect();
        Slabs {
            layers_per_slab,
            bounds,
        }
    }

    /// Scatter the records into the gradient by z-slabs, add TV, and take an Adam step on the
    /// touched vertices only.
    fn apply_gradients(&mut self, stride: usize, slabs: &Slabs) {
        let ch = self.field.grid.channels;
        let stamp_id = self.step as u32 + 1;
        let clock = std::time::Instant::now();
        // Without TV, each slab runs Adam on its vertices right after summing their gradients,
        // while those lines are still in cache (TV reads neighbours across slabs, so it needs
        // every slab's scatter finished first).
        let fused = self.cfg.tv_density == 0.0 && self.cfg.tv_color == 0.0;
        let adam = fused.then(|| self.adam_step());
        // The parameters leave the grid for the pass: the grid's brick index finds corners while
        // each slab writes its own parameters.
        let mut data = std::mem::take(&mut self.field.grid.data);
        let grid = &self.field.grid;
        let records = &self.records;
        let bounds = &slabs.bounds;
        let touched: Vec<Vec<u32>> = split_by(&mut self.grad, bounds, ch)
            .into_par_iter()
            .zip(split_by(&mut self.stamp, bounds, 1))
            .zip(split_by(&mut data, bounds, ch))
            .zip(split_by(&mut self.m, bounds, ch))
            .zip(split_by(&mut self.v, bounds, ch))
            .enumerate()
            .map(|(si, ((((gslab, stslab), pslab), mslab), vslab))| {
                let (v0, v1) = (bounds[si], bounds[si + 1]);
                let mut list = Vec::new();
                let slab = SlabScatter {
                    grid,
                    stride,
                    range: v0..v1,
                    stamp_id,
                };
                for rec in records {
                    slab.scatter(&rec[si], gslab, stslab, &mut list);
                }
                // Ascending order turns the optimiser's pass into a forward sweep of memory
                // (first-touch order is random and was cache-miss bound).
                list.sort_unstable();
                if let Some(a) = &adam {
                    a.apply(pslab, gslab, mslab, vslab, &list, v0, ch);
                }
                list
            })
            .collect();
        self.field.grid.data = data;
        self.phase_secs[1] += clock.elapsed().as_secs_f64();
        if !fused {
            let clock = std::time::Instant::now();
            self.tv_and_adam(&touched, bounds);
            self.phase_secs[2] += clock.elapsed().as_secs_f64();
        }
    }

    fn tv_and_adam(&mut self, touched: &[Vec<u32>], bounds: &[usize]) {
        let cfg = &self.cfg;
        let grid = &self.field.grid;
        let dims = grid.dims;
        let ch = grid.channels;
        let params = &grid.data;
        if cfg.tv_density > 0.0 || cfg.tv_color > 0.0 {
            // Reads parameters only, writes each slab's own gradients: order-independent.
            split_by(&mut self.grad, bounds, ch)
                .into_par_iter()
                .zip(touched.par_iter())
                .enumerate()
                .for_each(|(si, (gslab, list))| {
                    let v0 = bounds[si];
                    for &v in list {
                        let v = v as usize;
                        let coords = grid.vertex_coords(v as u32);
                        for a in 0..3 {
                            for dir in [-1isize, 1] {
                                let c = coords[a] as isize + dir;
                                if c < 0 || c as usize >= dims[a] {
                                    continue;
                                }
                                let mut nc = coords;
                                nc[a] = c as usize;
                                let n = grid.vertex_slot(nc[0], nc[1], nc[2]);
                                if n == NONE {
                                    continue;
                                }
                                let n = n as usize;
                                let g = &mut gslab[(v - v0) * ch..(v - v0 + 1) * ch];
                                for (j, gj) in g.iter_mut().enumerate() {
                                    let w = if j == 0 { cfg.tv_density } else { cfg.tv_color };
                                    *gj += w * 2.0 * (params[v * ch + j] - params[n * ch + j]);
                                }
                            }
                        }
                    }
                });
        }
        let step = self.adam_step();
        let ch = self.field.grid.channels;
        split_by(&mut self.field.grid.data, bounds, ch)
            .into_par_iter()
            .zip(split_by(&mut self.grad, bounds, ch))
            .zip(split_by(&mut self.m, bounds, ch))
            .zip(split_by(&mut self.v, bounds, ch))
            .zip(touched.par_iter())
            .enumerate()
            .for_each(|(si, ((((p, g), m), v), list))| {
                step.apply(p, g, m, v, list, bounds[si], ch);
            });
    }

    /// Sum the chunks' network gradients in chunk order and step the network.
    fn step_net(&mut self, nchunks: usize) {
        let lr = self.cfg.lr_net * self.cfg.lr_final.powf(self.progress());
        let (first, rest) = self.net_grads[..nchunks]
            .split_first_mut()
            .expect("a chunk");
        for g in rest.iter() {
            first.iter_mut().zip(g).for_each(|(a, b)| *a += b);
        }
        let cfg = &self.cfg;
        if let Some(net) = self.field.net.as_mut() {
            self.net_adam
                .step(&mut net.weights, first, lr, cfg.beta1, cfg.beta2);
        }
    }

    /// Advance the Adam step count and return this step's constants.
    fn adam_step(&mut self) -> AdamStep {
        self.adam_t += 1;
        let t = self.adam_t as i32;
        let cfg = &self.cfg;
        let decay = cfg.lr_final.powf(self.progress());
        AdamStep {
            b1: cfg.beta1,
            b2: cfg.beta2,
            c1: 1.0 - cfg.beta1.powi(t),
            c2: (1.0 - cfg.beta2.powi(t)).sqrt(),
            lr: [cfg.lr_density * decay, cfg.lr_color * decay],
        }
    }
}
/// Sums one slab's share of the records into its gradient, listing the vertices touched.
struct SlabScatter<'a> {
    grid: &'a Grid,
    stride: usize,
    /// The slab's vertex slots.
    range: std::ops::Range<usize>,
    stamp_id: u32,
}

impl SlabScatter<'_> {
    fn corners(&self, r: &[f32]) -> Corners {
        let cell = self.grid.cell_of_base(r[0].to_bits() as usize);
        self.grid.corners_of(cell, [r[1], r[2], r[3]])
    }

    /// The gradient lines of `k`'s corners are fetched a few records ahead: the corners are
    /// scattered over the slab and the sum was bound by cache misses, like the optimiser's pass.
    fn prefetch(&self, grad: &[f32], k: &Corners) {
        let ch = self.grid.channels;
        // Corners come in x-adjacent pairs (000/100, 010/110, ...): two lines cover each pair.
        for &v in k.idx.iter().step_by(2) {
            if self.range.contains(&(v as usize)) {
                let o = (v as usize - self.range.start) * ch;
                prefetch(grad, o);
                prefetch(grad, o + 2 * ch - 1);
            }
        }
    }

    fn scatter(&self, records: &[f32], grad: &mut [f32], stamp: &mut [u32], list: &mut Vec<u32>) {
        let ch = self.grid.channels;
        let (v0, v1) = (self.range.start, self.range.end);
        let n = records.len() / self.stride;
        let record = |i: usize| &records[i * self.stride..(i + 1) * self.stride];
        let mut ring = [Corners {
            idx: [NONE; 8],
            w: [0.0; 8],
        }; PREFETCH_AHEAD];
        for (i, slot) in ring.iter_mut().enumerate().take(n) {
            *slot = self.corners(record(i));
            self.prefetch(grad, slot);
        }
        for i in 0..n {
            let k = ring[i % PREFETCH_AHEAD];
            if i + PREFETCH_AHEAD < n {
                let ahead = self.corners(record(i + PREFETCH_AHEAD));
                self.prefetch(grad, &ahead);
                ring[i % PREFETCH_AHEAD] = ahead;
            }
            let g = &record(i)[4..];
            for (&vtx, &w) in k.idx.iter().zip(&k.w) {
                let vtx = vtx as usize;
                if vtx < v0 || vtx >= v1 {
                    continue; // another slab's vertex, or unallocated (NONE)
                }
                let local = vtx - v0;
                if stamp[local] != self.stamp_id {
                    stamp[local] = self.stamp_id;
                    list.push(vtx as u32);
                }
                let dst = &mut grad[local * ch..(local + 1) * ch];
                for (d, s) in dst.iter_mut().zip(g) {
                    *d += w * s;
                }
            }
        }
    }
}

/// The grid's slabs for one step: brick layers per slab, and each slab's first vertex (slot
/// index; the last entry is one past the end).
struct Slabs {
    layers_per_slab: usize,
    bounds: Vec<usize>,
}

impl Slabs {
    fn count(&self) -> usize {
        self.bounds.len() - 1
    }
}

/// `buf` (`per` values per vertex) cut at the vertex `bounds`: one slice per slab.
fn split_by<'a, T>(mut buf: &'a mut [T], bounds: &[usize], per: usize) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(bounds.len() - 1);
    for w in bounds.windows(2) {
        let (head, tail) = buf.split_at_mut((w[1] - w[0]) * per);
        out.push(head);
        buf = tail;
    }
    out
}

/// The rays of one step: `batch` drawn uniformly from the kept rays, plus `depth_batch` from
/// those with a depth target, sorted so that a chunk's rays (one view, nearby pixels) cross the
/// same voxels and its grid reads stay in cache (the sum over the batch does not depend on the
/// order).
fn draw_batch(
    cfg: &TrainConfig,
    step: usize,
    rays: &RaySet,
    param_bytes: usize,
) -> Vec<(u32, u32)> {
    let mut rng = Rng::fork(cfg.seed, step as u64);
    let mut picks: Vec<(u32, u32)> =
        Vec::with_capacity(cfg.batch + cfg.depth_batch + cfg.focus_batch);
    let run = match cfg.ray_run {
        0 if param_bytes > AUTO_RAY_RUN_BYTES => AUTO_RAY_RUN,
        0 => 1,
        n => n,
    };
    rays.draw_runs(cfg.batch, run, &mut rng, &mut picks);
    if cfg.depth_weight > 0.0 && !rays.depth_rays.is_empty() {
        for _ in 0..cfg.depth_batch {
            picks.push(rays.depth_rays[rng.below(rays.depth_rays.len())]);
        }
    }
    if !rays.focus.is_empty() {
        for _ in 0..cfg.focus_batch {
            picks.push(rays.focus[rng.below(rays.focus.len())]);
        }
    }
    picks.sort_unstable();
    picks
}

/// What every chunk of a step shares.
struct StepContext<'a> {
    field: &'a Field,
    cfg: &'a TrainConfig,
    views: &'a [View],
    step: usize,
    /// 1 / rays in the batch: the loss is a mean.
    inv_b: f32,
    /// Vertices per z-plane, and the z-slabs (of brick layers) the gradient records are
    /// bucketed by.
    plane: usize,
    nslabs: usize,
    layers_per_slab: usize,
}

/// One ray's loss and the gradients it hands the backward pass.
struct RayLoss {
    loss: f64,
    /// Squared colour error (mean over the channels), for the batch PSNR.
    sq_err: f64,
    g_rgb: [f32; 3],
    g_alpha: f32,
    g_depth: f32,
}

impl StepContext<'_> {
    /// Forward and backward for a chunk of rays (`ci`: its index in the batch): gradient
    /// records into `rec` (one list per z-slab), and (loss, squared error, samples) summed.
    fn chunk_gradients(
        &self,
        ci: usize,
        chunk: &[(u32, u32)],
        rec: &mut Vec<Vec<f32>>,
        net_grad: &mut [f32],
    ) -> (f64, f64, usize) {
        let (cfg, field) = (self.cfg, self.field);
        rec.resize_with(self.nslabs, Vec::new);
        rec.iter_mut().for_each(|r| r.clear());
        let unit = field.config.base_voxel;
        let delta = cfg.render.step * field.voxel / field.config.base_voxel;
        let mut samples: Vec<Sample> = Vec::with_capacity(512);
        let mut g_w: Vec<f32> = Vec::new();
        let (mut loss, mut mse, mut nsamp) = (0f64, 0f64, 0usize);
        for (ri, &(vi, px)) in chunk.iter().enumerate() {
            let mut r = Rng::fork(
                cfg.seed ^ 0x5eed,
                ((self.step as u64) << 24) | (ci * CHUNK + ri) as u64,
            );
            let view = &self.views[vi as usize];
            let (o, d) = view.ray(px);
            let mut bg = [r.f32(), r.f32(), r.f32()];
            // A mask-edge pixel is rendered over the background estimated behind it.
            let edge = view.edge_at(px);
            if let Some(e) = edge {
                bg = e.backdrop.map(|c| c as f32 / 255.0);
            }
            let out = forward(field, &cfg.render, o, d, r.f32(), bg, &mut samples);
            nsamp += samples.len();
            let l = self.ray_loss(view, px, bg, edge, &out);
            mse += l.sq_err;
            loss += l.loss;
            if samples.is_empty() {
                continue;
            }
            g_w.clear();
            if cfg.distortion_weight > 0.0 {
                let dl = distortion(&samples, unit, delta, &mut g_w);
                loss += (cfg.distortion_weight * dl) as f64;
                let k = cfg.distortion_weight * self.inv_b;
                g_w.iter_mut().for_each(|g| *g *= k);
            }
            if cfg.sparsity_weight > 0.0 {
                let kept: f32 = samples.iter().map(|s| s.alpha).sum();
                loss += (cfg.sparsity_weight * kept) as f64;
            }
            let (plane, nslabs, per) = (self.plane, self.nslabs, self.layers_per_slab);
            backward(
                field,
                &cfg.render,
                d,
                bg,
                &samples,
                &RayGrad {
                    rgb: l.g_rgb,
                    alpha: l.g_alpha,
                    depth: l.g_depth,
                    weights: &g_w,
                    alpha_each: cfg.sparsity_weight * self.inv_b,
                },
                net_grad,
                |s, gr| {
                    // The cell's corners lie in brick layers z / BRICK and (z + 1) / BRICK.
                    let z = s.base as usize / plane;
                    let (sa, sb) = (
                        (z / BRICK / per).min(nslabs - 1),
                        ((z + 1) / BRICK / per).min(nslabs - 1),
                    );
                    for b in &mut rec[sa..=sb] {
                        b.push(f32::from_bits(s.base));
                        b.extend_from_slice(&s.frac);
                        b.extend_from_slice(gr);
                    }
                },
            );
        }
        (loss, mse, nsamp)
    }

    /// The losses of one ray: colour against the pixel composited on the ray's random
    /// background (which also supervises alpha), the squared alpha error, and the depth of the
    /// opaque part against a depth target. A mask-edge pixel (`edge`; `bg` is its backdrop)
    /// has the photo as its colour target: the mask's alpha stays a (weak) prior there, and the
    /// colour decides.
    fn ray_loss(
        &self,
        view: &View,
        px: u32,
        bg: [f32; 3],
        edge: Option<&EdgePixel>,
        out: &RayOut,
    ) -> RayLoss {
        let cfg = self.cfg;
        let inv_b = self.inv_b;
        let p = view.rgba[px as usize];
        let a = p[3] as f32 / 255.0;
        let tgt = match edge {
            Some(e) => e.photo.map(|c| c as f32 / 255.0),
            None => [0, 1, 2].map(|c| p[c] as f32 / 255.0 + (1.0 - a) * bg[c]),
        };
        let mut g_rgb = [0f32; 3];
        let mut e2 = 0f32;
        for c in 0..3 {
            let e = out.rgb[c] - tgt[c];
            e2 += e * e;
            g_rgb[c] = 2.0 * e * inv_b / 3.0;
        }
        let ea = out.alpha - a;
        let mut g_alpha = 2.0 * cfg.alpha_weight * ea * inv_b;
        let mut loss = (e2 / 3.0 + cfg.alpha_weight * ea * ea) as f64;
        let mut g_depth = 0.0;
        if let Some(dt) = view.depth.as_ref().map(|d| d[px as usize]) {
            // The depth of the opaque part, D = sum w t / A with A = sum w: the unnormalised
            // sum would read a 0.5% opacity deficit at 2 m as a 1 cm depth error (and did: the
            // demo's surfaces came out a voxel too far). Rays still mostly transparent are left
            // to the alpha loss.
            if dt > 0.0 && cfg.depth_weight > 0.0 && out.alpha > MIN_DEPTH_ALPHA {
                let inv_voxel = 1.0 / self.field.config.base_voxel;
                let dn = out.depth / out.alpha;
                let ed = (dn - dt) * inv_voxel;
                let g = 2.0 * cfg.depth_weight * ed * inv_voxel * inv_b;
                g_depth = g / out.alpha;
                g_alpha -= g * dn / out.alpha;
                loss += (cfg.depth_weight * ed * ed) as f64;
            }
        }
        RayLoss {
            loss,
            sq_err: e2 as f64 / 3.0,
            g_rgb,
            g_alpha,
            g_depth,
        }
    }
}
