//! The removed objects' volume in a scene field: the cells every view that sees them sees
//! inside its hole. Separate from [`super::hole`] so the trainer's carving can keep it without
//! importing the hole's rendering.

use super::model::Field;
use super::view::View;
use rayon::prelude::*;

/// A view's hole: the pixels that carry no loss.
pub fn hole_of(v: &View) -> Vec<bool> {
    match &v.loss_mask {
        Some(m) => m.iter().map(|&k| !k).collect(),
        None => vec![false; (v.width * v.height) as usize],
    }
}

/// A cell lies in the removed objects' volume when at least this fraction of the views that see
/// its centre see it inside their hole (voting, as the object field's visual hull).
pub const REMOVED_HULL_VOTE: f32 = 0.8;

/// The occupied cells whose centre projects into the hole of at least [`REMOVED_HULL_VOTE`] of
/// the views that see it (two at least): the removed objects' volume and, seen from one side
/// only, what lies behind them (empty when no view has a hole).
pub fn removed_hull(field: &Field, views: &[View]) -> Vec<[usize; 3]> {
    if views.iter().all(|v| v.loss_mask.is_none()) {
        return Vec::new();
    }
    let holes: Vec<Vec<bool>> = views.iter().map(hole_of).collect();
    let space = field.space.clone();
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
