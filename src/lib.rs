//! objnerf: pull objects out of a multi-view capture as their own radiance fields and meshes (the
//! Obj-NeRF method, CVPR 2024). The modules follow the pipeline, and dependencies point one way
//! (ARCHITECTURE.md; `tests/architecture.rs` checks it):
//!
//! ```text
//! util ← scene ← (sam, models, segment, field) ← (mesh, render, eval, demo) ← pipeline ← (bench, batch) ← cli
//! ```
//!
//! The command line (`src/cli/`, part of the `objnerf` binary) is a thin layer over this library:
//! library code takes typed options, returns values and reports, and never prints.

pub mod batch;
pub mod bench;
pub mod demo;
pub mod edit;
pub mod error;
pub mod export;
pub mod field;
pub mod fit;
pub mod mesh;
pub mod models;
pub mod pipeline;
pub mod removal;
pub mod render;
pub mod sam;
pub mod scene;
pub mod segment;
pub mod space;
pub mod supervision;
pub mod util;

pub use error::{Error, Result};
pub use scene::Scene;
