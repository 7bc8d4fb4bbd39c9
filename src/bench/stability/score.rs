//! Scoring a case against the truth: masks (mIoU over the views segmentation kept, the share of
//! views where the object is visible that got a good mask, obstructed-view F1), the field on
//! views it never trained on (PSNR over the true mask's box, as the field's self-check measures
//! it), and the mesh (Chamfer distance to the true mesh over the true box's diagonal). The
//! floors below say which results count as good.

use crate::error::Result;
use crate::field::{load_views, Field, MaskSource};
use crate::fit::object_checks::measure_held_out;
use crate::mesh::chamfer::chamfer_distance;
use crate::mesh::Mesh;
use crate::scene::io::{mask_file, read_mask};
use crate::scene::Scene;
use crate::segment::ViewStatus;
use crate::util::mask::iou;
use image::GrayImage;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

/// A mask is good at this IoU with the truth, and a segmentation at this mIoU over the views it
/// kept (the floor for the 10th percentile of click stability).
pub const MIOU_FLOOR: f64 = 0.85;
/// Obstructed-view F1 under this: segmentation mostly mistook which views hide the object.
pub const F1_FLOOR: f64 = 0.5;
/// Object PSNR (dB over the true mask's padded box on white, in views the field never trained
/// on) under this is a visibly wrong object. The demo mug scores about 20 dB there with the
/// suite's step budget (its fine texture is near the grid's resolution; over the whole image
/// that is 34 dB); a mug smeared by 2 degrees of pose noise or made from 5 views scores 11-13.
/// (Restored: commit 9084cc6 lowered it to 16 in the change that made cases pass, see
/// CONTRIBUTING.md.)
pub const PSNR_FLOOR: f64 = 18.0;
/// Of the views that show the object, the share with a good mask (IoU at [`MIOU_FLOOR`]) under
/// this is a failed segmentation even when the mean holds: one view in ten with a visibly wrong
/// mask is what a user paging through the contact sheet notices, and each such view teaches the
/// field a wrong silhouette.
pub const SEGMENT_SHARE_FLOOR: f64 = 0.9;
/// Of the novel views scored (at most [`MAX_EVAL_VIEWS`]), the share at [`PSNR_FLOOR`] under
/// this is a failed field even when the mean holds: one bad view in six can be an unlucky angle,
/// two are a third of an orbit around the object.
pub const FIELD_SHARE_FLOOR: f64 = 0.8;
/// Chamfer distance over the true box diagonal above this is a visibly wrong shape (the demo
/// objects come out at 1-2%; `tests/extract.rs` holds them to 2% at more steps).
pub const CHAMFER_FLOOR: f64 = 0.03;
/// A view shows the object when at least this fraction of it is visible (in frame and
/// unoccluded); below, segmentation should call it obstructed (or cut by the frame).
pub const VISIBLE: f64 = 0.5;
/// Views scored for the field show this fraction of the object at least (fully visible:
/// a true mask of a partly hidden object is not what the field should render).
pub const FULLY_VISIBLE: f64 = 0.99;
/// Novel views scored per object at most (spread over the candidates).
pub const MAX_EVAL_VIEWS: usize = 6;

/// The truth of a subject: per object, per view name, the true mask and visible fraction; true
/// meshes where known; and the unperturbed scene with its images for novel views.
pub struct Truth {
    pub scene: Scene,
    pub masks: BTreeMap<String, BTreeMap<String, GrayImage>>,
    pub visible: BTreeMap<String, BTreeMap<String, f64>>,
    pub meshes: BTreeMap<String, PathBuf>,
}

impl Truth {
    /// The demo scene's truth (`truth/masks/<object>/`, objects.json, `truth/meshes/`).
    pub fn demo(scene_dir: &std::path::Path, scene: &Scene) -> Result<Truth> {
        let objects = crate::demo::read_truth(scene_dir)?;
        let mut t = Truth {
            scene: scene.clone(),
            masks: BTreeMap::new(),
            visible: BTreeMap::new(),
            meshes: BTreeMap::new(),
        };
        for o in objects {
            let dir = scene_dir.join("truth/masks").join(&o.name);
            let mut m = BTreeMap::new();
            for im in &scene.images {
                m.insert(im.name.clone(), read_mask(&mask_file(&dir, &im.name))?);
            }
            t.masks.insert(o.name.clone(), m);
            t.meshes.insert(
                o.name.clone(),
                scene_dir.join(format!("truth/meshes/{}.ply", o.name)),
            );
            t.visible.insert(o.name, o.visible);
        }
        Ok(t)
    }

    /// A NeRF-synthetic scene's truth: the object is the image's alpha, fully visible in
    /// every view; no mesh.
    pub fn alpha(object: &str, scene: &Scene) -> Result<Truth> {
        let mut m = BTreeMap::new();
        let mut v = BTreeMap::new();
        for im in &scene.images {
            m.insert(im.name.clone(), read_mask(&im.path)?);
            v.insert(im.name.clone(), 1.0);
        }
        Ok(Truth {
            scene: scene.clone(),
            masks: BTreeMap::from([(object.to_string(), m)]),
            visible: BTreeMap::from([(object.to_string(), v)]),
            meshes: BTreeMap::new(),
        })
    }

    fn visible(&self, object: &str, view: &str) -> f64 {
        self.visible
            .get(object)
            .and_then(|v| v.get(view))
            .copied()
            .unwrap_or(0.0)
    }
}

/// One object's scores; None where the stage did not run (or failed).
#[derive(Clone, Debug, Default, Serialize)]
pub struct ObjectScores {
    pub object: String,
    /// Mean IoU with the truth over the views segmentation marked ok.
    pub miou: Option<f64>,
    /// Of the views that show the object, the share marked ok with a mask at [`MIOU_FLOOR`],
    /// how many fell short (the worst views) of how many show it.
    pub segment_success: Option<f64>,
    pub segment_failed_views: usize,
    pub segment_views: usize,
    pub obstruction_f1: Option<f64>,
    /// Object PSNR over novel views, and the share of them at [`PSNR_FLOOR`].
    pub psnr: Option<f64>,
    pub field_success: Option<f64>,
    pub field_failed_views: usize,
    pub psnr_views: Vec<String>,
    /// Chamfer distance over the true box diagonal.
    pub chamfer: Option<f64>,
    /// Click cases: how far SAM's alternatives for the click agree with its mask (the
    /// `click_ambiguous` check's figure).
    pub click_agreement: Option<f64>,
}

impl ObjectScores {
    /// Whether the masks fall short of the floors: their mean, the share of good views, or
    /// which views hide the object.
    pub fn segment_bad(&self) -> bool {
        self.miou.is_none_or(|m| m < MIOU_FLOOR)
            || self
                .segment_success
                .is_some_and(|s| s < SEGMENT_SHARE_FLOOR)
            || self.obstruction_f1.is_some_and(|f| f < F1_FLOOR)
    }

    /// Whether the field falls short on novel views, in the mean or in too many of them (None:
    /// not scored).
    pub fn field_bad(&self) -> Option<bool> {
        self.psnr
            .map(|p| p < PSNR_FLOOR || self.field_success.is_some_and(|s| s < FIELD_SHARE_FLOOR))
    }

    /// Whether the mesh falls short (None: no true mesh, or no mesh).
    pub fn mesh_bad(&self) -> Option<bool> {
        self.chamfer.map(|c| c > CHAMFER_FLOOR)
    }
}

/// A view's segmentation as scored: its name, status, whether it was flagged "cut" (the
/// object runs off the frame: a partial view, said so) and mask.
pub struct ScoredView {
    pub view: String,
    pub status: ViewStatus,
    pub cut: bool,
    pub mask: Option<GrayImage>,
}

/// Score masks against the truth.
pub fn score_masks(truth: &Truth, object: &str, views: &[ScoredView]) -> ObjectScores {
    let empty = BTreeMap::new();
    let tm = truth.masks.get(object).unwrap_or(&empty);
    let mut ious = Vec::new();
    let (mut shown, mut good) = (0usize, 0usize);
    let (mut tp, mut fp, mut fneg) = (0usize, 0usize, 0usize);
    for v in views {
        let vis = truth.visible(object, &v.view);
        let hidden = vis < VISIBLE;
        let iou_v = match (&v.mask, tm.get(&v.view)) {
            (Some(m), Some(t)) if v.status == ViewStatus::Ok => Some(iou(m, t)),
            _ => None,
        };
        if let Some(i) = iou_v {
            ious.push(i);
        }
        if !hidden {
            shown += 1;
            good += iou_v.is_some_and(|i| i >= MIOU_FLOOR) as usize;
        }
        // A view showing under half the object should be obstructed, or flagged as cut by
        // the frame (the truth's visible fraction counts both).
        let flagged = v.status != ViewStatus::Ok || v.cut;
        match (flagged, hidden) {
            (true, true) => tp += 1,
            (true, false) => fp += 1,
            (false, true) => fneg += 1,
            _ => {}
        }
    }
    ObjectScores {
        object: object.to_string(),
        miou: (!ious.is_empty()).then(|| ious.iter().sum::<f64>() / ious.len() as f64),
        segment_success: (shown > 0).then(|| good as f64 / shown as f64),
        segment_failed_views: shown - good,
        segment_views: shown,
        obstruction_f1: (tp + fp + fneg > 0).then(|| 2.0 * tp as f64 / (2 * tp + fp + fneg) as f64),
        ..Default::default()
    }
}

/// Score a field on novel views of the unperturbed scene (views `trained` never held: not in
/// it, or held out of training), at `downscale`, with the true masks.
pub fn score_field(
    truth: &Truth,
    object: &str,
    field: &Field,
    trained: &[String],
    downscale: u32,
    scores: &mut ObjectScores,
) -> Result<()> {
    let empty = BTreeMap::new();
    let tm = truth.masks.get(object).unwrap_or(&empty);
    let candidates: Vec<usize> = truth
        .scene
        .images
        .iter()
        .enumerate()
        .filter(|(_, im)| {
            !trained.contains(&im.name) && truth.visible(object, &im.name) >= FULLY_VISIBLE
        })
        .map(|(i, _)| i)
        .collect();
    if candidates.is_empty() {
        return Ok(());
    }
    let k = candidates.len().min(MAX_EVAL_VIEWS);
    let keep: Vec<usize> = (0..k)
        .map(|j| candidates[(j * candidates.len()) / k])
        .collect();
    let sub = truth.scene.subset(&keep);
    let masks = sub
        .images
        .iter()
        .map(|im| tm.get(&im.name).cloned())
        .collect();
    let views = load_views(&sub, &MaskSource::Images(Arc::new(masks)), downscale)?;
    let m = measure_held_out(field, &views);
    scores.psnr = m.psnr;
    scores.field_success = (!m.view_psnr.is_empty()).then(|| {
        m.view_psnr.iter().filter(|p| **p >= PSNR_FLOOR).count() as f64 / m.view_psnr.len() as f64
    });
    scores.field_failed_views = m.view_psnr.iter().filter(|p| **p < PSNR_FLOOR).count();
    scores.psnr_views = m.views;
    Ok(())
}

/// Chamfer distance of `ours` to the object's true mesh over its box diagonal (None: no truth).
pub fn score_mesh(truth: &Truth, object: &str, ours: &Mesh) -> Result<Option<f64>> {
    let Some(path) = truth.meshes.get(object) else {
        return Ok(None);
    };
    let t = crate::mesh::io::read_ply(path)?;
    let (lo, hi) = t.bounds();
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo)) as f64;
    Ok(Some(chamfer_distance(ours, &t, 30_000, 1) / diag))
}
