//! Broken inputs make `objnerf info` fail with a message that names the broken file.

mod common;
mod support;

use objnerf::scene::formats::{colmap, nerfstudio};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Run `objnerf info` on `path`; it must fail, and its stderr must name `file` and contain every
/// word of `expect`. Returns stderr.
fn assert_info_fails(path: &Path, file: &str, expect: &[&str]) -> String {
    let out = Command::new(common::objnerf_bin())
        .arg("info")
        .arg(path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(
        !out.status.success(),
        "info succeeded on {}",
        path.display()
    );
    assert!(
        stderr.contains(file),
        "stderr does not name {file}: {stderr}"
    );
    for e in expect {
        assert!(stderr.contains(e), "stderr lacks '{e}': {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    eprintln!("{stderr}");
    stderr
}

/// A tiny COLMAP model in `tmp/model` (images in `tmp/images`).
fn colmap_model(tmp: &Path, format: colmap::ModelFormat) -> PathBuf {
    let scene = support::tiny_scene(tmp);
    let dir = tmp.join("model");
    colmap::write_model(&scene, &dir, format).unwrap();
    // The model is good before we break it.
    let ok = Command::new(common::objnerf_bin())
        .arg("info")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    dir
}

fn edit(path: &Path, f: impl FnOnce(&mut Vec<u8>)) {
    let mut bytes = std::fs::read(path).unwrap();
    f(&mut bytes);
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn colmap_cameras_bin_truncated() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Binary);
    edit(&dir.join("cameras.bin"), |b| b.truncate(b.len() - 5));
    assert_info_fails(&dir, "cameras.bin", &["truncated"]);
}

#[test]
fn colmap_images_bin_truncated() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Binary);
    edit(&dir.join("images.bin"), |b| b.truncate(b.len() - 30));
    assert_info_fails(&dir, "images.bin", &["truncated"]);
}

#[test]
fn colmap_unknown_camera_model_id() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Binary);
    // u64 count, i32 camera id, then the i32 model id.
    edit(&dir.join("cameras.bin"), |b| {
        b[12..16].copy_from_slice(&99i32.to_le_bytes())
    });
    assert_info_fails(&dir, "cameras.bin", &["unknown camera model id 99"]);
}

#[test]
fn colmap_points3d_bin_garbage() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Binary);
    edit(&dir.join("points3D.bin"), |b| {
        for (i, v) in b.iter_mut().enumerate() {
            *v = (i as u8).wrapping_mul(151).wrapping_add(17);
        }
    });
    assert_info_fails(&dir, "points3D.bin", &[]);
}

#[test]
fn colmap_cameras_txt_bad_number() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Text);
    let p = dir.join("cameras.txt");
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace(" 9.5 ", " 9.x5 ");
    std::fs::write(&p, text).unwrap();
    assert_info_fails(&dir, "cameras.txt", &["9.x5", "not a valid number"]);
}

/// A good transforms.json for the tiny scene, as a JSON value to break.
fn transforms(tmp: &Path) -> (PathBuf, Value) {
    let mut scene = support::tiny_scene(tmp);
    scene.cameras.truncate(1);
    for im in &mut scene.images {
        im.camera = 0;
        im.features.clear();
    }
    scene.points.clear();
    let path = tmp.join("transforms.json");
    nerfstudio::write(&scene, &path).unwrap();
    let v = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    (path, v)
}

fn save(path: &Path, v: &Value) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

#[test]
fn transforms_invalid_json() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, _) = transforms(tmp.path());
    std::fs::write(&path, "{ \"frames\": [ {\"file_path\": \"images/a.png\", ").unwrap();
    assert_info_fails(&path, "transforms.json", &["invalid JSON"]);
}

#[test]
fn transforms_nan_matrix() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, v) = transforms(tmp.path());
    // Python's json module writes NaN, which is not JSON.
    let text = serde_json::to_string_pretty(&v).unwrap();
    let m = v["frames"][1]["transform_matrix"][0][0].to_string();
    std::fs::write(&path, text.replacen(&m, "NaN", 1)).unwrap();
    assert_info_fails(&path, "transforms.json", &["invalid JSON", "NaN"]);
}

#[test]
fn transforms_scaled_matrix() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, mut v) = transforms(tmp.path());
    for r in 0..3 {
        for c in 0..3 {
            let x = v["frames"][1]["transform_matrix"][r][c].as_f64().unwrap();
            v["frames"][1]["transform_matrix"][r][c] = (2.0 * x).into();
        }
    }
    save(&path, &v);
    assert_info_fails(
        &path,
        "transforms.json",
        &["frame 1 ('images/b.png')", "not rigid"],
    );
}

#[test]
fn transforms_missing_image() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, mut v) = transforms(tmp.path());
    v["frames"][2]["file_path"] = "images/gone.png".into();
    save(&path, &v);
    assert_info_fails(
        &path,
        "transforms.json",
        &["frame 2", "images/gone.png", "missing"],
    );
}

#[test]
fn transforms_mask_for_some_frames_only() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, mut v) = transforms(tmp.path());
    v["frames"][0]["mask_path"] = "images/a.png".into();
    save(&path, &v);
    assert_info_fails(&path, "transforms.json", &["mask_path", "1 of 3 frames"]);
}

#[test]
fn transforms_size_disagrees_with_image() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, mut v) = transforms(tmp.path());
    v["w"] = 16.into();
    save(&path, &v);
    assert_info_fails(&path, "transforms.json", &["16x8", "8x8"]);
}

#[test]
fn llff_wrong_shape() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    support::tiny_scene(dir);
    let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 15), }";
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((header.len() as u16).to_le_bytes());
    bytes.extend(header.as_bytes());
    bytes.extend(vec![0u8; 3 * 15 * 8]);
    std::fs::write(dir.join("poses_bounds.npy"), bytes).unwrap();
    assert_info_fails(dir, "poses_bounds.npy", &["(N, 17)", "(3, 15)"]);
}
