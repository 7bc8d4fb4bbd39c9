//! The checkpoint's data.pkl alone (the pickle subset objnerf evaluates: no code is run).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = objnerf::sam::convert::pickle::parse(data);
});
