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
