//! Whole jobs that run several stages in one command, handing each other values in memory:
//! [`extract`] (segment → train → mesh → turntable), [`remove`] (objects taken out of a scene: a
//! scene field trained with the reverse alpha, its hole filled) and [`demo`] (the demo scene,
//! extracted and scored against its truth).

pub mod demo;
pub mod edit_fields;
pub mod extract;
pub mod extract_checks;
pub mod extract_report;
pub mod remove;
pub mod render_edit;
pub mod report_html;
pub mod train;

pub use extract::{extract, ExtractOptions, ExtractReport};
pub use remove::{remove, RemoveOptions, RemoveReport};
