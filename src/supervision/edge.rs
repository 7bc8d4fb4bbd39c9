//! The band along a segmenter's mask edges. SAM's masks are right to within a pixel or two at
//! best, and not at random: on the demo scene they stop two rows short of the mug's base in
//! every view (its contact shadow reads as floor), so a field that takes them as exact alpha
//! learns a mug without a base. Pixels within a few pixels of a mask's edge are therefore
//! trained on the photo itself, rendered over the background behind the object as estimated
//! from the pixels around the mask (harmonic inpainting of the photo), so whether the object
//! covers such a pixel is decided by its colour and by the other views; the mask's alpha stays
//! there only as the usual weak alpha term. Dropping that term too (tried) let the field grow a
//! floor-coloured fringe wherever the floor's texture departs from the smooth estimate.

use crate::error::{Error, Result};
use crate::field::view::{downscale_premultiplied, EdgePixel, View};
use crate::scene::io::read_image;
use crate::scene::Scene;
use crate::util::inpaint::inpaint_harmonic;
use crate::util::mask::{dilate_bits, MASK_THRESHOLD};
use rayon::prelude::*;

/// Give every view of `views` (the scene's images by name, downscaled by `factor`, masks as
/// alpha) the edge band of its mask, `band` pixels either side of the edge. Views whose mask is
/// empty or covers the whole frame get none. Returns the number of band pixels.
pub fn add_edge_bands(views: &mut [View], scene: &Scene, factor: u32, band: u32) -> Result<usize> {
    if band == 0 {
        return Ok(0);
    }
    let paths: std::collections::HashMap<&str, &std::path::Path> = scene
        .images
        .iter()
        .map(|im| (im.name.as_str(), im.path.as_path()))
        .collect();
    views
        .par_iter_mut()
        .map(|v| {
            let path = paths.get(v.name.as_str()).ok_or_else(|| {
                Error::invalid(format!("view {} is not an image of the scene", v.name))
            })?;
            let photo = read_image(path)?.to_rgba8();
            let (w, h, photo) = downscale_premultiplied(&photo, factor.max(1));
            if (w, h) != (v.width, v.height) {
                return Err(Error::format(
                    path,
                    format!(
                        "image is {w}x{h} after downscaling but its view is {}x{}",
                        v.width, v.height
                    ),
                ));
            }
            let mask: Vec<bool> = v.rgba.iter().map(|p| p[3] > MASK_THRESHOLD).collect();
            let rgb: Vec<[u8; 3]> = photo.iter().map(|p| [p[0], p[1], p[2]]).collect();
            v.edge = edge_band(&mask, &rgb, [w as usize, h as usize], band as usize);
            Ok(v.edge.len())
        })
        .sum()
}

/// The band of pixels within `band` of the edge of `mask` (both sides), sorted by pixel index,
/// each with its colour in `rgb` and the colour the photo has when the mask (grown by one more
/// pixel) is filled from around it.
pub fn edge_band(
    mask: &[bool],
    rgb: &[[u8; 3]],
    [w, h]: [usize; 2],
    band: usize,
) -> Vec<EdgePixel> {
    let inside = mask.iter().filter(|&&m| m).count();
    if inside == 0 || inside == mask.len() {
        return vec![];
    }
    let outside: Vec<bool> = mask.iter().map(|&m| !m).collect();
    let grown = dilate_bits(mask, [w, h], band);
    let shrunk_away = dilate_bits(&outside, [w, h], band);
    let hidden = dilate_bits(mask, [w, h], band + 1);
    let known: Vec<bool> = hidden.iter().map(|&u| !u).collect();
    let mut backdrop: Vec<f32> = rgb.iter().flat_map(|p| p.map(f32::from)).collect();
    if !inpaint_harmonic(&mut backdrop, &known, w, h, 3) {
        return vec![];
    }
    // Sure object: inside and away from the edge; sure background: beyond the outer band.
    let sure: Vec<Option<bool>> = (0..w * h)
        .map(|i| match (mask[i], shrunk_away[i], grown[i]) {
            (true, false, _) => Some(true),
            (false, _, false) => Some(false),
            _ => None,
        })
        .collect();
    (0..w * h)
        .filter(|&i| sure[i].is_none() && looks_like(i, !mask[i], rgb, &sure, [w, h], band + 2))
        .map(|i| EdgePixel {
            px: i as u32,
            photo: rgb[i],
            backdrop: [0, 1, 2].map(|c| backdrop[3 * i + c].round().clamp(0.0, 255.0) as u8),
        })
        .collect()
}

/// Whether pixel `i`'s colour is nearer the colours of the sure object (`object`) or of the sure
/// background (else) within `radius` than of the other side: only band pixels whose colour
/// argues against their mask are left for the colour to decide (a floor-coloured pixel beside
/// the object keeps its zero alpha, so the floor's texture cannot grow a fringe on it).
fn looks_like(
    i: usize,
    object: bool,
    rgb: &[[u8; 3]],
    sure: &[Option<bool>],
    [w, h]: [usize; 2],
    radius: usize,
) -> bool {
    let (x, y) = (i % w, i / w);
    let dist = |a: [u8; 3], b: [u8; 3]| -> u32 {
        (0..3)
            .map(|c| (a[c] as i32 - b[c] as i32).unsigned_abs().pow(2))
            .sum()
    };
    let mut nearest = [u32::MAX; 2];
    for yy in y.saturating_sub(radius)..(y + radius + 1).min(h) {
        for xx in x.saturating_sub(radius)..(x + radius + 1).min(w) {
            let j = yy * w + xx;
            if let Some(side) = sure[j] {
                let d = dist(rgb[i], rgb[j]);
                let k = side as usize;
                nearest[k] = nearest[k].min(d);
            }
        }
    }
    let (mine, other) = if object {
        (nearest[1], nearest[0])
    } else {
        (nearest[0], nearest[1])
    };
    mine < other
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_keeps_the_pixels_whose_colour_argues_against_their_mask() {
        // A 20x20 grey (100) frame with a red 6x6 square at x, y 7..13, whose mask misses the
        // square's bottom row (y = 12) and wrongly holds a grey column at x = 13.
        let (w, h) = (20, 20);
        let red = |x: usize, y: usize| (7..13).contains(&x) && (7..13).contains(&y);
        let masked = |x: usize, y: usize| (7..14).contains(&x) && (7..12).contains(&y);
        let rgb: Vec<[u8; 3]> = (0..w * h)
            .map(|i| match red(i % w, i / w) {
                true => [200, 0, 0],
                false => [100, 100, 100],
            })
            .collect();
        let mask: Vec<bool> = (0..w * h).map(|i| masked(i % w, i / w)).collect();
        let band = edge_band(&mask, &rgb, [w, h], 2);
        let at = |x: usize, y: usize| band.iter().find(|e| e.px as usize == y * w + x);
        for x in 7..13 {
            let e = at(x, 12).expect("the missed red row is left to the colour");
            assert_eq!(e.photo, [200, 0, 0]);
            assert_eq!(e.backdrop, [100, 100, 100], "the surround, not the square");
        }
        for y in 7..12 {
            assert!(at(13, y).is_some(), "the grey column wrongly in the mask");
            assert!(
                at(14, y).is_none(),
                "grey outside the mask stays background"
            );
        }
        assert!(
            at(9, 9).is_none() && at(7, 8).is_none(),
            "red inside stays object"
        );
        assert!(at(8, 13).is_none(), "grey below stays background");
        assert!(band.windows(2).all(|p| p[0].px < p[1].px), "sorted");
        assert!(edge_band(&vec![false; w * h], &rgb, [w, h], 2).is_empty());
        assert!(edge_band(&vec![true; w * h], &rgb, [w, h], 2).is_empty());
    }
}
