//! Marching cubes at 256³: objnerf's own (parallel over z-slabs, welded) against scikit-image's
//! `measure.marching_cubes` on the same volume and level, in one run. The volume is a seeded
//! blobby field (a sum of Gaussians) with a surface as busy as a real object's.
//!
//!     cargo run --release --example mesh_bench -- [--size 256] [--runs 7] [--out examples/results]
//!
//! Writes `mesh_marching_cubes.json` and `mesh_marching_cubes.svg`. scikit-image runs in its own
//! venv under the models dir (`$OBJNERF_HOME/venvs/bench-skimage`), created on first use.

#[path = "support/bench.rs"]
mod bench;

use bench::{ensure_venv, git_commit, machine, Stats};
use objnerf::mesh::marching::marching_cubes;
use objnerf::models::ModelsDir;
use objnerf::util::{mem::peak_rss_mib, Rng};
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

const PY: &str = r#"
import json, sys, time
import numpy as np
from skimage import measure
path, n, level, runs = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
# Our grid is x-fastest: v[x + n*(y + n*z)], i.e. a C array indexed [z, y, x].
vol = np.fromfile(path, dtype=np.float32).reshape(n, n, n)
measure.marching_cubes(vol, level)  # warm-up
times = []
for _ in range(runs):
    t = time.perf_counter()
    verts, faces, normals, values = measure.marching_cubes(vol, level)
    times.append(time.perf_counter() - t)
import skimage
print(json.dumps({"times": times, "vertices": len(verts), "triangles": len(faces), "version": skimage.__version__}))
"#;

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn volume(n: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed);
    let blobs: Vec<([f32; 3], f32)> = (0..40)
        .map(|_| {
            let c = [0, 1, 2].map(|_| 0.2 + 0.6 * rng.f64() as f32);
            (c, 0.03 + 0.07 * rng.f64() as f32)
        })
        .collect();
    let mut v = vec![0f32; n * n * n];
    let s = 1.0 / (n - 1) as f32;
    use rayon::prelude::*;
    v.par_chunks_mut(n * n).enumerate().for_each(|(z, slab)| {
        for y in 0..n {
            for x in 0..n {
                let p = [x as f32 * s, y as f32 * s, z as f32 * s];
                let mut f = 0.0;
                for (c, r) in &blobs {
                    let d2 = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2);
                    f += (-d2 / (r * r)).exp();
                }
                slab[x + n * y] = f;
            }
        }
    });
    v
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = arg(&args, "--size").map_or(Ok(256), |s| s.parse())?;
    let runs: usize = arg(&args, "--runs").map_or(Ok(7), |s| s.parse())?;
    let out = PathBuf::from(arg(&args, "--out").unwrap_or_else(|| "examples/results".into()));
    let level = 0.5f32;
    let vol = volume(n, 1);

    let time_ours = |threads: usize| -> (Stats, usize, usize) {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        pool.install(|| {
            let m = marching_cubes(&vol, [n, n, n], level); // warm-up
            let times: Vec<f64> = (0..runs)
                .map(|_| {
                    let t = Instant::now();
                    let m = marching_cubes(&vol, [n, n, n], level);
                    std::hint::black_box(&m);
                    t.elapsed().as_secs_f64()
                })
                .collect();
            (Stats::of(&times), m.positions.len(), m.triangles.len())
        })
    };
    let cores = machine().cores;
    let (ours_all, verts, tris) = time_ours(cores);
    let (ours_one, _, _) = time_ours(1);
    let rss = peak_rss_mib();

    let dir = tempfile::tempdir()?;
    let raw = dir.path().join("volume.f32");
    std::fs::write(
        &raw,
        vol.iter()
            .flat_map(|x| x.to_le_bytes())
            .collect::<Vec<u8>>(),
    )?;
    let script = dir.path().join("mc.py");
    std::fs::write(&script, PY)?;
    let venv = ModelsDir::from_env()?.root.join("venvs/bench-skimage");
    let py = ensure_venv(&venv, "import skimage, numpy", &["scikit-image", "numpy"])?;
    let o = Command::new(&py)
        .arg(&script)
        .arg(&raw)
        .arg(n.to_string())
        .arg(level.to_string())
        .arg(runs.to_string())
        .output()?;
    if !o.status.success() {
        return Err(format!(
            "scikit-image side failed: {}",
            String::from_utf8_lossy(&o.stderr)
        )
        .into());
    }
    let sk: serde_json::Value = serde_json::from_slice(&o.stdout)?;
    let sk_times: Vec<f64> = sk["times"]
        .as_array()
        .ok_or("no times")?
        .iter()
        .filter_map(|t| t.as_f64())
        .collect();
    let sk_stats = Stats::of(&sk_times);

    let report = serde_json::json!({
        "what": format!("marching cubes on a {n}^3 f32 volume (40 seeded Gaussian blobs, level {level}), {runs} timed runs after a warm-up, in one process run"),
        "command": format!("cargo run --release --example mesh_bench -- --size {n} --runs {runs}"),
        "machine": machine(),
        "git_commit": git_commit(),
        "ours_threads_all": ours_all,
        "ours_threads_1": ours_one,
        "ours_vertices": verts,
        "ours_triangles": tris,
        "ours_peak_rss_mib": rss,
        "skimage": sk_stats,
        "skimage_version": sk["version"],
        "skimage_vertices": sk["vertices"],
        "skimage_triangles": sk["triangles"],
        "speedup_all_cores": sk_stats.median / ours_all.median,
        "speedup_one_core": sk_stats.median / ours_one.median,
        "note": "scikit-image's marching_cubes is single-threaded (Lewiner, Cython); both weld vertices along shared edges",
    });
    std::fs::create_dir_all(&out)?;
    let json = out.join("mesh_marching_cubes.json");
    std::fs::write(&json, serde_json::to_string_pretty(&report)?)?;
    let svg = out.join("mesh_marching_cubes.svg");
    std::fs::write(
        &svg,
        chart(
            n,
            &[
                (format!("objnerf, {cores} threads"), ours_all.median),
                ("objnerf, 1 thread".to_string(), ours_one.median),
                (
                    format!("scikit-image {}", sk["version"].as_str().unwrap_or("")),
                    sk_stats.median,
                ),
            ],
        )?,
    )?;
    println!(
        "{n}^3: ours {:.3} s ({cores} threads), {:.3} s (1 thread); scikit-image {:.3} s -> {:.1}x / {:.1}x; {verts} vs {} vertices; peak RSS {rss} MiB\n{}",
        ours_all.median,
        ours_one.median,
        sk_stats.median,
        sk_stats.median / ours_all.median,
        sk_stats.median / ours_one.median,
        sk["vertices"],
        json.display()
    );
    Ok(())
}

fn chart(n: usize, bars: &[(String, f64)]) -> Result<String, Box<dyn std::error::Error>> {
    use plotters::prelude::*;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (720, 360)).into_drawing_area();
        root.fill(&WHITE)?;
        let hi = bars.iter().map(|b| b.1).fold(0.0, f64::max) * 1.2;
        let mut c = ChartBuilder::on(&root)
            .caption(
                format!("marching cubes, {n}^3 volume: median seconds"),
                ("sans-serif", 18),
            )
            .margin(16)
            .x_label_area_size(30)
            .y_label_area_size(190)
            .build_cartesian_2d(0f64..hi, (0..bars.len()).into_segmented())?;
        c.configure_mesh()
            .x_desc("seconds (median)")
            .y_labels(bars.len())
            .y_label_formatter(&|v| match v {
                SegmentValue::CenterOf(i) => bars.get(*i).map(|b| b.0.clone()).unwrap_or_default(),
                _ => String::new(),
            })
            .draw()?;
        let colours = [
            RGBColor(31, 119, 180),
            RGBColor(174, 199, 232),
            RGBColor(255, 127, 14),
        ];
        c.draw_series(bars.iter().enumerate().map(|(i, b)| {
            Rectangle::new(
                [
                    (0.0, SegmentValue::Exact(i)),
                    (b.1, SegmentValue::Exact(i + 1)),
                ],
                colours[i % 3].filled(),
            )
        }))?;
    }
    Ok(svg)
}
