//! Rendering trained fields to image files: turntables of one object ([`turntable`]) and the
//! views of a scene ([`views`]).

pub mod turntable;
pub mod views;

pub use turntable::{turntable_views, write_turntable, TurntableOptions};
pub use views::render_scene_views;
