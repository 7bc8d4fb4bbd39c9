//! Where the object is: the masks' visual hull, the box it gives, and the voxel size for it (the
//! pixel footprint, within a memory budget).

use super::view::View;
use crate::error::{Error, Result};
use crate::util::mask::dilate_bits;
use glam::Vec3;
use rayon::prelude::*;

/// A boolean "may be the object" image per view: mask > 0 or in the mask's edge band, dilated
/// by `radius` pixels.
fn dilated_mask(v: &View, radius: usize) -> Vec<bool> {
    let mut m: Vec<bool> = v.rgba.iter().map(|p| p[3] > 0).collect();
    for e in &v.edge {
        m[e.px as usize] = true;
    }
    dilate_bits(&m, [v.width as usize, v.height as usize], radius)
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
            (dilated_mask(v, r.min(64) as usize), r)
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
/// Only right when the cameras surround the object; [`object_box`] starts from its points.
pub fn hull_box(views: &[View], pad: f32) -> Result<(Vec3, Vec3)> {
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for v in views {
        lo = lo.min(v.center());
        hi = hi.max(v.center());
    }
    let c = 0.5 * (lo + hi);
    let r = (hi - lo).max_element().max(1e-3) * 0.5;
    let (lo, hi) = hull_within(views, c - Vec3::splat(r), c + Vec3::splat(r))?;
    let e = (hi - lo) * pad;
    Ok((lo - e, hi + e))
}

/// The visual hull's extent inside the search box `lo..hi`: a pass at 96^3 cells, then one at
/// 128^3 over what it found.
fn hull_within(views: &[View], mut lo: Vec3, mut hi: Vec3) -> Result<(Vec3, Vec3)> {
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
    Ok((lo, hi))
}

/// Fewest object points for the box to start from them (fewer: the cameras' cube).
pub const MIN_BOX_POINTS: usize = 8;
/// The points' box is their 2nd-98th percentiles per axis (robust to points that leaked in at a
/// mask's edge)...
const POINT_QUANTILE: f64 = 0.02;
/// ... grown by this fraction of its size per side to search the visual hull in (the
/// percentiles cut off thin parts: a spire, a handle, a plant's top), once more where the hull
/// reaches the search box's side.
const SEARCH_GROW: f32 = 0.5;

/// The object's box: from its sparse points (what the segmentation collected: the paper's
/// bounding box, robust percentiles), grown and cut to the masks' visual hull, so it holds the
/// object in any capture layout (cameras around it, facing it, or a facade). Without enough
/// points, the hull over the cameras' cube ([`hull_box`]). Returns the box padded by `pad`, and
/// which evidence set it.
pub fn object_box(views: &[View], points: &[Vec3], pad: f32) -> Result<(Vec3, Vec3, String)> {
    if points.len() < MIN_BOX_POINTS {
        let (lo, hi) = hull_box(views, pad)?;
        return Ok((
            lo,
            hi,
            format!(
                "box from the masks' visual hull over the cameras' cube ({} object points, fewer than {MIN_BOX_POINTS})",
                points.len()
            ),
        ));
    }
    let q = |a: usize, f: f64| {
        crate::util::stats::quantile(points.iter().map(|p| p[a] as f64).collect(), f).unwrap_or(0.0)
            as f32
    };
    let plo = Vec3::new(
        q(0, POINT_QUANTILE),
        q(1, POINT_QUANTILE),
        q(2, POINT_QUANTILE),
    );
    let phi = Vec3::new(
        q(0, 1.0 - POINT_QUANTILE),
        q(1, 1.0 - POINT_QUANTILE),
        q(2, 1.0 - POINT_QUANTILE),
    );
    let size =
        (phi - plo).max(Vec3::splat((phi - plo).max_element() * 0.05).max(Vec3::splat(1e-4)));
    let (mut slo, mut shi) = (plo - size * SEARCH_GROW, phi + size * SEARCH_GROW);
    let (mut lo, mut hi) = hull_within(views, slo, shi)?;
    // Where the hull reaches a side of the search box, the object may go on: search once more
    // with that side moved out.
    let near = |a: f32, b: f32| (a - b).abs() <= 0.02 * size.max_element();
    let mut grown = Vec::new();
    for a in 0..3 {
        if near(lo[a], slo[a]) {
            slo[a] -= size[a] * SEARCH_GROW;
            grown.push(format!("-{}", ["x", "y", "z"][a]));
        }
        if near(hi[a], shi[a]) {
            shi[a] += size[a] * SEARCH_GROW;
            grown.push(format!("+{}", ["x", "y", "z"][a]));
        }
    }
    if !grown.is_empty() {
        (lo, hi) = hull_within(views, slo, shi)?;
    }
    let e = (hi - lo) * pad;
    let why = format!(
        "box from {} object points (2-98%: {:.3} x {:.3} x {:.3}), searched {:.0}% wider{} and cut to the masks' visual hull: {:.3} x {:.3} x {:.3}",
        points.len(),
        phi.x - plo.x,
        phi.y - plo.y,
        phi.z - plo.z,
        100.0 * SEARCH_GROW,
        if grown.is_empty() {
            String::new()
        } else {
            format!(" (then wider towards {})", grown.join(", "))
        },
        hi.x - lo.x,
        hi.y - lo.y,
        hi.z - lo.z
    );
    Ok((lo - e, hi + e, why))
}

/// The scene's sparse points that belong to the object: seen by at least two of `views` (the
/// training views, masks as alpha, downscaled by `factor`), and inside the mask in at least two
/// thirds of them (the segmentation's own point set, recovered from its masks).
pub fn points_in_masks(scene: &crate::scene::Scene, views: &[View], factor: u32) -> Vec<Vec3> {
    let index: std::collections::HashMap<&str, &View> =
        views.iter().map(|v| (v.name.as_str(), v)).collect();
    let f = factor.max(1) as f64;
    scene
        .points
        .iter()
        .filter_map(|p| {
            let (mut seen, mut inside) = (0usize, 0usize);
            for o in &p.track {
                let im = &scene.images[o.image];
                let Some(v) = index.get(im.name.as_str()) else {
                    continue;
                };
                let xy = im.features[o.feature].xy / f;
                let (x, y) = (xy.x as u32, xy.y as u32);
                if x >= v.width || y >= v.height {
                    continue;
                }
                seen += 1;
                inside += (v.rgba[(y * v.width + x) as usize][3]
                    > crate::util::mask::MASK_THRESHOLD) as usize;
            }
            (seen >= 2 && 3 * inside >= 2 * seen).then(|| p.xyz.as_vec3())
        })
        .collect()
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
