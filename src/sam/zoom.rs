//! Zoom-in refinement for small objects. SAM's masks come from a 256 x 256 grid over the padded
//! 1024 frame, so an object a few dozen pixels wide is drawn with a handful of cells and its edges
//! are coarse (on the 320 x 240 demo scene one click on the mug gives IoU 0.90, the same in Python
//! onnxruntime). Re-running SAM on a crop around the first mask gives the object ~10x more cells.
//! It costs one more encoder pass per small object (cached by the crop's content like any image),
//! so it is opt-in.

use super::mask::Mask;
use super::prompt::{Point, Prompts};
use super::segmenter::Segmenter;
use crate::error::Result;
use image::RgbImage;

/// When and how much to zoom.
#[derive(Clone, Copy, Debug)]
pub struct ZoomOptions {
    /// Zoom only when the first mask's box is at most this fraction of the image's longest side.
    pub max_fraction: f64,
    /// The crop is the mask's box grown by this many box sizes on every side (1.0: 3x the box),
    /// enough context for SAM to tell the object from its surroundings.
    pub margin: f64,
    /// Smallest crop side in pixels.
    pub min_side: u32,
}

impl Default for ZoomOptions {
    fn default() -> Self {
        ZoomOptions {
            max_fraction: 1.0 / 3.0,
            margin: 1.0,
            min_side: 32,
        }
    }
}

impl Segmenter {
    /// Segment `img` with `prompts`, then, if the mask is small, again on a crop around it with
    /// the same points and the first mask's box (or the caller's box) as a box prompt: without a
    /// box a click in the zoomed view tends to pick a texture patch instead of the object.
    /// Returns the first mask when no zoom is needed or the zoomed mask comes back empty.
    pub fn segment_zoomed(
        &self,
        img: &RgbImage,
        prompts: &Prompts,
        opts: &ZoomOptions,
    ) -> Result<Mask> {
        let emb = self.embed(img)?;
        let first = self.predict(&emb, prompts)?;
        let (w, h) = (first.width, first.height);
        let Some((bx0, by0, bx1, by1)) = bbox(&first) else {
            return Ok(first);
        };
        let side = (bx1 - bx0).max(by1 - by0) as f64;
        if side > opts.max_fraction * w.max(h) as f64 {
            return Ok(first);
        }
        let crop_side = (side * (1.0 + 2.0 * opts.margin)).max(opts.min_side as f64);
        let (cx, cy) = ((bx0 + bx1) as f64 / 2.0, (by0 + by1) as f64 / 2.0);
        let x0 = (cx - crop_side / 2.0).floor().max(0.0) as u32;
        let y0 = (cy - crop_side / 2.0).floor().max(0.0) as u32;
        let x1 = ((cx + crop_side / 2.0).ceil() as u32).min(w);
        let y1 = ((cy + crop_side / 2.0).ceil() as u32).min(h);
        let crop = image::imageops::crop_imm(img, x0, y0, x1 - x0, y1 - y0).to_image();
        let (fx, fy) = (x0 as f32, y0 as f32);
        let (cw, ch) = ((x1 - x0) as f32, (y1 - y0) as f32);
        let points: Vec<Point> = prompts
            .points
            .iter()
            .map(|p| Point {
                x: p.x - fx,
                y: p.y - fy,
                positive: p.positive,
            })
            .filter(|p| (0.0..=cw).contains(&p.x) && (0.0..=ch).contains(&p.y))
            .collect();
        let b = prompts
            .bbox
            .unwrap_or([bx0 as f32, by0 as f32, bx1 as f32, by1 as f32]);
        let cb = [
            (b[0] - fx).clamp(0.0, cw),
            (b[1] - fy).clamp(0.0, ch),
            (b[2] - fx).clamp(0.0, cw),
            (b[3] - fy).clamp(0.0, ch),
        ];
        let zp = Prompts {
            points,
            bbox: (cb[2] > cb[0] && cb[3] > cb[1]).then_some(cb),
            mask_input: None,
        };
        let cemb = self.embed(&crop)?;
        let zoomed = self.predict_allow_empty(&cemb, &zp)?;
        if zoomed.is_empty() {
            return Ok(first);
        }
        // Paste the crop's answer into a full-size mask; outside the crop the first mask's logits
        // remain (its pixels there are background: the crop contains the first mask's box).
        let mut out = first.clone();
        out.bitmap.iter_mut().for_each(|b| *b = false);
        for y in 0..(y1 - y0) {
            for x in 0..(x1 - x0) {
                let src = (y * (x1 - x0) + x) as usize;
                let dst = ((y + y0) * w + x + x0) as usize;
                out.bitmap[dst] = zoomed.bitmap[src];
                out.logits[dst] = zoomed.logits[src];
            }
        }
        out.score = zoomed.score;
        out.decoder_seconds += zoomed.decoder_seconds;
        Ok(out)
    }
}

/// The mask's bounding box as pixel-corner coordinates (x0, y0, x1, y1), or None if empty.
pub fn bbox(m: &Mask) -> Option<(u32, u32, u32, u32)> {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (i, _) in m.bitmap.iter().enumerate().filter(|(_, &b)| b) {
        let (x, y) = (i as u32 % m.width, i as u32 / m.width);
        x0 = x0.min(x);
        y0 = y0.min(y);
        x1 = x1.max(x + 1);
        y1 = y1.max(y + 1);
    }
    (x1 > 0).then_some((x0, y0, x1, y1))
}
