//! `objnerf render-edit` and `objnerf edit-template`: edits of a captured scene.

use super::print_json;
use crate::cli::progress_bars::Bars;
use clap::{ArgGroup, Args};
use objnerf::demo::parse_size;
use objnerf::edit::recolour::{hex_colour, parse_hex_colour};
use objnerf::edit::template::{edit_template, TemplateBackground};
use objnerf::field::RenderOptions;
use objnerf::pipeline::render_edit::{render_edit, PathSource, RenderEditOptions};
use objnerf::render::frame_files::Passes;
use objnerf::render::gpu::DeviceChoice;
use objnerf::{Error, Result};
use std::path::PathBuf;

#[derive(Args)]
#[command(group(ArgGroup::new("cameras").required(true).args(["path", "views", "orbit"])))]
pub struct RenderEditCmd {
    /// The edit file (docs/edit-format.md).
    edit: PathBuf,
    /// A nerfstudio camera_path.json (in the scene's own frame, as `objnerf` and the Blender
    /// add-on write it).
    #[arg(long)]
    path: Option<PathBuf>,
    /// Render along the views of this scene.
    #[arg(long)]
    views: Option<PathBuf>,
    /// Render a ring of N cameras around the edit's objects.
    #[arg(long)]
    orbit: Option<usize>,
    /// Output folder: frame_00000.png ..., the passes, camera_path.json and a video.
    #[arg(long)]
    out: PathBuf,
    /// Render size WIDTHxHEIGHT (default: the path's; an orbit's 320x240).
    #[arg(long)]
    size: Option<String>,
    /// Passes to write besides RGB: any of rgb, alpha, depth, index (comma-separated).
    #[arg(long, default_value = "rgb")]
    passes: String,
    /// Sample spacing in voxels of each field's grid (smaller: slower, finer).
    #[arg(long, default_value_t = RenderEditOptions::default().render.step)]
    step: f32,
    /// Samples less opaque than this are skipped (and cells that cannot reach it are never
    /// evaluated).
    #[arg(long, default_value_t = RenderEditOptions::default().render.alpha_thresh)]
    alpha_thresh: f32,
    /// Frames per second of --views and --orbit renders (a path file has its own).
    #[arg(long, default_value_t = RenderEditOptions::default().fps)]
    fps: f64,
    /// Do not write the video.
    #[arg(long)]
    no_video: bool,
    /// Where to draw: auto (a hardware GPU when there is one, else the CPU), cpu, or gpu (any
    /// GPU adapter, a software one such as lavapipe too; none is an error).
    #[arg(long, default_value = "auto")]
    device: DeviceChoice,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

impl RenderEditCmd {
    pub fn run(self) -> Result<()> {
        let passes: Passes = self
            .passes
            .parse()
            .map_err(|e| Error::invalid(format!("--passes: {e}")))?;
        if !(self.step.is_finite() && self.step > 0.0) {
            return Err(Error::invalid(format!(
                "--step {}: must be a positive number of voxels",
                self.step
            )));
        }
        let path = match (self.path, self.views, self.orbit) {
            (Some(p), _, _) => PathSource::File(p),
            (_, Some(s), _) => PathSource::Views(s),
            (_, _, Some(0)) => return Err(Error::invalid("--orbit needs at least one view")),
            (_, _, Some(n)) => PathSource::Orbit(n),
            _ => unreachable!("clap requires one of --path, --views, --orbit"),
        };
        let opts = RenderEditOptions {
            path,
            size: self.size.as_deref().map(parse_size).transpose()?,
            passes,
            render: RenderOptions {
                step: self.step,
                alpha_thresh: self.alpha_thresh,
                ..RenderEditOptions::default().render
            },
            fps: self.fps,
            video: !self.no_video,
            device: self.device,
        };
        let r = render_edit(&self.edit, &opts, &self.out, &Bars::default())?;
        if self.json {
            print_json(&r);
        } else {
            println!(
                "rendered {} frames of {}x{} ({} fields each) on {} in {:.1} s: {:.2} frames/s; peak RSS {} MiB -> {}{}",
                r.frames,
                r.width,
                r.height,
                r.layers,
                r.device.describe(),
                r.seconds,
                r.frames_per_second,
                r.peak_rss_mib,
                r.out.display(),
                r.video
                    .as_ref()
                    .map(|v| format!(" (video {})", v.display()))
                    .unwrap_or_default()
            );
        }
        Ok(())
    }
}

#[derive(Args)]
pub struct EditTemplateCmd {
    /// An `objnerf extract` run folder.
    run: PathBuf,
    /// The background: a model file (.objf) or a colour #RRGGBB (default: a removal field in
    /// the run, else white).
    #[arg(long)]
    background: Option<String>,
    /// Where to write the edit file.
    #[arg(long)]
    out: PathBuf,
}

impl EditTemplateCmd {
    pub fn run(self) -> Result<()> {
        let background = self.background.as_deref().map(|b| {
            if b.starts_with('#') {
                parse_hex_colour(b)
                    .map(TemplateBackground::Color)
                    .map_err(|e| Error::invalid(format!("--background: {e}")))
            } else {
                Ok(TemplateBackground::Model(PathBuf::from(b)))
            }
        });
        let edit = edit_template(&self.run, background.transpose()?, &self.out)?;
        edit.write()?;
        println!(
            "wrote {}: {} objects in place over {}",
            self.out.display(),
            edit.objects.len(),
            match &edit.background {
                objnerf::edit::Background::Model { given, .. } => given.clone(),
                objnerf::edit::Background::Color(c) => hex_colour(*c),
            }
        );
        Ok(())
    }
}
