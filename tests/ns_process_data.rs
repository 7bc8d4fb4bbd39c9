//! Folders made by nerfstudio's `ns-process-data` read as scenes, with the cameras they were made
//! from. The layouts are built here from the demo scene as nerfstudio's process_data code writes
//! them (nerfstudio-project/nerfstudio, nerfstudio/process_data/):
//! - **COLMAP** (`ns-process-data images` / `video`, sfm tool colmap or hloc):
//!   `images/frame_00001.png...` (copies renamed in sorted order, `copy_images_list`),
//!   `images_2/`, `images_4/`, `images_8/` (`num_downscales = 3`), the model in `colmap/sparse/0`
//!   (COLMAP ran on `images/`, so it names the renamed frames), and `transforms.json` from
//!   `colmap_to_json`: the camera as OPENCV with zero distortion at the top level, frames with
//!   `file_path` `images/...`, `transform_matrix` (COLMAP's camera-to-world, y and z axes negated,
//!   rows reordered 0 2 1 and the new z row negated), `colmap_im_id`, that reordering as
//!   `applied_transform`, and `sparse_pc.ply` (the points, transformed, in ASCII).
//! - **transforms only** (`ns-process-data polycam` / `record3d` / `metashape` /
//!   `realitycapture` / `odm`, or `images --skip-colmap` with a model given): `images/`,
//!   `images_2/4/8`, and a `transforms.json` with the intrinsics in each frame
//!   (`polycam_utils`: `fl_x fl_y cx cy w h` per frame, `file_path` `./images/frame_00001.png`,
//!   `orientation_override: none`), no `colmap/`.

use glam::{DMat4, DVec3, DVec4};
use objnerf::demo::{write_demo_scene, DemoOptions};
use objnerf::scene::formats::colmap::{write_model, ModelFormat};
use objnerf::scene::SourceFormat;
use objnerf::Scene;
use serde_json::json;
use std::path::{Path, PathBuf};

/// nerfstudio's `applied_transform`: x, z, -y (rows 0 2 1 of the identity, the last negated).
const APPLIED: [[f64; 4]; 3] = [[1., 0., 0., 0.], [0., 0., 1., 0.], [0., -1., 0., 0.]];

fn demo(dir: &Path) -> Scene {
    let opts = DemoOptions {
        views: 12,
        ..DemoOptions::default()
    };
    write_demo_scene(&opts, &dir.join("demo")).unwrap();
    let scene = Scene::load(&dir.join("demo")).unwrap();
    assert_eq!(scene.format, SourceFormat::ColmapBinary);
    scene
}

/// Copy the scene's images to `out/images/frame_NNNNN.png` in name order, as
/// `copy_images_list` does, with the 2x, 4x and 8x downscales beside; the new name of each
/// image, by its old name.
fn copy_images(scene: &Scene, out: &Path) -> Vec<(String, String)> {
    let mut old: Vec<&objnerf::scene::ImageView> = scene.images.iter().collect();
    old.sort_by(|a, b| a.name.cmp(&b.name));
    let mut renamed = Vec::new();
    for (idx, im) in old.iter().enumerate() {
        let name = format!("frame_{:05}.png", idx + 1);
        std::fs::create_dir_all(out.join("images")).unwrap();
        std::fs::copy(&im.path, out.join("images").join(&name)).unwrap();
        let img = image::open(&im.path).unwrap();
        for f in [2, 4, 8] {
            let dir = out.join(format!("images_{f}"));
            std::fs::create_dir_all(&dir).unwrap();
            img.resize_exact(
                img.width() / f,
                img.height() / f,
                image::imageops::FilterType::Triangle,
            )
            .save(dir.join(&name))
            .unwrap();
        }
        renamed.push((im.name.clone(), name));
    }
    renamed
}

fn rows(m: DMat4) -> Vec<Vec<f64>> {
    (0..4).map(|r| m.row(r).to_array().to_vec()).collect()
}

/// `colmap_to_json`'s camera-to-world for a COLMAP pose.
fn nerfstudio_c2w(w2c: DMat4) -> DMat4 {
    let c2w = w2c.inverse();
    // c2w[0:3, 1:3] *= -1
    let mut m = c2w;
    m.y_axis = DVec4::new(-m.y_axis.x, -m.y_axis.y, -m.y_axis.z, m.y_axis.w);
    m.z_axis = DVec4::new(-m.z_axis.x, -m.z_axis.y, -m.z_axis.z, m.z_axis.w);
    // c2w = c2w[[0, 2, 1, 3], :]; c2w[2, :] *= -1
    let (r0, r1, r2, r3) = (m.row(0), m.row(1), m.row(2), m.row(3));
    DMat4::from_cols(r0, r2, -r1, r3).transpose()
}

fn applied() -> DMat4 {
    let r = |i: usize| DVec4::from_array(APPLIED[i]);
    DMat4::from_cols(r(0), r(1), r(2), DVec4::W).transpose()
}

/// The COLMAP layout of `ns-process-data images` in `out`.
fn colmap_layout(scene: &Scene, out: &Path) {
    let renamed = copy_images(scene, out);
    let mut model = scene.clone();
    for im in &mut model.images {
        let new = &renamed.iter().find(|(o, _)| *o == im.name).unwrap().1;
        im.name = new.clone();
        im.path = out.join("images").join(new);
    }
    write_model(&model, &out.join("colmap/sparse/0"), ModelFormat::Binary).unwrap();
    let cam = &model.cameras[0].camera;
    let (fx, fy) = cam.focal();
    let (cx, cy) = cam.principal_point();
    let frames: Vec<_> = model
        .images
        .iter()
        .map(|im| {
            json!({
                "file_path": format!("images/{}", im.name),
                "transform_matrix": rows(nerfstudio_c2w(im.pose.w2c_matrix())),
                "colmap_im_id": im.id,
            })
        })
        .collect();
    let transforms = json!({
        "w": cam.width, "h": cam.height, "fl_x": fx, "fl_y": fy, "cx": cx, "cy": cy,
        "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "camera_model": "OPENCV",
        "frames": frames,
        "applied_transform": APPLIED,
        "ply_file_path": "sparse_pc.ply",
    });
    std::fs::write(
        out.join("transforms.json"),
        serde_json::to_string_pretty(&transforms).unwrap(),
    )
    .unwrap();
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty uint8 red\nproperty uint8 green\nproperty uint8 blue\nend_header\n",
        model.points.len()
    );
    for p in &model.points {
        let q = applied().transform_point3(p.xyz);
        let [r, g, b] = p.rgb;
        ply += &format!("{:8.6} {:8.6} {:8.6} {r} {g} {b}\n", q.x, q.y, q.z);
    }
    std::fs::write(out.join("sparse_pc.ply"), ply).unwrap();
}

/// The transforms-only layout (Polycam's converter) in `out`.
fn transforms_layout(scene: &Scene, out: &Path) {
    let renamed = copy_images(scene, out);
    let frames: Vec<_> = scene
        .images
        .iter()
        .map(|im| {
            let cam = scene.camera_of(im);
            let (fx, fy) = cam.focal();
            let (cx, cy) = cam.principal_point();
            let new = &renamed.iter().find(|(o, _)| *o == im.name).unwrap().1;
            let c2w = im.pose.c2w_opengl();
            let mut m: Vec<Vec<f64>> = c2w.iter().map(|r| r.to_vec()).collect();
            m.push(vec![0.0, 0.0, 0.0, 1.0]);
            json!({
                "fl_x": fx, "fl_y": fy, "cx": cx, "cy": cy, "w": cam.width, "h": cam.height,
                "file_path": format!("./images/{new}"),
                "transform_matrix": m,
            })
        })
        .collect();
    let transforms = json!({
        "camera_model": "OPENCV",
        "orientation_override": "none",
        "frames": frames,
    });
    std::fs::write(
        out.join("transforms.json"),
        serde_json::to_string_pretty(&transforms).unwrap(),
    )
    .unwrap();
}

/// `loaded` has `original`'s cameras: the same intrinsics (any distortion zero) and poses
/// equal after `world` (the world transform from `original`'s frame to `loaded`'s), to 1e-9.
/// Images are matched through `renamed`.
fn assert_same_cameras(original: &Scene, loaded: &Scene, world: DMat4, out: &Path) {
    assert_eq!(loaded.images.len(), original.images.len());
    let mut names: Vec<&str> = original.images.iter().map(|i| i.name.as_str()).collect();
    names.sort();
    for im in &loaded.images {
        // Frames were numbered in the original names' order.
        let k: usize = im.name.trim_start_matches("images/")[6..11]
            .parse()
            .unwrap();
        let orig = &original.images[original.find_image(names[k - 1]).unwrap()];
        let (a, b) = (loaded.camera_of(im), original.camera_of(orig));
        assert_eq!((a.width, a.height), (b.width, b.height));
        assert_eq!(a.focal(), b.focal(), "{}", im.name);
        assert_eq!(a.principal_point(), b.principal_point(), "{}", im.name);
        let p = DVec3::new(0.3, -0.2, 2.0);
        let (pa, pb) = (a.project(p).unwrap(), b.project(p).unwrap());
        assert!((pa - pb).length() < 1e-9, "{}: {pa} vs {pb}", im.name);
        let want = orig.pose.transformed(world).unwrap();
        let d = (im.pose.c2w_matrix() - want.c2w_matrix()).abs();
        let worst = d.to_cols_array().iter().cloned().fold(0.0, f64::max);
        assert!(worst < 1e-9, "{}: pose differs by {worst}", im.name);
        // The full-size images, not a downscale.
        assert_eq!(
            std::fs::canonicalize(im.path.parent().unwrap()).unwrap(),
            std::fs::canonicalize(out.join("images")).unwrap()
        );
    }
}

#[test]
fn ns_process_data_colmap_layout_reads_as_its_colmap_model() {
    let dir = tempfile::tempdir().unwrap();
    let scene = demo(dir.path());
    let out = dir.path().join("processed");
    colmap_layout(&scene, &out);
    // The folder, the colmap/ folder and the model folder: the COLMAP model, with its tracks
    // and the images beside colmap/.
    let paths: [PathBuf; 3] = [out.clone(), out.join("colmap"), out.join("colmap/sparse/0")];
    for p in &paths {
        let s = Scene::load(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert_eq!(s.format, SourceFormat::ColmapBinary, "{}", p.display());
        assert!(s.has_tracks());
        assert_eq!(s.points.len(), scene.points.len());
        assert_same_cameras(&scene, &s, DMat4::IDENTITY, &out);
    }
    // Its transforms.json: the same cameras in nerfstudio's frame (applied_transform).
    let ns = Scene::load(&out.join("transforms.json")).unwrap();
    assert_eq!(ns.format, SourceFormat::Nerfstudio);
    assert_eq!(ns.applied_transform, Some(APPLIED));
    assert_eq!(ns.points.len(), scene.points.len());
    assert_same_cameras(&scene, &ns, applied(), &out);
}

#[test]
fn ns_process_data_transforms_layout_reads_as_a_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = demo(dir.path());
    let out = dir.path().join("processed");
    transforms_layout(&scene, &out);
    let s = Scene::load(&out).unwrap();
    assert_eq!(s.format, SourceFormat::Nerfstudio);
    // Per-frame intrinsics that agree make one camera.
    assert_eq!(s.cameras.len(), 1);
    assert_same_cameras(&scene, &s, DMat4::IDENTITY, &out);
}
