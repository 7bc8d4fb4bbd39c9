//! `extract`'s self-checks of each object's field and mesh: which ok views are kept out of
//! training to check the field on, and the checks themselves (see [`crate::fit::object_checks`] and
//! [`crate::mesh::mesh_checks`]).

use crate::error::Result;
use crate::field::{load_views, Field, MaskSource};
use crate::fit::object_checks::{check_field, measure_held_out, HeldOutCheck};
use crate::fit::TrainReport;
use crate::mesh::mesh_checks::check_mesh;
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::segment::{ObjectSegmentation, ViewResult, ViewStatus};
use crate::util::Warning;
use std::sync::Arc;

/// Ok views kept out of training to check the field on: one per [`VIEWS_PER_CHECK_VIEW`] ok
/// views, at most `most`, spread over the ok views (never the clicked one). Fewer than
/// [`VIEWS_PER_CHECK_VIEW`] ok views keep none back (the segmentation warns of too few views).
pub fn check_views(obj: &ObjectSegmentation, most: usize) -> Vec<String> {
    let ok_count = obj
        .views
        .iter()
        .filter(|v| v.status == ViewStatus::Ok)
        .count();
    let ok: Vec<&str> = obj
        .views
        .iter()
        .filter(|v| v.order != Some(0) && seen_whole(v))
        .map(|v| v.view.as_str())
        .collect();
    let k = most
        .min((ok_count + 1) / VIEWS_PER_CHECK_VIEW)
        .min(ok.len());
    (0..k)
        .map(|j| ok[((j as f64 + 0.5) * ok.len() as f64 / k as f64) as usize].to_string())
        .collect()
}

/// Views whose mask covers this much of the object's projected points (and that are not cut by
/// the frame) are taken to show it whole: a field is checked on those, since a mask of a
/// partly hidden object is not what the field renders there.
pub const WHOLE_COVERAGE: f64 = 0.9;

fn seen_whole(v: &ViewResult) -> bool {
    v.status == ViewStatus::Ok
        && v.flags.is_empty()
        && v.expected_coverage.is_some_and(|c| c >= WHOLE_COVERAGE)
}

/// One ok view in this many is kept back to check the field (so 10 views keep one back, 36
/// keep three with the default of three at most): enough to catch a field that does not
/// generalise, few enough not to starve training.
pub const VIEWS_PER_CHECK_VIEW: usize = 8;

/// Training views the field is compared on: at most this many ok views it trained on (that
/// show the object whole), spread over them. Views of one object score several dB apart (the
/// demo torus's 23 from 17.3 dB up, over their padded boxes), so a few make a noisy reference:
/// three picked 28.7 dB where all 23 score 25.8, and `heldout_gap` warned of a 6.0 dB gap on a
/// field 36.4 dB against the truth; eight come within 1 dB of all of them on the four demo
/// objects.
pub const TRAIN_VIEWS_COMPARED: usize = 8;

/// Measure the trained `field` on the `held_out` views and on a few training views (with the
/// segmentation's masks, at the training `downscale`) and run the field checks.
pub fn field_warnings(
    scene: &Scene,
    obj: &ObjectSegmentation,
    held_out: &[String],
    downscale: u32,
    field: &Field,
    train: &TrainReport,
    planned_steps: usize,
) -> Result<(HeldOutCheck, Vec<Warning>)> {
    let keep = check_indices(&obj.views, held_out);
    let mut held = if keep.is_empty() {
        HeldOutCheck::default()
    } else {
        measure(scene, obj, &keep, downscale, field)?
    };
    if !keep.is_empty() {
        let trained: Vec<usize> = (0..scene.images.len())
            .filter(|i| seen_whole(&obj.views[*i]) && !keep.contains(i))
            .collect();
        let k = trained.len().min(TRAIN_VIEWS_COMPARED);
        let pick: Vec<usize> = (0..k)
            .map(|j| trained[(2 * j + 1) * trained.len() / (2 * k)])
            .collect();
        held.train_psnr = measure(scene, obj, &pick, downscale, field)?.psnr;
    }
    let warnings = check_field(&obj.name, train, planned_steps, &held);
    Ok((held, warnings))
}

/// The held-out views the field is checked on: those that show the object whole (as the views
/// [`check_views`] picks and the training views compared with), where any do; else all of them.
/// A user's hold-out rule (`--hold-out-every`) also keeps back views where the object is partly
/// hidden, and there the field rightly draws what the mask leaves out (`objnerf demo`'s mug in
/// view_003, a sixth of it behind another object: 15.7 dB against 21.8-23.9 in the other
/// held-out views, a false `heldout_gap`).
fn check_indices(views: &[ViewResult], held_out: &[String]) -> Vec<usize> {
    let held: Vec<usize> = (0..views.len())
        .filter(|&i| held_out.contains(&views[i].view))
        .collect();
    let whole: Vec<usize> = held
        .iter()
        .copied()
        .filter(|&i| seen_whole(&views[i]))
        .collect();
    if whole.is_empty() {
        held
    } else {
        whole
    }
}

/// [`measure_held_out`] on the scene's views `keep` with the segmentation's masks.
fn measure(
    scene: &Scene,
    obj: &ObjectSegmentation,
    keep: &[usize],
    downscale: u32,
    field: &Field,
) -> Result<HeldOutCheck> {
    let sub = scene.subset(keep);
    let masks = keep.iter().map(|&i| obj.views[i].mask.clone()).collect();
    let views = load_views(&sub, &MaskSource::Images(Arc::new(masks)), downscale)?;
    Ok(measure_held_out(field, &views))
}

/// The mesh checks of `object`'s mesh cut from `field`.
pub fn mesh_warnings(object: &str, mesh: &Mesh, field: &Field) -> Vec<Warning> {
    check_mesh(object, mesh, field.box_min, field.box_max, field.voxel)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(name: &str, status: ViewStatus, coverage: f64) -> ViewResult {
        ViewResult {
            view: name.into(),
            status,
            score: 1.0,
            expected_iou: None,
            expected_coverage: Some(coverage),
            num_prompts: 1,
            num_projected: 10,
            order: None,
            spill: None,
            shortfall: None,
            flags: Vec::new(),
            mask: None,
            prompts: Vec::new(),
        }
    }

    #[test]
    fn held_out_views_partly_hidden_are_not_checked_while_whole_ones_are() {
        let views = [
            view("a", ViewStatus::Ok, 0.95),
            view("b", ViewStatus::Ok, 0.81), // a sixth hidden: drawn whole, masked in part
            view("c", ViewStatus::Ok, 0.97),
            view("d", ViewStatus::Ok, 0.99),
        ];
        let held = ["b".to_string(), "c".to_string()];
        assert_eq!(check_indices(&views, &held), vec![2]);
        // None of them whole: all are checked rather than none.
        assert_eq!(check_indices(&views, &held[..1]), vec![1]);
        assert!(check_indices(&views, &[]).is_empty());
    }
}
