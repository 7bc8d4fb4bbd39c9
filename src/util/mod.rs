//! Small shared helpers: atomic file output, a seeded random generator, image reading.

pub mod atomic;
pub mod bench;
pub mod mem;
pub mod paths;
pub mod progress;
pub mod rng;

pub use atomic::{write_atomic, AtomicDir};
pub use rng::Rng;
