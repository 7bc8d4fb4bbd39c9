//! What `objnerf segment` writes: per-object masks, the segmented sparse cloud, a contact sheet
//! of every view with its mask and status, and report.json.

use super::types::{ObjectSegmentation, ViewStatus};
use crate::error::Result;
use crate::scene::formats::ply;
use crate::scene::io::{mask_file, read_rgb};
use crate::scene::Scene;
use crate::util::atomic::save_image_atomic;
use crate::util::mask::is_object;
use image::{imageops, DynamicImage, GrayImage, Rgb, RgbImage};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// `dir/masks/<object>/<image name>.png` ([`mask_file`]) for every view with a mask (obstructed
/// views included: their status in report.json says to leave them out of training), and
/// `dir/<object>_points.ply`.
/// The folder of one object's masks in a segmentation output folder.
pub fn masks_dir(seg_dir: &Path, object: &str) -> PathBuf {
    seg_dir.join("masks").join(object)
}

pub fn write_object(scene: &Scene, obj: &ObjectSegmentation, dir: &Path) -> Result<()> {
    let mdir = masks_dir(dir, &obj.name);
    obj.views.par_iter().try_for_each(|v| -> Result<()> {
        if let Some(m) = &v.mask {
            save_image_atomic(
                &mask_file(&mdir, &v.view),
                &DynamicImage::ImageLuma8(m.clone()),
            )?;
        }
        Ok(())
    })?;
    let pts: Vec<_> = obj
        .points
        .iter()
        .map(|&p| (scene.points[p].xyz, scene.points[p].rgb))
        .collect();
    ply::write_points(&dir.join(format!("{}_points.ply", obj.name)), &pts)
}

/// All views in a grid: the image with the mask tinted, the prompts as dots (green positive,
/// red negative), and a border for the status (green ok, red obstructed, grey absent).
pub fn contact_sheet(
    scene: &Scene,
    obj: &ObjectSegmentation,
    thumb_width: u32,
) -> Result<RgbImage> {
    let thumbs: Vec<RgbImage> = scene
        .images
        .par_iter()
        .zip(&obj.views)
        .map(|(im, v)| -> Result<RgbImage> {
            let mut img = read_rgb(&im.path)?;
            if let Some(m) = &v.mask {
                tint(&mut img, m, [255, 60, 200]);
            }
            let radius = (img.width() / 120).max(2) as i64;
            for p in &v.prompts {
                let c = if p.positive {
                    [40, 255, 40]
                } else {
                    [255, 40, 40]
                };
                dot(&mut img, p.xy[0], p.xy[1], radius, c);
            }
            let h = (thumb_width as f64 * img.height() as f64 / img.width() as f64)
                .round()
                .max(1.0) as u32;
            let mut t = imageops::resize(&img, thumb_width, h, imageops::FilterType::Triangle);
            let border = match v.status {
                ViewStatus::Ok => [30, 200, 30],
                ViewStatus::Obstructed => [230, 30, 30],
                ViewStatus::Absent => [128, 128, 128],
            };
            frame(&mut t, 3, border);
            Ok(t)
        })
        .collect::<Result<Vec<_>>>()?;
    let cols = (thumbs.len() as f64).sqrt().ceil().max(1.0) as u32;
    let rows = (thumbs.len() as u32).div_ceil(cols);
    let th = thumbs.iter().map(|t| t.height()).max().unwrap_or(1);
    let gap = 4;
    let mut sheet = RgbImage::from_pixel(
        cols * (thumb_width + gap) + gap,
        rows * (th + gap) + gap,
        Rgb([24, 24, 24]),
    );
    for (i, t) in thumbs.iter().enumerate() {
        let (c, r) = (i as u32 % cols, i as u32 / cols);
        imageops::replace(
            &mut sheet,
            t,
            (gap + c * (thumb_width + gap)) as i64,
            (gap + r * (th + gap)) as i64,
        );
    }
    Ok(sheet)
}

pub fn write_contact_sheet(scene: &Scene, obj: &ObjectSegmentation, path: &Path) -> Result<()> {
    let sheet = contact_sheet(scene, obj, 240)?;
    save_image_atomic(path, &DynamicImage::ImageRgb8(sheet))
}

fn tint(img: &mut RgbImage, mask: &GrayImage, c: [u8; 3]) {
    for (x, y, px) in img.enumerate_pixels_mut() {
        if x < mask.width() && y < mask.height() && is_object(mask.get_pixel(x, y)[0]) {
            for k in 0..3 {
                px[k] = ((px[k] as u16 + c[k] as u16) / 2) as u8;
            }
        }
    }
}

fn dot(img: &mut RgbImage, x: f64, y: f64, r: i64, c: [u8; 3]) {
    let (cx, cy) = (x.floor() as i64, y.floor() as i64);
    for yy in cy - r..=cy + r {
        for xx in cx - r..=cx + r {
            if xx >= 0
                && yy >= 0
                && (xx as u32) < img.width()
                && (yy as u32) < img.height()
                && (xx - cx).pow(2) + (yy - cy).pow(2) <= r * r
            {
                img.put_pixel(xx as u32, yy as u32, Rgb(c));
            }
        }
    }
}

fn frame(img: &mut RgbImage, t: u32, c: [u8; 3]) {
    let (w, h) = (img.width(), img.height());
    for (x, y, px) in img.enumerate_pixels_mut() {
        if x < t || y < t || x + t >= w || y + t >= h {
            *px = Rgb(c);
        }
    }
}
