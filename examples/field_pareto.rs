//! The object field's accuracy against training time: lego at 100^2, 200^2 and 400^2 for several
//! time budgets and grid budgets (test PSNR on the 25 test views, on white), and the demo scene's
//! objects with and without dense depth (held-out PSNR, median depth error against truth). Each
//! run is its own `field_bench` process, so each has its own peak RSS. Writes
//! `OUT/field_pareto.json` and `OUT/field_pareto.svg`.
//!
//! cargo build --release --examples && target/release/examples/field_pareto \
//!     [--lego ../shared/data/lego] [--demo DEMO_DIR] [--out examples/results] [--quick]
//!
//! Without `--demo` the default demo scene is made in a temporary folder.
//!
//! `--sizes [--dense-bench PATH]` runs the other sweep instead: lego at 200^2, 400^2 and 800^2 for
//! the budgets in [`SIZES`] with today's sparse field, and, given the path of a `field_bench`
//! built before the grid became sparse (commit c3b87eb: `git worktree add /tmp/dense c3b87eb &&
//! cargo build --release --example field_bench` there), the same runs with that dense grid.
//! Writes `OUT/field_sizes.{json,svg}`; `--sizes --replot` redraws the SVG from that JSON.
//!
//! `--colours` compares the colour models within the same wall-clock budgets ([`COLOURS`]):
//! SH degree 1 (the default), SH degree 2 and a feature grid with a small colour network, on
//! lego at 200^2 (60 and 300 s) and on the demo objects (3000 steps, held-out PSNR). Writes
//! `OUT/field_colours.{json,svg}`; `--colours --replot` redraws the SVG.

use objnerf::util::chart::{
    layers, palette, series, svg, ChartResult, Layer, Panel, SeriesLabelPosition,
};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// One lego run: (label, downscale, seconds, FIELD_VPP voxels per pixel).
const LEGO: &[(&str, u32, f64, f32)] = &[
    ("100^2", 8, 15.0, 1.0),
    ("100^2", 8, 45.0, 1.0),
    ("200^2", 4, 30.0, 1.0),
    ("200^2", 4, 90.0, 1.0),
    ("200^2 half-res grid", 4, 90.0, 0.5),
    ("400^2", 2, 150.0, 1.0),
];
/// The size sweep: (label, downscale, seconds, voxels per pixel footprint of the finest grid,
/// also run with the dense grid). 1.0 is the default; the coarser runs show what a fixed time
/// buys at a lower resolution.
const SIZES: &[(&str, u32, f64, f32, bool)] = &[
    ("200^2", 4, 60.0, 1.0, true),
    ("200^2", 4, 300.0, 1.0, false),
    ("400^2", 2, 300.0, 1.0, true),
    ("800^2", 1, 1200.0, 1.0, false),
    ("400^2", 2, 300.0, 0.6, false),
    ("800^2", 1, 1200.0, 0.4, false),
];
/// The colour sweep: (label, SH degree, FIELD_NET "features,hidden" ("0,0": SH colour),
/// FIELD_VPP, lego budgets in seconds).
const COLOURS: &[(&str, u32, &str, f32, &[f64])] = &[
    ("SH 1", 1, "0,0", 1.0, &[60.0, 300.0]),
    ("SH 2", 2, "0,0", 1.0, &[60.0]),
    ("net 8x32", 1, "8,32", 1.0, &[60.0, 300.0]),
    ("net 8x32, 1.3 voxel/px", 1, "8,32", 1.3, &[300.0]),
];
/// Between a run's kind and its size in a series' name (`sizes_chart`).
const SIZE_SEP: &str = " @ ";
const DEMO_OBJECTS: &[&str] = &["mug", "sphere", "box", "torus"];
const DEMO_BUDGETS: &[f64] = &[40.0];

/// The 1-minute load average (Linux), to say how shared the machine was.
fn loadavg() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/loadavg").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

fn arg(args: &[String], name: &str) -> Option<String> {
    let i = args.iter().position(|a| a == name)?;
    args.get(i + 1).cloned()
}

/// Run `field_bench` (beside this executable) and parse the JSON it prints last.
fn bench(args: &[String], env: &[(&str, String)]) -> Value {
    let exe = std::env::current_exe().expect("own path");
    bench_with(&exe.with_file_name("field_bench"), args, env)
}

/// Run the `field_bench` at `bin` and parse the JSON it prints last.
fn bench_with(bin: &Path, args: &[String], env: &[(&str, String)]) -> Value {
    let mut cmd = std::process::Command::new(bin);
    cmd.args(args);
    for (k, v) in env {
        cmd.env(k, v);
    }
    eprintln!("running {} {}", bin.display(), args.join(" "));
    let out = cmd
        .output()
        .expect("field_bench runs (cargo build --release --examples)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let last = stdout.lines().last().unwrap_or("");
    match serde_json::from_str(last) {
        Ok(v) if out.status.success() => v,
        _ => {
            json!({"error": String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("").to_string()})
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let lego = PathBuf::from(arg(&args, "--lego").unwrap_or("../shared/data/lego".into()));
    let out_dir = PathBuf::from(arg(&args, "--out").unwrap_or("examples/results".into()));
    let quick = args.iter().any(|a| a == "--quick");
    if args.iter().any(|a| a == "--sizes") {
        sizes(&args, &lego, &out_dir, quick);
        return;
    }
    if args.iter().any(|a| a == "--colours") {
        colours(&args, &lego, &out_dir, quick);
        return;
    }
    let scale = if quick { 0.1 } else { 1.0 };
    let tmp = tempfile::tempdir().expect("temp dir");
    let demo_dir = match arg(&args, "--demo") {
        Some(d) => PathBuf::from(d),
        None => {
            let d = tmp.path().join("demo");
            objnerf::demo::write_demo_scene(&Default::default(), &d).expect("demo scene");
            d
        }
    };
    let start = std::time::Instant::now();
    let load_before = loadavg();
    let mut lego_runs = Vec::new();
    if lego.exists() {
        for &(label, ds, secs, vpp) in LEGO {
            let mut r = bench(
                &[
                    lego.display().to_string(),
                    ds.to_string(),
                    (secs * scale).to_string(),
                ],
                &[("FIELD_VPP", vpp.to_string())],
            );
            r["label"] = json!(label);
            r["voxels_per_pixel"] = json!(vpp);
            eprintln!(
                "  {label} {secs} s: PSNR {} dB, peak RSS {} MiB",
                r["test_psnr"], r["peak_rss_mib"]
            );
            lego_runs.push(r);
        }
    } else {
        eprintln!("SKIP lego: {} is absent", lego.display());
    }
    let mut demo_runs = Vec::new();
    for obj in DEMO_OBJECTS {
        for depth in ["none", "dense"] {
            for &secs in DEMO_BUDGETS {
                let r = bench(
                    &[
                        "demo".into(),
                        demo_dir.display().to_string(),
                        obj.to_string(),
                        (secs * scale).to_string(),
                        depth.into(),
                    ],
                    &[],
                );
                eprintln!(
                    "  {obj} {depth} {secs} s: PSNR {} dB, depth error {} of the diagonal",
                    r["report"]["psnr"], r["report"]["depth_error_fraction"]
                );
                demo_runs.push(r);
            }
        }
    }
    let result = json!({
        "what": "objnerf field: test PSNR (lego: 25 test views; demo: held-out views where the object is >= 90% visible, every 6th view held out) and demo median depth error against truth, for several time and grid budgets; one process per run",
        "machine": "2 cores, 24 GiB, no GPU, shared with other agents' builds and benchmarks (load average 4-11 during the run): wall-clock figures are pessimistic; cpu seconds are recorded per run",
        "command": args.join(" "),
        "total_s": start.elapsed().as_secs_f64(),
        "load_average_before_after": [load_before, loadavg()],
        "lego": lego_runs,
        "demo": demo_runs,
    });
    write_result(&out_dir, "field_pareto", &result, chart);
}

/// Write `OUT/STEM.json` (atomically) and its chart `OUT/STEM.svg`.
fn write_result(
    out_dir: &Path,
    stem: &str,
    result: &Value,
    chart: fn(&Value, &Path) -> ChartResult<()>,
) {
    std::fs::create_dir_all(out_dir).expect("output folder");
    let json_path = out_dir.join(format!("{stem}.json"));
    objnerf::util::atomic::write_bytes_atomic(
        &json_path,
        serde_json::to_string_pretty(result).unwrap().as_bytes(),
    )
    .expect("write JSON");
    chart(result, &out_dir.join(format!("{stem}.svg"))).expect("chart");
    eprintln!("wrote {} and {stem}.svg", json_path.display());
}

fn chart(result: &Value, path: &Path) -> ChartResult<()> {
    let empty = Vec::new();
    let lego = result["lego"].as_array().unwrap_or(&empty);
    let demo = result["demo"].as_array().unwrap_or(&empty);
    let lego_s = series(
        lego,
        |r| r["label"].as_str().unwrap_or("?").to_string(),
        |r| Some((r["train"]["seconds"].as_f64()?, r["test_psnr"].as_f64()?)),
    );
    let name = |r: &Value| {
        format!(
            "{} {}",
            r["report"]["object"].as_str().unwrap_or("?"),
            r["depth_supervision"]
                .as_str()
                .unwrap_or("?")
                .to_lowercase()
        )
    };
    let demo_psnr = series(demo, name, |r| {
        Some((
            r["report"]["run"]["seconds"].as_f64()?,
            r["report"]["psnr"].as_f64()?,
        ))
    });
    let demo_depth = series(demo, name, |r| {
        Some((
            r["report"]["run"]["seconds"].as_f64()?,
            100.0 * r["report"]["depth_error_fraction"].as_f64()?,
        ))
    });
    let panels = [
        Panel::fitted(
            "lego: test PSNR vs training time",
            "training wall seconds (shared 2-core machine)",
            "test PSNR (dB)",
            layers(lego_s),
        ),
        Panel::fitted(
            "demo objects: held-out PSNR",
            "training wall seconds",
            "PSNR on white (dB)",
            layers(demo_psnr),
        ),
        Panel::fitted(
            "demo objects: median depth error",
            "training wall seconds",
            "% of the box diagonal",
            layers(demo_depth),
        ),
    ];
    std::fs::write(path, svg((1400, 520), 1, &panels)?)?;
    Ok(())
}

/// The size sweep (`--sizes`): sparse and, where a dense `field_bench` is given, dense runs.
fn sizes(args: &[String], lego: &Path, out_dir: &Path, quick: bool) {
    if args.iter().any(|a| a == "--replot") {
        // Redraw from the JSON (runs added to it by hand included).
        let path = out_dir.join("field_sizes.json");
        let text = std::fs::read_to_string(&path).expect("field_sizes.json to redraw");
        let result: Value = serde_json::from_str(&text).expect("field_sizes.json is JSON");
        sizes_chart(&result, &out_dir.join("field_sizes.svg")).expect("chart");
        return;
    }
    if !lego.exists() {
        eprintln!("SKIP: {} is absent", lego.display());
        return;
    }
    let scale = if quick { 0.05 } else { 1.0 };
    let dense = arg(args, "--dense-bench").map(PathBuf::from);
    let exe = std::env::current_exe().expect("own path");
    let sparse = exe.with_file_name("field_bench");
    let start = std::time::Instant::now();
    let load_before = loadavg();
    let mut runs = Vec::new();
    for &(label, ds, secs, vpp, with_dense) in SIZES {
        let mut grids = vec![(format!("sparse {vpp} voxel/px"), sparse.clone())];
        if vpp == 1.0 {
            grids[0].0 = "sparse".into();
        }
        if let (true, Some(d)) = (with_dense, &dense) {
            grids.push(("dense".into(), d.clone()));
        }
        // Default settings stay default: FIELD_VPP only where the run asks for another value.
        let env: Vec<(&str, String)> = if vpp == 1.0 {
            vec![]
        } else {
            vec![("FIELD_VPP", vpp.to_string())]
        };
        for (grid, bin) in grids {
            let run_args = [
                lego.display().to_string(),
                ds.to_string(),
                (secs * scale).to_string(),
            ];
            let mut r = bench_with(&bin, &run_args, &env);
            r["label"] = json!(label);
            r["grid"] = json!(grid);
            r["load_average_after"] = json!(loadavg());
            eprintln!(
                "  {grid} {label} {secs} s: PSNR {} dB, peak RSS {} MiB",
                r["test_psnr"], r["peak_rss_mib"]
            );
            runs.push(r);
        }
    }
    let result = json!({
        "what": "objnerf field on lego (25 test views on white): test PSNR and peak RSS against the training budget at 200^2, 400^2 and 800^2, the sparse grid (this commit) against the dense grid (field_bench of commit c3b87eb, where given); one process per run",
        "machine": objnerf::util::machine::machine(),
        "git_commit": objnerf::util::machine::git_commit(),
        "command": args.join(" "),
        "total_s": start.elapsed().as_secs_f64(),
        "load_average_before": load_before,
        "runs": runs,
    });
    write_result(out_dir, "field_sizes", &result, sizes_chart);
}

fn sizes_chart(result: &Value, path: &Path) -> ChartResult<()> {
    let empty = Vec::new();
    let runs = result["runs"].as_array().unwrap_or(&empty);
    // One series a run kind and size (a line joins one size's budgets), one colour and one
    // legend entry a run kind: the sizes sit at their own budgets (200^2 at 60 and 300 s,
    // 400^2 at 300 s, 800^2 at 1200 s).
    let name = |r: &Value| {
        format!(
            "{}{SIZE_SEP}{}",
            r["grid"].as_str().unwrap_or("?"),
            r["label"].as_str().unwrap_or("?")
        )
    };
    let kind_layers = |named: Vec<(String, Vec<(f64, f64)>)>| {
        let mut kinds: Vec<String> = Vec::new();
        named
            .into_iter()
            .map(|(n, points)| {
                let kind = n.split(SIZE_SEP).next().unwrap_or("?").to_string();
                let first = !kinds.contains(&kind);
                if first {
                    kinds.push(kind.clone());
                }
                let i = kinds.iter().position(|k| *k == kind).unwrap_or(0);
                let mut layer = Layer::new(kind, palette(i), points);
                if !first {
                    layer.name = None;
                }
                layer
            })
            .collect::<Vec<_>>()
    };
    let budget = |r: &Value| r["train"]["seconds"].as_f64();
    // Where the time goes: the share of training in the gradient scatter and Adam (phase 1),
    // the rest being mostly forward + backward marching (phase 0).
    let scatter_share = series(runs, name, |r| {
        let p = r["phase_secs"].as_array()?;
        let total: f64 = p.iter().filter_map(Value::as_f64).sum();
        Some((budget(r)?, 100.0 * p.get(1)?.as_f64()? / total.max(1e-9)))
    });
    let psnr = series(runs, name, |r| Some((budget(r)?, r["test_psnr"].as_f64()?)));
    let rss = series(runs, name, |r| {
        Some((budget(r)?, r["peak_rss_mib"].as_f64()?))
    });
    let panels = [
        Panel::fitted(
            "test PSNR: 200^2 at 60/300 s, 400^2 300 s, 800^2 1200 s",
            "training wall seconds (2 cores)",
            "test PSNR on white (dB)",
            kind_layers(psnr),
        ),
        Panel::fitted(
            "peak RSS of each run",
            "training wall seconds (2 cores)",
            "peak RSS (MiB)",
            kind_layers(rss),
        ),
        Panel::fitted(
            "where the time goes",
            "training wall seconds (2 cores)",
            "% of training in gradient scatter + Adam",
            kind_layers(scatter_share),
        ),
    ];
    // The legend (one entry a run kind, ~15 px each) fills a corner: the chart is made tall
    // enough for it and ~220 px of points, and each y axis is extended away from the points
    // so the legend does not cover them.
    let entries = panels
        .iter()
        .map(|p| p.layers.iter().filter(|l| l.name.is_some()).count())
        .max()
        .unwrap_or(0) as f64;
    let legend_px = 15.0 * entries + 20.0;
    let plot_px = legend_px + 220.0;
    let height = (plot_px + 85.0) as u32;
    let panels = panels.map(|mut p| {
        let span = p.y.end - p.y.start;
        let extra = span * legend_px / (plot_px - legend_px);
        // Below the points unless that would show negative RSS or shares.
        if p.y.start - extra < 0.0 {
            p.y = p.y.start.max(0.0)..p.y.end + extra;
            p.legend = SeriesLabelPosition::UpperLeft;
        } else {
            p.y = p.y.start - extra..p.y.end;
        }
        p
    });
    std::fs::write(path, svg((1500, height.max(480)), 1, &panels)?)?;
    Ok(())
}

/// The colour sweep (`--colours`): lego at 200^2 for each of [`COLOURS`] within its budgets,
/// then the demo objects at 3000 steps with each colour model at 1 voxel/px.
fn colours(args: &[String], lego: &Path, out_dir: &Path, quick: bool) {
    let json_path = out_dir.join("field_colours.json");
    if args.iter().any(|a| a == "--replot") {
        let text = std::fs::read_to_string(&json_path).expect("field_colours.json to redraw");
        let result: Value = serde_json::from_str(&text).expect("field_colours.json is JSON");
        colours_chart(&result, &out_dir.join("field_colours.svg")).expect("chart");
        return;
    }
    let scale = if quick { 0.05 } else { 1.0 };
    let env_of = |net: &str, vpp: f32| {
        vec![
            ("FIELD_VPP", vpp.to_string()),
            ("FIELD_NET", net.to_string()),
        ]
    };
    let start = std::time::Instant::now();
    let load_before = loadavg();
    let mut lego_runs = Vec::new();
    if lego.exists() {
        for &(label, degree, net, vpp, budgets) in COLOURS {
            for &secs in budgets {
                let run_args = [
                    lego.display().to_string(),
                    "4".into(),
                    (secs * scale).to_string(),
                    degree.to_string(),
                ];
                let mut r = bench(&run_args, &env_of(net, vpp));
                r["colour"] = json!(label);
                r["load_average_after"] = json!(loadavg());
                eprintln!("  {label} {secs} s: PSNR {} dB", r["test_psnr"]);
                lego_runs.push(r);
            }
        }
    } else {
        eprintln!("SKIP lego: {} is absent", lego.display());
    }
    let tmp = tempfile::tempdir().expect("temp dir");
    let demo_dir = tmp.path().join("demo");
    objnerf::demo::write_demo_scene(&Default::default(), &demo_dir).expect("demo scene");
    let steps = if quick { 300 } else { 3000 };
    let mut demo_runs = Vec::new();
    for &(label, _, net, _, _) in COLOURS.iter().filter(|c| c.3 == 1.0 && c.1 == 1) {
        for obj in DEMO_OBJECTS {
            let mut env = env_of(net, 1.0);
            env.push(("FIELD_STEPS", steps.to_string()));
            let run_args = ["demo", &demo_dir.display().to_string(), obj, "1000", "none"];
            let mut r = bench(&run_args.map(String::from), &env);
            r["colour"] = json!(label);
            eprintln!("  {label} {obj}: PSNR {} dB", r["report"]["psnr"]);
            demo_runs.push(r);
        }
    }
    let result = json!({
        "what": "objnerf field colour models: lego 200^2 test PSNR (25 test views on white) within wall-clock budgets, and the demo objects' held-out PSNR at a fixed step count; one process per run",
        "machine": objnerf::util::machine::machine(),
        "git_commit": objnerf::util::machine::git_commit(),
        "command": args.join(" "),
        "total_s": start.elapsed().as_secs_f64(),
        "load_average_before": load_before,
        "lego": lego_runs,
        "demo": demo_runs,
    });
    write_result(out_dir, "field_colours", &result, colours_chart);
}

fn colours_chart(result: &Value, path: &Path) -> ChartResult<()> {
    let empty = Vec::new();
    let lego = result["lego"].as_array().unwrap_or(&empty);
    let demo = result["demo"].as_array().unwrap_or(&empty);
    let colour = |r: &Value| r["colour"].as_str().unwrap_or("?").to_string();
    let psnr = series(lego, colour, |r| {
        Some((r["train"]["seconds"].as_f64()?, r["test_psnr"].as_f64()?))
    });
    let rss = series(lego, colour, |r| {
        Some((r["train"]["seconds"].as_f64()?, r["peak_rss_mib"].as_f64()?))
    });
    // x: the object's place in DEMO_OBJECTS (1 mug, 2 sphere, 3 box, 4 torus).
    let demo_psnr = series(demo, colour, |r| {
        let obj = r["report"]["object"].as_str()?;
        let x = DEMO_OBJECTS.iter().position(|o| *o == obj)? as f64 + 1.0;
        Some((x, r["report"]["psnr"].as_f64()?))
    });
    let panels = [
        Panel::fitted(
            "lego 200^2: test PSNR vs training time",
            "training wall seconds (2 cores)",
            "test PSNR on white (dB)",
            layers(psnr),
        ),
        Panel::fitted(
            "lego 200^2: peak RSS",
            "training wall seconds (2 cores)",
            "peak RSS (MiB)",
            layers(rss),
        ),
        Panel::fitted(
            "demo objects, 3000 steps: held-out PSNR",
            "1 mug, 2 sphere, 3 box, 4 torus",
            "PSNR on white (dB)",
            layers(demo_psnr),
        ),
    ];
    std::fs::write(path, svg((1500, 480), 1, &panels)?)?;
    Ok(())
}
