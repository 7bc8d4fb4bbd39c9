//! Triangulation with known poses: the scene's cameras and poses stay as they are, COLMAP only
//! matches (pairs chosen from the poses) and triangulates points.

use super::colmap_run::{database_ids, s, Steps};
use super::commands::{extract_and_match, map_points, Matching};
use super::{finish, image_root, relative_name, rename_and_rescale, stage_images};
use super::{ImagesOut, Run, SfmOptions, SfmReport, Staged};
use crate::error::{Error, Result};
use crate::scene::formats::colmap::{self, ModelFormat};
use crate::scene::Scene;
use crate::util::Progress;
use std::path::{Path, PathBuf};

/// Triangulate points for a posed scene, keeping its cameras and poses. Writes `out/sparse/0`
/// (image names as in the scene, relative to `out/images`, which links to the scene's folder).
/// `progress` hears COLMAP's three programs finish.
pub fn triangulate(
    scene: &Scene,
    out: &Path,
    opts: &SfmOptions,
    progress: &dyn Progress,
) -> Result<SfmReport> {
    let run = Run::begin(out, opts)?;
    let root = image_root(scene)?;
    let paths: Vec<PathBuf> = scene.images.iter().map(|im| im.path.clone()).collect();
    let staged = Staged {
        names: stage_images(&paths, run.work(), opts.downscale)?,
        originals: scene
            .images
            .iter()
            .map(|im| relative_name(&im.path, &root))
            .collect(),
        paths,
    };
    let (mut known, cam_args) = known_model(scene, &staged.names, opts.downscale);
    let pairs = pairs_from_poses(scene, opts.pair_neighbours);
    let steps = Steps::new(progress);
    extract_and_match(
        &run.colmap,
        run.work(),
        opts,
        &cam_args,
        (
            Matching::choose(&opts.matcher, Some(&pairs), false)?,
            &staged.names,
        ),
        &steps,
    )?;
    // COLMAP numbers images and cameras as its extractor threads finish, not in list order:
    // take the ids from its database so the known model lines up with it.
    let ids = database_ids(&run.work().join("database.db"))?;
    for im in known.images.iter_mut() {
        let &(image_id, camera_id) = ids.get(&im.name).ok_or_else(|| {
            Error::external(
                "colmap feature_extractor",
                format!("image '{}' is missing from its database", im.name),
            )
        })?;
        im.id = image_id;
        known.cameras[im.camera].id = camera_id;
    }
    let input = run.work().join("known");
    colmap::write_model(&known, &input, ModelFormat::Text)?;
    let tri = run.work().join("triangulated");
    map_points(&run.colmap, run.work(), Some(&input), &tri, opts, &steps)?;
    let mut model = colmap::read_model(&tri, &run.work().join("images"))?;
    check_poses_kept(&model, scene, &staged.names)?;
    rename_and_rescale(&mut model, &staged)?;
    // Keep the scene's exact intrinsics and poses (COLMAP's text round trip is exact, but the
    // original numbers are the reference).
    for im in &mut model.images {
        if let Some(k) = staged.originals.iter().position(|n| *n == im.name) {
            im.pose = scene.images[k].pose;
        }
    }
    let times = steps.times();
    drop(steps);
    let mut report = finish(
        run,
        model,
        &staged,
        ImagesOut::Link(&root),
        "triangulate",
        times,
    )?;
    report.matched_pairs = Some(pairs.len());
    Ok(report)
}

/// The poses must come back unchanged; a mismatch means the database ids did not line up.
fn check_poses_kept(model: &Scene, scene: &Scene, staged: &[String]) -> Result<()> {
    for im in &model.images {
        let k = staged.iter().position(|n| *n == im.name).ok_or_else(|| {
            Error::external(
                "colmap point_triangulator",
                format!("unknown image '{}' in its output", im.name),
            )
        })?;
        let d = (im.pose.center() - scene.images[k].pose.center()).length();
        if d > 1e-6 * (1.0 + scene.images[k].pose.center().length()) {
            return Err(Error::external(
                "colmap point_triangulator",
                format!(
                    "image '{}' moved by {d}: database ids did not match",
                    scene.images[k].name
                ),
            ));
        }
    }
    Ok(())
}

/// The model COLMAP triangulates from: the scene's cameras (at the staged size) and poses under
/// the staged names, no points; and the feature extractor's camera arguments (one camera for
/// all, or one per image with the known intrinsics, so the database's ids line up).
fn known_model(scene: &Scene, staged: &[String], downscale: u32) -> (Scene, Vec<String>) {
    let mut known = scene.clone();
    known.points.clear();
    for (im, name) in known.images.iter_mut().zip(staged) {
        im.features.clear();
        im.name = name.clone();
    }
    for (i, c) in known.cameras.iter_mut().enumerate() {
        c.id = i as u32 + 1;
        c.camera = c.camera.downscaled(downscale);
    }
    for (i, im) in known.images.iter_mut().enumerate() {
        im.id = i as u32 + 1;
    }
    // One camera per image in the database, with the known intrinsics, so ids line up.
    let single = known.cameras.len() == 1;
    let cam = &known.cameras[0].camera;
    let cam_args = vec![
        s("--ImageReader.single_camera"),
        s(if single { "1" } else { "0" }),
        s("--ImageReader.single_camera_per_image"),
        s(if single { "0" } else { "1" }),
        s("--ImageReader.camera_model"),
        s(cam.model.name()),
        s("--ImageReader.camera_params"),
        cam.params
            .iter()
            .map(|p| p.to_string())
            .collect::<Vec<_>>()
            .join(","),
    ];
    if !single {
        // One camera per image; the ids come from COLMAP's database below.
        let cams: Vec<_> = known
            .images
            .iter()
            .map(|im| known.cameras[im.camera].camera.clone())
            .collect();
        known.cameras = cams
            .into_iter()
            .enumerate()
            .map(|(i, camera)| crate::scene::SceneCamera {
                id: i as u32 + 1,
                camera,
            })
            .collect();
        for (i, im) in known.images.iter_mut().enumerate() {
            im.camera = i;
        }
    }
    (known, cam_args)
}

/// Image pairs worth matching for a posed scene: each image with its `k` nearest neighbours by
/// viewing direction (angle between optical axes, ties broken by centre distance), limited to
/// axes within 90 degrees. Far fewer than all pairs, and the ones that share a view of the scene.
pub fn pairs_from_poses(scene: &Scene, k: usize) -> Vec<(usize, usize)> {
    let axes: Vec<glam::DVec3> = scene
        .images
        .iter()
        .map(|im| im.pose.camera_to_world_dir(glam::DVec3::Z))
        .collect();
    let mut pairs = std::collections::BTreeSet::new();
    for i in 0..scene.images.len() {
        let mut cand: Vec<(f64, f64, usize)> = (0..scene.images.len())
            .filter(|&j| j != i && axes[i].dot(axes[j]) > 0.0)
            .map(|j| {
                let angle = axes[i].dot(axes[j]).clamp(-1.0, 1.0).acos();
                (
                    angle,
                    (scene.images[i].pose.center() - scene.images[j].pose.center()).length(),
                    j,
                )
            })
            .collect();
        cand.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        for &(_, _, j) in cand.iter().take(k) {
            pairs.insert((i.min(j), i.max(j)));
        }
    }
    pairs.into_iter().collect()
}
