//! Progress bars for long stages (to stderr; hidden when stderr is not a terminal).

use indicatif::{ProgressBar, ProgressStyle};

/// A bar of `len` steps named `stage`.
pub fn bar(len: u64, stage: &str) -> ProgressBar {
    let b = ProgressBar::new(len);
    b.set_style(
        ProgressStyle::with_template("{prefix:>9} {elapsed_precise} [{bar:30}] {pos}/{len} {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    b.set_prefix(stage.to_string());
    b
}

/// The message a training bar shows: loss, PSNR and rays per second since the first step seen.
pub struct TrainProgress {
    bar: ProgressBar,
    first_step: Option<usize>,
    batch: f64,
}

impl TrainProgress {
    pub fn new(steps: usize, stage: &str) -> Self {
        TrainProgress {
            bar: bar(steps as u64, stage),
            first_step: None,
            batch: crate::field::TrainConfig::default().batch as f64,
        }
    }

    pub fn update(&mut self, s: &crate::field::train::StepStats, secs: f64) {
        let f = *self.first_step.get_or_insert(s.step.saturating_sub(1));
        self.bar.set_position(s.step as u64);
        if s.step % 10 == 0 {
            self.bar.set_message(format!(
                "loss {:.5}  psnr {:.2} dB  {:.0} rays/s",
                s.loss,
                s.psnr,
                (s.step - f) as f64 * self.batch / secs.max(1e-9)
            ));
        }
    }

    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
