//! SAM with the real MobileSAM model through ONNX Runtime. Skips (with the reason printed) when
//! `../shared/models/mobile_sam` is absent, or when the ONNX Runtime library is neither in
//! `$OBJNERF_HOME` nor installable with pip here.

mod common;

use image::GrayImage;
use objnerf::models::{install, InstallOptions, ModelsDir};
use objnerf::sam::{Precision, Prompts, Segmenter, SegmenterOptions};
use objnerf::scene::io::read_rgb;
use objnerf::segment::distance;
use objnerf::Error;
use std::sync::{Mutex, OnceLock};

/// The installed models directory, installing into it first if needed (once per test process).
fn models() -> Option<ModelsDir> {
    static SETUP: Mutex<Option<Option<ModelsDir>>> = Mutex::new(None);
    let mut g = SETUP.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(r) = &*g {
        return r.clone();
    }
    let r = (|| {
        let onnx = common::shared_model("mobile_sam")?;
        let dir = ModelsDir::from_env().ok()?;
        let int8 = dir.require_sam_at(Precision::Int8);
        if dir.require_library().is_err() || dir.require_sam().is_err() || int8.is_err() {
            let opts = InstallOptions {
                onnx_dir: Some(onnx),
                from: None,
                skip_checkpoint: true,
            };
            if let Err(e) = install(&dir, &opts) {
                common::skip(&format!("ONNX Runtime / MobileSAM not installed and `objnerf models install` failed here: {e}"));
                return None;
            }
        }
        Some(dir)
    })();
    *g = Some(r.clone());
    r
}

/// One segmenter (memory cache only) shared by the tests that do not count encoder runs.
fn shared() -> Option<&'static Segmenter> {
    static SEG: OnceLock<Option<Segmenter>> = OnceLock::new();
    SEG.get_or_init(|| {
        let dir = models()?;
        let (enc, dec) = dir.require_sam().ok()?;
        Some(
            Segmenter::from_files(
                &dir.require_library().ok()?,
                &enc,
                &dec,
                &SegmenterOptions::default(),
            )
            .expect("the installed models load"),
        )
    })
    .as_ref()
}

/// lego's first training view (RGB on white) and its alpha > 127 as the true mask.
fn lego() -> Option<(image::RgbImage, Vec<bool>)> {
    let path = common::shared_data("lego")?.join("train/r_0.png");
    let rgba = image::open(&path).expect("lego r_0.png").to_rgba8();
    let truth = rgba.pixels().map(|p| p[3] > 127).collect();
    Some((read_rgb(&path).unwrap(), truth))
}

fn to_gray(b: &[bool], w: u32, h: u32) -> GrayImage {
    GrayImage::from_raw(w, h, b.iter().map(|&v| if v { 255 } else { 0 }).collect()).unwrap()
}

#[test]
fn lego_one_click_at_the_most_interior_point() {
    let (Some(seg), Some((img, truth))) = (shared(), lego()) else {
        return;
    };
    let (x, y) = distance::most_interior_point(&to_gray(&truth, img.width(), img.height()))
        .expect("lego has an alpha mask");
    let mask = seg
        .segment(&img, &Prompts::click(x as f32, y as f32))
        .unwrap();
    let iou = mask.iou(&truth);
    println!(
        "lego r_0: click ({x}, {y}) -> IoU {iou:.4} against alpha > 127, score {:.3}",
        mask.score
    );
    assert!(iou >= 0.95, "IoU {iou:.4} < 0.95");
}

#[test]
fn other_prompts_on_the_same_image_do_not_run_the_encoder() {
    let (Some(dir), Some((img, truth))) = (models(), lego()) else {
        return;
    };
    let cache = tempfile::tempdir().unwrap();
    let opts = SegmenterOptions {
        threads: 0,
        disk_cache: Some(cache.path().to_path_buf()),
    };
    let (enc, dec) = dir.require_sam().unwrap();
    let lib = dir.require_library().unwrap();
    let seg = Segmenter::from_files(&lib, &enc, &dec, &opts).unwrap();
    let emb = seg.embed(&img).unwrap();
    assert_eq!(seg.encoder_runs(), 1);
    let first = seg.predict(&emb, &Prompts::click(400.0, 400.0)).unwrap();
    // Other prompts, a box, a refinement with the previous low-res mask: all reuse the embedding.
    let again = seg.embed(&img).unwrap();
    seg.predict(
        &again,
        &Prompts::click(300.0, 500.0).point(20.0, 20.0, false),
    )
    .unwrap();
    seg.predict(
        &again,
        &Prompts::new().with_box([150.0, 90.0, 650.0, 660.0]),
    )
    .unwrap();
    let refined = seg
        .segment(
            &img,
            &Prompts::click(400.0, 400.0)
                .point(250.0, 600.0, true)
                .with_mask_input(first.low_res.clone()),
        )
        .unwrap();
    assert_eq!(seg.encoder_runs(), 1, "the encoder ran again");
    println!(
        "one encoder run for 4 prompt sets; refined IoU {:.3}",
        refined.iou(&truth)
    );
    // A new segmenter (a new run) finds the embedding on disk.
    let seg2 = Segmenter::from_files(&lib, &enc, &dec, &opts).unwrap();
    let emb2 = seg2.embed(&img).unwrap();
    assert_eq!(seg2.encoder_runs(), 0, "the disk cache was not used");
    assert_eq!(emb2.data, emb.data);
    // A different image is a different key.
    let mut other = img.clone();
    other.put_pixel(0, 0, image::Rgb([1, 2, 3]));
    assert_ne!(seg2.embed(&other).unwrap().key, emb.key);
    assert_eq!(seg2.encoder_runs(), 1);
}

#[test]
fn prompts_outside_the_image_are_errors() {
    let (Some(seg), Some((img, _))) = (shared(), lego()) else {
        return;
    };
    let emb = seg.embed(&img).unwrap();
    for (p, what) in [
        (Prompts::click(800.5, 10.0), "outside"),
        (Prompts::click(-1.0, 10.0), "outside"),
        (Prompts::click(10.0, f32::INFINITY), "outside"),
        (
            Prompts::new().with_box([10.0, 10.0, 900.0, 50.0]),
            "outside",
        ),
        (Prompts::new().with_box([50.0, 10.0, 10.0, 50.0]), "empty"),
        (Prompts::new(), "no prompt"),
        (
            Prompts::click(10.0, 10.0).with_mask_input(vec![0.0; 7]),
            "mask input",
        ),
    ] {
        match seg.predict(&emb, &p) {
            Err(Error::Invalid(msg)) => {
                assert!(msg.contains(what), "{msg:?} should mention {what:?}")
            }
            other => panic!(
                "expected an Invalid error for {p:?}, got {:?}",
                other.map(|m| m.score)
            ),
        }
    }
    // The image border itself is inside (continuous coordinates run 0..=800).
    assert!(seg
        .predict_allow_empty(&emb, &Prompts::click(800.0, 800.0))
        .is_ok());
}

#[test]
fn an_empty_result_is_an_error() {
    let (Some(seg), Some((img, _))) = (shared(), lego()) else {
        return;
    };
    let emb = seg.embed(&img).unwrap();
    // Background clicks in the four white corners and a previous mask that says "nothing here"
    // (found by trying: SAM returns something for most prompts, even background-only ones).
    let p = Prompts::new()
        .point(10.0, 10.0, false)
        .point(790.0, 10.0, false)
        .point(10.0, 790.0, false)
        .point(790.0, 790.0, false)
        .with_mask_input(vec![-50.0; 256 * 256]);
    let raw = seg.predict_allow_empty(&emb, &p).unwrap();
    assert!(
        raw.is_empty(),
        "expected an empty mask, got {} px",
        raw.area()
    );
    match seg.predict(&emb, &p) {
        Err(Error::Invalid(msg)) => assert!(msg.contains("empty mask"), "{msg}"),
        other => panic!("expected an error, got {:?}", other.map(|m| m.area())),
    }
}

#[test]
fn a_corrupt_onnx_file_is_an_error() {
    let Some(dir) = models() else {
        return;
    };
    let lib = dir.require_library().unwrap();
    let (enc, dec) = dir.require_sam().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let bad = tmp.path().join("encoder.onnx");
    std::fs::write(&bad, b"this is not an ONNX model").unwrap();
    let truncated = tmp.path().join("decoder.onnx");
    let bytes = std::fs::read(&dec).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 3]).unwrap();
    let opts = SegmenterOptions::default();
    for (e, d, path) in [(&bad, &dec, &bad), (&enc, &truncated, &truncated)] {
        match Segmenter::from_files(&lib, e, d, &opts) {
            Err(Error::Format { path: p, msg }) => {
                assert_eq!(&p, path);
                println!("{}: {msg}", p.display());
            }
            Err(other) => panic!("expected a Format error, got {other}"),
            Ok(_) => panic!("a corrupt model loaded"),
        }
    }
    // A valid ONNX file that is the wrong model (the decoder given as the encoder).
    match Segmenter::from_files(&lib, &dec, &dec, &opts) {
        Err(Error::Format { msg, .. }) => {
            assert!(msg.contains("no input named \"image\""), "{msg}")
        }
        Err(other) => panic!("expected a Format error, got {other}"),
        Ok(_) => panic!("the decoder loaded as an encoder"),
    }
}

#[test]
fn a_missing_library_or_model_is_an_error_naming_the_install_command() {
    let tmp = tempfile::tempdir().unwrap();
    let empty = ModelsDir::at(tmp.path());
    for e in [
        empty
            .segmenter(1, Precision::Fp32)
            .err()
            .expect("no library"),
        empty.require_sam().expect_err("no models"),
        Segmenter::from_files(
            &tmp.path().join("libonnxruntime.so.1.31.1"),
            &tmp.path().join("e.onnx"),
            &tmp.path().join("d.onnx"),
            &SegmenterOptions::default(),
        )
        .err()
        .expect("no library"),
    ] {
        let msg = e.to_string();
        assert!(msg.contains("objnerf models install"), "{msg}");
    }
    // A library that is not a shared object at all: an error, not ort's panic. Only meaningful
    // before a real library was loaded in this process, so it runs in a child process.
    let bad = tmp.path().join("lib/libonnxruntime.so.1.31.1");
    std::fs::create_dir_all(bad.parent().unwrap()).unwrap();
    std::fs::write(&bad, b"not a library").unwrap();
    let out = std::process::Command::new(common::objnerf_bin())
        .args(["segment-view", "../shared/data/lego/train/r_0.png"])
        .args(["--point", "400,400", "--out"])
        .arg(tmp.path().join("m.png"))
        .current_dir(common::repo_root())
        .env("OBJNERF_HOME", tmp.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("objnerf models install"), "{err}");
}

#[test]
fn segment_view_writes_mask_overlay_and_json() {
    let (Some(_), Some(lego_dir)) = (models(), common::shared_data("lego")) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("mask.png");
    let run = |extra: &[&str]| {
        std::process::Command::new(common::objnerf_bin())
            .arg("segment-view")
            .arg(lego_dir.join("train/r_0.png"))
            .args(extra)
            .arg("--out")
            .arg(&out)
            .arg("--json")
            .output()
            .unwrap()
    };
    let o = run(&[
        "--point",
        "400,400",
        "--point",
        "30,30,bg",
        "--box",
        "150,90,650,660",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(report["score"].as_f64().unwrap() > 0.5, "{report}");
    assert!(report["embed"]["encoder_seconds"].is_number());
    let mask = image::open(&out).unwrap().to_luma8();
    assert_eq!(mask.dimensions(), (800, 800));
    let overlay = image::open(tmp.path().join("mask_overlay.png")).unwrap();
    assert_eq!((overlay.width(), overlay.height()), (800, 800));
    // A point outside the image: a clear error before any model work, no panic, no output.
    std::fs::remove_file(&out).unwrap();
    let o = run(&["--point", "1200,5"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("outside the 800x800 image") && !err.contains("panicked"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn a_non_square_image_maps_prompts_and_masks_back() {
    let (Some(seg), Some((img, truth))) = (shared(), lego()) else {
        return;
    };
    // Rows 120..680 of lego: 800 x 560, so the resized image is 1024 x 717 plus padding below.
    let (y0, h) = (120u32, 560u32);
    let crop = image::imageops::crop_imm(&img, 0, y0, 800, h).to_image();
    let t: Vec<bool> = truth[(y0 * 800) as usize..((y0 + h) * 800) as usize].to_vec();
    let (x, y) = distance::most_interior_point(&to_gray(&t, 800, h)).unwrap();
    let mask = seg
        .segment(&crop, &Prompts::click(x as f32, y as f32))
        .unwrap();
    assert_eq!((mask.width, mask.height), (800, h));
    let iou = mask.iou(&t);
    println!("lego r_0 rows {y0}..{}: IoU {iou:.4}", y0 + h);
    assert!(iou >= 0.95, "IoU {iou:.4}");
}

#[test]
fn models_install_again_changes_nothing_and_is_fast() {
    let (Some(dir), Some(onnx)) = (models(), common::shared_model("mobile_sam")) else {
        return;
    };
    let t0 = std::time::Instant::now();
    let opts = InstallOptions {
        onnx_dir: Some(onnx),
        from: None,
        skip_checkpoint: true,
    };
    let steps = install(&dir, &opts).unwrap();
    let secs = t0.elapsed().as_secs_f64();
    for s in &steps {
        assert!(
            s.action == "already installed" || s.action == "skipped",
            "{}: {}",
            s.name,
            s.action
        );
    }
    println!("second install: {secs:.2} s");
    assert!(secs < 10.0, "{secs} s");
    let list = dir.list();
    assert!(list[..3].iter().all(|e| e.status == "ok"), "{list:?}");
}

#[test]
fn a_small_object_is_sharper_zoomed() {
    let (Some(seg), Some((img, truth))) = (shared(), lego()) else {
        return;
    };
    // lego shrunk to 160 x 160 on an 800 x 600 white canvas: a small object.
    let small = image::imageops::resize(&img, 160, 160, image::imageops::FilterType::Triangle);
    let t = to_gray(&truth, 800, 800);
    let ts = image::imageops::resize(&t, 160, 160, image::imageops::FilterType::Triangle);
    let mut canvas = image::RgbImage::from_pixel(800, 600, image::Rgb([255, 255, 255]));
    image::imageops::replace(&mut canvas, &small, 300, 200);
    let mut tc = GrayImage::new(800, 600);
    image::imageops::replace(&mut tc, &ts, 300, 200);
    let truth: Vec<bool> = tc.pixels().map(|p| p[0] > 127).collect();
    let (x, y) = distance::most_interior_point(&tc).unwrap();
    let p = Prompts::click(x as f32, y as f32);
    let plain = seg.segment(&canvas, &p).unwrap();
    let zoomed = seg
        .segment_zoomed(&canvas, &p, &Default::default())
        .unwrap();
    let (a, b) = (plain.iou(&truth), zoomed.iou(&truth));
    println!("small lego: IoU {a:.4} plain, {b:.4} zoomed");
    assert!(b >= 0.9 && b >= a - 0.01, "plain {a:.4}, zoomed {b:.4}");
}

#[test]
fn demo_scene_each_object_one_click_in_view_0() {
    let Some(seg) = shared() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo");
    // Only view 0 is segmented, so a short ring is enough; the rest are the defaults.
    let opts = objnerf::demo::DemoOptions {
        views: 4,
        ..Default::default()
    };
    objnerf::demo::write_demo_scene(&opts, &out).unwrap();
    let objects = objnerf::demo::read_truth(&out).unwrap();
    assert!(!objects.is_empty());
    let mut worst = 1.0f64;
    for o in &objects {
        let img = read_rgb(&out.join("images").join(&o.view)).unwrap();
        let truth = image::open(out.join("truth/masks").join(&o.name).join(&o.view))
            .unwrap()
            .to_luma8();
        let t: Vec<bool> = truth.pixels().map(|p| p[0] > 127).collect();
        let p = Prompts::click(o.click[0] as f32, o.click[1] as f32);
        let plain = seg.segment(&img, &p).unwrap().iou(&t);
        let mask = seg.segment_zoomed(&img, &p, &Default::default()).unwrap();
        let iou = mask.iou(&t);
        println!(
            "demo {} in {}: click ({:.1}, {:.1}) -> IoU {iou:.4} zoomed ({plain:.4} one pass), score {:.3}",
            o.name, o.view, o.click[0], o.click[1], mask.score
        );
        worst = worst.min(iou);
    }
    assert!(worst >= 0.90, "worst IoU {worst:.4} < 0.90");

    // The same through the propagation's interface (the scene read back by `Scene::load`).
    use objnerf::segment::types::{PointPrompt, ViewSegmenter};
    let scene = objnerf::Scene::load(&out).unwrap();
    let mut views = objnerf::segment::SamViews::new(seg).with_zoom(Some(Default::default()));
    for o in &objects {
        let v = scene.find_image(&o.view).unwrap();
        let p = [PointPrompt {
            xy: o.click,
            positive: true,
        }];
        let m = views.segment(&scene, v, &p, None).unwrap();
        let truth = image::open(out.join("truth/masks").join(&o.name).join(&o.view))
            .unwrap()
            .to_luma8();
        let t: Vec<bool> = truth.pixels().map(|p| p[0] > 127).collect();
        let got: Vec<bool> = m.mask.pixels().map(|p| p[0] > 127).collect();
        assert!(
            objnerf::util::mask::iou_bits(got, t) >= 0.90,
            "{} through SamViews",
            o.name
        );
    }
}
