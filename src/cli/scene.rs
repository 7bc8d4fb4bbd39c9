//! `objnerf info`, `objnerf sfm` and `objnerf demo-scene`: scenes in.

use super::print_json;
use crate::cli::progress_bars::Bars;
use clap::Args;
use objnerf::demo::edit_truth::write_edit_truth;
use objnerf::demo::{parse_size, write_demo_scene, DemoLayout, DemoOptions, Variant};
use objnerf::edit::{load_edit, EditFile};
use objnerf::scene::camera_path::{CameraPath, PathFrame};
use objnerf::scene::info::scene_info;
use objnerf::scene::sfm::{self, SfmInput, SfmOptions};
use objnerf::{Error, Result, Scene};
use std::path::PathBuf;

#[derive(Args)]
pub struct InfoCmd {
    /// A COLMAP model folder, transforms.json, LLFF or RGB-D folder.
    scene: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

impl InfoCmd {
    pub fn run(self) -> Result<()> {
        let info = scene_info(&Scene::load(&self.scene)?);
        if self.json {
            print_json(&info);
        } else {
            print!("{}", info.to_text());
        }
        Ok(())
    }
}

#[derive(Args)]
pub struct SfmCmd {
    /// A folder of images or a video (full reconstruction), or a posed scene (triangulation).
    input: PathBuf,
    /// Output folder: gets sparse/0/ (COLMAP binary), database.db (COLMAP's, for its GUI) and
    /// images/ (a link to the images).
    #[arg(long)]
    out: PathBuf,
    /// Downscale images by this factor before feature extraction (the model is scaled back).
    #[arg(long, default_value_t = SfmOptions::default().downscale)]
    downscale: u32,
    /// Reconstruct from the images even when the input has poses.
    #[arg(long)]
    reconstruct: bool,
    /// auto (posed scenes: pairs chosen from the poses; else exhaustive), exhaustive, sequential, pairs.
    #[arg(long, default_value_t = SfmOptions::default().matcher)]
    matcher: String,
    /// COLMAP camera model for full reconstruction.
    #[arg(long, default_value_t = SfmOptions::default().camera_model)]
    camera_model: String,
    /// Most SIFT features per image.
    #[arg(long, default_value_t = SfmOptions::default().max_features)]
    max_features: u32,
    /// From a video: keep the sharpest frame of each of this many equal windows of it.
    #[arg(long, default_value_t = SfmOptions::default().video_frames)]
    frames: usize,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// Replace the output folder if it exists.
    #[arg(long)]
    overwrite: bool,
}

impl SfmCmd {
    pub fn run(self) -> Result<()> {
        if self.downscale == 0 {
            return Err(Error::invalid("--downscale must be at least 1"));
        }
        let opts = SfmOptions {
            downscale: self.downscale,
            camera_model: self.camera_model,
            max_features: self.max_features,
            matcher: self.matcher,
            video_frames: self.frames,
            overwrite: self.overwrite,
            ..Default::default()
        };
        let bars = Bars::default();
        let report = match sfm::resolve_input(&self.input, self.reconstruct)? {
            SfmInput::Images(dir) => sfm::reconstruct(&dir, &self.out, &opts, &bars)?,
            SfmInput::Posed(scene) => sfm::triangulate(&scene, &self.out, &opts, &bars)?,
            SfmInput::Video(video) => sfm::reconstruct_video(&video, &self.out, &opts, &bars)?,
        };
        if self.json {
            print_json(&report);
        } else {
            if let Some(v) = &report.video {
                println!(
                    "{}: the sharpest frame of each of {} windows of its {} frames (mean sharpness {:.0}, all frames {:.0})",
                    v.video.display(),
                    v.frames_chosen,
                    v.frames_in_video,
                    v.mean_sharpness_chosen,
                    v.mean_sharpness_all
                );
            }
            if let Some(n) = report.matched_pairs {
                println!("matched {n} image pairs chosen from the poses");
            }
            println!(
                "{}: {} of {} images registered, {} points (mean track length {:.2}) in {:.1} s -> {}",
                report.mode,
                report.num_registered,
                report.num_images,
                report.num_points,
                report.mean_track_length,
                report.seconds,
                report.model_dir.display()
            );
            let stages: Vec<String> = report
                .stages
                .iter()
                .map(|t| format!("{} {:.1} s", t.stage, t.seconds))
                .collect();
            println!(
                "COLMAP {}: {}; its database {} opens with the model in COLMAP's GUI",
                report.colmap_version,
                stages.join(", "),
                report.database.display()
            );
            super::print_warnings(&report.warnings);
        }
        Ok(())
    }
}

fn default_size() -> String {
    let d = DemoOptions::default();
    format!("{}x{}", d.width, d.height)
}

#[derive(Args)]
pub struct DemoSceneCmd {
    /// Output folder (created; must be empty unless --overwrite).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value_t = DemoOptions::default().seed)]
    seed: u64,
    /// Number of views.
    #[arg(long, default_value_t = DemoOptions::default().views)]
    views: usize,
    /// Where the cameras stand: ring (around the scene) or forward (a grid in front of it, all
    /// facing it, as LLFF captures; also writes poses_bounds.npy).
    #[arg(long, default_value_t = DemoOptions::default().layout)]
    layout: DemoLayout,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value_t = default_size())]
    size: String,
    /// Gaussian noise on the 2D features, in pixels.
    #[arg(long, default_value_t = DemoOptions::default().noise_px)]
    noise: f64,
    /// Fraction of 3D points given one wrong observation.
    #[arg(long, default_value_t = DemoOptions::default().outlier_fraction)]
    outliers: f64,
    /// A harder version of the scene, about the mug: out-of-frame (every third view cuts it
    /// in half), occluded (two panels hide it from one side), textureless (plain, few
    /// points), distractor (an identical mug beside it).
    #[arg(long, default_value_t = DemoOptions::default().variant)]
    variant: Variant,
    /// Replace the output folder if it exists.
    #[arg(long)]
    overwrite: bool,
    /// Render the exact truth of this edit file instead (its objects must be demo objects),
    /// along --path, into files named as `render-edit` names them.
    #[arg(long, requires = "path")]
    edit: Option<PathBuf>,
    /// The camera_path.json the edit's truth is rendered along.
    #[arg(long, requires = "edit")]
    path: Option<PathBuf>,
    /// Passes of the edit's truth besides RGB (rgb, alpha, depth, index).
    #[arg(long, default_value = "rgb,alpha,depth,index", requires = "edit")]
    passes: String,
}

impl DemoSceneCmd {
    pub fn run(self) -> Result<()> {
        if let (Some(edit), Some(path)) = (&self.edit, &self.path) {
            let passes = self
                .passes
                .parse()
                .map_err(|e| Error::invalid(format!("--passes: {e}")))?;
            let edit = load_edit(EditFile::read(edit)?, None)?;
            let path = CameraPath::read(path, &PathFrame::Data)?;
            let n = write_edit_truth(
                &edit,
                &path,
                self.seed,
                passes,
                &self.out,
                self.overwrite,
                &Bars::default(),
            )?;
            println!(
                "wrote the exact truth of {} along {} cameras into {}",
                edit.file.path.display(),
                n,
                self.out.display()
            );
            return Ok(());
        }
        let (width, height) = parse_size(&self.size)?;
        let opts = DemoOptions {
            seed: self.seed,
            views: self.views,
            width,
            height,
            noise_px: self.noise,
            outlier_fraction: self.outliers,
            overwrite: self.overwrite,
            variant: self.variant,
            layout: self.layout,
        };
        let s = write_demo_scene(&opts, &self.out)?;
        println!(
            "wrote {}: {} views, {} points, {} observations in {:.1} s",
            s.out.display(),
            s.views,
            s.points,
            s.observations,
            s.seconds
        );
        Ok(())
    }
}
