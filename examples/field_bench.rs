//! Lego benchmark for the object field: train at a downscale on the train views, evaluate on the
//! test views (composited on white), print one JSON line.
//!
//! cargo run --release --example field_bench -- DATA_DIR DOWNSCALE SECONDS [SH_DEGREE] [STEPS]

use objnerf::field::{self, MaskSource, SetupConfig, StopRule, TrainConfig};
use std::path::PathBuf;

fn main() -> objnerf::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let dir = PathBuf::from(
        args.get(1)
            .map(String::as_str)
            .unwrap_or("../shared/data/lego"),
    );
    let ds: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(4);
    let secs: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(120.0);
    let degree: u32 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(1);
    let steps: usize = args.get(5).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let t0 = std::time::Instant::now();
    let train = field::synthetic_tmp::load_scene(&dir.join("transforms_train.json"))?;
    let test = field::synthetic_tmp::load_scene(&dir.join("transforms_test.json"))?;
    let views = field::rays::load_views(&train, &MaskSource::Alpha, ds)?;
    let test_views = field::rays::load_views(&test, &MaskSource::Alpha, ds)?;
    let load_s = t0.elapsed().as_secs_f64();
    let setup = SetupConfig {
        sh_degree: degree,
        ..Default::default()
    };
    let mut cfg = TrainConfig {
        steps,
        ..Default::default()
    };
    if let Ok(st) = std::env::var("FIELD_STAGES") {
        // e.g. "0:0.5,0.3:1"
        cfg.stages = st
            .split(',')
            .filter_map(|p| p.split_once(':'))
            .map(|(a, b)| (a.parse().unwrap(), b.parse().unwrap()))
            .collect();
    }
    if let Ok(b) = std::env::var("FIELD_PRUNE") {
        cfg.prune_every = b.parse().unwrap();
    }
    if let Ok(b) = std::env::var("FIELD_TV") {
        let (a, c) = b.split_once(',').unwrap();
        cfg.tv_density = a.parse().unwrap();
        cfg.tv_color = c.parse().unwrap();
    }
    if let Ok(b) = std::env::var("FIELD_STEP") {
        cfg.render.step = b.parse().unwrap();
    }
    if let Ok(b) = std::env::var("FIELD_LR") {
        let (a, c) = b.split_once(',').unwrap();
        cfg.lr_density = a.parse().unwrap();
        cfg.lr_color = c.parse().unwrap();
    }
    if let Ok(b) = std::env::var("FIELD_BATCH") {
        cfg.batch = b.parse().unwrap();
    }
    let t1 = std::time::Instant::now();
    let (mut trainer, rays, report) = field::prepare(&views, &setup, cfg)?;
    let prep_s = t1.elapsed().as_secs_f64();
    eprintln!("{}", serde_json::to_string(&report).unwrap());
    let stop = StopRule {
        time_budget: Some(secs),
        plateau_db: None,
        window: 100,
    };
    let mut next_eval = 0.0;
    let summary = field::run(&mut trainer, &views, &rays, &stop, |s, t| {
        if t >= next_eval {
            eprintln!(
                "t={t:.1}s step={} loss={:.5} psnr={:.2} spr={:.1} dims={:?} occ={}",
                s.step,
                s.loss,
                s.psnr,
                s.samples_per_ray,
                trainer_dims(),
                0
            );
            next_eval = t + 10.0;
        }
    });
    let ev = field::eval::evaluate(&trainer.field, &trainer.cfg.render, &test_views);
    let out = serde_json::json!({
        "downscale": ds, "sh_degree": degree, "budget_s": secs,
        "load_s": load_s, "prepare_s": prep_s, "train": summary,
        "setup": report, "vertices": trainer.field.grid.num_vertices(),
        "dims": trainer.field.grid.dims,
        "occupied_cells": trainer.field.occupied_cells(),
        "phase_secs": trainer.phase_secs,
        "memory_mb": trainer.memory_bytes() as f64 / 1048576.0,
        "test_psnr": ev.psnr, "test_ssim": ev.ssim, "num_views": ev.num_views, "eval_s": ev.seconds,
    });
    println!("{out}");
    Ok(())
}

fn trainer_dims() -> &'static str {
    ""
}
