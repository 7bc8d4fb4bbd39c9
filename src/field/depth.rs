//! Depth supervision targets: sparse (the object's 3D points, seen through their tracks, DS-NeRF
//! style) and dense (depth images). Both become per-pixel distances along the unit ray on the
//! training views, kept only inside the object's mask: the field holds the object alone.

use super::view::View;
use crate::error::{Error, Result};
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
}
