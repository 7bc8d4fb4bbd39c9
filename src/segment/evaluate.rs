//! Scoring multi-view masks against truth masks (the demo scene's truth, or an RGBA capture's
//! alpha), and the oracle the benchmark compares with: one click per view at the truth mask's
//! most interior point.

use super::distance::most_interior_point;
use super::hull::iou;
use super::propagate::{ObjectSegmentation, PointPrompt, ViewResult, ViewSegmenter, ViewStatus};
use crate::error::{Error, Result};
use crate::scene::Scene;
use image::{GrayImage, Luma};
use rayon::prelude::*;
use std::path::Path;

/// The object mask of an RGBA image: alpha > 127 (NeRF-synthetic's alpha is the object).
pub fn alpha_mask(path: &Path) -> Result<GrayImage> {
    let img = image::open(path).map_err(|e| Error::image(path, e))?;
    if !img.color().has_alpha() {
        return Err(Error::invalid(format!(
            "{}: no alpha channel to take the truth mask from",
            path.display()
        )));
    }
    let rgba = img.to_rgba8();
    Ok(GrayImage::from_fn(rgba.width(), rgba.height(), |x, y| {
        Luma([if rgba.get_pixel(x, y)[3] > 127 {
            255
        } else {
            0
        }])
    }))
}

/// Every view's truth mask from its image's alpha.
pub fn alpha_truth(scene: &Scene) -> Result<Vec<GrayImage>> {
    scene
        .images
        .par_iter()
        .map(|im| alpha_mask(&im.path))
        .collect()
}

/// Every view's truth mask of `object` in a demo scene (`truth/masks/<object>/<stem>.png`).
pub fn demo_truth(scene_dir: &Path, scene: &Scene, object: &str) -> Result<Vec<GrayImage>> {
    scene
        .images
        .par_iter()
        .map(|im| {
            let stem = Path::new(&im.name).with_extension("");
            let p = scene_dir
                .join("truth/masks")
                .join(object)
                .join(format!("{}.png", stem.display()));
            Ok(image::open(&p).map_err(|e| Error::image(&p, e))?.to_luma8())
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
            None if t.pixels().all(|p| p[0] <= 127) => 1.0,
            None => 0.0,
        })
        .collect()
}

/// Mean of the per-view IoUs.
pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// The oracle: every view where the truth mask is not empty gets one click at its most interior
/// point (what a person clicking each view would do); views with an empty truth stay absent.
pub fn oracle(
    scene: &Scene,
    name: &str,
    truth: &[GrayImage],
    seg: &mut dyn ViewSegmenter,
) -> Result<ObjectSegmentation> {
    let mut views = Vec::with_capacity(scene.images.len());
    for (v, (im, t)) in scene.images.iter().zip(truth).enumerate() {
        let mut res = ViewResult::unsegmented(&im.name);
        if let Some((x, y)) = most_interior_point(t) {
            let prompts = vec![PointPrompt {
                xy: [x, y],
                positive: true,
            }];
            let m = seg.segment(scene, v, &prompts, None)?;
            res.status = ViewStatus::Ok;
            res.score = m.score;
            res.num_prompts = 1;
            res.prompts = prompts;
            res.order = Some(v);
            res.mask = Some(m.mask);
        }
        views.push(res);
    }
    Ok(ObjectSegmentation {
        name: name.to_string(),
        views,
        points: vec![],
    })
}
