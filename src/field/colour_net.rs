//! Colour from a feature grid through a small network (DVGO's colour): each vertex holds
//! `features` values beside its density; a sample's interpolated features and the spherical-
//! harmonic basis of its view direction go through one hidden ReLU layer to RGB (sigmoid).
//!
//! The network is shared by every sample, so its gradient is summed over a batch (per chunk of
//! rays, then in chunk order: deterministic) and stepped with its own Adam
//! ([`NetAdam`]). Forward and backward are written out by hand, as the rest of the field.

use super::activation::sigmoid;
use crate::util::Rng;

/// The most inputs (features + direction terms) and hidden units the render buffers hold.
pub const MAX_INPUTS: usize = 40;
pub const MAX_HIDDEN: usize = 128;

#[derive(Clone, Debug, PartialEq)]
pub struct ColourNet {
    /// Feature channels per vertex (after the density).
    pub features: usize,
    /// Direction terms: the SH basis of the view direction to the field's degree.
    pub dir_terms: usize,
    pub hidden: usize,
    /// W1 (inputs x hidden, input-major), b1 (hidden), W2 (3 x hidden), b2 (3).
    pub weights: Vec<f32>,
}

impl ColourNet {
    /// A network with uniform He initialisation (seeded) and zero biases: with the features at
    /// zero it starts near grey, as a fresh SH grid does.
    pub fn new(features: usize, dir_terms: usize, hidden: usize, seed: u64) -> ColourNet {
        assert!(features + dir_terms <= MAX_INPUTS && hidden <= MAX_HIDDEN && hidden > 0);
        let inputs = features + dir_terms;
        let mut net = ColourNet {
            features,
            dir_terms,
            hidden,
            weights: vec![0.0; Self::weight_count(inputs, hidden)],
        };
        let mut r = Rng::new(seed ^ 0xC0_10_0E);
        let a1 = (6.0 / inputs as f32).sqrt();
        let a2 = (6.0 / hidden as f32).sqrt() * 0.1;
        let (w1, w2) = (inputs * hidden, inputs * hidden + hidden);
        for w in &mut net.weights[..w1] {
            *w = (2.0 * r.f32() - 1.0) * a1;
        }
        for w in &mut net.weights[w2..w2 + 3 * hidden] {
            *w = (2.0 * r.f32() - 1.0) * a2;
        }
        net
    }

    pub fn weight_count(inputs: usize, hidden: usize) -> usize {
        inputs * hidden + hidden + 3 * hidden + 3
    }

    pub fn inputs(&self) -> usize {
        self.features + self.dir_terms
    }

    /// RGB for inputs `x` ([features, direction terms]); the hidden activations go to `h`.
    /// The whole network on one input, which the renderer splits per ray and per sample: kept
    /// for the gradient test, which checks the two parts through it.
    #[cfg(test)]
    pub fn forward(&self, x: &[f32], h: &mut [f32]) -> [f32; 3] {
        let mut bias = [0f32; MAX_HIDDEN];
        self.ray_bias(&x[self.features..self.inputs()], &mut bias);
        self.forward_features(&x[..self.features], &bias, h)
    }

    /// The hidden units' pre-activation from the biases and the direction terms `dir`, which
    /// every sample of a ray shares: computed once a ray, it leaves a sample only its features'
    /// rows of W1 (8 of 24 at the default size).
    pub fn ray_bias(&self, dir: &[f32], bias: &mut [f32]) {
        let (w1, b1, _, _) = self.parts();
        let (nf, nh) = (self.features, self.hidden);
        let bias = &mut bias[..nh];
        bias.copy_from_slice(b1);
        for (di, row) in dir[..self.dir_terms]
            .iter()
            .zip(w1[nf * nh..].chunks_exact(nh))
        {
            bias.iter_mut().zip(row).for_each(|(a, w)| *a += di * w);
        }
    }

    /// RGB for a sample's `features` on a ray whose [`ColourNet::ray_bias`] is `bias`; the
    /// hidden activations go to `h`.
    #[inline]
    pub fn forward_features(&self, features: &[f32], bias: &[f32], h: &mut [f32]) -> [f32; 3] {
        let (w1, _, w2, b2) = self.parts();
        let nh = self.hidden;
        let h = &mut h[..nh];
        h.copy_from_slice(&bias[..nh]);
        // Input-major W1: each input adds a scaled row to every hidden unit (vectorises).
        for (xi, row) in features[..self.features].iter().zip(w1.chunks_exact(nh)) {
            h.iter_mut().zip(row).for_each(|(a, w)| *a += xi * w);
        }
        h.iter_mut().for_each(|a| *a = a.max(0.0));
        [0, 1, 2].map(|c| sigmoid(b2[c] + dot(&w2[c * nh..(c + 1) * nh], h)))
    }

    /// Backward of [`ColourNet::forward`] for dL/dRGB `g`: adds dL/dweights to `g_w` and writes
    /// dL/dfeatures (the first `features` inputs) to `g_x`. For the gradient test, as `forward`.
    #[cfg(test)]
    pub fn backward(
        &self,
        x: &[f32],
        h: &[f32],
        rgb: [f32; 3],
        g: [f32; 3],
        g_x: &mut [f32],
        g_w: &mut [f32],
    ) {
        let mut g_bias = [0f32; MAX_HIDDEN];
        self.backward_features(&x[..self.features], h, rgb, g, g_x, g_w, &mut g_bias);
        self.backward_ray(&x[self.features..self.inputs()], &g_bias, g_w);
    }

    /// Backward of [`ColourNet::forward_features`] for dL/dRGB `g`: adds dL/dweights of W2, b2
    /// and W1's feature rows to `g_w`, writes dL/dfeatures to `g_x`, and adds dL/d(ray bias)
    /// to `g_bias`, which [`ColourNet::backward_ray`] turns into the rest once a ray.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn backward_features(
        &self,
        features: &[f32],
        h: &[f32],
        rgb: [f32; 3],
        g: [f32; 3],
        g_x: &mut [f32],
        g_w: &mut [f32],
        g_bias: &mut [f32],
    ) {
        let (ni, nh, nf) = (self.inputs(), self.hidden, self.features);
        let (w1, _, w2, _) = self.parts();
        let go = [0, 1, 2].map(|c| g[c] * rgb[c] * (1.0 - rgb[c]));
        let (gw1, rest) = g_w.split_at_mut(ni * nh);
        let (_, rest) = rest.split_at_mut(nh);
        let (gw2, gb2) = rest.split_at_mut(3 * nh);
        let h = &h[..nh];
        let mut dh = [0f32; MAX_HIDDEN];
        let dh = &mut dh[..nh];
        for c in 0..3 {
            gb2[c] += go[c];
            let (gw, w) = (&mut gw2[c * nh..(c + 1) * nh], &w2[c * nh..(c + 1) * nh]);
            for j in 0..nh {
                gw[j] += go[c] * h[j];
                dh[j] += go[c] * w[j];
            }
        }
        for (d, hj) in dh.iter_mut().zip(h) {
            if *hj <= 0.0 {
                *d = 0.0;
            }
        }
        g_bias[..nh]
            .iter_mut()
            .zip(dh.iter())
            .for_each(|(a, d)| *a += d);
        for (i, (xi, row)) in features[..nf]
            .iter()
            .zip(gw1.chunks_exact_mut(nh))
            .enumerate()
        {
            row.iter_mut()
                .zip(dh.iter())
                .for_each(|(a, d)| *a += xi * d);
            g_x[i] = dot(&w1[i * nh..(i + 1) * nh], dh);
        }
    }

    /// The backward of [`ColourNet::ray_bias`]: dL/d(ray bias) `g_bias`, summed over a ray's
    /// samples, into the gradients of b1 and W1's direction rows.
    pub fn backward_ray(&self, dir: &[f32], g_bias: &[f32], g_w: &mut [f32]) {
        let (ni, nh, nf) = (self.inputs(), self.hidden, self.features);
        let (gw1, rest) = g_w.split_at_mut(ni * nh);
        let gb1 = &mut rest[..nh];
        let g_bias = &g_bias[..nh];
        gb1.iter_mut().zip(g_bias).for_each(|(a, d)| *a += d);
        for (di, row) in dir[..self.dir_terms]
            .iter()
            .zip(gw1[nf * nh..].chunks_exact_mut(nh))
        {
            row.iter_mut().zip(g_bias).for_each(|(a, d)| *a += di * d);
        }
    }

    /// (W1 input-major: inputs x hidden, b1, W2: 3 x hidden, b2).
    fn parts(&self) -> (&[f32], &[f32], &[f32], &[f32]) {
        let (ni, nh) = (self.inputs(), self.hidden);
        let (w1, rest) = self.weights.split_at(ni * nh);
        let (b1, rest) = rest.split_at(nh);
        let (w2, b2) = rest.split_at(3 * nh);
        (w1, b1, w2, b2)
    }
}

/// A dot product in 8 independent lanes, so the compiler can vectorise the sum.
#[inline]
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    acc.iter().sum::<f32>() + tail
}

/// Adam for the network's weights (the grid has its own sparse Adam).
#[derive(Clone, Debug, Default)]
pub struct NetAdam {
    m: Vec<f32>,
    v: Vec<f32>,
    t: i32,
}

impl NetAdam {
    /// (m, v, step count), for saving; None before the first step.
    pub fn state(&self) -> Option<(&[f32], &[f32], u32)> {
        (self.t > 0).then_some((&self.m[..], &self.v[..], self.t as u32))
    }

    /// Restore a saved state.
    pub fn restore(m: Vec<f32>, v: Vec<f32>, t: u32) -> NetAdam {
        NetAdam { m, v, t: t as i32 }
    }

    /// One step on `weights` with the summed gradient `grad` at learning rate `lr`.
    pub fn step(&mut self, weights: &mut [f32], grad: &[f32], lr: f32, beta1: f32, beta2: f32) {
        if self.m.len() != weights.len() {
            self.m = vec![0.0; weights.len()];
            self.v = vec![0.0; weights.len()];
            self.t = 0;
        }
        self.t += 1;
        let c1 = 1.0 - beta1.powi(self.t);
        let c2 = (1.0 - beta2.powi(self.t)).sqrt();
        for i in 0..weights.len() {
            let g = grad[i];
            self.m[i] = beta1 * self.m[i] + (1.0 - beta1) * g;
            self.v[i] = beta2 * self.v[i] + (1.0 - beta2) * g * g;
            weights[i] -= lr * (self.m[i] / c1) / (self.v[i].sqrt() / c2 + 1e-8);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The backward against central differences of the forward, for weights and features.
    #[test]
    fn network_gradients_match_finite_differences() {
        let mut net = ColourNet::new(5, 4, 12, 3);
        let mut r = Rng::new(9);
        // Biases too, so some hidden units are active and some not.
        net.weights
            .iter_mut()
            .for_each(|w| *w = r.normal() as f32 * 0.5);
        let x: Vec<f32> = (0..net.inputs()).map(|_| r.normal() as f32).collect();
        let g = [0.7f32, -1.1, 0.4];
        let loss = |n: &ColourNet, x: &[f32]| {
            let mut h = [0f32; MAX_HIDDEN];
            let c = n.forward(x, &mut h);
            (0..3).map(|i| g[i] as f64 * c[i] as f64).sum::<f64>()
        };
        let mut h = [0f32; MAX_HIDDEN];
        let rgb = net.forward(&x, &mut h);
        let mut g_w = vec![0f32; net.weights.len()];
        let mut g_x = vec![0f32; net.features];
        net.backward(&x, &h, rgb, g, &mut g_x, &mut g_w);
        let eps = 1e-3f32;
        let close = |num: f64, ana: f32, what: &str| {
            let err = (num - ana as f64).abs() / num.abs().max(ana.abs() as f64).max(1e-2);
            assert!(err < 1e-2, "{what}: numeric {num} vs analytic {ana}");
        };
        for (i, &ana) in g_w.iter().enumerate() {
            let (mut p, mut m) = (net.clone(), net.clone());
            p.weights[i] += eps;
            m.weights[i] -= eps;
            close(
                (loss(&p, &x) - loss(&m, &x)) / (2.0 * eps as f64),
                ana,
                "weight",
            );
        }
        for i in 0..net.features {
            let (mut p, mut m) = (x.clone(), x.clone());
            p[i] += eps;
            m[i] -= eps;
            close(
                (loss(&net, &p) - loss(&net, &m)) / (2.0 * eps as f64),
                g_x[i],
                "feature",
            );
        }
        let touched = g_w.iter().filter(|v| v.abs() > 1e-6).count();
        assert!(touched > 20, "{touched} weights with a gradient");
    }
}
