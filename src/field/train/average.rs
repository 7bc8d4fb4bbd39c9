//! Polyak averaging: the mean of the parameters over the end of a run, taken as the trained
//! field. Sparse Adam moves a vertex by about the learning rate each time a ray crosses it, so
//! the last values of a vertex scatter around where its gradient balances; their mean lies
//! nearer that point than any one of them.

use rayon::prelude::*;

/// Values folded per parallel task (large enough that the split costs nothing).
const FOLD_CHUNK: usize = 1 << 16;

/// The running mean of the grid's values and the colour network's weights.
pub(super) struct ParamAverage {
    /// The grid's values, in its layout (it follows the grid's compactions).
    pub(super) data: Vec<f32>,
    pub(super) net: Vec<f32>,
    /// Snapshots folded in.
    pub(super) count: u32,
}

impl ParamAverage {
    /// An average of one snapshot.
    pub(super) fn start(data: &[f32], net: &[f32]) -> ParamAverage {
        ParamAverage {
            data: data.to_vec(),
            net: net.to_vec(),
            count: 1,
        }
    }

    /// Fold in one more snapshot (each value on its own, so the result does not depend on the
    /// thread count).
    pub(super) fn fold(&mut self, data: &[f32], net: &[f32]) {
        self.count += 1;
        let k = 1.0 / self.count as f32;
        let fold = |mean: &mut [f32], now: &[f32]| {
            mean.iter_mut()
                .zip(now)
                .for_each(|(a, p)| *a += (p - *a) * k)
        };
        self.data
            .par_chunks_mut(FOLD_CHUNK)
            .zip(data.par_chunks(FOLD_CHUNK))
            .for_each(|(a, p)| fold(a, p));
        fold(&mut self.net, net);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folding_gives_the_mean_of_the_snapshots() {
        let snaps = [[1.0f32, -2.0, 4.0], [3.0, 2.0, 4.0], [8.0, 0.0, 1.0]];
        let mut avg = ParamAverage::start(&snaps[0], &snaps[0][..1]);
        for s in &snaps[1..] {
            avg.fold(s, &s[..1]);
        }
        assert_eq!(avg.count, 3);
        for (j, a) in avg.data.iter().enumerate() {
            let mean = snaps.iter().map(|s| s[j]).sum::<f32>() / 3.0;
            assert!((a - mean).abs() < 1e-6, "value {j}: {a} against {mean}");
        }
        assert!((avg.net[0] - 4.0).abs() < 1e-6);
    }
}
