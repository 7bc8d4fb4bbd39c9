//! Where the object is: the masks' visual hull, the box it gives, and the voxel size for it (the
//! pixel footprint, within a memory budget).

use super::view::View;
use crate::error::{Error, Result};
use glam::Vec3;
use rayon::prelude::*;

/// A boolean "may be the object" image per view: mask > 0, dilated by `radius` pixels.
fn dilated_mask(v: &View, radius: i32) -> Vec<bool> {
    let (w, h) = (v.width as i32, v.height as i32);
    let m: Vec<bool> = v.rgba.iter().map(|p| p[3] > 0).collect();
    let mut tmp = vec![false; m.len()];
    for y in 0..h {
        for x in 0..w {
            let lo = (x - radius).max(0);
            let hi = (x + radius).min(w - 1);
            tmp[(y * w + x) as usize] = (lo..=hi).any(|xx| m[(y * w + xx) as usize]);
        }
    }
    let mut out = vec![false; m.len()];
    for y in 0..h {
        for x in 0..w {
            let lo = (y - radius).max(0);
            let hi = (y + radius).min(h - 1);
            out[(y * w + x) as usize] = (lo..=hi).any(|yy| tmp[(yy * w + x) as usize]);
        }
    }
    out
}

/// Fraction of the views seeing a point that may show it outside their mask before the hull
/// drops it. The demo scene's mug is partly hidden in about a tenth of the views; a strict
/// intersection cut off its base.
pub const HULL_TOLERANCE: f32 = 0.2;

/// The masks' visual hull sampled at cell centres of a `dims` grid over [lo, hi]: a cell is kept
/// when at most [`HULL_TOLERANCE`] of the views that see its centre see it on the background and
/// at least half the views see it at all.
/// Masks are dilated by the cell's pixel footprint so thin parts are not carved.
pub fn visual_hull(views: &[View], lo: Vec3, hi: Vec3, dims: [usize; 3]) -> Vec<bool> {
    let cell = (hi - lo) / Vec3::new(dims[0] as f32, dims[1] as f32, dims[2] as f32);
    let mid = 0.5 * (lo + hi);
    let masks: Vec<(Vec<bool>, i32)> = views
        .par_iter()
        .map(|v| {
            let dist = (v.center() - mid).length().max(1e-6);
            let fx = v.focal();
            let r = (0.87 * cell.max_element() * fx / dist).ceil() as i32 + 1;
            (dilated_mask(v, r.min(64)), r)
        })
        .collect();
    // A point seen by few views is barely constrained (a long cone behind each silhouette):
    // require half of them.
    let min_seen = views.len().div_ceil(2).max(views.len().min(2));
    let plane = dims[0] * dims[1];
    let mut keep = vec![false; plane * dims[2]];
    keep.par_chunks_mut(plane)
        .enumerate()
        .for_each(|(z, slab)| {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let p = lo + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * cell;
                    let mut seen = 0usize;
                    let mut outside = 0usize;
                    for (v, (m, _)) in views.iter().zip(&masks) {
                        let Some((u, w)) = v.project(p) else { continue };
                        if u < 0.0 || w < 0.0 || u >= v.width as f32 || w >= v.height as f32 {
                            continue;
                        }
                        seen += 1;
                        if !m[(w as u32 * v.width + u as u32) as usize] {
                            outside += 1;
                        }
                    }
                    // Voting, not a strict intersection: masks of the visible part would carve
                    // away what an occluder hides in a few views, and one bad mask would cut
                    // the object.
                    let allowed = (seen as f32 * HULL_TOLERANCE).floor() as usize;
                    slab[x + dims[0] * y] = outside <= allowed && seen >= min_seen;
                }
            }
        });
    keep
}

/// The object's box from the visual hull: a coarse pass over the cube that holds the cameras,
/// then a finer pass over what it found, padded by `pad` (a fraction of the size) on each side.
pub fn hull_box(views: &[View], pad: f32) -> Result<(Vec3, Vec3)> {
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for v in views {
        lo = lo.min(v.center());
        hi = hi.max(v.center());
    }
    let c = 0.5 * (lo + hi);
    let r = (hi - lo).max_element().max(1e-3) * 0.5;
    let (mut lo, mut hi) = (c - Vec3::splat(r), c + Vec3::splat(r));
    for res in [96usize, 128] {
        let dims = [res; 3];
        let keep = visual_hull(views, lo, hi, dims);
        let cell = (hi - lo) / res as f32;
        let (mut a, mut b) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for (i, &k) in keep.iter().enumerate() {
            if k {
                let x = i % res;
                let y = (i / res) % res;
                let z = i / (res * res);
                let p = lo + Vec3::new(x as f32, y as f32, z as f32) * cell;
                a = a.min(p);
                b = b.max(p + cell);
            }
        }
        if a.x > b.x {
            return Err(Error::invalid(
                "the masks' visual hull is empty: no point is inside the mask of every view that sees it (check the masks and poses)",
            ));
        }
        // Pad by a cell: the hull was tested at cell centres.
        lo = a - cell;
        hi = b + cell;
    }
    let e = (hi - lo) * pad;
    Ok((lo - e, hi + e))
}

/// The world length one pixel covers at the box's centre (median over the views of distance /
/// focal), and a sentence saying so.
pub fn pixel_footprint(views: &[View], lo: Vec3, hi: Vec3) -> (f32, String) {
    let mid = 0.5 * (lo + hi);
    let mut foot: Vec<(f32, f32, f32)> = views
        .iter()
        .map(|v| {
            let (dist, focal) = ((v.center() - mid).length(), v.focal());
            (dist / focal, dist, focal)
        })
        .collect();
    foot.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (median, dist, focal) = foot[foot.len() / 2];
    (
        median,
        format!(
            "one pixel at the median camera distance {dist:.3} (focal {focal:.0} px) covers {median:.5} world units"
        ),
    )
}

/// Enlarge `voxel` until a grid over `extent` with `bytes_per_vertex` fits in `budget` bytes;
/// `why` is extended with the reason when it had to.
pub fn fit_budget(
    extent: Vec3,
    mut voxel: f32,
    mut why: String,
    bytes_per_vertex: usize,
    budget: usize,
) -> (f32, String) {
    let count = |vx: f32| -> usize {
        [extent.x, extent.y, extent.z]
            .iter()
            .map(|l| (l / vx).ceil() as usize + 1)
            .product()
    };
    let want = count(voxel) * bytes_per_vertex;
    if want > budget {
        voxel *= (want as f32 / budget as f32).cbrt();
        while count(voxel) * bytes_per_vertex > budget {
            voxel *= 1.02;
        }
        why += &format!(
            ", enlarged to {voxel:.5} to fit the {} MiB budget",
            budget >> 20
        );
    }
    (voxel, why)
}
