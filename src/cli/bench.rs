//! `objnerf bench ...`: benchmark suites that run whole jobs and score them against truth.

use crate::cli::progress_bars::Bars;
use clap::{Args, Subcommand};
use objnerf::bench::stability::{run_suite, StabilityOptions, Verdict};
use objnerf::Result;
use std::path::PathBuf;

#[derive(Subcommand)]
pub enum BenchCmd {
    /// The perturbation suite: fewer views, pose noise, image noise, exposure, motion blur,
    /// 50 random clicks, hard objects (out of frame, occluded, textureless, a look-alike),
    /// several objects; each case scored against the truth and classified ok / detected /
    /// silent / false alarm from its scores and its own warnings. Writes stability.json,
    /// stability.md and two SVG charts into --out.
    Stability(StabilityCmd),
}

impl BenchCmd {
    pub fn run(self) -> Result<()> {
        match self {
            BenchCmd::Stability(c) => c.run(),
        }
    }
}

#[derive(Args)]
pub struct StabilityCmd {
    /// The suite's folder (scenes, cases, results); reused scenes are not rendered again.
    #[arg(long)]
    out: PathBuf,
    /// A few cases only (what the test suite runs).
    #[arg(long)]
    quick: bool,
    /// Training steps per object.
    #[arg(long, default_value_t = StabilityOptions::default().steps)]
    steps: usize,
    #[arg(long, default_value_t = StabilityOptions::default().seed)]
    seed: u64,
    /// lego triangulated by `objnerf sfm` (its COLMAP model), to add lego's cases.
    #[arg(long)]
    lego: Option<PathBuf>,
    /// Run only the cases whose id contains this (e.g. pose, click_inside).
    #[arg(long)]
    only: Option<String>,
    #[command(flatten)]
    sam: super::models::SamPrecisionArg,
}

impl StabilityCmd {
    fn run(self) -> Result<()> {
        let opts = StabilityOptions {
            out: self.out,
            quick: self.quick,
            seed: self.seed,
            steps: self.steps,
            lego: self.lego,
            only: self.only,
        };
        let seg = self.sam.segmenter()?;
        let command: Vec<String> = std::env::args().collect();
        let r = run_suite(&opts, &seg, &command.join(" "), &Bars::default())?;
        for c in &r.cases {
            let o = c.objects.first();
            println!(
                "{:<22} {:<12} mIoU {:>5} PSNR {:>5} Chamfer {:>6}  {}{}",
                c.spec.id,
                c.verdict.name(),
                o.and_then(|o| o.miou)
                    .map_or("-".into(), |v| format!("{v:.3}")),
                o.and_then(|o| o.psnr)
                    .map_or("-".into(), |v| format!("{v:.1}")),
                o.and_then(|o| o.chamfer)
                    .map_or("-".into(), |v| format!("{:.2}%", 100.0 * v)),
                c.warnings
                    .iter()
                    .map(|w| w.code)
                    .collect::<Vec<_>>()
                    .join(","),
                c.error
                    .as_deref()
                    .map(|e| format!(" error: {e}"))
                    .unwrap_or_default()
            );
        }
        let s = &r.summary;
        println!(
            "{} cases ({} scored): {:?}; silent {}; false alarms {:.1}%; {:.0} s wall, {:.0} s CPU",
            s.cases,
            s.scored,
            s.counts,
            s.silent,
            100.0 * s.false_alarm_rate,
            s.seconds,
            s.cpu_seconds
        );
        if let (Some(m), Some(p)) = (s.click_median_miou, s.click_p10_miou) {
            println!(
                "clicks inside: median mIoU {m:.3}, 10th percentile {p:.3}; {} below the floor, {} of them flagged",
                s.clicks_below_floor, s.clicks_below_floor_flagged
            );
        }
        println!("results: {}", opts.out.join("stability.md").display());
        if r.cases.iter().any(|c| c.verdict == Verdict::Silent) {
            return Err(objnerf::Error::invalid(
                "the suite found silent failures (see stability.md)",
            ));
        }
        Ok(())
    }
}
