//! What the stability suite does to a capture: fewer views, noisy poses, noisy, differently
//! exposed or motion-blurred images. Each is seeded, so a case is the same capture every run.
//! Images are rewritten into the case's folder and the scene points at them; the originals are
//! never touched.

use crate::error::{Error, Result};
use crate::scene::frames::rows_3x4;
use crate::scene::io::read_rgb;
use crate::scene::{Pose, Scene};
use crate::util::atomic::save_image_atomic;
use crate::util::Rng;
use glam::{DMat3, DVec3};
use image::RgbImage;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;

/// One perturbation of a capture, with its strength.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Perturbation {
    None,
    /// Keep this many views, evenly spaced in the scene's order from the clicked one.
    Views {
        count: usize,
    },
    /// Every camera turned by `degrees` about a random axis and moved by the matching arc
    /// (degrees in radians times its distance to the scene's centre) in a random direction;
    /// then the capture is triangulated again with those poses by COLMAP, as `objnerf sfm`
    /// would in use (`run::retriangulate`).
    PoseNoise {
        degrees: f64,
    },
    /// Gaussian noise of this standard deviation (fraction of full scale) on every pixel.
    ImageNoise {
        sigma: f64,
    },
    /// Every view's exposure scaled by 2^u stops, u uniform in [-stops, stops].
    Exposure {
        stops: f64,
    },
    /// Every view blurred along a random direction over this many pixels.
    MotionBlur {
        pixels: f64,
    },
}

impl Perturbation {
    /// The perturbation's group (the suite's table and charts are per group) and strength.
    pub fn group(&self) -> (&'static str, f64) {
        match *self {
            Perturbation::None => ("none", 0.0),
            Perturbation::Views { count } => ("views", count as f64),
            Perturbation::PoseNoise { degrees } => ("pose noise (deg)", degrees),
            Perturbation::ImageNoise { sigma } => ("image noise (sigma)", sigma),
            Perturbation::Exposure { stops } => ("exposure (+-stops)", stops),
            Perturbation::MotionBlur { pixels } => ("motion blur (px)", pixels),
        }
    }

    fn changes_images(&self) -> bool {
        matches!(
            self,
            Perturbation::ImageNoise { .. }
                | Perturbation::Exposure { .. }
                | Perturbation::MotionBlur { .. }
        )
    }
}

/// `scene` perturbed by `p` (seeded by `seed`); new images go to `dir/images/`. `anchor` (the
/// clicked view) stays when views are dropped.
pub fn perturb(
    scene: &Scene,
    p: Perturbation,
    seed: u64,
    anchor: usize,
    dir: &Path,
) -> Result<Scene> {
    let mut out = match p {
        Perturbation::Views { count } => {
            let n = scene.images.len();
            if count == 0 || count > n {
                return Err(Error::invalid(format!("cannot keep {count} of {n} views")));
            }
            let mut keep: Vec<usize> = (0..count).map(|j| (anchor + j * n / count) % n).collect();
            keep.sort_unstable();
            scene.subset(&keep)
        }
        Perturbation::PoseNoise { degrees } => pose_noise(scene, degrees, seed),
        _ => scene.clone(),
    };
    if p.changes_images() {
        let images = dir.join("images");
        let paths: Vec<_> = out
            .images
            .par_iter()
            .enumerate()
            .map(|(i, im)| {
                let mut rng = Rng::fork(seed, i as u64);
                let img = read_rgb(&im.path)?;
                let img = match p {
                    Perturbation::ImageNoise { sigma } => add_noise(&img, sigma, &mut rng),
                    Perturbation::Exposure { stops } => {
                        expose(&img, 2f64.powf(rng.range(-stops, stops)))
                    }
                    Perturbation::MotionBlur { pixels } => {
                        let a = rng.range(0.0, std::f64::consts::PI);
                        motion_blur(&img, pixels, a)
                    }
                    _ => img,
                };
                let path = images.join(
                    Path::new(&im.name)
                        .with_extension("png")
                        .file_name()
                        .unwrap_or_default(),
                );
                save_image_atomic(&path, &image::DynamicImage::ImageRgb8(img))?;
                Ok(path)
            })
            .collect::<Result<_>>()?;
        for (im, path) in out.images.iter_mut().zip(paths) {
            im.path = path;
        }
    }
    Ok(out)
}

/// Every pose turned by `degrees` about a random axis and its centre moved by the matching arc.
fn pose_noise(scene: &Scene, degrees: f64, seed: u64) -> Scene {
    let mut out = scene.clone();
    let (_, pts) = scene.bounds();
    let centre = pts.map_or(DVec3::ZERO, |(lo, hi)| 0.5 * (lo + hi));
    let angle = degrees.to_radians();
    for (i, im) in out.images.iter_mut().enumerate() {
        let mut rng = Rng::fork(seed, 0x9053 + i as u64);
        let axis = random_unit(&mut rng);
        let dir = random_unit(&mut rng);
        let r = DMat3::from_axis_angle(axis, angle) * im.pose.c2w_rotation();
        let c = im.pose.center();
        let moved = c + dir * angle * (c - centre).length();
        im.pose = Pose::from_c2w_opencv(rows_3x4(r, moved)).expect("a rotation stays rigid");
    }
    out
}

fn random_unit(rng: &mut Rng) -> DVec3 {
    loop {
        let v = DVec3::new(rng.normal(), rng.normal(), rng.normal());
        if v.length() > 1e-6 {
            return v.normalize();
        }
    }
}

fn add_noise(img: &RgbImage, sigma: f64, rng: &mut Rng) -> RgbImage {
    let mut out = img.clone();
    for v in out.iter_mut() {
        *v = (*v as f64 + rng.normal() * sigma * 255.0)
            .round()
            .clamp(0.0, 255.0) as u8;
    }
    out
}

fn expose(img: &RgbImage, gain: f64) -> RgbImage {
    let mut out = img.clone();
    for v in out.iter_mut() {
        *v = (*v as f64 * gain).round().clamp(0.0, 255.0) as u8;
    }
    out
}

/// The mean of `length` samples along direction `angle` through each pixel (nearest pixel,
/// clamped at the borders): a straight-line motion blur.
fn motion_blur(img: &RgbImage, length: f64, angle: f64) -> RgbImage {
    let (w, h) = img.dimensions();
    let n = length.round().max(1.0) as i64;
    let (dx, dy) = (angle.cos(), angle.sin());
    RgbImage::from_fn(w, h, |x, y| {
        let mut acc = [0u32; 3];
        for k in 0..n {
            let t = k as f64 - (n - 1) as f64 / 2.0;
            let sx = (x as f64 + t * dx).round().clamp(0.0, (w - 1) as f64) as u32;
            let sy = (y as f64 + t * dy).round().clamp(0.0, (h - 1) as f64) as u32;
            let p = img.get_pixel(sx, sy);
            for c in 0..3 {
                acc[c] += p[c] as u32;
            }
        }
        image::Rgb(acc.map(|a| (a as f64 / n as f64).round() as u8))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blur_keeps_flat_images_and_exposure_scales() {
        let img = RgbImage::from_pixel(8, 6, image::Rgb([100, 50, 200]));
        assert_eq!(motion_blur(&img, 5.0, 0.7), img);
        assert_eq!(expose(&img, 2.0).get_pixel(0, 0).0, [200, 100, 255]);
        let mut rng = Rng::new(1);
        let noisy = add_noise(&img, 0.05, &mut rng);
        let mean: f64 = noisy.pixels().map(|p| p[0] as f64).sum::<f64>() / 48.0;
        assert!((mean - 100.0).abs() < 5.0, "{mean}");
    }
}
