//! Segment Anything (MobileSAM) on one image at a time, through ONNX Runtime.
//!
//! - [`runtime`]: ONNX Runtime's shared library, loaded once per process.
//! - [`segmenter`]: the [`Segmenter`] (encoder once per image, decoder per prompt set).
//! - [`prompt`], [`preprocess`], [`mask`]: SAM's inputs and outputs, exactly as SAM defines them.
//! - [`cache`]: embeddings keyed by image content and model, in memory and on disk.
//! - [`zoom`]: a second pass on a crop for small objects.
//! - [`convert`]: the ONNX encoder and decoder written from the PyTorch checkpoint.
//! - [`view`]: one image, some prompts, a mask and an overlay (`objnerf segment-view`).
//!
//! Where the files come from (the models directory and its installer) is [`crate::models`];
//! SAM across the views of a scene is [`crate::segment`].

pub mod cache;
pub mod convert;
pub mod mask;
pub mod preprocess;
pub mod prompt;
pub mod runtime;
pub mod segmenter;
pub mod view;
pub mod zoom;

pub use cache::Embedding;
pub use mask::Mask;
pub use prompt::{Point, Prompts};
pub use segmenter::{EmbedInfo, Segmenter, SegmenterOptions};

/// The command that fixes a missing model or library; every "not installed" error quotes it.
pub const INSTALL_HINT: &str = "objnerf models install";
