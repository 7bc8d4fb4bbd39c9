//! A predicted mask and the overlay picture `segment-view` writes beside it.

use super::prompt::{Prompts, LOW_RES};
use image::{GrayImage, Luma, Rgb, RgbImage};

/// SAM's answer for one prompt set.
#[derive(Clone, Debug)]
pub struct Mask {
    pub width: u32,
    pub height: u32,
    /// Row-major, `width * height`: true = object (logit > 0).
    pub bitmap: Vec<bool>,
    /// The decoder's logits at the original size (same layout as `bitmap`).
    pub logits: Vec<f32>,
    /// SAM's predicted IoU for this mask.
    pub score: f32,
    /// 256 x 256 logits: pass to [`Prompts::with_mask_input`] to refine with more clicks.
    pub low_res: Vec<f32>,
    /// Decoder wall time, seconds.
    pub decoder_seconds: f64,
}

impl Mask {
    pub fn area(&self) -> usize {
        self.bitmap.iter().filter(|&&b| b).count()
    }
    pub fn is_empty(&self) -> bool {
        !self.bitmap.iter().any(|&b| b)
    }
    /// 255 = object, 0 = background.
    pub fn to_image(&self) -> GrayImage {
        GrayImage::from_fn(self.width, self.height, |x, y| {
            Luma([if self.bitmap[(y * self.width + x) as usize] {
                255
            } else {
                0
            }])
        })
    }
    /// IoU with another bitmap of the same size.
    pub fn iou(&self, other: &[bool]) -> f64 {
        crate::util::mask::iou_bits(self.bitmap.iter().copied(), other.iter().copied())
    }
    /// The low-res logits as prompts' mask input, for refinement.
    pub fn low_res_input(&self) -> Vec<f32> {
        debug_assert_eq!(self.low_res.len(), LOW_RES * LOW_RES);
        self.low_res.clone()
    }
}

/// The image with the mask tinted, its outline drawn, and the prompts marked (object points
/// green, background points red, the box blue), so a person can check a mask at a glance.
pub fn overlay(img: &RgbImage, mask: &Mask, prompts: &Prompts) -> RgbImage {
    let (w, h) = img.dimensions();
    let mut out = img.clone();
    let tint = [30.0f32, 144.0, 255.0];
    let at = |x: u32, y: u32| mask.bitmap[(y * w + x) as usize];
    for y in 0..h {
        for x in 0..w {
            if !at(x, y) {
                continue;
            }
            let edge = x == 0
                || y == 0
                || x + 1 == w
                || y + 1 == h
                || !at(x - 1, y)
                || !at(x + 1, y)
                || !at(x, y - 1)
                || !at(x, y + 1);
            let p = out.get_pixel_mut(x, y);
            if edge {
                *p = Rgb([255, 255, 0]);
            } else {
                for c in 0..3 {
                    p[c] = (0.5 * p[c] as f32 + 0.5 * tint[c]).round() as u8;
                }
            }
        }
    }
    let r = (w.max(h) as f32 / 150.0).max(3.0);
    if let Some([x0, y0, x1, y1]) = prompts.bbox {
        let t = (r / 2.0).max(1.0);
        draw_rect(&mut out, x0, y0, x1, y1, t, Rgb([40, 80, 255]));
    }
    for p in &prompts.points {
        let colour = if p.positive {
            Rgb([0, 220, 0])
        } else {
            Rgb([230, 0, 0])
        };
        draw_disc(&mut out, p.x, p.y, r + 1.5, Rgb([255, 255, 255]));
        draw_disc(&mut out, p.x, p.y, r, colour);
    }
    out
}

fn draw_disc(img: &mut RgbImage, cx: f32, cy: f32, r: f32, c: Rgb<u8>) {
    let (w, h) = img.dimensions();
    let x0 = (cx - r).floor().max(0.0) as u32;
    let y0 = (cy - r).floor().max(0.0) as u32;
    let x1 = ((cx + r).ceil() as u32).min(w);
    let y1 = ((cy + r).ceil() as u32).min(h);
    for y in y0..y1 {
        for x in x0..x1 {
            let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
            if dx * dx + dy * dy <= r * r {
                img.put_pixel(x, y, c);
            }
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn draw_rect(img: &mut RgbImage, x0: f32, y0: f32, x1: f32, y1: f32, t: f32, c: Rgb<u8>) {
    let (w, h) = img.dimensions();
    for y in 0..h {
        for x in 0..w {
            let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
            let inside_outer = px >= x0 - t && px <= x1 + t && py >= y0 - t && py <= y1 + t;
            let inside_inner = px > x0 + t && px < x1 - t && py > y0 + t && py < y1 - t;
            if inside_outer && !inside_inner {
                img.put_pixel(x, y, c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlay_marks_prompts() {
        let img = RgbImage::from_pixel(20, 10, Rgb([0, 0, 0]));
        let mut bitmap = vec![false; 200];
        for y in 2..8 {
            for x in 2..8 {
                bitmap[y * 20 + x] = true;
            }
        }
        let m = Mask {
            width: 20,
            height: 10,
            bitmap,
            logits: vec![0.0; 200],
            score: 1.0,
            low_res: vec![0.0; LOW_RES * LOW_RES],
            decoder_seconds: 0.0,
        };
        let o = overlay(&img, &m, &Prompts::click(15.5, 5.5));
        assert_eq!(*o.get_pixel(15, 5), Rgb([0, 220, 0]));
        assert_eq!(*o.get_pixel(2, 2), Rgb([255, 255, 0]));
        assert_ne!(*o.get_pixel(4, 4), Rgb([0, 0, 0]));
        assert_eq!(m.to_image().get_pixel(3, 3)[0], 255);
    }
}
