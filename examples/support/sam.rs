//! What the two SAM benchmarks share: the run record, the images they time, and the two-panel
//! chart of every timed run. Used through `#[path = "support/sam.rs"] mod sam_bench;`.
#![allow(dead_code)]

use super::bench::{git_commit, machine, Machine, Stats};
use image::RgbImage;
use objnerf::models::ONNXRUNTIME_VERSION;
use objnerf::scene::io::read_rgb;
use objnerf::util::chart::{svg, ChartResult, Layer, Panel, RGBColor};
use objnerf::Result;
use std::path::PathBuf;

/// What both SAM benchmarks are told: the images, how many runs, threads, where results go.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Images to encode (cycled run by run). Empty: one synthetic 800 x 600 image.
    #[arg(long = "image")]
    pub images: Vec<PathBuf>,
    /// Timed runs per side (at least 5), after one untimed warm-up each.
    #[arg(long, default_value_t = 7)]
    pub runs: usize,
    /// 0 = all available cores; the same number goes to both sides.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Where the JSON and the chart go.
    #[arg(long, default_value = "runs/bench")]
    pub out_dir: PathBuf,
}

/// What a benchmark report says about its run: the command, machine, commit, runtime, threads,
/// images and number of runs.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RunInfo {
    pub command: String,
    pub machine: Machine,
    pub git_commit: Option<String>,
    pub onnxruntime_version: String,
    pub threads: usize,
    pub images: Vec<String>,
    pub runs: usize,
}

impl RunInfo {
    pub fn new(threads: usize, images: Vec<String>, runs: usize) -> Self {
        RunInfo {
            command: std::env::args().collect::<Vec<_>>().join(" "),
            machine: machine(),
            git_commit: git_commit(),
            onnxruntime_version: ONNXRUNTIME_VERSION.into(),
            threads,
            images,
            runs,
        }
    }
}

/// The images to time and their names; a synthetic image when none is given.
pub fn bench_images(paths: &[PathBuf]) -> Result<(Vec<RgbImage>, Vec<String>)> {
    let mut images = Vec::new();
    let mut names = Vec::new();
    for p in paths {
        images.push(read_rgb(p)?);
        names.push(p.display().to_string());
    }
    if images.is_empty() {
        images.push(synthetic());
        names.push("synthetic 800x600".into());
    }
    Ok((images, names))
}

/// A synthetic image (smooth colours and a disc).
fn synthetic() -> RgbImage {
    RgbImage::from_fn(800, 600, |x, y| {
        let d = ((x as f32 - 400.0).powi(2) + (y as f32 - 300.0).powi(2)).sqrt();
        if d < 150.0 {
            image::Rgb([200, 40, 40])
        } else {
            image::Rgb([(x / 4) as u8, (y / 3) as u8, 128])
        }
    })
}

/// Two panels (e.g. encoder, decoder): every timed run of two contenders `names`, in
/// milliseconds, with the medians as dashed lines; each caption gives the ratio of medians.
pub fn chart_svg(
    panels_data: [(&str, &Stats, &Stats); 2],
    names: [&str; 2],
    ratio_label: &str,
    threads: usize,
) -> ChartResult<String> {
    let colours = [RGBColor(31, 119, 180), RGBColor(255, 127, 14)];
    let panels: Vec<Panel> = panels_data
        .iter()
        .map(|(title, ours, py)| {
            let mut layers = Vec::new();
            for ((stats, name), colour) in [(*ours, names[0]), (*py, names[1])]
                .into_iter()
                .zip(colours)
            {
                let runs: Vec<(f64, f64)> = stats
                    .runs
                    .iter()
                    .enumerate()
                    .map(|(i, s)| (i as f64 + 1.0, s * 1e3))
                    .collect();
                let x = 0.0..runs.len() as f64 + 1.0;
                layers.push(Layer::new(name, colour, runs));
                layers.push(Layer::level(None, colour, stats.median * 1e3, &x));
            }
            let mut p = Panel::fitted(
                &format!(
                    "{title}: {ratio_label} median {:.2} ({threads} threads)",
                    ours.median / py.median
                ),
                "run",
                "ms",
                layers,
            );
            p.y.start = 0.0;
            p
        })
        .collect();
    svg((900, 420), 1, &panels)
}
