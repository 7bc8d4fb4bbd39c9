//! Per-view appearance: a colour correction learnt for each training view, for captures whose
//! exposure and white balance drift between frames (phone videos), and left out when rendering.
//!
//! A training ray of view i is compared with `a_i * C + b_i * A + T * bg`, where `C = sum_k w_k
//! c_k` is the field's own colour (premultiplied), `A = 1 - T` its opacity, `a_i` per-channel
//! gains and `b_i` per-channel offsets. The background (random, or the backdrop behind a mask's
//! edge) is not the photo's exposure, so it is left as it is. Rendering, evaluation and meshes
//! take the identity (`a = 1`, `b = 0`): the field holds the capture's mean appearance, fixed
//! by re-centring the gains' mean logarithm and the offsets' mean to 0 after every step (else
//! the field and all the corrections could trade colour), and by a weak pull of each view to
//! the identity (a view few rays see stays near it).

use super::super::colour_net::NetAdam;
use crate::field::march::RayOut;
use serde::Serialize;

/// Parameters per view: gains (r, g, b), then offsets (r, g, b).
pub const PER_VIEW: usize = 6;

/// The learnt corrections of a run's training views, and their optimiser.
#[derive(Clone, Debug, Default)]
pub struct Appearance {
    /// `PER_VIEW` values per view, in the order of the training views.
    pub params: Vec<f32>,
    adam: NetAdam,
}

/// The gradients a corrected ray hands on: to the field's ray outputs (for
/// [`crate::field::march::backward`]) and to the view's correction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CorrectedGrad {
    pub rgb: [f32; 3],
    /// Added to the alpha gradient the loss gives.
    pub alpha: f32,
    pub params: [f32; PER_VIEW],
}

/// `out` (composited on `bg`) with its own colour corrected by `p` (gains, offsets): the
/// colour a training ray of that view is compared with.
pub fn corrected(out: &RayOut, bg: [f32; 3], p: &[f32]) -> RayOut {
    let t = 1.0 - out.alpha;
    let mut o = *out;
    for c in 0..3 {
        let own = out.rgb[c] - t * bg[c];
        o.rgb[c] = p[c] * own + p[3 + c] * out.alpha + t * bg[c];
    }
    o
}

/// The chain rule through [`corrected`]: `g` is dL/d(corrected colour). The field's colour
/// gradient is `a * g`; since the uncorrected output `C + T bg` already carries the background
/// term, its opacity gradient gains `sum_c g_c (b_c + (a_c - 1) bg_c)`.
pub fn corrected_grad(out: &RayOut, bg: [f32; 3], p: &[f32], g: [f32; 3]) -> CorrectedGrad {
    let t = 1.0 - out.alpha;
    let mut r = CorrectedGrad {
        rgb: [0.0; 3],
        alpha: 0.0,
        params: [0.0; PER_VIEW],
    };
    for c in 0..3 {
        let own = out.rgb[c] - t * bg[c];
        r.rgb[c] = p[c] * g[c];
        r.alpha += g[c] * (p[3 + c] + (p[c] - 1.0) * bg[c]);
        r.params[c] = g[c] * own;
        r.params[3 + c] = g[c] * out.alpha;
    }
    r
}

impl Appearance {
    /// The identity for `views` views.
    pub fn identity(views: usize) -> Appearance {
        let mut params = vec![0.0; views * PER_VIEW];
        for p in params.chunks_exact_mut(PER_VIEW) {
            p[..3].fill(1.0);
        }
        Appearance {
            params,
            adam: NetAdam::default(),
        }
    }

    pub fn views(&self) -> usize {
        self.params.len() / PER_VIEW
    }

    /// View `vi`'s gains and offsets.
    pub fn of(&self, vi: usize) -> &[f32] {
        &self.params[vi * PER_VIEW..(vi + 1) * PER_VIEW]
    }

    /// One Adam step on the summed data gradient `grad` plus the pull `pull * |p - identity|^2`
    /// per view, then the gauge fixed (mean log-gain and mean offset 0 per channel).
    pub fn step(&mut self, grad: &mut [f32], lr: f32, pull: f32, beta1: f32, beta2: f32) {
        for (g, p) in grad
            .chunks_exact_mut(PER_VIEW)
            .zip(self.params.chunks_exact(PER_VIEW))
        {
            for c in 0..3 {
                g[c] += 2.0 * pull * (p[c] - 1.0);
                g[3 + c] += 2.0 * pull * p[3 + c];
            }
        }
        self.adam.step(&mut self.params, grad, lr, beta1, beta2);
        self.recentre();
    }

    fn recentre(&mut self) {
        let n = self.views().max(1) as f32;
        for c in 0..3 {
            let (mut log_gain, mut offset) = (0f32, 0f32);
            for p in self.params.chunks_exact(PER_VIEW) {
                // A gain is kept positive: a view cannot be the negative of the field.
                log_gain += p[c].max(1e-3).ln();
                offset += p[3 + c];
            }
            let (scale, shift) = ((-log_gain / n).exp(), offset / n);
            for p in self.params.chunks_exact_mut(PER_VIEW) {
                p[c] = p[c].max(1e-3) * scale;
                p[3 + c] -= shift;
            }
        }
    }

    /// The corrections by view name (`names` in the order of the training views).
    pub fn report(&self, names: &[String]) -> Vec<ViewAppearance> {
        names
            .iter()
            .zip(self.params.chunks_exact(PER_VIEW))
            .map(|(name, p)| ViewAppearance {
                view: name.clone(),
                gain: [p[0], p[1], p[2]],
                offset: [p[3], p[4], p[5]],
            })
            .collect()
    }
}

/// One training view's learnt correction, for the training report.
#[derive(Clone, Debug, Serialize)]
pub struct ViewAppearance {
    pub view: String,
    pub gain: [f32; 3],
    pub offset: [f32; 3],
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The loss L = sum_c k_c * corrected_c + k_a * A, differentiated by hand against central
    /// differences in the ray's colour, its opacity and the correction.
    #[test]
    fn corrected_gradients_match_finite_differences() {
        let bg = [0.2, 0.7, 0.4];
        let k = [0.3f32, -1.1, 0.7];
        let p = [1.2f32, 0.8, 1.05, 0.03, -0.04, 0.1];
        // The field's own colour and opacity, the parameters of the test.
        let own = [0.25f32, 0.4, 0.1];
        let alpha = 0.6f32;
        let loss = |own: [f32; 3], alpha: f32, p: &[f32]| -> f64 {
            let out = RayOut {
                rgb: [0, 1, 2].map(|c| own[c] + (1.0 - alpha) * bg[c]),
                alpha,
                depth: 0.0,
            };
            let o = corrected(&out, bg, p);
            (0..3).map(|c| (k[c] * o.rgb[c]) as f64).sum()
        };
        let out = RayOut {
            rgb: [0, 1, 2].map(|c| own[c] + (1.0 - alpha) * bg[c]),
            alpha,
            depth: 0.0,
        };
        let g = corrected_grad(&out, bg, &p, k);
        let h = 1e-3f32;
        // The field's outputs enter the backward as (C + T bg, A): dL/dC_c is g.rgb[c] and
        // dL/dA, with C fixed, is g.alpha plus what the uncorrected output's own T bg term
        // takes (-sum g.rgb bg), as the march's backward adds it.
        for c in 0..3 {
            let (mut up, mut dn) = (own, own);
            up[c] += h;
            dn[c] -= h;
            let fd = (loss(up, alpha, &p) - loss(dn, alpha, &p)) / (2.0 * h as f64);
            assert!(
                (fd - g.rgb[c] as f64).abs() < 1e-3,
                "C{c}: {fd} {}",
                g.rgb[c]
            );
        }
        let fd = (loss(own, alpha + h, &p) - loss(own, alpha - h, &p)) / (2.0 * h as f64);
        let backward_alpha = g.alpha - (0..3).map(|c| g.rgb[c] * bg[c]).sum::<f32>();
        assert!(
            (fd - backward_alpha as f64).abs() < 1e-3,
            "A: {fd} {backward_alpha}"
        );
        for j in 0..PER_VIEW {
            let (mut up, mut dn) = (p, p);
            up[j] += h;
            dn[j] -= h;
            let fd = (loss(own, alpha, &up) - loss(own, alpha, &dn)) / (2.0 * h as f64);
            assert!(
                (fd - g.params[j] as f64).abs() < 1e-3,
                "param {j}: {fd} {}",
                g.params[j]
            );
        }
        // The identity changes nothing.
        let id = Appearance::identity(1);
        assert_eq!(corrected(&out, bg, id.of(0)), out);
        let gi = corrected_grad(&out, bg, id.of(0), k);
        assert_eq!((gi.rgb, gi.alpha), (k, 0.0));
    }

    #[test]
    fn the_gauge_keeps_the_mean_gain_one_and_the_mean_offset_zero() {
        let mut a = Appearance::identity(3);
        let mut grad = vec![0.0; 3 * PER_VIEW];
        // Every view asks for a brighter red: with the gauge fixed, nothing moves.
        for g in grad.chunks_exact_mut(PER_VIEW) {
            g[0] = -1.0;
            g[3] = -1.0;
        }
        a.step(&mut grad, 0.01, 0.0, 0.9, 0.99);
        for vi in 0..3 {
            assert!((a.of(vi)[0] - 1.0).abs() < 1e-5 && a.of(vi)[3].abs() < 1e-6);
        }
        // One view darker than the others: its gain falls, theirs rise, the product stays 1.
        let mut grad = vec![0.0; 3 * PER_VIEW];
        grad[PER_VIEW + 1] = 1.0;
        a.step(&mut grad, 0.01, 0.0, 0.9, 0.99);
        let g: Vec<f32> = (0..3).map(|vi| a.of(vi)[1]).collect();
        assert!(g[1] < 1.0 && g[0] > 1.0 && g[2] > 1.0, "{g:?}");
        assert!((g.iter().product::<f32>() - 1.0).abs() < 1e-5, "{g:?}");
    }
}
