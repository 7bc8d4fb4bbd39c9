//! The expected mask of an object in a view, from its segmented 3D points alone: project them,
//! drop isolated outliers, take the alpha shape (Delaunay triangles whose circumradius is below
//! alpha), rasterise, blur and threshold. Comparing it with SAM's mask finds obstructed views
//! (paper §4.2, "Obstruction handling"). A convex hull is not enough: one outlier ruins it.

use crate::util::stats::quantile;
use glam::DVec2;
use image::{GrayImage, Luma};
use spade::{DelaunayTriangulation, Point2, Triangulation};

#[derive(Clone, Debug)]
pub struct HullOptions {
    /// Alpha (circumradius limit) as a multiple of the spacing (the 90th percentile of the
    /// nearest-neighbour distances).
    pub alpha_factor: f64,
    /// A point whose nearest neighbour is farther than this multiple of the median spacing is an
    /// outlier.
    pub outlier_factor: f64,
    /// Gaussian blur sigma as a multiple of the median spacing (at least 1 px).
    pub blur_factor: f64,
    /// Threshold on the blurred hull. Samples sit about half a spacing inside the true outline;
    /// a straight edge blurred with sigma = spacing/2 falls to 0.16 one sigma outside it, so this
    /// grows the hull by that half spacing.
    pub threshold: f32,
}

impl Default for HullOptions {
    fn default() -> Self {
        HullOptions {
            alpha_factor: 3.0,
            outlier_factor: 4.0,
            blur_factor: 0.5,
            threshold: 0.16,
        }
    }
}

/// The expected mask (0/255) of the points `pts` (pixel coordinates) in a `width` x `height`
/// image, and the median spacing it used. Fewer than 3 usable points give an empty mask.
pub fn expected_mask(
    pts: &[DVec2],
    width: u32,
    height: u32,
    opts: &HullOptions,
) -> (GrayImage, f64) {
    let mut out = GrayImage::new(width, height);
    // Points far outside the frame say nothing about the visible silhouette but can still shape it
    // near the edge: keep a margin of one frame.
    let (w, h) = (width as f64, height as f64);
    let pts: Vec<DVec2> = pts
        .iter()
        .copied()
        .filter(|p| p.is_finite() && p.x > -w && p.x < 2.0 * w && p.y > -h && p.y < 2.0 * h)
        .collect();
    let Some((tri, spacing)) = triangulate_without_outliers(&pts, opts.outlier_factor) else {
        return (out, 0.0);
    };
    let alpha2 = (opts.alpha_factor * spacing).powi(2);
    let mut cover = vec![0f32; (width * height) as usize];
    for face in tri.inner_faces() {
        let (_, r2) = face.circumcircle();
        if r2 < alpha2 {
            let [a, b, c] = face.positions();
            fill_triangle(
                &mut cover,
                width,
                height,
                [
                    DVec2::new(a.x, a.y),
                    DVec2::new(b.x, b.y),
                    DVec2::new(c.x, c.y),
                ],
            );
        }
    }
    let sigma = (opts.blur_factor * spacing).max(1.0);
    let blurred = gaussian_blur(&cover, width as usize, height as usize, sigma as f32);
    for (i, v) in blurred.iter().enumerate() {
        if *v >= opts.threshold {
            out.put_pixel(i as u32 % width, i as u32 / width, Luma([255]));
        }
    }
    (out, spacing)
}

/// Delaunay triangulation of the points after removing isolated ones; returns it with the median
/// nearest-neighbour spacing.
fn triangulate_without_outliers(
    pts: &[DVec2],
    outlier_factor: f64,
) -> Option<(DelaunayTriangulation<Point2<f64>>, f64)> {
    let build = |p: &[DVec2]| -> Option<DelaunayTriangulation<Point2<f64>>> {
        DelaunayTriangulation::bulk_load_stable(p.iter().map(|q| Point2::new(q.x, q.y)).collect())
            .ok()
    };
    if pts.len() < 3 {
        return None;
    }
    let tri = build(pts)?;
    // The nearest neighbour of a point is one of its Delaunay neighbours.
    let nn: Vec<(Point2<f64>, f64)> = tri
        .vertices()
        .map(|v| {
            let p = v.position();
            let d = v
                .out_edges()
                .map(|e| {
                    let q = e.to().position();
                    ((p.x - q.x).powi(2) + (p.y - q.y).powi(2)).sqrt()
                })
                .fold(f64::INFINITY, f64::min);
            (p, d)
        })
        .collect();
    // Random samples leave gaps far wider than their median spacing, and overlapping surfaces
    // crowd some areas: a high quantile of the nearest-neighbour distances measures the gaps
    // the hull must bridge.
    let spacing = quantile(
        nn.iter().map(|x| x.1).filter(|d| d.is_finite()).collect(),
        0.9,
    )?;
    if spacing <= 0.0 {
        return None;
    }
    let kept: Vec<DVec2> = nn
        .iter()
        .filter(|(_, d)| *d <= outlier_factor * spacing)
        .map(|(p, _)| DVec2::new(p.x, p.y))
        .collect();
    if kept.len() < 3 {
        return None;
    }
    Some((build(&kept)?, spacing))
}

/// Set to 1 every pixel whose centre lies inside the triangle.
fn fill_triangle(cover: &mut [f32], width: u32, height: u32, t: [DVec2; 3]) {
    let lo = t[0].min(t[1]).min(t[2]);
    let hi = t[0].max(t[1]).max(t[2]);
    let x0 = (lo.x - 0.5).ceil().max(0.0) as i64;
    let y0 = (lo.y - 0.5).ceil().max(0.0) as i64;
    let x1 = ((hi.x - 0.5).floor() as i64).min(width as i64 - 1);
    let y1 = ((hi.y - 0.5).floor() as i64).min(height as i64 - 1);
    let edge = |a: DVec2, b: DVec2, p: DVec2| (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
    let area = edge(t[0], t[1], t[2]);
    if area == 0.0 {
        return;
    }
    for y in y0..=y1 {
        for x in x0..=x1 {
            let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let (e0, e1, e2) = (
                edge(t[1], t[2], p) * area,
                edge(t[2], t[0], p) * area,
                edge(t[0], t[1], p) * area,
            );
            if e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0 {
                cover[(y as u32 * width + x as u32) as usize] = 1.0;
            }
        }
    }
}

/// Separable Gaussian blur with clamped borders.
pub fn gaussian_blur(src: &[f32], w: usize, h: usize, sigma: f32) -> Vec<f32> {
    let r = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / sum).collect();
    let tmp = blur_axis(src, [w, h], &kernel, 0);
    blur_axis(&tmp, [w, h], &kernel, 1)
}

/// One pass of a separable blur along `axis` (0: x, 1: y), borders clamped.
fn blur_axis(src: &[f32], dims: [usize; 2], kernel: &[f32], axis: usize) -> Vec<f32> {
    let r = (kernel.len() / 2) as i64;
    let step = if axis == 0 { 1 } else { dims[0] };
    let mut out = vec![0f32; dims[0] * dims[1]];
    for y in 0..dims[1] {
        for x in 0..dims[0] {
            let at = [x, y][axis] as i64;
            let line_start = y * dims[0] + x - at as usize * step;
            out[y * dims[0] + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, kv)| {
                    let i = (at + k as i64 - r).clamp(0, dims[axis] as i64 - 1) as usize;
                    kv * src[line_start + i * step]
                })
                .sum();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The separable passes give exactly (bit for bit) the direct two-loop blur, so masks
    /// written before the passes were shared do not change.
    #[test]
    fn blur_equals_the_direct_definition() {
        let (w, h, sigma) = (23usize, 17usize, 2.3f32);
        let mut rng = crate::util::Rng::new(9);
        let src: Vec<f32> = (0..w * h).map(|_| rng.f32()).collect();
        let r = (3.0 * sigma).ceil() as i64;
        let k: Vec<f32> = (-r..=r)
            .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
            .collect();
        let sum: f32 = k.iter().sum();
        let k: Vec<f32> = k.iter().map(|v| v / sum).collect();
        let mut tmp = vec![0f32; w * h];
        let mut want = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for (j, kv) in k.iter().enumerate() {
                    let xx = (x as i64 + j as i64 - r).clamp(0, w as i64 - 1) as usize;
                    acc += kv * src[y * w + xx];
                }
                tmp[y * w + x] = acc;
            }
        }
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for (j, kv) in k.iter().enumerate() {
                    let yy = (y as i64 + j as i64 - r).clamp(0, h as i64 - 1) as usize;
                    acc += kv * tmp[yy * w + x];
                }
                want[y * w + x] = acc;
            }
        }
        assert_eq!(gaussian_blur(&src, w, h, sigma), want);
    }
    use crate::util::mask::iou;

    /// Points on a grid inside an L shape, plus one far outlier.
    fn l_shape() -> (Vec<DVec2>, GrayImage) {
        let mut pts = Vec::new();
        let mut truth = GrayImage::new(100, 100);
        let inside = |x: f64, y: f64| {
            (20.0..80.0).contains(&x) && (20.0..80.0).contains(&y) && !(x > 50.0 && y < 50.0)
        };
        for y in 0..100 {
            for x in 0..100 {
                if inside(x as f64 + 0.5, y as f64 + 0.5) {
                    truth.put_pixel(x, y, Luma([255]));
                }
            }
        }
        let mut y = 21.0;
        while y < 80.0 {
            let mut x = 21.0;
            while x < 80.0 {
                if inside(x, y) {
                    pts.push(DVec2::new(x, y));
                }
                x += 4.0;
            }
            y += 4.0;
        }
        pts.push(DVec2::new(95.0, 5.0));
        (pts, truth)
    }

    #[test]
    fn alpha_shape_follows_a_concave_outline_and_ignores_outliers() {
        let (pts, truth) = l_shape();
        let (mask, spacing) = expected_mask(&pts, 100, 100, &HullOptions::default());
        assert!((spacing - 4.0).abs() < 1e-9);
        let score = iou(&mask, &truth);
        assert!(score > 0.85, "IoU {score}");
        // The notch of the L (top right) and the outlier's corner stay empty.
        assert_eq!(mask.get_pixel(60, 40)[0], 0);
        assert_eq!(mask.get_pixel(95, 5)[0], 0);
        // A convex hull fills part of the notch even without the outlier.
        let (convex, _) = expected_mask(
            &pts[..pts.len() - 1],
            100,
            100,
            &HullOptions {
                alpha_factor: 1e9,
                ..Default::default()
            },
        );
        assert_eq!(convex.get_pixel(60, 40)[0], 255);
        assert!(
            iou(&convex, &truth) < score - 0.03,
            "convex {} vs alpha {score}",
            iou(&convex, &truth)
        );
    }

    #[test]
    fn too_few_points_give_an_empty_mask() {
        let (m, _) = expected_mask(
            &[DVec2::new(1.0, 1.0), DVec2::new(3.0, 3.0)],
            10,
            10,
            &HullOptions::default(),
        );
        assert!(m.pixels().all(|p| p[0] == 0));
    }
}
