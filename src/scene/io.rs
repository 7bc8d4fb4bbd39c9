//! Reading and writing the per-view rasters a scene refers to: colour images, masks and depth maps.

use crate::error::{Error, Result};
use crate::util::atomic::{save_image_atomic, write_bytes_atomic};
use image::{DynamicImage, GrayImage, ImageBuffer, Luma, RgbImage};
use std::path::{Component, Path, PathBuf};

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
    decode_depth(path, open(path)?, scale)
}

/// A file opened for decoding, with an error naming it.
fn open(path: &Path) -> Result<std::io::BufReader<std::fs::File>> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    Ok(std::io::BufReader::new(f))
}

/// An image decoded from `r`, its format from `path`'s extension (as `image::open` does), or
/// from its first bytes when the extension names none. `path` names the file in errors.
fn decode_image<R: std::io::BufRead + std::io::Seek>(path: &Path, r: R) -> Result<DynamicImage> {
    let mut reader = image::ImageReader::new(r);
    match image::ImageFormat::from_path(path) {
        Ok(f) => reader.set_format(f),
        Err(_) => {
            reader = reader
                .with_guessed_format()
                .map_err(|e| Error::io(path, e))?
        }
    }
    reader.decode().map_err(|e| Error::image(path, e))
}

/// [`read_depth`] on a stream of the file's bytes (`path` gives the format and names the file).
pub fn decode_depth<R: std::io::BufRead + std::io::Seek>(
    path: &Path,
    r: R,
    scale: f64,
) -> Result<DepthMap> {
    if is_exr(path) {
        return decode_depth_exr(path, r);
    }
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::invalid(format!(
            "{}: depth scale must be positive, got {scale}",
            path.display()
        )));
    }
    let img = decode_image(path, r)?;
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

fn decode_depth_exr<R: std::io::BufRead + std::io::Seek>(
    path: &Path,
    mut r: R,
) -> Result<DepthMap> {
    use exr::prelude::{FlatSamples, ReadChannels, ReadLayers};
    let bad = |e: exr::error::Error| Error::format(path, format!("cannot read EXR depth: {e}"));
    // The header's sizes size exr's sample buffers before any pixel is read (a corrupt 60-byte
    // file asked for 35 TB): check them first, against the image crate's default limit.
    // 256 MiB: an 8192 x 8192 float depth map; its f32 copy is counted too.
    const MAX_DECODED_BYTES: usize = 256 << 20;
    let meta = exr::meta::MetaData::read_from_buffered(&mut r, false).map_err(bad)?;
    for h in meta.headers.iter() {
        // Depth maps are one level; exr's reading of a corrupt multi-level file trips its own
        // consistency checks.
        let sample_bytes: usize = h
            .channels
            .list
            .iter()
            .map(|c| c.sample_type.bytes_per_sample())
            .sum();
        if let exr::meta::BlockDescription::Tiles(t) = &h.blocks {
            // exr sizes a block's buffers by the declared tile (a fuzzed 8x8 image with
            // 16711744x64 tiles took 1 GB): real tiles are 32 to 256 pixels a side.
            let (tw, th) = (t.tile_size.width(), t.tile_size.height());
            let tile_bytes = tw
                .checked_mul(th)
                .and_then(|n| n.checked_mul(sample_bytes.max(4)));
            if tile_bytes.is_none_or(|b| b > MAX_DECODED_BYTES / 16) {
                return Err(Error::format(
                    path,
                    format!("EXR tiles of {tw}x{th} pixels are not plausible (a corrupt header?)"),
                ));
            }
            if t.level_mode != exr::meta::attribute::LevelMode::Singular {
                return Err(Error::format(
                    path,
                    format!(
                        "EXR depth with {:?} levels is not supported (one level expected)",
                        t.level_mode
                    ),
                ));
            }
        }
        let (w, ht) = (h.layer_size.width(), h.layer_size.height());
        let bytes = w
            .checked_mul(ht)
            .and_then(|n| n.checked_mul(sample_bytes.max(4)));
        if bytes.is_none_or(|b| b > MAX_DECODED_BYTES) {
            return Err(Error::format(
                path,
                format!(
                    "EXR layer of {w}x{ht} pixels and {} channels would decode to more than {} MiB (a corrupt header?)",
                    h.channels.list.len(),
                    MAX_DECODED_BYTES >> 20
                ),
            ));
        }
    }
    r.seek(std::io::SeekFrom::Start(0))
        .map_err(|e| Error::io(path, e))?;
    let img = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(r)
        .map_err(bad)?;
    let layer = img.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let mut channels = layer.channel_data.list.into_vec();
    // Channels are stored sorted by name, so "first" would be B for an RGB file: prefer the names
    // depth tools use.
    let pick = ["R", "Y", "Z", "depth", "D"]
        .iter()
        .find_map(|n| channels.iter().position(|c| c.name.eq(n)))
        .or((!channels.is_empty()).then_some(0))
        .ok_or_else(|| Error::format(path, "EXR depth has no channels"))?;
    // Taken, not copied: a large depth map is not held twice.
    let metres: Vec<f32> = match channels.swap_remove(pick).sample_data {
        FlatSamples::F16(v) => v.iter().map(|x| x.to_f32()).collect(),
        FlatSamples::F32(v) => v,
        FlatSamples::U32(v) => v.iter().map(|&x| x as f32).collect(),
    };
    drop(channels);
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

/// Write a depth map as a one-channel ("Y") 32-bit float OpenEXR in metres (0 = unknown),
/// atomically: uncompressed scanlines in increasing order, written by hand because encoders that
/// compress blocks in parallel write them in completion order, so their bytes differ between
/// runs; these files are byte-stable.
pub fn write_depth_exr(path: &Path, depth: &DepthMap) -> Result<()> {
    write_exr_y(path, depth, 0.0)
}

/// [`write_depth_exr`] with +inf where nothing was hit instead of 0 (render passes: a Z-combine
/// must put anything in front of "nothing").
pub fn write_depth_exr_far(path: &Path, depth: &DepthMap) -> Result<()> {
    write_exr_y(path, depth, f32::INFINITY)
}

/// The one EXR writer: `unknown` where a depth is not a positive finite number.
fn write_exr_y(path: &Path, depth: &DepthMap, unknown: f32) -> Result<()> {
    check_len(path, depth)?;
    let (w, h) = (depth.width as usize, depth.height as usize);
    fn attr(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
        out.extend_from_slice(name.as_bytes());
        out.push(0);
        out.extend_from_slice(kind.as_bytes());
        out.push(0);
        out.extend_from_slice(&(value.len() as i32).to_le_bytes());
        out.extend_from_slice(value);
    }
    let i32s = |v: &[i32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let mut out = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
    // One channel "Y": FLOAT (2), linear 0, sampling 1x1.
    let mut chlist = b"Y\0".to_vec();
    chlist.extend_from_slice(&i32s(&[2, 0, 1, 1]));
    chlist.push(0);
    attr(&mut out, "channels", "chlist", &chlist);
    attr(&mut out, "compression", "compression", &[0]);
    let window = i32s(&[0, 0, w as i32 - 1, h as i32 - 1]);
    attr(&mut out, "dataWindow", "box2i", &window);
    attr(&mut out, "displayWindow", "box2i", &window);
    attr(&mut out, "lineOrder", "lineOrder", &[0]);
    attr(&mut out, "pixelAspectRatio", "float", &1f32.to_le_bytes());
    attr(&mut out, "screenWindowCenter", "v2f", &[0; 8]);
    attr(&mut out, "screenWindowWidth", "float", &1f32.to_le_bytes());
    out.push(0);
    // Offset table: one uncompressed scanline per block.
    let row_bytes = 4 * w;
    let first = out.len() + 8 * h;
    for y in 0..h {
        out.extend_from_slice(&((first + y * (8 + row_bytes)) as u64).to_le_bytes());
    }
    for (y, row) in depth.metres.chunks(w.max(1)).enumerate().take(h) {
        out.extend_from_slice(&(y as i32).to_le_bytes());
        out.extend_from_slice(&(row_bytes as i32).to_le_bytes());
        for &d in row {
            let d = if d.is_finite() && d > 0.0 { d } else { unknown };
            out.extend_from_slice(&d.to_le_bytes());
        }
    }
    write_bytes_atomic(path, &out)
}

/// The image files objnerf reads (by extension, any case).
pub const IMAGE_EXTENSIONS: [&str; 3] = ["png", "jpg", "jpeg"];

/// Whether `path` names an image objnerf reads (by its extension; the file is not opened).
pub fn is_image(path: &Path) -> bool {
    path.extension().is_some_and(|e| {
        let e = e.to_string_lossy().to_ascii_lowercase();
        IMAGE_EXTENSIONS.contains(&e.as_str())
    })
}

/// Open an image file of any supported format.
pub fn read_image(path: &Path) -> Result<DynamicImage> {
    decode_image(path, open(path)?)
}

/// Read a colour image as 8-bit RGB. Images with alpha (NeRF-synthetic's RGBA) are composited
/// onto white, the standard protocol for those datasets, so transparent pixels do not become
/// black.
pub fn read_rgb(path: &Path) -> Result<RgbImage> {
    decode_rgb(path, open(path)?)
}

/// [`read_rgb`] on a stream of the file's bytes (`path` gives the format and names the file).
pub fn decode_rgb<R: std::io::BufRead + std::io::Seek>(path: &Path, r: R) -> Result<RgbImage> {
    Ok(rgb_on_white(&decode_image(path, r)?))
}

/// An image as 8-bit RGB, alpha composited onto white.
pub fn rgb_on_white(img: &DynamicImage) -> RgbImage {
    if !img.color().has_alpha() {
        return img.to_rgb8();
    }
    let rgba = img.to_rgba8();
    RgbImage::from_fn(rgba.width(), rgba.height(), |x, y| {
        let p = rgba.get_pixel(x, y);
        let a = p[3] as f32 / 255.0;
        let c = |v: u8| (v as f32 * a + 255.0 * (1.0 - a)).round() as u8;
        image::Rgb([c(p[0]), c(p[1]), c(p[2])])
    })
}

/// Which channel of an image file a mask was taken from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaskChannel {
    /// The alpha channel: the image is a cut-out (its alpha varies).
    Alpha,
    /// The luma: a single-channel mask (or a colour image with constant alpha).
    Luma,
}

/// Read a mask as one 8-bit channel (object where [`crate::util::mask::is_object`]). The one
/// rule for which channel: the alpha of an image whose alpha varies (an RGBA cut-out, a
/// NeRF-synthetic view), else the luma. Masks saved as RGBA with an opaque alpha thus read by
/// their grey values, not as all-object; masks saved as 0/1 (numpy's `bool.astype(uint8)`;
/// nerfstudio takes any non-zero value as the object) read as 0/255.
pub fn read_mask(path: &Path) -> Result<GrayImage> {
    read_mask_channel(path).map(|(m, _)| m)
}

/// [`read_mask`], also saying which channel the mask came from.
pub fn read_mask_channel(path: &Path) -> Result<(GrayImage, MaskChannel)> {
    decode_mask_channel(path, open(path)?)
}

/// [`read_mask`] on a stream of the file's bytes (`path` gives the format and names the file).
pub fn decode_mask<R: std::io::BufRead + std::io::Seek>(path: &Path, r: R) -> Result<GrayImage> {
    decode_mask_channel(path, r).map(|(m, _)| m)
}

fn decode_mask_channel<R: std::io::BufRead + std::io::Seek>(
    path: &Path,
    r: R,
) -> Result<(GrayImage, MaskChannel)> {
    let img = decode_image(path, r)?;
    if img.color().has_alpha() {
        let rgba = img.to_rgba8();
        let first = rgba.pixels().next().map_or(255, |p| p.0[3]);
        if rgba.pixels().any(|p| p.0[3] != first) {
            let (w, h) = rgba.dimensions();
            let alpha = rgba.pixels().map(|p| p.0[3]).collect();
            let m = GrayImage::from_raw(w, h, alpha)
                .ok_or_else(|| Error::format(path, "mask size mismatch"))?;
            return Ok((m, MaskChannel::Alpha));
        }
    }
    let mut m = img.to_luma8();
    if m.iter().all(|&v| v <= 1) {
        m.iter_mut().for_each(|v| *v *= 255);
    }
    Ok((m, MaskChannel::Luma))
}

/// Where the mask of the image named `image_name` lies under a masks folder: the image's name
/// (its sub-folders kept) with the extension `.png` (`sub/view_035.jpg` -> `sub/view_035.png`).
/// The one rule, used by every writer and reader of mask folders. Components that would leave
/// the folder (`..`, a root) are dropped.
pub fn mask_file(dir: &Path, image_name: &str) -> PathBuf {
    let rel: PathBuf = Path::new(image_name)
        .components()
        .filter_map(|c| match c {
            Component::Normal(s) => Some(s),
            _ => None,
        })
        .collect();
    dir.join(rel.with_extension("png"))
}

/// The mask of `image_name` in a folder: [`mask_file`]'s path, else (for folders made by other
/// tools) a file named like the image, or its stem with a png/jpg extension, at the top level.
pub fn find_mask(dir: &Path, image_name: &str) -> Result<PathBuf> {
    let p = Path::new(image_name);
    // Also as objnerf 0.1's `segment` flattened them (`images/r_0.png` -> `images_r_0.png`).
    let flat = Path::new(image_name)
        .with_extension("")
        .to_string_lossy()
        .replace(['/', '\\'], "_");
    let mut cands = vec![
        mask_file(dir, image_name),
        dir.join(image_name),
        dir.join(format!("{flat}.png")),
    ];
    if let Some(fname) = p.file_name() {
        cands.push(dir.join(fname));
    }
    if let Some(stem) = p.file_stem() {
        for ext in ["png", "jpg", "jpeg"] {
            cands.push(dir.join(format!("{}.{ext}", stem.to_string_lossy())));
        }
    }
    cands.into_iter().find(|c| c.is_file()).ok_or_else(|| {
        Error::format(
            dir,
            format!(
                "no mask for view '{image_name}' in this folder (looked for {})",
                mask_file(Path::new(""), image_name).display()
            ),
        )
    })
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
        // Byte-stable: the same depth gives the same file.
        let bytes = std::fs::read(&p).unwrap();
        write_depth_exr(&p, &sample()).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), bytes);
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
    fn mask_names_keep_folders() {
        let d = Path::new("m");
        assert_eq!(
            mask_file(d, "sub/view_035.jpg"),
            Path::new("m/sub/view_035.png")
        );
        assert_eq!(mask_file(d, "../x/./r_0.png"), Path::new("m/x/r_0.png"));
        assert_eq!(mask_file(d, "view_000.png"), Path::new("m/view_000.png"));
        assert!(is_image(Path::new("a/B.JPG")) && !is_image(Path::new("a/b.txt")));
    }

    #[test]
    fn opaque_rgba_mask_reads_luma() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.png");
        let mut img = image::RgbaImage::new(2, 1);
        img.put_pixel(0, 0, image::Rgba([0, 0, 0, 255]));
        img.put_pixel(1, 0, image::Rgba([255, 255, 255, 255]));
        img.save(&p).unwrap();
        assert_eq!(read_mask_channel(&p).unwrap().1, MaskChannel::Luma);
        assert_eq!(read_mask(&p).unwrap().as_raw(), &vec![0, 255]);
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
