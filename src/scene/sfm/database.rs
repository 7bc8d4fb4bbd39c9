//! COLMAP's database kept beside the model (`out/database.db`), so that a run opens in COLMAP's
//! GUI (File > Import model: `out/sparse/0`, this database, `out/images`) and COLMAP can go on
//! from it. COLMAP saw the staged images (`00000.png`, maybe downscaled): the copy gets the
//! model's image names, and with `--downscale` its cameras, keypoints and two-view geometries are
//! scaled to the original image size, as the model is.

use crate::error::{Error, Result};
use crate::scene::{Camera, CameraModel};
use rusqlite::{params, Connection, OptionalExtension};
use std::collections::HashMap;
use std::path::Path;

/// COLMAP's pair id: `MAX_IMAGES * image_id1 + image_id2` with `image_id1 < image_id2`.
const MAX_IMAGES: i64 = i32::MAX as i64;

/// A pixel scale (full size / staged size) per axis.
type Scale = [f64; 3];

/// Copy COLMAP's database `src` to `dest`, renaming each staged image `staged[k]` to
/// `originals[k]` and scaling what is in pixels by `full_sizes[k]` / the staged camera's size.
pub(super) fn keep_database(
    src: &Path,
    dest: &Path,
    staged: &[String],
    originals: &[String],
    full_sizes: &[(u32, u32)],
) -> Result<()> {
    std::fs::copy(src, dest).map_err(|e| Error::io(src, e))?;
    let err = sql_error(dest);
    let mut conn = Connection::open(dest).map_err(err)?;
    let tx = conn.transaction().map_err(err)?;
    let images = {
        let mut stmt = tx
            .prepare("SELECT image_id, name, camera_id FROM images")
            .map_err(err)?;
        let rows = stmt
            .query_map([], |r| {
                Ok((r.get::<_, i64>(0)?, r.get::<_, String>(1)?, r.get(2)?))
            })
            .map_err(err)?;
        rows.collect::<std::result::Result<Vec<(i64, String, i64)>, _>>()
            .map_err(err)?
    };
    // Through names no image has, so that no rename collides with a name not yet renamed.
    tx.execute("UPDATE images SET name = char(1) || image_id", [])
        .map_err(err)?;
    let mut camera_full_size = HashMap::new();
    let mut image_camera = HashMap::new();
    for (id, name, camera) in &images {
        let k = staged.iter().position(|n| n == name).ok_or_else(|| {
            Error::format(src, format!("image '{name}' is not one objnerf staged"))
        })?;
        tx.execute(
            "UPDATE images SET name = ?1 WHERE image_id = ?2",
            params![originals[k], id],
        )
        .map_err(err)?;
        camera_full_size.entry(*camera).or_insert(full_sizes[k]);
        image_camera.insert(*id, *camera);
    }
    let scales = scale_cameras(&tx, dest, &camera_full_size)?;
    if scales.values().any(|s| *s != [1.0; 3]) {
        let image_scale: HashMap<i64, Scale> = image_camera
            .iter()
            .map(|(i, c)| (*i, scales.get(c).copied().unwrap_or([1.0; 3])))
            .collect();
        scale_keypoints(&tx, &image_scale).map_err(err)?;
        scale_geometries(&tx, &image_scale).map_err(err)?;
    }
    tx.commit().map_err(err)
}

fn sql_error(db: &Path) -> impl Fn(rusqlite::Error) -> Error + Copy + '_ {
    move |e| Error::format(db, format!("COLMAP's database: {e}"))
}

fn f64s(blob: &[u8]) -> Vec<f64> {
    blob.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect()
}

fn f64_bytes(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Resize each camera to its images' full size; the scale per camera.
fn scale_cameras(
    tx: &rusqlite::Transaction,
    db: &Path,
    full_size: &HashMap<i64, (u32, u32)>,
) -> Result<HashMap<i64, Scale>> {
    let err = sql_error(db);
    let mut scales = HashMap::new();
    for (&id, &(w, h)) in full_size {
        let row: Option<(i32, u32, u32, Vec<u8>)> = tx
            .query_row(
                "SELECT model, width, height, params FROM cameras WHERE camera_id = ?1",
                [id],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)),
            )
            .optional()
            .map_err(&err)?;
        let Some((model, cw, ch, params)) = row else {
            continue;
        };
        if (cw, ch) == (w, h) {
            scales.insert(id, [1.0; 3]);
            continue;
        }
        let model = CameraModel::from_id(model).ok_or_else(|| {
            Error::format(db, format!("camera {id} has unknown model id {model}"))
        })?;
        let cam = Camera::new(model, cw, ch, f64s(&params))
            .map_err(|e| Error::format(db, format!("camera {id}: {e}")))?
            .resized(w, h);
        tx.execute(
            "UPDATE cameras SET width = ?1, height = ?2, params = ?3 WHERE camera_id = ?4",
            params![w, h, f64_bytes(&cam.params), id],
        )
        .map_err(&err)?;
        scales.insert(id, [w as f64 / cw as f64, h as f64 / ch as f64, 1.0]);
    }
    Ok(scales)
}

/// Keypoints are rows of float32 (x, y), (x, y, scale, orientation) or (x, y, a11, a12, a21,
/// a22): positions and shapes scale with the image.
fn scale_keypoints(
    tx: &rusqlite::Transaction,
    image_scale: &HashMap<i64, Scale>,
) -> rusqlite::Result<()> {
    let rows: Vec<(i64, i64, Vec<u8>)> = {
        let mut stmt = tx.prepare("SELECT image_id, cols, data FROM keypoints")?;
        let rows = stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?;
        rows.collect::<rusqlite::Result<_>>()?
    };
    for (id, cols, data) in rows {
        let Some(&[sx, sy, _]) = image_scale.get(&id) else {
            continue;
        };
        let per_col: Vec<f64> = match cols {
            2 => vec![sx, sy],
            4 => vec![sx, sy, 0.5 * (sx + sy), 1.0],
            6 => vec![sx, sy, sx, sx, sy, sy],
            _ => continue,
        };
        let scaled: Vec<u8> = data
            .chunks_exact(4)
            .enumerate()
            .flat_map(|(i, c)| {
                let v = f32::from_le_bytes(c.try_into().expect("4 bytes"));
                ((v as f64 * per_col[i % per_col.len()]) as f32).to_le_bytes()
            })
            .collect();
        tx.execute(
            "UPDATE keypoints SET data = ?1 WHERE image_id = ?2",
            params![scaled, id],
        )?;
    }
    Ok(())
}

/// Two-view geometries: with x_full = S x_staged, x2' F x1 = 0 and x2 = H x1 become
/// F' = S2^-T F S1^-1 and H' = S2 H S1^-1 (both stored row-major); E and the relative pose are
/// in camera coordinates and do not change.
fn scale_geometries(
    tx: &rusqlite::Transaction,
    image_scale: &HashMap<i64, Scale>,
) -> rusqlite::Result<()> {
    type Row = (i64, Option<Vec<u8>>, Option<Vec<u8>>);
    let rows: Vec<Row> = {
        let mut stmt = tx.prepare("SELECT pair_id, F, H FROM two_view_geometries")?;
        let rows = stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?;
        rows.collect::<rusqlite::Result<_>>()?
    };
    for (pair, f, h) in rows {
        let (id1, id2) = (pair / MAX_IMAGES, pair % MAX_IMAGES);
        let (Some(s1), Some(s2)) = (image_scale.get(&id1), image_scale.get(&id2)) else {
            continue;
        };
        let map = |blob: Option<Vec<u8>>, g: &dyn Fn(usize, usize) -> f64| {
            blob.filter(|b| b.len() == 72).map(|b| {
                let m = f64s(&b);
                let out: Vec<f64> = (0..9).map(|i| m[i] * g(i / 3, i % 3)).collect();
                f64_bytes(&out)
            })
        };
        let f = map(f, &|a, b| 1.0 / (s2[a] * s1[b]));
        let h = map(h, &|a, b| s2[a] / s1[b]);
        tx.execute(
            "UPDATE two_view_geometries SET F = coalesce(?1, F), H = coalesce(?2, H) WHERE pair_id = ?3",
            params![f, h, pair],
        )?;
    }
    Ok(())
}
