//! Redwood / Open3D trajectory.log.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("trajectory.log");
    if let Ok(poses) = objnerf::scene::formats::rgbd::parse_trajectory(path, data) {
        for p in &poses {
            let _ = p.center();
        }
    }
});
