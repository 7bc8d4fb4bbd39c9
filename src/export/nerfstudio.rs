//! `objnerf export nerfstudio`: a dataset nerfstudio's `NerfstudioDataParser` loads unchanged.
//!
//! ```text
//! DIR/transforms.json   cameras (nerfstudio's model names, per-frame intrinsics where cameras
//!                       differ), camera-to-world in the OpenGL frame, applied_transform if any
//! DIR/images/...        the views: hard links to the originals (copies across file systems), or
//!                       PNGs resized by --downscale
//! DIR/masks/....png     one channel, 0 = ignore: the object's masks, or their reverse for
//!                       --background, or the scene's own masks
//! DIR/depth/....png     16-bit millimetres, when the scene has depth
//! DIR/sparse_pc.ply     the object's segmented points, the sparse points without the objects'
//!                       (--background), or all of them
//! ```
//!
//! The input is a scene, or a run of `objnerf segment` / `objnerf extract`, whose
//! `segment/report.json` names the scene and says per view whether the object is ok, obstructed
//! or absent: an object export keeps the ok views only.

use crate::error::{Error, Result};
use crate::scene::formats::{intern_camera, nerfstudio};
use crate::scene::io::{read_depth, read_mask, write_depth_png_mm, DepthMap};
use crate::scene::{Camera, ImageView, Point3D, Scene, SceneCamera};
use crate::segment::saved::{RunObject, SegmentRun};
use crate::util::atomic::save_image_atomic;
use crate::util::paths::normalize;
use crate::util::AtomicDir;
use glam::DVec3;
use image::{imageops, DynamicImage, GrayImage};
use rayon::prelude::*;
use std::collections::HashSet;
use std::path::{Component, Path, PathBuf};
use std::time::Instant;

/// What to export and how.
#[derive(Clone, Debug, Default)]
pub struct ExportOptions {
    /// The run's object whose masks to export (default: the run's only object).
    pub object: Option<String>,
    /// Export the scene without the run's objects: reverse masks, every view.
    pub background: bool,
    /// Resize images, masks and depth by this factor (1: link the images as they are).
    pub downscale: u32,
    /// Replace a non-empty output folder.
    pub overwrite: bool,
}

/// A view that is not in the export, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct LeftOut {
    pub view: String,
    /// The segmentation's status for the object: "obstructed", "absent", or "not segmented".
    pub status: String,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct ExportReport {
    pub out: PathBuf,
    pub scene: PathBuf,
    pub frames: usize,
    /// What the masks hold, when there are masks.
    pub masks: Option<String>,
    pub depth: bool,
    pub points: usize,
    pub images_linked: usize,
    pub images_copied: usize,
    pub images_resized: usize,
    pub left_out: Vec<LeftOut>,
    pub seconds: f64,
}

impl ExportReport {
    /// A few lines for a person.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "wrote {}: {} frames from {} (images: {} linked, {} copied, {} resized)\n",
            self.out.display(),
            self.frames,
            self.scene.display(),
            self.images_linked,
            self.images_copied,
            self.images_resized
        );
        let masks = self.masks.as_deref().unwrap_or("none");
        let depth = if self.depth { "16-bit mm" } else { "none" };
        s += &format!("masks: {masks}; depth: {depth}; points: {}\n", self.points);
        for status in ["obstructed", "absent", "not segmented"] {
            let views: Vec<&str> = self
                .left_out
                .iter()
                .filter(|l| l.status == status)
                .map(|l| l.view.as_str())
                .collect();
            if !views.is_empty() {
                s += &format!(
                    "left out {} {status} view(s): {}\n",
                    views.len(),
                    views.join(", ")
                );
            }
        }
        s + &format!("in {:.1} s", self.seconds)
    }
}

/// Where a view's mask comes from.
#[derive(Clone, Debug)]
enum MaskSource {
    None,
    /// Kept where the mask is on (> 127): an object's mask or the scene's own.
    Keep(PathBuf),
    /// Kept where none of these masks is on (none: all kept).
    Reverse(Vec<PathBuf>),
}

struct FramePlan {
    image: usize,
    mask: MaskSource,
}

struct Plan {
    scene: Scene,
    frames: Vec<FramePlan>,
    masks: Option<String>,
    points: Vec<(DVec3, [u8; 3])>,
    left_out: Vec<LeftOut>,
}

/// Export `input` (a scene, or a segment/extract run) as a nerfstudio dataset in `out`.
/// Nothing is left in `out` on an error: it is built beside it and renamed into place.
pub fn export(input: &Path, out: &Path, opts: &ExportOptions) -> Result<ExportReport> {
    let t0 = Instant::now();
    if opts.downscale == 0 {
        return Err(Error::invalid("--downscale must be at least 1"));
    }
    if opts.background && opts.object.is_some() {
        return Err(Error::invalid(
            "give --object or --background, not both: --background leaves out every object of the run",
        ));
    }
    let dest = AtomicDir::new(out, opts.overwrite)?;
    let plan = match SegmentRun::find(input) {
        Some(dir) => plan_run(SegmentRun::open(&dir)?, opts)?,
        None if opts.object.is_some() || opts.background => {
            return Err(Error::invalid(format!(
                "{}: --object and --background need a run of `objnerf segment` or `objnerf extract` (a folder with segment/report.json or report.json and masks/), not a scene",
                input.display()
            )))
        }
        None => plan_scene(Scene::load(input)?),
    };
    if plan.frames.is_empty() {
        return Err(Error::invalid(format!(
            "{}: no view is left to export ({} left out)",
            input.display(),
            plan.left_out.len()
        )));
    }
    check_unique_names(&plan)?;
    let root = dest.path().to_path_buf();
    let written: Vec<FrameOut> = plan
        .frames
        .par_iter()
        .map(|f| write_frame(&plan.scene, f, &root, opts.downscale))
        .collect::<Result<_>>()?;
    let exported = export_scene(&plan, &written, &root);
    nerfstudio::write(&exported, &root.join("transforms.json"))?;
    let count = |p: Placed| written.iter().filter(|f| f.placed == p).count();
    let report = ExportReport {
        out: out.to_path_buf(),
        scene: plan.scene.source.clone(),
        frames: written.len(),
        masks: plan.masks.clone(),
        depth: written.iter().any(|f| f.depth.is_some()),
        points: plan.points.len(),
        images_linked: count(Placed::Linked),
        images_copied: count(Placed::Copied),
        images_resized: count(Placed::Resized),
        left_out: plan.left_out,
        seconds: 0.0,
    };
    dest.commit()?;
    Ok(ExportReport {
        seconds: t0.elapsed().as_secs_f64(),
        ..report
    })
}

/// The objects an export is about: `--object`, all for `--background`, or the run's only one.
fn chosen_objects<'a>(run: &'a SegmentRun, opts: &ExportOptions) -> Result<Vec<&'a RunObject>> {
    match (&opts.object, opts.background) {
        (_, true) => Ok(run.objects.iter().collect()),
        (Some(name), false) => Ok(vec![run.object(name)?]),
        (None, false) if run.objects.len() == 1 => Ok(vec![&run.objects[0]]),
        (None, false) => Err(Error::invalid(format!(
            "{}: the run has {} objects ({}): choose one with --object, or --background",
            run.dir.join("report.json").display(),
            run.objects.len(),
            run.object_names().join(", ")
        ))),
    }
}

fn plan_run(run: SegmentRun, opts: &ExportOptions) -> Result<Plan> {
    let objects = chosen_objects(&run, opts)?;
    let (mut frames, mut left_out) = (Vec::new(), Vec::new());
    for (i, im) in run.scene.images.iter().enumerate() {
        let mask = if opts.background {
            // Every view: the objects' masks where they were segmented (ok or obstructed).
            let masks = objects.iter().map(|o| run.mask_path(&o.name, &im.name));
            MaskSource::Reverse(masks.filter(|p| p.is_file()).collect())
        } else {
            match objects[0].status.get(&im.name).map(String::as_str) {
                Some("ok") => MaskSource::Keep(run.mask_path(&objects[0].name, &im.name)),
                other => {
                    left_out.push(LeftOut {
                        view: im.name.clone(),
                        status: other.unwrap_or("not segmented").to_string(),
                    });
                    continue;
                }
            }
        };
        frames.push(FramePlan { image: i, mask });
    }
    let (masks, points) = if opts.background {
        let names: Vec<String> = objects.iter().map(|o| format!("'{}'", o.name)).collect();
        let mut taken = HashSet::new();
        for o in &objects {
            taken.extend(run.object_points(&o.name)?.iter().map(|(p, _)| f32_key(*p)));
        }
        let rest = run
            .scene
            .points
            .iter()
            .filter(|p| !taken.contains(&f32_key(p.xyz)));
        (
            format!("background (the reverse of {})", names.join(", ")),
            rest.map(|p| (p.xyz, p.rgb)).collect(),
        )
    } else {
        let name = &objects[0].name;
        (format!("object '{name}'"), run.object_points(name)?)
    };
    Ok(Plan {
        scene: run.scene,
        frames,
        masks: Some(masks),
        points,
        left_out,
    })
}

/// A point as the segmented-points PLY stores it (float32), to match the scene's points.
fn f32_key(p: DVec3) -> [u32; 3] {
    p.to_array().map(|v| (v as f32).to_bits())
}

fn plan_scene(scene: Scene) -> Plan {
    let frames = scene
        .images
        .iter()
        .enumerate()
        .map(|(i, im)| FramePlan {
            image: i,
            mask: im
                .mask_path
                .clone()
                .map_or(MaskSource::None, MaskSource::Keep),
        })
        .collect();
    Plan {
        masks: scene
            .images
            .iter()
            .any(|i| i.mask_path.is_some())
            .then(|| "the scene's masks".to_string()),
        points: scene.points.iter().map(|p| (p.xyz, p.rgb)).collect(),
        frames,
        left_out: Vec::new(),
        scene,
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Placed {
    Linked,
    Copied,
    Resized,
}

struct FrameOut {
    image: usize,
    /// Paths relative to the dataset folder.
    file: PathBuf,
    mask: Option<PathBuf>,
    depth: Option<PathBuf>,
    camera: Camera,
    placed: Placed,
}

/// A view's path under the dataset's `images/`, `masks/` and `depth/`: its name, never leading
/// outside the folder, without a first `images/` (a transforms.json's names often start with it).
fn inside(name: &str) -> PathBuf {
    let p = normalize(Path::new(name));
    let p = if p.components().all(|c| matches!(c, Component::Normal(_))) {
        p
    } else {
        PathBuf::from(p.file_name().unwrap_or(p.as_os_str()))
    };
    match p.strip_prefix("images") {
        Ok(rest) if !rest.as_os_str().is_empty() => rest.to_path_buf(),
        _ => p,
    }
}

/// Two views whose names differ only in their extension would share a mask, depth or resized
/// image file.
fn check_unique_names(plan: &Plan) -> Result<()> {
    let mut seen = HashSet::new();
    for f in &plan.frames {
        let name = &plan.scene.images[f.image].name;
        if !seen.insert(inside(name).with_extension("png")) {
            return Err(Error::format(
                &plan.scene.source,
                format!("two views are named '{}' but for their extension: their masks and depth would share a file", Path::new(name).with_extension("").display()),
            ));
        }
    }
    Ok(())
}

fn write_frame(scene: &Scene, plan: &FramePlan, root: &Path, factor: u32) -> Result<FrameOut> {
    let im = &scene.images[plan.image];
    let full = scene.camera_of(im);
    let camera = if factor > 1 {
        full.downscaled(factor)
    } else {
        full.clone()
    };
    let size = (camera.width, camera.height);
    let rel = inside(&im.name);
    let as_png = rel.with_extension("png");
    let (file, placed) = if factor > 1 {
        let img = image::open(&im.path).map_err(|e| Error::image(&im.path, e))?;
        check_size(&im.path, (img.width(), img.height()), full)?;
        let small = resize_view(&img, size);
        let file = Path::new("images").join(&as_png);
        save_image_atomic(&root.join(&file), &small)?;
        (file, Placed::Resized)
    } else {
        check_size(&im.path, crate::scene::formats::image_size(&im.path)?, full)?;
        let file = Path::new("images").join(&rel);
        (file.clone(), place_file(&im.path, &root.join(&file))?)
    };
    let mask = match mask_image(&plan.mask, full, size)? {
        Some(m) => {
            let file = Path::new("masks").join(&as_png);
            save_image_atomic(&root.join(&file), &DynamicImage::ImageLuma8(m))?;
            Some(file)
        }
        None => None,
    };
    let depth = match &im.depth_path {
        Some(src) => {
            let d = read_depth(src, scene.depth_scale)?;
            check_size(src, (d.width, d.height), full)?;
            let file = Path::new("depth").join(&as_png);
            write_depth_png_mm(&root.join(&file), &resample_nearest(&d, size))?;
            Some(file)
        }
        None => None,
    };
    Ok(FrameOut {
        image: plan.image,
        file,
        mask,
        depth,
        camera,
        placed,
    })
}

/// A view resized; with alpha, resized premultiplied so that the colour of transparent pixels
/// (black in NeRF-synthetic files) does not darken the object's edges.
fn resize_view(img: &DynamicImage, (w, h): (u32, u32)) -> DynamicImage {
    if !img.color().has_alpha() {
        return img.resize_exact(w, h, imageops::FilterType::Triangle);
    }
    let mut rgba = img.to_rgba32f();
    for p in rgba.pixels_mut() {
        let a = p.0[3];
        p.0[..3].iter_mut().for_each(|c| *c *= a);
    }
    let mut small = imageops::resize(&rgba, w, h, imageops::FilterType::Triangle);
    for p in small.pixels_mut() {
        let a = p.0[3];
        p.0[..3]
            .iter_mut()
            .for_each(|c| *c = if a > 0.0 { *c / a } else { 0.0 });
    }
    DynamicImage::ImageRgba8(DynamicImage::ImageRgba32F(small).to_rgba8())
}

fn check_size(path: &Path, got: (u32, u32), camera: &Camera) -> Result<()> {
    if got != (camera.width, camera.height) {
        return Err(Error::format(
            path,
            format!(
                "is {}x{} but its camera says {}x{}",
                got.0, got.1, camera.width, camera.height
            ),
        ));
    }
    Ok(())
}

/// Hard-link `src` (links resolved) to `dest`, or copy it where a link cannot be made (another
/// file system).
fn place_file(src: &Path, dest: &Path) -> Result<Placed> {
    let src = src.canonicalize().map_err(|e| Error::io(src, e))?;
    if let Some(dir) = dest.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    if std::fs::hard_link(&src, dest).is_ok() {
        return Ok(Placed::Linked);
    }
    std::fs::copy(&src, dest).map_err(|e| Error::io(dest, e))?;
    Ok(Placed::Copied)
}

/// The nerfstudio mask (255 = use, 0 = ignore) at `size`, from masks at the camera's full size.
fn mask_image(source: &MaskSource, full: &Camera, size: (u32, u32)) -> Result<Option<GrayImage>> {
    let read = |p: &PathBuf| -> Result<GrayImage> {
        let m = read_mask(p)?;
        check_size(p, m.dimensions(), full)?;
        Ok(m)
    };
    let keep = match source {
        MaskSource::None => return Ok(None),
        MaskSource::Keep(p) => {
            let mut m = read(p)?;
            m.pixels_mut()
                .for_each(|v| v.0[0] = if v.0[0] > 127 { 255 } else { 0 });
            m
        }
        MaskSource::Reverse(objects) => {
            let mut keep = GrayImage::from_pixel(full.width, full.height, image::Luma([255]));
            for p in objects {
                for (k, v) in keep.pixels_mut().zip(read(p)?.pixels()) {
                    if v.0[0] > 127 {
                        k.0[0] = 0;
                    }
                }
            }
            keep
        }
    };
    if keep.dimensions() == size {
        return Ok(Some(keep));
    }
    let mut small = imageops::resize(&keep, size.0, size.1, imageops::FilterType::Triangle);
    small
        .pixels_mut()
        .for_each(|v| v.0[0] = if v.0[0] > 127 { 255 } else { 0 });
    Ok(Some(small))
}

/// Depth at `size` by nearest sampling (as nerfstudio resizes depth): averaging across an edge
/// would invent depths that are on neither surface.
fn resample_nearest(d: &DepthMap, size: (u32, u32)) -> DepthMap {
    if (d.width, d.height) == size {
        return d.clone();
    }
    let (w, h) = size;
    let src = |i: u32, n: u32, m: u32| (((i as f64 + 0.5) * m as f64 / n as f64) as u32).min(m - 1);
    let mut metres = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        let sy = src(y, h, d.height);
        for x in 0..w {
            metres.push(d.metres[(sy * d.width + src(x, w, d.width)) as usize]);
        }
    }
    DepthMap {
        width: w,
        height: h,
        metres,
    }
}

/// The exported dataset as a scene, its files under `root`, for the transforms.json writer.
fn export_scene(plan: &Plan, written: &[FrameOut], root: &Path) -> Scene {
    let mut cameras: Vec<SceneCamera> = Vec::new();
    let images = written
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let src = &plan.scene.images[f.image];
            ImageView {
                id: i as u32 + 1,
                name: f.file.to_string_lossy().replace('\\', "/"),
                path: root.join(&f.file),
                camera: intern_camera(&mut cameras, f.camera.clone()),
                pose: src.pose,
                mask_path: f.mask.as_ref().map(|m| root.join(m)),
                depth_path: f.depth.as_ref().map(|d| root.join(d)),
                features: Vec::new(),
                depth_bounds: None,
            }
        })
        .collect();
    let points = plan
        .points
        .iter()
        .enumerate()
        .map(|(i, &(xyz, rgb))| Point3D {
            id: i as u64 + 1,
            xyz,
            rgb,
            error: -1.0,
            track: Vec::new(),
        })
        .collect();
    Scene {
        source: root.join("transforms.json"),
        format: crate::scene::SourceFormat::Nerfstudio,
        cameras,
        images,
        points,
        depth_scale: 1000.0,
        applied_transform: plan.scene.applied_transform,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transparent_pixels_do_not_darken_edges() {
        // Left half opaque red, right half transparent black: the edge pixel of the half-size
        // image is half covered and red, not dark red.
        let img = image::RgbaImage::from_fn(8, 2, |x, _| {
            image::Rgba(if x < 3 {
                [255, 0, 0, 255]
            } else {
                [0, 0, 0, 0]
            })
        });
        let small = resize_view(&DynamicImage::ImageRgba8(img), (4, 1)).to_rgba8();
        let edge = small.get_pixel(1, 0).0;
        assert!(edge[3] > 60 && edge[3] < 250, "{edge:?}");
        assert_eq!(&edge[..3], &[255, 0, 0]);
    }

    #[test]
    fn names_stay_inside_the_dataset() {
        assert_eq!(inside("images/a.jpg"), Path::new("a.jpg"));
        assert_eq!(inside("train/r_0.png"), Path::new("train/r_0.png"));
        assert_eq!(inside("../../etc/x.png"), Path::new("x.png"));
        assert_eq!(inside("/abs/y.png"), Path::new("y.png"));
    }
}
