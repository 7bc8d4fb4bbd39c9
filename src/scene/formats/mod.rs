//! Readers and writers for each capture format, all producing and consuming [`Scene`].

pub mod colmap;
pub mod json;
pub mod llff;
pub mod nerfstudio;
pub mod ply;
pub mod rgbd;

use crate::error::{Error, Result};
use crate::scene::Scene;
use std::path::Path;

/// Read a scene, finding the format from the path (see [`Scene::load`]).
pub fn load(path: &Path) -> Result<Scene> {
    if !path.exists() {
        return Err(Error::format(path, "no such file or folder"));
    }
    let scene = if path.is_file() {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        if name.ends_with(".json") {
            nerfstudio::read(path)?
        } else if name == "poses_bounds.npy" {
            llff::read(path.parent().unwrap_or(Path::new(".")))?
        } else if name.starts_with("cameras.") {
            let dir = path.parent().unwrap_or(Path::new("."));
            colmap::read_model(dir, &colmap::default_images_root(dir))?
        } else {
            return Err(Error::format(
                path,
                "unknown scene file: expected a transforms*.json, poses_bounds.npy, or a COLMAP cameras.bin/.txt",
            ));
        }
    } else if colmap::detect(path).is_some() {
        colmap::read_model(path, &colmap::default_images_root(path))?
    } else if let Some(dir) = model_folder(path) {
        colmap::read_model(&dir, &colmap::default_images_root(&dir))?
    } else if path.join("transforms.json").is_file() {
        nerfstudio::read(&path.join("transforms.json"))?
    } else if path.join("transforms_train.json").is_file() {
        nerfstudio::read(&path.join("transforms_train.json"))?
    } else if path.join("poses_bounds.npy").is_file() {
        llff::read(path)?
    } else if path.join("trajectory.log").is_file() {
        rgbd::read_redwood(path)?
    } else {
        return Err(Error::format(
            path,
            "no scene found here: expected a COLMAP model (cameras.bin/.txt, sparse/0/ or colmap/sparse/0/), transforms.json, transforms_train.json, poses_bounds.npy or trajectory.log",
        ));
    };
    check_files_exist(&scene)?;
    Ok(scene)
}

/// The COLMAP model in a project folder: `sparse/0` (COLMAP's own layout), or `colmap/sparse/0`
/// (`ns-process-data`'s, with `images/` beside `colmap/`; preferred over its transforms.json,
/// which has no tracks).
fn model_folder(path: &Path) -> Option<std::path::PathBuf> {
    ["sparse/0", "colmap/sparse/0"]
        .iter()
        .map(|sub| path.join(sub))
        .find(|dir| colmap::detect(dir).is_some())
}

/// Every image (and mask/depth, where given) the scene lists must exist.
pub fn check_files_exist(scene: &Scene) -> Result<()> {
    for im in &scene.images {
        if !im.path.is_file() {
            return Err(Error::format(
                &scene.source,
                format!(
                    "image '{}' is listed but its file {} is missing",
                    im.name,
                    im.path.display()
                ),
            ));
        }
        for (kind, p) in [("mask", &im.mask_path), ("depth", &im.depth_path)] {
            if let Some(p) = p {
                if !p.is_file() {
                    return Err(Error::format(
                        &scene.source,
                        format!(
                            "image '{}': its {kind} file {} is missing",
                            im.name,
                            p.display()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The index of `camera` in `cameras`, adding it (with the next id) unless an identical one is
/// there: formats that give intrinsics per frame share one camera per distinct set.
pub(crate) fn intern_camera(
    cameras: &mut Vec<crate::scene::SceneCamera>,
    camera: crate::scene::Camera,
) -> usize {
    if let Some(i) = cameras.iter().position(|c| c.camera == camera) {
        return i;
    }
    cameras.push(crate::scene::SceneCamera {
        id: cameras.len() as u32 + 1,
        camera,
    });
    cameras.len() - 1
}

/// The size of an image file from its header, with an error naming the file.
pub(crate) fn image_size(path: &Path) -> Result<(u32, u32)> {
    if !path.is_file() {
        return Err(Error::format(path, "image file is missing"));
    }
    image::image_dimensions(path).map_err(|e| Error::image(path, e))
}

/// A text file's bytes as UTF-8, with an error naming the file and where the bad byte is.
pub(crate) fn text<'a>(path: &Path, bytes: &'a [u8]) -> Result<&'a str> {
    std::str::from_utf8(bytes).map_err(|e| {
        Error::format(
            path,
            format!("not UTF-8 text: invalid byte at offset {}", e.valid_up_to()),
        )
    })
}
