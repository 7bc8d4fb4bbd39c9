//! `objnerf render`: a model rendered from every view of a scene.

use crate::error::Result;
use crate::field::eval::render_view;
use crate::field::io::Model;
use crate::field::{RayCamera, RenderOptions};
use crate::scene::io::{write_depth_png_mm, DepthMap};
use crate::scene::Scene;
use crate::util::atomic::save_image_atomic;
use crate::util::{AtomicDir, Detail, Progress};
use std::path::Path;

/// Render every view of `scene` (downscaled by `downscale`, default: the model's training
/// downscale): `<stem>.png` (RGB on white), `<stem>_alpha.png` and `<stem>_depth.png` (z-depth,
/// 16-bit millimetres, 0 = empty) into `out`, which is replaced, each pixel the mean of
/// `pixel_samples` x `pixel_samples` rays ([`RenderOptions::pixel_samples`]). Returns the files
/// written.
pub fn render_scene_views(
    model: &Model,
    scene: &Scene,
    downscale: Option<u32>,
    pixel_samples: u32,
    out: &Path,
    progress: &dyn Progress,
) -> Result<usize> {
    let cams = RayCamera::for_scene(scene, downscale.unwrap_or_else(|| model.downscale()));
    let dir = AtomicDir::new(out, true)?;
    // The default sampling (half-voxel steps), however coarsely training sampled.
    let opt = RenderOptions {
        pixel_samples,
        ..RenderOptions::default()
    };
    progress.begin("render", cams.len() as u64);
    for (i, cam) in cams.iter().enumerate() {
        let r = render_view(&model.field, &opt, cam, [1.0; 3]);
        let stem = Path::new(&cam.name)
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_else(|| cam.name.clone());
        // z-depth, as depth images store it, from the distance along the ray.
        let depth = DepthMap {
            width: r.width,
            height: r.height,
            metres: (0..r.width * r.height)
                .map(|i| r.depth[i as usize] / cam.ray_scale(i))
                .collect(),
        };
        let path = |suffix: &str| dir.path().join(format!("{stem}{suffix}.png"));
        save_image_atomic(&path(""), &r.rgb8().into())?;
        save_image_atomic(&path("_alpha"), &r.alpha8().into())?;
        write_depth_png_mm(&path("_depth"), &depth)?;
        progress.advance(i as u64 + 1, Detail::Item(&cam.name));
    }
    progress.end();
    dir.commit()?;
    Ok(cams.len() * 3)
}
