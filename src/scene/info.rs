//! `objnerf info`: what a scene holds, as text or JSON.

use super::Scene;
use serde::Serialize;

#[derive(Debug, Serialize)]
pub struct ImageInfo {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub camera_model: &'static str,
    /// Distortion parameters in COLMAP's order (empty for pinhole models).
    pub distortion: Vec<f64>,
    pub num_features: usize,
    pub num_observations: usize,
}

#[derive(Debug, Serialize)]
pub struct TrackStats {
    pub min: usize,
    pub max: usize,
    pub mean: f64,
    pub median: f64,
}

#[derive(Debug, Serialize)]
pub struct Bounds {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

#[derive(Debug, Serialize)]
pub struct SceneInfo {
    pub source: String,
    pub format: String,
    pub num_images: usize,
    pub num_cameras: usize,
    pub num_points: usize,
    pub num_observations: usize,
    pub track_length: Option<TrackStats>,
    /// Mean reprojection error over all observations, recomputed from the model (pixels).
    pub mean_reprojection_error: Option<f64>,
    pub camera_bounds: Option<Bounds>,
    pub point_bounds: Option<Bounds>,
    pub has_masks: bool,
    pub has_depth: bool,
    /// The world's up direction from the cameras ([`Scene::up`]), and how it was found.
    pub up: [f64; 3],
    pub up_why: String,
    pub images: Vec<ImageInfo>,
}

pub fn scene_info(scene: &Scene) -> SceneInfo {
    let images = scene
        .images
        .iter()
        .map(|im| {
            let cam = scene.camera_of(im);
            let (fx, fy) = cam.focal();
            let (cx, cy) = cam.principal_point();
            let first_extra = cam.model.num_params() - distortion_len(cam.model);
            ImageInfo {
                name: im.name.clone(),
                width: cam.width,
                height: cam.height,
                fx,
                fy,
                cx,
                cy,
                camera_model: cam.model.name(),
                distortion: cam.params[first_extra..].to_vec(),
                num_features: im.features.len(),
                num_observations: im.features.iter().filter(|f| f.point.is_some()).count(),
            }
        })
        .collect();
    let mut lens: Vec<usize> = scene.points.iter().map(|p| p.track.len()).collect();
    lens.sort_unstable();
    let track_length = (!lens.is_empty()).then(|| TrackStats {
        min: lens[0],
        max: *lens.last().unwrap(),
        mean: lens.iter().sum::<usize>() as f64 / lens.len() as f64,
        median: if lens.len() % 2 == 1 {
            lens[lens.len() / 2] as f64
        } else {
            0.5 * (lens[lens.len() / 2 - 1] + lens[lens.len() / 2]) as f64
        },
    });
    let errs = scene.reprojection_errors();
    let (cams, pts) = scene.bounds();
    let b = |x: Option<(glam::DVec3, glam::DVec3)>| {
        x.map(|(lo, hi)| Bounds {
            min: lo.to_array(),
            max: hi.to_array(),
        })
    };
    let (up, up_why) = scene.up();
    SceneInfo {
        source: scene.source.display().to_string(),
        format: format!("{:?}", scene.format),
        num_images: scene.images.len(),
        num_cameras: scene.cameras.len(),
        num_points: scene.points.len(),
        num_observations: lens.iter().sum(),
        track_length,
        mean_reprojection_error: (!errs.is_empty())
            .then(|| errs.iter().sum::<f64>() / errs.len() as f64),
        camera_bounds: b(cams),
        point_bounds: b(pts),
        has_masks: scene.images.iter().any(|i| i.mask_path.is_some()),
        has_depth: scene.images.iter().any(|i| i.depth_path.is_some()),
        up: up.to_array(),
        up_why,
        images,
    }
}

fn distortion_len(model: crate::scene::CameraModel) -> usize {
    use crate::scene::CameraModel::*;
    match model {
        SimplePinhole | Pinhole => 0,
        SimpleRadial | SimpleRadialFisheye => 1,
        Radial | RadialFisheye => 2,
        OpenCv | OpenCvFisheye => 4,
        FullOpenCv => 8,
        Fov => 1,
        ThinPrismFisheye => 8,
    }
}

impl SceneInfo {
    /// A human-readable summary.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "scene      {} ({})", self.source, self.format);
        let _ = writeln!(
            s,
            "images     {} ({} camera{})",
            self.num_images,
            self.num_cameras,
            if self.num_cameras == 1 { "" } else { "s" }
        );
        if let Some(im) = self.images.first() {
            let _ = writeln!(
                s,
                "first      {} {}x{} {} fx={:.2} fy={:.2} cx={:.2} cy={:.2}{}",
                im.name,
                im.width,
                im.height,
                im.camera_model,
                im.fx,
                im.fy,
                im.cx,
                im.cy,
                if im.distortion.is_empty() {
                    String::new()
                } else {
                    format!(" distortion={:?}", im.distortion)
                }
            );
        }
        let _ = writeln!(
            s,
            "points     {} ({} observations)",
            self.num_points, self.num_observations
        );
        if let Some(t) = &self.track_length {
            let _ = writeln!(
                s,
                "tracks     length min {} / median {} / mean {:.2} / max {}",
                t.min, t.median, t.mean, t.max
            );
        }
        if let Some(e) = self.mean_reprojection_error {
            let _ = writeln!(s, "reproj.    mean {e:.3} px");
        }
        for (name, b) in [
            ("cameras in", &self.camera_bounds),
            ("points in", &self.point_bounds),
        ] {
            if let Some(b) = b {
                let _ = writeln!(
                    s,
                    "{name:<10} [{:.3}, {:.3}, {:.3}] .. [{:.3}, {:.3}, {:.3}]",
                    b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]
                );
            }
        }
        let _ = writeln!(
            s,
            "masks      {}\ndepth      {}",
            if self.has_masks { "yes" } else { "no" },
            if self.has_depth { "yes" } else { "no" }
        );
        let _ = writeln!(
            s,
            "up         ({:.3}, {:.3}, {:.3}): {}",
            self.up[0], self.up[1], self.up[2], self.up_why
        );
        s
    }
}
