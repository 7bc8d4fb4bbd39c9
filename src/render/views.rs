//! `objnerf render` and `objnerf eval`: a model rendered from every view of a scene, and scored
//! there, on the device asked for.

use super::gpu::{open_device, renderer, single, DeviceChoice, DeviceUsed};
use crate::error::Result;
use crate::field::eval::{eval_views, evaluate_with, EvalReport};
use crate::field::holdout::HoldOut;
use crate::field::io::Model;
use crate::field::{MaskSource, RayCamera, RenderOptions};
use crate::scene::io::{write_depth_png_mm, DepthMap};
use crate::scene::Scene;
use crate::util::atomic::save_image_atomic;
use crate::util::{AtomicDir, Detail, Progress};
use std::path::Path;

/// Render every view of `scene` (downscaled by `downscale`, default: the model's training
/// downscale): `<stem>.png` (RGB on white), `<stem>_alpha.png` and `<stem>_depth.png` (z-depth,
/// 16-bit millimetres, 0 = empty) into `out`, which is replaced, each pixel the mean of
/// `pixel_samples` x `pixel_samples` rays ([`RenderOptions::pixel_samples`]), on `device`.
/// Returns the files written and the device that drew them.
pub fn render_scene_views(
    model: &Model,
    scene: &Scene,
    downscale: Option<u32>,
    pixel_samples: u32,
    device: DeviceChoice,
    out: &Path,
    progress: &dyn Progress,
) -> Result<(usize, DeviceUsed)> {
    let cams = RayCamera::for_scene(scene, downscale.unwrap_or_else(|| model.downscale()));
    let dir = AtomicDir::new(out, true)?;
    // The default sampling (half-voxel steps), however coarsely training sampled.
    let opt = RenderOptions {
        pixel_samples,
        ..RenderOptions::default()
    };
    let composite = single(&model.field, &opt, [1.0; 3]);
    let (gpu, mut used) = open_device(device)?;
    let views = renderer(&composite, gpu.as_ref(), device, &mut used)?;
    progress.note(&format!("rendering on {}", used.describe()));
    progress.begin("render", cams.len() as u64);
    for (i, cam) in cams.iter().enumerate() {
        let r = views.render_view(cam)?;
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
    Ok((cams.len() * 3, used))
}

/// Score `model` on `scene`'s views ([`eval_views`]) drawn on `device` with the default
/// sampling (half-voxel steps, however coarsely training sampled) and `pixel_samples` x
/// `pixel_samples` rays a pixel.
pub fn evaluate_model(
    model: &Model,
    scene: &Scene,
    masks: &MaskSource,
    downscale: Option<u32>,
    hold_out: HoldOut,
    pixel_samples: u32,
    device: DeviceChoice,
) -> Result<(EvalReport, DeviceUsed)> {
    let views = eval_views(model, scene, masks, downscale, hold_out)?;
    let opt = RenderOptions {
        pixel_samples,
        ..RenderOptions::default()
    };
    let composite = single(&model.field, &opt, [1.0; 3]);
    let (gpu, mut used) = open_device(device)?;
    let r = renderer(&composite, gpu.as_ref(), device, &mut used)?;
    let report = evaluate_with(&views, |v| r.render_view(&v.cam))?;
    Ok((report, used))
}
