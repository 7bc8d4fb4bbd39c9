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
//! budgets (default: `--budgets`). LLFF scenes named as the
//! dataset names them (fern, flower, fortress, horns, leaves, orchids, room, trex) are charted
//! with NeRF's and Plenoxels' published held-out PSNR (504x378 is half the resolution they
//! report at; see examples/results/scene_field.md). `--chart-only` redraws the chart from the
//! JSON.

#[path = "support/bench.rs"]
mod bench;

use objnerf::util::chart::{palette, svg, ChartResult, Layer, Panel, SeriesLabelPosition};
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
/// levels; a last panel of rays per second against time for every capture.
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
    let cols = 2;
    let rows = panels.len().div_ceil(cols);
    std::fs::write(path, svg((1100, 400 * rows as u32), rows, &panels)?)?;
    Ok(())
}
