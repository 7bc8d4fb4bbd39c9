//! Whole jobs that run several stages in one command, handing each other values in memory:
//! [`extract`] (segment → train → mesh → turntable) and [`demo`] (the demo scene, extracted and
//! scored against its truth).

pub mod demo;
pub mod extract;
pub mod render_edit;

pub use extract::{extract, ExtractOptions, ExtractReport};
