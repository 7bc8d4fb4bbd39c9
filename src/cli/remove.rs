//! `objnerf remove`: objects taken out of a scene (a scene field trained with the reverse alpha).

use super::training::{AppearanceArg, HoldOutArg, TimeBudgetArg};
use crate::cli::progress_bars::Bars;
use clap::Args;
use objnerf::field::SetupConfig;
use objnerf::fit::{FitOptions, SceneFitOptions};
use objnerf::pipeline::{remove, RemoveOptions};
use objnerf::removal::hole::HoleFill;
use objnerf::space::SpaceChoice;
use objnerf::{Result, Scene};
use std::path::PathBuf;

#[derive(Args)]
pub struct RemoveCmd {
    /// The scene (COLMAP model folder, transforms.json, ...) the segmentation was made on.
    scene: PathBuf,
    /// The `objnerf segment` output folder (or an extract run's `segment/`).
    #[arg(long)]
    segment: PathBuf,
    /// An object to remove (as named in the segmentation); repeat for several.
    #[arg(long = "object", required = true)]
    objects: Vec<String>,
    /// Output folder (created; must be empty unless --overwrite).
    #[arg(long)]
    out: PathBuf,
    /// The field's space: auto (from the capture's layout), box, unbounded or forward.
    #[arg(long, default_value_t = SpaceChoice::default())]
    space: SpaceChoice,
    /// Train on images downscaled by this factor (box filter).
    #[arg(long, default_value_t = FitOptions::default().downscale)]
    downscale: u32,
    #[command(flatten)]
    time: TimeBudgetArg,
    /// Most optimisation steps (the learning-rate schedule spans them).
    #[arg(long, default_value_t = FitOptions::default().steps)]
    steps: usize,
    /// Memory for the grid and optimiser state, MiB.
    #[arg(long, default_value_t = SetupConfig::default().memory_budget >> 20)]
    memory_mb: usize,
    /// Grow the removed masks by this many pixels before they are left out.
    #[arg(long, default_value_t = SceneFitOptions::default().dilate_px)]
    dilate: u32,
    /// The views left out of training and scored.
    #[command(flatten)]
    hold_out: HoldOutArg,
    /// How the part of the hole no view saw is filled: pattern (the repeating pattern around it
    /// continued where there is one, smooth elsewhere), smooth (harmonic) or none.
    #[arg(long, default_value_t = HoleFill::default())]
    fill: HoleFill,
    #[arg(long, default_value_t = FitOptions::default().seed)]
    seed: u64,
    #[command(flatten)]
    appearance: AppearanceArg,
    /// Replace the output folder if it exists.
    #[arg(long)]
    overwrite: bool,
}

impl RemoveCmd {
    pub(super) fn options(&self) -> RemoveOptions {
        let defaults = RemoveOptions::default();
        let mut field = defaults.field.clone();
        field.space = self.space;
        field.dilate_px = self.dilate;
        field.fit.downscale = self.downscale;
        field.fit.time_budget = self.time.or(defaults.field.fit.time_budget);
        field.fit.steps = self.steps;
        field.fit.seed = self.seed;
        field.fit.appearance_lr = self.appearance.rate;
        field.fit.setup.memory_budget = self.memory_mb << 20;
        RemoveOptions {
            objects: self.objects.clone(),
            field,
            hold_out: self.hold_out.or(defaults.hold_out),
            fill: self.fill,
            overwrite: self.overwrite,
            ..defaults
        }
    }

    pub fn run(self) -> Result<()> {
        let scene = Scene::load(&self.scene)?;
        let opts = self.options();
        let bars = Bars::default();
        let r = remove(&scene, &self.segment, &opts, &self.out, &bars)?;
        if let Some(s) = &r.train.setup {
            println!(
                "grid: {:?} reached ({} vertices allocated; planned {:?}), {} MiB with optimiser state",
                r.train.dims,
                r.train.vertices,
                s.final_dims,
                r.train.memory_bytes >> 20
            );
        }
        let run = &r.train.run;
        println!(
            "trained {} steps in {:.0} s (stopped by {}), batch PSNR {:.2} dB; {} hole pixels filled ({} continuing a pattern), {} cells occupied again under them",
            run.steps, r.seconds.train, run.stopped_by, run.final_psnr, r.filled_px, r.patterned_px, r.reopened_cells
        );
        let (hole, unseen) = r
            .holes
            .iter()
            .fold((0, 0), |a, h| (a.0 + h.hole_px, a.1 + h.unseen_px));
        println!(
            "hole: {hole} pixels over {} views, {:.1}% of them seen by no training view",
            r.holes.iter().filter(|h| h.hole_px > 0).count(),
            100.0 * unseen as f64 / hole.max(1) as f64
        );
        if let Some(c) = &r.train.scene_fit {
            println!(
                "fit to its {} training views (outside the holes): {:.2} dB; most see-through: {} ({:.2}% of its pixels)",
                c.views,
                c.psnr,
                c.see_through_view,
                100.0 * c.see_through
            );
        }
        if let Some(c) = &r.held_out_outside_holes {
            println!(
                "against its {} held-out photos (outside the holes): {:.2} dB",
                c.views, c.psnr
            );
        }
        if let Some(s) = &r.scores {
            println!(
                "against the truth ({} views): PSNR {:.2} dB; inside the objects' masks (+{} px): {}",
                s.views.len(),
                s.psnr,
                objnerf::pipeline::remove::SCORE_DILATE_PX,
                s.hole_psnr
                    .iter()
                    .map(|(o, p)| format!("{o} {p:.2} dB"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        println!(
            "wrote {} in {:.0} s (peak {} MiB)",
            r.out.display(),
            r.seconds.total,
            r.peak_rss_mib
        );
        super::print_warnings(&r.warnings);
        Ok(())
    }
}
