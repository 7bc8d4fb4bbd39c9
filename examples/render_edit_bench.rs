//! `objnerf render-edit` speed on the demo scene: frames per second at 320x240 and 640x480 for
//! the background alone, with one object and with four, and time against PSNR (against the exact
//! truth) for the sample step, on a 24-frame orbit like the demo's cameras.
//!
//!     cargo run --release --example render_edit_bench -- [--fields DIR] [--out examples/results]
//!
//! `--fields DIR` holds the demo scene and its trained fields (`demo::fields::ensure_edit_fields`:
//! made there when missing, ~10 CPU-minutes for the background). Writes `render_edit.json` and
//! `render_edit.svg`. Rendering is timed alone (the fields are loaded before the clock starts);
//! CPU seconds are this process's, so a loaded machine shows in wall time, not in CPU time.

#[path = "support/bench.rs"]
mod bench;

use bench::{cpu_seconds, git_commit, machine};
use objnerf::demo::edit_truth::{demo_orbit, EditTruth};
use objnerf::edit::{load_edit, EditFile};
use objnerf::field::{RayCamera, RenderOptions};
use objnerf::pipeline::edit_fields::ensure_edit_fields;
use objnerf::pipeline::render_edit::RenderEditOptions;
use objnerf::render::composite::{render_frame, Composite};
use objnerf::render::frame_files::Passes;
use objnerf::scene::camera_path::CameraPath;
use objnerf::util::chart::{layers, series, svg, Layer, Panel, RGBColor, SeriesLabelPosition};
use objnerf::util::mem::peak_rss_mib;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

type Res<T> = Result<T, Box<dyn std::error::Error>>;
/// A frame's RGB, row-major.
type Rgb = Vec<[f32; 3]>;

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

/// An edit file in `dir` named `name` with `objects` over the background.
fn edit(dir: &Path, name: &str, bg: &Path, objects: serde_json::Value) -> Res<PathBuf> {
    let p = dir.join(format!("{name}.json"));
    let doc = json!({"version": 1, "background": {"model": bg}, "objects": objects});
    std::fs::write(&p, serde_json::to_string_pretty(&doc)?)?;
    Ok(p)
}

/// Render every frame of `path`; returns (wall seconds, CPU seconds, the frames' RGB).
fn time_render(
    edit: &Path,
    render: &RenderOptions,
    path: &CameraPath,
) -> Res<(f64, f64, Vec<Rgb>)> {
    let loaded = load_edit(EditFile::read(edit)?, Some(render))?;
    let comp = Composite::from_edit(&loaded, *render);
    let (t0, c0) = (Instant::now(), cpu_seconds());
    let mut frames = Vec::new();
    for (k, c) in path.cameras.iter().enumerate() {
        let cam = RayCamera::new(format!("{k}"), c.camera.clone(), c.pose);
        frames.push(render_frame(&comp, &cam).rgb);
    }
    Ok((t0.elapsed().as_secs_f64(), cpu_seconds() - c0, frames))
}

fn psnr(frames: &[Rgb], truth: &[image::RgbImage]) -> f64 {
    let (mut se, mut n) = (0.0f64, 0.0f64);
    for (f, t) in frames.iter().zip(truth) {
        for (p, q) in f.iter().zip(t.pixels()) {
            for c in 0..3 {
                let a = (p[c].clamp(0.0, 1.0) * 255.0).round() as f64;
                se += ((a - q[c] as f64) / 255.0).powi(2);
                n += 1.0;
            }
        }
    }
    -10.0 * (se / n).log10()
}

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().collect();
    let fields_dir = PathBuf::from(arg(&args, "--fields").unwrap_or("target/edit-fields".into()));
    // The edit files it writes live in a temporary folder: models are named absolutely.
    let fields_dir = std::path::absolute(&fields_dir)?;
    let out = PathBuf::from(arg(&args, "--out").unwrap_or("examples/results".into()));
    let machine_start = machine();
    let f = ensure_edit_fields(&fields_dir, &mut |m| eprintln!("{m}"))?;
    let tmp = tempfile::tempdir()?;
    let (mug, torus) = (f.mug.to_str().unwrap(), f.torus.to_str().unwrap());
    let configs = [
        (
            "background only",
            edit(tmp.path(), "bg", &f.background, json!([]))?,
        ),
        (
            "background + 1 object",
            edit(
                tmp.path(),
                "one",
                &f.background,
                json!([{"name": "mug", "model": mug}]),
            )?,
        ),
        (
            "background + 4 objects",
            edit(
                tmp.path(),
                "four",
                &f.background,
                json!([{"name": "mug", "model": mug}, {"name": "torus", "model": torus},
                    {"name": "mug.001", "model": mug, "translation": [0.9, 0.0, 0.0]},
                    {"name": "torus.001", "model": torus, "translation": [0.6, 0.8, 0.0]}]),
            )?,
        ),
    ];
    let default = RenderEditOptions::default().render;
    let mut speed = Vec::new();
    for (w, h) in [(320, 240), (640, 480)] {
        let path = demo_orbit(24, w, h)?;
        for (name, file) in &configs {
            let (wall, cpu, _) = time_render(file, &default, &path)?;
            let fps = 24.0 / wall;
            eprintln!(
                "{w}x{h} {name}: {fps:.2} frames/s, {:.3} CPU-s per frame",
                cpu / 24.0
            );
            speed.push(json!({"size": format!("{w}x{h}"), "config": name,
                "frames": 24, "wall_s": wall, "cpu_s": cpu, "frames_per_second": fps,
                "cpu_s_per_frame": cpu / 24.0}));
        }
    }
    // Time against PSNR for the step (background + the mug, 320x240), against the exact truth.
    let path = demo_orbit(24, 320, 240)?;
    let one = &configs[1].1;
    let truth_edit = load_edit(EditFile::read(one)?, None)?;
    let truth = EditTruth::new(&truth_edit, 0)?;
    let truth_frames: Vec<image::RgbImage> = path
        .cameras
        .iter()
        .map(|c| truth.render(&c.camera, &c.pose, Passes::default()).rgb)
        .collect();
    let mut sweep = Vec::new();
    for alpha in [default.alpha_thresh, 1e-4] {
        for step in [0.5f32, 0.75, 1.0, 1.5, 2.0] {
            let r = RenderOptions {
                step,
                alpha_thresh: alpha,
                ..default
            };
            let (wall, cpu, frames) = time_render(one, &r, &path)?;
            let p = psnr(&frames, &truth_frames);
            eprintln!(
                "step {step}, alpha threshold {alpha}: {:.3} s/frame ({:.3} CPU-s), {p:.2} dB",
                wall / 24.0,
                cpu / 24.0
            );
            sweep.push(
                json!({"step": step, "alpha_thresh": alpha, "wall_s_per_frame": wall / 24.0,
                "cpu_s_per_frame": cpu / 24.0, "psnr": p}),
            );
        }
    }
    let report = json!({
        "what": "render-edit on the demo scene (background field without the mug and torus, + the mug, + 4 objects) along a 24-frame orbit like the demo cameras; fields loaded before timing",
        "command": "cargo run --release --example render_edit_bench",
        "machine_at_start": machine_start,
        "machine_at_end": machine(),
        "git_commit": git_commit(),
        "default_render": {"step": default.step, "alpha_thresh": default.alpha_thresh,
            "term_thresh": default.term_thresh},
        "speed": speed,
        "step_sweep": sweep,
        "peak_rss_mib": peak_rss_mib(),
    });
    std::fs::create_dir_all(&out)?;
    let json_path = out.join("render_edit.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&report)?)?;
    std::fs::write(out.join("render_edit.svg"), chart(&speed, &sweep)?)?;
    println!("{}", json_path.display());
    Ok(())
}

fn chart(speed: &[serde_json::Value], sweep: &[serde_json::Value]) -> Res<String> {
    // Frames per second against the number of objects over the background, a line per size.
    let objects = |c: &str| {
        if c.contains("4 objects") {
            4.0
        } else if c.contains("1 object") {
            1.0
        } else {
            0.0
        }
    };
    let fps = series(
        speed,
        |s| s["size"].as_str().unwrap_or("?").to_string(),
        |s| {
            Some((
                objects(s["config"].as_str()?),
                s["frames_per_second"].as_f64()?,
            ))
        },
    );
    let mut left = Panel::fitted(
        "render-edit: frames per second (wall)",
        "objects over the background field",
        "frames / s",
        layers(fps),
    );
    left.y.start = 0.0;
    left.layers.push(Layer::level(
        Some("5 frames/s"),
        RGBColor(200, 0, 0),
        5.0,
        &left.x,
    ));
    left.legend = SeriesLabelPosition::UpperRight;
    // Quality against cost for the sample step, a line per alpha threshold (steps 0.5 .. 2 from
    // right to left).
    let sweep_series = series(
        sweep,
        |s| {
            format!(
                "alpha threshold {:.0e}",
                s["alpha_thresh"].as_f64().unwrap_or(0.0)
            )
        },
        |s| Some((s["cpu_s_per_frame"].as_f64()?, s["psnr"].as_f64()?)),
    );
    let right = Panel::fitted(
        "PSNR against CPU s per frame (320x240, bg + 1; step 2 left .. 0.5 right)",
        "CPU s / frame",
        "PSNR dB",
        layers(sweep_series),
    );
    svg((1100, 420), 1, &[left, right])
}
