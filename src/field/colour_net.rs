//! Colour from a feature grid through a small network (DVGO's colour): each vertex holds
//! `features` values beside its density; a sample's interpolated features and the spherical-
//! harmonic basis of its view direction go through one hidden ReLU layer to RGB (sigmoid).
//! Optionally the basis of the view direction reflected about the density's normal joins them
//! (Ref-NeRF's reflected direction): a highlight then sits where the reflection points, which
//! the network can share across the points of a glossy part, rather than where the views it was
//! trained on saw it. Optionally a second hidden layer follows the first (DVGO's has two).
//!
//! The network is shared by every sample, so its gradient is summed over a batch (per chunk of
//! rays, then in chunk order: deterministic) and stepped with its own Adam
//! ([`NetAdam`]). Forward and backward are written out by hand, as the rest of the field.

use super::activation::sigmoid;
use crate::util::Rng;

/// The most inputs (features + direction and reflection terms) and hidden units a network
/// takes: a grid's features (at most 27) and two degree-3 bases.
pub const MAX_INPUTS: usize = 59;
/// The most units of each hidden layer.
pub const MAX_HIDDEN: usize = 128;
/// The hidden activations a sample keeps for its backward: both layers'.
pub const MAX_ACTIVATIONS: usize = 2 * MAX_HIDDEN;

#[derive(Clone, Debug, PartialEq)]
pub struct ColourNet {
    /// Feature channels per vertex (after the density).
    pub features: usize,
    /// Direction terms: the SH basis of the view direction to the field's degree.
    pub dir_terms: usize,
    /// Reflection terms: the SH basis of the reflected view direction ([`reflect`]); 0: none.
    pub refl_terms: usize,
    pub hidden: usize,
    /// Units of the second hidden layer; 0: none (the output reads the first).
    pub hidden2: usize,
    /// W1 (inputs x hidden, input-major; rows: features, direction, reflection), b1 (hidden),
    /// then with a second layer Wm (hidden x hidden2, input-major) and bm (hidden2), then
    /// Wout (3 x the last layer's units) and bout (3).
    pub weights: Vec<f32>,
}

impl ColourNet {
    /// A network with uniform He initialisation (seeded) and zero biases: with the features at
    /// zero it starts near grey, as a fresh SH grid does.
    pub fn new(
        features: usize,
        dir_terms: usize,
        refl_terms: usize,
        [hidden, hidden2]: [usize; 2],
        seed: u64,
    ) -> ColourNet {
        let inputs = features + dir_terms + refl_terms;
        assert!(inputs <= MAX_INPUTS && hidden <= MAX_HIDDEN && hidden > 0);
        assert!(hidden2 <= MAX_HIDDEN);
        let mut net = ColourNet {
            features,
            dir_terms,
            refl_terms,
            hidden,
            hidden2,
            weights: vec![0.0; Self::weight_count(inputs, hidden, hidden2)],
        };
        let mut r = Rng::new(seed ^ 0xC0_10_0E);
        let mut uniform = |ws: &mut [f32], a: f32| {
            ws.iter_mut().for_each(|w| *w = (2.0 * r.f32() - 1.0) * a);
        };
        let last = net.last_units();
        let (w1, mid, out) = net.offsets();
        uniform(&mut net.weights[..w1], (6.0 / inputs as f32).sqrt());
        if hidden2 > 0 {
            uniform(
                &mut net.weights[mid..mid + hidden * hidden2],
                (6.0 / hidden as f32).sqrt(),
            );
        }
        uniform(
            &mut net.weights[out..out + 3 * last],
            (6.0 / last as f32).sqrt() * 0.1,
        );
        net
    }

    pub fn weight_count(inputs: usize, hidden: usize, hidden2: usize) -> usize {
        let last = last_layer_units(hidden, hidden2);
        inputs * hidden + hidden + hidden * hidden2 + hidden2 + 3 * last + 3
    }

    /// Units of the layer the output reads.
    fn last_units(&self) -> usize {
        last_layer_units(self.hidden, self.hidden2)
    }

    /// Where b1, Wm and Wout start in `weights`.
    fn offsets(&self) -> (usize, usize, usize) {
        let (nh, nh2) = (self.hidden, self.hidden2);
        let b1 = self.inputs() * nh;
        (b1, b1 + nh, b1 + nh + nh * nh2 + nh2)
    }

    pub fn inputs(&self) -> usize {
        self.features + self.dir_terms + self.refl_terms
    }

    /// RGB for inputs `x` ([features, direction terms, reflection terms]); the hidden
    /// activations go to `h`.
    /// The whole network on one input, which the renderer splits per ray and per sample: kept
    /// for the gradient test, which checks the two parts through it.
    #[cfg(test)]
    pub fn forward(&self, x: &[f32], h: &mut [f32]) -> [f32; 3] {
        let mut bias = [0f32; MAX_HIDDEN];
        let (nf, nd) = (self.features, self.dir_terms);
        self.ray_bias(&x[nf..nf + nd], &mut bias);
        self.forward_features(&x[..nf], &x[nf + nd..self.inputs()], &bias, h)
    }

    /// The hidden units' pre-activation from the biases and the direction terms `dir`, which
    /// every sample of a ray shares: computed once a ray, it leaves a sample only its features'
    /// rows of W1 (8 of 24 at the default size).
    pub fn ray_bias(&self, dir: &[f32], bias: &mut [f32]) {
        let (w1, b1, ..) = self.parts();
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

    /// RGB for a sample's `features` and reflection terms `refl` (empty without them) on a
    /// ray whose [`ColourNet::ray_bias`] is `bias`; the hidden activations go to `h` (the
    /// first layer's, then the second's).
    #[inline]
    pub fn forward_features(
        &self,
        features: &[f32],
        refl: &[f32],
        bias: &[f32],
        h: &mut [f32],
    ) -> [f32; 3] {
        let (w1, _, wm, bm, wo, bo) = self.parts();
        let (nh, nh2) = (self.hidden, self.hidden2);
        let (h, h2) = h.split_at_mut(nh);
        h.copy_from_slice(&bias[..nh]);
        // Input-major W1: each input adds a scaled row to every hidden unit (vectorises).
        for (xi, row) in features[..self.features].iter().zip(w1.chunks_exact(nh)) {
            h.iter_mut().zip(row).for_each(|(a, w)| *a += xi * w);
        }
        let refl_rows = &w1[(self.features + self.dir_terms) * nh..];
        for (xi, row) in refl[..self.refl_terms]
            .iter()
            .zip(refl_rows.chunks_exact(nh))
        {
            h.iter_mut().zip(row).for_each(|(a, w)| *a += xi * w);
        }
        h.iter_mut().for_each(|a| *a = a.max(0.0));
        if nh2 == 0 {
            return [0, 1, 2].map(|c| sigmoid(bo[c] + dot(&wo[c * nh..(c + 1) * nh], h)));
        }
        let h2 = &mut h2[..nh2];
        h2.copy_from_slice(bm);
        for (xi, row) in h.iter().zip(wm.chunks_exact(nh2)) {
            if *xi > 0.0 {
                h2.iter_mut().zip(row).for_each(|(a, w)| *a += xi * w);
            }
        }
        h2.iter_mut().for_each(|a| *a = a.max(0.0));
        [0, 1, 2].map(|c| sigmoid(bo[c] + dot(&wo[c * nh2..(c + 1) * nh2], h2)))
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
        let (nf, nd) = (self.features, self.dir_terms);
        let refl = &x[nf + nd..self.inputs()];
        self.backward_features(&x[..nf], refl, h, rgb, g, g_x, g_w, &mut g_bias);
        self.backward_ray(&x[nf..nf + nd], &g_bias, g_w);
    }

    /// Backward of [`ColourNet::forward_features`] for dL/dRGB `g`: adds dL/dweights of the
    /// output and second layers and of W1's feature and reflection rows to `g_w`, writes dL/dfeatures to `g_x`, and adds
    /// dL/d(ray bias) to `g_bias`, which [`ColourNet::backward_ray`] turns into the rest once a
    /// ray. The reflection terms get no gradient: the normal they come from is held fixed, as
    /// the density's own losses shape it.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn backward_features(
        &self,
        features: &[f32],
        refl: &[f32],
        h: &[f32],
        rgb: [f32; 3],
        g: [f32; 3],
        g_x: &mut [f32],
        g_w: &mut [f32],
        g_bias: &mut [f32],
    ) {
        let (ni, nh, nh2, nf) = (self.inputs(), self.hidden, self.hidden2, self.features);
        let (w1, _, wm, _, wo, _) = self.parts();
        let go = [0, 1, 2].map(|c| g[c] * rgb[c] * (1.0 - rgb[c]));
        let (gw1, rest) = g_w.split_at_mut(ni * nh);
        let (_, rest) = rest.split_at_mut(nh);
        let (gwm, rest) = rest.split_at_mut(nh * nh2);
        let (gbm, rest) = rest.split_at_mut(nh2);
        let nl = self.last_units();
        let (gwo, gbo) = rest.split_at_mut(3 * nl);
        let (h, h2) = h.split_at(nh);
        let last = if nh2 > 0 { &h2[..nh2] } else { h };
        // dL/d(the last layer's pre-activation).
        let mut dl = [0f32; MAX_HIDDEN];
        let dl = &mut dl[..nl];
        for c in 0..3 {
            gbo[c] += go[c];
            let (gw, w) = (&mut gwo[c * nl..(c + 1) * nl], &wo[c * nl..(c + 1) * nl]);
            for j in 0..nl {
                gw[j] += go[c] * last[j];
                dl[j] += go[c] * w[j];
            }
        }
        relu_backward(dl, last);
        let mut dh = [0f32; MAX_HIDDEN];
        let dh = &mut dh[..nh];
        if nh2 > 0 {
            gbm.iter_mut().zip(dl.iter()).for_each(|(a, d)| *a += d);
            for (i, (hi, row)) in h.iter().zip(gwm.chunks_exact_mut(nh2)).enumerate() {
                if *hi > 0.0 {
                    row.iter_mut()
                        .zip(dl.iter())
                        .for_each(|(a, d)| *a += hi * d);
                    dh[i] = dot(&wm[i * nh2..(i + 1) * nh2], dl);
                }
            }
        } else {
            dh.copy_from_slice(dl);
        }
        relu_backward(dh, h);
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
        let refl_rows = gw1[(nf + self.dir_terms) * nh..].chunks_exact_mut(nh);
        for (xi, row) in refl[..self.refl_terms].iter().zip(refl_rows) {
            row.iter_mut()
                .zip(dh.iter())
                .for_each(|(a, d)| *a += xi * d);
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

    /// (W1 input-major: inputs x hidden, b1, Wm: hidden x hidden2, bm (both empty without a
    /// second layer), Wout: 3 x the last layer's units, bout).
    #[allow(clippy::type_complexity)]
    fn parts(&self) -> (&[f32], &[f32], &[f32], &[f32], &[f32], &[f32]) {
        let (ni, nh, nh2) = (self.inputs(), self.hidden, self.hidden2);
        let (w1, rest) = self.weights.split_at(ni * nh);
        let (b1, rest) = rest.split_at(nh);
        let (wm, rest) = rest.split_at(nh * nh2);
        let (bm, rest) = rest.split_at(nh2);
        let (wo, bo) = rest.split_at(3 * self.last_units());
        (w1, b1, wm, bm, wo, bo)
    }
}

/// Units of the layer the output reads: the second hidden layer's, or the first's without one.
fn last_layer_units(hidden: usize, hidden2: usize) -> usize {
    if hidden2 > 0 {
        hidden2
    } else {
        hidden
    }
}

/// A ReLU's backward: no gradient through the units that were off.
#[inline]
fn relu_backward(d: &mut [f32], out: &[f32]) {
    for (d, o) in d.iter_mut().zip(out) {
        if *o <= 0.0 {
            *d = 0.0;
        }
    }
}

/// The unit view direction `d` reflected about the surface whose density gradient is `grad`
/// (either sign: a reflection does not depend on the normal's orientation); `d` itself where
/// the density is flat.
#[inline]
pub fn reflect(d: glam::Vec3, grad: glam::Vec3) -> glam::Vec3 {
    let len2 = grad.length_squared();
    if len2 < 1e-12 {
        return d;
    }
    d - grad * (2.0 * d.dot(grad) / len2)
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

    /// The backward against central differences of the forward, for weights and features,
    /// with one hidden layer and with two.
    #[test]
    fn network_gradients_match_finite_differences() {
        for hidden2 in [0, 7] {
            network_gradients_check(ColourNet::new(5, 4, 3, [12, hidden2], 3));
        }
    }

    fn network_gradients_check(mut net: ColourNet) {
        let mut r = Rng::new(9);
        // Biases too, so some hidden units are active and some not.
        net.weights
            .iter_mut()
            .for_each(|w| *w = r.normal() as f32 * 0.5);
        let x: Vec<f32> = (0..net.inputs()).map(|_| r.normal() as f32).collect();
        let g = [0.7f32, -1.1, 0.4];
        let loss = |n: &ColourNet, x: &[f32]| {
            let mut h = [0f32; MAX_ACTIVATIONS];
            let c = n.forward(x, &mut h);
            (0..3).map(|i| g[i] as f64 * c[i] as f64).sum::<f64>()
        };
        let mut h = [0f32; MAX_ACTIVATIONS];
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
