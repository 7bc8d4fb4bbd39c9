//! `objnerf render-edit`: an edit file rendered along a camera path (a nerfstudio
//! `camera_path.json`, a scene's own views, or a generated orbit) into numbered frames with the
//! passes asked for, the path it rendered along (`camera_path.json`) and a video.
//!
//! Everything is read and checked before anything is written (the edit, every model it names,
//! the path): a bad input leaves no output. Frames are then written as they are rendered, each
//! file atomically, so a caller can count them for progress (the Blender add-on does).

use crate::edit::{load_edit, EditFile, LoadedBackground, LoadedEdit};
use crate::error::{Error, Result};
use crate::field::{RayCamera, RenderOptions};
use crate::render::composite::{Composite, Frame};
use crate::render::frame_files::{write_frame, write_video, FrameImages, Passes};
use crate::render::gpu::{open_device, renderer, DeviceChoice, DeviceUsed};
use crate::scene::camera_path::{CameraPath, Orbit, PathFrame};
use crate::scene::io::DepthMap;
use crate::scene::Scene;
use crate::util::{Detail, Progress};
use glam::DVec3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where the cameras come from.
#[derive(Clone, Debug)]
pub enum PathSource {
    /// A nerfstudio camera_path.json in the data frame (the scene's own).
    File(PathBuf),
    /// A scene's views, in order.
    Views(PathBuf),
    /// A ring of this many cameras around the edit's objects.
    Orbit(usize),
}

/// How to render an edit.
#[derive(Clone, Debug)]
pub struct RenderEditOptions {
    pub path: PathSource,
    /// Render size (default: the path's; an orbit's 320x240); cameras keep their vertical fov.
    pub size: Option<(u32, u32)>,
    pub passes: Passes,
    pub render: RenderOptions,
    /// Frames per second of scene views and orbits (a path file says its own).
    pub fps: f64,
    /// Also write the frames as a video.
    pub video: bool,
    /// Where frames are drawn (`auto`: a hardware GPU when there is one).
    pub device: DeviceChoice,
}

impl Default for RenderEditOptions {
    fn default() -> Self {
        RenderEditOptions {
            path: PathSource::Orbit(24),
            size: None,
            passes: Passes::default(),
            // A sample per voxel, and samples under 0.3% opacity skipped (their cells never
            // evaluated): on the demo edits the same PSNR as half-voxel steps at 1e-4, in about
            // 40% of the time (examples/results/render_edit.json).
            render: RenderOptions {
                step: 1.0,
                alpha_thresh: 3e-3,
                ..RenderOptions::default()
            },
            fps: 24.0,
            video: true,
            device: DeviceChoice::default(),
        }
    }
}

/// What was rendered.
#[derive(Clone, Debug, Serialize)]
pub struct RenderEditReport {
    pub out: PathBuf,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// Fields drawn per frame (the background's included).
    pub layers: usize,
    pub seconds: f64,
    pub frames_per_second: f64,
    pub video: Option<PathBuf>,
    pub peak_rss_mib: u64,
    /// Which device drew the frames, and why.
    pub device: DeviceUsed,
}

/// The default orbit: around the visible objects' world boxes (else the background's box),
/// looking at their centre from 2.8 times their half-diagonal (the whole box in a 45 degree
/// view), a third of that above, the capture's up kept up.
pub fn default_orbit(edit: &LoadedEdit, views: usize, size: (u32, u32), fps: f64) -> Orbit {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for b in edit.visible().filter_map(|o| o.world_box()) {
        lo = lo.min(b.0);
        hi = hi.max(b.1);
    }
    if let (false, LoadedBackground::Field(m)) = (lo.is_finite(), &edit.background) {
        if m.field.space == crate::space::Space::Box {
            (lo, hi) = (m.field.box_min.as_dvec3(), m.field.box_max.as_dvec3());
        }
    }
    if !lo.is_finite() {
        (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    }
    let up = up_of(edit).unwrap_or(DVec3::Z);
    let half = 0.5 * (hi - lo).length();
    let radius = 2.8 * half.max(1e-6);
    Orbit {
        center: 0.5 * (lo + hi),
        radius,
        elevation: radius / 3.0,
        up,
        views,
        fov_y_deg: 45.0,
        width: size.0,
        height: size.1,
        fps,
    }
}

/// The capture's up direction, as the background's (else the first object's) model recorded it.
fn up_of(edit: &LoadedEdit) -> Option<DVec3> {
    let bg = match &edit.background {
        LoadedBackground::Field(m) => m.up(),
        LoadedBackground::Color(_) => None,
    };
    bg.or_else(|| edit.objects.iter().find_map(|o| o.model.up()))
        .and_then(|u| u.try_normalize())
}

/// The cameras to render along, at the size asked for.
pub fn camera_path(edit: &LoadedEdit, opts: &RenderEditOptions) -> Result<CameraPath> {
    let path = match &opts.path {
        PathSource::File(p) => CameraPath::read(p, &PathFrame::Data)?,
        PathSource::Views(scene) => CameraPath::from_scene_views(&Scene::load(scene)?, opts.fps)?,
        PathSource::Orbit(n) => {
            let size = opts.size.unwrap_or((320, 240));
            CameraPath::orbit(&default_orbit(edit, *n, size, opts.fps))?
        }
    };
    match opts.size {
        Some((w, h)) if (w, h) != (path.width, path.height) => path.resized(w, h),
        _ => Ok(path),
    }
}

/// The images of one rendered frame; depth from the edit's units to metres.
fn frame_images(f: &Frame, passes: Passes, metres_per_unit: f64) -> FrameImages {
    FrameImages {
        rgb: f.rgb8(),
        alpha: passes.alpha.then(|| f.alpha8()),
        depth: passes.depth.then(|| DepthMap {
            width: f.width,
            height: f.height,
            metres: f
                .depth
                .iter()
                .map(|d| (*d as f64 * metres_per_unit) as f32)
                .collect(),
        }),
        index: passes.index.then(|| f.index8()),
    }
}

/// Read and check the edit (and every model it names) and the path; nothing is written.
pub fn prepare(edit_path: &Path, opts: &RenderEditOptions) -> Result<(LoadedEdit, CameraPath)> {
    let edit = load_edit(EditFile::read(edit_path)?, Some(&opts.render))?;
    if edit.objects.len() > 254 {
        return Err(Error::format(
            edit_path,
            "objects: more than 254 objects do not fit the 8-bit object-index pass",
        ));
    }
    let path = camera_path(&edit, opts)?;
    Ok((edit, path))
}

/// Render `edit_path` as `opts` says into `out` (created if needed; frames of an earlier render
/// with the same names are replaced).
pub fn render_edit(
    edit_path: &Path,
    opts: &RenderEditOptions,
    out: &Path,
    progress: &dyn Progress,
) -> Result<RenderEditReport> {
    let (edit, path) = prepare(edit_path, opts)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let composite = Composite::from_edit(&edit, opts.render);
    let (gpu, mut device) = open_device(opts.device)?;
    let frames = renderer(&composite, gpu.as_ref(), opts.device, &mut device)?;
    progress.note(&format!("rendering on {}", device.describe()));
    let mpu = edit.file.metres_per_unit;
    let start = Instant::now();
    let mut rgb = Vec::with_capacity(path.cameras.len());
    progress.begin("render", path.cameras.len() as u64);
    for (k, c) in path.cameras.iter().enumerate() {
        let cam = RayCamera::new(format!("frame_{k:05}"), c.camera.clone(), c.pose);
        let f = frames.render_frame(&cam)?;
        let images = frame_images(&f, opts.passes, mpu);
        write_frame(out, k, &images)?;
        let fps = (k + 1) as f64 / start.elapsed().as_secs_f64().max(1e-9);
        let msg = format!("{fps:.2} frames/s");
        progress.advance(k as u64 + 1, Detail::Item(&msg));
        if opts.video {
            rgb.push(images.rgb);
        }
    }
    progress.end();
    let seconds = start.elapsed().as_secs_f64();
    path.write(&out.join("camera_path.json"), &PathFrame::Data)?;
    let video = if opts.video {
        Some(write_video(out, &rgb, path.fps)?)
    } else {
        None
    };
    Ok(RenderEditReport {
        out: out.to_path_buf(),
        frames: path.cameras.len(),
        width: path.width,
        height: path.height,
        layers: composite.layers.len(),
        seconds,
        frames_per_second: path.cameras.len() as f64 / seconds.max(1e-9),
        video,
        peak_rss_mib: crate::util::mem::peak_rss_mib(),
        device,
    })
}
