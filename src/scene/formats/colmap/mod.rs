//! COLMAP sparse models, binary and text: cameras, images with their 2D features, and points3D
//! with their tracks. Ids and order are kept so that a model read and written again is unchanged.

use crate::error::{Error, Result};
use crate::scene::{
    Camera, CameraModel, Feature, ImageView, Point3D, Pose, Scene, SceneCamera, SourceFormat,
    TrackElement,
};
use crate::util::write_atomic;
use glam::{DVec2, DVec3};
use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};

mod binary;
mod raw;
mod text;

use binary::{read_cameras_bin, read_images_bin, read_points_bin};
use raw::{RawCamera, RawImage, RawPoint};
use text::{read_cameras_txt, read_images_txt, read_points_txt};

/// Which files make up a model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelFormat {
    Binary,
    Text,
}

impl ModelFormat {
    fn ext(self) -> &'static str {
        match self {
            ModelFormat::Binary => "bin",
            ModelFormat::Text => "txt",
        }
    }
}

/// Detect whether `dir` holds a binary or text model (binary preferred when both exist).
pub fn detect(dir: &Path) -> Option<ModelFormat> {
    [ModelFormat::Binary, ModelFormat::Text]
        .into_iter()
        .find(|f| dir.join(format!("cameras.{}", f.ext())).is_file())
}

/// Read a COLMAP model from `dir`; image paths are `images_root/<name>`.
pub fn read_model(dir: &Path, images_root: &Path) -> Result<Scene> {
    let format = detect(dir)
        .ok_or_else(|| Error::format(dir, "not a COLMAP model: no cameras.bin or cameras.txt"))?;
    let file = |n: &str| dir.join(format!("{n}.{}", format.ext()));
    // One file at a time, so a broken cameras file is reported before images are read.
    let cameras = read_file(&file("cameras"))?;
    let cameras = parse_cameras(&file("cameras"), format, &cameras)?;
    let images = read_file(&file("images"))?;
    let images = parse_images(&file("images"), format, &images)?;
    let points = read_file(&file("points3D"))?;
    let points = parse_points(&file("points3D"), format, &points)?;
    let raw = RawModel {
        cameras,
        images,
        points,
    };
    raw.into_scene(dir, format, images_root, src_format(format))
}

/// A COLMAP model from the bytes of its three files, as [`read_model`] reads them from `dir`
/// (which only names the files in errors; nothing is read from it).
pub fn parse_model(
    dir: &Path,
    images_root: &Path,
    format: ModelFormat,
    cameras: &[u8],
    images: &[u8],
    points3d: &[u8],
) -> Result<Scene> {
    let file = |n: &str| dir.join(format!("{n}.{}", format.ext()));
    let raw = RawModel {
        cameras: parse_cameras(&file("cameras"), format, cameras)?,
        images: parse_images(&file("images"), format, images)?,
        points: parse_points(&file("points3D"), format, points3d)?,
    };
    raw.into_scene(dir, format, images_root, src_format(format))
}

fn parse_cameras(path: &Path, format: ModelFormat, bytes: &[u8]) -> Result<Vec<RawCamera>> {
    match format {
        ModelFormat::Binary => read_cameras_bin(path, bytes),
        ModelFormat::Text => read_cameras_txt(path, bytes),
    }
}

fn parse_images(path: &Path, format: ModelFormat, bytes: &[u8]) -> Result<Vec<RawImage>> {
    match format {
        ModelFormat::Binary => read_images_bin(path, bytes),
        ModelFormat::Text => read_images_txt(path, bytes),
    }
}

fn parse_points(path: &Path, format: ModelFormat, bytes: &[u8]) -> Result<Vec<RawPoint>> {
    match format {
        ModelFormat::Binary => read_points_bin(path, bytes),
        ModelFormat::Text => read_points_txt(path, bytes),
    }
}

fn src_format(format: ModelFormat) -> SourceFormat {
    match format {
        ModelFormat::Binary => SourceFormat::ColmapBinary,
        ModelFormat::Text => SourceFormat::ColmapText,
    }
}

/// Write `scene` as a COLMAP model into `dir` (created if needed); each file is written atomically.
pub fn write_model(scene: &Scene, dir: &Path, format: ModelFormat) -> Result<()> {
    let raw = RawModel::from_scene(scene)?;
    let p = |n: &str| dir.join(format!("{n}.{}", format.ext()));
    match format {
        ModelFormat::Binary => {
            write_atomic(&p("cameras"), |w| raw.write_cameras_bin(w))?;
            write_atomic(&p("images"), |w| raw.write_images_bin(w))?;
            write_atomic(&p("points3D"), |w| raw.write_points_bin(w))?;
        }
        ModelFormat::Text => {
            write_atomic(&p("cameras"), |w| raw.write_cameras_txt(w))?;
            write_atomic(&p("images"), |w| raw.write_images_txt(w))?;
            write_atomic(&p("points3D"), |w| raw.write_points_txt(w))?;
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// The model read whole: cameras, images and points as COLMAP stores them (`raw.rs`).

struct RawModel {
    cameras: Vec<RawCamera>,
    images: Vec<RawImage>,
    points: Vec<RawPoint>,
}

impl RawModel {
    fn into_scene(
        self,
        dir: &Path,
        format: ModelFormat,
        images_root: &Path,
        src: SourceFormat,
    ) -> Result<Scene> {
        let file = |n: &str| dir.join(format!("{n}.{}", format.ext()));
        let mut cameras = Vec::with_capacity(self.cameras.len());
        let mut cam_index = HashMap::new();
        for c in self.cameras {
            let model = CameraModel::from_id(c.model_id).ok_or_else(|| {
                Error::format(
                    file("cameras"),
                    format!(
                        "camera {}: unknown camera model id {} (COLMAP ids are 0-10)",
                        c.id, c.model_id
                    ),
                )
            })?;
            let (w, h) = (u32::try_from(c.width), u32::try_from(c.height));
            let (Ok(w), Ok(h)) = (w, h) else {
                return Err(Error::format(
                    file("cameras"),
                    format!(
                        "camera {}: size {}x{} is too large",
                        c.id, c.width, c.height
                    ),
                ));
            };
            let camera = Camera::new(model, w, h, c.params)
                .map_err(|m| Error::format(file("cameras"), format!("camera {}: {m}", c.id)))?;
            if cam_index.insert(c.id, cameras.len()).is_some() {
                return Err(Error::format(
                    file("cameras"),
                    format!("camera id {} appears twice", c.id),
                ));
            }
            cameras.push(SceneCamera { id: c.id, camera });
        }
        let mut point_index = HashMap::with_capacity(self.points.len());
        for (i, p) in self.points.iter().enumerate() {
            if point_index.insert(p.id, i).is_some() {
                return Err(Error::format(
                    file("points3D"),
                    format!("point3D id {} appears twice", p.id),
                ));
            }
        }
        let mut images = Vec::with_capacity(self.images.len());
        let mut image_index = HashMap::new();
        for im in self.images {
            let camera = *cam_index.get(&im.camera_id).ok_or_else(|| {
                Error::format(
                    file("images"),
                    format!(
                        "image '{}' uses camera {}, which is not in the model",
                        im.name, im.camera_id
                    ),
                )
            })?;
            let pose = Pose::from_colmap(im.qvec, im.tvec)
                .map_err(|m| Error::format(file("images"), format!("image '{}': {m}", im.name)))?;
            let mut features = Vec::with_capacity(im.points2d.len());
            for &(x, y, pid) in &im.points2d {
                if !(x.is_finite() && y.is_finite()) {
                    return Err(Error::format(
                        file("images"),
                        format!("image '{}' has a non-finite 2D point ({x}, {y})", im.name),
                    ));
                }
                let point = if pid < 0 || pid as u64 == u64::MAX {
                    None
                } else {
                    Some(*point_index.get(&(pid as u64)).ok_or_else(|| {
                        Error::format(
                            file("images"),
                            format!(
                                "image '{}' refers to point3D {pid}, which is not in the model",
                                im.name
                            ),
                        )
                    })?)
                };
                features.push(Feature {
                    xy: DVec2::new(x, y),
                    point,
                });
            }
            if image_index.insert(im.id, images.len()).is_some() {
                return Err(Error::format(
                    file("images"),
                    format!("image id {} appears twice", im.id),
                ));
            }
            images.push(ImageView {
                id: im.id,
                path: images_root.join(&im.name),
                name: im.name,
                camera,
                pose,
                mask_path: None,
                depth_path: None,
                features,
                depth_bounds: None,
            });
        }
        let mut points = Vec::with_capacity(self.points.len());
        for p in self.points {
            if !p.xyz.iter().all(|v| v.is_finite()) {
                return Err(Error::format(
                    file("points3D"),
                    format!("point3D {} is not finite: {:?}", p.id, p.xyz),
                ));
            }
            let mut track = Vec::with_capacity(p.track.len());
            for &(iid, idx) in &p.track {
                let image = *image_index.get(&iid).ok_or_else(|| {
                    Error::format(
                        file("points3D"),
                        format!(
                            "point3D {} is seen in image {iid}, which is not in the model",
                            p.id
                        ),
                    )
                })?;
                if idx as usize >= images[image].features.len() {
                    return Err(Error::format(
                        file("points3D"),
                        format!(
                            "point3D {} refers to 2D point {idx} of image {iid}, which has {}",
                            p.id,
                            images[image].features.len()
                        ),
                    ));
                }
                track.push(TrackElement {
                    image,
                    feature: idx as usize,
                });
            }
            points.push(Point3D {
                id: p.id,
                xyz: DVec3::from_array(p.xyz),
                rgb: p.rgb,
                error: p.error,
                track,
            });
        }
        let scene = Scene {
            source: dir.to_path_buf(),
            format: src,
            cameras,
            images,
            points,
            depth_scale: 1000.0,
            applied_transform: None,
        };
        scene.validate(dir)?;
        Ok(scene)
    }

    fn from_scene(scene: &Scene) -> Result<RawModel> {
        let cameras = scene
            .cameras
            .iter()
            .map(|c| RawCamera {
                id: c.id,
                model_id: c.camera.model.id(),
                width: c.camera.width as u64,
                height: c.camera.height as u64,
                params: c.camera.params.clone(),
            })
            .collect();
        let images = scene
            .images
            .iter()
            .map(|im| RawImage {
                id: im.id,
                qvec: im.pose.qvec(),
                tvec: im.pose.tvec(),
                camera_id: scene.cameras[im.camera].id,
                name: im.name.clone(),
                points2d: im
                    .features
                    .iter()
                    .map(|f| {
                        (
                            f.xy.x,
                            f.xy.y,
                            f.point.map(|p| scene.points[p].id as i64).unwrap_or(-1),
                        )
                    })
                    .collect(),
            })
            .collect();
        let points = scene
            .points
            .iter()
            .map(|p| RawPoint {
                id: p.id,
                xyz: p.xyz.to_array(),
                rgb: p.rgb,
                error: p.error,
                track: p
                    .track
                    .iter()
                    .map(|t| (scene.images[t.image].id, t.feature as u32))
                    .collect(),
            })
            .collect();
        Ok(RawModel {
            cameras,
            images,
            points,
        })
    }

    // --- binary writers -----------------------------------------------------------------------

    fn write_cameras_bin(&self, w: &mut dyn Write) -> std::io::Result<()> {
        w.write_all(&(self.cameras.len() as u64).to_le_bytes())?;
        for c in &self.cameras {
            w.write_all(&(c.id as i32).to_le_bytes())?;
            w.write_all(&c.model_id.to_le_bytes())?;
            w.write_all(&c.width.to_le_bytes())?;
            w.write_all(&c.height.to_le_bytes())?;
            for p in &c.params {
                w.write_all(&p.to_le_bytes())?;
            }
        }
        Ok(())
    }

    fn write_images_bin(&self, w: &mut dyn Write) -> std::io::Result<()> {
        w.write_all(&(self.images.len() as u64).to_le_bytes())?;
        for im in &self.images {
            w.write_all(&(im.id as i32).to_le_bytes())?;
            for v in im.qvec.iter().chain(im.tvec.iter()) {
                w.write_all(&v.to_le_bytes())?;
            }
            w.write_all(&(im.camera_id as i32).to_le_bytes())?;
            w.write_all(im.name.as_bytes())?;
            w.write_all(&[0])?;
            w.write_all(&(im.points2d.len() as u64).to_le_bytes())?;
            for &(x, y, id) in &im.points2d {
                w.write_all(&x.to_le_bytes())?;
                w.write_all(&y.to_le_bytes())?;
                w.write_all(&id.to_le_bytes())?;
            }
        }
        Ok(())
    }

    fn write_points_bin(&self, w: &mut dyn Write) -> std::io::Result<()> {
        w.write_all(&(self.points.len() as u64).to_le_bytes())?;
        for p in &self.points {
            w.write_all(&p.id.to_le_bytes())?;
            for v in &p.xyz {
                w.write_all(&v.to_le_bytes())?;
            }
            w.write_all(&p.rgb)?;
            w.write_all(&p.error.to_le_bytes())?;
            w.write_all(&(p.track.len() as u64).to_le_bytes())?;
            for &(iid, idx) in &p.track {
                w.write_all(&(iid as i32).to_le_bytes())?;
                w.write_all(&(idx as i32).to_le_bytes())?;
            }
        }
        Ok(())
    }

    // --- text writers (COLMAP's layout; `{}` prints the shortest exact f64) --------------------

    fn write_cameras_txt(&self, w: &mut dyn Write) -> std::io::Result<()> {
        writeln!(w, "# Camera list with one line of data per camera:")?;
        writeln!(w, "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]")?;
        writeln!(w, "# Number of cameras: {}", self.cameras.len())?;
        for c in &self.cameras {
            let name = CameraModel::from_id(c.model_id)
                .map(|m| m.name())
                .unwrap_or("UNKNOWN");
            write!(w, "{} {} {} {}", c.id, name, c.width, c.height)?;
            for p in &c.params {
                write!(w, " {p}")?;
            }
            writeln!(w)?;
        }
        Ok(())
    }

    fn write_images_txt(&self, w: &mut dyn Write) -> std::io::Result<()> {
        let n_obs: usize = self
            .images
            .iter()
            .map(|i| i.points2d.iter().filter(|p| p.2 >= 0).count())
            .sum();
        let mean = if self.images.is_empty() {
            0.0
        } else {
            n_obs as f64 / self.images.len() as f64
        };
        writeln!(w, "# Image list with two lines of data per image:")?;
        writeln!(
            w,
            "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME"
        )?;
        writeln!(w, "#   POINTS2D[] as (X, Y, POINT3D_ID)")?;
        writeln!(
            w,
            "# Number of images: {}, mean observations per image: {mean}",
            self.images.len()
        )?;
        for im in &self.images {
            let [qw, qx, qy, qz] = im.qvec;
            let [tx, ty, tz] = im.tvec;
            writeln!(
                w,
                "{} {qw} {qx} {qy} {qz} {tx} {ty} {tz} {} {}",
                im.id, im.camera_id, im.name
            )?;
            let mut first = true;
            for &(x, y, id) in &im.points2d {
                if !first {
                    write!(w, " ")?;
                }
                first = false;
                write!(w, "{x} {y} {id}")?;
            }
            writeln!(w)?;
        }
        Ok(())
    }

    fn write_points_txt(&self, w: &mut dyn Write) -> std::io::Result<()> {
        let total: usize = self.points.iter().map(|p| p.track.len()).sum();
        let mean = if self.points.is_empty() {
            0.0
        } else {
            total as f64 / self.points.len() as f64
        };
        writeln!(w, "# 3D point list with one line of data per point:")?;
        writeln!(
            w,
            "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)"
        )?;
        writeln!(
            w,
            "# Number of points: {}, mean track length: {mean}",
            self.points.len()
        )?;
        for p in &self.points {
            let [x, y, z] = p.xyz;
            let [r, g, b] = p.rgb;
            write!(w, "{} {x} {y} {z} {r} {g} {b} {}", p.id, p.error)?;
            for &(iid, idx) in &p.track {
                write!(w, " {iid} {idx}")?;
            }
            writeln!(w)?;
        }
        Ok(())
    }
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::io(path, e))
}

/// Where a model's images are, by COLMAP's usual layouts: `X/sparse/N` → `X/images`,
/// `X/colmap/sparse/N` → `X/images` (ns-process-data), a model in `X` → `X/images`, else the
/// model's parent's `images`.
pub fn default_images_root(model_dir: &Path) -> PathBuf {
    let mut candidates = Vec::new();
    if let Some(p) = model_dir.parent() {
        if p.file_name().is_some_and(|n| n == "sparse") {
            if let Some(pp) = p.parent() {
                candidates.push(pp.join("images"));
                // ns-process-data: <out>/colmap/sparse/0 with the images in <out>/images.
                if pp.file_name().is_some_and(|n| n == "colmap") {
                    if let Some(ppp) = pp.parent() {
                        candidates.push(ppp.join("images"));
                    }
                }
            }
        }
        candidates.push(p.join("images"));
    }
    candidates.push(model_dir.join("images"));
    candidates
        .iter()
        .find(|c| c.is_dir())
        .cloned()
        .unwrap_or_else(|| candidates[0].clone())
}
