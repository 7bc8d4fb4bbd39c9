//! Object fields of the demo scene trained from its exact truth (true masks), for the edit tests
//! and benchmarks, on step budgets, not time budgets, so a result does not depend on the
//! machine's load. (Backgrounds come from `objnerf remove`: `pipeline::demo_edit`.)

use super::geometry::World;
use crate::error::{Error, Result};
use crate::field::io::{save, IDENTITY};
use crate::field::MaskSource;
use crate::fit::FitOptions;
use crate::fit::{fit_object, model_notes, FieldKind, TrainReport};
use crate::scene::Scene;
use crate::supervision::DepthMode;
use std::path::Path;

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
        // The true masks are exact.
        mask_band: 0,
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
    let fitted = fit_object(&scene, &masks, &fit, None, &mut |s| report(opts, s))?;
    let notes = model_notes(FieldKind::Object, &scene, &fit, &fitted.report);
    save(out, &fitted.trainer.parts(IDENTITY, notes))?;
    Ok(fitted.report)
}
