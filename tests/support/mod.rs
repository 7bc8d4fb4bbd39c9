//! A tiny scene built in a temporary folder, for the format tests: three 8x8 PNG views, two
//! cameras, and a sparse model whose features include some with and some without a 3D point.
#![allow(dead_code)]

use glam::{DVec2, DVec3};
use objnerf::scene::{
    Camera, CameraModel, Feature, ImageView, Point3D, Pose, Scene, SceneCamera, SourceFormat,
    TrackElement,
};
use std::path::Path;

pub const NAMES: [&str; 3] = ["a.png", "b.png", "c.png"];

/// Write 8x8 RGB images `dir/images/{a,b,c}.png` and return a scene that refers to them.
pub fn tiny_scene(dir: &Path) -> Scene {
    let img_dir = dir.join("images");
    std::fs::create_dir_all(&img_dir).unwrap();
    for (i, n) in NAMES.iter().enumerate() {
        let img = image::RgbImage::from_fn(8, 8, |x, y| {
            image::Rgb([x as u8 * 30, y as u8 * 30, i as u8 * 80])
        });
        img.save(img_dir.join(n)).unwrap();
    }
    let cameras = vec![
        SceneCamera {
            id: 1,
            camera: Camera::new(CameraModel::Pinhole, 8, 8, vec![9.5, 9.25, 4.0, 4.125]).unwrap(),
        },
        SceneCamera {
            id: 7,
            camera: Camera::new(
                CameraModel::OpenCv,
                8,
                8,
                vec![10.0, 10.5, 3.9, 4.1, 0.01, -0.002, 0.0003, -0.0001],
            )
            .unwrap(),
        },
    ];
    let eyes = [
        DVec3::new(3.0, 0.1, 1.0),
        DVec3::new(0.2, 3.1, 1.2),
        DVec3::new(-2.9, 0.3, 0.8),
    ];
    let images: Vec<ImageView> = NAMES
        .iter()
        .enumerate()
        .map(|(i, n)| ImageView {
            id: [3, 5, 9][i],
            name: n.to_string(),
            path: img_dir.join(n),
            camera: i % 2,
            pose: Pose::look_at(eyes[i], DVec3::new(0.01, -0.02, 0.03), DVec3::Z),
            mask_path: None,
            depth_path: None,
            features: (0..5)
                .map(|k| Feature {
                    xy: DVec2::new(
                        0.5 + k as f64 * 1.25,
                        7.5 - k as f64 * 0.75 + i as f64 * 0.1,
                    ),
                    point: None,
                })
                .collect(),
            depth_bounds: None,
        })
        .collect();
    let t = |image, feature| TrackElement { image, feature };
    let points = vec![
        Point3D {
            id: 11,
            xyz: DVec3::new(0.1, 0.2, 0.3),
            rgb: [10, 20, 30],
            error: 0.25,
            track: vec![t(0, 0), t(1, 1), t(2, 4)],
        },
        Point3D {
            id: 12,
            xyz: DVec3::new(-0.3, 0.05, 0.1),
            rgb: [200, 100, 0],
            error: 1.0 / 3.0,
            track: vec![t(0, 2), t(2, 0)],
        },
        Point3D {
            id: 40,
            xyz: DVec3::new(0.0, -0.25, 0.5),
            rgb: [1, 2, 3],
            error: 0.0,
            track: vec![t(1, 3), t(2, 2)],
        },
        // A point seen nowhere (COLMAP can hold these after filtering).
        Point3D {
            id: 41,
            xyz: DVec3::new(0.7, 0.7, 0.7),
            rgb: [255, 255, 255],
            error: -1.0,
            track: vec![],
        },
    ];
    let mut scene = Scene {
        source: dir.to_path_buf(),
        format: SourceFormat::ColmapBinary,
        cameras,
        images,
        points,
        depth_scale: 1000.0,
        applied_transform: None,
    };
    scene.link_features_from_tracks();
    scene.validate(dir).unwrap();
    scene
}
