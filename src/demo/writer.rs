//! Writing the demo's rasters and truth: colour PNGs, depth (16-bit PNG millimetres and f32 EXR
//! metres), per-object masks, and the per-object truth record (`truth/objects.json`).

use super::render::ViewRender;
use crate::error::{Error, Result};
use crate::scene::io::{mask_file, write_depth_exr, write_depth_png_mm, DepthMap};
use crate::util::atomic::save_image_atomic;
use crate::util::write_atomic;
use image::{DynamicImage, GrayImage, Luma, RgbImage};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// What `truth/objects.json` says about one object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectTruth {
    pub name: String,
    /// The view the suggested click is in (view 0's image name; for an object view 0 does not
    /// see, the first view that does).
    pub view: String,
    /// The interior point of the object's mask in `view` farthest from its edge, in pixel
    /// coordinates (pixel centres at +0.5, DESIGN.md §2).
    pub click: [f64; 2],
    /// Per image name: the fraction of the object's full silhouette that is unoccluded and in
    /// frame.
    pub visible: BTreeMap<String, f64>,
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
}

#[derive(Serialize, Deserialize)]
struct ObjectsFile {
    objects: Vec<ObjectTruth>,
}

/// Read `truth/objects.json` of a demo scene folder.
pub fn read_truth(scene_dir: &Path) -> Result<Vec<ObjectTruth>> {
    let path = scene_dir.join("truth/objects.json");
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let file: ObjectsFile = serde_json::from_str(&text).map_err(|e| Error::json(&path, e))?;
    Ok(file.objects)
}

/// Every view's true mask of `object` (`truth/masks/<object>/`), in the scene's image order.
pub fn truth_masks(scene_dir: &Path, scene: &crate::Scene, object: &str) -> Result<Vec<GrayImage>> {
    use rayon::prelude::*;
    let dir = scene_dir.join("truth/masks").join(object);
    scene
        .images
        .par_iter()
        .map(|im| crate::scene::io::read_mask(&crate::scene::io::find_mask(&dir, &im.name)?))
        .collect()
}

pub fn write_truth(path: &Path, objects: &[ObjectTruth]) -> Result<()> {
    let file = ObjectsFile {
        objects: objects.to_vec(),
    };
    let text = serde_json::to_string_pretty(&file).map_err(|e| Error::json(path, e))?;
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

/// Write one view: `images/<name>`, `truth/depth/<stem>.{png,exr}` and
/// `truth/masks/<object>/<name>` for every object (`objects`: names in id order).
pub fn write_view(
    root: &Path,
    name: &str,
    (w, h): (u32, u32),
    r: &ViewRender,
    objects: &[&str],
) -> Result<()> {
    let stem = Path::new(name)
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| name.to_string());
    let rgb = RgbImage::from_raw(w, h, r.rgb.clone()).expect("buffer has w*h*3 bytes");
    save_image_atomic(
        &root.join("images").join(name),
        &DynamicImage::ImageRgb8(rgb),
    )?;

    let (png, exr) = depth_paths(root, &stem);
    let depth = DepthMap {
        width: w,
        height: h,
        metres: r.depth.clone(),
    };
    write_depth_png_mm(&png, &depth)?;
    write_depth_exr(&exr, &depth)?;

    for (i, obj) in objects.iter().enumerate() {
        let mask = GrayImage::from_fn(w, h, |x, y| {
            Luma([if r.ids[(y * w + x) as usize] == i as u8 {
                255
            } else {
                0
            }])
        });
        let path = mask_file(&root.join("truth/masks").join(obj), name);
        save_image_atomic(&path, &DynamicImage::ImageLuma8(mask))?;
    }
    Ok(())
}

/// Where the truth of removing `objects` lies: `truth/removed/<a>+<b>...`, the names in the
/// scene's order ([`super::OBJECT_NAMES`]), whatever order they are given in.
pub fn removed_dir(root: &Path, objects: &[&str]) -> std::path::PathBuf {
    let mut names: Vec<&str> = objects.to_vec();
    names.sort_by_key(|n| super::OBJECT_NAMES.iter().position(|o| o == n));
    names.dedup();
    root.join("truth/removed").join(names.join("+"))
}

/// Write one view of a removal's truth into `dir` ([`removed_dir`]).
pub fn write_removed(dir: &Path, name: &str, w: u32, h: u32, rgb: Vec<u8>) -> Result<()> {
    let img = RgbImage::from_raw(w, h, rgb).expect("buffer has w*h*3 bytes");
    save_image_atomic(&mask_file(dir, name), &DynamicImage::ImageRgb8(img))
}

/// Where a view's truth depth maps go (PNG millimetres, EXR metres).
pub fn depth_paths(root: &Path, stem: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let d = root.join("truth/depth");
    (d.join(format!("{stem}.png")), d.join(format!("{stem}.exr")))
}

/// The mask pixel farthest from the mask's edge (Euclidean distance to the nearest pixel outside
/// the mask or the image), as pixel-centre coordinates; `None` for an empty mask. Exact by brute
/// force over the boundary pixels, which is cheap at demo sizes. Ties go to the first in raster
/// order, so the result is deterministic.
pub fn farthest_interior(mask: &[bool], w: usize, h: usize) -> Option<[f64; 2]> {
    let inside = |x: i64, y: i64| {
        x >= 0
            && y >= 0
            && (x as usize) < w
            && (y as usize) < h
            && mask[y as usize * w + x as usize]
    };
    let mut outside_edge = Vec::new();
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            if !inside(x, y)
                && [(1, 0), (-1, 0), (0, 1), (0, -1)]
                    .iter()
                    .any(|(dx, dy)| inside(x + dx, y + dy))
            {
                outside_edge.push((x as f64, y as f64));
            }
        }
    }
    let mut best: Option<(f64, usize)> = None;
    for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        // The image border counts as outside (a pixel just past it).
        let mut d2 = [x + 1.0, y + 1.0, w as f64 - x, h as f64 - y]
            .iter()
            .fold(f64::INFINITY, |a, &b| a.min(b * b));
        for &(ox, oy) in &outside_edge {
            d2 = d2.min((ox - x).powi(2) + (oy - y).powi(2));
        }
        if best.is_none_or(|(b, _)| d2 > b) {
            best = Some((d2, i));
        }
    }
    best.map(|(_, i)| [(i % w) as f64 + 0.5, (i / w) as f64 + 0.5])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn farthest_interior_of_a_square_is_its_centre() {
        let (w, h) = (20, 15);
        let mut m = vec![false; w * h];
        for y in 3..10 {
            for x in 5..12 {
                m[y * w + x] = true;
            }
        }
        assert_eq!(farthest_interior(&m, w, h), Some([8.5, 6.5]));
        assert_eq!(farthest_interior(&vec![false; w * h], w, h), None);
    }
}
