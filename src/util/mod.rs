//! Small shared helpers, used by every stage: atomic file output, benchmark charts, named option enums, hashes, binary masks,
//! inpainting, grid neighbours, memory, paths, progress reporting, a seeded random generator, points' principal axes, order statistics,
//! the self-checks' warnings.

pub mod atomic;
pub mod bf16;
pub mod chart;
pub mod choice;
pub mod digest;
pub mod inpaint;
pub mod lattice;
pub mod machine;
pub mod mask;
pub mod mem;
pub mod paths;
pub mod progress;
pub mod rng;
pub mod spread;
pub mod stats;
pub mod warnings;

pub use atomic::{write_atomic, AtomicDir};
pub use progress::{Detail, Progress, Silent};
pub use rng::Rng;
pub use warnings::{Stage, Warning};
