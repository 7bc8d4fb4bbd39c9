//! The forward half of a step: each chunk of rays rendered, its losses, and the backward pass's
//! gradient records bucketed by the z-slab they touch.

use super::super::grid::BRICK;
use super::super::model::Field;
use super::super::view::{EdgePixel, View};
use super::appearance::{corrected, corrected_grad, PER_VIEW};
use super::config::TrainConfig;
use crate::field::march::{
    backward, distortion, forward_seen_from, free_space, RayGrad, RayOut, Sample,
};
use crate::util::Rng;

/// Rays a chunk: the unit of work, and of the order in which gradients are summed.
pub(super) const CHUNK: usize = 256;

/// Opacity a ray needs before its depth is supervised (its normalised depth means little before).
const MIN_DEPTH_ALPHA: f32 = 0.1;

/// What every chunk of a step shares.
pub(super) struct StepContext<'a> {
    pub(super) field: &'a Field,
    pub(super) cfg: &'a TrainConfig,
    pub(super) views: &'a [View],
    pub(super) step: usize,
    /// 1 / rays in the batch: the loss is a mean.
    pub(super) inv_b: f32,
    /// Vertices per z-plane, and the z-slabs (of brick layers) the gradient records are
    /// bucketed by.
    pub(super) plane: usize,
    pub(super) nslabs: usize,
    pub(super) slab_of_layer: &'a [u32],
    /// Each training view's colour correction (`PER_VIEW` values a view), when learnt.
    pub(super) appearance: Option<&'a [f32]>,
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
    /// records into `rec` (one list per z-slab), the network's and the views' corrections'
    /// gradients added to `net_grad` and `app_grad`, and (loss, squared error, samples) summed.
    pub(super) fn chunk_gradients(
        &self,
        ci: usize,
        chunk: &[(u32, u32)],
        rec: &mut Vec<Vec<f32>>,
        net_grad: &mut [f32],
        app_grad: &mut [f32],
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
            let jitter = r.f32();
            let view_d = jittered(d, cfg.view_jitter, &mut r);
            let out = forward_seen_from(field, &cfg.render, o, d, view_d, jitter, bg, &mut samples);
            nsamp += samples.len();
            // The depth target, and the space length a world length spans there (the depth
            // and free-space losses both measure in finest voxels at the target).
            let target = view.depth.as_ref().map_or(0.0, |d| d[px as usize]);
            let per_world = if target > 0.0 {
                field.space.space_per_world(o, d, target)
            } else {
                0.0
            };
            let correction = self
                .appearance
                .map(|a| &a[vi as usize * PER_VIEW..(vi as usize + 1) * PER_VIEW]);
            let mut l = match correction {
                Some(p) => self.ray_loss(view, px, per_world, bg, edge, &corrected(&out, bg, p)),
                None => self.ray_loss(view, px, per_world, bg, edge, &out),
            };
            if let Some(p) = correction {
                let g = corrected_grad(&out, bg, p, l.g_rgb);
                l.g_rgb = g.rgb;
                l.g_alpha += g.alpha;
                let at = vi as usize * PER_VIEW;
                app_grad[at..at + PER_VIEW]
                    .iter_mut()
                    .zip(g.params)
                    .for_each(|(a, b)| *a += b);
            }
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
            if cfg.free_space_weight > 0.0 && target > 0.0 {
                // The margin in finest voxels, as world length at the target.
                let front = target - cfg.free_space_margin * unit / per_world.max(1e-9);
                let k = cfg.free_space_weight * self.inv_b;
                loss += (free_space(&samples, front, k, &mut g_w) / self.inv_b) as f64;
            }
            if cfg.sparsity_weight > 0.0 {
                let kept: f32 = samples.iter().map(|s| s.alpha).sum();
                loss += (cfg.sparsity_weight * kept) as f64;
            }
            let (plane, slab_of) = (self.plane, self.slab_of_layer);
            let last = slab_of.len() - 1;
            backward(
                field,
                &cfg.render,
                view_d,
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
                        slab_of[(z / BRICK).min(last)] as usize,
                        slab_of[((z + 1) / BRICK).min(last)] as usize,
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
    /// colour decides. `per_world`: the space length a world length spans at the depth target
    /// ([`crate::space::Space::space_per_world`]).
    fn ray_loss(
        &self,
        view: &View,
        px: u32,
        per_world: f32,
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
                // The error in finest voxels at the target (world units in a box; NDC and the
                // contraction shrink distance, and world units there would weigh a far target's
                // stereo error thousands of times a near one's).
                let inv_voxel = per_world / self.field.config.base_voxel;
                let dn = out.depth / out.alpha;
                let ed = (dn - dt) * inv_voxel;
                let (penalty, slope) = depth_penalty(ed, cfg.depth_robust_voxels);
                let g = cfg.depth_weight * slope * inv_voxel * inv_b;
                g_depth = g / out.alpha;
                g_alpha -= g * dn / out.alpha;
                loss += (cfg.depth_weight * penalty) as f64;
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

/// The depth loss of an error of `e` finest voxels and its derivative: `e^2`, or with a scale
/// `c > 0` Cauchy's `c^2 ln(1 + (e/c)^2)`, the same near 0 and whose pull is at most `c`.
fn depth_penalty(e: f32, c: f32) -> (f32, f32) {
    if c <= 0.0 {
        return (e * e, 2.0 * e);
    }
    let r = 1.0 + (e / c) * (e / c);
    (c * c * r.ln(), 2.0 * e / r)
}

/// `d` turned by a random angle of about `sigma` radians (each component of the turn drawn
/// normal): the colour is then learnt as seen from near the camera, not from it alone.
fn jittered(d: glam::Vec3, sigma: f32, r: &mut Rng) -> glam::Vec3 {
    if sigma <= 0.0 {
        return d;
    }
    let n = glam::Vec3::new(r.normal() as f32, r.normal() as f32, r.normal() as f32);
    (d + sigma * n).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_robust_depth_penalty_is_the_square_near_zero_and_caps_its_pull() {
        for e in [-30.0f32, -3.0, -0.5, 0.0, 0.2, 2.0, 7.0, 100.0] {
            let (sq, dsq) = depth_penalty(e, 0.0);
            assert_eq!((sq, dsq), (e * e, 2.0 * e));
            let (p, d) = depth_penalty(e, 3.0);
            // The derivative is the penalty's slope.
            let h = 1e-2;
            let fd = (depth_penalty(e + h, 3.0).0 - depth_penalty(e - h, 3.0).0) / (2.0 * h);
            assert!(
                (d - fd).abs() < 1e-2 * (1.0 + d.abs()),
                "e {e}: {d} vs {fd}"
            );
            assert!(p <= sq + 1e-6 && d.abs() <= 3.0 + 1e-6, "e {e}: {p} {d}");
        }
        // A tenth of the scale off: within 1% of the square.
        let (p, _) = depth_penalty(0.3, 3.0);
        assert!((p - 0.09).abs() < 0.01 * 0.09, "{p}");
        // Far off, the pull falls: ten scales off it is a fifth of its most.
        assert!(
            depth_penalty(30.0, 3.0).1 < 0.6,
            "{:?}",
            depth_penalty(30.0, 3.0)
        );
    }

    #[test]
    fn jittered_directions_turn_by_about_sigma() {
        let d = glam::Vec3::new(0.3, -0.5, 0.8).normalize();
        let mut r = Rng::new(7);
        assert_eq!(jittered(d, 0.0, &mut r), d);
        let sigma = 2f32.to_radians();
        let n = 4000;
        let mut mean = 0.0;
        for _ in 0..n {
            let j = jittered(d, sigma, &mut r);
            assert!((j.length() - 1.0).abs() < 1e-5);
            mean += j.dot(d).clamp(-1.0, 1.0).acos() / n as f32;
        }
        // The turn is the draw's part across d, a 2-D normal: its mean length is
        // sigma * sqrt(pi / 2).
        let expect = sigma * (std::f32::consts::PI / 2.0).sqrt();
        assert!(
            (mean - expect).abs() < 0.05 * expect,
            "{mean} against {expect}"
        );
    }
}
