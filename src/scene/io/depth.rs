//! Depth maps: 16-bit PNGs in millimetres and one-channel EXRs in metres, each saying its unit.

use super::decode::{decode_image, open};
use crate::error::{Error, Result};
use crate::util::atomic::write_bytes_atomic;
use image::DynamicImage;
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

/// The PNG text chunk and the EXR header attribute in which objnerf's depth files say their
/// unit: "mm" (its 16-bit PNGs) or "m" (its EXRs). nerfstudio and Blender ignore both.
pub const PNG_DEPTH_UNIT_KEY: &str = "depth_unit";
pub const EXR_DEPTH_UNIT_ATTRIBUTE: &str = "depthUnit";

/// Stored values per metre for a unit a depth file declares.
fn per_metre(path: &Path, unit: &str) -> Result<f64> {
    match unit.trim() {
        "mm" => Ok(1000.0),
        "m" => Ok(1.0),
        other => Err(Error::format(
            path,
            format!("declares depth unit '{other}'; objnerf reads 'mm' or 'm'"),
        )),
    }
}

/// Read a depth image: a 16-bit PNG storing depth * `scale` (millimetres: scale = 1000, 0 =
/// unknown), or an EXR storing metres (the R, Y or Z channel, else the first one; `scale`
/// unused). A unit the file declares ([`PNG_DEPTH_UNIT_KEY`], [`EXR_DEPTH_UNIT_ATTRIBUTE`])
/// wins over `scale`.
pub fn read_depth(path: &Path, scale: f64) -> Result<DepthMap> {
    decode_depth(path, open(path)?, scale)
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
    let mut r = r;
    let scale = match png_depth_unit(&mut r) {
        Some(unit) => per_metre(path, &unit)?,
        None => scale,
    };
    r.seek(std::io::SeekFrom::Start(0))
        .map_err(|e| Error::io(path, e))?;
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

/// The unit a PNG's [`PNG_DEPTH_UNIT_KEY`] text chunk declares; None for any other file (the
/// image decoder then says what is wrong with it).
fn png_depth_unit<R: std::io::BufRead + std::io::Seek>(r: &mut R) -> Option<String> {
    let png = png::Decoder::new(r).read_info().ok()?;
    let info = png.info();
    let unit = info
        .uncompressed_latin1_text
        .iter()
        .find(|t| t.keyword == PNG_DEPTH_UNIT_KEY)
        .map(|t| t.text.clone());
    unit
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
    let declared = meta.headers.first().and_then(|h| {
        match h
            .own_attributes
            .other
            .get(&exr::prelude::Text::from(EXR_DEPTH_UNIT_ATTRIBUTE))
        {
            Some(exr::prelude::AttributeValue::Text(t)) => Some(t.to_string()),
            _ => None,
        }
    });
    let per_metre = declared.map_or(Ok(1.0), |u| per_metre(path, &u))?;
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
    let mut metres: Vec<f32> = match channels.swap_remove(pick).sample_data {
        FlatSamples::F16(v) => v.iter().map(|x| x.to_f32()).collect(),
        FlatSamples::F32(v) => v,
        FlatSamples::U32(v) => v.iter().map(|&x| x as f32).collect(),
    };
    if per_metre != 1.0 {
        metres
            .iter_mut()
            .for_each(|d| *d = (*d as f64 / per_metre) as f32);
    }
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

/// Write a depth map as a 16-bit PNG in millimetres (0 = unknown), atomically, the unit in its
/// [`PNG_DEPTH_UNIT_KEY`] text chunk ("mm"). nerfstudio reads these without flags (its
/// `depth_unit_scale_factor` defaults to 1e-3).
pub fn write_depth_png_mm(path: &Path, depth: &DepthMap) -> Result<()> {
    check_len(path, depth)?;
    let bad = |e: png::EncodingError| Error::format(path, format!("cannot encode PNG: {e}"));
    let samples: Vec<u8> = depth
        .metres
        .iter()
        .flat_map(|&d| to_mm(d).to_be_bytes())
        .collect();
    let mut bytes = Vec::new();
    let mut enc = png::Encoder::new(&mut bytes, depth.width, depth.height);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Sixteen);
    enc.add_text_chunk(PNG_DEPTH_UNIT_KEY.into(), "mm".into())
        .map_err(bad)?;
    let mut w = enc.write_header().map_err(bad)?;
    w.write_image_data(&samples).map_err(bad)?;
    w.finish().map_err(bad)?;
    write_bytes_atomic(path, &bytes)
}

/// Write a depth map as a one-channel ("Y") 32-bit float OpenEXR in metres (0 = unknown),
/// atomically, the unit in its [`EXR_DEPTH_UNIT_ATTRIBUTE`] header attribute ("m").
/// Uncompressed scanlines written in order by one thread: the same depth gives the same bytes.
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
    use exr::prelude::{AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples};
    use exr::prelude::{Image, Layer, LayerAttributes, SmallVec, Text, WritableImage};
    check_len(path, depth)?;
    let values: Vec<f32> = depth
        .metres
        .iter()
        .map(|&d| if d.is_finite() && d > 0.0 { d } else { unknown })
        .collect();
    let channel = AnyChannel::new("Y", FlatSamples::F32(values));
    // One entry in `other` (a HashMap): more would be written in a random order.
    let mut attributes = LayerAttributes {
        software_name: Some(Text::from("objnerf")),
        ..LayerAttributes::default()
    };
    attributes.other.insert(
        Text::from(EXR_DEPTH_UNIT_ATTRIBUTE),
        AttributeValue::Text(Text::from("m")),
    );
    let layer = Layer::new(
        (depth.width as usize, depth.height as usize),
        attributes,
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    let mut bytes = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_buffered(&mut bytes)
        .map_err(|e| Error::format(path, format!("cannot encode EXR: {e}")))?;
    write_bytes_atomic(path, bytes.get_ref())
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::GrayImage;

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
    fn depth_files_say_their_unit() {
        let dir = tempfile::tempdir().unwrap();
        let (png, exr) = (dir.path().join("d.png"), dir.path().join("d.exr"));
        write_depth_png_mm(&png, &sample()).unwrap();
        write_depth_exr(&exr, &sample()).unwrap();
        // The PNG's text chunk, as png readers see it.
        let file = std::io::BufReader::new(std::fs::File::open(&png).unwrap());
        let reader = png::Decoder::new(file).read_info().unwrap();
        let texts: Vec<(String, String)> = reader
            .info()
            .uncompressed_latin1_text
            .iter()
            .map(|t| (t.keyword.clone(), t.text.clone()))
            .collect();
        assert_eq!(texts, [("depth_unit".to_string(), "mm".to_string())]);
        // The EXR's header, as the exr crate reads it.
        let meta = exr::meta::MetaData::read_from_file(&exr, false).unwrap();
        let h = &meta.headers[0];
        assert_eq!(
            h.own_attributes
                .other
                .get(&exr::prelude::Text::from("depthUnit")),
            Some(&exr::prelude::AttributeValue::Text("m".into()))
        );
        assert_eq!(h.channels.list.len(), 1);
        assert_eq!(h.channels.list[0].name, exr::prelude::Text::from("Y"));
        // A declared unit wins over the scale the caller assumes.
        assert_eq!(read_depth(&png, 1.0).unwrap().metres[2], 1.234);
        assert_eq!(read_depth(&exr, 1000.0).unwrap(), sample());
    }

    #[test]
    fn exr_in_millimetres_and_unknown_units() {
        use exr::prelude::*;
        let dir = tempfile::tempdir().unwrap();
        let write = |unit: &str| {
            let p = dir.path().join(format!("{unit}.exr"));
            let mut attrs = LayerAttributes::default();
            attrs
                .other
                .insert(Text::from("depthUnit"), AttributeValue::Text(unit.into()));
            let ch = AnyChannel::new("Z", FlatSamples::F32(vec![1500.0, 0.0]));
            let layer = Layer::new(
                (2, 1),
                attrs,
                Encoding::UNCOMPRESSED,
                AnyChannels::sort(SmallVec::from_vec(vec![ch])),
            );
            Image::from_layer(layer).write().to_file(&p).unwrap();
            p
        };
        assert_eq!(
            read_depth(&write("mm"), 1.0).unwrap().metres,
            vec![1.5, 0.0]
        );
        let err = read_depth(&write("furlong"), 1.0).unwrap_err().to_string();
        assert!(
            err.contains("furlong.exr") && err.contains("'furlong'"),
            "{err}"
        );
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
}
