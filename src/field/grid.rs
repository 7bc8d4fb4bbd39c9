//! Dense vertex grids with all channels of a vertex stored together, trilinear interpolation and
//! its backward (the interpolation weights), and resampling for coarse-to-fine growth.
//!
//! Positions are in grid units: vertex (i, j, k) sits at (i, j, k); the grid spans
//! [0, nx-1] x [0, ny-1] x [0, nz-1]. Storage is x-fastest, then y, then z, and a vertex's
//! channels are contiguous so one interpolation touches 8 short runs of memory, not 8 x C.

use rayon::prelude::*;

#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Vertex counts per axis (each >= 2).
    pub dims: [usize; 3],
    /// Channels per vertex.
    pub channels: usize,
    pub data: Vec<f32>,
}

/// The 8 vertices around a point and their trilinear weights.
#[derive(Clone, Copy, Debug)]
pub struct Corners {
    /// Vertex indices (not multiplied by the channel count), in the order
    /// (000, 100, 010, 110, 001, 101, 011, 111) of (dx, dy, dz).
    pub idx: [u32; 8],
    pub w: [f32; 8],
}

impl Grid {
    pub fn new(dims: [usize; 3], channels: usize, fill: &[f32]) -> Grid {
        assert!(dims.iter().all(|&d| d >= 2) && fill.len() == channels);
        let n = dims[0] * dims[1] * dims[2];
        let mut data = Vec::with_capacity(n * channels);
        for _ in 0..n {
            data.extend_from_slice(fill);
        }
        Grid {
            dims,
            channels,
            data,
        }
    }

    pub fn num_vertices(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    #[inline]
    pub fn vertex_index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    #[inline]
    pub fn vertex(&self, v: usize) -> &[f32] {
        &self.data[v * self.channels..(v + 1) * self.channels]
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
        Grid::corners_in(self.dims, base, f)
    }

    /// [`Grid::corners_of`] for a grid of `dims`, without borrowing it (the optimiser needs the
    /// corners while it writes the grid).
    #[inline]
    pub fn corners_in(dims: [usize; 3], base: [usize; 3], f: [f32; 3]) -> Corners {
        let sx = 1;
        let sy = dims[0];
        let sz = dims[0] * dims[1];
        let b = (base[0] + dims[0] * (base[1] + dims[1] * base[2])) as u32;
        let (sx, sy, sz) = (sx as u32, sy as u32, sz as u32);
        let (fx, fy, fz) = (f[0], f[1], f[2]);
        let (gx, gy, gz) = (1.0 - fx, 1.0 - fy, 1.0 - fz);
        Corners {
            idx: [
                b,
                b + sx,
                b + sy,
                b + sx + sy,
                b + sz,
                b + sx + sz,
                b + sy + sz,
                b + sx + sy + sz,
            ],
            w: [
                gx * gy * gz,
                fx * gy * gz,
                gx * fy * gz,
                fx * fy * gz,
                gx * gy * fz,
                fx * gy * fz,
                gx * fy * fz,
                fx * fy * fz,
            ],
        }
    }

    #[inline]
    pub fn corners(&self, p: [f32; 3]) -> Corners {
        let (b, f) = self.locate(p);
        self.corners_of(b, f)
    }

    /// Interpolate channel `c` alone.
    #[inline]
    pub fn interp_channel(&self, k: &Corners, c: usize) -> f32 {
        let ch = self.channels;
        let mut s = 0.0;
        for i in 0..8 {
            s += k.w[i] * self.data[k.idx[i] as usize * ch + c];
        }
        s
    }

    /// Interpolate channels `from..from + out.len()` into `out`.
    #[inline]
    pub fn interp_range(&self, k: &Corners, from: usize, out: &mut [f32]) {
        let ch = self.channels;
        out.iter_mut().for_each(|o| *o = 0.0);
        for i in 0..8 {
            let w = k.w[i];
            let base = k.idx[i] as usize * ch + from;
            let src = &self.data[base..base + out.len()];
            for (o, s) in out.iter_mut().zip(src) {
                *o += w * s;
            }
        }
    }

    /// Interpolate every channel at `p`.
    pub fn sample(&self, p: [f32; 3], out: &mut [f32]) {
        let k = self.corners(p);
        self.interp_range(&k, 0, out);
    }

    /// Backward of [`Grid::interp_range`]: add `w_i * g` to each corner's channels in `grad`
    /// (a buffer laid out like `data`).
    #[inline]
    pub fn scatter(grad: &mut [f32], channels: usize, k: &Corners, g: &[f32]) {
        for i in 0..8 {
            let w = k.w[i];
            let base = k.idx[i] as usize * channels;
            for (d, s) in grad[base..base + channels].iter_mut().zip(g) {
                *d += w * s;
            }
        }
    }

    /// This grid resampled to `dims` over the same extent (trilinear), for coarse-to-fine growth.
    pub fn resampled(&self, dims: [usize; 3]) -> Grid {
        let ch = self.channels;
        let scale: Vec<f32> = (0..3)
            .map(|a| (self.dims[a] - 1) as f32 / (dims[a] - 1) as f32)
            .collect();
        let plane = dims[0] * dims[1];
        let mut data = vec![0f32; plane * dims[2] * ch];
        data.par_chunks_mut(plane * ch)
            .enumerate()
            .for_each(|(z, slab)| {
                for y in 0..dims[1] {
                    for x in 0..dims[0] {
                        let p = [
                            x as f32 * scale[0],
                            y as f32 * scale[1],
                            z as f32 * scale[2],
                        ];
                        let o = (x + dims[0] * y) * ch;
                        self.sample(p, &mut slab[o..o + ch]);
                    }
                }
            });
        Grid {
            dims,
            channels: ch,
            data,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> Grid {
        let mut g = Grid::new([4, 3, 5], 2, &[0.0, 0.0]);
        for z in 0..5 {
            for y in 0..3 {
                for x in 0..4 {
                    let v = g.vertex_index(x, y, z);
                    g.data[v * 2] = 1.0 + 2.0 * x as f32 - 0.5 * y as f32 + 3.0 * z as f32;
                    g.data[v * 2 + 1] = (x * y + z) as f32;
                }
            }
        }
        g
    }

    #[test]
    fn trilinear_reproduces_linear_functions_and_vertices() {
        let g = ramp();
        let mut out = [0.0; 2];
        for p in [
            [0.3, 1.7, 2.2],
            [3.0, 2.0, 4.0],
            [0.0, 0.0, 0.0],
            [2.5, 0.5, 3.9],
        ] {
            g.sample(p, &mut out);
            let want = 1.0 + 2.0 * p[0] - 0.5 * p[1] + 3.0 * p[2];
            assert!((out[0] - want).abs() < 1e-5, "{p:?}: {} vs {want}", out[0]);
        }
        g.sample([2.0, 1.0, 3.0], &mut out);
        assert_eq!(out[1], 5.0);
        let k = g.corners([1.25, 0.5, 2.75]);
        assert!((k.w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn scatter_is_the_transpose_of_interpolation() {
        // <interp(data), g> == <data, scatter(g)> for any data and g.
        let g = ramp();
        let k = g.corners([1.3, 0.6, 2.9]);
        let mut out = [0.0; 2];
        g.interp_range(&k, 0, &mut out);
        let up = [0.7f32, -1.3];
        let lhs = out[0] * up[0] + out[1] * up[1];
        let mut grad = vec![0.0; g.data.len()];
        Grid::scatter(&mut grad, 2, &k, &up);
        let rhs: f32 = grad.iter().zip(&g.data).map(|(a, b)| a * b).sum();
        assert!((lhs - rhs).abs() < 1e-4, "{lhs} vs {rhs}");
    }

    #[test]
    fn resampling_keeps_linear_functions() {
        let g = ramp();
        let h = g.resampled([7, 5, 9]);
        let mut a = [0.0; 2];
        let mut b = [0.0; 2];
        // Grid point (x, y, z) of h is (x/2, y/2, z/2) of g.
        h.sample([3.0, 1.0, 5.0], &mut a);
        g.sample([1.5, 0.5, 2.5], &mut b);
        assert!((a[0] - b[0]).abs() < 1e-5);
    }
}
