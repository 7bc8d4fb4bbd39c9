//! Training on some views of a scene and scoring the others: the split, and the depth error of a
//! field against true depth (the demo scene's truth, or any depth images).

use super::model::Field;
use super::view::View;
use crate::field::march::{forward, RenderOptions};
use rayon::prelude::*;
use serde::Serialize;

/// Which views of a capture are left out of training, to score a field on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase", tag = "rule", content = "n")]
pub enum HoldOut {
    /// Every view trains.
    #[default]
    None,
    /// Every n-th view, starting at n/2: views n/2, n/2 + n, ... (the first view, where a demo
    /// click is, stays in training; 6 holds out 6 of the demo scene's 36 views, spread around
    /// the ring). 0 and 1 are taken as none.
    Every(usize),
    /// The LLFF convention: views 0, 8, 16, ... (NeRF's `llffhold = 8`, as the LLFF figures in
    /// the literature are scored).
    Llff,
}

impl HoldOut {
    /// Every `n`-th view (0: none).
    pub fn every(n: usize) -> HoldOut {
        if n == 0 {
            HoldOut::None
        } else {
            HoldOut::Every(n)
        }
    }

    /// Whether view `i` (in the scene's order) is held out.
    pub fn holds_out(&self, i: usize) -> bool {
        match *self {
            HoldOut::None => false,
            HoldOut::Every(n) => n > 1 && i % n == n / 2,
            HoldOut::Llff => i % 8 == 0,
        }
    }

    pub fn is_none(&self) -> bool {
        matches!(self, HoldOut::None | HoldOut::Every(0) | HoldOut::Every(1))
    }
}

impl std::str::FromStr for HoldOut {
    type Err = String;

    /// `none`, `llff`, or a number n (every n-th view).
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "none" | "0" => Ok(HoldOut::None),
            "llff" => Ok(HoldOut::Llff),
            n => n.parse::<usize>().map(HoldOut::every).map_err(|_| {
                format!("'{s}' is not a hold-out rule: 'llff' (views 0, 8, 16, ...), 'none', or N (every N-th view)")
            }),
        }
    }
}

impl std::fmt::Display for HoldOut {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HoldOut::None => write!(f, "none"),
            HoldOut::Every(n) => write!(f, "{n}"),
            HoldOut::Llff => write!(f, "llff"),
        }
    }
}

/// Split views into (train, held out) by `hold_out`.
pub fn split(views: Vec<View>, hold_out: HoldOut) -> (Vec<View>, Vec<View>) {
    let (mut train, mut test) = (Vec::new(), Vec::new());
    for (i, v) in views.into_iter().enumerate() {
        if hold_out.holds_out(i) {
            test.push(v);
        } else {
            train.push(v);
        }
    }
    (train, test)
}

/// Depth error of a field over the pixels that have a true depth (views' `depth`: distance along
/// the unit ray, set inside the object's mask only), in z-depth (the convention of depth images).
#[derive(Clone, Debug, Default, Serialize)]
pub struct DepthError {
    /// Median |rendered - true| z-depth, world units.
    pub median: f64,
    /// Mean signed error (rendered - true): > 0 means the surface is rendered too far.
    pub mean_signed: f64,
    /// 90th percentile of the absolute error.
    pub p90: f64,
    /// Median |error| of the depth where the opacity along the ray first reaches one half (the
    /// median termination depth), for comparison.
    pub median_half: f64,
    /// Pixels scored.
    pub pixels: usize,
    /// Pixels where the field's opacity is below 0.5 although the object is there (scored with
    /// their normalised expected depth all the same).
    pub transparent: usize,
}

/// Render the depth of every pixel with a true depth and compare. The rendered depth is the
/// expected termination distance normalised by the opacity (sum w t / sum w), converted to z-depth.
pub fn depth_error(f: &Field, opt: &RenderOptions, views: &[View]) -> DepthError {
    let per: Vec<(Vec<(f64, f64)>, usize)> = views
        .par_iter()
        .filter_map(|v| v.depth.as_ref().map(|d| (v, d)))
        .map(|(v, truth)| {
            let mut scratch = Vec::new();
            let mut errs = Vec::new();
            let mut transparent = 0;
            for (i, &dt) in truth.iter().enumerate() {
                if dt <= 0.0 {
                    continue;
                }
                let (o, d) = v.ray(i as u32);
                let r = forward(f, opt, o, d, 0.5, [1.0; 3], &mut scratch);
                if r.alpha < 0.5 {
                    transparent += 1;
                }
                let dr = if r.alpha > 1e-3 {
                    r.depth / r.alpha
                } else {
                    0.0
                };
                let half = scratch
                    .iter()
                    .find(|s| 1.0 - s.trans * (1.0 - s.alpha) >= 0.5)
                    .map_or(0.0, |s| s.t);
                let k = v.ray_scale(i as u32);
                errs.push((((dr - dt) / k) as f64, ((half - dt) / k) as f64));
            }
            (errs, transparent)
        })
        .collect();
    let transparent = per.iter().map(|p| p.1).sum();
    let both: Vec<(f64, f64)> = per.into_iter().flat_map(|p| p.0).collect();
    let signed: Vec<f64> = both.iter().map(|e| e.0).collect();
    let mut half: Vec<f64> = both.iter().map(|e| e.1.abs()).collect();
    half.sort_by(|a, b| a.total_cmp(b));
    if signed.is_empty() {
        return DepthError::default();
    }
    let mut abs: Vec<f64> = signed.iter().map(|e| e.abs()).collect();
    abs.sort_by(|a, b| a.total_cmp(b));
    let q = |p: f64| abs[((abs.len() - 1) as f64 * p).round() as usize];
    DepthError {
        median: q(0.5),
        mean_signed: signed.iter().sum::<f64>() / signed.len() as f64,
        p90: q(0.9),
        median_half: half.get(half.len() / 2).copied().unwrap_or(0.0),
        pixels: abs.len(),
        transparent,
    }
}

/// The names of the views of `scene` that `hold_out` leaves out of training.
pub fn held_out_views(scene: &crate::scene::Scene, hold_out: HoldOut) -> Vec<String> {
    scene
        .images
        .iter()
        .enumerate()
        .filter(|(i, _)| hold_out.holds_out(*i))
        .map(|(_, im)| im.name.clone())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hold_out_rules_pick_the_views_they_name() {
        let picked = |h: HoldOut| (0..20).filter(|&i| h.holds_out(i)).collect::<Vec<_>>();
        assert_eq!(picked(HoldOut::Llff), vec![0, 8, 16]);
        assert_eq!(picked(HoldOut::Every(6)), vec![3, 9, 15]);
        assert!(picked(HoldOut::None).is_empty());
        assert!(picked(HoldOut::every(0)).is_empty());
        assert_eq!("llff".parse::<HoldOut>(), Ok(HoldOut::Llff));
        assert_eq!("LLFF".parse::<HoldOut>(), Ok(HoldOut::Llff));
        assert_eq!("8".parse::<HoldOut>(), Ok(HoldOut::Every(8)));
        assert_eq!("none".parse::<HoldOut>(), Ok(HoldOut::None));
        assert!("every other"
            .parse::<HoldOut>()
            .unwrap_err()
            .contains("llff"));
    }
}
