//! Harmonic inpainting: the unknown pixels of an image take the smooth (Laplace) interpolation of
//! the known pixels around them. It is exact for anything linear across the hole (a plane's
//! disparity, a colour gradient) and never overshoots its boundary values, which is what a fill
//! of never-seen ground should do; texture is not synthesised.
//!
//! Solved coarse to fine: the unknowns are first solved on a 2x-smaller image (known pixels
//! averaged), which starts the Gauss-Seidel sweeps at full size near the answer, so a hole of
//! any size converges in a few dozen sweeps per level.

/// Fill the pixels where `known` is false in `values` (`channels` floats per pixel, row-major,
/// `w` x `h`), in place. Returns false when no pixel is known (nothing is changed then).
pub fn inpaint_harmonic(
    values: &mut [f32],
    known: &[bool],
    w: usize,
    h: usize,
    channels: usize,
) -> bool {
    assert_eq!(
        values.len(),
        w * h * channels,
        "values hold w*h*channels floats"
    );
    assert_eq!(known.len(), w * h, "one known flag per pixel");
    if !known.iter().any(|&k| k) {
        return false;
    }
    if known.iter().all(|&k| k) {
        return true;
    }
    // Start the unknowns from the coarser level's solution (or the mean of the known pixels).
    if w > 8 && h > 8 {
        let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
        let mut coarse = vec![0.0f32; cw * ch * channels];
        let mut coarse_known = vec![false; cw * ch];
        for cy in 0..ch {
            for cx in 0..cw {
                let mut acc = vec![0.0f32; channels];
                let mut n = 0;
                for (x, y) in
                    [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(dx, dy)| (2 * cx + dx, 2 * cy + dy))
                {
                    if x < w && y < h && known[y * w + x] {
                        let o = (y * w + x) * channels;
                        for c in 0..channels {
                            acc[c] += values[o + c];
                        }
                        n += 1;
                    }
                }
                if n > 0 {
                    let o = (cy * cw + cx) * channels;
                    for c in 0..channels {
                        coarse[o + c] = acc[c] / n as f32;
                    }
                    coarse_known[cy * cw + cx] = true;
                }
            }
        }
        inpaint_harmonic(&mut coarse, &coarse_known, cw, ch, channels);
        for y in 0..h {
            for x in 0..w {
                if !known[y * w + x] {
                    let (o, co) = ((y * w + x) * channels, ((y / 2) * cw + x / 2) * channels);
                    values[o..o + channels].copy_from_slice(&coarse[co..co + channels]);
                }
            }
        }
    } else {
        let mut mean = vec![0.0f32; channels];
        let n = known.iter().filter(|&&k| k).count() as f32;
        for (i, _) in known.iter().enumerate().filter(|(_, &k)| k) {
            for c in 0..channels {
                mean[c] += values[i * channels + c] / n;
            }
        }
        for (i, _) in known.iter().enumerate().filter(|(_, &k)| !k) {
            values[i * channels..(i + 1) * channels].copy_from_slice(&mean);
        }
    }
    let unknown: Vec<usize> = (0..w * h).filter(|&i| !known[i]).collect();
    let mut acc = vec![0.0f32; channels];
    for _ in 0..SWEEPS {
        for &i in &unknown {
            let (x, y) = (i % w, i / w);
            acc.iter_mut().for_each(|a| *a = 0.0);
            let mut n = 0;
            for (nx, ny) in [
                (x.wrapping_sub(1), y),
                (x + 1, y),
                (x, y.wrapping_sub(1)),
                (x, y + 1),
            ] {
                if nx < w && ny < h {
                    let o = (ny * w + nx) * channels;
                    for c in 0..channels {
                        acc[c] += values[o + c];
                    }
                    n += 1;
                }
            }
            for c in 0..channels {
                values[i * channels + c] = acc[c] / n as f32;
            }
        }
    }
    true
}

/// Gauss-Seidel sweeps per level (the coarser level's answer is already close).
const SWEEPS: usize = 40;

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear ramp is harmonic: the fill reproduces it inside a large hole.
    #[test]
    fn fills_a_linear_ramp_exactly() {
        let (w, h) = (64, 48);
        let truth: Vec<f32> = (0..w * h)
            .map(|i| 0.3 + 0.01 * (i % w) as f32 - 0.02 * (i / w) as f32)
            .collect();
        let known: Vec<bool> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                !((10..50).contains(&x) && (8..40).contains(&y))
            })
            .collect();
        let mut v: Vec<f32> = truth
            .iter()
            .zip(&known)
            .map(|(t, k)| if *k { *t } else { 9.0 })
            .collect();
        assert!(inpaint_harmonic(&mut v, &known, w, h, 1));
        let worst = v
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(worst < 2e-3, "worst error {worst}");
    }

    /// Values stay within the range of the known ones (a maximum principle), channel by channel.
    #[test]
    fn stays_within_the_known_range() {
        let (w, h) = (40, 30);
        let mut v = vec![0.0f32; w * h * 3];
        let known: Vec<bool> = (0..w * h).map(|i| (i % w) < 5 || (i % w) > 34).collect();
        for i in 0..w * h {
            let left = i % w < 20;
            v[3 * i..3 * i + 3].copy_from_slice(&if left {
                [1.0, 0.0, 0.5]
            } else {
                [0.0, 1.0, 0.5]
            });
        }
        assert!(inpaint_harmonic(&mut v, &known, w, h, 3));
        assert!(v.iter().all(|x| (-1e-6..=1.0 + 1e-6).contains(x)));
        assert!(v.chunks(3).all(|p| (p[2] - 0.5).abs() < 1e-5));
        assert!(!inpaint_harmonic(&mut v, &vec![false; w * h], w, h, 3));
    }
}
