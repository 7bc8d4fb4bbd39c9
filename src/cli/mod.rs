//! The command line: every clap struct, every print and every progress bar of `objnerf`. Each
//! command parses its arguments into the library's typed options, calls the library, and prints
//! what it returns. Defaults live in the library's `Default` impls; the arguments read them.

mod batch;
mod bench;
mod camera_path;
mod edit;
mod export;
mod field;
mod mesh;
mod models;
mod progress_bars;
mod remove;
mod run;
mod scene;
mod segment;
mod training;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use objnerf::Result;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "objnerf",
    version,
    about = "Pull objects out of a multi-view capture as their own radiance fields and meshes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Describe a scene: images, intrinsics, sparse points, tracks, bounds.
    Info(scene::InfoCmd),
    /// Give a scene 2D-3D feature tracks with COLMAP: full reconstruction from a folder of images,
    /// or triangulation with the known poses of a posed scene (e.g. a transforms.json).
    Sfm(scene::SfmCmd),
    /// The models directory ($OBJNERF_HOME, default <cache dir>/objnerf): install and list.
    Models {
        #[command(subcommand)]
        action: models::ModelsCmd,
    },
    /// Segment one image with SAM from point and box prompts; writes the mask and an overlay.
    SegmentView(models::SegmentViewCmd),
    /// Segment objects in every view from clicks in one (Obj-NeRF's Algorithm 1): masks, segmented
    /// points, contact sheets and report.json.
    Segment(segment::SegmentCmd),
    /// Train the object's radiance field (voxel grid) from masked views and save the model.
    Train(field::TrainCmd),
    /// Render a model from every view of a scene: RGB on white, alpha and depth PNGs.
    Render(field::RenderCmd),
    /// Score a model on held-out views (PSNR, SSIM; composited on white).
    Eval(field::EvalCmd),
    /// Marching cubes on a trained model: a mesh with vertex colours as .glb, .obj or .ply.
    Mesh(mesh::MeshCmd),
    /// Click to mesh in one command: segment, train each object's field, mesh it, render a
    /// turntable; everything in one run folder with report.json.
    Extract(run::ExtractCmd),
    /// The main job on the built-in demo scene: render it, extract one object from one click
    /// (segment, train, mesh, turntable) and score each stage against the scene's exact truth.
    Demo(run::DemoCmd),
    /// Take objects out of a scene: a field of the scene without them (trained with the reverse
    /// alpha, the part of the hole no view saw filled), renders of every view, a contact sheet.
    Remove(remove::RemoveCmd),
    /// Render the built-in demo scene with its exact truth (masks, depth, meshes, visibility).
    DemoScene(scene::DemoSceneCmd),
    /// Render an edit (docs/edit-format.md: a background and objects moved, turned, scaled,
    /// duplicated, removed, recoloured or inserted) along a camera path, in one pass over all
    /// fields: frames, passes (alpha, depth, object index), camera_path.json and a video.
    RenderEdit(edit::RenderEditCmd),
    /// Write an edit file for an extract run: every object in place over a background.
    EditTemplate(edit::EditTemplateCmd),
    /// Run every job of a manifest (JSON Lines: a scene and its stages, sfm, extract, remove,
    /// export, one job a line), each into OUT/<id>/; complete jobs are skipped, so a rerun
    /// resumes; summary.json and a table at the end (docs/batch.md).
    Batch(batch::BatchCmd),
    /// Benchmark suites scored against truth (`bench stability`).
    Bench {
        #[command(subcommand)]
        suite: bench::BenchCmd,
    },
    /// Export a run or a scene for other tools.
    Export {
        #[command(subcommand)]
        to: export::ExportCmd,
    },
    /// Read a nerfstudio camera_path.json (data frame, or the viewer's with the run's
    /// dataparser_transforms.json): print its cameras; --out writes it in the data frame.
    CameraPath(camera_path::CameraPathCmd),
}

/// Parse the command line, run the command, print an error and exit 1 if it failed.
pub fn main() -> ExitCode {
    restore_sigpipe();
    let matches = Cli::command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // `segment` and `extract` read the order of their --view/--object/--point options.
    let sub = matches.subcommand().map(|(_, m)| m);
    match run(cli.command, sub) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Rust ignores SIGPIPE, so `println!` into a closed pipe (`objnerf mesh ... | head -1`)
/// panicked; with the default action the process ends quietly, as other command-line tools do.
/// Commands print their results after their outputs are renamed into place (and a killed run's
/// partial folder is cleaned up by the next run), so nothing is left half-written.
fn restore_sigpipe() {
    // SAFETY: setting a signal's disposition to its default before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn run(command: Command, sub: Option<&clap::ArgMatches>) -> Result<()> {
    match command {
        Command::Info(cmd) => cmd.run(),
        Command::Sfm(cmd) => cmd.run(),
        Command::Models { action } => action.run(),
        Command::SegmentView(cmd) => cmd.run(),
        Command::Segment(cmd) => cmd.run(sub.expect("segment has matches")),
        Command::Train(cmd) => cmd.run(),
        Command::Render(cmd) => cmd.run(),
        Command::Eval(cmd) => cmd.run(),
        Command::Mesh(cmd) => cmd.run(),
        Command::Extract(cmd) => cmd.run(sub.expect("extract has matches")),
        Command::Demo(cmd) => cmd.run(),
        Command::DemoScene(cmd) => cmd.run(),
        Command::Remove(cmd) => cmd.run(),
        Command::RenderEdit(cmd) => cmd.run(),
        Command::EditTemplate(cmd) => cmd.run(),
        Command::Export { to } => to.run(),
        Command::Batch(cmd) => cmd.run(),
        Command::Bench { suite } => suite.run(),
        Command::CameraPath(cmd) => cmd.run(),
    }
}

/// The self-checks that tripped, last thing a command prints (stdout, so they stay beside the
/// summary they qualify), or a line saying every check passed.
fn print_warnings(warnings: &[objnerf::util::Warning]) {
    if warnings.is_empty() {
        println!("self-checks: all passed");
        return;
    }
    println!("self-checks: {} warning(s)", warnings.len());
    for w in warnings {
        println!("  warning {}", w.line());
    }
}

/// Print a report as pretty JSON on stdout.
fn print_json<T: serde::Serialize>(v: &T) {
    println!(
        "{}",
        serde_json::to_string_pretty(v).expect("reports serialise")
    );
}
