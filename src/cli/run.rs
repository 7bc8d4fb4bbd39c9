//! `objnerf extract` (click to mesh) and `objnerf demo` (the same on the built-in scene, scored
//! against its truth).

use super::segment::{prompts_in_order, ClickArgs};
use super::training::{AppearanceArg, HoldOutArg, TimeBudgetArg};
use super::{print_json, print_warnings};
use crate::cli::progress_bars::Bars;
use clap::{ArgMatches, Args};
use objnerf::field::holdout::HoldOut;
use objnerf::mesh::from_field::FieldMeshOptions;
use objnerf::pipeline::demo::{prepare_demo, run_demo};
use objnerf::pipeline::{extract, ExtractOptions, ExtractReport};
use objnerf::render::TurntableOptions;
use objnerf::segment::check_request;
use objnerf::supervision::DepthMode;
use objnerf::{Result, Scene};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ExtractCmd {
    #[command(flatten)]
    pub clicks: ClickArgs,
    /// Run folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Train on images downscaled by this factor.
    #[arg(long, default_value_t = ExtractOptions::default().fit.downscale)]
    pub downscale: u32,
    #[command(flatten)]
    pub time: TimeBudgetArg,
    /// Most training steps per object.
    #[arg(long, default_value_t = ExtractOptions::default().fit.steps)]
    pub steps: usize,
    /// Depth supervision: sparse (the object's 3D points), spread (their depths spread over each
    /// view where nearby points agree on a surface), stereo (plane-sweep stereo), dense (depth
    /// images) or none.
    #[arg(long, default_value_t = ExtractOptions::default().fit.depth)]
    pub depth: DepthMode,
    #[arg(long, default_value_t = ExtractOptions::default().fit.seed)]
    pub seed: u64,
    /// Colour from this many features per vertex through a small network where the object
    /// has enough views (0: SH always; see `objnerf train --help`).
    #[arg(long, default_value_t = objnerf::field::SetupConfig::default().net_features)]
    pub colour_net: usize,
    #[command(flatten)]
    pub appearance: AppearanceArg,
    /// Marching-cubes samples along the box's longest side (default: the field's grid).
    #[arg(long)]
    pub resolution: Option<usize>,
    /// Surface opacity per voxel for marching cubes (0..1).
    #[arg(long, default_value_t = FieldMeshOptions::default().iso_alpha)]
    pub iso: f32,
    #[command(flatten)]
    pub export: super::mesh::MeshExportArgs,
    /// Each object's glTF origin (RUN/<object>/mesh.glb): base, centre or capture.
    #[arg(long, default_value = "base")]
    pub origin: String,
    /// Turntable frames per object.
    #[arg(long, default_value_t = TurntableOptions::default().frames)]
    pub frames: usize,
    /// The views left out of training to score each field on (none: a few ok views are kept
    /// back to check each field on instead).
    #[command(flatten)]
    pub hold_out: HoldOutArg,
    /// Replace the run folder if it exists.
    #[arg(long)]
    pub overwrite: bool,
    /// Print report.json to stdout.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub sam: super::models::SamPrecisionArg,
}

impl ExtractCmd {
    pub(super) fn options(&self) -> Result<ExtractOptions> {
        let mut o = ExtractOptions {
            overwrite: self.overwrite,
            hold_out: self.hold_out.or(ExtractOptions::default().hold_out),
            ..Default::default()
        };
        o.fit.downscale = self.downscale;
        o.fit.time_budget = self.time.or(o.fit.time_budget);
        o.fit.steps = self.steps;
        o.fit.depth = self.depth;
        o.fit.seed = self.seed;
        o.fit.setup.net_features = self.colour_net;
        o.fit.appearance_lr = self.appearance.rate;
        o.mesh.resolution = self.resolution;
        o.mesh.iso_alpha = self.iso;
        o.mesh.export = self.export.export()?;
        o.mesh.placement = self
            .export
            .placement(objnerf::mesh::frame::Origin::parse(&self.origin)?);
        o.turntable.frames = self.frames.max(1);
        Ok(o)
    }

    pub fn run(self, m: &ArgMatches) -> Result<()> {
        let scene = Scene::load(&self.clicks.scene)?;
        let prompts = prompts_in_order(m, &scene)?;
        check_request(&scene, &prompts)?;
        let seg = self.sam.segmenter()?;
        let report = extract(
            &scene,
            &prompts,
            &self.options()?,
            &seg,
            &self.out,
            &Bars::default(),
        )?;
        if self.json {
            print_json(&report);
        }
        print_summary(&report);
        print_warnings(&report.warnings);
        Ok(())
    }
}

/// What a person wants to read after a run: where things are and how each stage went.
fn print_summary(r: &ExtractReport) {
    for o in &r.objects {
        let s = &o.segmentation;
        println!(
            "{}: segmented {} ok / {} obstructed / {} absent of {} views ({} points)",
            o.name, s.num_ok, s.num_obstructed, s.num_absent, s.num_views, s.num_points
        );
        println!(
            "  field: {}x{}x{} grid, {} steps in {:.0} s, training PSNR {:.2} dB -> {}",
            o.train.dims[0],
            o.train.dims[1],
            o.train.dims[2],
            o.train.run.steps,
            o.train_seconds,
            o.train.run.final_psnr,
            o.model.display()
        );
        let texture = o
            .export
            .atlas
            .as_ref()
            .map_or("vertex colours".to_string(), |a| {
                format!("{0}x{0} px texture", a.size)
            });
        println!(
            "  mesh: {} triangles ({} in the full mesh.ply), {texture}, {:?}, origin {:?} -> {}",
            o.export.triangles,
            o.mesh.triangles,
            o.export.shading,
            o.frame.origin,
            o.mesh_glb.display()
        );
        println!("  turntable: {}", o.turntable_gif.display());
    }
    println!(
        "all objects: {}; report: {}",
        r.out.join("mesh.glb").display(),
        r.out.join("report.json").display()
    );
    println!(
        "{:.0} s (segment {:.0}, train {:.0}, mesh {:.1}, render {:.0}); peak memory {} MiB",
        r.seconds.total,
        r.seconds.segment,
        r.seconds.train,
        r.seconds.mesh,
        r.seconds.render,
        r.peak_rss_mib
    );
}

/// The demo's own defaults: a shorter budget than `extract`'s, every 6th view held out.
fn demo_options() -> ExtractOptions {
    let mut o = ExtractOptions {
        overwrite: true,
        hold_out: HoldOut::Every(6),
        ..Default::default()
    };
    o.fit.time_budget = Some(90.0);
    o.fit.steps = 6000;
    o
}

#[derive(Args, Debug)]
pub struct DemoCmd {
    /// Run folder (its contents are replaced): scene/ and run/ go in it.
    #[arg(long, default_value = "runs/demo")]
    pub out: PathBuf,
    /// Which object to extract: mug, sphere, box or torus.
    #[arg(long, default_value = "mug")]
    pub object: String,
    #[command(flatten)]
    pub time: TimeBudgetArg,
    /// Most training steps.
    #[arg(long, default_value_t = demo_options().fit.steps)]
    pub steps: usize,
    /// Colour from this many features per vertex through a small network where the object
    /// has enough views (0: SH always; see `objnerf train --help`).
    #[arg(long, default_value_t = objnerf::field::SetupConfig::default().net_features)]
    pub colour_net: usize,
    #[command(flatten)]
    pub sam: super::models::SamPrecisionArg,
}

impl DemoCmd {
    pub(super) fn options(&self) -> ExtractOptions {
        let mut opts = demo_options();
        opts.fit.time_budget = self.time.or(opts.fit.time_budget);
        opts.fit.steps = self.steps;
        opts.fit.setup.net_features = self.colour_net;
        opts
    }

    pub fn run(self) -> Result<()> {
        let opts = self.options();
        let setup = prepare_demo(&self.out, &self.object)?;
        let s = &setup.written;
        println!(
            "demo scene: {} views, {} points -> {}",
            s.views,
            s.points,
            s.out.display()
        );
        let click = setup.truth.click;
        println!(
            "extracting '{}' from one click at ({:.1}, {:.1}) in {}",
            self.object, click[0], click[1], setup.truth.view
        );
        let seg = self.sam.segmenter()?;
        let job = run_demo(&setup, &self.out, &opts, &seg, &Bars::default())?;
        print_summary(&job.report);
        let t = &job.truth;
        println!(
            "against the truth: mask mIoU {:.3} (ok views); held-out PSNR {:.2} dB, SSIM {:.3} ({} views); \
             Chamfer {:.4} = {:.2}% of the true box diagonal ({:.2}% over the surfaces the \
             training views see: {:.0}% of ours, {:.0}% of the truth)",
            t.miou_ok_views,
            t.heldout_psnr,
            t.heldout_ssim,
            t.heldout_views,
            t.chamfer,
            100.0 * t.chamfer_fraction_of_diagonal,
            100.0 * t.chamfer_seen_fraction_of_diagonal,
            100.0 * t.ours_seen,
            100.0 * t.truth_seen
        );
        println!(
            "open {} in Blender (File > Import > glTF 2.0) or any glTF viewer",
            job.report.out.join("mesh.glb").display()
        );
        print_warnings(&job.report.warnings);
        Ok(())
    }
}
