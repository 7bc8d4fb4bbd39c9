//! The encoder's input, exactly as SAM prepares it: resize so the longest side is 1024
//! (bilinear, as torchvision's resize on a PIL image), normalise each channel with ImageNet's mean
//! and std on 0..255 values, and zero-pad right and bottom to 1024 x 1024.

use image::{imageops::FilterType, RgbImage};

/// SAM's input side.
pub const INPUT_SIZE: u32 = 1024;
const MEAN: [f32; 3] = [123.675, 116.28, 103.53];
const STD: [f32; 3] = [58.395, 57.12, 57.375];

/// The resized size and the scale (resized / original) for an image of `w` x `h`: SAM's
/// `get_preprocess_shape` (`floor(side * 1024 / longest + 0.5)`). The decoder computes the same
/// size from `orig_im_size` to crop its masks, so the two must agree.
pub fn resized_size(w: u32, h: u32) -> (u32, u32, f64) {
    let scale = INPUT_SIZE as f64 / w.max(h) as f64;
    let nw = ((w as f64 * scale + 0.5).floor() as u32).clamp(1, INPUT_SIZE);
    let nh = ((h as f64 * scale + 0.5).floor() as u32).clamp(1, INPUT_SIZE);
    (nw, nh, scale)
}

/// The normalised, padded 1 x 3 x 1024 x 1024 tensor (CHW, row-major), and the scale.
pub fn encoder_input(img: &RgbImage) -> (Vec<f32>, f64) {
    let (w, h) = img.dimensions();
    let (nw, nh, scale) = resized_size(w, h);
    let resized;
    let src = if (nw, nh) == (w, h) {
        img
    } else {
        resized = image::imageops::resize(img, nw, nh, FilterType::Triangle);
        &resized
    };
    let n = (INPUT_SIZE * INPUT_SIZE) as usize;
    let mut out = vec![0f32; 3 * n];
    let (r, rest) = out.split_at_mut(n);
    let (g, b) = rest.split_at_mut(n);
    for (y, row) in src.rows().enumerate() {
        let base = y * INPUT_SIZE as usize;
        for (x, p) in row.enumerate() {
            r[base + x] = (p[0] as f32 - MEAN[0]) / STD[0];
            g[base + x] = (p[1] as f32 - MEAN[1]) / STD[1];
            b[base + x] = (p[2] as f32 - MEAN[2]) / STD[2];
        }
    }
    (out, scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes() {
        assert_eq!(resized_size(800, 800), (1024, 1024, 1.28));
        let (w, h, _) = resized_size(1500, 2250);
        assert_eq!((w, h), (683, 1024));
        let (w, h, _) = resized_size(640, 480);
        assert_eq!((w, h), (1024, 768));
    }

    #[test]
    fn normalised_and_padded() {
        let img = RgbImage::from_pixel(4, 2, image::Rgb([124, 116, 104]));
        let (t, s) = encoder_input(&img);
        assert_eq!(s, 256.0);
        assert_eq!(t.len(), 3 * 1024 * 1024);
        // Inside: near zero (the pixel is the mean); the padding is exactly zero.
        assert!(t[0].abs() < 0.01);
        assert!(t[511 * 1024 + 1023].abs() < 0.01);
        assert!(t[512 * 1024].abs() < 0.01);
        assert!(t[600 * 1024 + 3] == 0.0);
    }
}
