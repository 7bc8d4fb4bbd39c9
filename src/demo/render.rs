//! The CPU renderer: the camera ring, anti-aliased colour (3x3 stratified samples per pixel,
//! Lambertian shading under a fixed directional light plus ambient), and per-pixel-centre truth
//! (z-depth and the id of the first surface). Rows are rendered in parallel; every pixel is a pure
//! function of its position, so the output does not depend on thread scheduling.

use super::geometry::{Ray, World, NONE};
use super::texture::Textures;
use crate::scene::{Camera, Pose};
use crate::util::lattice::box_corners;
use crate::util::Rng;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// Samples per pixel side. Odd, so the middle sample is the pixel centre (the truth ray).
pub(super) const SS: u32 = 3;
pub(super) const AMBIENT: f64 = 0.42;
pub(super) const DIFFUSE: f64 = 0.62;
pub(super) const SKY: [u8; 3] = [200, 215, 235];

/// Camera ring radius and the point the cameras look at.
pub(super) const RING_RADIUS: f64 = 1.95;
pub(super) const TARGET: DVec3 = DVec3::new(0.0, 0.0, 0.13);

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

/// Plane (y = this) the forward-facing cameras stand on: in front of the scene on the side
/// view 0 of the ring looks from.
const FORWARD_Y: f64 = -1.75;
/// Half extents of the forward-facing cameras' grid: x (across) and z (height, about 0.75).
const FORWARD_HALF: (f64, f64) = (0.45, 0.2);

/// `n` forward-facing poses (an LLFF-style sweep): a jittered grid of cameras on a plane in
/// front of the scene, each aimed at its centre (all axes within ~16 degrees of each other).
/// View 0 is the grid's middle camera.
pub fn forward_poses(n: usize, rng: &mut Rng) -> Vec<Pose> {
    let cols = ((n as f64 * 1.5).sqrt().ceil() as usize).max(1);
    let rows = n.div_ceil(cols);
    let mut poses: Vec<Pose> = (0..n)
        .map(|i| {
            let (c, r) = (i % cols, i / cols);
            let fx = if cols > 1 {
                c as f64 / (cols - 1) as f64
            } else {
                0.5
            };
            let fz = if rows > 1 {
                r as f64 / (rows - 1) as f64
            } else {
                0.5
            };
            let eye = DVec3::new(
                FORWARD_HALF.0 * (2.0 * fx - 1.0) + rng.range(-0.02, 0.02),
                FORWARD_Y + rng.range(-0.05, 0.05),
                0.75 + FORWARD_HALF.1 * (1.0 - 2.0 * fz) + rng.range(-0.02, 0.02),
            );
            let aim = TARGET + DVec3::new(rng.range(-0.03, 0.03), rng.range(-0.03, 0.03), 0.0);
            Pose::look_at(eye, aim, DVec3::Z)
        })
        .collect();
    poses.swap(0, n / 2);
    poses
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
    let rows: Vec<Vec<Pixel>> = (0..h)
        .into_par_iter()
        .map(|row| {
            (0..w)
                .map(|col| render_pixel(world, tex, cam, pose, col, row))
                .collect()
        })
        .collect();
    let mut out = ViewRender {
        rgb: Vec::with_capacity(w * h * 3),
        depth: Vec::with_capacity(w * h),
        ids: Vec::with_capacity(w * h),
    };
    for p in rows.into_iter().flatten() {
        out.rgb.extend(p.rgb);
        out.depth.push(p.depth);
        out.ids.push(p.id);
    }
    out
}

/// One pixel of a [`ViewRender`].
struct Pixel {
    rgb: [u8; 3],
    depth: f32,
    id: u8,
}

/// The colour of pixel (`col`, `row`) from [`SS`] x [`SS`] stratified samples, and the truth
/// (z-depth, surface id) at its centre.
fn render_pixel(
    world: &World,
    tex: &Textures,
    cam: &Camera,
    pose: &Pose,
    col: usize,
    row: usize,
) -> Pixel {
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
    Pixel {
        rgb: c
            .to_array()
            .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8),
        depth: centre.0,
        id: centre.1,
    }
}

/// The colour of view `full` (rendered from `world`) once the objects `objs` are taken away:
/// only the pixels of each object's projected box (padded by a pixel for the anti-aliased edge)
/// are rendered again, the rest is copied. The truth of a removal.
pub fn render_without(
    world: &World,
    tex: &Textures,
    cam: &Camera,
    pose: &Pose,
    objs: &[usize],
    full: &ViewRender,
) -> Vec<u8> {
    let mut without = world.clone();
    without.hidden.extend(objs);
    let (w, h) = (cam.width as i64, cam.height as i64);
    let mut redo = vec![false; (w * h) as usize];
    for &obj in objs {
        let (x0, y0, x1, y1) = projected_rect(world, obj, cam, pose, (0, 0, w, h));
        for row in (y0 - 1).max(0)..(y1 + 1).min(h) {
            for col in (x0 - 1).max(0)..(x1 + 1).min(w) {
                redo[(row * w + col) as usize] = true;
            }
        }
    }
    let mut rgb = full.rgb.clone();
    let redone: Vec<(usize, [u8; 3])> = (0..redo.len())
        .into_par_iter()
        .filter(|&i| redo[i])
        .map(|i| {
            let (col, row) = (i % w as usize, i / w as usize);
            (i, render_pixel(&without, tex, cam, pose, col, row).rgb)
        })
        .collect();
    for (i, c) in redone {
        rgb[3 * i..3 * i + 3].copy_from_slice(&c);
    }
    rgb
}

/// The pixel rectangle (x0, y0, x1, y1) that object `obj`'s bounding box projects to, clipped to
/// `canvas`; the whole canvas when a corner is behind the camera.
fn projected_rect(
    world: &World,
    obj: usize,
    cam: &Camera,
    pose: &Pose,
    canvas: (i64, i64, i64, i64),
) -> (i64, i64, i64, i64) {
    let (lo, hi) = world.objects[obj].world_bbox();
    let mut rect = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
    for c in box_corners(lo, hi) {
        let pc = pose.world_to_camera(c);
        match cam.project(pc) {
            Some(p) if pc.z > 1e-3 => {
                rect.0 = rect.0.min(p.x.floor() as i64);
                rect.1 = rect.1.min(p.y.floor() as i64);
                rect.2 = rect.2.max(p.x.ceil() as i64);
                rect.3 = rect.3.max(p.y.ceil() as i64);
            }
            _ => return canvas,
        }
    }
    (
        rect.0.max(canvas.0),
        rect.1.max(canvas.1),
        rect.2.min(canvas.2),
        rect.3.min(canvas.3),
    )
}

/// Area in pixels of object `obj`'s full silhouette in this view: the object alone, nothing in
/// front of it, on a canvas three times the image in each direction (so parts outside the frame
/// count). Only the pixels inside the object's projected bounding box are traced.
pub fn silhouette_area(world: &World, obj: usize, cam: &Camera, pose: &Pose) -> f64 {
    let (w, h) = (cam.width as i64, cam.height as i64);
    let (x0, y0, x1, y1) = projected_rect(world, obj, cam, pose, (-w, -h, 2 * w, 2 * h));
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
