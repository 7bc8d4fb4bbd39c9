//! PLY point clouds (a transforms.json's ply_file_path) and meshes (`objnerf` truth meshes).
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("points.ply");
    let _ = objnerf::scene::formats::ply::parse(path, data, false);
    if let Ok(mesh) = objnerf::scene::formats::ply::parse(path, data, true) {
        let n = mesh.vertices.len();
        assert!(mesh.triangles.iter().flatten().all(|&v| (v as usize) < n));
    }
});
