//! The translations that map a sampled 2D texture onto itself: the peaks of its normalised
//! autocorrelation, fitted to the lattice of one or two periods they lie on. Used to continue a
//! repeating pattern (tiles, planks, wallpaper) into a hole ([`crate::removal::pattern`]).

use glam::{DVec2, Vec2};

/// A translation is a symmetry of the texture where the texture moved by it correlates with
/// itself at least this much (normalised cross-correlation; unrelated texture scores near 0).
pub const MIN_CORRELATION: f64 = 0.4;
/// Shifts closer than this many texels are the zero shift's own peak.
const MIN_SHIFT_TEXELS: i32 = 3;

/// The shifts (texels, sub-texel) within `reach` texels on each axis under which `texture`
/// (`n` x `n`, row-major, None: not sampled) correlates with itself at least
/// [`MIN_CORRELATION`], on the lattice of its periods, each with its correlation. Empty for a
/// texture that does not repeat. Costs `n^2 (2 reach + 1)^2 / 2`.
pub fn periodic_shifts(texture: &[Option<f64>], n: usize, reach: i32) -> Vec<(Vec2, f64)> {
    let valid = texture.iter().filter(|t| t.is_some()).count();
    let side = (2 * reach + 1) as usize;
    let at = |dx: i32, dy: i32| ((dy + reach) as usize) * side + (dx + reach) as usize;
    let mut ncc = vec![f64::NEG_INFINITY; side * side];
    for dy in 0..=reach {
        for dx in -reach..=reach {
            if dy == 0 && dx < 0 {
                continue;
            }
            let c = correlation(texture, n, dx, dy, valid / 4);
            ncc[at(dx, dy)] = c;
            ncc[at(-dx, -dy)] = c;
        }
    }
    let mut found = Vec::new();
    for dy in -reach + 1..reach {
        for dx in -reach + 1..reach {
            let c = ncc[at(dx, dy)];
            if c < MIN_CORRELATION || dx * dx + dy * dy < MIN_SHIFT_TEXELS * MIN_SHIFT_TEXELS {
                continue;
            }
            let around = (-1..=1).flat_map(|j| (-1..=1).map(move |i| (i, j)));
            if around
                .filter(|&(i, j)| (i, j) != (0, 0))
                .any(|(i, j)| ncc[at(dx + i, dy + j)] > c)
            {
                continue;
            }
            // Sub-texel peak: a parabola through the peak and its neighbours on each axis.
            let vertex = |lo: f64, hi: f64| {
                let den = lo - 2.0 * c + hi;
                if den < 0.0 && den.is_finite() {
                    (0.5 * (lo - hi) / den).clamp(-0.5, 0.5)
                } else {
                    0.0
                }
            };
            let fx = vertex(ncc[at(dx - 1, dy)], ncc[at(dx + 1, dy)]);
            let fy = vertex(ncc[at(dx, dy - 1)], ncc[at(dx, dy + 1)]);
            let shift = Vec2::new(dx as f32 + fx as f32, dy as f32 + fy as f32);
            found.push((shift, c));
        }
    }
    on_lattice(&found)
}

/// The correlation peaks (shift, correlation) that are whole multiples of the pattern's
/// periods, moved onto the lattice those periods span. Each peak alone is good to a fraction of
/// a texel; the periods fitted to all of them by least squares are far better, and a shift of
/// several periods taken from a single peak would blur the pattern it carries. The first period
/// is the best-correlated peak, the second the best one across it (none for stripes).
fn on_lattice(peaks: &[(Vec2, f64)]) -> Vec<(Vec2, f64)> {
    let mut order: Vec<&(Vec2, f64)> = peaks.iter().collect();
    order.sort_by(|a, b| b.1.total_cmp(&a.1));
    let Some(&&(t1, _)) = order.first() else {
        return Vec::new();
    };
    let across = |p: Vec2| t1.perp_dot(p).abs() > 0.3 * t1.length() * p.length();
    let t2 = order.iter().map(|p| p.0).find(|&p| across(p));
    // Whole-period coordinates of each peak; those off the lattice by more than a texel go.
    let coords = |p: Vec2, t1: Vec2, t2: Option<Vec2>| -> (f32, f32) {
        match t2 {
            Some(t2) => {
                let det = t1.perp_dot(t2);
                (p.perp_dot(t2) / det, t1.perp_dot(p) / det)
            }
            None => (p.dot(t1) / t1.length_squared(), 0.0),
        }
    };
    let kept: Vec<(f32, f32, Vec2, f64)> = peaks
        .iter()
        .filter_map(|&(p, c)| {
            let (a, b) = coords(p, t1, t2);
            let (a, b) = (a.round(), b.round());
            let off = p - t1 * a - t2.unwrap_or(Vec2::ZERO) * b;
            (off.length() <= 1.0 && (a, b) != (0.0, 0.0)).then_some((a, b, p, c))
        })
        .collect();
    if kept.is_empty() {
        return Vec::new();
    }
    // Least squares for the periods: sum |a t1 + b t2 - p|^2, per coordinate.
    let (mut aa, mut ab, mut bb, mut ap, mut bp) = (0.0f64, 0.0, 0.0, DVec2::ZERO, DVec2::ZERO);
    for &(a, b, p, _) in &kept {
        let (a, b, p) = (a as f64, b as f64, p.as_dvec2());
        aa += a * a;
        ab += a * b;
        bb += b * b;
        ap += p * a;
        bp += p * b;
    }
    let (p1, p2) = match t2 {
        Some(_) => {
            let det = aa * bb - ab * ab;
            if det.abs() < 1e-9 {
                return Vec::new();
            }
            ((ap * bb - bp * ab) / det, (bp * aa - ap * ab) / det)
        }
        None => (ap / aa, DVec2::ZERO),
    };
    let (p1, p2) = (p1.as_vec2(), p2.as_vec2());
    kept.iter()
        .map(|&(a, b, _, c)| (p1 * a + p2 * b, c))
        .collect()
}

/// Normalised cross-correlation of `texture` (`n` x `n`, None: no sample) with itself moved by
/// (`dx`, `dy`) texels, over the texels where both are sampled; -inf with fewer than
/// `min_pairs` of them.
fn correlation(texture: &[Option<f64>], n: usize, dx: i32, dy: i32, min_pairs: usize) -> f64 {
    let (mut sa, mut sb, mut saa, mut sbb, mut sab, mut pairs) = (0.0, 0.0, 0.0, 0.0, 0.0, 0);
    let n_i = n as i32;
    for y in 0.max(-dy)..n_i.min(n_i - dy) {
        for x in 0.max(-dx)..n_i.min(n_i - dx) {
            let (Some(a), Some(b)) = (
                texture[(y * n_i + x) as usize],
                texture[((y + dy) * n_i + x + dx) as usize],
            ) else {
                continue;
            };
            sa += a;
            sb += b;
            saa += a * a;
            sbb += b * b;
            sab += a * b;
            pairs += 1;
        }
    }
    if pairs < min_pairs.max(16) {
        return f64::NEG_INFINITY;
    }
    let k = pairs as f64;
    let va = saa - sa * sa / k;
    let vb = sbb - sb * sb / k;
    if va <= 0.0 || vb <= 0.0 {
        return f64::NEG_INFINITY;
    }
    (sab - sa * sb / k) / (va * vb).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::Rng;

    const N: usize = 64;

    /// A checker of `square`-texel squares plus uniform noise of amplitude `noise`, a fifth of
    /// its texels unsampled.
    fn checker(square: f64, noise: f64, seed: u64) -> Vec<Option<f64>> {
        let mut rng = Rng::new(seed);
        (0..N * N)
            .map(|i| {
                let (x, y) = ((i % N) as f64, (i / N) as f64);
                let on = ((x / square).floor() + (y / square).floor()) as i64 & 1 == 0;
                let v = if on { 1.0 } else { 0.0 } + noise * rng.f64();
                (rng.f64() > 0.2).then_some(v)
            })
            .collect()
    }

    #[test]
    fn a_checker_repeats_on_its_lattice() {
        // Squares of 5.5 texels: period 11 on each axis, and (5.5, 5.5) diagonally.
        let shifts = periodic_shifts(&checker(5.5, 0.8, 1), N, 20);
        assert!(shifts.len() >= 8, "{shifts:?}");
        for (s, c) in &shifts {
            assert!(*c >= MIN_CORRELATION);
            let (a, b) = (s.x / 5.5, s.y / 5.5);
            assert!(
                (a - a.round()).abs() < 0.05 && (b - b.round()).abs() < 0.05,
                "{s:?}"
            );
            assert_eq!(
                (a.round() + b.round()) as i64 & 1,
                0,
                "{s:?} is not a period"
            );
        }
    }

    #[test]
    fn noise_does_not_repeat() {
        let mut rng = Rng::new(2);
        let noise: Vec<Option<f64>> = (0..N * N).map(|_| Some(rng.f64())).collect();
        assert!(periodic_shifts(&noise, N, 20).is_empty());
    }
}
