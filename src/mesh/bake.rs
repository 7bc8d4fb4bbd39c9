//! The base-colour texture of an unwrapped mesh, baked from its field.
//!
//! Every texel whose centre lies in a triangle of the atlas is the field's colour at that point
//! of the surface, read as the vertex colours are ([`surface_colour`]: composited along the
//! inward normal, the mean over the training cameras that face the point; the module
//! [`super::colour`] says how view dependence is resolved). Texels outside every chart are then dilated
//! from the charts' edges across the gutters, so bilinear filtering and mipmaps at a chart's
//! seam read the chart's own colour, and what is still empty takes the mean colour.

use super::colour::{surface_colour, RayReach};
use super::visibility::SeenFrom;
use super::Mesh;
use crate::edit::Recolour;
use crate::error::{Error, Result};
use crate::field::model::Field;
use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

/// What the bake did.
#[derive(Clone, Debug, Serialize)]
pub struct BakeReport {
    /// Texels read from the field (centre inside a triangle).
    pub texels_baked: usize,
    /// Texels filled by dilation from the charts' edges.
    pub texels_dilated: usize,
}

/// Rings of texels grown out of the charts before the rest takes the mean colour.
const DILATE_RINGS: usize = 16;

/// Bake the base colour of `mesh` (with `uvs`, in the field's world frame) into a `size` x
/// `size` sRGB image. `reach`: how far (the mesh may lie off the field's surface) and how finely
/// each camera's ray through a texel is read; `seen` (the training cameras, which of them see a
/// point) and `recolour`: as for vertex colours.
pub fn bake_base_colour(
    field: &Field,
    mesh: &Mesh,
    size: u32,
    reach: RayReach,
    seen: &SeenFrom,
    recolour: Option<Recolour>,
) -> Result<(image::RgbImage, BakeReport)> {
    let uvs = mesh
        .uvs
        .as_ref()
        .ok_or_else(|| Error::invalid(format!("'{}' has no UVs to bake into", mesh.name)))?;
    let s = size as usize;
    let recolour = recolour.map(|r| r.prepare());
    // Each triangle's texels (atlas charts do not overlap, so each texel comes once).
    let texels: Vec<(usize, [f32; 3])> = mesh
        .triangles
        .par_iter()
        .flat_map_iter(|t| {
            let mut out = Vec::new();
            let uv = t.map(|i| glam::Vec2::from(uvs[i as usize]) * size as f32);
            let p = t.map(|i| Vec3::from(mesh.positions[i as usize]));
            let n = t.map(|i| Vec3::from(mesh.normals[i as usize]));
            for_texels_in(uv, s, |idx, w| {
                let q = p[0] * w[0] + p[1] * w[1] + p[2] * w[2];
                let nq = (n[0] * w[0] + n[1] * w[1] + n[2] * w[2]).normalize_or(n[0]);
                let c = surface_colour(field, q, nq, reach, seen);
                out.push((idx, recolour.map_or(c, |r| r.apply(c))));
            });
            out.into_iter()
        })
        .collect();
    let mut rgb = vec![[0f32; 3]; s * s];
    let mut filled = vec![false; s * s];
    for (i, c) in &texels {
        rgb[*i] = *c;
        filled[*i] = true;
    }
    let texels_baked = filled.iter().filter(|f| **f).count();
    let texels_dilated = dilate(&mut rgb, &mut filled, s, DILATE_RINGS);
    let img = image::RgbImage::from_fn(size, size, |x, y| {
        let c = rgb[x as usize + s * y as usize];
        image::Rgb(c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
    });
    Ok((
        img,
        BakeReport {
            texels_baked,
            texels_dilated,
        },
    ))
}

/// Call `f(index, barycentric weights)` for every texel of an `s` x `s` page whose centre lies
/// in the triangle `uv` (texel units).
fn for_texels_in(uv: [glam::Vec2; 3], s: usize, mut f: impl FnMut(usize, [f32; 3])) {
    let lo = uv[0].min(uv[1]).min(uv[2]);
    let hi = uv[0].max(uv[1]).max(uv[2]);
    let area = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]);
    if area.abs() < 1e-12 {
        return;
    }
    let x0 = (lo.x - 0.5).ceil().max(0.0) as usize;
    let y0 = (lo.y - 0.5).ceil().max(0.0) as usize;
    let x1 = ((hi.x - 0.5).floor() as i64).min(s as i64 - 1);
    let y1 = ((hi.y - 0.5).floor() as i64).min(s as i64 - 1);
    for y in y0 as i64..=y1 {
        for x in x0 as i64..=x1 {
            let c = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let w0 = (uv[1] - c).perp_dot(uv[2] - c) / area;
            let w1 = (uv[2] - c).perp_dot(uv[0] - c) / area;
            let w2 = 1.0 - w0 - w1;
            // A texel centre on a shared edge goes to both triangles: harmless, same colour.
            if w0 >= -1e-5 && w1 >= -1e-5 && w2 >= -1e-5 {
                f(x as usize + s * y as usize, [w0, w1, w2]);
            }
        }
    }
}

/// Grow the filled texels outward `rings` times (each empty texel next to filled ones takes
/// their mean), then give every texel still empty the mean colour. Returns the texels grown.
fn dilate(rgb: &mut [[f32; 3]], filled: &mut [bool], s: usize, rings: usize) -> usize {
    let mut grown = 0;
    for _ in 0..rings {
        let next: Vec<(usize, [f32; 3])> = (0..s * s)
            .into_par_iter()
            .filter(|&i| !filled[i])
            .filter_map(|i| {
                let (x, y) = ((i % s) as i64, (i / s) as i64);
                let mut acc = [0f32; 3];
                let mut n = 0;
                for (dx, dy) in [
                    (-1, 0),
                    (1, 0),
                    (0, -1),
                    (0, 1),
                    (-1, -1),
                    (1, 1),
                    (-1, 1),
                    (1, -1),
                ] {
                    let (u, v) = (x + dx, y + dy);
                    if u < 0 || v < 0 || u >= s as i64 || v >= s as i64 {
                        continue;
                    }
                    let j = u as usize + s * v as usize;
                    if filled[j] {
                        (0..3).for_each(|k| acc[k] += rgb[j][k]);
                        n += 1;
                    }
                }
                (n > 0).then(|| (i, acc.map(|a| a / n as f32)))
            })
            .collect();
        if next.is_empty() {
            break;
        }
        grown += next.len();
        for (i, c) in next {
            rgb[i] = c;
            filled[i] = true;
        }
    }
    let (sum, n) = rgb.iter().zip(filled.iter()).filter(|(_, f)| **f).fold(
        ([0f64; 3], 0usize),
        |(a, n), (c, _)| {
            (
                [a[0] + c[0] as f64, a[1] + c[1] as f64, a[2] + c[2] as f64],
                n + 1,
            )
        },
    );
    let mean = sum.map(|v| (v / n.max(1) as f64) as f32);
    for (c, f) in rgb.iter_mut().zip(filled.iter()) {
        if !*f {
            *c = mean;
        }
    }
    grown
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texels_of_a_triangle_and_dilation() {
        let uv = [
            glam::Vec2::new(1.0, 1.0),
            glam::Vec2::new(7.0, 1.0),
            glam::Vec2::new(1.0, 7.0),
        ];
        let mut hits = vec![];
        for_texels_in(uv, 8, |i, w| {
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            hits.push(i)
        });
        // Centres (x+0.5, y+0.5) with x, y >= 1 and x + y + 1 <= 8 - ... : 21 of them.
        assert_eq!(hits.len(), 21, "{hits:?}");
        let mut rgb = vec![[0f32; 3]; 64];
        let mut filled = vec![false; 64];
        for i in &hits {
            rgb[*i] = [1.0, 0.5, 0.0];
            filled[*i] = true;
        }
        let grown = dilate(&mut rgb, &mut filled, 8, 1);
        assert!(grown > 0 && filled.iter().filter(|f| !**f).count() == 64 - 21 - grown);
        // Every texel ends with the only colour there is.
        assert!(rgb.iter().all(|c| (c[1] - 0.5).abs() < 1e-6));
    }
}
