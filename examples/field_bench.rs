//! Lego benchmark for the object field: train at a downscale on the 100 train views within a time
//! budget, evaluate on the test views (composited on white), print one JSON object (and write it
//! to `--json PATH` if given).
//!
//! cargo run --release --example field_bench -- DATA_DIR DOWNSCALE SECONDS [SH_DEGREE] [STEPS]
//! cargo run --release --example field_bench -- demo SCENE_DIR OBJECT SECONDS [none|dense|sparse]
//!     (FIELD_STEPS=N: N steps instead of the time budget; FIELD_LR, FIELD_LR_FINAL as below)
//!
//! `examples/field_pareto.rs` runs a sweep of these (one process each, for peak RSS) and draws
//! the chart.
//!
//! Environment overrides for sweeps: FIELD_BATCH, FIELD_RUN (pixels per run of neighbours a batch
//! is drawn in; default 1; 0: runs of 8 on large grids), FIELD_SPARSE (sparsity loss weight),
//! FIELD_STEP (sample spacing in voxels), FIELD_STAGES ("0:0.5,0.3:1": fraction of the schedule and
//! grid scale; taken whether or not the memory budget binds), FIELD_PRUNE (steps between occupancy
//! updates), FIELD_TV ("density,colour"), FIELD_LR ("density,colour"), FIELD_VPP (voxels per pixel
//! footprint), FIELD_MEM_MB, FIELD_FIRST_SHARE (share of the memory the dense first stage may
//! take), FIELD_CARVE (carve weight before each growth), FIELD_LR_FINAL, FIELD_ALPHA_INIT,
//! FIELD_SEED, FIELD_NET ("features,hidden": colour network at any view count; "0,0": SH),
//! FIELD_LR_NET, FIELD_LARGE (passes over the pixels from which the large model is taken; FIELD_NET
//! and FIELD_VPP turn it off), FIELD_NET_SH (SH degree of the network's view input), FIELD_PRUNE_ALPHA (cells
//! less opaque than this a step are pruned), FIELD_DIST (distortion loss weight, distances in
//! finest voxels); FIELD_LR, FIELD_LR_FINAL, FIELD_SEED, FIELD_RUN, FIELD_BATCH, FIELD_BETAS
//! ("beta1,beta2": Adam's), FIELD_NET_REFLECT (1: the network also takes the reflected view
//! direction), FIELD_NET_HIDDEN2 (units of a second hidden layer at any view size; 0: one
//! layer), FIELD_VIEW_JITTER (degrees a training ray's view direction is turned by at random),
//! FIELD_EVAL_PIXELS (n: the JSON's "antialiased" scores the same parameters with each pixel the
//! mean of n x n rays; `demo` scores with it instead of one ray), FIELD_SPARSE,
//! FIELD_PRUNE_ALPHA and FIELD_DIST apply to `demo` too.

#[path = "support/bench.rs"]
mod bench;

use bench::cpu_seconds;
use objnerf::field::{self, MaskSource, SetupConfig, StopRule, TrainConfig};
use std::path::PathBuf;

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn pair(name: &str) -> Option<(f32, f32)> {
    let v = std::env::var(name).ok()?;
    let (a, b) = v.split_once(',')?;
    Some((a.parse().ok()?, b.parse().ok()?))
}

/// The overrides both benchmarks take: FIELD_BATCH, FIELD_LR, FIELD_LR_FINAL, FIELD_SEED,
/// FIELD_RUN, FIELD_BETAS, FIELD_SPARSE, FIELD_PRUNE_ALPHA, FIELD_DIST, FIELD_AVERAGE
/// ("from,every": Polyak averaging from that fraction of the run).
fn optimiser_overrides(cfg: &mut TrainConfig) {
    if let Some(v) = env("FIELD_BATCH") {
        cfg.batch = v;
    }
    if let Some((a, b)) = pair("FIELD_LR") {
        (cfg.lr_density, cfg.lr_color) = (a, b);
    }
    if let Some(v) = env("FIELD_LR_FINAL") {
        (cfg.lr_final, cfg.lr_final_network) = (v, v);
    }
    if let Some(v) = env("FIELD_SEED") {
        cfg.seed = v;
    }
    if let Some(v) = env("FIELD_RUN") {
        cfg.ray_run = v;
    }
    if let Some((a, b)) = pair("FIELD_BETAS") {
        (cfg.beta1, cfg.beta2) = (a, b);
    }
    if let Some(v) = env("FIELD_SPARSE") {
        cfg.sparsity_weight = v;
    }
    if let Some(v) = env("FIELD_PRUNE_ALPHA") {
        cfg.prune_alpha = v;
    }
    if let Some(v) = env("FIELD_DIST") {
        cfg.distortion_weight = v;
    }
    if let Some(v) = env::<f32>("FIELD_VIEW_JITTER") {
        cfg.view_jitter = v.to_radians();
    }
    if let Some((from, every)) = pair("FIELD_AVERAGE") {
        (cfg.average_from, cfg.average_from_network) = (from, from);
        cfg.average_every = every as usize;
    }
}

/// The colour overrides both benchmarks take: FIELD_NET ("features,hidden"; "0,0": SH colour;
/// either at any number of views) and FIELD_LR_NET.
fn net_overrides(setup: &mut SetupConfig, cfg: &mut TrainConfig) {
    if let Some((f, h)) = pair("FIELD_NET") {
        (setup.net_features, setup.net_hidden) = (f as usize, h as usize);
        setup.net_min_views = 0;
        // The network asked for, not the large model.
        setup.large_model_passes = f64::INFINITY;
    }
    if let Some(v) = env("FIELD_LARGE") {
        setup.large_model_passes = v;
    }
    if let Some(v) = env("FIELD_LR_NET") {
        cfg.lr_net = v;
    }
    if let Some(v) = env("FIELD_NET_SH") {
        setup.net_sh_degree = v;
    }
    if let Some(v) = env::<u32>("FIELD_NET_REFLECT") {
        setup.net_reflect = v != 0;
    }
    if let Some(v) = env("FIELD_NET_HIDDEN2") {
        // At any view size.
        (setup.net_hidden2, setup.net_hidden2_min_view_pixels) = (v, 0);
    }
}

/// `demo SCENE_DIR OBJECT SECONDS [none|dense|sparse]`: one demo object from its true masks,
/// scored on the held-out views (`demo::holdout::demo_object`).
fn demo(args: &[String]) -> objnerf::Result<()> {
    use objnerf::demo::holdout::{demo_object, DemoRun};
    let dir = PathBuf::from(&args[2]);
    let object = &args[3];
    let secs: f64 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(30.0);
    let depth = args
        .get(5)
        .map(|s| s.parse().map_err(objnerf::Error::invalid))
        .transpose()?
        .unwrap_or(objnerf::supervision::DepthMode::None);
    // FIELD_STEPS: a fixed step count instead of the time budget (the same result at any load).
    let mut train = TrainConfig::default();
    optimiser_overrides(&mut train);
    let steps: Option<usize> = env("FIELD_STEPS");
    if let Some(n) = steps {
        train.steps = n;
    }
    let mut setup = SetupConfig::default();
    net_overrides(&mut setup, &mut train);
    let cpu0 = cpu_seconds();
    let r = demo_object(
        &dir,
        object,
        &DemoRun {
            depth,
            setup,
            train,
            stop: StopRule {
                time_budget: steps.is_none().then_some(secs),
                plateau_db: None,
                window: 100,
                ..Default::default()
            },
            pixel_samples: env("FIELD_EVAL_PIXELS").unwrap_or(1),
            ..Default::default()
        },
    )?;
    let out = serde_json::json!({
        "command": args.join(" "), "git_commit": bench::git_commit(),
        "threads": rayon::current_num_threads(), "budget_s": secs,
        "depth_supervision": format!("{depth:?}"), "cpu_s": cpu_seconds() - cpu0,
        "peak_rss_mib": objnerf::util::mem::peak_rss_mib(), "report": r,
    });
    println!("{out}");
    Ok(())
}

fn main() -> objnerf::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("demo") {
        return demo(&args);
    }
    let dir = PathBuf::from(
        args.get(1)
            .map(String::as_str)
            .unwrap_or("../shared/data/lego"),
    );
    let ds: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(4);
    let secs: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(120.0);
    let degree: u32 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(1);
    // No step cap by default: the schedule follows the time budget (as `objnerf train
    // --time-budget` without `--steps`).
    let steps: usize = args
        .get(5)
        .and_then(|s| s.parse().ok())
        .unwrap_or(objnerf::fit::UNCAPPED_STEPS);
    let t0 = std::time::Instant::now();
    let train = objnerf::Scene::load(&dir.join("transforms_train.json"))?;
    let test = objnerf::Scene::load(&dir.join("transforms_test.json"))?;
    let views = field::load_views(&train, &MaskSource::Alpha, ds)?;
    let test_views = field::load_views(&test, &MaskSource::Alpha, ds)?;
    let load_s = t0.elapsed().as_secs_f64();
    // Sized for the budget as `objnerf train --time-budget` sizes it (a STEPS argument caps
    // the passes the budget affords).
    let mut setup = SetupConfig {
        sh_degree: degree,
        ..Default::default()
    };
    if let Some(v) = env("FIELD_VPP") {
        setup.voxels_per_pixel = v;
        setup.large_model_passes = f64::INFINITY;
    }
    if let Some(v) = env("FIELD_ALPHA_INIT") {
        setup.alpha_init = v;
    }
    if let Some(v) = env::<usize>("FIELD_MEM_MB") {
        setup.memory_budget = v << 20;
    }
    if let Some(v) = env("FIELD_FIRST_SHARE") {
        setup.first_stage_share = v;
    }
    let mut cfg = TrainConfig {
        steps,
        ..Default::default()
    };
    net_overrides(&mut setup, &mut cfg);
    if let Ok(st) = std::env::var("FIELD_STAGES") {
        cfg.stages = st
            .split(',')
            .filter_map(|p| p.split_once(':'))
            .filter_map(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
            .collect();
        cfg.stages_when_capped = cfg.stages.clone();
    }
    if let Some(v) = env("FIELD_PRUNE") {
        cfg.prune_every = v;
    }
    if let Some((a, b)) = pair("FIELD_TV") {
        (cfg.tv_density, cfg.tv_color) = (a, b);
    }
    if let Some(v) = env("FIELD_STEP") {
        cfg.render.step = v;
    }
    if let Some(v) = env("FIELD_CARVE") {
        cfg.carve_weight = v;
    }
    optimiser_overrides(&mut cfg);
    let cpu0 = cpu_seconds();
    let t1 = std::time::Instant::now();
    let (mut trainer, rays, report) = field::prepare(&views, &[], &setup, cfg, Some(secs))?;
    let prep_s = t1.elapsed().as_secs_f64();
    eprintln!("{}", serde_json::to_string(&report).unwrap_or_default());
    let stop = StopRule {
        time_budget: Some(secs),
        plateau_db: None,
        window: 100,
        // The last parameters are scored beside their mean, below.
        keep_last: true,
        ..Default::default()
    };
    let mut next_log = 0.0;
    let summary = field::run(&mut trainer, &views, &rays, &stop, |s| {
        let t = s.seconds;
        if t >= next_log {
            eprintln!(
                "t={t:.1}s step={} loss={:.5} psnr={:.2} samples/ray={:.1}",
                s.step, s.loss, s.psnr, s.samples_per_ray
            );
            next_log = t + 10.0;
        }
    });
    let train_cpu = cpu_seconds() - cpu0;
    let memory_mb = trainer.memory_bytes() as f64 / 1048576.0;
    // The last parameters scored beside their mean, when the run kept one: the same run, so
    // the difference is the averaging's alone.
    let last = trainer.has_average().then(|| {
        field::eval::evaluate(
            &trainer.field,
            &field::RenderOptions::default(),
            &test_views,
        )
    });
    let averaged = trainer.take_average();
    // Evaluate with the default (finer) sampling whatever the training step was.
    let ev = field::eval::evaluate(
        &trainer.field,
        &field::RenderOptions::default(),
        &test_views,
    );
    // FIELD_EVAL_PIXELS=n: the same parameters scored again, each pixel the mean of n x n rays.
    let antialiased = env::<u32>("FIELD_EVAL_PIXELS").map(|n| {
        let opt = field::RenderOptions {
            pixel_samples: n,
            ..field::RenderOptions::default()
        };
        let e = field::eval::evaluate(&trainer.field, &opt, &test_views);
        serde_json::json!({
            "pixel_samples": n, "test_psnr": e.psnr, "test_ssim": e.ssim, "test_views": e.views,
        })
    });
    let commit = bench::git_commit();
    let out = serde_json::json!({
        "command": args.join(" "),
        "git_commit": commit,
        "threads": rayon::current_num_threads(),
        "downscale": ds, "sh_degree": degree, "field_sh_degree": trainer.field.config.sh_degree,
        "budget_s": secs,
        "batch": trainer.cfg.batch, "step_voxels": trainer.cfg.render.step,
        "load_s": load_s, "prepare_s": prep_s, "train": summary,
        "train_cpu_s": train_cpu,
        "setup": report, "vertices": trainer.field.grid.num_vertices(),
        "dims": trainer.field.grid.dims,
        "occupied_cells": trainer.field.occupied_cells(), "finest": trainer.finest,
        "phase_secs": trainer.phase_secs,
        "memory_mb": memory_mb, "peak_rss_mib": objnerf::util::mem::peak_rss_mib(),
        "test_psnr": ev.psnr, "test_ssim": ev.ssim, "num_views": ev.num_views, "eval_s": ev.seconds,
        "test_views": ev.views,
        "antialiased": antialiased,
        "averaged_snapshots": averaged,
        "last_params": last.map(|l| serde_json::json!({
            "test_psnr": l.psnr, "test_ssim": l.ssim, "test_views": l.views,
        })),
    });
    println!("{out}");
    if let Some(i) = args.iter().position(|a| a == "--json") {
        if let Some(p) = args.get(i + 1) {
            objnerf::util::atomic::write_bytes_atomic(
                std::path::Path::new(p),
                serde_json::to_string_pretty(&out)
                    .unwrap_or_default()
                    .as_bytes(),
            )?;
        }
    }
    Ok(())
}
