//! Full reconstruction: features, exhaustive matching and COLMAP's mapper on a folder of
//! images without poses.

use super::colmap_run::{colmap_program, extract_and_match, map_points, s, MatchPlan, Steps};
use super::{check_out, finish, rename_and_rescale, stage_images, work_dir, SfmOptions, SfmReport};
use crate::error::{Error, Result};
use crate::scene::formats::colmap;
use crate::scene::io::is_image;
use crate::scene::Scene;
use crate::util::Progress;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Full reconstruction of the images in `images_dir`; writes `out/sparse/0` and links
/// `out/images` to the images. `progress` hears COLMAP's three programs finish.
pub fn reconstruct(
    images_dir: &Path,
    out: &Path,
    opts: &SfmOptions,
    progress: &dyn Progress,
) -> Result<SfmReport> {
    let start = Instant::now();
    let program = colmap_program()?;
    check_out(out, opts)?;
    let mut paths: Vec<PathBuf> = std::fs::read_dir(images_dir)
        .map_err(|e| Error::io(images_dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| is_image(p))
        .collect();
    paths.sort();
    if paths.len() < 2 {
        return Err(Error::format(
            images_dir,
            format!(
                "found {} images; structure from motion needs at least 2",
                paths.len()
            ),
        ));
    }
    let work = work_dir()?;
    let log = work.path().join("colmap.log");
    let staged = stage_images(&paths, work.path(), opts.downscale)?;
    let steps = Steps::new(progress);
    extract_and_match(
        &program,
        work.path(),
        opts,
        &[
            s("--ImageReader.single_camera"),
            s("1"),
            s("--ImageReader.camera_model"),
            opts.camera_model.clone(),
        ],
        MatchPlan {
            pairs: None,
            staged: &staged,
        },
        &log,
        &steps,
    )?;
    let sparse = work.path().join("sparse");
    map_points(&program, work.path(), None, &sparse, opts, &steps)?;
    // COLMAP may split the images into several models: keep the one with the most images.
    let mut best: Option<Scene> = None;
    for entry in std::fs::read_dir(&sparse)
        .map_err(|e| Error::io(&sparse, e))?
        .flatten()
    {
        if colmap::detect(&entry.path()).is_some() {
            let m = colmap::read_model(&entry.path(), &work.path().join("images"))?;
            if best
                .as_ref()
                .is_none_or(|b| m.images.len() > b.images.len())
            {
                best = Some(m);
            }
        }
    }
    let mut model = best.ok_or_else(|| {
        Error::external(
            "colmap mapper",
            format!(
                "registered no images (too few matches?); log {}",
                log.display()
            ),
        )
    })?;
    let originals: Vec<String> = paths
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().to_string())
        .collect();
    rename_and_rescale(&mut model, &staged, &originals, &paths)?;
    finish(
        model,
        out,
        images_dir,
        "reconstruct",
        paths.len(),
        start,
        work,
    )
}
