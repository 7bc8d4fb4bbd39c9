//! The removed objects' volume: its cells (a vote of the views' holes, as the object field's
//! visual hull), cleared before the hole is looked for, and the air in it emptied after
//! training.
//!
//! A removal field trains without the removed objects' pixels, so few rays with a loss cross
//! the volume they occupied: [`clear_removed_volume`] gives it a fresh start (what other views
//! saw of the ground behind grows back from their rays, the unseen part from the fill's
//! targets, [`super::hole`]); [`empty_air_in_holes`] then empties what no ray taught, the air in
//! front of the surfaces the holes show.

use super::hole::hole_of;
use crate::field::march::{forward, RenderOptions};
use crate::field::model::Field;
use crate::field::view::View;
use rayon::prelude::*;

/// A cell lies in the removed objects' volume when at least this fraction of the views that see
/// its centre see it inside their hole (voting, as the object field's visual hull).
pub const REMOVED_HULL_VOTE: f32 = 0.8;

/// What a cleared cell's density logit (`raw + shift`) is set to: -4.6, a new cell's (alpha_init
/// = 1% a voxel), and its colour to grey (SH 0). Cleared cells are trained afresh: those other
/// views saw outside their holes are carved or raised again by their rays, the never-seen
/// ground under the object by the fill's targets. Lower values starve them: at -30 (the first
/// version) the ground under a removed object rendered as a white hole in every view; at -8 the
/// seen ground came back but 11% of the demo's hole pixels stayed see-through (the gradient,
/// sigmoid(-8) times a tiny sample weight, fell below Adam's epsilon), and the object's old
/// colours tinted the fill. At -4.6 with grey (the demo edits' background, scored on all 36
/// views): no see-through pixels, full frame 24.57 -> 25.75 dB, inside the mug/torus masks 16.3/14.0 -> 18.7/17.0 dB.
pub const CLEARED_LOGIT: f32 = -4.6;

/// The cells of the removed objects' volume: those whose centre projects into the hole of at
/// least [`REMOVED_HULL_VOTE`] of the views that see it (two at least).
fn removed_hull(field: &Field, views: &[View]) -> Vec<[usize; 3]> {
    let holes: Vec<Vec<bool>> = views.iter().map(hole_of).collect();
    let space = &field.space;
    field
        .occupied_cell_list()
        .into_par_iter()
        .filter(|&c| {
            let Some(p) = space.unmap(field.cell_center(c)) else {
                return false;
            };
            let (mut seen, mut hole) = (0usize, 0usize);
            for (v, h) in views.iter().zip(&holes) {
                let Some((u, w)) = v.project(p) else { continue };
                if u < 0.0 || w < 0.0 || u >= v.width as f32 || w >= v.height as f32 {
                    continue;
                }
                seen += 1;
                hole += h[(w as u32 * v.width + u as u32) as usize] as usize;
            }
            seen >= 2 && hole as f32 >= REMOVED_HULL_VOTE * seen as f32
        })
        .collect()
}

/// Set the density logit (`raw + shift`) of the vertices of `cells` to `logit`; with `only_lower`
/// a vertex already below it keeps its value.
fn set_cells_density(field: &mut Field, cells: &[[usize; 3]], logit: f32, only_lower: bool) {
    let value = logit - field.shift();
    for c in cells {
        for i in 0..8 {
            let v = field
                .grid
                .vertex_slot(c[0] + (i & 1), c[1] + ((i >> 1) & 1), c[2] + (i >> 2));
            if v == crate::field::grid::NONE {
                continue;
            }
            let v = v as usize;
            let density = field.grid.density_mut(v);
            if only_lower {
                *density = density.min(value);
            } else {
                *density = value;
                field.grid.colour_mut(v).fill(0.0);
            }
        }
    }
}

/// Empty the removed objects' volume ([`removed_hull`]): its cells start afresh (density at
/// [`CLEARED_LOGIT`], grey). Few rays with a loss cross that volume, so it would keep whatever it
/// held (a remnant of the object); what lies behind it stays, and the fill's targets raise the
/// ground there again (the cells stay occupied). Returns the cells emptied.
pub fn clear_removed_volume(field: &mut Field, views: &[View]) -> usize {
    let inside = removed_hull(field, views);
    set_cells_density(field, &inside, CLEARED_LOGIT, false);
    inside.len()
}

/// The density logit of the air [`empty_air_in_holes`] finds: softplus 3e-7, nothing a view
/// could see through a whole scene.
pub const AIR_LOGIT: f32 = -15.0;

/// Cells this many finest voxels in front of the surface a hole ray ends on are air: their
/// corners stay clear of the surface's cells even on rays that graze it. (The field's own
/// surface, not another view's: no relative depth tolerance.)
const AIR_MARGIN_VOXELS: f32 = 4.0;

/// Empty the air the removed objects left: the cells of their volume ([`removed_hull`]) that some
/// hole ray of `views` crosses in front of the surface it ends on (where its opacity passes 1/2).
/// No ray with a loss crosses that air (every view that looks through it looks at the removed
/// object), so it keeps the faint grey [`clear_removed_volume`] gave it: on the demo ring 16% of
/// the weight on the ground seen behind the removed torus (a grey haze), 5% after; that ground
/// (seen by 7+ training views) 23.1 -> 23.7 dB in the held-out views at 6000 steps. Returns the
/// cells emptied.
pub fn empty_air_in_holes(field: &mut Field, opt: &RenderOptions, views: &[View]) -> usize {
    let in_hull: std::collections::HashSet<[usize; 3]> =
        removed_hull(field, views).into_iter().collect();
    let f = &*field;
    let margin = AIR_MARGIN_VOXELS * f.voxel;
    let mut cells: Vec<[usize; 3]> = views
        .par_iter()
        .flat_map_iter(|v| {
            let hole = hole_of(v);
            let mut samples = Vec::new();
            let mut air = Vec::new();
            for p in (0..hole.len()).filter(|&p| hole[p]) {
                let (o, d) = v.ray(p as u32);
                forward(f, opt, o, d, 0.5, [0.0; 3], &mut samples);
                let Some(surface) = samples
                    .iter()
                    .find(|s| s.trans * (1.0 - s.alpha) <= 0.5)
                    .map(|s| s.t)
                else {
                    continue;
                };
                let cutoff = surface - margin;
                air.extend(
                    samples
                        .iter()
                        .take_while(|s| s.t < cutoff)
                        .map(|s| f.grid.cell_of_base(s.base as usize))
                        .filter(|c| in_hull.contains(c)),
                );
            }
            air.sort_unstable();
            air.dedup();
            air
        })
        .collect();
    cells.sort_unstable();
    cells.dedup();
    set_cells_density(field, &cells, AIR_LOGIT, true);
    cells.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::eval::render_view;
    use crate::field::model::FieldConfig;
    use crate::scene::{Camera, Pose};
    use glam::{DVec3, Vec3};

    #[test]
    fn the_air_in_front_of_what_a_hole_shows_is_emptied() {
        // An opaque wall at z = 0.4 (grid z 14) behind faint air, seen by two views whose whole
        // image is a hole: the air goes, the wall and what lies behind it stay.
        let dims = [21, 21, 21];
        let cfg = FieldConfig {
            sh_degree: 0,
            alpha_init: 0.01,
            base_voxel: 0.1,
        };
        let mut f = Field::new(cfg, Vec3::splat(-1.0), Vec3::splat(1.0), dims);
        let shift = f.shift();
        for v in 0..f.grid.num_vertices() {
            let z = f.grid.vertex_coords(v as u32)[2];
            *f.grid.density_mut(v) = if z >= 14 { 10.0 } else { CLEARED_LOGIT } - shift;
        }
        let cam = Camera::pinhole(16, 16, 20.0, 20.0, 8.0, 8.0);
        let views: Vec<View> = [0.0, 0.3]
            .iter()
            .map(|&x| {
                let eye = DVec3::new(x, 0.0, -3.0);
                let pose = Pose::look_at(eye, DVec3::new(x, 0.0, 0.0), DVec3::Y);
                let mut v = View::new("v".into(), cam.clone(), pose, vec![[0, 0, 0, 255]; 256]);
                v.loss_mask = Some(vec![false; 256]);
                v
            })
            .collect();
        let density = |f: &Field, c: [usize; 3]| {
            f.grid
                .density(f.grid.vertex_slot(c[0], c[1], c[2]) as usize)
                + shift
        };
        assert!(empty_air_in_holes(&mut f, &RenderOptions::default(), &views) > 0);
        assert_eq!(
            density(&f, [10, 10, 5]),
            AIR_LOGIT,
            "the air in front is emptied"
        );
        assert_eq!(density(&f, [10, 10, 14]), 10.0, "the wall stays");
        assert_eq!(
            density(&f, [10, 10, 11]),
            CLEARED_LOGIT,
            "so do the cells next to it"
        );
        let r = render_view(&f, &RenderOptions::default(), &views[0], [1.0; 3]);
        // (The view is wider than the box: its middle looks at the wall.)
        let middle =
            (0..256).filter(|p| (4..12).contains(&(p % 16)) && (4..12).contains(&(p / 16)));
        assert!(
            middle.map(|p| r.alpha[p]).all(|a| a > 0.99),
            "the wall still renders opaque"
        );
    }
}
