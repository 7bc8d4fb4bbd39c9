//! The ONNX files objnerf writes from `mobile_sam.pt` against the
//! PyTorch exporter's (`../shared/models/mobile_sam`), both run by our ONNX Runtime path with the
//! same threads, on the same prepared inputs, interleaved run by run (who goes first alternates)
//! so that load from other work on the machine hits both alike. Writes JSON and an SVG chart.
//!
//! cargo run --release --example bench_sam_convert -- [--reference DIR] [--image IMG]... [--runs N]

#[path = "support/bench.rs"]
mod bench;
#[path = "support/sam.rs"]
mod sam_bench;

use bench::Stats;
use clap::Parser;
use objnerf::models::ModelsDir;
use objnerf::sam::convert::write_mobile_sam_onnx;
use objnerf::sam::preprocess::encoder_input;
use objnerf::sam::{Prompts, Segmenter, SegmenterOptions};
use objnerf::util::atomic::write_bytes_atomic;
use objnerf::util::mem::peak_rss_mib;
use objnerf::{Error, Result};
use sam_bench::{bench_images, chart_svg, BenchArgs, RunInfo};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser, Debug)]
pub struct ConvertBenchOptions {
    /// The folder with the reference encoder.onnx and decoder.onnx.
    #[arg(long, default_value = "../shared/models/mobile_sam")]
    pub reference: PathBuf,
    #[command(flatten)]
    pub common: BenchArgs,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct ModelTimes {
    pub name: String,
    pub encoder_file: PathBuf,
    pub encoder_sha256: String,
    pub load_seconds: f64,
    pub encoder: Stats,
    pub decoder: Stats,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct ConvertBenchReport {
    #[serde(flatten)]
    pub run: RunInfo,
    /// Reading the checkpoint and writing both graphs.
    pub convert_seconds: f64,
    pub converted: ModelTimes,
    pub reference: ModelTimes,
    /// converted / reference, medians.
    pub encoder_ratio: f64,
    pub decoder_ratio: f64,
    /// Median of the per-round ratios (the two run back to back in each round).
    pub encoder_paired_ratio: f64,
    /// The goal: our encoder within 10% of the reference's.
    pub encoder_goal_met: bool,
    /// Largest |difference| between the two embeddings of the first image.
    pub embedding_max_abs_diff: f64,
    /// This process's peak resident memory (VmHWM), MiB.
    pub peak_rss_mib: Option<u64>,
    pub json: PathBuf,
    pub chart: PathBuf,
}

pub fn bench_convert(dir: &ModelsDir, opts: &ConvertBenchOptions) -> Result<ConvertBenchReport> {
    let runs = opts.common.runs.max(5);
    let lib = dir.require_library()?;
    let ckpt = dir.checkpoint();
    let work = tempfile::Builder::new()
        .prefix("objnerf-bench-convert-")
        .tempdir()
        .map_err(|e| Error::io(std::env::temp_dir(), e))?;
    let t0 = Instant::now();
    let [enc, dec, _] = write_mobile_sam_onnx(&ckpt, work.path())?;
    let convert_seconds = t0.elapsed().as_secs_f64();

    let so = SegmenterOptions {
        threads: opts.common.threads,
        disk_cache: None,
    };
    let (ref_enc, ref_dec) = (
        opts.reference.join("encoder.onnx"),
        opts.reference.join("decoder.onnx"),
    );
    let ours = Segmenter::from_files(&lib, &enc, &dec, &so)?;
    let theirs = Segmenter::from_files(&lib, &ref_enc, &ref_dec, &so)?;

    let (images, names) = bench_images(&opts.common.images)?;
    let inputs: Vec<Vec<f32>> = images.iter().map(|i| encoder_input(i).0).collect();
    // Both decoders get the reference's embedding and one click at the image centre.
    let mut embs = Vec::new();
    for img in &images {
        let p = Prompts::click(img.width() as f32 / 2.0, img.height() as f32 / 2.0);
        embs.push((theirs.embed(img)?, p));
    }
    let mine = ours.embed(&images[0])?;
    let diff = mine
        .data
        .iter()
        .zip(&embs[0].0.data)
        .map(|(a, b)| (a - b).abs() as f64)
        .fold(0.0, f64::max);
    // Warm-up (untimed).
    for s in [&ours, &theirs] {
        s.run_encoder(&inputs[0])?;
        s.predict_allow_empty(&embs[0].0, &embs[0].1)?;
    }

    let (mut oe, mut re, mut od, mut rd) = (vec![], vec![], vec![], vec![]);
    for r in 0..runs {
        let i = r % images.len();
        eprintln!("run {}/{runs}", r + 1);
        let order = if r % 2 == 0 { [0, 1] } else { [1, 0] };
        for who in order {
            let (s, e, d) = if who == 0 {
                (&ours, &mut oe, &mut od)
            } else {
                (&theirs, &mut re, &mut rd)
            };
            e.push(s.run_encoder(&inputs[i])?.1);
            for _ in 0..3 {
                d.push(
                    s.predict_allow_empty(&embs[i].0, &embs[i].1)?
                        .decoder_seconds,
                );
            }
        }
    }

    let times = |name: &str, s: &Segmenter, file: PathBuf, e: &[f64], d: &[f64]| ModelTimes {
        name: name.into(),
        encoder_file: file,
        encoder_sha256: s.model_sha256().into(),
        load_seconds: s.load_seconds,
        encoder: Stats::of(e),
        decoder: Stats::of(d),
    };
    let converted = times("objnerf (from mobile_sam.pt)", &ours, enc, &oe, &od);
    let reference = times("torch.onnx export", &theirs, ref_enc, &re, &rd);
    let encoder_ratio = converted.encoder.median / reference.encoder.median;
    let paired: Vec<f64> = oe.iter().zip(&re).map(|(a, b)| a / b).collect();
    let json = opts.common.out_dir.join("bench_sam_convert.json");
    let chart = opts.common.out_dir.join("bench_sam_convert.svg");
    let report = ConvertBenchReport {
        run: RunInfo::new(ours.threads(), names, runs),
        convert_seconds,
        encoder_ratio,
        decoder_ratio: converted.decoder.median / reference.decoder.median,
        encoder_paired_ratio: Stats::of(&paired).median,
        encoder_goal_met: encoder_ratio <= 1.1,
        embedding_max_abs_diff: diff,
        peak_rss_mib: Some(peak_rss_mib()),
        converted,
        reference,
        json: json.clone(),
        chart: chart.clone(),
    };
    let text = serde_json::to_string_pretty(&report).expect("report serialises");
    write_bytes_atomic(&json, text.as_bytes())?;
    let svg = chart_svg(
        [
            (
                "encoder",
                &report.converted.encoder,
                &report.reference.encoder,
            ),
            (
                "decoder",
                &report.converted.decoder,
                &report.reference.decoder,
            ),
        ],
        ["objnerf's ONNX", "torch.onnx export"],
        "ours/export",
        report.run.threads,
    )
    .map_err(|e| Error::invalid(format!("chart: {e}")))?;
    write_bytes_atomic(&chart, svg.as_bytes())?;
    Ok(report)
}

fn main() -> Result<()> {
    let opts = ConvertBenchOptions::parse();
    let r = bench_convert(&ModelsDir::from_env()?, &opts)?;
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
    Ok(())
}
