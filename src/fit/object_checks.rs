//! Self-checks of a trained object field (see [`crate::util::warnings`]): how well it predicts
//! views it never trained on (PSNR over the object's box in a few held-out views, against their
//! masked photos), opacity it puts outside the object's masks there (floaters), and whether
//! training diverged or was cut short by its time budget.
//! A scene field's checks are in [`super::scene_checks`].

use crate::field::eval::{psnr, render_view, truth_on};
use crate::field::march::RenderOptions;
use crate::field::model::Field;
use crate::field::view::View;
use crate::fit::TrainReport;
use crate::util::mask::{dilate, is_object};
use crate::util::warnings::{Stage, Warning};
use image::GrayImage;
use serde::Serialize;

/// Held-out PSNR (dB, over the mask's box on white) this far under the same measure on a few
/// training views: the field reproduces the views it was fit to but not new ones (poses that
/// disagree, too few views). A good field generalises within a few dB; comparing with its own
/// training views, not with a fixed figure, keeps image noise and fine texture (which lower
/// both alike) from reading as failure.
pub const MAX_HELDOUT_GAP_DB: f64 = 4.0;
/// Held-out PSNR under this: the field does not reproduce the object from a new viewpoint,
/// whatever the training views score. A good demo field scores 28-34 dB there; 20 dB is a
/// visibly blurred or misplaced object (misregistered poses, too few views). (Restored: commit
/// 9084cc6 lowered it to 13 in the change that made cases pass, see CONTRIBUTING.md.)
pub const MIN_HELDOUT_PSNR: f64 = 20.0;
/// Opacity outside the held-out views' masks (grown by [`OUTSIDE_MARGIN_PX`]), as a fraction of
/// the masks' area, above this: the field holds floaters that the training views' masks did
/// not carve (a few percent come from edges alone).
pub const MAX_OUTSIDE_OPACITY: f64 = 0.15;
/// Pixels (at the training resolution) that a mask is grown by before opacity outside it counts:
/// edges are soft by a pixel or two.
pub const OUTSIDE_MARGIN_PX: u32 = 2;
/// The box around the mask that held-out PSNR is measured over grows by this fraction of its
/// size per side, so a field that misses the object or blurs it past its edge is scored there.
pub const BOX_PAD: f64 = 0.1;
/// A final training PSNR (dB, on its batch) under this means training diverged or never fit:
/// an untrained grid on white backgrounds already scores about 10 dB.
pub const MIN_TRAIN_PSNR: f32 = 12.0;
/// Training stopped by its time budget before this fraction of its steps is far from
/// converged: the coarse-to-fine schedule had not reached its finest stage's work.
pub const MIN_STEP_FRACTION: f64 = 0.5;

/// What the field check measured on the held-out views (and on a few training views, to
/// compare).
#[derive(Clone, Debug, Default, Serialize)]
pub struct HeldOutCheck {
    pub views: Vec<String>,
    /// The same PSNR on training views (None: none measured).
    pub train_psnr: Option<f64>,
    /// PSNR over the masks' padded boxes, composited on white (None: no held-out view).
    pub psnr: Option<f64>,
    /// The same per view (views without mask pixels are left out).
    pub view_psnr: Vec<f64>,
    /// Opacity outside the grown masks over the masks' area (None: no held-out view).
    pub outside_opacity: Option<f64>,
}

/// Render each held-out view (its mask as alpha) and measure PSNR over the mask's box and the
/// opacity outside the mask.
pub fn measure_held_out(field: &Field, views: &[View]) -> HeldOutCheck {
    let white = [1.0f32; 3];
    let (mut se, mut n, mut outside, mut area) = (0.0f64, 0usize, 0.0f64, 0usize);
    let mut view_psnr = Vec::new();
    for v in views {
        let r = render_view(field, &RenderOptions::default(), &v.cam, white);
        let truth = truth_on(v, white);
        let (w, h) = (v.width, v.height);
        let mask = GrayImage::from_fn(w, h, |x, y| image::Luma([v.rgba[(y * w + x) as usize][3]]));
        let Some((x0, y0, x1, y1)) = padded_box(&mask) else {
            continue;
        };
        let mut rb = Vec::new();
        let mut tb = Vec::new();
        for y in y0..y1 {
            for x in x0..x1 {
                let i = (y * w + x) as usize;
                rb.push(r.rgb[i]);
                tb.push(truth[i]);
            }
        }
        let p = psnr(&rb, &tb);
        view_psnr.push(p);
        se += 10f64.powf(-p / 10.0) * rb.len() as f64;
        n += rb.len();
        let grown = dilate(&mask, OUTSIDE_MARGIN_PX);
        for (i, g) in grown.pixels().enumerate() {
            if !is_object(g[0]) {
                outside += r.alpha[i] as f64;
            }
        }
        area += crate::util::mask::area(&mask);
    }
    HeldOutCheck {
        views: views.iter().map(|v| v.name.clone()).collect(),
        train_psnr: None,
        psnr: (n > 0).then(|| -10.0 * (se / n as f64).max(1e-20).log10()),
        view_psnr,
        outside_opacity: (area > 0).then(|| outside / area as f64),
    }
}

/// The mask's bounding box grown by [`BOX_PAD`] per side (+1 px), clamped to the image.
fn padded_box(mask: &GrayImage) -> Option<(u32, u32, u32, u32)> {
    let (w, h) = mask.dimensions();
    let mut b: Option<(u32, u32, u32, u32)> = None;
    for (x, y, p) in mask.enumerate_pixels() {
        if is_object(p[0]) {
            b = Some(match b {
                None => (x, y, x + 1, y + 1),
                Some((a, c, d, e)) => (a.min(x), c.min(y), d.max(x + 1), e.max(y + 1)),
            });
        }
    }
    b.map(|(x0, y0, x1, y1)| {
        let px = ((x1 - x0) as f64 * BOX_PAD).ceil() as u32 + 1;
        let py = ((y1 - y0) as f64 * BOX_PAD).ceil() as u32 + 1;
        (
            x0.saturating_sub(px),
            y0.saturating_sub(py),
            (x1 + px).min(w),
            (y1 + py).min(h),
        )
    })
}

/// Every field check for `object`: training as it ran (`planned_steps` it was given) and the
/// held-out measurements.
pub fn check_field(
    object: &str,
    train: &TrainReport,
    planned_steps: usize,
    held: &HeldOutCheck,
) -> Vec<Warning> {
    let mut out = Vec::new();
    let warn = |code, figure: f64, threshold: f64, msg: String| {
        Warning::new(Stage::Field, code, figure, threshold, msg).about(object)
    };
    let run = &train.run;
    if !run.final_psnr.is_finite() || run.final_psnr < MIN_TRAIN_PSNR {
        out.push(warn(
            "training_diverged",
            run.final_psnr as f64,
            MIN_TRAIN_PSNR as f64,
            format!(
                "training ended at {:.1} dB on its own views: it diverged or never fit; check the masks and poses",
                run.final_psnr
            ),
        ));
    }
    let frac = run.steps as f64 / planned_steps.max(1) as f64;
    if run.stopped_by == "time budget" && frac < MIN_STEP_FRACTION {
        out.push(warn(
            "training_cut_short",
            frac,
            MIN_STEP_FRACTION,
            format!(
                "the time budget stopped training at step {} of {planned_steps}: far from converged; give it a larger --time-budget",
                run.steps
            ),
        ));
    }
    let names = held.views.join(", ");
    if let Some(p) = held.psnr {
        let gap = held.train_psnr.map(|t| t - p);
        if p < MIN_HELDOUT_PSNR {
            out.push(warn(
                "heldout_psnr_low",
                p,
                MIN_HELDOUT_PSNR,
                format!(
                    "on views kept out of training ({names}) the field scores {p:.1} dB around the object: it does not reproduce the object (inaccurate poses or masks, too few views)"
                ),
            ));
        } else if let Some(g) = gap.filter(|g| *g > MAX_HELDOUT_GAP_DB) {
            out.push(warn(
                "heldout_gap",
                g,
                MAX_HELDOUT_GAP_DB,
                format!(
                    "on views kept out of training ({names}) the field scores {p:.1} dB around the object, {g:.1} dB under its training views: it fits the views it saw but not new ones (inaccurate poses, too few views)"
                ),
            ));
        }
    }
    if let Some(o) = held.outside_opacity.filter(|o| *o > MAX_OUTSIDE_OPACITY) {
        out.push(warn(
            "floaters",
            o,
            MAX_OUTSIDE_OPACITY,
            format!(
                "on views kept out of training ({names}) the field is opaque outside the object's masks ({:.0}% of the object's area): floaters; the mesh may carry stray pieces",
                100.0 * o
            ),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::session::RunSummary;

    fn train(psnr: f32, steps: usize, stopped_by: &str) -> TrainReport {
        TrainReport {
            setup: None,
            run: RunSummary {
                steps,
                seconds: 1.0,
                rays_per_second: 1.0,
                final_psnr: psnr,
                stopped_by: stopped_by.into(),
                ..Default::default()
            },
            vertices: 0,
            dims: [1; 3],
            memory_bytes: 0,
            occupied_cells: 0,
            depth_targets: 0,
            finest: None,
            scene_fit: None,
            warnings: Vec::new(),
            appearance: Vec::new(),
        }
    }

    fn held(psnr: f64, train_psnr: f64, outside: f64) -> HeldOutCheck {
        HeldOutCheck {
            views: vec!["a".into()],
            train_psnr: Some(train_psnr),
            psnr: Some(psnr),
            view_psnr: vec![psnr],
            outside_opacity: Some(outside),
        }
    }

    fn codes(t: &TrainReport, h: &HeldOutCheck) -> Vec<&'static str> {
        check_field("o", t, 1000, h)
            .iter()
            .map(|w| w.code)
            .collect()
    }

    #[test]
    fn each_field_fault_is_named() {
        let good = train(28.0, 1000, "steps");
        assert!(codes(&good, &held(20.0, 22.0, 0.02)).is_empty());
        // Noise lowers training and held-out views alike: no gap, but low is low.
        assert!(codes(&good, &held(21.0, 22.0, 0.02)).is_empty());
        assert_eq!(codes(&good, &held(15.0, 16.0, 0.02)), ["heldout_psnr_low"]);
        assert_eq!(codes(&good, &held(22.0, 27.0, 0.02)), ["heldout_gap"]);
        assert_eq!(codes(&good, &held(10.0, 11.0, 0.02)), ["heldout_psnr_low"]);
        assert_eq!(codes(&good, &held(20.0, 22.0, 0.5)), ["floaters"]);
        assert_eq!(
            codes(&train(f32::NAN, 1000, "steps"), &held(20.0, 22.0, 0.0)),
            ["training_diverged"]
        );
        assert_eq!(
            codes(&train(28.0, 100, "time budget"), &held(20.0, 22.0, 0.0)),
            ["training_cut_short"]
        );
        assert!(codes(&good, &HeldOutCheck::default()).is_empty());
    }

    #[test]
    fn the_padded_box_grows_and_clamps() {
        let mut m = GrayImage::new(40, 30);
        for y in 10..20 {
            for x in 5..15 {
                m.put_pixel(x, y, image::Luma([255]));
            }
        }
        assert_eq!(padded_box(&m), Some((3, 8, 17, 22)));
        assert_eq!(padded_box(&GrayImage::new(4, 4)), None);
    }
}
