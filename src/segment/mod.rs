//! Segment Anything (MobileSAM) through ONNX Runtime, and multi-view segmentation.
//!
//! - [`models`]: the models directory (`$OBJNERF_HOME`) and `objnerf models install/list`.
//! - [`sam`]: the [`Segmenter`] (encoder once per image, decoder per prompt set).
//! - [`prompt`], [`preprocess`], [`mask`]: SAM's inputs and outputs, exactly as SAM defines them.
//! - [`cache`]: embeddings keyed by image content and model, in memory and on disk.
//! - [`convert`]: the ONNX encoder and decoder written from the PyTorch checkpoint.
//! - [`view`]: `objnerf segment-view`; [`bench`]: `objnerf bench sam` (ours against Python
//!   onnxruntime in the same run); [`bench_convert`]: `objnerf bench sam-convert` (our ONNX
//!   files against the PyTorch export).
//! - [`scene_views`] (SAM for [`propagate`]), [`zoom`] (small objects).
//! - [`distance`], [`hull`], [`propagate`] with [`view_prompts`] and [`regions`], [`output`]: multi-view segmentation; [`evaluate`]:
//!   scoring it against truth masks, and the one-click-per-view oracle.

pub mod bench;
pub mod bench_convert;
pub mod cache;
pub mod cli;
pub mod convert;
pub mod distance;
pub mod evaluate;
pub mod hull;
pub mod mask;
pub mod models;
pub mod output;
pub mod preprocess;
pub mod prompt;
pub mod propagate;
pub mod regions;
pub mod run;
pub mod sam;
pub mod scene_views;
pub mod view;
pub mod view_prompts;
pub mod zoom;

pub use cache::Embedding;
pub use mask::Mask;
pub use models::ModelsDir;
pub use prompt::{Point, Prompts};
pub use sam::{Segmenter, SegmenterOptions};
