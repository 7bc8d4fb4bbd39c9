//! nerfstudio / NeRF-synthetic transforms.json (its images, and sparse_pc.ply, in a scratch folder).
#![no_main]
mod common;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = common::scene_dir().join("transforms.json");
    if let Ok(scene) = objnerf::scene::formats::nerfstudio::parse(&path, data) {
        common::use_scene(&scene);
    }
});
