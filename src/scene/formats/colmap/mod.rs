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
// The model as COLMAP stores it: ids everywhere.

struct RawCamera {
    id: u32,
    model_id: i32,
    width: u64,
    height: u64,
    params: Vec<f64>,
}

struct RawImage {
    id: u32,
    qvec: [f64; 4],
    tvec: [f64; 3],
    camera_id: u32,
    name: String,
    /// (x, y, point3D id or -1)
    points2d: Vec<(f64, f64, i64)>,
}

struct RawPoint {
    id: u64,
    xyz: [f64; 3],
    rgb: [u8; 3],
    error: f64,
    /// (image id, point2D index)
    track: Vec<(u32, u32)>,
}

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

// ---------------------------------------------------------------------------------------------
// Binary readers: the whole file in memory, every read bounds-checked.

struct BinReader<'a> {
    path: &'a Path,
    buf: &'a [u8],
    pos: usize,
}

impl<'a> BinReader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if self.buf.len() - self.pos < n {
            return Err(Error::format(
                self.path,
                format!(
                    "truncated: {what} needs {n} bytes at offset {}, the file has {}",
                    self.pos,
                    self.buf.len()
                ),
            ));
        }
        let s = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u8(&mut self, what: &str) -> Result<u8> {
        Ok(self.take(1, what)?[0])
    }
    fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn i64(&mut self, what: &str) -> Result<i64> {
        Ok(i64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    /// A count of records each at least `min_record` bytes long, checked against what is left
    /// so that a corrupt count cannot ask for a huge allocation.
    fn count(&mut self, min_record: usize, what: &str) -> Result<usize> {
        let n = self.u64(what)?;
        let left = (self.buf.len() - self.pos) as u64;
        if n.saturating_mul(min_record as u64) > left {
            return Err(Error::format(
                self.path,
                format!(
                    "corrupt or truncated: {what} says {n} records but only {left} bytes follow"
                ),
            ));
        }
        Ok(n as usize)
    }
    fn id32(&mut self, what: &str) -> Result<u32> {
        let v = self.i32(what)?;
        u32::try_from(v).map_err(|_| Error::format(self.path, format!("{what} {v} is negative")))
    }
    fn finish(&self) -> Result<()> {
        if self.pos != self.buf.len() {
            return Err(Error::format(
                self.path,
                format!(
                    "{} unexpected bytes after the last record",
                    self.buf.len() - self.pos
                ),
            ));
        }
        Ok(())
    }
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::io(path, e))
}

fn read_cameras_bin(path: &Path, buf: &[u8]) -> Result<Vec<RawCamera>> {
    let mut r = BinReader { path, buf, pos: 0 };
    let n = r.count(24, "number of cameras")?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let id = r.id32("camera id")?;
        let model_id = r.i32("camera model")?;
        let model = CameraModel::from_id(model_id).ok_or_else(|| {
            Error::format(
                path,
                format!("camera {id}: unknown camera model id {model_id} (COLMAP ids are 0-10)"),
            )
        })?;
        let width = r.u64("camera width")?;
        let height = r.u64("camera height")?;
        let params = (0..model.num_params())
            .map(|_| r.f64("camera parameter"))
            .collect::<Result<Vec<_>>>()?;
        out.push(RawCamera {
            id,
            model_id,
            width,
            height,
            params,
        });
    }
    r.finish()?;
    Ok(out)
}

fn read_images_bin(path: &Path, buf: &[u8]) -> Result<Vec<RawImage>> {
    let mut r = BinReader { path, buf, pos: 0 };
    let n = r.count(73, "number of images")?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let id = r.id32("image id")?;
        let mut q = [0.0; 4];
        for v in q.iter_mut() {
            *v = r.f64("image rotation")?;
        }
        let mut t = [0.0; 3];
        for v in t.iter_mut() {
            *v = r.f64("image translation")?;
        }
        let camera_id = r.id32("image camera id")?;
        let start = r.pos;
        let end = buf[start..].iter().position(|&b| b == 0).ok_or_else(|| {
            Error::format(
                path,
                format!("truncated: image {id}'s name has no terminating NUL"),
            )
        })?;
        let name = std::str::from_utf8(&buf[start..start + end])
            .map_err(|_| Error::format(path, format!("image {id}'s name is not UTF-8")))?
            .to_string();
        r.pos = start + end + 1;
        let n2d = r.count(24, "number of 2D points")?;
        let mut points2d = Vec::with_capacity(n2d);
        for _ in 0..n2d {
            let x = r.f64("2D point x")?;
            let y = r.f64("2D point y")?;
            let pid = r.i64("2D point's point3D id")?;
            points2d.push((x, y, pid));
        }
        out.push(RawImage {
            id,
            qvec: q,
            tvec: t,
            camera_id,
            name,
            points2d,
        });
    }
    r.finish()?;
    Ok(out)
}

fn read_points_bin(path: &Path, buf: &[u8]) -> Result<Vec<RawPoint>> {
    let mut r = BinReader { path, buf, pos: 0 };
    let n = r.count(51, "number of points")?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let id = r.u64("point3D id")?;
        let xyz = [r.f64("point x")?, r.f64("point y")?, r.f64("point z")?];
        let rgb = [
            r.u8("point colour")?,
            r.u8("point colour")?,
            r.u8("point colour")?,
        ];
        let error = r.f64("point error")?;
        let len = r.count(8, "track length")?;
        let mut track = Vec::with_capacity(len);
        for _ in 0..len {
            let iid = r.id32("track image id")?;
            let idx = r.id32("track 2D point index")?;
            track.push((iid, idx));
        }
        out.push(RawPoint {
            id,
            xyz,
            rgb,
            error,
            track,
        });
    }
    r.finish()?;
    Ok(out)
}

// ---------------------------------------------------------------------------------------------
// Text readers.

fn data_lines(path: &Path, bytes: &[u8]) -> Result<Vec<(usize, String)>> {
    let text = super::text(path, bytes)?;
    Ok(text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim_start().starts_with('#'))
        .map(|(i, l)| (i + 1, l.trim().to_string()))
        .collect())
}

fn parse<T: std::str::FromStr>(
    path: &Path,
    line: usize,
    tok: Option<&str>,
    what: &str,
) -> Result<T> {
    let tok = tok.ok_or_else(|| Error::format(path, format!("line {line}: missing {what}")))?;
    tok.parse::<T>().map_err(|_| {
        Error::format(
            path,
            format!("line {line}: {what} '{tok}' is not a valid number"),
        )
    })
}

fn read_cameras_txt(path: &Path, bytes: &[u8]) -> Result<Vec<RawCamera>> {
    let mut out = Vec::new();
    for (ln, line) in data_lines(path, bytes)? {
        if line.is_empty() {
            continue;
        }
        let mut it = line.split_whitespace();
        let id: u32 = parse(path, ln, it.next(), "camera id")?;
        let name = it
            .next()
            .ok_or_else(|| Error::format(path, format!("line {ln}: missing camera model")))?;
        let model = CameraModel::from_name(name).ok_or_else(|| {
            Error::format(path, format!("line {ln}: unknown camera model '{name}'"))
        })?;
        let width: u64 = parse(path, ln, it.next(), "width")?;
        let height: u64 = parse(path, ln, it.next(), "height")?;
        let params = it
            .map(|t| parse::<f64>(path, ln, Some(t), "camera parameter"))
            .collect::<Result<Vec<_>>>()?;
        out.push(RawCamera {
            id,
            model_id: model.id(),
            width,
            height,
            params,
        });
    }
    Ok(out)
}

fn read_images_txt(path: &Path, bytes: &[u8]) -> Result<Vec<RawImage>> {
    let lines = data_lines(path, bytes)?;
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let (ln, line) = &lines[i];
        if line.is_empty() && out.is_empty() {
            i += 1;
            continue;
        }
        let toks: Vec<&str> = line.split_whitespace().collect();
        if toks.len() < 10 {
            return Err(Error::format(
                path,
                format!(
                    "line {ln}: an image line needs 10 fields, found {}",
                    toks.len()
                ),
            ));
        }
        let id: u32 = parse(path, *ln, Some(toks[0]), "image id")?;
        let mut q = [0.0; 4];
        for (k, v) in q.iter_mut().enumerate() {
            *v = parse(path, *ln, Some(toks[1 + k]), "quaternion")?;
        }
        let mut t = [0.0; 3];
        for (k, v) in t.iter_mut().enumerate() {
            *v = parse(path, *ln, Some(toks[5 + k]), "translation")?;
        }
        let camera_id: u32 = parse(path, *ln, Some(toks[8]), "camera id")?;
        let name = toks[9..].join(" ");
        let mut points2d = Vec::new();
        if let Some((ln2, pts)) = lines.get(i + 1) {
            let vals: Vec<&str> = pts.split_whitespace().collect();
            if vals.len() % 3 != 0 {
                return Err(Error::format(
                    path,
                    format!(
                        "line {ln2}: 2D points come in triples (X Y POINT3D_ID), found {} values",
                        vals.len()
                    ),
                ));
            }
            for c in vals.chunks(3) {
                points2d.push((
                    parse(path, *ln2, Some(c[0]), "2D point x")?,
                    parse(path, *ln2, Some(c[1]), "2D point y")?,
                    parse(path, *ln2, Some(c[2]), "point3D id")?,
                ));
            }
        } else {
            return Err(Error::format(
                path,
                format!("line {ln}: image {id} has no 2D-point line (truncated?)"),
            ));
        }
        out.push(RawImage {
            id,
            qvec: q,
            tvec: t,
            camera_id,
            name,
            points2d,
        });
        i += 2;
    }
    Ok(out)
}

fn read_points_txt(path: &Path, bytes: &[u8]) -> Result<Vec<RawPoint>> {
    let mut out = Vec::new();
    for (ln, line) in data_lines(path, bytes)? {
        if line.is_empty() {
            continue;
        }
        let toks: Vec<&str> = line.split_whitespace().collect();
        if toks.len() < 8 || (toks.len() - 8) % 2 != 0 {
            return Err(Error::format(
                path,
                format!("line {ln}: a point line needs 8 fields and (IMAGE_ID, POINT2D_IDX) pairs"),
            ));
        }
        let id: u64 = parse(path, ln, Some(toks[0]), "point3D id")?;
        let xyz = [
            parse(path, ln, Some(toks[1]), "x")?,
            parse(path, ln, Some(toks[2]), "y")?,
            parse(path, ln, Some(toks[3]), "z")?,
        ];
        let rgb = [
            parse(path, ln, Some(toks[4]), "red")?,
            parse(path, ln, Some(toks[5]), "green")?,
            parse(path, ln, Some(toks[6]), "blue")?,
        ];
        let error = parse(path, ln, Some(toks[7]), "error")?;
        let track = toks[8..]
            .chunks(2)
            .map(|c| {
                Ok((
                    parse(path, ln, Some(c[0]), "track image id")?,
                    parse(path, ln, Some(c[1]), "track 2D index")?,
                ))
            })
            .collect::<Result<Vec<_>>>()?;
        out.push(RawPoint {
            id,
            xyz,
            rgb,
            error,
            track,
        });
    }
    Ok(out)
}

/// Where a model's images are, by COLMAP's usual layouts: `X/sparse/N` → `X/images`,
/// a model in `X` → `X/images`, else the model's parent's `images`.
pub fn default_images_root(model_dir: &Path) -> PathBuf {
    let candidates: Vec<PathBuf> = {
        let mut c = Vec::new();
        if let Some(p) = model_dir.parent() {
            if p.file_name().is_some_and(|n| n == "sparse") {
                if let Some(pp) = p.parent() {
                    c.push(pp.join("images"));
                }
            }
            c.push(p.join("images"));
        }
        c.push(model_dir.join("images"));
        c
    };
    candidates
        .iter()
        .find(|c| c.is_dir())
        .cloned()
        .unwrap_or_else(|| candidates[0].clone())
}
