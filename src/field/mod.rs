//! The object field: a voxel-grid radiance field of one object (DVGO-style density,
//! Plenoxels-style spherical-harmonic colour), trained on CPU from masked views.
//!
//! Pipeline: [`rays`] turns a scene's views and masks into training rays inside the object's box
//! (from the masks' visual hull), [`train`] fits the [`model::Field`] with per-voxel Adam,
//! [`render`] marches rays through it (forward and hand-written backward), [`eval`] scores
//! held-out views, and [`io`] saves and loads the model file.

pub mod grid;
pub mod model;
pub mod render;

pub use model::{Field, FieldConfig};
