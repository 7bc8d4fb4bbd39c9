//! The hole a removed object leaves: which of its pixels no other view saw, and a fill for them.
//!
//! A removal field is trained without the removed objects' pixels; what they hid in one view is
//! learnt from the views that saw it (the paper's "inferred by other views"). Part of it no view
//! saw (the ground under the object). [`find_unseen`] marks, per view, the hole pixels whose
//! surface point no other view observed: it projects into that view outside its own hole and
//! nothing nearer stands in the way (its rendered depth agrees). The surface point is tried at
//! the trained field's depth there and at the depth the hole's surroundings continue across it.
//! [`fill_unseen`] gives those pixels targets, so training can go on with them (and draws them
//! more often than the rest): colour and disparity inpainted harmonically from what surrounds
//! the unseen part (a smooth continuation of the ground, never grey fog or floaters), the
//! disparity as a depth target so the filled surface lies where the surroundings say; where the
//! surroundings are a plane with a repeating pattern, the colour continues the pattern
//! ([`super::pattern`]).
//! [`reopen_filled_surface`] gives the filled pixels that would render see-through (their cells
//! carved away) cells to grow in.

use super::pattern::continue_pattern;
use crate::field::eval::Rendered;
use crate::field::model::Field;
use crate::field::train::Trainer;
use crate::field::view::View;
use crate::util::choice::named_choices;
use crate::util::inpaint::inpaint_harmonic;
use crate::util::{Stage, Warning};
use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

/// Relative depth difference under which a view is taken to see the same surface point (the
/// trained field's depth is accurate to a few voxels, a few percent of the distance).
pub const SAME_SURFACE_REL: f32 = 0.03;
/// A hole pixel whose render is less opaque than this has no surface to look for elsewhere: it is
/// unseen.
const MIN_SURFACE_ALPHA: f32 = 0.5;

/// One view's hole.
#[derive(Clone, Debug, Serialize)]
pub struct ViewHole {
    pub view: String,
    /// Pixels the removed objects' (dilated) masks cover, at training resolution.
    pub hole_px: usize,
    /// Of those, the pixels whose surface no other view observed.
    pub unseen_px: usize,
    /// unseen_px / hole_px (0 for a view without a hole).
    pub unseen_fraction: f64,
}

/// Per view: the unseen pixels (row-major flags, empty for a view without a hole) and their
/// counts.
pub struct Holes {
    pub unseen: Vec<Vec<bool>>,
    pub stats: Vec<ViewHole>,
}

/// A view's hole: the pixels that carry no loss.
pub(crate) fn hole_of(v: &View) -> Vec<bool> {
    match &v.loss_mask {
        Some(m) => m.iter().map(|&k| !k).collect(),
        None => vec![false; (v.width * v.height) as usize],
    }
}

/// How much more of a view's hole than of the rest of it may render see-through (opacity below
/// 1/2) before the removal is flagged. Where the ground behind a removed object does not grow
/// back, renders show the background colour through the floor (white patches in every view);
/// a scene field is otherwise opaque almost everywhere, so a few percent is already a defect.
pub const MAX_SEE_THROUGH_EXCESS: f64 = 0.05;

/// The removal's self-check: the view whose hole is most see-through compared with the rest of
/// it (`renders` of `views`, holes marked by their loss masks), as a warning past
/// [`MAX_SEE_THROUGH_EXCESS`].
pub fn see_through_check(views: &[View], renders: &[Rendered]) -> Option<Warning> {
    let worst = views
        .iter()
        .zip(renders)
        .filter_map(|(v, r)| {
            let hole = hole_of(v);
            let (mut n, mut clear) = ([0usize; 2], [0usize; 2]);
            for (h, a) in hole.iter().zip(&r.alpha) {
                n[*h as usize] += 1;
                clear[*h as usize] += (*a < MIN_SURFACE_ALPHA) as usize;
            }
            (n[1] > 0).then(|| {
                let frac = |k: usize| clear[k] as f64 / n[k].max(1) as f64;
                (v.name.as_str(), frac(1) - frac(0), frac(1))
            })
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    (worst.1 > MAX_SEE_THROUGH_EXCESS).then(|| {
        Warning::new(
            Stage::Field,
            "removal_see_through",
            worst.1,
            MAX_SEE_THROUGH_EXCESS,
            format!(
                "{:.0}% of the removed objects' pixels in {} render see-through (opacity below {MIN_SURFACE_ALPHA}): the ground behind them did not grow back, renders show holes there; train longer or check the segment run's masks",
                100.0 * worst.2,
                worst.0
            ),
        )
    })
}

/// Find, in every view of `views` (holes marked by their loss masks; `renders` of each from the
/// trained field), the hole pixels that none of the first `observers` views (those it trained
/// on) observed.
pub fn find_unseen(views: &[View], renders: &[Rendered], observers: usize) -> Holes {
    let holes: Vec<Vec<bool>> = views.iter().map(hole_of).collect();
    let unseen: Vec<Vec<bool>> = (0..views.len())
        .into_par_iter()
        .map(|i| {
            if !holes[i].iter().any(|&h| h) {
                return Vec::new();
            }
            let v = &views[i];
            let guess = depth_across_hole(v, &holes[i], &renders[i]);
            (0..(v.width * v.height) as usize)
                .map(|p| {
                    if !holes[i][p] {
                        return false;
                    }
                    let r = &renders[i];
                    let rendered = (r.alpha[p] >= MIN_SURFACE_ALPHA).then_some(r.depth[p]);
                    let guessed = (guess[p] > 0.0).then_some(guess[p]);
                    let (o, d) = v.ray(p as u32);
                    ![rendered, guessed]
                        .into_iter()
                        .flatten()
                        .any(|t| seen_elsewhere(i, o + d * t, &views[..observers], &holes, renders))
                })
                .collect()
        })
        .collect();
    let stats = views
        .iter()
        .zip(&holes)
        .zip(&unseen)
        .map(|((v, h), u)| {
            let hole_px = h.iter().filter(|&&x| x).count();
            let unseen_px = u.iter().filter(|&&x| x).count();
            ViewHole {
                view: v.name.clone(),
                hole_px,
                unseen_px,
                unseen_fraction: if hole_px > 0 {
                    unseen_px as f64 / hole_px as f64
                } else {
                    0.0
                },
            }
        })
        .collect();
    Holes { unseen, stats }
}

/// The depth behind a view's hole as its surroundings continue it: the rendered disparity outside
/// the hole, harmonically inpainted across it (exact for a plane, such as the ground an object
/// stands on; 0 where nothing around it is opaque). A candidate surface beside the render's own
/// depth, which inside the removed volume is whatever grew back (on the demo ring a rim of
/// seen ground around each hole rendered too shallow or too faint and was taken for unseen:
/// 7 908 pixels of four views against 6 853 by the truth's geometry; 6 907 with this depth).
fn depth_across_hole(v: &View, hole: &[bool], r: &Rendered) -> Vec<f32> {
    let (w, h) = (v.width as usize, v.height as usize);
    let known: Vec<bool> = (0..w * h)
        .map(|p| !hole[p] && r.alpha[p] >= MIN_SURFACE_ALPHA && r.depth[p] > 0.0)
        .collect();
    let mut disparity: Vec<f32> = (0..w * h)
        .map(|p| if known[p] { 1.0 / r.depth[p] } else { 0.0 })
        .collect();
    if !inpaint_harmonic(&mut disparity, &known, w, h, 1) {
        return vec![0.0; w * h];
    }
    disparity
        .iter()
        .map(|&d| if d > 0.0 { 1.0 / d } else { 0.0 })
        .collect()
}

/// Whether surface point `x` (behind a hole pixel of view `i`) is observed by another of the
/// `observers` (the first views): it projects outside that view's hole, onto a surface at its
/// distance (nothing nearer stands in the way).
fn seen_elsewhere(
    i: usize,
    x: Vec3,
    observers: &[View],
    holes: &[Vec<bool>],
    renders: &[Rendered],
) -> bool {
    observers.iter().enumerate().any(|(j, vj)| {
        if j == i {
            return false;
        }
        let Some((u, w)) = vj.project(x) else {
            return false;
        };
        if u < 0.0 || w < 0.0 || u >= vj.width as f32 || w >= vj.height as f32 {
            return false;
        }
        let q = (w as u32 * vj.width + u as u32) as usize;
        if holes[j][q] || renders[j].alpha[q] < MIN_SURFACE_ALPHA {
            return false;
        }
        let dist = (x - vj.center()).length();
        (renders[j].depth[q] - dist).abs() <= SAME_SURFACE_REL * dist
    })
}

/// Give every unseen pixel of `views` a target: colour inpainted from the view's own pixels
/// around its hole, disparity from those and the field's render in the seen part of the hole,
/// so training may go on with them (their loss mask set, a depth target added). Returns
/// the pixels that got a target, as (view, pixel).
pub fn fill_unseen(
    views: &mut [View],
    holes: &Holes,
    renders: &[Rendered],
    how: HoleFill,
) -> FilledPixels {
    let per_view: Vec<(Vec<(u32, u32)>, usize)> = views
        .par_iter_mut()
        .zip(holes.unseen.par_iter().zip(renders.par_iter()))
        .enumerate()
        .map(|(i, (v, (unseen, r)))| {
            if how == HoleFill::None || !unseen.iter().any(|&u| u) {
                return (Vec::new(), 0);
            }
            let patterned = fill_view(v, unseen, r, how);
            let pixels = (0..unseen.len() as u32)
                .filter(|&p| unseen[p as usize])
                .map(|p| (i as u32, p))
                .collect();
            (pixels, patterned)
        })
        .collect();
    FilledPixels {
        patterned: per_view.iter().map(|(_, n)| n).sum(),
        pixels: per_view.into_iter().flat_map(|(p, _)| p).collect(),
    }
}

/// How the part of a hole no view saw is filled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HoleFill {
    /// Left without a loss: whatever the field grows there.
    None,
    /// Harmonic: the smooth continuation of the photo around the hole.
    Smooth,
    /// The repeating pattern around the hole continued where it has one ([`super::pattern`]),
    /// harmonic elsewhere.
    #[default]
    Pattern,
}

named_choices!(HoleFill, "fill", {
    None => "none",
    Smooth => "smooth",
    Pattern => "pattern",
});

/// The pixels [`fill_unseen`] gave targets, as (view, pixel), and how many of them continue a
/// pattern.
pub struct FilledPixels {
    pub pixels: Vec<(u32, u32)>,
    pub patterned: usize,
}

/// Relative depth band around a filled pixel's depth target in which [`filled_surface_cells`]
/// opens cells (the inpainted disparity is a smooth guess, a few percent off).
const FILLED_BAND_REL: f32 = 0.03;

/// Occupy again the cells where the surface of the filled pixels that rendered see-through
/// (`renders`: the field the fill was made from) and have no occupied cell within
/// [`FILLED_BAND_REL`] of their depth target lies (that band and one cell around), and start a surface there from the fill's
/// targets ([`Field::seed_surfaces`], only in cells that were free: a surface the field holds is
/// left to training). Carving keeps only cells that rays with a loss end in, and no such ray
/// reaches what lies behind a removed object in a one-sided capture (the wall behind fox's
/// head): without this, those cells are released before the fill exists and the filled pixels
/// render see-through. Returns the cells occupied again.
pub fn reopen_filled_surface(
    trainer: &mut Trainer,
    views: &[View],
    holes: &Holes,
    renders: &[Rendered],
) -> usize {
    let cells = filled_surface_cells(&trainer.field, views, holes, renders);
    let opened = trainer.occupy(&cells);
    let field = &trainer.field;
    let seeds: Vec<(Vec3, [u8; 3])> = views
        .par_iter()
        .zip(holes.unseen.par_iter().zip(renders.par_iter()))
        .flat_map_iter(|(v, (unseen, r))| {
            let depth = v.depth.as_deref().unwrap_or(&[]);
            (0..unseen.len())
                .filter(|&p| see_through(unseen, r, depth, p))
                .filter_map(|p| {
                    let (o, dir) = v.ray(p as u32);
                    let x = o + dir * depth[p];
                    let g = field.to_grid(x);
                    let c = [g.x, g.y, g.z].map(|q| q.max(0.0) as usize);
                    let px = v.rgba[p];
                    opened
                        .binary_search(&c)
                        .is_ok()
                        .then_some((x, [px[0], px[1], px[2]]))
                })
                .collect::<Vec<_>>()
        })
        .collect();
    trainer.field.seed_surfaces(&seeds);
    opened.len()
}

/// Whether filled pixel `p` (of a view with `unseen` pixels, rendered `r`, depth targets
/// `depth`) rendered see-through and has a depth target. Only those may be reopened: elsewhere
/// the field holds a surface the fill's targets train, and the inpainted depth (a smooth guess
/// across whatever bounds the hole) would start surfaces in the air (on the demo ring it did:
/// a ghost over the mug's patch, 20.4 -> 19.3 dB inside it).
fn see_through(unseen: &[bool], r: &Rendered, depth: &[f32], p: usize) -> bool {
    unseen[p] && r.alpha[p] < MIN_SURFACE_ALPHA && depth.get(p).is_some_and(|&t| t > 0.0)
}

/// The cells of [`reopen_filled_surface`], sorted.
fn filled_surface_cells(
    field: &Field,
    views: &[View],
    holes: &Holes,
    renders: &[Rendered],
) -> Vec<[usize; 3]> {
    let d = field.grid.dims;
    let inside = |c: [i64; 3]| (0..3).all(|a| c[a] >= 0 && (c[a] as usize) + 1 < d[a]);
    // Deduplicated per view and then overall before the one-cell dilation: a fox removal fills
    // 1.6 M pixels, and 27 neighbours of 7 samples each would be 300 M entries.
    let mut centres: Vec<[i64; 3]> = views
        .par_iter()
        .zip(holes.unseen.par_iter().zip(renders.par_iter()))
        .flat_map_iter(|(v, (unseen, r))| {
            let mut out = Vec::new();
            let Some(depth) = &v.depth else { return out };
            for p in (0..unseen.len()).filter(|&p| see_through(unseen, r, depth, p)) {
                let (o, dir) = v.ray(p as u32);
                let band = (-3..=3).map(|k| {
                    let t = depth[p] * (1.0 + FILLED_BAND_REL * k as f32 / 3.0);
                    let g = field.to_grid(o + dir * t);
                    [g.x, g.y, g.z].map(|x| x.floor() as i64)
                });
                // Cells still there (emptied, not released: the ground under an object on the
                // demo ring) grow by training; only a band with none at all is reopened.
                if band
                    .clone()
                    .all(|c| !inside(c) || !field.occupied(c.map(|x| x as usize)))
                {
                    out.extend(band);
                }
            }
            out.sort_unstable();
            out.dedup();
            out
        })
        .collect();
    centres.par_sort_unstable();
    centres.dedup();
    let mut cells: Vec<[usize; 3]> = centres
        .par_iter()
        .flat_map_iter(|c| {
            (0..27).filter_map(move |n| {
                let c = [c[0] + n % 3 - 1, c[1] + (n / 3) % 3 - 1, c[2] + n / 9 - 1];
                inside(c).then(|| c.map(|x| x as usize))
            })
        })
        .collect();
    cells.par_sort_unstable();
    cells.dedup();
    cells
}

/// Returns how many pixels' colour continues a pattern.
fn fill_view(v: &mut View, unseen: &[bool], r: &Rendered, how: HoleFill) -> usize {
    let (w, h) = (v.width as usize, v.height as usize);
    let hole = hole_of(v);
    let mut rgb = vec![0.0f32; w * h * 3];
    let mut disparity = vec![0.0f32; w * h];
    let mut known_depth = vec![false; w * h];
    for p in 0..w * h {
        let px = v.rgba[p];
        for k in 0..3 {
            rgb[3 * p + k] = px[k] as f32 / 255.0;
        }
        if !unseen[p] && r.alpha[p] >= MIN_SURFACE_ALPHA && r.depth[p] > 0.0 {
            disparity[p] = 1.0 / r.depth[p];
            known_depth[p] = true;
        }
    }
    // The colour continues the photo around the hole only. The field's renders of the seen part
    // of the hole, at the time of the fill, are still regrowing from the emptied volume's grey:
    // with them the demo mug's fill rendered +10 / +14 / +19 levels (R, G, B) off the truth,
    // with the photo alone +7 / +6 / +3 (inside the unseen part 17.6 -> 18.5 dB).
    let known_colour: Vec<bool> = hole.iter().map(|&h| !h).collect();
    inpaint_harmonic(&mut rgb, &known_colour, w, h, 3);
    let patterned = if how == HoleFill::Pattern {
        continue_pattern(v, &hole, unseen, r, &mut rgb)
    } else {
        0
    };
    let has_depth = inpaint_harmonic(&mut disparity, &known_depth, w, h, 1);
    let mask = v.loss_mask.get_or_insert_with(|| vec![true; w * h]);
    let depth = v.depth.get_or_insert_with(|| vec![0.0; w * h]);
    for p in (0..w * h).filter(|&p| unseen[p]) {
        let c = [0, 1, 2].map(|k| (rgb[3 * p + k].clamp(0.0, 1.0) * 255.0).round() as u8);
        v.rgba[p] = [c[0], c[1], c[2], 255];
        mask[p] = true;
        if has_depth && disparity[p] > 0.0 {
            depth[p] = 1.0 / disparity[p];
        }
    }
    patterned
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::model::FieldConfig;
    use crate::field::train::TrainConfig;
    use crate::scene::{Camera, Pose};
    use glam::DVec3;

    /// A field with every cell released, and one 8x8 view from z = -3 looking at a wall at
    /// z = 0.4, its whole image a filled hole (colour 200, 100, 50) with the wall's depth.
    fn empty_field_and_filled_view() -> (Trainer, Vec<View>, Holes) {
        let dims = [21, 21, 21];
        let cfg = FieldConfig {
            sh_degree: 0,
            alpha_init: 0.01,
            base_voxel: 0.1,
        };
        let mut field = Field::new(cfg, Vec3::splat(-1.0), Vec3::splat(1.0), dims);
        field.fill_occupancy(false);
        field.release_free_bricks();
        assert_eq!(field.grid.num_slots(), 0);
        let trainer = Trainer::new(field, dims, TrainConfig::default());
        let pose = Pose::look_at(DVec3::new(0.0, 0.0, -3.0), DVec3::ZERO, DVec3::Y);
        let cam = Camera::pinhole(8, 8, 10.0, 10.0, 4.0, 4.0);
        let mut v = View::new("v".into(), cam, pose, vec![[200, 100, 50, 255]; 64]);
        v.depth = Some((0..64).map(|p| 3.4 / v.ray(p).1.z).collect());
        let holes = Holes {
            unseen: vec![vec![true; 64]],
            stats: Vec::new(),
        };
        (trainer, vec![v], holes)
    }

    fn rendered(alpha: f32) -> Vec<Rendered> {
        vec![Rendered {
            width: 8,
            height: 8,
            rgb: vec![[1.0; 3]; 64],
            alpha: vec![alpha; 64],
            depth: vec![0.0; 64],
        }]
    }

    #[test]
    fn a_see_through_fill_gets_cells_and_a_surface_at_its_depth() {
        let (mut trainer, views, holes) = empty_field_and_filled_view();
        let opened = reopen_filled_surface(&mut trainer, &views, &holes, &rendered(0.0));
        assert!(opened > 0);
        let f = &trainer.field;
        // The wall at z = 0.4 is grid z = 14 (voxel 0.1 from -1); the rays run near the axis.
        assert!(f.occupied([9, 9, 14]), "the cell on the wall is occupied");
        assert!(
            !f.occupied([9, 9, 4]),
            "nothing opens far in front of the wall"
        );
        let densest = (0..f.grid.num_vertices() as u32)
            .max_by(|&a, &b| {
                f.grid
                    .density(a as usize)
                    .total_cmp(&f.grid.density(b as usize))
            })
            .unwrap();
        assert!((14..=15).contains(&f.grid.vertex_coords(densest)[2]));
        let v = f.grid.vertex_values(densest as usize);
        let alpha = 1.0 - (-crate::field::activation::softplus(v[0] + f.shift())).exp();
        assert!(alpha > 0.25, "seeded opaque: alpha {alpha}");
        let red = crate::field::activation::sigmoid(0.282_094_8 * v[1]);
        assert!(
            (red - 200.0 / 255.0).abs() < 0.01,
            "seeded with the fill's colour: {red}"
        );
        // Still see-through, but now with cells in the band: training raises it, nothing opens.
        assert_eq!(
            reopen_filled_surface(&mut trainer, &views, &holes, &rendered(0.0)),
            0
        );
    }

    /// Two 16x16 views of a wall at z = 0.4 from z = -3, the second shifted sideways by 0.3; the
    /// first has a hole at pixels x, y 5..11 (the second none). Renders: the wall (red, opaque,
    /// at its depth) outside the hole; inside it `inside_alpha` over white, at `inside_depth`.
    fn two_views_of_a_wall(inside_alpha: f32, inside_depth: f32) -> (Vec<View>, Vec<Rendered>) {
        let cam = Camera::pinhole(16, 16, 20.0, 20.0, 8.0, 8.0);
        let in_hole = |p: usize| (5..11).contains(&(p % 16)) && (5..11).contains(&(p / 16));
        let mut views: Vec<View> = [0.0, 0.3]
            .iter()
            .map(|&x| {
                let eye = DVec3::new(x, 0.0, -3.0);
                let pose = Pose::look_at(eye, DVec3::new(x, 0.0, 0.0), DVec3::Y);
                View::new("v".into(), cam.clone(), pose, vec![[200, 0, 0, 255]; 256])
            })
            .collect();
        views[0].loss_mask = Some((0..256).map(|p| !in_hole(p)).collect());
        let renders = views
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let hole = |p: usize| i == 0 && in_hole(p);
                let a = |p: usize| if hole(p) { inside_alpha } else { 1.0 };
                Rendered {
                    width: 16,
                    height: 16,
                    rgb: (0..256)
                        .map(|p| [0.8 * a(p) + 1.0 - a(p), 1.0 - a(p), 1.0 - a(p)])
                        .collect(),
                    alpha: (0..256).map(a).collect(),
                    depth: (0..256u32)
                        .map(|p| match hole(p as usize) {
                            true => inside_depth,
                            false => 3.4 / v.ray(p).1.z,
                        })
                        .collect(),
                }
            })
            .collect();
        (views, renders)
    }

    #[test]
    fn ground_the_surroundings_continue_is_seen_though_the_hole_renders_empty() {
        // Inside the hole the field holds nothing yet (or something at the wrong depth): the
        // wall the surroundings continue is what the second view sees.
        for (alpha, depth) in [(0.0, 0.0), (1.0, 1.5)] {
            let (views, renders) = two_views_of_a_wall(alpha, depth);
            let holes = find_unseen(&views, &renders, 2);
            assert_eq!(holes.stats[0].hole_px, 36);
            assert_eq!(holes.stats[0].unseen_px, 0, "alpha {alpha}, depth {depth}");
        }
        // Seen by no one: the second view has a hole there too.
        let (mut views, renders) = two_views_of_a_wall(0.0, 0.0);
        views[1].loss_mask = Some(vec![false; 256]);
        assert_eq!(find_unseen(&views, &renders, 2).stats[0].unseen_px, 36);
    }

    #[test]
    fn the_fill_takes_its_colour_from_the_photo_around_the_hole() {
        // The hole's right half was seen but renders half-grown (alpha 0.5 over white: pink);
        // its left half is unseen. The fill continues the red photo around it, not the pink.
        let (mut views, renders) = two_views_of_a_wall(0.5, 0.0);
        let hole: Vec<bool> = views[0]
            .loss_mask
            .as_ref()
            .unwrap()
            .iter()
            .map(|&k| !k)
            .collect();
        let unseen: Vec<bool> = (0..256).map(|p| hole[p] && p % 16 < 8).collect();
        let holes = Holes {
            unseen: vec![unseen, Vec::new()],
            stats: Vec::new(),
        };
        let filled = fill_unseen(&mut views, &holes, &renders, HoleFill::Smooth).pixels;
        assert_eq!(filled.len(), 18);
        for &(v, p) in &filled {
            assert_eq!(v, 0);
            assert_eq!(views[0].rgba[p as usize], [200, 0, 0, 255]);
            assert!(views[0].loss_mask.as_ref().unwrap()[p as usize]);
        }
    }

    #[test]
    fn a_fill_over_a_surface_the_field_holds_opens_nothing() {
        let (mut trainer, views, holes) = empty_field_and_filled_view();
        assert_eq!(
            reopen_filled_surface(&mut trainer, &views, &holes, &rendered(0.9)),
            0
        );
        assert_eq!(trainer.field.occupied_cells(), 0);
    }
}
