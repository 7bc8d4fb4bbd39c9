//! COLMAP models survive binary <-> text conversion byte for byte.

mod support;

use objnerf::scene::formats::colmap::{read_model, write_model, ModelFormat};
use std::path::Path;

fn assert_same_files(a: &Path, b: &Path, ext: &str) {
    for f in ["cameras", "images", "points3D"] {
        let name = format!("{f}.{ext}");
        let x = std::fs::read(a.join(&name)).unwrap();
        let y = std::fs::read(b.join(&name)).unwrap();
        assert!(
            x == y,
            "{name} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

/// Write `scene` as `first`, then convert through the other format and back.
fn convert_twice(first: ModelFormat, other: ModelFormat, ext: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let scene = support::tiny_scene(tmp.path());
    let images = tmp.path().join("images");
    let (d1, d2, d3) = (
        tmp.path().join("m1"),
        tmp.path().join("m2"),
        tmp.path().join("m3"),
    );
    write_model(&scene, &d1, first).unwrap();
    let s1 = read_model(&d1, &images).unwrap();
    write_model(&s1, &d2, other).unwrap();
    let s2 = read_model(&d2, &images).unwrap();
    write_model(&s2, &d3, first).unwrap();
    assert_same_files(&d1, &d3, ext);
    // The scenes read are equal (apart from where they were read from and their format); against
    // the original, the pose's matrix is recomputed from COLMAP's quaternion, so compare q and t.
    assert_eq!(s1.cameras, s2.cameras);
    assert_eq!(s1.images, s2.images);
    assert_eq!(s1.points, s2.points);
    assert_eq!(s1.cameras, scene.cameras);
    assert_eq!(s1.points, scene.points);
    for (a, b) in s1.images.iter().zip(&scene.images) {
        assert_eq!(
            (a.id, &a.name, a.camera, &a.features),
            (b.id, &b.name, b.camera, &b.features)
        );
        assert_eq!(
            (a.pose.qvec(), a.pose.tvec()),
            (b.pose.qvec(), b.pose.tvec())
        );
    }
    assert!(s1.has_tracks());
    assert!(s1.images[0].features.iter().any(|f| f.point.is_none()));
    assert!(s1.images[0].features.iter().any(|f| f.point.is_some()));
}

#[test]
fn binary_text_binary_is_byte_identical() {
    convert_twice(ModelFormat::Binary, ModelFormat::Text, "bin");
}

#[test]
fn text_binary_text_is_byte_identical() {
    convert_twice(ModelFormat::Text, ModelFormat::Binary, "txt");
}
