//! The MobileSAM checkpoint (`objnerf models convert --checkpoint mobile_sam.pt`): a zip of a
//! pickle and raw storages.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::io::Cursor;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    use objnerf::sam::convert::torch::StateDict;
    if let Ok(sd) = StateDict::parse(Path::new("mobile_sam.pt"), Cursor::new(data)) {
        for t in sd.tensors.values() {
            assert_eq!(t.len(), t.shape.iter().product::<usize>());
        }
    }
});
