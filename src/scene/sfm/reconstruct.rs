//! Full reconstruction: features, matching and COLMAP's mapper on images without poses (a
//! folder of images, or the frames chosen from a video).

use super::colmap_run::Steps;
use super::commands::{extract_and_match, map_points, Matching};
use super::{finish, rename_and_rescale, stage_images, ImagesOut, Run, SfmOptions, SfmReport};
use super::{StageTime, Staged};
use crate::error::{Error, Result};
use crate::scene::formats::colmap;
use crate::scene::io::is_image;
use crate::scene::Scene;
use crate::util::Progress;
use std::path::{Path, PathBuf};

/// Full reconstruction of the images in `images_dir`; writes `out/sparse/0`, COLMAP's
/// `out/database.db`, and links `out/images` to the images. `progress` hears COLMAP's three
/// programs finish.
pub fn reconstruct(
    images_dir: &Path,
    out: &Path,
    opts: &SfmOptions,
    progress: &dyn Progress,
) -> Result<SfmReport> {
    let run = Run::begin(out, opts)?;
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
    reconstruct_images(
        run,
        paths,
        ImagesOut::Link(images_dir),
        false,
        opts,
        progress,
    )
}

/// Reconstruct from `paths` (sorted: for a video, in time order) within `run`.
pub(super) fn reconstruct_images(
    run: Run,
    paths: Vec<PathBuf>,
    images: ImagesOut,
    video: bool,
    opts: &SfmOptions,
    progress: &dyn Progress,
) -> Result<SfmReport> {
    let staged = Staged {
        names: stage_images(&paths, run.work(), opts.downscale)?,
        originals: paths
            .iter()
            .map(|p| {
                p.file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .to_string()
            })
            .collect(),
        paths,
    };
    let steps = Steps::new(progress);
    extract_and_match(
        &run.colmap,
        run.work(),
        opts,
        &[
            "--ImageReader.single_camera".into(),
            "1".into(),
            "--ImageReader.camera_model".into(),
            opts.camera_model.clone(),
        ],
        (Matching::choose(&opts.matcher, None, video)?, &staged.names),
        &steps,
    )?;
    let sparse = run.work().join("sparse");
    map_points(&run.colmap, run.work(), None, &sparse, opts, &steps)?;
    let mut model = best_model(&sparse, &run.work().join("images"))?.ok_or_else(|| {
        Error::external(
            "colmap mapper",
            format!(
                "registered no images (too few matches?); log {}",
                run.work().join("colmap.log").display()
            ),
        )
    })?;
    rename_and_rescale(&mut model, &staged)?;
    let times: Vec<StageTime> = steps.times();
    drop(steps);
    finish(run, model, &staged, images, "reconstruct", times)
}

/// COLMAP may split the images into several models: the one with the most images.
fn best_model(sparse: &Path, images: &Path) -> Result<Option<Scene>> {
    let mut best: Option<Scene> = None;
    for entry in std::fs::read_dir(sparse)
        .map_err(|e| Error::io(sparse, e))?
        .flatten()
    {
        if colmap::detect(&entry.path()).is_some() {
            let m = colmap::read_model(&entry.path(), images)?;
            if best
                .as_ref()
                .is_none_or(|b| m.images.len() > b.images.len())
            {
                best = Some(m);
            }
        }
    }
    Ok(best)
}
