//! objnerf: pull one object out of a multi-view capture as its own radiance field and mesh
//! (the Obj-NeRF method, CVPR 2024). The modules follow the pipeline: `scene` (capture formats in),
//! `demo` (the built-in synthetic scene), `segment` (SAM and multi-view propagation), and the
//! stages after it. See ARCHITECTURE.md.

pub mod demo;
pub mod error;
pub mod eval;
pub mod export;
pub mod extract;
pub mod field;
pub mod info;
pub mod mesh;
pub mod scene;
pub mod segment;
pub mod util;

pub use error::{Error, Result};
pub use scene::Scene;
