//! nerfstudio `transforms.json` (and the NeRF-synthetic form), read and written.
//!
//! Intrinsics sit at the top level or per frame (a frame's values override the top level);
//! NeRF-synthetic files give only `camera_angle_x` and extension-less `file_path`s. Poses are
//! camera-to-world in the OpenGL frame; [`Pose`] does the conversion and keeps the numbers so that
//! a file read and written again carries the same matrices.

use super::json::parse_json;
pub(crate) use super::json::read_json_file;
use super::{check_files_exist, image_size, intern_camera, ply};
use crate::error::{Error, Result};
use crate::scene::{Camera, CameraModel, ImageView, Point3D, Pose, Scene, SourceFormat};
use crate::util::paths::{normalize, relative_to, same_file_or_path};
use crate::util::write_atomic;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Intrinsic keys, at the top level or in a frame. Unknown keys (`sharpness`, `aabb_scale`, ...)
/// are ignored on reading and not written.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct Intrinsics {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    camera_model: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fl_x: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fl_y: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    cx: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    cy: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    w: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    h: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    k1: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    k2: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    k3: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    k4: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    p1: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    p2: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    camera_angle_x: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    camera_angle_y: Option<f64>,
}

#[derive(Debug, Serialize, Deserialize)]
struct Frame {
    file_path: String,
    transform_matrix: Vec<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mask_path: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    depth_file_path: Option<String>,
    #[serde(flatten)]
    intrinsics: Intrinsics,
}

#[derive(Debug, Serialize, Deserialize)]
struct Transforms {
    #[serde(flatten)]
    intrinsics: Intrinsics,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    applied_transform: Option<Vec<Vec<f64>>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    ply_file_path: Option<String>,
    /// Metres per stored depth unit, named as nerfstudio's dataparser option (which defaults to
    /// 1e-3 and does not read this key): written with depth (0.001, millimetres) so the file
    /// says its unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    depth_unit_scale_factor: Option<f64>,
    frames: Vec<Frame>,
}

impl Intrinsics {
    /// This frame's values, falling back to the top level's.
    fn over(&self, top: &Intrinsics) -> Intrinsics {
        macro_rules! pick {
            ($($f:ident),*) => { Intrinsics { $($f: self.$f.clone().or_else(|| top.$f.clone()),)* } };
        }
        pick!(
            camera_model,
            fl_x,
            fl_y,
            cx,
            cy,
            w,
            h,
            k1,
            k2,
            k3,
            k4,
            p1,
            p2,
            camera_angle_x,
            camera_angle_y
        )
    }
}

/// Read a nerfstudio or NeRF-synthetic transforms JSON file.
pub fn read(path: &Path) -> Result<Scene> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(path, &bytes)
}

/// A transforms JSON from its bytes, as [`read`] reads it from `path`: `path` names the file in
/// errors and its folder is where the images (and masks, depth, PLY) are looked up.
pub fn parse(path: &Path, bytes: &[u8]) -> Result<Scene> {
    let tf: Transforms = parse_json(path, bytes)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let resolve = |p: &str| dir.join(normalize(Path::new(p)));
    if tf.frames.is_empty() {
        return Err(Error::format(path, "no frames"));
    }
    for (key, count) in [
        (
            "mask_path",
            tf.frames.iter().filter(|f| f.mask_path.is_some()).count(),
        ),
        (
            "depth_file_path",
            tf.frames
                .iter()
                .filter(|f| f.depth_file_path.is_some())
                .count(),
        ),
    ] {
        all_or_none(path, key, count, tf.frames.len())?;
    }
    let mut cameras = Vec::new();
    let mut images = Vec::with_capacity(tf.frames.len());
    for (i, fr) in tf.frames.iter().enumerate() {
        let what = format!("frame {i} ('{}')", fr.file_path);
        let err = |msg: String| Error::format(path, format!("{what}: {msg}"));
        let name = image_name(dir, &fr.file_path).ok_or_else(|| {
            err(format!(
                "image file {} is missing",
                dir.join(&fr.file_path).display()
            ))
        })?;
        let image_path = dir.join(&name);
        let camera = frame_camera(&fr.intrinsics.over(&tf.intrinsics), &image_path).map_err(err)?;
        let pose = matrix_3x4(&fr.transform_matrix, "transform_matrix")
            .and_then(Pose::from_c2w_opengl)
            .map_err(err)?;
        images.push(ImageView {
            id: i as u32 + 1,
            name,
            path: image_path,
            camera: intern_camera(&mut cameras, camera),
            pose,
            mask_path: fr.mask_path.as_deref().map(resolve),
            depth_path: fr.depth_file_path.as_deref().map(resolve),
            features: Vec::new(),
            depth_bounds: None,
        });
    }
    let applied_transform = match &tf.applied_transform {
        None => None,
        Some(m) => Some(matrix_3x4(m, "applied_transform").map_err(|m| Error::format(path, m))?),
    };
    let points = match &tf.ply_file_path {
        None => Vec::new(),
        Some(p) => ply::read_points(&resolve(p))?
            .into_iter()
            .enumerate()
            .map(|(i, (xyz, rgb))| Point3D {
                id: i as u64 + 1,
                xyz,
                rgb,
                error: -1.0,
                track: Vec::new(),
            })
            .collect(),
    };
    // NeRF-synthetic ships one file per split.
    let synthetic = path.file_name().is_some_and(|n| {
        [
            "transforms_train.json",
            "transforms_test.json",
            "transforms_val.json",
        ]
        .contains(&n.to_string_lossy().as_ref())
    });
    let scene = Scene {
        source: path.to_path_buf(),
        format: if synthetic {
            SourceFormat::NerfSynthetic
        } else {
            SourceFormat::Nerfstudio
        },
        cameras,
        images,
        points,
        depth_scale: match tf.depth_unit_scale_factor {
            None => 1000.0,
            Some(f) if f.is_finite() && f > 0.0 => 1.0 / f,
            Some(f) => {
                return Err(Error::format(
                    path,
                    format!("depth_unit_scale_factor {f} is not a positive number"),
                ))
            }
        },
        applied_transform,
    };
    scene.validate(path)?;
    check_files_exist(&scene)?;
    Ok(scene)
}

fn all_or_none(path: &Path, key: &str, count: usize, total: usize) -> Result<()> {
    if count != 0 && count != total {
        return Err(Error::format(
            path,
            format!("{key} is given for {count} of {total} frames: give it for all frames or none"),
        ));
    }
    Ok(())
}

/// The image's name relative to the json folder, with the `.png` that NeRF-synthetic files leave
/// out added when needed; `None` when no such file exists.
fn image_name(dir: &Path, file_path: &str) -> Option<String> {
    let name = normalize(Path::new(file_path))
        .to_string_lossy()
        .to_string();
    [name.clone(), format!("{name}.png")]
        .into_iter()
        .find(|n| dir.join(n).is_file())
}

/// A 3x4 (or 4x4 with a last row of 0 0 0 1) row-major matrix; `what` names it in errors.
fn matrix_3x4(m: &[Vec<f64>], what: &str) -> std::result::Result<[[f64; 4]; 3], String> {
    if !(m.len() == 3 || m.len() == 4) || m.iter().any(|r| r.len() != 4) {
        return Err(format!("{what} must be 3x4 or 4x4"));
    }
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err(format!("{what} has a non-finite entry"));
    }
    if m.len() == 4 {
        let last = &m[3];
        let want = [0.0, 0.0, 0.0, 1.0];
        if last.iter().zip(want).any(|(a, b)| (a - b).abs() > 1e-6) {
            return Err(format!("{what}'s last row is {last:?}, not [0, 0, 0, 1]"));
        }
    }
    Ok([0, 1, 2].map(|r| [m[r][0], m[r][1], m[r][2], m[r][3]]))
}

/// A size value from the json as a pixel count.
fn pixels(v: f64, key: &str) -> std::result::Result<u32, String> {
    if v.fract() == 0.0 && v >= 1.0 && v <= u32::MAX as f64 {
        Ok(v as u32)
    } else {
        Err(format!(
            "{key} = {v} is not a positive whole number of pixels"
        ))
    }
}

/// The camera of one frame (top-level values already merged in), checked against its image file.
fn frame_camera(k: &Intrinsics, image: &Path) -> std::result::Result<Camera, String> {
    let (iw, ih) = image_size(image).map_err(|e| e.to_string())?;
    let (w, h) = match (k.w, k.h) {
        (Some(w), Some(h)) => (pixels(w, "w")?, pixels(h, "h")?),
        (None, None) => (iw, ih),
        _ => return Err("give both w and h, or neither".into()),
    };
    if (w, h) != (iw, ih) {
        return Err(format!(
            "the json says the image is {w}x{h} but {} is {iw}x{ih}",
            image.display()
        ));
    }
    let (wf, hf) = (w as f64, h as f64);
    let fx = match (k.fl_x, k.camera_angle_x) {
        (Some(f), _) => f,
        (None, Some(a)) => 0.5 * wf / (0.5 * a).tan(),
        (None, None) => return Err("no focal length: give fl_x or camera_angle_x".into()),
    };
    let fy = match (k.fl_y, k.camera_angle_y) {
        (Some(f), _) => f,
        (None, Some(a)) => 0.5 * hf / (0.5 * a).tan(),
        (None, None) => fx,
    };
    let (cx, cy) = (k.cx.unwrap_or(0.5 * wf), k.cy.unwrap_or(0.5 * hf));
    let z = |v: Option<f64>| v.unwrap_or(0.0);
    let (k1, k2, k3, k4, p1, p2) = (z(k.k1), z(k.k2), z(k.k3), z(k.k4), z(k.p1), z(k.p2));
    let has_distortion = [k1, k2, k3, k4, p1, p2].iter().any(|&v| v != 0.0);
    let name = match k.camera_model.as_deref() {
        Some(m) => m,
        None if has_distortion => "OPENCV",
        None => "PINHOLE",
    };
    let (model, params) = match name {
        "SIMPLE_PINHOLE" | "PINHOLE" if has_distortion => {
            return Err(format!("camera_model {name} with non-zero distortion terms"))
        }
        "SIMPLE_PINHOLE" => (CameraModel::SimplePinhole, vec![fx, cx, cy]),
        "PINHOLE" => (CameraModel::Pinhole, vec![fx, fy, cx, cy]),
        "OPENCV" if k4 != 0.0 => {
            return Err(format!(
                "OPENCV with k4 = {k4}: an r^8 radial term has no COLMAP model"
            ))
        }
        // COLMAP's OPENCV has no k3; FULL_OPENCV's k3 is the same r^6 term.
        "OPENCV" if k3 != 0.0 => (
            CameraModel::FullOpenCv,
            vec![fx, fy, cx, cy, k1, k2, p1, p2, k3, 0.0, 0.0, 0.0],
        ),
        "OPENCV" => (CameraModel::OpenCv, vec![fx, fy, cx, cy, k1, k2, p1, p2]),
        "OPENCV_FISHEYE" if p1 != 0.0 || p2 != 0.0 => {
            return Err("OPENCV_FISHEYE has no tangential terms (p1, p2)".into())
        }
        "OPENCV_FISHEYE" => (
            CameraModel::OpenCvFisheye,
            vec![fx, fy, cx, cy, k1, k2, k3, k4],
        ),
        other => {
            return Err(format!(
                "camera_model '{other}' is not supported (SIMPLE_PINHOLE, PINHOLE, OPENCV, OPENCV_FISHEYE)"
            ))
        }
    };
    Camera::new(model, w, h, params)
}

/// The json keys for a camera; the reverse of [`frame_camera`] (models nerfstudio lacks are
/// written as the OPENCV or OPENCV_FISHEYE camera with the same projection).
fn camera_keys(cam: &Camera) -> std::result::Result<Intrinsics, String> {
    let p = &cam.params;
    let (fx, fy) = cam.focal();
    let (cx, cy) = cam.principal_point();
    let mut k = Intrinsics {
        fl_x: Some(fx),
        fl_y: Some(fy),
        cx: Some(cx),
        cy: Some(cy),
        w: Some(cam.width as f64),
        h: Some(cam.height as f64),
        ..Intrinsics::default()
    };
    let model = match cam.model {
        // fl_y too: nerfstudio's parser needs it for every model.
        CameraModel::SimplePinhole => "SIMPLE_PINHOLE",
        CameraModel::Pinhole => "PINHOLE",
        CameraModel::SimpleRadial | CameraModel::Radial => {
            k.k1 = Some(p[3]);
            k.k2 = Some(p.get(4).copied().unwrap_or(0.0));
            k.p1 = Some(0.0);
            k.p2 = Some(0.0);
            "OPENCV"
        }
        CameraModel::OpenCv | CameraModel::FullOpenCv => {
            if p.len() > 9 && p[9..].iter().any(|&v| v != 0.0) {
                return Err(
                    "FULL_OPENCV with k4..k6 (rational terms) cannot be written to transforms.json"
                        .into(),
                );
            }
            (k.k1, k.k2, k.p1, k.p2) = (Some(p[4]), Some(p[5]), Some(p[6]), Some(p[7]));
            k.k3 = p.get(8).copied();
            "OPENCV"
        }
        CameraModel::OpenCvFisheye => {
            (k.k1, k.k2, k.k3, k.k4) = (Some(p[4]), Some(p[5]), Some(p[6]), Some(p[7]));
            "OPENCV_FISHEYE"
        }
        CameraModel::SimpleRadialFisheye | CameraModel::RadialFisheye => {
            k.k1 = Some(p[3]);
            k.k2 = Some(p.get(4).copied().unwrap_or(0.0));
            "OPENCV_FISHEYE"
        }
        CameraModel::Fov | CameraModel::ThinPrismFisheye => {
            return Err(format!(
                "camera model {} cannot be written",
                cam.model.name()
            ))
        }
    };
    k.camera_model = Some(model.to_string());
    Ok(k)
}

/// Write `scene` as a nerfstudio transforms.json at `path` (file paths relative to its folder;
/// sparse points, if any, to `sparse_pc.ply` beside it).
pub fn write(scene: &Scene, path: &Path) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new(""));
    let n = scene.images.len();
    all_or_none(
        path,
        "mask_path",
        scene
            .images
            .iter()
            .filter(|i| i.mask_path.is_some())
            .count(),
        n,
    )?;
    all_or_none(
        path,
        "depth_file_path",
        scene
            .images
            .iter()
            .filter(|i| i.depth_path.is_some())
            .count(),
        n,
    )?;
    let keys = scene
        .cameras
        .iter()
        .map(|c| {
            camera_keys(&c.camera).map_err(|m| Error::format(path, format!("camera {}: {m}", c.id)))
        })
        .collect::<Result<Vec<_>>>()?;
    // nerfstudio reads depth images as millimetres unless its dataparser is told otherwise on
    // the command line; the key written below says so but nerfstudio does not read it.
    let has_depth = scene.images.iter().any(|i| i.depth_path.is_some());
    if has_depth && scene.depth_scale != 1000.0 {
        return Err(Error::invalid(format!(
            "{}: depth images store depth x {}, but transforms.json depth must be millimetres (x 1000)",
            path.display(),
            scene.depth_scale
        )));
    }
    let shared = scene.cameras.len() == 1;
    let top_model = top_camera_model(&keys).map_err(|m| Error::format(path, m))?;
    let frames = scene
        .images
        .iter()
        .map(|im| {
            let gl = im.pose.c2w_opengl();
            let mut m: Vec<Vec<f64>> = gl.iter().map(|r| r.to_vec()).collect();
            m.push(vec![0.0, 0.0, 0.0, 1.0]);
            Frame {
                file_path: file_ref(&im.path, Some(&im.name), dir),
                transform_matrix: m,
                mask_path: im.mask_path.as_deref().map(|p| file_ref(p, None, dir)),
                depth_file_path: im.depth_path.as_deref().map(|p| file_ref(p, None, dir)),
                intrinsics: if shared {
                    Intrinsics::default()
                } else {
                    keys[im.camera].clone()
                },
            }
        })
        .collect();
    let ply_file_path = if scene.points.is_empty() {
        None
    } else {
        let ply_path = dir.join("sparse_pc.ply");
        let pts: Vec<_> = scene.points.iter().map(|p| (p.xyz, p.rgb)).collect();
        ply::write_points(&ply_path, &pts)?;
        Some("sparse_pc.ply".to_string())
    };
    let tf = Transforms {
        intrinsics: if shared {
            keys[0].clone()
        } else {
            Intrinsics {
                camera_model: Some(top_model),
                ..Intrinsics::default()
            }
        },
        applied_transform: scene
            .applied_transform
            .map(|m| m.iter().map(|r| r.to_vec()).collect()),
        ply_file_path,
        depth_unit_scale_factor: has_depth.then_some(0.001),
        frames,
    };
    let json = serde_json::to_string_pretty(&tf).map_err(|e| Error::json(path, e))?;
    write_atomic(path, |w| {
        w.write_all(json.as_bytes())?;
        w.write_all(b"\n")
    })
}

/// The top-level `camera_model`, the only one nerfstudio reads (frames keep their own for us):
/// the cameras' shared model, else OPENCV when all are perspective (its distortion terms, zero or
/// not, cover the others).
fn top_camera_model(keys: &[Intrinsics]) -> std::result::Result<String, String> {
    let models: Vec<&str> = keys
        .iter()
        .filter_map(|k| k.camera_model.as_deref())
        .collect();
    if models.windows(2).all(|w| w[0] == w[1]) {
        return Ok(models.first().unwrap_or(&"PINHOLE").to_string());
    }
    if models.contains(&"OPENCV_FISHEYE") {
        return Err(format!(
            "the cameras mix fisheye and perspective models ({}): nerfstudio reads one camera type per transforms.json",
            models.join(", ")
        ));
    }
    Ok("OPENCV".into())
}

/// How a json in `dir` refers to `file`: `name` when it still names the same file from `dir`
/// (so names survive a write next to, or into a link of, the source folder), else a path
/// relative to `dir`.
fn file_ref(file: &Path, name: Option<&str>, dir: &Path) -> String {
    match name {
        Some(name) if same_file_or_path(&dir.join(name), file) => name.to_string(),
        _ => relative_to(file, dir).to_string_lossy().replace('\\', "/"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(json: &str) -> Intrinsics {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn camera_models_from_keys_and_back() {
        let dir = tempfile::tempdir().unwrap();
        let img = dir.path().join("i.png");
        image::RgbImage::new(40, 30).save(&img).unwrap();
        let cam = |j: &str| frame_camera(&keys(j), &img);
        // NeRF-synthetic: focal from the field of view, centred principal point, size from file.
        let c = cam(r#"{"camera_angle_x": 1.0}"#).unwrap();
        assert_eq!(c.model, CameraModel::Pinhole);
        assert_eq!(
            c.params,
            vec![20.0 / 0.5f64.tan(), 20.0 / 0.5f64.tan(), 20.0, 15.0]
        );
        let c =
            cam(r#"{"fl_x": 50, "fl_y": 51, "cx": 20, "cy": 15, "k1": 0.1, "k3": 0.01}"#).unwrap();
        assert_eq!(c.model, CameraModel::FullOpenCv);
        assert_eq!(c.params[8], 0.01);
        let c = cam(r#"{"camera_model": "OPENCV_FISHEYE", "fl_x": 50, "k1": 0.1, "k4": 0.01}"#)
            .unwrap();
        assert_eq!((c.model, c.params[7]), (CameraModel::OpenCvFisheye, 0.01));
        // A frame's keys override the top level's.
        let top = keys(
            r#"{"camera_model": "OPENCV", "fl_x": 50, "fl_y": 51, "k1": 0.1, "w": 40, "h": 30}"#,
        );
        let c = frame_camera(&keys(r#"{"fl_x": 60, "k1": 0.2}"#).over(&top), &img).unwrap();
        assert_eq!(c.params, vec![60.0, 51.0, 20.0, 15.0, 0.2, 0.0, 0.0, 0.0]);
        let c = cam(r#"{"camera_model": "SIMPLE_PINHOLE", "fl_x": 50, "w": 40, "h": 30}"#).unwrap();
        assert_eq!(c.params, vec![50.0, 20.0, 15.0]);
        for (bad, why) in [
            (r#"{"camera_model": "OPENCV", "fl_x": 50, "k4": 0.1}"#, "k4"),
            (
                r#"{"camera_model": "EQUIRECTANGULAR", "fl_x": 50}"#,
                "not supported",
            ),
            (
                r#"{"camera_model": "PINHOLE", "fl_x": 50, "k1": 0.1}"#,
                "distortion",
            ),
            (r#"{"fl_x": 50, "w": 40}"#, "both w and h"),
            (r#"{"fl_x": 50, "w": 40.5, "h": 30}"#, "whole number"),
            (r#"{"cx": 3}"#, "no focal length"),
        ] {
            let e = cam(bad).unwrap_err();
            assert!(e.contains(why), "{bad}: {e}");
        }
        // Every model we can write reads back as the same projection.
        let models = [
            (CameraModel::SimplePinhole, vec![50.0, 20.0, 15.0]),
            (CameraModel::Pinhole, vec![50.0, 52.0, 20.0, 15.0]),
            (CameraModel::SimpleRadial, vec![50.0, 20.0, 15.0, 0.1]),
            (CameraModel::Radial, vec![50.0, 20.0, 15.0, 0.1, -0.02]),
            (
                CameraModel::OpenCv,
                vec![50.0, 52.0, 20.0, 15.0, 0.1, -0.02, 0.001, 0.002],
            ),
            (
                CameraModel::OpenCvFisheye,
                vec![50.0, 52.0, 20.0, 15.0, 0.1, -0.02, 0.01, 0.001],
            ),
            (
                CameraModel::RadialFisheye,
                vec![50.0, 20.0, 15.0, 0.1, -0.02],
            ),
        ];
        for (model, params) in models {
            let orig = Camera::new(model, 40, 30, params).unwrap();
            let back = frame_camera(&camera_keys(&orig).unwrap(), &img).unwrap();
            let p = glam::DVec3::new(0.2, -0.1, 1.0);
            let (a, b) = (orig.project(p).unwrap(), back.project(p).unwrap());
            assert!((a - b).length() < 1e-12, "{model:?}: {a} vs {b}");
        }
    }
}
