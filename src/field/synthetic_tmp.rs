//! TEMPORARY: a minimal NeRF-synthetic `transforms_*.json` reader, used only while
//! `scene::formats::nerfstudio` is not built on this branch. [`load_scene`] tries `Scene::load`
//! first and falls back to this, so once the formats branch is merged the real reader is used.
//! Delete this file when that has happened.

use crate::error::{Error, Result};
use crate::scene::{Camera, ImageView, Pose, Scene, SceneCamera, SourceFormat};
use std::path::{Path, PathBuf};

#[derive(serde::Deserialize)]
struct Frame {
    file_path: String,
    transform_matrix: Vec<Vec<f64>>,
}

#[derive(serde::Deserialize)]
struct Transforms {
    camera_angle_x: f64,
    frames: Vec<Frame>,
}

/// Read a scene with `Scene::load`, falling back to the temporary NeRF-synthetic reader.
pub fn load_scene(path: &Path) -> Result<Scene> {
    match Scene::load(path) {
        Ok(s) => Ok(s),
        Err(e) => {
            let json = if path.is_dir() {
                path.join("transforms_train.json")
            } else {
                path.to_path_buf()
            };
            if json.extension().is_some_and(|x| x == "json") && json.is_file() {
                read_nerf_synthetic(&json)
            } else {
                Err(e)
            }
        }
    }
}

fn read_nerf_synthetic(path: &Path) -> Result<Scene> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let t: Transforms = serde_json::from_str(&text).map_err(|e| Error::json(path, e))?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let first = t
        .frames
        .first()
        .ok_or_else(|| Error::format(path, "no frames"))?;
    let first_path = image_path(&dir, &first.file_path);
    let (w, h) = image::image_dimensions(&first_path).map_err(|e| Error::image(&first_path, e))?;
    let fx = 0.5 * w as f64 / (0.5 * t.camera_angle_x).tan();
    let camera = Camera::pinhole(w, h, fx, fx, 0.5 * w as f64, 0.5 * h as f64);
    let mut images = Vec::new();
    for (i, fr) in t.frames.iter().enumerate() {
        let m = &fr.transform_matrix;
        if m.len() < 3 || m.iter().take(3).any(|r| r.len() != 4) {
            return Err(Error::format(
                path,
                format!("frame {i}: transform_matrix is not 4x4"),
            ));
        }
        let rows = [0, 1, 2].map(|r| [m[r][0], m[r][1], m[r][2], m[r][3]]);
        let pose = Pose::from_c2w_opengl(rows).map_err(|e| Error::format(path, e))?;
        let p = image_path(&dir, &fr.file_path);
        images.push(ImageView {
            id: i as u32 + 1,
            name: fr.file_path.trim_start_matches("./").to_string(),
            path: p,
            camera: 0,
            pose,
            mask_path: None,
            depth_path: None,
            features: Vec::new(),
        });
    }
    Ok(Scene {
        source: path.to_path_buf(),
        format: SourceFormat::NerfSynthetic,
        cameras: vec![SceneCamera { id: 1, camera }],
        images,
        points: Vec::new(),
        depth_scale: 1000.0,
        applied_transform: None,
    })
}

fn image_path(dir: &Path, file: &str) -> PathBuf {
    let p = dir.join(file.trim_start_matches("./"));
    if p.extension().is_some() {
        p
    } else {
        p.with_extension("png")
    }
}
