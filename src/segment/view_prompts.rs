//! The prompts for one view of the propagation (Algorithm 1): positives from the view's own
//! features whose 3D point is in D, negatives from features of points known to be outside, and a
//! box around the positives.
//!
//! Correspondences alone fail where a view shares few tracks with the views already segmented:
//! fox's close-ups from below see the head at another scale, and of their ~1000 tracked features
//! only 4-5 belong to D, mostly on the snout, so SAM was given the snout (or, after one bad mask,
//! the wallpaper). There the positives are filled in with D's points *projected* into the view,
//! but only those that pass a free-space test against the view's own features: a projected point
//! is dropped when a feature of a point outside D lies near it at another depth (an occluder in
//! front, or background seen through where the object should be) or was voted outside. This is
//! the projection the paper argues against, made safe by the evidence it lacks: what the view
//! itself saw at that pixel.

use super::types::{PointPrompt, PropagationOptions, Votes};
use crate::scene::Scene;
use glam::DVec2;
use std::collections::HashMap;

/// What SAM is given for one view.
pub struct ViewPrompts {
    pub points: Vec<PointPrompt>,
    pub bbox: Option<[f64; 4]>,
    /// Positives that came from projected points rather than correspondences.
    pub projected: usize,
}

pub fn view_prompts(
    scene: &Scene,
    v: usize,
    votes: &[Votes],
    in_d: &[bool],
    opts: &PropagationOptions,
) -> ViewPrompts {
    let feats = &scene.images[v].features;
    let corr: Vec<DVec2> = feats
        .iter()
        .filter(|f| f.point.is_some_and(|p| in_d[p]))
        .map(|f| f.xy)
        .collect();
    let mut positives = farthest_point_sample(&corr, opts.max_prompts);
    let mut spread = corr.clone();
    let mut projected = 0;
    if positives.len() < opts.max_prompts && opts.projected_fill {
        let fill = projected_free_space(scene, v, votes, in_d, opts);
        let before = positives.len();
        positives = farthest_point_extend(positives, &fill, opts.max_prompts);
        projected = positives.len() - before;
        spread.extend(fill);
    }
    let mut points: Vec<PointPrompt> = positives
        .iter()
        .map(|p| PointPrompt {
            xy: [p.x, p.y],
            positive: true,
        })
        .collect();
    points.extend(
        negatives(feats, votes, &positives, opts)
            .into_iter()
            .map(|p| PointPrompt {
                xy: [p.x, p.y],
                positive: false,
            }),
    );
    let bbox = match opts.box_padding {
        Some(pad) if !spread.is_empty() => Some(padded_box(scene, v, &spread, pad)),
        _ => None,
    };
    ViewPrompts {
        points,
        bbox,
        projected,
    }
}

/// Features of points known to be outside (voted out, never in), nearest to the positives'
/// centroid, spread out; none closer than two edge margins to a positive.
fn negatives(
    feats: &[crate::scene::Feature],
    votes: &[Votes],
    positives: &[DVec2],
    opts: &PropagationOptions,
) -> Vec<DVec2> {
    if opts.max_negatives == 0 || positives.is_empty() {
        return vec![];
    }
    let centroid = positives.iter().fold(DVec2::ZERO, |a, p| a + *p) / positives.len() as f64;
    let min_gap = 2.0 * opts.edge_margin_px;
    let mut neg: Vec<(f64, DVec2)> = feats
        .iter()
        .filter(|f| f.point.is_some_and(|p| votes[p].is_outside()))
        .filter(|f| positives.iter().all(|q| (*q - f.xy).length() >= min_gap))
        .map(|f| ((f.xy - centroid).length(), f.xy))
        .collect();
    neg.sort_by(|a, b| a.0.total_cmp(&b.0));
    let near: Vec<DVec2> = neg
        .iter()
        .take(4 * opts.max_negatives)
        .map(|x| x.1)
        .collect();
    farthest_point_sample(&near, opts.max_negatives)
}

/// D's points projected into view `v` that the view's own features do not contradict: no
/// feature of a point outside D within `free_space_radius` (a fraction of the image's larger
/// side) that was voted outside or lies at a depth differing by more than `free_space_depth`
/// (relative).
fn projected_free_space(
    scene: &Scene,
    v: usize,
    votes: &[Votes],
    in_d: &[bool],
    opts: &PropagationOptions,
) -> Vec<DVec2> {
    let im = &scene.images[v];
    let cam = scene.camera_of(im);
    let radius = opts.free_space_radius * cam.width.max(cam.height) as f64;
    let others: Vec<Witness> = im
        .features
        .iter()
        .filter_map(|f| {
            let p = f.point.filter(|&p| !in_d[p])?;
            Some(Witness {
                xy: f.xy,
                depth: im.pose.world_to_camera(scene.points[p].xyz).z,
                outside: votes[p].is_outside(),
            })
        })
        .collect();
    let grid = WitnessGrid::new(&others, radius);
    let mut out = Vec::new();
    for (p, inside) in in_d.iter().enumerate() {
        if !inside {
            continue;
        }
        let q = im.pose.world_to_camera(scene.points[p].xyz);
        let Some(xy) = cam.project(q).filter(|xy| cam.contains(*xy)) else {
            continue;
        };
        let contradicted = grid.near(xy).any(|w| {
            (w.xy - xy).length() < radius
                && (w.outside || (w.depth - q.z).abs() > opts.free_space_depth * q.z)
        });
        if !contradicted {
            out.push(xy);
        }
    }
    out
}

/// A feature of the view whose point is not in D: what the view saw at that pixel.
struct Witness {
    xy: DVec2,
    /// Its point's depth in the view's camera.
    depth: f64,
    /// Its point was voted outside the object.
    outside: bool,
}

/// Witnesses bucketed in square cells of side `cell`, for "who is within `cell` of here".
struct WitnessGrid<'a> {
    cell: f64,
    buckets: HashMap<(i64, i64), Vec<&'a Witness>>,
}

impl<'a> WitnessGrid<'a> {
    fn new(items: &'a [Witness], cell: f64) -> Self {
        let mut buckets: HashMap<(i64, i64), Vec<&'a Witness>> = HashMap::new();
        for w in items {
            buckets.entry(Self::key(w.xy, cell)).or_default().push(w);
        }
        WitnessGrid { cell, buckets }
    }

    fn key(xy: DVec2, cell: f64) -> (i64, i64) {
        ((xy.x / cell).floor() as i64, (xy.y / cell).floor() as i64)
    }

    /// Witnesses in the 3 x 3 cells around `xy` (a superset of those within `cell`).
    fn near(&self, xy: DVec2) -> impl Iterator<Item = &'a Witness> + '_ {
        let (cx, cy) = Self::key(xy, self.cell);
        (-1..=1)
            .flat_map(move |dy| (-1..=1).map(move |dx| (cx + dx, cy + dy)))
            .filter_map(|k| self.buckets.get(&k))
            .flatten()
            .copied()
    }
}

/// The box around `pts`, grown by `pad` of its size and clipped to view `v`'s frame.
fn padded_box(scene: &Scene, v: usize, pts: &[DVec2], pad: f64) -> [f64; 4] {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in pts {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let g = (hi - lo) * pad;
    let cam = scene.camera_of(&scene.images[v]);
    let max = DVec2::new(cam.width as f64, cam.height as f64);
    let (lo, hi) = ((lo - g).max(DVec2::ZERO), (hi + g).min(max));
    [lo.x, lo.y, hi.x, hi.y]
}

/// Up to `k` points spread out: start at the point nearest the centroid, then repeatedly take the
/// point farthest from those chosen. Deterministic.
pub fn farthest_point_sample(pts: &[DVec2], k: usize) -> Vec<DVec2> {
    if pts.len() <= k {
        return pts.to_vec();
    }
    let centroid = pts.iter().fold(DVec2::ZERO, |a, p| a + *p) / pts.len() as f64;
    let start = (0..pts.len())
        .min_by(|&a, &b| {
            (pts[a] - centroid)
                .length_squared()
                .total_cmp(&(pts[b] - centroid).length_squared())
        })
        .unwrap_or(0);
    farthest_point_extend(vec![pts[start]], pts, k)
}

/// Add points of `pts` to `chosen`, each the farthest from those already chosen, until there are
/// `k` (or `pts` runs out). Deterministic.
pub fn farthest_point_extend(mut chosen: Vec<DVec2>, pts: &[DVec2], k: usize) -> Vec<DVec2> {
    let mut dist: Vec<f64> = pts
        .iter()
        .map(|p| {
            chosen
                .iter()
                .map(|c| (*p - *c).length_squared())
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    while chosen.len() < k {
        let (i, d) =
            dist.iter().enumerate().fold(
                (0, -1.0),
                |acc, (i, d)| if *d > acc.1 { (i, *d) } else { acc },
            );
        if d <= 0.0 {
            break; // every candidate is already chosen
        }
        chosen.push(pts[i]);
        for (d, p) in dist.iter_mut().zip(pts) {
            *d = d.min((*p - pts[i]).length_squared());
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn farthest_point_sampling_spreads_out() {
        let pts: Vec<DVec2> = (0..100)
            .map(|i| DVec2::new((i % 10) as f64, (i / 10) as f64))
            .collect();
        let s = farthest_point_sample(&pts, 5);
        assert_eq!(s.len(), 5);
        // The four corners are among the picks after the central start.
        for c in [
            DVec2::new(0.0, 0.0),
            DVec2::new(9.0, 0.0),
            DVec2::new(0.0, 9.0),
            DVec2::new(9.0, 9.0),
        ] {
            assert!(s.contains(&c), "{c} not in {s:?}");
        }
        assert_eq!(farthest_point_sample(&pts[..3], 5).len(), 3);
    }

    #[test]
    fn extending_keeps_the_chosen_and_adds_the_farthest() {
        let chosen = vec![DVec2::new(0.0, 0.0)];
        let pts = [
            DVec2::new(1.0, 0.0),
            DVec2::new(10.0, 0.0),
            DVec2::new(0.0, 0.0),
        ];
        let s = farthest_point_extend(chosen, &pts, 5);
        assert_eq!(s[0], DVec2::new(0.0, 0.0));
        assert_eq!(s[1], DVec2::new(10.0, 0.0));
        // (0, 0) is a duplicate of a chosen point and is not added again.
        assert_eq!(s.len(), 3);
    }
}
