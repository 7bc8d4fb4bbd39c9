//! Multi-view segmentation (Obj-NeRF's Algorithm 1): a click in one view becomes a mask in every
//! view, carried by the scene's 2D-3D feature tracks.
//!
//! - [`types`]: prompts, a segmenter's answer, per-view results, options (shared by the rest).
//! - [`propagate`]: Algorithm 1 (votes, covisibility order, obstruction test, several objects,
//!   overlaps) and the projection baseline; [`view_prompts`]: one view's prompts (farthest-point
//!   positives, negatives, box, projected fill-in with a free-space test).
//! - [`hull`] (the alpha-shape expected mask), [`regions`] (mask islands and pin-holes),
//!   [`distance`] (exact distance transforms).
//! - [`sam_views`]: SAM ([`crate::sam`]) as the propagation's segmenter.
//! - [`run`]: `objnerf segment` as a call (checks, propagation, outputs); [`checks`]: the
//!   self-checks written into its report as warnings; [`output`]: masks, point clouds, contact
//!   sheets; [`saved`]: a saved run read back; [`evaluate`]: scores against truth masks.

pub mod distance;
pub mod evaluate;
pub mod hull;
pub mod mask_checks;
pub mod output;
pub mod propagate;
pub mod regions;
pub mod run;
pub mod sam_views;
pub mod saved;
pub mod types;
pub mod view_prompts;

pub use run::{check_request, segment_scene, SegmentReport};
pub use sam_views::SamViews;
pub use types::{
    ObjectPrompt, ObjectSegmentation, PointPrompt, PropagationOptions, ViewResult, ViewStatus,
};
