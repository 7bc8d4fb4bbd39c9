//! The library's progress reports drawn as terminal bars on stderr (hidden when stderr is not a
//! terminal, as indicatif does).

use indicatif::{ProgressBar, ProgressStyle};
use objnerf::util::{Detail, Progress};
use std::sync::Mutex;

/// One bar per stage: a stage's `begin` replaces the bar, `end` clears it.
#[derive(Default)]
pub struct Bars {
    bar: Mutex<Option<ProgressBar>>,
}

impl Progress for Bars {
    fn begin(&self, stage: &str, total: u64) {
        let b = ProgressBar::new(total);
        b.set_style(
            ProgressStyle::with_template(
                "{prefix:>9} {elapsed_precise} [{bar:30}] {pos}/{len} {msg}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        b.set_prefix(stage.to_string());
        if let Some(old) = self.bar.lock().expect("bar lock").replace(b) {
            old.finish_and_clear();
        }
    }

    fn advance(&self, done: u64, detail: Detail) {
        let guard = self.bar.lock().expect("bar lock");
        let Some(b) = guard.as_ref() else { return };
        b.set_position(done);
        match detail {
            Detail::None => {}
            Detail::Item(name) => b.set_message(name.to_string()),
            // Every step is reported; redrawing the text every tenth is enough.
            Detail::Training {
                loss,
                psnr,
                rays_per_second,
            } if done % 10 == 0 => b.set_message(format!(
                "loss {loss:.5}  psnr {psnr:.2} dB  {rays_per_second:.0} rays/s"
            )),
            Detail::Training { .. } => {}
        }
    }

    fn end(&self) {
        if let Some(b) = self.bar.lock().expect("bar lock").take() {
            b.finish_and_clear();
        }
    }

    fn note(&self, line: &str) {
        match self.bar.lock().expect("bar lock").as_ref() {
            Some(b) => b.suspend(|| eprintln!("{line}")),
            None => eprintln!("{line}"),
        }
    }
}
