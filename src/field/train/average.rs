//! Polyak averaging: the mean of the parameters over the end of a run, taken as the trained
//! field. Sparse Adam moves a vertex by about the learning rate each time a ray crosses it, so
//! the last values of a vertex scatter around where its gradient balances; their mean lies
//! nearer that point than any one of them.

use super::Trainer;
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

impl Trainer {
    /// Fold the parameters into the running mean when the schedule says so.
    pub(super) fn maybe_fold_average(&mut self) {
        let cfg = &self.cfg;
        if cfg.average_from >= 1.0
            || self.progress() < cfg.average_from
            || self.step % cfg.average_every.max(1) != 0
        {
            return;
        }
        let c = std::time::Instant::now();
        let data = &self.field.grid.data;
        let net = self.field.net.as_ref().map_or(&[][..], |n| &n.weights[..]);
        match &mut self.average {
            Some(a) => a.fold(data, net),
            None => self.average = Some(ParamAverage::start(data, net)),
        }
        self.phase_secs[3] += c.elapsed().as_secs_f64();
    }

    /// Whether a running mean is kept (the run has passed `cfg.average_from`).
    pub fn has_average(&self) -> bool {
        self.average.is_some()
    }

    /// End the run on the mean of its last parameters
    /// ([`super::TrainConfig::average_from`]) if one was kept; returns how many snapshots it
    /// averaged (0: none, the field is as trained).
    pub fn take_average(&mut self) -> u32 {
        let Some(a) = self.average.take() else {
            return 0;
        };
        self.field.grid.data = a.data;
        if let Some(net) = self.field.net.as_mut() {
            net.weights = a.net;
        }
        a.count
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
