//! COLMAP's points3d.txt (with the other two files of a good model beside it).
#![no_main]
mod common;
use libfuzzer_sys::fuzz_target;
use objnerf::scene::formats::colmap::ModelFormat;

fuzz_target!(|data: &[u8]| common::colmap(ModelFormat::Text, 2, data));
