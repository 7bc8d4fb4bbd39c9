//! Depth maps: EXR in metres.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::io::Cursor;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(d) =
        objnerf::scene::io::decode_depth(Path::new("depth.exr"), Cursor::new(data), 1000.0)
    {
        assert_eq!(d.metres.len(), d.width as usize * d.height as usize);
    }
});
