//! Cameras and training views: rays through pixel centres, images downscaled by a box filter on
//! premultiplied colour, and the object's mask as alpha.

use crate::error::{Error, Result};
use crate::scene::io::{find_mask, read_image, read_mask};
use crate::scene::{Camera, Pose, Scene};
use glam::{Mat3, Vec3};
use image::GrayImage;
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;

/// Where the object's mask of each view comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum MaskSource {
    /// The image's own alpha channel (NeRF-synthetic RGBA).
    Alpha,
    /// Every pixel is opaque: a scene field sees everything.
    Opaque,
    /// A folder of masks ([`crate::scene::io::find_mask`]: named like the images).
    Dir(PathBuf),
    /// Each view's `mask_path` in the scene.
    Scene,
    /// Masks in memory, one per scene image (a segmentation just made); `None`: the image's
    /// alpha.
    Images(Arc<Vec<Option<GrayImage>>>),
}

impl MaskSource {
    /// Masks drawn by a segmenter (a folder, the scene's mask files, masks in memory), whose
    /// edges may be off by a pixel or two; an image's alpha and "all opaque" are exact.
    pub fn is_segmented(&self) -> bool {
        matches!(
            self,
            MaskSource::Dir(_) | MaskSource::Scene | MaskSource::Images(_)
        )
    }

    /// Parse the `--masks` option: `alpha`, `scene` (each view's mask_path), `truth:OBJECT` (the
    /// demo scene's `truth/masks/OBJECT/`, found at or above the scene path) or a folder.
    pub fn parse(s: &str, scene: &std::path::Path) -> Result<MaskSource> {
        if s == "alpha" {
            return Ok(MaskSource::Alpha);
        }
        if s == "scene" {
            return Ok(MaskSource::Scene);
        }
        if let Some(obj) = s.strip_prefix("truth:") {
            // The scene may be named by its folder or by a file inside it (transforms.json,
            // sparse/0): look upwards for truth/masks/OBJECT.
            let start = if scene.is_dir() {
                scene.to_path_buf()
            } else {
                scene
                    .parent()
                    .unwrap_or(std::path::Path::new("."))
                    .to_path_buf()
            };
            return start
                .ancestors()
                .map(|dir| dir.join("truth/masks").join(obj))
                .find(|d| d.is_dir())
                .map(MaskSource::Dir)
                .ok_or_else(|| Error::invalid(format!(
                    "--masks truth:{obj}: no truth/masks/{obj}/ folder at or above {} (true masks come with the demo scene: objnerf demo-scene)",
                    start.display()
                )));
        }
        let p = PathBuf::from(s);
        if p.is_dir() {
            Ok(MaskSource::Dir(p))
        } else {
            Err(Error::invalid(format!(
                "--masks {s}: expected 'alpha', 'scene', 'truth:OBJECT' or an existing folder of masks"
            )))
        }
    }

    /// The mask of scene image `index` and the file it came from (`None`: use the image's
    /// alpha; no file: a mask in memory).
    fn mask_of(&self, scene: &Scene, index: usize) -> Result<Option<(GrayImage, Option<PathBuf>)>> {
        let im = &scene.images[index];
        let file = match self {
            MaskSource::Alpha => return Ok(None),
            MaskSource::Opaque => {
                let (w, h) = (scene.camera_of(im).width, scene.camera_of(im).height);
                return Ok(Some((
                    GrayImage::from_pixel(w, h, image::Luma([255])),
                    None,
                )));
            }
            MaskSource::Images(masks) => {
                return Ok(masks.get(index).cloned().flatten().map(|m| (m, None)))
            }
            MaskSource::Dir(dir) => find_mask(dir, &im.name)?,
            MaskSource::Scene => im.mask_path.clone().ok_or_else(|| {
                Error::invalid(format!("view '{}' has no mask_path in the scene", im.name))
            })?,
        };
        Ok(Some((read_mask(&file)?, Some(file))))
    }
}

/// A camera to cast rays from: intrinsics, pose and the pixel grid, with the per-ray constants
/// precomputed. Rendering needs nothing more; a training [`View`] adds the pixels.
#[derive(Clone, Debug)]
pub struct RayCamera {
    pub name: String,
    pub camera: Camera,
    pub pose: Pose,
    pub width: u32,
    pub height: u32,
    rot: Mat3,
    center: Vec3,
    intr: [f32; 4],
    pinhole: bool,
}

impl RayCamera {
    pub fn new(name: String, camera: Camera, pose: Pose) -> RayCamera {
        let (fx, fy) = camera.focal();
        let (cx, cy) = camera.principal_point();
        RayCamera {
            name,
            width: camera.width,
            height: camera.height,
            pinhole: camera.is_pinhole(),
            intr: [fx as f32, fy as f32, cx as f32, cy as f32],
            rot: pose.c2w_rotation().as_mat3(),
            center: pose.center().as_vec3(),
            camera,
            pose,
        }
    }

    /// Every view of `scene` as a camera (no pixels read), downscaled by `factor`.
    pub fn for_scene(scene: &Scene, factor: u32) -> Vec<RayCamera> {
        scene
            .images
            .iter()
            .map(|im| RayCamera::new(im.name.clone(), scene.camera_of(im).binned(factor), im.pose))
            .collect()
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
        self.ray_through(idx, [0.5, 0.5])
    }

    /// The ray through the point `at` of pixel `idx`, in pixels from its top-left corner
    /// (`[0.5, 0.5]`: its centre).
    #[inline]
    pub fn ray_through(&self, idx: u32, at: [f32; 2]) -> (Vec3, Vec3) {
        let col = idx % self.width;
        let row = idx / self.width;
        let dc = if self.pinhole {
            let [fx, fy, cx, cy] = self.intr;
            Vec3::new(
                (col as f32 + at[0] - cx) / fx,
                (row as f32 + at[1] - cy) / fy,
                1.0,
            )
        } else {
            let p = glam::DVec2::new(col as f64 + at[0] as f64, row as f64 + at[1] as f64);
            self.camera.unproject(p).as_vec3()
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

    /// The larger focal length, pixels.
    pub fn focal(&self) -> f32 {
        self.intr[0].max(self.intr[1])
    }
}

/// A pixel in the band along a segmented mask's edge ([`crate::supervision::edge`]): its photo colour and
/// the background estimated behind the object there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgePixel {
    pub px: u32,
    pub photo: [u8; 3],
    pub backdrop: [u8; 3],
}

/// One training view: a camera and its pixels (colour premultiplied by the mask), downscaled.
#[derive(Clone, Debug)]
pub struct View {
    pub cam: RayCamera,
    /// Premultiplied RGB and alpha (the mask), row-major.
    pub rgba: Vec<[u8; 4]>,
    /// Depth targets per pixel as distance along the unit ray (0 = none), when supervised.
    pub depth: Option<Vec<f32>>,
    /// Pixels that carry a loss (None: all): a scene field leaves out what removed objects
    /// covered.
    pub loss_mask: Option<Vec<bool>>,
    /// The band along the mask's edge, sorted by pixel (empty: the mask is taken as exact):
    /// these pixels' colour target is the photo over the background behind them
    /// ([`crate::supervision::edge`]).
    pub edge: Vec<EdgePixel>,
}

impl View {
    /// Grey levels in 0-1, row-major (colour premultiplied by the mask; a scene field's views are
    /// opaque).
    pub fn luma(&self) -> Vec<f32> {
        self.rgba
            .iter()
            .map(|p| (0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32) / 255.0)
            .collect()
    }

    pub fn new(name: String, camera: Camera, pose: Pose, rgba: Vec<[u8; 4]>) -> View {
        View {
            cam: RayCamera::new(name, camera, pose),
            rgba,
            depth: None,
            loss_mask: None,
            edge: Vec::new(),
        }
    }

    /// The edge-band pixel at `px`, if it is one.
    pub fn edge_at(&self, px: u32) -> Option<&EdgePixel> {
        self.edge
            .binary_search_by_key(&px, |e| e.px)
            .ok()
            .map(|i| &self.edge[i])
    }
}

/// A view is its camera plus pixels: everything a camera answers, a view answers.
impl std::ops::Deref for View {
    type Target = RayCamera;
    fn deref(&self) -> &RayCamera {
        &self.cam
    }
}

/// Read every view of `scene`, downscaled by `factor`, with its mask as alpha.
pub fn load_views(scene: &Scene, masks: &MaskSource, factor: u32) -> Result<Vec<View>> {
    (0..scene.images.len())
        .into_par_iter()
        .map(|i| {
            let im = &scene.images[i];
            let cam = scene.camera_of(im);
            let img = read_image(&im.path)?;
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
            if let Some((m, file)) = masks.mask_of(scene, i)? {
                if m.dimensions() != (w, h) {
                    let (mw, mh) = m.dimensions();
                    return Err(Error::format(
                        file.as_deref().unwrap_or(&im.path),
                        format!("mask is {mw}x{mh} but its image {} is {w}x{h}", im.name),
                    ));
                }
                for (p, q) in rgba.pixels_mut().zip(m.pixels()) {
                    p.0[3] = q.0[0];
                }
            }
            if w < factor || h < factor {
                return Err(Error::invalid(format!(
                    "{}: --downscale {factor} leaves no pixels of a {w}x{h} image",
                    im.name
                )));
            }
            // Sizes that the factor does not divide lose their last columns/rows (as nerfstudio
            // floors them); the camera is binned to match.
            let (dw, dh, data) = downscale_premultiplied(&rgba, factor);
            let camera = cam.binned(factor);
            debug_assert_eq!((camera.width, camera.height), (dw, dh));
            Ok(View::new(im.name.clone(), camera, im.pose, data))
        })
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::CameraModel;
    use glam::DVec3;

    fn pose() -> Pose {
        Pose::look_at(DVec3::new(0.3, -2.0, 1.5), DVec3::ZERO, DVec3::Z)
    }

    /// A point of a pixel, as a ray, projects back to that point: pinhole and distorted models.
    #[test]
    fn a_ray_through_a_point_of_a_pixel_projects_back_to_it() {
        let pinhole = Camera::pinhole(40, 30, 35.0, 36.0, 19.5, 15.2);
        let radial = Camera::new(
            CameraModel::SimpleRadial,
            40,
            30,
            vec![35.0, 19.5, 15.2, 0.08],
        )
        .expect("a valid camera");
        for camera in [pinhole, radial] {
            let cam = RayCamera::new("v".into(), camera, pose());
            for (idx, at) in [(0u32, [0.5f32, 0.5]), (37, [0.1, 0.9]), (1199, [0.99, 0.0])] {
                let (o, d) = cam.ray_through(idx, at);
                let (u, v) = cam.project(o + 2.0 * d).expect("in front");
                let (col, row) = ((idx % 40) as f32, (idx / 40) as f32);
                assert!((u - col - at[0]).abs() < 1e-3, "{idx} {at:?}: u {u}");
                assert!((v - row - at[1]).abs() < 1e-3, "{idx} {at:?}: v {v}");
            }
            assert_eq!(cam.ray(37), cam.ray_through(37, [0.5, 0.5]));
        }
    }
}
