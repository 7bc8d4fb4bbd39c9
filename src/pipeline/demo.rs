//! `objnerf demo`, the README's main job: render the built-in scene, extract one object from its
//! suggested click (segment → train → mesh → turntable), and score every stage against the
//! scene's exact truth: mask IoU, PSNR on held-out views, Chamfer distance to the true mesh.

use super::extract::{extract, object_masks_dir, write_report, ExtractOptions, ExtractReport};
use crate::demo::{read_truth, write_demo_scene, DemoOptions, DemoSummary, ObjectTruth};
use crate::error::{Error, Result};
use crate::field::{eval::evaluate, load_views, MaskSource, RenderOptions};
use crate::mesh::chamfer::{chamfer_distance, chamfer_distance_seen};
use crate::sam::Segmenter;
use crate::scene::io::{mask_file, read_mask};
use crate::scene::Scene;
use crate::segment::ObjectPrompt;
use crate::util::mask::iou;
use crate::util::Progress;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// How the extracted object compares with the truth.
#[derive(Clone, Debug, Serialize)]
pub struct TruthScores {
    pub object: String,
    /// Mean IoU of the masks against the true masks, over the views segmentation marked ok.
    pub miou_ok_views: f64,
    /// PSNR / SSIM of the field on held-out views where the object is fully visible (on white).
    pub heldout_psnr: f64,
    pub heldout_ssim: f64,
    pub heldout_views: usize,
    /// Symmetric Chamfer distance to the true mesh, world units and as a fraction of the true
    /// box diagonal.
    pub chamfer: f64,
    pub chamfer_fraction_of_diagonal: f64,
    /// The same over the parts of each surface some training view sees (in its own mesh), as a
    /// fraction of the diagonal: the ring of cameras cannot see the inside of a cup below its rim.
    pub chamfer_seen_fraction_of_diagonal: f64,
    /// Shares of our surface and of the true surface the training views see.
    pub ours_seen: f64,
    pub truth_seen: f64,
    pub true_box_diagonal: f64,
}

pub struct DemoJob {
    pub scene_dir: PathBuf,
    pub report: ExtractReport,
    pub truth: TruthScores,
}

/// The demo scene written and the object to extract chosen: what the job runs on.
pub struct DemoSetup {
    pub scene_dir: PathBuf,
    pub scene: Scene,
    /// What writing the scene did.
    pub written: DemoSummary,
    pub truth: ObjectTruth,
    pub prompt: ObjectPrompt,
}

/// Write the demo scene to `out/scene` and take `object`'s suggested click (in view 0) as the
/// prompt.
pub fn prepare_demo(out: &Path, object: &str) -> Result<DemoSetup> {
    let scene_dir = out.join("scene");
    let written = write_demo_scene(
        &DemoOptions {
            overwrite: true,
            ..Default::default()
        },
        &scene_dir,
    )?;
    let truths = read_truth(&scene_dir)?;
    let truth = truths
        .iter()
        .find(|t| t.name == object)
        .cloned()
        .ok_or_else(|| {
            let names: Vec<&str> = truths.iter().map(|t| t.name.as_str()).collect();
            Error::invalid(format!(
                "the demo scene has no object '{object}' (it has {})",
                names.join(", ")
            ))
        })?;
    let scene = Scene::load(&scene_dir)?;
    let prompt = ObjectPrompt::click(&scene, object, &truth.view, truth.click)?;
    Ok(DemoSetup {
        scene_dir,
        scene,
        written,
        truth,
        prompt,
    })
}

/// Extract the prepared object into `out/run` and score it against the truth.
pub fn run_demo(
    setup: &DemoSetup,
    out: &Path,
    opts: &ExtractOptions,
    seg: &Segmenter,
    progress: &dyn Progress,
) -> Result<DemoJob> {
    let run = out.join("run");
    let mut report = extract(
        &setup.scene,
        std::slice::from_ref(&setup.prompt),
        opts,
        seg,
        &run,
        progress,
    )?;
    let scores = score(&setup.scene_dir, &setup.scene, &report, &setup.truth)?;
    report.truth = Some(serde_json::to_value(&scores).map_err(|e| Error::json(&run, e))?);
    write_report(&run, &report)?;
    Ok(DemoJob {
        scene_dir: setup.scene_dir.clone(),
        report,
        truth: scores,
    })
}

fn score(
    scene_dir: &Path,
    scene: &Scene,
    report: &ExtractReport,
    truth: &ObjectTruth,
) -> Result<TruthScores> {
    let name = &truth.name;
    let obj = &report.objects[0];
    let truth_masks = scene_dir.join("truth/masks").join(name);
    let seg_masks = object_masks_dir(&report.out, name);
    let mut ious = Vec::new();
    for view in &obj.segmentation.ok_views {
        let a = read_mask(&mask_file(&seg_masks, view))?;
        let b = read_mask(&mask_file(&truth_masks, view))?;
        ious.push(iou(&a, &b));
    }
    let miou = ious.iter().sum::<f64>() / ious.len().max(1) as f64;

    let model = crate::field::io::load_field(&obj.model)?;
    let views = load_views(scene, &MaskSource::Dir(truth_masks), 1)?;
    let held: Vec<_> = views
        .into_iter()
        .filter(|v| {
            obj.segmentation.held_out.contains(&v.name)
                && truth.visible.get(&v.name).copied().unwrap_or(0.0) > 0.999
        })
        .collect();
    let eval = evaluate(&model.field, &RenderOptions::default(), &held);

    let true_mesh = crate::mesh::io::read_ply(&scene_dir.join(format!("truth/meshes/{name}.ply")))?;
    let ours = crate::mesh::io::read_ply(&obj.mesh_glb.with_extension("ply"))?;
    let chamfer = chamfer_distance(&ours, &true_mesh, 50_000, 7);
    let training: Vec<_> = crate::field::RayCamera::for_scene(scene, 1)
        .into_iter()
        .filter(|c| {
            let s = &obj.segmentation;
            !s.held_out.contains(&c.name) && !s.excluded.contains(&c.name)
        })
        .collect();
    let seen = chamfer_distance_seen(&ours, &true_mesh, &training, 50_000, 7);
    let (lo, hi) = true_mesh.bounds();
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo)) as f64;
    Ok(TruthScores {
        object: name.clone(),
        miou_ok_views: miou,
        heldout_psnr: eval.psnr,
        heldout_ssim: eval.ssim,
        heldout_views: eval.num_views,
        chamfer,
        chamfer_fraction_of_diagonal: chamfer / diag,
        chamfer_seen_fraction_of_diagonal: seen.distance / diag,
        ours_seen: seen.a_seen,
        truth_seen: seen.b_seen,
        true_box_diagonal: diag,
    })
}
