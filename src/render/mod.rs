//! Rendering trained fields to image files: turntables of one object ([`turntable`]), the views
//! of a scene ([`views`]), and edits: a background and placed objects in one pass
//! ([`composite`]); the same on a GPU through wgpu ([`gpu`]).

pub mod composite;
pub mod frame_files;
pub mod gpu;
pub mod turntable;
pub mod views;

pub use turntable::{turntable_views, write_turntable, Orbit, TurntableOptions};
pub use views::{evaluate_model, render_scene_views};
