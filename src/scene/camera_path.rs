//! nerfstudio camera paths (`camera_path.json`, as `ns-render camera-path` reads it), in and out.
//!
//! A path's `camera_to_world` matrices are 4x4 row-major, OpenGL camera axes, in one of two worlds:
//! the dataset's own (the frame of its transforms.json, our scene's frame: [`PathFrame::Data`]) or
//! the frame nerfstudio's viewer and `ns-render` work in, the dataparser's output
//! ([`PathFrame::Viewer`], with the run's `dataparser_transforms.json`: data -> viewer is
//! `p -> scale * (T p)` after undoing the dataset's `applied_transform`). Intrinsics are a vertical
//! field of view in degrees at the path's render size: square pixels, centred principal point, no
//! distortion. Axis flips go through `frames.rs`.
//!
//! Every file written says which world it is in ([`FRAME_KEY`]: "data" or "viewer"; nerfstudio
//! reads keys by name and ignores it). A file without the key (nerfstudio's viewer writes none)
//! is in the world its reader assumes; one in a world objnerf does not know is an error.

use crate::error::{Error, Result};
use crate::scene::formats::json::parse_json;
use crate::scene::{Camera, CameraModel, Pose, Scene};
use crate::util::write_atomic;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::Path;

mod frame;
pub use frame::{DataparserTransform, FrameName, PathFrame, FRAME_KEY};

/// The lens of every camera in a path (nerfstudio's `camera_type`). nerfstudio's panoramic types
/// (equirectangular, omnidirectional, vr180) have no focal length and are refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathLens {
    Perspective,
    /// Equidistant fisheye (r = f * theta): our OPENCV_FISHEYE with zero distortion.
    Fisheye,
}

impl PathLens {
    /// nerfstudio's name for it (`camera_type`).
    pub fn name(self) -> &'static str {
        match self {
            PathLens::Perspective => "perspective",
            PathLens::Fisheye => "fisheye",
        }
    }
}

/// One camera of a path: where it is and what it sees.
#[derive(Clone, Debug, PartialEq)]
pub struct PathCamera {
    pub pose: Pose,
    /// PINHOLE (or OPENCV_FISHEYE for fisheye paths) at the path's size, fx = fy, centred.
    pub camera: Camera,
}

/// A camera path: cameras at one render size, played at `fps` for `seconds`.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPath {
    pub width: u32,
    pub height: u32,
    pub fps: f64,
    pub seconds: f64,
    pub lens: PathLens,
    pub cameras: Vec<PathCamera>,
}

/// The path camera with a vertical field of view `fov_deg` at `width` x `height`.
pub fn path_camera(
    lens: PathLens,
    width: u32,
    height: u32,
    fov_deg: f64,
) -> std::result::Result<Camera, String> {
    if !(fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 180.0) {
        return Err(format!(
            "fov = {fov_deg} is not a field of view in degrees (0 < fov < 180)"
        ));
    }
    // nerfstudio's three_js_perspective_camera_focal_length.
    let f = 0.5 * height as f64 / (0.5 * fov_deg.to_radians()).tan();
    let (cx, cy) = (0.5 * width as f64, 0.5 * height as f64);
    match lens {
        PathLens::Perspective => {
            Camera::new(CameraModel::Pinhole, width, height, vec![f, f, cx, cy])
        }
        PathLens::Fisheye => Camera::new(
            CameraModel::OpenCvFisheye,
            width,
            height,
            vec![f, f, cx, cy, 0.0, 0.0, 0.0, 0.0],
        ),
    }
}

/// The vertical field of view of a path camera, or why `camera` is not one of this path's.
fn fov_deg(camera: &Camera, lens: PathLens, size: (u32, u32)) -> std::result::Result<f64, String> {
    let (w, h) = size;
    let (fx, fy) = camera.focal();
    let (cx, cy) = camera.principal_point();
    let model_ok = match lens {
        PathLens::Perspective => camera.is_pinhole(),
        PathLens::Fisheye => {
            camera.model == CameraModel::OpenCvFisheye
                && camera.params[4..].iter().all(|&k| k == 0.0)
        }
    };
    let near = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0);
    if !model_ok {
        return Err(format!(
            "a {} path holds no {} camera with distortion",
            lens.name(),
            camera.model.name()
        ));
    }
    if (camera.width, camera.height) != size {
        return Err(format!(
            "camera is {}x{} but the path renders {w}x{h}",
            camera.width, camera.height
        ));
    }
    if !near(fx, fy) || !near(cx, 0.5 * w as f64) || !near(cy, 0.5 * h as f64) {
        return Err(format!(
            "a camera path needs square pixels and a centred principal point (fx {fx}, fy {fy}, cx {cx}, cy {cy})"
        ));
    }
    Ok(2.0 * (0.5 * h as f64 / fy).atan().to_degrees())
}

/// A path's camera_to_world as 16 row-major numbers, OpenGL axes.
fn matrix_16(pose: &Pose) -> [f64; 16] {
    let m = pose.c2w_opengl();
    let mut out = [0.0; 16];
    for (r, row) in m.iter().enumerate() {
        out[r * 4..r * 4 + 4].copy_from_slice(row);
    }
    out[15] = 1.0;
    out
}

/// The pose from 16 row-major numbers, OpenGL axes.
fn pose_from_16(v: &[f64]) -> std::result::Result<Pose, String> {
    if v.len() != 16 {
        return Err(format!(
            "camera_to_world has {} numbers, not 16 (4x4 row-major)",
            v.len()
        ));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err("camera_to_world has a non-finite entry".into());
    }
    let last = &v[12..16];
    if last
        .iter()
        .zip([0.0, 0.0, 0.0, 1.0])
        .any(|(a, b)| (a - b).abs() > 1e-9)
    {
        return Err(format!(
            "camera_to_world's last row is {last:?}, not [0, 0, 0, 1]"
        ));
    }
    Pose::from_c2w_opengl([0, 1, 2].map(|r| [v[r * 4], v[r * 4 + 1], v[r * 4 + 2], v[r * 4 + 3]]))
        .map_err(|e| format!("camera_to_world: {e}"))
}

#[derive(Deserialize)]
struct PathFileIn {
    objnerf_frame: Option<serde_json::Value>,
    render_width: Option<f64>,
    render_height: Option<f64>,
    fps: Option<f64>,
    seconds: Option<f64>,
    camera_type: Option<String>,
    camera_path: Option<Vec<PathEntryIn>>,
}

#[derive(Deserialize)]
struct PathEntryIn {
    camera_to_world: Option<Vec<f64>>,
    fov: Option<f64>,
}

#[derive(Serialize)]
struct PathFileOut {
    objnerf_frame: &'static str,
    camera_type: &'static str,
    render_width: u32,
    render_height: u32,
    fps: f64,
    seconds: f64,
    is_cycle: bool,
    smoothness_value: f64,
    default_fov: f64,
    default_transition_sec: f64,
    /// The viewer's "Load path" reads these (every camera is a keyframe); ns-render reads
    /// `camera_path`.
    keyframes: Vec<KeyframeOut>,
    camera_path: Vec<PathEntryOut>,
}

#[derive(Serialize)]
struct KeyframeOut {
    matrix: [f64; 16],
    fov: f64,
    aspect: f64,
}

#[derive(Serialize)]
struct PathEntryOut {
    camera_to_world: [f64; 16],
    fov: f64,
    aspect: f64,
}

fn whole_pixels(v: Option<f64>, key: &str) -> std::result::Result<u32, String> {
    let v = v.ok_or_else(|| format!("missing key '{key}'"))?;
    if v.fract() == 0.0 && v >= 1.0 && v <= u32::MAX as f64 {
        Ok(v as u32)
    } else {
        Err(format!(
            "{key} = {v} is not a positive whole number of pixels"
        ))
    }
}

fn positive(v: f64, key: &str) -> std::result::Result<f64, String> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{key} = {v} is not a positive number"))
    }
}

fn parse_lens(camera_type: Option<&str>) -> std::result::Result<PathLens, String> {
    match camera_type.map(str::to_lowercase).as_deref() {
        None | Some("perspective") => Ok(PathLens::Perspective),
        Some("fisheye") => Ok(PathLens::Fisheye),
        Some(t @ ("equirectangular" | "omnidirectional" | "vr180")) => Err(format!(
            "camera_type '{t}' is a panorama without a focal length: objnerf reads perspective and fisheye paths"
        )),
        Some(t) => Err(format!(
            "unknown camera_type '{t}' (nerfstudio's are perspective, fisheye, equirectangular, omnidirectional, vr180)"
        )),
    }
}

impl CameraPath {
    /// Read a camera_path.json; the cameras come out in the data frame. A file that states its
    /// world ([`FRAME_KEY`]) is read in it (a viewer-frame file needs `frame` to be
    /// [`PathFrame::Viewer`], for its transform); one that does not is read in `frame`. Every error
    /// names the file and, for a camera, its index.
    pub fn read(path: &Path, frame: &PathFrame) -> Result<CameraPath> {
        Self::read_stated(path, frame).map(|(p, _)| p)
    }

    /// [`CameraPath::read`], also returning the world the file stated (None: it stated none and
    /// was read in `frame`).
    pub fn read_stated(path: &Path, frame: &PathFrame) -> Result<(CameraPath, Option<FrameName>)> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::parse(path, &bytes, frame)
    }

    /// [`CameraPath::read_stated`] on a file's bytes (`path` names it in errors).
    pub fn parse(
        path: &Path,
        bytes: &[u8],
        frame: &PathFrame,
    ) -> Result<(CameraPath, Option<FrameName>)> {
        let file: PathFileIn = parse_json(path, bytes)?;
        Self::from_file(file, frame).map_err(|m| Error::format(path, m))
    }

    /// The same cameras rendered at `width` x `height`: each keeps its pose and vertical field of
    /// view (as `ns-render` sizes a path's frames).
    pub fn resized(&self, width: u32, height: u32) -> Result<CameraPath> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!(
                "size {width}x{height}: both sides must be at least 1 pixel"
            )));
        }
        let size = (self.width, self.height);
        let cameras = self
            .cameras
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let fov = fov_deg(&c.camera, self.lens, size)
                    .and_then(|fov| path_camera(self.lens, width, height, fov))
                    .map_err(|m| Error::invalid(format!("camera {i}: {m}")))?;
                Ok(PathCamera {
                    pose: c.pose,
                    camera: fov,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(CameraPath {
            width,
            height,
            cameras,
            ..self.clone()
        })
    }

    fn from_file(
        file: PathFileIn,
        frame: &PathFrame,
    ) -> std::result::Result<(CameraPath, Option<FrameName>), String> {
        let stated = FrameName::stated(file.objnerf_frame.as_ref())?;
        let width = whole_pixels(file.render_width, "render_width")?;
        let height = whole_pixels(file.render_height, "render_height")?;
        let seconds = positive(file.seconds.ok_or("missing key 'seconds'")?, "seconds")?;
        let lens = parse_lens(file.camera_type.as_deref())?;
        let entries = file.camera_path.ok_or("missing key 'camera_path'")?;
        if entries.is_empty() {
            return Err("camera_path is empty".into());
        }
        // ns-render plays the cameras over `seconds`; the viewer also writes fps.
        let fps = match file.fps {
            Some(f) => positive(f, "fps")?,
            None => entries.len() as f64 / seconds,
        };
        let to_data = match (stated, frame) {
            (Some(FrameName::Data), _) | (None, PathFrame::Data) => None,
            (Some(FrameName::Viewer), PathFrame::Data) => {
                return Err(format!(
                    "the path is in nerfstudio's viewer frame ({FRAME_KEY} \"viewer\"): reading it needs the training run's dataparser_transforms.json (objnerf camera-path PATH --dataparser-transforms F --scene DATASET --out DATA_PATH --frame data)"
                ))
            }
            (_, PathFrame::Viewer(t)) => Some(
                t.data_to_viewer()
                    .map_err(|m| format!("dataparser transform: {m}"))?
                    .inverse(),
            ),
        };
        let cameras = entries
            .iter()
            .enumerate()
            .map(|(i, e)| -> std::result::Result<PathCamera, String> {
                let at = |m: String| format!("camera_path[{i}]: {m}");
                let m = e
                    .camera_to_world
                    .as_deref()
                    .ok_or_else(|| at("missing key 'camera_to_world'".into()))?;
                let pose = pose_from_16(m).map_err(at)?;
                let pose = match to_data {
                    Some(w) => pose.transformed(w).map_err(at)?,
                    None => pose,
                };
                let fov = e.fov.ok_or_else(|| at("missing key 'fov'".into()))?;
                let camera = path_camera(lens, width, height, fov).map_err(at)?;
                Ok(PathCamera { pose, camera })
            })
            .collect::<std::result::Result<Vec<_>, _>>()?;
        let path = CameraPath {
            width,
            height,
            fps,
            seconds,
            lens,
            cameras,
        };
        Ok((path, stated))
    }

    /// Write the path with its matrices in `frame`, which the file states, atomically. Fails (writing nothing) when a
    /// camera is not a path camera (distortion, off-centre, other size) or a number is not finite.
    pub fn write(&self, path: &Path, frame: &PathFrame) -> Result<()> {
        let file = self.to_file(frame).map_err(|m| {
            Error::invalid(format!(
                "{}: cannot write this camera path: {m}",
                path.display()
            ))
        })?;
        let json = serde_json::to_string_pretty(&file).map_err(|e| Error::json(path, e))?;
        write_atomic(path, |w| {
            w.write_all(json.as_bytes())?;
            w.write_all(b"\n")
        })
    }

    fn to_file(&self, frame: &PathFrame) -> std::result::Result<PathFileOut, String> {
        positive(self.fps, "fps")?;
        positive(self.seconds, "seconds")?;
        if self.cameras.is_empty() {
            return Err("it has no cameras".into());
        }
        let to_viewer = match frame {
            PathFrame::Data => None,
            PathFrame::Viewer(t) => Some(t.data_to_viewer()?),
        };
        let aspect = self.width as f64 / self.height as f64;
        let mut entries = Vec::with_capacity(self.cameras.len());
        for (i, c) in self.cameras.iter().enumerate() {
            let at = |m: String| format!("camera {i}: {m}");
            let fov = fov_deg(&c.camera, self.lens, (self.width, self.height)).map_err(at)?;
            let pose = match to_viewer {
                Some(w) => c.pose.transformed(w).map_err(at)?,
                None => c.pose,
            };
            entries.push(PathEntryOut {
                camera_to_world: matrix_16(&pose),
                fov,
                aspect,
            });
        }
        Ok(PathFileOut {
            objnerf_frame: frame.name().as_str(),
            camera_type: self.lens.name(),
            render_width: self.width,
            render_height: self.height,
            fps: self.fps,
            seconds: self.seconds,
            is_cycle: false,
            smoothness_value: 0.0,
            default_fov: entries[0].fov,
            default_transition_sec: self.seconds / entries.len() as f64,
            keyframes: entries
                .iter()
                .map(|e| KeyframeOut {
                    matrix: e.camera_to_world,
                    fov: e.fov,
                    aspect: e.aspect,
                })
                .collect(),
            camera_path: entries,
        })
    }

    /// A perspective path through `(pose, vertical fov in degrees)` at `width` x `height`.
    pub fn from_poses(
        width: u32,
        height: u32,
        fps: f64,
        poses: &[(Pose, f64)],
    ) -> Result<CameraPath> {
        positive(fps, "fps").map_err(Error::invalid)?;
        let cameras = poses
            .iter()
            .map(|(pose, fov)| {
                path_camera(PathLens::Perspective, width, height, *fov)
                    .map(|camera| PathCamera {
                        pose: *pose,
                        camera,
                    })
                    .map_err(Error::invalid)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(CameraPath {
            width,
            height,
            fps,
            seconds: cameras.len() as f64 / fps,
            lens: PathLens::Perspective,
            cameras,
        })
    }

    /// The scene's views as a path, in scene order, at the first view's size. A path keeps each
    /// view's pose and vertical field of view; lens distortion and an off-centre principal point,
    /// which a camera path cannot hold, are left out.
    pub fn from_scene_views(scene: &Scene, fps: f64) -> Result<CameraPath> {
        let first = scene
            .images
            .first()
            .ok_or_else(|| Error::invalid(format!("{}: no views", scene.source.display())))?;
        let cam = scene.camera_of(first);
        let poses: Vec<(Pose, f64)> = scene
            .images
            .iter()
            .map(|im| {
                let c = scene.camera_of(im);
                let fov = 2.0 * (0.5 * c.height as f64 / c.focal().1).atan().to_degrees();
                (im.pose, fov)
            })
            .collect();
        Self::from_poses(cam.width, cam.height, fps, &poses)
    }

    /// A ring of cameras looking at a centre (see [`Orbit`]).
    pub fn orbit(orbit: &Orbit) -> Result<CameraPath> {
        let o = orbit;
        let up =
            o.up.try_normalize()
                .ok_or_else(|| Error::invalid("orbit: up is zero"))?;
        if !(o.radius.is_finite() && o.radius > 0.0 && o.elevation.is_finite()) {
            return Err(Error::invalid(format!(
                "orbit: radius {} must be positive and elevation {} finite",
                o.radius, o.elevation
            )));
        }
        if o.views == 0 || !o.center.is_finite() {
            return Err(Error::invalid(
                "orbit: needs at least one view and a finite centre",
            ));
        }
        // The first camera sits along the world axis least aligned with up, made perpendicular.
        let axis = [DVec3::X, DVec3::Y, DVec3::Z]
            .into_iter()
            .min_by(|a, b| a.dot(up).abs().total_cmp(&b.dot(up).abs()))
            .expect("three axes");
        let e1 = (axis - axis.dot(up) * up).normalize();
        let e2 = up.cross(e1);
        let poses: Vec<(Pose, f64)> = (0..o.views)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / o.views as f64;
                let eye = o.center + o.radius * (a.cos() * e1 + a.sin() * e2) + o.elevation * up;
                (Pose::look_at(eye, o.center, up), o.fov_y_deg)
            })
            .collect();
        Self::from_poses(o.width, o.height, o.fps, &poses)
    }
}

/// A ring of `views` cameras around `center`, `radius` away from the up axis through it and
/// `elevation` above it, all looking at the centre, counter-clockwise seen from above.
#[derive(Clone, Debug, PartialEq)]
pub struct Orbit {
    pub center: DVec3,
    pub radius: f64,
    pub elevation: f64,
    pub up: DVec3,
    pub views: usize,
    pub fov_y_deg: f64,
    pub width: u32,
    pub height: u32,
    pub fps: f64,
}
