//! Ray marching and volume rendering, forward and backward.
//!
//! A ray is clipped to the field's box and sampled every `step` voxels (a per-ray jitter in
//! training). Empty bricks and blocks of bricks ([`LiveBricks`](super::live::LiveBricks)) are
//! jumped, samples in free cells (occupancy) are skipped without touching the grid, samples with
//! alpha below `alpha_thresh` are dropped (DVGO's fast_color_thres), and marching stops once the
//! transmittance falls below `term_thresh` (early termination).
//!
//! Colour composite: C = sum_i T_i a_i c_i + T_end * bg, opacity A = 1 - T_end. The backward uses
//! the suffix form dC/da_i = T_i (c_i - R_i), where R_i is what the ray sees behind sample i
//! (normalised by its transmittance): this needs no division by (1 - a_i), so it stays exact when
//! a sample is opaque.

// Index loops over the 3 colour channels read as the maths does; iterators would obscure it.
#![allow(clippy::needless_range_loop)]

use super::activation::alpha_and_slope;
use super::colour_net::{MAX_ACTIVATIONS, MAX_HIDDEN};
use super::grid::BRICK;
use super::live::BLOCK;
use super::model::{Field, RayShading, MAX_CHANNELS};
use super::sh::{sh_basis, SH_TERMS};
use crate::space::{ContractedSteps, LineDepth, RayPath};
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RenderOptions {
    /// Sample spacing in voxels of the current grid.
    pub step: f32,
    pub alpha_thresh: f32,
    pub term_thresh: f32,
    /// Rays a pixel takes per axis when a whole view is rendered ([`render_view`]): the pixel's
    /// colour is the mean of `n x n` rays on a regular grid over its square (antialiasing).
    /// One by default: 2 x 2 scored +0.10 dB on lego 800^2's test views but -0.35 to -0.61 dB
    /// on the demo objects' held-out views, fit closely to their box-filtered pixels
    /// (examples/results/field.md, "Pixels as the mean of 2 x 2 rays").
    ///
    /// [`render_view`]: super::eval::render_view
    #[serde(default = "one_ray")]
    pub pixel_samples: u32,
}

/// Model files written before `pixel_samples` rendered one ray a pixel.
fn one_ray() -> u32 {
    1
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            step: 0.5,
            alpha_thresh: 1e-4,
            term_thresh: 1e-4,
            pixel_samples: 1,
        }
    }
}

/// One kept sample, with what the backward needs.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sample {
    /// Linear index of the cell's base vertex and the fractional position in the cell.
    pub base: u32,
    pub frac: [f32; 3],
    pub t: f32,
    /// Distance along the path in space coordinates (from where the march began): the
    /// distortion loss measures spread in space, whose samples are evenly spaced, not in world
    /// length, which NDC and the contraction stretch without bound towards infinity.
    pub s: f32,
    pub alpha: f32,
    /// Transmittance in front of the sample.
    pub trans: f32,
    pub rgb: [f32; 3],
    /// sigmoid(raw + shift): d softplus / d raw.
    pub dsp: f32,
    /// Whether its colour was computed (a network's colour skips samples of negligible weight;
    /// `rgb` is then 0).
    pub shaded: bool,
}

/// Weight (T alpha) below which a network-coloured sample gets no colour, at a step of one
/// voxel (training's). The marcher scales it with the step, since a sample's weight in a
/// surface does: with the weight fixed, rendering lego 800^2's 20-minute model every quarter
/// voxel left more of each surface's samples uncoloured (black) and scored 33.95 dB against
/// 34.19 with every sample coloured (examples/results/field.md, "The finest stage sooner;
/// colour threshold and step").
pub const NET_MIN_WEIGHT: f32 = 3e-3;

/// The result of one ray.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayOut {
    /// Colour composited on the background.
    pub rgb: [f32; 3],
    pub alpha: f32,
    /// Expected depth sum_i w_i t_i (world units along the unit direction; not normalised).
    pub depth: f32,
}

/// March one ray (unit world direction `d`), composite on `bg`, and record the kept samples.
/// `jitter` in [0, 1) offsets the first sample by that fraction of a step. The samples' `t` is
/// the distance along the world ray, in every [`Space`](crate::space::Space).
pub fn forward(
    f: &Field,
    opt: &RenderOptions,
    o: Vec3,
    d: Vec3,
    jitter: f32,
    bg: [f32; 3],
    samples: &mut Vec<Sample>,
) -> RayOut {
    forward_seen_from(f, opt, o, d, d, jitter, bg, samples)
}

/// [`forward`] with the colour taken as seen along `view_d` (a unit direction) rather than
/// along the ray: training jitters it ([`TrainConfig::view_jitter`]).
///
/// [`TrainConfig::view_jitter`]: super::train::TrainConfig::view_jitter
#[allow(clippy::too_many_arguments)]
pub fn forward_seen_from(
    f: &Field,
    opt: &RenderOptions,
    o: Vec3,
    d: Vec3,
    view_d: Vec3,
    jitter: f32,
    bg: [f32; 3],
    samples: &mut Vec<Sample>,
) -> RayOut {
    samples.clear();
    let mut m = Marcher::new(f, opt, view_d, samples);
    match f.space.ray_path(o, d, f.box_min, f.box_max) {
        None => {}
        Some(RayPath::Line { o, d, s0, s1, t }) => m.line(o, d, s0, s1, t, jitter),
        Some(RayPath::Contracted {
            o,
            d,
            t0,
            center,
            radius,
        }) => {
            let step = opt.step * f.voxel;
            let steps = ContractedSteps::new(o, d, t0, center, radius, step, jitter);
            for (k, (t, x)) in steps.enumerate() {
                let p = (x - f.box_min) / f.voxel;
                let (b, fr) = f.grid.locate([p.x, p.y, p.z]);
                if !f.brick_occupied(b) {
                    continue;
                }
                if !m.visit(b, fr, t, k as f32 * step) {
                    break;
                }
            }
        }
    }
    m.finish(bg)
}

/// The state of one ray's march: the field's constants, the transmittance so far and what has
/// been composited.
struct Marcher<'a> {
    f: &'a Field,
    opt: &'a RenderOptions,
    shading: RayShading,
    /// The ray's unit direction (for a reflected direction).
    d: Vec3,
    /// Sample spacing in finest voxels (alpha = 1 - exp(-density * delta)).
    delta: f32,
    shift: f32,
    /// Raw density (with the shift) under which a sample is below `alpha_thresh`, a little
    /// low so that the check before the exponentials drops nothing the exact test keeps.
    raw_min: f32,
    trans: f32,
    out: RayOut,
    feat: [f32; MAX_CHANNELS],
    /// Scratch for a network's hidden units.
    h: [f32; MAX_ACTIVATIONS],
    /// [`NET_MIN_WEIGHT`] at this step.
    min_weight: f32,
    samples: &'a mut Vec<Sample>,
}

impl<'a> Marcher<'a> {
    fn new(f: &'a Field, opt: &'a RenderOptions, d: Vec3, samples: &'a mut Vec<Sample>) -> Self {
        let mut basis = [0f32; SH_TERMS];
        sh_basis(f.config.sh_degree, d, &mut basis);
        let delta = opt.step * f.voxel / f.config.base_voxel;
        Marcher {
            f,
            opt,
            shading: f.shading(basis),
            d,
            delta,
            shift: f.shift(),
            raw_min: f.raw_for_alpha(opt.alpha_thresh, delta) + f.shift() - 1e-3,
            trans: 1.0,
            out: RayOut::default(),
            feat: [0f32; MAX_CHANNELS],
            h: [0f32; MAX_ACTIVATIONS],
            min_weight: NET_MIN_WEIGHT * opt.step,
            samples,
        }
    }

    /// A straight path in space: samples every `step` voxels from `s0 + jitter * step`; empty
    /// bricks are jumped over to the next sample of the same lattice.
    fn line(&mut self, o: Vec3, d: Vec3, s0: f32, s1: f32, depth: LineDepth, jitter: f32) {
        let f = self.f;
        let step_w = self.opt.step * f.voxel;
        let og = (o - f.box_min) / f.voxel;
        let dg = d / f.voxel;
        let dims = f.grid.dims;
        let t0 = s0 + jitter * step_w;
        // Sample k sits at t0 + k * step (not an accumulated sum), so skipping ahead lands on
        // exactly the samples a dense march would take.
        let mut ks = 0u32;
        let mut t = t0;
        let inv_dg = dg.recip();
        while t < s1 {
            let p = og + dg * t;
            let (b, fr) = f.grid.locate([p.x, p.y, p.z]);
            if !f.brick_occupied(b) {
                // Jump to the first sample of the lattice t0 + k * step past this brick's exit
                // (or its whole block's, when that is empty too), so the samples taken are the
                // same as without skipping.
                let size = if f.live.block(b.map(|v| v / BRICK)) {
                    BRICK
                } else {
                    BRICK * BLOCK
                };
                let bb = b.map(|v| v / size);
                let mut t_exit = f32::MAX;
                for a in 0..3 {
                    let lo = (bb[a] * size) as f32;
                    let hi = ((bb[a] + 1) * size).min(dims[a] - 1) as f32;
                    let bound = if inv_dg[a] > 0.0 { hi } else { lo };
                    let te = (bound - og[a]) * inv_dg[a];
                    if te.is_finite() {
                        t_exit = t_exit.min(te);
                    }
                }
                let kn = ((t_exit - t0) / step_w).ceil() as u32;
                ks = kn.max(ks + 1);
                t = t0 + ks as f32 * step_w;
                continue;
            }
            ks += 1;
            let t_next = t0 + ks as f32 * step_w;
            // The march waits on memory: fetch the next sample's cell while this one shades.
            let p_next = og + dg * t_next;
            f.grid
                .prefetch_cell(f.grid.locate([p_next.x, p_next.y, p_next.z]).0);
            if !self.visit(b, fr, depth.world_t(t), t) {
                break;
            }
            t = t_next;
        }
    }

    /// Shade the sample at cell `b`, fraction `fr`, world distance `t` and space distance `s`:
    /// composite and record it when it is occupied and not transparent. False once the ray is
    /// opaque (stop marching).
    #[inline]
    fn visit(&mut self, b: [usize; 3], fr: [f32; 3], t: f32, s: f32) -> bool {
        let f = self.f;
        if !f.occupied(b) {
            return true;
        }
        let kc = f.grid.corners_of(b, fr);
        let raw = f.grid.interp_density(&kc) + self.shift;
        if raw < self.raw_min {
            return true;
        }
        let (alpha, slope) = alpha_and_slope(raw, self.delta);
        if alpha < self.opt.alpha_thresh {
            return true;
        }
        let w = self.trans * alpha;
        // A network's colour costs a few thousand multiply-adds: samples that add almost
        // nothing to the pixel keep their alpha but no colour (DVGO's fast_color_thres).
        let shaded = f.net.is_none() || w >= self.min_weight;
        let mut rgb = [0f32; 3];
        if shaded {
            let ch = f.grid.channels;
            f.grid.interp_colour(&kc, &mut self.feat[..ch - 1]);
            let refl = f.reflection_basis(&kc, fr, self.d);
            rgb = f.shade(&self.feat, &refl, &self.shading, &mut self.h);
        }
        for c in 0..3 {
            self.out.rgb[c] += w * rgb[c];
        }
        self.out.depth += w * t;
        let dims = f.grid.dims;
        self.samples.push(Sample {
            base: (b[0] + dims[0] * (b[1] + dims[1] * b[2])) as u32,
            frac: fr,
            t,
            s,
            alpha,
            trans: self.trans,
            rgb,
            dsp: slope,
            shaded,
        });
        self.trans *= 1.0 - alpha;
        self.trans >= self.opt.term_thresh
    }

    fn finish(mut self, bg: [f32; 3]) -> RayOut {
        self.out.alpha = 1.0 - self.trans;
        for c in 0..3 {
            self.out.rgb[c] += self.trans * bg[c];
        }
        self.out
    }
}

/// The loss's gradients with respect to one ray's outputs, for [`backward`].
#[derive(Clone, Copy, Debug, Default)]
pub struct RayGrad<'a> {
    /// dL/dC, dL/dA and dL/d depth.
    pub rgb: [f32; 3],
    pub alpha: f32,
    pub depth: f32,
    /// dL/dw_i for each sample's weight w_i = T_i a_i, if not empty (e.g. from [`distortion`]).
    pub weights: &'a [f32],
    /// dL/da_i, the same for every sample: the sparsity loss L = lambda sum_i a_i over the
    /// ray's kept samples (what lies behind the opaque part is not kept, so hidden insides
    /// are not emptied).
    pub alpha_each: f32,
}

/// Backward of [`forward`] for the loss gradients `g`. For each kept sample, `emit(sample,
/// grad)` receives the gradient of the loss with respect to the interpolated channels [raw
/// density, SH coefficients or features]; a network's weight gradient is added to `net_grad`.
#[allow(clippy::too_many_arguments)]
pub fn backward(
    f: &Field,
    opt: &RenderOptions,
    d: Vec3,
    bg: [f32; 3],
    samples: &[Sample],
    g: &RayGrad,
    net_grad: &mut [f32],
    mut emit: impl FnMut(&Sample, &[f32]),
) {
    let (g_rgb, g_alpha, g_depth, g_weights) = (g.rgb, g.alpha, g.depth, g.weights);
    let k = f.sh_k();
    let ch = f.grid.channels;
    let mut basis = [0f32; SH_TERMS];
    sh_basis(f.config.sh_degree, d, &mut basis);
    let shading = f.shading(basis);
    let delta = opt.step * f.voxel / f.config.base_voxel;
    // What lies behind the current sample, per unit of transmittance there.
    let mut r_rgb = bg;
    let mut r_a = 0.0f32;
    let mut r_d = 0.0f32;
    let mut grad = [0f32; MAX_CHANNELS];
    let (mut feat, mut h) = ([0f32; MAX_CHANNELS], [0f32; MAX_ACTIVATIONS]);
    // dL/d(the ray's shared pre-activation), summed over its samples.
    let mut g_bias = [0f32; MAX_HIDDEN];
    for (i, s) in samples.iter().enumerate().rev() {
        let w = s.trans * s.alpha;
        // Everything linear in the weights as one value per sample: depth (t) and g_weights.
        let value = g_depth * s.t + g_weights.get(i).copied().unwrap_or(0.0);
        let mut g_a = 0.0;
        for c in 0..3 {
            g_a += g_rgb[c] * (s.rgb[c] - r_rgb[c]);
        }
        g_a += g_alpha * (1.0 - r_a) + (value - r_d);
        g_a = g_a * s.trans + g.alpha_each;
        // d alpha / d raw = (1 - alpha) * delta * sigmoid(raw)
        grad[0] = g_a * (1.0 - s.alpha) * delta * s.dsp;
        match &f.net {
            Some(net) if s.shaded => {
                // The network's hidden units are recomputed rather than stored per sample.
                let kc = f
                    .grid
                    .corners_of(f.grid.cell_of_base(s.base as usize), s.frac);
                f.grid.interp_colour(&kc, &mut feat[..ch - 1]);
                let refl = f.reflection_basis(&kc, s.frac, d);
                f.shade(&feat, &refl, &shading, &mut h);
                let gc = g_rgb.map(|c| c * w);
                let nf = net.features;
                net.backward_features(
                    &feat[..nf],
                    &refl,
                    &h,
                    s.rgb,
                    gc,
                    &mut grad[1..],
                    net_grad,
                    &mut g_bias,
                );
            }
            Some(_) => grad[1..ch].fill(0.0),
            None => {
                for c in 0..3 {
                    let gc = g_rgb[c] * w * s.rgb[c] * (1.0 - s.rgb[c]);
                    for j in 0..k {
                        grad[1 + c * k + j] = gc * basis[j];
                    }
                }
            }
        }
        emit(s, &grad[..ch]);
        for c in 0..3 {
            r_rgb[c] = s.alpha * s.rgb[c] + (1.0 - s.alpha) * r_rgb[c];
        }
        r_a = s.alpha + (1.0 - s.alpha) * r_a;
        r_d = s.alpha * value + (1.0 - s.alpha) * r_d;
    }
    if let Some(net) = &f.net {
        net.backward_ray(&basis[..net.dir_terms], &g_bias, net_grad);
    }
}

/// Mip-NeRF 360's distortion loss over a ray's kept samples, with distances along the path in
/// space coordinates ([`Sample::s`]) in `unit` lengths and each sample spanning `delta` units:
/// L = sum_ij w_i w_j |s_i - s_j| + sum_i w_i^2 delta / 3. It is small when the weight sits in
/// one short interval, so it pulls a surface's weight together where colour alone leaves it
/// spread (uniformly coloured parts of an object, seen from few directions). Measured in world
/// length it put forward fields on their near plane, where NDC's samples are closest in the
/// world: fern and the forward demo without depth held out 14.4-14.5 dB (3000 steps), 27.5 on
/// the demo with the loss off. Writes dL/dw_i into `g_w` and returns L.
pub fn distortion(samples: &[Sample], unit: f32, delta: f32, g_w: &mut Vec<f32>) -> f32 {
    g_w.clear();
    let inv = 1.0 / unit;
    let (mut w_all, mut ws_all) = (0f32, 0f32);
    for s in samples {
        let w = s.trans * s.alpha;
        w_all += w;
        ws_all += w * s.s * inv;
    }
    // Prefix sums of w and w s before the current sample: sum_j w_j |s_i - s_j| =
    // s_i W_before - S_before + (S_after - s_i W_after).
    let (mut w_before, mut ws_before) = (0f32, 0f32);
    let mut loss = 0f32;
    for s in samples {
        let w = s.trans * s.alpha;
        let si = s.s * inv;
        let w_after = w_all - w_before - w;
        let ws_after = ws_all - ws_before - w * si;
        let spread = si * w_before - ws_before + ws_after - si * w_after;
        loss += w * spread + w * w * delta / 3.0;
        g_w.push(2.0 * spread + 2.0 * w * delta / 3.0);
        w_before += w;
        ws_before += w * si;
    }
    loss
}

/// The free-space loss over a ray's kept samples (in order along the ray): L = weight sum_i w_i
/// over the samples nearer than `front`, the ray's depth target less a margin: the space between
/// a camera and a point it sees is empty. Adds dL/dw_i into `g_w` (sized to the samples;
/// zeros where it was empty) and returns L.
pub fn free_space(samples: &[Sample], front: f32, weight: f32, g_w: &mut Vec<f32>) -> f32 {
    g_w.resize(samples.len(), 0.0);
    let mut seen = 0f32;
    for (s, g) in samples.iter().zip(g_w.iter_mut()) {
        if s.t >= front {
            break;
        }
        seen += s.trans * s.alpha;
        *g += weight;
    }
    weight * seen
}

/// Render one ray without recording (for images).
pub fn render_ray(
    f: &Field,
    opt: &RenderOptions,
    o: Vec3,
    d: Vec3,
    bg: [f32; 3],
    scratch: &mut Vec<Sample>,
) -> RayOut {
    forward(f, opt, o, d, 0.5, bg, scratch)
}

#[cfg(test)]
mod tests;
