//! Whole jobs that run several stages in one command, handing each other values in memory:
//! [`extract`] (segment → train → mesh → turntable), [`remove`] (objects taken out of a scene: a
//! scene field trained with the reverse alpha, its hole filled) and [`demo`] (the demo scene,
//! extracted and scored against its truth).

pub mod checks;
pub mod demo;
pub mod demo_edit;
pub mod extract;
pub mod remove;
pub mod render_edit;

pub use extract::{extract, ExtractOptions, ExtractReport};
pub use remove::{remove, RemoveOptions, RemoveReport};
