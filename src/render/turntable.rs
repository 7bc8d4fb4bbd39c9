//! Turntable renders of an object field: a ring of cameras around the object's box, looking at
//! its centre, the world's up kept up; written as numbered PNGs and an animated GIF.

use crate::error::{Error, Result};
use crate::field::{eval::render_view, Field, RayCamera, RenderOptions};
use crate::scene::{camera::Camera, frames::Pose};
use crate::util::atomic::{save_image_atomic, write_bytes_atomic};
use crate::util::{Detail, Progress};
use glam::DVec3;
use image::{Delay, Frame, RgbaImage};
use std::path::Path;

#[derive(Clone, Debug)]
pub struct TurntableOptions {
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// Camera height above the object's centre, degrees.
    pub elevation_deg: f64,
    /// Horizontal field of view, degrees.
    pub fov_deg: f64,
}

impl Default for TurntableOptions {
    fn default() -> Self {
        TurntableOptions {
            frames: 24,
            width: 320,
            height: 240,
            elevation_deg: 25.0,
            fov_deg: 40.0,
        }
    }
}

/// The ring's views: the box `lo..hi` (e.g. the mesh's bounds) in frame from every angle.
pub fn turntable_views(lo: DVec3, hi: DVec3, up: DVec3, opts: &TurntableOptions) -> Vec<RayCamera> {
    let centre = 0.5 * (lo + hi);
    let radius = 0.5 * (hi - lo).length();
    let fx = 0.5 * opts.width as f64 / (0.5 * opts.fov_deg.to_radians()).tan();
    // The narrower side's half-angle decides the distance that fits a sphere around the box.
    let half = (0.5 * opts.width.min(opts.height) as f64 / fx).atan();
    let dist = radius / half.sin() * 1.05;
    let up = up.normalize();
    let side = up.any_orthonormal_vector();
    let fwd = up.cross(side);
    let camera = Camera::pinhole(
        opts.width,
        opts.height,
        fx,
        fx,
        0.5 * opts.width as f64,
        0.5 * opts.height as f64,
    );
    let (se, ce) = opts.elevation_deg.to_radians().sin_cos();
    (0..opts.frames)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / opts.frames as f64;
            let dir = (side * a.cos() + fwd * a.sin()) * ce + up * se;
            let pose = Pose::look_at(centre + dir * dist, centre, up);
            RayCamera::new(format!("frame_{i:03}"), camera.clone(), pose)
        })
        .collect()
}

/// Render the ring around `lo..hi` on `background` and write `dir/frame_NNN.png` and `gif`
/// (looping, 12 fps). `progress` hears one step per frame of the current stage.
#[allow(clippy::too_many_arguments)]
pub fn write_turntable(
    field: &Field,
    (lo, hi): (DVec3, DVec3),
    up: DVec3,
    opts: &TurntableOptions,
    background: [f32; 3],
    dir: &Path,
    gif: &Path,
    progress: &dyn Progress,
) -> Result<usize> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let render = RenderOptions::default();
    let mut frames = Vec::new();
    for (i, v) in turntable_views(lo, hi, up, opts).iter().enumerate() {
        let r = render_view(field, &render, v, background);
        let img = r.rgb8();
        let file = format!("{}.png", v.name);
        save_image_atomic(&dir.join(&file), &img.clone().into())?;
        frames.push(img);
        progress.advance(i as u64 + 1, Detail::Item(&file));
    }
    let mut bytes = Vec::new();
    {
        let mut enc = image::codecs::gif::GifEncoder::new_with_speed(&mut bytes, 10);
        enc.set_repeat(image::codecs::gif::Repeat::Infinite)
            .map_err(|e| Error::image(gif, e))?;
        for f in &frames {
            let rgba: RgbaImage = image::DynamicImage::ImageRgb8(f.clone()).into_rgba8();
            let delay = Delay::from_numer_denom_ms(1000, 12);
            enc.encode_frame(Frame::from_parts(rgba, 0, 0, delay))
                .map_err(|e| Error::image(gif, e))?;
        }
    }
    write_bytes_atomic(gif, &bytes)?;
    Ok(frames.len())
}
