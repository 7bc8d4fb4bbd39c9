//! Self-checks of a scene's poses and sparse model (see [`crate::util::warnings`]): views that
//! are nearly without tracks (as good as unregistered), a high reprojection error (poses and
//! points disagree), short tracks, and an object that too few cameras see.

use super::Scene;
use crate::util::warnings::{name_list as list, Stage, Warning};

/// A view with fewer tracked features than this carries no click or prompt further and is as
/// good as unregistered: COLMAP registers an image from a few dozen 2D-3D matches at least.
pub const MIN_VIEW_OBSERVATIONS: usize = 20;
/// More than this fraction of such views means the reconstruction lost part of the capture
/// (COLMAP registers nearly every image of a good capture; a tenth missing is a visible gap).
pub const MAX_UNTRACKED_FRACTION: f64 = 0.1;
/// Mean reprojection error (pixels at the scene's resolution) above which the poses and the
/// points disagree: bundle adjustment ends well under 1 px on a good capture, and the demo's
/// object fields lose their edges once rays miss by a few pixels (1° of pose noise at the
/// demo's 336 px focal length is about 6 px; see the stability suite).
pub const MAX_REPROJECTION_PX: f64 = 2.0;
/// Mean track length under this: most points are seen by two views only, so prompts reach few
/// views and the points' positions are poorly constrained.
pub const MIN_MEAN_TRACK_LENGTH: f64 = 2.5;
/// Fewer views than this seeing the object (at least half of its points in frame) leave the
/// field underconstrained: a voxel field needs views all round what it reconstructs.
pub const MIN_VIEWS_SEEING_OBJECT: usize = 8;

/// COLMAP registering fewer than this fraction of the images lost part of the capture (it
/// registers nearly every image of a capture with enough overlap).
pub const MIN_REGISTERED_FRACTION: f64 = 0.9;

/// The check of a reconstruction: enough of the `given` images registered.
pub fn check_registration(given: usize, registered: usize) -> Option<Warning> {
    let frac = registered as f64 / given.max(1) as f64;
    (frac < MIN_REGISTERED_FRACTION).then(|| {
        Warning::new(
            Stage::Scene,
            "few_images_registered",
            frac,
            MIN_REGISTERED_FRACTION,
            format!(
                "COLMAP registered {registered} of {given} images: the others had too little overlap or texture; add images between them or raise --max-features"
            ),
        )
    })
}

/// Checks of the scene alone (before segmentation).
pub fn check_scene(scene: &Scene) -> Vec<Warning> {
    let mut out = Vec::new();
    let n = scene.images.len();
    if n == 0 {
        return out;
    }
    let untracked: Vec<&str> = scene
        .images
        .iter()
        .filter(|im| {
            im.features.iter().filter(|f| f.point.is_some()).count() < MIN_VIEW_OBSERVATIONS
        })
        .map(|im| im.name.as_str())
        .collect();
    let frac = untracked.len() as f64 / n as f64;
    if frac > MAX_UNTRACKED_FRACTION {
        out.push(Warning::new(
            Stage::Scene,
            "views_without_tracks",
            frac,
            MAX_UNTRACKED_FRACTION,
            format!(
                "{} of {n} views have fewer than {MIN_VIEW_OBSERVATIONS} tracked features ({}): they are as good as unregistered; rerun `objnerf sfm` with more features or check those images",
                untracked.len(),
                list(&untracked)
            ),
        ));
    }
    let errs = scene.reprojection_errors();
    if !errs.is_empty() {
        let mean = errs.iter().sum::<f64>() / errs.len() as f64;
        if mean > MAX_REPROJECTION_PX {
            out.push(Warning::new(
                Stage::Scene,
                "high_reprojection_error",
                mean,
                MAX_REPROJECTION_PX,
                format!(
                    "the sparse points reproject {mean:.2} px from their features on average: the poses are inaccurate, so masks and the field will not line up across views; refine the poses (COLMAP bundle adjustment)"
                ),
            ));
        }
    }
    if !scene.points.is_empty() {
        let mean_track = scene.points.iter().map(|p| p.track.len()).sum::<usize>() as f64
            / scene.points.len() as f64;
        if mean_track < MIN_MEAN_TRACK_LENGTH {
            out.push(Warning::new(
                Stage::Scene,
                "short_tracks",
                mean_track,
                MIN_MEAN_TRACK_LENGTH,
                format!(
                    "points are seen by {mean_track:.1} views on average: clicks propagate poorly; capture with more overlap between views"
                ),
            ));
        }
    }
    out
}

/// How many cameras see the object whose sparse points are `points` (indices into the scene):
/// at least half of them projecting in front of the camera and inside its frame.
pub fn views_seeing(scene: &Scene, points: &[usize]) -> usize {
    if points.is_empty() {
        return 0;
    }
    scene
        .images
        .iter()
        .filter(|im| {
            let cam = scene.camera_of(im);
            let inside = points
                .iter()
                .filter(|&&p| {
                    cam.project(im.pose.world_to_camera(scene.points[p].xyz))
                        .is_some_and(|px| cam.contains(px))
                })
                .count();
            2 * inside >= points.len()
        })
        .count()
}

/// The check of the clicked object's visibility: too few cameras see it.
pub fn check_object_visibility(scene: &Scene, object: &str, points: &[usize]) -> Option<Warning> {
    let seeing = views_seeing(scene, points);
    (seeing < MIN_VIEWS_SEEING_OBJECT).then(|| {
        Warning::new(
            Stage::Scene,
            "few_cameras_see_object",
            seeing as f64,
            MIN_VIEWS_SEEING_OBJECT as f64,
            format!(
                "only {seeing} of {} cameras see the clicked object (half its points in frame): its field is seen from too few sides; capture more views around it",
                scene.images.len()
            ),
        )
        .about(object)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{
        Camera, Feature, ImageView, Point3D, Pose, SceneCamera, SourceFormat, TrackElement,
    };
    use glam::DVec3;

    /// `views` cameras on a ring round 60 points near the origin, each seeing every point at
    /// its exact projection shifted by `shift_px`.
    fn ring(views: usize, shift_px: f64) -> Scene {
        let cam = Camera::pinhole(200, 150, 180.0, 180.0, 100.0, 75.0);
        let mut rng = crate::util::Rng::new(3);
        let pts: Vec<DVec3> = (0..60)
            .map(|_| {
                DVec3::new(
                    rng.range(-0.3, 0.3),
                    rng.range(-0.3, 0.3),
                    rng.range(-0.3, 0.3),
                )
            })
            .collect();
        let mut images = Vec::new();
        let mut tracks = vec![Vec::new(); pts.len()];
        for v in 0..views {
            let a = std::f64::consts::TAU * v as f64 / views as f64;
            let pose = Pose::look_at(
                DVec3::new(3.0 * a.cos(), 3.0 * a.sin(), 1.0),
                DVec3::ZERO,
                DVec3::Z,
            );
            let features = pts
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    tracks[i].push(TrackElement {
                        image: v,
                        feature: i,
                    });
                    let xy = cam.project(pose.world_to_camera(*p)).unwrap();
                    Feature {
                        xy: xy + glam::DVec2::new(shift_px, 0.0),
                        point: Some(i),
                    }
                })
                .collect();
            images.push(ImageView {
                id: v as u32 + 1,
                name: format!("v{v}.png"),
                path: format!("v{v}.png").into(),
                camera: 0,
                pose,
                mask_path: None,
                depth_path: None,
                features,
                depth_bounds: None,
            });
        }
        Scene {
            source: "ring".into(),
            format: SourceFormat::ColmapBinary,
            cameras: vec![SceneCamera { id: 1, camera: cam }],
            images,
            points: pts
                .iter()
                .zip(tracks)
                .enumerate()
                .map(|(i, (p, track))| Point3D {
                    id: i as u64 + 1,
                    xyz: *p,
                    rgb: [0; 3],
                    error: -1.0,
                    track,
                })
                .collect(),
            depth_scale: 1.0,
            applied_transform: None,
        }
    }

    fn codes(s: &Scene) -> Vec<&'static str> {
        check_scene(s).iter().map(|w| w.code).collect()
    }

    #[test]
    fn a_consistent_scene_passes_and_each_fault_is_named() {
        let good = ring(12, 0.0);
        assert!(codes(&good).is_empty());
        let all: Vec<usize> = (0..60).collect();
        assert_eq!(views_seeing(&good, &all), 12);
        assert!(check_object_visibility(&good, "o", &all).is_none());
        assert_eq!(codes(&ring(12, 3.0)), ["high_reprojection_error"]);
        // Keep two views of every track: short tracks.
        let two = good.subset(&[0, 6]);
        assert!(codes(&two).contains(&"short_tracks"));
        let w = check_object_visibility(&two, "o", &all).unwrap();
        assert_eq!((w.code, w.figure), ("few_cameras_see_object", 2.0));
        // Two of twelve views lose their tracks.
        let mut lost = good.clone();
        for im in &mut lost.images[..2] {
            for f in &mut im.features {
                f.point = None;
            }
        }
        assert!(codes(&lost).contains(&"views_without_tracks"));
        assert!(check_registration(10, 8).is_some() && check_registration(10, 10).is_none());
    }
}
