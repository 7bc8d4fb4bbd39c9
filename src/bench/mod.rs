//! Benchmarks that run as commands (`objnerf bench ...`): suites of whole jobs scored against
//! truth. [`stability`]: how the pipeline behaves as the capture gets worse, and whether each
//! failure is flagged by its self-checks.

pub mod stability;
