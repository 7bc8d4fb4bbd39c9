//! Sparse vertex grids: vertices are stored in bricks of [`BRICK`]^3, and only the bricks that
//! hold something are allocated, so memory follows the occupied surface rather than the box. An
//! unallocated vertex reads as the grid's `fill` value.
//!
//! A brick's values are its 64 densities (channel 0), then its vertices' other channels (colour
//! or features) vertex by vertex. The march reads the density of every sample and the colour of
//! few, so the densities of a cell's 8 corners lie in two 64-byte lines of memory (one per
//! z-layer of the brick) instead of eight runs of C values; the colour of a vertex is still one
//! contiguous run. [`density_index`] and [`colour_index`] say where a vertex's values lie in any
//! buffer laid out like `data` (gradients, optimiser moments).
//!
//! Positions are in grid units: vertex (i, j, k) sits at (i, j, k); the grid spans
//! [0, nx-1] x [0, ny-1] x [0, nz-1]. Bricks are indexed x-fastest; allocated bricks take slots
//! in (z, y, x) order, so a range of brick layers is a contiguous range of memory (the trainer
//! hands each thread such a slab). A vertex's *slot index* is `slot * BRICK^3 + local`, local
//! x-fastest inside its brick.

use crate::util::mem::prefetch;
use rayon::prelude::*;

/// Vertices per brick side.
pub const BRICK: usize = 4;
/// Vertices per brick.
pub const BRICK_VERTICES: usize = BRICK * BRICK * BRICK;
/// The slot index of a vertex whose brick is not allocated.
pub const NONE: u32 = u32::MAX;

#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Vertex counts per axis (each >= 2).
    pub dims: [usize; 3],
    /// Channels per vertex.
    pub channels: usize,
    /// Bricks per axis: ceil(dims / BRICK).
    pub brick_dims: [usize; 3],
    /// Per brick (x-fastest): its slot, or [`NONE`].
    index: Vec<u32>,
    /// Per slot: the brick's position in bricks, slots in (z, y, x) order.
    bricks: Vec<[u32; 3]>,
    /// Per slot, BRICK^3 values of channel 0 (vertices x-fastest), then BRICK^3 runs of the
    /// other `channels - 1` (see the module notes).
    pub data: Vec<f32>,
    /// What an unallocated vertex holds.
    fill: Vec<f32>,
}

/// The 8 vertices around a point and their trilinear weights.
#[derive(Clone, Copy, Debug)]
pub struct Corners {
    /// Slot indices of the vertices ([`NONE`] where unallocated), in the order
    /// (000, 100, 010, 110, 001, 101, 011, 111) of (dx, dy, dz).
    pub idx: [u32; 8],
    pub w: [f32; 8],
}

/// Offsets of the 8 corners from the 000 corner inside one brick.
const IN_BRICK: [u32; 8] = {
    let (x, y, z) = (1, BRICK as u32, (BRICK * BRICK) as u32);
    [0, x, y, x + y, z, x + z, y + z, x + y + z]
};

impl Grid {
    /// A dense grid: every brick allocated, every vertex `fill`.
    pub fn new(dims: [usize; 3], channels: usize, fill: &[f32]) -> Grid {
        Grid::with_bricks(dims, channels, fill, |_| true)
    }

    /// A grid with the bricks `keep` accepts (by brick position) allocated, every vertex `fill`.
    pub fn with_bricks(
        dims: [usize; 3],
        channels: usize,
        fill: &[f32],
        keep: impl Fn([usize; 3]) -> bool,
    ) -> Grid {
        assert!(dims.iter().all(|&d| d >= 2) && fill.len() == channels);
        let brick_dims = dims.map(|d| d.div_ceil(BRICK));
        let mut bricks = Vec::new();
        for z in 0..brick_dims[2] {
            for y in 0..brick_dims[1] {
                for x in 0..brick_dims[0] {
                    if keep([x, y, z]) {
                        bricks.push([x as u32, y as u32, z as u32]);
                    }
                }
            }
        }
        let data = brick_of(fill).repeat(bricks.len());
        Grid::from_parts(dims, channels, fill, bricks, data)
            .expect("bricks listed in (z, y, x) order inside the grid")
    }

    /// A grid from saved parts: the allocated bricks' positions (in (z, y, x) order) and their
    /// vertices' values (laid out as `data`). Errors say what does not fit.
    pub fn from_parts(
        dims: [usize; 3],
        channels: usize,
        fill: &[f32],
        bricks: Vec<[u32; 3]>,
        data: Vec<f32>,
    ) -> std::result::Result<Grid, String> {
        if dims.iter().any(|&d| d < 2) || fill.len() != channels {
            return Err(format!("bad grid dims {dims:?} or channels {channels}"));
        }
        let brick_dims = dims.map(|d| d.div_ceil(BRICK));
        let nbricks: usize = brick_dims.iter().product();
        let mut index = vec![NONE; nbricks];
        let key = |b: &[u32; 3]| (b[2], b[1], b[0]);
        for (s, b) in bricks.iter().enumerate() {
            if (0..3).any(|a| b[a] as usize >= brick_dims[a]) {
                return Err(format!(
                    "brick {b:?} lies outside the grid's {brick_dims:?} bricks"
                ));
            }
            if s > 0 && key(&bricks[s - 1]) >= key(b) {
                return Err("bricks are not in (z, y, x) order, or repeat".into());
            }
            index
                [b[0] as usize + brick_dims[0] * (b[1] as usize + brick_dims[1] * b[2] as usize)] =
                s as u32;
        }
        if data.len() != bricks.len() * BRICK_VERTICES * channels {
            return Err(format!(
                "{} values for {} bricks of {BRICK_VERTICES} vertices x {channels} channels",
                data.len(),
                bricks.len()
            ));
        }
        Ok(Grid {
            dims,
            channels,
            brick_dims,
            index,
            bricks,
            data,
            fill: fill.to_vec(),
        })
    }

    /// Per brick (x-fastest over `brick_dims`), its slot or [`NONE`].
    pub fn brick_index(&self) -> &[u32] {
        &self.index
    }

    /// What an unallocated vertex holds, channel by channel.
    pub fn fill(&self) -> &[f32] {
        &self.fill
    }

    /// The allocated bricks' positions, by slot.
    pub fn brick_list(&self) -> &[[u32; 3]] {
        &self.bricks
    }

    /// Allocated bricks.
    pub fn num_slots(&self) -> usize {
        self.bricks.len()
    }

    /// Allocated vertices (slots x BRICK^3): what memory and the optimiser see.
    pub fn num_vertices(&self) -> usize {
        self.bricks.len() * BRICK_VERTICES
    }

    /// Vertices of the whole box, allocated or not.
    pub fn box_vertices(&self) -> usize {
        self.dims.iter().product()
    }

    /// The brick position of slot `s`.
    pub fn brick_of_slot(&self, s: usize) -> [usize; 3] {
        self.bricks[s].map(|v| v as usize)
    }

    /// The slot of the brick at brick position `b`, if allocated.
    #[inline]
    pub fn slot(&self, b: [usize; 3]) -> Option<usize> {
        let bd = self.brick_dims;
        let s = self.index[b[0] + bd[0] * (b[1] + bd[1] * b[2])];
        (s != NONE).then_some(s as usize)
    }

    /// The slot index of vertex (x, y, z), or [`NONE`].
    #[inline]
    pub fn vertex_slot(&self, x: usize, y: usize, z: usize) -> u32 {
        match self.slot([x / BRICK, y / BRICK, z / BRICK]) {
            Some(s) => (s * BRICK_VERTICES + local(x, y, z)) as u32,
            None => NONE,
        }
    }

    /// The cell whose base vertex has linear index `base` (x fastest over the vertex grid, as
    /// [`crate::field::march::Sample::base`] records it).
    #[inline]
    pub fn cell_of_base(&self, base: usize) -> [usize; 3] {
        let d = self.dims;
        [base % d[0], (base / d[0]) % d[1], base / (d[0] * d[1])]
    }

    /// The grid position of a slot index.
    #[inline]
    pub fn vertex_coords(&self, v: u32) -> [usize; 3] {
        let (s, l) = (v as usize / BRICK_VERTICES, v as usize % BRICK_VERTICES);
        let b = self.bricks[s];
        [
            b[0] as usize * BRICK + l % BRICK,
            b[1] as usize * BRICK + (l / BRICK) % BRICK,
            b[2] as usize * BRICK + l / (BRICK * BRICK),
        ]
    }

    /// Channel `c` of vertex (x, y, z) (the fill value where unallocated).
    #[inline]
    pub fn get(&self, x: usize, y: usize, z: usize, c: usize) -> f32 {
        match self.vertex_slot(x, y, z) {
            NONE => self.fill[c],
            v => self.data[value_index(v as usize, c, self.channels)],
        }
    }

    /// The raw density (channel 0) of slot index `v` (which must be allocated).
    #[inline]
    pub fn density(&self, v: usize) -> f32 {
        self.data[density_index(v, self.channels)]
    }

    #[inline]
    pub fn density_mut(&mut self, v: usize) -> &mut f32 {
        &mut self.data[density_index(v, self.channels)]
    }

    /// The other channels (colour or features) of slot index `v`.
    #[inline]
    pub fn colour(&self, v: usize) -> &[f32] {
        let o = colour_index(v, self.channels);
        &self.data[o..o + self.channels - 1]
    }

    #[inline]
    pub fn colour_mut(&mut self, v: usize) -> &mut [f32] {
        let o = colour_index(v, self.channels);
        &mut self.data[o..o + self.channels - 1]
    }

    /// Every channel of slot index `v`, density first.
    pub fn vertex_values(&self, v: usize) -> Vec<f32> {
        let mut out = vec![self.density(v)];
        out.extend_from_slice(self.colour(v));
        out
    }

    /// The cell containing `p` (clamped into the grid) and the fractional position inside it.
    #[inline]
    pub fn locate(&self, p: [f32; 3]) -> ([usize; 3], [f32; 3]) {
        let mut base = [0usize; 3];
        let mut frac = [0f32; 3];
        for a in 0..3 {
            // q >= 0 after the clamp, so truncation is floor (and avoids a libm call).
            let q = p[a].clamp(0.0, self.dims[a] as f32 - 1.0);
            let b = (q as usize).min(self.dims[a] - 2);
            base[a] = b;
            frac[a] = q - b as f32;
        }
        (base, frac)
    }

    /// The 8 corners and weights of a cell base and fractional position.
    #[inline]
    pub fn corners_of(&self, base: [usize; 3], f: [f32; 3]) -> Corners {
        let (fx, fy, fz) = (f[0], f[1], f[2]);
        let (gx, gy, gz) = (1.0 - fx, 1.0 - fy, 1.0 - fz);
        let w = [
            gx * gy * gz,
            fx * gy * gz,
            gx * fy * gz,
            fx * fy * gz,
            gx * gy * fz,
            fx * gy * fz,
            gx * fy * fz,
            fx * fy * fz,
        ];
        let [x, y, z] = base;
        let inside = x % BRICK < BRICK - 1 && y % BRICK < BRICK - 1 && z % BRICK < BRICK - 1;
        if inside {
            // All 8 corners in one brick (27 of 64 cells): one look-up.
            let v0 = self.vertex_slot(x, y, z);
            if v0 != NONE {
                return Corners {
                    idx: IN_BRICK.map(|o| v0 + o),
                    w,
                };
            }
            return Corners { idx: [NONE; 8], w };
        }
        let mut idx = [NONE; 8];
        for (i, v) in idx.iter_mut().enumerate() {
            *v = self.vertex_slot(x + (i & 1), y + ((i >> 1) & 1), z + (i >> 2));
        }
        Corners { idx, w }
    }

    /// Ask the cache for what a sample in cell `b` will read (a hint, no effect on results):
    /// its corners' densities (the two z-layers of its brick) and the colour of its four
    /// x-adjacent corner pairs. The march calls it a sample ahead, so that the next sample's
    /// misses overlap this sample's work.
    #[inline]
    pub fn prefetch_cell(&self, b: [usize; 3]) {
        let v = self.vertex_slot(b[0], b[1], b[2]);
        if v == NONE {
            return;
        }
        let (v, ch) = (v as usize, self.channels);
        let d = density_index(v, ch);
        prefetch(&self.data, d);
        prefetch(&self.data, d + BRICK * BRICK);
        let c = colour_index(v, ch);
        let (y, z) = (BRICK * (ch - 1), BRICK * BRICK * (ch - 1));
        for o in [0, y, z, y + z] {
            prefetch(&self.data, c + o);
        }
    }

    #[inline]
    pub fn corners(&self, p: [f32; 3]) -> Corners {
        let (b, f) = self.locate(p);
        self.corners_of(b, f)
    }

    /// The 8 corners' raw densities (the fill's where unallocated).
    #[inline]
    fn corner_densities(&self, k: &Corners) -> [f32; 8] {
        let ch = self.channels;
        k.idx.map(|v| match v {
            NONE => self.fill[0],
            v => self.data[density_index(v as usize, ch)],
        })
    }

    /// Interpolate the raw density (channel 0).
    #[inline]
    pub fn interp_density(&self, k: &Corners) -> f32 {
        let d = self.corner_densities(k);
        (0..8).map(|i| k.w[i] * d[i]).sum()
    }

    /// The gradient of the raw density's trilinear interpolation at fraction `f` of the cell
    /// whose corners are `k`, per voxel of this grid.
    #[inline]
    pub fn density_gradient(&self, k: &Corners, f: [f32; 3]) -> [f32; 3] {
        let v = self.corner_densities(k);
        let g = f.map(|x| 1.0 - x);
        // Corner i is (i & 1, i >> 1 & 1, i >> 2): each axis's gradient is the bilinear
        // interpolation, over the other two axes, of the differences along it.
        let weight = |i: usize, axis: usize| {
            if (i >> axis) & 1 == 1 {
                f[axis]
            } else {
                g[axis]
            }
        };
        let along = |a: usize| {
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            let stride = 1 << a;
            (0..8)
                .filter(|i| i & stride == 0)
                .map(|i| weight(i, b) * weight(i, c) * (v[i + stride] - v[i]))
                .sum()
        };
        [along(0), along(1), along(2)]
    }

    /// Interpolate the first `out.len()` colour channels (channels 1..) into `out`.
    #[inline]
    pub fn interp_colour(&self, k: &Corners, out: &mut [f32]) {
        let ch = self.channels;
        let n = out.len();
        out.iter_mut().for_each(|o| *o = 0.0);
        for i in 0..8 {
            let w = k.w[i];
            let src = match k.idx[i] {
                NONE => &self.fill[1..1 + n],
                v => {
                    let base = colour_index(v as usize, ch);
                    &self.data[base..base + n]
                }
            };
            for (o, s) in out.iter_mut().zip(src) {
                *o += w * s;
            }
        }
    }

    /// Interpolate every channel at `p` (density first).
    pub fn sample(&self, p: [f32; 3], out: &mut [f32]) {
        let k = self.corners(p);
        out[0] = self.interp_density(&k);
        self.interp_colour(&k, &mut out[1..]);
    }

    /// Backward of interpolating every channel: add `w_i * g` to each allocated corner's
    /// channels in `grad` (a buffer laid out like `data`; `g` density first).
    #[inline]
    pub fn scatter(grad: &mut [f32], channels: usize, k: &Corners, g: &[f32]) {
        for i in 0..8 {
            if k.idx[i] == NONE {
                continue;
            }
            let (w, v) = (k.w[i], k.idx[i] as usize);
            grad[density_index(v, channels)] += w * g[0];
            let base = colour_index(v, channels);
            for (d, s) in grad[base..base + channels - 1].iter_mut().zip(&g[1..]) {
                *d += w * s;
            }
        }
    }

    /// This grid resampled to `dims` over the same extent (trilinear), with the bricks `keep`
    /// accepts allocated, for coarse-to-fine growth.
    pub fn resampled(&self, dims: [usize; 3], keep: impl Fn([usize; 3]) -> bool) -> Grid {
        let ch = self.channels;
        let mut out = Grid::with_bricks(dims, ch, &self.fill, keep);
        let scale: Vec<f32> = (0..3)
            .map(|a| (self.dims[a] - 1) as f32 / (dims[a] - 1) as f32)
            .collect();
        let bricks = out.bricks.clone();
        out.data
            .par_chunks_mut(BRICK_VERTICES * ch)
            .zip(bricks.par_iter())
            .for_each(|(brick, b)| {
                let mut v = vec![0f32; ch];
                for l in 0..BRICK_VERTICES {
                    let p = [
                        (b[0] as usize * BRICK + l % BRICK) as f32 * scale[0],
                        (b[1] as usize * BRICK + (l / BRICK) % BRICK) as f32 * scale[1],
                        (b[2] as usize * BRICK + l / (BRICK * BRICK)) as f32 * scale[2],
                    ];
                    self.sample(p, &mut v);
                    put_vertex(brick, l, &v);
                }
            });
        out
    }

    /// Keep only the slots `keep` accepts (their values move down, order kept). Returns, per old
    /// slot, its new slot or [`NONE`], so that state laid out like `data` can follow.
    pub fn compact(&mut self, keep: &[bool]) -> Vec<u32> {
        let ch = self.channels;
        let per = BRICK_VERTICES * ch;
        let mut map = vec![NONE; self.bricks.len()];
        let mut next = 0usize;
        for (s, &k) in keep.iter().enumerate() {
            let b = self.bricks[s];
            let bi = b[0] as usize
                + self.brick_dims[0] * (b[1] as usize + self.brick_dims[1] * b[2] as usize);
            if k {
                if next != s {
                    self.data.copy_within(s * per..(s + 1) * per, next * per);
                    self.bricks[next] = b;
                }
                self.index[bi] = next as u32;
                map[s] = next as u32;
                next += 1;
            } else {
                self.index[bi] = NONE;
            }
        }
        self.bricks.truncate(next);
        self.data.truncate(next * per);
        map
    }

    /// The first slot of each brick layer (z), and one past the last: slots of layers
    /// `z0..z1` are `starts[z0]..starts[z1]`.
    pub fn layer_starts(&self) -> Vec<usize> {
        let mut starts = vec![0usize; self.brick_dims[2] + 1];
        for b in &self.bricks {
            starts[b[2] as usize + 1] += 1;
        }
        for z in 0..self.brick_dims[2] {
            starts[z + 1] += starts[z];
        }
        starts
    }
}

/// A vertex's index inside its brick.
#[inline]
fn local(x: usize, y: usize, z: usize) -> usize {
    x % BRICK + BRICK * (y % BRICK + BRICK * (z % BRICK))
}

/// Where slot index `v`'s raw density lies in a buffer laid out like [`Grid::data`] with
/// `channels` values a vertex (or in a slice of it that starts at a brick).
#[inline(always)]
pub fn density_index(v: usize, channels: usize) -> usize {
    (v / BRICK_VERTICES) * BRICK_VERTICES * channels + v % BRICK_VERTICES
}

/// Where slot index `v`'s other channels begin (`channels - 1` values in a row), as
/// [`density_index`].
#[inline(always)]
pub fn colour_index(v: usize, channels: usize) -> usize {
    let (s, l) = (v / BRICK_VERTICES, v % BRICK_VERTICES);
    s * BRICK_VERTICES * channels + BRICK_VERTICES + l * (channels - 1)
}

/// Where channel `c` of slot index `v` lies, as [`density_index`].
#[inline]
pub fn value_index(v: usize, c: usize, channels: usize) -> usize {
    match c {
        0 => density_index(v, channels),
        c => colour_index(v, channels) + c - 1,
    }
}

/// Write every channel of slot index `v` (`values`, density first) into a buffer laid out like
/// [`Grid::data`] (or a slice of it that starts at a brick).
#[inline]
pub fn put_vertex(buf: &mut [f32], v: usize, values: &[f32]) {
    let ch = values.len();
    buf[density_index(v, ch)] = values[0];
    let o = colour_index(v, ch);
    buf[o..o + ch - 1].copy_from_slice(&values[1..]);
}

/// One brick's values with every vertex holding `fill`, laid out as [`Grid::data`].
fn brick_of(fill: &[f32]) -> Vec<f32> {
    let mut out = vec![fill[0]; BRICK_VERTICES];
    out.extend(fill[1..].repeat(BRICK_VERTICES));
    out
}

/// Rewrite bricks of values stored vertex by vertex (every channel of a vertex together, the
/// layout of model files before version 5) into [`Grid::data`]'s layout, in place.
pub fn from_interleaved(buf: &mut [f32], channels: usize) {
    let mut scratch = vec![0f32; BRICK_VERTICES * channels];
    for brick in buf.chunks_exact_mut(BRICK_VERTICES * channels) {
        for (l, v) in brick.chunks_exact(channels).enumerate() {
            put_vertex(&mut scratch, l, v);
        }
        brick.copy_from_slice(&scratch);
    }
}

/// Apply a slot map from [`Grid::compact`] to a buffer laid out like the grid's data (`per`
/// values per slot): kept slots move down, the rest are dropped.
pub fn compact_buffer<T: Copy>(buf: &mut Vec<T>, map: &[u32], per: usize) {
    for (s, &to) in map.iter().enumerate() {
        if to != NONE && to as usize != s {
            buf.copy_within(s * per..(s + 1) * per, to as usize * per);
        }
    }
    let kept = map.iter().filter(|&&m| m != NONE).count();
    buf.truncate(kept * per);
}

#[cfg(test)]
mod tests;
