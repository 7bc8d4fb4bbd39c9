//! The GPU renderer against the CPU renderer: `render-edit` frames per second per device and
//! size on the demo's objects (the mug alone, and four objects: the mug, the torus and a moved
//! copy of each, over white; with `DIR/removed/background.objf` there, the same over the
//! background field too), along an orbit like the demo cameras; every GPU adapter found (here
//! Mesa's lavapipe, a software Vulkan device) and the CPU.
//!
//!     cargo run --release --example gpu_render_bench -- [--fields DIR] [--frames N] [--out examples/results]
//!
//! `--fields DIR` (default `target/gpu-bench-fields`) holds the demo scene and its mug and
//! torus fields, trained there when missing (600 steps each, a few CPU-minutes). Writes
//! `gpu_render.json` and `gpu_render.svg`. Fields are loaded and uploaded before the clock
//! starts (the upload is timed apart); a GPU frame's time includes making its rays on the CPU,
//! the dispatch and reading the frame back, as `render-edit` pays them. Each GPU frame is
//! checked against the CPU's (largest RGB difference recorded).

use objnerf::demo::edit_truth::demo_orbit;
use objnerf::demo::fields::{write_object_field, DemoFieldOptions};
use objnerf::demo::{write_demo_scene, DemoOptions};
use objnerf::edit::{load_edit, EditFile};
use objnerf::field::RayCamera;
use objnerf::pipeline::render_edit::RenderEditOptions;
use objnerf::render::composite::{render_frame, Composite, Frame};
use objnerf::render::gpu::Gpu;
use objnerf::util::chart::{layers, series, svg, Panel, SeriesLabelPosition};
use objnerf::util::machine::{git_commit, machine};
use objnerf::util::mem::peak_rss_mib;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

/// The demo scene and its mug and torus fields in `dir` (made when missing).
fn fields(dir: &Path) -> Res<(PathBuf, PathBuf)> {
    let scene = dir.join("demo");
    if !scene.join("truth/objects.json").is_file() {
        write_demo_scene(&DemoOptions::default(), &scene)?;
    }
    let (mug, torus) = (dir.join("mug.objf"), dir.join("torus.objf"));
    for (name, out) in [("mug", &mug), ("torus", &torus)] {
        if !out.is_file() {
            let r = write_object_field(&scene, name, &DemoFieldOptions::steps(600), out)?;
            eprintln!("{name}: {} steps in {:.0} s", r.run.steps, r.run.seconds);
        }
    }
    Ok((mug, torus))
}

fn write_edit(
    dir: &Path,
    name: &str,
    bg: &serde_json::Value,
    objects: serde_json::Value,
) -> Res<PathBuf> {
    let p = dir.join(format!("{name}.json"));
    let doc = json!({"version": 1, "background": bg, "objects": objects});
    std::fs::write(&p, serde_json::to_string_pretty(&doc)?)?;
    Ok(p)
}

fn max_rgb_diff(a: &Frame, b: &Frame) -> f32 {
    a.rgb
        .iter()
        .zip(&b.rgb)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().collect();
    let dir = PathBuf::from(arg(&args, "--fields").unwrap_or("target/gpu-bench-fields".into()));
    let dir = std::path::absolute(&dir)?;
    std::fs::create_dir_all(&dir)?;
    let out = PathBuf::from(arg(&args, "--out").unwrap_or("examples/results".into()));
    let frames: usize = arg(&args, "--frames")
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(8);
    let machine_start = machine();
    let (mug, torus) = fields(&dir)?;
    let tmp = tempfile::tempdir()?;
    let (mug, torus) = (mug.to_str().unwrap(), torus.to_str().unwrap());
    let four = json!([{"name": "mug", "model": mug}, {"name": "torus", "model": torus},
        {"name": "mug.001", "model": mug, "translation": [0.9, 0.0, 0.0]},
        {"name": "torus.001", "model": torus, "translation": [0.6, 0.8, 0.0]}]);
    let white = json!({"color": "#ffffff"});
    let mut configs = vec![
        (
            "1 object",
            write_edit(
                tmp.path(),
                "one",
                &white,
                json!([{"name": "mug", "model": mug}]),
            )?,
        ),
        (
            "4 objects",
            write_edit(tmp.path(), "four", &white, four.clone())?,
        ),
    ];
    let bg = dir.join("removed/background.objf");
    if bg.is_file() {
        let bgj = json!({"model": bg});
        configs.push((
            "background + 1 object",
            write_edit(
                tmp.path(),
                "bg1",
                &bgj,
                json!([{"name": "mug", "model": mug}]),
            )?,
        ));
        configs.push((
            "background + 4 objects",
            write_edit(tmp.path(), "bg4", &bgj, four)?,
        ));
    }
    let gpu = match Gpu::open(true) {
        Ok(g) => Some(g),
        Err(e) => {
            eprintln!("no GPU adapter: {e}");
            None
        }
    };
    let render = RenderEditOptions::default().render;
    let mut speed = Vec::new();
    for (w, h) in [(320u32, 240u32), (640, 480)] {
        let path = demo_orbit(frames, w, h)?;
        let cams: Vec<RayCamera> = path
            .cameras
            .iter()
            .enumerate()
            .map(|(k, c)| RayCamera::new(format!("{k}"), c.camera.clone(), c.pose))
            .collect();
        for (name, file) in &configs {
            let edit = load_edit(EditFile::read(file)?, Some(&render))?;
            let comp = Composite::from_edit(&edit, render);
            let t0 = Instant::now();
            let cpu: Vec<Frame> = cams.iter().map(|c| render_frame(&comp, c)).collect();
            let wall = t0.elapsed().as_secs_f64();
            let fps = frames as f64 / wall;
            eprintln!("{w}x{h} {name}, cpu: {fps:.2} frames/s");
            speed.push(
                json!({"size": format!("{w}x{h}"), "config": name, "device": "cpu",
                "frames": frames, "wall_s": wall, "frames_per_second": fps}),
            );
            let Some(g) = &gpu else { continue };
            let t0 = Instant::now();
            let up = g.upload(&comp)?;
            let upload_s = t0.elapsed().as_secs_f64();
            let t0 = Instant::now();
            let mut worst = 0f32;
            for (c, f) in cams.iter().zip(&cpu) {
                let gf = up.render_frame(c)?;
                worst = worst.max(max_rgb_diff(f, &gf));
            }
            let wall = t0.elapsed().as_secs_f64();
            let fps = frames as f64 / wall;
            eprintln!(
                "{w}x{h} {name}, {}: {fps:.2} frames/s (upload {upload_s:.2} s), max |rgb diff| vs cpu {worst:.1e}",
                g.name()
            );
            speed.push(json!({"size": format!("{w}x{h}"), "config": name,
                "device": format!("gpu: {}", g.name()), "frames": frames, "wall_s": wall,
                "frames_per_second": fps, "upload_s": upload_s, "max_rgb_diff_vs_cpu": worst}));
        }
    }
    let report = json!({
        "what": "render-edit frames per second per device and size: the demo's mug (SH, 600 steps) alone and four objects over white, along an orbit like the demo cameras; render-edit's default sampling (step 1 voxel, alpha threshold 3e-3)",
        "command": format!("cargo run --release --example gpu_render_bench -- --frames {frames}"),
        "machine_at_start": machine_start,
        "machine_at_end": machine(),
        "gpu": gpu.as_ref().map(|g| g.name()),
        "git_commit": git_commit(),
        "speed": speed,
        "peak_rss_mib": peak_rss_mib(),
    });
    std::fs::create_dir_all(&out)?;
    let json_path = out.join("gpu_render.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&report)?)?;
    std::fs::write(out.join("gpu_render.svg"), chart(&speed)?)?;
    println!("{}", json_path.display());
    Ok(())
}

/// Frames per second against the configuration, a line per device and size.
fn chart(speed: &[serde_json::Value]) -> Res<String> {
    let order = [
        "1 object",
        "4 objects",
        "background + 1 object",
        "background + 4 objects",
    ];
    let x = |c: &str| order.iter().position(|o| *o == c).unwrap_or(0) as f64;
    let s = series(
        speed,
        |s| {
            let dev = s["device"].as_str().unwrap_or("?");
            let dev = dev.split(" (").next().unwrap_or(dev);
            format!("{dev}, {}", s["size"].as_str().unwrap_or("?"))
        },
        |s| Some((x(s["config"].as_str()?), s["frames_per_second"].as_f64()?)),
    );
    let mut p = Panel::fitted(
        "render-edit frames per second (wall) by device and size",
        "0: 1 object, 1: 4 objects (2, 3: the same over the background field)",
        "frames / s",
        layers(s),
    );
    p.y.start = 0.0;
    p.legend = SeriesLabelPosition::UpperRight;
    svg((900, 480), 1, &[p])
}
