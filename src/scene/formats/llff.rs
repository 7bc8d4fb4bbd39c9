//! LLFF: `poses_bounds.npy` beside an `images/` folder.
//!
//! Each row of the (N, 17) array is a row-major 3x5 matrix [R | t | hwf] followed by the near and
//! far depth bounds. R's columns are the camera's axes in LLFF's [down, right, back] order; hwf is
//! the height, width and focal length of the images the poses were computed for.

use super::{image_size, intern_camera};
use crate::error::{Error, Result};
use crate::scene::io::is_image;
use crate::scene::{Camera, ImageView, Pose, Scene, SourceFormat};
use std::path::{Path, PathBuf};

/// Read an LLFF scene folder.
pub fn read(dir: &Path) -> Result<Scene> {
    let npy = dir.join("poses_bounds.npy");
    let bytes = std::fs::read(&npy).map_err(|e| Error::io(&npy, e))?;
    parse(dir, &bytes)
}

/// An LLFF scene from the bytes of its `poses_bounds.npy`; the images are looked up in `dir`.
pub fn parse(dir: &Path, npy_bytes: &[u8]) -> Result<Scene> {
    let npy = dir.join("poses_bounds.npy");
    let (shape, data) = parse_npy_f64(&npy, npy_bytes)?;
    if shape.len() != 2 || shape[1] != 17 {
        return Err(Error::format(
            &npy,
            format!(
                "expected shape (N, 17), found ({})",
                shape
                    .iter()
                    .map(|d| d.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    let n = shape[0];
    let files = find_images(dir, n)?;
    let mut cameras = Vec::new();
    let mut images = Vec::with_capacity(n);
    for (i, (row, file)) in data.chunks_exact(17).zip(files).enumerate() {
        let err = |m: String| Error::format(&npy, format!("row {i}: {m}"));
        let at = |r: usize, c: usize| row[r * 5 + c];
        // LLFF [down, right, back] -> OpenGL [right, up, back].
        let gl = [0, 1, 2].map(|r| [at(r, 1), -at(r, 0), at(r, 2), at(r, 3)]);
        let pose = Pose::from_c2w_opengl(gl).map_err(err)?;
        let (h, w, f) = (at(0, 4), at(1, 4), at(2, 4));
        if !(h > 0.0 && w > 0.0 && f > 0.0) {
            return Err(err(format!("hwf = ({h}, {w}, {f}) is not positive")));
        }
        let (iw, ih) = image_size(&file)?;
        // The poses' focal length is for the size in hwf; images may be downscaled copies.
        let (sx, sy) = (iw as f64 / w, ih as f64 / h);
        let camera = Camera::new(
            crate::scene::CameraModel::Pinhole,
            iw,
            ih,
            vec![f * sx, f * sy, 0.5 * iw as f64, 0.5 * ih as f64],
        )
        .map_err(err)?;
        let name = file
            .file_name()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        images.push(ImageView {
            id: i as u32 + 1,
            name,
            path: file,
            camera: intern_camera(&mut cameras, camera),
            pose,
            mask_path: None,
            depth_path: None,
            features: Vec::new(),
            depth_bounds: (row[15] > 0.0 && row[16] > row[15] && row[16].is_finite())
                .then_some([row[15], row[16]]),
        });
    }
    let scene = Scene {
        source: dir.to_path_buf(),
        format: SourceFormat::Llff,
        cameras,
        images,
        points: Vec::new(),
        depth_scale: 1000.0,
        applied_transform: None,
    };
    scene.validate(dir)?;
    Ok(scene)
}

/// Write `scene`'s poses as LLFF's `poses_bounds.npy` (one row per image, in the scene's
/// order; `bounds[i]` = the near and far depth of image i). LLFF keeps a single pinhole focal
/// length per image (hwf): every camera must be a centred pinhole with fx = fy, as LLFF's own
/// (`imgs2poses.py`) are.
pub fn write(scene: &Scene, bounds: &[[f64; 2]], path: &Path) -> Result<()> {
    let mut values = Vec::with_capacity(scene.images.len() * 17);
    for (im, b) in scene.images.iter().zip(bounds) {
        let cam = scene.camera_of(im);
        let (fx, fy) = cam.focal();
        let (w, h) = (cam.width as f64, cam.height as f64);
        let centred = cam.principal_point() == (0.5 * w, 0.5 * h);
        if (fx - fy).abs() > 1e-9 * fx || !centred || !cam.is_pinhole() {
            return Err(Error::invalid(format!(
                "{}: image {} has a camera LLFF cannot store (it keeps one focal length, a centred principal point and no distortion)",
                path.display(),
                im.name
            )));
        }
        let gl = im.pose.c2w_opengl();
        // OpenGL [right, up, back] -> LLFF [down, right, back].
        for (r, hwf) in gl.iter().zip([h, w, fx]) {
            values.extend([-r[1], r[0], r[2], r[3], hwf]);
        }
        values.extend(b);
    }
    let mut header = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({}, 17), }}",
        scene.images.len()
    );
    // The header, with its newline, pads the data to a 64-byte boundary (npy format 1.0).
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    crate::util::write_atomic(path, |w| {
        w.write_all(b"\x93NUMPY\x01\x00")?;
        w.write_all(&(header.len() as u16).to_le_bytes())?;
        w.write_all(header.as_bytes())?;
        for v in &values {
            w.write_all(&v.to_le_bytes())?;
        }
        Ok(())
    })
}

/// The sorted images of `images/`, or of the first `images_*` folder holding exactly `n`.
fn find_images(dir: &Path, n: usize) -> Result<Vec<PathBuf>> {
    let list = |d: &Path| -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(d)
            .map(|rd| {
                rd.filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.is_file() && is_image(p))
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    };
    let mut folders = vec![dir.join("images")];
    let mut others: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_dir()
                && p.file_name()
                    .is_some_and(|s| s.to_string_lossy().starts_with("images_"))
        })
        .collect();
    others.sort();
    folders.extend(others);
    let mut seen = Vec::new();
    for f in &folders {
        let files = list(f);
        if files.len() == n {
            return Ok(files);
        }
        if f.is_dir() {
            seen.push(format!("{} has {}", f.display(), files.len()));
        }
    }
    Err(Error::format(
        dir.join("poses_bounds.npy"),
        format!(
            "{n} poses but no image folder with {n} images ({})",
            if seen.is_empty() {
                "no images/ folder".to_string()
            } else {
                seen.join(", ")
            }
        ),
    ))
}

/// A float array from a .npy file (little-endian '<f8' or '<f4', C order): shape and values.
pub fn read_npy_f64(path: &Path) -> Result<(Vec<usize>, Vec<f64>)> {
    let buf = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_npy_f64(path, &buf)
}

/// [`read_npy_f64`] on the file's bytes (`path` names it in errors).
pub fn parse_npy_f64(path: &Path, buf: &[u8]) -> Result<(Vec<usize>, Vec<f64>)> {
    let bad = |m: &str| Error::format(path, format!("not a valid .npy file: {m}"));
    if buf.len() < 10 || &buf[..6] != b"\x93NUMPY" {
        return Err(bad("no \\x93NUMPY magic"));
    }
    let (header_len, start) = match buf[6] {
        1 => (u16::from_le_bytes([buf[8], buf[9]]) as usize, 10),
        2 | 3 if buf.len() >= 12 => (
            u32::from_le_bytes([buf[8], buf[9], buf[10], buf[11]]) as usize,
            12,
        ),
        v => return Err(bad(&format!("unknown version {v}"))),
    };
    let header = buf
        .get(start..start + header_len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(|| bad("truncated header"))?;
    let value_of = |key: &str| -> Option<&str> {
        let at = header.find(&format!("'{key}'"))? + key.len() + 2;
        Some(header[at..].trim_start().strip_prefix(':')?.trim_start())
    };
    let descr = value_of("descr").ok_or_else(|| bad("no 'descr' in header"))?;
    let size = if descr.starts_with("'<f8'") {
        8
    } else if descr.starts_with("'<f4'") {
        4
    } else {
        let d = descr.split(',').next().unwrap_or(descr);
        return Err(Error::format(
            path,
            format!("dtype {d} is not supported (little-endian float64 or float32)"),
        ));
    };
    if !value_of("fortran_order").is_some_and(|v| v.starts_with("False")) {
        return Err(Error::format(
            path,
            "Fortran-order arrays are not supported",
        ));
    }
    let shape_text = value_of("shape")
        .and_then(|v| v.strip_prefix('('))
        .and_then(|v| v.split(')').next())
        .ok_or_else(|| bad("no 'shape' in header"))?;
    let shape = shape_text
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<usize>()
                .map_err(|_| bad("shape is not a tuple of integers"))
        })
        .collect::<Result<Vec<_>>>()?;
    let count = shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
    let body = &buf[start + header_len..];
    match count {
        Some(c) if c.checked_mul(size) == Some(body.len()) => {}
        _ => {
            return Err(Error::format(
                path,
                format!(
                    "shape {shape:?} of {size}-byte values does not match the {} bytes of data",
                    body.len()
                ),
            ))
        }
    }
    let values = body
        .chunks_exact(size)
        .map(|b| match b.len() {
            8 => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
            _ => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        })
        .collect();
    Ok((shape, values))
}
