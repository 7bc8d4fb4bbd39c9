//! A scene field finds a capture's geometry from its photos alone (issue 53): a forward-facing
//! capture, whose cameras stand close together, trained with no depth at all, renders its
//! held-out views. Its distortion loss once measured spread in world length, which NDC stretches
//! without bound toward infinity, and put every ray's weight on the near plane: the forward demo
//! then held out 14.5 dB. Here (12 views at 160x120, 600 steps, ~60 s on 2 cores) it holds out
//! 21.45 dB, and 14.78 with the distortion loss at a ring's weight: the test fails on either.

use objnerf::demo::{write_demo_scene, DemoLayout, DemoOptions};
use objnerf::field::eval::evaluate;
use objnerf::field::holdout::{held_out_views, HoldOut};
use objnerf::field::{load_views, MaskSource, RenderOptions};
use objnerf::fit::{FitOptions, SceneFitOptions};
use objnerf::supervision::DepthMode;
use objnerf::Scene;

/// The stability suite's line for a novel view a user would accept (the stripes of the demo mug
/// soft but all there: docs/floors.md), decided before this test's results.
const HELD_OUT_FLOOR_DB: f64 = objnerf::bench::stability::score::PSNR_FLOOR;

#[test]
fn a_forward_field_finds_its_depth_from_the_photos_alone() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("forward");
    let demo = DemoOptions {
        views: 12,
        layout: DemoLayout::Forward,
        width: 160,
        height: 120,
        ..Default::default()
    };
    write_demo_scene(&demo, &out).unwrap();
    let scene = Scene::load(&out).unwrap();
    let held = held_out_views(&scene, HoldOut::Every(4));
    let mut opts = SceneFitOptions {
        fit: FitOptions {
            steps: 600,
            depth: DepthMode::None,
            exclude_views: held.clone(),
            ..Default::default()
        },
        ..Default::default()
    };
    // No depth at all: not the sparse points', not stereo's, no surfaces seeded from them.
    opts.forward.depth_weight = 0.0;
    opts.forward.free_space_weight = 0.0;
    opts.forward.seed_from_depth = false;
    opts.exclude_points = (0..scene.points.len()).collect();
    let mut fit = objnerf::fit::SceneFit::new(&scene, &opts).unwrap();
    assert!(
        fit.space_choice().starts_with("forward"),
        "{}",
        fit.space_choice()
    );
    fit.train(&opts.fit.stop_rule(), &mut |_| {});
    let fitted = fit.finish();
    // The report says where the training time went (the captures' chart reads it).
    let run = &fitted.report.run;
    let p = run.phases;
    let parts = p.rays + p.scatter + p.tv + p.upkeep;
    assert!(p.rays > 0.0 && p.scatter > 0.0, "{run:?}");
    assert!(
        parts <= run.seconds,
        "{parts} s of parts in {} s",
        run.seconds
    );
    assert!(run.samples_per_ray > 0.0, "{run:?}");
    let field = fitted.trainer.field;
    let views: Vec<_> = load_views(&scene, &MaskSource::Opaque, 1)
        .unwrap()
        .into_iter()
        .filter(|v| held.contains(&v.name))
        .collect();
    assert_eq!(views.len(), 3);
    let report = evaluate(&field, &RenderOptions::default(), &views);
    println!("forward demo, no depth: held out {:.2} dB", report.psnr);
    assert!(
        report.psnr >= HELD_OUT_FLOOR_DB,
        "held-out PSNR {:.2} < {HELD_OUT_FLOOR_DB} dB: the field did not find the geometry",
        report.psnr
    );
}
