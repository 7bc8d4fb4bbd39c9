//! The `objnerf` command line: a thin layer over the library.

use clap::{Parser, Subcommand};
use objnerf::field::commands::{self as fc, DepthMode};
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
    /// Give a scene 2D-3D feature tracks with COLMAP: full reconstruction from a folder of images,
    /// or triangulation with the known poses of a posed scene (e.g. a transforms.json).
    Sfm {
        /// A folder of images (full reconstruction) or a posed scene (triangulation).
        input: PathBuf,
        /// Output folder: gets sparse/0/ (COLMAP binary) and images/ (a link to the images).
        #[arg(long)]
        out: PathBuf,
        /// Downscale images by this factor before feature extraction (the model is scaled back).
        #[arg(long, default_value_t = 1)]
        downscale: u32,
        /// Reconstruct from the images even when the input has poses.
        #[arg(long)]
        reconstruct: bool,
        /// auto (posed scenes: pairs chosen from the poses; else exhaustive), exhaustive, sequential, pairs.
        #[arg(long, default_value = "auto")]
        matcher: String,
        /// COLMAP camera model for full reconstruction.
        #[arg(long, default_value = "SIMPLE_RADIAL")]
        camera_model: String,
        /// Most SIFT features per image.
        #[arg(long, default_value_t = 8192)]
        max_features: u32,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// Replace the output folder if it exists.
        #[arg(long)]
        overwrite: bool,
    },
    /// The models directory ($OBJNERF_HOME, default <cache dir>/objnerf): install and list.
    Models {
        #[command(subcommand)]
        action: objnerf::segment::cli::ModelsCmd,
    },
    /// Segment objects in every view from clicks in one (Obj-NeRF's Algorithm 1): masks, segmented
    /// points, contact sheets and report.json.
    Segment(objnerf::segment::run::SegmentCmd),
    /// Click to mesh in one command: segment, train each object's field, mesh it, render a
    /// turntable; everything in one run folder with report.json.
    Extract(objnerf::extract::cli::ExtractCmd),
    /// Marching cubes on a trained model: a mesh with vertex colours as .glb, .obj or .ply.
    Mesh(objnerf::mesh::cli::MeshCmd),
    /// Segment one image with SAM from point and box prompts; writes the mask and an overlay.
    SegmentView(objnerf::segment::cli::SegmentViewCmd),
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        what: objnerf::segment::cli::BenchSamCmd,
    },
    /// The main job on the built-in demo scene: render it, extract one object from one click
    /// (segment, train, mesh, turntable) and score each stage against the scene's exact truth.
    Demo(objnerf::demo::job::DemoCmd),
    /// Export a run or a scene for other tools.
    Export {
        #[command(subcommand)]
        to: ExportTo,
    },
    /// Render the built-in demo scene with its exact truth (masks, depth, meshes, visibility).
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
    /// Train the object's radiance field (voxel grid) from masked views and save the model.
    Train {
        /// A COLMAP model folder, transforms.json or other scene.
        scene: PathBuf,
        /// The object's masks: 'alpha' (the images' alpha), a folder of masks, 'scene' (each
        /// view's mask_path) or 'truth:OBJECT' (the demo scene's true masks).
        #[arg(long)]
        masks: String,
        /// Where to write the model (.objf).
        #[arg(long)]
        out: PathBuf,
        /// Train on images downscaled by this factor (box filter).
        #[arg(long, default_value_t = 1)]
        downscale: u32,
        /// Stop after this many seconds of training.
        #[arg(long)]
        time_budget: Option<f64>,
        /// Depth supervision: sparse (the object's 3D points), dense (depth images) or none.
        #[arg(long, default_value = "none")]
        depth: DepthMode,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Most optimisation steps (the learning-rate schedule spans them).
        #[arg(long, default_value_t = 20_000)]
        steps: usize,
        /// Spherical-harmonic degree of the colour (0-2).
        #[arg(long, default_value_t = 1)]
        sh_degree: u32,
        /// Memory for the grid and optimiser state, MiB.
        #[arg(long, default_value_t = 1024)]
        memory_mb: usize,
        /// Continue training this model.
        #[arg(long)]
        resume: Option<PathBuf>,
    },
    /// Render a model from every view of a scene: RGB on white, alpha and depth PNGs.
    Render {
        model: PathBuf,
        #[arg(long)]
        scene: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Downscale of the scene's cameras (default: the one the model was trained at).
        #[arg(long)]
        downscale: Option<u32>,
    },
    /// Score a model on held-out views (PSNR, SSIM; composited on white).
    Eval {
        model: PathBuf,
        #[arg(long)]
        scene: PathBuf,
        #[arg(long, default_value = "alpha")]
        masks: String,
        #[arg(long)]
        downscale: Option<u32>,
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum ExportTo {
    /// A nerfstudio dataset: transforms.json, images, masks (0 = ignore), depth, sparse_pc.ply.
    Nerfstudio(ExportNerfstudio),
}

#[derive(clap::Args)]
struct ExportNerfstudio {
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
    #[arg(long)]
    overwrite: bool,
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
        Command::Sfm {
            input,
            out,
            downscale,
            reconstruct,
            matcher,
            camera_model,
            max_features,
            json,
            overwrite,
        } => {
            use objnerf::scene::sfm;
            if downscale == 0 {
                return Err(objnerf::Error::invalid("--downscale must be at least 1"));
            }
            let opts = sfm::SfmOptions {
                downscale,
                camera_model,
                max_features,
                matcher,
                overwrite,
                ..Default::default()
            };
            let report = match sfm::resolve_input(&input, reconstruct)? {
                sfm::SfmInput::Images(dir) => sfm::reconstruct(&dir, &out, &opts)?,
                sfm::SfmInput::Posed(scene) => sfm::triangulate(&scene, &out, &opts)?,
            };
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&report).expect("report serialises")
                );
            } else {
                println!(
                    "{}: {} of {} images registered, {} points (mean track length {:.2}) in {:.1} s -> {}",
                    report.mode, report.num_registered, report.num_images, report.num_points, report.mean_track_length, report.seconds, report.model_dir.display()
                );
            }
            Ok(())
        }
        Command::Models { action } => action.run(),
        Command::SegmentView(cmd) => cmd.run(),
        Command::Mesh(cmd) => cmd.run(),
        Command::Extract(cmd) => cmd.run(&std::env::args().collect::<Vec<_>>()),
        Command::Segment(cmd) => cmd.run(&std::env::args().collect::<Vec<_>>()),
        Command::Bench { what } => what.run(),
        Command::Demo(cmd) => cmd.run(),
        Command::Export {
            to: ExportTo::Nerfstudio(a),
        } => {
            use objnerf::export::nerfstudio::{export, ExportOptions};
            let (object, background) = (a.object, a.background);
            let opts = ExportOptions {
                object,
                background,
                downscale: a.downscale,
                overwrite: a.overwrite,
            };
            println!("{}", export(&a.input, &a.out, &opts)?.summary());
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
        Command::Train {
            scene,
            masks,
            out,
            downscale,
            time_budget,
            depth,
            seed,
            steps,
            sh_degree,
            memory_mb,
            resume,
        } => {
            let args = fc::TrainArgs {
                exclude_views: vec![],
                masks: fc::parse_masks(&masks, &scene)?,
                scene,
                out: out.clone(),
                downscale,
                time_budget,
                depth,
                seed,
                steps,
                setup: objnerf::field::SetupConfig {
                    sh_degree: sh_degree.min(2),
                    memory_budget: memory_mb << 20,
                    ..Default::default()
                },
                resume,
            };
            let mut bar = objnerf::util::progress::TrainProgress::new(steps, "train");
            let report = fc::train(&args, |s, secs| bar.update(s, secs))?;
            bar.finish();
            if let Some(s) = &report.setup {
                eprintln!(
                    "box {:?}..{:?} (the masks' visual hull); grid {:?} ({} vertices) because {}",
                    s.box_min, s.box_max, s.final_dims, s.final_vertices, s.why
                );
                eprintln!(
                    "rays: {} of {} kept ({:.1}% pruned: they miss the object's box)",
                    s.rays_kept,
                    s.rays_total,
                    100.0 * s.pruned_fraction
                );
            }
            eprintln!(
                "trained {} steps in {:.1} s ({:.0} rays/s, stopped by {}); batch PSNR {:.2} dB; {} occupied cells; {:.0} MiB; model {}",
                report.run.steps,
                report.run.seconds,
                report.run.rays_per_second,
                report.run.stopped_by,
                report.run.final_psnr,
                report.occupied_cells,
                report.memory_bytes as f64 / 1048576.0,
                out.display()
            );
            Ok(())
        }
        Command::Render {
            model,
            scene,
            out,
            downscale,
        } => {
            let n = fc::render(&model, &scene, &out, downscale)?;
            eprintln!("wrote {n} images to {}", out.display());
            Ok(())
        }
        Command::Eval {
            model,
            scene,
            masks,
            downscale,
            json,
        } => {
            let r = fc::eval(&model, &scene, &fc::parse_masks(&masks, &scene)?, downscale)?;
            if json {
                let v = serde_json::json!({
                    "psnr": r.psnr, "ssim": r.ssim, "num_views": r.num_views, "views": r.views,
                    "seconds": r.seconds,
                });
                println!("{v}");
            } else {
                println!(
                    "PSNR {:.2} dB, SSIM {:.4} over {} views",
                    r.psnr, r.ssim, r.num_views
                );
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
