//! `objnerf export nerfstudio` on a small run (a COLMAP scene, a segmentation with an ok, an
//! obstructed and an ok view) and on a scene with depth; nerfstudio itself checks the real
//! captures in tests/nerfstudio_check.rs (scripts/check-nerfstudio).

mod common;
mod support;

use glam::DVec3;
use objnerf::export::nerfstudio::{export, ExportOptions, LeftOut};
use objnerf::scene::formats::{colmap, nerfstudio, ply};
use objnerf::scene::io::{read_depth, write_depth_png_mm, DepthMap};
use objnerf::scene::Scene;
use std::path::{Path, PathBuf};

/// `dir/scene` (COLMAP binary model + images) and `dir/run/segment` as `objnerf segment` writes
/// it: object "cube" (left half of each 8x8 view; b.png obstructed) and its first two points.
fn fixture(dir: &Path) -> (Scene, PathBuf) {
    let scene_dir = dir.join("scene");
    let scene = support::tiny_scene(&scene_dir);
    let model = scene_dir.join("sparse/0");
    std::fs::create_dir_all(&model).unwrap();
    colmap::write_model(&scene, &model, colmap::ModelFormat::Binary).unwrap();
    let scene = Scene::load(&scene_dir).unwrap();
    let seg = dir.join("run/segment");
    std::fs::create_dir_all(seg.join("masks/cube")).unwrap();
    for n in support::NAMES {
        let stem = Path::new(n).file_stem().unwrap().to_str().unwrap();
        image::GrayImage::from_fn(8, 8, |x, _| image::Luma([if x < 4 { 255 } else { 0 }]))
            .save(seg.join(format!("masks/cube/{stem}.png")))
            .unwrap();
    }
    let pts: Vec<_> = scene.points[..2].iter().map(|p| (p.xyz, p.rgb)).collect();
    ply::write_points(&seg.join("cube_points.ply"), &pts).unwrap();
    let views: Vec<_> = support::NAMES
        .iter()
        .zip(["ok", "obstructed", "ok"])
        .map(|(v, s)| serde_json::json!({"view": v, "status": s, "score": 0.9}))
        .collect();
    let report = serde_json::json!({
        "scene": model, "objects": [{"name": "cube", "num_points": 2, "views": views}],
    });
    std::fs::write(seg.join("report.json"), report.to_string()).unwrap();
    (scene, dir.join("run"))
}

fn opts() -> ExportOptions {
    ExportOptions {
        downscale: 1,
        ..Default::default()
    }
}

/// Poses and cameras of the export (read back) are the source's to 1e-9.
fn assert_views_match(exported: &Scene, source: &Scene, names: &[&str]) {
    assert_eq!(exported.images.len(), names.len());
    for (im, name) in exported.images.iter().zip(names) {
        let src = &source.images[source.find_image(name).unwrap()];
        assert_eq!(im.name, format!("images/{name}"));
        let (a, b) = (im.pose.c2w_opencv(), src.pose.c2w_opencv());
        for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
            assert!((x - y).abs() < 1e-9, "{name}: {x} vs {y}");
        }
        assert_eq!(exported.camera_of(im), source.camera_of(src), "{name}");
    }
}

/// A mask as nerfstudio reads it: one channel, non-zero = use.
fn kept_columns(path: &Path) -> Vec<u32> {
    let img = image::open(path).unwrap();
    assert_eq!(img.color(), image::ColorType::L8, "{}", path.display());
    let m = img.to_luma8();
    assert!(m.pixels().all(|p| p.0[0] == 0 || p.0[0] == 255));
    (0..m.width())
        .filter(|&x| m.get_pixel(x, 0).0[0] > 0)
        .collect()
}

#[test]
fn object_export_keeps_ok_views_with_their_masks() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene, run) = fixture(tmp.path());
    let out = tmp.path().join("ns");
    let report = export(&run, &out, &opts()).unwrap();
    assert_eq!(report.frames, 2);
    assert_eq!(
        report.left_out,
        vec![LeftOut {
            view: "b.png".into(),
            status: "obstructed".into()
        }]
    );
    assert!(report
        .summary()
        .contains("left out 1 obstructed view(s): b.png"));
    assert_eq!(report.images_linked + report.images_copied, 2);
    let ns = nerfstudio::read(&out.join("transforms.json")).unwrap();
    assert_views_match(&ns, &scene, &["a.png", "c.png"]);
    for im in &ns.images {
        assert_eq!(
            kept_columns(im.mask_path.as_ref().unwrap()),
            vec![0, 1, 2, 3]
        );
        assert_eq!(std::fs::read(&im.path).unwrap(), {
            let name = im.path.file_name().unwrap();
            std::fs::read(tmp.path().join("scene/images").join(name)).unwrap()
        });
    }
    // splatfacto's points: the object's.
    assert_eq!(ns.points.len(), 2);
    assert!((ns.points[0].xyz - scene.points[0].xyz).length() < 1e-6);
}

#[test]
fn background_export_reverses_the_masks_of_every_view() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene, run) = fixture(tmp.path());
    let out = tmp.path().join("bg");
    let o = ExportOptions {
        background: true,
        ..opts()
    };
    let report = export(&run, &out, &o).unwrap();
    assert!(report.left_out.is_empty());
    let ns = nerfstudio::read(&out.join("transforms.json")).unwrap();
    assert_views_match(&ns, &scene, &support::NAMES);
    for im in &ns.images {
        assert_eq!(
            kept_columns(im.mask_path.as_ref().unwrap()),
            vec![4, 5, 6, 7]
        );
    }
    // The sparse points without the object's.
    let key = |p: DVec3| p.as_vec3().to_array();
    let got: Vec<_> = ns.points.iter().map(|p| key(p.xyz)).collect();
    let want: Vec<_> = scene.points[2..].iter().map(|p| key(p.xyz)).collect();
    assert_eq!(got, want);
}

#[test]
fn scene_export_with_depth_downscaled() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    let mut scene = support::tiny_scene(&dir);
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    for (i, im) in scene.images.iter_mut().enumerate() {
        let depth = dir.join("depth").join(&im.name);
        let metres = (0..64)
            .map(|k| 1.0 + (k % 8) as f32 * 0.25 + i as f32)
            .collect();
        let map = DepthMap {
            width: 8,
            height: 8,
            metres,
        };
        write_depth_png_mm(&depth, &map).unwrap();
        im.depth_path = Some(depth);
        im.features.clear();
    }
    scene.points.iter_mut().for_each(|p| p.track.clear());
    let json = dir.join("transforms.json");
    nerfstudio::write(&scene, &json).unwrap();
    let out = tmp.path().join("ns");
    let o = ExportOptions {
        downscale: 2,
        ..opts()
    };
    let report = export(&json, &out, &o).unwrap();
    assert_eq!((report.frames, report.images_resized), (3, 3));
    assert!(report.depth && report.masks.is_none());
    let ns = nerfstudio::read(&out.join("transforms.json")).unwrap();
    for (im, src) in ns.images.iter().zip(&scene.images) {
        let (cam, full) = (ns.camera_of(im), scene.camera_of(src));
        assert_eq!((cam.width, cam.height), (4, 4));
        assert_eq!(cam, &full.downscaled(2));
        assert_eq!(image::image_dimensions(&im.path).unwrap(), (4, 4));
        // Depth, 16-bit millimetres, sampled at the nearest full-size pixel: column 2x+1.
        let d = read_depth(im.depth_path.as_ref().unwrap(), 1000.0).unwrap();
        let i = scene
            .images
            .iter()
            .position(|s| s.name == src.name)
            .unwrap() as f32;
        for x in 0..4 {
            let want = 1.0 + (2 * x + 1) as f32 * 0.25 + i;
            assert!((d.get(x, 1).unwrap() - want).abs() < 1e-3);
        }
    }
    assert_eq!(ns.points.len(), scene.points.len());
}

#[test]
fn bad_requests_are_errors_and_write_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, run) = fixture(tmp.path());
    let out = tmp.path().join("taken");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("keep.txt"), "mine").unwrap();
    let before: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().collect();
    let e = export(&run, &out, &opts()).unwrap_err().to_string();
    assert!(e.contains("taken") && e.contains("--overwrite"), "{e}");
    assert_eq!(
        std::fs::read_to_string(out.join("keep.txt")).unwrap(),
        "mine"
    );
    let o = ExportOptions {
        object: Some("teapot".into()),
        ..opts()
    };
    let e = export(&run, &tmp.path().join("x"), &o)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no object 'teapot'") && e.contains("cube"),
        "{e}"
    );
    let scene = tmp.path().join("scene");
    let e = export(&scene, &tmp.path().join("x"), &o)
        .unwrap_err()
        .to_string();
    assert!(e.contains("need a run"), "{e}");
    // A run whose mask of an ok view is missing.
    std::fs::remove_file(run.join("segment/masks/cube/c.png")).unwrap();
    let e = export(&run, &tmp.path().join("x"), &opts())
        .unwrap_err()
        .to_string();
    assert!(e.contains("c.png"), "{e}");
    // Nothing new beside the inputs: no output, no temporary folder.
    let after: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().collect();
    assert_eq!(before.len(), after.len());
    // --overwrite replaces the folder.
    let (_, run) = fixture(&tmp.path().join("again"));
    let o = ExportOptions {
        overwrite: true,
        ..opts()
    };
    export(&run, &out, &o).unwrap();
    assert!(!out.join("keep.txt").exists() && out.join("transforms.json").is_file());
}

#[test]
fn cli_exports_a_run() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, run) = fixture(tmp.path());
    let out = tmp.path().join("cli");
    let o = common::objnerf_ok(&[
        "export",
        "nerfstudio",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--object",
        "cube",
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("2 frames") && text.contains("b.png"),
        "{text}"
    );
    let bad = std::process::Command::new(common::objnerf_bin())
        .args(["export", "nerfstudio", run.to_str().unwrap(), "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("not empty"));
}
