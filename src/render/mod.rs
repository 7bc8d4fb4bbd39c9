//! Rendering trained fields to image files: turntables of one object ([`turntable`]), the views
//! of a scene ([`views`]), and edits: a background and placed objects in one pass
//! ([`composite`]).

pub mod composite;
pub mod frame_files;
pub mod turntable;
pub mod views;

pub use turntable::{turntable_views, write_turntable, TurntableOptions};
pub use views::render_scene_views;
