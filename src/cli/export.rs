//! `objnerf export nerfstudio`: a run or a scene as a dataset nerfstudio loads unchanged.

use clap::{Args, Subcommand};
use objnerf::export::nerfstudio::{export, ExportOptions};
use objnerf::Result;
use std::path::PathBuf;

#[derive(Subcommand)]
pub enum ExportCmd {
    /// A nerfstudio dataset: transforms.json, images, masks (0 = ignore), depth, sparse_pc.ply.
    Nerfstudio(NerfstudioCmd),
}

#[derive(Args)]
pub struct NerfstudioCmd {
    /// A run of `objnerf segment` or `objnerf extract`, or a scene.
    input: PathBuf,
    /// Output folder (must be empty unless --overwrite).
    #[arg(long)]
    out: PathBuf,
    /// The run's object (default: its only one); obstructed and absent views are left out.
    #[arg(long, conflicts_with = "background")]
    object: Option<String>,
    /// The scene without the run's objects: their masks reversed, every view.
    #[arg(long)]
    background: bool,
    /// Resize images, masks and depth by this factor (1: images linked as they are).
    #[arg(long, default_value_t = 1)]
    downscale: u32,
    /// Replace the output folder if it exists.
    #[arg(long)]
    overwrite: bool,
}

impl ExportCmd {
    pub fn run(self) -> Result<()> {
        match self {
            ExportCmd::Nerfstudio(a) => {
                let opts = ExportOptions {
                    object: a.object,
                    background: a.background,
                    downscale: a.downscale,
                    overwrite: a.overwrite,
                };
                println!("{}", export(&a.input, &a.out, &opts)?.summary());
                Ok(())
            }
        }
    }
}
