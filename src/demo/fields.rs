//! Fields of the demo scene trained from its exact truth, for the edit tests and benchmarks: an
//! object's field from its true masks, and the background field of the scene with some objects
//! removed (their true masks, dilated, carry no loss; their sparse points seed nothing). Step
//! budgets, not time budgets, so a result does not depend on the machine's load.

use super::geometry::World;
use crate::error::{Error, Result};
use crate::field::fit::{fit_scene, fit_scene_field, model_notes, FieldKind, TrainReport};
use crate::field::io::{save, IDENTITY};
use crate::field::{DepthMode, FitOptions, MaskSource, SceneFitOptions};
use crate::scene::Scene;
use std::path::Path;
use std::sync::Arc;

/// How long to train and at which image size.
#[derive(Clone, Debug)]
pub struct DemoFieldOptions {
    pub steps: usize,
    pub seed: u64,
    pub downscale: u32,
    pub depth: DepthMode,
    /// Memory for the grid and its optimiser state, MiB.
    pub memory_mb: usize,
    /// Progress: called with (step, seconds, batch PSNR) every step.
    pub progress: Option<fn(usize, f64, f32)>,
}

impl Default for DemoFieldOptions {
    fn default() -> Self {
        DemoFieldOptions {
            steps: 2000,
            seed: 0,
            downscale: 1,
            depth: DepthMode::Dense,
            memory_mb: 1024,
            progress: None,
        }
    }
}

fn fit_options(o: &DemoFieldOptions) -> FitOptions {
    FitOptions {
        downscale: o.downscale,
        depth: o.depth,
        seed: o.seed,
        steps: o.steps,
        setup: crate::field::SetupConfig {
            memory_budget: o.memory_mb << 20,
            ..Default::default()
        },
        ..Default::default()
    }
}

fn report(o: &DemoFieldOptions, s: &crate::field::train::StepStats) {
    if let Some(p) = o.progress {
        p(s.step, s.seconds, s.psnr);
    }
}

fn load_scene(scene_dir: &Path) -> Result<Scene> {
    Scene::load(&scene_dir.join("transforms.json"))
}

fn check_object(scene_dir: &Path, object: &str) -> Result<()> {
    if World::demo().object(object).is_none() {
        return Err(Error::invalid(format!(
            "{}: the demo scene has no object '{object}'",
            scene_dir.display()
        )));
    }
    Ok(())
}

/// Train `object`'s field of the demo scene in `scene_dir` from its true masks and save it to
/// `out` (an object field, as `objnerf train --masks truth:OBJECT` writes).
pub fn write_object_field(
    scene_dir: &Path,
    object: &str,
    opts: &DemoFieldOptions,
    out: &Path,
) -> Result<TrainReport> {
    check_object(scene_dir, object)?;
    let scene = load_scene(scene_dir)?;
    let masks = MaskSource::Dir(scene_dir.join("truth/masks").join(object));
    let fit = fit_options(opts);
    let fitted = fit_scene(&scene, &masks, &fit, None, &mut |s| report(opts, s))?;
    let notes = model_notes(FieldKind::Object, &scene, &fit, &fitted.report);
    save(out, &fitted.trainer.parts(IDENTITY, notes))?;
    Ok(fitted.report)
}

/// Train the demo scene's background without `removed` (their true masks carry no loss) and save
/// it to `out` (a scene field).
pub fn write_background_field(
    scene_dir: &Path,
    removed: &[&str],
    opts: &DemoFieldOptions,
    out: &Path,
) -> Result<TrainReport> {
    for o in removed {
        check_object(scene_dir, o)?;
    }
    let scene = load_scene(scene_dir)?;
    let world = World::demo();
    let mut union: Vec<Option<image::GrayImage>> = vec![None; scene.images.len()];
    for name in removed {
        let masks = super::truth_masks(scene_dir, &scene, name)?;
        for (u, m) in union.iter_mut().zip(masks) {
            match u {
                None => *u = Some(m),
                Some(acc) => {
                    for (a, b) in acc.pixels_mut().zip(m.pixels()) {
                        a[0] = a[0].max(b[0]);
                    }
                }
            }
        }
    }
    // The removed objects' own sparse points (on their surfaces) seed no density.
    let exclude_points = scene
        .points
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            removed
                .iter()
                .any(|name| world.object(name).is_some_and(|o| o.distance(p.xyz) < 2e-3))
        })
        .map(|(i, _)| i)
        .collect();
    let sopts = SceneFitOptions {
        fit: fit_options(opts),
        removed: (!removed.is_empty()).then(|| Arc::new(union)),
        exclude_points,
        ..Default::default()
    };
    let fitted = fit_scene_field(&scene, &sopts, &mut |s| report(opts, s))?;
    let notes = model_notes(FieldKind::Scene, &scene, &sopts.fit, &fitted.report);
    save(out, &fitted.trainer.parts(IDENTITY, notes))?;
    Ok(fitted.report)
}

/// The files of [`ensure_edit_fields`].
#[derive(Clone, Debug)]
pub struct EditFields {
    pub scene: std::path::PathBuf,
    /// The scene without the mug and the torus.
    pub background: std::path::PathBuf,
    pub mug: std::path::PathBuf,
    pub torus: std::path::PathBuf,
}

/// Step budgets of [`ensure_edit_fields`]: the background's 3000 steps take ~10 CPU-minutes
/// and ~4 GiB at the 512 MiB grid budget (it overshoots on the demo's large floor).
pub const EDIT_BACKGROUND_STEPS: usize = 3000;
pub const EDIT_OBJECT_STEPS: usize = 2000;

/// The demo scene and the fields its edit tests and benchmarks use, in `dir`: made when missing
/// (the default demo scene; the mug and the torus from their true masks; the background
/// without them), reused when present. `log` hears what was trained.
pub fn ensure_edit_fields(dir: &Path, log: &mut dyn FnMut(String)) -> Result<EditFields> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let f = EditFields {
        scene: dir.join("demo"),
        background: dir.join("background.objf"),
        mug: dir.join("mug.objf"),
        torus: dir.join("torus.objf"),
    };
    if !f.scene.join("truth/objects.json").is_file() {
        super::write_demo_scene(&super::DemoOptions::default(), &f.scene)?;
    }
    for (name, out) in [("mug", &f.mug), ("torus", &f.torus)] {
        if !out.is_file() {
            let opts = DemoFieldOptions {
                steps: EDIT_OBJECT_STEPS,
                ..Default::default()
            };
            let r = write_object_field(&f.scene, name, &opts, out)?;
            log(format!(
                "{name}: {} steps in {:.0} s, grid {:?}",
                r.run.steps, r.run.seconds, r.dims
            ));
        }
    }
    if !f.background.is_file() {
        let opts = DemoFieldOptions {
            steps: EDIT_BACKGROUND_STEPS,
            memory_mb: 512,
            ..Default::default()
        };
        let r = write_background_field(&f.scene, &["mug", "torus"], &opts, &f.background)?;
        log(format!(
            "background without the mug and the torus: {} steps in {:.0} s, grid {:?}",
            r.run.steps, r.run.seconds, r.dims
        ));
    }
    Ok(f)
}
