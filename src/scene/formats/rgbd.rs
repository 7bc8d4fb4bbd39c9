//! RGB-D captures in the Redwood/Open3D layout: `camera_*.json` intrinsics, `trajectory.log`
//! camera-to-world poses, `rgbd.match` pairing depth and colour images.

use super::intern_camera;
use crate::error::{Error, Result};
use crate::scene::{Camera, CameraModel, ImageView, Pose, Scene, SourceFormat};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Open3D's `PinholeCameraIntrinsic` JSON.
#[derive(Deserialize)]
struct Intrinsic {
    width: u32,
    height: u32,
    /// 3x3, column-major: fx 0 0, 0 fy 0, cx cy 1.
    intrinsic_matrix: Vec<f64>,
}

/// Read a Redwood RGB-D folder. Depth images are millimetres (`depth_scale` 1000).
pub fn read_redwood(dir: &Path) -> Result<Scene> {
    let camera = read_intrinsics(dir)?;
    let log = dir.join("trajectory.log");
    let poses = read_trajectory(&log)?;
    let pairs = read_pairs(dir)?;
    if pairs.len() != poses.len() {
        return Err(Error::format(
            &log,
            format!(
                "{} poses but {} depth/colour pairs",
                poses.len(),
                pairs.len()
            ),
        ));
    }
    let mut cameras = Vec::new();
    let cam = intern_camera(&mut cameras, camera);
    let images = pairs
        .into_iter()
        .zip(poses)
        .enumerate()
        .map(|(i, ((depth, colour), pose))| ImageView {
            id: i as u32 + 1,
            path: dir.join(&colour),
            name: colour,
            camera: cam,
            pose,
            mask_path: None,
            depth_path: Some(dir.join(depth)),
            features: Vec::new(),
            depth_bounds: None,
        })
        .collect();
    let scene = Scene {
        source: dir.to_path_buf(),
        format: SourceFormat::RgbdRedwood,
        cameras,
        images,
        points: Vec::new(),
        depth_scale: 1000.0,
        applied_transform: None,
    };
    scene.validate(dir)?;
    Ok(scene)
}

/// The first `camera_*.json` (by name) in `dir`.
fn read_intrinsics(dir: &Path) -> Result<Camera> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name().is_some_and(|n| {
                let n = n.to_string_lossy();
                n.starts_with("camera") && n.ends_with(".json")
            })
        })
        .collect();
    found.sort();
    let path = found
        .first()
        .ok_or_else(|| Error::format(dir, "no camera_*.json intrinsics file"))?;
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let k: Intrinsic = serde_json::from_str(&text).map_err(|e| Error::json(path, e))?;
    let m = &k.intrinsic_matrix;
    if m.len() != 9 {
        return Err(Error::format(path, "intrinsic_matrix must have 9 values"));
    }
    // Open3D puts pixel centres at integer coordinates; ours (COLMAP's) at +0.5.
    Camera::new(
        CameraModel::Pinhole,
        k.width,
        k.height,
        vec![m[0], m[4], m[6] + 0.5, m[7] + 0.5],
    )
    .map_err(|e| Error::format(path, e))
}

/// Redwood `.log`: per frame a line "i j n", then four rows of a camera-to-world 4x4 whose camera
/// axes follow OpenCV.
fn read_trajectory(path: &Path) -> Result<Vec<Pose>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_trajectory(path, &bytes)
}

/// The poses of a Redwood `trajectory.log` from its bytes (`path` names it in errors).
pub fn parse_trajectory(path: &Path, bytes: &[u8]) -> Result<Vec<Pose>> {
    let text = super::text(path, bytes)?;
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    if lines.len() % 5 != 0 {
        return Err(Error::format(
            path,
            format!(
                "{} non-empty lines: each pose takes 5 (a header and 4 matrix rows)",
                lines.len()
            ),
        ));
    }
    let mut poses = Vec::with_capacity(lines.len() / 5);
    for block in lines.chunks_exact(5) {
        let mut m = [[0.0; 4]; 4];
        for (row, &(ln, line)) in m.iter_mut().zip(&block[1..]) {
            let vals: Vec<f64> = line
                .split_whitespace()
                .map(|t| t.parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| Error::format(path, format!("line {ln}: not a number in '{line}'")))?;
            if vals.len() != 4 {
                return Err(Error::format(
                    path,
                    format!("line {ln}: a matrix row needs 4 numbers"),
                ));
            }
            row.copy_from_slice(&vals);
        }
        let ln = block[0].0;
        if m[3]
            .iter()
            .zip([0.0, 0.0, 0.0, 1.0])
            .any(|(a, b)| (a - b).abs() > 1e-6)
        {
            return Err(Error::format(
                path,
                format!("pose at line {ln}: last row is not 0 0 0 1"),
            ));
        }
        let pose = Pose::from_c2w_opencv([m[0], m[1], m[2]])
            .map_err(|e| Error::format(path, format!("pose at line {ln}: {e}")))?;
        poses.push(pose);
    }
    Ok(poses)
}

/// (depth, colour) paths relative to `dir`: from `rgbd.match`, else the sorted `depth/` and
/// `color/` folders.
fn read_pairs(dir: &Path) -> Result<Vec<(String, String)>> {
    let matches = dir.join("rgbd.match");
    if matches.is_file() {
        let text = std::fs::read_to_string(&matches).map_err(|e| Error::io(&matches, e))?;
        return text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
            .map(|(i, l)| {
                let t: Vec<&str> = l.split_whitespace().collect();
                match t.as_slice() {
                    [d, c] => Ok((d.to_string(), c.to_string())),
                    _ => Err(Error::format(
                        &matches,
                        format!("line {}: expected 'depth_path colour_path'", i + 1),
                    )),
                }
            })
            .collect();
    }
    let list = |sub: &str| -> Result<Vec<String>> {
        let d = dir.join(sub);
        let mut v: Vec<String> = std::fs::read_dir(&d)
            .map_err(|e| Error::io(&d, e))?
            .filter_map(|e| e.ok())
            .filter(|e| e.path().is_file())
            .map(|e| format!("{sub}/{}", e.file_name().to_string_lossy()))
            .collect();
        v.sort();
        Ok(v)
    };
    let (depth, colour) = (list("depth")?, list("color")?);
    if depth.len() != colour.len() {
        return Err(Error::format(
            dir,
            format!(
                "no rgbd.match, and depth/ has {} files but color/ has {}",
                depth.len(),
                colour.len()
            ),
        ));
    }
    Ok(depth.into_iter().zip(colour).collect())
}
