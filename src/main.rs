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
