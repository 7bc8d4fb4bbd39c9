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
}
