//! COLMAP's text model files: one record a line (two for an image), `#` comments.

use super::raw::{RawCamera, RawImage, RawPoint};
use crate::error::{Error, Result};
use crate::scene::CameraModel;
use std::path::Path;

fn data_lines(path: &Path, bytes: &[u8]) -> Result<Vec<(usize, String)>> {
    let text = super::super::text(path, bytes)?;
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

pub(super) fn read_cameras_txt(path: &Path, bytes: &[u8]) -> Result<Vec<RawCamera>> {
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

pub(super) fn read_images_txt(path: &Path, bytes: &[u8]) -> Result<Vec<RawImage>> {
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

pub(super) fn read_points_txt(path: &Path, bytes: &[u8]) -> Result<Vec<RawPoint>> {
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
