//! `objnerf segment-view`: one image, some prompts, a mask PNG and an overlay PNG beside it.

use super::mask::overlay;
use super::prompt::{BoxPrompt, Point, Prompts};
use super::segmenter::{EmbedInfo, Segmenter};
use crate::error::{Error, Result};
use crate::scene::io::read_rgb;
use crate::util::atomic::save_image_atomic;
use image::DynamicImage;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to segment.
#[derive(Clone, Debug)]
pub struct SegmentViewArgs {
    pub image: PathBuf,
    pub points: Vec<Point>,
    pub bbox: Option<BoxPrompt>,
    pub out: PathBuf,
    /// 0 = all available cores.
    pub threads: usize,
}

/// What was done, for `--json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SegmentViewReport {
    pub image: PathBuf,
    pub mask: PathBuf,
    pub overlay: PathBuf,
    pub width: u32,
    pub height: u32,
    pub score: f32,
    pub area: usize,
    pub threads: usize,
    pub load_seconds: f64,
    pub embed: EmbedInfo,
    pub decoder_seconds: f64,
    pub total_seconds: f64,
}

/// `mask.png` -> `mask_overlay.png` in the same folder.
pub fn overlay_path(out: &Path) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mask".into());
    out.with_file_name(format!("{stem}_overlay.png"))
}

/// Segment one image. `open(threads)` loads SAM; it is called only once the image is read and
/// the prompts are checked, so bad input costs no model load.
pub fn segment_view(
    args: &SegmentViewArgs,
    open: impl FnOnce(usize) -> Result<Segmenter>,
) -> Result<SegmentViewReport> {
    let t0 = Instant::now();
    if image::ImageFormat::from_path(&args.out).ok() != Some(image::ImageFormat::Png) {
        return Err(Error::invalid(format!(
            "--out {}: the mask is written as PNG; give a .png path",
            args.out.display()
        )));
    }
    let img = read_rgb(&args.image)?;
    let prompts = Prompts {
        points: args.points.clone(),
        bbox: args.bbox,
        mask_input: None,
    };
    // Check the prompts before paying for the model load and the encoder.
    prompts.validate(img.width(), img.height())?;
    let seg = open(args.threads)?;
    let (emb, embed) = seg.embed_timed(&img)?;
    let mask = seg.predict(&emb, &prompts)?;
    save_image_atomic(&args.out, &DynamicImage::ImageLuma8(mask.to_image()))?;
    let ov = overlay_path(&args.out);
    save_image_atomic(
        &ov,
        &DynamicImage::ImageRgb8(overlay(&img, &mask, &prompts)),
    )?;
    Ok(SegmentViewReport {
        image: args.image.clone(),
        mask: args.out.clone(),
        overlay: ov,
        width: img.width(),
        height: img.height(),
        score: mask.score,
        area: mask.area(),
        threads: seg.threads(),
        load_seconds: seg.load_seconds,
        embed,
        decoder_seconds: mask.decoder_seconds,
        total_seconds: t0.elapsed().as_secs_f64(),
    })
}
