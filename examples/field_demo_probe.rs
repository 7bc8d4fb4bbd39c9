//! Probe: train one demo object from its true masks on 30 views, score the 6 held out.
use objnerf::field::{self, holdout, MaskSource, SetupConfig, StopRule, TrainConfig};
use std::path::PathBuf;

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn main() -> objnerf::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    let dir = PathBuf::from(&a[1]);
    let obj = a[2].clone();
    let secs: f64 = a[3].parse().unwrap();
    let depth_mode = a.get(4).cloned().unwrap_or("none".into());
    let scene = objnerf::Scene::load(&dir.join("transforms.json"))?;
    let ds = env("DS").unwrap_or(1);
    let mut views = field::rays::load_views(
        &scene,
        &MaskSource::Dir(dir.join("truth/masks").join(&obj)),
        ds,
    )?;
    field::depth::add_dense_depth(&mut views, &scene, ds)?;
    let (mut train, test) = holdout::split_every(views, 6);
    if depth_mode == "none" {
        train.iter_mut().for_each(|v| v.depth = None);
    }
    let mut setup = SetupConfig::default();
    if let Some(v) = env("VPP") {
        setup.voxels_per_pixel = v;
    }
    if let Some(v) = env("PAD") {
        setup.pad = v;
    }
    let mut cfg = TrainConfig {
        steps: env("STEPS").unwrap_or(100_000),
        ..Default::default()
    };
    if let Some(v) = env("DW") {
        cfg.depth_weight = v;
    }
    if let Some(v) = env("DIST") {
        cfg.distortion_weight = v;
    }
    if let Some(v) = env("AW") {
        cfg.alpha_weight = v;
    }
    if let Some(v) = env("STEP") {
        cfg.render.step = v;
    }
    if let Some(v) = env("BATCH") {
        cfg.batch = v;
    }
    if let Some(v) = env("TVD") {
        cfg.tv_density = v;
    }
    let (mut t, rays, rep) = field::prepare(&train, &setup, cfg)?;
    eprintln!("{}", serde_json::to_string(&rep).unwrap());
    let stop = StopRule {
        time_budget: Some(secs),
        plateau_db: None,
        window: 500,
    };
    let run = field::run(&mut t, &train, &rays, &stop, |_, _| {});
    let mut opt = field::RenderOptions::default();
    if let Some(v) = env("EVALSTEP") {
        opt.step = v;
    }
    let ev = field::eval::evaluate(&t.field, &opt, &test);
    let de = holdout::depth_error(&t.field, &opt, &test);
    let de_tr = holdout::depth_error(&t.field, &opt, &train);
    if let Ok(out) = std::env::var("DUMP") {
        for (k, v) in test.iter().enumerate() {
            let r = field::eval::render_view(&t.field, &opt, v, [1.0; 3]);
            let td = v.depth.as_ref().unwrap();
            let img = image::RgbImage::from_fn(v.width, v.height, |x, y| {
                let i = (y * v.width + x) as usize;
                if td[i] <= 0.0 {
                    return image::Rgb([if r.alpha[i] > 0.5 { 255 } else { 0 }, 255, 0]);
                }
                let e = (r.depth[i] - td[i]) / v.ray_scale(i as u32) * 1000.0; // mm
                let c = |q: f32| (q.clamp(0.0, 1.0) * 255.0) as u8;
                image::Rgb([c(e / 20.0), c(-e / 20.0), c(1.0 - e.abs() / 20.0) / 2])
            });
            img.save(format!("{out}_{k}.png")).unwrap();
        }
    }
    let truth = objnerf::demo::read_truth(&dir)?;
    let o = truth.iter().find(|o| o.name == obj).unwrap();
    let diag = glam::DVec3::from(o.bbox_max).distance(glam::DVec3::from(o.bbox_min));
    println!(
        "{}",
        serde_json::json!({
            "obj": obj, "depth": depth_mode, "steps": run.steps, "secs": run.seconds,
            "psnr": ev.psnr, "ssim": ev.ssim, "per_view": ev.views.iter().map(|v| (v.name.clone(), (v.psnr*100.0).round()/100.0)).collect::<Vec<_>>(),
            "depth_med_mm": de.median*1000.0, "depth_frac_diag": de.median/diag, "signed_mm": de.mean_signed*1000.0, "p90_mm": de.p90*1000.0, "half_med_mm": de.median_half*1000.0,
            "transparent": de.transparent, "pixels": de.pixels,
            "train_depth_med_mm": de_tr.median*1000.0, "train_signed_mm": de_tr.mean_signed*1000.0,
            "voxel_mm": rep.voxel*1000.0, "diag": diag, "pruned": rep.pruned_fraction,
        })
    );
    Ok(())
}
