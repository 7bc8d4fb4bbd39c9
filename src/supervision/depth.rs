//! Depth supervision targets: sparse (the object's 3D points, seen through their tracks, DS-NeRF
//! style) and dense (depth images). Both become per-pixel distances along the unit ray on the
//! training views, kept only inside the object's mask: the field holds the object alone.

use crate::error::{Error, Result};
use crate::field::view::View;
use crate::scene::Scene;
use rayon::prelude::*;

/// Set sparse depth targets from the scene's 3D points: for each track element, the point's
/// camera z-depth becomes a target at the pixel holding its feature (in the downscaled view), if
/// that pixel is inside the mask. `views` are the scene's images in order. Returns the count.
pub fn add_sparse_depth(views: &mut [View], scene: &Scene, downscale: u32) -> Result<usize> {
    if views.len() != scene.images.len() {
        return Err(Error::invalid("views and scene images do not match"));
    }
    let f = downscale.max(1) as f64;
    let mut n = 0;
    for p in &scene.points {
        for t in &p.track {
            let im = &scene.images[t.image];
            let Some(feat) = im.features.get(t.feature) else {
                continue;
            };
            let v = &mut views[t.image];
            let (col, row) = ((feat.xy.x / f).floor(), (feat.xy.y / f).floor());
            if col < 0.0 || row < 0.0 || col >= v.width as f64 || row >= v.height as f64 {
                continue;
            }
            let idx = row as u32 * v.width + col as u32;
            if v.rgba[idx as usize][3] < 128 {
                continue;
            }
            let z = im.pose.world_to_camera(p.xyz).z;
            if z <= 0.0 {
                continue;
            }
            let target = z as f32 * v.ray_scale(idx);
            let npx = (v.width * v.height) as usize;
            let d = v.depth.get_or_insert_with(|| vec![0.0; npx]);
            d[idx as usize] = target;
            n += 1;
        }
    }
    if n == 0 {
        return Err(Error::invalid(
            "--depth sparse: no 3D point of the scene is seen inside the object's masks (the scene needs a sparse model with tracks)",
        ));
    }
    Ok(n)
}

/// Set dense depth targets from each view's depth image (z-depth; 0 = unknown), averaged over the
/// valid pixels of each downscaled block. Returns the number of target pixels.
pub fn add_dense_depth(views: &mut [View], scene: &Scene, downscale: u32) -> Result<usize> {
    if views.len() != scene.images.len() {
        return Err(Error::invalid("views and scene images do not match"));
    }
    let f = downscale.max(1);
    let counts: Vec<usize> = views
        .par_iter_mut()
        .zip(&scene.images)
        .map(|(v, im)| -> Result<usize> {
            let Some(path) = &im.depth_path else {
                return Err(Error::invalid(format!(
                    "--depth dense: view '{}' has no depth image",
                    im.name
                )));
            };
            let dm = crate::scene::io::read_depth(path, scene.depth_scale)?;
            // Depth maps may be smaller (or larger) than their photos, as a phone's LiDAR depth
            // is (256x192 beside 1920x1440): each view pixel takes the depth pixels whose
            // centres fall in its footprint, or the nearest one (nerfstudio resizes depth to
            // the image, nearest). Only the shape must agree.
            let cam = scene.camera_of(im);
            let (sx, sy) = (
                dm.width as f64 / cam.width as f64,
                dm.height as f64 / cam.height as f64,
            );
            if dm.width == 0 || dm.height == 0 || (sx / sy - 1.0).abs() > 0.02 {
                return Err(Error::format(
                    path,
                    format!(
                        "depth is {}x{} but its image {}x{}: the aspect ratios differ",
                        dm.width, dm.height, cam.width, cam.height
                    ),
                ));
            }
            // Depth pixels whose centres lie in [lo, hi) (in depth pixels), else the nearest.
            let span = |lo: f64, hi: f64, n: u32| -> std::ops::Range<u32> {
                let a = ((lo - 0.5).ceil().max(0.0) as u32).min(n);
                let b = ((hi - 0.5).ceil().max(0.0) as u32).min(n);
                if a < b {
                    a..b
                } else {
                    let c = ((0.5 * (lo + hi)).floor().max(0.0) as u32).min(n - 1);
                    c..c + 1
                }
            };
            let ff = f as f64;
            let mut d = vec![0f32; (v.width * v.height) as usize];
            let mut n = 0;
            for row in 0..v.height {
                let ys = span(row as f64 * ff * sy, (row + 1) as f64 * ff * sy, dm.height);
                for col in 0..v.width {
                    let idx = row * v.width + col;
                    if v.rgba[idx as usize][3] < 128 {
                        continue;
                    }
                    let xs = span(col as f64 * ff * sx, (col + 1) as f64 * ff * sx, dm.width);
                    let (mut sum, mut cnt) = (0f64, 0u32);
                    for y in ys.clone() {
                        for x in xs.clone() {
                            let z = dm.metres[(y * dm.width + x) as usize];
                            if z.is_finite() && z > 0.0 {
                                sum += z as f64;
                                cnt += 1;
                            }
                        }
                    }
                    // Half the block valid at least, or edges mix foreground and holes.
                    if cnt * 2 >= ys.len() as u32 * xs.len() as u32 {
                        d[idx as usize] = (sum / cnt as f64) as f32 * v.ray_scale(idx);
                        n += 1;
                    }
                }
            }
            v.depth = Some(d);
            Ok(n)
        })
        .collect::<Result<_>>()?;
    Ok(counts.iter().sum())
}

/// Neighbourhood radii of [`spread_sparse_depth`], smallest first, as fractions of the view's
/// larger side: a small one follows a curved or small surface, a large one bridges the sparse
/// parts of a wide one.
pub const SPREAD_RADII: [f64; 3] = [0.03, 0.06, 0.1];
/// Fewest sparse targets a neighbourhood needs before a plane is fitted through them.
pub const SPREAD_MIN_POINTS: usize = 6;
/// Widest gap between a neighbourhood's inverse depths, in depth order, relative to the smaller:
/// one surface's points spread continuously, two surfaces' points fall in two clusters.
pub const SPREAD_MAX_GAP: f64 = 0.25;
/// Share of a neighbourhood's targets that must lie on its plane after the stray ones are
/// dropped.
pub const SPREAD_MIN_INLIERS: f64 = 0.8;
/// Largest residual of a neighbourhood's plane (in inverse depth, relative to its value) for
/// the neighbourhood to count as one surface.
pub const SPREAD_MAX_RESIDUAL: f64 = 0.02;

/// Spread each view's sparse depth targets (from [`add_sparse_depth`]) to the pixels between
/// them where they agree on a surface: around each pixel, the targets within each of
/// [`SPREAD_RADII`] in turn are fitted by a plane in inverse depth (exact for a planar surface under
/// perspective) and the pixel takes the plane's depth when the fit holds every target within
/// [`SPREAD_MAX_RESIDUAL`] and the targets surround it (three quadrants or more: no
/// extrapolation past an edge). Where an object meets what is behind it, the targets disagree
/// and the pixel keeps no target. Returns the number of targets added.
pub fn spread_sparse_depth(views: &mut [View]) -> usize {
    views.par_iter_mut().map(spread_view).sum()
}

fn spread_view(v: &mut View) -> usize {
    let Some(depth) = &v.depth else { return 0 };
    let (w, h) = (v.width as usize, v.height as usize);
    let radii = SPREAD_RADII.map(|r| (r * w.max(h) as f64).max(2.0));
    let cell = radii[radii.len() - 1].ceil() as usize;
    let (gw, gh) = (w.div_ceil(cell), h.div_ceil(cell));
    // Targets as (x, y, inverse z-depth), bucketed by cell.
    let mut buckets: Vec<Vec<[f64; 3]>> = vec![Vec::new(); gw * gh];
    // A removed object's own targets (under its loss mask) say nothing of what it hid.
    let carries_loss = |i: usize| v.loss_mask.as_ref().is_none_or(|m| m[i]);
    for (i, &d) in depth.iter().enumerate() {
        if d > 0.0 && carries_loss(i) {
            let (x, y) = (i % w, i / w);
            let z = d as f64 / v.ray_scale(i as u32) as f64;
            buckets[(y / cell) * gw + x / cell].push([x as f64 + 0.5, y as f64 + 0.5, 1.0 / z]);
        }
    }
    let mut out = depth.clone();
    let mut added = 0;
    let mut near: Vec<([f64; 3], f64)> = Vec::new();
    let mut within: Vec<[f64; 3]> = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if out[i] > 0.0 || v.rgba[i][3] < 128 || !carries_loss(i) {
                continue;
            }
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            near.clear();
            let (cx, cy) = (x / cell, y / cell);
            for by in cy.saturating_sub(1)..(cy + 2).min(gh) {
                for bx in cx.saturating_sub(1)..(cx + 2).min(gw) {
                    near.extend(
                        buckets[by * gw + bx]
                            .iter()
                            .map(|s| (*s, (s[0] - px).powi(2) + (s[1] - py).powi(2))),
                    );
                }
            }
            for r in radii {
                within.clear();
                within.extend(near.iter().filter(|n| n.1 <= r * r).map(|n| n.0));
                if let Some(inv) = plane_at(&within, px, py) {
                    out[i] = (1.0 / inv) as f32 * v.ray_scale(i as u32);
                    added += 1;
                    break;
                }
            }
        }
    }
    v.depth = Some(out);
    added
}

/// The inverse depth at (`px`, `py`) of the plane through `near` (x, y, inverse depth), if they
/// surround the point and lie on one plane. One round of outlier rejection: a stray sparse point
/// (a wrong match) would otherwise void every neighbourhood it falls in; the targets left must
/// be at least [`SPREAD_MIN_INLIERS`] of them.
fn plane_at(near: &[[f64; 3]], px: f64, py: f64) -> Option<f64> {
    if near.len() < SPREAD_MIN_POINTS || !surrounds(near, px, py) {
        return None;
    }
    let first = fit_plane(near, px, py)?;
    let residual = |p: &[f64; 3], s: &[f64; 3]| {
        (p[0] + p[1] * (s[0] - px) + p[2] * (s[1] - py) - s[2]).abs() <= SPREAD_MAX_RESIDUAL * s[2]
    };
    if near.iter().all(|s| residual(&first, s)) {
        return (first[0] > 0.0 && continuous(near)).then_some(first[0]);
    }
    let kept: Vec<[f64; 3]> = near
        .iter()
        .copied()
        .filter(|s| residual(&first, s))
        .collect();
    if (kept.len() as f64) < SPREAD_MIN_INLIERS * near.len() as f64
        || kept.len() < SPREAD_MIN_POINTS
        || !surrounds(&kept, px, py)
    {
        return None;
    }
    let plane = fit_plane(&kept, px, py)?;
    (near.iter().filter(|s| residual(&plane, s)).count() >= kept.len()
        && plane[0] > 0.0
        && continuous(&kept))
    .then_some(plane[0])
}

/// Whether the inverse depths of `pts` leave no gap wider than [`SPREAD_MAX_GAP`] between
/// neighbours in depth order: two surfaces at different depths (an object's edge over a wall)
/// seen as two rows of points fit a plane exactly, but their depths come in two clusters.
fn continuous(pts: &[[f64; 3]]) -> bool {
    let mut inv: Vec<f64> = pts.iter().map(|s| s[2]).collect();
    inv.sort_by(f64::total_cmp);
    inv.windows(2)
        .all(|p| p[1] <= p[0] * (1.0 + SPREAD_MAX_GAP))
}

/// Whether `near` has points in three of the four quadrants around (`px`, `py`).
fn surrounds(near: &[[f64; 3]], px: f64, py: f64) -> bool {
    let mut quadrants = [false; 4];
    for s in near {
        quadrants[(s[0] >= px) as usize + 2 * (s[1] >= py) as usize] = true;
    }
    quadrants.iter().filter(|&&q| q).count() >= 3
}

/// Least squares for inv = a + b (x - px) + c (y - py) through `pts`: [a, b, c] (the normal
/// equations by Cramer's rule), None when they are degenerate.
fn fit_plane(pts: &[[f64; 3]], px: f64, py: f64) -> Option<[f64; 3]> {
    let mut m = [[0f64; 3]; 3];
    let mut r = [0f64; 3];
    for s in pts {
        let u = [1.0, s[0] - px, s[1] - py];
        for a in 0..3 {
            for b in 0..3 {
                m[a][b] += u[a] * u[b];
            }
            r[a] += u[a] * s[2];
        }
    }
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&m);
    if d.abs() < 1e-12 {
        return None;
    }
    let solve = |k: usize| {
        let mut mk = m;
        for a in 0..3 {
            mk[a][k] = r[a];
        }
        det(&mk) / d
    };
    Some([solve(0), solve(1), solve(2)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{
        Camera, Feature, ImageView, Point3D, Pose, SceneCamera, SourceFormat, TrackElement,
    };
    use glam::{DVec2, DVec3};

    /// A scene of one view "a" seen by `cam` from `pose`.
    fn one_view_scene(
        cam: &Camera,
        pose: Pose,
        depth_path: Option<std::path::PathBuf>,
        features: Vec<Feature>,
    ) -> Scene {
        Scene {
            source: "mem".into(),
            format: SourceFormat::Demo,
            cameras: vec![SceneCamera {
                id: 1,
                camera: cam.clone(),
            }],
            images: vec![ImageView {
                id: 1,
                name: "a".into(),
                path: "a.png".into(),
                camera: 0,
                pose,
                mask_path: None,
                depth_path,
                features,
                depth_bounds: None,
            }],
            points: Vec::new(),
            depth_scale: 1000.0,
            applied_transform: None,
        }
    }

    /// A point seen through its track becomes a target at its feature's pixel, as the distance
    /// along that pixel's ray; a feature outside the mask gives none.
    #[test]
    fn sparse_depth_from_tracks() {
        let cam = Camera::pinhole(40, 40, 40.0, 40.0, 20.0, 20.0);
        let pose = Pose::look_at(DVec3::new(0.0, 0.0, -3.0), DVec3::ZERO, DVec3::Y);
        let pts = [DVec3::new(0.3, -0.2, 0.5), DVec3::new(-0.5, 0.4, 0.0)];
        let features: Vec<Feature> = pts
            .iter()
            .enumerate()
            .map(|(i, p)| Feature {
                xy: cam.project(pose.world_to_camera(*p)).unwrap(),
                point: Some(i),
            })
            .collect();
        let mut scene = one_view_scene(&cam, pose, None, features.clone());
        scene.points = pts
            .iter()
            .enumerate()
            .map(|(i, p)| Point3D {
                id: i as u64 + 1,
                xyz: *p,
                rgb: [0; 3],
                error: 0.0,
                track: vec![TrackElement {
                    image: 0,
                    feature: i,
                }],
            })
            .collect();
        // Mask: the left half of the image is the object.
        let rgba = (0..1600)
            .map(|i| if i % 40 < 20 { [9, 9, 9, 255] } else { [0; 4] })
            .collect();
        let mut views = vec![View::new("a".into(), cam, pose, rgba)];
        let n = add_sparse_depth(&mut views, &scene, 1).unwrap();
        let inside: Vec<usize> = features
            .iter()
            .enumerate()
            .filter(|(_, f)| f.xy.x < 20.0)
            .map(|(i, _)| i)
            .collect();
        assert_eq!(n, inside.len());
        assert!(n >= 1);
        let d = views[0].depth.as_ref().unwrap();
        for i in inside {
            let xy: DVec2 = features[i].xy;
            let idx = xy.y.floor() as u32 * 40 + xy.x.floor() as u32;
            let (o, dir) = views[0].ray(idx);
            // The target is the distance along the pixel-centre ray to the point's z-plane.
            let z = pose.world_to_camera(pts[i]).z as f32;
            let along = d[idx as usize];
            let hit = o + dir * along;
            let hz = pose.world_to_camera(hit.as_dvec3()).z as f32;
            assert!((hz - z).abs() < 1e-4, "{hz} vs {z}");
        }
    }

    /// A depth map at a quarter of its photo's size (a phone's LiDAR depth beside its photo)
    /// gives every masked pixel the depth of the depth pixel under it, at any downscale; a depth
    /// map of another shape is refused.
    #[test]
    fn dense_depth_smaller_than_the_photo() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (40u32, 32u32);
        let cam = Camera::pinhole(w, h, 40.0, 40.0, 20.0, 16.0);
        let pose = Pose::look_at(DVec3::new(0.0, 0.0, -3.0), DVec3::ZERO, DVec3::Y);
        // Depth 1 m on the left half, 2 m on the right, at 10x8.
        let dm = crate::scene::io::DepthMap {
            width: 10,
            height: 8,
            metres: (0..80)
                .map(|i| if i % 10 < 5 { 1.0 } else { 2.0 })
                .collect(),
        };
        let depth = dir.path().join("d.png");
        crate::scene::io::write_depth_png_mm(&depth, &dm).unwrap();
        let mut scene = one_view_scene(&cam, pose, Some(depth.clone()), Vec::new());
        for f in [1u32, 2, 3] {
            let c = cam.binned(f);
            let rgba = vec![[9, 9, 9, 255]; (c.width * c.height) as usize];
            let mut views = vec![View::new("a".into(), c.clone(), pose, rgba)];
            let n = add_dense_depth(&mut views, &scene, f).unwrap();
            assert_eq!(n, (c.width * c.height) as usize, "factor {f}");
            let d = views[0].depth.as_ref().unwrap();
            for row in 0..c.height {
                for col in 0..c.width {
                    let idx = row * c.width + col;
                    // The full-size pixel under this one's centre, then the depth pixel under that.
                    let u = (col as f64 + 0.5) * f as f64;
                    let want = if u < 20.0 { 1.0 } else { 2.0 };
                    let z = d[idx as usize] / views[0].ray_scale(idx);
                    // A view pixel straddling the edge averages both sides.
                    let straddles = ((col * f) as f64) < 20.0 && (((col + 1) * f) as f64) > 20.0;
                    assert!(straddles || (z - want).abs() < 1e-3, "{f} {col} {row}: {z}");
                }
            }
        }
        let dm = crate::scene::io::DepthMap {
            width: 16,
            height: 8,
            metres: vec![1.0; 128],
        };
        crate::scene::io::write_depth_png_mm(&depth, &dm).unwrap();
        scene.images[0].depth_path = Some(depth);
        let rgba = vec![[9, 9, 9, 255]; (w * h) as usize];
        let mut views = vec![View::new("a".into(), cam, pose, rgba)];
        let e = add_dense_depth(&mut views, &scene, 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("aspect"), "{e}");
    }

    /// A 100 x 100 view with sparse z-depth targets `z(x, y)` every 4th pixel.
    fn sparse_view(z: impl Fn(f64, f64) -> f64) -> View {
        let cam = Camera::pinhole(100, 100, 100.0, 100.0, 50.0, 50.0);
        let pose = Pose::look_at(DVec3::new(0.0, 0.0, -3.0), DVec3::ZERO, DVec3::Y);
        let mut v = View::new("a".into(), cam, pose, vec![[9, 9, 9, 255]; 10_000]);
        let mut d = vec![0f32; 10_000];
        for y in (2..100).step_by(4) {
            for x in (2..100).step_by(4) {
                let i = y * 100 + x;
                d[i] = z(x as f64 + 0.5, y as f64 + 0.5) as f32 * v.ray_scale(i as u32);
            }
        }
        v.depth = Some(d);
        v
    }

    fn z_at(v: &View, x: usize, y: usize) -> f64 {
        let i = y * 100 + x;
        (v.depth.as_ref().unwrap()[i] / v.ray_scale(i as u32)) as f64
    }

    #[test]
    fn spread_depth_fills_a_plane_exactly() {
        // A slanted plane: inverse depth linear in the image (the floor seen from a camera).
        let plane = |x: f64, y: f64| 1.0 / (0.25 + 0.002 * x + 0.001 * y);
        let mut v = vec![sparse_view(plane)];
        let added = spread_sparse_depth(&mut v);
        assert!(added > 8000, "{added} targets added");
        for y in 4..96 {
            for x in 4..96 {
                let z = z_at(&v[0], x, y);
                let want = plane(x as f64 + 0.5, y as f64 + 0.5);
                assert!((z - want).abs() < 1e-4 * want, "({x}, {y}): {z} vs {want}");
            }
        }
    }

    #[test]
    fn spread_depth_does_not_bridge_two_surfaces() {
        // An object at 2 m in front of a wall at 4 m, edge at x = 50: no pixel takes a depth
        // between them, and pixels away from the edge are filled.
        let step = |x: f64, _: f64| if x < 50.0 { 2.0 } else { 4.0 };
        let mut v = vec![sparse_view(step)];
        spread_sparse_depth(&mut v);
        for y in 0..100 {
            for x in 0..100 {
                let z = z_at(&v[0], x, y);
                assert!(
                    z == 0.0 || (z - 2.0).abs() < 1e-3 || (z - 4.0).abs() < 1e-3,
                    "({x}, {y}): {z}"
                );
            }
        }
        assert!((z_at(&v[0], 20, 50) - 2.0).abs() < 1e-3);
        assert!((z_at(&v[0], 80, 50) - 4.0).abs() < 1e-3);
    }
}
