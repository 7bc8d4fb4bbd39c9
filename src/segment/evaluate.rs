//! Scoring multi-view masks against truth masks: the demo scene's truth, or an RGBA capture's
//! alpha (NeRF-synthetic: the alpha is the object).

use super::types::ObjectSegmentation;
use crate::error::{Error, Result};
use crate::scene::io::{read_mask_channel, MaskChannel};
use crate::scene::Scene;
use crate::util::mask::{iou, is_object};
use image::{GrayImage, Luma};
use rayon::prelude::*;

/// Every view's truth mask from its image's alpha (binarised); an error for an image without
/// a cut-out alpha.
pub fn alpha_truth(scene: &Scene) -> Result<Vec<GrayImage>> {
    scene
        .images
        .par_iter()
        .map(|im| {
            let (m, channel) = read_mask_channel(&im.path)?;
            if channel != MaskChannel::Alpha {
                return Err(Error::format(
                    &im.path,
                    "no alpha channel to take the truth mask from",
                ));
            }
            Ok(GrayImage::from_fn(m.width(), m.height(), |x, y| {
                Luma([if is_object(m.get_pixel(x, y)[0]) {
                    255
                } else {
                    0
                }])
            }))
        })
        .collect()
}

/// IoU of every view's mask with its truth (a view without a mask has IoU 0 unless the truth
/// is empty too, then 1).
pub fn view_ious(obj: &ObjectSegmentation, truth: &[GrayImage]) -> Vec<f64> {
    obj.views
        .iter()
        .zip(truth)
        .map(|(v, t)| match &v.mask {
            Some(m) => iou(m, t),
            None if t.pixels().all(|p| !is_object(p[0])) => 1.0,
            None => 0.0,
        })
        .collect()
}
