//! COLMAP's binary model files: the whole file in memory, every read bounds-checked, every
//! count checked against the bytes left before anything is allocated.

use super::raw::{RawCamera, RawImage, RawPoint};
use crate::error::{Error, Result};
use crate::scene::CameraModel;
use std::path::Path;

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

/// The records (the file's leading u64 says how many, each at least `min_record` bytes)
/// read by `record`, and nothing after them.
fn read_records<T>(
    path: &Path,
    buf: &[u8],
    min_record: usize,
    what: &str,
    mut record: impl FnMut(&mut BinReader) -> Result<T>,
) -> Result<Vec<T>> {
    let mut r = BinReader { path, buf, pos: 0 };
    let n = r.count(min_record, what)?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        out.push(record(&mut r)?);
    }
    r.finish()?;
    Ok(out)
}

pub(super) fn read_cameras_bin(path: &Path, buf: &[u8]) -> Result<Vec<RawCamera>> {
    read_records(path, buf, 24, "number of cameras", |r| {
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
        Ok(RawCamera {
            id,
            model_id,
            width,
            height,
            params,
        })
    })
}

pub(super) fn read_images_bin(path: &Path, buf: &[u8]) -> Result<Vec<RawImage>> {
    read_records(path, buf, 73, "number of images", |r| {
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
        Ok(RawImage {
            id,
            qvec: q,
            tvec: t,
            camera_id,
            name,
            points2d,
        })
    })
}

pub(super) fn read_points_bin(path: &Path, buf: &[u8]) -> Result<Vec<RawPoint>> {
    read_records(path, buf, 51, "number of points", |r| {
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
        Ok(RawPoint {
            id,
            xyz,
            rgb,
            error,
            track,
        })
    })
}
