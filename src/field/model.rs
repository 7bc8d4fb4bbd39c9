//! The object field: one vertex grid holding, per vertex, a raw density and spherical-harmonic
//! colour coefficients (Plenoxels-style colour, DVGO-style density), inside an axis-aligned box,
//! plus an occupancy bitmap over cells for empty-space skipping.
//!
//! Density is "post-activated" as in DVGO: the raw value is interpolated first, then
//! alpha = 1 - exp(-softplus(raw + shift) * delta), which gives sharp surfaces from a coarse grid.
//! `delta` is the sample spacing measured in units of the finest voxel, so a raw value keeps its
//! meaning when the grid is refined.

use super::activation::sigmoid;
use super::colour_net::{reflect, ColourNet, MAX_HIDDEN};
use super::grid::{Corners, Grid, BRICK, BRICK_VERTICES, NONE};
use super::live::LiveBricks;
use super::sh::{sh_basis, sh_coeffs, SH_TERMS};
use crate::space::Space;
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
    /// Sparse: only bricks around occupied cells are allocated.
    pub grid: Grid,
    /// Per grid slot, one bit per cell whose base vertex lies in that brick (x-fastest, as the
    /// brick's vertices): the cell may hold density. A cell's 8 corners are always allocated
    /// when it is occupied; rays skip bricks whose word is 0.
    /// Private to the field's modules, which keep [`Field::live`] with it.
    pub(super) occupancy: Vec<u64>,
    /// The bricks that hold an occupied cell, for the marcher (kept with `occupancy`).
    pub(super) live: LiveBricks,
    /// Colour from features through a network ([`ColourNet`]) instead of SH coefficients: the
    /// channels are then [raw density, features].
    pub net: Option<ColourNet>,
}

/// The most channels a vertex holds (density and colour): the size of the renderer's
/// per-sample buffers (SH degree 2: 28; a colour network's features are bounded by it too).
pub const MAX_CHANNELS: usize = 28;

/// Raw density that makes one finest voxel this opaque where a sparse point was seen.
const SEED_ALPHA: f32 = 0.3;

/// What every sample of a ray shares for its colour ([`Field::shading`]): the SH basis of its
/// direction and, with a colour network, the hidden units' pre-activation from that direction
/// ([`ColourNet::ray_bias`]), so a sample pays only for its features.
#[derive(Clone, Copy, Debug)]
pub struct RayShading {
    pub basis: [f32; SH_TERMS],
    pub bias: [f32; MAX_HIDDEN],
}

impl Field {
    /// A fresh field over a box: density 0 (alpha = alpha_init per finest voxel), grey colour,
    /// every cell occupied (every brick allocated).
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
            occupancy: Vec::new(),
            live: LiveBricks::default(),
            grid,
            net: None,
        };
        f.fill_occupancy(true);
        f
    }

    /// The same box and dims with colour from `features` grid channels through a network of
    /// `hidden` units in its first hidden layer and in its second (0: none); its direction
    /// input is the SH basis to the config's degree, and with `reflect` the basis of the
    /// reflected view direction too ([`Field::reflection_basis`]). Every vertex starts at
    /// density 0 and zero features.
    pub fn with_colour_net(
        mut self,
        features: usize,
        hidden: [usize; 2],
        reflect: bool,
        seed: u64,
    ) -> Field {
        let ch = 1 + features;
        self.grid = Grid::new(self.grid.dims, ch, &vec![0.0; ch]);
        self.fill_occupancy(true);
        let (k, refl) = (self.sh_k(), if reflect { self.sh_k() } else { 0 });
        self.net = Some(ColourNet::new(features, k, refl, hidden, seed));
        self
    }

    /// The SH basis of the unit direction `d` reflected about the density's normal at fraction
    /// `fr` of the cell with corners `k`, for a colour network that takes it; zeros otherwise.
    #[inline]
    pub fn reflection_basis(&self, k: &Corners, fr: [f32; 3], d: Vec3) -> [f32; SH_TERMS] {
        let mut basis = [0f32; SH_TERMS];
        if self.net.as_ref().is_some_and(|n| n.refl_terms > 0) {
            let g = Vec3::from(self.grid.density_gradient(k, fr));
            sh_basis(self.config.sh_degree, reflect(d, g), &mut basis);
        }
        basis
    }

    /// What the samples of a ray seen along the SH basis `basis` share for their colour.
    pub fn shading(&self, basis: [f32; SH_TERMS]) -> RayShading {
        let mut bias = [0f32; MAX_HIDDEN];
        if let Some(net) = &self.net {
            net.ray_bias(&basis[..net.dir_terms], &mut bias);
        }
        RayShading { basis, bias }
    }

    /// Colour of a sample from its interpolated colour channels `feat` (SH coefficients or
    /// features) and [`Field::reflection_basis`] `refl` on a ray shaded by `s`; `h` is scratch
    /// for the network's hidden units.
    #[inline]
    pub fn shade(&self, feat: &[f32], refl: &[f32], s: &RayShading, h: &mut [f32]) -> [f32; 3] {
        let k = self.sh_k();
        match &self.net {
            Some(net) => net.forward_features(&feat[..net.features], refl, &s.bias, h),
            None => [0, 1, 2].map(|c| {
                let coef = &feat[c * k..(c + 1) * k];
                sigmoid(coef.iter().zip(&s.basis[..k]).map(|(a, b)| a * b).sum())
            }),
        }
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

    /// The raw density at which a sample `delta` finest voxels long is `alpha` opaque: the
    /// inverse of alpha = 1 - exp(-softplus(raw + shift) delta).
    pub fn raw_for_alpha(&self, alpha: f32, delta: f32) -> f32 {
        let sp = -(1.0 - alpha).ln() / delta;
        // softplus^-1(sp) = ln(exp(sp) - 1), which is sp to float precision past 15.
        let raw = if sp > 15.0 { sp } else { sp.exp_m1().ln() };
        raw - self.shift()
    }

    /// Cells of the whole box.
    pub fn num_cells(&self) -> usize {
        let d = self.grid.dims;
        (d[0] - 1) * (d[1] - 1) * (d[2] - 1)
    }

    /// The word and bit of cell `b` (its base vertex), if its brick is allocated.
    #[inline]
    fn cell_bit(&self, b: [usize; 3]) -> Option<(usize, u32)> {
        let s = self.grid.slot(b.map(|v| v / BRICK))?;
        let l = b[0] % BRICK + BRICK * (b[1] % BRICK + BRICK * (b[2] % BRICK));
        Some((s, l as u32))
    }

    /// Whether cell `b` (its base vertex) may hold density.
    #[inline]
    pub fn occupied(&self, b: [usize; 3]) -> bool {
        self.cell_bit(b)
            .is_some_and(|(s, l)| self.occupancy[s] >> l & 1 == 1)
    }

    /// Whether any cell of the brick holding cell `b` may hold density (rays skip it if not).
    #[inline]
    pub fn brick_occupied(&self, b: [usize; 3]) -> bool {
        self.live.brick(b.map(|v| v / BRICK))
    }

    /// Set every cell of the box free or occupied (occupied needs every brick allocated).
    pub fn fill_occupancy(&mut self, on: bool) {
        self.occupancy = vec![0; self.grid.num_slots()];
        if on {
            let d = self.grid.dims;
            for s in 0..self.grid.num_slots() {
                let b = self.grid.brick_of_slot(s);
                let mut word = 0u64;
                for l in 0..BRICK_VERTICES {
                    let c = [
                        b[0] * BRICK + l % BRICK,
                        b[1] * BRICK + (l / BRICK) % BRICK,
                        b[2] * BRICK + l / (BRICK * BRICK),
                    ];
                    if c[0] + 1 < d[0] && c[1] + 1 < d[1] && c[2] + 1 < d[2] {
                        word |= 1 << l;
                    }
                }
                self.occupancy[s] = word;
            }
        }
        self.refresh_live_bricks();
    }

    /// Mark cell `b` occupied or free. Its corners' bricks must be allocated to occupy it.
    pub fn set_occupied(&mut self, b: [usize; 3], on: bool) {
        let Some((s, l)) = self.cell_bit(b) else {
            debug_assert!(!on, "cell {b:?} occupied without its brick");
            return;
        };
        if on {
            self.occupancy[s] |= 1 << l;
            self.mark_live(b);
        } else {
            self.occupancy[s] &= !(1 << l);
        }
    }

    /// The bricks that hold an occupied cell (what the marcher skips by).
    pub fn live_bricks(&self) -> &LiveBricks {
        &self.live
    }

    /// The occupancy words, one a grid slot (see the field's doc).
    pub fn occupancy_words(&self) -> &[u64] {
        &self.occupancy
    }

    pub fn occupied_cells(&self) -> usize {
        self.occupancy.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// Every occupied cell, by its base vertex.
    pub fn occupied_cell_list(&self) -> Vec<[usize; 3]> {
        let mut out = Vec::with_capacity(self.occupied_cells());
        for (s, &word) in self.occupancy.iter().enumerate() {
            let b = self.grid.brick_of_slot(s);
            let mut w = word;
            while w != 0 {
                let l = w.trailing_zeros() as usize;
                w &= w - 1;
                out.push([
                    b[0] * BRICK + l % BRICK,
                    b[1] * BRICK + (l / BRICK) % BRICK,
                    b[2] * BRICK + l / (BRICK * BRICK),
                ]);
            }
        }
        out
    }

    /// The bricks the occupied cells `cells` need: those of every cell's 8 corners.
    pub(super) fn needed_bricks(grid_dims: [usize; 3], cells: &[[usize; 3]]) -> Vec<bool> {
        let bd = grid_dims.map(|d| d.div_ceil(BRICK));
        let mut need = vec![false; bd.iter().product()];
        for &c in cells {
            mark_corner_bricks(&mut need, bd, c);
        }
        need
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

    /// The voxel of a grid of `dims` over this field's box (the longest axis fixes it).
    pub fn voxel_for(&self, dims: [usize; 3]) -> f32 {
        (self.box_max - self.box_min).max_element() / (dims.iter().max().unwrap() - 1) as f32
    }

    /// The occupied cells of a grid of `dims` over this box: each new cell takes the occupancy
    /// of the old cell holding its centre. Work follows the occupied cells, not the box: per
    /// axis, the new cells whose centres fall in each old cell form a range.
    pub fn for_each_cell_at(&self, dims: [usize; 3], mut visit: impl FnMut([usize; 3])) {
        let voxel = self.voxel_for(dims);
        let old = self.grid.dims;
        let ranges: Vec<Vec<(usize, usize)>> = (0..3)
            .map(|a| {
                let mut r = vec![(usize::MAX, 0usize); old[a] - 1];
                for x in 0..dims[a] - 1 {
                    // As the grid's `locate`, one axis at a time.
                    let centre = self.box_min[a] + (x as f32 + 0.5) * voxel;
                    let g = (centre - self.box_min[a]) / self.voxel;
                    let i = (g.clamp(0.0, old[a] as f32 - 1.0) as usize).min(old[a] - 2);
                    r[i] = (r[i].0.min(x), r[i].1.max(x));
                }
                r
            })
            .collect();
        for c in self.occupied_cell_list() {
            let (rx, ry, rz) = (ranges[0][c[0]], ranges[1][c[1]], ranges[2][c[2]]);
            if rx.0 > rx.1 || ry.0 > ry.1 || rz.0 > rz.1 {
                continue;
            }
            for z in rz.0..=rz.1 {
                for y in ry.0..=ry.1 {
                    for x in rx.0..=rx.1 {
                        visit([x, y, z]);
                    }
                }
            }
        }
    }

    /// Bricks a grid of `dims` over this box would allocate for the occupied cells.
    pub fn bricks_at(&self, dims: [usize; 3]) -> usize {
        let mut need = vec![false; dims.map(|d| d.div_ceil(BRICK)).iter().product()];
        let bd = dims.map(|d| d.div_ceil(BRICK));
        self.for_each_cell_at(dims, |c| mark_corner_bricks(&mut need, bd, c));
        need.iter().filter(|&&n| n).count()
    }

    /// Grow the grid to `dims` (trilinear resampling); occupancy maps each new cell to the old
    /// cell holding its centre, so carved space stays carved; only the bricks the occupied cells
    /// need are allocated.
    pub fn upsample(&mut self, dims: [usize; 3]) {
        let mut cells = Vec::new();
        self.for_each_cell_at(dims, |c| cells.push(c));
        let need = Field::needed_bricks(dims, &cells);
        let bd = dims.map(|d| d.div_ceil(BRICK));
        self.grid = self
            .grid
            .resampled(dims, |b| need[b[0] + bd[0] * (b[1] + bd[1] * b[2])]);
        self.voxel = self.voxel_for(dims);
        // The box is re-derived from the dims so that vertices still span it exactly.
        self.box_max = self.box_min
            + Vec3::new(
                (dims[0] - 1) as f32,
                (dims[1] - 1) as f32,
                (dims[2] - 1) as f32,
            ) * self.voxel;
        self.fill_occupancy(false);
        for c in cells {
            self.set_occupied(c, true);
        }
    }

    /// Start surfaces at points (a scene field's sparse points; a removal's fill targets): the
    /// corners of every cell holding a point get a density (one voxel [`SEED_ALPHA`] opaque) and
    /// the point's colour as their view-independent colour, so the first rays already stop near
    /// the right depth with about the right colour (from a transparent start, training takes
    /// most of its time finding the surfaces).
    pub fn seed_surfaces(&mut self, seeds: &[(Vec3, [u8; 3])]) {
        let raw = self.raw_for_alpha(SEED_ALPHA, 1.0);
        let k = self.sh_k();
        // sigmoid(C0 * dc) = colour
        const C0: f32 = 0.282_094_8;
        for (p, rgb) in seeds {
            let g = self.to_grid(*p);
            let d = self.grid.dims;
            if (0..3).any(|a| g[a] < 0.0 || g[a] >= (d[a] - 1) as f32) {
                continue;
            }
            let (b, _) = self.grid.locate([g.x, g.y, g.z]);
            for i in 0..8 {
                let v =
                    self.grid
                        .vertex_slot(b[0] + (i & 1), b[1] + ((i >> 1) & 1), b[2] + (i >> 2));
                if v == NONE {
                    continue;
                }
                let density = self.grid.density_mut(v as usize);
                *density = density.max(raw);
                // A colour network's features have no colour of their own to set.
                if self.net.is_some() {
                    continue;
                }
                let colour = self.grid.colour_mut(v as usize);
                for c in 0..3 {
                    let x = (rgb[c] as f32 / 255.0).clamp(0.02, 0.98);
                    colour[c * k] = (x / (1.0 - x)).ln() / C0;
                }
            }
        }
    }

    /// Occupy `cells` (base vertices; those outside the grid are skipped), allocating the bricks
    /// they need: a released brick comes back as a new one (density at alpha_init, grey), the
    /// values already held stay. Returns the cells that were free before, in `cells`' order.
    /// The grid's slots are laid out anew when bricks were added: state laid out like the data
    /// must be reset.
    pub fn occupy(&mut self, cells: &[[usize; 3]]) -> Vec<[usize; 3]> {
        let d = self.grid.dims;
        let new: Vec<[usize; 3]> = cells
            .iter()
            .copied()
            .filter(|c| (0..3).all(|a| c[a] + 1 < d[a]) && !self.occupied(*c))
            .collect();
        if new.is_empty() {
            return new;
        }
        let mut all = self.occupied_cell_list();
        all.extend_from_slice(&new);
        let need = Field::needed_bricks(d, &all);
        let bd = self.grid.brick_dims;
        let brick = |i: usize| [i % bd[0], (i / bd[0]) % bd[1], i / (bd[0] * bd[1])];
        let held = |i: usize| self.grid.slot(brick(i)).is_some();
        if (0..need.len()).any(|i| need[i] && !held(i)) {
            // Same dims: every kept vertex is resampled at its own position, value for value.
            let kept: Vec<bool> = (0..need.len()).map(|i| need[i] || held(i)).collect();
            self.grid = self
                .grid
                .resampled(d, |b| kept[b[0] + bd[0] * (b[1] + bd[1] * b[2])]);
            self.fill_occupancy(false);
        }
        for c in all {
            self.set_occupied(c, true);
        }
        new
    }

    /// Bytes held by the parameters (not counting optimiser state).
    pub fn param_bytes(&self) -> usize {
        self.grid.data.len() * 4 + self.occupancy.len() * 8
    }
}

/// Mark the bricks holding the 8 corners of cell `c` in a brick map of `bd` bricks.
#[inline]
fn mark_corner_bricks(need: &mut [bool], bd: [usize; 3], c: [usize; 3]) {
    for dz in 0..2 {
        for dy in 0..2 {
            for dx in 0..2 {
                let b = [
                    (c[0] + dx) / BRICK,
                    (c[1] + dy) / BRICK,
                    (c[2] + dz) / BRICK,
                ];
                need[b[0] + bd[0] * (b[1] + bd[1] * b[2])] = true;
            }
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::field::activation::softplus;

    /// A field over the unit cube, alpha_init 0.01.
    pub(in crate::field) fn unit_cube_field(sh_degree: u32, dims: [usize; 3]) -> Field {
        let config = FieldConfig {
            sh_degree,
            alpha_init: 0.01,
            base_voxel: 0.1,
        };
        Field::new(config, Vec3::ZERO, Vec3::ONE, dims)
    }

    #[test]
    fn shift_gives_alpha_init() {
        let f = unit_cube_field(1, [5, 5, 5]);
        let a = 1.0 - (-softplus(f.shift())).exp();
        assert!((a - 0.01).abs() < 1e-5);
        assert_eq!(f.grid.channels, 13);
        assert_eq!(f.occupied_cells(), 64);
    }

    /// The basis is orthonormal over the sphere to degree 3 (a wrong constant or sign in a
    /// term shows as a wrong norm or a cross term): a Monte Carlo integral over 200 000
    /// random directions.
    #[test]
    fn sh_basis_is_orthonormal() {
        let mut r = crate::util::Rng::new(3);
        let n = 200_000;
        let mut gram = [[0f64; SH_TERMS]; SH_TERMS];
        let mut b = [0f32; SH_TERMS];
        for _ in 0..n {
            let d = loop {
                let v = Vec3::new(r.f32(), r.f32(), r.f32()) * 2.0 - Vec3::ONE;
                if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                    break v.normalize();
                }
            };
            sh_basis(3, d, &mut b);
            for i in 0..SH_TERMS {
                for j in 0..SH_TERMS {
                    gram[i][j] += (b[i] * b[j]) as f64;
                }
            }
        }
        let area = 4.0 * std::f64::consts::PI / n as f64;
        for (i, row) in gram.iter().enumerate() {
            for (j, &g) in row.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!(
                    (g * area - want).abs() < 0.03,
                    "terms {i} and {j}: {:.3} (want {want})",
                    g * area
                );
            }
        }
    }

    #[test]
    fn upsampling_keeps_occupancy_and_extent() {
        let mut f = unit_cube_field(0, [5, 5, 5]);
        f.fill_occupancy(false);
        f.set_occupied([0, 0, 0], true);
        f.upsample([9, 9, 9]);
        assert_eq!(f.occupied_cells(), 8);
        // Only the bricks those 8 cells touch: the 2x2x2 cells' corners reach vertex 2 of each
        // axis, inside brick 0.
        assert_eq!(f.grid.num_slots(), 1);
        assert!((f.box_max - Vec3::ONE).abs().max_element() < 1e-6);
    }

    #[test]
    fn occupying_released_cells_brings_their_bricks_back_and_keeps_every_value() {
        let mut f = unit_cube_field(0, [13, 13, 13]);
        for (i, x) in f.grid.data.iter_mut().enumerate() {
            *x = (i as f32 * 0.37).sin();
        }
        f.fill_occupancy(false);
        f.set_occupied([1, 1, 1], true);
        f.release_free_bricks();
        assert_eq!(f.grid.num_slots(), 1);
        let kept = f.grid.vertex_values(f.grid.vertex_slot(2, 2, 2) as usize);
        // [9, 9, 9] lies in brick (2, 2, 2), released; [1, 1, 1] is occupied already; [12, ...]
        // is past the last cell.
        let opened = f.occupy(&[[1, 1, 1], [9, 9, 9], [12, 0, 0]]);
        assert_eq!(opened, vec![[9, 9, 9]]);
        assert!(f.occupied([1, 1, 1]) && f.occupied([9, 9, 9]));
        assert_eq!(f.occupied_cells(), 2);
        assert_eq!(
            f.grid.vertex_values(f.grid.vertex_slot(2, 2, 2) as usize),
            kept
        );
        // The brought-back brick holds a new cell's values (density 0: alpha_init, grey).
        let v = f.grid.vertex_slot(10, 10, 10);
        assert_ne!(v, NONE);
        assert!(f.grid.vertex_values(v as usize).iter().all(|&x| x == 0.0));
        assert!(f.occupy(&[[9, 9, 9]]).is_empty());
    }
}
