//! Removal: objects taken out of a scene field. The job (`objnerf remove`) is
//! [`crate::pipeline::remove`]: a scene field trained with the objects' dilated masks carrying no
//! loss ([`crate::fit::SceneFit`] with `removed`, [`crate::supervision::loss_mask`]), then the
//! parts of the hole no view saw found and filled here:
//!
//! - [`hole`]: the never-seen hole, its fill (smooth or pattern) and the see-through check;
//! - [`removed`]: the removed objects' volume, cleared and its air emptied;
//! - [`pattern`]: a repeating pattern (a tiled floor) continued into the hole, with [`periods`]
//!   (the translations that map a sampled texture onto itself);
//! - harmonic inpainting, shared with the mask-edge supervision, is [`crate::util::inpaint`].

pub mod hole;
pub mod pattern;
pub mod periods;
pub mod removed;
