//! The `objnerf` command line: a thin layer over the library.

use clap::{Parser, Subcommand};
use objnerf::{Result, Scene};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "objnerf",
    version,
    about = "Pull one object out of a multi-view capture as its own radiance field and mesh"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Describe a scene: images, intrinsics, sparse points, tracks, bounds.
    Info {
        /// A COLMAP model folder, transforms.json, LLFF or RGB-D folder.
        scene: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Write the built-in synthetic scene (four textured objects, a camera ring, a COLMAP model
    /// with true tracks, and truth masks, depth and meshes).
    DemoScene {
        /// Output folder (created; must be empty unless --overwrite).
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Number of views on the camera ring.
        #[arg(long, default_value_t = 36)]
        views: usize,
        /// Image size, WIDTHxHEIGHT.
        #[arg(long, default_value = "320x240")]
        size: String,
        /// Gaussian noise on the 2D features, in pixels.
        #[arg(long, default_value_t = 0.0)]
        noise: f64,
        /// Fraction of 3D points given one wrong observation.
        #[arg(long, default_value_t = 0.0)]
        outliers: f64,
        /// Replace the output folder if it exists.
        #[arg(long)]
        overwrite: bool,
    },
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Info { scene, json } => {
            let scene = Scene::load(&scene)?;
            let info = objnerf::info::scene_info(&scene);
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&info).expect("info serialises")
                );
            } else {
                print!("{}", info.to_text());
            }
            Ok(())
        }
        Command::DemoScene {
            out,
            seed,
            views,
            size,
            noise,
            outliers,
            overwrite,
        } => {
            let (width, height) = objnerf::demo::parse_size(&size)?;
            let opts = objnerf::demo::DemoOptions {
                seed,
                views,
                width,
                height,
                noise_px: noise,
                outlier_fraction: outliers,
                overwrite,
            };
            let s = objnerf::demo::write_demo_scene(&opts, &out)?;
            for w in &s.warnings {
                eprintln!("warning: {w}");
            }
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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
