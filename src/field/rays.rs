//! Training rays: the (view, pixel) pairs whose ray meets the object's box; the rest are pruned
//! (an order of magnitude fewer rays for an object that fills a tenth of the views).

use super::model::Field;
use super::view::View;
use crate::util::Rng;
use rayon::prelude::*;

/// Training rays: (view, pixel) pairs whose ray meets the box.
#[derive(Clone, Debug)]
pub struct RaySet {
    pub rays: Vec<(u32, u32)>,
    pub total: usize,
    /// Kept rays that carry a depth target (drawn in addition to the colour batch, since sparse
    /// depth pixels are too rare to be hit by uniform sampling).
    pub depth_rays: Vec<(u32, u32)>,
    /// Rays drawn in addition, [`TrainConfig::focus_batch`](super::train::TrainConfig) a step:
    /// a removal's filled pixels (ten thousand among millions: drawn uniformly, each would be
    /// seen a few times before training ends). Empty unless set.
    pub focus: Vec<(u32, u32)>,
    /// Each view's image width, and where its rays start in `rays` (one past the last view's
    /// end at the back), to find a pixel's neighbours for [`RaySet::draw_runs`].
    widths: Vec<u32>,
    view_starts: Vec<usize>,
}

impl RaySet {
    /// The rays of `views` that meet the field's box (in its space) and carry a loss (a view's
    /// `loss_mask`: a removed object's pixels carry none).
    pub fn build(views: &[View], field: &Field) -> RaySet {
        let (lo, hi) = (field.box_min, field.box_max);
        let per: Vec<Vec<(u32, u32)>> = views
            .par_iter()
            .enumerate()
            .map(|(vi, v)| {
                (0..v.width * v.height)
                    .filter(|&p| {
                        let (o, d) = v.ray(p);
                        v.loss_mask.as_ref().is_none_or(|m| m[p as usize])
                            && field.space.ray_hits(o, d, lo, hi)
                    })
                    .map(|p| (vi as u32, p))
                    .collect()
            })
            .collect();
        let total = views.iter().map(|v| (v.width * v.height) as usize).sum();
        let mut view_starts = vec![0];
        for p in &per {
            view_starts.push(view_starts.last().unwrap() + p.len());
        }
        let rays: Vec<(u32, u32)> = per.into_iter().flatten().collect();
        let depth_rays = rays
            .iter()
            .copied()
            .filter(|&(vi, p)| {
                views[vi as usize]
                    .depth
                    .as_ref()
                    .is_some_and(|d| d[p as usize] > 0.0)
            })
            .collect();
        RaySet {
            rays,
            total,
            depth_rays,
            focus: Vec::new(),
            widths: views.iter().map(|v| v.width).collect(),
            view_starts,
        }
    }

    /// Draw `count` rays in runs of `run` neighbouring pixels along a row of one view (each run
    /// holds a random training ray at a random place in it, and only training rays, so a run at
    /// a mask edge holds fewer; every training ray is drawn equally often). Neighbouring rays
    /// share grid corners: a batch of runs reads and scatters through cache rather than memory.
    /// Runs rather than square tiles: at the same speed-up, tiles' rays are more alike and lego
    /// trained worse (examples/results/field.md).
    pub fn draw_runs(&self, count: usize, run: usize, rng: &mut Rng, out: &mut Vec<(u32, u32)>) {
        let goal = out.len() + count;
        while out.len() < goal {
            if let Some(drawn) = self.draw_run(run.max(1), rng) {
                let room = goal - out.len();
                out.extend_from_slice(&drawn[..drawn.len().min(room)]);
            }
        }
    }

    /// One run for [`RaySet::draw_runs`], or None where it was drawn and not kept.
    fn draw_run(&self, run: usize, rng: &mut Rng) -> Option<&[(u32, u32)]> {
        let at = rng.below(self.rays.len());
        let (view, anchor) = self.rays[at];
        if run == 1 {
            return Some(&self.rays[at..at + 1]);
        }
        let (v, w) = (view as usize, self.widths[view as usize]);
        // The run's first column, possibly left of the image: runs are cut to the image, not
        // moved into it, so every pixel lies in exactly `run` of them.
        let (x, row) = ((anchor % w) as i64, (anchor - anchor % w) as i64);
        let x0 = x - rng.below(run) as i64;
        let from = (row + x0.max(0)) as u32;
        let to = (row + (x0 + run as i64).min(w as i64)) as u32;
        // A view's rays are sorted by pixel, so the run's are the anchor's neighbours in the
        // list (a search per draw instead cost a third of the step).
        let (first, end) = (self.view_starts[v], self.view_starts[v + 1]);
        let mut lo = at;
        while lo > first && self.rays[lo - 1].1 >= from {
            lo -= 1;
        }
        let mut hi = at + 1;
        while hi < end && self.rays[hi].1 < to {
            hi += 1;
        }
        // A run holding k training rays was drawn k times as often as one holding one: keep it
        // with probability 1/k, so rays at mask edges are drawn as often as any.
        (rng.below(hi - lo) == 0).then(|| &self.rays[lo..hi])
    }

    /// Fraction of all pixels whose rays were pruned.
    pub fn pruned_fraction(&self) -> f64 {
        1.0 - self.rays.len() as f64 / self.total.max(1) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two 10x4 views; the training rays are a disc-like patch of the first and one row of the
    /// second.
    fn ray_set() -> RaySet {
        let mut per = [Vec::new(), Vec::new()];
        for p in 0..40u32 {
            let (x, y) = (p % 10, p / 10);
            if (2..8).contains(&x) && (1..3).contains(&y) || x == 4 {
                per[0].push((0, p));
            }
            if y == 2 {
                per[1].push((1, p));
            }
        }
        let view_starts = vec![0, per[0].len(), per[0].len() + per[1].len()];
        RaySet {
            rays: per.concat(),
            total: 80,
            depth_rays: Vec::new(),
            focus: Vec::new(),
            widths: vec![10, 10],
            view_starts,
        }
    }

    #[test]
    fn runs_are_neighbours_in_a_row_and_cover_every_ray_evenly() {
        let set = ray_set();
        let mut rng = Rng::new(3);
        let mut counts = std::collections::HashMap::new();
        for _ in 0..2000 {
            let mut out = Vec::new();
            set.draw_runs(37, 4, &mut rng, &mut out);
            assert_eq!(out.len(), 37);
            for r in &out {
                assert!(set.rays.contains(r), "{r:?} is not a training ray");
                *counts.entry(*r).or_insert(0usize) += 1;
            }
        }
        // Each run: training rays of one view and row, within `run` pixels.
        for _ in 0..500 {
            let Some(drawn) = set.draw_run(4, &mut rng) else {
                continue;
            };
            let (first, last) = (drawn[0], drawn[drawn.len() - 1]);
            assert!(drawn.iter().all(|r| r.0 == first.0), "{drawn:?}");
            assert_eq!(first.1 / 10, last.1 / 10, "{drawn:?} spans rows");
            assert!(last.1 - first.1 < 4, "{drawn:?} is longer than 4 pixels");
        }
        assert_eq!(
            counts.len(),
            set.rays.len(),
            "some training ray was never drawn"
        );
        // Rays at the patch's edges and lone ones are drawn as often as those in the middle:
        // 2000 * 37 draws over 24 rays, 3083 each on average.
        let (lo, hi) = (
            counts.values().min().unwrap(),
            counts.values().max().unwrap(),
        );
        assert!(*lo > 2700 && *hi < 3500, "uneven draws: {lo} to {hi}");
    }
}
