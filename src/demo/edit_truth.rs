//! The exact truth of an edit of the demo scene (`objnerf demo-scene --edit EDIT --path PATH`):
//! the scene rendered by the ray tracer with the edit's objects moved, turned, scaled, duplicated,
//! removed and recoloured, along a camera path, into files named as `objnerf render-edit` names
//! them, so that the two folders compare file by file.
//!
//! Which demo object an edit object is: the one whose name it has, or whose name comes before its
//! first '.' (Blender names a duplicate `mug.001`). Its transform is the edit's (the object's
//! surface, texture and all, carried by the similarity). Over a background model the scene keeps
//! its floor, backdrop and every object the edit does not name (the background field is the
//! scene without the edit's objects); over a plain colour only the edit's objects are drawn.
//! A radiance field carries the light it was captured under: moved and turned, an object keeps
//! its shading (the truth shades it with the light turned along with it, as in its captured
//! pose), and a recolour applies the edit's recolour function to each sample's radiance, as the
//! renderer applies it to the field's radiance.

use super::geometry::{Object, World};
use super::render::{pixel_ray, AMBIENT, DIFFUSE, RING_RADIUS, SKY, SS, TARGET};
use super::texture::Textures;
use crate::edit::recolour::PreparedRecolour;
use crate::edit::{LoadedBackground, LoadedEdit};
use crate::error::{Error, Result};
use crate::render::frame_files::{write_frame, FrameImages, Passes};
use crate::scene::camera_path::{CameraPath, Orbit};
use crate::scene::io::DepthMap;
use crate::scene::{Camera, Pose};
use crate::util::{Detail, Progress};
use glam::{DMat3, DVec2, DVec3};
use rayon::prelude::*;
use std::path::Path;

/// A ring of `views` cameras like the demo's own (radius 1.95 m around the scene's centre, eyes
/// at 0.85 m, the demo camera's field of view) at `width` x `height`: novel views to render
/// edits of the demo scene along.
pub fn demo_orbit(views: usize, width: u32, height: u32) -> Result<CameraPath> {
    let cam = super::render::demo_camera(width, height);
    CameraPath::orbit(&Orbit {
        center: TARGET,
        radius: RING_RADIUS,
        elevation: 0.85 - TARGET.z,
        up: DVec3::Z,
        views,
        fov_y_deg: 2.0 * (0.5 * height as f64 / cam.focal().1).atan().to_degrees(),
        width,
        height,
        fps: 24.0,
    })
}

/// The demo object an edit object's name stands for (`mug`, or `mug.001` for a duplicate).
pub fn demo_object_of(world: &World, name: &str) -> Option<usize> {
    let base = name.split('.').next().unwrap_or(name);
    world
        .objects
        .iter()
        .position(|o| o.name == name || o.name == base)
}

/// The demo scene as an edit makes it.
pub struct EditTruth {
    world: World,
    tex: Textures,
    /// Per object of `world`: its object-index value (0: an object of the background).
    index: Vec<u8>,
    recolour: Vec<Option<PreparedRecolour>>,
    /// Per object of `world`: the direction towards the light in its shading (the world's
    /// light turned by the object's edit).
    light: Vec<DVec3>,
    /// What rays that hit nothing show.
    background: DVec3,
    metres_per_unit: f64,
}

impl EditTruth {
    /// The edited demo scene (textures of demo seed `seed`).
    pub fn new(edit: &LoadedEdit, seed: u64) -> Result<EditTruth> {
        let demo = World::demo();
        let mut named = vec![false; demo.objects.len()];
        let mut placed: Vec<(Object, u8, Option<PreparedRecolour>, DVec3)> = Vec::new();
        for o in &edit.objects {
            let k = demo_object_of(&demo, &o.name).ok_or_else(|| {
                Error::format(
                    &edit.file.path,
                    format!(
                        "objects[{}].name: '{}' is not an object of the demo scene ({}), so it has no exact truth",
                        o.index,
                        o.name,
                        super::OBJECT_NAMES.join(", ")
                    ),
                )
            })?;
            named[k] = true;
            if !o.visible {
                continue;
            }
            let s = &o.to_world;
            let mut obj = demo.objects[k].clone();
            obj.place = obj
                .place
                .then(s.scale, DMat3::from_quat(s.rotation), s.translation);
            let light = s.rotation * demo.light;
            let index = (o.index + 1).min(255) as u8;
            placed.push((obj, index, o.recolour.map(|r| r.prepare()), light));
        }
        let scenery = matches!(edit.background, LoadedBackground::Field(_));
        let mut objects = Vec::new();
        let mut index = Vec::new();
        let mut recolour = Vec::new();
        let mut light = Vec::new();
        if scenery {
            for (k, obj) in demo.objects.iter().enumerate() {
                if !named[k] {
                    objects.push(obj.clone());
                    index.push(0);
                    recolour.push(None);
                    light.push(demo.light);
                }
            }
        }
        for (obj, i, r, l) in placed {
            objects.push(obj);
            index.push(i);
            recolour.push(r);
            light.push(l);
        }
        let background = match edit.background {
            LoadedBackground::Color(c) => DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64),
            LoadedBackground::Field(_) => DVec3::from_array(SKY.map(|c| c as f64 / 255.0)),
        };
        Ok(EditTruth {
            world: World {
                objects,
                scenery,
                ..demo
            },
            tex: Textures::new(seed),
            index,
            recolour,
            light,
            background,
            metres_per_unit: edit.file.metres_per_unit,
        })
    }

    /// One pixel: colour (3x3 samples), coverage, and at its centre the z-depth (world units,
    /// +inf for nothing) and the object-index value.
    fn pixel(&self, cam: &Camera, pose: &Pose, col: u32, row: u32) -> ([f64; 3], f64, f32, u8) {
        let mut acc = DVec3::ZERO;
        let mut hits = 0;
        let mut centre = (f32::INFINITY, 0u8);
        for sy in 0..SS {
            for sx in 0..SS {
                let px = DVec2::new(
                    col as f64 + (sx as f64 + 0.5) / SS as f64,
                    row as f64 + (sy as f64 + 0.5) / SS as f64,
                );
                let hit = self.world.trace(&pixel_ray(cam, pose, px), None);
                let c = match &hit {
                    Some(h) => {
                        hits += 1;
                        let light = self.light.get(h.id as usize).unwrap_or(&self.world.light);
                        let shade = AMBIENT + DIFFUSE * h.n.dot(*light).max(0.0);
                        let c = self.tex.albedo(&self.world, h) * shade;
                        match self.recolour.get(h.id as usize).copied().flatten() {
                            Some(r) => {
                                let rgb = c.to_array().map(|v| v.clamp(0.0, 1.0) as f32);
                                DVec3::from_array(r.apply(rgb).map(|v| v as f64))
                            }
                            None => c,
                        }
                    }
                    None => self.background,
                };
                acc += c;
                if sx == SS / 2 && sy == SS / 2 {
                    if let Some(h) = hit {
                        let i = self.index.get(h.id as usize).copied().unwrap_or(0);
                        centre = (pose.world_to_camera(h.p).z as f32, i);
                    }
                }
            }
        }
        let n = (SS * SS) as f64;
        let c = acc / n;
        (c.to_array(), hits as f64 / n, centre.0, centre.1)
    }

    /// Render the edited scene from one camera.
    pub fn render(&self, cam: &Camera, pose: &Pose, passes: Passes) -> FrameImages {
        let (w, h) = (cam.width, cam.height);
        let px: Vec<([f64; 3], f64, f32, u8)> = (0..h)
            .into_par_iter()
            .flat_map_iter(|row| (0..w).map(move |col| self.pixel(cam, pose, col, row)))
            .collect();
        let at = |x: u32, y: u32| &px[(y * w + x) as usize];
        let byte = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        let mpu = self.metres_per_unit as f32;
        FrameImages {
            rgb: image::RgbImage::from_fn(w, h, |x, y| image::Rgb(at(x, y).0.map(byte))),
            alpha: passes
                .alpha
                .then(|| image::GrayImage::from_fn(w, h, |x, y| image::Luma([byte(at(x, y).1)]))),
            depth: passes.depth.then(|| DepthMap {
                width: w,
                height: h,
                metres: px.iter().map(|p| p.2 * mpu).collect(),
            }),
            index: passes
                .index
                .then(|| image::GrayImage::from_fn(w, h, |x, y| image::Luma([at(x, y).3]))),
        }
    }
}

/// Render the truth of `edit` along `path` into `out` (frames as `render-edit` names them, and
/// the path as `camera_path.json`), the folder built aside and moved into place. Returns the
/// number of frames.
pub fn write_edit_truth(
    edit: &LoadedEdit,
    path: &CameraPath,
    seed: u64,
    passes: Passes,
    out: &Path,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<usize> {
    let truth = EditTruth::new(edit, seed)?;
    let dir = crate::util::AtomicDir::new(out, overwrite)?;
    progress.begin("truth", path.cameras.len() as u64);
    for (k, c) in path.cameras.iter().enumerate() {
        let f = truth.render(&c.camera, &c.pose, passes);
        write_frame(dir.path(), k, &f)?;
        progress.advance(k as u64 + 1, Detail::None);
    }
    progress.end();
    path.write(
        &dir.path().join("camera_path.json"),
        &crate::scene::camera_path::PathFrame::Data,
    )?;
    dir.commit()?;
    Ok(path.cameras.len())
}
