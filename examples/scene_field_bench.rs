//! Scene field on the demo scene: train on all views but every 6th, score the held-out ones
//! (full frame, on the truth), print one JSON line. Settings from the environment for sweeps:
//! SF_DOWNSCALE, SF_SECONDS, SF_ALPHA_INIT, SF_SH, SF_MEM_MB, SF_FIRST_SHARE (share of the memory
//! the dense first stage may take), SF_SPACE, SF_STEPS, SF_STAGES, SF_HOLD (llff, N: the views
//! held out), SF_NET, SF_SCENE_NET, SF_HIDDEN (a scene colour network's hidden units), SF_VPP, SF_TV_D, SF_TV_C, SF_TV_EVERY (TV on every this many steps, at that many times the weight), SF_TV_UNTIL (the fraction of the schedule after which TV stops), SF_BATCH, SF_LR_D, SF_LR_C (the rates before SF_RATE_SCALE_DEPTH, their factor where depth targets exist), SF_FREE, SF_DEPTH_W, SF_DEPTH_C (a ring's or
//! unbounded capture's), SF_FWD_DIST, SF_FWD_DEPTH_W, SF_FWD_DEPTH_C, SF_FWD_FREE, SF_FWD_SEED, SF_FWD_TV_D, SF_FWD_TV_C, SF_FWD_TV_EVERY, SF_FWD_TV_UNTIL (a forward capture's), SF_TERM (training's early termination), SF_SAMPLE_STEP (training's sample spacing in voxels), SF_WHOLE (train for the whole SF_SECONDS, the schedule
//! following the time, as `objnerf train --time-budget` does).
//!
//! cargo run --release --example scene_field_bench -- DEMO_SCENE_DIR

#[path = "support/bench.rs"]
mod bench;

use objnerf::field::eval::evaluate;
use objnerf::field::holdout::{held_out_views, HoldOut};
use objnerf::field::{load_views, MaskSource, RenderOptions, SetupConfig, TrainConfig};
use objnerf::fit::{FitOptions, SceneFit, SceneFitOptions, SCENE_FIT_VIEWS};
use std::path::PathBuf;

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn main() -> objnerf::Result<()> {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or("runs/demo/scene".into()));
    let scene = objnerf::Scene::load(&dir)?;
    let downscale: u32 = env("SF_DOWNSCALE").unwrap_or(1);
    let mut setup = SetupConfig::default();
    if let Some(a) = env("SF_ALPHA_INIT") {
        setup.alpha_init = a;
    }
    if let Some(d) = env("SF_SH") {
        setup.sh_degree = d;
    }
    if let Some(m) = env::<usize>("SF_MEM_MB") {
        setup.memory_budget = m << 20;
    }
    if let Some(v) = env("SF_FIRST_SHARE") {
        setup.first_stage_share = v;
    }
    if let Some(f) = env("SF_NET") {
        setup.net_features = f;
    }
    if let Some(f) = env("SF_SCENE_NET") {
        setup.scene_net_features = Some(f);
    }
    if let Some(h) = env("SF_HIDDEN") {
        setup.scene_net_hidden = h;
    }
    if let Some(v) = env("SF_VPP") {
        setup.voxels_per_pixel = v;
    }
    let hold: HoldOut = env("SF_HOLD").unwrap_or(HoldOut::Every(6));
    let held = held_out_views(&scene, hold);
    let d = SceneFitOptions::default();
    let mut opts = SceneFitOptions {
        space: env("SF_SPACE").unwrap_or_default(),
        fit: FitOptions {
            downscale,
            time_budget: Some(env("SF_SECONDS").unwrap_or(120.0)),
            steps: env("SF_STEPS").unwrap_or(20_000),
            // SF_WHOLE=true: the schedule follows SF_SECONDS, as `train --time-budget` does.
            whole_budget: env("SF_WHOLE").unwrap_or(false),
            setup,
            exclude_views: held.clone(),
            depth: env("SF_DEPTH").unwrap_or(d.fit.depth),
            ..Default::default()
        },
        train: TrainConfig {
            prune_after: env("SF_PRUNE_AFTER").unwrap_or(d.train.prune_after),
            carve_weight: env("SF_CARVE").unwrap_or(d.train.carve_weight),
            distortion_weight: env("SF_DIST").unwrap_or(d.train.distortion_weight),
            prune_alpha: env("SF_PRUNE_ALPHA").unwrap_or(d.train.prune_alpha),
            free_space_weight: env("SF_FREE").unwrap_or(d.train.free_space_weight),
            depth_weight: env("SF_DEPTH_W").unwrap_or(d.train.depth_weight),
            depth_robust_voxels: env("SF_DEPTH_C").unwrap_or(d.train.depth_robust_voxels),
            tv_density: env("SF_TV_D").unwrap_or(d.train.tv_density),
            tv_color: env("SF_TV_C").unwrap_or(d.train.tv_color),
            tv_every: env("SF_TV_EVERY").unwrap_or(d.train.tv_every),
            tv_until: env("SF_TV_UNTIL").unwrap_or(d.train.tv_until),
            batch: env("SF_BATCH").unwrap_or(d.train.batch),
            lr_density: env("SF_LR_D").unwrap_or(d.train.lr_density),
            lr_color: env("SF_LR_C").unwrap_or(d.train.lr_color),
            render: objnerf::field::march::RenderOptions {
                term_thresh: env("SF_TERM").unwrap_or(d.train.render.term_thresh),
                step: env("SF_SAMPLE_STEP").unwrap_or(d.train.render.step),
                ..d.train.render
            },
            ..d.train.clone()
        },
        ..Default::default()
    };
    // A forward capture's depth settings (SF_FWD_*).
    let f = &mut opts.forward;
    f.distortion_weight = env("SF_FWD_DIST").unwrap_or(f.distortion_weight);
    f.depth_weight = env("SF_FWD_DEPTH_W").unwrap_or(f.depth_weight);
    f.depth_robust_voxels = env("SF_FWD_DEPTH_C").unwrap_or(f.depth_robust_voxels);
    f.free_space_weight = env("SF_FWD_FREE").unwrap_or(f.free_space_weight);
    f.seed_from_depth = env("SF_FWD_SEED").unwrap_or(f.seed_from_depth);
    f.rate_scale_with_depth = env("SF_RATE_SCALE_DEPTH").unwrap_or(f.rate_scale_with_depth);
    f.tv = (
        env("SF_FWD_TV_D").unwrap_or(f.tv.0),
        env("SF_FWD_TV_C").unwrap_or(f.tv.1),
        env("SF_FWD_TV_EVERY").unwrap_or(f.tv.2),
    );
    f.tv_until = env("SF_FWD_TV_UNTIL").unwrap_or(f.tv_until);
    opts.rate_scale_with_depth = env("SF_RATE_SCALE_DEPTH").unwrap_or(opts.rate_scale_with_depth);
    // The stages are a training setting; sweeps may override them ("0:0.25,0.3:1").
    if let Ok(st) = std::env::var("SF_STAGES") {
        opts.train.stages = st
            .split(',')
            .filter_map(|p| p.split_once(':'))
            .filter_map(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
            .collect();
    }
    let cpu0 = bench::cpu_seconds();
    let t0 = std::time::Instant::now();
    let mut last = 0.0;
    // SF_LOG_EVERY: a line every this many steps (else every 20 s).
    let log_every: usize = env("SF_LOG_EVERY").unwrap_or(0);
    let (mut spr, mut nspr) = (0.0f64, 0usize);
    let mut fit = SceneFit::new(&scene, &opts)?;
    eprintln!("space: {}", fit.space_choice());
    fit.train(&opts.fit.stop_rule(), &mut |s| {
        spr += s.samples_per_ray as f64;
        nspr += 1;
        if (log_every > 0 && s.step % log_every == 0) || (log_every == 0 && s.seconds >= last) {
            eprintln!(
                "t={:.0}s step={} psnr={:.2} samples/ray={:.1} rays/s={:.0}",
                s.seconds, s.step, s.psnr, s.samples_per_ray, s.rays_per_second
            );
            last = s.seconds + 20.0;
        }
    });
    fit.check_fit(SCENE_FIT_VIEWS);
    let fitted = fit.finish();
    let train_s = t0.elapsed().as_secs_f64();
    if let Ok(path) = std::env::var("SF_SAVE") {
        let notes = objnerf::fit::model_notes(
            objnerf::fit::FieldKind::Scene,
            &scene,
            &opts.fit,
            &fitted.report,
        );
        objnerf::field::io::save(
            std::path::Path::new(&path),
            &fitted.trainer.parts(objnerf::field::io::IDENTITY, notes),
        )?;
    }
    let views: Vec<_> = load_views(&scene, &MaskSource::Opaque, downscale)?
        .into_iter()
        .filter(|v| held.contains(&v.name))
        .collect();
    let ev = evaluate(&fitted.trainer.field, &RenderOptions::default(), &views);
    let out = serde_json::json!({
        "downscale": downscale, "train_s": train_s, "cpu_s": bench::cpu_seconds() - cpu0,
        "steps": fitted.report.run.steps, "rays_per_s": fitted.report.run.rays_per_second,
        "mean_samples_per_ray": spr / nspr.max(1) as f64, "heldout_psnr": ev.psnr, "heldout_ssim": ev.ssim,
        "finest": fitted.report.finest, "occupied_cells": fitted.report.occupied_cells,
        "memory_mb": fitted.report.memory_bytes >> 20,
        "peak_rss_mib": objnerf::util::mem::peak_rss_mib(),
        "space": fitted.report.setup.as_ref().map(|s| s.space.name()),
        "phase_seconds": fitted.report.run.phases,
    });
    println!("{out}");
    Ok(())
}
