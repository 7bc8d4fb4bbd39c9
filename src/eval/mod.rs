//! Accuracy measures against ground truth: mask IoU lives with segmentation; here, geometry.

pub mod chamfer;
