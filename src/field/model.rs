//! The object field: one vertex grid holding, per vertex, a raw density and spherical-harmonic
//! colour coefficients (Plenoxels-style colour, DVGO-style density), inside an axis-aligned box,
//! plus an occupancy bitmap over cells for empty-space skipping.
//!
//! Density is "post-activated" as in DVGO: the raw value is interpolated first, then
//! alpha = 1 - exp(-softplus(raw + shift) * delta), which gives sharp surfaces from a coarse grid.
//! `delta` is the sample spacing measured in units of the finest voxel, so a raw value keeps its
//! meaning when the grid is refined.

use super::grid::Grid;
use super::space::Space;
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Settings that fix the model's layout and activations (saved with it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FieldConfig {
    /// Spherical-harmonic degree of the colour (0..=2).
    pub sh_degree: u32,
    /// Alpha of one finest voxel at raw density 0 (DVGO's alpha_init).
    pub alpha_init: f32,
    /// World length of one voxel of the final (finest) grid: densities are per this length.
    pub base_voxel: f32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    pub config: FieldConfig,
    /// Where the grid lives: the box, voxel and densities are in this space's coordinates (the
    /// world itself for an object's [`Space::Box`]).
    pub space: Space,
    /// Box corners in space coordinates; grid vertex (0,0,0) sits at `box_min`.
    pub box_min: Vec3,
    pub box_max: Vec3,
    /// Length of one voxel of the current grid in space coordinates (cubic voxels).
    pub voxel: f32,
    /// Channels: [raw density, SH red (K), SH green (K), SH blue (K)], K = (degree + 1)^2.
    pub grid: Grid,
    /// One bit per cell (cells are (nx-1)(ny-1)(nz-1), x-fastest): may hold density.
    pub occupancy: Vec<u64>,
    /// Per block of BLOCK^3 cells: does any cell in it hold density? Lets a ray jump over empty
    /// blocks instead of testing every sample position. Derived from `occupancy` by
    /// [`Field::rebuild_blocks`].
    pub blocks: Vec<bool>,
    pub block_dims: [usize; 3],
}

/// Cells per side of an empty-space-skipping block.
pub const BLOCK: usize = 8;

pub fn sh_coeffs(degree: u32) -> usize {
    ((degree + 1) * (degree + 1)) as usize
}

/// Real spherical-harmonic basis (the constants of Plenoxels/PlenOctrees) for a unit direction.
#[inline]
pub fn sh_basis(degree: u32, d: Vec3, out: &mut [f32; 9]) {
    const C0: f32 = 0.282_094_8;
    const C1: f32 = 0.488_602_5;
    const C2: [f32; 5] = [
        1.092_548_4,
        -1.092_548_4,
        0.315_391_57,
        -1.092_548_4,
        0.546_274_2,
    ];
    out[0] = C0;
    if degree >= 1 {
        out[1] = -C1 * d.y;
        out[2] = C1 * d.z;
        out[3] = -C1 * d.x;
    }
    if degree >= 2 {
        let (x, y, z) = (d.x, d.y, d.z);
        out[4] = C2[0] * x * y;
        out[5] = C2[1] * y * z;
        out[6] = C2[2] * (2.0 * z * z - x * x - y * y);
        out[7] = C2[3] * x * z;
        out[8] = C2[4] * (x * x - y * y);
    }
}

#[inline]
pub fn softplus(x: f32) -> f32 {
    if x > 15.0 {
        x
    } else {
        x.exp().ln_1p()
    }
}

#[inline]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

impl Field {
    /// A fresh field over a box: density 0 (alpha = alpha_init per finest voxel), grey colour,
    /// every cell occupied.
    pub fn new(config: FieldConfig, box_min: Vec3, box_max: Vec3, dims: [usize; 3]) -> Field {
        let k = sh_coeffs(config.sh_degree);
        let fill = vec![0.0f32; 1 + 3 * k];
        let grid = Grid::new(dims, 1 + 3 * k, &fill);
        let voxel = (box_max - box_min).max_element() / (dims.iter().max().unwrap() - 1) as f32;
        let mut f = Field {
            config,
            space: Space::Box,
            box_min,
            box_max,
            voxel,
            grid,
            occupancy: Vec::new(),
            blocks: Vec::new(),
            block_dims: [0; 3],
        };
        f.fill_occupancy(true);
        f.rebuild_blocks();
        f
    }

    /// Grid dimensions (vertices) for a box and a voxel size: cubic voxels, at least 2 per axis.
    pub fn dims_for(box_min: Vec3, box_max: Vec3, voxel: f32) -> [usize; 3] {
        let e = box_max - box_min;
        [e.x, e.y, e.z].map(|l| ((l / voxel).ceil() as usize + 1).max(2))
    }

    pub fn sh_k(&self) -> usize {
        sh_coeffs(self.config.sh_degree)
    }

    /// Raw-density offset so that raw 0 gives alpha_init over one finest voxel (DVGO's act_shift).
    pub fn shift(&self) -> f32 {
        let a = self.config.alpha_init.clamp(1e-9, 0.999);
        (1.0 / (1.0 - a) - 1.0).ln()
    }

    pub fn num_cells(&self) -> usize {
        let d = self.grid.dims;
        (d[0] - 1) * (d[1] - 1) * (d[2] - 1)
    }

    #[inline]
    pub fn cell_index(&self, b: [usize; 3]) -> usize {
        let d = self.grid.dims;
        b[0] + (d[0] - 1) * (b[1] + (d[1] - 1) * b[2])
    }

    #[inline]
    pub fn occupied(&self, cell: usize) -> bool {
        self.occupancy[cell >> 6] >> (cell & 63) & 1 == 1
    }

    pub fn fill_occupancy(&mut self, on: bool) {
        let n = self.num_cells();
        self.occupancy = vec![if on { u64::MAX } else { 0 }; n.div_ceil(64)];
    }

    pub fn set_occupied(&mut self, cell: usize, on: bool) {
        if on {
            self.occupancy[cell >> 6] |= 1 << (cell & 63);
        } else {
            self.occupancy[cell >> 6] &= !(1 << (cell & 63));
        }
    }

    /// Recompute the block map from the cell occupancy (call after changing occupancy).
    pub fn rebuild_blocks(&mut self) {
        let d = self.grid.dims;
        let cd = [d[0] - 1, d[1] - 1, d[2] - 1];
        let bd = cd.map(|c| c.div_ceil(BLOCK));
        let mut blocks = vec![false; bd[0] * bd[1] * bd[2]];
        for z in 0..cd[2] {
            for y in 0..cd[1] {
                for x in 0..cd[0] {
                    if self.occupied(self.cell_index([x, y, z])) {
                        blocks[x / BLOCK + bd[0] * (y / BLOCK + bd[1] * (z / BLOCK))] = true;
                    }
                }
            }
        }
        self.blocks = blocks;
        self.block_dims = bd;
    }

    pub fn occupied_cells(&self) -> usize {
        let n = self.num_cells();
        (0..n).filter(|&c| self.occupied(c)).count()
    }

    /// Drop cells whose largest possible alpha (over a step of `delta` finest voxels) is below
    /// `thresh`. Post-activation is monotone in the raw density, so a cell's alpha never exceeds
    /// that of its densest corner: the bound is exact and skipping loses nothing above `thresh`.
    /// Cells already free stay free (the visual hull carved them).
    pub fn prune_occupancy(&mut self, delta: f32, thresh: f32) {
        let d = self.grid.dims;
        let ch = self.grid.channels;
        // raw density at which alpha reaches thresh
        let sp = -(1.0 - thresh).ln() / delta;
        let raw_min = if sp > 15.0 { sp } else { sp.exp_m1().ln() } - self.shift();
        let dense: Vec<bool> = self
            .grid
            .data
            .chunks_exact(ch)
            .map(|v| v[0] >= raw_min)
            .collect();
        for z in 0..d[2] - 1 {
            for y in 0..d[1] - 1 {
                for x in 0..d[0] - 1 {
                    let c = self.cell_index([x, y, z]);
                    if !self.occupied(c) {
                        continue;
                    }
                    let mut any = false;
                    'corners: for dz in 0..2 {
                        for dy in 0..2 {
                            for dx in 0..2 {
                                if dense[self.grid.vertex_index(x + dx, y + dy, z + dz)] {
                                    any = true;
                                    break 'corners;
                                }
                            }
                        }
                    }
                    if !any {
                        self.set_occupied(c, false);
                    }
                }
            }
        }
        self.rebuild_blocks();
    }

    /// World point to grid units (points a space cannot map, behind an NDC camera's near plane,
    /// land outside the grid).
    #[inline]
    pub fn to_grid(&self, p: Vec3) -> Vec3 {
        match self.space.map(p) {
            Some(q) => (q - self.box_min) / self.voxel,
            None => Vec3::splat(-1.0),
        }
    }

    /// The cell-centre position of a cell base, in space coordinates (the world for a box).
    pub fn cell_center(&self, b: [usize; 3]) -> Vec3 {
        self.box_min + (Vec3::new(b[0] as f32, b[1] as f32, b[2] as f32) + 0.5) * self.voxel
    }

    /// Grow the grid to `dims` (trilinear resampling); occupancy maps each new cell to the old
    /// cell holding its centre, so carved space stays carved.
    pub fn upsample(&mut self, dims: [usize; 3]) {
        let old = self.clone();
        self.grid = self.grid.resampled(dims);
        self.voxel =
            (self.box_max - self.box_min).max_element() / (dims.iter().max().unwrap() - 1) as f32;
        // The box is re-derived from the dims so that vertices still span it exactly.
        self.box_max = self.box_min
            + Vec3::new(
                (dims[0] - 1) as f32,
                (dims[1] - 1) as f32,
                (dims[2] - 1) as f32,
            ) * self.voxel;
        self.fill_occupancy(false);
        for z in 0..dims[2] - 1 {
            for y in 0..dims[1] - 1 {
                for x in 0..dims[0] - 1 {
                    let c = self.cell_center([x, y, z]);
                    let g = (c - old.box_min) / old.voxel;
                    let (b, _) = old.grid.locate([g.x, g.y, g.z]);
                    if old.occupied(old.cell_index(b)) {
                        let ci = self.cell_index([x, y, z]);
                        self.set_occupied(ci, true);
                    }
                }
            }
        }
        self.rebuild_blocks();
    }

    /// Bytes held by the parameters (not counting optimiser state).
    pub fn param_bytes(&self) -> usize {
        self.grid.data.len() * 4 + self.occupancy.len() * 8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_gives_alpha_init() {
        let f = Field::new(
            FieldConfig {
                sh_degree: 1,
                alpha_init: 0.01,
                base_voxel: 0.1,
            },
            Vec3::ZERO,
            Vec3::ONE,
            [5, 5, 5],
        );
        let a = 1.0 - (-softplus(f.shift())).exp();
        assert!((a - 0.01).abs() < 1e-5);
        assert_eq!(f.grid.channels, 13);
        assert_eq!(f.occupied_cells(), 64);
    }

    #[test]
    fn upsampling_keeps_occupancy_and_extent() {
        let mut f = Field::new(
            FieldConfig {
                sh_degree: 0,
                alpha_init: 0.01,
                base_voxel: 0.1,
            },
            Vec3::ZERO,
            Vec3::ONE,
            [5, 5, 5],
        );
        f.fill_occupancy(false);
        let c = f.cell_index([0, 0, 0]);
        f.set_occupied(c, true);
        f.upsample([9, 9, 9]);
        assert_eq!(f.occupied_cells(), 8);
        assert!((f.box_max - Vec3::ONE).abs().max_element() < 1e-6);
    }
}
