//! Training views and rays: images (downscaled by a box filter) with the object's mask as alpha,
//! rays through pixel centres, the object's box from the masks' visual hull, the grid resolution
//! from the pixel footprint, and the pruning of rays that miss the box.

use super::render::ray_box;
use crate::error::{Error, Result};
use crate::scene::{Camera, Pose, Scene};
use glam::{Mat3, Vec3};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Where the object's mask of each view comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum MaskSource {
    /// The image's own alpha channel (NeRF-synthetic RGBA).
    Alpha,
    /// A folder of single-channel masks named like the images (black = not the object).
    Dir(PathBuf),
    /// Each view's `mask_path` in the scene.
    Scene,
}

/// One view, downscaled, with its colour premultiplied by the mask.
#[derive(Clone, Debug)]
pub struct View {
    pub name: String,
    pub camera: Camera,
    pub pose: Pose,
    pub width: u32,
    pub height: u32,
    /// Premultiplied RGB and alpha (the mask), row-major.
    pub rgba: Vec<[u8; 4]>,
    /// Depth targets per pixel as distance along the unit ray (0 = none), when supervised.
    pub depth: Option<Vec<f32>>,
    rot: Mat3,
    center: Vec3,
    intr: [f32; 4],
    pinhole: bool,
}

impl View {
    pub fn new(name: String, camera: Camera, pose: Pose, rgba: Vec<[u8; 4]>) -> View {
        let (fx, fy) = camera.focal();
        let (cx, cy) = camera.principal_point();
        View {
            name,
            width: camera.width,
            height: camera.height,
            pinhole: camera.is_pinhole(),
            intr: [fx as f32, fy as f32, cx as f32, cy as f32],
            rot: pose.c2w_rotation().as_mat3(),
            center: pose.center().as_vec3(),
            camera,
            pose,
            rgba,
            depth: None,
        }
    }

    /// The length of the camera-frame ray through pixel `idx` with z = 1: a z-depth times this
    /// is the distance along the unit ray.
    pub fn ray_scale(&self, idx: u32) -> f32 {
        let (_, d) = self.ray(idx);
        let z = (self.rot.transpose() * d).z;
        1.0 / z.max(1e-6)
    }

    /// World origin and unit direction of the ray through the centre of pixel `idx` (row-major).
    #[inline]
    pub fn ray(&self, idx: u32) -> (Vec3, Vec3) {
        let col = idx % self.width;
        let row = idx / self.width;
        let dc = if self.pinhole {
            let [fx, fy, cx, cy] = self.intr;
            Vec3::new(
                (col as f32 + 0.5 - cx) / fx,
                (row as f32 + 0.5 - cy) / fy,
                1.0,
            )
        } else {
            self.camera.pixel_center_ray(col, row).as_vec3()
        };
        (self.center, (self.rot * dc).normalize())
    }

    /// Pixel position of a world point, if in front of the camera.
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let q = self.rot.transpose() * (p - self.center);
        if q.z <= 1e-6 {
            return None;
        }
        if self.pinhole {
            let [fx, fy, cx, cy] = self.intr;
            Some((fx * q.x / q.z + cx, fy * q.y / q.z + cy))
        } else {
            self.camera
                .project(q.as_dvec3())
                .map(|p| (p.x as f32, p.y as f32))
        }
    }

    pub fn center(&self) -> Vec3 {
        self.center
    }
}

/// Read every view of `scene` (or those in `only`), downscaled by `factor`, with masks.
pub fn load_views(scene: &Scene, masks: &MaskSource, factor: u32) -> Result<Vec<View>> {
    scene
        .images
        .par_iter()
        .map(|im| {
            let cam = scene.camera_of(im);
            let img = image::open(&im.path).map_err(|e| Error::image(&im.path, e))?;
            let (w, h) = (img.width(), img.height());
            if (w, h) != (cam.width, cam.height) {
                return Err(Error::format(
                    &im.path,
                    format!(
                        "image is {w}x{h} but its camera says {}x{}",
                        cam.width, cam.height
                    ),
                ));
            }
            let mut rgba = img.to_rgba8();
            let mask_file = match masks {
                MaskSource::Alpha => None,
                MaskSource::Dir(dir) => Some(find_mask(dir, &im.name)?),
                MaskSource::Scene => Some(im.mask_path.clone().ok_or_else(|| {
                    Error::invalid(format!("view '{}' has no mask_path in the scene", im.name))
                })?),
            };
            if let Some(mp) = mask_file {
                let m = image::open(&mp).map_err(|e| Error::image(&mp, e))?.to_luma8();
                if m.dimensions() != (w, h) {
                    return Err(Error::format(
                        &mp,
                        format!("mask is {:?} but its image is {w}x{h}", m.dimensions()),
                    ));
                }
                for (p, q) in rgba.pixels_mut().zip(m.pixels()) {
                    p.0[3] = q.0[0];
                }
            }
            let (dw, dh, data) = downscale_premultiplied(&rgba, factor);
            let camera = if factor > 1 {
                cam.downscaled(factor)
            } else {
                cam.clone()
            };
            if (camera.width, camera.height) != (dw, dh) {
                return Err(Error::invalid(format!(
                    "{}: downscaling by {factor} gives {dw}x{dh} pixels but the camera {}x{}; use a factor that divides the image size",
                    im.name, camera.width, camera.height
                )));
            }
            Ok(View::new(im.name.clone(), camera, im.pose, data))
        })
        .collect()
}

fn find_mask(dir: &Path, name: &str) -> Result<PathBuf> {
    let p = Path::new(name);
    let stem = p.file_stem().map(|s| s.to_string_lossy().to_string());
    let mut cands = vec![dir.join(name)];
    if let Some(fname) = p.file_name() {
        cands.push(dir.join(fname));
    }
    if let Some(s) = &stem {
        for ext in ["png", "jpg", "jpeg"] {
            cands.push(dir.join(format!("{s}.{ext}")));
        }
    }
    cands
        .into_iter()
        .find(|c| c.is_file())
        .ok_or_else(|| Error::format(dir, format!("no mask for view '{name}' in this folder")))
}

/// Box-filter downscale by an integer factor on premultiplied colour (so the object's colour does
/// not bleed into the background at its edges). Returns premultiplied RGBA8.
pub fn downscale_premultiplied(img: &image::RgbaImage, f: u32) -> (u32, u32, Vec<[u8; 4]>) {
    let f = f.max(1);
    let (w, h) = img.dimensions();
    let (dw, dh) = (w / f, h / f);
    let n = (f * f) as f32;
    let mut out = Vec::with_capacity((dw * dh) as usize);
    for y in 0..dh {
        for x in 0..dw {
            let mut acc = [0f32; 4];
            for yy in 0..f {
                for xx in 0..f {
                    let p = img.get_pixel(x * f + xx, y * f + yy).0;
                    let a = p[3] as f32 / 255.0;
                    for c in 0..3 {
                        acc[c] += p[c] as f32 * a;
                    }
                    acc[3] += p[3] as f32;
                }
            }
            out.push(acc.map(|v| (v / n).round().clamp(0.0, 255.0) as u8));
        }
    }
    (dw, dh, out)
}

/// A boolean "may be the object" image per view: mask > 0, dilated by `radius` pixels.
fn dilated_mask(v: &View, radius: i32) -> Vec<bool> {
    let (w, h) = (v.width as i32, v.height as i32);
    let m: Vec<bool> = v.rgba.iter().map(|p| p[3] > 0).collect();
    let mut tmp = vec![false; m.len()];
    for y in 0..h {
        for x in 0..w {
            let lo = (x - radius).max(0);
            let hi = (x + radius).min(w - 1);
            tmp[(y * w + x) as usize] = (lo..=hi).any(|xx| m[(y * w + xx) as usize]);
        }
    }
    let mut out = vec![false; m.len()];
    for y in 0..h {
        for x in 0..w {
            let lo = (y - radius).max(0);
            let hi = (y + radius).min(h - 1);
            out[(y * w + x) as usize] = (lo..=hi).any(|yy| tmp[(yy * w + x) as usize]);
        }
    }
    out
}

/// Fraction of the views seeing a point that may show it outside their mask before the hull
/// drops it. The demo scene's mug is partly hidden in about a tenth of the views; a strict
/// intersection cut off its base.
pub const HULL_TOLERANCE: f32 = 0.2;

/// The masks' visual hull sampled at cell centres of a `dims` grid over [lo, hi]: a cell is kept
/// when at most [`HULL_TOLERANCE`] of the views that see its centre see it on the background and
/// at least half the views see it at all.
/// Masks are dilated by the cell's pixel footprint so thin parts are not carved.
pub fn visual_hull(views: &[View], lo: Vec3, hi: Vec3, dims: [usize; 3]) -> Vec<bool> {
    let cell = (hi - lo) / Vec3::new(dims[0] as f32, dims[1] as f32, dims[2] as f32);
    let mid = 0.5 * (lo + hi);
    let masks: Vec<(Vec<bool>, i32)> = views
        .par_iter()
        .map(|v| {
            let dist = (v.center - mid).length().max(1e-6);
            let fx = v.intr[0].max(v.intr[1]);
            let r = (0.87 * cell.max_element() * fx / dist).ceil() as i32 + 1;
            (dilated_mask(v, r.min(64)), r)
        })
        .collect();
    // A point seen by few views is barely constrained (a long cone behind each silhouette):
    // require half of them.
    let min_seen = views.len().div_ceil(2).max(views.len().min(2));
    let plane = dims[0] * dims[1];
    let mut keep = vec![false; plane * dims[2]];
    keep.par_chunks_mut(plane)
        .enumerate()
        .for_each(|(z, slab)| {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let p = lo + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * cell;
                    let mut seen = 0usize;
                    let mut outside = 0usize;
                    for (v, (m, _)) in views.iter().zip(&masks) {
                        let Some((u, w)) = v.project(p) else { continue };
                        if u < 0.0 || w < 0.0 || u >= v.width as f32 || w >= v.height as f32 {
                            continue;
                        }
                        seen += 1;
                        if !m[(w as u32 * v.width + u as u32) as usize] {
                            outside += 1;
                        }
                    }
                    // Voting, not a strict intersection: masks of the visible part would carve
                    // away what an occluder hides in a few views, and one bad mask would cut
                    // the object.
                    let allowed = (seen as f32 * HULL_TOLERANCE).floor() as usize;
                    slab[x + dims[0] * y] = outside <= allowed && seen >= min_seen;
                }
            }
        });
    keep
}

/// The object's box from the visual hull: a coarse pass over the cube that holds the cameras,
/// then a finer pass over what it found, padded by `pad` (a fraction of the size) on each side.
pub fn hull_box(views: &[View], pad: f32) -> Result<(Vec3, Vec3)> {
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for v in views {
        lo = lo.min(v.center);
        hi = hi.max(v.center);
    }
    let c = 0.5 * (lo + hi);
    let r = (hi - lo).max_element().max(1e-3) * 0.5;
    let (mut lo, mut hi) = (c - Vec3::splat(r), c + Vec3::splat(r));
    for res in [96usize, 128] {
        let dims = [res; 3];
        let keep = visual_hull(views, lo, hi, dims);
        let cell = (hi - lo) / res as f32;
        let (mut a, mut b) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for (i, &k) in keep.iter().enumerate() {
            if k {
                let x = i % res;
                let y = (i / res) % res;
                let z = i / (res * res);
                let p = lo + Vec3::new(x as f32, y as f32, z as f32) * cell;
                a = a.min(p);
                b = b.max(p + cell);
            }
        }
        if a.x > b.x {
            return Err(Error::invalid(
                "the masks' visual hull is empty: no point is inside the mask of every view that sees it (check the masks and poses)",
            ));
        }
        // Pad by a cell: the hull was tested at cell centres.
        lo = a - cell;
        hi = b + cell;
    }
    let e = (hi - lo) * pad;
    Ok((lo - e, hi + e))
}

/// Voxel size for about one voxel per pixel at the median viewing distance (`per_pixel` voxels
/// per pixel footprint), made coarser if the grid with its optimiser state (`bytes_per_vertex`)
/// would exceed `budget` bytes. Returns (voxel, why) where `why` explains the choice.
pub fn choose_voxel(
    views: &[View],
    lo: Vec3,
    hi: Vec3,
    per_pixel: f32,
    bytes_per_vertex: usize,
    budget: usize,
) -> (f32, String) {
    let mid = 0.5 * (lo + hi);
    let mut foot: Vec<(f32, f32, f32)> = views
        .iter()
        .map(|v| {
            let (dist, focal) = ((v.center - mid).length(), v.intr[0].max(v.intr[1]));
            (dist / focal, dist, focal)
        })
        .collect();
    foot.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (median, dist, focal) = foot[foot.len() / 2];
    let mut voxel = median / per_pixel;
    let e = hi - lo;
    let count = |vx: f32| -> usize {
        [e.x, e.y, e.z]
            .iter()
            .map(|l| (l / vx).ceil() as usize + 1)
            .product()
    };
    let mut why = format!(
        "one pixel at the median camera distance {dist:.3} (focal {focal:.0} px) covers {median:.5} world units; {per_pixel} voxel(s) per pixel -> voxel {voxel:.5}"
    );
    let want = count(voxel) * bytes_per_vertex;
    if want > budget {
        voxel *= (want as f32 / budget as f32).cbrt();
        while count(voxel) * bytes_per_vertex > budget {
            voxel *= 1.02;
        }
        why += &format!(
            ", enlarged to {voxel:.5} to fit the {} MiB budget",
            budget >> 20
        );
    }
    (voxel, why)
}

/// Training rays: (view, pixel) pairs whose ray meets the box.
#[derive(Clone, Debug)]
pub struct RaySet {
    pub rays: Vec<(u32, u32)>,
    pub total: usize,
    /// Kept rays that carry a depth target (drawn in addition to the colour batch, since sparse
    /// depth pixels are too rare to be hit by uniform sampling).
    pub depth_rays: Vec<(u32, u32)>,
}

impl RaySet {
    pub fn build(views: &[View], lo: Vec3, hi: Vec3) -> RaySet {
        let per: Vec<Vec<(u32, u32)>> = views
            .par_iter()
            .enumerate()
            .map(|(vi, v)| {
                (0..v.width * v.height)
                    .filter(|&p| {
                        let (o, d) = v.ray(p);
                        ray_box(o, d, lo, hi).is_some()
                    })
                    .map(|p| (vi as u32, p))
                    .collect()
            })
            .collect();
        let total = views.iter().map(|v| (v.width * v.height) as usize).sum();
        let rays: Vec<(u32, u32)> = per.into_iter().flatten().collect();
        let depth_rays = rays
            .iter()
            .copied()
            .filter(|&(vi, p)| {
                views[vi as usize]
                    .depth
                    .as_ref()
                    .is_some_and(|d| d[p as usize] > 0.0)
            })
            .collect();
        RaySet {
            rays,
            total,
            depth_rays,
        }
    }

    /// Fraction of all pixels whose rays were pruned.
    pub fn pruned_fraction(&self) -> f64 {
        1.0 - self.rays.len() as f64 / self.total.max(1) as f64
    }
}
