//! The edit file (edit.json), as `objnerf render-edit` and `demo-scene --edit` read it; what was
//! read is written back to JSON and read again.
#![no_main]
use libfuzzer_sys::fuzz_target;
use objnerf::edit::EditFile;

fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("/fuzz/edit.json");
    if let Ok(edit) = EditFile::parse(path, data) {
        let text = edit.to_json().to_string();
        let again = EditFile::parse(path, text.as_bytes()).expect("a written edit reads back");
        assert_eq!(again.objects.len(), edit.objects.len());
    }
});
