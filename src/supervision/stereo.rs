//! Dense depth from the photos themselves: plane-sweep stereo. A scene field's geometry is what
//! its sparse points leave short (the ring demo's field: 25.1 dB held out with the sparse points
//! spread, 29.6 with the truth's dense depth), and the photos hold far more of it: every textured
//! pixel seen from two nearby views. For each view, fronto-parallel planes (uniform in inverse
//! depth over the range of its sparse points) warp its nearest views onto it; a pixel takes the
//! plane where the photos agree best (normalised cross-correlation of 5x5 windows, the mean of
//! its two best neighbours so one occluded view does not veto it), refined by a parabola. A depth
//! is kept only where the agreement is clear and two neighbours' own depth maps put the same
//! surface there (geometric consistency), as MVS pipelines (COLMAP, MVSNet's filtering) do.

use crate::field::view::View;
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Plane-sweep settings.
#[derive(Clone, Debug)]
pub struct StereoOptions {
    /// Views warped onto each view (its nearest, looking the same way within `max_angle_deg`).
    pub neighbours: usize,
    pub max_angle_deg: f32,
    /// Depth planes, uniform in inverse depth.
    pub planes: usize,
    /// The sparse points' depth percentiles in a view, widened by this factor each way.
    pub range_margin: f32,
    /// Least correlation (mean of the two best neighbours) for a depth to be kept.
    pub min_ncc: f32,
    /// Least grey-level standard deviation of a window (0-1 scale): flat windows say nothing.
    pub min_texture: f32,
    /// Neighbours whose depth map must agree (within `consistency` relative depth).
    pub min_consistent: usize,
    pub consistency: f32,
}

impl Default for StereoOptions {
    fn default() -> Self {
        StereoOptions {
            neighbours: 4,
            max_angle_deg: 45.0,
            planes: 96,
            range_margin: 1.3,
            min_ncc: 0.6,
            min_texture: 0.01,
            min_consistent: 2,
            consistency: 0.01,
        }
    }
}

/// Window radius of the correlation (5x5).
const RADIUS: usize = 2;

/// Set depth targets from plane-sweep stereo on every pixel of `views` (the scene's images in
/// order) that carries a loss and has no target yet. Returns the number of targets added.
pub fn add_stereo_depth(views: &mut [View], scene: &Scene, opts: &StereoOptions) -> usize {
    if views.len() != scene.images.len() {
        return 0;
    }
    let grey: Vec<Vec<f32>> = views.par_iter().map(View::luma).collect();
    // A capture with neither points nor bounds sweeps around where its cameras look.
    let focus = crate::space::layout::layout(scene)
        .ok()
        .map(|l| DVec3::from_array(l.focus));
    let ranges: Vec<Option<(f32, f32)>> = (0..views.len())
        .map(|i| depth_range(scene, i, focus, opts.range_margin))
        .collect();
    let near: Vec<Vec<usize>> = (0..views.len())
        .map(|i| neighbours(views, i, opts))
        .collect();
    let depths: Vec<Vec<f32>> = (0..views.len())
        .into_par_iter()
        .map(|i| match ranges[i] {
            Some(range) if !near[i].is_empty() => sweep(views, &grey, i, &near[i], range, opts),
            _ => vec![0.0; grey[i].len()],
        })
        .collect();
    let kept: Vec<Vec<f32>> = (0..views.len())
        .into_par_iter()
        .map(|i| consistent(views, &depths, i, &near[i], opts))
        .collect();
    let mut added = 0;
    for (v, z) in views.iter_mut().zip(kept) {
        let npx = (v.width * v.height) as usize;
        let carries = |p: usize| v.loss_mask.as_ref().is_none_or(|m| m[p]);
        let scale: Vec<f32> = (0..npx).map(|p| v.ray_scale(p as u32)).collect();
        let mask: Vec<bool> = (0..npx)
            .map(|p| v.rgba[p][3] >= 128 && carries(p))
            .collect();
        let d = v.depth.get_or_insert_with(|| vec![0.0; npx]);
        for p in 0..npx {
            if z[p] > 0.0 && d[p] == 0.0 && mask[p] {
                d[p] = z[p] * scale[p];
                added += 1;
            }
        }
    }
    added
}

/// The z-depths of the sparse points that view `i` tracks (2nd-98th percentiles), else the
/// capture's depth bounds for it, else [`FOCUS_SPAN`] either side of the depth of `focus` (the
/// point the cameras look at), widened by `margin`.
fn depth_range(scene: &Scene, i: usize, focus: Option<DVec3>, margin: f32) -> Option<(f32, f32)> {
    let pose = &scene.images[i].pose;
    let mut z: Vec<f64> = scene
        .points
        .iter()
        .filter(|p| p.track.iter().any(|t| t.image == i))
        .map(|p| pose.world_to_camera(p.xyz).z)
        .filter(|&z| z > 0.0)
        .collect();
    if z.len() < 10 {
        // No sparse model: the depth bounds the capture gives (LLFF), else the focus.
        let [near, far] = match scene.images[i].depth_bounds {
            Some(b) => b,
            None => {
                let zf = pose.world_to_camera(focus?).z;
                if zf <= 0.0 {
                    return None;
                }
                [zf / FOCUS_SPAN, zf * FOCUS_SPAN]
            }
        };
        return Some(((near as f32) / margin, (far as f32) * margin));
    }
    z.sort_by(f64::total_cmp);
    let (lo, hi) = (z[z.len() / 50], z[z.len() - 1 - z.len() / 50]);
    Some(((lo as f32) / margin, (hi as f32) * margin))
}

/// How far nearer and farther than the focus a pose-only capture's surfaces may lie: a factor of
/// 3 each way (an object at the focus and the wall behind it; a close-up's nearer surfaces).
const FOCUS_SPAN: f64 = 3.0;

/// The views nearest view `i` whose optical axes are within the angle limit.
fn neighbours(views: &[View], i: usize, opts: &StereoOptions) -> Vec<usize> {
    let axis = |v: &View| v.cam.pose.c2w_rotation().as_mat3() * Vec3::Z;
    let (ai, ci) = (axis(&views[i]), views[i].center());
    let cos_max = opts.max_angle_deg.to_radians().cos();
    let mut cand: Vec<(f32, usize)> = views
        .iter()
        .enumerate()
        .filter(|&(j, v)| j != i && axis(v).dot(ai) >= cos_max)
        .map(|(j, v)| ((v.center() - ci).length(), j))
        .filter(|&(d, _)| d > 1e-6)
        .collect();
    cand.sort_by(|a, b| a.0.total_cmp(&b.0));
    cand.into_iter()
        .take(opts.neighbours)
        .map(|(_, j)| j)
        .collect()
}

/// Box sums of radius [`RADIUS`] (clamped at the borders; the count is kept separately).
fn box_sum(a: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut rows = vec![0f32; a.len()];
    for y in 0..h {
        let r = &a[y * w..(y + 1) * w];
        let mut acc: f32 = r.iter().take(RADIUS + 1).sum();
        for x in 0..w {
            rows[y * w + x] = acc;
            if x + RADIUS + 1 < w {
                acc += r[x + RADIUS + 1];
            }
            if x >= RADIUS {
                acc -= r[x - RADIUS];
            }
        }
    }
    let mut out = vec![0f32; a.len()];
    for x in 0..w {
        let mut acc = 0f32;
        for y in 0..(RADIUS + 1).min(h) {
            acc += rows[y * w + x];
        }
        for y in 0..h {
            out[y * w + x] = acc;
            if y + RADIUS + 1 < h {
                acc += rows[(y + RADIUS + 1) * w + x];
            }
            if y >= RADIUS {
                acc -= rows[(y - RADIUS) * w + x];
            }
        }
    }
    out
}

/// Bilinear sample of a grey image at continuous pixel coordinates (pixel centres at +0.5).
fn sample(img: &[f32], w: usize, h: usize, x: f32, y: f32) -> Option<f32> {
    let (fx, fy) = (x - 0.5, y - 0.5);
    if fx < 0.0 || fy < 0.0 || fx > (w - 1) as f32 || fy > (h - 1) as f32 {
        return None;
    }
    let (x0, y0) = (fx as usize, fy as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
    let a = img[y0 * w + x0] * (1.0 - tx) + img[y0 * w + x1] * tx;
    let b = img[y1 * w + x0] * (1.0 - tx) + img[y1 * w + x1] * tx;
    Some(a * (1.0 - ty) + b * ty)
}

/// View `i`'s depth map (z-depth, 0 = none) by sweeping planes through `range`.
fn sweep(
    views: &[View],
    grey: &[Vec<f32>],
    i: usize,
    near: &[usize],
    (zmin, zmax): (f32, f32),
    opts: &StereoOptions,
) -> Vec<f32> {
    let v = &views[i];
    let (w, h) = (v.width as usize, v.height as usize);
    let n = w * h;
    let img = &grey[i];
    let win = ((2 * RADIUS + 1) * (2 * RADIUS + 1)) as f32;
    let s_i = box_sum(img, w, h);
    let s_ii = box_sum(&img.iter().map(|a| a * a).collect::<Vec<_>>(), w, h);
    let var_i: Vec<f32> = (0..n)
        .map(|p| (s_ii[p] / win - (s_i[p] / win).powi(2)).max(0.0))
        .collect();
    // Unit rays and their z in the camera (z-depth t gives the point c + d * t / dz).
    let rays: Vec<(Vec3, f32)> = (0..n as u32)
        .map(|p| {
            let (_, d) = v.ray(p);
            (d, 1.0 / v.ray_scale(p))
        })
        .collect();
    let c = v.center();
    let planes = opts.planes.max(2);
    let (inv_lo, inv_hi) = (1.0 / zmax, 1.0 / zmin);
    let z_of = |j: f32| 1.0 / (inv_hi + (inv_lo - inv_hi) * j / (planes - 1) as f32);
    let mut best = vec![(f32::MIN, 0usize, f32::NAN, f32::NAN); n];
    let mut prev = vec![f32::MIN; n];
    let mut scores: Vec<Vec<f32>> = vec![vec![0.0; n]; near.len()];
    let (mut warped, mut valid) = (vec![0f32; n], vec![0f32; n]);
    let mut ww = vec![0f32; n];
    let mut iw = vec![0f32; n];
    for j in 0..planes {
        let z = z_of(j as f32);
        for (k, &nb) in near.iter().enumerate() {
            let other = &views[nb];
            let (ow, oh) = (other.width as usize, other.height as usize);
            for p in 0..n {
                let (d, dz) = rays[p];
                let x = c + d * (z / dz);
                let s = other
                    .project(x)
                    .and_then(|(px, py)| sample(&grey[nb], ow, oh, px, py));
                warped[p] = s.unwrap_or(0.0);
                valid[p] = s.is_some() as u8 as f32;
                ww[p] = warped[p] * warped[p];
                iw[p] = warped[p] * img[p];
            }
            let (s_w, s_ww, s_iw, s_v) = (
                box_sum(&warped, w, h),
                box_sum(&ww, w, h),
                box_sum(&iw, w, h),
                box_sum(&valid, w, h),
            );
            let out = &mut scores[k];
            for p in 0..n {
                out[p] = if s_v[p] < win - 0.5 {
                    -1.0
                } else {
                    let (mi, mw) = (s_i[p] / win, s_w[p] / win);
                    let cov = s_iw[p] / win - mi * mw;
                    let var_w = (s_ww[p] / win - mw * mw).max(0.0);
                    cov / (var_i[p] * var_w).sqrt().max(1e-6)
                };
            }
        }
        for p in 0..n {
            // The mean of the two best neighbours: one occluded view does not veto a depth.
            let (mut a, mut b) = (-1f32, -1f32);
            for s in &scores {
                let x = s[p];
                if x > a {
                    b = a;
                    a = x;
                } else if x > b {
                    b = x;
                }
            }
            let s = if near.len() >= 2 { 0.5 * (a + b) } else { a };
            let e = &mut best[p];
            if s > e.0 {
                *e = (s, j, prev[p], f32::NAN);
            } else if e.1 + 1 == j {
                e.3 = s;
            }
            prev[p] = s;
        }
    }
    let min_var = opts.min_texture * opts.min_texture;
    (0..n)
        .map(|p| {
            let (s, j, l, r) = best[p];
            if s < opts.min_ncc || var_i[p] < min_var || j == 0 || j + 1 == planes {
                return 0.0;
            }
            // Parabola through the best plane and its two neighbours, in plane units.
            let den = l - 2.0 * s + r;
            let off = if den < -1e-6 {
                (0.5 * (l - r) / den).clamp(-0.5, 0.5)
            } else {
                0.0
            };
            z_of(j as f32 + off)
        })
        .collect()
}

/// View `i`'s depths that at least `min_consistent` of its neighbours' depth maps confirm.
fn consistent(
    views: &[View],
    depths: &[Vec<f32>],
    i: usize,
    near: &[usize],
    opts: &StereoOptions,
) -> Vec<f32> {
    let v = &views[i];
    let c = v.center();
    let w2c: Vec<glam::Mat3> = near
        .iter()
        .map(|&nb| views[nb].cam.pose.c2w_rotation().as_mat3().transpose())
        .collect();
    (0..depths[i].len())
        .map(|p| {
            let z = depths[i][p];
            if z <= 0.0 {
                return 0.0;
            }
            let (_, d) = v.ray(p as u32);
            let x = c + d * (z * v.ray_scale(p as u32));
            let agree = near
                .iter()
                .zip(&w2c)
                .filter(|&(&nb, rot)| {
                    let o = &views[nb];
                    let Some((px, py)) = o.project(x) else {
                        return false;
                    };
                    if px < 0.0 || py < 0.0 || px >= o.width as f32 || py >= o.height as f32 {
                        return false;
                    }
                    let q = py as usize * o.width as usize + px as usize;
                    let zo = depths[nb][q];
                    let zx = (*rot * (x - o.center())).z;
                    zo > 0.0 && (zo - zx).abs() <= opts.consistency * zx
                })
                .count();
            if agree >= opts.min_consistent {
                z
            } else {
                0.0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_sums_match_a_direct_sum() {
        let (w, h) = (7, 6);
        let a: Vec<f32> = (0..w * h).map(|i| (i * 7 % 11) as f32).collect();
        let s = box_sum(&a, w, h);
        for y in 0..h {
            for x in 0..w {
                let mut want = 0.0;
                for yy in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(h) {
                    for xx in x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w) {
                        want += a[yy * w + xx];
                    }
                }
                assert_eq!(s[y * w + x], want, "at {x},{y}");
            }
        }
    }
}
