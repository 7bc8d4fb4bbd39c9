//! Reading and writing the per-view rasters a scene refers to: colour images, masks and depth maps.

use crate::error::{Error, Result};
use image::{DynamicImage, GrayImage, RgbImage};
use std::path::{Component, Path, PathBuf};

mod decode;
mod depth;
use decode::{decode_image, open};
pub use depth::{decode_depth, read_depth, write_depth_exr, write_depth_exr_far};
pub use depth::{write_depth_png_mm, DepthMap, EXR_DEPTH_UNIT_ATTRIBUTE, PNG_DEPTH_UNIT_KEY};

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
