//! The .objf model file (src/field/io.rs), read whole and without its optimiser state.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::io::Cursor;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    use objnerf::field::io::read_from;
    let path = Path::new("model.objf");
    let n = data.len() as u64;
    if let Ok(m) = read_from(path, Cursor::new(data), n, true) {
        let f = &m.field;
        assert_eq!(
            f.grid.data.len(),
            f.grid.dims.iter().product::<usize>() * f.grid.channels
        );
        let _ = f.occupied_cells();
    }
    let _ = read_from(path, Cursor::new(data), n, false);
});
