//! `objnerf segment` as a library call: one or more objects from clicks in one view, propagated
//! to every view; writes masks, the segmented sparse clouds, contact sheets and report.json.

use super::output::{write_contact_sheet, write_object};
use super::propagate::{propagate_objects, require_tracks, require_view_tracks};
use super::sam_views::SamViews;
use super::types::{ObjectPrompt, ObjectSegmentation, PropagationOptions, ViewResult, ViewStatus};
use crate::error::{Error, Result};
use crate::sam::Segmenter;
use crate::scene::capture_checks::{check_object_visibility, check_scene};
use crate::scene::Scene;
use crate::segment::mask_checks::check_segmentation;
use crate::util::{AtomicDir, Progress, Warning};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

#[derive(Serialize)]
pub struct ObjectReport {
    pub name: String,
    pub num_points: usize,
    pub num_ok: usize,
    pub num_obstructed: usize,
    pub num_absent: usize,
    /// How far SAM's alternatives for the click agree with its mask (see `segment::checks`).
    pub click_agreement: Option<f64>,
    pub views: Vec<ViewResult>,
}

#[derive(Serialize, Default)]
pub struct Timings {
    pub total: f64,
    pub encoder: f64,
    pub decoder: f64,
    pub propagation: f64,
    pub writing: f64,
}

#[derive(Serialize)]
pub struct SegmentReport {
    pub scene: String,
    pub objects: Vec<ObjectReport>,
    pub encoder_runs: usize,
    pub timings: Timings,
    /// What the scene and segmentation self-checks found ([`segmentation_warnings`]).
    pub warnings: Vec<Warning>,
}

/// Check the prompts before any work: names usable as file names and distinct, at least one
/// click each, every click inside its view.
pub fn check_prompts(scene: &Scene, prompts: &[ObjectPrompt]) -> Result<()> {
    if prompts.is_empty() {
        return Err(Error::invalid(
            "give at least one --point (and --object NAME for several objects)",
        ));
    }
    for o in prompts {
        check_object_name(&o.name)?;
        if o.points.is_empty() {
            return Err(Error::invalid(format!(
                "object '{}' has no --point",
                o.name
            )));
        }
        let im = scene.images.get(o.view).ok_or_else(|| {
            Error::invalid(format!(
                "object '{}': no view {} in the scene",
                o.name, o.view
            ))
        })?;
        let cam = scene.camera_of(im);
        for p in &o.points {
            if !(p.xy[0] >= 0.0
                && p.xy[1] >= 0.0
                && p.xy[0] < cam.width as f64
                && p.xy[1] < cam.height as f64)
            {
                return Err(Error::invalid(format!(
                    "click ({}, {}) for '{}' is outside view '{}' ({}x{})",
                    p.xy[0], p.xy[1], o.name, im.name, cam.width, cam.height
                )));
            }
        }
    }
    let mut names: Vec<&str> = prompts.iter().map(|o| o.name.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    if names.len() != prompts.len() {
        return Err(Error::invalid("object names must differ"));
    }
    Ok(())
}

/// Object names become folder and file names: letters, digits, '_' and '-' only.
pub fn check_object_name(name: &str) -> Result<()> {
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        return Err(Error::invalid(format!(
            "object name '{name}': use letters, digits, '_' and '-'"
        )));
    }
    Ok(())
}

/// Everything that can be checked before SAM is loaded: the prompts, and tracks in the scene
/// and in every clicked view.
pub fn check_request(scene: &Scene, prompts: &[ObjectPrompt]) -> Result<()> {
    check_prompts(scene, prompts)?;
    require_tracks(scene)?;
    for p in prompts {
        require_view_tracks(scene, p.view)?;
    }
    Ok(())
}

/// Segment and write everything under `out` (atomically). `progress` hears one stage,
/// "segment", of one step per view and object.
pub fn segment_scene(
    scene: &Scene,
    prompts: &[ObjectPrompt],
    opts: &PropagationOptions,
    seg: &Segmenter,
    out: &Path,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<(SegmentReport, Vec<ObjectSegmentation>)> {
    let t0 = Instant::now();
    check_request(scene, prompts)?;
    let dest = AtomicDir::new(out, overwrite)?;
    progress.begin("segment", (scene.images.len() * prompts.len()) as u64);
    let mut views = SamViews::new(seg).with_progress(progress);
    let objects = propagate_objects(scene, prompts, &mut views, opts)?;
    progress.end();
    let t_prop = t0.elapsed().as_secs_f64();
    for o in &objects {
        write_object(scene, o, dest.path())?;
        write_contact_sheet(
            scene,
            o,
            &dest.path().join(format!("contact_sheet_{}.png", o.name)),
        )?;
    }
    let report = SegmentReport {
        scene: scene.source.display().to_string(),
        objects: objects.iter().map(ObjectReport::of).collect(),
        warnings: segmentation_warnings(scene, &objects),
        encoder_runs: seg.encoder_runs(),
        timings: Timings {
            total: t0.elapsed().as_secs_f64(),
            encoder: views.encoder_seconds,
            decoder: views.decoder_seconds,
            propagation: t_prop - views.encoder_seconds - views.decoder_seconds,
            writing: t0.elapsed().as_secs_f64() - t_prop,
        },
    };
    let path = dest.path().join("report.json");
    let json = serde_json::to_string_pretty(&report).map_err(|e| Error::json(&path, e))?;
    crate::util::atomic::write_bytes_atomic(&path, json.as_bytes())?;
    dest.commit()?;
    Ok((report, objects))
}

/// The scene's self-checks, and per object the cameras that see it and the segmentation's.
pub fn segmentation_warnings(scene: &Scene, objects: &[ObjectSegmentation]) -> Vec<Warning> {
    let mut out = check_scene(scene);
    for o in objects {
        out.extend(check_object_visibility(scene, &o.name, &o.points));
        out.extend(check_segmentation(scene, o));
    }
    out
}

impl ObjectReport {
    fn of(o: &ObjectSegmentation) -> ObjectReport {
        let count = |s| o.views.iter().filter(|v| v.status == s).count();
        ObjectReport {
            name: o.name.clone(),
            num_points: o.points.len(),
            num_ok: count(ViewStatus::Ok),
            num_obstructed: count(ViewStatus::Obstructed),
            num_absent: count(ViewStatus::Absent),
            click_agreement: o.click_agreement,
            views: o.views.clone(),
        }
    }
}
