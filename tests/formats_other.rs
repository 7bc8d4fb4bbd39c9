//! LLFF, Redwood RGB-D and PLY: readers checked against data written here with known values, and
//! the RGB-D capture checked for metric, consistently posed depth.

mod common;

use glam::{DVec2, DVec3};
use objnerf::scene::formats::{llff, ply};
use objnerf::scene::io::read_depth;
use objnerf::scene::{Pose, Scene, SourceFormat};
use std::path::Path;

/// A version-1 .npy of little-endian f64 in C order.
fn write_npy(path: &Path, rows: &[[f64; 17]]) {
    let mut header = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({}, 17), }}",
        rows.len()
    );
    // Magic (6) + version (2) + length (2) + header + '\n' is a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((header.len() as u16).to_le_bytes());
    bytes.extend(header.as_bytes());
    for v in rows.iter().flatten() {
        bytes.extend(v.to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

/// An LLFF row from a pose: OpenGL [right, up, back] -> LLFF [down, right, back], then hwf, bounds.
fn llff_row(pose: &Pose, hwf: [f64; 3]) -> [f64; 17] {
    let gl = pose.c2w_opengl();
    let mut row = [0.0; 17];
    for r in 0..3 {
        let m = [-gl[r][1], gl[r][0], gl[r][2], gl[r][3], hwf[r]];
        row[r * 5..r * 5 + 5].copy_from_slice(&m);
    }
    row[15] = 0.5;
    row[16] = 9.0;
    row
}

#[test]
fn llff_poses_and_scaled_focal() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::create_dir_all(dir.join("images")).unwrap();
    let poses: Vec<Pose> = (0..4)
        .map(|i| {
            let a = i as f64 * 0.4;
            Pose::look_at(
                DVec3::new(3.0 * a.cos(), 3.0 * a.sin(), 0.5 + 0.1 * i as f64),
                DVec3::ZERO,
                DVec3::Z,
            )
        })
        .collect();
    for i in 0..4 {
        // The images are half the size the poses were computed at.
        image::RgbImage::new(16, 12)
            .save(dir.join(format!("images/IMG_{i:03}.JPG")))
            .unwrap();
    }
    let rows: Vec<[f64; 17]> = poses
        .iter()
        .map(|p| llff_row(p, [24.0, 32.0, 40.0]))
        .collect();
    write_npy(&dir.join("poses_bounds.npy"), &rows);
    let scene = Scene::load(dir).unwrap();
    assert_eq!(scene.format, SourceFormat::Llff);
    assert_eq!(scene.images.len(), 4);
    assert_eq!(scene.images[2].name, "IMG_002.JPG");
    assert_eq!(scene.cameras.len(), 1);
    let cam = &scene.cameras[0].camera;
    assert_eq!((cam.width, cam.height), (16, 12));
    assert_eq!(cam.params, vec![20.0, 20.0, 8.0, 6.0]);
    // The near and far bounds are kept: without a sparse model they bound stereo and NDC.
    assert!(scene
        .images
        .iter()
        .all(|im| im.depth_bounds == Some([0.5, 9.0])));
    for (im, p) in scene.images.iter().zip(&poses) {
        let (a, b) = (im.pose.c2w_opencv(), p.c2w_opencv());
        for r in 0..3 {
            for c in 0..4 {
                assert!(
                    (a[r][c] - b[r][c]).abs() < 1e-9,
                    "{}: {a:?} vs {b:?}",
                    im.name
                );
            }
        }
        // Looking at the origin, as built.
        let o = im.pose.world_to_camera(DVec3::ZERO);
        assert!(o.z > 0.0 && o.x.abs() < 1e-9 && o.y.abs() < 1e-9);
    }
}

#[test]
fn llff_image_folder_must_match_pose_count() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::create_dir_all(dir.join("images")).unwrap();
    image::RgbImage::new(4, 4)
        .save(dir.join("images/a.png"))
        .unwrap();
    let p = Pose::look_at(DVec3::X * 2.0, DVec3::ZERO, DVec3::Z);
    write_npy(
        &dir.join("poses_bounds.npy"),
        &[llff_row(&p, [4.0, 4.0, 5.0]); 2],
    );
    let msg = llff::read(dir).unwrap_err().to_string();
    assert!(msg.contains("2 poses") && msg.contains("has 1"), "{msg}");
    // A downscaled folder with the right count is used instead, focal scaled to it.
    std::fs::create_dir_all(dir.join("images_2")).unwrap();
    for n in ["x.png", "y.png"] {
        image::RgbImage::new(2, 2)
            .save(dir.join("images_2").join(n))
            .unwrap();
    }
    let scene = llff::read(dir).unwrap();
    assert!(scene.images[1].path.ends_with("images_2/y.png"));
    assert_eq!(scene.cameras[0].camera.params, vec![2.5, 2.5, 1.0, 1.0]);
}

#[test]
fn ply_round_trip() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("pts.ply");
    // f32-exact values: the writer stores float.
    let pts: Vec<(DVec3, [u8; 3])> = (0..50)
        .map(|i| {
            (
                DVec3::new(i as f64 * 0.25, -(i as f64) * 0.5, 1.0 / 1024.0 * i as f64),
                [i as u8, 255 - i as u8, 7],
            )
        })
        .collect();
    ply::write_points(&p, &pts).unwrap();
    assert_eq!(ply::read_points(&p).unwrap(), pts);
    ply::write_points(&p, &[]).unwrap();
    assert!(ply::read_points(&p).unwrap().is_empty());
}

/// Median relative difference between frame `a`'s depth carried into frame `b` and `b`'s depth.
fn depth_agreement(scene: &Scene, a: usize, b: usize) -> (f64, usize) {
    let (ia, ib) = (&scene.images[a], &scene.images[b]);
    let da = read_depth(ia.depth_path.as_ref().unwrap(), scene.depth_scale).unwrap();
    let db = read_depth(ib.depth_path.as_ref().unwrap(), scene.depth_scale).unwrap();
    let cam = scene.camera_of(ia);
    let mut rel = Vec::new();
    for row in (0..da.height).step_by(4) {
        for col in (0..da.width).step_by(4) {
            let Some(d) = da.get(col, row) else { continue };
            let world = ia
                .pose
                .camera_to_world_dir(cam.pixel_center_ray(col, row) * d as f64)
                + ia.pose.center();
            let pb = ib.pose.world_to_camera(world);
            let Some(px) = scene.camera_of(ib).project(pb) else {
                continue;
            };
            if !cam.contains(px) {
                continue;
            }
            let px = px - DVec2::splat(0.5);
            let (c, r) = (px.x.round() as u32, px.y.round() as u32);
            if let Some(d2) = db.get(c.min(db.width - 1), r.min(db.height - 1)) {
                rel.push(((d2 as f64 - pb.z) / pb.z).abs());
            }
        }
    }
    rel.sort_by(|x, y| x.total_cmp(y));
    (rel[rel.len() / 2], rel.len())
}

#[test]
fn icl_rgbd_metric_depth_and_poses() {
    let Some(dir) = common::shared_data("icl_rgbd") else {
        return;
    };
    let scene = Scene::load(&dir).unwrap();
    assert_eq!(scene.format, SourceFormat::RgbdRedwood);
    assert_eq!(scene.images.len(), 5);
    assert_eq!(scene.depth_scale, 1000.0);
    assert_eq!(scene.images[0].name, "color/00000.jpg");
    let cam = &scene.cameras[0].camera;
    assert_eq!((cam.width, cam.height), (640, 480));
    // Open3D's cx = 319.5 (pixel centres at integers) is 320 with corner-origin pixels.
    assert_eq!(cam.principal_point(), (320.0, 240.0));
    for im in &scene.images {
        let d = read_depth(im.depth_path.as_ref().unwrap(), scene.depth_scale).unwrap();
        let valid: Vec<f32> = d.metres.iter().copied().filter(|&v| v > 0.0).collect();
        let in_range = valid.iter().filter(|&&v| v > 0.3 && v < 3.0).count();
        assert!(
            valid.len() > d.metres.len() / 2,
            "{}: too few valid depths",
            im.name
        );
        assert!(
            in_range as f64 > 0.95 * valid.len() as f64,
            "{}: depths not in metres?",
            im.name
        );
    }
    for b in [1, 4] {
        let (median, n) = depth_agreement(&scene, 0, b);
        eprintln!("frame 0 -> {b}: median relative depth difference {median:.4} over {n} pixels");
        assert!(n > 5000, "too few overlapping pixels: {n}");
        assert!(
            median < 0.03,
            "frame 0 -> {b}: median relative difference {median}"
        );
    }
    // The check can tell conventions apart: reading the log's matrices as world-to-camera
    // instead of camera-to-world makes the depths disagree.
    let mut wrong = scene.clone();
    for im in &mut wrong.images {
        let m = im.pose.w2c_matrix().transpose().to_cols_array_2d();
        im.pose = Pose::from_c2w_opencv([m[0], m[1], m[2]]).unwrap();
    }
    let (median, n) = depth_agreement(&wrong, 0, 4);
    eprintln!("wrong convention: median {median:.4} over {n} pixels");
    assert!(median > 0.03, "the wrong convention agrees too ({median})");
}
