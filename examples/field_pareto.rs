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

use objnerf::util::chart::{layers, series, svg, ChartResult, Panel};
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
    let bin = exe.with_file_name("field_bench");
    let mut cmd = std::process::Command::new(&bin);
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
    std::fs::create_dir_all(&out_dir).expect("output folder");
    let json_path = out_dir.join("field_pareto.json");
    objnerf::util::atomic::write_bytes_atomic(
        &json_path,
        serde_json::to_string_pretty(&result).unwrap().as_bytes(),
    )
    .expect("write JSON");
    chart(&result, &out_dir.join("field_pareto.svg")).expect("chart");
    eprintln!("wrote {} and field_pareto.svg", json_path.display());
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
