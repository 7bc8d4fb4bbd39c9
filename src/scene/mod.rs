//! Scene in: one [`Scene`] type that every capture format is read into and written from.
//!
//! `Scene::load` finds the format from the path; each reader lives in `formats/`.

pub mod camera;
pub mod camera_path;
pub mod capture_checks;
pub mod formats;
pub mod frames;
pub mod info;
pub mod io;
pub mod sfm;
mod subset;

pub use camera::{Camera, CameraModel};
pub use frames::Pose;

use crate::error::{Error, Result};
use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A 2D feature of an image and the 3D point it observes, if any (COLMAP's point3D_id).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Feature {
    pub xy: DVec2,
    /// Index into [`Scene::points`].
    pub point: Option<usize>,
}

/// One observation of a 3D point: an image and the index of the feature in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TrackElement {
    /// Index into [`Scene::images`].
    pub image: usize,
    /// Index into that image's `features`.
    pub feature: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Point3D {
    /// COLMAP's id, kept so that models round-trip unchanged.
    pub id: u64,
    pub xyz: DVec3,
    pub rgb: [u8; 3],
    /// Mean reprojection error in pixels (COLMAP's), or -1 when unknown.
    pub error: f64,
    pub track: Vec<TrackElement>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageView {
    /// COLMAP's id, kept so that models round-trip unchanged.
    pub id: u32,
    /// Name as the source gives it (COLMAP: path relative to the image folder).
    pub name: String,
    /// Where the image file is.
    pub path: PathBuf,
    /// Index into [`Scene::cameras`].
    pub camera: usize,
    pub pose: Pose,
    pub mask_path: Option<PathBuf>,
    pub depth_path: Option<PathBuf>,
    pub features: Vec<Feature>,
    /// The nearest and farthest depth of the scene in this view where the source gives them
    /// (LLFF's `poses_bounds.npy`): a capture without a sparse model still bounds its depth.
    #[serde(default)]
    pub depth_bounds: Option<[f64; 2]>,
}

/// Camera intrinsics with the COLMAP id they were read under.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneCamera {
    pub id: u32,
    pub camera: Camera,
}

/// The format a scene was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SourceFormat {
    ColmapBinary,
    ColmapText,
    Nerfstudio,
    NerfSynthetic,
    Llff,
    RgbdRedwood,
    Demo,
}

/// A multi-view capture: cameras, posed images, and a sparse model with 2D-3D tracks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// The file or folder the scene was read from.
    pub source: PathBuf,
    pub format: SourceFormat,
    pub cameras: Vec<SceneCamera>,
    pub images: Vec<ImageView>,
    pub points: Vec<Point3D>,
    /// Depth images store depth * this factor (PNG millimetres: 1000).
    pub depth_scale: f64,
    /// nerfstudio's `applied_transform` (3x4, row-major), kept for writing back.
    pub applied_transform: Option<[[f64; 4]; 3]>,
}

impl Scene {
    /// Read a scene, finding its format from the path:
    /// a COLMAP model folder (`cameras.bin`/`cameras.txt`, or a folder with `sparse/0/`),
    /// a nerfstudio or NeRF-synthetic `transforms*.json` (or a folder holding one),
    /// an LLFF folder (`poses_bounds.npy`), or a Redwood RGB-D folder (`trajectory.log`).
    pub fn load(path: &Path) -> Result<Scene> {
        formats::load(path)
    }

    /// The world's up direction, from the cameras ([`frames::up_from_cameras`]), and how it was
    /// found.
    pub fn up(&self) -> (DVec3, String) {
        frames::up_from_cameras(self.images.iter().map(|im| &im.pose))
    }

    pub fn camera_of(&self, image: &ImageView) -> &Camera {
        &self.cameras[image.camera].camera
    }

    /// Find an image by its name, its file name, or its file stem (`r_0`, `r_0.png`,
    /// `train/r_0.png` all find lego's first view), or by its index in the scene.
    pub fn find_image(&self, key: &str) -> Result<usize> {
        if let Some(i) = self.images.iter().position(|im| im.name == key) {
            return Ok(i);
        }
        let by = |f: &dyn Fn(&ImageView) -> bool| -> Vec<usize> {
            self.images
                .iter()
                .enumerate()
                .filter(|(_, im)| f(im))
                .map(|(i, _)| i)
                .collect()
        };
        let file_name = |im: &ImageView| {
            Path::new(&im.name)
                .file_name()
                .map(|s| s.to_string_lossy().to_string())
        };
        let stem = |im: &ImageView| {
            Path::new(&im.name)
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
        };
        for hits in [
            by(&|im| file_name(im).as_deref() == Some(key)),
            by(&|im| stem(im).as_deref() == Some(key)),
        ] {
            match hits.len() {
                0 => {}
                1 => return Ok(hits[0]),
                _ => {
                    return Err(Error::invalid(format!(
                        "view '{key}' is ambiguous in {}: it names {} images",
                        self.source.display(),
                        hits.len()
                    )))
                }
            }
        }
        if let Ok(i) = key.parse::<usize>() {
            if i < self.images.len() {
                return Ok(i);
            }
        }
        Err(Error::invalid(format!(
            "no view '{key}' in {} ({} images, e.g. '{}')",
            self.source.display(),
            self.images.len(),
            self.images.first().map(|i| i.name.as_str()).unwrap_or("")
        )))
    }

    /// True when the sparse model has 2D-3D tracks (needed for multi-view segmentation).
    pub fn has_tracks(&self) -> bool {
        self.points.iter().any(|p| !p.track.is_empty())
    }

    /// Check the internal references (camera, point and feature indices) and that the tracks and
    /// features agree. Readers call this before returning.
    pub fn validate(&self, path: &Path) -> Result<()> {
        for im in &self.images {
            if im.camera >= self.cameras.len() {
                return Err(Error::format(
                    path,
                    format!("image '{}' refers to a missing camera", im.name),
                ));
            }
            for f in &im.features {
                if let Some(p) = f.point {
                    if p >= self.points.len() {
                        return Err(Error::format(
                            path,
                            format!("image '{}' has a feature with a missing 3D point", im.name),
                        ));
                    }
                }
                if !f.xy.is_finite() {
                    return Err(Error::format(
                        path,
                        format!("image '{}' has a non-finite 2D feature", im.name),
                    ));
                }
            }
        }
        for p in &self.points {
            if !p.xyz.is_finite() {
                return Err(Error::format(
                    path,
                    format!("3D point {} is not finite", p.id),
                ));
            }
            for t in &p.track {
                let ok = self
                    .images
                    .get(t.image)
                    .and_then(|im| im.features.get(t.feature))
                    .is_some();
                if !ok {
                    return Err(Error::format(
                        path,
                        format!(
                            "3D point {} has a track element outside the images' features",
                            p.id
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Rebuild every image's feature → point links from the points' tracks.
    pub fn link_features_from_tracks(&mut self) {
        for im in &mut self.images {
            for f in &mut im.features {
                f.point = None;
            }
        }
        for (pi, p) in self.points.iter().enumerate() {
            for t in &p.track {
                if let Some(f) = self
                    .images
                    .get_mut(t.image)
                    .and_then(|im| im.features.get_mut(t.feature))
                {
                    f.point = Some(pi);
                }
            }
        }
    }

    /// Axis-aligned bounds of the camera centres and of the sparse points (min, max).
    #[allow(clippy::type_complexity)] // two optional (min, max) boxes read plainly enough
    pub fn bounds(&self) -> (Option<(DVec3, DVec3)>, Option<(DVec3, DVec3)>) {
        fn bbox(it: impl Iterator<Item = DVec3>) -> Option<(DVec3, DVec3)> {
            it.fold(None, |acc, p| match acc {
                None => Some((p, p)),
                Some((lo, hi)) => Some((lo.min(p), hi.max(p))),
            })
        }
        (
            bbox(self.images.iter().map(|im| im.pose.center())),
            bbox(self.points.iter().map(|p| p.xyz)),
        )
    }

    /// Reprojection error of every observation, in pixels.
    pub fn reprojection_errors(&self) -> Vec<f64> {
        let mut errs = Vec::new();
        for p in &self.points {
            for t in &p.track {
                let im = &self.images[t.image];
                let cam = self.camera_of(im);
                if let Some(px) = cam.project(im.pose.world_to_camera(p.xyz)) {
                    errs.push((px - im.features[t.feature].xy).length());
                }
            }
        }
        errs
    }
}
