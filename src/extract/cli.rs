//! `objnerf extract` arguments.

use super::{extract, ExtractOptions, ExtractReport};
use crate::error::Result;
use crate::field::commands::DepthMode;
use crate::scene::Scene;
use crate::segment::run::{group_prompts, ClickArgs};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ExtractCmd {
    #[command(flatten)]
    pub clicks: ClickArgs,
    /// Run folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Train on images downscaled by this factor.
    #[arg(long, default_value_t = 1)]
    pub downscale: u32,
    /// Seconds of training per object.
    #[arg(long, default_value_t = 120.0)]
    pub time_budget: f64,
    /// Most training steps per object.
    #[arg(long, default_value_t = 20_000)]
    pub steps: usize,
    /// Depth supervision: sparse (the object's 3D points), dense (depth images) or none.
    #[arg(long, default_value = "sparse")]
    pub depth: DepthMode,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Marching-cubes samples along the box's longest side (default: the field's grid).
    #[arg(long)]
    pub resolution: Option<usize>,
    /// Surface opacity per voxel for marching cubes (0..1).
    #[arg(long, default_value_t = 0.5)]
    pub iso: f32,
    /// Turntable frames per object.
    #[arg(long, default_value_t = 24)]
    pub frames: usize,
    /// Replace the run folder if it exists.
    #[arg(long)]
    pub overwrite: bool,
    /// Print report.json to stdout.
    #[arg(long)]
    pub json: bool,
}

impl ExtractCmd {
    pub fn options(&self) -> ExtractOptions {
        let mut o = ExtractOptions {
            downscale: self.downscale,
            time_budget: Some(self.time_budget),
            steps: self.steps,
            depth: self.depth,
            seed: self.seed,
            overwrite: self.overwrite,
            ..Default::default()
        };
        o.mesh.resolution = self.resolution;
        o.mesh.iso_alpha = self.iso;
        o.turntable.frames = self.frames.max(1);
        o
    }

    /// `argv` is the raw command line, read for the order of --view/--object/--point.
    pub fn run(self, argv: &[String]) -> Result<()> {
        let scene = Scene::load(&self.clicks.scene)?;
        let prompts = group_prompts(argv, &scene)?;
        let report = extract(
            &self.clicks.scene,
            &scene,
            &prompts,
            &self.options(),
            &self.out,
        )?;
        if self.json {
            println!(
                "{}",
                serde_json::to_string_pretty(&report).expect("report serialises")
            );
        }
        print_summary(&report);
        Ok(())
    }
}

/// What a person wants to read after a run: where things are and how each stage went.
pub fn print_summary(r: &ExtractReport) {
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
        println!(
            "  mesh: {} vertices, {} triangles -> {}",
            o.mesh.vertices,
            o.mesh.triangles,
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
