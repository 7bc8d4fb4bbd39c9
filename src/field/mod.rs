//! The object field: a voxel-grid radiance field of one object (DVGO-style density,
//! Plenoxels-style spherical-harmonic colour), trained on CPU from masked views.
//!
//! Pipeline: [`rays`] turns a scene's views and masks into training rays inside the object's box
//! (from the masks' visual hull), [`session`] sizes the grid and runs [`train`], which fits the
//! [`model::Field`] with per-voxel Adam; [`render`] marches rays through it (forward and
//! hand-written backward), [`eval`] renders and scores views, and [`io`] saves and loads the model.

pub mod commands;
pub mod depth;
pub mod eval;
pub mod grid;
pub mod io;
pub mod model;
pub mod rays;
pub mod render;
pub mod session;
pub mod train;

pub use model::{Field, FieldConfig};
pub use rays::{MaskSource, View};
pub use render::RenderOptions;
pub use session::{prepare, run, SetupConfig, StopRule};
pub use train::{TrainConfig, Trainer};
