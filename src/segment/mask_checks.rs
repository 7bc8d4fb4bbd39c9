//! Self-checks of a multi-view segmentation (see [`crate::util::warnings`]): the clicked view's
//! mask (near empty, most of the image, or a click SAM answers differently when it moves a
//! little), masks that disagree with the other views (spill onto something the others see as
//! background; much larger than the object's projected points), and too few usable views.

use super::types::{ObjectSegmentation, ViewResult, ViewStatus};
use crate::scene::Scene;
use crate::util::mask;
use crate::util::warnings::{name_list, Stage, Warning};

/// A clicked mask under this fraction of the image is a speck: a part of the object (a logo)
/// or an empty answer; SAM's masks of whole objects in a capture are rarely this small.
pub const MIN_CLICK_MASK_FRACTION: f64 = 0.001;
/// A clicked mask over this fraction of the image is more likely a surface (table, wall, floor)
/// than an object that a capture goes around (the background itself is refused outright).
pub const MAX_CLICK_MASK_FRACTION: f64 = 0.4;
/// SAM's answer refined by its own logits, or most of its answers to the click moved by 1% of
/// the image (three of four directions), overlapping the chosen mask less than this: the click
/// sits between a part and the whole, or on something smaller than a click's slack, and a
/// slightly different click would have selected something else. Masks of one object from
/// nearby clicks agree to 0.98 and more on the demo; part and whole rarely to more than 0.7.
pub const MIN_CLICK_AGREEMENT: f64 = 0.8;
/// A view whose mask holds more than this fraction of features that other views saw outside the
/// object has spilled (plant onto planter). Edges give a few percent at most: features within
/// the vote margin of the edge are not counted.
pub const MAX_SPILL: f64 = 0.2;
/// A view whose mask leaves out more features that other views saw inside the object than this
/// fraction of the features it holds has fallen short of the object (SAM cut it along a shade).
/// Over 90 sfm runs of the Blender add-on's test scene, views whose mask covered 95% of the
/// truth and more stayed at 0.011 and below (lego 0.013, demo 0.021); 18 of the 20 views
/// covering under 70% scored above 0.05 (0.019-0.434).
pub const MAX_SHORTFALL: f64 = 0.05;
/// A view whose mask overlaps the expected mask (the object's points projected, hulled) less
/// than this is much larger than the object there: a spill where no features are (a plain
/// table top). Fully visible views score 0.84-0.94 on the demo (the hull of sparse points is a
/// little small), so half is far outside that.
pub const MIN_EXPECTED_IOU: f64 = 0.5;
/// Ok views leaving an angular gap around the object (about the scene's up axis) this much
/// wider than the capture's own widest gap: a quarter turn and more of the object is seen only
/// in obstructed views, and the field makes that side up (the demo mug between two panels
/// comes out with a 200-degree gap and a dented mesh; every unobstructed case of the stability
/// suite stays within 30 degrees of its capture's gap). Forward-facing captures have a wide
/// gap of their own, which is why the capture's gap is subtracted.
pub const MAX_EXTRA_GAP_DEG: f64 = 90.0;
/// Fewer ok views than this leave the object field underconstrained (it reconstructs what
/// some views see and guesses the rest); DVGO-style fields want views all round.
pub const MIN_OK_VIEWS: usize = 8;

/// Every segmentation check for one object.
pub fn check_segmentation(scene: &Scene, obj: &ObjectSegmentation) -> Vec<Warning> {
    let mut out = Vec::new();
    let warn = |code, figure: f64, threshold: f64, msg: String| {
        Warning::new(Stage::Segment, code, figure, threshold, msg).about(&obj.name)
    };
    if let Some(clicked) = obj.views.iter().find(|v| v.order == Some(0)) {
        if let Some(m) = &clicked.mask {
            let frac = mask::area(m) as f64 / (m.width() as f64 * m.height() as f64);
            if frac < MIN_CLICK_MASK_FRACTION {
                out.push(warn(
                    "click_mask_tiny",
                    frac,
                    MIN_CLICK_MASK_FRACTION,
                    format!(
                        "the clicked mask in '{}' covers {:.2}% of the image: SAM found a speck, not an object; click nearer the object's middle or add a box",
                        clicked.view,
                        100.0 * frac
                    ),
                ));
            } else if frac > MAX_CLICK_MASK_FRACTION {
                out.push(warn(
                    "click_mask_huge",
                    frac,
                    MAX_CLICK_MASK_FRACTION,
                    format!(
                        "the clicked mask in '{}' covers {:.0}% of the image: a surface rather than an object? check contact_sheet_{}.png",
                        clicked.view,
                        100.0 * frac,
                        obj.name
                    ),
                ));
            }
        }
        if let Some(a) = obj.click_agreement.filter(|a| *a < MIN_CLICK_AGREEMENT) {
            out.push(warn(
                "click_ambiguous",
                a,
                MIN_CLICK_AGREEMENT,
                format!(
                    "SAM's answer changes when the click in '{}' is refined or moved a little (IoU {a:.2}): the click is between a part and the whole, or on something very small; click nearer the middle of what you want, or add a second --point",
                    clicked.view
                ),
            ));
        }
    }
    let ok: Vec<_> = obj
        .views
        .iter()
        .filter(|v| v.status == ViewStatus::Ok)
        .collect();
    if let Some((names, worst)) = ok_views_over(&ok, |v| v.spill, MAX_SPILL) {
        out.push(warn(
            "mask_spill",
            worst,
            MAX_SPILL,
            format!(
                "{} ok view(s) have masks holding points that other views see outside the object ({}; worst {:.0}%): the mask spilled onto a neighbour; those views train the field on the wrong pixels",
                names.len(),
                name_list(&names),
                100.0 * worst
            ),
        ));
    }
    if let Some((names, worst)) = ok_views_over(&ok, |v| v.shortfall, MAX_SHORTFALL) {
        out.push(warn(
            "mask_short",
            worst,
            MAX_SHORTFALL,
            format!(
                "{} ok view(s) have masks leaving out points that other views see inside the object ({}; worst {:.0}% of the points they hold): the mask fell short of the object; those views teach the field that part is empty",
                names.len(),
                name_list(&names),
                100.0 * worst
            ),
        ));
    }
    let oversized: Vec<(&str, f64)> = ok
        .iter()
        .filter_map(|v| {
            v.expected_iou
                .filter(|i| *i < MIN_EXPECTED_IOU)
                .map(|i| (v.view.as_str(), i))
        })
        .collect();
    if let Some(worst) = oversized.iter().map(|s| s.1).min_by(|a, b| a.total_cmp(b)) {
        let names: Vec<&str> = oversized.iter().map(|s| s.0).collect();
        out.push(warn(
            "mask_beyond_points",
            worst,
            MIN_EXPECTED_IOU,
            format!(
                "{} ok view(s) have masks far larger than the object's projected points ({}; IoU with them as low as {worst:.2}): the mask covers more than the object",
                oversized.len(),
                name_list(&names)
            ),
        ));
    }
    if let Some((gap, capture_gap)) = ok_view_gap(scene, obj) {
        if gap - capture_gap > MAX_EXTRA_GAP_DEG {
            out.push(warn(
                "one_sided_views",
                gap - capture_gap,
                MAX_EXTRA_GAP_DEG,
                format!(
                    "the ok views leave a {gap:.0}-degree gap around the object (the capture's widest is {capture_gap:.0}): one side of it is seen only in obstructed views, so the field and mesh guess it; capture that side unobstructed"
                ),
            ));
        }
    }
    if ok.len() < MIN_OK_VIEWS {
        out.push(warn(
            "few_views_ok",
            ok.len() as f64,
            MIN_OK_VIEWS as f64,
            format!(
                "only {} of {} views have an unobstructed mask: the field sees the object from too few sides; capture more views",
                ok.len(),
                scene.images.len()
            ),
        ));
    }
    out
}

/// The widest angular gap (degrees, about the scene's up axis through the object's median
/// point) between ok views, and the same over every view of the capture. None without points
/// or with fewer than two ok views.
pub fn ok_view_gap(scene: &Scene, obj: &ObjectSegmentation) -> Option<(f64, f64)> {
    let centre = median_point(scene, &obj.points)?;
    let (up, _) = scene.up();
    let e1 = up.any_orthonormal_vector();
    let e2 = up.cross(e1);
    let azimuth = |i: usize| {
        let d = scene.images[i].pose.center() - centre;
        d.dot(e2).atan2(d.dot(e1)).to_degrees()
    };
    let ok: Vec<f64> = (0..scene.images.len().min(obj.views.len()))
        .filter(|&i| obj.views[i].status == ViewStatus::Ok)
        .map(azimuth)
        .collect();
    let all: Vec<f64> = (0..scene.images.len()).map(azimuth).collect();
    (ok.len() >= 2).then(|| (widest_gap(ok), widest_gap(all)))
}

fn median_point(scene: &Scene, points: &[usize]) -> Option<glam::DVec3> {
    let med = |f: fn(glam::DVec3) -> f64| {
        crate::util::stats::median(points.iter().map(|&p| f(scene.points[p].xyz)).collect())
    };
    Some(glam::DVec3::new(
        med(|p| p.x)?,
        med(|p| p.y)?,
        med(|p| p.z)?,
    ))
}

/// The widest gap between angles (degrees) around the circle.
fn widest_gap(mut a: Vec<f64>) -> f64 {
    if a.len() < 2 {
        return 360.0;
    }
    a.sort_by(|x, y| x.total_cmp(y));
    let wrap = a[0] + 360.0 - a[a.len() - 1];
    a.windows(2).map(|w| w[1] - w[0]).fold(wrap, f64::max)
}

/// The names of the ok views whose figure exceeds `max`, and the largest such figure; `None`
/// when no view exceeds it.
fn ok_views_over<'a>(
    ok: &[&'a ViewResult],
    figure: impl Fn(&ViewResult) -> Option<f64>,
    max: f64,
) -> Option<(Vec<&'a str>, f64)> {
    let over: Vec<(&str, f64)> = ok
        .iter()
        .filter_map(|v| figure(v).filter(|f| *f > max).map(|f| (v.view.as_str(), f)))
        .collect();
    let worst = over.iter().map(|s| s.1).max_by(|a, b| a.total_cmp(b))?;
    Some((over.into_iter().map(|s| s.0).collect(), worst))
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::GrayImage;

    fn scene() -> Scene {
        Scene {
            source: "s".into(),
            format: crate::scene::SourceFormat::Demo,
            cameras: vec![],
            images: vec![],
            points: vec![],
            depth_scale: 1.0,
            applied_transform: None,
        }
    }

    /// `n` ok views with a 10 x 10 mask in a 100 x 100 image (1%), the first clicked.
    fn object(n: usize) -> ObjectSegmentation {
        let views = (0..n)
            .map(|i| {
                let mut v = ViewResult::unsegmented(&format!("v{i}"));
                v.status = ViewStatus::Ok;
                v.order = Some(i);
                v.expected_iou = Some(0.9);
                v.spill = Some(0.0);
                let mut m = GrayImage::new(100, 100);
                for y in 0..10 {
                    for x in 0..10 {
                        m.put_pixel(x, y, image::Luma([255]));
                    }
                }
                v.mask = Some(m);
                v
            })
            .collect();
        ObjectSegmentation {
            name: "o".into(),
            views,
            points: vec![],
            click_agreement: Some(0.95),
        }
    }

    fn codes(o: &ObjectSegmentation) -> Vec<&'static str> {
        check_segmentation(&scene(), o)
            .iter()
            .map(|w| w.code)
            .collect()
    }

    #[test]
    fn gaps_wrap_around_the_circle() {
        assert_eq!(widest_gap(vec![10.0, 100.0, 190.0, 280.0]), 90.0);
        assert_eq!(widest_gap(vec![-170.0, 170.0]), 340.0);
        assert_eq!(widest_gap(vec![5.0]), 360.0);
    }

    #[test]
    fn a_clean_segmentation_passes_and_each_fault_is_named() {
        assert!(codes(&object(12)).is_empty());
        assert_eq!(codes(&object(5)), ["few_views_ok"]);
        let mut o = object(12);
        o.click_agreement = Some(0.5);
        o.views[3].spill = Some(0.4);
        o.views[6].shortfall = Some(0.2);
        o.views[4].expected_iou = Some(0.3);
        assert_eq!(
            codes(&o),
            [
                "click_ambiguous",
                "mask_spill",
                "mask_short",
                "mask_beyond_points"
            ]
        );
        let mut o = object(12);
        o.views[0].mask = Some(GrayImage::from_pixel(100, 100, image::Luma([255])));
        assert_eq!(codes(&o), ["click_mask_huge"]);
        let mut o = object(12);
        let mut speck = GrayImage::new(100, 100);
        speck.put_pixel(5, 5, image::Luma([255]));
        o.views[0].mask = Some(speck);
        let w = check_segmentation(&scene(), &o);
        assert_eq!(w[0].code, "click_mask_tiny");
        assert_eq!(w[0].figure, 1e-4);
        assert_eq!(w[0].object.as_deref(), Some("o"));
        // Obstructed views do not count as spilled or oversized.
        let mut o = object(12);
        o.views[5].status = ViewStatus::Obstructed;
        o.views[5].spill = Some(0.9);
        o.views[5].shortfall = Some(0.9);
        assert!(codes(&o).is_empty());
    }
}
