//! Multi-view segmentation from one click (paper §4.2, Algorithm 1): a mask in the first view
//! selects 3D points D through the features inside it; every further view, visited in order of
//! covisibility with D, is prompted with its own features whose 3D point is in D, and its mask
//! adds points to D. Correspondences, not projections, carry the prompts, so a point hidden in a
//! view (no feature there) never prompts an occluder.
//!
//! Guard against leaks: each point collects votes from every segmented view that observes it:
//! "in" when its feature lies at least `edge_margin_px` inside the mask, "out" when at least that
//! far outside. D = points with an "in" vote and no "out" vote, recomputed after every view, so
//! a point that leaked in at a mask's edge leaves D once another view sees it clearly outside.

use super::distance::signed_distance;
use super::hull::expected_mask;
use super::regions::clean_mask;
use super::types::*;
use super::view_prompts::{farthest_point_sample, view_prompts};
use crate::error::{Error, Result};
use crate::scene::{Point3D, Scene};
use crate::util::mask::{self, coverage, iou, is_object};
use crate::util::stats::median;
use glam::{DVec2, DVec3};
use image::GrayImage;

/// Propagation needs 2D-3D tracks; say how to get them.
pub fn require_tracks(scene: &Scene) -> Result<()> {
    if !scene.has_tracks() {
        return Err(Error::invalid(format!(
            "{} has no 2D-3D feature tracks; run `objnerf sfm {} --out DIR` first and segment DIR",
            scene.source.display(),
            scene.source.display()
        )));
    }
    Ok(())
}

/// The clicked view must have features with 3D points, or nothing can carry the click further.
pub fn require_view_tracks(scene: &Scene, view: usize) -> Result<()> {
    let im = &scene.images[view];
    if !im.features.iter().any(|f| f.point.is_some()) {
        return Err(Error::invalid(format!(
            "view '{}' of {} has no 2D-3D tracks (COLMAP triangulated none of its features): click in another view",
            im.name,
            scene.source.display()
        )));
    }
    Ok(())
}

/// The click's mask must be an object: not empty, and not the background. A mask that touches
/// all four borders and covers more than half the image is taken for the background (SAM's
/// answer to a click beside the object; lego's r_0 clicked at (40, 40) gives 76% of the image).
fn check_click_mask(scene: &Scene, prompt: &ObjectPrompt, mask: &GrayImage) -> Result<()> {
    let name = &scene.images[prompt.view].name;
    let (w, h) = mask.dimensions();
    let on = |x: u32, y: u32| is_object(mask.get_pixel(x, y)[0]);
    let area = mask::area(mask);
    if area == 0 {
        return Err(Error::invalid(format!(
            "the click on view '{name}' gave an empty mask for '{}': click inside the object",
            prompt.name
        )));
    }
    let touches_all = (0..w).any(|x| on(x, 0))
        && (0..w).any(|x| on(x, h - 1))
        && (0..h).any(|y| on(0, y))
        && (0..h).any(|y| on(w - 1, y));
    let fraction = area as f64 / (w as f64 * h as f64);
    if touches_all && fraction > 0.5 {
        return Err(Error::invalid(format!(
            "the click on view '{name}' for '{}' selected the background (its mask covers {:.0}% of the image and touches every border): click on the object",
            prompt.name,
            100.0 * fraction
        )));
    }
    Ok(())
}

/// Run Algorithm 1 for one object.
pub fn propagate(
    scene: &Scene,
    prompt: &ObjectPrompt,
    seg: &mut dyn ViewSegmenter,
    opts: &PropagationOptions,
) -> Result<ObjectSegmentation> {
    require_tracks(scene)?;
    let n_views = scene.images.len();
    let mut votes = vec![Votes::default(); scene.points.len()];
    let mut views: Vec<ViewResult> = scene
        .images
        .iter()
        .map(|im| ViewResult::unsegmented(&im.name))
        .collect();

    require_view_tracks(scene, prompt.view)?;
    // The clicked view.
    let mut first = seg.segment(scene, prompt.view, &prompt.points, prompt.bbox)?;
    clean(&mut first, &prompt.points, opts);
    check_click_mask(scene, prompt, &first.mask)?;
    let click_agreement = click_agreement(scene, prompt, &first.mask, seg)?;
    vote(
        scene,
        prompt.view,
        &first.mask,
        opts.edge_margin_px,
        &mut votes,
    );
    let d0 = members(scene, &votes, opts);
    if d0.is_empty() {
        return Err(Error::invalid(format!(
            "no tracked feature of view '{}' lies inside the mask of '{}': the object has no 3D points to propagate (is it textured? try another view, or more features in `objnerf sfm`)",
            scene.images[prompt.view].name, prompt.name
        )));
    }
    record(&mut views[prompt.view], first, prompt.points.clone(), 0);
    let mut visited = vec![false; n_views];
    visited[prompt.view] = true;

    for order in 1..n_views {
        let in_d: Vec<bool> = membership(scene, &votes, opts);
        // Next: the unvisited view that sees most points of D.
        let mut best: Option<(usize, usize)> = None;
        for (v, im) in scene.images.iter().enumerate() {
            if visited[v] {
                continue;
            }
            let count = im
                .features
                .iter()
                .filter(|f| f.point.is_some_and(|p| in_d[p]))
                .count();
            if best.is_none_or(|(_, c)| count > c) {
                best = Some((v, count));
            }
        }
        let Some((v, count)) = best else { break };
        visited[v] = true;
        if count < opts.min_prompts.max(1) {
            // No view left sees the object: the rest are absent.
            continue;
        }
        let prompts = view_prompts(scene, v, &votes, &in_d, opts);
        let mut result = seg.segment(scene, v, &prompts.points, prompts.bbox)?;
        clean(&mut result, &prompts.points, opts);
        vote(scene, v, &result.mask, opts.edge_margin_px, &mut votes);
        record(&mut views[v], result, prompts.points, order);
        views[v].num_projected = prompts.projected;
    }

    let points = members(scene, &votes, opts);
    classify_views(scene, &points, &votes, &mut views, opts);
    Ok(ObjectSegmentation {
        name: prompt.name.clone(),
        views,
        points,
        click_agreement,
    })
}

/// How far the segmenter's alternatives for a lone click agree with the clicked mask: the lower
/// of its IoU with the refined answer (a flip between part and whole) and the IoU that most of
/// the moved clicks reach (the second-highest of four: three of them leaving the object means
/// the click is on something smaller than a click's slack, while one or two leaving is just a
/// click near an edge, which is harmless). None without alternatives (several clicks, a box,
/// or a segmenter that gives none).
pub fn click_agreement(
    scene: &Scene,
    prompt: &ObjectPrompt,
    mask: &GrayImage,
    seg: &mut dyn ViewSegmenter,
) -> Result<Option<f64>> {
    if prompt.points.len() != 1 || prompt.bbox.is_some() {
        return Ok(None);
    }
    let alts = seg.alternatives(scene, prompt.view, &prompt.points)?;
    let refined = alts.refined.as_ref().map(|r| iou(mask, r));
    let mut moved: Vec<f64> = alts.moved.iter().map(|m| iou(mask, m)).collect();
    moved.sort_by(|a, b| b.total_cmp(a));
    let most_moved = (moved.len() >= 2).then(|| moved[1]);
    Ok(match (refined, most_moved) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    })
}

/// SAM's mask without stray islands and pin-holes (see [`super::regions`]).
fn clean(m: &mut ViewMask, prompts: &[PointPrompt], opts: &PropagationOptions) {
    if let Some(c) = &opts.clean {
        let positives: Vec<DVec2> = prompts
            .iter()
            .filter(|p| p.positive)
            .map(|p| DVec2::new(p.xy[0], p.xy[1]))
            .collect();
        clean_mask(&mut m.mask, &positives, c);
    }
}

fn record(v: &mut ViewResult, m: ViewMask, prompts: Vec<PointPrompt>, order: usize) {
    v.status = ViewStatus::Ok;
    v.score = m.score;
    v.num_prompts = prompts.iter().filter(|p| p.positive).count();
    v.prompts = prompts;
    v.order = Some(order);
    v.mask = Some(m.mask);
}

/// D: the points voted in and never out, less those far from D's bulk. A feature matched
/// across two objects (a two-view track from the sphere in one view to the ground beside the
/// cube in another) triangulates off in space, yet its sphere end votes it in. As a farthest
/// point it was then picked as a positive prompt in the other view, SAM took the cube, and the
/// cube's points joined D (the Blender add-on's dataset test: 5 of 90 runs of COLMAP's
/// unseeded matching, mIoU 0.67-0.69; none of the 90 with this filter).
fn membership(scene: &Scene, votes: &[Votes], opts: &PropagationOptions) -> Vec<bool> {
    let mut in_d: Vec<bool> = votes
        .iter()
        .map(|v| v.inside > 0 && v.outside == 0)
        .collect();
    if let Some(spread) = opts.max_spread {
        drop_far_points(&scene.points, &mut in_d, spread);
    }
    in_d
}

/// Drop members farther from the members' median (per axis) than `spread` times their median
/// distance to it: a robust radius, which one far point cannot widen.
fn drop_far_points(points: &[Point3D], in_d: &mut [bool], spread: f64) {
    let xyz: Vec<(usize, DVec3)> = (0..in_d.len())
        .filter(|&p| in_d[p])
        .map(|p| (p, points[p].xyz))
        .collect();
    let axis = |k: usize| median(xyz.iter().map(|(_, x)| x[k]).collect());
    let (Some(cx), Some(cy), Some(cz)) = (axis(0), axis(1), axis(2)) else {
        return;
    };
    let centre = DVec3::new(cx, cy, cz);
    let Some(radius) = median(xyz.iter().map(|(_, x)| x.distance(centre)).collect()) else {
        return;
    };
    for (p, x) in &xyz {
        if x.distance(centre) > spread * radius {
            in_d[*p] = false;
        }
    }
}

fn members(scene: &Scene, votes: &[Votes], opts: &PropagationOptions) -> Vec<usize> {
    membership(scene, votes, opts)
        .iter()
        .enumerate()
        .filter(|(_, m)| **m)
        .map(|(i, _)| i)
        .collect()
}

/// Every tracked feature of the view votes in or out by its distance to the mask's edge.
fn vote(scene: &Scene, view: usize, mask: &GrayImage, margin: f64, votes: &mut [Votes]) {
    let side = MaskSide::new(mask, margin);
    for f in &scene.images[view].features {
        let Some(p) = f.point else { continue };
        match side.of(f.xy.x.floor() as i64, f.xy.y.floor() as i64) {
            Some(true) => votes[p].inside += 1,
            Some(false) => votes[p].outside += 1,
            None => {}
        }
    }
}

/// Which side of a mask's edge a feature clearly lies on: outside when at least `margin` px
/// outside; inside when at least `margin` px inside or, on a part of the mask thinner than two
/// margins, at least half the part's own depth inside (the largest distance to the edge within
/// `margin` of the feature; at least 1 px). A mug's handle 3 px wide never holds a feature 3 px
/// inside: its points never joined D, became negatives once a propagated view's mask left the
/// handle out, and 23 of 24 views of the forward-facing demo lost it. At the edge of a thick
/// part the depth nearby is large and the full margin applies, so leaks at edges still stay out.
struct MaskSide {
    sd: Vec<f32>,
    w: i64,
    h: i64,
    margin: f64,
}

impl MaskSide {
    fn new(mask: &GrayImage, margin: f64) -> Self {
        MaskSide {
            sd: signed_distance(mask),
            w: mask.width() as i64,
            h: mask.height() as i64,
            margin,
        }
    }

    /// Some(true) inside, Some(false) outside, None near the edge or off the image.
    fn of(&self, x: i64, y: i64) -> Option<bool> {
        let (w, h) = (self.w, self.h);
        if x < 0 || y < 0 || x >= w || y >= h {
            return None;
        }
        let d = self.sd[(y * w + x) as usize] as f64;
        if d <= -self.margin {
            return Some(false);
        }
        if d >= self.margin {
            return Some(true);
        }
        if d <= 0.0 {
            return None;
        }
        let r = self.margin.ceil() as i64;
        let mut depth = 0f32;
        for yy in (y - r).max(0)..=(y + r).min(h - 1) {
            for xx in (x - r).max(0)..=(x + r).min(w - 1) {
                depth = depth.max(self.sd[(yy * w + xx) as usize]);
            }
        }
        (d >= (0.5 * depth as f64).max(1.0)).then_some(true)
    }
}

/// Compare every mask with the expected mask of D's projection; mark obstructed, cut and tiny
/// views; measure each mask's spill and shortfall (see [`disagreement`]).
fn classify_views(
    scene: &Scene,
    points: &[usize],
    votes: &[Votes],
    views: &mut [ViewResult],
    opts: &PropagationOptions,
) {
    let mut in_d = vec![false; scene.points.len()];
    for &p in points {
        in_d[p] = true;
    }
    for (v, res) in views.iter_mut().enumerate() {
        let im = &scene.images[v];
        let cam = scene.camera_of(im);
        let proj: Vec<DVec2> = points
            .iter()
            .filter_map(|&p| cam.project(im.pose.world_to_camera(scene.points[p].xyz)))
            .collect();
        let in_frame = proj.iter().filter(|p| cam.contains(**p)).count();
        if !proj.is_empty() && (in_frame as f64) < 0.8 * proj.len() as f64 {
            res.flags.push("cut");
        }
        let Some(mask) = &res.mask else { continue };
        (res.spill, res.shortfall) =
            disagreement(scene, v, mask, &in_d, votes, opts.edge_margin_px);
        let area = mask::area(mask);
        if (area as f64) < opts.tiny_fraction * (mask.width() * mask.height()) as f64 {
            res.flags.push("tiny");
        }
        let (expected, _) = expected_mask(&proj, cam.width, cam.height, &opts.hull);
        res.expected_iou = Some(iou(mask, &expected));
        let covered = coverage(mask, &expected);
        res.expected_coverage = Some(covered);
        if area == 0 {
            res.status = ViewStatus::Absent;
        } else if covered < opts.obstruction_coverage {
            res.status = ViewStatus::Obstructed;
        }
    }
}

/// Masks with fewer tracked features this far inside have no spill figure: a few features
/// cannot tell a spill from a feature near an edge.
pub const MIN_SPILL_FEATURES: usize = 8;

/// How a mask disagrees with the other views, from the view's tracked features at least
/// `margin` inside and outside it; both figures are per feature inside, None with fewer than
/// [`MIN_SPILL_FEATURES`] inside.
///
/// Spill: the features inside whose 3D point is not in D. Each of them voted "in" from this
/// view, so it left D because another view saw it clearly outside the object: this mask covers
/// something the others do not (a planter under a plant).
///
/// Shortfall: the features outside whose 3D point was voted in by at least as many views as
/// voted it out. A mask that stops short of the object (SAM cut the Blender test's sphere along
/// a shade of its texture) leaves out points that the views seeing that side whole voted in.
/// Counting points any view voted in flagged every view of fox, whose few spilled close-ups
/// vote wallpaper in.
fn disagreement(
    scene: &Scene,
    view: usize,
    mask: &GrayImage,
    in_d: &[bool],
    votes: &[Votes],
    margin: f64,
) -> (Option<f64>, Option<f64>) {
    let sd = signed_distance(mask);
    let (w, h) = (mask.width() as i64, mask.height() as i64);
    let (mut inside, mut spilled, mut short) = (0usize, 0usize, 0usize);
    for f in &scene.images[view].features {
        let Some(p) = f.point else { continue };
        let (x, y) = (f.xy.x.floor() as i64, f.xy.y.floor() as i64);
        if x < 0 || y < 0 || x >= w || y >= h {
            continue;
        }
        let d = sd[(y * w + x) as usize] as f64;
        if d >= margin {
            inside += 1;
            spilled += (!in_d[p]) as usize;
        } else if d <= -margin && votes[p].inside >= votes[p].outside.max(1) {
            short += 1;
        }
    }
    if inside < MIN_SPILL_FEATURES {
        return (None, None);
    }
    let per_inside = |n: usize| Some(n as f64 / inside as f64);
    (per_inside(spilled), per_inside(short))
}

/// Several objects in one pass: Algorithm 1 for each (the segmenter's embedding cache makes every
/// view's encoder run once for all objects), then overlaps settled: a pixel claimed by two
/// objects goes to the one nearer the camera in that view (median depth of its points), since
/// the nearer object is the one that can be seen there.
pub fn propagate_objects(
    scene: &Scene,
    prompts: &[ObjectPrompt],
    seg: &mut dyn ViewSegmenter,
    opts: &PropagationOptions,
) -> Result<Vec<ObjectSegmentation>> {
    let mut objects = prompts
        .iter()
        .map(|p| propagate(scene, p, seg, opts))
        .collect::<Result<Vec<_>>>()?;
    resolve_overlaps(scene, &mut objects);
    Ok(objects)
}

fn resolve_overlaps(scene: &Scene, objects: &mut [ObjectSegmentation]) {
    if objects.len() < 2 {
        return;
    }
    for v in 0..scene.images.len() {
        let im = &scene.images[v];
        // Depth of each object in this view; objects without points sort last.
        let mut order: Vec<(f64, usize)> = objects
            .iter()
            .enumerate()
            .map(|(k, o)| {
                let depths: Vec<f64> = o
                    .points
                    .iter()
                    .map(|&p| im.pose.world_to_camera(scene.points[p].xyz).z)
                    .filter(|z| *z > 0.0)
                    .collect();
                (median(depths).unwrap_or(f64::INFINITY), k)
            })
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        let Some(first) = objects.iter().find_map(|o| o.views[v].mask.as_ref()) else {
            continue;
        };
        let mut taken = vec![false; (first.width() * first.height()) as usize];
        for &(_, k) in &order {
            if let Some(mask) = objects[k].views[v].mask.as_mut() {
                for (i, px) in mask.pixels_mut().enumerate() {
                    if is_object(px[0]) {
                        if taken[i] {
                            px[0] = 0;
                        } else {
                            taken[i] = true;
                        }
                    }
                }
            }
        }
    }
}

/// The baseline the paper argues against: prompts made by projecting the first view's points
/// into every other view, with no visibility test (an occluder in front of a projected point
/// gets prompted). Every prompted view is reported "ok": the baseline has no obstruction check.
pub fn projection_baseline(
    scene: &Scene,
    prompt: &ObjectPrompt,
    seg: &mut dyn ViewSegmenter,
    opts: &PropagationOptions,
) -> Result<ObjectSegmentation> {
    let first = seg.segment(scene, prompt.view, &prompt.points, prompt.bbox)?;
    let mut votes = vec![Votes::default(); scene.points.len()];
    vote(
        scene,
        prompt.view,
        &first.mask,
        opts.edge_margin_px,
        &mut votes,
    );
    let points = members(scene, &votes, opts);
    let mut views = Vec::with_capacity(scene.images.len());
    for (v, im) in scene.images.iter().enumerate() {
        let mut res = ViewResult::unsegmented(&im.name);
        if v == prompt.view {
            record(&mut res, first.clone(), prompt.points.clone(), 0);
        } else {
            let cam = scene.camera_of(im);
            let proj: Vec<DVec2> = points
                .iter()
                .filter_map(|&p| cam.project(im.pose.world_to_camera(scene.points[p].xyz)))
                .filter(|p| cam.contains(*p))
                .collect();
            if !proj.is_empty() {
                let prompts: Vec<PointPrompt> = farthest_point_sample(&proj, opts.max_prompts)
                    .into_iter()
                    .map(|p| PointPrompt {
                        xy: [p.x, p.y],
                        positive: true,
                    })
                    .collect();
                let m = seg.segment(scene, v, &prompts, None)?;
                record(&mut res, m, prompts, v);
            }
        }
        views.push(res);
    }
    Ok(ObjectSegmentation {
        name: prompt.name.clone(),
        views,
        points,
        click_agreement: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Luma;

    #[test]
    fn a_thin_part_votes_in_and_the_edge_of_a_thick_one_does_not() {
        // A 20x20 block at x 10..30 and a bar 3 px wide at x 40..43.
        let mask = GrayImage::from_fn(60, 40, |x, y| {
            let on = (10..30).contains(&x) && (10..30).contains(&y)
                || (40..43).contains(&x) && (5..35).contains(&y);
            Luma([if on { 255 } else { 0 }])
        });
        let side = MaskSide::new(&mask, 3.0);
        assert_eq!(side.of(41, 20), Some(true), "the bar's middle column");
        assert_eq!(
            side.of(40, 20),
            Some(true),
            "the bar's edge column, 1 px inside"
        );
        assert_eq!(side.of(20, 20), Some(true), "deep in the block");
        assert_eq!(side.of(10, 20), None, "the block's edge column");
        assert_eq!(side.of(11, 20), None, "2 px inside the block");
        assert_eq!(side.of(12, 20), Some(true), "3 px inside the block");
        assert_eq!(side.of(36, 20), Some(false), "between them, 4 px from each");
        assert_eq!(side.of(8, 20), None, "2 px outside");
        assert_eq!(side.of(-1, 20), None, "off the image");
    }

    #[test]
    fn a_point_far_from_the_rest_of_d_leaves_it() {
        // 100 points on a unit sphere, one 5 units from its centre (a mismatched track), one
        // far off but not in D.
        let mut xyz: Vec<DVec3> = (0..100)
            .map(|i| {
                let (t, p) = (i as f64 * 2.4, (i as f64 + 0.5) / 100.0);
                let z = 1.0 - 2.0 * p;
                let r = (1.0 - z * z).sqrt();
                DVec3::new(r * t.cos(), r * t.sin(), z)
            })
            .collect();
        xyz.push(DVec3::new(0.0, 5.0, 0.0));
        xyz.push(DVec3::new(0.0, 9.0, 0.0));
        let points: Vec<Point3D> = xyz
            .into_iter()
            .map(|xyz| Point3D {
                id: 0,
                xyz,
                rgb: [0; 3],
                error: -1.0,
                track: vec![],
            })
            .collect();
        let mut in_d = vec![true; 102];
        in_d[101] = false;
        drop_far_points(&points, &mut in_d, 4.0);
        assert!(in_d[..100].iter().all(|&m| m), "the sphere stays");
        assert!(!in_d[100], "the far point leaves");
        assert!(!in_d[101], "a non-member stays out");
        let mut in_d = vec![true; 101];
        drop_far_points(&points[..101], &mut in_d, 6.0);
        assert!(in_d[100], "within a wider spread it stays");
    }
}
