//! What the fuzz targets share: the tiny valid files in `fuzz/seeds/` that a target's input is
//! read beside (a fuzzed cameras.bin with a good images.bin and points3D.bin), and a scratch
//! folder holding the images a scene file refers to.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

pub const COLMAP_BIN: [&[u8]; 3] = [
    include_bytes!("../../seeds/colmap_cameras_bin/cameras.bin"),
    include_bytes!("../../seeds/colmap_images_bin/images.bin"),
    include_bytes!("../../seeds/colmap_points3d_bin/points3D.bin"),
];
pub const COLMAP_TXT: [&[u8]; 3] = [
    include_bytes!("../../seeds/colmap_cameras_txt/cameras.txt"),
    include_bytes!("../../seeds/colmap_images_txt/images.txt"),
    include_bytes!("../../seeds/colmap_points3d_txt/points3D.txt"),
];
const IMAGES: [(&str, &[u8]); 3] = [
    ("a.png", include_bytes!("../../seeds/_scene/images/a.png")),
    ("b.png", include_bytes!("../../seeds/_scene/images/b.png")),
    ("c.png", include_bytes!("../../seeds/_scene/images/c.png")),
];
const SPARSE_PC: &[u8] = include_bytes!("../../seeds/ply/sparse_pc.ply");

/// A scratch scene folder (made once per process, removed by scripts/fuzz): `images/{a,b,c}.png`
/// (8x8) and `sparse_pc.ply`, for the readers that look files up beside the one fuzzed.
pub fn scene_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("objnerf-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("images")).expect("scratch folder");
        for (name, bytes) in IMAGES {
            std::fs::write(dir.join("images").join(name), bytes).expect("scratch image");
        }
        std::fs::write(dir.join("sparse_pc.ply"), SPARSE_PC).expect("scratch ply");
        dir
    })
}

/// Everything `objnerf info` computes from a scene that was read.
pub fn use_scene(scene: &objnerf::Scene) {
    let info = objnerf::scene::info::scene_info(scene);
    let _ = info.to_text();
}

/// One COLMAP model with file `which` (0 cameras, 1 images, 2 points3D) replaced by `data`.
pub fn colmap(format: objnerf::scene::formats::colmap::ModelFormat, which: usize, data: &[u8]) {
    use objnerf::scene::formats::colmap::{parse_model, ModelFormat};
    let mut files = match format {
        ModelFormat::Binary => COLMAP_BIN,
        ModelFormat::Text => COLMAP_TXT,
    };
    files[which] = data;
    if let Ok(scene) = parse_model(
        Path::new("sparse/0"),
        Path::new("images"),
        format,
        files[0],
        files[1],
        files[2],
    ) {
        use_scene(&scene);
    }
}
