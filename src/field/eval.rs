//! Rendering whole views (RGB, depth, alpha; multi-threaded by rows) and scoring them: PSNR and
//! SSIM against the truth composited on white (the NeRF-synthetic protocol).

use super::holdout::HoldOut;
use super::io::Model;
use super::model::Field;
use super::view::{load_views, MaskSource, RayCamera, View};
use crate::error::Result;
use crate::field::march::{render_ray, RenderOptions};
use crate::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;

/// A rendered view: RGB in [0, 1] (composited on the background), alpha, and depth (expected
/// distance along the ray over the opaque part: sum w t / sum w; 0 where alpha is ~0).
#[derive(Clone, Debug)]
pub struct Rendered {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<[f32; 3]>,
    pub alpha: Vec<f32>,
    pub depth: Vec<f32>,
}

/// A whole view over the background `bg`, rows in parallel, each pixel the mean of
/// Render every view of `views` (colour on white, alpha, depth).
pub fn render_all(field: &Field, opt: &RenderOptions, views: &[View]) -> Vec<Rendered> {
    views
        .iter()
        .map(|v| render_view(field, opt, v, [1.0; 3]))
        .collect()
}

/// `opt.pixel_samples` x `opt.pixel_samples` rays over its square.
pub fn render_view(f: &Field, opt: &RenderOptions, view: &RayCamera, bg: [f32; 3]) -> Rendered {
    let (w, h) = (view.width, view.height);
    let n = opt.pixel_samples.max(1);
    let inv = 1.0 / (n * n) as f32;
    let rows: Vec<Vec<(f32, f32, [f32; 3])>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut scratch = Vec::new();
            (0..w)
                .map(|x| {
                    let (mut alpha, mut depth, mut rgb) = (0.0, 0.0, [0.0; 3]);
                    for j in 0..n {
                        for i in 0..n {
                            let at = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
                            let (o, d) = view.ray_through(y * w + x, at);
                            let r = render_ray(f, opt, o, d, bg, &mut scratch);
                            alpha += r.alpha * inv;
                            depth += r.depth * inv;
                            (0..3).for_each(|c| rgb[c] += r.rgb[c] * inv);
                        }
                    }
                    let depth = if alpha > 1e-3 { depth / alpha } else { 0.0 };
                    (alpha, depth, rgb)
                })
                .collect()
        })
        .collect();
    let mut out = Rendered::with_capacity(w, h);
    for (a, d, c) in rows.into_iter().flatten() {
        out.alpha.push(a);
        out.depth.push(d);
        out.rgb.push(c);
    }
    out
}

impl Rendered {
    /// An empty render of a `width` x `height` view, its passes' room reserved.
    pub fn with_capacity(width: u32, height: u32) -> Rendered {
        let n = (width * height) as usize;
        Rendered {
            width,
            height,
            rgb: Vec::with_capacity(n),
            alpha: Vec::with_capacity(n),
            depth: Vec::with_capacity(n),
        }
    }

    /// The colour as an 8-bit RGB image.
    pub fn rgb8(&self) -> image::RgbImage {
        rgb8(self.width, self.height, &self.rgb)
    }

    /// The opacity as an 8-bit grey image.
    pub fn alpha8(&self) -> image::GrayImage {
        gray8(self.width, self.height, &self.alpha)
    }
}

/// Row-major colours in [0, 1] as an 8-bit RGB image.
pub fn rgb8(width: u32, height: u32, rgb: &[[f32; 3]]) -> image::RgbImage {
    image::RgbImage::from_fn(width, height, |x, y| {
        let p = rgb[(y * width + x) as usize];
        image::Rgb(p.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8))
    })
}

/// Row-major values in [0, 1] as an 8-bit grey image.
pub fn gray8(width: u32, height: u32, v: &[f32]) -> image::GrayImage {
    image::GrayImage::from_fn(width, height, |x, y| {
        let a = v[(y * width + x) as usize];
        image::Luma([(a.clamp(0.0, 1.0) * 255.0).round() as u8])
    })
}

/// A view's truth composited on a background.
pub fn truth_on(view: &View, bg: [f32; 3]) -> Vec<[f32; 3]> {
    view.rgba
        .iter()
        .map(|p| {
            let a = p[3] as f32 / 255.0;
            [0, 1, 2].map(|c| p[c] as f32 / 255.0 + (1.0 - a) * bg[c])
        })
        .collect()
}

pub fn psnr(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let mse: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (0..3).map(|c| ((x[c] - y[c]) as f64).powi(2)).sum::<f64>())
        .sum::<f64>()
        / (3 * a.len().max(1)) as f64;
    -10.0 * mse.max(1e-20).log10()
}

/// PSNR of `a` against `b` after the affine colour map (3 x 4, least squares over the whole
/// image) that brings `a` closest to `b`: how methods that learn a per-image appearance
/// (NeRF-W) are scored on held-out views, whose appearance no training fixed.
pub fn psnr_colour_fit(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    // Normal equations: (X^T X) M_c = X^T t_c with rows X = [r, g, b, 1].
    let mut xtx = [[0f64; 4]; 4];
    let mut xtt = [[0f64; 3]; 4];
    for (x, t) in a.iter().zip(b) {
        let row = [x[0] as f64, x[1] as f64, x[2] as f64, 1.0];
        for i in 0..4 {
            for j in 0..4 {
                xtx[i][j] += row[i] * row[j];
            }
            for c in 0..3 {
                xtt[i][c] += row[i] * t[c] as f64;
            }
        }
    }
    // A little ridge keeps a flat render (one colour) solvable.
    for (i, r) in xtx.iter_mut().enumerate() {
        r[i] += 1e-6 * a.len().max(1) as f64;
    }
    let Some(m) = solve4(xtx, xtt) else {
        return psnr(a, b);
    };
    let mapped: Vec<[f32; 3]> = a
        .iter()
        .map(|x| {
            let row = [x[0] as f64, x[1] as f64, x[2] as f64, 1.0];
            [0, 1, 2].map(|c| (0..4).map(|i| row[i] * m[i][c]).sum::<f64>() as f32)
        })
        .collect();
    psnr(&mapped, b)
}

/// Solve `m x = rhs` (4 x 4, three right-hand sides) by Gaussian elimination with partial
/// pivoting; None when singular.
fn solve4(mut m: [[f64; 4]; 4], mut rhs: [[f64; 3]; 4]) -> Option<[[f64; 3]; 4]> {
    for col in 0..4 {
        let piv = (col..4).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        if m[piv][col].abs() < 1e-12 {
            return None;
        }
        m.swap(col, piv);
        rhs.swap(col, piv);
        let (pivot_row, pivot_rhs) = (m[col], rhs[col]);
        for r in (0..4).filter(|&r| r != col) {
            let f = m[r][col] / pivot_row[col];
            m[r].iter_mut()
                .zip(pivot_row)
                .for_each(|(v, p)| *v -= f * p);
            rhs[r]
                .iter_mut()
                .zip(pivot_rhs)
                .for_each(|(v, p)| *v -= f * p);
        }
    }
    for (r, row) in rhs.iter_mut().enumerate() {
        row.iter_mut().for_each(|v| *v /= m[r][r]);
    }
    Some(rhs)
}

/// SSIM (Wang et al. 2004: 11x11 Gaussian window, sigma 1.5, K1 0.01, K2 0.03, data range 1),
/// averaged over the valid window positions and the three channels, as the NeRF papers compute it.
pub fn ssim(a: &[[f32; 3]], b: &[[f32; 3]], w: usize, h: usize) -> f64 {
    let k: Vec<f64> = {
        let g: Vec<f64> = (0..11)
            .map(|i| (-((i as f64 - 5.0).powi(2)) / (2.0 * 1.5 * 1.5)).exp())
            .collect();
        let s: f64 = g.iter().sum();
        g.iter().map(|v| v / s).collect()
    };
    if w < 11 || h < 11 {
        return f64::NAN;
    }
    let (ow, oh) = (w - 10, h - 10);
    // Valid separable filtering.
    let filt = |img: &[f64]| -> Vec<f64> {
        let mut tmp = vec![0.0; ow * h];
        for y in 0..h {
            for x in 0..ow {
                tmp[y * ow + x] = (0..11).map(|i| k[i] * img[y * w + x + i]).sum();
            }
        }
        let mut out = vec![0.0; ow * oh];
        for y in 0..oh {
            for x in 0..ow {
                out[y * ow + x] = (0..11).map(|i| k[i] * tmp[(y + i) * ow + x]).sum();
            }
        }
        out
    };
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let total: f64 = (0..3)
        .into_par_iter()
        .map(|c| {
            let x: Vec<f64> = a.iter().map(|p| p[c] as f64).collect();
            let y: Vec<f64> = b.iter().map(|p| p[c] as f64).collect();
            let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
            let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
            let xy: Vec<f64> = x.iter().zip(&y).map(|(p, q)| p * q).collect();
            let (mx, my) = (filt(&x), filt(&y));
            let (sxx, syy, sxy) = (filt(&xx), filt(&yy), filt(&xy));
            let mut s = 0.0;
            for i in 0..mx.len() {
                let (ux, uy) = (mx[i], my[i]);
                let vx = sxx[i] - ux * ux;
                let vy = syy[i] - uy * uy;
                let cxy = sxy[i] - ux * uy;
                s += ((2.0 * ux * uy + c1) * (2.0 * cxy + c2))
                    / ((ux * ux + uy * uy + c1) * (vx + vy + c2));
            }
            s / mx.len() as f64
        })
        .sum();
    total / 3.0
}

#[derive(Clone, Debug, Serialize)]
pub struct ViewScore {
    pub name: String,
    pub psnr: f64,
    pub ssim: f64,
    /// PSNR after the render's best affine colour map to the truth ([`psnr_colour_fit`]).
    pub psnr_colour_fit: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    pub psnr: f64,
    pub ssim: f64,
    /// The views' mean [`ViewScore::psnr_colour_fit`].
    pub psnr_colour_fit: f64,
    pub num_views: usize,
    pub views: Vec<ViewScore>,
    pub seconds: f64,
}

/// Render every view on white and score it against its truth on white.
pub fn evaluate(f: &Field, opt: &RenderOptions, views: &[View]) -> EvalReport {
    let on_cpu =
        |v: &View| Ok::<_, std::convert::Infallible>(render_view(f, opt, &v.cam, [1.0; 3]));
    match evaluate_with(views, on_cpu) {
        Ok(r) => r,
        Err(never) => match never {},
    }
}

/// [`evaluate`] with each view drawn (on white) by `render` (the GPU renderer's, say).
pub fn evaluate_with<E>(
    views: &[View],
    mut render: impl FnMut(&View) -> std::result::Result<Rendered, E>,
) -> std::result::Result<EvalReport, E> {
    let start = std::time::Instant::now();
    let white = [1.0; 3];
    let mut scores = Vec::with_capacity(views.len());
    for v in views {
        let r = render(v)?;
        let t = truth_on(v, white);
        scores.push(ViewScore {
            name: v.name.clone(),
            psnr: psnr(&r.rgb, &t),
            ssim: ssim(&r.rgb, &t, v.width as usize, v.height as usize),
            psnr_colour_fit: psnr_colour_fit(&r.rgb, &t),
        });
    }
    let n = scores.len().max(1) as f64;
    Ok(EvalReport {
        psnr: scores.iter().map(|s| s.psnr).sum::<f64>() / n,
        ssim: scores.iter().map(|s| s.ssim).sum::<f64>() / n,
        psnr_colour_fit: scores.iter().map(|s| s.psnr_colour_fit).sum::<f64>() / n,
        num_views: scores.len(),
        views: scores,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The views a model is scored on (`objnerf eval`, `render::views::evaluate_model`): a scene's
/// views (only those `hold_out` leaves out of training, when it holds any out), with `masks` as
/// the truth's alpha, at `downscale` (default: the one it was trained at).
pub fn eval_views(
    model: &Model,
    scene: &Scene,
    masks: &MaskSource,
    downscale: Option<u32>,
    hold_out: HoldOut,
) -> Result<Vec<View>> {
    let mut views = load_views(scene, masks, downscale.unwrap_or_else(|| model.downscale()))?;
    if !hold_out.is_none() {
        views = super::holdout::split(views, hold_out).1;
    }
    Ok(views)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psnr_and_ssim_of_identical_and_noisy_images() {
        let (w, h) = (32, 24);
        let a: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let v = ((i * 37) % 101) as f32 / 100.0;
                [v, 1.0 - v, 0.5]
            })
            .collect();
        assert!(psnr(&a, &a) > 100.0);
        // A render that is the truth under a colour map scores as the truth after the fit.
        let a: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                [
                    (i * 37 % 101) as f32,
                    (i * 53 % 97) as f32,
                    (i * 11 % 89) as f32,
                ]
            })
            .map(|p| [p[0] / 101.0, p[1] / 97.0, p[2] / 89.0])
            .collect();
        let mapped: Vec<[f32; 3]> = a
            .iter()
            .map(|p| {
                [
                    0.8 * p[0] + 0.1,
                    0.9 * p[1] + 0.05 * p[0],
                    1.1 * p[2] - 0.02,
                ]
            })
            .collect();
        assert!(psnr(&mapped, &a) < 30.0);
        assert!(
            psnr_colour_fit(&mapped, &a) > 80.0,
            "{}",
            psnr_colour_fit(&mapped, &a)
        );
        assert!(psnr_colour_fit(&a, &a) > 80.0);
        assert!((ssim(&a, &a, w, h) - 1.0).abs() < 1e-9);
        let b: Vec<[f32; 3]> = a.iter().map(|p| p.map(|v| (v + 0.1).min(1.0))).collect();
        let p = psnr(&a, &b);
        assert!(p > 19.0 && p < 21.0, "{p}");
        let s = ssim(&a, &b, w, h);
        assert!(s < 1.0 && s > 0.5, "{s}");
    }

    /// A pixel rendered with n x n rays is the mean of the rays through those points of its
    /// square; with one ray, the ray through its centre.
    #[test]
    fn a_pixel_is_the_mean_of_its_rays() {
        use super::super::grid::value_index;
        use super::super::model::FieldConfig;
        use crate::scene::{Camera, Pose};
        use crate::util::Rng;
        use glam::{DVec3, Vec3};
        let config = FieldConfig {
            sh_degree: 1,
            alpha_init: 0.05,
            base_voxel: 0.25,
        };
        let mut f = Field::new(config, Vec3::splat(-1.0), Vec3::splat(1.0), [6, 7, 6]);
        let mut r = Rng::new(5);
        let ch = f.grid.channels;
        for v in 0..f.grid.num_vertices() {
            for c in 0..ch {
                f.grid.data[value_index(v, c, ch)] = 2.0 * r.normal() as f32;
            }
        }
        let camera = Camera::pinhole(12, 10, 9.0, 9.0, 6.0, 5.0);
        let pose = Pose::look_at(DVec3::new(0.4, -3.0, 0.8), DVec3::ZERO, DVec3::Z);
        let cam = RayCamera::new("v".into(), camera, pose);
        let bg = [0.2, 0.6, 0.9];
        let ray = |idx: u32, at: [f32; 2]| {
            let (o, d) = cam.ray_through(idx, at);
            render_ray(&f, &RenderOptions::default(), o, d, bg, &mut Vec::new())
        };
        let one = render_view(&f, &RenderOptions::default(), &cam, bg);
        let four = render_view(
            &f,
            &RenderOptions {
                pixel_samples: 2,
                ..RenderOptions::default()
            },
            &cam,
            bg,
        );
        let mut differs = 0;
        for idx in 0..120u32 {
            let i = idx as usize;
            assert_eq!(one.rgb[i], ray(idx, [0.5, 0.5]).rgb);
            let outs =
                [[0.25, 0.25], [0.75, 0.25], [0.25, 0.75], [0.75, 0.75]].map(|at| ray(idx, at));
            let alpha: f32 = outs.iter().map(|o| o.alpha).sum::<f32>() / 4.0;
            assert!((four.alpha[i] - alpha).abs() < 1e-5, "{idx}");
            for c in 0..3 {
                let mean: f32 = outs.iter().map(|o| o.rgb[c]).sum::<f32>() / 4.0;
                assert!((four.rgb[i][c] - mean).abs() < 1e-5, "{idx} {c}");
            }
            differs += usize::from((four.rgb[i][0] - one.rgb[i][0]).abs() > 1e-3);
        }
        assert!(
            differs > 10,
            "the sub-pixel rays see other colours: {differs}"
        );
    }
}
