//! `objnerf train`, `objnerf render` and `objnerf eval`: one field at a time.

use super::training::{AppearanceArg, HoldOutArg, TimeBudgetArg};
use crate::cli::progress_bars::Bars;
use clap::Args;
use objnerf::field::holdout::{held_out_views, HoldOut};
use objnerf::field::io;
use objnerf::field::{MaskSource, SetupConfig};
use objnerf::fit::{FitOptions, SceneFitOptions};
use objnerf::pipeline::train::{train, FieldTarget};
use objnerf::render::gpu::DeviceChoice;
use objnerf::render::{evaluate_model, render_scene_views};
use objnerf::space::SpaceChoice;
use objnerf::supervision::DepthMode;
use objnerf::{Result, Scene};
use std::path::PathBuf;

#[derive(Args)]
pub struct TrainCmd {
    /// A COLMAP model folder, transforms.json or other scene.
    scene: PathBuf,
    /// The object's masks: 'alpha' (the images' alpha), a folder of masks, 'scene' (each
    /// view's mask_path) or 'truth:OBJECT' (the demo scene's true masks).
    #[arg(long, required_unless_present = "scene_field")]
    masks: Option<String>,
    /// Train a field of the whole scene instead of one object (no masks).
    #[arg(long, conflicts_with = "masks")]
    scene_field: bool,
    /// The scene field's space: auto (from the capture's layout), box, unbounded or forward.
    #[arg(long, default_value_t = SpaceChoice::default(), requires = "scene_field")]
    space: SpaceChoice,
    /// Where to write the model (.objf).
    #[arg(long)]
    out: PathBuf,
    /// Train on images downscaled by this factor (box filter).
    #[arg(long, default_value_t = FitOptions::default().downscale)]
    downscale: u32,
    /// Without --steps the schedule follows the time and training runs to the end of it; with
    /// --steps it stops at whichever comes first.
    #[command(flatten)]
    time: TimeBudgetArg,
    /// Depth supervision: sparse (the sparse 3D points), spread (their depths spread over each
    /// view where nearby points agree on a surface), stereo (plane-sweep stereo between
    /// neighbouring photos where it is clear), dense (depth images) or none. Default: none for an
    /// object field, stereo for a scene field (without depth a scene field has no geometry to
    /// hold its views together).
    #[arg(long)]
    depth: Option<DepthMode>,
    #[arg(long, default_value_t = FitOptions::default().seed)]
    seed: u64,
    /// Most optimisation steps (the learning-rate schedule spans them); unless it trains for a
    /// whole --time-budget, training also stops when the batch PSNR stops rising. Default:
    /// 20 000, or as many as the --time-budget allows.
    #[arg(long)]
    steps: Option<usize>,
    /// Spherical-harmonic degree of the colour (0-2).
    #[arg(long, default_value_t = SetupConfig::default().sh_degree)]
    sh_degree: u32,
    /// Colour from this many features per vertex through a small network (DVGO-style, 32
    /// hidden units, or the large model's 12 x 64 on a long run: --large-model-passes; the view
    /// direction enters as its SH basis to --colour-net-sh-degree) when
    /// the object has at least --colour-net-min-views training views, SH coefficients otherwise
    /// (0: SH always; default 8; examples/results/field.md, "Colour by view count"). A scene
    /// field (--scene-field) takes a network of this many features whatever its view count (0:
    /// SH colour); without it, 9 features on a forward-facing capture and SH colour in the
    /// other layouts (examples/results/scene_field.md).
    #[arg(long)]
    colour_net: Option<usize>,
    /// Fewer training views than this: SH colour (a network's view dependence does not hold
    /// between few views: the demo sphere, 30 views, -0.9 dB held out; lego, 100, +0.6).
    #[arg(long, default_value_t = SetupConfig::default().net_min_views)]
    colour_net_min_views: usize,
    /// Spherical-harmonic degree of the view direction the colour network takes (0-3).
    #[arg(long, default_value_t = SetupConfig::default().net_sh_degree)]
    colour_net_sh_degree: u32,
    /// A run that affords this many passes over its training pixels (its steps, or its
    /// --time-budget at the rate of a 2-core machine) trains the large model: a colour network
    /// of 12 features and 64 hidden units on a grid 1.3x finer ('inf': never).
    #[arg(long, default_value_t = SetupConfig::default().large_model_passes)]
    large_model_passes: f64,
    /// Memory for the grid and optimiser state, MiB.
    #[arg(long, default_value_t = SetupConfig::default().memory_budget >> 20)]
    memory_mb: usize,
    /// Pixels either side of a segmented mask's edge trained on the photo over the background
    /// behind the object, where the mask may be a pixel or two off (0: the masks are exact,
    /// e.g. 'truth:OBJECT').
    #[arg(long, default_value_t = FitOptions::default().mask_band)]
    mask_band: u32,
    #[command(flatten)]
    pub(super) appearance: AppearanceArg,
    /// Continue training this model.
    #[arg(long)]
    resume: Option<PathBuf>,
    /// The views left out of training, for `eval` with the same rule.
    #[command(flatten)]
    hold_out: HoldOutArg,
    /// Print the training report (with the process's peak RSS) to stdout as JSON.
    #[arg(long)]
    json: bool,
}

impl TrainCmd {
    /// The training time this command was given (none by default).
    pub(super) fn time_budget(&self) -> Option<f64> {
        self.time.or(None)
    }

    fn options(&self, scene: &Scene) -> FitOptions {
        FitOptions {
            downscale: self.downscale,
            time_budget: self.time_budget(),
            depth: self.depth.unwrap_or(if self.scene_field {
                SceneFitOptions::default().fit.depth
            } else {
                FitOptions::default().depth
            }),
            seed: self.seed,
            steps: self.steps.unwrap_or(FitOptions::default().steps),
            whole_budget: self.steps.is_none(),
            setup: SetupConfig {
                sh_degree: self.sh_degree.min(2),
                net_features: self
                    .colour_net
                    .unwrap_or(SetupConfig::default().net_features),
                scene_net_features: self.colour_net,
                net_min_views: self.colour_net_min_views,
                net_sh_degree: self.colour_net_sh_degree,
                large_model_passes: self.large_model_passes,
                memory_budget: self.memory_mb << 20,
                ..Default::default()
            },
            exclude_views: held_out_views(scene, self.hold_out.or(HoldOut::None)),
            mask_band: self.mask_band,
            appearance_lr: self.appearance.rate,
        }
    }

    pub fn run(self) -> Result<()> {
        let scene = Scene::load(&self.scene)?;
        let opts = self.options(&scene);
        let target = match &self.masks {
            Some(masks) => FieldTarget::Object {
                masks: MaskSource::parse(masks, &self.scene)?,
                resume: self.resume.clone(),
            },
            None => FieldTarget::Scene { space: self.space },
        };
        let report = train(&scene, &target, &opts, &self.out, &Bars::default())?;
        if self.json {
            let mut v = serde_json::to_value(&report).expect("reports serialise");
            v["peak_rss_mib"] = objnerf::util::mem::peak_rss_mib().into();
            super::print_json(&v);
        }
        let r = &report;
        if let Some(s) = &r.setup {
            eprintln!(
                "{} space, box {:?}..{:?}; grid {:?} ({} vertices) because {}",
                s.space.name(),
                s.box_min,
                s.box_max,
                s.final_dims,
                s.final_vertices,
                s.why
            );
            eprintln!(
                "rays: {} of {} kept ({:.1}% pruned: they miss the box or carry no loss)",
                s.rays_kept,
                s.rays_total,
                100.0 * s.pruned_fraction
            );
        }
        if let Some(f) = &r.finest {
            eprintln!(
                "finest stage: voxel {:.5}, {} bricks x {} KiB: {}",
                f.voxel,
                f.bricks,
                f.bytes_per_brick >> 10,
                f.why
            );
        }
        let mean = match r.run.averaged {
            0 => String::new(),
            n => format!(", ending on the mean of {n} snapshots of its last parameters"),
        };
        eprintln!(
            "trained {} steps in {:.1} s ({:.0} rays/s, stopped by {}{mean}); batch PSNR {:.2} dB; {} occupied cells; {:.0} MiB; model {}",
            r.run.steps,
            r.run.seconds,
            r.run.rays_per_second,
            r.run.stopped_by,
            r.run.final_psnr,
            r.occupied_cells,
            r.memory_bytes as f64 / 1048576.0,
            self.out.display()
        );
        if let Some(c) = &r.scene_fit {
            eprintln!(
                "fit to {} of its training views: {:.2} dB; most see-through: {} ({:.2}% of its pixels)",
                c.views,
                c.psnr,
                c.see_through_view,
                100.0 * c.see_through
            );
            // With --json the warnings are in the report, and stdout is the JSON alone.
            if !self.json {
                super::print_warnings(&r.warnings);
            }
        }
        Ok(())
    }
}

#[derive(Args)]
pub struct RenderCmd {
    model: PathBuf,
    #[arg(long)]
    scene: PathBuf,
    #[arg(long)]
    out: PathBuf,
    /// Downscale of the scene's cameras (default: the one the model was trained at).
    #[arg(long)]
    downscale: Option<u32>,
    #[command(flatten)]
    pixels: PixelSamples,
    #[command(flatten)]
    device: DeviceArg,
}

/// Where views are drawn, for `render` and `eval` alike.
#[derive(Args)]
pub struct DeviceArg {
    /// auto (a hardware GPU when there is one, else the CPU), cpu, or gpu (any GPU adapter, a
    /// software one such as lavapipe too; none is an error).
    #[arg(long = "device", default_value = "auto")]
    choice: DeviceChoice,
}

/// Antialiasing, for `render` and `eval` alike.
#[derive(Args)]
pub struct PixelSamples {
    /// Each pixel is the mean of N x N rays over its square (antialiasing; N^2 times the
    /// rendering time) rather than one ray through its centre.
    #[arg(long = "pixel-samples", value_name = "N", default_value_t = 1,
          value_parser = clap::value_parser!(u32).range(1..=8))]
    n: u32,
}

impl RenderCmd {
    pub fn run(self) -> Result<()> {
        let model = io::load_field(&self.model)?;
        let scene = Scene::load(&self.scene)?;
        let (n, device) = render_scene_views(
            &model,
            &scene,
            self.downscale,
            self.pixels.n,
            self.device.choice,
            &self.out,
            &Bars::default(),
        )?;
        eprintln!(
            "wrote {n} images to {} (on {})",
            self.out.display(),
            device.describe()
        );
        Ok(())
    }
}

#[derive(Args)]
pub struct EvalCmd {
    model: PathBuf,
    #[arg(long)]
    scene: PathBuf,
    /// The truth's masks, as `train --masks` takes them (default: the images' alpha for an
    /// object field, every pixel for a scene field).
    #[arg(long)]
    masks: Option<String>,
    #[arg(long)]
    downscale: Option<u32>,
    /// Score only the views `train` left out with the same rule.
    #[command(flatten)]
    hold_out: HoldOutArg,
    #[command(flatten)]
    pixels: PixelSamples,
    #[command(flatten)]
    device: DeviceArg,
    #[arg(long)]
    json: bool,
}

impl EvalCmd {
    pub fn run(self) -> Result<()> {
        let model = io::load_field(&self.model)?;
        let scene = Scene::load(&self.scene)?;
        let masks = match (&self.masks, model.is_scene_field()) {
            (Some(m), _) => MaskSource::parse(m, &self.scene)?,
            (None, true) => MaskSource::Opaque,
            (None, false) => MaskSource::Alpha,
        };
        let n = self.pixels.n;
        let (r, device) = evaluate_model(
            &model,
            &scene,
            &masks,
            self.downscale,
            self.hold_out.or(HoldOut::None),
            n,
            self.device.choice,
        )?;
        if self.json {
            let v = serde_json::json!({
                "psnr": r.psnr, "ssim": r.ssim, "psnr_colour_fit": r.psnr_colour_fit,
                "num_views": r.num_views, "views": r.views,
                "seconds": r.seconds, "pixel_samples": n, "device": device,
            });
            println!("{v}");
        } else {
            println!(
                "PSNR {:.2} dB, SSIM {:.4} over {} views ({:.2} dB after each view's best affine colour map), on {}",
                r.psnr, r.ssim, r.num_views, r.psnr_colour_fit, device.describe()
            );
        }
        Ok(())
    }
}
