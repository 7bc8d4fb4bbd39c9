//! Binary masks stored as 8-bit images: the one threshold that says which pixels are the object,
//! and the overlap measures every stage scores masks with.

use crate::util::lattice::face_neighbours;
use image::GrayImage;

/// A mask pixel above this is the object. Masks objnerf writes are 0/255; soft masks and alpha
/// channels are cut at half.
pub const MASK_THRESHOLD: u8 = 127;

/// Whether an 8-bit mask value is the object.
#[inline]
pub fn is_object(v: u8) -> bool {
    v > MASK_THRESHOLD
}

/// Intersection over union of two equally long bitmaps; 1.0 when both are empty (two empty
/// masks agree).
pub fn iou_bits(a: impl IntoIterator<Item = bool>, b: impl IntoIterator<Item = bool>) -> f64 {
    let (mut inter, mut union) = (0u64, 0u64);
    for (x, y) in a.into_iter().zip(b) {
        inter += (x && y) as u64;
        union += (x || y) as u64;
    }
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

/// [`iou_bits`] of two masks of the same size.
pub fn iou(a: &GrayImage, b: &GrayImage) -> f64 {
    iou_bits(
        a.pixels().map(|p| is_object(p[0])),
        b.pixels().map(|p| is_object(p[0])),
    )
}

/// |a ∩ b| / |b|: how much of `b` the mask `a` covers; 0 when `b` is empty.
pub fn coverage(a: &GrayImage, b: &GrayImage) -> f64 {
    let (mut inter, mut total) = (0u64, 0u64);
    for (pa, pb) in a.pixels().zip(b.pixels()) {
        if is_object(pb[0]) {
            total += 1;
            inter += is_object(pa[0]) as u64;
        }
    }
    if total == 0 {
        0.0
    } else {
        inter as f64 / total as f64
    }
}

/// Pixels that are the object.
pub fn area(m: &GrayImage) -> usize {
    m.pixels().filter(|p| is_object(p[0])).count()
}

/// The label [`components`] gives pixels that are off.
pub const NO_COMPONENT: u32 = u32::MAX;

/// 4-connected components of the `true` pixels of a row-major `w` x `h` image: a label per pixel
/// ([`NO_COMPONENT`] where false) and each label's size.
pub fn components(on: &[bool], w: usize, h: usize) -> (Vec<u32>, Vec<usize>) {
    let mut labels = vec![NO_COMPONENT; on.len()];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for start in 0..on.len() {
        if !on[start] || labels[start] != NO_COMPONENT {
            continue;
        }
        let l = sizes.len() as u32;
        let mut size = 0;
        labels[start] = l;
        stack.push(start);
        while let Some(i) = stack.pop() {
            size += 1;
            face_neighbours(i, [w, h, 1], |j| {
                if on[j] && labels[j] == NO_COMPONENT {
                    labels[j] = l;
                    stack.push(j);
                }
            });
        }
        sizes.push(size);
    }
    (labels, sizes)
}

/// The mask grown by `radius` pixels (a square neighbourhood; separable max filter), as 0/255.
pub fn dilate(m: &GrayImage, radius: u32) -> GrayImage {
    let (w, h) = m.dimensions();
    let on: Vec<bool> = m.pixels().map(|p| is_object(p[0])).collect();
    let out = dilate_bits(&on, [w as usize, h as usize], radius as usize);
    GrayImage::from_raw(w, h, out.iter().map(|&b| if b { 255 } else { 0 }).collect())
        .expect("one value per pixel")
}

/// Square dilation of a row-major boolean image of `[w, h]` pixels: on where an on pixel lies
/// within `radius` in x and y. Two passes (rows, then columns), each O(pixels) whatever the
/// radius.
pub fn dilate_bits(on: &[bool], [w, h]: [usize; 2], radius: usize) -> Vec<bool> {
    let rows = dilate_lines(on, [w, h], radius, 1, w);
    dilate_lines(&rows, [h, w], radius, w, 1)
}

/// One pass of [`dilate_bits`]: `lines` lines of `len` samples, sample `k` of line `l` at
/// `l * line_step + k * step`.
fn dilate_lines(
    on: &[bool],
    [len, lines]: [usize; 2],
    radius: usize,
    step: usize,
    line_step: usize,
) -> Vec<bool> {
    let mut out = vec![false; on.len()];
    for l in 0..lines {
        let at = |k: usize| l * line_step + k * step;
        // Forward then backward: a sample is on when an on sample lies within the radius.
        let mut last_on: Option<usize> = None;
        for k in 0..len {
            if on[at(k)] {
                last_on = Some(k);
            }
            out[at(k)] = last_on.is_some_and(|j| k - j <= radius);
        }
        let mut next_on: Option<usize> = None;
        for k in (0..len).rev() {
            if on[at(k)] {
                next_on = Some(k);
            }
            if next_on.is_some_and(|j| j - k <= radius) {
                out[at(k)] = true;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iou_and_coverage() {
        assert_eq!(iou_bits([true, true, false], [true, false, false]), 0.5);
        assert_eq!(iou_bits([false], [false]), 1.0);
        let a = GrayImage::from_raw(4, 1, vec![255, 255, 0, 0]).unwrap();
        let b = GrayImage::from_raw(4, 1, vec![255, 0, 0, 128]).unwrap();
        assert!((iou(&a, &b) - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(coverage(&a, &b), 0.5);
        assert_eq!(area(&b), 2);
        assert_eq!(coverage(&a, &GrayImage::new(4, 1)), 0.0);
        assert_eq!(iou(&GrayImage::new(2, 2), &GrayImage::new(2, 2)), 1.0);
    }

    #[test]
    fn dilation_grows_by_the_radius() {
        let mut m = GrayImage::new(9, 7);
        m.put_pixel(4, 3, image::Luma([255]));
        let d = dilate(&m, 2);
        assert_eq!(area(&d), 25);
        assert!(is_object(d.get_pixel(2, 1)[0]) && is_object(d.get_pixel(6, 5)[0]));
        assert!(!is_object(d.get_pixel(1, 3)[0]) && !is_object(d.get_pixel(4, 6)[0]));
        assert_eq!(dilate(&m, 0), m);
    }

    /// The two-pass dilation equals the definition (any on pixel in the square) on a
    /// non-square image with pixels at the borders.
    #[test]
    fn dilate_bits_matches_the_square_neighbourhood() {
        let (w, h) = (13usize, 6usize);
        let mut rng = crate::util::Rng::new(3);
        let on: Vec<bool> = (0..w * h).map(|_| rng.f32() < 0.08).collect();
        for r in [0usize, 1, 3] {
            let fast = dilate_bits(&on, [w, h], r);
            for y in 0..h {
                for x in 0..w {
                    let want = (y.saturating_sub(r)..=(y + r).min(h - 1)).any(|yy| {
                        (x.saturating_sub(r)..=(x + r).min(w - 1)).any(|xx| on[yy * w + xx])
                    });
                    assert_eq!(fast[y * w + x], want, "r {r} at ({x}, {y})");
                }
            }
        }
    }
}
