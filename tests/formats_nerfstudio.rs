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

/// The distortion as nerfstudio holds it: k1, k2, k3, k4, p1, p2.
fn nerfstudio_distortion(cam: &objnerf::scene::Camera) -> [f64; 6] {
    let p = &cam.params;
    match cam.model {
        CameraModel::SimplePinhole | CameraModel::Pinhole => [0.0; 6],
        CameraModel::SimpleRadial => [p[3], 0.0, 0.0, 0.0, 0.0, 0.0],
        CameraModel::Radial => [p[3], p[4], 0.0, 0.0, 0.0, 0.0],
        CameraModel::OpenCv => [p[4], p[5], 0.0, 0.0, p[6], p[7]],
        CameraModel::FullOpenCv => [p[4], p[5], p[8], 0.0, p[6], p[7]],
        CameraModel::OpenCvFisheye => [p[4], p[5], p[6], p[7], 0.0, 0.0],
        m => panic!("{m:?}"),
    }
}

#[test]
fn colmap_to_transforms_and_back_keeps_poses_and_intrinsics() {
    use objnerf::scene::formats::colmap::{read_model, write_model, ModelFormat};
    use objnerf::scene::{Camera, SceneCamera};
    let tmp = tempfile::tempdir().unwrap();
    let mut scene = support::tiny_scene(tmp.path());
    // One camera per view, in models transforms.json names differently.
    let cams = [
        (CameraModel::SimpleRadial, vec![9.5, 4.0, 4.125, 0.012]),
        (
            CameraModel::FullOpenCv,
            vec![
                10.0, 10.5, 3.9, 4.1, 0.01, -0.002, 3e-4, -1e-4, 5e-4, 0.0, 0.0, 0.0,
            ],
        ),
        (CameraModel::Radial, vec![9.75, 4.05, 3.95, -0.01, 0.003]),
    ];
    scene.cameras = cams
        .into_iter()
        .enumerate()
        .map(|(i, (m, p))| SceneCamera {
            id: i as u32 + 4,
            camera: Camera::new(m, 8, 8, p).unwrap(),
        })
        .collect();
    for (i, im) in scene.images.iter_mut().enumerate() {
        im.camera = i;
    }
    let model = tmp.path().join("sparse/0");
    std::fs::create_dir_all(&model).unwrap();
    write_model(&scene, &model, ModelFormat::Binary).unwrap();
    let colmap = read_model(&model, &tmp.path().join("images")).unwrap();
    let json = tmp.path().join("transforms.json");
    nerfstudio::write(&colmap, &json).unwrap();
    let back = nerfstudio::read(&json).unwrap();
    for (a, b) in colmap.images.iter().zip(&back.images) {
        let (m, n) = (a.pose.c2w_opencv(), b.pose.c2w_opencv());
        for (x, y) in m.iter().flatten().zip(n.iter().flatten()) {
            assert!((x - y).abs() < 1e-9, "{}: {x} vs {y}", a.name);
        }
        for (x, y) in a.pose.qvec().iter().zip(b.pose.qvec()) {
            assert!((x - y).abs() < 1e-9, "{}: q", a.name);
        }
        for (x, y) in a.pose.tvec().iter().zip(b.pose.tvec()) {
            assert!((x - y).abs() < 1e-9, "{}: t", a.name);
        }
        let (c, d) = (colmap.camera_of(a), back.camera_of(b));
        assert_eq!((c.width, c.height), (d.width, d.height));
        let pairs = [
            (c.focal().0, d.focal().0),
            (c.focal().1, d.focal().1),
            (c.principal_point().0, d.principal_point().0),
            (c.principal_point().1, d.principal_point().1),
        ];
        for (x, y) in pairs {
            assert!((x - y).abs() < 1e-9, "{}: {x} vs {y}", a.name);
        }
        let (k, l) = (nerfstudio_distortion(c), nerfstudio_distortion(d));
        for (x, y) in k.iter().zip(l) {
            assert!((x - y).abs() < 1e-9, "{}: {k:?} vs {l:?}", a.name);
        }
        let p = glam::DVec3::new(0.3, -0.2, 1.0);
        assert!((c.project(p).unwrap() - d.project(p).unwrap()).length() < 1e-9);
    }
    // nerfstudio reads camera_model at the top only, every other key per frame when they differ.
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(j["camera_model"], "OPENCV");
    assert!(j.get("fl_x").is_none());
    for f in j["frames"].as_array().unwrap() {
        for key in ["fl_x", "fl_y", "cx", "cy", "w", "h", "k1", "k2", "p1", "p2"] {
            assert!(f.get(key).is_some(), "{key} missing in {f}");
        }
    }
    // A fisheye camera beside perspective ones cannot be one nerfstudio file.
    let mut mixed = colmap.clone();
    mixed.cameras[0].camera = Camera::new(
        CameraModel::OpenCvFisheye,
        8,
        8,
        vec![9.0, 9.0, 4.0, 4.0, 0.01, 0.0, 0.0, 0.0],
    )
    .unwrap();
    let e = nerfstudio::write(&mixed, &tmp.path().join("mixed.json"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("mix fisheye and perspective"), "{e}");
    assert!(!tmp.path().join("mixed.json").exists());
}
