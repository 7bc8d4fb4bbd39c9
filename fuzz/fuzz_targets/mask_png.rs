//! Masks: PNG (grey, grey+alpha, RGB, RGBA, 8 or 16 bit), read as objnerf reads a mask.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::io::Cursor;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let _ = objnerf::scene::io::decode_mask(Path::new("mask.png"), Cursor::new(data));
});
