//! The optimiser's half of a step: the gradient records summed into the grid by z-slabs (each
//! slab in chunk order, with the lines it will touch prefetched) and the sparse Adam update of the
//! touched vertices.

use super::super::grid::{colour_index, density_index, Corners, Grid, NONE};
use crate::util::bf16::{from_bf16, to_bf16};
use crate::util::mem::prefetch;

/// How many listed vertices ahead [`AdamStep::apply`] prefetches.
pub(super) const PREFETCH_AHEAD: usize = 8;

/// One Adam step's constants (bias corrections and the decayed learning rates).
#[derive(Clone, Copy)]
pub(super) struct AdamStep {
    pub(super) b1: f32,
    pub(super) b2: f32,
    pub(super) c1: f32,
    pub(super) c2: f32,
    pub(super) lr: [f32; 2],
}

impl AdamStep {
    /// Update the listed vertices of one slab (slices start at vertex `v0`) and clear their
    /// gradients.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(super) fn apply(
        &self,
        p: &mut [f32],
        g: &mut [f32],
        m: &mut [u16],
        v: &mut [u16],
        list: &[u32],
        v0: usize,
        ch: usize,
    ) {
        // lr (m / c1) / (sqrt(v) / c2 + eps) = (lr c2 / c1) m / (sqrt(v) + eps c2): one division
        // per value, and the density channel (its own rate) split off so the colour channels
        // run as one branch-free loop the compiler vectorises.
        let rate = self.lr.map(|l| l * self.c2 / self.c1);
        let eps = 1e-8 * self.c2;
        let n = ch - 1;
        for (k, &vtx) in list.iter().enumerate() {
            // The list ascends with irregular gaps, which the hardware prefetcher does not
            // follow: fetch the values a few vertices ahead.
            if let Some(&ahead) = list.get(k + PREFETCH_AHEAD) {
                let a = ahead as usize - v0;
                let (d, c) = (density_index(a, ch), colour_index(a, ch));
                for buf in [&*p, &*g] {
                    prefetch(buf, d);
                    prefetch(buf, c);
                    prefetch(buf, c + n - 1);
                }
                for buf in [&*m, &*v] {
                    prefetch(buf, d);
                    prefetch(buf, c);
                    prefetch(buf, c + n - 1);
                }
            }
            let local = vtx as usize - v0;
            let d = density_index(local, ch);
            self.update(
                &mut p[d..d + 1],
                &mut g[d..d + 1],
                &mut m[d..d + 1],
                &mut v[d..d + 1],
                rate[0],
                eps,
            );
            let c = colour_index(local, ch);
            let r = c..c + n;
            self.update(
                &mut p[r.clone()],
                &mut g[r.clone()],
                &mut m[r.clone()],
                &mut v[r],
                rate[1],
                eps,
            );
        }
    }

    /// Adam on equal-length runs of values (parameters, gradients, moments); clears the
    /// gradients.
    #[inline(always)]
    fn update(
        &self,
        p: &mut [f32],
        g: &mut [f32],
        m: &mut [u16],
        v: &mut [u16],
        rate: f32,
        eps: f32,
    ) {
        let (b1, b2) = (self.b1, self.b2);
        for (((p, g), m), v) in p
            .iter_mut()
            .zip(g.iter_mut())
            .zip(m.iter_mut())
            .zip(v.iter_mut())
        {
            let gj = *g;
            *g = 0.0;
            let mj = b1 * from_bf16(*m) + (1.0 - b1) * gj;
            let vj = b2 * from_bf16(*v) + (1.0 - b2) * gj * gj;
            *m = to_bf16(mj);
            *v = to_bf16(vj);
            *p -= rate * mj / (vj.sqrt() + eps);
        }
    }
}

/// Sums one slab's share of the records into its gradient, listing the vertices touched.
pub(super) struct SlabScatter<'a> {
    pub(super) grid: &'a Grid,
    pub(super) stride: usize,
    /// The slab's vertex slots.
    pub(super) range: std::ops::Range<usize>,
    pub(super) stamp_id: u32,
}

impl SlabScatter<'_> {
    fn corners(&self, r: &[f32]) -> Corners {
        let cell = self.grid.cell_of_base(r[0].to_bits() as usize);
        self.grid.corners_of(cell, [r[1], r[2], r[3]])
    }

    /// The gradient lines of `k`'s corners are fetched a few records ahead: the corners are
    /// scattered over the slab and the sum was bound by cache misses, like the optimiser's pass.
    fn prefetch(&self, grad: &[f32], k: &Corners) {
        let ch = self.grid.channels;
        // Corners come in x-adjacent pairs (000/100, 010/110, ...): two lines cover each
        // pair's colour, one its densities.
        for &v in k.idx.iter().step_by(2) {
            if self.range.contains(&(v as usize)) {
                let local = v as usize - self.range.start;
                let o = colour_index(local, ch);
                prefetch(grad, density_index(local, ch));
                prefetch(grad, o);
                prefetch(grad, o + 2 * ch - 3);
            }
        }
    }

    pub(super) fn scatter(
        &self,
        records: &[f32],
        grad: &mut [f32],
        stamp: &mut [u32],
        list: &mut Vec<u32>,
    ) {
        let ch = self.grid.channels;
        let (v0, v1) = (self.range.start, self.range.end);
        let n = records.len() / self.stride;
        let record = |i: usize| &records[i * self.stride..(i + 1) * self.stride];
        let mut ring = [Corners {
            idx: [NONE; 8],
            w: [0.0; 8],
        }; PREFETCH_AHEAD];
        for (i, slot) in ring.iter_mut().enumerate().take(n) {
            *slot = self.corners(record(i));
            self.prefetch(grad, slot);
        }
        for i in 0..n {
            let k = ring[i % PREFETCH_AHEAD];
            if i + PREFETCH_AHEAD < n {
                let ahead = self.corners(record(i + PREFETCH_AHEAD));
                self.prefetch(grad, &ahead);
                ring[i % PREFETCH_AHEAD] = ahead;
            }
            let g = &record(i)[4..];
            for (&vtx, &w) in k.idx.iter().zip(&k.w) {
                let vtx = vtx as usize;
                if vtx < v0 || vtx >= v1 {
                    continue; // another slab's vertex, or unallocated (NONE)
                }
                let local = vtx - v0;
                if stamp[local] != self.stamp_id {
                    stamp[local] = self.stamp_id;
                    list.push(vtx as u32);
                }
                grad[density_index(local, ch)] += w * g[0];
                let o = colour_index(local, ch);
                for (d, s) in grad[o..o + ch - 1].iter_mut().zip(&g[1..]) {
                    *d += w * s;
                }
            }
        }
    }
}

/// The grid's slabs for one step: the slab of each brick layer, and each slab's first vertex
/// (slot index; the last entry is one past the end).
pub(super) struct Slabs {
    pub(super) slab_of_layer: Vec<u32>,
    pub(super) bounds: Vec<usize>,
}

impl Slabs {
    pub(super) fn count(&self) -> usize {
        self.bounds.len() - 1
    }
}

/// `buf` (`per` values per vertex) cut at the vertex `bounds`: one slice per slab.
pub(super) fn split_by<'a, T>(
    mut buf: &'a mut [T],
    bounds: &[usize],
    per: usize,
) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(bounds.len() - 1);
    for w in bounds.windows(2) {
        let (head, tail) = buf.split_at_mut((w[1] - w[0]) * per);
        out.push(head);
        buf = tail;
    }
    out
}
