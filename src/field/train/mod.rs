//! Training: random ray batches, colour + alpha loss on a random background, hand-written
//! backward, and a sparse per-voxel Adam step with total variation on the touched voxels.
//!
//! Determinism: a batch is cut into fixed chunks of rays whose randomness comes from the seed, the
//! step and the ray's position in the batch (not from the thread that runs it). Each chunk writes
//! its per-sample gradients as records; the grid is then split into z-slabs, one per task, and
//! every slab adds the records that touch it in chunk order. So each voxel's gradient is summed in
//! the same order whatever the thread count, and two runs with one seed give identical grids.

mod appearance;
mod average;
mod config;
mod optim;
mod step;

pub use appearance::{Appearance, ViewAppearance};
pub use config::{StepStats, TrainConfig, AUTO_RAY_RUN};

use super::colour_net::NetAdam;
use super::grid::{compact_buffer, value_index, BRICK_VERTICES, NONE};
use super::model::Field;
use super::rays::RaySet;
use super::view::View;
use crate::field::march::forward;
use crate::util::bf16::to_bf16;
use crate::util::Rng;
use config::AUTO_RAY_RUN_BYTES;
use optim::{split_by, AdamStep, SlabScatter, Slabs};
use rayon::prelude::*;
use serde::Serialize;
use step::{StepContext, CHUNK};

/// [`Trainer::carve_by_weight`] keeps the cells where a ray's accumulated opacity passes from
/// this to 1 minus this: a shell around the surfaces, not the fog in front of them.
const CARVE_BAND: f32 = 0.02;

/// Slabs per thread for the gradient's sum and the optimiser's step (more balance the threads'
/// work; each adds a record list per chunk and duplicates the records of cells on its border).
const SLABS_PER_THREAD: usize = 4;

/// Training memory per grid vertex of `channels`: each value and its gradient in f32, Adam's m
/// and v in bfloat16 ([`crate::util::bf16`]), and the touch stamp.
pub fn bytes_per_vertex(channels: usize) -> usize {
    channels * (4 + 4 + 2 + 2) + 4
}

/// Optimiser state and the buffers of one training run.
pub struct Trainer {
    pub field: Field,
    pub cfg: TrainConfig,
    /// Dims of the finest stage.
    pub final_dims: [usize; 3],
    pub step: usize,
    grad: Vec<f32>,
    m: Vec<u16>,
    v: Vec<u16>,
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
    /// Seconds spent in (forward + backward, gradient scatter, TV + Adam, occupancy pruning and
    /// parameter averaging).
    pub phase_secs: [f64; 4],
    /// Bytes the grid and its optimiser state may take at the finest stage (None: as planned).
    pub budget: Option<usize>,
    /// How the finest stage's resolution was chosen, once it started.
    pub finest: Option<FinestStage>,
    /// The running mean of the parameters, once `cfg.average_from` has passed.
    average: Option<average::ParamAverage>,
    /// Each training view's learnt colour correction (`cfg.appearance_lr` > 0), and its
    /// gradient per chunk (summed in chunk order, as the network's).
    pub appearance: Option<Appearance>,
    app_grads: Vec<Vec<f32>>,
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
            average: None,
            appearance: None,
            app_grads: Vec::new(),
        };
        t.reset_state();
        t
    }

    fn reset_state(&mut self) {
        let n = self.field.grid.data.len();
        self.grad = vec![0.0; n];
        self.m = vec![0; n];
        self.v = vec![0; n];
        self.stamp = vec![0; self.field.grid.num_vertices()];
        self.adam_t = 0;
        self.average = None;
    }

    /// Follow the grid when it dropped bricks: the optimiser state of the kept slots moves with
    /// them (the gradient is all zero between steps).
    fn follow_compaction(&mut self, map: &[u32]) {
        let per = BRICK_VERTICES * self.field.grid.channels;
        compact_buffer(&mut self.m, map, per);
        compact_buffer(&mut self.v, map, per);
        self.grad.truncate(self.m.len());
        compact_buffer(&mut self.stamp, map, BRICK_VERTICES);
        if let Some(a) = &mut self.average {
            compact_buffer(&mut a.data, map, per);
        }
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

    /// Optimiser state (m, v as bfloat16, step count) for saving a resumable model.
    pub fn adam_state(&self) -> (&[u16], &[u16], u32) {
        (&self.m, &self.v, self.adam_t)
    }

    /// Restore optimiser state saved with [`Trainer::adam_state`] (the file holds f32).
    pub fn set_adam_state(&mut self, m: Vec<f32>, v: Vec<f32>, t: u32) {
        if m.len() == self.grad.len() && v.len() == self.grad.len() {
            self.m = m.into_iter().map(to_bf16).collect();
            self.v = v.into_iter().map(to_bf16).collect();
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
            + self.grad.len() * 4
            + (self.m.len() + self.v.len()) * 2
            + self.stamp.len() * 4
            + self.average.as_ref().map_or(0, |a| a.data.len() * 4)
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
        let per_brick = BRICK_VERTICES * bytes_per_vertex(self.field.grid.channels);
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
        if self.cfg.appearance_lr > 0.0
            && self.appearance.as_ref().map(Appearance::views) != Some(views.len())
        {
            self.appearance = Some(Appearance::identity(views.len()));
        }
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
            slab_of_layer: &slabs.slab_of_layer,
            appearance: self.appearance.as_ref().map(|a| &a.params[..]),
        };
        let net_len = field.net.as_ref().map_or(0, |n| n.weights.len());
        let app_len = self.appearance.as_ref().map_or(0, |a| a.params.len());
        self.net_grads.resize_with(nchunks, Vec::new);
        self.app_grads.resize_with(nchunks, Vec::new);
        let stats: Vec<(f64, f64, usize)> = self
            .records
            .par_iter_mut()
            .zip(self.net_grads.par_iter_mut())
            .zip(self.app_grads.par_iter_mut())
            .zip(picks.par_chunks(CHUNK))
            .enumerate()
            .map(|(ci, (((rec, net_grad), app_grad), chunk))| {
                net_grad.clear();
                net_grad.resize(net_len, 0.0);
                app_grad.clear();
                app_grad.resize(app_len, 0.0);
                ctx.chunk_gradients(ci, chunk, rec, net_grad, app_grad)
            })
            .collect();
        let (loss, mse, nsamp) = stats
            .iter()
            .fold((0.0, 0.0, 0), |a, s| (a.0 + s.0, a.1 + s.1, a.2 + s.2));
        if net_len > 0 {
            self.step_net(nchunks);
        }
        if app_len > 0 {
            self.step_appearance(nchunks);
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
        self.maybe_fold_average();
        let n = picks.len() as f64;
        StepStats {
            step: self.step,
            loss: (loss / n) as f32,
            psnr: (-10.0 * (mse / n).max(1e-12).log10()) as f32,
            samples_per_ray: nsamp as f32 / n as f32,
            ..Default::default()
        }
    }

    /// The grid's z-slabs: ranges of brick layers, each a contiguous range of slots, a few per
    /// thread, cut where the allocated bricks split evenly (a step touches vertices about where
    /// they are allocated: layers of equal count left one thread idle while the other finished
    /// the base plate's slab). Each thread sums and applies the gradient of its own slabs; the
    /// split depends on the thread count and the bricks, neither of which changes the sums (see
    /// the module notes).
    fn slabs(&self) -> Slabs {
        let grid = &self.field.grid;
        let layers = grid.brick_dims[2];
        let starts = grid.layer_starts();
        let total = starts[layers];
        let want = (rayon::current_num_threads() * SLABS_PER_THREAD).clamp(1, layers.max(1));
        let mut slab_of_layer = Vec::with_capacity(layers);
        let mut cuts = vec![0usize];
        for &start in &starts[..layers] {
            let next = cuts.len();
            if next < want && start * want >= next * total && start > *cuts.last().unwrap() {
                cuts.push(start);
            }
            slab_of_layer.push((cuts.len() - 1) as u32);
        }
        cuts.push(total);
        Slabs {
            slab_of_layer,
            bounds: cuts.into_iter().map(|b| b * BRICK_VERTICES).collect(),
        }
    }

    /// Scatter the records into the gradient by z-slabs, add TV, and take an Adam step on the
    /// touched vertices only.
    fn apply_gradients(&mut self, stride: usize, slabs: &Slabs) {
        let ch = self.field.grid.channels;
        let stamp_id = self.step as u32 + 1;
        let clock = std::time::Instant::now();
        // On a step without TV, each slab runs Adam on its vertices right after summing their
        // gradients, while those lines are still in cache (TV reads neighbours across slabs, so
        // it needs every slab's scatter finished first).
        let fused = !self.tv_this_step();
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

    /// Whether this step adds TV (on every `tv_every`-th step before `tv_until`, when any TV
    /// weight is set).
    fn tv_this_step(&self) -> bool {
        let cfg = &self.cfg;
        (cfg.tv_density > 0.0 || cfg.tv_color > 0.0)
            && self.step % cfg.tv_every.max(1) == 0
            && self.progress() < cfg.tv_until
    }

    fn tv_and_adam(&mut self, touched: &[Vec<u32>], bounds: &[usize]) {
        let cfg = &self.cfg;
        let grid = &self.field.grid;
        let dims = grid.dims;
        let ch = grid.channels;
        let params = &grid.data;
        // DVGO's TV, so its weights carry over: each neighbour's difference clamped to
        // [-1, 1], the weight over the batch (the colour loss is a mean) and six neighbours,
        // times the grid's largest side over 128 (the same smoothing at any resolution),
        // times the period between TV steps.
        let scale = dims.iter().copied().max().unwrap_or(1) as f32
            / 128.0
            / (6.0 * cfg.batch.max(1) as f32)
            * cfg.tv_every.max(1) as f32;
        let (w_density, w_colour) = (cfg.tv_density * scale, cfg.tv_color * scale);
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
                            for j in 0..ch {
                                let w = if j == 0 { w_density } else { w_colour };
                                let diff =
                                    params[value_index(v, j, ch)] - params[value_index(n, j, ch)];
                                gslab[value_index(v - v0, j, ch)] += w * diff.clamp(-1.0, 1.0);
                            }
                        }
                    }
                }
            });
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

    /// Sum the chunks' appearance gradients in chunk order and step the views' corrections.
    fn step_appearance(&mut self, nchunks: usize) {
        let cfg = &self.cfg;
        let lr = cfg.appearance_lr * cfg.lr_final.powf(self.progress());
        let (first, rest) = self.app_grads[..nchunks]
            .split_first_mut()
            .expect("a chunk");
        for g in rest.iter() {
            first.iter_mut().zip(g).for_each(|(a, b)| *a += b);
        }
        if let Some(a) = self.appearance.as_mut() {
            a.step(first, lr, cfg.appearance_pull, cfg.beta1, cfg.beta2);
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
