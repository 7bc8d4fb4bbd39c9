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

/// Which MobileSAM encoder runs. Both are written from the same checkpoint by [`convert`]; the
/// decoder is the same for both.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// The reference graph: the PyTorch exporter's operators, in float32. The default: int8 saves
    /// too little time for masks that differ on ambiguous clicks (examples/results/bench_sam.md).
    #[default]
    Fp32,
    /// Linear layers in int8 and fused attention ([`convert::encoder::Variant::INT8`]): 0.75-0.85
    /// x fp32's encoder time on the 2-core machines measured (examples/results/bench_sam.md).
    Int8,
}

impl Precision {
    pub fn name(self) -> &'static str {
        match self {
            Precision::Fp32 => "fp32",
            Precision::Int8 => "int8",
        }
    }

    /// `fp32` or `int8`.
    pub fn parse(s: &str) -> crate::error::Result<Self> {
        match s {
            "fp32" => Ok(Precision::Fp32),
            "int8" => Ok(Precision::Int8),
            _ => Err(crate::error::Error::invalid(format!(
                "unknown SAM precision {s:?}: use fp32 or int8"
            ))),
        }
    }
}

impl std::fmt::Display for Precision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
