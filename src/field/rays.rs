//! Training rays: the (view, pixel) pairs whose ray meets the object's box; the rest are pruned
//! (an order of magnitude fewer rays for an object that fills a tenth of the views).

use super::model::Field;
use super::view::View;
use rayon::prelude::*;

/// Training rays: (view, pixel) pairs whose ray meets the box.
#[derive(Clone, Debug)]
pub struct RaySet {
    pub rays: Vec<(u32, u32)>,
    pub total: usize,
    /// Kept rays that carry a depth target (drawn in addition to the colour batch, since sparse
    /// depth pixels are too rare to be hit by uniform sampling).
    pub depth_rays: Vec<(u32, u32)>,
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
        }
    }

    /// Fraction of all pixels whose rays were pruned.
    pub fn pruned_fraction(&self) -> f64 {
        1.0 - self.rays.len() as f64 / self.total.max(1) as f64
    }
}
