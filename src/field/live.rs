//! The bricks of a sparse grid that hold an occupied cell, as bitsets the marcher can afford to
//! ask at every step through space.

/// Bricks per edge of a [`LiveBricks`] block.
pub const BLOCK: usize = 4;

/// Which bricks, and which blocks of [`BLOCK`]^3 bricks, hold an occupied cell: one bit each,
/// by brick coordinates. The marcher asks this for every step through space. The brick index and
/// occupancy words it asked before are megabytes on a large grid (lego 800^2: 633 k bricks, a
/// 2.5 MB index), and their cache misses were half the marcher's own time; the bitset is 79 KB
/// there, and an empty block is jumped at once. Conservative: a clear bit is an empty brick; a
/// cell made free leaves its brick's bit set until the next rebuild
/// (`Field::refresh_live_bricks`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LiveBricks {
    pub brick_dims: [usize; 3],
    bricks: Vec<u64>,
    block_dims: [usize; 3],
    blocks: Vec<u64>,
}

impl LiveBricks {
    pub fn new(brick_dims: [usize; 3]) -> LiveBricks {
        let block_dims = brick_dims.map(|d| d.div_ceil(BLOCK));
        let bits = |d: [usize; 3]| vec![0u64; d.iter().product::<usize>().div_ceil(64)];
        LiveBricks {
            brick_dims,
            bricks: bits(brick_dims),
            block_dims,
            blocks: bits(block_dims),
        }
    }

    /// Mark brick `b` (brick coordinates) and its block as holding an occupied cell.
    pub fn mark(&mut self, b: [usize; 3]) {
        let (d, e) = (self.brick_dims, self.block_dims);
        let i = b[0] + d[0] * (b[1] + d[1] * b[2]);
        self.bricks[i / 64] |= 1 << (i % 64);
        let c = b.map(|v| v / BLOCK);
        let j = c[0] + e[0] * (c[1] + e[1] * c[2]);
        self.blocks[j / 64] |= 1 << (j % 64);
    }

    /// The bits by brick, then by block (x-fastest, 64 a word), and the blocks per axis: what the
    /// GPU renderer uploads to skip space as [`LiveBricks::brick`] and [`LiveBricks::block`] do.
    pub fn words(&self) -> (&[u64], &[u64], [usize; 3]) {
        (&self.bricks, &self.blocks, self.block_dims)
    }

    /// Whether brick `b` (brick coordinates, inside the grid) may hold an occupied cell.
    #[inline]
    pub fn brick(&self, b: [usize; 3]) -> bool {
        let d = self.brick_dims;
        let i = b[0] + d[0] * (b[1] + d[1] * b[2]);
        self.bricks
            .get(i / 64)
            .is_some_and(|w| w >> (i % 64) & 1 == 1)
    }

    /// Whether the block holding brick `b` may hold an occupied cell.
    #[inline]
    pub fn block(&self, b: [usize; 3]) -> bool {
        let e = self.block_dims;
        let j = b[0] / BLOCK + e[0] * (b[1] / BLOCK + e[1] * (b[2] / BLOCK));
        self.blocks
            .get(j / 64)
            .is_some_and(|w| w >> (j % 64) & 1 == 1)
    }
}
