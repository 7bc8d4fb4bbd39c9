//! Object removal on the demo scene: PSNR inside the removed mug's true mask (grown by 4 px) and
//! over the whole frame, on the held-out views (every 6th), against training time, for the
//! scene field with each fill of the never-seen hole (pattern, smooth, none), beside the per-view 2D
//! inpainting baseline (OpenCV's Telea, `examples/removal_telea.py`, in its own venv). Each
//! removal is its own `objnerf remove` process, so each report has its own peak RSS. Writes
//! `OUT/removal_bench.json` and `OUT/removal_bench.svg`.
//!
//! cargo build --release --examples && target/release/examples/removal_bench \
//!     [--steps 1000,2000,4000] [--downscale 1] [--scene DEMO_DIR --segment SEGMENT_DIR]
//!     [--out examples/results] [--chart-only]
//!
//! `--chart-only` redraws `OUT/removal_bench.svg` from `OUT/removal_bench.json`.
//!
//! Without `--scene` the default demo scene is made and the mug segmented from its one click in a
//! temporary folder.

#[path = "support/bench.rs"]
mod bench;

use objnerf::util::chart::{layers, series, svg, ChartResult, Panel, SeriesLabelPosition};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

fn arg(name: &str) -> Option<String> {
    let a: Vec<String> = std::env::args().collect();
    a.iter()
        .position(|x| x == name)
        .and_then(|i| a.get(i + 1).cloned())
}

fn main() {
    let out_dir = PathBuf::from(arg("--out").unwrap_or("examples/results".into()));
    if std::env::args().any(|a| a == "--chart-only") {
        let json_path = out_dir.join("removal_bench.json");
        let text = std::fs::read_to_string(&json_path).expect("read removal_bench.json");
        let result: Value = serde_json::from_str(&text).expect("parse removal_bench.json");
        chart(&result, &out_dir.join("removal_bench.svg")).expect("chart");
        return;
    }
    let steps: Vec<usize> = arg("--steps")
        .unwrap_or("1000,2000,4000".into())
        .split(',')
        .map(|s| s.parse().expect("--steps N,N,..."))
        .collect();
    let downscale = arg("--downscale").unwrap_or("1".into());
    let tmp = tempfile::tempdir().expect("temp dir");
    let (scene, segment) = match (arg("--scene"), arg("--segment")) {
        (Some(s), Some(g)) => (PathBuf::from(s), PathBuf::from(g)),
        _ => make_scene_and_segment(tmp.path()),
    };
    let held: Vec<String> = (0..36)
        .filter(|i| i % 6 == 3)
        .map(|i| format!("view_{i:03}.png"))
        .collect();
    let mut runs = Vec::new();
    for &s in &steps {
        for fill in ["pattern", "smooth", "none"] {
            let dir = tmp.path().join(format!("rm_{s}_{fill}"));
            let mut a: Vec<String> = ["remove", &scene.display().to_string(), "--segment"]
                .map(String::from)
                .to_vec();
            a.push(segment.display().to_string());
            a.extend(
                [
                    "--object",
                    "mug",
                    "--hold-out-every",
                    "6",
                    "--time-budget",
                    "1000000",
                ]
                .map(String::from),
            );
            a.extend([
                "--steps".to_string(),
                s.to_string(),
                "--out".to_string(),
                dir.display().to_string(),
            ]);
            a.extend(["--fill".into(), fill.into()]);
            let t = std::time::Instant::now();
            bench::run_objnerf(&a);
            let wall = t.elapsed().as_secs_f64();
            let r: Value =
                serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap())
                    .unwrap();
            let rec = json!({
                "fill": fill,
                "steps": s,
                "wall_seconds": wall,
                "train_seconds": r["seconds"]["train"],
                "psnr": r["scores"]["psnr"],
                "hole_psnr": r["scores"]["hole_psnr"][0][1],
                "filled_px": r["filled_px"],
                "patterned_px": r["patterned_px"],
                "unseen_fraction": unseen_fraction(&r),
                "peak_rss_mib": r["peak_rss_mib"],
                "load_average": bench::machine().load_average,
            });
            eprintln!("{rec}");
            runs.push(rec);
        }
    }
    let telea = telea(&scene, &segment, &held, &downscale);
    eprintln!("telea: {telea}");
    let result = json!({
        "what": "demo scene, mug removed from its one-click segmentation; PSNR on the 6 held-out views against truth/removed/mug",
        "downscale": downscale,
        "command": std::env::args().collect::<Vec<_>>().join(" "),
        "machine": bench::machine(),
        "commit": bench::git_commit(),
        "runs": runs,
        "telea": telea,
    });
    std::fs::create_dir_all(&out_dir).expect("out dir");
    let json_path = out_dir.join("removal_bench.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&result).unwrap()).expect("write JSON");
    chart(&result, &out_dir.join("removal_bench.svg")).expect("chart");
    eprintln!("wrote {} and removal_bench.svg", json_path.display());
}

/// The fraction of the held-out views' hole pixels that no training view saw.
fn unseen_fraction(r: &Value) -> f64 {
    let held: Vec<&str> = r["held_out"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    let (mut hole, mut unseen) = (0.0, 0.0);
    for h in r["holes"].as_array().unwrap() {
        if held.contains(&h["view"].as_str().unwrap_or("")) {
            hole += h["hole_px"].as_f64().unwrap_or(0.0);
            unseen += h["unseen_px"].as_f64().unwrap_or(0.0);
        }
    }
    unseen / hole.max(1.0)
}

fn make_scene_and_segment(tmp: &Path) -> (PathBuf, PathBuf) {
    let scene = tmp.join("demo");
    bench::run_objnerf(&[
        "demo-scene".into(),
        "--out".into(),
        scene.display().to_string(),
    ]);
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(scene.join("truth/objects.json")).unwrap())
            .unwrap();
    let mug = truth["objects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|o| o["name"] == "mug")
        .unwrap();
    let seg = tmp.join("seg");
    bench::run_objnerf(&[
        "segment".into(),
        scene.display().to_string(),
        "--view".into(),
        mug["view"].as_str().unwrap().into(),
        "--object".into(),
        "mug".into(),
        "--point".into(),
        format!("{},{}", mug["click"][0], mug["click"][1]),
        "--out".into(),
        seg.display().to_string(),
    ]);
    (scene, seg)
}

/// Telea on the held-out views, over the region the removal leaves out.
fn telea(scene: &Path, segment: &Path, views: &[String], downscale: &str) -> Value {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let py = bench::ensure_venv(
        &root.join("target/venv-opencv"),
        "import cv2, numpy",
        &["opencv-python-headless", "numpy"],
    )
    .expect("the baseline's venv");
    let out = Command::new(py)
        .arg(root.join("examples/removal_telea.py"))
        .arg(scene)
        .arg(segment)
        .args([
            "--objects",
            "mug",
            "--views",
            &views.join(","),
            "--downscale",
            downscale,
        ])
        .output()
        .expect("run removal_telea.py");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).expect("its JSON");
    json!({
        "hole_psnr": v["psnr_inside"]["mug"],
        "psnr": v["psnr_frame_mean"],
        "seconds": v["seconds"],
    })
}

fn chart(result: &Value, path: &Path) -> ChartResult<()> {
    let runs = result["runs"].as_array().cloned().unwrap_or_default();
    let name = |r: &Value| {
        match r["fill"].as_str() {
            Some("pattern") => "scene field, pattern fill",
            Some("smooth") => "scene field, smooth fill",
            _ => "scene field, no fill",
        }
        .to_string()
    };
    let telea = &result["telea"];
    let panel = |title: &str, key: &str| {
        let mut s = series(&runs, name, |r| {
            Some((r["train_seconds"].as_f64()?, r[key].as_f64()?))
        });
        if let (Some(x), Some(y)) = (telea["seconds"].as_f64(), telea[key].as_f64()) {
            s.push(("Telea 2D inpainting (per view)".into(), vec![(x, y)]));
        }
        Panel::fitted(
            title,
            "training seconds (2-core machine)",
            "PSNR (dB), held-out views",
            layers(s),
        )
    };
    let mut inside = panel(
        "mug removed: PSNR inside its true mask (+4 px)",
        "hole_psnr",
    );
    // The fills' lines lie above, the unfilled one and Telea below: the legend between them.
    inside.legend = SeriesLabelPosition::MiddleRight;
    let panels = [inside, panel("mug removed: full-frame PSNR", "psnr")];
    std::fs::write(path, svg((1100, 480), 1, &panels)?)?;
    Ok(())
}
