//! Supervision: what a field is trained against besides the photos' colours. Depth targets
//! ([`depth`]: the sparse points, spread over surfaces, or the scene's depth maps; [`stereo`]:
//! plane-sweep stereo between neighbouring photos), the band along a segmented mask's edge whose
//! colour the photo decides ([`edge`]), and which pixels carry a loss at all ([`loss_mask`]: a
//! removed object's pixels carry none). The training loop itself is [`crate::field`]'s; the
//! options that choose among these are [`crate::fit`]'s.

pub mod depth;
pub mod edge;
pub mod stereo;

use crate::error::Result;
use crate::field::view::View;
use crate::scene::Scene;
use crate::util::choice::named_choices;
use crate::util::mask::{dilate, is_object};
use depth::{add_dense_depth, add_sparse_depth, spread_sparse_depth};
use image::GrayImage;
use serde::Serialize;
use stereo::{add_stereo_depth, StereoOptions};

/// Depth supervision.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DepthMode {
    None,
    /// The depth of the object's sparse 3D points in each view (DS-NeRF style).
    Sparse,
    /// The scene's depth images.
    Dense,
    /// The sparse points' depths, spread over each view where nearby points agree on a
    /// surface ([`depth::spread_sparse_depth`]).
    Spread,
    /// The sparse points' depths, and plane-sweep stereo between neighbouring photos where it
    /// is clear and consistent ([`stereo`]).
    Stereo,
}

named_choices!(DepthMode, "depth", {
    None => "none",
    Sparse => "sparse",
    Dense => "dense",
    Spread => "spread",
    Stereo => "stereo",
});

/// Set the depth targets `mode` asks for on `views` (the scene's images in order, downscaled
/// by `downscale`); returns how many pixels have one.
pub fn add_depth_targets(
    views: &mut [View],
    scene: &Scene,
    mode: DepthMode,
    downscale: u32,
) -> Result<usize> {
    Ok(match mode {
        DepthMode::None => 0,
        DepthMode::Sparse => add_sparse_depth(views, scene, downscale)?,
        DepthMode::Dense => add_dense_depth(views, scene, downscale)?,
        DepthMode::Spread => {
            add_sparse_depth(views, scene, downscale)? + spread_sparse_depth(views)
        }
        DepthMode::Stereo => {
            // A capture without a sparse model (LLFF's poses_bounds.npy) still has the photos.
            let sparse = if scene.points.is_empty() {
                0
            } else {
                add_sparse_depth(views, scene, downscale)?
            };
            sparse + add_stereo_depth(views, scene, &StereoOptions::default())
        }
    })
}

/// Which pixels of a view (downscaled by `factor` to `w` x `h`) carry a loss: those whose whole
/// block lies outside the removed mask grown by `dilate_px`.
pub fn loss_mask(removed: &GrayImage, dilate_px: u32, factor: u32, w: u32, h: u32) -> Vec<bool> {
    let grown = dilate(removed, dilate_px);
    let f = factor.max(1);
    let mut keep = vec![true; (w * h) as usize];
    for (x, y, p) in grown.enumerate_pixels() {
        let (dx, dy) = (x / f, y / f);
        if is_object(p[0]) && dx < w && dy < h {
            keep[(dy * w + dx) as usize] = false;
        }
    }
    keep
}
