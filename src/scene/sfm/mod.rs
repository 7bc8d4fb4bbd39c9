//! `objnerf sfm`: give a scene 2D-3D feature tracks with the real COLMAP (Debian package
//! `colmap`, CPU). Two modes:
//! - **full reconstruction** from an images folder (features, exhaustive matching, mapper), and
//! - **triangulation with known poses** for a posed scene without tracks (e.g. NeRF-synthetic),
//!   which keeps the scene's cameras and world frame and only adds points and tracks.
//!
//! Images may be downscaled before feature extraction; the model is scaled back to the full image
//! size afterwards, so its intrinsics and 2D features always match the original images.

mod colmap_run;
mod commands;
mod database;
mod reconstruct;
mod triangulate;
mod video;

pub use colmap_run::{colmap_program, Colmap, ColmapVersion};
pub use reconstruct::reconstruct;
pub use triangulate::{pairs_from_poses, triangulate};
pub use video::{reconstruct_video, sharpest_per_window, sharpness, take_frames};
pub use video::{ChosenFrame, VideoFrames, VideoReport};

use crate::error::{Error, Result};
use crate::scene::formats::colmap::{self, ModelFormat};
use crate::scene::io::{is_image, read_image};
use crate::scene::{Scene, SourceFormat};
use crate::util::AtomicDir;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct SfmOptions {
    /// Downscale images by this factor before feature extraction (1 = full size).
    pub downscale: u32,
    /// COLMAP camera model for full reconstruction.
    pub camera_model: String,
    /// Most SIFT features per image.
    pub max_features: u32,
    /// "auto" (posed scenes: pairs chosen from the poses; otherwise exhaustive), "exhaustive",
    /// "sequential" or "pairs" (posed scenes only).
    pub matcher: String,
    /// With pose-chosen pairs: match each image with this many neighbours.
    pub pair_neighbours: usize,
    /// COLMAP's threads (-1 = all cores).
    pub threads: i32,
    /// From a video: keep the sharpest frame of each of this many equal windows.
    pub video_frames: usize,
    /// Replace the output folder if it exists.
    pub overwrite: bool,
}

impl Default for SfmOptions {
    fn default() -> Self {
        SfmOptions {
            downscale: 1,
            camera_model: "SIMPLE_RADIAL".into(),
            max_features: 8192,
            matcher: "auto".into(),
            pair_neighbours: 12,
            threads: -1,
            // nerfstudio's `ns-process-data video --num-frames-target` default.
            video_frames: 300,
            overwrite: false,
        }
    }
}

/// What a run did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SfmReport {
    pub mode: &'static str,
    pub num_images: usize,
    pub num_registered: usize,
    pub num_points: usize,
    pub mean_track_length: f64,
    pub seconds: f64,
    /// The time each stage took, in order (COLMAP's programs: features, matching, mapping or
    /// triangulation).
    pub stages: Vec<StageTime>,
    pub model_dir: PathBuf,
    /// COLMAP's database beside the model (image names and sizes as the model's), so that the
    /// run opens in COLMAP's GUI.
    pub database: PathBuf,
    /// The COLMAP that ran.
    pub colmap_version: String,
    /// Image pairs matched when they were chosen from the poses (triangulation).
    pub matched_pairs: Option<usize>,
    /// The self-checks of the model COLMAP made ([`crate::scene::capture_checks`]).
    pub warnings: Vec<crate::util::Warning>,
    /// From a video: what was taken from it.
    pub video: Option<VideoReport>,
}

/// How long one stage of a run took.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StageTime {
    pub stage: String,
    pub seconds: f64,
}

/// What `objnerf sfm` was given.
pub enum SfmInput {
    /// A folder of images without poses: full reconstruction.
    Images(PathBuf),
    /// A posed scene: triangulation with its poses.
    Posed(Scene),
    /// A video: frames chosen by sharpness, then full reconstruction.
    Video(PathBuf),
}

fn has_images(dir: &Path) -> bool {
    std::fs::read_dir(dir)
        .map(|d| d.flatten().any(|e| is_image(&e.path())))
        .unwrap_or(false)
}

/// A posed scene if `input` reads as one (and `force_reconstruct` is off), a video if it is a
/// file that is no scene file (ffmpeg says whether it reads it), else a folder of images.
pub fn resolve_input(input: &Path, force_reconstruct: bool) -> Result<SfmInput> {
    if input.is_file() && !is_scene_file(input) && !is_image(input) {
        return Ok(SfmInput::Video(input.to_path_buf()));
    }
    match Scene::load(input) {
        Ok(scene) if !force_reconstruct => Ok(SfmInput::Posed(scene)),
        other => {
            for dir in [input.to_path_buf(), input.join("images")] {
                if dir.is_dir() && has_images(&dir) {
                    return Ok(SfmInput::Images(dir));
                }
            }
            match other {
                Err(e) => Err(e),
                Ok(_) => Err(Error::format(input, "no images folder to reconstruct from")),
            }
        }
    }
}

/// Files [`Scene::load`] reads by their name.
fn is_scene_file(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    name.ends_with(".json") || name == "poses_bounds.npy" || name.starts_with("cameras.")
}

/// One run's state: the COLMAP that runs, a scratch folder for its database and the staged
/// images (removed when dropped), and the output folder being built (locked; renamed into place
/// at the end, removed if the run fails).
struct Run {
    colmap: colmap_run::Colmap,
    work: tempfile::TempDir,
    dest: AtomicDir,
    start: Instant,
    stages: Vec<StageTime>,
}

impl Run {
    /// Find COLMAP, claim `out` (refused before minutes of work if it is not empty and
    /// `--overwrite` is off), make the scratch folder.
    fn begin(out: &Path, opts: &SfmOptions) -> Result<Run> {
        let start = Instant::now();
        let colmap = colmap_run::Colmap::find()?;
        let dest = AtomicDir::new(out, opts.overwrite)?;
        let work = tempfile::Builder::new()
            .prefix("objnerf-sfm-")
            .tempdir()
            .map_err(|e| Error::io(std::env::temp_dir(), e))?;
        Ok(Run {
            colmap,
            work,
            dest,
            start,
            stages: Vec::new(),
        })
    }

    fn work(&self) -> &Path {
        self.work.path()
    }
}

/// The images COLMAP saw: `names[k]` in `work/images` is the image `paths[k]`, called
/// `originals[k]` in the model.
struct Staged {
    names: Vec<String>,
    originals: Vec<String>,
    paths: Vec<PathBuf>,
}

/// Where the output's `images/` comes from.
enum ImagesOut<'a> {
    /// A link to the folder the images are in.
    Link(&'a Path),
    /// Already written into the output folder.
    InPlace,
}

/// Prepare `work/images/NNNNN.ext`: symlinks to the originals, or downscaled copies. Sorted names
/// make COLMAP's image ids follow the scene's order.
fn stage_images(paths: &[PathBuf], work: &Path, downscale: u32) -> Result<Vec<String>> {
    let dir = work.join("images");
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let mut names = Vec::with_capacity(paths.len());
    for (i, p) in paths.iter().enumerate() {
        let ext = p
            .extension()
            .map(|e| e.to_string_lossy().to_lowercase())
            .unwrap_or_else(|| "png".into());
        let name = if downscale > 1 {
            format!("{i:05}.png")
        } else {
            format!("{i:05}.{ext}")
        };
        let dst = dir.join(&name);
        if downscale > 1 {
            let img = read_image(p)?;
            let (w, h) = (img.width(), img.height());
            let (nw, nh) = (
                ((w as f64 / downscale as f64).round() as u32).max(1),
                ((h as f64 / downscale as f64).round() as u32).max(1),
            );
            let small = img.resize_exact(nw, nh, image::imageops::FilterType::Triangle);
            small.save(&dst).map_err(|e| Error::image(&dst, e))?;
        } else {
            let abs = std::fs::canonicalize(p).map_err(|e| Error::io(p, e))?;
            std::os::unix::fs::symlink(&abs, &dst).map_err(|e| Error::io(&dst, e))?;
        }
        names.push(name);
    }
    Ok(names)
}

/// The folder all the scene's images sit under (their longest common ancestor).
fn image_root(scene: &Scene) -> Result<PathBuf> {
    let mut root: Option<PathBuf> = None;
    for im in &scene.images {
        let abs = std::fs::canonicalize(&im.path).map_err(|e| Error::io(&im.path, e))?;
        let parent = abs.parent().unwrap_or(Path::new("/")).to_path_buf();
        root = Some(match root {
            None => parent,
            Some(r) => {
                let mut r = r;
                while !parent.starts_with(&r) {
                    r = r.parent().unwrap_or(Path::new("/")).to_path_buf();
                }
                r
            }
        });
    }
    root.ok_or_else(|| Error::format(&scene.source, "the scene has no images"))
}

fn relative_name(path: &Path, root: &Path) -> String {
    let abs = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    abs.strip_prefix(root)
        .unwrap_or(&abs)
        .to_string_lossy()
        .to_string()
}

/// Give the model's images their original names and paths, and scale cameras and features
/// from the staged (downscaled) size back to the original image size.
fn rename_and_rescale(model: &mut Scene, staged: &Staged) -> Result<()> {
    let mut scale_for_camera: Vec<Option<(u32, u32)>> = vec![None; model.cameras.len()];
    for im in &mut model.images {
        let k = staged
            .names
            .iter()
            .position(|n| *n == im.name)
            .ok_or_else(|| {
                Error::external(
                    "colmap",
                    format!("unknown image '{}' in its output", im.name),
                )
            })?;
        im.name = staged.originals[k].clone();
        im.path = staged.paths[k].clone();
        let (w, h) = image_size(&staged.paths[k])?;
        let cam = &model.cameras[im.camera].camera;
        let (sx, sy) = (w as f64 / cam.width as f64, h as f64 / cam.height as f64);
        for f in &mut im.features {
            f.xy.x *= sx;
            f.xy.y *= sy;
        }
        scale_for_camera[im.camera] = Some((w, h));
    }
    for (c, size) in model.cameras.iter_mut().zip(scale_for_camera) {
        if let Some((w, h)) = size {
            c.camera = c.camera.resized(w, h);
        }
    }
    Ok(())
}

fn image_size(path: &Path) -> Result<(u32, u32)> {
    image::image_dimensions(path).map_err(|e| Error::image(path, e))
}

/// Write the model (renamed and rescaled: [`rename_and_rescale`]) and COLMAP's database into the
/// output folder, link or keep its images, and move it into place.
fn finish(
    mut run: Run,
    mut model: Scene,
    staged: &Staged,
    images: ImagesOut,
    mode: &'static str,
    steps: Vec<StageTime>,
) -> Result<SfmReport> {
    let dest = run.dest.path().to_path_buf();
    colmap::write_model(&model, &dest.join("sparse/0"), ModelFormat::Binary)?;
    if let ImagesOut::Link(root) = images {
        let abs_root = std::fs::canonicalize(root).map_err(|e| Error::io(root, e))?;
        std::os::unix::fs::symlink(&abs_root, dest.join("images"))
            .map_err(|e| Error::io(dest.join("images"), e))?;
    }
    let full_sizes = staged
        .paths
        .iter()
        .map(|p| image_size(p))
        .collect::<Result<Vec<_>>>()?;
    database::keep_database(
        &run.work().join("database.db"),
        &dest.join("database.db"),
        &staged.names,
        &staged.originals,
        &full_sizes,
    )?;
    let _ = std::fs::copy(run.work().join("colmap.log"), dest.join("colmap.log"));
    run.stages.extend(steps);
    let out = run.dest.commit()?;
    model.source = out.join("sparse/0");
    model.format = SourceFormat::ColmapBinary;
    let num_images = staged.names.len();
    let obs: usize = model.points.iter().map(|p| p.track.len()).sum();
    let mut warnings: Vec<_> =
        crate::scene::capture_checks::check_registration(num_images, model.images.len())
            .into_iter()
            .collect();
    warnings.extend(crate::scene::capture_checks::check_scene(&model));
    Ok(SfmReport {
        mode,
        num_images,
        num_registered: model.images.len(),
        num_points: model.points.len(),
        mean_track_length: if model.points.is_empty() {
            0.0
        } else {
            obs as f64 / model.points.len() as f64
        },
        seconds: run.start.elapsed().as_secs_f64(),
        stages: run.stages,
        model_dir: out.join("sparse/0"),
        database: out.join("database.db"),
        colmap_version: run.colmap.version.to_string(),
        matched_pairs: None,
        warnings,
        video: None,
    })
}
