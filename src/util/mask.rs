//! Binary masks stored as 8-bit images: the one threshold that says which pixels are the object,
//! and the overlap measures every stage scores masks with.

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

/// The mask grown by `radius` pixels (a square neighbourhood; separable max filter), as 0/255.
pub fn dilate(m: &GrayImage, radius: u32) -> GrayImage {
    let (w, h) = m.dimensions();
    let r = radius as i64;
    let on: Vec<bool> = m.pixels().map(|p| is_object(p[0])).collect();
    let mut rows = vec![false; on.len()];
    for y in 0..h as i64 {
        let mut last_on = i64::MIN / 2;
        // Left to right, then right to left: a pixel is on when an on pixel lies within r.
        for x in 0..w as i64 {
            if on[(y * w as i64 + x) as usize] {
                last_on = x;
            }
            rows[(y * w as i64 + x) as usize] = x - last_on <= r;
        }
        let mut next_on = i64::MAX / 2;
        for x in (0..w as i64).rev() {
            if on[(y * w as i64 + x) as usize] {
                next_on = x;
            }
            let i = (y * w as i64 + x) as usize;
            rows[i] = rows[i] || next_on - x <= r;
        }
    }
    let mut out = GrayImage::new(w, h);
    for x in 0..w as i64 {
        let mut last_on = i64::MIN / 2;
        let mut col = vec![false; h as usize];
        for y in 0..h as i64 {
            if rows[(y * w as i64 + x) as usize] {
                last_on = y;
            }
            col[y as usize] = y - last_on <= r;
        }
        let mut next_on = i64::MAX / 2;
        for y in (0..h as i64).rev() {
            if rows[(y * w as i64 + x) as usize] {
                next_on = y;
            }
            if col[y as usize] || next_on - y <= r {
                out.put_pixel(x as u32, y as u32, image::Luma([255]));
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
}
