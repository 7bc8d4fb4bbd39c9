//! Reading and writing the per-view rasters a scene refers to: colour images, masks and depth maps.

use crate::error::{Error, Result};
use crate::util::atomic::{save_image_atomic, write_bytes_atomic};
use image::{DynamicImage, GrayImage, ImageBuffer, Luma};
use std::path::Path;

/// A depth map in metres; 0 (or non-finite) means unknown.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthMap {
    pub width: u32,
    pub height: u32,
    /// Row-major, `width * height` values.
    pub metres: Vec<f32>,
}

impl DepthMap {
    /// Depth at pixel (col, row), `None` when unknown.
    pub fn get(&self, col: u32, row: u32) -> Option<f32> {
        let d = *self
            .metres
            .get((row as usize) * self.width as usize + col as usize)?;
        (d.is_finite() && d > 0.0).then_some(d)
    }
}

fn is_exr(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

/// Read a depth image: a 16-bit PNG storing depth * `scale` (millimetres: scale = 1000, 0 =
/// unknown), or an EXR storing metres (the R, Y or Z channel, else the first one; `scale` unused).
pub fn read_depth(path: &Path, scale: f64) -> Result<DepthMap> {
    if is_exr(path) {
        return read_depth_exr(path);
    }
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::invalid(format!(
            "{}: depth scale must be positive, got {scale}",
            path.display()
        )));
    }
    let img = image::open(path).map_err(|e| Error::image(path, e))?;
    let (width, height) = (img.width(), img.height());
    let raw: Vec<u16> = match img {
        DynamicImage::ImageLuma16(b) => b.into_raw(),
        DynamicImage::ImageLumaA16(b) => b.pixels().map(|p| p.0[0]).collect(),
        other => {
            return Err(Error::format(
                path,
                format!(
                    "depth images must be 16-bit single-channel PNGs (depth x {scale}) or EXR, this one is {:?}",
                    other.color()
                ),
            ))
        }
    };
    let inv = 1.0 / scale;
    let metres = raw.iter().map(|&v| (v as f64 * inv) as f32).collect();
    Ok(DepthMap {
        width,
        height,
        metres,
    })
}

fn read_depth_exr(path: &Path) -> Result<DepthMap> {
    use exr::prelude::{FlatSamples, ReadChannels, ReadLayers};
    let bad = |e: exr::error::Error| Error::format(path, format!("cannot read EXR depth: {e}"));
    let img = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(bad)?;
    let layer = img.layer_data;
    let channels = &layer.channel_data.list;
    // Channels are stored sorted by name, so "first" would be B for an RGB file: prefer the names
    // depth tools use.
    let chan = ["R", "Y", "Z", "depth", "D"]
        .iter()
        .find_map(|n| channels.iter().find(|c| c.name.eq(n)))
        .or_else(|| channels.first())
        .ok_or_else(|| Error::format(path, "EXR depth has no channels"))?;
    let metres: Vec<f32> = match &chan.sample_data {
        FlatSamples::F16(v) => v.iter().map(|x| x.to_f32()).collect(),
        FlatSamples::F32(v) => v.clone(),
        FlatSamples::U32(v) => v.iter().map(|&x| x as f32).collect(),
    };
    let (w, h) = (layer.size.width(), layer.size.height());
    if metres.len() != w * h {
        return Err(Error::format(
            path,
            "EXR depth channel size does not match the image",
        ));
    }
    Ok(DepthMap {
        width: w as u32,
        height: h as u32,
        metres,
    })
}

/// Millimetres as a 16-bit PNG would store them: 0 for unknown, non-positive or out of range
/// (beyond 65.535 m) depths, since a clamped value would be a wrong depth rather than no depth.
fn to_mm(d: f32) -> u16 {
    let mm = (d as f64 * 1000.0).round();
    if d.is_finite() && mm >= 1.0 && mm <= u16::MAX as f64 {
        mm as u16
    } else {
        0
    }
}

fn check_len(path: &Path, depth: &DepthMap) -> Result<()> {
    if depth.metres.len() != depth.width as usize * depth.height as usize {
        return Err(Error::invalid(format!(
            "{}: depth map has {} values for {}x{} pixels",
            path.display(),
            depth.metres.len(),
            depth.width,
            depth.height
        )));
    }
    Ok(())
}

/// Write a depth map as a 16-bit PNG in millimetres (0 = unknown), atomically.
pub fn write_depth_png_mm(path: &Path, depth: &DepthMap) -> Result<()> {
    check_len(path, depth)?;
    let raw: Vec<u16> = depth.metres.iter().map(|&d| to_mm(d)).collect();
    let buf: ImageBuffer<Luma<u16>, Vec<u16>> =
        ImageBuffer::from_raw(depth.width, depth.height, raw)
            .ok_or_else(|| Error::invalid("depth buffer size mismatch"))?;
    save_image_atomic(path, &DynamicImage::ImageLuma16(buf))
}

/// Write a depth map as a one-channel ("Y") 32-bit float EXR in metres (0 = unknown), atomically.
pub fn write_depth_exr(path: &Path, depth: &DepthMap) -> Result<()> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec,
        WritableImage,
    };
    check_len(path, depth)?;
    let values = depth
        .metres
        .iter()
        .map(|&d| if d.is_finite() && d > 0.0 { d } else { 0.0 })
        .collect();
    let channel = AnyChannel::new("Y", FlatSamples::F32(values));
    let layer = Layer::new(
        (depth.width as usize, depth.height as usize),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    let mut buf = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut buf)
        .map_err(|e| Error::format(path, format!("cannot encode EXR depth: {e}")))?;
    write_bytes_atomic(path, buf.get_ref())
}

/// Read a mask as one 8-bit channel, object where > 127: the alpha channel of images that have
/// one (an RGBA cut-out), else the luma.
pub fn read_mask(path: &Path) -> Result<GrayImage> {
    let img = image::open(path).map_err(|e| Error::image(path, e))?;
    if img.color().has_alpha() {
        let rgba = img.to_rgba8();
        let (w, h) = rgba.dimensions();
        let alpha = rgba.pixels().map(|p| p.0[3]).collect();
        return GrayImage::from_raw(w, h, alpha)
            .ok_or_else(|| Error::format(path, "mask size mismatch"));
    }
    Ok(img.to_luma8())
}

/// Read a colour image as 8-bit RGB.
pub fn read_rgb(path: &Path) -> Result<image::RgbImage> {
    let img = image::open(path).map_err(|e| Error::image(path, e))?;
    Ok(img.to_rgb8())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> DepthMap {
        DepthMap {
            width: 3,
            height: 2,
            metres: vec![0.0, 0.5, 1.234, 2.0, 65.535, 70.0],
        }
    }

    #[test]
    fn png_mm_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.png");
        write_depth_png_mm(&p, &sample()).unwrap();
        let d = read_depth(&p, 1000.0).unwrap();
        assert_eq!((d.width, d.height), (3, 2));
        assert_eq!(d.metres, vec![0.0, 0.5, 1.234, 2.0, 65.535, 0.0]);
        assert_eq!(d.get(0, 0), None);
        assert_eq!(d.get(1, 0), Some(0.5));
    }

    #[test]
    fn exr_round_trip_and_8bit_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.exr");
        write_depth_exr(&p, &sample()).unwrap();
        assert_eq!(read_depth(&p, 1000.0).unwrap(), sample());
        let q = dir.path().join("d8.png");
        GrayImage::new(2, 2).save(&q).unwrap();
        assert!(read_depth(&q, 1000.0)
            .unwrap_err()
            .to_string()
            .contains("16-bit"));
    }

    #[test]
    fn rgb_exr_reads_the_red_channel() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("rgb.exr");
        let img = image::Rgb32FImage::from_fn(2, 2, |x, y| {
            image::Rgb([1.5 + x as f32, 9.0, 9.0 + y as f32])
        });
        DynamicImage::ImageRgb32F(img).save(&p).unwrap();
        let d = read_depth(&p, 1000.0).unwrap();
        assert_eq!(d.metres, vec![1.5, 2.5, 1.5, 2.5]);
    }

    #[test]
    fn mask_takes_alpha() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.png");
        let mut img = image::RgbaImage::new(2, 1);
        img.put_pixel(0, 0, image::Rgba([0, 0, 0, 255]));
        img.put_pixel(1, 0, image::Rgba([255, 255, 255, 0]));
        img.save(&p).unwrap();
        let m = read_mask(&p).unwrap();
        assert_eq!(m.as_raw(), &vec![255, 0]);
    }
}
