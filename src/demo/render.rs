//! The CPU renderer: the camera ring, anti-aliased colour (3x3 stratified samples per pixel,
//! Lambertian shading under a fixed directional light plus ambient), and per-pixel-centre truth
//! (z-depth and the id of the first surface). Rows are rendered in parallel; every pixel is a pure
//! function of its position, so the output does not depend on thread scheduling.

use super::geometry::{Ray, World, NONE};
use super::texture::Textures;
use crate::scene::{Camera, Pose};
use crate::util::Rng;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// Samples per pixel side. Odd, so the middle sample is the pixel centre (the truth ray).
pub(super) const SS: u32 = 3;
pub(super) const AMBIENT: f64 = 0.42;
pub(super) const DIFFUSE: f64 = 0.62;
pub(super) const SKY: [u8; 3] = [200, 215, 235];

/// Camera ring radius and the point the cameras look at.
const RING_RADIUS: f64 = 1.95;
const TARGET: DVec3 = DVec3::new(0.0, 0.0, 0.13);

/// The demo's camera: pinhole, about 60 degrees wide, principal point at the image centre.
pub fn demo_camera(width: u32, height: u32) -> Camera {
    let f = 1.05 * width as f64;
    Camera::pinhole(width, height, f, f, 0.5 * width as f64, 0.5 * height as f64)
}

/// `n` poses on a ring around the scene, looking at its centre; view 0 is on the -y side. Radius,
/// height and aim are jittered slightly (from `rng`) so the ring is not perfectly regular.
pub fn demo_poses(n: usize, rng: &mut Rng) -> Vec<Pose> {
    (0..n)
        .map(|i| {
            let a = -std::f64::consts::FRAC_PI_2 + std::f64::consts::TAU * i as f64 / n as f64;
            let r = RING_RADIUS + rng.range(-0.05, 0.05);
            let z = 0.85 + 0.1 * (3.0 * a).sin() + rng.range(-0.03, 0.03);
            let eye = DVec3::new(r * a.cos(), r * a.sin(), z);
            let aim = TARGET + DVec3::new(rng.range(-0.02, 0.02), rng.range(-0.02, 0.02), 0.0);
            Pose::look_at(eye, aim, DVec3::Z)
        })
        .collect()
}

/// The world ray through a pixel position.
pub fn pixel_ray(cam: &Camera, pose: &Pose, px: DVec2) -> Ray {
    Ray {
        o: pose.center(),
        d: pose.camera_to_world_dir(cam.unproject(px)).normalize(),
    }
}

/// One rendered view: RGB, z-depth in metres along the optical axis (0 = nothing hit) and the
/// id of the first surface at each pixel centre (`NONE` for sky).
pub struct ViewRender {
    pub rgb: Vec<u8>,
    pub depth: Vec<f32>,
    pub ids: Vec<u8>,
}

pub fn render_view(world: &World, tex: &Textures, cam: &Camera, pose: &Pose) -> ViewRender {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let rows: Vec<(Vec<u8>, Vec<f32>, Vec<u8>)> = (0..h)
        .into_par_iter()
        .map(|row| {
            let mut rgb = Vec::with_capacity(w * 3);
            let mut depth = Vec::with_capacity(w);
            let mut ids = Vec::with_capacity(w);
            for col in 0..w {
                let mut acc = DVec3::ZERO;
                let mut centre = (0.0f32, NONE);
                for sy in 0..SS {
                    for sx in 0..SS {
                        let px = DVec2::new(
                            col as f64 + (sx as f64 + 0.5) / SS as f64,
                            row as f64 + (sy as f64 + 0.5) / SS as f64,
                        );
                        let ray = pixel_ray(cam, pose, px);
                        let hit = world.trace(&ray, None);
                        acc += match &hit {
                            Some(hit) => {
                                let shade = AMBIENT + DIFFUSE * hit.n.dot(world.light).max(0.0);
                                tex.albedo(world, hit) * shade
                            }
                            None => DVec3::from_array(SKY.map(|c| c as f64 / 255.0)),
                        };
                        if sx == SS / 2 && sy == SS / 2 {
                            if let Some(hit) = hit {
                                centre = (pose.world_to_camera(hit.p).z as f32, hit.id);
                            }
                        }
                    }
                }
                let c = acc / (SS * SS) as f64;
                for v in c.to_array() {
                    rgb.push((v.clamp(0.0, 1.0) * 255.0).round() as u8);
                }
                depth.push(centre.0);
                ids.push(centre.1);
            }
            (rgb, depth, ids)
        })
        .collect();
    let mut out = ViewRender {
        rgb: Vec::with_capacity(w * h * 3),
        depth: Vec::with_capacity(w * h),
        ids: Vec::with_capacity(w * h),
    };
    for (rgb, depth, ids) in rows {
        out.rgb.extend(rgb);
        out.depth.extend(depth);
        out.ids.extend(ids);
    }
    out
}

/// Area in pixels of object `obj`'s full silhouette in this view: the object alone, nothing in
/// front of it, on a canvas three times the image in each direction (so parts outside the frame
/// count). Only the pixels inside the object's projected bounding box are traced.
pub fn silhouette_area(world: &World, obj: usize, cam: &Camera, pose: &Pose) -> f64 {
    let (w, h) = (cam.width as i64, cam.height as i64);
    let (lo, hi) = world.objects[obj].world_bbox();
    let mut rect = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
    let mut behind = false;
    for i in 0..8 {
        let c = DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        match cam.project(pose.world_to_camera(c)) {
            Some(p) if pose.world_to_camera(c).z > 1e-3 => {
                rect.0 = rect.0.min(p.x.floor() as i64);
                rect.1 = rect.1.min(p.y.floor() as i64);
                rect.2 = rect.2.max(p.x.ceil() as i64);
                rect.3 = rect.3.max(p.y.ceil() as i64);
            }
            _ => behind = true,
        }
    }
    let canvas = (-w, -h, 2 * w, 2 * h);
    let (x0, y0, x1, y1) = if behind {
        canvas
    } else {
        (
            rect.0.max(canvas.0),
            rect.1.max(canvas.1),
            rect.2.min(canvas.2),
            rect.3.min(canvas.3),
        )
    };
    if x1 <= x0 || y1 <= y0 {
        return 0.0;
    }
    (y0..y1)
        .into_par_iter()
        .map(|row| {
            (x0..x1)
                .filter(|&col| {
                    let px = DVec2::new(col as f64 + 0.5, row as f64 + 0.5);
                    world.trace(&pixel_ray(cam, pose, px), Some(obj)).is_some()
                })
                .count()
        })
        .sum::<usize>() as f64
}
