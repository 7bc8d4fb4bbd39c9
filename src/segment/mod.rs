//! Segment Anything (MobileSAM) through ONNX Runtime, and multi-view segmentation.
pub mod hull;
