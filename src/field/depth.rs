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
            if dm.width / f != v.width || dm.height / f != v.height {
                return Err(Error::format(
                    path,
                    format!(
                        "depth is {}x{}, the view is {}x{} after downscaling by {f}",
                        dm.width, dm.height, v.width, v.height
                    ),
                ));
            }
            let mut d = vec![0f32; (v.width * v.height) as usize];
            let mut n = 0;
            for row in 0..v.height {
                for col in 0..v.width {
                    let idx = row * v.width + col;
                    if v.rgba[idx as usize][3] < 128 {
                        continue;
                    }
                    let (mut sum, mut cnt) = (0f64, 0u32);
                    for yy in 0..f {
                        for xx in 0..f {
                            let z = dm.metres[((row * f + yy) * dm.width + col * f + xx) as usize];
                            if z.is_finite() && z > 0.0 {
                                sum += z as f64;
                                cnt += 1;
                            }
                        }
                    }
                    // Half the block valid at least, or edges mix foreground and holes.
                    if cnt * 2 >= f * f {
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
        let scene = Scene {
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
                depth_path: None,
                features: features.clone(),
            }],
            points: pts
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
                .collect(),
            depth_scale: 1000.0,
            applied_transform: None,
        };
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
}
