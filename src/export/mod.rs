//! Exports for other tools' training pipelines. `nerfstudio`: a dataset (transforms.json, images,
//! masks, depth, points) that nerfstudio's own dataparser loads unchanged.

pub mod nerfstudio;
