//! Progress of long work: the library reports it through [`Progress`], and whoever listens draws
//! it (the command line's bars, `crate::cli::progress_bars`). Library code never draws or prints.

/// What the step just finished was about, for the listener to show.
#[derive(Clone, Copy, Debug)]
pub enum Detail<'a> {
    None,
    /// The item just done (a view's name, a frame's file).
    Item(&'a str),
    /// A training step: its loss, the batch PSNR, and rays per second since the stage began.
    Training {
        loss: f32,
        psnr: f32,
        rays_per_second: f64,
    },
}

/// A listener for stages of work. Every method has a default that does nothing.
pub trait Progress: Sync {
    /// A stage of `total` steps begins (e.g. "segment", "train mug").
    fn begin(&self, _stage: &str, _total: u64) {}
    /// `done` steps of the current stage are finished.
    fn advance(&self, _done: u64, _detail: Detail) {}
    /// The current stage is over.
    fn end(&self) {}
    /// A line the user should read now rather than in the final report (e.g. the space a scene
    /// field chose, and why, before it trains).
    fn note(&self, _line: &str) {}
}

/// Reports nothing.
pub struct Silent;

impl Progress for Silent {}
