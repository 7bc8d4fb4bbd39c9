//! Segment Anything (MobileSAM) through ONNX Runtime, and multi-view segmentation.
pub mod distance;
pub mod hull;
pub mod output;
pub mod propagate;
