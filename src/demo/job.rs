//! `objnerf demo`, the README's main job: render the built-in scene, extract one object from its
//! suggested click (segment → train → mesh → turntable), and score every stage against the
//! scene's exact truth: mask IoU, PSNR on held-out views, Chamfer distance to the true mesh.

use super::{read_truth, write_demo_scene, DemoOptions};
use crate::error::{Error, Result};
use crate::eval::chamfer::chamfer_distance;
use crate::extract::{extract, write_report, ExtractOptions, ExtractReport};
use crate::field::{eval::evaluate, rays::load_views, MaskSource, RenderOptions};
use crate::scene::Scene;
use crate::segment::output::mask_file_stem;
use crate::segment::propagate::{ObjectPrompt, PointPrompt};
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
    pub true_box_diagonal: f64,
}

pub struct DemoJob {
    pub scene_dir: PathBuf,
    pub report: ExtractReport,
    pub truth: TruthScores,
}

/// Write the scene to `out/scene`, extract `object` into `out/run`, score it.
pub fn run_demo(out: &Path, object: &str, opts: &ExtractOptions) -> Result<DemoJob> {
    let scene_dir = out.join("scene");
    let s = write_demo_scene(
        &DemoOptions {
            overwrite: true,
            ..Default::default()
        },
        &scene_dir,
    )?;
    println!(
        "demo scene: {} views, {} points -> {}",
        s.views,
        s.points,
        s.out.display()
    );
    let truths = read_truth(&scene_dir)?;
    let truth = truths.iter().find(|t| t.name == object).ok_or_else(|| {
        let names: Vec<&str> = truths.iter().map(|t| t.name.as_str()).collect();
        Error::invalid(format!(
            "the demo scene has no object '{object}' (it has {})",
            names.join(", ")
        ))
    })?;
    let scene = Scene::load(&scene_dir)?;
    let prompt = ObjectPrompt {
        name: object.to_string(),
        view: scene.find_image(&truth.view)?,
        points: vec![PointPrompt {
            xy: truth.click,
            positive: true,
        }],
        bbox: None,
    };
    println!(
        "extracting '{object}' from one click at ({:.1}, {:.1}) in {}",
        truth.click[0], truth.click[1], truth.view
    );
    let run = out.join("run");
    let mut report = extract(&scene_dir, &scene, &[prompt], opts, &run)?;
    let scores = score(&scene_dir, &scene, &report, truth)?;
    report.truth = Some(serde_json::to_value(&scores).map_err(|e| Error::json(&run, e))?);
    write_report(&run.join("report.json"), &report)?;
    Ok(DemoJob {
        scene_dir,
        report,
        truth: scores,
    })
}

fn score(
    scene_dir: &Path,
    scene: &Scene,
    report: &ExtractReport,
    truth: &super::ObjectTruth,
) -> Result<TruthScores> {
    let name = &truth.name;
    let obj = &report.objects[0];
    let truth_masks = scene_dir.join("truth/masks").join(name);
    let seg_masks = report.out.join("segment/masks").join(name);
    let mut ious = Vec::new();
    for view in &obj.segmentation.ok_views {
        let stem = mask_file_stem(view);
        let a = crate::scene::io::read_mask(&seg_masks.join(format!("{stem}.png")))?;
        let b = crate::scene::io::read_mask(&truth_masks.join(view))?;
        ious.push(crate::segment::hull::iou(&a, &b));
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
        true_box_diagonal: diag,
    })
}

/// `objnerf demo` arguments.
#[derive(clap::Args, Debug)]
pub struct DemoCmd {
    /// Run folder (its contents are replaced): scene/ and run/ go in it.
    #[arg(long, default_value = "runs/demo")]
    pub out: PathBuf,
    /// Which object to extract: mug, sphere, box or torus.
    #[arg(long, default_value = "mug")]
    pub object: String,
    /// Seconds of training.
    #[arg(long, default_value_t = 90.0)]
    pub time_budget: f64,
    /// Most training steps.
    #[arg(long, default_value_t = 6000)]
    pub steps: usize,
}

impl DemoCmd {
    pub fn run(self) -> Result<()> {
        let opts = ExtractOptions {
            time_budget: Some(self.time_budget),
            steps: self.steps,
            overwrite: true,
            hold_out_every: 6,
            ..Default::default()
        };
        let job = run_demo(&self.out, &self.object, &opts)?;
        crate::extract::cli::print_summary(&job.report);
        let t = &job.truth;
        println!(
            "against the truth: mask mIoU {:.3} (ok views); held-out PSNR {:.2} dB, SSIM {:.3} ({} views); \
             Chamfer {:.4} = {:.2}% of the true box diagonal",
            t.miou_ok_views,
            t.heldout_psnr,
            t.heldout_ssim,
            t.heldout_views,
            t.chamfer,
            100.0 * t.chamfer_fraction_of_diagonal
        );
        println!(
            "open {} in Blender (File > Import > glTF 2.0) or any glTF viewer",
            job.report.out.join("mesh.glb").display()
        );
        Ok(())
    }
}
