//! bfloat16: the top half of an f32 (its sign, exponent and 7 mantissa bits). The optimiser
//! keeps Adam's moments in it: they set a step's size, not the weights' values, and half the
//! bytes is what a memory-bound pass over them pays for.

/// f32 to bfloat16, rounded to nearest even. Branch-free so the optimiser's loop vectorises: a
/// NaN whose payload is all in the low half would come out as infinity (the quiet NaN that
/// arithmetic makes stays NaN).
#[inline(always)]
pub fn to_bf16(x: f32) -> u16 {
    let b = x.to_bits();
    ((b + 0x7fff + ((b >> 16) & 1)) >> 16) as u16
}

/// bfloat16 to f32 (exact).
#[inline(always)]
pub fn from_bf16(h: u16) -> f32 {
    f32::from_bits((h as u32) << 16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_to_nearest_even_and_back_exactly() {
        // Representable values survive the round trip.
        let tiny = 2f32.powi(-100);
        for x in [
            0.0f32,
            -0.0,
            1.0,
            -2.5,
            0.15625,
            tiny,
            1.0 / tiny,
            f32::INFINITY,
        ] {
            assert_eq!(from_bf16(to_bf16(x)).to_bits(), x.to_bits(), "{x}");
        }
        // 1 + 2^-8 lies halfway between 1 and 1 + 2^-7: ties go to the even mantissa (1).
        assert_eq!(from_bf16(to_bf16(1.0 + 1.0 / 256.0)), 1.0);
        // 1 + 3 * 2^-8 is halfway between 1 + 2^-7 (odd) and 1 + 2^-6: up to the even one.
        assert_eq!(from_bf16(to_bf16(1.0 + 3.0 / 256.0)), 1.0 + 1.0 / 64.0);
        // Just above halfway rounds up; the relative error is at most 2^-8.
        assert_eq!(
            from_bf16(to_bf16(1.0 + 1.0 / 256.0 + 1e-6)),
            1.0 + 1.0 / 128.0
        );
        let mut r = crate::util::Rng::new(5);
        for _ in 0..10_000 {
            let x = (r.f32() - 0.5) * 10f32.powi((r.f32() * 20.0) as i32 - 10);
            let y = from_bf16(to_bf16(x));
            assert!((y - x).abs() <= x.abs() / 256.0, "{x} -> {y}");
        }
        assert!(from_bf16(to_bf16(f32::NAN)).is_nan());
    }
}
