//! Photos: JPEG, read as objnerf reads a capture's colour image.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::io::Cursor;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let _ = objnerf::scene::io::decode_rgb(Path::new("photo.jpg"), Cursor::new(data));
});
