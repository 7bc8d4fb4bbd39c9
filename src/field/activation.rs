//! The activations the field, its renderer and its colour network share.

#[inline]
pub fn softplus(x: f32) -> f32 {
    if x > 15.0 {
        x
    } else {
        x.exp().ln_1p()
    }
}

#[inline]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// A sample's opacity over `delta` voxels, alpha = 1 - exp(-softplus(raw) delta), and
/// sigmoid(raw) (softplus's slope, which the backward needs), from one exponential where the
/// march takes whole voxels: at delta = 1, alpha = 1 - 1 / (1 + e^raw) = sigmoid(raw).
#[inline]
pub fn alpha_and_slope(raw: f32, delta: f32) -> (f32, f32) {
    if raw > 15.0 {
        return (1.0 - (-raw * delta).exp(), sigmoid(raw));
    }
    let e = raw.exp();
    let slope = e / (1.0 + e);
    let alpha = if delta == 1.0 {
        slope
    } else {
        1.0 - (-e.ln_1p() * delta).exp()
    };
    (alpha, slope)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_and_slope_agree_with_their_definitions() {
        for raw in [-60.0f32, -9.0, -2.5, 0.0, 0.7, 14.9, 15.1, 40.0] {
            for delta in [0.25f32, 0.5, 1.0, 2.0] {
                let (alpha, slope) = alpha_and_slope(raw, delta);
                let want = 1.0 - (-softplus(raw) * delta).exp();
                let tol = 1e-6 + 2e-6 * want.abs();
                assert!(
                    (alpha - want).abs() <= tol,
                    "{raw} {delta}: {alpha} vs {want}"
                );
                assert!((slope - sigmoid(raw)).abs() <= 1e-6, "{raw}: slope {slope}");
            }
        }
    }
}
