//! LLFF poses_bounds.npy (with a scratch images/ folder of three images).
#![no_main]
mod common;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(scene) = objnerf::scene::formats::llff::parse(common::scene_dir(), data) {
        common::use_scene(&scene);
    }
});
