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

/// How to train a demo object's field: on a step budget (no time budget, so the result does
/// not depend on the machine's load), from the truth's exact masks and depth.
#[derive(Clone, Debug)]
pub struct DemoFieldOptions {
    pub fit: FitOptions,
    /// Progress: called with (step, seconds, batch PSNR) every step.
    pub progress: Option<fn(usize, f64, f32)>,
}

impl DemoFieldOptions {
    /// Train for `steps` steps, the rest as [`Default`].
    pub fn steps(steps: usize) -> DemoFieldOptions {
        let mut o = DemoFieldOptions::default();
        o.fit.steps = steps;
        o
    }
}

impl Default for DemoFieldOptions {
    fn default() -> Self {
        DemoFieldOptions {
            fit: FitOptions {
                steps: 2000,
                depth: DepthMode::Dense,
                setup: crate::field::SetupConfig {
                    memory_budget: 1024 << 20,
                    ..Default::default()
                },
                // The true masks are exact.
                mask_band: 0,
                ..Default::default()
            },
            progress: None,
        }
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
    let fit = &opts.fit;
    let fitted = fit_object(&scene, &masks, fit, None, &mut |s| report(opts, s))?;
    let notes = model_notes(FieldKind::Object, &scene, fit, &fitted.report);
    save(out, &fitted.trainer.parts(IDENTITY, notes))?;
    Ok(fitted.report)
}
