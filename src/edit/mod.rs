//! Edits of a captured scene: the edit file ([`file`]: a background and objects, each a field
//! under a transform, with an optional recolour; `docs/edit-format.md`), its transforms
//! ([`Similarity`]), recolouring in OKLab ([`recolour`]), and the edit loaded with its fields
//! ([`scene`]), which `render::composite` draws in one volume-rendering pass and the demo's truth
//! renderer draws exactly.

pub mod file;
pub mod recolour;
pub mod scene;
pub mod similarity;
pub mod template;

pub use file::{Background, EditFile, EditObject};
pub use recolour::Recolour;
pub use scene::{load_edit, LoadedBackground, LoadedEdit, Placed};
pub use similarity::Similarity;
