//! Real captures that objnerf must take as they come (issue 18, part 4): sizes no factor divides,
//! upper-case extensions, image names with folders, grayscale, 16-bit and RGBA photos, and masks
//! stored as 0/1.

mod common;

use serde_json::json;
use std::path::Path;
use std::process::Command;

const W: u32 = 33;
const H: u32 = 25;

/// Three views around the origin, each photo stored differently; `masks/` beside them.
fn capture(dir: &Path) -> std::path::PathBuf {
    std::fs::create_dir_all(dir.join("images/sub")).unwrap();
    std::fs::create_dir_all(dir.join("masks/sub")).unwrap();
    let px = |x: u32, y: u32, i: u32| ((x * 7 + y * 5 + i * 40) % 256) as u8;
    let rgb = image::RgbImage::from_fn(W, H, |x, y| image::Rgb([px(x, y, 0), 90, 200]));
    rgb.save(dir.join("images/sub/A.JPG")).unwrap();
    let grey16 = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(W, H, |x, y| {
        image::Luma([px(x, y, 1) as u16 * 257])
    });
    grey16.save(dir.join("images/b.png")).unwrap();
    let rgba = image::RgbaImage::from_fn(W, H, |x, y| image::Rgba([px(x, y, 2), 9, 9, 255]));
    rgba.save(dir.join("images/C.PNG")).unwrap();
    // Masks as 0/1 (numpy's bool.astype(uint8)): the middle of the image is the object.
    let mask = image::GrayImage::from_fn(W, H, |x, y| {
        image::Luma([u8::from((8..25).contains(&x) && (6..19).contains(&y))])
    });
    let names = ["images/sub/A.JPG", "images/b.png", "images/C.PNG"];
    let masks = ["masks/sub/A.png", "masks/b.png", "masks/C.png"];
    for m in masks {
        mask.save(dir.join(m)).unwrap();
    }
    // Cameras on a ring at distance 3, looking at the origin (OpenGL camera-to-world).
    let frames: Vec<_> = (0..3)
        .map(|i| {
            let a = i as f64 * 0.4;
            let (s, c) = a.sin_cos();
            json!({
                "file_path": names[i],
                "mask_path": masks[i],
                "transform_matrix": [
                    [c, 0.0, s, 3.0 * s],
                    [0.0, 1.0, 0.0, 0.0],
                    [-s, 0.0, c, 3.0 * c],
                    [0.0, 0.0, 0.0, 1.0]
                ]
            })
        })
        .collect();
    let tf = json!({
        "camera_model": "PINHOLE",
        "fl_x": 30.0, "fl_y": 30.0, "cx": W as f64 / 2.0, "cy": H as f64 / 2.0,
        "w": W, "h": H,
        "frames": frames
    });
    let path = dir.join("transforms.json");
    std::fs::write(&path, serde_json::to_string_pretty(&tf).unwrap()).unwrap();
    path
}

fn objnerf(args: &[&str]) -> (bool, String) {
    let out = Command::new(common::objnerf_bin())
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    (out.status.success(), err)
}

#[test]
fn info_reads_every_kind_of_photo() {
    let tmp = tempfile::tempdir().unwrap();
    let tf = capture(tmp.path());
    let (ok, err) = objnerf(&["info", tf.to_str().unwrap(), "--json"]);
    assert!(ok, "{err}");
}

#[test]
fn train_at_downscale_2_on_an_odd_size() {
    let tmp = tempfile::tempdir().unwrap();
    let tf = capture(tmp.path());
    let model = tmp.path().join("model.objf");
    let (ok, err) = objnerf(&[
        "train",
        tf.to_str().unwrap(),
        "--masks",
        "scene",
        "--downscale",
        "2",
        "--steps",
        "3",
        "--out",
        model.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(model.is_file());
}

/// `objnerf segment` names a mask after its image, folders kept and the extension `.png`
/// (`images/sub/A.JPG` -> `images/sub/A.png`: `scene::io::mask_file`), and objnerf 0.1 flattened
/// the folders (`images_sub_A.png`); `train --masks DIR` (and so `extract`) finds either.
#[test]
fn train_finds_the_masks_segment_wrote_for_names_with_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let tf = capture(tmp.path());
    let names = ["images/sub/A.JPG", "images/b.png", "images/C.PNG"];
    let sources = ["masks/sub/A.png", "masks/b.png", "masks/C.png"];
    for layout in ["rule", "flattened"] {
        let seg = tmp.path().join(layout).join("masks/object");
        for (n, m) in names.iter().zip(sources) {
            let dest = match layout {
                "rule" => objnerf::scene::io::mask_file(&seg, n),
                _ => seg.join(format!(
                    "{}.png",
                    std::path::Path::new(n)
                        .with_extension("")
                        .to_string_lossy()
                        .replace('/', "_")
                )),
            };
            std::fs::create_dir_all(dest.parent().unwrap()).unwrap();
            std::fs::copy(tmp.path().join(m), dest).unwrap();
        }
        let model = tmp.path().join(format!("{layout}.objf"));
        let (ok, err) = objnerf(&[
            "train",
            tf.to_str().unwrap(),
            "--masks",
            seg.to_str().unwrap(),
            "--steps",
            "3",
            "--out",
            model.to_str().unwrap(),
        ]);
        assert!(ok, "{layout}: {err}");
    }
}
