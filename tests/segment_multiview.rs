//! Multi-view segmentation (Algorithm 1) with the real SAM on the demo scene, against its truth:
//! masks, obstructed views, and the projection baseline.
mod common;

use objnerf::demo::{read_truth, write_demo_scene, DemoOptions};
use objnerf::models::ModelsDir;
use objnerf::sam::{Precision, Segmenter};
use objnerf::segment::evaluate::{alpha_truth, view_ious};
use objnerf::segment::propagate::{projection_baseline, propagate_objects};
use objnerf::segment::{
    segment_scene, ObjectPrompt, ObjectSegmentation, PointPrompt, PropagationOptions, SamViews,
    ViewStatus,
};
use objnerf::util::mask::iou;
use objnerf::util::stats::mean;
use objnerf::util::Silent;
use objnerf::Scene;

fn models() -> Option<ModelsDir> {
    let dir = ModelsDir::from_env().ok()?;
    if dir.require_sam().is_err() || dir.require_library().is_err() {
        common::skip("SAM models are not installed (scripts/setup runs `objnerf models install`)");
        return None;
    }
    Some(dir)
}

fn truth_mask(scene_dir: &std::path::Path, object: &str, view: &str) -> image::GrayImage {
    let stem = std::path::Path::new(view).with_extension("");
    image::open(
        scene_dir
            .join("truth/masks")
            .join(object)
            .join(format!("{}.png", stem.display())),
    )
    .unwrap()
    .to_luma8()
}

struct Scores {
    miou_ok: f64,
    f1: f64,
    occluded_iou: f64,
}

/// mIoU over the views marked ok, F1 of obstruction detection (truth: visible < 0.5), and mean
/// IoU over the truly occluded views where the object is at least partly visible.
fn score(
    scene_dir: &std::path::Path,
    scene: &Scene,
    seg: &ObjectSegmentation,
    visible: &std::collections::BTreeMap<String, f64>,
) -> (Scores, Counts) {
    let (mut ok_sum, mut ok_n, mut tp, mut fp, mut fneg) = (0.0, 0, 0, 0, 0);
    let (mut occ_sum, mut occ_n) = (0.0, 0);
    for (v, res) in seg.views.iter().enumerate() {
        let name = &scene.images[v].name;
        let truth = truth_mask(scene_dir, &seg.name, name);
        let i = res.mask.as_ref().map(|m| iou(m, &truth)).unwrap_or(0.0);
        let vis = visible[name];
        let flagged = res.status != ViewStatus::Ok;
        let obstructed = vis < 0.5;
        match (flagged, obstructed) {
            (true, true) => tp += 1,
            (true, false) => fp += 1,
            (false, true) => fneg += 1,
            _ => {}
        }
        if !flagged {
            ok_sum += i;
            ok_n += 1;
        }
        if obstructed && vis > 0.05 {
            occ_sum += i;
            occ_n += 1;
        }
        eprintln!(
            "  {} {name} {:?} iou {i:.3} expected_iou {:.3} visible {vis:.2} prompts {} coverage {:.3}",
            seg.name,
            res.status,
            res.expected_iou.unwrap_or(-1.0),
            res.num_prompts,
            res.expected_coverage.unwrap_or(-1.0)
        );
    }
    let counts = Counts { tp, fp, fneg };
    let f1 = if tp == 0 && fp == 0 && fneg == 0 {
        1.0
    } else {
        f1(&counts)
    };
    (
        Scores {
            miou_ok: ok_sum / ok_n.max(1) as f64,
            f1,
            occluded_iou: if occ_n == 0 {
                f64::NAN
            } else {
                occ_sum / occ_n as f64
            },
        },
        counts,
    )
}

struct Counts {
    tp: usize,
    fp: usize,
    fneg: usize,
}

fn f1(c: &Counts) -> f64 {
    2.0 * c.tp as f64 / (2.0 * c.tp as f64 + c.fp as f64 + c.fneg as f64).max(1.0)
}

/// Every object of the demo scene from its suggested click in view 0, in one pass, scored
/// against the truth. Returns per object (name, ours, baseline) and the pooled obstruction counts.
fn run_demo(models: &ModelsDir) -> (Vec<(String, Scores, Scores)>, Counts) {
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    write_demo_scene(&DemoOptions::default(), &scene_dir).unwrap();
    let scene = Scene::load(&scene_dir).unwrap();
    let truth = read_truth(&scene_dir).unwrap();
    let prompts: Vec<ObjectPrompt> = truth
        .iter()
        .map(|t| ObjectPrompt {
            name: t.name.clone(),
            view: scene.find_image(&t.view).unwrap(),
            points: vec![PointPrompt {
                xy: t.click,
                positive: true,
            }],
            bbox: None,
        })
        .collect();
    let opts = PropagationOptions::default();
    let seg = models.segmenter(0, Precision::Fp32).unwrap();
    let (report, objects) = segment_scene(
        &scene,
        &prompts,
        &opts,
        &seg,
        &dir.path().join("seg"),
        false,
        &Silent,
    )
    .unwrap();
    assert!(dir.path().join("seg/report.json").is_file());
    for (t, obj) in truth.iter().zip(&objects) {
        assert!(dir
            .path()
            .join(format!("seg/{}_points.ply", t.name))
            .is_file());
        assert!(dir
            .path()
            .join(format!("seg/contact_sheet_{}.png", t.name))
            .is_file());
        let written = std::fs::read_dir(dir.path().join("seg/masks").join(&t.name))
            .unwrap()
            .count();
        assert_eq!(
            written,
            obj.views.iter().filter(|v| v.mask.is_some()).count()
        );
    }
    // Each view is encoded once for all four objects.
    assert!(
        report.encoder_runs <= scene.images.len(),
        "{} encoder runs",
        report.encoder_runs
    );

    let mut views = SamViews::new(&seg);
    let mut pooled = Counts {
        tp: 0,
        fp: 0,
        fneg: 0,
    };
    let mut out = vec![];
    for (t, obj) in truth.iter().zip(&objects) {
        let (ours, c) = score(&scene_dir, &scene, obj, &t.visible);
        pooled.tp += c.tp;
        pooled.fp += c.fp;
        pooled.fneg += c.fneg;
        let prompt = prompts.iter().find(|p| p.name == t.name).unwrap();
        let base = projection_baseline(&scene, prompt, &mut views, &opts).unwrap();
        let (baseline, _) = score(&scene_dir, &scene, &base, &t.visible);
        eprintln!(
            "{}: mIoU(ok) {:.3}, obstruction F1 {:.3}, occluded-view IoU ours {:.3} vs projection baseline {:.3}",
            t.name, ours.miou_ok, ours.f1, ours.occluded_iou, baseline.occluded_iou
        );
        out.push((t.name.clone(), ours, baseline));
    }
    eprintln!(
        "pooled obstruction F1 {:.3} (tp {} fp {} fn {})",
        f1(&pooled),
        pooled.tp,
        pooled.fp,
        pooled.fneg
    );
    (out, pooled)
}

/// Issue 4's thresholds on the demo scene: every object's mIoU >= 0.92 over the views it marks
/// ok, obstructed-view detection (truth: visible fraction < 0.5) F1 >= 0.9 pooled over the
/// objects' views, and the correspondences beat the projection baseline in the occluded views.
#[test]
fn demo_scene_every_object_from_one_click() {
    let Some(models) = models() else { return };
    let (objects, pooled) = run_demo(&models);
    let mut failures = vec![];
    for (name, ours, baseline) in &objects {
        if ours.miou_ok < 0.92 {
            failures.push(format!("{name}: mIoU {:.3} < 0.92", ours.miou_ok));
        }
        if ours.occluded_iou.is_finite() && ours.occluded_iou <= baseline.occluded_iou {
            failures.push(format!(
                "{name}: occluded-view IoU {:.3} does not beat the baseline's {:.3}",
                ours.occluded_iou, baseline.occluded_iou
            ));
        }
    }
    if f1(&pooled) < 0.9 {
        failures.push(format!("pooled obstruction F1 {:.3} < 0.9", f1(&pooled)));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn bad_requests_are_clear_errors() {
    let Some(lego) = common::shared_data("lego") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("seg");
    let json = lego.join("transforms_train.json");
    // `objnerf segment` on lego (no tracks) with a view and a click: it must fail; its stderr.
    let fails = |view: &str, point: &str| -> String {
        let o = std::process::Command::new(common::objnerf_bin())
            .args([
                "segment",
                json.to_str().unwrap(),
                "--view",
                view,
                "--point",
                point,
                "--out",
                out.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        assert!(!o.status.success());
        String::from_utf8_lossy(&o.stderr).to_string()
    };
    // A scene without tracks says to run sfm.
    let err = fails("r_0", "400,400");
    assert!(err.contains("objnerf sfm"), "{err}");
    let err = fails("r_0", "900,10");
    assert!(err.contains("outside view"), "{err}");
    let err = fails("nope", "1,1");
    assert!(err.contains("no view 'nope'"), "{err}");
    // Nothing is written.
    assert!(!out.exists());
}

/// One click for `name` at (x, y) in `view`.
fn click(scene: &Scene, name: &str, view: &str, x: f64, y: f64) -> ObjectPrompt {
    ObjectPrompt {
        name: name.into(),
        view: scene.find_image(view).unwrap(),
        points: vec![PointPrompt {
            xy: [x, y],
            positive: true,
        }],
        bbox: None,
    }
}

/// Issue 4: lego from one click on r_0 with tracks from `objnerf sfm` (the model the sfm test
/// builds, shared): mIoU >= 0.95 over the 100 views against alpha, every view marked ok.
#[test]
fn lego_from_one_click_matches_alpha() {
    let Some(models) = models() else { return };
    let Some(model) = common::lego_sfm_model() else {
        return;
    };
    let scene = Scene::load(&model).unwrap();
    let truth = alpha_truth(&scene).unwrap();
    let prompt = click(&scene, "lego", "r_0", 397.5, 492.5);
    let dir = tempfile::tempdir().unwrap();
    let opts = PropagationOptions::default();
    let seg = models.segmenter(0, Precision::Fp32).unwrap();
    let (_, objects) = segment_scene(
        &scene,
        &[prompt],
        &opts,
        &seg,
        &dir.path().join("seg"),
        false,
        &Silent,
    )
    .unwrap();
    let ious = view_ious(&objects[0], &truth);
    let worst = ious.iter().copied().fold(1.0, f64::min);
    let not_ok: Vec<&str> = objects[0]
        .views
        .iter()
        .filter(|v| v.status != ViewStatus::Ok)
        .map(|v| v.view.as_str())
        .collect();
    eprintln!(
        "lego: mIoU {:.4} over {} views (worst {worst:.3}); not ok: {not_ok:?}",
        mean(&ious),
        ious.len()
    );
    assert_eq!(ious.len(), 100);
    assert!(mean(&ious) >= 0.95, "mIoU {:.4} < 0.95", mean(&ious));
    assert!(
        not_ok.is_empty(),
        "lego is visible in every view: {not_ok:?}"
    );

    // A click on the white background: SAM masks the background; a clear error, nothing written.
    let out = dir.path().join("bg");
    let bg = click(&scene, "lego", "r_0", 40.0, 40.0);
    let err = segment_scene(&scene, &[bg], &opts, &seg, &out, false, &Silent)
        .err()
        .expect("a background click fails")
        .to_string();
    assert!(err.contains("selected the background"), "{err}");
    assert!(!out.exists());

    // A clicked view without tracks (its features dropped): says so before running SAM.
    let mut bare = scene.clone();
    let r0 = bare.find_image("r_0").unwrap();
    bare.images[r0].features.clear();
    let err = segment_scene(
        &bare,
        &[click(&bare, "lego", "r_0", 397.5, 492.5)],
        &opts,
        &seg,
        &out,
        false,
        &Silent,
    )
    .err()
    .expect("a view without tracks fails")
    .to_string();
    assert!(
        err.contains("r_0") && err.contains("no 2D-3D tracks"),
        "{err}"
    );
    assert!(!out.exists());
}

/// k objects in one pass share each view's embedding: with a memory-only cache, the encoder
/// runs at most once per view for three objects (the timing this buys is in the benchmark).
#[test]
fn several_objects_share_one_encoder_pass_per_view() {
    let Some(models) = models() else { return };
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    let demo = DemoOptions {
        views: 8,
        ..Default::default()
    };
    write_demo_scene(&demo, &scene_dir).unwrap();
    let scene = Scene::load(&scene_dir).unwrap();
    let truth = read_truth(&scene_dir).unwrap();
    let prompts: Vec<ObjectPrompt> = truth
        .iter()
        .take(3)
        .map(|t| click(&scene, &t.name, &t.view, t.click[0], t.click[1]))
        .collect();
    let (lib, (enc, dec)) = (
        models.require_library().unwrap(),
        models.require_sam().unwrap(),
    );
    let seg = Segmenter::from_files(&lib, &enc, &dec, &Default::default()).unwrap();
    let mut views = SamViews::new(&seg);
    let objects =
        propagate_objects(&scene, &prompts, &mut views, &PropagationOptions::default()).unwrap();
    let requested: usize = objects
        .iter()
        .map(|o| o.views.iter().filter(|v| v.mask.is_some()).count())
        .sum();
    eprintln!(
        "{} masks over {} views, {} encoder runs",
        requested,
        scene.images.len(),
        seg.encoder_runs()
    );
    assert!(requested > scene.images.len(), "{requested} masks");
    assert!(
        seg.encoder_runs() <= scene.images.len(),
        "{} encoder runs for {} views",
        seg.encoder_runs(),
        scene.images.len()
    );
}
