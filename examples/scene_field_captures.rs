//! Scene fields on real captures: held-out PSNR and SSIM against training time, with rays per
//! second and peak RSS at every point, beside the published figures for the same scenes. Each
//! point is its own `objnerf train --scene-field --json` process (so its own peak RSS), scored
//! by `objnerf eval` on the views the same hold-out rule left out. Writes
//! `OUT/scene_field_captures.json` and `OUT/scene_field_captures.svg`.
//!
//! cargo build --release --examples && target/release/examples/scene_field_captures \
//!     --capture fern=DATA/llff/fern@llff [--capture NAME=PATH[@RULE[@S,S,...]] ...] \
//!     [--budgets 150,300,600] [--out examples/results] [--chart-only]
//!
//! RULE is a `--hold-out` rule (`llff`, N, `none`; default `llff`); S,S,... the capture's own
//! budgets (default: `--budgets`). The last panel splits each capture's longest run's time into
//! the trainer's parts (`RunSummary::phases`). LLFF scenes named as the
//! dataset names them (fern, flower, fortress, horns, leaves, orchids, room, trex) are charted
//! with NeRF's and Plenoxels' published held-out PSNR (504x378 is half the resolution they
//! report at; see examples/results/scene_field.md). `--chart-only` redraws the chart from the
//! JSON.

#[path = "support/bench.rs"]
mod bench;

use objnerf::util::chart::{palette, svg, ChartResult, Layer, Mark, Panel, SeriesLabelPosition};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Published held-out PSNR on the LLFF scenes: (scene, NeRF, Plenoxels), from the NeRF paper's
/// and the Plenoxels paper's per-scene tables (every 8th view held out).
const PUBLISHED: [(&str, f64, f64); 8] = [
    ("fern", 25.17, 25.46),
    ("flower", 27.40, 27.83),
    ("fortress", 31.16, 31.09),
    ("horns", 27.45, 27.58),
    ("leaves", 20.92, 21.41),
    ("orchids", 20.36, 20.24),
    ("room", 32.70, 30.22),
    ("trex", 26.80, 26.48),
];

fn run_json(args: &[String]) -> Value {
    let out = bench::run_objnerf(args);
    serde_json::from_slice(&out.stdout).expect("objnerf --json prints JSON")
}

fn args_named(name: &str) -> Vec<String> {
    let a: Vec<String> = std::env::args().collect();
    a.iter()
        .enumerate()
        .filter(|(_, x)| *x == name)
        .filter_map(|(i, _)| a.get(i + 1).cloned())
        .collect()
}

fn main() {
    let out_dir = PathBuf::from(
        args_named("--out")
            .pop()
            .unwrap_or("examples/results".into()),
    );
    let json_path = out_dir.join("scene_field_captures.json");
    let svg_path = out_dir.join("scene_field_captures.svg");
    if std::env::args().any(|a| a == "--chart-only") {
        let text = std::fs::read_to_string(&json_path).expect("read scene_field_captures.json");
        let result: Value = serde_json::from_str(&text).expect("parse the JSON");
        chart(&result, &svg_path).expect("chart");
        return;
    }
    let budgets: Vec<f64> = args_named("--budgets")
        .pop()
        .unwrap_or("150,300,600".into())
        .split(',')
        .map(|s| s.parse().expect("--budgets S,S,..."))
        .collect();
    let captures: Vec<(String, PathBuf, String, Vec<f64>)> = args_named("--capture")
        .iter()
        .map(|c| {
            let (name, rest) = c
                .split_once('=')
                .expect("--capture NAME=PATH[@RULE[@S,...]]");
            let mut parts = rest.split('@');
            let path = parts.next().expect("a path");
            let rule = parts.next().unwrap_or("llff");
            let own: Vec<f64> = parts
                .next()
                .map(|b| {
                    b.split(',')
                        .map(|s| s.parse().expect("budgets S,S,..."))
                        .collect()
                })
                .unwrap_or_else(|| budgets.clone());
            (name.to_string(), PathBuf::from(path), rule.to_string(), own)
        })
        .collect();
    assert!(
        !captures.is_empty(),
        "give at least one --capture NAME=PATH[@RULE]"
    );
    let tmp = tempfile::tempdir().expect("temp dir");
    let mut runs = Vec::new();
    for (name, path, rule, budgets) in &captures {
        for &budget in budgets {
            let model = tmp.path().join(format!("{name}_{budget}.objf"));
            let scene = path.display().to_string();
            let train = run_json(&[
                "train".into(),
                scene.clone(),
                "--scene-field".into(),
                "--hold-out".into(),
                rule.clone(),
                "--time-budget".into(),
                budget.to_string(),
                "--out".into(),
                model.display().to_string(),
                "--json".into(),
            ]);
            let eval = run_json(&[
                "eval".into(),
                model.display().to_string(),
                "--scene".into(),
                scene,
                "--hold-out".into(),
                rule.clone(),
                "--json".into(),
            ]);
            let run = json!({
                "capture": name, "hold_out": rule, "budget_s": budget,
                "space": train["setup"]["space"]["kind"],
                "train_seconds": train["run"]["seconds"], "steps": train["run"]["steps"],
                "rays_per_second": train["run"]["rays_per_second"],
                "samples_per_ray": train["run"]["samples_per_ray"],
                "phase_seconds": train["run"]["phases"],
                "occupied_cells": train["occupied_cells"], "memory_bytes": train["memory_bytes"],
                "peak_rss_mib": train["peak_rss_mib"],
                "fit_psnr": train["scene_fit"]["psnr"],
                "heldout_psnr": eval["psnr"], "heldout_ssim": eval["ssim"],
                "heldout_views": eval["num_views"],
            });
            eprintln!("{run}");
            runs.push(run);
        }
    }
    let published: Vec<Value> = PUBLISHED
        .iter()
        .map(|(s, nerf, plenoxels)| json!({"scene": s, "nerf": nerf, "plenoxels": plenoxels}))
        .collect();
    let result = json!({
        "machine": objnerf::util::machine::machine(),
        "command": std::env::args().collect::<Vec<_>>().join(" "),
        "runs": runs,
        "published": published,
    });
    std::fs::create_dir_all(&out_dir).expect("create the output folder");
    std::fs::write(
        &json_path,
        serde_json::to_string_pretty(&result).expect("JSON"),
    )
    .expect("write the JSON");
    chart(&result, &svg_path).expect("chart");
}

/// One panel per capture: held-out PSNR against training time, with the published figures as
/// levels; a panel of rays per second against time for every capture, and one of where each
/// capture's longest run spent its time.
fn chart(result: &Value, path: &Path) -> ChartResult<()> {
    let runs = result["runs"].as_array().cloned().unwrap_or_default();
    let mut names: Vec<String> = Vec::new();
    for r in &runs {
        let n = r["capture"].as_str().unwrap_or("?").to_string();
        if !names.contains(&n) {
            names.push(n);
        }
    }
    let points = |name: &str, key: &str| -> Vec<(f64, f64)> {
        runs.iter()
            .filter(|r| r["capture"].as_str() == Some(name))
            .filter_map(|r| Some((r["train_seconds"].as_f64()?, r[key].as_f64()?)))
            .collect()
    };
    let mut panels = Vec::new();
    for (i, name) in names.iter().enumerate() {
        let pts = points(name, "heldout_psnr");
        let xmax = pts.iter().map(|p| p.0).fold(60.0, f64::max) * 1.1;
        let range = 0.0..xmax;
        let mut layers = vec![Layer::new("objnerf scene field", palette(i), pts)];
        if let Some((_, nerf, plenoxels)) = PUBLISHED.iter().find(|p| p.0 == name) {
            layers.push(Layer::level(
                Some("NeRF (published)"),
                palette(6),
                *nerf,
                &range,
            ));
            layers.push(Layer::level(
                Some("Plenoxels (published)"),
                palette(7),
                *plenoxels,
                &range,
            ));
        }
        panels.push(Panel::fitted(
            &format!("{name}: held-out PSNR"),
            "training seconds (2-core machine)",
            "PSNR (dB)",
            layers,
        ));
    }
    let speed: Vec<Layer> = names
        .iter()
        .enumerate()
        .map(|(i, n)| Layer::new(n.clone(), palette(i), points(n, "rays_per_second")))
        .collect();
    panels.push(Panel::fitted(
        "training rays per second",
        "training seconds (2-core machine)",
        "rays / s",
        speed,
    ));
    // The runs end at the right, near the bottom when short of the published levels: the
    // legend at the lower right hid them.
    for p in &mut panels {
        p.legend = SeriesLabelPosition::LowerLeft;
    }
    if let Some(p) = time_panel(&runs, &names) {
        panels.push(p);
    }
    let cols = 2;
    let rows = panels.len().div_ceil(cols);
    std::fs::write(path, svg((1100, 400 * rows as u32), rows, &panels)?)?;
    Ok(())
}

/// Where each capture's longest run spent its training time, in milliseconds a thousand rays
/// (what the rays-per-second line reads), stacked by part: marching the rays forward and back,
/// the gradient's scatter into the grid (with Adam), TV, pruning and averaging, and the rest
/// (growing the grid between stages, the loop). None for runs recorded before the parts were.
fn time_panel(runs: &[Value], names: &[String]) -> Option<Panel> {
    const PARTS: [(&str, &str); 4] = [
        ("rays", "rays forward + backward"),
        ("scatter", "gradient scatter + Adam"),
        ("tv", "TV"),
        ("upkeep", "pruning, averaging"),
    ];
    let mut stacks: Vec<Vec<(f64, f64)>> = vec![Vec::new(); PARTS.len() + 1];
    for (i, name) in names.iter().enumerate() {
        let Some(r) = runs
            .iter()
            .filter(|r| r["capture"].as_str() == Some(name.as_str()))
            .filter(|r| r["phase_seconds"].is_object())
            .max_by(|a, b| {
                let t = |r: &Value| r["train_seconds"].as_f64().unwrap_or(0.0);
                t(a).total_cmp(&t(b))
            })
        else {
            continue;
        };
        let seconds = r["train_seconds"].as_f64()?;
        let rays = r["rays_per_second"].as_f64()? * seconds;
        let ms = 1e6 / rays.max(1.0);
        let mut total = 0.0;
        for (k, (key, _)) in PARTS.iter().enumerate() {
            total += r["phase_seconds"][key].as_f64().unwrap_or(0.0) * ms;
            stacks[k].push((i as f64 + 1.0, total));
        }
        stacks[PARTS.len()].push((i as f64 + 1.0, seconds * ms));
    }
    if stacks[0].is_empty() {
        return None;
    }
    let names_of_parts: Vec<&str> = PARTS.iter().map(|p| p.1).chain(["the rest"]).collect();
    // The tallest (the whole) first, so each shorter part's bar is drawn over it.
    let layers: Vec<Layer> = (names_of_parts.into_iter().zip(stacks).enumerate().rev())
        .map(|(k, (part, pts))| Layer::new(part, palette(k + 10), pts).mark(Mark::Bars(0.6)))
        .collect();
    let top = layers[0].points.iter().map(|p| p.1).fold(0.0, f64::max);
    let order: Vec<String> = (names.iter().enumerate())
        .map(|(i, n)| format!("{} {n}", i + 1))
        .collect();
    let mut panel = Panel::fitted(
        "where the longest run's time went",
        &format!("capture ({})", order.join(", ")),
        "ms a thousand rays",
        layers,
    );
    panel.x = 0.4..names.len() as f64 + 0.6;
    panel.y = 0.0..top * 1.35;
    panel.legend = SeriesLabelPosition::UpperRight;
    Some(panel)
}
