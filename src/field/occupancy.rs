//! The occupancy bitmap's upkeep during training: cells whose densest corner is too faint are
//! dropped, then the bricks no occupied cell needs are released. Both work from the occupancy
//! words, brick by brick (every 100 steps at lego 800^2 they walked ~4 M cells in a list, 11%
//! of training). Pruning rebuilds the marcher's bitset of the bricks that hold an occupied cell
//! ([`LiveBricks`]); releasing leaves it as it is.

use super::grid::{BRICK, NONE};
use super::live::LiveBricks;
use super::model::Field;
use rayon::prelude::*;

impl Field {
    /// Rebuild [`Field::live`] from the occupancy words (after the grid or the words change
    /// wholesale).
    pub fn refresh_live_bricks(&mut self) {
        let mut live = LiveBricks::new(self.grid.brick_dims);
        for (s, &word) in self.occupancy.iter().enumerate() {
            if word != 0 {
                live.mark(self.grid.brick_of_slot(s));
            }
        }
        self.live = live;
    }

    /// Mark the brick of cell `b` live (a cell was just occupied).
    pub(super) fn mark_live(&mut self, b: [usize; 3]) {
        if self.live.brick_dims != self.grid.brick_dims {
            self.refresh_live_bricks();
        }
        self.live.mark(b.map(|v| v / BRICK));
    }

    /// Replace the occupancy words (one a grid slot, as [`Field::occupancy`]).
    pub fn set_occupancy_words(&mut self, words: Vec<u64>) {
        self.occupancy = words;
        self.refresh_live_bricks();
    }

    /// Drop the bricks no occupied cell needs. Returns the slot map ([`Grid::compact`]) when
    /// something was dropped, for state laid out like the grid to follow.
    ///
    /// [`Grid::compact`]: super::grid::Grid::compact
    pub fn release_free_bricks(&mut self) -> Option<Vec<u32>> {
        // A brick's cells need its own vertices, and those on its far faces the next brick's.
        let bd = self.grid.brick_dims;
        let mut need = vec![false; bd.iter().product()];
        for (s, &word) in self.occupancy.iter().enumerate() {
            if word == 0 {
                continue;
            }
            let b = self.grid.brick_of_slot(s);
            for (d, &mask) in FAR_FACE_CELLS.iter().enumerate() {
                let n = [b[0] + (d & 1), b[1] + ((d >> 1) & 1), b[2] + (d >> 2)];
                if word & mask != 0 && n.iter().zip(bd).all(|(&v, m)| v < m) {
                    need[n[0] + bd[0] * (n[1] + bd[1] * n[2])] = true;
                }
            }
        }
        let keep: Vec<bool> = (0..self.grid.num_slots())
            .map(|s| {
                let b = self.grid.brick_of_slot(s);
                need[b[0] + bd[0] * (b[1] + bd[1] * b[2])]
            })
            .collect();
        if keep.iter().all(|&k| k) {
            return None;
        }
        let map = self.grid.compact(&keep);
        // Only bricks with no occupied cell go, and the live bits are by brick coordinates,
        // not slots: they stay as they are.
        super::grid::compact_buffer(&mut self.occupancy, &map, 1);
        Some(map)
    }

    /// Drop cells whose largest possible alpha (over a step of `delta` finest voxels) is below
    /// `thresh`. Post-activation is monotone in the raw density, so a cell's alpha never exceeds
    /// that of its densest corner: the bound is exact and skipping loses nothing above `thresh`.
    /// Cells already free stay free (the visual hull carved them).
    pub fn prune_occupancy(&mut self, delta: f32, thresh: f32) {
        let raw_min = self.raw_for_alpha(thresh, delta);
        let grid = &self.grid;
        let dense = |x: usize, y: usize, z: usize| match grid.vertex_slot(x, y, z) {
            NONE => false,
            v => grid.density(v as usize) >= raw_min,
        };
        // Each word on its own, in parallel.
        let kept: Vec<u64> = self
            .occupancy
            .par_iter()
            .enumerate()
            .map(|(s, &word)| {
                let b = grid.brick_of_slot(s).map(|v| v * BRICK);
                let mut keep = word;
                let mut rest = word;
                while rest != 0 {
                    let l = rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    let c = [
                        b[0] + l % BRICK,
                        b[1] + (l / BRICK) % BRICK,
                        b[2] + l / (BRICK * BRICK),
                    ];
                    if !(0..8)
                        .any(|i| dense(c[0] + (i & 1), c[1] + ((i >> 1) & 1), c[2] + (i >> 2)))
                    {
                        keep &= !(1 << l);
                    }
                }
                keep
            })
            .collect();
        self.set_occupancy_words(kept);
    }
}

/// Per neighbour d = dx + 2 dy + 4 dz (each 0 or 1) of a brick, the cells of the brick (bits of
/// its occupancy word) with a corner in that neighbour: those on the far faces d names.
const FAR_FACE_CELLS: [u64; 8] = {
    let mut masks = [0u64; 8];
    let mut d = 0;
    while d < 8 {
        let mut l = 0;
        while l < BRICK * BRICK * BRICK {
            let at = [l % BRICK, (l / BRICK) % BRICK, l / (BRICK * BRICK)];
            let (mut on, mut axis) = (true, 0);
            while axis < 3 {
                on &= (d >> axis) & 1 == 0 || at[axis] == BRICK - 1;
                axis += 1;
            }
            if on {
                masks[d] |= 1 << l;
            }
            l += 1;
        }
        d += 1;
    }
    masks
};

#[cfg(test)]
mod tests {
    use super::super::model::tests::unit_cube_field;
    use super::*;
    use crate::field::live::BLOCK;

    /// A brick is live exactly when its occupancy word is not 0, and a block when any of its
    /// bricks is.
    fn assert_live_bricks_follow_the_words(f: &Field) {
        let bd = f.grid.brick_dims;
        let mut blocks = std::collections::HashSet::new();
        for i in 0..bd.iter().product::<usize>() {
            let b = [i % bd[0], (i / bd[0]) % bd[1], i / (bd[0] * bd[1])];
            let word = f.grid.slot(b).map_or(0, |s| f.occupancy[s]);
            assert_eq!(f.live.brick(b), word != 0, "brick {b:?}");
            if word != 0 {
                blocks.insert(b.map(|v| v / BLOCK));
            }
        }
        for i in 0..bd.iter().product::<usize>() {
            let b = [i % bd[0], (i / bd[0]) % bd[1], i / (bd[0] * bd[1])];
            assert_eq!(f.live.block(b), blocks.contains(&b.map(|v| v / BLOCK)));
        }
    }

    /// Pruning and releasing bricks from the occupancy words agree with the cell-by-cell rules:
    /// a cell stays while a corner is dense enough; a brick stays while a cell needs a vertex
    /// in it (cells on a brick's far faces need the next brick's).
    #[test]
    fn pruning_and_release_follow_the_cells() {
        let mut f = unit_cube_field(0, [23, 18, 15]);
        let mut r = crate::util::Rng::new(3);
        for v in 0..f.grid.num_vertices() {
            *f.grid.density_mut(v) = if r.f32() < 0.02 { 5.0 } else { -20.0 };
        }
        let (delta, thresh) = (1.0, 0.01);
        let raw_min = f.raw_for_alpha(thresh, delta);
        let dense = |f: &Field, x, y, z| match f.grid.vertex_slot(x, y, z) {
            NONE => false,
            v => f.grid.density(v as usize) >= raw_min,
        };
        let expected: Vec<[usize; 3]> = f
            .occupied_cell_list()
            .into_iter()
            .filter(|c| {
                (0..8).any(|i| dense(&f, c[0] + (i & 1), c[1] + ((i >> 1) & 1), c[2] + (i >> 2)))
            })
            .collect();
        f.prune_occupancy(delta, thresh);
        assert_eq!(f.occupied_cell_list(), expected);
        assert!(!expected.is_empty() && expected.len() < f.num_cells() / 2);
        let need = Field::needed_bricks(f.grid.dims, &expected);
        let before = f.clone();
        f.release_free_bricks();
        let bd = f.grid.brick_dims;
        for (i, &n) in need.iter().enumerate() {
            let b = [i % bd[0], (i / bd[0]) % bd[1], i / (bd[0] * bd[1])];
            assert_eq!(f.grid.slot(b).is_some(), n, "brick {b:?}");
        }
        assert!(f.grid.num_slots() < before.grid.num_slots());
        assert_eq!(f.occupied_cell_list(), expected);
        assert_live_bricks_follow_the_words(&f);
        // Emptied, then one cell occupied: its brick and block are live at once, and only they.
        f.fill_occupancy(false);
        assert_live_bricks_follow_the_words(&f);
        let brick = [5, 4, 3];
        let cell = brick.map(|v| v * BRICK);
        f.occupy(&[cell]);
        assert!(f.live.brick(brick) && f.live.block(brick) && f.occupied(cell));
        assert!(!f.live.brick([4, 4, 3]) && !f.live.block([0, 0, 0]));
        assert_live_bricks_follow_the_words(&f);
        // Every vertex an occupied cell reads is kept, with its value.
        for c in &expected {
            for i in 0..8 {
                let v = [c[0] + (i & 1), c[1] + ((i >> 1) & 1), c[2] + (i >> 2)];
                let (a, b) = (
                    f.grid.vertex_slot(v[0], v[1], v[2]),
                    before.grid.vertex_slot(v[0], v[1], v[2]),
                );
                assert_eq!(
                    f.grid.vertex_values(a as usize),
                    before.grid.vertex_values(b as usize)
                );
            }
        }
    }
}
