//! nerfstudio's camera_path.json (data frame), as `objnerf render-edit --path` reads it; the path
//! read is resized as `--size` does and its cameras cast rays.
#![no_main]
use libfuzzer_sys::fuzz_target;
use objnerf::scene::camera_path::{CameraPath, PathFrame};

fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("/fuzz/camera_path.json");
    if let Ok(p) = CameraPath::parse(path, data, &PathFrame::Data) {
        if let Ok(small) = p.resized(8, 6) {
            for c in small.cameras.iter().take(64) {
                let cam = objnerf::field::RayCamera::new(String::new(), c.camera.clone(), c.pose);
                let _ = cam.ray(0);
            }
        }
    }
});
