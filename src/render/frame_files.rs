//! The files of a rendered path (docs/edit-format.md): `frame_00000.png` (RGB) and, on request,
//! `alpha_00000.png`, `depth_00000.exr` (z-depth in metres, one float channel `Y`, +inf where
//! nothing was hit) and `index_00000.png` (0 = background, i + 1 = the edit's `objects[i]`).
//! `objnerf render-edit` and the demo's exact truth (`objnerf demo-scene --edit`) both write
//! them, so two folders compare file by file.

use crate::error::{Error, Result};
use crate::scene::io::{write_depth_exr_far, DepthMap};
use crate::util::atomic::{save_image_atomic, write_bytes_atomic};
use image::{GrayImage, RgbImage};
use std::path::{Path, PathBuf};

/// Which files each frame gets besides its RGB.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Passes {
    pub alpha: bool,
    pub depth: bool,
    pub index: bool,
}

impl std::str::FromStr for Passes {
    type Err = String;
    /// A comma-separated list of rgb, alpha, depth, index (rgb is always written).
    fn from_str(s: &str) -> std::result::Result<Passes, String> {
        let mut p = Passes::default();
        for part in s.split(',').map(str::trim).filter(|x| !x.is_empty()) {
            match part {
                "rgb" => {}
                "alpha" => p.alpha = true,
                "depth" => p.depth = true,
                "index" => p.index = true,
                _ => {
                    return Err(format!(
                        "unknown pass '{part}' (the passes are rgb, alpha, depth, index)"
                    ))
                }
            }
        }
        Ok(p)
    }
}

impl std::fmt::Display for Passes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut v = vec!["rgb"];
        for (on, name) in [
            (self.alpha, "alpha"),
            (self.depth, "depth"),
            (self.index, "index"),
        ] {
            if on {
                v.push(name);
            }
        }
        f.write_str(&v.join(","))
    }
}

/// The file of pass `kind` ("frame", "alpha", "depth", "index") of frame `k` in `dir`.
pub fn frame_file(dir: &Path, kind: &str, k: usize) -> PathBuf {
    let ext = if kind == "depth" { "exr" } else { "png" };
    dir.join(format!("{kind}_{k:05}.{ext}"))
}

/// One frame's images.
pub struct FrameImages {
    pub rgb: RgbImage,
    pub alpha: Option<GrayImage>,
    /// z-depth in metres.
    pub depth: Option<DepthMap>,
    pub index: Option<GrayImage>,
}

/// Write frame `k`'s files into `dir` (each atomically; the RGB last, so a frame counts as done
/// when its RGB exists).
pub fn write_frame(dir: &Path, k: usize, f: &FrameImages) -> Result<()> {
    if let Some(a) = &f.alpha {
        save_image_atomic(&frame_file(dir, "alpha", k), &a.clone().into())?;
    }
    if let Some(d) = &f.depth {
        write_depth_exr_far(&frame_file(dir, "depth", k), d)?;
    }
    if let Some(i) = &f.index {
        save_image_atomic(&frame_file(dir, "index", k), &i.clone().into())?;
    }
    save_image_atomic(&frame_file(dir, "frame", k), &f.rgb.clone().into())
}

/// The frames as a video: `video.mp4` through ffmpeg when it is installed, else an animated
/// `video.gif`. Returns the file written.
pub fn write_video(dir: &Path, frames: &[RgbImage], fps: f64) -> Result<PathBuf> {
    if let Some(p) = ffmpeg_mp4(dir, frames.len(), fps)? {
        return Ok(p);
    }
    let gif = dir.join("video.gif");
    let mut bytes = Vec::new();
    {
        let mut enc = image::codecs::gif::GifEncoder::new_with_speed(&mut bytes, 10);
        enc.set_repeat(image::codecs::gif::Repeat::Infinite)
            .map_err(|e| Error::image(&gif, e))?;
        let ms = (1000.0 / fps.max(1e-3)).round().max(1.0) as u32;
        for f in frames {
            let rgba = image::DynamicImage::ImageRgb8(f.clone()).into_rgba8();
            let delay = image::Delay::from_numer_denom_ms(ms, 1);
            enc.encode_frame(image::Frame::from_parts(rgba, 0, 0, delay))
                .map_err(|e| Error::image(&gif, e))?;
        }
    }
    write_bytes_atomic(&gif, &bytes)?;
    Ok(gif)
}

/// `video.mp4` from `dir/frame_%05d.png` with ffmpeg (H.264, yuv420p; odd sizes padded by a
/// pixel), or None when ffmpeg is not installed.
fn ffmpeg_mp4(dir: &Path, n: usize, fps: f64) -> Result<Option<PathBuf>> {
    let found = std::process::Command::new("ffmpeg")
        .arg("-version")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !found || n == 0 {
        return Ok(None);
    }
    let out = dir.join("video.mp4");
    let tmp = dir.join(".video.tmp.mp4");
    let res = std::process::Command::new("ffmpeg")
        .args(["-y", "-loglevel", "error", "-framerate"])
        .arg(format!("{fps}"))
        .arg("-i")
        .arg(dir.join("frame_%05d.png"))
        .args([
            "-frames:v",
            &n.to_string(),
            "-vf",
            "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            "-c:v",
            "libx264",
            "-pix_fmt",
            "yuv420p",
            "-f",
            "mp4",
        ])
        .arg(&tmp)
        .output()
        .map_err(|e| Error::io(&tmp, e))?;
    if !res.status.success() {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::external(
            "ffmpeg",
            format!(
                "making {} failed: {}",
                out.display(),
                String::from_utf8_lossy(&res.stderr).trim()
            ),
        ));
    }
    std::fs::rename(&tmp, &out).map_err(|e| Error::io(&out, e))?;
    Ok(Some(out))
}
