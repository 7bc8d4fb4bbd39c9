//! Whole jobs that run several stages in one command, handing each other values in memory:
//! [`extract`] (segment → train → mesh → turntable) and [`demo`] (the demo scene, extracted and
//! scored against its truth).

pub mod checks;
pub mod demo;
pub mod extract;

pub use extract::{extract, ExtractOptions, ExtractReport};
