//! `objnerf sfm` with the real COLMAP: the demo scene reconstructed from its images alone, and
//! lego triangulated with its known poses; both models load through the reader.
mod common;

use objnerf::demo::{write_demo_scene, DemoOptions};
use objnerf::Scene;
use std::process::Command;

fn have_colmap() -> bool {
    let ok = objnerf::scene::sfm::colmap_program().is_ok();
    if !ok {
        // CI installs it (scripts/setup); a developer without it sees why this is skipped.
        common::skip("colmap is not installed (scripts/setup installs it)");
    }
    ok
}

#[test]
fn demo_scene_registers_every_view_from_images_alone() {
    if !have_colmap() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    write_demo_scene(&DemoOptions::default(), &scene_dir).unwrap();
    let out = dir.path().join("sfm");
    let status = Command::new(common::objnerf_bin())
        .args([
            "sfm",
            scene_dir.join("images").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
    assert_eq!(report["num_registered"], 36, "{report}");
    let model = Scene::load(&out).unwrap();
    assert_eq!(model.images.len(), 36);
    assert!(model.points.len() > 1000, "{} points", model.points.len());
    assert!(model.has_tracks());
    let errs = model.reprojection_errors();
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    assert!(mean < 1.0, "mean reprojection error {mean} px");
    // Image paths resolve to the demo's images through out/images.
    assert!(model.images.iter().all(|im| im.path.is_file()));
}

#[test]
fn lego_is_triangulated_with_its_known_poses() {
    // Built once and shared with the segmentation tests.
    let Some(out) = common::lego_sfm_model() else {
        return;
    };
    let json = common::shared_data("lego")
        .unwrap()
        .join("transforms_train.json");
    let original = Scene::load(&json).unwrap();
    let model = Scene::load(&out).unwrap();
    assert_eq!(model.images.len(), 100);
    assert!(model.points.len() > 1000, "{} points", model.points.len());
    // Poses and intrinsics are lego's own, at full resolution (lego's matrices are f32-rounded,
    // so its rotations are orthonormal only to ~1e-7: the COLMAP quaternion form agrees to that).
    for im in &model.images {
        let k = original.find_image(&im.name).unwrap();
        let d = (im.pose.center() - original.images[k].pose.center()).length();
        assert!(d < 1e-5, "{} moved by {d}", im.name);
        let cam = model.camera_of(im);
        assert_eq!((cam.width, cam.height), (800, 800));
        assert!((cam.focal().0 - 1111.111).abs() < 0.01);
    }
    // Points lie on the model: inside lego's box, and they reproject onto their features.
    let errs = model.reprojection_errors();
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    assert!(mean < 1.5, "mean reprojection error {mean} px");
    let inside = model
        .points
        .iter()
        .filter(|p| p.xyz.abs().max_element() < 1.5)
        .count();
    assert!(
        inside as f64 > 0.95 * model.points.len() as f64,
        "{inside} of {} points inside the box",
        model.points.len()
    );
}

#[test]
fn missing_colmap_says_how_to_install_it() {
    let dir = tempfile::tempdir().unwrap();
    let imgs = dir.path().join("imgs");
    std::fs::create_dir_all(&imgs).unwrap();
    for i in 0..2 {
        image::RgbImage::new(8, 8)
            .save(imgs.join(format!("{i}.png")))
            .unwrap();
    }
    let out = Command::new(common::objnerf_bin())
        .args([
            "sfm",
            imgs.to_str().unwrap(),
            "--out",
            dir.path().join("o").to_str().unwrap(),
        ])
        .env("PATH", dir.path())
        .env_remove("OBJNERF_COLMAP")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("apt-get install") && err.contains("colmap"),
        "{err}"
    );
    assert!(!dir.path().join("o").exists(), "nothing half-written");
}
