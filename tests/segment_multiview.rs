//! Multi-view segmentation (Algorithm 1) with the real SAM on the demo scene, against its truth:
//! masks, obstructed views, and the projection baseline.
mod common;

use objnerf::demo::{read_truth, write_demo_scene, DemoOptions};
use objnerf::segment::hull::iou;
use objnerf::segment::propagate::{
    projection_baseline, ObjectPrompt, ObjectSegmentation, PointPrompt, PropagationOptions,
    ViewStatus,
};
use objnerf::segment::run::segment_scene;
use objnerf::segment::scene_views::SamViews;
use objnerf::segment::{ModelsDir, Segmenter};
use objnerf::Scene;

fn models() -> Option<ModelsDir> {
    let dir = ModelsDir::from_env().ok()?;
    if dir.require_sam().is_err() || dir.require_library().is_err() {
        eprintln!(
            "SKIP: SAM models are not installed (scripts/setup runs `objnerf models install`)"
        );
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
    let (report, objects) =
        segment_scene(&scene, &prompts, &opts, &dir.path().join("seg"), false).unwrap();
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

    let seg = Segmenter::open(models, 0).unwrap();
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
