//! What the two SAM benchmarks share: the run record, the images they time, and the two-panel
//! chart of every timed run. Used through `#[path = "support/sam.rs"] mod sam_bench;`.
#![allow(dead_code)]

use super::bench::{git_commit, machine, Machine, Stats};
use image::RgbImage;
use objnerf::models::ONNXRUNTIME_VERSION;
use objnerf::scene::io::read_rgb;
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
) -> std::result::Result<String, Box<dyn std::error::Error>> {
    use plotters::prelude::*;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 420)).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((1, 2));
        let blue = RGBColor(31, 119, 180);
        let orange = RGBColor(255, 127, 14);
        for (area, (title, ours, py)) in panels.iter().zip(panels_data) {
            let ms = |v: &Vec<f64>| v.iter().map(|s| s * 1e3).collect::<Vec<_>>();
            let (o, p) = (ms(&ours.runs), ms(&py.runs));
            let hi = o.iter().chain(&p).copied().fold(0.0, f64::max) * 1.15 + 1e-6;
            let n = o.len().max(p.len()).max(1);
            let mut c = ChartBuilder::on(area)
                .caption(
                    format!(
                        "{title}: {ratio_label} median {:.2} ({threads} threads)",
                        ours.median / py.median,
                    ),
                    ("sans-serif", 16),
                )
                .margin(12)
                .x_label_area_size(30)
                .y_label_area_size(50)
                .build_cartesian_2d(0f64..(n as f64 + 1.0), 0f64..hi)?;
            c.configure_mesh()
                .x_desc("run")
                .y_desc("ms")
                .disable_x_mesh()
                .draw()?;
            for (vals, med, colour, name) in [
                (&o, ours.median * 1e3, blue, names[0]),
                (&p, py.median * 1e3, orange, names[1]),
            ] {
                let pts: Vec<(f64, f64)> = vals
                    .iter()
                    .enumerate()
                    .map(|(i, &v)| (i as f64 + 1.0, v))
                    .collect();
                c.draw_series(LineSeries::new(pts.clone(), colour.stroke_width(1)))?
                    .label(name)
                    .legend(move |(x, y)| Circle::new((x + 8, y), 4, colour.filled()));
                c.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
                c.draw_series(DashedLineSeries::new(
                    vec![(0.0, med), (n as f64 + 1.0, med)],
                    6,
                    4,
                    colour.stroke_width(1),
                ))?;
            }
            c.configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .position(SeriesLabelPosition::LowerRight)
                .draw()?;
        }
        root.present()?;
    }
    Ok(svg)
}
