//! Mask clean-up after SAM, as SAM's own automatic mask generator does (`remove_small_regions`):
//! stray islands and pin-hole gaps removed.
//!
//! Why it matters here: every mask votes points into D. A separate blob of wallpaper in fox's
//! clicked view (SAM's answer to one click on the head) put wallpaper points into D, and from
//! there into the prompts of later views. An island that holds no positive prompt and is small
//! next to the mask's main part is such a blob; an object cut in two by an occluder keeps both
//! parts, since each is large or prompted. Tiny holes are decoder speckle (fox's close-ups show a
//! checkerboard of them), not structure; a mug handle's hole is thousands of pixels.

use crate::util::mask::{components, is_object, NO_COMPONENT as NONE};
use glam::DVec2;
use image::GrayImage;

#[derive(Clone, Copy, Debug)]
pub struct CleanOptions {
    /// Islands without a positive prompt smaller than this fraction of the largest island go.
    pub stray_fraction: f64,
    /// Holes (background not connected to the border) smaller than this fraction of the image
    /// are filled.
    pub hole_fraction: f64,
}

impl Default for CleanOptions {
    fn default() -> Self {
        CleanOptions {
            stray_fraction: 0.2,
            hole_fraction: 1e-4,
        }
    }
}

/// Remove stray islands and fill pin-holes in place; `positives` are the view's positive prompts
/// (pixels, corner origin). Returns the number of pixels changed.
pub fn clean_mask(mask: &mut GrayImage, positives: &[DVec2], opts: &CleanOptions) -> usize {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let mut changed = 0;
    // Islands.
    let on: Vec<bool> = mask.pixels().map(|p| is_object(p[0])).collect();
    let (labels, sizes) = components(&on, w, h);
    if sizes.len() > 1 {
        let largest = sizes.iter().copied().max().unwrap_or(0);
        let mut keep: Vec<bool> = sizes
            .iter()
            .map(|&s| s as f64 >= opts.stray_fraction * largest as f64)
            .collect();
        for p in positives {
            let (x, y) = (p.x.floor() as i64, p.y.floor() as i64);
            if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                let l = labels[y as usize * w + x as usize];
                if l != NONE {
                    keep[l as usize] = true;
                }
            }
        }
        for (i, px) in mask.pixels_mut().enumerate() {
            let l = labels[i];
            if l != NONE && !keep[l as usize] {
                px[0] = 0;
                changed += 1;
            }
        }
    }
    // Holes: background islands that do not touch the border.
    let off: Vec<bool> = mask.pixels().map(|p| !is_object(p[0])).collect();
    let (labels, sizes) = components(&off, w, h);
    let mut border = vec![false; sizes.len()];
    for x in 0..w {
        for y in [0, h - 1] {
            if let Some(b) = border.get_mut(labels[y * w + x] as usize) {
                *b = true;
            }
        }
    }
    for y in 0..h {
        for x in [0, w - 1] {
            if let Some(b) = border.get_mut(labels[y * w + x] as usize) {
                *b = true;
            }
        }
    }
    let max_hole = opts.hole_fraction * (w * h) as f64;
    for (i, px) in mask.pixels_mut().enumerate() {
        let l = labels[i];
        if l != NONE && !border[l as usize] && (sizes[l as usize] as f64) < max_hole {
            px[0] = 255;
            changed += 1;
        }
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(m: &mut GrayImage, x0: u32, y0: u32, s: u32, v: u8) {
        for y in y0..y0 + s {
            for x in x0..x0 + s {
                m.put_pixel(x, y, image::Luma([v]));
            }
        }
    }

    #[test]
    fn stray_islands_go_prompted_and_large_ones_stay() {
        let mut m = GrayImage::new(100, 100);
        square(&mut m, 10, 10, 40, 255); // main part, 1600 px
        square(&mut m, 70, 70, 10, 255); // stray, 100 px, no prompt
        square(&mut m, 70, 10, 10, 255); // small but prompted
        square(&mut m, 10, 60, 20, 255); // 400 px = 25% of the main part
        let n = clean_mask(
            &mut m,
            &[DVec2::new(30.0, 30.0), DVec2::new(75.5, 15.5)],
            &CleanOptions::default(),
        );
        assert_eq!(n, 100);
        assert_eq!(m.get_pixel(75, 75)[0], 0);
        assert_eq!(m.get_pixel(75, 15)[0], 255);
        assert_eq!(m.get_pixel(15, 65)[0], 255);
    }

    #[test]
    fn pin_holes_are_filled_and_real_holes_kept() {
        let mut m = GrayImage::new(200, 200);
        square(&mut m, 10, 10, 150, 255);
        square(&mut m, 20, 20, 2, 0); // 4 px speckle
        square(&mut m, 60, 60, 40, 0); // 1600 px: a handle's hole
        let opts = CleanOptions {
            stray_fraction: 0.2,
            hole_fraction: 1e-3, // 40 px
        };
        assert_eq!(clean_mask(&mut m, &[], &opts), 4);
        assert_eq!(m.get_pixel(20, 20)[0], 255);
        assert_eq!(m.get_pixel(70, 70)[0], 0);
        // The background outside touches the border and is never filled.
        assert_eq!(m.get_pixel(190, 190)[0], 0);
    }
}
