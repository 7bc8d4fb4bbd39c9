//! nerfstudio / NeRF-synthetic transforms.json: reading the shared captures, and read -> write ->
//! read giving the same scene.

mod common;
mod support;

use glam::DVec2;
use objnerf::scene::formats::nerfstudio;
use objnerf::scene::io::{write_depth_png_mm, DepthMap};
use objnerf::scene::{CameraModel, Scene, SourceFormat};
use std::path::Path;
use std::process::Command;

fn same_file(a: &Path, b: &Path) -> bool {
    a.canonicalize().unwrap() == b.canonicalize().unwrap()
}

/// Everything but `source` is equal; files are compared by what they resolve to, since a scene
/// written elsewhere refers to the same files by other paths.
fn assert_same_scene(a: &Scene, b: &Scene) {
    assert_eq!(a.format, b.format);
    assert_eq!(a.cameras, b.cameras);
    assert_eq!(a.points, b.points);
    assert_eq!(a.depth_scale, b.depth_scale);
    assert_eq!(a.applied_transform, b.applied_transform);
    assert_eq!(a.images.len(), b.images.len());
    for (x, y) in a.images.iter().zip(&b.images) {
        assert_eq!((x.id, &x.name, x.camera), (y.id, &y.name, y.camera));
        assert_eq!(x.pose, y.pose, "pose of {}", x.name);
        assert_eq!(x.features, y.features);
        assert!(
            same_file(&x.path, &y.path),
            "{} vs {}",
            x.path.display(),
            y.path.display()
        );
        for (p, q) in [(&x.mask_path, &y.mask_path), (&x.depth_path, &y.depth_path)] {
            match (p, q) {
                (None, None) => {}
                (Some(p), Some(q)) => {
                    assert!(same_file(p, q), "{} vs {}", p.display(), q.display())
                }
                _ => panic!("{}: mask/depth present in one scene only", x.name),
            }
        }
    }
}

/// Read `json`, write it into a temporary folder that links the source's image folder `images`,
/// read that back and compare; writing what was read back reproduces the file byte for byte.
fn round_trip_shared(json: &Path, images: &str) {
    let a = nerfstudio::read(json).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let linked = json.parent().unwrap().join(images).canonicalize().unwrap();
    let write_into = |dir: &Path, scene: &Scene| {
        std::fs::create_dir_all(dir).unwrap();
        std::os::unix::fs::symlink(&linked, dir.join(images)).unwrap();
        let out = dir.join(json.file_name().unwrap());
        nerfstudio::write(scene, &out).unwrap();
        out
    };
    let out = write_into(tmp.path(), &a);
    let b = nerfstudio::read(&out).unwrap();
    assert_same_scene(&a, &b);
    let again = write_into(&tmp.path().join("again"), &b);
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());
}

#[test]
fn lego_info_json() {
    let Some(lego) = common::shared_data("lego") else {
        return;
    };
    let out = Command::new(common::objnerf_bin())
        .args(["info", "--json"])
        .arg(lego.join("transforms_train.json"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(info["num_images"], 100);
    assert_eq!(info["format"], "NerfSynthetic");
    let first = &info["images"][0];
    assert_eq!(
        (first["width"].as_u64(), first["height"].as_u64()),
        (Some(800), Some(800))
    );
    let fx = first["fx"].as_f64().unwrap();
    assert!((fx - 1111.11).abs() < 0.01, "fx = {fx}");
    assert_eq!(first["name"], "train/r_0.png");
}

#[test]
fn lego_folder_loads_transforms_train() {
    let Some(lego) = common::shared_data("lego") else {
        return;
    };
    let scene = Scene::load(&lego).unwrap();
    assert_eq!(scene.source.file_name().unwrap(), "transforms_train.json");
    assert_eq!(scene.format, SourceFormat::NerfSynthetic);
    assert_eq!(scene.images.len(), 100);
    assert_eq!(scene.cameras.len(), 1);
    assert_eq!(scene.images[99].id, 100);
    // Blender cameras look at the origin: the object is in front of every camera.
    for im in &scene.images {
        assert!(
            im.pose.world_to_camera(glam::DVec3::ZERO).z > 0.0,
            "{}",
            im.name
        );
    }
}

#[test]
fn lego_round_trip() {
    let Some(lego) = common::shared_data("lego") else {
        return;
    };
    round_trip_shared(&lego.join("transforms_train.json"), "train");
}

#[test]
fn fox_opencv_camera() {
    let Some(fox) = common::shared_data("fox") else {
        return;
    };
    let scene = Scene::load(&fox).unwrap();
    assert_eq!(scene.images.len(), 50);
    assert_eq!(scene.cameras.len(), 1);
    let cam = &scene.cameras[0].camera;
    assert_eq!(cam.model, CameraModel::OpenCv);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fox.join("transforms.json")).unwrap())
            .unwrap();
    let key = |k: &str| json[k].as_f64().unwrap();
    assert_eq!(
        cam.params,
        vec![
            key("fl_x"),
            key("fl_y"),
            key("cx"),
            key("cy"),
            key("k1"),
            key("k2"),
            key("p1"),
            key("p2")
        ]
    );
    assert_eq!((cam.width, cam.height), (1080, 1920));
    // Projection through the distortion inverts unprojection, corners included.
    let (w, h) = (cam.width as f64, cam.height as f64);
    for px in [
        DVec2::new(0.5, 0.5),
        DVec2::new(w - 0.5, 0.5),
        DVec2::new(0.5, h - 0.5),
        DVec2::new(w - 0.5, h - 0.5),
        DVec2::new(w / 2.0, h / 3.0),
    ] {
        let back = cam.project(cam.unproject(px) * 3.0).unwrap();
        assert!((back - px).length() < 1e-4, "{px} -> {back}");
    }
    // The distortion moves corners by a plausible amount (pixels, not hundreds).
    let corner = DVec2::new(0.5, 0.5);
    let ray = cam.unproject(corner);
    let (fx, fy) = cam.focal();
    let (cx, cy) = cam.principal_point();
    let pinhole = DVec2::new(fx * ray.x + cx, fy * ray.y + cy);
    let shift = (pinhole - corner).length();
    assert!(shift > 1.0 && shift < 200.0, "corner shift {shift}");
}

#[test]
fn fox_round_trip() {
    let Some(fox) = common::shared_data("fox") else {
        return;
    };
    round_trip_shared(&fox.join("transforms.json"), "images");
}

#[test]
fn masks_depth_points_and_applied_transform_round_trip() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let mut scene = support::tiny_scene(dir);
    std::fs::create_dir_all(dir.join("masks")).unwrap();
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    for im in &mut scene.images {
        im.features.clear();
        let mask = dir.join("masks").join(&im.name);
        image::GrayImage::from_fn(8, 8, |x, _| image::Luma([if x < 4 { 255 } else { 0 }]))
            .save(&mask)
            .unwrap();
        let depth = dir.join("depth").join(&im.name);
        write_depth_png_mm(
            &depth,
            &DepthMap {
                width: 8,
                height: 8,
                metres: vec![1.5; 64],
            },
        )
        .unwrap();
        im.mask_path = Some(mask);
        im.depth_path = Some(depth);
    }
    scene.points.truncate(3);
    for p in &mut scene.points {
        p.track.clear();
    }
    scene.applied_transform = Some([
        [0.0, 1.0, 0.0, 0.5],
        [1.0, 0.0, 0.0, -0.25],
        [0.0, 0.0, -1.0, 2.0],
    ]);
    let first = dir.join("transforms.json");
    nerfstudio::write(&scene, &first).unwrap();
    let a = nerfstudio::read(&first).unwrap();
    assert_eq!(a.format, SourceFormat::Nerfstudio);
    assert_eq!(
        a.cameras.len(),
        2,
        "per-frame intrinsics, two distinct cameras"
    );
    assert_eq!(a.points.len(), 3);
    assert!(a
        .images
        .iter()
        .all(|i| i.mask_path.is_some() && i.depth_path.is_some()));
    assert_eq!(a.applied_transform, scene.applied_transform);
    // Poses survive the OpenGL conversion to rounding.
    for (x, y) in a.images.iter().zip(&scene.images) {
        assert!((x.pose.center() - y.pose.center()).length() < 1e-12);
    }
    let second = dir.join("transforms_copy.json");
    nerfstudio::write(&a, &second).unwrap();
    let b = nerfstudio::read(&second).unwrap();
    assert_same_scene(&a, &b);
    let text = std::fs::read_to_string(&second).unwrap();
    assert!(text.contains("\"mask_path\": \"masks/a.png\""), "{text}");
    assert!(text.contains("\"depth_file_path\": \"depth/a.png\""));

    // Into another folder: paths become relative to it, and still name the same files.
    let other = dir.join("out/nested/transforms.json");
    nerfstudio::write(&a, &other).unwrap();
    let text = std::fs::read_to_string(&other).unwrap();
    assert!(
        text.contains("\"file_path\": \"../../images/a.png\""),
        "{text}"
    );
    let c = nerfstudio::read(&other).unwrap();
    for (x, y) in a.images.iter().zip(&c.images) {
        assert!(same_file(&x.path, &y.path));
        assert!(same_file(
            x.mask_path.as_ref().unwrap(),
            y.mask_path.as_ref().unwrap()
        ));
    }
}
